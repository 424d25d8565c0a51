"""Host arrays onto the device (jaxcds._arrays) and builders that compile nothing per mesh."""

import contextlib

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxcds import batch
from jaxcds._arrays import to_device
from jaxcds.generators import random_planar_triangulation
from jaxcds.structures import registry

_COMPILE_EVENT = "/jax/core/compile/backend_compile_duration"


@contextlib.contextmanager
def counting_compilations():
    """Counts XLA compilations (jax.monitoring's backend-compile events) inside the block."""
    seen = []

    def listener(event, duration, **kwargs):
        if event == _COMPILE_EVENT:
            seen.append(duration)

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        yield seen
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)


def test_the_counter_sees_jnp_asarray_compile_a_new_shape():
    # the reason for to_device: if jax stops compiling here, this module can go
    with counting_compilations() as seen:
        jnp.asarray(np.zeros(1237, np.int32))
    assert len(seen) >= 1


@pytest.mark.parametrize("x, dtype, want", [
    (np.arange(5, dtype=np.int64), None, jnp.int32),
    (np.arange(5, dtype=np.float64), None, jnp.float32),
    (np.arange(5, dtype=np.uint8), None, jnp.uint8),
    (np.ones(5, bool), None, jnp.bool_),
    ([1, 2, 3], None, jnp.int32),
    ([1.5, 2.0], None, jnp.float32),
    (np.arange(5, dtype=np.int64), np.int32, jnp.int32),
    (np.arange(5, dtype=np.int32), jnp.float32, jnp.float32),
])
def test_dtypes_are_those_of_jnp_asarray(x, dtype, want):
    got = to_device(x, dtype)
    assert isinstance(got, jax.Array) and got.dtype == want
    np.testing.assert_array_equal(np.asarray(got), np.asarray(x).astype(want))


def test_big_endian_arrays_are_read_in_native_order():
    # jnp.asarray refuses them ("not a valid JAX array type"); a binary file read as it is has them
    for a in (np.arange(5, dtype=">f8"), np.arange(5, dtype=">i4"), np.arange(5, dtype=">u2")):
        got = to_device(a)
        np.testing.assert_array_equal(np.asarray(got), a.astype(a.dtype.newbyteorder("=")))


def test_shapes_are_kept_zero_d_and_strided_too():
    assert to_device(np.int64(3)).shape == ()
    assert to_device(np.zeros((0, 3), np.int64)).shape == (0, 3)
    strided = np.arange(12).reshape(3, 4)[:, ::2]
    np.testing.assert_array_equal(np.asarray(to_device(strided)), strided)


def test_jax_arrays_and_tracers_pass_through():
    x = jnp.arange(4, dtype=jnp.int32)
    assert to_device(x) is x
    assert to_device(x, jnp.float32).dtype == jnp.float32
    assert int(jax.jit(lambda y: to_device(y, jnp.int32).sum())(x)) == 6
    # a nested list under jit is a list of scalar tracers
    assert float(jax.jit(lambda rows: to_device(rows).sum())([[1.0, 2.0], [3.0, 4.0]])) == 10.0


def test_copy_keeps_the_device_array_apart_from_the_callers_buffer():
    for n in (1, 10, 1000, 100_000):
        a = np.arange(n, dtype=np.int32) + 1
        got = to_device(a, copy=True)
        a[:] = -5
        assert int(got[0]) == 1 and int(got[-1]) == n


def test_new_shapes_compile_nothing():
    with counting_compilations() as seen:
        for n in (1301, 1303, 1307):
            to_device(np.zeros(n, np.int32))
            to_device(np.zeros((n, 3)), jnp.float32, copy=True)
    assert seen == []


@pytest.mark.parametrize("name", registry.names())
def test_builds_and_packs_compile_nothing_per_mesh(name):
    """A build or a pack on a mesh of a new size runs host code only: 10,000 pembs spent most of
    their build compiling jnp.asarray copies before (70 ms of a 3 ms build per 2,000-vertex
    mesh; jaxcds._arrays)."""
    meshes = [random_planar_triangulation(n, seed=n) for n in (40, 61, 83, 117)]
    registry.build(name, meshes[0])  # once: numba caches, first-call set-up
    batch.pack(meshes[:1], name)
    with counting_compilations() as seen:
        registry.build(name, meshes[1])
        registry.build(name, meshes[2])
        batch.pack(meshes[1:], name)
    assert seen == [], f"{name}: {len(seen)} XLA compilations in two builds and a pack"


def test_operators_and_normals_take_big_endian_arrays():
    """jnp.asarray and jax.jit refuse big-endian numpy arrays (TypeError naming neither the
    argument nor the fix); the protocol's operators and vertex_normals read them in native order."""
    from jaxcds.algorithms import vertex_normals
    from jaxcds.generators import icosphere

    mesh = icosphere(1)
    s = registry.build("halfedge", mesh)
    ids = np.arange(7)
    np.testing.assert_array_equal(np.asarray(s.twin(ids.astype(">i4"))), np.asarray(s.twin(ids.astype(np.int32))))
    p = np.asarray(mesh.vertices, np.float32)
    np.testing.assert_array_equal(np.asarray(vertex_normals(s, p.astype(">f4"))),
                                  np.asarray(vertex_normals(s, p)))


