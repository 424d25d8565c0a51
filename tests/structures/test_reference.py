"""HalfEdge and CornerTable against a brute-force oracle written with Python dicts."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxcds import errors
from jaxcds.mesh import close_boundaries, load_mesh, split_nonmanifold_vertices
from jaxcds.structures import CornerTable, HalfEdge

from conftest import CLOSED_GENUS0, HIGHER_GENUS, HOLED_GENUS0, load_shared, mesh_params, octahedron


def oracle(faces):
    """Every dart as (u, v) -> dict of expected (u, v) results, the obvious way."""
    inner = {}
    for f in faces.tolist():
        for k in range(3):
            a, b, c = f[k], f[(k + 1) % 3], f[(k + 2) % 3]
            inner[(a, b)] = {"next": (b, c), "prev": (c, a), "face": tuple(sorted(f))}
    border = {(b, a) for (a, b) in inner if (b, a) not in inner}
    leaving = {u: (u, v) for (u, v) in border}
    entering = {v: (u, v) for (u, v) in border}
    out = dict(inner)
    for (u, v) in border:
        out[(u, v)] = {"next": leaving[v], "prev": entering[u], "face": None}
    for (u, v), r in out.items():
        r["twin"] = (v, u)
    return out


def dart_pairs(s, e):
    return list(zip(np.asarray(s.origin(e)).tolist(), np.asarray(s.target(e)).tolist()))


def check_against_oracle(s, faces):
    want = oracle(faces)
    darts = jnp.asarray(s.all_darts())
    got = dart_pairs(s, darts)
    assert sorted(got) == sorted(want)
    for op in ("next", "prev", "twin"):
        res = dart_pairs(s, getattr(s, op)(darts))
        assert res == [want[d][op] for d in got], op
    fv = np.sort(np.asarray(s.face_vertices()), axis=1)
    faces_of = np.asarray(s.face(darts))
    for d, f in zip(got, faces_of.tolist()):
        expect = want[d]["face"]
        assert (f == s.num_faces) if expect is None else tuple(fv[f]) == expect


@pytest.mark.parametrize("name", mesh_params(CLOSED_GENUS0 + HOLED_GENUS0 + HIGHER_GENUS))
def test_halfedge_matches_oracle(name):
    m = load_shared(name)
    check_against_oracle(HalfEdge.from_mesh(m), m.faces)


@pytest.mark.parametrize("name", mesh_params(CLOSED_GENUS0 + HOLED_GENUS0 + HIGHER_GENUS))
def test_corner_table_matches_oracle(name):
    m = close_boundaries(load_shared(name))
    ct = CornerTable.from_mesh(m)
    check_against_oracle(ct, m.faces)
    # Rossignac's identities: c.o.o = c, c.n.n.n = c, c.s = c.n.o.n
    c = jnp.arange(ct.num_darts)
    np.testing.assert_array_equal(ct.o(ct.o(c)), c)
    np.testing.assert_array_equal(ct.n(ct.n(ct.n(c))), c)
    np.testing.assert_array_equal(ct.V[ct.s(c)], ct.V[c])


def test_beetle_after_repair_builds():
    m = split_nonmanifold_vertices(load_shared("beetle.off"))
    check_against_oracle(HalfEdge.from_mesh(m), m.faces)


def test_reference_counts():
    v, f = octahedron()
    m = load_mesh(v, f)
    he, ct = HalfEdge.from_mesh(m), CornerTable.from_mesh(m)
    n = m.num_vertices
    # closed triangulation: 3F = 6n - 12 half-edges
    assert he.references == 3 * (6 * n - 12) + n
    assert ct.references == 2 * (6 * n - 12) + n
    assert he.vertex_order is None and ct.vertex_order is None
    assert he.nbytes == 4 * he.references


def test_corner_table_refuses_borders():
    with pytest.raises(errors.UnsupportedTopologyError, match="close_boundaries"):
        CornerTable.from_mesh(load_shared("grid.off"))


def test_structures_are_pytrees_and_jit_without_retracing():
    v, f = octahedron()
    he = HalfEdge.from_mesh(load_mesh(v, f))
    leaves = jax.tree_util.tree_leaves(he)
    assert all(x.dtype == jnp.int32 for x in leaves)
    doubled = jax.tree_util.tree_map(lambda x: x, he)
    assert isinstance(doubled, HalfEdge) and doubled.num_faces == he.num_faces
    traces = []

    @jax.jit
    def nxt(s, e):
        traces.append(1)
        return s.next(e)

    e = jnp.arange(he.num_darts)
    np.testing.assert_array_equal(nxt(he, e), he.next(e))
    nxt(he, e + 0)
    assert len(traces) == 1
    # vmap over a batch of queries gives the same as the batched call
    np.testing.assert_array_equal(jax.vmap(he.twin)(e), he.twin(e))
    with pytest.raises(Exception):
        he.num_faces = 3  # frozen
