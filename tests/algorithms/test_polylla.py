"""Polylla (issue 7): conformance with the reference output, grids, random point sets against a
slow sequential port of the reference algorithm, invariants, I/O and errors, every structure."""

from __future__ import annotations

import json
import math
import os
import pathlib
import re
import types

import jax
import numpy as np
import pytest

from jaxcds import errors
from jaxcds.algorithms import polylla as P
from jaxcds import polylla_io as io
from jaxcds.structures import registry

SHARED = pathlib.Path(os.environ.get("JAXCDS_SHARED",
                                     pathlib.Path(__file__).resolve().parents[2].parent / "shared"))
POLYLLA = SHARED / "polylla"

# Polylla needs borders: the structures of the registry that accept them (pemb once it lands).
STRUCTURES = [pytest.param(n, marks=pytest.mark.skipif(
    n not in registry.names(), reason=f"structure {n} not registered yet")) for n in ("halfedge", "pemb")]


def _need(path: pathlib.Path) -> str:
    if not path.exists():
        pytest.skip(f"{path} not found")
    return str(path)


# ------------------------------------------------------------------------ slow reference port
def reference_polylla(points: np.ndarray, faces: np.ndarray, sequential: bool = False,
                      exact: bool = False):
    """Sequential port of the reference (Polylla-Mesh-DCEL ``polylla.hpp``): seeds in dart order,
    ``travel_triangles``, ``has_BarrierEdgeTip`` (poly[i] == poly[i+2]), ``search_middle_edge``
    with its even/odd cases, ``barrieredge_tip_reparation``. Plain Python lists, no protocol.
    The faces are taken as given: corner order (ties go to the first of ``c0c1, c1c2, c2c0``),
    orientation (clockwise faces give clockwise polygons) and numbering (half-edge ``3 i + j``,
    ``edge_of_vertex`` = the last one written for its origin).

    ``exact``: the reference as it is, the oracle of ``mode="reference"``: a walk stops the first
    time it meets its starting vertex again (``v_curr != v_init``), tips are repaired one after
    the other (each middle edge marked frontier at once), and the pieces are walked from the
    middle-edge darts in reverse order, crossing off the darts a walk passes
    (``seed_bet_mark``); polygons in the reference's output order.
    Otherwise, the oracle of ``mode="canonical"``: walks close on their starting dart, repaired
    pieces are de-duplicated as cycles, and (unless ``sequential``) the middle edges of all tips
    of a polygon are chosen before any is marked frontier.
    Returns ``(polygons, barrier_edge_tips, repaired_polygons)``."""
    faces = np.asarray(faces)
    nd = 3 * faces.shape[0]
    org = faces.ravel().tolist()
    nxt = [3 * (d // 3) + (d % 3 + 1) % 3 for d in range(nd)]
    where = {(org[d], org[nxt[d]]): d for d in range(nd)}
    tw = [where.get((org[nxt[d]], org[d]), -1) for d in range(nd)]

    def length(d):  # the reference's distance(): sqrt(pow(dx, 2) + pow(dy, 2))
        a, b = points[org[d]], points[org[nxt[d]]]
        return math.sqrt(float((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2))

    mx = [False] * nd
    for f in range(faces.shape[0]):
        e0, e1, e2 = 3 * f, 3 * f + 1, 3 * f + 2
        d0, d1, d2 = length(e0), length(e1), length(e2)
        if (d0 >= d1 and d1 >= d2) or (d0 >= d2 and d2 >= d1):
            mx[e0] = True
        elif (d1 >= d0 and d0 >= d2) or (d1 >= d2 and d2 >= d0):
            mx[e1] = True
        else:
            mx[e2] = True
    seeds = [d for d in range(nd)
             if (tw[d] >= 0 and mx[d] and mx[tw[d]] and d < tw[d]) or (tw[d] < 0 and mx[d])]
    # the exterior half-edges, as the reference adds them: twin of each border dart (ids from
    # nd on, in the border darts' order), next = the next exterior one turning ccw
    prv = [3 * (d // 3) + (d % 3 + 2) % 3 for d in range(nd)]
    for d in range(nd):
        if tw[d] < 0:
            tw[d] = len(org)
            org.append(org[nxt[d]])
            tw.append(d)
    outer = lambda e: e >= nd  # noqa: E731
    for h in range(nd, len(org)):
        n = tw[prv[tw[h]]]  # CCW_edge_to_vertex(twin(h))
        while not outer(n):
            n = tw[prv[n]]
        nxt.append(n)
    frontier = [outer(d) or outer(tw[d]) or not (mx[d] or mx[tw[d]]) for d in range(len(org))]
    cw = lambda e: nxt[tw[e]]  # noqa: E731  CW_edge_to_vertex = next(twin(e))
    edge_of_vertex = {}
    for d in range(nd):
        edge_of_vertex[org[d]] = d

    def search(e, cross=None):
        while not frontier[e]:
            e = cw(e)
            if cross is not None:
                cross[e] = False
        return e

    def travel(e, cross=None):
        e0 = search(e, cross)
        poly, cur = [], e0
        if exact:  # the reference's loop: from target(e0) until origin(e0) comes round again
            # (its OFF files list the polygon from origin(e0): rotated by the caller)
            cur = nxt[e0]
            poly.append(org[cur])
            if cross is not None:
                cross[cur] = False
            while cur != e0 and org[cur] != org[e0]:
                cur = nxt[search(cur, cross)]
                poly.append(org[cur])
                if cross is not None:
                    cross[cur] = False
            return poly
        while True:
            poly.append(org[cur])
            cur = search(nxt[cur])
            if cur == e0:
                return poly

    def has_tip(p):
        return any(p[i] == p[(i + 2) % len(p)] for i in range(len(p)))

    def middle_edge(v):
        fe = search(edge_of_vertex[v])
        n, adv = cw(fe), 1
        while n != fe:
            n, adv = cw(n), adv + 1
        adv -= 1
        adv = adv // 2 - 1 if adv % 2 == 0 else adv // 2
        n = cw(fe)
        while adv:
            n, adv = cw(n), adv - 1
        return n

    out, tips, repaired = [], 0, 0
    first = (lambda p: p[-1:] + p[:-1]) if exact else (lambda p: p)  # noqa: E731
    for e in seeds:
        poly = travel(e)
        if not has_tip(poly):
            out.append(first(poly))
            continue
        repaired += 1
        starts = []
        for i in range(len(poly)):
            if poly[i] == poly[(i + 2) % len(poly)]:
                tips += 1
                m = middle_edge(poly[(i + 1) % len(poly)])
                if sequential or exact:
                    frontier[m] = frontier[tw[m]] = True
                starts += [m, tw[m]]
        for m in starts:
            frontier[m] = True
        if exact:
            cross = [False] * len(org)
            for m in starts:
                cross[m] = True
            for t in reversed(starts):
                if cross[t]:
                    cross[t] = False
                    out.append(first(travel(t, cross)))
            continue
        seen = set()
        for t in starts:
            p = travel(t)
            key = P.canonical_cycle(p)
            if key not in seen:
                seen.add(key)
                out.append(p)
    return out, tips, repaired


# ------------------------------------------------------------------------ helpers
def grid(k: int, hole: bool = False):
    """k x k grid points, every cell split by the diagonal (i, j)-(i+1, j+1); ``hole`` removes
    the central cells (a domain with a hole)."""
    xs, ys = np.meshgrid(np.arange(k, dtype=float), np.arange(k, dtype=float))
    pts = np.column_stack([xs.ravel(), ys.ravel()])
    vid = lambda i, j: j * k + i  # noqa: E731
    faces = []
    for j in range(k - 1):
        for i in range(k - 1):
            if hole and k // 3 <= i < k - k // 3 - 1 and k // 3 <= j < k - k // 3 - 1:
                continue
            a, b, c, d = vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1)
            faces += [[a, b, c], [a, c, d]]
    return io.Triangulation2D(points=pts, faces=np.array(faces, np.int32), source="grid")


def signed_area(points, poly):
    p = points[np.asarray(poly)]
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def run_on(tri, structure="halfedge"):
    s = P.build_structure(tri, structure)
    return P.polylla(s, tri.points)


def check_partition(tri, mesh, slack: float = 0.0):
    """Polygons tile the triangulated domain: areas add up, every polygon is ccw (``slack``: a
    polygon of Qhull slivers may have a float area of about zero), and each undirected frontier
    edge is used once per side."""
    total = sum(signed_area(tri.points, f) for f in tri.faces)
    areas = [signed_area(tri.points, p) for p in mesh.polygons()]
    assert min(areas) > -slack
    np.testing.assert_allclose(sum(areas), total, rtol=1e-9)
    darts = [(p[i], p[(i + 1) % len(p)]) for p in mesh.polygons() for i in range(len(p))]
    assert len(set(darts)) == len(darts), "a directed edge is used by two polygons"


# ------------------------------------------------------------------------ conformance
@pytest.mark.parametrize("structure", STRUCTURES)
def test_points50_matches_reference_off(structure):
    tri = io.read_triangle(_need(POLYLLA / "points50.1.node"))
    assert (tri.num_vertices, tri.num_faces) == (50, 83)
    mesh = run_on(tri, structure)
    _, ref = io.read_polygon_off(_need(POLYLLA / "points50.1.off"))
    assert len(ref) == 17
    assert mesh.num_polygons == 17
    assert P.polygons_as_cycles(mesh.polygons()) == P.polygons_as_cycles(ref)
    # reference mode (the input's rows): the file's own order, each polygon from its first vertex
    exact = P.polylla(P.build_structure(tri, structure), tri.points, corners=tri.input_faces)
    assert exact.polygons() == [list(map(int, p)) for p in ref]
    check_partition(tri, mesh)


def test_points50_neigh_optional_and_off_input(tmp_path):
    node = _need(POLYLLA / "points50.1.node")
    a = io.read_triangle(node)  # finds and checks .neigh
    b = io.read_triangle(node, str(POLYLLA / "points50.1.ele"), neigh=None)
    np.testing.assert_array_equal(a.faces, b.faces)
    # the same triangulation as a 2D OFF file
    off = tmp_path / "tri.off"
    with open(off, "w") as fh:
        fh.write(f"OFF\n{a.num_vertices} {a.num_faces} 0\n")
        for x, y in a.points:
            fh.write(f"{float(x)!r} {float(y)!r} 0\n")
        for f in a.faces:
            fh.write(f"3 {f[0]} {f[1]} {f[2]}\n")
    c = io.read_off_2d(str(off))
    assert P.polygons_as_cycles(run_on(c).polygons()) == P.polygons_as_cycles(run_on(a).polygons())


@pytest.mark.parametrize("structure", STRUCTURES)
@pytest.mark.parametrize("k", [3, 6])
def test_grid_gives_quads(structure, k):
    tri = grid(k)
    mesh = run_on(tri, structure)
    assert mesh.num_polygons == (k - 1) ** 2
    assert np.all(np.diff(mesh.offsets) == 4)
    assert mesh.barrier_edge_tips == 0 and mesh.repaired_polygons == 0
    check_partition(tri, mesh)


def test_grid_with_hole():
    tri = grid(9, hole=True)
    mesh = run_on(tri)
    cells = (tri.num_faces // 2)
    assert mesh.num_polygons == cells and np.all(np.diff(mesh.offsets) == 4)
    check_partition(tri, mesh)


# ------------------------------------------------------------------------ random point sets
def random_tri(seed: int, n: int = 400):
    """Delaunay of ``n`` uniform points; tests share these (one compilation per mesh size)."""
    key = (seed, n)
    if key not in _RANDOM:
        _RANDOM[key] = io.from_points(np.random.default_rng(seed).random((n, 2)), f"random{seed}")
    return _RANDOM[key]


_RANDOM: dict = {}


@pytest.mark.parametrize("seed", [0, 1])
def test_random_points_match_sequential_reference(seed):
    tri = random_tri(seed)
    mesh = run_on(tri)
    ref, tips, repaired = reference_polylla(tri.points, tri.faces)
    assert P.polygons_as_cycles(mesh.polygons()) == P.polygons_as_cycles(ref)
    assert mesh.barrier_edge_tips == tips
    assert mesh.repaired_polygons == repaired
    assert mesh.num_polygons == len(ref)
    check_partition(tri, mesh)
    # the reference's own (sequential) marking finds the same tips and repairs the same regions
    _, tips_seq, repaired_seq = reference_polylla(tri.points, tri.faces, sequential=True)
    assert (tips_seq, repaired_seq) == (tips, repaired)


# the modes part on all three seeds (see below); pemb on the shape other tests compile it for
@pytest.mark.parametrize("structure, seed", [("halfedge", 1), ("halfedge", 5), ("halfedge", 9),
                                             *[pytest.param(p.values[0], 1, marks=p.marks)
                                               for p in STRUCTURES[1:]]])
def test_reference_mode_is_the_reference_polygon_for_polygon(structure, seed):
    """``mode="reference"`` (the default with the input's rows) gives the reference's output
    as it is: the same polygons in the same order, each from the same vertex, the same tip and
    repair counts, on random inputs whose faces are listed in a shuffled order."""
    tri = random_tri(seed)
    perm = np.random.default_rng(seed).permutation(tri.num_faces)
    t = io.Triangulation2D(tri.points, tri.faces[perm].astype(np.int32), "shuffled")
    exact, tips, repaired = reference_polylla(t.points, t.input_faces, exact=True)
    s = P.build_structure(t, structure)
    mesh = P.polylla(s, t.points, corners=t.input_faces)
    assert mesh.polygons() == exact
    assert (mesh.barrier_edge_tips, mesh.repaired_polygons) == (tips, repaired)
    canon = P.polylla(s, t.points, corners=t.input_faces, mode="canonical")
    assert (mesh.regions, mesh.frontier_edges) == (canon.regions, canon.frontier_edges)
    if _simple(mesh):
        check_partition(t, mesh)


def _simple(mesh):
    return all(p[i] != p[(i + 2) % len(p)] for p in mesh.polygons() for i in range(len(p)))


@pytest.mark.parametrize("seed, tip_left, sequential_only", [(5, False, True), (9, True, False)])
def test_reference_mode_keeps_the_reference_order_dependence(seed, tip_left, sequential_only):
    """Where the two modes part, reference mode follows the reference. 400 points, seed 5: only
    the repair order matters (the canonical port with the reference's marking order gives the
    reference's polygons); seed 9: a walk cut short at its starting vertex leaves a barrier-edge
    tip in a polygon, which canonical mode splits."""
    tri = random_tri(seed)
    exact, _, _ = reference_polylla(tri.points, tri.input_faces, exact=True)
    canon, _, _ = reference_polylla(tri.points, tri.input_faces)
    seq, _, _ = reference_polylla(tri.points, tri.input_faces, sequential=True)
    s = P.build_structure(tri)
    ref_mode = P.polylla(s, tri.points, corners=tri.input_faces)
    canon_mode = P.polylla(s, tri.points, corners=tri.input_faces, mode="canonical")
    assert ref_mode.polygons() == exact
    assert P.polygons_as_cycles(canon_mode.polygons()) == P.polygons_as_cycles(canon)
    assert P.polygons_as_cycles(exact) != P.polygons_as_cycles(canon)  # not vacuous
    assert (P.polygons_as_cycles(exact) == P.polygons_as_cycles(seq)) == sequential_only
    assert _simple(ref_mode) != tip_left and _simple(canon_mode)
    check_partition(tri, canon_mode)


def test_random_points_exercise_repair():
    """The random cases above are not vacuous: barrier-edge tips do occur and are repaired."""
    tri = random_tri(1)
    mesh = run_on(tri)
    assert mesh.barrier_edge_tips > 0 and mesh.repaired_polygons > 0
    assert mesh.num_polygons > mesh.regions  # repair splits regions into more polygons
    # after repair no polygon walks up and back a barrier edge
    for p in mesh.polygons():
        assert all(p[i] != p[(i + 2) % len(p)] for i in range(len(p))) or len(p) < 3


@pytest.mark.parametrize("clockwise", [False, True])
def test_polygon_lists_host_route_equals_pointer_doubling(monkeypatch, clockwise):
    """Canonical mode's polygon lists on a CPU device come from one walk per cycle on the host
    (``polylla_cycles``); on other devices from ``cycles_to_csr``'s doubling: same arrays, same
    order (``canonical=False``: by head dart), same repaired-region count."""
    tri = random_tri(1)
    s = P.build_structure(tri, "halfedge", check=False)
    # clockwise: the polygons reversed after the lists (the reference's orientation)
    kw = dict(mode="canonical", canonical=False, clockwise=clockwise)
    host = P.polylla(s, tri.points, **kw)
    monkeypatch.setattr(P, "_on_cpu", lambda x: False)
    dev = P.polylla(s, tri.points, **kw)
    assert host.repaired_polygons > 0 and host.num_polygons > 100
    np.testing.assert_array_equal(host.offsets, dev.offsets)
    np.testing.assert_array_equal(host.indices, dev.indices)
    assert host.repaired_polygons == dev.repaired_polygons


def test_polygon_lists_host_route_refuses_a_broken_successor_map():
    from jaxcds.algorithms.polylla_cycles import cycles_csr_host

    E = 8
    vo = np.arange(E, dtype=np.int32)
    ok_map = np.array([1, 2, 0, 4, 3, E, E, E], np.int32)  # cycles (0 1 2), (3 4)
    off, idx, pod, ok = cycles_csr_host(ok_map, vo)
    assert ok and off.tolist() == [0, 3, 5] and idx.tolist() == [0, 1, 2, 3, 4]
    assert pod.tolist() == [0, 0, 0, 1, 1, -1, -1, -1]
    for broken in ([1, 2, 1, 4, 3, E, E, E],   # 0 -> 1 -> 2 -> 1: a rho
                   [1, 2, 5, 4, 3, E, E, E],   # 2 -> 5, a dart off the frontier
                   [1, 2, 0, 4, 3, 3, E, E]):  # 5 -> 3: two darts share a successor
        assert not cycles_csr_host(np.array(broken, np.int32), vo)[3]


def test_domain_with_holes_random():
    rng = np.random.default_rng(7)
    pts = rng.random((600, 2))
    tri = io.from_points(pts)
    c = tri.points[tri.faces].mean(axis=1)
    keep = np.linalg.norm(c - 0.5, axis=1) > 0.2  # punch a round hole
    from jaxcds.mesh import TriMesh, split_nonmanifold_vertices
    faces = tri.faces[keep]
    # drop bow-tie corners the cut may create: keep faces of the largest clean set
    m = split_nonmanifold_vertices(TriMesh(np.column_stack([tri.points, np.zeros(len(pts))]), faces))
    tri2 = io.Triangulation2D(points=m.vertices[:, :2], faces=m.faces, source="holed")
    mesh = run_on(tri2)
    ref, tips, repaired = reference_polylla(tri2.points, tri2.faces)
    assert P.polygons_as_cycles(mesh.polygons()) == P.polygons_as_cycles(ref)
    check_partition(tri2, mesh)
    # reference mode: the walks along the hole's border as the reference's exterior half-edges
    exact, tips_x, _ = reference_polylla(tri2.points, tri2.faces, exact=True)
    got = P.polylla(P.build_structure(tri2), tri2.points, corners=tri2.faces)
    assert got.polygons() == exact and got.barrier_edge_tips == tips_x


@pytest.mark.parametrize("structure", STRUCTURES)
def test_output_independent_of_structure_and_face_order(structure):
    rng = np.random.default_rng(3)
    tri = random_tri(1)
    a = run_on(tri, "halfedge")
    perm = rng.permutation(tri.num_faces)
    rot = rng.integers(0, 3, tri.num_faces)
    f = tri.faces[perm]
    f = np.stack([np.roll(r, -k) for r, k in zip(f, rot[perm])])
    b = run_on(io.Triangulation2D(tri.points, f.astype(np.int32)), structure)
    # canonical output: identical arrays, not only identical sets of cycles
    np.testing.assert_array_equal(a.offsets, b.offsets)
    np.testing.assert_array_equal(a.indices, b.indices)
    assert (a.barrier_edge_tips, a.repaired_polygons) == (b.barrier_edge_tips, b.repaired_polygons)


# ------------------------------------------------------------------------ ties, orientation
def tie_lattice(k: int = 7):
    """Rows of points offset by half a step, ``(2i + j % 2, 3j)``: every triangle is isosceles
    with its two long sides exactly equal (sqrt 10 against 2), so every longest edge is a tie."""
    pts = np.array([(2 * i + j % 2, 3 * j) for j in range(k) for i in range(k)], float)
    vid = lambda i, j: j * k + i  # noqa: E731
    faces = []
    for j in range(k - 1):
        for i in range(k - 1):
            a, b, c, d = vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1)
            faces += [[a, b, d], [b, c, d]] if j % 2 == 0 else [[a, b, c], [a, c, d]]
    return io.Triangulation2D(points=pts, faces=np.array(faces, np.int32), source="ties")


@pytest.mark.parametrize("rotation", [0, 1, 2, "random"])
def test_ties_follow_the_input_corner_order(rotation):
    """The reference breaks a tie between equally long edges by its triangle's corner order
    (the first of c0c1, c1c2, c2c0). Each rotation of the corners is a different input, with its
    own polygons; the run follows it, on the half-edge and on pemb (whose faces are numbered
    its own way: the rows are matched to them)."""
    tri = tie_lattice()
    rot = (np.random.default_rng(5).integers(0, 3, tri.num_faces) if rotation == "random"
           else np.full(tri.num_faces, rotation))
    faces = np.stack([np.roll(f, -r) for f, r in zip(tri.faces, rot)]).astype(np.int32)
    t = io.Triangulation2D(tri.points, faces, "ties")
    ref, tips, _ = reference_polylla(t.points, t.faces)
    exact, _, _ = reference_polylla(t.points, t.faces, exact=True)
    got = {st: P.run(t, structure=st) for st in ("halfedge", "pemb")}
    for st in got:
        for mode, want in (("canonical", ref), ("reference", exact)):
            mesh = P.polylla(P.build_structure(t, st), t.points, corners=t.input_faces, mode=mode)
            assert P.polygons_as_cycles(mesh.polygons()) == P.polygons_as_cycles(want), (st, mode)
            assert mesh.barrier_edge_tips == tips
            check_partition(t, mesh)
        assert mesh.polygons() == exact  # reference mode: the reference's order, vertex for vertex
    assert got["halfedge"] == {**got["pemb"], "structure": "halfedge", "timings": got["halfedge"]["timings"]}


def test_tie_lattice_is_not_vacuous():
    """The corner order decides: rotations of the triangles' corners give different polygons
    (a leg that neither of its triangles picks splits a row of the lattice)."""
    tri = tie_lattice()
    seen = set()
    s = P.build_structure(tri)
    for seed in range(3):
        rot = np.random.default_rng(seed).integers(0, 3, tri.num_faces)
        faces = np.stack([np.roll(f, -r) for f, r in zip(tri.faces, rot)])
        mesh = P.polylla(s, tri.points, corners=faces)  # same faces, other corner order
        seen.add(tuple(P.polygons_as_cycles(mesh.polygons())))
    assert len(seen) > 1


def test_clockwise_input_gives_the_reference_output():
    """A clockwise input (every triangle, as ``pikachu.1.ele`` of the reference's data): the
    reference keeps the orientation, so its polygons run clockwise, and its barrier-edge repair
    turns ``next(twin)``, counter-clockwise on such input: at a tip of odd degree that is the
    other middle edge."""
    tri = random_tri(1)
    cw = io._make(tri.points, tri.faces[:, ::-1], "clockwise")
    assert cw.all_clockwise and cw.flipped == cw.num_faces
    np.testing.assert_array_equal(cw.input_faces, tri.faces[:, ::-1])
    ref, tips, repaired = reference_polylla(cw.points, cw.input_faces)
    exact, tips_x, repaired_x = reference_polylla(cw.points, cw.input_faces, exact=True)
    for st in STRUCTURES:
        st = st.values[0]
        s = P.build_structure(cw, st)
        got = P.polylla(s, cw.points, corners=cw.input_faces)  # reference mode
        assert got.polygons() == exact, st
        assert (got.barrier_edge_tips, got.repaired_polygons) == (tips_x, repaired_x)
        mesh = P.polylla(s, cw.points, corners=cw.input_faces, mode="canonical")
        assert P.polygons_as_cycles(mesh.polygons()) == P.polygons_as_cycles(ref), st
        assert (mesh.barrier_edge_tips, mesh.repaired_polygons) == (tips, repaired)
        areas = [signed_area(cw.points, p) for p in mesh.polygons()]
        assert max(areas) < 0
        np.testing.assert_allclose(sum(areas), -sum(signed_area(tri.points, f) for f in tri.faces))
    # not vacuous: as polygons (vertex sets), the clockwise run differs from the ccw one
    ccw = run_on(tri)
    assert (sorted(map(sorted, ccw.polygons())) != sorted(map(sorted, mesh.polygons())))


@pytest.mark.parametrize("clockwise,shuffled", [(False, False), (True, False), (False, True)])
def test_pemb_runs_each_piece_of_a_disconnected_input(clockwise, shuffled):
    """pemb is one connected planar embedding: a triangulation in several pieces (the reference's
    pikachu has three) runs piece by piece and gives the half-edge's polygons, arrays and counts
    included; ``shuffled``: the pieces' vertex ids and triangle rows interleaved (each piece is
    cut out by slices of one sort, ``mesh.component_pieces``)."""
    a, b = random_tri(0, 60), tie_lattice(4)
    pts = np.concatenate([a.points, b.points + [2.0, 0.0]])
    faces = np.concatenate([a.faces, b.faces + a.num_vertices])
    if shuffled:
        rng = np.random.default_rng(5)
        perm = rng.permutation(pts.shape[0])  # new id of every vertex
        inv = np.argsort(perm)
        pts, faces = pts[inv], perm[faces][rng.permutation(faces.shape[0])]
        assert np.unique(P._components_of(io._make(pts, faces, "x"))[1][:10]).size == 2
    if clockwise:
        faces = faces[:, ::-1]
    tri = io._make(pts, faces, "pieces")
    assert tri.all_clockwise == clockwise
    he, pe = P.run(tri, structure="halfedge"), P.run(tri, structure="pemb")
    for k in ("polygons", "barrier_edge_tips", "repaired_polygons", "regions", "frontier_edges",
              "vertices", "triangles"):
        assert he[k] == pe[k], k
    s = P.build_structure(tri)
    ref = P.polylla(s, tri.points, corners=tri.input_faces, clockwise=clockwise)
    with pytest.raises(errors.UnsupportedTopologyError, match="2 components"):
        P.build_structure(tri, "pemb")
    out = P._run_by_component(tri, P._components_of(tri), "pemb", check=True, tables=True)[0]
    np.testing.assert_array_equal(out.offsets, ref.offsets)
    np.testing.assert_array_equal(out.indices, ref.indices)


@pytest.mark.parametrize("structure", ["lr", "lr-bits"])
def test_a_piece_the_structure_refuses_is_named(structure):
    """LR needs a ring of at least 4 vertices: a lone triangle beside a larger piece is refused
    with the piece named by its input triangle, not only the ring's own message."""
    a = random_tri(0, 40)
    lone = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]) + [5.0, 5.0]
    pts = np.concatenate([a.points, lone])
    faces = np.concatenate([a.faces, [[a.num_vertices, a.num_vertices + 1, a.num_vertices + 2]]])
    tri = io._make(pts, faces, "pieces")
    with pytest.raises(errors.UnsupportedTopologyError,
                       match=rf"connected piece 1 of 2 \(input triangle\(s\) {a.num_faces}; 1 in all\)"
                             r".*3 vertices"):
        P.run(tri, structure=structure)


def test_corners_are_checked():
    tri = random_tri(0)
    s = P.build_structure(tri)
    for bad, match in [(tri.faces[:5], r"must be \(\d+, 3\)"), (tri.faces + 10**6, "outside"),
                       (tri.faces.astype(float), "integer")]:
        with pytest.raises(errors.PolyllaError, match=match):
            P.polylla(s, tri.points, corners=bad)
    # "no" read as True (clockwise polygons), an array as an untyped ValueError
    for bad in ("no", np.array([True, False]), 1):
        with pytest.raises(errors.PolyllaError, match="clockwise must be True, False or None"):
            P.polylla(s, tri.points, corners=tri.faces, clockwise=bad)
    # reference mode needs the rows to be the structure's triangles (any order)
    other = random_tri(1)
    with pytest.raises(errors.PolyllaError, match="corners are not the triangles"):
        P.polylla(s, tri.points, corners=other.faces[: tri.num_faces] % tri.num_vertices)
    with pytest.raises(errors.PolyllaError, match="unknown Polylla mode 'fast'"):
        P.polylla(s, tri.points, corners=tri.faces, mode="fast")
    # the rows listed in another order are matched to the faces: same polygons, listed as the
    # reference would list that input
    perm = np.random.default_rng(0).permutation(tri.num_faces)
    got = P.polylla(s, tri.points, corners=tri.faces[perm])
    exact, _, _ = reference_polylla(tri.points, tri.faces[perm], exact=True)
    assert got.polygons() == exact
    # without corners, reference mode reads the structure's own faces as the rows
    assert P.polylla(s, tri.points, mode="reference").polygons() == \
        reference_polylla(tri.points, tri.faces, exact=True)[0]


def test_positions_are_checked():
    """Bad positions are a PolyllaError on the host before any work, naming the shape, dtype or
    the first vertex with a NaN / inf (a NaN length had run silently and returned polygons; 1-d
    positions had been an IndexError inside)."""
    tri = random_tri(0)
    s = P.build_structure(tri)
    v = tri.num_vertices
    nan, inf = tri.points.copy(), tri.points.copy()
    nan[7, 1], nan[9, 0] = np.nan, np.nan
    inf[3, 0] = -np.inf
    for bad, match in [
            (nan, r"vertex 7 has a non-finite coordinate \[.*, nan\]"),
            (inf, r"vertex 3 has a non-finite coordinate \[-inf, "),
            (tri.points.ravel(), rf"must be \({v}, 2\) or \({v}, 3\).*got shape \({2 * v},\)"),
            (np.zeros((v, 4)), rf"got shape \({v}, 4\)"),
            (tri.points[:, :1], rf"got shape \({v}, 1\)"),
            (np.zeros((v, 2, 1)), rf"got shape \({v}, 2, 1\)"),
            (tri.points[:-1], rf"{v - 1} positions for a structure of {v} vertices"),
            (tri.points.astype(complex), "real numbers, got dtype complex128"),
            (tri.points.astype(str), "real numbers, got dtype <U"),
            (tri.points > 0.5, "real numbers, got dtype bool"),
            (None, "real numbers, got dtype object"),
            ([[0.0, 1.0], [1.0]], "not an array of numbers")]:
        with pytest.raises(errors.PolyllaError, match=match):
            P.polylla(s, bad, corners=tri.faces)
    # (V, 3): z is ignored, same polygons as (V, 2)
    got = P.polylla(s, np.column_stack([tri.points, np.ones(v)]), corners=tri.faces)
    assert got.polygons() == P.polylla(s, tri.points, corners=tri.faces).polygons()


def test_phases_same_without_jit():
    tri = grid(3)
    tri = io.Triangulation2D(tri.points + 0.01 * np.random.default_rng(0).random(tri.points.shape),
                             tri.faces)  # jittered: unequal edges, a non-trivial labelling
    a = run_on(tri)
    with jax.disable_jit():
        b = run_on(tri)
    np.testing.assert_array_equal(a.indices, b.indices)
    np.testing.assert_array_equal(a.offsets, b.offsets)


def test_label_phase_definitions():
    """Every triangle has exactly one longest edge; frontier is symmetric; seeds = regions."""
    tri = random_tri(0)
    s = P.build_structure(tri)
    with jax.enable_x64(True):
        mx, fr, sd = (np.asarray(x) for x in P.label_phase(
            s, jax.numpy.asarray(tri.points), jax.numpy.arange(s.num_vertices, dtype=np.int32)))
    inner = np.arange(s.num_darts) < 3 * s.num_faces
    assert np.all(mx[: 3 * s.num_faces].reshape(-1, 3).sum(axis=1) == 1)
    tw = np.asarray(s.opposite)
    np.testing.assert_array_equal(fr, fr[tw])
    assert not np.any(mx & fr & ~np.asarray(s.is_border(tw)))
    assert np.all(inner[sd])
    mesh = P.polylla(s, tri.points)
    assert mesh.regions == int(sd.sum())


# ------------------------------------------------------------------------ file to file, errors
def test_run_writes_off_and_reports(tmp_path):
    out = tmp_path / "p.off"
    d = P.run(str(POLYLLA / "points50.1.node") if (POLYLLA / "points50.1.node").exists()
              else pytest.skip("no points50"), str(out))
    for key in ("polygons", "barrier_edge_tips", "repaired_polygons", "vertices", "triangles"):
        assert key in d
    assert (d["polygons"], d["vertices"], d["triangles"]) == (17, 50, 83)
    json.dumps(d)
    pts, polys = io.read_polygon_off(str(out))
    assert pts.shape == (50, 2) and len(polys) == 17
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".")]  # no temporary left