@pytest.mark.parametrize("kind", ["pemb", "cds5n", "cds5n-o1", "lr"])
def test_eager_operators_compile_once_per_power_of_two(kind):
    """Eager pemb operators compiled every while_loop of their searches for each exact batch
    size and kept it (stop 43: 24 calls of 100-5,000 darts, 119 s and 2.4 GB that stayed); the
    CDS's and LR's loops compiled again on every eager call. Now an eager call (of the classes
    with ``eager_buckets``) is one jitted program per power-of-two size: other sizes in the same bucket
    compile nothing, answers unchanged."""
    from jaxcds.generators import random_planar_triangulation
    from jaxcds.structures import registry

    s = registry.build(kind, random_planar_triangulation(300, seed=3))
    d = s.all_darts()
    e = d[np.random.default_rng(0).integers(0, d.size, 128)].astype(np.int32)
    want = np.asarray(jax.jit(lambda s, e: s.target(e))(s, e))
    np.testing.assert_array_equal(np.asarray(s.target(e[:120])), want[:120])  # bucket 128: compiled
    with counting_compilations() as seen:
        for n in (97, 100, 113, 127, 128):
            np.testing.assert_array_equal(np.asarray(s.target(e[:n])), want[:n])
            np.testing.assert_array_equal(np.asarray(s.target(e[:n].reshape(1, n))), want[None, :n])
    assert seen == []
    np.testing.assert_array_equal(np.asarray(s.target(e[5])), want[5])  # a scalar id
    assert s.target(np.zeros(0, np.int32)).shape == (0,)


@pytest.mark.parametrize("kind", ["cds5n", "cds5n-o1", "lr"])
def test_eager_whole_mesh_methods_are_one_program(kind):
    """Eager whole-mesh methods of the classes that name them in ``jit_when_eager`` run as one
    jitted program: a second call compiles nothing and dispatches no primitive by primitive
    (the CDS kinds' face_vertices / target_table took 0.12-0.19 s per call at 3,000 vertices
    that way, stop 46); answers equal the traced method's, also under ``jax.disable_jit()``."""
    from jaxcds.generators import random_planar_triangulation
    from jaxcds.structures import registry

    s = registry.build(kind, random_planar_triangulation(211, seed=4))
    names = sorted(k for k in type(s).jit_when_eager if callable(getattr(s, k, None)))
    assert "face_vertices" in names
    first = {k: np.asarray(getattr(s, k)()[0] if k == "face_vertices_padded" else getattr(s, k)())
             for k in names}
    with counting_compilations() as seen:
        for k in names:
            got = getattr(s, k)()
            np.testing.assert_array_equal(np.asarray(got[0] if k == "face_vertices_padded" else got),
                                          first[k], err_msg=k)
    assert seen == []
    traced = jax.jit(lambda s: s.face_vertices())(s)
    np.testing.assert_array_equal(np.asarray(traced), first["face_vertices"])
    with jax.disable_jit():
        np.testing.assert_array_equal(np.asarray(s.face_vertices()), first["face_vertices"])


def _has_loop(fn, *args) -> bool:
    jaxpr = str(jax.make_jaxpr(fn)(*args))
    return "while[" in jaxpr or "scan[" in jaxpr  # fori_loop with static bounds is a scan


@pytest.mark.parametrize("platform", ["gpu", "cuda", "rocm", "tpu"])
def test_cache_shaped_routes_follow_one_cpu_decision(monkeypatch, platform):
    """Chunked queries (base), chunked normal sums (batch) and CDS plans in a one-trip loop all
    ask traced_for_cpu: a non-CPU default backend turns all three off, and jax.default_device
    naming a CPU device turns them on again (the query chunks asked jax.default_backend()
    alone before: off even there)."""
    from jaxcds import _arrays
    from jaxcds.structures import base

    mesh = random_planar_triangulation(60, seed=3)
    lr = registry.build("lr", mesh)
    cds = registry.build("cds5n-o1", mesh)
    ids = jnp.zeros(2 * base.QUERY_CHUNK + 5, jnp.int32)
    in_loop = []
    computed_in_loop = base.computed_in_loop
    monkeypatch.setattr(base, "computed_in_loop",
                        lambda *a, **k: in_loop.append(1) or computed_in_loop(*a, **k))

    def routes():
        in_loop.clear()
        jax.make_jaxpr(lambda c: c.all_edge_targets())(cds)
        with base.per_query_routes():  # the chunks, not LR's table of every dart (any backend)
            chunked = _has_loop(lambda d: lr.right_front(d), ids)
        return _arrays.traced_for_cpu(), batch.chunks_pay_off(), chunked, bool(in_loop)

    assert routes() == (True, True, True, True)
    monkeypatch.setattr(jax, "default_backend", lambda: platform)
    assert routes() == (False, False, False, False)
    with jax.default_device(jax.devices("cpu")[0]):
        assert routes() == (True, True, True, True)
