"""CornerTable (and HalfEdge) from the twins that validation hands out (jaxcds.mesh.Twins)
equal the ones that match twins themselves (corner_table._closed_corner_table, the
half-edge's _match_twins)."""

from __future__ import annotations

import numpy as np
import pytest

from jaxcds import mesh as M
from jaxcds.generators import random_planar_triangulation_faces
from jaxcds.structures import CornerTable

from conftest import load_shared, mesh_params


def _same(a: CornerTable, b: CornerTable):
    for field in ("V", "O", "vertex_corner"):
        np.testing.assert_array_equal(np.asarray(getattr(a, field)), np.asarray(getattr(b, field)))
    assert (a.num_vertices, a.num_faces) == (b.num_vertices, b.num_faces)


@pytest.mark.parametrize("name", mesh_params(["bunny.off", "3holes.off", "grid.off",
                                              "stanford-bunny.obj"]))
def test_corner_table_from_validation_twins(name):
    m, twins = M.validate_and_close(load_shared(name), connected=False, return_twins=True)
    assert twins is not None
    _same(CornerTable.from_faces(m.faces, m.num_vertices, twins=twins),
          CornerTable.from_faces(m.faces, m.num_vertices))


@pytest.mark.parametrize("seed", range(3))
def test_corner_table_from_mesh_uses_twins_on_random_triangulations(seed):
    f = random_planar_triangulation_faces(200 + 37 * seed, seed=seed)
    m = M.TriMesh(vertices=np.zeros((int(f.max()) + 1, 3)), faces=f)
    ct = CornerTable.from_mesh(m)
    _same(ct, CornerTable.from_faces(f, m.num_vertices))
    # O is an involution without fixed points, c.o.v is the vertex facing c's edge
    O = np.asarray(ct.O)
    assert (O[O] == np.arange(O.size)).all() and (O != np.arange(O.size)).all()


def test_twins_of_another_face_list_are_refused():
    """Twins of another face list were ignored when their size differed (matched again) and used
    when it was the same (a wrong table); since stop 50 both are refused by name."""
    from jaxcds import errors

    f = random_planar_triangulation_faces(50, seed=1)
    _, twins = M.validate(M.TriMesh(vertices=np.zeros((50, 3)), faces=f), return_twins=True)
    g = random_planar_triangulation_faces(60, seed=2)
    with pytest.raises(errors.ArgumentError, match="CornerTable.from_faces: twins.opp must be"):
        CornerTable.from_faces(g, 60, twins=twins)
    h = random_planar_triangulation_faces(50, seed=3)  # the same size, other faces
    with pytest.raises(errors.ArgumentError, match="CornerTable.from_faces: twins.opp.* is not the twin"):
        CornerTable.from_faces(h, 50, twins=twins)
    _same(CornerTable.from_faces(f, 50, twins=twins), CornerTable.from_faces(f, 50))


@pytest.mark.parametrize("name", mesh_params(["grid.off", "stanford-bunny.obj", "3holes.off"]))
def test_halfedge_from_validation_twins(name):
    from jaxcds.structures import HalfEdge

    m = load_shared(name)
    a, b = HalfEdge.from_mesh(m), HalfEdge.from_faces(m.faces, m.num_vertices)  # twins / matched
    for field in ("next_", "opposite", "vertex", "vertex_edge", "border_prev"):
        np.testing.assert_array_equal(np.asarray(getattr(a, field)), np.asarray(getattr(b, field)))


