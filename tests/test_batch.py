"""Packed batches (jaxcds.batch): one structure over the disjoint union of many meshes.

Every check compares the batch with the per-mesh structures built independently (the brute
force reference): operators through mesh-local ids, degrees, normals, their gradients, and the
union structure against the HalfEdge with jaxcds.verify.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from jaxcds import batch as B
from jaxcds import errors
from jaxcds._dataclass import replace
from jaxcds.algorithms import adjacent, face_list_vertex_normals, vertex_degrees, vertex_normals
from jaxcds.generators import icosphere, random_planar_triangulation
from jaxcds.mesh import TriMesh, close_boundaries, load_mesh
from jaxcds.structures import CornerTable, HalfEdge, registry
from jaxcds.verify import verify

from conftest import CDS_FAMILY, crash_probe, load_shared, octahedron


def open_meshes():
    """Meshes with and without borders, of different sizes (the HalfEdge case)."""
    return [load_shared("grid.off"), icosphere(1), load_shared("2triangles.off"),
            random_planar_triangulation(40, seed=3), load_mesh(*octahedron())]


def closed_meshes():
    return [icosphere(1), random_planar_triangulation(40, seed=3), close_boundaries(load_shared("grid.off")),
            load_mesh(*octahedron()), random_planar_triangulation(7, seed=1)]


CASES = [("halfedge", HalfEdge, open_meshes), ("corner-table", CornerTable, closed_meshes)]


@pytest.mark.parametrize("name,cls,meshes", CASES)
def test_union_build_equals_concatenated_parts(name, cls, meshes):
    ms = meshes()
    b = B.pack(ms, name)
    c = B.concatenate([cls.from_mesh(m) for m in ms])
    for f in jax.tree_util.tree_leaves(b):
        assert f.dtype == jnp.int32
    la, ta = jax.tree_util.tree_flatten(b)
    lb, tb = jax.tree_util.tree_flatten(c)
    assert ta == tb
    for x, y in zip(la, lb):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    assert b.num_meshes == len(ms)
    assert b.num_vertices == sum(m.num_vertices for m in ms)
    assert b.num_faces == sum(m.num_faces for m in ms)
    if name == "halfedge":  # grid.off and 2triangles.off have borders: the extra dart block
        assert int(np.sum(np.asarray(b.n_extra_dart))) == 32 + 4
        assert b.num_extra_darts == 36


@pytest.mark.parametrize("name,cls,meshes", CASES)
@pytest.mark.parametrize("jit", [pytest.param(False, marks=pytest.mark.slow), True], ids=["eager", "jit"])
def test_local_queries_equal_per_mesh_structures(name, cls, meshes, jit):
    ms = meshes()
    b = B.pack(ms, name)
    parts = [cls.from_mesh(m) for m in ms]
    # one query batch mixing every mesh: (mesh, local id) pairs
    rng = np.random.default_rng(0)
    mesh_ids = rng.integers(0, len(ms), 300).astype(np.int32)
    for op, (arg, _) in B.OPERATOR_KINDS.items():
        size = {"dart": lambda p: p.num_darts, "vertex": lambda p: p.num_vertices,
                "face": lambda p: p.num_faces}[arg]
        local = np.array([rng.integers(0, size(parts[i])) for i in mesh_ids], np.int32)
        q = (jax.jit(lambda s, m, e: s.query(op, m, e)) if jit else
             (lambda s, m, e: s.query(op, m, e)))
        got = np.asarray(q(b, jnp.asarray(mesh_ids), jnp.asarray(local)))
        want = np.zeros_like(got)
        for i, p in enumerate(parts):  # reference: each mesh's own structure, vectorised
            sel = mesh_ids == i
            want[sel] = np.asarray(getattr(p, op)(jnp.asarray(local[sel])))
        np.testing.assert_array_equal(got, want, err_msg=f"{name}.{op}")


def test_local_global_round_trip_and_owner():
    ms = open_meshes()
    b = B.pack(ms, "halfedge")
    for kind, cnt in (("vertex", b.n_vertex), ("face", b.n_face)):
        m = np.repeat(np.arange(b.num_meshes), np.asarray(cnt))
        loc = np.concatenate([np.arange(c) for c in np.asarray(cnt)])
        g = np.asarray(b.to_global(kind, m, loc))
        np.testing.assert_array_equal(g, np.arange(g.size))  # contiguous, in mesh order
        np.testing.assert_array_equal(np.asarray(b.mesh_of(kind, g)), m)
        np.testing.assert_array_equal(np.asarray(b.to_local(kind, m, g)), loc)
        np.testing.assert_array_equal(np.asarray(b.vertex_mesh() if kind == "vertex" else b.face_mesh()), m)
    # darts: the border (extra) block of mesh i lies after every inner dart
    nd = np.asarray(b.n_dart) + np.asarray(b.n_extra_dart)
    m = np.repeat(np.arange(b.num_meshes), nd)
    loc = np.concatenate([np.arange(c) for c in nd])
    g = np.asarray(b.to_global("dart", m, loc))
    assert np.unique(g).size == b.num_darts == g.size
    np.testing.assert_array_equal(np.asarray(b.mesh_of("dart", g)), m)
    np.testing.assert_array_equal(np.asarray(b.dart_mesh())[g], m)
    np.testing.assert_array_equal(np.asarray(b.to_local("dart", m, g)), loc)
    # sentinels: one past the end locally <-> globally
    assert int(b.to_global("face", 0, int(b.n_face[0]))) == b.num_faces
    assert int(b.to_local("face", 2, b.num_faces)) == int(b.n_face[2])
    assert int(b.to_global("dart", 1, int(nd[1]))) == b.num_darts
    assert int(b.mesh_of("vertex", b.num_vertices)) == b.num_meshes


@pytest.mark.parametrize("name", ["halfedge", "cds5n", "lr", pytest.param("pemb", marks=pytest.mark.slow)])
def test_ids_out_of_range_answer_absent(name):
    """A negative local id, or a mesh index outside the batch, used to be answered from another
    mesh (JAX wraps negative indices and clamps large ones): now they read as the sentinel."""
    ms = [load_mesh(*octahedron()), icosphere(1)]
    b = B.pack(ms, name)
    nb = b.num_meshes
    for mesh, local in ((1, -1), (0, -5), (nb, 0), (-1, 0), (nb + 3, 2)):
        assert int(b.to_global("dart", mesh, local)) == b.num_darts
        assert int(b.to_global("vertex", mesh, local)) == b.num_vertices
        assert int(b.to_global("face", mesh, local)) == b.num_faces
        assert not bool(b.query("dart_valid", mesh, local))
        near = min(max(mesh, 0), nb - 1)
        assert int(b.query("origin", mesh, local)) == int(b.n_vertex[near])  # the local "absent"
        assert int(b.query("twin", mesh, local)) == int(b.n_dart[near] + b.n_extra_dart[near])
        assert int(b.query("edge_of_vertex", mesh, local)) == int(b.n_dart[near] + b.n_extra_dart[near])
    # in range: unchanged
    d = b.query("edge_of_vertex", 1, 3)
    assert bool(b.query("dart_valid", 1, d)) and int(b.query("origin", 1, d)) == 3


@pytest.mark.parametrize("name,cls,meshes", CASES)
def test_union_structure_passes_verify(name, cls, meshes):
    ms = meshes()
    b = B.pack(ms, name)
    rep = verify(b, B._union(ms))
    assert rep.ok, str(rep)


@pytest.mark.parametrize("name,cls,meshes", [CASES[0], pytest.param(*CASES[1], marks=pytest.mark.slow)])
def test_degrees_normals_and_gradients_equal_per_mesh(name, cls, meshes):
    ms = meshes()
    b = B.pack(ms, name)
    parts = [cls.from_mesh(m) for m in ms]
    pos = B.pack_positions(b, ms)
    np.testing.assert_array_equal(
        np.asarray(vertex_degrees(b)),
        np.concatenate([np.asarray(vertex_degrees(p)) for p in parts]))
    got = np.asarray(vertex_normals(b, pos))
    want = np.concatenate([np.asarray(vertex_normals(p, jnp.asarray(m.vertices, jnp.float32)))
                           for p, m in zip(parts, ms)])
    np.testing.assert_allclose(got, want, atol=1e-5)
    # the navigation (gather) route turns around every vertex of every mesh in one loop
    np.testing.assert_allclose(np.asarray(vertex_normals(b, pos, method="gather")), got, atol=1e-5)
    # the face-list baseline on the union faces agrees as well
    np.testing.assert_allclose(np.asarray(vertex_normals(b, pos)),
                               np.asarray(face_list_vertex_normals(pos, jnp.asarray(B._union(ms).faces))),
                               atol=1e-5)
    # gradient of one scalar over the whole batch == per-mesh gradients, concatenated
    w = jnp.asarray(np.random.default_rng(1).normal(size=pos.shape), jnp.float32)
    g = np.asarray(jax.jit(jax.grad(lambda p: jnp.sum(vertex_normals(b, p) * w)))(pos))
    wl = b.split(np.asarray(w))
    for i, (p, m) in enumerate(zip(parts, ms)):
        gi = jax.grad(lambda q: jnp.sum(vertex_normals(p, q) * wl[i]))(jnp.asarray(m.vertices, jnp.float32))
        np.testing.assert_allclose(b.split(g)[i], np.asarray(gi), atol=1e-4)
    assert np.all(np.isfinite(g)) and np.any(g != 0)


def _check_adjacent_local(b, parts, count: int):
    """``b.adjacent_local`` on ``count`` random mesh-local pairs (half of them true neighbours,
    found through the batch's own Target) equals each part's ``adjacent``; returns the pairs'
    ``(mesh_ids, u)``."""
    rng = np.random.default_rng(2)
    mesh_ids = rng.integers(0, len(parts), count).astype(np.int32)
    u = np.array([rng.integers(0, parts[i].num_vertices) for i in mesh_ids], np.int32)
    v = np.array([rng.integers(0, parts[i].num_vertices) for i in mesh_ids], np.int32)
    v[::2] = np.asarray(b.query("target", mesh_ids, b.query("edge_of_vertex", mesh_ids, u)))[::2]
    got = np.asarray(jax.jit(lambda s, m, a, c: s.adjacent_local(m, a, c))(b, mesh_ids, u, v))
    want = np.zeros(got.shape, bool)
    for i, p in enumerate(parts):
        sel = mesh_ids == i
        want[sel] = np.asarray(adjacent(p, u[sel], v[sel]))
    np.testing.assert_array_equal(got, want)
    assert got[::2].all()
    return mesh_ids, u


def test_adjacent_with_local_ids():
    ms = open_meshes()
    b = B.pack(ms, "halfedge")
    parts = [HalfEdge.from_mesh(m) for m in ms]
    mesh_ids, u = _check_adjacent_local(b, parts, 300)
    # a vertex is never adjacent to a vertex of another mesh
    other = np.asarray(b.to_global("vertex", (mesh_ids + 1) % len(ms), 0))
    assert not np.asarray(adjacent(b, b.to_global("vertex", mesh_ids, u), other)).any()


def test_per_mesh_reductions():
    ms = closed_meshes()
    b = B.pack(ms, "corner-table")
    deg = vertex_degrees(b)
    got = np.asarray(b.per_mesh_sum(deg))
    # sum of degrees = 2E = 6V - 12 on a closed genus-0 mesh (Euler), per mesh
    np.testing.assert_array_equal(got, [6 * m.num_vertices - 12 for m in ms])
    mean = np.asarray(b.per_mesh_mean(deg.astype(jnp.float32)))
    np.testing.assert_allclose(mean, [6 - 12 / m.num_vertices for m in ms], rtol=1e-6)
    area2 = np.asarray(b.per_mesh_sum(jnp.ones(b.num_faces), kind="face"))
    np.testing.assert_array_equal(area2, [m.num_faces for m in ms])


def test_per_mesh_reductions_read_host_values_by_value():
    """Sweep 13: big-endian values raised jax's TypeError, uint8 sums wrapped at 256, bools and
    lists and masked arrays were untyped failures or silently unmasked."""
    ms = closed_meshes()
    b = B.pack(ms, "corner-table")
    nv = np.array([m.num_vertices for m in ms])
    v = np.arange(b.num_vertices, dtype=np.float32)
    want = np.asarray(b.per_mesh_sum(v))
    np.testing.assert_array_equal(np.asarray(b.per_mesh_sum(v.astype(">f4"))), want)
    np.testing.assert_array_equal(np.asarray(b.per_mesh_sum(v.tolist())), want)
    np.testing.assert_allclose(np.asarray(b.per_mesh_mean(v.astype(">f8"))), want / nv, rtol=1e-6)
    np.testing.assert_array_equal(np.asarray(b.per_mesh_sum(np.full(b.num_vertices, 200, np.uint8))), 200 * nv)
    np.testing.assert_array_equal(np.asarray(b.per_mesh_sum(np.ones(b.num_vertices, bool))), nv)
    with pytest.raises(errors.ArgumentError, match="per_mesh_sum: values are a masked array"):
        b.per_mesh_sum(np.ma.array(v, mask=v > 3))
    with pytest.raises(errors.ArgumentError, match="per_mesh_mean: values must be real numbers"):
        b.per_mesh_mean(v.astype(str))


def test_batch_helpers_refuse_bad_arguments_by_name():
    """An unknown operator or id kind, and per-vertex / per-face arrays of the wrong length, are
    ArgumentErrors naming the call (a segment sum dropped or misassigned rows silently)."""
    ms = closed_meshes()
    b = B.pack(ms, "corner-table")
    with pytest.raises(errors.ArgumentError, match="unknown operator 'tagret'"):
        b.query("tagret", 0, 0)
    with pytest.raises(errors.ArgumentError, match="unknown id kind 'edge'"):
        b.per_mesh_sum(jnp.ones(b.num_vertices), kind="edge")
    with pytest.raises(errors.ArgumentError, match=f"per_mesh_sum.*one row per vertex.*{b.num_vertices}"):
        b.per_mesh_sum(jnp.ones(b.num_vertices - 1))
    with pytest.raises(errors.ArgumentError, match="one row per face"):
        b.per_mesh_mean(jnp.ones(b.num_vertices), kind="face")
    with pytest.raises(errors.ArgumentError, match="split.*one row per vertex"):
        b.split(np.ones(3))
    with pytest.raises(errors.ArgumentError, match="unpermute"):
        b.unpermute(np.ones(b.num_vertices + 1))
    with pytest.raises(errors.ArgumentError, match="split"):
        b.split(np.float32(1.0))  # a scalar has no rows
    # the right lengths still pass, under jit too
    assert len(b.split(np.ones(b.num_faces), kind="face")) == len(ms)
    assert jax.jit(lambda x: b.per_mesh_sum(x))(jnp.ones(b.num_vertices)).shape == (len(ms),)


@pytest.mark.parametrize("name", ["cds6n", "cds4n"])
def test_per_mesh_reductions_are_the_input_meshes_on_holed_meshes(name):
    """A CDS batch keeps each hole's dummy vertex and fan: per-mesh sums and means over vertices
    and faces leave them out, so they equal the half-edge batch's of the same open meshes."""
    ms = [icosphere(1), load_shared("grid.off")]
    b, h = B.pack(ms, name), B.pack(ms, "halfedge")
    assert int(np.asarray(b.dummy_vertex_mask()).sum()) >= 1
    for f in ("per_mesh_sum", "per_mesh_mean"):
        np.testing.assert_allclose(np.asarray(getattr(b, f)(vertex_degrees(b).astype(jnp.float32))),
                                   np.asarray(getattr(h, f)(vertex_degrees(h).astype(jnp.float32))), rtol=1e-6)
        # positions: the dummies (at their holes' centroids) are not the meshes' vertices
        np.testing.assert_allclose(np.asarray(getattr(b, f)(B.pack_positions(b, ms))),
                                   np.asarray(getattr(h, f)(B.pack_positions(h, ms))), rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(np.asarray(getattr(b, f)(jnp.ones(b.num_faces), kind="face")),
                                   np.asarray(getattr(h, f)(jnp.ones(h.num_faces), kind="face")))


def test_same_totals_do_not_recompile():
    """Counts and offsets are leaves: two batches with the same totals share one compilation."""
    a = [icosphere(1), random_planar_triangulation(40, seed=3)]
    c = [random_planar_triangulation(40, seed=4), icosphere(1)]  # same totals, other split
    ba, bc = B.pack(a, "corner-table"), B.pack(c, "corner-table")
    traces = []

    @jax.jit
    def f(s, p):
        traces.append(1)
        return s.per_mesh_sum(vertex_normals(s, p)[:, 2])

    f(ba, B.pack_positions(ba, a))
    out = f(bc, B.pack_positions(bc, c))
    assert len(traces) == 1
    assert out.shape == (2,)


def test_errors_name_the_mesh():
    good = icosphere(1)
    with pytest.raises(errors.NonManifoldEdgeError, match="mesh 1"):
        B.pack([good, load_shared("cow.off")], "halfedge")
    with pytest.raises(errors.UnsupportedTopologyError, match="mesh 2.*closed"):
        B.pack([good, good, load_shared("grid.off")], "corner-table")
    with pytest.raises(errors.EmptyMeshError):
        B.pack([], "halfedge")
    with pytest.raises(errors.JaxcdsError, match="unknown structure"):
        B.pack([good], "no-such-structure")
    with pytest.raises(errors.UnsupportedTopologyError, match="one structure kind"):
        B.concatenate([HalfEdge.from_mesh(good), CornerTable.from_mesh(good)])
    with pytest.raises(errors.ArgumentError, match="2 meshes for a batch of 1"):
        B.pack_positions(B.pack([good], "halfedge"), [good, good])
    with pytest.raises(errors.MeshError, match="mesh 0 has 12 positions"):
        B.pack_positions(B.pack([good], "halfedge"), [np.zeros((12, 3))])


def test_class_without_concatenate_is_refused():
    from jaxcds.structures.base import MeshStructure

    class NoHook(MeshStructure):  # a structure class that did not implement the hook
        name = "nohook"

    with pytest.raises(errors.UnsupportedTopologyError, match="no `concatenate"):
        B.concatenate([NoHook(), NoHook()])
    s = CornerTable.from_mesh(icosphere(1))
    assert isinstance(B.concatenate([s, s]).structure, CornerTable)


COMPACT = [n for n in registry.names() if n not in ("halfedge", "corner-table")]


@pytest.mark.slow  # builds every registered structure (numba compiles on a cold cache)
@pytest.mark.parametrize("name", COMPACT or ["(none registered)"])
def test_registry_structures_pack(name):
    """Every other registered structure: packed through its ``concatenate`` and checked operator
    by operator against the HalfEdge of the union. Structures without the hook must be refused
    with a clear error (listed as 'still to do' in the issue note)."""
    if name == "(none registered)":
        pytest.skip("no compact structure registered yet")
    ms = [random_planar_triangulation(30, seed=s) for s in range(3)]
    try:
        b = B.pack(ms, name)
    except errors.UnsupportedTopologyError as exc:
        # the refusals allowed here: a class without the hook, or one refused by name with its reason
        assert name in B.REFUSED or "concatenate" in str(exc), str(exc)
        pytest.xfail(f"{name}: {exc}")
    rep = verify(b, B._union(ms))
    assert rep.ok, str(rep)


# ---------------------------------------------------------------------------------- compact kinds
# CDS family: ids shifted (30-bit vertex fields, service bits kept), roots per mesh;
# LR / lr-bits: ids kept local, every operator evaluated on each element's mesh;
# pemb: bit vectors and parentheses concatenated, roots and walk ends per mesh.
PACKABLE = [*CDS_FAMILY, "lr", "lr-bits", "pemb"]
QUICK_OPS = ("target", "twin", "next", "prev", "face_left", "face_right", "ccw_vertex_edge",
             "corner_opposite", "edge_of_vertex", "edge_of_face", "dart_valid")


def compact_meshes():
    """Four small closed genus-0 meshes of different sizes (CDS and pemb need connected genus 0)."""
    return [icosphere(1), random_planar_triangulation(30, seed=3), load_mesh(*octahedron()),
            random_planar_triangulation(9, seed=1)]


def _local_ids(part, arg):
    if arg == "dart":  # valid darts only: on the holes of the id space (LR's i = 3, 7, redundant
        return part.all_darts()  # T2 slots) a single structure answers garbage, not a dart
    return np.arange(part.num_vertices if arg == "vertex" else part.num_faces, dtype=np.int32)


def _check_ops(b, parts, ops, jit=True):
    for op in ops:
        arg = B.OPERATOR_KINDS[op][0]
        locs = [_local_ids(p, arg) for p in parts]
        mesh = np.concatenate([np.full(x.size, i, np.int32) for i, x in enumerate(locs)])
        q = jax.jit(lambda s, m, e: s.query(op, m, e)) if jit else (lambda s, m, e: s.query(op, m, e))
        got = np.asarray(q(b, jnp.asarray(mesh), jnp.asarray(np.concatenate(locs))))
        want = np.concatenate([np.asarray(getattr(p, op)(jnp.asarray(x))) for p, x in zip(parts, locs)])
        np.testing.assert_array_equal(got, want, err_msg=f"{type(parts[0]).__name__}.{op}")


def _probe(s, ids):
    """Main operators on every valid id, degrees and faces: ONE program per structure (compile
    time dominates these tests)."""
    d, v, f = ids
    return (s.target(d), s.next(d), s.face_left(d), s.edge_of_vertex(v), s.edge_of_face(f),
            vertex_degrees(s), s.face_vertices())


@pytest.mark.parametrize("name", ["cds5n", "lr"])
def test_compact_batch_quick(name):
    """Quick check of both routes (CDS shift, LR local evaluation) on two small meshes: global
    answers of the batch == per-mesh answers shifted by the offsets (the slow tests below run
    every kind and every operator)."""
    ms = compact_meshes()[2:]
    b = B.pack(ms, name)
    parts = [registry.build(name, m) for m in ms]
    vo, fo, do = (np.asarray(x) for x in (b.vertex_offsets, b.face_offsets, b.dart_offsets))
    ids = [(p.all_darts(), np.arange(p.num_vertices, dtype=np.int32), np.arange(p.num_faces, dtype=np.int32))
           for p in parts]
    gids = tuple(jnp.asarray(np.concatenate([x[k] + o[i] for i, x in enumerate(ids)]))
                 for k, o in enumerate((do, vo, fo)))
    got = jax.jit(_probe)(b, gids)
    want = [jax.jit(_probe)(p, tuple(jnp.asarray(a) for a in x)) for p, x in zip(parts, ids)]
    kinds = (vo, do, fo, do, do, None, vo)  # the offset of each answer's kind
    for k, off in enumerate(kinds):
        w = np.concatenate([np.asarray(wi[k]) + (0 if off is None else off[i]) for i, wi in enumerate(want)])
        np.testing.assert_array_equal(np.asarray(got[k]), w, err_msg=f"{name} output {k}")


@pytest.mark.slow
@pytest.mark.parametrize("name", PACKABLE)
def test_compact_batch_equals_per_mesh_structures(name):
    """One packed batch per kind, against the per-mesh structures mapped through the offsets:
    the main operators on every valid local id, degrees, normals (in the composed vertex order)
    and the gradient of one scalar over the whole batch == the per-mesh gradients."""
    ms = compact_meshes()
    b = B.pack(ms, name)
    parts = [registry.build(name, m) for m in ms]
    assert b.num_meshes == 4 and b.num_vertices == sum(p.num_vertices for p in parts)
    assert b.num_faces == sum(p.num_faces for p in parts) and b.num_darts == sum(p.num_darts for p in parts)
    _check_ops(b, parts, QUICK_OPS)
    np.testing.assert_array_equal(np.asarray(vertex_degrees(b)),
                                  np.concatenate([np.asarray(vertex_degrees(p)) for p in parts]))
    # faces: mesh i's face f is face_offsets[i] + f, vertices shifted by vertex_offsets[i]
    fv = np.asarray(b.face_vertices())
    want_fv = np.concatenate([np.asarray(p.face_vertices()) + o
                              for p, o in zip(parts, np.asarray(b.vertex_offsets))])
    np.testing.assert_array_equal(fv, want_fv)
    pos = B.pack_positions(b, ms)
    per = [jnp.asarray(m.vertices if p.vertex_order is None else m.vertices[p.vertex_order], jnp.float32)
           for p, m in zip(parts, ms)]
    np.testing.assert_array_equal(np.asarray(pos), np.concatenate([np.asarray(x) for x in per]))
    got = np.asarray(jax.jit(vertex_normals)(b, pos))
    np.testing.assert_allclose(got, np.concatenate([np.asarray(vertex_normals(p, x)) for p, x in zip(parts, per)]),
                               atol=1e-5)
    w = jnp.asarray(np.random.default_rng(1).normal(size=pos.shape), jnp.float32)
    g = np.asarray(jax.jit(jax.grad(lambda p: jnp.sum(vertex_normals(b, p) * w)))(pos))
    wl = b.split(np.asarray(w))
    for i, (p, x) in enumerate(zip(parts, per)):
        gi = jax.grad(lambda q: jnp.sum(vertex_normals(p, q) * wl[i]))(x)
        np.testing.assert_allclose(b.split(g)[i], np.asarray(gi), atol=1e-4)
    assert all(np.any(gi != 0) for gi in b.split(g))  # every mesh's positions get a gradient


@pytest.mark.slow
@pytest.mark.parametrize("name", PACKABLE)
def test_compact_batch_every_operator_and_verify(name):
    """Every protocol operator (valid ids), Adjacent with local ids, the gather normals route,
    and the union structure against the HalfEdge of the union with jaxcds.verify."""
    ms = compact_meshes()
    b = B.pack(ms, name)
    parts = [registry.build(name, m) for m in ms]
    _check_ops(b, parts, tuple(B.OPERATOR_KINDS))
    _check_adjacent_local(b, parts, 200)
    pos = B.pack_positions(b, ms)
    np.testing.assert_allclose(np.asarray(vertex_normals(b, pos, method="gather")),
                               np.asarray(vertex_normals(b, pos)), atol=1e-5)
    rep = verify(b, B._union(ms))
    assert rep.ok, str(rep)


def test_cds_concatenate_shifts_vertex_fields_and_keeps_service_bits():
    """The bit-packed references of the union, read independently: low 30 bits = the part's
    + its vertex offset, bits 30-31 unchanged; F_blue shifted; the cwBFS order composed."""
    from jaxcds.structures.cds import CDS4n

    ms = compact_meshes()
    parts = [CDS4n.from_mesh(m) for m in ms]
    s = CDS4n.concatenate(parts)
    u = np.asarray(s.refs).view(np.uint32)
    off = 0
    for p in parts:
        x = np.asarray(p.refs).view(np.uint32)
        y = u[off:off + p.num_vertices]
        np.testing.assert_array_equal(y & 0x3FFFFFFF, (x & 0x3FFFFFFF) + off)
        np.testing.assert_array_equal(y >> 30, x >> 30)
        np.testing.assert_array_equal(np.asarray(s.F_blue)[off:off + p.num_vertices], np.asarray(p.F_blue) + off)
        np.testing.assert_array_equal(s.vertex_order[off:off + p.num_vertices], p.vertex_order + off)
        off += p.num_vertices
    assert sorted(s.vertex_order.tolist()) == list(range(off))
    with pytest.raises(errors.UnsupportedTopologyError, match="one structure kind"):
        CDS4n.concatenate([parts[0], registry.build("cds5n", ms[0])])


def _pemb_probe(s, d, v, f):
    return (s.origin(d), s.next(d), s.face(d), s.edge_of_vertex(v), s.edge_of_face(f), s.last(v))


def _probe_per_mesh(parts):
    """The probe (tables route) of each mesh's own pemb, jitted once per shape."""
    ar = lambda n: jnp.arange(n, dtype=jnp.int32)  # noqa: E731
    probe = jax.jit(_pemb_probe)
    return [probe(p.with_tables(), ar(p.num_darts), ar(p.num_vertices), ar(p.num_faces)) for p in parts]


def _assert_probe_of_union(s, b, parts, want, label=""):
    """The probe on every global id of the union structure ``s`` (of batch ``b``) equals each
    mesh's answers ``want`` mapped through the offsets (a face sentinel to the union's)."""
    ar = lambda n: jnp.arange(n, dtype=jnp.int32)  # noqa: E731
    got = jax.jit(_pemb_probe)(s, ar(s.num_darts), ar(s.num_vertices), ar(s.num_faces))
    do, vo, fo = (np.asarray(x) for x in (b.dart_offsets, b.vertex_offsets, b.face_offsets))
    for k, off in enumerate((vo, do, fo, do, do, do)):
        w = np.concatenate([np.where((k == 2) & (np.asarray(wi[k]) == p.num_faces), s.num_faces,
                                     np.asarray(wi[k]) + off[i])
                            for i, (wi, p) in enumerate(zip(want, parts))])
        np.testing.assert_array_equal(np.asarray(got[k]), w, err_msg=f"{label} output {k}")


def _annulus(m):
    """``m`` with face 0 and a face sharing no vertex with it removed (two border loops, every
    vertex still in a triangle); ``m`` itself when no such face exists."""
    far = ~np.isin(m.faces, m.faces[0]).any(axis=1)
    if not far.any():
        return m
    keep = np.ones(m.num_faces, bool)
    keep[[0, int(np.argmax(far))]] = False
    return TriMesh(vertices=m.vertices, faces=m.faces[keep], source="annulus")


def test_pemb_batch_quick():
    """pemb batch, quick: meshes with and without border loops, one program of the main
    operators on every global id (every root, walk end and border loop), searched and with
    the per-phase tables, == each mesh's own pemb (its tables) mapped through the offsets."""
    ms = [load_shared("2triangles.off"), random_planar_triangulation(12, seed=2),
          load_shared("grid.off"), load_mesh(*octahedron())]
    b = B.pack(ms, "pemb")
    parts = [registry.build("pemb", m) for m in ms]
    u = b.structure
    want = _probe_per_mesh(parts)
    for s in (u, u.with_tables()):
        _assert_probe_of_union(s, b, parts, want, type(s).__name__)
    with pytest.raises(errors.UnsupportedTopologyError, match="packed batch cannot be packed again"):
        type(u).concatenate([u, u])


@pytest.mark.slow
@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sizes=st.lists(st.integers(4, 80), min_size=2, max_size=4),
       opened=st.lists(st.booleans(), min_size=4, max_size=4), seed=st.integers(0, 2**31 - 1))
def test_pemb_batch_on_random_triangulations(sizes, opened, seed):
    """Hypothesis: 2 to 4 random planar triangulations of 4 to 80 vertices, some opened (two
    faces apart removed: two border loops, the walk starts on one, the other is a hole of the
    union's face renumbering), packed as pemb: the main
    operators on every global id (per-phase tables route, the searching route's equal is the
    quick test's) == each mesh's own pemb mapped through the offsets."""
    ms = []
    for i, n in enumerate(sizes):
        m = random_planar_triangulation(n, seed=(seed + i) % 2**31)
        ms.append(_annulus(m) if opened[i] else m)
    b = B.pack(ms, "pemb")
    parts = [registry.build("pemb", m) for m in ms]
    u = b.structure
    _assert_probe_of_union(u.with_tables(), b, parts, _probe_per_mesh(parts))
    np.testing.assert_array_equal(np.asarray(u.face_vertices()), np.concatenate(
        [np.asarray(p.face_vertices()) + o for p, o in zip(parts, np.asarray(b.vertex_offsets))]))


@pytest.mark.slow
def test_pemb_batch_every_operator_with_borders():
    """pemb (concatenated walks, jaxcds.structures.pemb_packed): meshes with and without border
    loops, every protocol operator on every local id, with and without the per-phase tables
    (their roots per mesh), and faces == the per-mesh pembs' shifted."""
    from jaxcds.structures.pemb_packed import PackedPEMB, PackedPEMBTables

    ms = [load_shared("grid.off"), random_planar_triangulation(12, seed=2),
          load_shared("2triangles.off"), load_mesh(*octahedron())]
    b = B.pack(ms, "pemb")
    parts = [registry.build("pemb", m) for m in ms]
    assert isinstance(b.structure, PackedPEMB) and not b.structure.root_border
    _check_ops(b, parts, tuple(B.OPERATOR_KINDS))
    tb = replace(b, structure=b.structure.with_tables())
    assert isinstance(tb.structure, PackedPEMBTables)
    _check_ops(tb, parts, ("origin", "target", "twin", "next", "face", "edge_of_face"))
    vo = np.asarray(b.vertex_offsets)
    np.testing.assert_array_equal(np.asarray(b.face_vertices()), np.concatenate(
        [np.asarray(p.face_vertices()) + o for p, o in zip(parts, vo)]))
    u = b.structure  # first/last/degree of every vertex (the roots: per mesh)
    v = jnp.arange(u.num_vertices, dtype=jnp.int32)
    do = np.asarray(b.dart_offsets)
    for op in ("first", "last"):
        np.testing.assert_array_equal(np.asarray(getattr(u, op)(v)), np.concatenate(
            [np.asarray(getattr(p, op)(jnp.arange(p.num_vertices))) + o for p, o in zip(parts, do)]))
    with pytest.raises(errors.UnsupportedTopologyError, match="packed batch cannot be packed again"):
        type(u).concatenate([u, u])


def test_pemb_batch_of_bordered_meshes_reads_borders_by_excess():
    """When every mesh's only border loop is its root face (the walk starts on it), the union
    keeps pemb's ``is_border`` by excess (``root_border``), answered per mesh."""
    ms = [load_shared("grid.off"), load_shared("2triangles.off"), load_shared("grid.off")]
    b = B.pack(ms, "pemb")
    parts = [registry.build("pemb", m) for m in ms]
    assert b.structure.root_border and all(p.root_border for p in parts)
    _check_ops(b, parts, ("is_border",))


@pytest.mark.parametrize("name", ["cds5n", "cds4n", "lr"])
def test_pack_positions_of_holed_meshes(name):
    """Holed meshes: the CDS family keeps each hole's dummy vertex as a vertex (CDS paper Sec.
    4.5), LR gives it a null index (LR paper Sec. 4.6). pack_positions follows the structure:
    the packed normals equal each mesh's own structure's normals on its own positions (the
    closed mesh's for a CDS)."""
    from jaxcds.mesh import validate_and_close

    ms = [load_shared("2triangles.off"), load_shared("grid.off"), icosphere(1)]
    b = B.pack(ms, name)
    parts = [registry.build(name, m) for m in ms]
    pos = B.pack_positions(b, ms)
    assert pos.shape == (b.num_vertices, 3)
    want = []
    for p, m in zip(parts, ms):
        v = m.vertices if p.num_vertices == m.num_vertices else validate_and_close(m).vertices
        assert v.shape[0] == p.num_vertices
        v = v if p.vertex_order is None else v[np.asarray(p.vertex_order)]
        want.append(np.asarray(vertex_normals(p, jnp.asarray(v, jnp.float32))))
    np.testing.assert_allclose(np.asarray(vertex_normals(b, pos)), np.concatenate(want), atol=1e-5)
    with pytest.raises(errors.MeshError, match="mesh 1 has 3 positions"):
        B.pack_positions(b, [ms[0], np.zeros((3, 3)), ms[2]])
    # meshes the user closed (dummies flagged): the same list packs and positions, for a
    # structure that keeps the dummies (CDS) and one that drops them (LR)
    closed = [validate_and_close(m) for m in ms]
    bc = B.pack(closed, name)
    np.testing.assert_allclose(np.asarray(vertex_normals(bc, B.pack_positions(bc, closed))),
                               np.asarray(vertex_normals(b, pos)), atol=1e-5)


def test_pack_positions_checks_the_width():
    """(n, 2), (n, 4) and 1-D arrays passed the row-count check (then np.concatenate failed, or
    nothing did): a MeshError names the mesh and the shape."""
    ms = [load_mesh(*octahedron()), icosphere(1)]
    b = B.pack(ms, "halfedge")
    good = [np.asarray(m.vertices) for m in ms]
    for bad in (good[1][:, :2], np.hstack([good[1], good[1][:, :1]]), good[1].reshape(-1)):
        with pytest.raises(errors.MeshError, match="mesh 1's positions have shape"):
            B.pack_positions(b, [good[0], bad])
    assert B.pack_positions(b, good).shape == (b.num_vertices, 3)


def test_host_ids_that_would_wrap_or_truncate_are_not_answered_as_another_id():
    """Eighth sweep: ``query``/``to_global`` cast host ids to int32, so 2**32 + 1 wrapped onto
    local id 1 (and a mesh index 2**32 + 1 onto mesh 1), 1.7 truncated to 1 and True read as 1:
    answers about another id. Now integers past int32 read as out of range ("absent"), floats,
    bools and strings are InvalidIndexErrors, shapes that do not broadcast an ArgumentError."""
    ms = [load_mesh(*octahedron()), icosphere(1)]
    b = B.pack(ms, "halfedge")
    big = np.int64(2**32 + 1)
    assert not bool(b.query("dart_valid", 0, big))
    assert not bool(b.query("dart_valid", big, 1))
    assert int(b.query("origin", 0, np.array([big, -big, 1]))[0]) == int(b.n_vertex[0])
    assert int(b.query("origin", 0, np.array([big, -big, 1]))[1]) == int(b.n_vertex[0])
    assert int(b.query("edge_of_vertex", 1, np.uint64(2**63 + 3))) == int(b.n_dart[1] + b.n_extra_dart[1])
    assert int(b.to_global("vertex", 1, big)) == b.num_vertices
    for bad in (1.7, True, "a", np.array([0.0, 1.0])):
        with pytest.raises(errors.InvalidIndexError, match="query.*local ids must be integers"):
            b.query("target", 0, bad)
        with pytest.raises(errors.InvalidIndexError, match="mesh indices must be integers"):
            b.query("target", bad, 0)
    with pytest.raises(errors.ArgumentError, match=r"shape \(3,\).*shape \(2,\) do not broadcast"):
        b.query("target", np.array([0, 1, 0]), np.array([0, 1]))
    # to_local too (sweep 13: [1.9] was read as global vertex 1; non-broadcasting shapes raised
    # numpy's own error); a global id past int32 reads as the sentinel
    assert b.to_local("vertex", 1, [b.vertex_offsets[1] + 2]).tolist() == [2]
    assert int(b.to_local("vertex", 1, big)) == int(b.n_vertex[1])
    for bad in ([1.9], True, "a"):
        with pytest.raises(errors.InvalidIndexError, match=r"to_local\('vertex'\).*must be integers"):
            b.to_local("vertex", 0, bad)
    with pytest.raises(errors.ArgumentError, match="do not broadcast"):
        b.to_local("face", np.array([0, 1, 0]), np.array([0, 1]))
    # int32 ids, eager and under jit, are answered as before
    d = b.query("edge_of_vertex", 1, 3)
    assert int(b.query("origin", 1, d)) == 3
    q = jax.jit(lambda s, m, e: s.query("origin", m, e))
    assert int(q(b, jnp.int32(1), d)) == 3
    with pytest.raises(errors.InvalidIndexError, match="must be integers"):
        jax.jit(lambda s, e: s.query("origin", 0, e))(b, jnp.float32(1.0))


def test_mesh_of_negative_and_adjacent_local_out_of_range():
    """mesh_of(-1) answered -1 (not the documented num_meshes); adjacent_local with a vertex out
    of the mesh's range read the sentinel's row of the union structure and answered True."""
    ms = [load_mesh(*octahedron()), icosphere(1)]
    for name in ("halfedge", "cds5n"):
        b = B.pack(ms, name)
        for kind in ("vertex", "face", "dart"):
            assert int(b.mesh_of(kind, -1)) == b.num_meshes
        for mesh, u, v in ((0, 0, 100), (0, 100, 0), (0, -1, 1), (5, 0, 1), (-1, 0, 1), (0, 0, 6)):
            assert not bool(b.adjacent_local(mesh, u, v)), (name, mesh, u, v)
        h = registry.build("halfedge", ms[0])
        e = np.asarray(h.all_darts())
        o, t = np.asarray(h.origin(e)), np.asarray(h.target(e))
        if b.vertex_order is None:  # halfedge: local ids are the input's
            assert bool(np.all(np.asarray(b.adjacent_local(0, o, t))))


def test_pack_and_pack_positions_take_lists_only_and_real_positions():
    """pack(one TriMesh) and pack(None) raised TypeError, pack('file.off') loaded each character
    as a path ('/: is a directory'); an unknown structure was a bare JaxcdsError; pack_positions
    refused jax arrays ('cannot load a mesh from ArrayImpl'), raised ValueError on string arrays
    and TypeError on None."""
    tet = load_mesh(*octahedron())
    for one in (tet, "some/file.off", None, 3, (tet.vertices, tet.faces)):
        with pytest.raises(errors.ArgumentError, match="pack: give a list of meshes"):
            B.pack(one, "halfedge")
    with pytest.raises(errors.ArgumentError, match="unknown structure 'nope'"):
        B.pack([tet], "nope")
    b = B.pack([tet, tet], "halfedge")
    p = B.pack_positions(b, [jnp.asarray(tet.vertices), tet.vertices])
    np.testing.assert_allclose(np.asarray(p), np.concatenate([tet.vertices] * 2), rtol=1e-6)
    with pytest.raises(errors.MeshError, match="mesh 1's positions must be real numbers"):
        B.pack_positions(b, [tet.vertices, np.full((6, 3), "a")])
    with pytest.raises(errors.ArgumentError, match="pack_positions: give a list of meshes"):
        B.pack_positions(b, None)


# ---------------------------------------------------------------------- chunked normal sums
def _batch_face_list(b, ms):
    """The input meshes' faces, one union, renumbered as the batch numbers its vertices
    (``b.vertex_order``): the plain face list a renumbering batch's normals must equal."""
    inv = np.argsort(np.asarray(b.vertex_order))
    voff = np.concatenate([[0], np.cumsum([m.num_vertices for m in ms])[:-1]])
    return jnp.asarray(inv[np.concatenate([m.faces + o for m, o in zip(ms, voff)])])


def test_packed_pemb_chunk_tables_by_sort(monkeypatch):
    """MATCH_BY_SORT (the sort route, the GPU candidate): a packed pemb's rows derived chunk by
    chunk, each chunk's matches by one sort over its windows (the last chunk's windows start
    inside earlier meshes: their positions are left out), give the face list's normals."""
    from jaxcds.structures import pemb_packed
    from jaxcds.structures.succinct import bp as bp_mod

    calls = []
    by_level = bp_mod.matches_by_level
    monkeypatch.setattr(bp_mod, "MATCH_BY_SORT", True)
    monkeypatch.setattr(bp_mod, "matches_by_level", lambda *a: calls.append(1) or by_level(*a))
    monkeypatch.setattr(B, "NORMALS_CHUNK_VERTICES", 60)
    monkeypatch.setattr(pemb_packed, "CHUNKED_ROWS_FROM", 2)
    # sizes no other test packs (a fresh trace reads the switch)
    ms = [random_planar_triangulation(n, seed=s) for s, n in enumerate((23, 37, 14, 93, 9, 44))]
    ms[1:1] = [load_shared("grid.off"), load_shared("2triangles.off")]
    ms.append(_annulus(random_planar_triangulation(31, seed=9)))
    b = B.pack(ms, "pemb")
    assert b.chunk_starts is not None and b.chunk_starts.shape[0] >= 5
    pos = B.pack_positions(b, ms)
    got = np.asarray(vertex_normals(b, pos))
    assert calls  # traced through the sort route
    faces = _batch_face_list(b, ms)
    np.testing.assert_allclose(got, np.asarray(face_list_vertex_normals(pos, faces)), atol=1e-5)


def test_chunk_plan_groups_whole_meshes():
    """Consecutive whole meshes up to the chunk size; a larger mesh alone; starts of every
    column (vertices, then each row block) and the largest chunk per column."""
    starts, caps = B.chunk_plan([5, 3, 10, 2], [[10, 6, 20, 4], [1, 0, 2, 1]], chunk=8)
    np.testing.assert_array_equal(starts, [[0, 0, 0], [8, 16, 1], [18, 36, 3], [20, 40, 4]])
    assert caps == (10, 20, 2)
    assert B.chunk_plan([5, 3], [[10, 6]], chunk=8) is None  # one chunk: the whole-union route


@pytest.mark.parametrize("name", ["halfedge", "cds4n", "lr", "pemb",  # pemb: rows derived per chunk
                                  *[pytest.param(n, marks=pytest.mark.slow)
                                    for n in ("corner-table", "cds6n", "cds5n", "cds5n-o1", "lr-bits")]])
def test_chunked_normals_equal_whole_union_and_per_mesh(name, monkeypatch):
    """With chunks of a few meshes (the plan of a 10,000-mesh batch, at test size): normals
    equal the whole-union route's and each mesh's own structure's (pemb: the input faces' face
    list), their gradient the whole route's (pemb: the face list's); borders (LR,
    half-edge, pemb) and the CDS's hole-closing fans included, chunks of one mesh larger than
    the chunk size too, and (pemb) the rows derived chunk by chunk, the last chunk's windows
    starting before its meshes (static window sizes)."""
    from jaxcds.mesh import validate_and_close
    from jaxcds.structures import pemb_packed

    monkeypatch.setattr(B, "NORMALS_CHUNK_VERTICES", 60)
    monkeypatch.setattr(pemb_packed, "CHUNKED_ROWS_FROM", 2)  # pemb: each chunk's rows apart
    holed = name != "corner-table"  # the corner table takes closed meshes only
    ms = [random_planar_triangulation(n, seed=s) for s, n in enumerate((20, 35, 12, 90, 8, 41))]
    if holed:
        ms[1:1] = [load_shared("grid.off"), load_shared("2triangles.off")]
    if name == "pemb":  # an annulus: a border loop that is not the root face (the holes table)
        ms.append(_annulus(random_planar_triangulation(30, seed=9)))
    b = B.pack(ms, name)
    assert b.chunk_starts is not None and b.chunk_starts.shape[0] >= 5
    if name == "pemb":
        assert b.structure.holes.shape[0] >= 1
        assert callable(B._row_blocks(b.structure, b.chunk_starts.shape[0] - 1))
    whole = replace(b, chunk_starts=None, chunk_caps=())
    pos = B.pack_positions(b, ms)
    got = np.asarray(vertex_normals(b, pos))
    np.testing.assert_allclose(got, np.asarray(vertex_normals(whole, pos)), atol=1e-5)
    w = jnp.asarray(np.random.default_rng(2).normal(size=pos.shape), jnp.float32)
    grad = jax.jit(jax.grad(lambda s, p: jnp.sum(vertex_normals(s, p) * w), argnums=1))
    g = np.asarray(grad(b, pos))
    if name == "pemb":
        # each mesh's own pemb would compile its large normals program once per mesh size (35 s
        # of CI): the input faces, renumbered as the batch numbers vertices, through the plain
        # face list instead (the pemb normals of each mesh equal those: test_protocol)
        faces = _batch_face_list(b, ms)
        np.testing.assert_allclose(got, np.asarray(face_list_vertex_normals(pos, faces)), atol=1e-5)
        g0 = np.asarray(jax.grad(lambda p: jnp.sum(face_list_vertex_normals(p, faces) * w))(pos))
    else:
        parts = [registry.build(name, m) for m in ms]
        want = []
        for p, m in zip(parts, ms):
            v = m.vertices if p.num_vertices == m.num_vertices else validate_and_close(m).vertices
            v = v if p.vertex_order is None else v[np.asarray(p.vertex_order)]
            want.append(np.asarray(vertex_normals(p, jnp.asarray(v, jnp.float32))))
        np.testing.assert_allclose(got, np.concatenate(want), atol=1e-5)
        g0 = np.asarray(grad(whole, pos))
    np.testing.assert_allclose(g, g0, rtol=1e-4, atol=1e-3 * np.abs(g0).max())
    assert np.any(g != 0)


def test_chunked_sums_run_for_cpu_only(monkeypatch):
    """The chunk loop is for a CPU cache: traced for a GPU the whole-union route runs (its trips
    run one after the other there; measured on an H100, RESULTS.md)."""
    monkeypatch.setattr(B, "NORMALS_CHUNK_VERTICES", 40)
    ms = [random_planar_triangulation(n, seed=s) for s, n in enumerate((30, 25, 44))]
    b = B.pack(ms, "corner-table")
    pos = B.pack_positions(b, ms)
    assert B.chunks_pay_off() and b.normal_sums(pos) is not None
    with jax.default_device(jax.devices("cpu")[0]):
        assert B.chunks_pay_off()
    for platform in ("gpu", "cuda", "rocm", "tpu"):
        monkeypatch.setattr(jax, "default_backend", lambda: platform)
        assert not B.chunks_pay_off() and b.normal_sums(pos) is None
        with jax.default_device(jax.devices("cpu")[0]):  # a CPU device named: chunks again
            assert B.chunks_pay_off()
    # normal_sums None: _scatter_sums takes the whole-union route, the one a batch without a
    # chunk plan takes (equal to the chunked normals: test_chunked_normals_equal_whole_union_and_per_mesh)


def test_sharded_packed_batch_with_a_chunk_plan(monkeypatch):
    """A sharded union has other row blocks than the plan's: its normals take the partitioned
    whole route and equal the unsharded (chunked) ones."""
    from jaxcds import sharding as S

    monkeypatch.setattr(B, "NORMALS_CHUNK_VERTICES", 40)
    ms = [random_planar_triangulation(n, seed=s) for s, n in enumerate((30, 25, 44))]
    b = B.pack(ms, "cds5n")
    assert b.chunk_starts is not None
    pos = B.pack_positions(b, ms)
    sb = S.shard_structure(b, S.device_mesh())
    np.testing.assert_allclose(np.asarray(S.sharded_vertex_normals(sb, pos)),
                               np.asarray(vertex_normals(b, pos)), atol=1e-5)


def test_pack_positions_refuses_a_dtype_that_is_not_floating():
    """Ninth sweep: pack_positions(dtype="nonsense") raised numpy's TypeError, dtype=object JAX's;
    an integer dtype truncated the coordinates silently, bool and complex gave no positions. The
    floating dtypes (float16 and bfloat16 too: vertex_normals sums them in float32) and None
    still work."""
    ms = [random_planar_triangulation(12, seed=3), icosphere(0)]
    b = B.pack(ms, "halfedge")
    for bad in ("nonsense", 3, [1, 2]):
        with pytest.raises(errors.ArgumentError, match=r"pack_positions: dtype .* is not a dtype"):
            B.pack_positions(b, ms, dtype=bad)
    for bad in (np.int32, "int64", bool, "complex64", object, "U3"):
        with pytest.raises(errors.ArgumentError,
                           match=rf"pack_positions: dtype {np.dtype(bad)} is not a floating dtype"):
            B.pack_positions(b, ms, dtype=bad)
    want = np.asarray(B.pack_positions(b, ms))
    assert want.dtype == np.float32
    for ok in (None, np.float32, "float64", np.float16, jnp.bfloat16, "bfloat16"):
        p = B.pack_positions(b, ms, dtype=ok)
        assert jnp.issubdtype(p.dtype, jnp.floating) and p.shape == want.shape
        np.testing.assert_allclose(np.asarray(p, np.float32), want, rtol=1e-2, atol=1e-2)
    n = np.asarray(vertex_normals(b, B.pack_positions(b, ms, dtype=jnp.bfloat16)))
    assert n.dtype == np.float32 and np.isfinite(n).all()


# (sweep 14b) pack(..., check=False): the union builders skip validation. A face id outside its
# mesh crashed the numba builders (negative or past the union) or, inside the union, joined
# two meshes silently; border sides that do not chain wrote out of range. Probed in a child.
_PACK_TRUSTED_CHILD = r"""
import numpy as np
from jaxcds import batch as B
from jaxcds.mesh import TriMesh

tet = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], np.int32)
bad = {"negative": ([[0, 1, 2], [0, 2, -1]], 4), "past_union": ([[0, 1, 2], [0, 2, 1 << 30]], 4),
       "into_next_mesh": ([[0, 1, 2], [0, 2, 5]], 4),  # vertex 1 of the next mesh in the union
       "pinched": ([[0, 1, 2], [0, 3, 4]], 5), "flipped": ([[0, 1, 2], [0, 1, 3]], 4)}
for kind in ("halfedge", "corner-table"):
    for name, (f, nv) in bad.items():
        meshes = [TriMesh(np.zeros((4, 3)), tet), TriMesh(np.zeros((nv, 3)), np.array(f, np.int32)),
                  TriMesh(np.zeros((4, 3)), tet)]
        record(kind + ":" + name, lambda ms, k: B.pack(ms, k, check=False), meshes, kind)
"""


def test_pack_unchecked_refuses_ids_out_of_range_and_unchained_borders():
    out = crash_probe(_PACK_TRUSTED_CHILD)
    for kind in ("halfedge", "corner-table"):
        for name, vertex in (("negative", -1), ("past_union", 1 << 30), ("into_next_mesh", 5)):
            cls, msg = out[f"{kind}:{name}"]
            assert cls == "InvalidIndexError", (kind, name, cls, msg)
            assert msg.startswith(f"pack: mesh 1 (arrays): face 1 refers to vertex {vertex}, "
                                  "outside [0, 4)"), msg
        for name, cls in (("pinched", "NonManifoldVertexError"),
                          ("flipped", "InconsistentOrientationError")):
            assert out[f"{kind}:{name}"][0] == cls, out[f"{kind}:{name}"]
            assert out[f"{kind}:{name}"][1].startswith("pack: mesh 1 (arrays): "), out[f"{kind}:{name}"]


@pytest.mark.parametrize("name", ["cds6n", "lr-bits"])
def test_packed_compact_batches_pickle_and_compare(name):
    """A packed CDS or LR batch could not be pickled (its union class is made at run time by
    ``packed_class``: PicklingError "attribute lookup PackedCDS6n on
    jaxcds.structures.cds_packed failed"), and ``==`` on two packs raised JAX's ambiguous truth
    value. Now the class is found by name (made on first use, so a fresh process can unpickle),
    the copy is equal to the original and answers as it does."""
    import copy
    import importlib
    import pickle

    ms = [icosphere(1), random_planar_triangulation(12, seed=1)]
    b = B.pack(ms, name)
    for c in (pickle.loads(pickle.dumps(b)), copy.deepcopy(b)):
        assert type(c.structure) is type(b.structure) and c == b and c == B.pack(ms, name)
        np.testing.assert_array_equal(np.asarray(c.target(c.all_darts())), np.asarray(b.target(b.all_darts())))
    assert "Array" not in repr(b.structure) and len(repr(b.structure)) < 200
    mod = importlib.import_module(type(b.structure).__module__)
    base = type(b.structure)._base  # the per-mesh class (CDS6n, LRBits)
    assert mod.__getattr__(f"Packed{base.__name__}") is type(b.structure)
    with pytest.raises(AttributeError):
        mod.__getattr__("PackedNothing")


@pytest.mark.parametrize("chunked", [True, False])
def test_a_non_finite_dummy_position_carries_no_gradient(chunked, monkeypatch):
    """Sweep 15a: a hole's fan was masked after its cross products, so a NaN or inf position
    at a CDS dummy vertex (zero normal by design) made every gradient on its border NaN
    (0 * NaN in the cross product's derivative), chunked or over the whole union. Now the
    gradients equal those with the dummy at its centroid; the other meshes' never changed."""
    from jaxcds.mesh import validate_and_close

    monkeypatch.setattr(B, "NORMALS_CHUNK_VERTICES", 40)
    ms = [random_planar_triangulation(20, seed=1), load_shared("grid.off"),
          random_planar_triangulation(35, seed=2)]
    b = B.pack(ms, "cds4n")
    assert b.chunk_starts is not None
    if not chunked:
        b = replace(b, chunk_starts=None, chunk_caps=())
    pos = np.asarray(B.pack_positions(b, ms))
    dummy = np.asarray(b.dummy_vertex_mask())
    assert dummy.sum() == 1 and validate_and_close(ms[1]).num_vertices == ms[1].num_vertices + 1
    w = jnp.asarray(np.random.default_rng(0).normal(size=pos.shape), jnp.float32)
    grad = jax.jit(jax.grad(lambda p: jnp.sum(vertex_normals(b, p) * w)))
    clean = np.asarray(grad(jnp.asarray(pos)))
    for bad in (np.nan, np.inf):
        q = pos.copy()
        q[dummy] = bad
        g = np.asarray(grad(jnp.asarray(q)))
        np.testing.assert_array_equal(g[dummy], 0.0)
        np.testing.assert_allclose(g, clean, rtol=1e-5, atol=1e-6)


def test_batch_entry_points_name_arguments_of_the_wrong_kind():
    """PackedBatch.query(['target'], ...) raised TypeError 'unhashable type: list';
    concatenate(one structure) TypeError 'not subscriptable' and concatenate([TriMesh]) a refusal
    of 'TriMesh (?)' as a class without concatenate; pack_positions(None, ...) AttributeError on
    n_vertex; pack(..., check='no') validated (a truthy string). Each is an ArgumentError now."""
    from jaxcds.structures.halfedge import HalfEdge

    m = load_mesh(*octahedron())
    b = B.pack([m, m], "halfedge")
    with pytest.raises(errors.ArgumentError, match=r"PackedBatch.query: unknown operator \['target'\]"):
        b.query(["target"], 0, 0)
    s = HalfEdge.from_mesh(m)
    with pytest.raises(errors.ArgumentError, match="concatenate: give a list of structures .*single HalfEdge"):
        B.concatenate(s)
    with pytest.raises(errors.ArgumentError, match="concatenate: structure 1 is a TriMesh, not a jaxcds structure"):
        B.concatenate([s, m])
    assert B.concatenate(iter([s, s])).num_meshes == 2  # any iterable of structures
    with pytest.raises(errors.ArgumentError, match="pack_positions: batch must be a PackedBatch .*got NoneType"):
        B.pack_positions(None, [m])
    with pytest.raises(errors.ArgumentError, match="pack: check must be True or False, got 'no'"):
        B.pack([m], "halfedge", check="no")


def test_id_shifting_needs_one_count_per_part_and_concatenate_a_list():
    """Sweep 49b's leftovers: mismatched counts raised numpy's broadcast ValueError, and
    ``concatenate(None)`` was an ``EmptyMeshError`` (no structures) rather than a wrong argument."""
    with pytest.raises(errors.ArgumentError, match="shift_ids: 2 arrays but 3 counts"):
        B.shift_ids([np.arange(3), np.arange(2)], [3, 2, 4])
    with pytest.raises(errors.ArgumentError, match="shift_darts: 1 arrays but 2 counts"):
        B.shift_darts([np.arange(3)], [3, 1], [0, 0])
    np.testing.assert_array_equal(B.shift_ids([np.arange(3), np.arange(2)], [3, 2]), [0, 1, 2, 3, 4])
    with pytest.raises(errors.ArgumentError, match="got None"):
        B.concatenate(None)
    with pytest.raises(errors.EmptyMeshError):
        B.concatenate([])


def test_packed_lr_normals_under_rank_promotion_raise():
    """A packed LR batch gathers each mesh's T0 rows at ``(rows, 1)`` starts plus a ``(3,)``
    column offset, which met by rank promotion: users running with
    ``jax.numpy_rank_promotion("raise")`` got JAX's ValueError from vertex_normals (sweep 52c).
    The normals are the half-edge batch's."""
    ms = [icosphere(1), load_shared("grid.off"), random_planar_triangulation(30, seed=1)]
    b = B.pack(ms, "lr")
    pos = B.pack_positions(b, ms)
    with jax.numpy_rank_promotion("raise"):
        got = vertex_normals(b, pos)
    h = B.pack(ms, "halfedge")
    want = np.asarray(vertex_normals(h, B.pack_positions(h, ms)))
    order = np.asarray(b.vertex_order) if b.vertex_order is not None else np.arange(len(want))
    np.testing.assert_allclose(np.asarray(got), want[order], rtol=1e-5, atol=1e-6)


def test_packed_cds_under_strict_dtype_promotion():
    """A packed CDS batch compacts union face slots by adding bools to ints: users running with
    ``jax.numpy_dtype_promotion("strict")`` got JAX's TypePromotionError from its face
    operators (sweep 52c). The batch's faces of every dart are the default setting's."""
    ms = [icosphere(1), random_planar_triangulation(30, seed=1)]
    b = B.pack(ms, "cds5n")
    e = jnp.arange(b.num_darts, dtype=jnp.int32)
    faces = jax.jit(lambda b, e: (b.face_left(e), b.face_right(e), b.edge_of_face(
        jnp.arange(b.num_faces, dtype=jnp.int32))))
    with jax.numpy_dtype_promotion("strict"):
        got = faces(b, e)
    for g, w in zip(got, faces(b, e)):
        np.testing.assert_array_equal(np.asarray(g), np.asarray(w))


@pytest.mark.parametrize("parts,error,msg", [
    (5, errors.ArgumentError, "concatenate: give a list of structures, got int"),
    (None, errors.ArgumentError, "concatenate: give a list of structures, got None"),
    ([], errors.EmptyMeshError, "concatenate: no structures given"),
])
def test_concatenate_names_what_is_not_a_list_of_structures(parts, error, msg):
    with pytest.raises(error, match=msg):
        B.concatenate(parts)


@pytest.mark.parametrize("method,args", [
    ("mesh_of", (np.array([0, 1]), "dart")),
    ("to_global", (np.array([0, 1]), 0, 3)),
    ("to_local", (np.array([0, 1]), 0, 3)),
    ("to_local", ("edge", 0, 3)),
])
def test_id_maps_name_an_id_kind_that_is_not_one(method, args):
    """Ids where the kind goes: ``to_local`` / ``to_global`` raised numpy's untyped 'truth value of
    an array is ambiguous' ValueError (``mesh_of`` an InvalidIndexError about its ids)."""
    b = B.pack([load_mesh(*octahedron())] * 2, "halfedge")
    with pytest.raises(errors.ArgumentError, match=rf"{method}: unknown id kind .*: 'vertex', 'face' or 'dart' "
                                                   r"\(the kind comes first\)"):
        getattr(b, method)(*args)


@pytest.mark.parametrize("name,change,msg", [
    ("cds6n", lambda s: replace(s, num_faces=19),
     r"CDS6n.concatenate: part 1 has F = 19 faces for n = 12 vertices, not 2n - 4 = 20"),
    ("cds6n", lambda s: replace(s, unused_slots=tuple(sorted(s.unused_slots))[:3]),
     r"CDS6n.concatenate: every part must have 4 unused face slots; part 1 has 3"),
    ("lr", lambda s: replace(s, L=s.L[:-1]), r"LR.concatenate: part 1's L has \d+ entries, not 1 m_r = \d+"),
])
def test_concatenate_names_the_hand_made_part_that_does_not_fit(name, change, msg):
    """Parts assembled by hand: the refusals did not say which part; three unused slots raised
    numpy's untyped 'inhomogeneous shape' ValueError before the refusal meant for them."""
    from jaxcds.generators import icosphere
    from jaxcds.structures import registry

    s = registry.build(name, icosphere(0))
    with pytest.raises(errors.StructureError, match=msg):
        B.concatenate([s, change(s)])


@pytest.mark.parametrize("method", ["per_mesh_sum", "per_mesh_mean", "split"])
def test_per_mesh_reductions_name_a_kind_that_is_no_string(method):
    """An array as ``kind`` raised numpy's untyped 'truth value of an array is ambiguous'
    ValueError from ``kind == "vertex"``."""
    b = B.pack([load_mesh(*octahedron())] * 2, "halfedge")
    with pytest.raises(errors.ArgumentError, match=r"unknown id kind a ndarray: 'vertex' or 'face' here"):
        getattr(b, method)(jnp.ones(b.num_vertices), kind=np.array(["vertex", "face"]))


@pytest.mark.parametrize("cls", [HalfEdge, CornerTable])
def test_class_concatenate_of_no_parts_or_mixed_parts_is_named(cls):
    """``HalfEdge.concatenate([])`` / ``CornerTable.concatenate([])`` raised numpy's untyped
    broadcast ValueError; a part of the other class had its fields read as if it were one."""
    m = load_mesh(*octahedron())
    other = CornerTable if cls is HalfEdge else HalfEdge
    with pytest.raises(errors.EmptyMeshError, match="concatenate: no structures given"):
        cls.concatenate([])
    with pytest.raises(errors.UnsupportedTopologyError, match=rf"{cls.__name__}.concatenate: part 1 is a "
                                                              rf"{other.__name__}"):
        cls.concatenate([cls.from_mesh(m), other.from_mesh(m)])
    assert cls.concatenate([cls.from_mesh(m)] * 2).num_vertices == 2 * m.num_vertices