def test_run_on_point_file(tmp_path):
    tri = random_tri(0)
    xy = tmp_path / "pts.xy"
    np.savetxt(xy, tri.points, fmt="%.17g")
    d = P.run(str(xy), str(tmp_path / "o.off"))
    assert (d["vertices"], d["polygons"]) == (400, run_on(tri).num_polygons)


@pytest.mark.parametrize("sep", ["\v", "\f", "\x1c", "\x85", "\u2028"])
def test_point_list_lines_end_at_line_ends_only(sep, tmp_path):
    """str.splitlines ended a line at a vertical tab, a form feed and other separators:
    "0.5 0.9<VT>0.3 0.3" read as two points (fuzzing, sweep 54b). Inside a line they are
    blanks, as load_mesh reads them; CR and CRLF still end lines."""
    xy = tmp_path / "pts.xy"
    xy.write_text(f"0 0\r\n1 0\r2 0.5{sep}9 9\n0 1\n", encoding="utf-8")
    np.testing.assert_array_equal(io.read_input(str(xy)).points, [[0, 0], [1, 0], [2, 0.5], [0, 1]])


@pytest.mark.parametrize("content, match", [
    ("", "empty"),
    ("3 2 0 0\n0 0 0\n1 1 0\n", "only 2"),
    ("3 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n", "dimension 3"),
    ("3 2 0 0\n0 0 0\n1 1 0\n5 0 1\n", "consecutively"),
])
def test_bad_node_files(tmp_path, content, match):
    (tmp_path / "a.node").write_text(content)
    (tmp_path / "a.ele").write_text("1 3 0\n0 0 1 2\n")
    with pytest.raises(errors.PolyllaError, match=match):
        io.read_triangle(str(tmp_path / "a.node"))


