"""Polylla on pemb vs on the HalfEdge (issue 7): the same polygons on both half-edges.

The reference C++ code gives different polygon counts for its two structures; ours must not. On
``points50.1`` (the reference output's 17 polygons), a k x k grid with all diagonals one way
((k-1)^2 quads, no barrier-edge tips), random point sets (hypothesis) and random domains with a
hole, every polygon (as a canonical vertex cycle), every count (tips, repaired polygons, regions,
frontier edges) and even the canonical CSR arrays are equal.

Cost: jit compiles every phase once per structure *shape* (pemb: ~18 s of CPU per shape, the
half-edge ~2.5 s), so the random cases are built with the shapes of the fixed ones: the plain
random sets have a fixed 15-gon hull and 35 inner points (50 vertices, 83 triangles: the shape of
points50.1), the holed domains a fixed 12-gon hull and a hexagonal hole (one shape for all).
"""

from __future__ import annotations

import os
import pathlib

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from jaxcds import errors
from jaxcds import polylla_io as io
from jaxcds.algorithms import polylla as P

SHARED = pathlib.Path(os.environ.get("JAXCDS_SHARED",
                                     pathlib.Path(__file__).resolve().parents[2].parent / "shared"))
POLYLLA = SHARED / "polylla"
SETTINGS = settings(max_examples=4, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow])


# ------------------------------------------------------------------------ helpers
def run_both(tri):
    """Polylla on the HalfEdge and on pemb of ``tri``: ``(halfedge mesh, pemb mesh)``."""
    return tuple(P.polylla(P.build_structure(tri, s), tri.points) for s in ("halfedge", "pemb"))


def assert_same(a, b):
    """Identical outputs: same polygons as sets of canonical cycles, same counts, and (the output
    being canonical) the same CSR arrays."""
    assert P.polygons_as_cycles(a.polygons()) == P.polygons_as_cycles(b.polygons())
    for key in ("barrier_edge_tips", "repaired_polygons", "regions", "frontier_edges", "triangles"):
        assert getattr(a, key) == getattr(b, key), key
    np.testing.assert_array_equal(a.offsets, b.offsets)
    np.testing.assert_array_equal(a.indices, b.indices)


def area2(points, poly):
    p = points[np.asarray(poly)]
    return float(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))


def assert_tiles(tri, mesh):
    """The polygons are ccw and tile the triangulated domain (areas add up, no directed edge
    used twice): a sanity check that the common output is a polygonal mesh of the domain."""
    areas = [area2(tri.points, p) for p in mesh.polygons()]
    assert min(areas) > 0
    np.testing.assert_allclose(sum(areas), sum(area2(tri.points, f) for f in tri.faces), rtol=1e-9)
    darts = [(p[i], p[(i + 1) % len(p)]) for p in mesh.polygons() for i in range(len(p))]
    assert len(set(darts)) == len(darts)


def grid(k: int):
    """k x k grid points, every cell split by its (i, j)-(i+1, j+1) diagonal."""
    xs, ys = np.meshgrid(np.arange(k, dtype=float), np.arange(k, dtype=float))
    pts = np.column_stack([xs.ravel(), ys.ravel()])
    faces = []
    for j in range(k - 1):
        for i in range(k - 1):
            a, b, c, d = j * k + i, j * k + i + 1, (j + 1) * k + i + 1, (j + 1) * k + i
            faces += [[a, b, c], [a, c, d]]
    return io.Triangulation2D(points=pts, faces=np.array(faces, np.int32), source=f"grid{k}")


def regular(k: int, radius: float, phase: float = 0.0):
    t = phase + 2 * np.pi * np.arange(k) / k
    return radius * np.column_stack([np.cos(t), np.sin(t)])


def in_annulus(rng, n: int, r0: float, r1: float):
    """``n`` uniform points in the annulus ``r0 < |p| < r1``."""
    r = np.sqrt(r0 ** 2 + rng.random(n) * (r1 ** 2 - r0 ** 2))
    t = 2 * np.pi * rng.random(n)
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


HULL, INNER = 15, 35  # 50 vertices, 2*50 - 2 - 15 = 83 triangles: the shape of points50.1


def random_points(seed: int):
    """Delaunay of a fixed regular 15-gon hull and 35 uniform points strictly inside it."""
    rng = np.random.default_rng(seed)
    pts = np.concatenate([regular(HULL, 1.0), in_annulus(rng, INNER, 0.0, 0.95 * np.cos(np.pi / HULL))])
    tri = io.from_points(pts, f"random{seed}")
    assert (tri.num_vertices, tri.num_faces) == (50, 83)
    return tri


OUT, HOLE, RING = 12, 6, 32  # 50 vertices, 18 border edges, 2*50 - 18 = 82 triangles
HOLED_WITH_TIPS = 2  # a seed whose domain has a barrier-edge tip (asserted below)


