"""Generators: topology of every generator, and the Poulalhon--Schaeffer sampler checked three ways:

* its numba closure against a slow, obviously-correct Python closure (repeat "find a stem
  followed by two sides, close it" until none is left) on every tree of small size;
* exact uniformity: over *all* blossoming trees with k nodes (and both coins), every rooted
  triangulation with k + 2 vertices is produced equally often (Tutte/A000260 counts 1, 3, 13,
  68, 399 for 4..8 vertices come out of the enumeration);
* the degree law of CDS Sec. 4.4 (p_6 ~ 11.6%) on large samples.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import example, given, settings, strategies as st

from jaxcds import errors, generators as gen
from jaxcds.mesh import TriMesh, topology, validate


# ---------------------------------------------------------------------------------- helpers
def _check_sphere_triangulation(f: np.ndarray, n: int) -> None:
    """Closed, simple, consistently oriented, manifold, genus 0 -- from first principles."""
    f = np.asarray(f, dtype=np.int64)
    assert f.shape == (2 * n - 4, 3)
    assert f.min() == 0 and f.max() == n - 1 and np.unique(f).size == n
    assert np.all((f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])), "loop"
    d = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    key = d[:, 0] * n + d[:, 1]
    # each directed edge once (orientation + no multi-edge on one side) and its twin present
    assert np.unique(key).size == key.size, "a directed edge is used twice"
    assert np.all(np.isin(d[:, 1] * n + d[:, 0], key)), "a dart without twin (border)"
    und = np.unique(np.minimum(d[:, 0], d[:, 1]) * n + np.maximum(d[:, 0], d[:, 1]))
    assert und.size == 3 * n - 6, "multiple edges"  # E = 3n - 6 with no multi-edge
    assert n - und.size + f.shape[0] == 2  # Euler characteristic of the sphere
    # manifold vertices: the faces around each vertex form one cycle (one fan)
    nxt = {}
    for a, b, c in f:
        nxt[(a, b)] = c  # around vertex a: from neighbour b to neighbour c
        nxt[(b, c)] = a
        nxt[(c, a)] = b
    deg = np.bincount(f.ravel(), minlength=n)
    seen = set()
    for (v, w0) in list(nxt):
        if v in seen:
            continue
        seen.add(v)
        w, steps = nxt[(v, w0)], 1
        while w != w0:
            w, steps = nxt[(v, w)], steps + 1
        assert steps == deg[v], f"vertex {v} is not a single fan"


def _slow_closure(kind, cu, cv, k, swap):
    """Textbook closure: repeatedly close any stem followed (cyclically) by two sides."""
    word = [(int(a), int(b), int(c)) for a, b, c in zip(kind, cu, cv)]
    faces = []
    changed = True
    while changed:
        changed = False
        L = len(word)
        for i in range(L):
            a, b, c = word[i], word[(i + 1) % L], word[(i + 2) % L]
            if a[0] == 1 and b[0] == 0 and c[0] == 0:
                faces.append((b[1], b[2], c[2]))  # stem at u, sides u->v, v->w: (u, v, w)
                word = word[i:] + word[:i]  # rotate the pattern to the front, then replace it
                word = [(0, b[1], c[2])] + word[3:]  # by the new side u->w
                changed = True
                break
    R = len(word)
    cs = [i for i in range(R) if word[i][0] == 1 and word[(i + 1) % R][0] == 1]
    assert len(cs) == 2
    ci, di = cs
    if swap:
        ci, di = di, ci
    A, B = k, k + 1
    for a0, a1, X in ((ci, di, A), (di, ci, B)):
        i = (a0 + 1) % R
        while i != a1:
            if word[i][0] == 0:
                faces.append((word[i][1], word[i][2], X))
            i = (i + 1) % R
    faces.append((word[ci][1], A, B))
    faces.append((word[di][1], B, A))
    return faces


def _canon_face(t):
    t = tuple(int(x) for x in t)
    i = t.index(min(t))
    return t[i:] + t[:i]


def _tree_words(k):
    """Every planted blossoming tree with k nodes, as the sampler's word (prefix code)."""
    m = 4 * k - 1
    for ones in itertools.combinations(range(1, m), k - 1):  # first letter must open the root
        z = np.zeros(m, dtype=np.int8)
        z[0] = 1
        z[list(ones)] = 1
        s = np.cumsum(np.where(z == 1, 3, -1))
        if np.all(s > 0):
            yield np.concatenate([z, np.zeros(1, np.int8)])


