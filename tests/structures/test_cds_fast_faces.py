"""The CDS family's whole-mesh routes (Castelli Aleardi & Devillers, Sec. 2, Thm 2/6/7) against
independent oracles: every Target at once (``all_edge_targets``) == Thm 2's walk edge by edge
(``_target_walk``, a masked while_loop of LeftFront steps), ``face_vertices`` == the protocol's
generic route (``edge_of_face`` + ``next`` + ``origin``, row by row, same rotation), the padded
slots of ``face_vertices_padded`` == the same faces once each, the normals and their gradients ==
the plain face-list normals on those faces. Single structures on real meshes (holed ones after
``close_boundaries``) and random triangulations, and a packed batch of three meshes.

Cost: small meshes only, one jitted program per (structure, mesh).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxcds.algorithms import vertex_normals
from jaxcds.algorithms.normals import face_list_vertex_normals
from jaxcds.batch import pack, pack_positions
from jaxcds.generators import random_planar_triangulation
from jaxcds.mesh import close_boundaries
from jaxcds.structures import registry
from jaxcds.structures.base import MeshStructure
from jaxcds.structures.cds import _CDS

from conftest import CDS_FAMILY as CDS, load_shared, slow_params


def _mesh(name):
    if name.startswith("random:"):
        n, seed = name[7:].split("/")
        return random_planar_triangulation(int(n), seed=int(seed))
    return close_boundaries(load_shared(name))


@jax.jit
def _fast(s):
    fv, valid = s.face_vertices_padded()
    return s.all_edge_targets(), s.face_vertices(), fv, valid


@jax.jit
def _oracle(s):
    e = jnp.arange(3 * s.num_vertices, dtype=jnp.int32)
    ok = s.edge_valid(e)
    # Thm 2's walk (the per-query route), not the pointer jumping / Thm 6 of all_edge_targets
    walk = _CDS._target_walk(s, jnp.where(ok, e, 0)) if not getattr(s, "packed", False) \
        else s._target_walk(jnp.where(ok, e, 0))
    return ok, walk, MeshStructure.face_vertices(s)


def _dummy_mask(m, order=None):
    """``m``'s dummy vertices (holes closed, Sec. 4.5) in structure order; all False if none."""
    d = np.zeros(m.num_vertices, bool) if m.dummy_vertices is None else np.asarray(m.dummy_vertices)
    return d if order is None else d[np.asarray(order)]


def _check(s, positions, dummy):
    t, fv, pad, valid = _fast(s)
    ok, walk, fv_ref = _oracle(s)
    ok = np.asarray(ok)
    np.testing.assert_array_equal(np.asarray(t)[ok], np.asarray(walk)[ok])
    np.testing.assert_array_equal(np.asarray(fv), np.asarray(fv_ref))
    pad, valid = np.asarray(pad), np.asarray(valid)
    assert pad.shape == (2 * s.num_vertices, 3) and valid.shape == (2 * s.num_vertices,)
    assert int(valid.sum()) == s.num_faces
    assert pad.min() >= 0 and pad.max() < s.num_vertices
    key = lambda a: a[np.lexsort(a.T[::-1])]  # noqa: E731
    np.testing.assert_array_equal(key(pad[valid]), key(np.asarray(fv_ref)))
    # normals and gradients == the face list on the same faces
    p = jnp.asarray(positions, jnp.float32)
    # the surface's own faces: the fans closing holes are left out of the normals
    own = ~np.asarray(dummy)[np.asarray(fv_ref)].any(axis=1)
    assert own.all() or s.dummy_vertex_mask() is not None
    faces = jnp.asarray(np.asarray(fv_ref)[own])
    np.testing.assert_allclose(np.asarray(vertex_normals(s, p)),
                               np.asarray(face_list_vertex_normals(p, faces)), atol=2e-5)
    w = jnp.linspace(-1.0, 1.0, 3 * s.num_vertices).reshape(-1, 3)
    g = jax.grad(lambda q: jnp.sum(vertex_normals(s, q) * w))(p)
    g_ref = jax.grad(lambda q: jnp.sum(face_list_vertex_normals(q, faces) * w))(p)
    np.testing.assert_allclose(np.asarray(g), np.asarray(g_ref), atol=2e-4, rtol=1e-3)