def test_bad_ele_and_neigh(tmp_path):
    (tmp_path / "a.node").write_text("4 2 0 0\n0 0 0\n1 1 0\n2 1 1\n3 0 1\n")
    (tmp_path / "a.ele").write_text("2 3 0\n0 0 1 2\n1 0 2 9\n")
    with pytest.raises(errors.PolyllaError, match="triangle 1 refers to vertex 9"):
        io.read_triangle(str(tmp_path / "a.node"))
    (tmp_path / "a.ele").write_text("2 3 0\n0 0 1 2\n1 0 2 3\n")
    (tmp_path / "a.neigh").write_text("2 3\n0 -1 -1 -1\n1 0 -1 -1\n")
    with pytest.raises(errors.PolyllaError, match="triangle 1 lists triangle 0 as neighbour 0"):
        io.read_triangle(str(tmp_path / "a.node"))
    (tmp_path / "a.neigh").write_text("2 3\n0 -1 1 -1\n1 -1 -1 0\n")
    assert io.read_triangle(str(tmp_path / "a.node")).num_faces == 2


def test_regular_triangle_files_are_read_in_one_pass(tmp_path, monkeypatch):
    """A regular .node / .ele / .neigh (no comment, every line its header's field count) is
    parsed by numpy in one pass (6.3 s -> 1.3 s for a 1M-triangle input, stop 52), giving the
    line-by-line reader's triangulation bit for bit: ids from 1, attributes and markers, a
    second-order .ele. A file with a comment or a short line goes line by line, as before."""
    rng = np.random.default_rng(7)
    pts = rng.uniform(-1, 1, (40, 2))
    pts[0] = [0.1, 1e-300]  # digits the parsers must round alike
    tri = io.from_points(pts)
    F, V = tri.num_faces, tri.num_vertices
    node = "\n".join([f"{V} 2 1 1"] + [f"{i + 1} {x!r} {y!r} 0.5 {i % 2}"
                                         for i, (x, y) in enumerate(tri.points.tolist())])
    mid = rng.integers(1, V + 1, (F, 3))  # second-order rows: 3 corners, then 3 midpoints
    ele = "\n".join([f"{F} 6 0"] + [f"{t + 1} {a + 1} {b + 1} {c + 1} {m[0]} {m[1]} {m[2]}"
                                      for t, ((a, b, c), m) in enumerate(zip(tri.faces.tolist(), mid.tolist()))])
    (tmp_path / "r.node").write_text(node + "\n\n")
    (tmp_path / "r.ele").write_text(ele + "\n")
    read_by_lines = []
    real_rows = io._rows
    monkeypatch.setattr(io, "_rows",
                        lambda path, *text: read_by_lines.append(path) or real_rows(path, *text))
    fast = io.read_triangle(str(tmp_path / "r.node"))
    assert read_by_lines == []
    monkeypatch.setattr(io, "_regular_table", lambda *a: None)
    slow = io.read_triangle(str(tmp_path / "r.node"))
    assert len(read_by_lines) == 2
    assert np.array_equal(fast.points, slow.points) and np.array_equal(fast.faces, slow.faces)
    assert fast.points[0].tolist() == [0.1, 1e-300] and fast.faces.dtype == np.int32
    monkeypatch.undo()
    lines = node.split("\n")
    # a comment; a line one field short (its marker): not taken in one pass, read line by line
    # (which takes the first three fields of each line), the same triangulation
    for broken in (lines[:3] + ["# a comment"] + lines[3:],
                   lines[:5] + [lines[5].rsplit(" ", 1)[0]] + lines[6:]):
        (tmp_path / "r.node").write_text("\n".join(broken))
        assert io._regular_table(io._text(str(tmp_path / "r.node")), lambda h: 5) is None
        assert np.array_equal(io.read_triangle(str(tmp_path / "r.node")).points, slow.points)