def _rooted_codes(f):
    """Canonical codes of the map rooted at each dart (BFS numbering of darts through next and
    twin); returns (class id = min code, number of distinct rootings = 2E / |Aut+|)."""
    f = np.asarray(f)
    F = f.shape[0]
    darts = [(int(f[i, j]), int(f[i, (j + 1) % 3])) for i in range(F) for j in range(3)]
    index = {d: i for i, d in enumerate(darts)}
    nxt = [3 * (i // 3) + (i % 3 + 1) % 3 for i in range(3 * F)]
    twin = [index[(b, a)] for a, b in darts]
    codes = set()
    for r in range(3 * F):
        order = {r: 0}
        queue = [r]
        code = []
        for d in queue:
            for e in (nxt[d], twin[d]):
                if e not in order:
                    order[e] = len(order)
                    queue.append(e)
                code.append(order[e])
        codes.add(tuple(code))
    return min(codes), len(codes)


# ---------------------------------------------------------------------------------- PS sampler
def test_cycle_lemma_rotation_is_the_unique_valid_one():
    rng = np.random.default_rng(0)
    for k in (1, 2, 3, 5, 8):
        for _ in range(50):
            z = rng.permutation(np.r_[np.ones(k, np.int8), np.zeros(3 * k - 1, np.int8)])
            good = [r for r in range(z.size)
                    if np.all(np.cumsum(np.where(np.roll(z, -r) == 1, 3, -1)) > 0)]
            assert len(good) == 1
            w = gen._rotate_word(z)
            np.testing.assert_array_equal(w[:-1], np.roll(z, -good[0]))
            assert w[-1] == 0


@pytest.mark.parametrize("k", [2, 3, 4, 5])
def test_closure_matches_slow_reference_on_every_tree(k):
    count = 0
    for w in _tree_words(k):
        kind, cu, cv = gen._contour(w, k)
        assert kind.size == 4 * k - 2 and np.sum(kind == 1) == 2 * k
        # which of the two final "stem stem" places is C depends on where the residual word
        # starts, so compare the pair of results of both coins
        fast = {frozenset(_canon_face(t) for t in gen._closure(kind, cu, cv, k, swap))
                for swap in (False, True)}
        slow = {frozenset(_canon_face(t) for t in _slow_closure(kind, cu, cv, k, swap))
                for swap in (False, True)}
        assert fast == slow
        assert all(len(x) == 2 * k for x in fast)
        count += 1
    assert count == math.comb(4 * k - 2, k - 1) // k  # T = z / (1 - T)^3


# rooted simple triangulations of the sphere with V vertices (Tutte; OEIS A000260)
ROOTED = {4: 1, 5: 3, 6: 13, 7: 68, 8: 399}


@pytest.mark.parametrize("n", [4, 5, 6, 7, pytest.param(8, marks=pytest.mark.slow)])
def test_sampler_is_exactly_uniform_on_rooted_triangulations(n):
    """Each tree and coin gives one triangulation T; uniformity on rooted triangulations means
    #preimages(T) is the same multiple of #rootings(T) = 2E/|Aut+(T)| for every T."""
    k = n - 2
    hits, rootings = {}, {}
    for w in _tree_words(k):
        for swap in (False, True):
            f = gen._close_word(w, k, swap)
            _check_sphere_triangulation(f, n)
            cls, r = _rooted_codes(f)
            hits[cls] = hits.get(cls, 0) + 1
            rootings[cls] = r
    assert sum(rootings.values()) == ROOTED[n]
    ratios = {hits[c] / rootings[c] for c in hits}
    assert ratios == {4 * k - 2}  # trees x 2 coins = (4k - 2) x rooted triangulations


def test_sampled_frequencies_of_six_vertex_triangulations():
    """End to end through the random word: the octahedron (24 darts, |Aut+| = 24: 1 of the 13
    rooted triangulations on 6 vertices) comes out with probability 1/13."""
    trials = 1300
    octa = 0
    for seed in range(trials):
        f = gen.random_planar_triangulation_faces(6, seed)
        octa += int(np.all(np.bincount(f.ravel(), minlength=6) == 4))
    p = 1 / 13
    sd = math.sqrt(trials * p * (1 - p))
    assert abs(octa - trials * p) < 4.5 * sd, octa


@settings(max_examples=40, deadline=None)
@given(n=st.integers(4, 400), seed=st.integers(0, 2**32 - 1))
def test_random_triangulation_is_simple_closed_sphere(n, seed):
    m = gen.random_planar_triangulation(n, seed)
    assert isinstance(m, TriMesh)
    assert m.vertices.shape == (n, 3) and m.vertices.dtype == np.float64
    assert m.faces.dtype == np.int32
    np.testing.assert_allclose(np.linalg.norm(m.vertices, axis=1), 1.0)
    _check_sphere_triangulation(m.faces, n)
    validate(m, closed=True, connected=True)
    t = topology(m)
    assert (t["euler_characteristic"], t["genus"], t["components"]) == (2, 0, 1)
    assert t["manifold"] and t["orientable"] and t["consistently_oriented"] and not t["defects"]


def test_seeded_and_varied():
    a = gen.random_planar_triangulation(500, seed=7)
    b = gen.random_planar_triangulation(500, seed=7)
    c = gen.random_planar_triangulation(500, seed=8)
    np.testing.assert_array_equal(a.faces, b.faces)
    np.testing.assert_array_equal(a.vertices, b.vertices)
    assert not np.array_equal(a.faces, c.faces)


def test_degree_law_formula():
    assert gen.degree_law(6)[0] == pytest.approx(0.1168, abs=5e-5)  # "about 11.6%", Sec. 4.4
    assert gen.degree_law([0, 1, 2]).sum() == 0
    assert gen.degree_law(np.arange(3, 2000)).sum() == pytest.approx(1.0, abs=1e-9)
    # mean degree 6 (E = 3n - 6): sum i p_i = 6
    i = np.arange(3, 2000)
    assert np.sum(i * gen.degree_law(i)) == pytest.approx(6.0, abs=1e-9)


def test_degree_distribution_matches_sec_4_4():
    n = 300_000
    f = gen.random_planar_triangulation_faces(n, seed=11)
    deg = np.bincount(f.ravel(), minlength=n)
    freq = np.bincount(deg, minlength=40)[:40] / n
    law = gen.degree_law(np.arange(40))
    assert freq[6] == pytest.approx(0.1168, abs=0.003)
    assert np.max(np.abs(freq - law)) < 0.004
    assert deg.min() >= 3
    # an icosphere is far from this law: the check can fail
    ico = np.bincount(gen.icosphere(3).faces.ravel())
    assert np.bincount(ico)[6] / ico.size > 0.9


@pytest.mark.slow
def test_ten_million_vertices_fast_and_sound():
    import time

    t = time.perf_counter()
    f = gen.random_planar_triangulation_faces(10_000_000, seed=1)
    dt = time.perf_counter() - t
    n = 10_000_000
    assert f.shape == (2 * n - 4, 3)
    assert dt < 60  # ~3.5 s on the 2-core dev machine; generous for CI
    deg = np.bincount(f.ravel(), minlength=n)
    assert deg.sum() == 3 * (2 * n - 4) and deg.min() >= 3
    assert (deg == 6).mean() == pytest.approx(0.1168, abs=0.001)


@pytest.mark.parametrize("n", [0, 3, -5])
def test_random_triangulation_refuses_tiny(n):
    with pytest.raises(errors.MeshError, match="n >= 4"):
        gen.random_planar_triangulation(n)


# ---------------------------------------------------------------------------------- others
@pytest.mark.parametrize("s", [0, 1, 3])
def test_icosphere(s):
    m = gen.icosphere(s)
    assert m.num_vertices == 10 * 4**s + 2 and m.num_faces == 20 * 4**s
    validate(m, closed=True, connected=True)
    deg = np.bincount(m.faces.ravel())
    assert np.sum(deg == 5) == 12 and np.all((deg == 5) | (deg == 6))
    _assert_outward(m)


def _assert_outward(m):
    """Every face sees all vertices on its inner side (convex polytope, outward normals)."""
    v, f = m.vertices, m.faces
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    nrm = np.cross(b - a, c - a)
    side = np.einsum("fj,fvj->fv", nrm, v[None, :, :] - a[:, None, :])
    assert np.all(side <= 1e-12)


@settings(max_examples=15, deadline=None)
@given(n=st.integers(4, 300), seed=st.integers(0, 10**6))
@example(n=4, seed=1)  # the origin lies outside this tetrahedron
def test_sphere_hull(n, seed):
    m = gen.sphere_hull(n, seed)
    assert m.num_vertices == n and m.num_faces == 2 * n - 4
    validate(m, closed=True, connected=True)
    _check_sphere_triangulation(m.faces, n)
    _assert_outward(m)


@settings(max_examples=15, deadline=None)
@given(n=st.integers(3, 300), seed=st.integers(0, 10**6))
def test_delaunay_square_open_and_closed(n, seed):
    m = gen.delaunay_square(n, seed)
    t = topology(m)
    assert m.num_vertices == n and t["boundary_loops"] == 1 and t["euler_characteristic"] == 1
    assert t["manifold"] and t["consistently_oriented"]
    v, f = m.vertices, m.faces
    assert np.all(v[:, 2] == 0) and np.all((v[:, :2] >= 0) & (v[:, :2] <= 1))
    area2 = ((v[f[:, 1], 0] - v[f[:, 0], 0]) * (v[f[:, 2], 1] - v[f[:, 0], 1])
             - (v[f[:, 1], 1] - v[f[:, 0], 1]) * (v[f[:, 2], 0] - v[f[:, 0], 0]))
    assert np.all(area2 > 0)  # ccw seen from +z
    c = gen.delaunay_square(n, seed, closed=True)
    tc = topology(c)
    assert c.num_vertices == n + 1 and tc["closed"] and tc["euler_characteristic"] == 2
    assert c.dummy_vertices is not None and c.dummy_vertices.sum() == 1 and c.dummy_vertices[n]
    assert c.dummy_faces.sum() == t["boundary_loop_lengths"][0]
    np.testing.assert_array_equal(c.faces[: m.num_faces], m.faces)
    validate(c, closed=True, connected=True)


def test_delaunay_disk_is_delaunay_and_refuses_bad_points():
    rng = np.random.default_rng(3)
    p = rng.random((200, 2))
    m = gen.delaunay_disk(p)
    v, f = m.vertices[:, :2], m.faces
    # empty circumcircle, brute force: incircle(a, b, c, d) > 0 iff d inside the circle of the
    # ccw triangle (a, b, c)
    for tri in f:
        rows = v[tri][None, :, :] - v[:, None, :]  # (V, 3, 2): a - d, b - d, c - d
        mat = np.concatenate([rows, np.sum(rows**2, axis=2, keepdims=True)], axis=2)
        inc = np.linalg.det(mat)
        others = np.ones(len(v), bool)
        others[tri] = False
        assert np.all(inc[others] <= 1e-12)
    with pytest.raises(errors.MeshError, match="point 1"):
        gen.delaunay_disk(np.array([[0, 0], [1, 0], [0, 1], [1, 0.0]]))
    with pytest.raises(errors.NonFiniteCoordinateError, match="point 2"):
        gen.delaunay_disk(np.array([[0, 0], [1, 0], [np.nan, 1]]))
    with pytest.raises(errors.MeshError, match=r"shape \(n, 2\)"):
        gen.delaunay_disk(np.zeros((5, 3)))


def test_generator_arguments_are_checked_by_name():
    """Bad counts, seeds and radii were plain ValueError / TypeError / MemoryError or silently
    truncated (4.7 vertices -> 4); collinear points a raw multi-line QhullError."""
    from jaxcds import generators as G

    for call, msg in [(lambda: G.random_planar_triangulation(10, seed=-1), "seed must be >= 0"),
                      (lambda: G.random_planar_triangulation(10, seed=1.5), "seed must be an integer"),
                      (lambda: G.random_planar_triangulation(None), "n must be an integer"),
                      (lambda: G.random_planar_triangulation(True), "n must be an integer, got True"),
                      (lambda: G.icosphere(np.bool_(True)), "subdivisions must be an integer"),
                      (lambda: G.random_planar_triangulation(4.7), "n must be an integer, got 4.7"),
                      (lambda: G.icosphere(2.5), "subdivisions must be an integer"),
                      (lambda: G.icosphere(1, radius=float("nan")), "radius must be a finite number"),
                      (lambda: G.icosphere(1, radius="x"), "radius"),
                      (lambda: G.random_sphere_points(-1), r"n must be in \[0, 2\^30\]")]:
        with pytest.raises(errors.ArgumentError, match=msg):
            call()
    with pytest.raises(errors.MeshError, match="exceeds int32"):
        G.delaunay_square(10**12)
    with pytest.raises(errors.MeshError, match="every point lies on one line") as exc:
        G.delaunay_disk(np.array([[0, 0], [1, 0], [2, 0.0]]))
    assert "\n" not in str(exc.value)
    # integral floats and numpy integers are integers
    assert G.icosphere(2.0).num_vertices == 162
    assert G.random_planar_triangulation(np.int64(8), seed=np.uint64(3)).num_vertices == 8


@pytest.mark.parametrize("call,error,msg", [
    (lambda G: G.icosphere(11), errors.MeshError, r"icosphere: subdivisions must be in \[0, 10\], got 11"),
    (lambda G: G.icosphere(-1), errors.MeshError, r"icosphere: subdivisions must be in \[0, 10\], got -1"),
    (lambda G: G.sphere_hull(3), errors.MeshError, "sphere_hull: need at least 4 points, got 3"),
    (lambda G: G.delaunay_disk(np.zeros((2, 2))), errors.EmptyMeshError,
     "delaunay_disk: need at least 3 points, got 2"),
    (lambda G: G.delaunay_square(2), errors.MeshError, "delaunay_square: need at least 3 points, got 2"),
    (lambda G: G.random_planar_triangulation(2**30 + 1), errors.MeshError,
     "random_planar_triangulation: n = 1073741825 exceeds int32 dart ids"),
])
def test_generator_sizes_out_of_range_are_named(call, error, msg):
    from jaxcds import generators as G

    with pytest.raises(error, match=msg):
        call(G)


def test_random_planar_triangulation_refuses_unknown_positions_before_sampling(monkeypatch):
    """The faces (3.5 s at 10M vertices) were sampled before ``positions`` was looked at."""
    from jaxcds import generators as G

    def sampled(*a, **k):
        raise AssertionError("the faces were sampled before the refusal")

    monkeypatch.setattr(G, "random_planar_triangulation_faces", sampled)
    with pytest.raises(errors.MeshError, match="positions must be 'sphere', got 'plane'"):
        G.random_planar_triangulation(10, positions="plane")


def test_random_planar_triangulation_names_positions_that_are_no_string():
    """An array as ``positions`` raised numpy's untyped 'truth value' ValueError."""
    from jaxcds import generators as G

    with pytest.raises(errors.MeshError, match="positions must be 'sphere', got array"):
        G.random_planar_triangulation(10, positions=np.array(["sphere", "plane"]))


def test_delaunay_disk_names_a_point_qhull_dropped_and_its_neighbour():
    """A point 1e-17 from another is distinct for np.unique but merged by Qhull; the message
    guessed 'collinear input?' and did not name the point it was merged with."""
    from jaxcds import generators as G

    with pytest.raises(errors.MeshError, match=r"delaunay_disk: point 3 .* is not a vertex of the triangulation: "
                                               r"Qhull dropped it \(the nearest point, 0, is 1e-17 away"):
        G.delaunay_disk(np.array([[0, 0], [1, 0], [0, 1], [1e-17, 0]], float))