def test_corner_table_of_a_hub_of_high_degree_in_random_face_order():
    # a bipyramid: hubs 0 and k+1 of degree k, faces shuffled (the former first-unpaired scan
    # was quadratic in the hub's degree here); c.o against the geometry of the construction
    k = 3000
    ring, nxt = 1 + np.arange(k), 1 + (np.arange(k) + 1) % k
    f = np.concatenate([np.stack([np.zeros(k, int), ring, nxt], 1),
                        np.stack([np.full(k, k + 1), nxt, ring], 1)]).astype(np.int32)
    f = f[np.random.default_rng(0).permutation(f.shape[0])]
    m = M.TriMesh(vertices=np.zeros((k + 2, 3)), faces=f)
    for ct in (CornerTable.from_mesh(m), CornerTable.from_faces(f, k + 2)):
        V, O = np.asarray(ct.V), np.asarray(ct.O)
        hub = np.nonzero(V == 0)[0]  # corner at hub 0 faces ring edge (r, r+1): apex k+1 opposite
        assert (V[O[hub]] == k + 1).all()
        assert (O[O] == np.arange(O.size)).all()


def test_from_faces_names_twins_of_the_wrong_kind():
    """``twins`` must be None or validation's ``Twins`` (``twins=1`` raised an AttributeError
    about ``.opp``), for the corner table and the half-edge alike."""
    from jaxcds import errors
    from jaxcds.structures.halfedge import HalfEdge
    from conftest import octahedron

    _, f = octahedron()
    for cls in (CornerTable, HalfEdge):
        for bad in (1, "twins", (np.zeros(24, np.int32), np.zeros(6, np.int32))):
            with pytest.raises(errors.ArgumentError, match=f"{cls.__name__}.from_faces: twins must be"):
                cls.from_faces(f, 6, twins=bad)
    from jaxcds.structures.halfedge import halfedge_arrays

    with pytest.raises(errors.ArgumentError, match="halfedge_arrays: twins must be"):
        halfedge_arrays(f, 6, 1)  # sweep 50c: an AttributeError about .opp


@pytest.mark.parametrize("change, message", [
    ("swap", r"twins.opp\[0\] = \d+ is not the twin of dart 0 \(\d+ -> \d+\) in these faces"),
    ("big", r"twins.opp\[5\] = 1000000 is not the twin of dart 5"),
    ("short", r"twins.opp must be \(240,\) integers for these faces, got int32 \(10,\)"),
    ("float", r"twins.opp must be \(240,\) integers for these faces, got float64"),
    ("corner", r"twins.vertex_corner\[0\] = \d+ is not a corner of vertex 0 in these faces"),
])
def test_from_faces_checks_the_twins_are_those_of_the_faces(change, message):
    """Stop 50 (sweep 50c's leftover): hand-made ``Twins`` were copied into the structure as
    given, a wrong table without a word (an ``opp`` out of range, not an involution, of other
    faces). ``from_faces`` and ``halfedge_arrays`` now check them, O(F); ``from_mesh`` passes
    the twins validation has just returned unchecked. Holed meshes' twins (-1 on borders) and
    validation's own are taken."""
    from jaxcds import errors
    from jaxcds.generators import icosphere
    from jaxcds.structures.halfedge import HalfEdge, halfedge_arrays

    m = icosphere(1)
    _, tw = M.validate(m, return_twins=True)
    opp, vc = np.asarray(tw.opp), np.asarray(tw.vertex_corner)
    if change == "swap":
        opp = opp[[1, 0] + list(range(2, opp.size))]
    elif change == "big":
        opp = np.where(np.arange(opp.size) == 5, 10 ** 6, opp).astype(np.int32)
    elif change == "short":
        opp = opp[:10]
    elif change == "float":
        opp = opp.astype(float)
    else:
        vc = np.roll(vc, 1)
    bad = M.Twins(opp, vc)
    for cls in (CornerTable, HalfEdge):
        assert cls.from_faces(m.faces, m.num_vertices, twins=tw).num_faces == 80
        with pytest.raises(errors.ArgumentError, match=rf"{cls.__name__}.from_faces: " + message):
            cls.from_faces(m.faces, m.num_vertices, twins=bad)
    with pytest.raises(errors.ArgumentError, match="halfedge_arrays: " + message):
        halfedge_arrays(m.faces, m.num_vertices, bad)
    holed = load_shared("grid.off")
    _, htw = M.validate(holed, return_twins=True)
    assert HalfEdge.from_faces(holed.faces, holed.num_vertices, twins=htw).num_faces == holed.num_faces