@pytest.mark.parametrize("neigh,match", [
    ("2 3\n0 -1 -1 -1\n1 -1 -1 -1\n", r"triangle 0 lists no neighbour \(-1\) as neighbour 1, "
     r"but triangle 1 shares that edge \(2, 0\)"),
    ("2 3\n0 -1 1 -1\n1 -1 -1 -1\n", r"triangle 1 lists no neighbour \(-1\) as neighbour 2, "
     r"but triangle 0 shares that edge \(0, 2\)"),
])
def test_neigh_with_a_border_where_triangles_meet_is_refused(tmp_path, neigh, match):
    """Sweep 52b: a .neigh listing -1 across an edge that two triangles share passed its check;
    the reference, which trusts the file, cuts the domain there (a gmsh plate with six such
    edges gave it 69 polygons against our 66), so the run differed without a word."""
    (tmp_path / "a.node").write_text(_NODE4)
    (tmp_path / "a.ele").write_text("2 3 0\n0 0 1 2\n1 0 2 3\n")
    (tmp_path / "a.neigh").write_text(neigh)
    with pytest.raises(errors.PolyllaError, match=match):
        P.run(str(tmp_path / "a.node"))


def test_bad_inputs(tmp_path):
    with pytest.raises(errors.PolyllaError, match="no such file"):
        P.run(str(tmp_path / "missing.off"))
    quad = tmp_path / "q.off"
    quad.write_text("OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n")
    with pytest.raises(errors.PolyllaError, match="face 0 has 4 vertices"):
        P.run(str(quad))
    flat = tmp_path / "f.off"
    flat.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n2 0 0\n3 0 1 2\n")
    with pytest.raises(errors.PolyllaError, match="triangle 0 .* zero area"):
        P.run(str(flat))
    with pytest.raises(errors.PolyllaError, match="collinear|Delaunay|at least 3"):
        P.run(np.array([[0.0, 0.0], [1.0, 1.0]]))
    with pytest.raises(errors.PolyllaError, match="unknown Polylla input"):
        P.run(str(tmp_path / "x.stl"))
    # three triangles on one edge: refused by validation, naming the edge
    nm = tmp_path / "nm.off"
    nm.write_text("OFF\n5 3 0\n0 0 0\n1 0 0\n0.5 1 0\n0.5 -1 0\n0.5 2 0\n"
                  "3 0 1 2\n3 1 0 3\n3 0 1 4\n")
    with pytest.raises(errors.MeshError, match="edge"):
        P.run(str(nm))


_SQUARE = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n"


@pytest.mark.parametrize("name,content,match", [
    # the fifth sweep: each of these was a traceback (ValueError, OverflowError) or no line named
    ("short.off", "OFF\n4 2 0\n" + _SQUARE + "3 0 1 2\n3 1 3\n", r"face 1 lists 2 of its 3 vertices"),
    ("big.off", "OFF\n4 2 0\n" + _SQUARE + "3 0 1 2\n3 1 3 99999999999999999999999\n",
     r"face 1 .* outside \[0, 4\)"),
    ("v.off", "OFF\n4 2 0\n0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n", r"vertex 0 has 1 coordinate"),
    ("ragged.xy", "0 0\n1\n1 1\n0 1\n", r"point 1 has 1 coordinate"),
])
def test_bad_off_and_point_lines_are_named(tmp_path, name, content, match):
    (tmp_path / name).write_text(content)
    with pytest.raises(errors.PolyllaError, match=match):
        P.run(str(tmp_path / name))


def test_off_counts_on_the_keyword_line_and_bom(tmp_path):
    """``OFF 4 2 0`` (counts on the keyword's line, which load_mesh reads) was read with the
    first vertex as the counts: 3 vertices, 1 triangle, exit 0. A UTF-8 BOM before a ``.node``
    header was refused as a non-integer count."""
    off = tmp_path / "sq.off"
    off.write_text("OFF 4 2 0\n" + _SQUARE + "3 0 1 2\n3 0 2 3\n")
    d = P.run(str(off))
    assert (d["vertices"], d["triangles"], d["polygons"]) == (4, 2, 1)
    (tmp_path / "b.node").write_bytes(b"\xef\xbb\xbf4 2 0 0\n0 0 0\n1 1 0\n2 1 1\n3 0 1\n")
    (tmp_path / "b.ele").write_text("2 3 0\n0 0 1 2\n1 0 2 3\n")
    assert P.run(str(tmp_path / "b.node"))["triangles"] == 2


def test_inputs_that_are_not_files_are_refused(tmp_path):
    """A directory was reported as an *output* error; a FIFO blocked forever and /dev/zero filled
    memory. A .neigh naming a triangle as its own neighbour passed its check."""
    (tmp_path / "d.off").mkdir()
    with pytest.raises(errors.PolyllaError, match="d.off: is a directory"):
        P.run(str(tmp_path / "d.off"))
    os.mkfifo(tmp_path / "fifo.xy")
    with pytest.raises(errors.PolyllaError, match="not a regular file"):
        P.run(str(tmp_path / "fifo.xy"))
    os.symlink("/dev/zero", tmp_path / "zero.npy")
    with pytest.raises(errors.PolyllaError, match="not a regular file"):
        P.run(str(tmp_path / "zero.npy"))
    (tmp_path / "s.node").write_text(_NODE4)
    (tmp_path / "s.ele").write_text("2 3 0\n0 0 1 2\n1 0 2 3\n")
    (tmp_path / "s.neigh").write_text("2 3\n0 0 -1 -1\n1 -1 -1 1\n")
    with pytest.raises(errors.PolyllaError, match="triangle 0 lists itself"):
        P.run(str(tmp_path / "s.node"))


@pytest.mark.parametrize("points,match", [
    (np.array([["a", "b"], ["c", "d"], ["e", "f"]]), "real numbers"),
    (np.zeros(3, dtype=[("x", "f8"), ("y", "f8")]), "real numbers"),
    (np.array([[0, 0], [1, 0], [0, 1j]]), "real numbers"),
])
def test_point_arrays_of_other_kinds_are_refused(points, match):
    with pytest.raises(errors.PolyllaError, match=match):
        io.from_points(points)


@pytest.mark.parametrize("scale", [1e300, 1e-300, 1e-310])
def test_point_sets_at_extreme_scales_triangulate(scale):
    """Qhull refused the same five points at 1e300, 1e-300 and subnormal 1e-310 ("can not scale
    last coordinate"); points near 1e308 failed inside the collinearity diagnosis (LinAlgError)."""
    pts = np.array([(0, 0), (1, 0), (0, 1), (1, 1), (0.5, 0.3)])
    assert P.run(pts * scale)["polygons"] == P.run(pts)["polygons"]
    with pytest.raises(errors.PolyllaError, match="one line"):
        io.from_points(np.array([[0, 0], [1e308, 1e308], [-1e308, -1e308]]))


def test_cw_input_triangles_are_reoriented():
    tri = grid(4)
    flipped = io.Triangulation2D(tri.points, tri.faces[:, ::-1].copy())
    again = io._make(flipped.points, flipped.faces, "flipped")
    assert again.flipped == tri.num_faces
    a, b = run_on(tri), run_on(again)
    np.testing.assert_array_equal(a.indices, b.indices)


def test_off_roundtrip(tmp_path):
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [2, 0.5]], float)
    off = np.array([0, 4, 7])
    idx = np.array([0, 1, 2, 3, 1, 4, 2])
    io.write_polygon_off(str(tmp_path / "p.off"), pts, off, idx)
    p2, polys = io.read_polygon_off(str(tmp_path / "p.off"))
    np.testing.assert_array_equal(p2, pts)
    assert polys == [[0, 1, 2, 3], [1, 4, 2]]


@pytest.mark.slow
def test_random_50k_invariants():
    rng = np.random.default_rng(42)
    tri = io.from_points(rng.random((50_000, 2)))
    mesh = run_on(tri)
    check_partition(tri, mesh)
    assert 0.28 < mesh.num_polygons / tri.num_vertices < 0.36  # reference: 322,520 / 1M


