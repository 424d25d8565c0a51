"""Mesh generators: icospheres, convex hulls of random sphere points, Delaunay triangulations of
random points in a square (optionally closed by one dummy vertex), and **uniform random planar
triangulations** with the Poulalhon--Schaeffer sampler.

Every generator returns a :class:`jaxcds.mesh.TriMesh` (float64 positions, int32 faces,
counter-clockwise seen from outside / from ``+z`` for planar meshes) and is deterministic for a
given ``seed``.

The random planar triangulations are the ones the CDS paper uses in its experiments (Castelli
Aleardi and Devillers, *Array-based compact data structures for triangulations*, Sec. 4,
reference [38]: D. Poulalhon and G. Schaeffer, *Optimal coding and sampling of triangulations*,
Algorithmica 46(3-4), 2006). The sampler is the PS bijection:

1. draw a uniform *blossoming tree*: a plane tree with ``k = n - 2`` nodes, each node carrying
   exactly two *stems* (dangling half-edges), planted at a corner of its root. Such trees are
   counted by ``T = z / (1 - T)^3``, i.e. ``(1/(4k-1)) C(4k-1, k)`` of them; they are drawn in
   linear time with the cycle lemma (:func:`_blossoming_word`);
2. *partial closure*: walking around the tree (contour order), every stem followed by two edge sides is
   closed into a triangle (a stack makes this one linear pass, :func:`_closure`);
3. *complete closure*: two new vertices ``A`` and ``B`` (joined by an edge) receive the stems
   left open; the two places where two open stems are consecutive split them between ``A`` and
   ``B`` (a fair coin decides which side is ``A``).

Every closure of such a tree is a simple triangulation of the sphere (3-connected for
``n >= 4``), and closing a uniform planted tree (with the coin) gives a uniform *rooted*
triangulation with ``n`` vertices: an unlabelled triangulation ``T`` appears with probability
proportional to ``2 E / |Aut+(T)|`` (checked exhaustively for ``n <= 8`` in
``tests/test_generators.py``). The degree distribution then tends to the law
``p_i = 16 (i - 2) / i * C(2i - 2, i - 1) * (3/16)^i`` quoted in CDS Sec. 4.4
(:func:`degree_law`; ``p_6 ~ 11.68%``).
"""

from __future__ import annotations

import math
import numba
import numpy as np

from jaxcds import errors
from jaxcds._args import is_integer
from jaxcds.mesh import TriMesh
from jaxcds.polylla_io import qhull_failure_reason, twice_signed_areas

__all__ = [
    "icosphere",
    "sphere_hull",
    "delaunay_disk",
    "delaunay_square",
    "random_planar_triangulation",
    "random_planar_triangulation_faces",
    "degree_law",
    "random_sphere_points",
]

# ---------------------------------------------------------------------------------- simple ones
def _count(name: str, value) -> int:
    """An integer argument (a numpy integer, or a float with an integral value) as an int;
    :class:`~jaxcds.errors.ArgumentError` naming it otherwise (4.7 was truncated to 4)."""
    if is_integer(value):
        return int(value)
    if isinstance(value, (float, np.floating)) and float(value).is_integer():
        return int(value)
    raise errors.ArgumentError(f"{name} must be an integer, got {value!r}")


def _seed(name: str, seed) -> int:
    """A seed for :func:`numpy.random.default_rng`: an integer >= 0, named otherwise."""
    s = _count(name, seed)
    if s < 0:
        raise errors.ArgumentError(f"{name} must be >= 0 (numpy's seeds are non-negative), got {seed!r}")
    return s


def icosphere(subdivisions: int = 3, radius: float = 1.0) -> TriMesh:
    """Icosahedron subdivided ``subdivisions`` times (loop-style 1:4 splits), projected on the
    sphere: ``10 * 4**s + 2`` vertices, all of degree 6 except the 12 of degree 5.

    ``icosphere(8)`` has 655,362 vertices (the benchmark mesh of the issue)."""
    s = _count("icosphere: subdivisions", subdivisions)
    if s < 0 or s > 10:
        raise errors.MeshError(f"icosphere: subdivisions must be in [0, 10], got {subdivisions}")
    try:
        r = float(radius)
    except (TypeError, ValueError):
        r = float("nan")
    if not (np.isfinite(r) and r > 0):
        raise errors.ArgumentError(f"icosphere: radius must be a finite number > 0, got {radius!r}")
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=s, radius=r)
    return TriMesh(vertices=np.ascontiguousarray(m.vertices, dtype=np.float64),
                   faces=np.ascontiguousarray(m.faces, dtype=np.int32), source=f"icosphere({s})")


