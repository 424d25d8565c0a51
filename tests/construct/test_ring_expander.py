"""RING-EXPANDER (LR paper Sec. 4.2) and HYBRID-RING-EXPANDER (Sec. 6.1), numba kernels against
slow Python versions of the listings, and the ring they produce (no JAX: cheap)."""

from __future__ import annotations

import collections
import dataclasses

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from jaxcds import errors
from jaxcds.construct.ring_expander import (best_ring, extract_ring, hybrid_ring_expander,
                                            reference_ring_expander, ring_expander)
from jaxcds.generators import random_planar_triangulation_faces
from jaxcds.mesh import close_boundaries, load_mesh
from jaxcds.structures.corner_table import CornerTable

from conftest import load_shared


def _vo(faces, nv):
    ct = CornerTable.from_faces(faces, nv)
    return np.asarray(ct.V), np.asarray(ct.O)


def _nx(c):
    return 3 * (c // 3) + (c + 1) % 3


def _pv(c):
    return 3 * (c // 3) + (c + 2) % 3


def reference_hybrid(V, O, nv, seed, k, dummy=None):
    """The Sec. 6.1 listing with a Python deque (``k = 0``: never breadth-first)."""
    vm = np.zeros(nv, bool) if dummy is None else np.asarray(dummy, bool).copy()
    tm = np.zeros(len(V) // 3, bool)
    c = seed
    vm[V[_nx(c)]] = vm[V[_pv(c)]] = True
    d = collections.deque([O[c]])
    n = 0
    while True:
        if not vm[V[c]]:
            vm[V[c]] = tm[c // 3] = True
            d.append(O[_nx(c)])
            d.append(O[_pv(c)])
            n += 1
        if not d:
            break
        c = d.popleft() if (k > 0 and n % k == 0) else d.pop()
    return tm.astype(np.uint8), vm.astype(np.uint8)


def _meshes():
    out = {}
    for name in ("cube.off", "grid.off", "3holes.off"):
        m = close_boundaries(load_shared(name))
        out[name] = (m.faces, m.num_vertices, m.dummy_vertices)
    return out


@pytest.fixture(scope="module")
def meshes():
    return _meshes()


def _check_ring(V, O, tm, vm, nv, dummy, seed):
    """Invaded triangles form a disk whose boundary is the ring: ``m_r - 2`` triangles, every
    ring vertex visited, no dummy on the ring (Sec. 4.6)."""
    ring = extract_ring(V, O, tm, nv, seed)
    m_r = ring.order.size
    assert int(tm.sum()) == m_r - 2
    assert np.unique(ring.order).size == m_r
    assert vm[ring.order].all()
    if dummy is not None:
        assert not np.asarray(dummy, bool)[ring.order].any()
    # every vertex is on the ring or isolated: m_i = m - m_r
    assert ring.num_isolated == nv - m_r
    return ring


@pytest.mark.parametrize("name", ["cube.off", "grid.off", "3holes.off"])
def test_ring_expander_equals_reference_listing(meshes, name):
    faces, nv, dummy = meshes[name]
    V, O = _vo(faces, nv)
    ok = ~np.asarray(dummy, bool)[V.reshape(-1, 3)].any(axis=1)
    for t in np.nonzero(ok)[0][:: max(1, ok.sum() // 6)][:6]:
        seed = int(3 * t)
        tm, vm = ring_expander(V, O, nv, seed, dummy)
        rtm, rvm = reference_ring_expander(V, O, nv, seed, dummy)
        np.testing.assert_array_equal(tm, rtm)
        np.testing.assert_array_equal(vm, rvm)
        _check_ring(V, O, tm, vm, nv, dummy, seed)


@pytest.mark.parametrize("k", [1, 2, 16, 0])
def test_hybrid_ring_expander_equals_reference_listing(meshes, k):
    faces, nv, dummy = meshes["3holes.off"]
    V, O = _vo(faces, nv)
    for seed in (0, 300, 3 * 1000 + 1):
        tm, vm = hybrid_ring_expander(V, O, nv, seed, k, dummy)
        rtm, rvm = reference_hybrid(V, O, nv, seed, k, dummy)
        np.testing.assert_array_equal(tm, rtm)
        np.testing.assert_array_equal(vm, rvm)
        _check_ring(V, O, tm, vm, nv, dummy, seed)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(5, 300), seed=st.integers(0, 2**31 - 1), k=st.sampled_from([None, 1, 3, 0]))
def test_random_triangulations_against_reference(n, seed, k):
    faces = random_planar_triangulation_faces(n, seed=seed)
    V, O = _vo(faces, n)
    s = int(seed % (3 * len(faces)))
    if k is None:
        got, want = ring_expander(V, O, n, s), reference_ring_expander(V, O, n, s)
    else:
        got, want = hybrid_ring_expander(V, O, n, s, k), reference_hybrid(V, O, n, s, k)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    _check_ring(V, O, got[0], got[1], n, None, s)


def test_second_walk_reaches_the_vertex_behind_s_o():
    """A lone quad closed by a dummy: the Sec. 4.2 listing stops at ``s.o`` and would leave the
    fourth vertex isolated; the second walk from ``s.o`` puts it on the ring."""
    quad = load_mesh(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float),
                     np.array([[0, 1, 2], [0, 2, 3]]))
    m = close_boundaries(quad)
    V, O = _vo(m.faces, m.num_vertices)
    for seed in (0, 1, 2, 3, 4, 5):
        tm, vm = ring_expander(V, O, m.num_vertices, seed, m.dummy_vertices)
        ring = _check_ring(V, O, tm, vm, m.num_vertices, m.dummy_vertices, seed)
        assert ring.order.size == 4 and ring.num_isolated == 1  # only the dummy is off the ring


def test_best_ring_keeps_fewest_isolated(meshes):
    faces, nv, dummy = meshes["3holes.off"]
    V, O = _vo(faces, nv)
    seeds = [0, 30, 3000, 9000, 15000]
    rings = [best_ring(V, O, nv, seeds=[s], dummy=dummy) for s in seeds]
    best = best_ring(V, O, nv, seeds=seeds, dummy=dummy)
    assert best.num_isolated == min(r.num_isolated for r in rings)


def test_corrupted_corner_table_is_refused():
    # every opposite points at one corner: no ring can be extracted (typed error, not a hang)
    faces = random_planar_triangulation_faces(20, seed=1)
    V, O = _vo(faces, 20)
    O_bad = O.copy()
    O_bad[:] = O_bad[0]
    with pytest.raises((errors.StructureError, errors.UnsupportedTopologyError)):
        tm, _ = ring_expander(V, O_bad, 20, 0)
        extract_ring(V, O_bad, tm, 20, 0)


@pytest.mark.parametrize("skipping", [True, False])
@pytest.mark.parametrize("name,faces", [("armadillo.obj", None), ("random", 3000)])
def test_irregular_split_t1_t2_against_ring_edges(name, faces, skipping):
    """Table 1's T^i split into T_1^i and T_2^i: an irregular slot's triangle is a T_2^i when
    two of its edges are ring edges, counted here straight from the ring order (oracle). With
    wart skipping every T_2 next to a T_0 is a wart and is absorbed (T_2^i = 0, as the paper's
    Table 1 shows no T_2^i column for standard LR); without it the warts are the T_2^i."""
    from jaxcds.construct.ring_expander import lr_tables

    if faces is None:
        m = load_shared(name)
        f, nv = m.faces, m.num_vertices
    else:
        f = random_planar_triangulation_faces(faces, seed=4)
        nv = int(f.max()) + 1
    V, O = _vo(f, nv)
    tb = lr_tables(V, O, best_ring(V, O, nv, seeds=2), nv, wart_skipping=skipping)
    ring = tb.order
    edges = {frozenset((int(a), int(b))) for a, b in zip(ring, np.roll(ring, -1))}
    tris = np.concatenate([tb.left_corner // 3, tb.right_corner // 3])
    irr = np.concatenate([tb.irr_left, tb.irr_right])
    skip = np.concatenate([tb.skip_left, tb.skip_right])
    t2 = 0
    for t, sk in zip(tris[irr], skip[irr]):
        a, b, c = (int(x) for x in V[3 * t: 3 * t + 3])
        k = sum(frozenset(e) in edges for e in ((a, b), (b, c), (c, a)))
        t2 += (k == 2) and not sk
    st = tb.stats(len(V) // 3)
    assert st["Ti"] == int(irr.sum()) > 0
    assert st["T2i"] == t2
    assert st["T1i"] + st["T2i"] == st["Ti"]
    assert (st["T2i"] == 0) if skipping else (st["T2i"] > 0)


def test_ring_functions_check_a_corner_table_they_did_not_build():
    """Sweep 50c: the ring functions handed ``V``, ``O``, ``tm``, the seed corner and a ring to
    their numba kernels unchecked (a seed or an ``O`` entry out of range, a ring corner out of
    range: segmentation faults); the library's own LR builder keeps the unchecked route. Run in
    a child interpreter, so the old crash fails this test instead of ending the run."""
    from conftest import crash_probe_lines

    code = ("import dataclasses, numpy as np\nfrom jaxcds import errors, CornerTable\n"
            "from jaxcds.construct.ring_expander import (best_ring, extract_ring, hybrid_ring_expander,\n"
            "    lr_tables, ring_expander)\n"
            "from jaxcds.construct.ring_search import improve_ring, ring_cost\n"
            "from jaxcds.generators import icosphere\n"
            "ct = CornerTable.from_mesh(icosphere(1))\nV, O = np.asarray(ct.V), np.asarray(ct.O)\n"
            "tm, _ = ring_expander(V, O, 42, 0)\nr = best_ring(V, O, 42)\n"
            "assert lr_tables(V, O, r, 42).num_t2 >= 0 and ring_cost(V, O, r.invaded, 42) > 0\n"
            "big = O.copy()\nbig[7] = 10 ** 7\nswap = O.copy()\nswap[[0, 1]] = swap[[1, 0]]\n"
            "rc = dataclasses.replace(r, right_corner=np.full_like(r.right_corner, 10 ** 7))\n"
            "for call in (lambda: ring_expander(V, O, 42, 10 ** 7), lambda: ring_expander(V, swap, 42, 0),\n"
            "             lambda: hybrid_ring_expander(V, big, 42, 0, 3), lambda: best_ring(V, big, 42),\n"
            "             lambda: extract_ring(V, big, tm, 42), lambda: lr_tables(V, O, rc, 42),\n"
            "             lambda: improve_ring(V, big, tm, 42, sweeps=2), lambda: ring_cost(V, O, tm[:2], 42)):\n"
            "    try:\n        call()\n        print('accepted')\n"
            "    except errors.JaxcdsError as exc:\n        print(type(exc).__name__, str(exc)[:80])\n")
    lines = crash_probe_lines(code)
    assert len(lines) == 8 and all(a.startswith(b) for a, b in zip(lines, [
        "ArgumentError ring_expander: seed must be a corner id in [0, 240), got 10000000",
        "StructureError ring_expander: O[0] = 14 is not the opposite of corner 0: O must be an",
        "StructureError hybrid_ring_expander: O[7] = 10000000 is not a corner id in [0, 240)",
        "StructureError best_ring: O[7] = 10000000 is not a corner id in [0, 240)",
        "StructureError extract_ring: O[7] = 10000000 is not a corner id in [0, 240)",
        "StructureError lr_tables: ring entry 0 (order ",
        "StructureError improve_ring: O[7] = 10000000 is not a corner id in [0, 240)",
        "ArgumentError ring_cost: tm must be 80 flags 0/1 (one per triangle)"])), lines


def _icosahedron_vo():
    from jaxcds.generators import icosphere

    return _vo(np.asarray(icosphere(0).faces), 12)


def _with(a, index, value):
    a = np.array(a)
    a[index] = value
    return a


@pytest.mark.parametrize("call,error,msg", [
    (lambda V, O: ring_expander(V, O, 12.5, 0), errors.ArgumentError,
     r"ring_expander: num_vertices must be an integer in \[0, 2\^31\), got 12.5"),
    (lambda V, O: ring_expander([[0, 1], [2]], O, 12, 0), errors.ArgumentError, "ring_expander: V is not an array"),
    (lambda V, O: ring_expander(V.astype(float), O, 12, 0), errors.ArgumentError,
     r"ring_expander: V must be a 1-D integer array of 3F > 0 corners, got dtype float64 shape \(60,\)"),
    (lambda V, O: ring_expander(V, O[:-3], 12, 0), errors.ArgumentError,
     r"V and O must have one length \(3F\), got 60 and 57"),
    (lambda V, O: ring_expander(_with(V, 4, 12), O, 12, 0), errors.StructureError,
     r"ring_expander: V\[4\] = 12 is outside \[0, 12\)"),
    (lambda V, O: best_ring(V, _with(O, 5, -1), 12), errors.StructureError,
     r"best_ring: O\[5\] = -1 is not a corner id in \[0, 60\)"),
    (lambda V, O: ring_expander(V, O, 12, 0, dummy=np.zeros(11, bool)), errors.ArgumentError,
     r"dummy must be 12 flags 0/1 \(one per vertex\), got dtype bool shape \(11,\)"),
    (lambda V, O: ring_expander(V, O, 12, 0, dummy=np.full(12, 2)), errors.ArgumentError,
     r"dummy must be 12 flags 0/1"),
    (lambda V, O: best_ring(V, O, 12, seeds=0), errors.ArgumentError,
     "seeds must be a count >= 1 or a list of corner ids, got 0"),
    (lambda V, O: best_ring(V, O, 12, seeds=[]), errors.ArgumentError, "an empty list of seed corners"),
    (lambda V, O: best_ring(V, O, 12, seeds=[99]), errors.ArgumentError,
     r"seeds\[0\] = 99 is not a corner id in \[0, 60\)"),
    (lambda V, O: best_ring(V, O, 12, seeds=[0], dummy=np.ones(12, bool)), errors.ArgumentError,
     r"seeds\[0\] = corner 0 is on a hole-closing \(dummy\) triangle"),
    (lambda V, O: best_ring(V, O, 12, dummy=np.ones(12, bool)), errors.UnsupportedTopologyError,
     "no triangle without a dummy vertex to seed the ring"),
    (lambda V, O: hybrid_ring_expander(V, O, 12, 0, -1), errors.ArgumentError,
     r"hybrid_ring_expander: k must be an integer >= 0, got -1"),
    (lambda V, O: hybrid_ring_expander(V, O, 12, 0, 2.5), errors.ArgumentError,
     r"hybrid_ring_expander: k must be an integer >= 0, got 2.5"),
])
def test_ring_functions_name_a_bad_argument(call, error, msg):
    """Checks before the kernels that no test ran in-process (the child-process test above
    covers the ones that crashed)."""
    V, O = _icosahedron_vo()
    with pytest.raises(error, match=msg):
        call(V, O)


@pytest.mark.parametrize("change,error,msg", [
    (lambda r: "ring", errors.ArgumentError, "lr_tables: ring must be a Ring .*got str"),
    (lambda r: dataclasses.replace(r, order=r.order[:3], right_corner=r.right_corner[:3]), errors.StructureError,
     r"ring.order and ring.right_corner must be 1-D integer arrays of one length >= 4, got int32 \(3,\)"),
    (lambda r: dataclasses.replace(r, order=r.order.astype(float)), errors.StructureError,
     r"1-D integer arrays of one length >= 4, got float64 \(12,\) and int32 \(12,\)"),
])
def test_lr_tables_names_a_ring_of_the_wrong_kind(change, error, msg):
    from jaxcds.construct.ring_expander import lr_tables

    V, O = _icosahedron_vo()
    with pytest.raises(error, match=msg):
        lr_tables(V, O, change(best_ring(V, O, 12)), 12)


def test_lr_tables_refuses_a_ring_through_a_vertex_twice():
    """One edge a -> b walked there and back twice: every entry a ring edge of the table, but
    not a simple loop."""
    from jaxcds.construct.ring_expander import lr_tables

    V, O = _icosahedron_vo()
    c = 0  # corner 0 faces the edge V[1] -> V[2]; its opposite corner faces V[2] -> V[1]
    a, b = int(V[_nx(c)]), int(V[_pv(c)])
    r = best_ring(V, O, 12)
    back_and_forth = dataclasses.replace(r, order=np.array([a, b, a, b], np.int32),
                                         right_corner=np.array([c, O[c], c, O[c]], np.int32))
    with pytest.raises(errors.StructureError, match=r"lr_tables: ring.order repeats a vertex \(a ring is a simple loop\)"):
        lr_tables(V, O, back_and_forth, 12)


def _merged_far_vertices():
    """icosphere(1) with vertex 0 and its antipode made one vertex: every edge stays manifold
    (they share no neighbour), one connected surface, and vertex 0 has two fans (a pinch)."""
    from jaxcds.generators import icosphere

    m = icosphere(1)
    f, p = np.asarray(m.faces), np.asarray(m.vertices)
    far = int(np.argmin(p @ p[0]))
    g = f.copy()
    g[g == far] = 0
    g[g == 41] = far  # the last vertex takes the freed id
    return g, 41


@pytest.mark.parametrize("case,msg", [
    ("pinch", r"vertex 0 has two fans of triangles \(corners 0 and \d+ do not swing into each other\): "
              "a pinch"),
    ("two parts", r"the corner table has 2 connected parts \(triangles 0 and 20 are in different ones\)"),
    ("unused vertex", r"vertex 12 is in no triangle \(num_vertices = 13\)"),
])
@pytest.mark.parametrize("call", [lambda V, O, n: ring_expander(V, O, n, 0), lambda V, O, n: best_ring(V, O, n)])
def test_ring_functions_refuse_a_corner_table_that_is_not_one_surface(case, msg, call):
    """Consistent opposites were all the check asked for: a hand-made corner table with a pinch
    vertex, two parts or a vertex in no triangle got a ring of one fan or one part (the rest
    "isolated") without a word. The builders validate the mesh first, so only callers of the
    public ring functions met it."""
    f = np.asarray(_icosahedron_faces())
    faces, n = {"pinch": _merged_far_vertices(), "two parts": (np.concatenate([f, f + 12]), 24),
                "unused vertex": (f, 13)}[case]
    V, O = _vo(faces, n)
    with pytest.raises(errors.StructureError, match=msg):
        call(V, O, n)


def _icosahedron_faces():
    from jaxcds.generators import icosphere

    return icosphere(0).faces