def test_qhull_slivers_keep_qhull_orientation():
    """A 30 x 30 grid moved by < 1e-13: Qhull's slivers along the nearly straight hull have
    floating-point areas of the wrong sign (16 of 1,712 here). Orienting them by that sign made
    validation blame the input ("orient faces consistently"); Qhull's own counter-clockwise
    order is kept now, and the polygons tile the domain."""
    rng = np.random.default_rng(5)
    g = np.stack(np.meshgrid(np.arange(30.0), np.arange(30.0)), -1).reshape(-1, 2)
    tri = io.from_points(g + 1e-13 * rng.random(g.shape))
    # since stop 54 Qhull's triangles are mended exactly (from_points): every one is exactly
    # counter-clockwise, whatever its floating-point area says
    assert (io.orientation_signs(tri.points, tri.faces) > 0).all() and tri.flipped == 0
    check_partition(tri, run_on(tri), slack=1e-9)


def test_points_far_from_the_origin_are_all_triangulated():
    """Georeferenced-like coordinates (offset 1e10, spread 1e3): Qhull's paraboloid lost the
    digits that tell them apart and dropped points ("point 0 is a duplicate"); centred first,
    every point is in a triangle and the polygons tile the domain."""
    pts = 1e10 + np.random.default_rng(5).random((200, 2)) * 1e3
    tri = io.from_points(pts)
    assert np.unique(tri.faces).size == 200
    mesh = run_on(tri)
    # areas measured near the origin (at 1e10, x * y has no digits left for them)
    check_partition(io.Triangulation2D(points=pts - 1e10, faces=tri.faces, source="shifted"), mesh)


def test_collinear_points_are_named_in_one_line():
    """Qhull's 50-line diagnostic for a flat point set becomes one line naming the cause."""
    for pts in (np.array([[0, 0], [1, 1], [2, 2], [3, 3]], float),
                np.zeros((5, 2)) + 7.0):
        with pytest.raises(errors.PolyllaError, match="every point lies on one line") as exc:
            io.from_points(pts, "flat")
        assert "\n" not in str(exc.value)


def exact_delaunay_faults(pts: np.ndarray, faces: np.ndarray) -> list:
    """What keeps ``faces`` from being the exact Delaunay triangulation of the distinct points
    of ``pts`` (empty: nothing), decided in rational arithmetic on the float64 coordinates:
    a triangle not strictly counter-clockwise, a distinct point in no triangle (or a later
    copy of one in a triangle), a border edge with a point strictly right of it (the border is
    not the convex hull), an interior edge whose opposite corner is strictly inside the circle."""
    from fractions import Fraction

    p = [(Fraction(x), Fraction(y)) for x, y in np.asarray(pts, float).tolist()]

    def orient(a, b, c):
        (ax, ay), (bx, by), (cx, cy) = p[a], p[b], p[c]
        return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)

    def incircle(a, b, c, d):
        (dx, dy) = p[d]
        r = [(x - dx, y - dy) for x, y in (p[a], p[b], p[c])]
        (ax, ay), (bx, by), (cx, cy) = r
        return ((ax * ax + ay * ay) * (bx * cy - cx * by) + (bx * bx + by * by) * (cx * ay - ax * cy)
                + (cx * cx + cy * cy) * (ax * by - bx * ay))

    faults = [f"triangle {f} is not counter-clockwise" for f in faces.tolist() if orient(*f) <= 0]
    first = {}
    for i, xy in enumerate(p):
        first.setdefault(xy, i)
    used = set(faces.ravel().tolist())
    faults += [f"point {i} is a first copy in no triangle" for i, xy in enumerate(p)
               if first[xy] == i and i not in used]
    faults += [f"point {i} repeats point {first[xy]} and is in a triangle" for i, xy in enumerate(p)
               if first[xy] != i and i in used]
    apex = {}
    for a, b, c in faces.tolist():
        apex.update({(a, b): c, (b, c): a, (c, a): b})
    for (a, b), c in apex.items():
        if (b, a) not in apex:
            faults += [f"point {x} is outside border edge {(a, b)}" for x in used if orient(a, b, x) < 0]
        elif a < b and incircle(c, a, b, apex[(b, a)]) > 0:
            faults.append(f"edge {(a, b)} is not locally Delaunay")
    return faults


def sorted_triangles(faces) -> list:
    f = np.sort(np.asarray(faces), axis=1)
    return f[np.lexsort(f.T[::-1])].tolist()


# Small point sets (real-world: projections of Debian's sweethome3d-furniture models, reduced;
# and a 10 x 10 grid moved by 1e-12) where Qhull's triangulation is not Triangle's; the expected
# triangles are Triangle's (Shewchuk's, exact predicates; no four of these points are cocircular,
# so the Delaunay triangulation is unique)
QHULL_CASES = {
    # Qhull merged point 4 with point 1 (1.1e-5 apart, 2e-8 of the extent): in no triangle
    "merged": ([[1.15618, -2.627288], [1.15618, -24.417175], [1.156169, -24.417175],
                [-28.490551, -68.059509], [1.156179, -24.417175]],
               [[0, 1, 4], [0, 2, 3], [0, 2, 4], [1, 3, 4], [2, 3, 4]]),
    # Qhull's Qt made a triangle of three exactly collinear points (zero area)
    "zero-area": ([[1.971326, -39.437103], [1.97133, 38.916229], [1.97133, 38.916218],
                   [73.565849, 40.34145], [1.97133, 40.34145], [1.97133, 40.341457]],
                  [[0, 1, 2], [0, 1, 4], [0, 2, 3], [0, 4, 5], [1, 2, 3], [1, 3, 4], [3, 4, 5]]),
    # Qhull output an exactly clockwise sliver over nearly collinear points
    "inverted": ([[-72.431435, 33.223255], [-77.376282, 33.223255], [22.592625, 33.223263],
                  [22.118916, 32.384586], [23.06633, 32.384586], [22.592623, 33.223263]],
                 [[0, 1, 3], [0, 1, 5], [0, 3, 5], [2, 4, 5], [3, 4, 5]]),
    # a perturbed grid: Qhull kept a diagonal whose opposite corner is (just) inside the circle
    "not-delaunay": ([[6.000000000008586, 1.000000000003981], [7.000000000007696, 1.0000000000016918],
                      [0.9999999999943763, 2.000000000027925], [4.999999999999103, 1.9999999999974782],
                      [5.99999999999423, 1.9999999999893343], [7.00000000000506, 2.000000000008576]],
                     [[0, 1, 5], [0, 2, 3], [0, 3, 4], [0, 4, 5], [2, 3, 5], [3, 4, 5]]),
}


@pytest.mark.parametrize("case", sorted(QHULL_CASES))
def test_point_sets_get_the_exact_delaunay_triangulation(case, monkeypatch):
    """Qhull works in floating point: it merged near points (39 of 682 real-world sets were
    refused: "Qhull merged it with a point too near"), left zero-area and inverted triangles,
    and kept edges that are not Delaunay. Mended with exact predicates, the triangles are
    Triangle's, and exactly Delaunay; by the repairs of Qhull's output, not the slow build
    from scratch."""
    from jaxcds import _exact_delaunay

    def no_fallback(*args):
        raise AssertionError("built from scratch")

    monkeypatch.setattr(_exact_delaunay, "build_from_scratch", no_fallback)
    pts, expected = QHULL_CASES[case]
    pts = np.array(pts)
    tri = io.from_points(pts, case)
    assert exact_delaunay_faults(pts, tri.faces) == []
    assert sorted_triangles(tri.faces) == expected
    assert P.run(tri)["triangles"] == len(expected)


def test_point_sets_qhull_cannot_mend_are_built_from_scratch(monkeypatch):
    """Points 1e-15 off a line: Qhull inverts slivers again after its inverted triangles'
    corners are taken out, so the triangulation is built from scratch by exact insertion (the
    fallback); still exactly Delaunay."""
    from jaxcds import _exact_delaunay

    built = []
    scratch = _exact_delaunay.build_from_scratch
    monkeypatch.setattr(_exact_delaunay, "build_from_scratch", lambda *a: built.append(1) or scratch(*a))
    r = np.random.default_rng(12)
    t = r.random(int(r.integers(3, 50)))
    line = np.c_[t, 0.3 * t + 0.1] + r.integers(-1, 2, (t.size, 2)) * 1e-15
    pts = np.vstack([line, [[0.5, 2.0]]])
    tri = io.from_points(pts, "near-line")
    assert built and exact_delaunay_faults(pts, tri.faces) == []


def test_a_qhull_mesh_that_does_not_close_falls_back_and_a_lost_build_is_typed(monkeypatch):
    """Qhull's neighbours that do not describe one mesh (a walk around a corner that never
    ends) send the build from scratch, not a hang or a bare exception; should that build itself
    lose its mesh, a PolyllaError says so (never seen)."""
    from jaxcds import _exact_delaunay

    def broken(*args):
        raise _exact_delaunay._Broken

    pts = np.random.default_rng(2).random((30, 2))
    monkeypatch.setattr(_exact_delaunay, "repair", broken)
    assert exact_delaunay_faults(pts, io.from_points(pts).faces) == []
    monkeypatch.setattr(_exact_delaunay, "build_from_scratch", broken)
    with pytest.raises(errors.PolyllaError, match="pts: Delaunay triangulation failed: the exact "
                       "build lost its mesh"):
        io.from_points(pts, "pts")


def test_points_qhull_merges_are_all_triangulated():
    """Sweep 47: three clusters 1e-6 wide in a unit domain lost points to Qhull's precision
    (refused since: "Qhull merged it with a point too near"). Each is inserted now, exactly."""
    rng = np.random.default_rng(5)
    clusters = np.vstack([c + 1e-6 * rng.random((80, 2)) for c in ([0, 0], [1, 0], [0.5, 1])])
    tri = io.from_points(clusters, "clusters")
    assert np.unique(tri.faces).size == 240
    assert exact_delaunay_faults(clusters, tri.faces) == []
    check_partition(tri, run_on(tri), slack=1e-9)


def test_exact_duplicates_are_left_out_with_a_warning():
    """A point repeating an earlier one was refused ("remove duplicates"); Triangle, Polylla's
    own triangulator, leaves it in no triangle with a warning. So does jaxcds now: the first
    copy is used, ids unchanged, a PolyllaWarning names how many and the first pair, and the
    run's report counts them."""
    rng = np.random.default_rng(5)
    base = rng.random((30, 2))
    dup = np.vstack([base, [[0.25, 0.75], [0.25, 0.75]]])
    with pytest.warns(errors.PolyllaWarning, match=r"dup: 1 of the 32 points repeat an earlier "
                      r"point and are left in no triangle.*\(point 31 repeats point 30 \[0.25, 0.75\]\)"):
        tri = io.from_points(dup, "dup")
    assert exact_delaunay_faults(dup, tri.faces) == []
    assert 31 not in tri.faces and tri.duplicates == 1
    alone = io.from_points(dup[:31], "alone")
    assert sorted_triangles(tri.faces) == sorted_triangles(alone.faces)
    many = np.vstack([dup, dup[:5], [[0.25, 0.75]]])
    with pytest.warns(errors.PolyllaWarning, match=r"7 of the 38 points .*point 31 repeats point 30 "):
        tri = io.from_points(many, "many")
    assert sorted_triangles(tri.faces) == sorted_triangles(alone.faces)
    with pytest.warns(errors.PolyllaWarning):
        rep = P.run(many)
    assert rep["duplicate_points"] == 7 and "7 of the 38 points" in rep["notes"][0]
    assert rep["vertices"] == 38


@pytest.mark.parametrize("structure", io.BORDER_STRUCTURES)
def test_duplicates_run_on_every_structure(structure, tmp_path):
    """The later copies are vertices in no triangle: run() meshes around them on every
    structure, with the half-edge's polygons."""
    rng = np.random.default_rng(7)
    base = rng.random((40, 2))
    pts = np.vstack([base, base[[3, 9, 3]]])
    with pytest.warns(errors.PolyllaWarning):
        tri = io.from_points(pts)
    polygons = {}
    for s in ("halfedge", structure):
        P.run(tri, str(tmp_path / f"{s}.off"), structure=s)
        polygons[s] = P.polygons_as_cycles(io.read_polygon_off(str(tmp_path / f"{s}.off"))[1])
    assert polygons[structure] == polygons["halfedge"]