# quick: one mesh per class (CI time); the border case (grid.off: dummy vertex) is in the slow set
# here, and in the quick set of the packed test below, tests/structures/test_protocol.py and
# tests/algorithms/test_generic.py
_SINGLE_MESHES = ["cube.off", "grid.off", "random:2000/7", "decimated-knight.off", "2triangles.off", "random:500/1"]


@pytest.mark.parametrize("mesh", slow_params(_SINGLE_MESHES, set(_SINGLE_MESHES) - {"random:2000/7"}))
@pytest.mark.parametrize("name", CDS)
def test_whole_mesh_routes_single(name, mesh):
    m = _mesh(mesh)
    s = registry.build(name, m)
    pos = np.asarray(m.vertices, np.float64)
    if s.vertex_order is not None:
        pos = pos[np.asarray(s.vertex_order)]
    _check(s, pos, _dummy_mask(m, s.vertex_order))


# cds5n / cds4n: the packed views are the same code as for cds6n and cds5n-o1, and their own
# rows are checked single above: slow (14-16 s each, CI time)
@pytest.mark.parametrize("name", slow_params(CDS, {"cds5n", "cds4n"}))
def test_whole_mesh_routes_packed(name):
    meshes = [_mesh("decimated-knight.off"), _mesh("random:300/2"), _mesh("grid.off")]
    b = pack(meshes, name)
    s = b.structure
    pos = np.asarray(pack_positions(b, meshes))
    # the union's vertex_order maps its labels to union input ids (meshes one after another)
    dummy = np.concatenate([_dummy_mask(m) for m in meshes])
    if s.vertex_order is not None:
        dummy = dummy[np.asarray(s.vertex_order)]
    assert dummy.any()  # grid.off has holes
    _check(s, pos, dummy)
    # the batch forwards the padded faces and the dummy mask: the batch normals == the face
    # list's on the surfaces' own faces
    fv = np.asarray(s.face_vertices())
    own = jnp.asarray(fv[~dummy[fv].any(axis=1)])
    np.testing.assert_allclose(np.asarray(vertex_normals(b, jnp.asarray(pos, jnp.float32))),
                               np.asarray(face_list_vertex_normals(jnp.asarray(pos, jnp.float32), own)),
                               atol=2e-5)


def test_slot_blocks_and_every_block_count_is_a_permutation(monkeypatch):
    """The large-mesh block counts (8, 4: :func:`cds.slot_blocks`) are not reached by the small
    meshes of the other tests: force them and compare the normals with the face list."""
    from jaxcds.structures import cds as cds_module
    from jaxcds.structures.base import interleave_rows

    assert [cds_module.slot_blocks(n) for n in (4, 299_999, 300_000, 1_999_999, 2_000_000)] == [16, 16, 8, 8, 4]
    for b in (4, 8, 16):
        for m in (3, 37, 64):
            x = np.asarray(interleave_rows(jnp.arange(m), b))
            assert sorted(x.tolist()) == list(range(m))
    mesh = random_planar_triangulation(300, seed=5)
    p = np.asarray(mesh.vertices, np.float32)
    want = np.asarray(face_list_vertex_normals(jnp.asarray(p), jnp.asarray(mesh.faces)))
    for blocks in (8, 4):
        monkeypatch.setattr(cds_module, "slot_blocks", lambda n, b=blocks: b)
        for name in ("cds6n", "cds5n-o1"):
            s = registry.build(name, mesh)
            order = s.vertex_order
            q = p if order is None else p[np.asarray(order)]
            fv, ok = s.face_vertices_padded()
            assert int(np.asarray(ok).sum()) == s.num_faces
            got = np.asarray(vertex_normals.__wrapped__(s, jnp.asarray(q)))
            ref = want if order is None else want[np.asarray(order)]
            np.testing.assert_allclose(got, ref, atol=1e-5)


