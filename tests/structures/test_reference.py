"""HalfEdge and CornerTable against a brute-force oracle written with Python dicts."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxcds import errors
from jaxcds.mesh import close_boundaries, load_mesh, split_nonmanifold_vertices
from jaxcds.structures import CornerTable, HalfEdge

from conftest import (CLOSED_GENUS0, HIGHER_GENUS, HOLED_GENUS0, crash_probe, load_shared, mesh_params,
                      octahedron)


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


# ----------------------------------------------------------------- the unvalidated from_faces
# (sweep 14b) ``from_faces`` skips validation for speed; ids out of range made the numba
# builders read and write outside their arrays (a segfault, or a silent write), and border sides
# that do not chain into loops wrote ``border_prev`` out of range (-1 - 3F) or left slots of
# ``np.empty`` garbage that pemb then read. Probed in a child: without the checks it crashes.
_TRUSTED_CHILD = r"""
import numpy as np
from jaxcds.structures import CornerTable, HalfEdge
from jaxcds.structures.halfedge import halfedge_arrays

cases = {
    "id_big": ([[0, 1, 2], [0, 2, 7]], 4),
    "id_huge": ([[0, 1, 2], [0, 2, 1 << 30]], 4),
    "id_negative": ([[0, 1, 2], [0, 2, -1]], 4),
    "id_neg_huge": ([[0, 1, 2], [0, 2, -(1 << 30)]], 4),
    "pinched": ([[0, 1, 2], [0, 3, 4]], 5),
    "flipped": ([[0, 1, 2], [0, 1, 3]], 4),
    "nm_edge": ([[0, 1, 2], [1, 0, 3], [0, 1, 4]], 5),
    "no_faces": (np.zeros((0, 3), np.int32), 4),
    "nv_negative": ([[0, 1, 2]], -1),
}
builders = {"he": HalfEdge.from_faces, "ct": CornerTable.from_faces,
            "arrays": lambda f, n: halfedge_arrays(np.asarray(f, np.int32), n)}
for b, build in builders.items():
    for name, (f, nv) in cases.items():
        record(b + ":" + name, build, np.asarray(f, np.int32), nv)
"""


def test_from_faces_trusted_input_cannot_crash():
    out = crash_probe(_TRUSTED_CHILD)
    for b, where in (("he", "HalfEdge.from_faces"), ("ct", "CornerTable.from_faces"),
                     ("arrays", "halfedge_arrays")):
        for name, vertex in (("id_big", "7"), ("id_huge", str(1 << 30)), ("id_negative", "-1"),
                             ("id_neg_huge", str(-(1 << 30)))):
            cls, msg = out[f"{b}:{name}"]
            assert cls == "InvalidIndexError", (b, name, cls, msg)
            assert msg.startswith(f"{where}: face 1 refers to vertex {vertex}, outside [0, 4)"), msg
        # border sides that do not chain: the defect named as validate names it
        assert out[f"{b}:pinched"][0] == "NonManifoldVertexError", out[f"{b}:pinched"]
        assert "vertex 0" in out[f"{b}:pinched"][1]
        assert out[f"{b}:flipped"][0] == "InconsistentOrientationError", out[f"{b}:flipped"]
        assert "edge (0, 1)" in out[f"{b}:flipped"][1]
        assert out[f"{b}:nm_edge"][0] == "NonManifoldEdgeError", out[f"{b}:nm_edge"]
        assert out[f"{b}:nv_negative"][0] == "ArgumentError", out[f"{b}:nv_negative"]
    for b in ("he", "ct"):  # a structure without darts: every query's gather failed raw
        assert out[f"{b}:no_faces"][0] == "EmptyMeshError", out[f"{b}:no_faces"]


@pytest.mark.parametrize("cls_name", ["HalfEdge", "CornerTable", "PEMB"])
def test_from_faces_of_no_faces_is_an_empty_mesh_error(cls_name):
    """No dart: every query's gather would index an empty table; refused by name."""
    from jaxcds.structures.pemb import PEMB

    cls = {"HalfEdge": HalfEdge, "CornerTable": CornerTable, "PEMB": PEMB}[cls_name]
    with pytest.raises(errors.EmptyMeshError, match=rf"{cls.__name__}.from_faces: no faces \(3 vertices\); "
                                                    "nothing to build"):
        cls.from_faces(np.zeros((0, 3), np.int32), 3)