@pytest.mark.parametrize("pts", [
    np.stack(np.meshgrid(np.arange(6.0), np.arange(5.0)), -1).reshape(-1, 2),
    np.array([(5, 0), (-5, 0), (0, 5), (0, -5), (3, 4), (-3, 4), (3, -4), (-3, -4), (4, 3),
              (-4, 3), (4, -3), (-4, -3)], float),
    np.array([(5, 0), (-5, 0), (0, 5), (0, -5), (3, 4), (-3, 4), (3, -4), (-3, -4), (0, 0)], float),
], ids=["grid", "circle", "circle-centre"])
def test_exactly_cocircular_points_keep_a_delaunay_diagonal(pts):
    """Exactly cocircular quadruples: either diagonal is Delaunay (Qhull's is kept); every
    edge is still exactly legal, and the count is any triangulation's, 2n - h - 2."""
    tri = io.from_points(pts)
    assert exact_delaunay_faults(pts, tri.faces) == []
    darts = {(a, b) for f in tri.faces.tolist() for a, b in zip(f, f[1:] + f[:1])}
    border = {a for a, b in darts if (b, a) not in darts}  # collinear border points included
    assert tri.num_faces == 2 * pts.shape[0] - len(border) - 2


def test_z_order_walks_the_grid_cell_by_cell():
    """Qhull gets the points in Z order (``_exact_delaunay._qhull``, faster on points in random
    order): on a 4 x 4 grid the order is Morton's (x bits at even positions, y at odd), points
    of one cell keep their order, and a flat or one-point set is left as it is."""
    from jaxcds._exact_delaunay import z_order

    xy = np.stack(np.meshgrid(np.arange(4.0), np.arange(4.0)), -1).reshape(-1, 2)
    perm = np.random.default_rng(3).permutation(16)
    got = xy[perm][z_order(xy[perm])]
    morton = [sum(((int(x) >> b & 1) << 2 * b) | ((int(y) >> b & 1) << 2 * b + 1) for b in range(2))
              for x, y in got]
    assert morton == list(range(16))
    twice = np.repeat(xy[perm], 2, axis=0) + np.tile([[0.0, 0.0], [1e-9, 0.0]], (16, 1))
    order = z_order(twice)
    assert sorted(order.tolist()) == list(range(32))
    assert all(order[i] < order[i + 1] for i in range(0, 32, 2))  # a cell's two points, in order
    assert z_order(np.zeros((5, 2))).tolist() == list(range(5))
    assert z_order(np.ones((1, 2))).tolist() == [0]


def test_incircle_filter_flags_every_sign_it_gets_wrong():
    """The float in-circle filter (a numba loop since stop 55) on 3,000 nearly cocircular
    quadruples (a circle of radius 1e-3 off the origin, corners rounded to float64): about 8 of
    its float signs are wrong, and every one is flagged unsure (Shewchuk's bound), so the exact
    test decides it; every sign it does not flag is the exact one."""
    import jaxcds._exact_delaunay as ed

    theta = np.sort(np.random.default_rng(1).random((3000, 4)) * 2 * np.pi, axis=1)
    pts = (np.array([0.3, 0.2]) + 1e-3 * np.stack([np.cos(theta), np.sin(theta)], -1)).reshape(-1, 2)
    a, b, c, d = (np.arange(3000) * 4 + k for k in range(4))  # a, b, c counter-clockwise
    sign, unsure = ed.incircle_filter(ed.scaled(pts)[0], a, b, c, d)
    exact = np.array([ed.exact_incircle(pts, a[i], b[i], c[i], d[i]) for i in range(3000)])
    assert (sign != exact).sum() >= 3  # the float evaluation does go wrong here
    assert not ((sign != exact) & ~unsure).any()
    assert unsure.sum() < 1000  # and the filter decides most of them itself


@pytest.mark.parametrize("scale", [1e-160, 1e160, 1e300])
def test_points50_at_extreme_coordinate_scales(scale, tmp_path):
    """Polylla does not depend on the scale: squared lengths overflowed (1e160) or fell into
    subnormals (1e-160) and ties gave 28 polygons instead of 17; now such coordinates are
    scaled by a power of two first (exact; polylla_io.length_scale). Through the files too,
    without overflow warnings."""
    import warnings

    tri = io.read_triangle(_need(POLYLLA / "points50.1.node"))
    _, ref = io.read_polygon_off(_need(POLYLLA / "points50.1.off"))
    scaled = io.Triangulation2D(points=tri.points * scale, faces=tri.faces, source="scaled", flipped=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mesh = run_on(scaled)
        assert P.polygons_as_cycles(mesh.polygons()) == P.polygons_as_cycles(ref)
        node = tmp_path / "big.node"
        with open(node, "w") as fh:
            fh.write(f"{tri.num_vertices} 2 0 0\n")
            for i, (x, y) in enumerate(tri.points * scale):
                fh.write(f"{i} {float(x)!r} {float(y)!r}\n")
        ele = tmp_path / "big.ele"
        with open(ele, "w") as fh:
            fh.write(f"{tri.num_faces} 3 0\n")
            for i, f in enumerate(tri.faces):
                fh.write(f"{i} {f[0]} {f[1]} {f[2]}\n")
        assert P.run(str(node))["polygons"] == 17


_NODE4 = "4 2 0 0\n0 0 0\n1 1 0\n2 1 1\n3 0 1\n"


@pytest.mark.parametrize("node,ele,match", [
    # an .ele index past int64 escaped as an OverflowError traceback
    (_NODE4, "2 3 0\n0 0 1 2\n1 0 99999999999999999999 3\n",
     r"a.ele: triangle 1 \(1 0 99999999999999999999 3\)"),
    # a float vertex id was truncated
    ("4 2 0 0\n0 0 0\n1.5 1 0\n2 1 1\n3 0 1\n", "2 3 0\n0 0 1 2\n1 0 2 3\n", "vertex 1 has id 1.5"),
    # rows past the header's count were ignored
    (_NODE4, "1 3 0\n0 0 1 2\n1 0 2 3\n", "announces 1 triangles but 2 rows follow"),
    # the plural of vertex (it read "vertexs")
    ("5 2 0 0\n0 0 0\n1 1 0\n2 1 1\n3 0 1\n", "1 3 0\n0 0 1 2\n", "announces 5 vertices but only 4"),
    # a header of 6 nodes per triangle (second order) over rows of 3 was accepted
    (_NODE4, "2 6 0\n0 0 1 2\n1 0 2 3\n", "triangle 0 has 4 fields, expected at least 7"),
])
def test_triangle_files_with_huge_indices_float_ids_or_extra_rows(tmp_path, node, ele, match):
    (tmp_path / "a.node").write_text(node)
    (tmp_path / "a.ele").write_text(ele)
    with pytest.raises(errors.PolyllaError, match=match):
        io.read_triangle(str(tmp_path / "a.node"))


def test_a_point_in_no_triangle_on_pemb_gives_a_polylla_hint():
    """load_mesh's hint ("load_mesh drops them") does not apply to a Polylla input."""
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]], float)
    tri = io.Triangulation2D(points=pts, faces=np.array([[0, 1, 2], [0, 2, 3]]), source="hole", flipped=0)
    with pytest.raises(errors.UnreferencedVertexError, match="vertex 4 is in no face.*halfedge") as exc:
        P.run(tri, structure="pemb")
    assert "load_mesh" not in str(exc.value)
    assert P.run(tri, structure="halfedge")["polygons"] >= 1


@pytest.mark.parametrize("structure", ["halfedge", "pemb"])
def test_overlapping_triangles_are_named_as_a_fold_not_an_orientation(tmp_path, structure):
    """Robustness sweep: two triangles on the same side of their shared edge (a misplaced
    point: (0.5, 0.5) instead of (3, 3)) were refused with "orient faces consistently", which
    the input cannot do (every triangle is oriented by its area). The message names the two
    triangles, the edge and the overlap; a hand-made clockwise Triangulation2D keeps the
    orientation message."""
    (tmp_path / "fold.node").write_text("4 2 0 0\n0 0 0\n1 2 0\n2 0 2\n3 0.5 0.5\n")
    (tmp_path / "fold.ele").write_text("2 3 0\n0 0 1 2\n1 1 2 3\n")
    with pytest.raises(errors.InconsistentOrientationError,
                       match=r"faces \[0, 1\] .* edge \(1, 2\) .* overlap: the triangulation folds") as exc:
        P.run(str(tmp_path / "fold.node"), structure=structure)
    assert "orient faces consistently" not in str(exc.value)
    pts = np.array([[0, 0], [2, 0], [0, 2], [2, 2]], float)
    hand = io.Triangulation2D(points=pts, faces=np.array([[0, 1, 2], [1, 2, 3]], np.int32))
    with pytest.raises(errors.InconsistentOrientationError, match="orient faces consistently"):
        P.run(hand, structure=structure)


# --------------------------------------------- reference outputs of inputs not in ../shared
REFERENCE_CASES = pathlib.Path(__file__).resolve().parents[1] / "data" / "polylla_reference"


def _reference_cases(pinched: bool) -> list:
    """The stored cases; ``pinch_*`` ones have a pinch vertex, which only :func:`P.run` takes."""
    return sorted(p.name for p in REFERENCE_CASES.iterdir()
                  if p.is_dir() and p.name.startswith("pinch_") == pinched)


@pytest.mark.parametrize("structure", STRUCTURES)
@pytest.mark.parametrize("case", _reference_cases(pinched=False))
def test_reference_mode_gives_the_compiled_references_file(case, structure):
    """Outputs of the compiled reference (tests/data/polylla_reference/README.md): reference
    mode gives its polygons in its order, each from its first vertex. ``mixedscale`` failed
    while lengths were taken on coordinates scaled to the unit box (a rhombus's squares fell
    into subnormals), ``reject_area`` while areas were tested in floating point only."""
    d = REFERENCE_CASES / case
    tri = io.read_triangle(str(d / "in.node"))
    _, ref = io.read_polygon_off(str(d / "reference.off"))
    got = P.polylla(P.build_structure(tri, structure), tri.points, corners=tri.input_faces)
    assert got.polygons() == [list(map(int, p)) for p in ref]
    if not tri.flipped:  # clockwise input: clockwise polygons, as the reference's
        # the reference's crossing-off of repaired pieces is incomplete: it can list a piece
        # twice (``gmsh_blob_flipped``), and so does reference mode; the others tile the domain
        polygons = got.polygons()
        distinct = [p for i, p in enumerate(polygons) if p not in polygons[:i]]
        check_partition(tri, types.SimpleNamespace(polygons=lambda: distinct))


@pytest.mark.parametrize("structure", STRUCTURES)
@pytest.mark.parametrize("case", _reference_cases(pinched=True))
def test_pinch_vertices_are_meshed_as_the_reference_meshes_them(case, structure, tmp_path):
    """Sweep 52b: a hole's corner on the outer border (a pinch vertex: two fans of triangles
    touch there) was refused ("vertex 1 joins 2 separate fans"), where Triangle and gmsh make
    such meshes and the reference meshes them. ``run`` now walks the fans apart (a copy of the
    point per fan) and gives the polygons back in the input's ids: the reference's file."""
    d = REFERENCE_CASES / case
    tri = io.read_triangle(str(d / "in.node"))
    with pytest.raises(errors.NonManifoldVertexError, match="separate fans"):
        P.build_structure(tri, structure)  # a structure still needs manifold vertices
    out = tmp_path / "out.off"
    got = P.run(str(d / "in"), str(out), structure=structure)
    _, ref = io.read_polygon_off(str(d / "reference.off"))
    _, polys = io.read_polygon_off(str(out))
    assert [list(map(int, p)) for p in polys] == [list(map(int, p)) for p in ref]
    assert got["vertices"] == tri.num_vertices and got["barrier_edge_tips"] == 1