def holed_domain(seed: int):
    """A random domain with a hole: a 12-gon hull, a hexagonal hole of radius 0.25 and 32 uniform
    points in between, kept at radius > 1.4 * 0.25 so that no point lies in the diametral circle
    of a hole edge (the hexagon's edges are then Delaunay edges and the triangles with three
    hexagon corners are exactly the hole)."""
    rng = np.random.default_rng(seed)
    pts = np.concatenate([regular(OUT, 1.0), regular(HOLE, 0.25, 0.3),
                          in_annulus(rng, RING, 1.4 * 0.25, 0.95 * np.cos(np.pi / OUT))])
    full = io.from_points(pts, f"holed{seed}")
    in_hole = (full.faces >= OUT) & (full.faces < OUT + HOLE)
    faces = full.faces[~in_hole.all(axis=1)]
    assert faces.shape[0] == 2 * pts.shape[0] - (OUT + HOLE) == full.num_faces - (HOLE - 2)
    return io.Triangulation2D(points=full.points, faces=faces, source=f"holed{seed}")


# ------------------------------------------------------------------------ fixed inputs
@pytest.fixture(scope="module")
def points50():
    node = POLYLLA / "points50.1.node"
    if not node.exists():
        pytest.skip(f"{node} not found")
    tri = io.read_triangle(str(node))
    return tri, run_both(tri)


def test_points50_same_17_polygons_as_reference(points50):
    tri, (he, pe) = points50
    assert (tri.num_vertices, tri.num_faces) == (50, 83)
    _, ref = io.read_polygon_off(str(POLYLLA / "points50.1.off"))
    assert len(ref) == 17
    assert_same(he, pe)
    assert pe.num_polygons == 17
    assert P.polygons_as_cycles(pe.polygons()) == P.polygons_as_cycles(ref)
    assert_tiles(tri, pe)


@pytest.mark.slow  # a third pemb shape (~18 s CPU); test_polylla.py's quick grid(6) runs pemb too
def test_grid_quads_no_barrier_tips():
    k = 6  # the size test_polylla.py uses too: one compilation when both run in one process
    tri = grid(k)
    he, pe = run_both(tri)
    assert_same(he, pe)
    assert pe.num_polygons == (k - 1) ** 2 and np.all(np.diff(pe.offsets) == 4)
    assert pe.barrier_edge_tips == 0 and pe.repaired_polygons == 0
    # each quad is one cell: its four corners are the cell's corners
    cells = {tuple(sorted((j * k + i, j * k + i + 1, (j + 1) * k + i + 1, (j + 1) * k + i)))
             for j in range(k - 1) for i in range(k - 1)}
    assert {tuple(sorted(p)) for p in pe.polygons()} == cells


def test_domain_with_hole_and_repair():
    """A fixed holed domain whose regions have barrier-edge tips: the repair phase (middle edges,
    successor updates) runs on pemb's border darts and gives the half-edge's polygons."""
    tri = holed_domain(HOLED_WITH_TIPS)
    he, pe = run_both(tri)
    assert_same(he, pe)
    assert pe.barrier_edge_tips > 0 and pe.repaired_polygons > 0
    assert_tiles(tri, pe)
    # the hole is not covered: the hexagon (ccw) is walked only clockwise, from the domain side
    hole_side = {(OUT + i, OUT + (i + 1) % HOLE) for i in range(HOLE)}
    used = {(p[i], p[(i + 1) % len(p)]) for p in pe.polygons() for i in range(len(p))}
    assert used.isdisjoint(hole_side)
    assert {(b, a) for a, b in hole_side} <= used  # its border edges are frontier edges


# ------------------------------------------------------------------------ random point sets
@SETTINGS
@given(seed=st.integers(0, 2**32 - 1))
def test_random_point_sets_same_on_both(seed):
    tri = random_points(seed)
    he, pe = run_both(tri)
    assert_same(he, pe)
    assert_tiles(tri, pe)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1))
def test_random_domains_with_a_hole_same_on_both(seed):
    tri = holed_domain(seed)
    he, pe = run_both(tri)
    assert_same(he, pe)
    assert_tiles(tri, pe)


# ------------------------------------------------------------------------ what pemb refuses
def test_pemb_refuses_vertex_in_no_triangle_by_name():
    """pemb's spanning tree must reach every vertex: a point in no triangle (here the centre of
    a grid whose four middle cells were cut out) is refused by name; the half-edge accepts it."""
    tri = grid(5)
    keep = [f for f in tri.faces if 12 not in f]  # vertex 12 = (2, 2), the centre
    holed = io.Triangulation2D(tri.points, np.array(keep, np.int32), "grid5-cut")
    assert P.build_structure(holed, "halfedge").num_vertices == 25
    with pytest.raises(errors.UnreferencedVertexError, match="vertex 12 is in no face"):
        P.build_structure(holed, "pemb")


# ------------------------------------------------------------------------ without run tables
@pytest.mark.slow  # ~31 s of pemb compilations; pemb's searching operators stay in the quick set
def test_pemb_without_navigation_tables_same_polygons():
    """``tables=False``: Polylla on pemb's own searching operators (no per-run twin / origin /
    face tables at any time) gives the tabulated run's polygons, repair included."""
    tri = holed_domain(HOLED_WITH_TIPS)
    s = P.build_structure(tri, "pemb")
    with_tables = P.polylla(s, tri.points)
    searching = P.polylla(s, tri.points, tables=False)
    assert searching.barrier_edge_tips > 0 and searching.repaired_polygons > 0
    assert_same(with_tables, searching)