def _rounds_needed(s) -> int:
    """Pointer-jumping rounds that resolve every Target of ``s``, counted by running them in numpy
    from the library's start values (independent of the builder's fan count)."""
    v, rounds = np.asarray(s._target_start()), 0
    while (v < 0).any():
        assert rounds <= 32, "a LeftFront chain does not end"
        pend = v < 0
        v = np.where(pend, v[np.where(pend, -v - 1, 0)], v)
        rounds += 1
    return rounds


@pytest.mark.parametrize("mesh", ["cube.off", "grid.off", "random:2000/7", "random:3000/3"])
@pytest.mark.parametrize("name", ["cds6n", "cds5n", "cds4n"])
def test_target_rounds_is_exact_and_a_wrong_count_is_still_right(name, mesh):
    """The builders' static round count (``target_rounds``, from the longest fan) is the number of
    rounds the chains need; the targets are the same with it, without it (``-1``: data-driven
    loop) and with too few rounds (the safety-net loop finishes them)."""
    import dataclasses

    s = registry.build(name, _mesh(mesh))
    assert s.target_rounds == _rounds_needed(s) >= 1
    want = np.asarray(s.all_edge_targets())
    for r in (-1, 0, 1, s.target_rounds + 1):
        got = np.asarray(dataclasses.replace(s, target_rounds=r).all_edge_targets())
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("parts", [1, 2, 3, 4, 64])
@pytest.mark.parametrize("length", [40_001, 40_002, 32_767])
def test_pointer_jump_padded_for_the_thread_split(monkeypatch, parts, length):
    """``pointer_jump`` pads a long array up to a multiple of the thread count (XLA:CPU emits a
    scalar loop for a round split into unequal parts): the answers equal a numpy pointer jumping,
    whatever the count (monkeypatched), for lengths under, at and past the padding threshold,
    with the static round count, too few rounds and none (-1, the data-driven loop)."""
    from jaxcds.structures import base as base_module
    from jaxcds.structures import cds as cds_module

    monkeypatch.setattr(base_module, "split_multiple", lambda: parts)
    rng = np.random.default_rng(length + parts)
    # chains of length up to 40: entry i points further along a random permutation
    order = rng.permutation(length)
    val = np.empty(length, np.int32)
    starts = np.sort(rng.choice(np.arange(1, length), length // 20, replace=False))
    for chain in np.split(order, starts):
        val[chain[-1]] = rng.integers(0, 1000)  # the resolved end of the chain
        val[chain[:-1]] = -(chain[1:] + 1)
    want = val.copy()
    while (want < 0).any():
        want = np.where(want < 0, want[np.where(want < 0, -want - 1, 0)], want)
    rounds = int(max(len(c) for c in np.split(order, starts)) - 1).bit_length()
    for r in (rounds, 1, -1):
        got = np.asarray(jax.jit(lambda v, r=r: cds_module.pointer_jump(v, r))(jnp.asarray(val)))
        assert got.shape == (length,)
        np.testing.assert_array_equal(got, want)


def test_packed_target_rounds_is_the_largest_part():
    meshes = [_mesh("random:300/2"), _mesh("cube.off"), _mesh("random:2000/7")]
    parts = [registry.build("cds6n", m) for m in meshes]
    s = pack(meshes, "cds6n").structure
    assert s.target_rounds == max(p.target_rounds for p in parts)
    assert s.target_rounds == _rounds_needed(s._whole_view())


def test_with_target_rounds_measures_the_tables_and_names_a_chain_that_does_not_end(monkeypatch):
    """``with_target_rounds`` (the decoders' count) equals the builders' fan count and the numpy
    count; chains that cycle or leave the id range raise StructureError naming the edge id."""
    import dataclasses

    from jaxcds import errors
    from jaxcds.structures import cds as cds_module

    for name in CDS:
        s = registry.build(name, _mesh("random:2000/7"))
        got = cds_module.with_target_rounds(dataclasses.replace(s, target_rounds=-1))
        assert got.target_rounds == s.target_rounds == _rounds_needed(s) >= 1, name
    meshes = [_mesh("random:300/2"), _mesh("cube.off"), _mesh("random:2000/7")]
    for name in ("cds6n", "cds4n"):  # a packed union: measured on its whole-mesh view
        s = pack(meshes, name).structure
        got = cds_module.with_target_rounds(dataclasses.replace(s, target_rounds=-1))
        assert got.target_rounds == s.target_rounds == _rounds_needed(s._whole_view()), name
    chain = np.array([-2, -3, 7, -1], dtype=np.int32)  # 0 -> 1 -> 2 (resolved), 3 -> 0
    assert tuple(cds_module._longest_chain(chain)) == (3, -1)
    assert tuple(cds_module._longest_chain(np.array([4, 5], np.int32))) == (0, -1)
    for bad, at in (([-2, -1, 7], 0), ([-2, -9, 7], 1)):  # a cycle 0 <-> 1; an id out of range
        steps, where = cds_module._longest_chain(np.array(bad, np.int32))
        assert steps == -1 and where == at
    monkeypatch.setattr(cds_module, "_jit_target_start", lambda s: jnp.asarray([5, -3, -2], jnp.int32))
    with pytest.raises(errors.StructureError, match="edge id 1"):
        cds_module.with_target_rounds(s)


@pytest.mark.parametrize("name", CDS)
def test_slot_faces_without_lf_words(name, monkeypatch):
    """The slot rows read the LeftFronts as one word each from 8,192 to 2^28 vertices
    (``_lf_word``); outside, each consumer reads the parts off the rows. Both routes forced on a
    small mesh: the same faces and normals."""
    from jaxcds.structures import cds as cds_module

    mesh = _mesh("random:500/4")
    s = registry.build(name, mesh)
    assert s.num_vertices < cds_module._WORD_MIN_VERTICES  # the library's route here: parts
    monkeypatch.setattr(cds_module, "_WORD_MIN_VERTICES", 0)  # words
    want = np.asarray(s.face_vertices())
    assert tuple(int(x) for x in cds_module._lf_unword(cds_module._lf_word((7, 2, 1)))) == (7, 2, 1)
    monkeypatch.setattr(cds_module, "_WORD_VERTICES", 0)
    np.testing.assert_array_equal(np.asarray(s.face_vertices()), want)
    order = s.vertex_order
    p = np.asarray(mesh.vertices, np.float32)
    q = p if order is None else p[np.asarray(order)]
    got = np.asarray(vertex_normals.__wrapped__(s, jnp.asarray(q)))
    ref = np.asarray(face_list_vertex_normals(jnp.asarray(q), jnp.asarray(want)))
    np.testing.assert_allclose(got, ref, atol=1e-5)


@pytest.mark.parametrize("name", CDS)
def test_target_start_with_static_roots_equals_the_masked_one(name):
    """The pointer-jumping start of a single structure (roots static: one lean pass, the six root
    and absent ids patched after) equals the per-vertex masked start of the packed views, entry
    by entry, in both layouts (edge id ``3u + c``; by colour, ``c n + u``: the same values
    renumbered); padded, it is followed by resolved zeros only."""
    from jaxcds.structures import base as base_module

    for mesh in (_mesh("cube.off"), _mesh("random:2000/7"), _mesh("bunny.off")):
        s = registry.build(name, mesh)
        lean = np.asarray(jax.jit(lambda s: s._target_start())(s))
        masked = np.asarray(jax.jit(lambda s: s._target_start_masked(s._lf_parts_cols()))(s))
        assert lean.shape == (3 * s.num_vertices,)
        np.testing.assert_array_equal(lean, masked)
        padded = np.asarray(jax.jit(lambda s: s._target_start(padded=True))(s))
        assert padded.shape[0] == lean.shape[0] + base_module.split_padding(lean.shape[0])
        np.testing.assert_array_equal(padded[:lean.shape[0]], lean)
        assert (padded[lean.shape[0]:] == 0).all()
        # by colour (entry c n + u, pointers likewise): the same start, renumbered
        n = s.num_vertices
        by_colour = np.asarray(jax.jit(lambda s: s._target_start(by_colour=True))(s))
        np.testing.assert_array_equal(
            by_colour, np.asarray(jax.jit(lambda s: s._target_start_masked(s._lf_parts_cols(), True))(s)))
        edge = np.where(by_colour < 0, -(3 * ((-by_colour - 1) % n) + (-by_colour - 1) // n) - 1, by_colour)
        np.testing.assert_array_equal(edge.reshape(3, n).T.reshape(-1), lean)


@pytest.mark.parametrize("name", CDS)
def test_small_mesh_normals_split_no_more_kernels_over_threads_than_the_face_list(name):
    """XLA:CPU splits a kernel over its threads once its flops pass the bytes it moves (a cost
    model of the entry computation, ``ParallelTaskAssigner``), and on 2 cores a split kernel of a
    few thousand elements waits for the second thread (bunny: 30 us against 3). The CDS
    whole-mesh routes are written so that on the bunny no kernel of theirs is split; the face
    list's program has none either. A jax upgrade that changes the cost model fails here: the
    small-mesh normals must then be measured again (``benchmarks/race_face_derivation.py``).
    Counted in the compiled HLO (``outer_dimension_partitions``); nothing is timed."""
    from jaxcds.algorithms import normals as normals_module

    mesh = load_shared("bunny.off")
    pos = jnp.asarray(np.asarray(mesh.vertices, np.float32))
    faces = jnp.asarray(np.asarray(mesh.faces, np.int32))
    s = registry.build(name, mesh)

    def splits(f, *args):
        return jax.jit(f).lower(*args).compile().as_text().count("outer_dimension_partitions")

    face_list = splits(face_list_vertex_normals, pos, faces)
    assert splits(lambda s, p: normals_module._vertex_normals.__wrapped__(s, p), s, pos) <= face_list


@pytest.mark.parametrize("structure", ["cds6n", "cds5n-o1"])
def test_cds_under_strict_dtype_promotion(structure):
    """Users of a JAX library may run with ``jax.numpy_dtype_promotion("strict")``: a CDS keeps
    a LeftFront's entering flag as a bool or an int32 (``_parts``) and compared or selected it
    against ints, and its face slots added bools to ints, so face_vertices, the operators,
    degrees and normals raised JAX's TypePromotionError there (sweep 52c). On a holed mesh (a
    dummy vertex), every operator agrees with the half-edge and the normals and degrees with
    the default setting's."""
    from jaxcds.algorithms import vertex_degrees, vertex_normals
    from jaxcds.mesh import close_boundaries
    from jaxcds.structures import registry
    from jaxcds.verify import verify

    m = load_shared("2triangles.off")
    s = registry.build(structure, m)
    pos = jnp.asarray(close_boundaries(m).vertices, jnp.float32)
    pos = pos if s.vertex_order is None else pos[s.vertex_order]
    with jax.numpy_dtype_promotion("strict"):
        rep = verify(s, m)
        got = vertex_normals(s, pos), vertex_normals(s, pos, "gather"), vertex_degrees(s)
    assert rep.mismatches == 0 and rep.checked > 0, str(rep)
    want = vertex_normals(s, pos), vertex_normals(s, pos, "gather"), vertex_degrees(s)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(np.asarray(g), np.asarray(w))


def test_slot_faces_as_lf_words_under_strict_dtype_promotion(monkeypatch):
    """The LeftFront word (from 8,192 vertices) or-ed a bool entering flag into an int32, so
    users running with ``jax.numpy_dtype_promotion("strict")`` got JAX's TypePromotionError
    from face_vertices and the normals of larger meshes (sweep 52c). The word route forced on
    a small mesh: the default setting's faces."""
    from jaxcds.structures import cds as cds_module

    s = registry.build("cds5n", _mesh("random:500/4"))
    monkeypatch.setattr(cds_module, "_WORD_MIN_VERTICES", 0)
    with jax.numpy_dtype_promotion("strict"):
        got = np.asarray(s.face_vertices())
    np.testing.assert_array_equal(got, np.asarray(s.face_vertices()))