def test_pieces_meeting_at_a_corner_are_meshed_apart(tmp_path):
    """Two squares that share one corner (a pinch between two pieces): one polygon each, in
    the input's ids, on the half-edge and on pemb (one run per connected piece)."""
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [2, 1], [2, 2], [1, 2]], float)
    faces = np.array([[0, 1, 2], [0, 2, 3], [2, 4, 5], [2, 5, 6]], np.int32)
    for structure in ("halfedge", "pemb"):
        out = tmp_path / f"{structure}.off"
        got = P.run(io.Triangulation2D(points=pts, faces=faces), str(out), structure=structure)
        _, polys = io.read_polygon_off(str(out))
        assert got["vertices"] == 7, (structure, got)
        assert sorted(sorted(map(int, p)) for p in polys) == [[0, 1, 2, 3], [2, 4, 5, 6]]


_NEAR_TIES_CHILD = r"""
import jax, jax.numpy as jnp, numpy as np
from jaxcds.algorithms import polylla as P
from jaxcds.structures.halfedge import HalfEdge

rng = np.random.default_rng(52)
n = 400
apex = rng.uniform(-1, 1, (n, 2))
r, th, dth = rng.uniform(0.1, 1, n), rng.uniform(0, 2 * np.pi, n), rng.uniform(0.05, 0.5, n)
p1 = apex + r[:, None] * np.column_stack([np.cos(th), np.sin(th)])
p2 = apex + r[:, None] * np.column_stack([np.cos(th + dth), np.sin(th + dth)])


def rounded_apart(a, b):  # numpy rounds each product: no contraction
    d = a - b
    return np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])


l01, l20 = rounded_apart(apex, p1), rounded_apart(p2, apex)  # the short base aside
s = HalfEdge.from_faces(np.array([[0, 1, 2]], np.int32), 3)  # one triangle: a short array
d = jnp.arange(s.num_darts, dtype=jnp.int32)
ends = np.stack([np.asarray(s.origin(d)), np.asarray(s.target(d))], axis=1)
wrong, tried = [], 0
for i in np.flatnonzero(l01 != l20):
    with jax.enable_x64(True):
        max_edge, _, _ = P.label_phase(s, jnp.asarray(np.stack([apex[i], p1[i], p2[i]])),
                                       jnp.arange(3, dtype=jnp.int32))
    got = set(ends[int(np.flatnonzero(np.asarray(max_edge))[0])].tolist())
    tried += 1
    if got != ({0, 1} if l01[i] > l20[i] else {0, 2}):
        wrong.append(int(i))
print(tried, wrong)
"""


def test_longest_edges_are_taken_on_squares_rounded_apart():
    """Two sides of a triangle within an ulp of each other: the longest is the reference's,
    ``sqrt(pow(dx, 2) + pow(dy, 2))`` with each square rounded. XLA:CPU fused a square into the
    sum (a fused multiply-add) in the scalar loop that runs a short array, and the label took
    the other side in 10 of these 199 near-isoceles triangles (sweep 52b: a polygon listed from
    another vertex than the reference's). Run in a child at XLA's default optimisation: this
    suite's -O0 (conftest) contracts nothing."""
    import subprocess
    import sys

    from conftest import ROOT

    flags = os.environ.get("XLA_FLAGS", "").replace("--xla_backend_optimization_level=0", "")
    env = dict(os.environ, PYTHONPATH=str(ROOT), XLA_FLAGS=flags)
    r = subprocess.run([sys.executable, "-c", _NEAR_TIES_CHILD], env=env, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.split() == ["199", "[]"], r.stdout


def test_orientation_signs_are_exact_on_slivers():
    """Near-collinear corners far from the origin, subnormal features next to huge ones: the
    floating-point determinant decides only where its error bound allows, the rest exactly."""
    from fractions import Fraction

    rng = np.random.default_rng(5)
    base = rng.uniform(-1, 1, (400, 1, 2)) * 10.0 ** rng.integers(-300, 300, (400, 1, 1))
    t = rng.uniform(0, 1, (400, 3, 1))
    d = rng.uniform(-1, 1, (400, 1, 2))
    pts = base + t * d * np.abs(base)  # three points on a line through base...
    pts[:, 2] += rng.choice([0.0, 1.0], (400, 1)) * np.spacing(pts[:, 2])  # ...one nudged by an ulp
    pts = pts.reshape(-1, 2)
    for k in (-1000, -500, 0, 500, 1000):  # exactly collinear, exact in binary at every scale
        line = np.ldexp(np.array([[3.0, 5.0], [4.0, 7.0], [6.0, 11.0]]), k)
        pts = np.concatenate([pts, line, line[[0, 2, 1]]])
    faces = np.arange(pts.shape[0]).reshape(-1, 3)
    got = io.orientation_signs(pts, faces)
    want = []
    for f in faces:
        (ax, ay), (bx, by), (cx, cy) = ((Fraction(float(x)), Fraction(float(y))) for x, y in pts[f])
        v = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        want.append((v > 0) - (v < 0))
    assert got.tolist() == want
    assert 0 in want and len(set(want)) == 3  # the sample has all three kinds


def test_length_scale_keeps_ordinary_coordinates_as_given():
    p = np.array([[1e-10, 3.0], [1e150, -2e150]])
    assert io.length_scale(p) is not None and np.array_equal(io.length_scale(p), p)
    for big in (1e160, 1e300, 1e-130, 1e-300):
        q = io.length_scale(np.array([[big, 0.0], [0.0, big / 3]]))
        lo, hi = io.LENGTH_EXPONENTS
        assert lo < np.frexp(np.max(np.abs(q)))[1] <= hi
        ratio = q / np.array([[big, 1.0], [1.0, big / 3]])
        assert ratio[0, 0] == ratio[1, 1] and np.frexp(ratio[0, 0])[0] == 0.5  # a power of two


_HAND_TRIANGLES = {  # a Triangulation2D's faces as a hand-made one may hold them
    "big-endian": lambda f: f.astype(">i4"),
    "float": lambda f: f.astype(np.float64),
    "uint16": lambda f: f.astype(np.uint16),
    "uint64": lambda f: f.astype(np.uint64),
    "int64": lambda f: f.astype(np.int64),
    "nested list": lambda f: f.tolist(),
}


def test_a_hand_made_triangulation_takes_any_integer_faces_and_real_points():
    """Sweep: a Triangulation2D made by hand with big-endian or float faces failed in Polylla's
    numba kernels (TypingError), unsigned ones with OverflowError, lists with AttributeError.
    They are native C-contiguous int32 / float64 now, with the same polygons."""
    tri = io.from_points(np.random.default_rng(3).random((40, 2)), source="pts")
    want = P.run(tri)
    again = io.Triangulation2D(points=tri.points, faces=tri.faces)
    assert again.points is tri.points and again.faces is tri.faces  # canonical: no copy
    points = {"big-endian": tri.points.astype(">f8"), "nested list": tri.points.tolist(),
              "z = 0": np.c_[tri.points, np.zeros(40)]}
    for kind, make in _HAND_TRIANGLES.items():
        for pk, pts in points.items():
            hand = io.Triangulation2D(points=pts, faces=make(tri.faces))
            assert hand.faces.dtype == np.int32 and hand.faces.dtype.isnative, (kind, pk)
            assert hand.points.dtype == np.float64 and hand.points.dtype.isnative, (kind, pk)
            np.testing.assert_array_equal(hand.faces, tri.faces)
            np.testing.assert_array_equal(hand.points, tri.points)
        got = P.run(hand)
        assert (got["polygons"], got["barrier_edge_tips"]) == (want["polygons"], want["barrier_edge_tips"]), kind
    assert P.run(io.Triangulation2D(tri.points, tri.faces.astype(">i4")), structure="pemb")["polygons"] == \
        P.run(tri, structure="pemb")["polygons"]


@pytest.mark.parametrize("points,faces,match", [
    (None, lambda f: np.where(f == 3, 0.5, f), r"arrays: triangle indices must be integers, got float64 \(triangle \d+ is"),
    (None, lambda f: f.astype(bool), "triangle indices must be integers, got bool"),
    (None, lambda f: np.where(f == 3, 2**32 + 3, f.astype(np.int64)), r"triangle \d+ refers to vertex 4294967299, outside \[0, 5\)"),
    (None, lambda f: np.where(f == 3, np.uint64(2**64 - 1), f.astype(np.uint64)).astype(np.uint64),
     "refers to vertex 18446744073709551615"),
    (None, lambda f: f[:, :2], r"triangles must have shape \(F, 3\), got \(4, 2\)"),
    (None, lambda f: [[0, 1, 2], [0, 1]], "triangles are not an array of vertex ids"),
    (lambda p: p.astype(complex), None, "points must be real numbers, got complex128"),
    (lambda p: p.astype(str), None, "points must be real numbers, got <U"),
    (lambda p: np.c_[p, np.ones(5)], None, r"points must have shape \(N, 2\), got \(5, 3\) with z = 1.0 at point 0"),
    (lambda p: p[:, :1], None, r"points must have shape \(N, 2\), got \(5, 1\)"),
], ids=["fraction", "bool", "int64>int32", "uint64>int64", "two-columns", "ragged", "complex",
        "strings", "z != 0", "one-column"])
def test_a_hand_made_triangulation_refuses_what_is_not_one(points, faces, match):
    tri = io.from_points(np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.4]], float))
    with pytest.raises(errors.PolyllaError, match=match):
        io.Triangulation2D(points=tri.points if points is None else points(tri.points),
                           faces=tri.faces if faces is None else faces(tri.faces))



def _square_triangulation():
    from jaxcds.generators import delaunay_square

    m = delaunay_square(30, 3)
    return m, io.Triangulation2D(points=m.vertices[:, :2], faces=m.faces.astype(np.int32), source="sq")


@pytest.mark.parametrize("structure", ["lr", "lr-bits"])
def test_laced_rings_give_the_half_edges_polygons(structure):
    """Sweep 16a, Polylla x registry: LR keeps borders (and renumbers vertices), so Polylla runs
    on it unchanged and gives the half-edge's polygons, in both modes (untested before)."""
    _, tri = _square_triangulation()
    he, s = P.build_structure(tri, "halfedge"), P.build_structure(tri, structure)
    for mode in ("reference", "canonical"):
        want = P.polylla(he, tri.points, corners=tri.input_faces, mode=mode)
        assert P.polylla(s, tri.points, corners=tri.input_faces, mode=mode).polygons() == want.polygons()


def test_structures_without_the_border_are_refused_by_name():
    """The CDS family closes the hole with a dummy vertex: Polylla on it was refused as "30
    positions for a structure of 31 vertices", and given the closed mesh's positions ran on the
    closed surface (polygons through the dummy); the corner table advised close_boundaries,
    which Polylla cannot use. Each is now refused naming the border (sweep 16a)."""
    from jaxcds.mesh import close_boundaries

    m, tri = _square_triangulation()
    with pytest.raises(errors.PolyllaError, match=r"border: this cds6n closed its holes \(1 dummy"):
        P.run(tri, structure="cds6n")
    s = registry.build("cds5n-o1", m)
    for pos in (tri.points, close_boundaries(m).vertices):  # the dummy's position too
        with pytest.raises(errors.PolyllaError, match="halfedge, pemb, lr, lr-bits"):
            P.polylla(s, pos, mode="canonical")
    with pytest.raises(errors.UnsupportedTopologyError, match="Polylla on corner-table") as exc:
        P.run(tri, structure="corner-table")
    assert "close_boundaries" not in str(exc.value) and "halfedge, pemb, lr, lr-bits" in str(exc.value)


