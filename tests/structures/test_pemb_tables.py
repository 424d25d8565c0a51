"""pemb's per-run navigation tables (issue 7): ``BalancedParens.match_all``, ``BitVector``
word ranks and ``PEMB.with_tables`` against independent oracles.

``match_all`` (a search from every ``(`` only, then a scatter) against a stack matching, on
sequences with near and far matches and chunks small enough to loop; ``rank1`` with word ranks
against a prefix sum; the tabulated structure's operators (twin, origin, next, prev, cw, ccw,
is_border, face, edge_of_face, target) against the searching structure's on all darts, for a
mesh with a border (root border loop: the ``is_border`` excess shortcut), one with a hole (a
border loop that is not the root face: ``face`` renumbering) and a closed one: quick, against the
HalfEdge arrays of the same faces mapped through the walk's positions; slow, against the
searching structure's operators (their programs take ~40 s to compile). Reusing the tables
(``tables=``) gives the same structure.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxcds.structures.pemb import PEMB, PEMBTables
from jaxcds.structures.succinct import BalancedParens, BitVector
from jaxcds.structures.succinct import bitvector as bvmod

from parens_helpers import random_balanced
from pemb_helpers import delaunay_faces, stack_match


@functools.partial(jax.jit, static_argnames=("chunk",))
def _match_all(bp, chunk):
    return bp.match_all(chunk=chunk)


# two-stage + compaction (pairs above SELECT_ALL_BELOW, chunk 64: many loop trips; p_open 0.95:
# deep nesting, most matches far) and the small-batch route (100 pairs: the slow route alone)
@pytest.mark.parametrize("pairs,p_open,seed,chunk", [
    (bvmod.SELECT_ALL_BELOW // 2 + 700, 0.5, 0, 64),
    (bvmod.SELECT_ALL_BELOW // 2 + 700, 0.95, 1, 64),
    (bvmod.SELECT_ALL_BELOW // 2 + 700, 0.3, 2, None),
    (100, 0.6, 3, None),
])
def test_match_all_against_stack(pairs, p_open, seed, chunk):
    b = random_balanced(seed, pairs, p_open)
    got = np.asarray(_match_all(BalancedParens.from_bits(b), chunk))
    np.testing.assert_array_equal(got, stack_match(b))


def test_word_rank_against_prefix_sum():
    bits = (np.random.default_rng(4).random(5000) < 0.3).astype(np.uint8)
    bv = BitVector.from_bits(bits)
    i = jnp.arange(bits.size + 1, dtype=jnp.int32)
    want = np.concatenate([[0], np.cumsum(bits)])
    got = jax.jit(lambda bv, i: bv.with_word_rank().rank1(i))(bv, i)
    np.testing.assert_array_equal(np.asarray(got), want)
    np.testing.assert_array_equal(np.asarray(jax.jit(lambda bv, i: bv.rank1(i))(bv, i)), want)


def _cube():
    faces = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                      [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]], np.int32)
    return faces, 8


def _ops(t, e, f):
    return (t.twin(e), t.origin(e), t.next(e), t.prev(e), t.cw_vertex_edge(e), t.ccw_vertex_edge(e),
            t.is_border(e), t.face(e), t.edge_of_face(f), t.target(e))


@jax.jit
def _both(s, e, f):
    return _ops(s, e, f), _ops(s.with_tables(), e, f)


def _mesh(name):
    return {"border": lambda: delaunay_faces(300, 5),
            "hole": lambda: delaunay_faces(300, 6, hole=True),
            "closed": _cube}[name]()


@jax.jit
def _tab_ops(s, e, f):
    t = s.with_tables()
    return (t.twin(e), t.origin(e), t.next(e), t.prev(e), t.is_border(e), t.face(e),
            t.face(t.edge_of_face(f)))


@pytest.mark.parametrize("mesh", ["hole", pytest.param("border", marks=pytest.mark.slow),
                                  pytest.param("closed", marks=pytest.mark.slow)])
def test_tables_against_halfedge(mesh):
    """The tabulated operators against the HalfEdge arrays of the same faces, mapped through
    the walk's dart -> position map (recomputed here from the encoder). Quick on the holed mesh
    (~12 s on a loaded box: the table programs' searches compile once per shape); the root-border
    mesh (Polylla's case, also covered by its pemb-vs-HalfEdge tests) and the closed cube are
    slow."""
    from jaxcds.structures.halfedge import halfedge_arrays
    from jaxcds.structures.pemb import _bfs_tree, encode_rotation_system, rotation_system_from_faces

    faces, nv = _mesh(mesh)
    s = PEMB.from_faces(faces, nv)
    opp, ccw, vert, border = rotation_system_from_faces(faces, nv)
    start = int(ccw[int(np.argmax(border))]) if border.any() else 0
    enc = encode_rotation_system(opp, ccw, vert, nv, start, _bfs_tree(opp, ccw, vert, start, nv))
    pos, order = enc["position"], enc["order"]
    nxt = halfedge_arrays(faces, nv)[0]
    inner = np.arange(opp.size) < 3 * faces.shape[0]
    e = jnp.arange(s.num_darts, dtype=jnp.int32)
    f = jnp.arange(s.num_faces, dtype=jnp.int32)
    tw, org, nx, pv, isb, face, back = (np.asarray(x) for x in _tab_ops(s, e, f))
    np.testing.assert_array_equal(tw[pos], pos[opp])
    np.testing.assert_array_equal(order[org[pos]], vert)
    np.testing.assert_array_equal(nx[pos[inner]], pos[nxt[inner]])
    np.testing.assert_array_equal(pv[pos[nxt[inner]]], pos[inner])
    np.testing.assert_array_equal(isb[pos], ~inner)
    tri = face[pos[inner]].reshape(-1, 3)  # the three darts of a triangle share its face id
    assert (tri == tri[:, :1]).all() and np.unique(tri[:, 0]).size == faces.shape[0]
    assert (face[pos[~inner]] == s.num_faces).all() and tri.max() < s.num_faces
    np.testing.assert_array_equal(back, np.arange(s.num_faces))  # face(edge_of_face(f)) == f
    # a later phase rebuilds the same tabulated structure from the returned tables
    t = jax.jit(lambda s: s.with_tables().tables)(s)
    assert set(t) == {"ra", "rp", "tw", "vb", "fe"}
    u = s.with_tables(tables=t)
    assert isinstance(u, PEMBTables) and u.with_tables() is u
    np.testing.assert_array_equal(np.asarray(u.tw), tw)
    assert u.bits == s.bits  # the tables are not part of the compact structure's count


@pytest.mark.slow
@pytest.mark.parametrize("mesh", ["border", "hole", "closed"])
def test_tables_against_searches(mesh):
    """Slow (~45 s each: the searching operators' programs): every tabulated operator equals
    the searching structure's on all darts."""
    faces, nv = _mesh(mesh)
    s = PEMB.from_faces(faces, nv)
    if mesh == "hole":
        assert int(s.holes.shape[0]) == 2 and not s.root_border
    e = jnp.arange(s.num_darts, dtype=jnp.int32)
    f = jnp.arange(s.num_faces, dtype=jnp.int32)
    plain, tab = _both(s, e, f)
    names = ("twin", "origin", "next", "prev", "cw", "ccw", "is_border", "face", "edge_of_face",
             "target")
    for name, a, b in zip(names, plain, tab):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b), err_msg=name)


def test_eager_tables_are_one_program():
    """``with_tables()`` called eagerly (as ``face_vertices()`` does) runs as one jitted program
    per mesh shape: primitive by primitive it compiled hundreds of small programs for every new
    shape (4-8 s) and took 1.2 s per call after that. Same tables as traced inside a jit."""
    from jaxcds.generators import random_planar_triangulation
    from jaxcds.structures import registry

    from test_arrays import counting_compilations

    p = registry.build("pemb", random_planar_triangulation(37, seed=5))  # a size no other test uses
    with counting_compilations() as seen:
        t = p.with_tables()
        jax.block_until_ready(t.tw)
    assert len(seen) <= 2, f"{len(seen)} compilations"
    assert isinstance(t, PEMBTables)
    traced = jax.jit(lambda s: s.with_tables())(p)
    for name in ("tw", "vb", "fe"):
        np.testing.assert_array_equal(getattr(t, name), getattr(traced, name), err_msg=name)
    assert t.with_tables() is t  # holds them already: nothing computed