def random_sphere_points(n: int, seed: int = 0) -> np.ndarray:
    """``(n, 3)`` float64 points drawn uniformly on the unit sphere (normalised Gaussians)."""
    n = _count("random_sphere_points: n", n)
    if not 0 <= n <= 2**30:
        raise errors.ArgumentError(f"random_sphere_points: n must be in [0, 2^30], got {n}")
    rng = np.random.default_rng(_seed("random_sphere_points: seed", seed))
    p = rng.standard_normal((n, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    return p


def sphere_hull(n: int, seed: int = 0) -> TriMesh:
    """Convex hull of ``n`` random points on the unit sphere (every point is a hull vertex):
    a closed genus-0 triangulation, faces oriented outward. Random (non-uniform) degrees, so
    a "realistic" irregular mesh of any size."""
    n = _count("sphere_hull: n", n)
    if n < 4:
        raise errors.MeshError(f"sphere_hull: need at least 4 points, got {n}")
    from scipy.spatial import ConvexHull

    p = random_sphere_points(n, seed)
    hull = ConvexHull(p)
    f = np.ascontiguousarray(hull.simplices, dtype=np.int32)
    # qhull's facet equations carry outward normals (the origin may lie outside the hull of few
    # points, so "normal . centroid > 0" is not a safe test)
    f = _orient_like(p, f, hull.equations[:, :3])
    if np.unique(f).size != n:  # pragma: no cover - probability 0 on the sphere
        raise errors.StructureError(f"sphere_hull: only {np.unique(f).size} of {n} points on the hull")
    return TriMesh(vertices=p, faces=f, source=f"sphere_hull({n}, seed={seed})")


def _orient_like(p: np.ndarray, f: np.ndarray, outward: np.ndarray) -> np.ndarray:
    """Flip the faces whose normal points against ``outward`` (one vector per face)."""
    a, b, c = p[f[:, 0]], p[f[:, 1]], p[f[:, 2]]
    inward = np.einsum("ij,ij->i", np.cross(b - a, c - a), outward) < 0
    f = f.copy()
    f[inward] = f[inward][:, [0, 2, 1]]
    return f


def delaunay_disk(points) -> TriMesh:
    """Delaunay triangulation of 2-D ``points`` (``(n, 2)``; ``z = 0`` in the result), faces
    counter-clockwise seen from ``+z``. One boundary loop (the convex hull). Duplicate points
    are refused."""
    from scipy.spatial import Delaunay

    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise errors.MeshError(f"delaunay_disk: points must have shape (n, 2), got {pts.shape}")
    if pts.shape[0] < 3:
        raise errors.EmptyMeshError(f"delaunay_disk: need at least 3 points, got {pts.shape[0]}")
    if not np.all(np.isfinite(pts)):
        bad = int(np.nonzero(~np.all(np.isfinite(pts), axis=1))[0][0])
        raise errors.NonFiniteCoordinateError(f"delaunay_disk: point {bad} is not finite: {pts[bad]}")
    _, first, counts = np.unique(pts, axis=0, return_index=True, return_counts=True)
    if np.any(counts > 1):
        dup = int(first[np.argmax(counts > 1)])
        raise errors.MeshError(f"delaunay_disk: point {dup} {pts[dup]} appears {counts.max()} times")
    try:
        tri = Delaunay(pts)
    except Exception as exc:  # Qhull: collinear points, coordinates out of its range
        raise errors.MeshError(f"delaunay_disk: Delaunay triangulation failed: "
                               f"{qhull_failure_reason(exc, pts)}") from None
    f = np.ascontiguousarray(tri.simplices, dtype=np.int32)
    cw = twice_signed_areas(pts, f) < 0
    f[cw] = f[cw][:, [0, 2, 1]]
    used = np.zeros(pts.shape[0], bool)
    used[f.ravel()] = True
    if not used.all():  # near-duplicate or coplanar/collinear leftovers: qhull drops them
        k = int(np.argmin(used))
        dist = np.linalg.norm(pts - pts[k], axis=1)
        dist[k] = np.inf
        j = int(np.argmin(dist))  # a point within rounding of another was the usual cause
        raise errors.MeshError(
            f"delaunay_disk: point {k} {pts[k]} is not a vertex of the triangulation: Qhull dropped "
            f"it (the nearest point, {j}, is {dist[j]:.3g} away; points closer than rounding are "
            "merged, and collinear leftovers dropped)")
    v = np.concatenate([pts, np.zeros((pts.shape[0], 1))], axis=1)
    return TriMesh(vertices=v, faces=f, source=f"delaunay_disk({pts.shape[0]})")


def delaunay_square(n: int, seed: int = 0, closed: bool = False) -> TriMesh:
    """Delaunay triangulation of ``n`` uniform random points in the unit square ``[0, 1]^2``.

    With ``closed=True`` the hull is closed by one dummy vertex (at the hull's centroid, index
    ``n``) joined to every hull vertex (:func:`jaxcds.mesh.close_boundaries`, CDS Sec. 4.5):
    a closed genus-0 triangulation with ``n + 1`` vertices whose dummy vertex and faces are
    flagged in ``dummy_vertices`` / ``dummy_faces``."""
    n = _count("delaunay_square: n", n)
    if n < 3:
        raise errors.MeshError(f"delaunay_square: need at least 3 points, got {n}")
    if n > 2**30:
        raise errors.MeshError(f"delaunay_square: n = {n} exceeds int32 ids")
    rng = np.random.default_rng(_seed("delaunay_square: seed", seed))
    m = delaunay_disk(rng.random((n, 2)))
    m = TriMesh(vertices=m.vertices, faces=m.faces,
                source=f"delaunay_square({n}, seed={seed}{', closed' if closed else ''})")
    if closed:
        from jaxcds.mesh import close_boundaries

        m = close_boundaries(m)
    return m


# ---------------------------------------------------------------------------------- PS sampler
def degree_law(i) -> np.ndarray:
    """Limit law of the degree of a vertex in a uniform random planar triangulation (CDS Sec.
    4.4, after [23, 34]): ``p_i = 16 (i - 2) / i * C(2i - 2, i - 1) * (3/16)^i`` for ``i >= 3``
    (0 below). ``degree_law(6) ~ 0.1168``; the ``p_i`` sum to 1."""
    i = np.atleast_1d(np.asarray(i, dtype=np.int64))
    out = np.zeros(i.shape, dtype=np.float64)
    for k, d in enumerate(i.ravel()):
        if d >= 3:
            # log-space: C(2d-2, d-1) overflows float64 beyond d ~ 500
            lg = (math.lgamma(2 * d - 1) - 2 * math.lgamma(d) + d * math.log(3 / 16))
            out.ravel()[k] = 16.0 * (d - 2) / d * math.exp(lg)
    return out


def _blossoming_word(k: int, rng: np.random.Generator) -> np.ndarray:
    """A uniform planted blossoming tree with ``k`` nodes, as its prefix word (int8, length 4k):
    ``1`` opens a node, ``0`` closes one of its three child groups; a node reads
    ``1 G1 0 G2 0 G3 0`` where the ``G`` are its children, the first two ``0`` are its stems.

    Cycle lemma: words of ``k`` ones (+3) and ``3k - 1`` zeros (-1) sum to +1; exactly one
    rotation -- the one starting just after the *last* minimum of the prefix sums -- has all
    prefix sums positive, and those are the tree words without their final ``0``. A uniform
    arrangement rotated that way is therefore a uniform tree."""
    m = 4 * k - 1
    z = np.zeros(m, dtype=np.int8)
    z[:k] = 1
    z = rng.permutation(z)
    return _rotate_word(z)


@numba.njit(cache=True)
def _rotate_word(z):
    m = z.shape[0]
    s = 0
    best = 0
    arg = 0  # position i (0..m-1) of the last minimum of P_0..P_{m-1}
    for i in range(m):
        if s <= best:
            best = s
            arg = i
        s += 3 if z[i] == 1 else -1
    w = np.empty(m + 1, dtype=np.int8)
    for j in range(m):
        w[j] = z[(arg + j) % m]
    w[m] = 0
    return w


@numba.njit(cache=True)
def _contour(w, k):
    """Contour of the tree of word ``w``: for each of the ``4k - 2`` letters, its kind (``1``: a
    stem, sitting at a vertex; ``0``: a side of an edge, from a vertex to the next one along the
    contour) and its vertices (``u``: where it starts; ``v``: where a side ends). Vertices are
    numbered in preorder. The walk keeps the tree on its right."""
    L = 4 * k - 2
    kind = np.empty(L, dtype=np.int8)
    cu = np.empty(L, dtype=np.int32)
    cv = np.empty(L, dtype=np.int32)
    st_node = np.empty(k, dtype=np.int32)
    st_left = np.empty(k, dtype=np.int8)
    top = -1
    nodes = 0
    pos = 0
    for i in range(w.shape[0]):
        if w[i] == 1:
            c = nodes
            nodes += 1
            if top >= 0:  # side parent -> child
                kind[pos] = 0
                cu[pos] = st_node[top]
                cv[pos] = c
                pos += 1
            top += 1
            st_node[top] = c
            st_left[top] = 3
        else:
            v = st_node[top]
            st_left[top] -= 1
            if st_left[top] > 0:  # a stem at v
                kind[pos] = 1
                cu[pos] = v
                cv[pos] = -1
                pos += 1
            else:
                top -= 1
                if top >= 0:  # side child -> parent
                    kind[pos] = 0
                    cu[pos] = v
                    cv[pos] = st_node[top]
                    pos += 1
    return kind, cu, cv


@numba.njit(cache=True)
def _closure(kind, cu, cv, k, swap):
    """Partial then complete closure (PS Sec. 3) of a blossoming contour; returns ``(2k, 3)``
    int32 faces on the ``k + 2`` vertices (tree nodes ``0..k-1``, ``A = k``, ``B = k + 1``)."""
    L = kind.shape[0]
    # Start just after the first minimum of the walk stem=+1 / side=-1 (total +2): then every
    # stem that ever closes closes within one linear pass (no wrap-around).
    s = 0
    best = 0
    start = 0
    for i in range(L):
        s += 1 if kind[i] == 1 else -1
        if s < best:
            best = s
            start = i + 1
    start = start % L
    faces = np.empty((2 * k, 3), dtype=np.int32)
    nf = 0
    sk = np.empty(L, dtype=np.int8)
    su = np.empty(L, dtype=np.int32)
    sv = np.empty(L, dtype=np.int32)
    top = -1
    for j in range(L):
        i = (start + j) % L
        top += 1
        sk[top] = kind[i]
        su[top] = cu[i]
        sv[top] = cv[i]
        # local closure: stem at u, side u->v, side v->w  ==>  triangle (u, v, w), new side u->w
        while top >= 2 and sk[top] == 0 and sk[top - 1] == 0 and sk[top - 2] == 1:
            u = su[top - 1]
            v = sv[top - 1]
            ww = sv[top]
            faces[nf, 0] = u
            faces[nf, 1] = v
            faces[nf, 2] = ww
            nf += 1
            top -= 2
            sk[top] = 0
            su[top] = u
            sv[top] = ww
    R = top + 1
    # complete closure: the residual cyclic word has exactly two places "stem stem" (C and D)
    ci = -1
    di = -1
    for i in range(R):
        if sk[i] == 1 and sk[(i + 1) % R] == 1:
            if ci < 0:
                ci = i
            elif di < 0:
                di = i
            else:
                return faces[:0]  # invalid (cannot happen for a blossoming tree); caller checks
    if di < 0:
        return faces[:0]
    if swap:
        ci, di = di, ci
    A = k
    B = k + 1
    # stems after C up to D go to A, after D up to C go to B; each side x->y between two of
    # them closes the triangle (x, y, A) (resp. B)
    for seg in range(2):
        a0 = ci if seg == 0 else di
        a1 = di if seg == 0 else ci
        X = A if seg == 0 else B
        i = (a0 + 1) % R
        while i != a1:
            if sk[i] == 0:
                faces[nf, 0] = su[i]
                faces[nf, 1] = sv[i]
                faces[nf, 2] = X
                nf += 1
            i = (i + 1) % R
    # corner at C (B-stem then A-stem) and at D (A-stem then B-stem)
    faces[nf, 0] = su[ci]
    faces[nf, 1] = A
    faces[nf, 2] = B
    nf += 1
    faces[nf, 0] = su[di]
    faces[nf, 1] = B
    faces[nf, 2] = A
    nf += 1
    return faces[:nf]


def _close_word(w: np.ndarray, k: int, swap: bool) -> np.ndarray:
    kind, cu, cv = _contour(w, k)
    f = _closure(kind, cu, cv, k, bool(swap))
    if f.shape[0] != 2 * k:  # pragma: no cover - would be a bug in the closure
        raise errors.StructureError(
            f"Poulalhon-Schaeffer closure produced {f.shape[0]} faces instead of {2 * k}")
    return f


def random_planar_triangulation_faces(n: int, seed: int = 0) -> np.ndarray:
    """Faces only (``(2n - 4, 3)`` int32) of :func:`random_planar_triangulation`."""
    n = _count("random_planar_triangulation: n", n)
    if n < 4:
        raise errors.MeshError(
            f"random_planar_triangulation: need n >= 4 vertices (a simple triangulation of the "
            f"sphere), got {n}")
    if n > 2**30:
        raise errors.MeshError(f"random_planar_triangulation: n = {n} exceeds int32 dart ids")
    rng = np.random.default_rng(_seed("random_planar_triangulation: seed", seed))
    k = n - 2
    w = _blossoming_word(k, rng)
    swap = bool(rng.integers(2))
    return _close_word(w, k, swap)


def random_planar_triangulation(n: int, seed: int = 0, positions: str = "sphere") -> TriMesh:
    """A uniform random planar triangulation with ``n`` vertices (Poulalhon--Schaeffer sampler,
    CDS Sec. 4 ref. [38]): closed, genus 0, simple (no loops, no multiple edges, hence
    3-connected), ``2n - 4`` faces, consistently oriented; linear time (numba), seeded.

    Vertices ``0..n-3`` are the tree nodes in preorder (so neighbours tend to have close ids,
    as in a mesh file), ``n-2`` and ``n-1`` the two vertices added by the complete closure.

    Args:
      n: number of vertices (>= 4).
      seed: seed of :func:`numpy.random.default_rng`; same seed, same mesh.
      positions: ``"sphere"``: uniform random points on the unit sphere (seeded by ``seed``),
        independent of the connectivity. They make normals and any geometric kernel timeable,
        but they are *not* an embedding (triangles cross each other). A Tutte (barycentric)
        embedding is no better: for random triangulations most of its triangles have areas
        below 1e-20, and its sparse solve is far from linear time at 10M vertices.

    Time and memory (2-core dev machine, see ``benchmarks/RESULTS.md``): 1M vertices ~0.3 s
    for the faces, 10M vertices ~3.5 s for the faces, ~4.7 s with positions, 1.4 GB peak RSS.

    Raises:
      MeshError: ``n < 4`` or ``n`` too large for int32 ids (also a ``ValueError``).
    """
    # before the faces (3.5 s at 10M vertices spent for a refusal); an array compared
    # elementwise raised numpy's untyped "truth value" ValueError
    if not isinstance(positions, str) or positions != "sphere":
        raise errors.MeshError(f"random_planar_triangulation: positions must be 'sphere', got {positions!r}")
    f = random_planar_triangulation_faces(n, seed)
    n = int(n)
    v = random_sphere_points(n, np.random.default_rng(seed).integers(2**63))
    return TriMesh(vertices=v, faces=f, source=f"random_planar_triangulation({n}, seed={seed})")