def test_entry_points_name_arguments_of_the_wrong_kind(tmp_path, monkeypatch):
    """``run``: an output that is no path was written as ``str(output)`` (a file named '5' in
    the working folder), a missing folder was found only after the run, ``tables='no'`` ran
    with tables and ``mode=None`` reported mode None; ``polylla`` read flags as truthy / falsy
    and a Triangulation2D as ``s`` raised an AttributeError, as did ``build_structure`` of a
    non-triangulation. Nothing is written by a refused call."""
    monkeypatch.chdir(tmp_path)
    pts = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]
    for out in (5, b"x.off", ["a"]):
        with pytest.raises(errors.ArgumentError, match="output path"):
            P.run(pts, out)
    with pytest.raises(errors.OutputError, match="does not exist"):
        P.run(pts, tmp_path / "missing" / "x.off")  # checked before any work
    for flag in ("check", "tables"):
        for bad in ("no", 0, None):
            with pytest.raises(errors.ArgumentError, match=f"run: {flag} must be True or False"):
                P.run(pts, **{flag: bad})
    with pytest.raises(errors.PolyllaError, match="unknown Polylla mode None"):
        P.run(pts, mode=None)
    assert sorted(os.listdir(tmp_path)) == []
    tri = io.from_points(pts)
    with pytest.raises(errors.ArgumentError, match="build_structure: tri must be"):
        P.build_structure("points.xy")
    with pytest.raises(errors.ArgumentError, match="build_structure: check must be"):
        P.build_structure(tri, check="no")
    s = P.build_structure(tri)
    with pytest.raises(errors.ArgumentError, match="polylla: s: expected a jaxcds structure"):
        P.polylla(tri, tri.points)
    for flag in ("tables", "sync_timings", "canonical"):
        with pytest.raises(errors.ArgumentError, match=f"polylla: {flag} must be True"):
            P.polylla(s, tri.points, **{flag: "no"})
    rep = P.run(tri, pathlib.Path(tmp_path / "out.off"))
    assert rep["output"] == str(tmp_path / "out.off") and rep["tables"] is True
    assert sorted(os.listdir(tmp_path)) == ["out.off"]


@pytest.mark.parametrize("bad", ["short", "float", "str", "neg", "dup", "huge", "2d", "scalar",
                                 "bool"])
def test_row_ids_refused_by_name(bad):
    """``row_ids`` were handed to the reference walks' numba kernel unchecked: a short array was
    read past its end (wrong seed ids, or a misleading "corners do not match"), floats truncated,
    booleans read as 0/1, duplicates accepted, a scalar or 2-D array raised numba's TypingError."""
    tri = grid(4)
    s = P.build_structure(tri, "halfedge")
    F = s.num_faces
    ok = np.arange(F) + 100
    assert list(P.polylla(s, tri.points, corners=tri.input_faces, row_ids=ok).seed_edges[:1]) == [302]
    row_ids = {"short": ok[:-3], "float": ok + 0.5, "str": ["a"] * F, "neg": ok - 105,
               "dup": np.zeros(F, np.int64), "huge": ok + 2 ** 62, "2d": ok.reshape(-1, 1),
               "scalar": 3, "bool": np.ones(F, bool)}[bad]
    with pytest.raises(errors.PolyllaError, match="row_ids"):
        P.polylla(s, tri.points, corners=tri.input_faces, row_ids=row_ids)


def test_cycles_csr_host_checks_its_shapes():
    """Sweep 50c: a ``vertex_of_dart`` shorter than ``succ`` was read past its end by the numba
    kernel (polygons of garbage vertex ids, no error)."""
    from jaxcds import errors
    from jaxcds.algorithms.polylla_cycles import cycles_csr_host

    offsets, indices, _, ok = cycles_csr_host(np.array([1, 2, 0]), np.array([4, 5, 6]))
    assert ok and offsets.tolist() == [0, 3] and indices.tolist() == [4, 5, 6]
    with pytest.raises(errors.ArgumentError, match="cycles_csr_host: succ and vertex_of_dart must be"):
        cycles_csr_host(np.array([1, 2, 0]), np.array([4]))


_WALKS_PROBE = r"""
import numpy as np
from jaxcds.algorithms import polylla as P
from jaxcds.algorithms import polylla_reference as R
from jaxcds.generators import delaunay_disk
from jaxcds.structures import registry

pts = np.random.default_rng(3).random((40, 2))
m = delaunay_disk(pts)
s = registry.build("halfedge", m)
seen = []
inner = R._reference_walks
R._reference_walks = lambda *a, **k: seen.append((a, k)) or inner(*a, **k)
want = P.polylla(s, m.vertices[:, :2], corners=m.faces)
(H, face, seed, rows, corners, n), kw = seen[0]
H = np.array(H)
got = R.reference_walks(H.copy(), face, seed, rows, corners, n, **kw)
out["same"] = bool(np.array_equal(got[0], np.asarray(want.offsets)))
e = H.shape[0]
for what, change in (("twin", lambda a: a[0].__setitem__((5, 1), 10 ** 7)),
                     ("next", lambda a: a[0].__setitem__((2, 0), -4)),
                     ("origin", lambda a: a[0].__setitem__((3, 3), 10 ** 6)),
                     ("corners", lambda a: a[4].__setitem__((1, 2), 10 ** 6)),
                     ("row_of_face", lambda a: a[3].__setitem__(0, 10 ** 6)),
                     ("seed", lambda a: a.__setitem__(2, np.asarray(a[2])[:3]))):
    args = [H.copy(), np.array(face), np.array(seed), np.array(rows), np.array(corners), n]
    change(args)
    record(what, lambda: R.reference_walks(*args, **kw))
"""


def test_reference_walks_checks_arrays_it_did_not_make():
    """Stop 50: the public ``reference_walks`` handed its dart rows to the numba kernel
    unchecked: a twin out of range crashed the interpreter. It now names the argument and the
    entry (ArgumentError); ``polylla`` passes its own arrays to the unchecked
    ``_reference_walks`` (same answer). Run in a child interpreter (``crash_probe``), so the
    old crash fails this test instead of ending the run."""
    from conftest import crash_probe

    out = crash_probe(_WALKS_PROBE)
    assert out.pop("same")
    refusals = [f"{c}: {m}" for c, m in out.values()]
    expect = [r"H\[5\] twin = 10000000 is not a dart in \[0, \d+\)", r"H\[2\] next = -4 is not a dart",
              r"H\[3\] origin 1000000 is not a vertex in \[0, 40\)", r"corners\[1\] = 1000000 is outside \[0, 40\)",
              r"row_of_face\[0\] = 1000000 is outside", r"seed must be \(\d+,\) flags"]
    assert len(refusals) == len(expect), refusals
    for pattern, message in zip(expect, refusals):
        assert re.match(r"ArgumentError: reference_walks: " + pattern, message), message


@pytest.mark.parametrize("mode", ["reference", "canonical"])
def test_polylla_under_strict_dtype_promotion(mode, tmp_path):
    """Users of a JAX library may run with ``jax.numpy_dtype_promotion("strict")``: the label
    phase added two bool tie flags to an int32 one, so Polylla raised JAX's TypePromotionError
    there (sweep 52c). An integer grid (tied longest edges) gives the default setting's
    polygons."""
    g = np.arange(6.0)
    pts = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    pts[:, 0] += 0.5 * (pts[:, 1] % 2)  # a triangular lattice: equally long edges everywhere
    tri = io.from_points(pts)
    with jax.numpy_dtype_promotion("strict"):
        got = P.run(tri, tmp_path / "strict.off", mode=mode)
    want = P.run(tri, tmp_path / "default.off", mode=mode)
    assert got["polygons"] == want["polygons"] > 0
    assert (tmp_path / "strict.off").read_text() == (tmp_path / "default.off").read_text()


def _npy_with_header(tmp_path, name, old, new):
    """A 12-point .npy whose header text has ``old`` replaced by ``new`` (padding kept, so the
    header's length field still holds)."""
    import io as pyio

    buf = pyio.BytesIO()
    np.save(buf, np.random.default_rng(0).random((12, 2)))
    data = buf.getvalue()
    hlen = int.from_bytes(data[8:10], "little")
    head = data[10:10 + hlen].replace(old, new)
    head = head[:-1].rstrip(b" ")[:hlen - 1].ljust(hlen - 1) + b"\n"
    path = tmp_path / name
    path.write_bytes(data[:10] + head + data[10 + hlen:])
    return str(path)


@pytest.mark.parametrize("old,new,match", [
    (b"(12, 2)", b"(1000000000000, 2)", r"shape \(1000000000000, 2\) \(16000000000000 bytes from byte 128\), "
                                         r"the file holds 192 bytes"),
    (b"(12, 2)", b"(12, 18446744073709551616)", r"shape \(12, 18446744073709551616\)"),
    (b"'shape': (12, 2), }", b"'shape': (12, 2, }", r"its header \(bytes 0-127\) does not parse"),
], ids=["huge-shape", "shape-past-int64", "unclosed-bracket"])
def test_npy_header_is_checked_before_numpy_reads_the_data(tmp_path, old, new, match):
    """Fuzzing (sweep 54b): numpy allocates the shape a .npy header declares before it reads the
    data (a flipped count asked for 16 TB: MemoryError), a shape past int64 raised OverflowError
    and an unclosed bracket tokenize's TokenError; all named by the header now."""
    path = _npy_with_header(tmp_path, "p.npy", old, new)
    with pytest.raises(errors.PolyllaError, match=match):
        io.read_input(path)
    assert io.read_input(_npy_with_header(tmp_path, "ok.npy", b"", b"")).num_vertices == 12


@pytest.mark.parametrize("vid", ["inf", "nan", "-inf", "1e30"])
def test_node_id_that_is_no_integer_is_named_without_a_cast_warning(tmp_path, vid):
    """Fuzzing (sweep 54b): a .node id 'inf' (or one past int64) was cast to int64 with a
    RuntimeWarning on stderr and the refusal named the id -9223372036854775808."""
    import warnings

    (tmp_path / "a.node").write_text(f"4 2 0 1\n1 0 0 1\n2 1 0 1\n{vid} 1 1 1\n4 0 1 1\n")
    (tmp_path / "a.ele").write_text("2 3 0\n1 1 2 3\n2 1 3 4\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(errors.PolyllaError, match=rf"a.node: vertex 2 has id {re.escape(repr(float(vid)))}; ids are"):
            io.read_input(str(tmp_path / "a.node"))


_SQUARE_OFF = "4 {nf} 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n"


@pytest.mark.parametrize("text,faces", [("OFF\n" + _SQUARE_OFF.format(nf=1), None),
                                        ("OFF\n" + _SQUARE_OFF.format(nf=2) + "OFF\n", None),
                                        ("{ appearance {+edge +face} LIST\nOFF\n" + _SQUARE_OFF.format(nf=2) + "}\n", 2)],
                         ids=["count-too-low", "junk-after-faces", "geomview-wrapper"])
def test_off_2d_rows_past_the_declared_faces_are_named(tmp_path, text, faces):
    """Fuzzing (sweep 54b): read_off_2d read the faces its header counts and dropped the rest
    without a word ('4 1 0' over two triangles meshed one triangle); the '}' closing the
    reference's geomview wrapper is not data."""
    (tmp_path / "m.off").write_text(text)
    if faces is not None:
        assert io.read_input(str(tmp_path / "m.off")).num_faces == faces
        return
    with pytest.raises(errors.PolyllaError, match=r"m.off: data past the last face the OFF header declares "
                                                  r"\(4 vertices, \d faces\): 1 more line\(s\)"):
        io.read_input(str(tmp_path / "m.off"))
