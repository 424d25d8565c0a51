"""An exactly Delaunay triangulation of a 2-D point set: Qhull's, repaired with exact predicates.

Why: Polylla's pipeline triangulates with Shewchuk's Triangle, which decides every orientation
and in-circle test exactly. Qhull (``scipy.spatial.Delaunay``) works in floating point: it
merges points nearer than its precision (about 3e-8 of the extent: 39 of 682 real-world sets
lost points), its ``Qt`` option leaves zero-area triangles, and near (nearly) cocircular
points its triangulation is only approximately Delaunay. For a set without four exactly
cocircular points the Delaunay triangulation is unique, so an exact one is Triangle's.

What is done here, after Qhull (Lawson, "Software for C1 surface interpolation", 1977;
Shewchuk, "Adaptive precision floating-point arithmetic and fast robust geometric
predicates", 1997, for the filters):

- zero-area triangles are flipped away (the edge opposite the middle corner), or dropped
  where that edge is on the hull;
- reflex hull corners (Qhull's hull is convex up to rounding) get the triangle that fills them;
- every distinct point in no triangle is located by a walk with exact orientation tests and
  inserted (split triangle, split edge, or triangles to the hull edges it sees);
- every interior edge is tested in a vectorised float64 in-circle filter with Shewchuk's
  ``iccerrboundA``; the few it cannot decide are decided exactly (Python integers on the
  float64 coordinates, dyadic rationals brought to one denominator); illegal edges are
  flipped until none is left (Lawson's flips terminate). Exactly cocircular quadruples keep
  Qhull's diagonal (either is Delaunay).

Exact tests use the coordinates as given, not the centred and scaled ones Qhull saw (centring
rounds). Should Qhull fail, or its output not be a triangulation these repairs can mend (an
inverted triangle), the triangulation is built here from scratch by the same insertion.

Everything is numpy on the host; the repairs loop in Python over the few triangles they touch.
"""

from __future__ import annotations

import math

import numba
import numpy as np

_EPS = 2.0 ** -53
_CCW_BOUND = (3.0 + 16.0 * _EPS) * _EPS  # Shewchuk's ccwerrboundA
_ICC_BOUND = (10.0 + 96.0 * _EPS) * _EPS  # Shewchuk's iccerrboundA
#: below this the filters' products may have lost bits to subnormals: decided exactly
_TINY = 2.0 ** -900


class Collinear(Exception):
    """Every point lies on one line (exactly): no triangulation."""


class _Broken(Exception):
    """The triangulation being mended is not one (a neighbour that does not list its
    neighbour back): the caller builds from scratch."""


def _slot(rows: np.ndarray, r: int, x: int) -> int:
    """Where ``x`` is in row ``r`` of ``rows`` (three entries); :class:`_Broken` if nowhere."""
    a, b, c = rows[r].tolist()
    if a == x:
        return 0
    if b == x:
        return 1
    if c == x:
        return 2
    raise _Broken


def scaled(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(q, lossy)``: ``points`` times the power of two that brings the largest coordinate into
    ``[0.5, 1)`` (the filters' products neither overflow nor underflow), and which points lost
    bits to that scaling (a tiny coordinate beside a huge one became subnormal): the filters
    leave those to the exact tests."""
    big = float(np.max(np.abs(points)))
    if big == 0.0:
        return points.copy(), np.zeros(points.shape[0], bool)
    e = int(np.frexp(big)[1])
    q = np.ldexp(points, -e)
    return q, (np.ldexp(q, e) != points).any(axis=1)


def _exact_ints(values) -> list[int]:
    """Dyadic rationals (float64s) as integers over one common power-of-two denominator (exact;
    every test here is homogeneous, so its sign is unchanged)."""
    ratios = [float(x).as_integer_ratio() for x in values]
    den = max(d for _, d in ratios)
    return [n * (den // d) for n, d in ratios]


def exact_orient(p: np.ndarray, a: int, b: int, c: int) -> int:
    ax, ay, bx, by, cx, cy = _exact_ints((*p[a], *p[b], *p[c]))
    d = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    return (d > 0) - (d < 0)


def exact_incircle(p: np.ndarray, a: int, b: int, c: int, d: int) -> int:
    """Sign of the in-circle determinant: positive when ``d`` is inside the circle through the
    counter-clockwise ``a, b, c``."""
    ax, ay, bx, by, cx, cy, dx, dy = _exact_ints((*p[a], *p[b], *p[c], *p[d]))
    adx, ady, bdx, bdy, cdx, cdy = ax - dx, ay - dy, bx - dx, by - dy, cx - dx, cy - dy
    det = ((adx * adx + ady * ady) * (bdx * cdy - cdx * bdy)
           + (bdx * bdx + bdy * bdy) * (cdx * ady - adx * cdy)
           + (cdx * cdx + cdy * cdy) * (adx * bdy - bdx * ady))
    return (det > 0) - (det < 0)


def incircle_filter(q: np.ndarray, a, b, c, d) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised in-circle signs of ``(a, b, c, d)`` id arrays on the scaled points ``q``, and
    which of them the float64 evaluation cannot vouch for (Shewchuk's forward error bound
    ``iccerrboundA`` times the permanent, or products near the subnormal range).

    One numba loop (the same float operations in the same order as numpy's vectorised form,
    without its twenty ``(E,)`` temporaries: 1.46 s -> under 0.2 s over the 3M edges of 1M
    points)."""
    ids = [np.ascontiguousarray(x, dtype=np.int64) for x in (a, b, c, d)]
    sign = np.empty(ids[0].shape[0], np.int8)
    unsure = np.empty(ids[0].shape[0], np.bool_)
    _incircle_filter(np.ascontiguousarray(q, dtype=np.float64), *ids, sign, unsure)
    return sign, unsure


@numba.njit(cache=True, nogil=True)
def _incircle_filter(q, a, b, c, d, sign, unsure):
    for i in range(a.shape[0]):
        dx, dy = q[d[i], 0], q[d[i], 1]
        adx, ady = q[a[i], 0] - dx, q[a[i], 1] - dy
        bdx, bdy = q[b[i], 0] - dx, q[b[i], 1] - dy
        cdx, cdy = q[c[i], 0] - dx, q[c[i], 1] - dy
        bc1, bc2 = bdx * cdy, cdx * bdy
        ca1, ca2 = cdx * ady, adx * cdy
        ab1, ab2 = adx * bdy, bdx * ady
        alift = adx * adx + ady * ady
        blift = bdx * bdx + bdy * bdy
        clift = cdx * cdx + cdy * cdy
        det = alift * (bc1 - bc2) + blift * (ca1 - ca2) + clift * (ab1 - ab2)
        perm = ((abs(bc1) + abs(bc2)) * alift + (abs(ca1) + abs(ca2)) * blift
                + (abs(ab1) + abs(ab2)) * clift)
        sign[i] = 1 if det > 0 else (-1 if det < 0 else 0)
        unsure[i] = (abs(det) <= _ICC_BOUND * perm) or (perm < _TINY)


class _Mesh:
    """A triangulation being repaired: ``v[t]`` counter-clockwise corners, ``n[t][k]`` the
    triangle across the edge opposite corner ``k`` (-1 on the hull), dead triangles marked by
    ``v[t][0] == -1``. Grown by doubling; predicates filtered, then exact."""

    def __init__(self, p, q, lossy, v, n, lists: bool = False):
        self.p, self.q, self.lossy = p, q, lossy
        if lists:  # Python floats for the scalar predicates: several times faster than numpy's
            self.q, self.lossy = q.tolist(), lossy.tolist()
        self.qa, self.lossy_a = q, lossy  # the arrays, for the vectorised filter
        self.count = v.shape[0]
        self.v = np.array(v, np.int64)
        self.n = np.array(n, np.int64)
        self.rng = np.random.default_rng(0)

    # ------------------------------------------------------------------ predicates
    def orient(self, a: int, b: int, c: int) -> int:
        q = self.q
        ax, ay = q[a]
        bx, by = q[b]
        cx, cy = q[c]
        left = (bx - ax) * (cy - ay)
        right = (by - ay) * (cx - ax)
        det = left - right
        mag = abs(left) + abs(right)
        if abs(det) > _CCW_BOUND * mag and mag >= _TINY and not (
                self.lossy[a] or self.lossy[b] or self.lossy[c]):
            return 1 if det > 0 else -1
        return exact_orient(self.p, a, b, c)

    def incircle(self, a: int, b: int, c: int, d: int) -> int:
        """:func:`incircle_filter` for one quadruple, in Python floats, else exact."""
        q = self.q
        dx, dy = q[d]
        ax, ay = q[a]
        bx, by = q[b]
        cx, cy = q[c]
        adx, ady, bdx, bdy, cdx, cdy = ax - dx, ay - dy, bx - dx, by - dy, cx - dx, cy - dy
        bc1, bc2, ca1, ca2, ab1, ab2 = bdx * cdy, cdx * bdy, cdx * ady, adx * cdy, adx * bdy, bdx * ady
        alift, blift, clift = adx * adx + ady * ady, bdx * bdx + bdy * bdy, cdx * cdx + cdy * cdy
        det = alift * (bc1 - bc2) + blift * (ca1 - ca2) + clift * (ab1 - ab2)
        perm = ((abs(bc1) + abs(bc2)) * alift + (abs(ca1) + abs(ca2)) * blift
                + (abs(ab1) + abs(ab2)) * clift)
        lossy = self.lossy
        if abs(det) > _ICC_BOUND * perm and perm >= _TINY and not (
                lossy[a] or lossy[b] or lossy[c] or lossy[d]):
            return 1 if det > 0 else -1
        return exact_incircle(self.p, a, b, c, d)

    # ------------------------------------------------------------------ storage
    def new(self, verts, nbrs) -> int:
        if self.count == self.v.shape[0]:
            grow = max(16, self.count)
            self.v = np.concatenate([self.v, np.full((grow, 3), -1, np.int64)])
            self.n = np.concatenate([self.n, np.full((grow, 3), -1, np.int64)])
        t = self.count
        self.count += 1
        self.set(t, verts, nbrs)
        return t

    def set(self, t, verts, nbrs) -> None:
        self.v[t] = verts
        self.n[t] = nbrs

    def relink(self, s: int, old: int, new: int) -> None:
        """Triangle ``s`` (if any) now has ``new`` where it had the neighbour ``old``."""
        if s >= 0:
            self.n[s, _slot(self.n, s, old)] = new

    def corner(self, t: int, x: int) -> int:
        return _slot(self.v, t, x)

    def faces(self) -> np.ndarray:
        v = self.v[:self.count]
        return v[v[:, 0] >= 0]

    # ------------------------------------------------------------------ flips
    def flip(self, t: int, k: int) -> int:
        """Flip the edge opposite corner ``k`` of ``t``; returns the other triangle ``u``. After
        it, ``t = (a, b, d)`` and ``u = (a, d, c)`` where ``a`` was ``t``'s corner ``k`` and
        ``d`` the apex across."""
        v, n = self.v, self.n
        u = int(n[t, k])
        a, b, c = int(v[t, k]), int(v[t, (k + 1) % 3]), int(v[t, (k + 2) % 3])
        j = _slot(n, u, t)
        d = int(v[u, j])
        t_b, t_c = int(n[t, (k + 1) % 3]), int(n[t, (k + 2) % 3])
        u_c, u_b = int(n[u, (j + 1) % 3]), int(n[u, (j + 2) % 3])
        self.set(t, (a, b, d), (u_c, u, t_c))
        self.set(u, (a, d, c), (u_b, t_b, t))
        self.relink(t_b, t, u)
        self.relink(u_c, u, t)
        return u

    def legalize(self, stack: list) -> int:
        """Lawson's flips from the edges ``(t, k)`` on ``stack`` (the edge opposite corner
        ``k``), each flip pushing the four edges around its quadrilateral; returns how many."""
        flips = 0
        v, n = self.v, self.n
        while stack:
            t, k = stack.pop()
            u = int(n[t, k])
            if u < 0 or v[t, 0] < 0:
                continue
            j = _slot(n, u, t)
            if self.incircle(int(v[t, 0]), int(v[t, 1]), int(v[t, 2]), int(v[u, j])) <= 0:
                continue
            u = self.flip(t, k)
            flips += 1
            stack.extend(((t, 0), (t, 2), (u, 0), (u, 1)))
        return flips

    # ------------------------------------------------------------------ insertion
    def locate(self, x: int, t: int):
        """Walk from ``t`` to point ``x`` (visibility walk, edges tried from a random one, which
        terminates on any triangulation): ``("in", t, on)`` with ``on`` the corners whose
        opposite edge holds ``x``, or ``("out", t, k)`` with the hull edge opposite corner
        ``k`` of ``t`` seeing ``x``."""
        v, n = self.v, self.n
        for _ in range(4 * self.count + 64):  # a walk longer than that circles: not a mesh
            r = int(self.rng.integers(3))
            on = []
            for i in range(3):
                k = (r + i) % 3
                o = self.orient(int(v[t, (k + 1) % 3]), int(v[t, (k + 2) % 3]), x)
                if o < 0:
                    if n[t, k] < 0:
                        return "out", t, k
                    t = int(n[t, k])
                    break
                if o == 0:
                    on.append(k)
            else:
                return "in", t, on
        raise _Broken

    def insert(self, x: int, start: int) -> int:
        """Insert point ``x`` (distinct from every vertex) and restore the Delaunay property
        around it; returns a triangle at ``x``."""
        where, t, k = self.locate(x, start)
        if where == "out":
            made = self._insert_outside(x, t, k)
        elif len(k) == 0:
            made = self._split_triangle(x, t)
        else:
            made = self._split_edge(x, t, k[0])
        self.legalize([(s, self.corner(s, x)) for s in made])
        return made[0]

    def _split_triangle(self, x, t):
        v, n = self.v, self.n
        a, b, c = (int(y) for y in v[t])
        na, nb, nc = (int(y) for y in n[t])
        t1, t2 = self.new((b, c, x), (-1, -1, na)), self.new((c, a, x), (-1, -1, nb))
        self.set(t, (a, b, x), (t1, t2, nc))
        self.n[t1, :2] = (t2, t)
        self.n[t2, :2] = (t, t1)
        self.relink(na, t, t1)
        self.relink(nb, t, t2)
        return [t, t1, t2]

    def _split_edge(self, x, t, k):
        v, n = self.v, self.n  # read before new() may grow (and replace) the arrays
        a, b, c = int(v[t, k]), int(v[t, (k + 1) % 3]), int(v[t, (k + 2) % 3])
        u, n_b, n_c = int(n[t, k]), int(n[t, (k + 1) % 3]), int(n[t, (k + 2) % 3])
        if u >= 0:
            j = _slot(n, u, t)
            d = int(v[u, j])
            m_c, m_b = int(n[u, (j + 1) % 3]), int(n[u, (j + 2) % 3])
        t2 = self.new((a, x, c), (-1, n_b, t))
        self.set(t, (a, b, x), (-1, t2, n_c))
        self.relink(n_b, t, t2)
        if u < 0:
            return [t, t2]
        u2 = self.new((d, x, b), (t, m_c, u))
        self.set(u, (d, c, x), (t2, u2, m_b))
        self.relink(m_c, u, u2)
        self.n[t, 0], self.n[t2, 0] = u2, u
        return [t, t2, u, u2]

    def next_hull(self, t, k):
        """The hull edge after the one opposite corner ``k`` of ``t`` (counter-clockwise)."""
        return self._around_to_hull(t, k, 2)

    def prev_hull(self, t, k):
        """The hull edge before the one opposite corner ``k`` of ``t``."""
        return self._around_to_hull(t, k, 1)

    def _around_to_hull(self, t, k, turn):
        """Walk around the end of edge ``(t, k)`` that corner ``(k + turn) % 3`` holds (``turn``
        2: its head, counter-clockwise; 1: its tail, clockwise) to the next hull edge."""
        i = (k + turn) % 3
        pivot = int(self.v[t, i])
        s = t
        for _ in range(self.count + 1):  # a fan that does not end is not a mesh
            j = (i + turn) % 3
            nx = int(self.n[s, j])
            if nx < 0:
                return s, j
            s, i = nx, self.corner(nx, pivot)
        raise _Broken

    def hull_edge(self, t, k):
        return int(self.v[t, (k + 1) % 3]), int(self.v[t, (k + 2) % 3])

    def _sees(self, x, e) -> bool:
        a, b = self.hull_edge(*e)
        return self.orient(a, b, x) < 0

    def _insert_outside(self, x, t, k):
        chain = [(t, k)]
        e = self.prev_hull(t, k)
        while e not in chain and self._sees(x, e):
            chain.insert(0, e)
            e = self.prev_hull(*e)
        e = self.next_hull(t, k)
        while e not in chain and self._sees(x, e):
            chain.append(e)
            e = self.next_hull(*e)
        made = []
        for s, j in chain:  # hull edge w_i -> w_i+1 gets (w_i+1, w_i, x)
            w0, w1 = self.hull_edge(s, j)
            m = self.new((w1, w0, x), (made[-1] if made else -1, -1, s))
            if made:
                self.n[made[-1], 1] = m
            self.n[s, j] = m
            made.append(m)
        return made

    # ------------------------------------------------------------------ Qhull's output mended
    def remove_flat(self, flat) -> bool:
        """Flip away (or, on the hull, drop) the zero-area triangles ``flat``; False when some
        cannot be (then the caller builds from scratch)."""
        todo = [int(t) for t in flat]
        while todo:
            left = []
            for t in todo:
                if self.v[t, 0] < 0:
                    continue
                if not self._unflatten(t):
                    left.append(t)
            if len(left) == len(todo):
                return False
            todo = left
        return True

    def _unflatten(self, t) -> bool:
        v, n, p = self.v, self.n, self.p
        ids = [int(y) for y in v[t]]
        if self.orient(*ids) != 0:
            return True  # mended by an earlier flip
        xs = [tuple(p[i]) for i in ids]
        k = sorted(range(3), key=lambda i: xs[i])[1]  # the middle corner (distinct points)
        u = int(n[t, k])
        if u < 0:  # the long edge is on the hull: the middle corner becomes a hull vertex
            self.relink(int(n[t, (k + 1) % 3]), t, -1)
            self.relink(int(n[t, (k + 2) % 3]), t, -1)
            v[t] = -1
            n[t] = -1
            return True
        j = _slot(n, u, t)
        m, d = ids[k], int(v[u, j])
        if self.orient(m, ids[(k + 1) % 3], d) <= 0 or self.orient(m, d, ids[(k + 2) % 3]) <= 0:
            return False  # the triangle across is flat too: later
        self.flip(t, k)
        return True

    def fill_reflex_hull(self) -> None:
        """Give every reflex hull corner the triangle that fills it, until the hull is convex."""
        n = self.n[:self.count]
        ts, ks = np.nonzero((n < 0) & (self.v[:self.count, :1] >= 0))
        work = list(zip(ts.tolist(), ks.tolist()))
        while work:
            t, k = work.pop()
            if self.n[t, k] >= 0 or self.v[t, 0] < 0:
                continue
            s, j = self.next_hull(t, k)
            a, b = self.hull_edge(t, k)
            c = self.hull_edge(s, j)[1]
            if self.orient(a, b, c) >= 0:
                continue
            f = self.new((a, c, b), (s, t, -1))
            self.n[t, k], self.n[s, j] = f, f
            work.extend([(f, 2), self.prev_hull(f, 2)])

    def hull_is_convex(self) -> bool:
        """One boundary cycle, turning left (or straight) at every corner, once around."""
        v, n = self.v[:self.count], self.n[:self.count]
        ts, ks = np.nonzero((n < 0) & (v[:, :1] >= 0))
        if ts.size < 3:
            return False
        start = (int(ts[0]), int(ks[0]))
        e, seen, corners = start, 0, []
        while True:
            corners.append(self.hull_edge(*e)[0])
            e = self.next_hull(*e)
            seen += 1
            if e == start or seen > ts.size:
                break
        if seen != ts.size:
            return False
        h = len(corners)
        if any(self.orient(corners[i - 1], corners[i], corners[(i + 1) % h]) < 0 for i in range(h)):
            return False
        # winding once: one lowest corner in (y, x) order, where the walk turns upwards
        ys = [tuple(self.p[c][::-1]) for c in corners]
        minima = sum(ys[i - 1] > ys[i] < ys[(i + 1) % h] for i in range(h))
        return minima == 1


def _edges(v: np.ndarray, n: np.ndarray):
    """Every interior edge once: ``(t, k, u, apex)``, the triangle ``u`` across the edge opposite
    corner ``k`` of ``t`` and its corner ``apex`` off that edge."""
    live = v[:, 0] >= 0
    t, k = np.nonzero((n > np.arange(n.shape[0])[:, None]) & live[:, None])
    u = n[t, k]
    j = np.argmax(n[u] == t[:, None], axis=1)
    return t, k, u, v[u, j]


def illegal_edges(m: _Mesh) -> list:
    """``(t, k)`` of every interior edge whose opposite apex lies strictly inside ``t``'s
    circumcircle: float filter for all, exact for the undecided."""
    v, n = m.v[:m.count], m.n[:m.count]
    t, k, u, d = _edges(v, n)
    sign, unsure = incircle_filter(m.qa, v[t, 0], v[t, 1], v[t, 2], d)
    unsure |= m.lossy_a[v[t]].any(axis=1) | m.lossy_a[d]
    for i in np.flatnonzero(unsure):
        sign[i] = exact_incircle(m.p, *(int(x) for x in v[t[i]]), int(d[i]))
    bad = np.flatnonzero(sign > 0)
    return list(zip(t[bad].tolist(), k[bad].tolist()))


def _orientations(m: _Mesh, faces: np.ndarray) -> np.ndarray:
    from jaxcds.polylla_io import orientation_signs

    return orientation_signs(m.p, faces)


def _make_delaunay(m: _Mesh) -> None:
    """Lawson's flips from every illegal interior edge. One global pass is enough: a flip
    pushes the four edges of its quadrilateral, the only ones whose test it changes, so when
    the stack is empty every edge is legal."""
    m.legalize(illegal_edges(m))


def _seed_triangle(p: np.ndarray, q: np.ndarray) -> tuple[int, int, int]:
    """Three points not on one line (exact), counter-clockwise; :class:`Collinear` if none.
    (``q``: ``p`` scaled, where the distances cannot overflow.)"""
    from jaxcds.polylla_io import orientation_signs

    a = 0
    b = int(np.argmax(np.abs(q - q[0]).sum(axis=1)))
    rest = np.arange(p.shape[0])
    signs = orientation_signs(p, np.stack([np.full_like(rest, a), np.full_like(rest, b), rest], 1))
    nz = np.flatnonzero(signs)
    if b == a or not nz.size:
        raise Collinear
    c = int(nz[0])
    return (a, b, c) if signs[c] > 0 else (a, c, b)


def build_from_scratch(p: np.ndarray, q: np.ndarray, lossy: np.ndarray) -> np.ndarray:
    """Incremental exact Delaunay triangulation of the distinct points ``p`` (the fallback):
    inserted in a snake order over a grid, each walk starting at the previous insertion."""
    seed = _seed_triangle(p, q)
    m = _Mesh(p, q, lossy, np.array([seed]), np.full((1, 3), -1), lists=True)
    cells = max(1, int(math.sqrt(p.shape[0] / 4)))
    lo, span = q.min(axis=0), np.maximum(np.ptp(q, axis=0), _TINY)
    g = np.minimum(((q - lo) / span * cells).astype(np.int64), cells - 1)
    col = np.where(g[:, 1] % 2 == 0, g[:, 0], cells - 1 - g[:, 0])
    order = np.lexsort((col, g[:, 1]))
    t = 0
    for x in order.tolist():
        if x not in seed:
            t = m.insert(x, t)
    return m.faces()


#: Qhull runs at most this many times, each without the corners of the triangles it inverted
#: before (their points are inserted exactly afterwards), before the build from scratch
QHULL_TRIES = 4


def triangulate(p: np.ndarray) -> np.ndarray:
    """``(F, 3)`` counter-clockwise triangles of the exact Delaunay triangulation of the
    distinct points ``p`` (float64, finite); :class:`Collinear` when they all lie on one line.

    Qhull first; where it inverts triangles (an exactly clockwise sliver among nearly collinear
    points: 2 of 246 real-world sets), it runs again without their corners, which are then
    inserted exactly like the points it merged; where it fails, or its output still cannot be
    mended, the triangulation is built here from scratch (slower: Python loops)."""
    q, lossy = scaled(p)
    skip = np.zeros(p.shape[0], bool)
    for _ in range(QHULL_TRIES):
        keep = np.flatnonzero(~skip)
        if keep.size < 3:
            break
        try:
            simplices, neighbors = _qhull(q[keep])
        except Exception:  # Qhull's errors (QhullError, ValueError): a flat or nearly flat set
            break
        try:
            faces, inverted = repair(p, q, lossy, keep[simplices], neighbors)
        except _Broken:  # Qhull's neighbours do not describe one mesh
            break
        if faces is not None:
            return faces
        if inverted is None:
            break
        skip[inverted] = True
    return build_from_scratch(p, q, lossy)


def _qhull(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(simplices, neighbors)`` of ``scipy.spatial.Delaunay`` of the scaled points ``q``
    (simplices in ids of ``q``): centred first, as Qhull lifts the points to a paraboloid, whose
    heights lose every digit that tells the points apart at a large offset (200 points at 1e10
    read as duplicates); then scaled by a power of two (exact) so that tiny or huge coordinates
    (1e-300, 1e300) neither underflow nor overflow there.

    Qhull is given the points in Z order (:func:`z_order`): on points in random order it
    spends a third of its time waiting on memory (1M uniform points on stop 55's host: 9.5-11.7
    s as given, 7.0-7.7 s in Z order; points already in a spatially coherent order: no change,
    6.3-7.1 against 6.7-7.0 s)."""
    from scipy.spatial import Delaunay

    from jaxcds.polylla_io import unit_scale

    order = z_order(q)
    tri = Delaunay(unit_scale(q[order] - (q.min(axis=0) + q.max(axis=0)) / 2))
    return order[tri.simplices], tri.neighbors


def _spread_bits(x: np.ndarray) -> np.ndarray:
    """The low 16 bits of each ``uint64`` of ``x`` moved to the even bit positions 0, 2, ..., 30."""
    x = x & np.uint64(0xFFFF)
    for shift, mask in ((8, 0x00FF00FF), (4, 0x0F0F0F0F), (2, 0x33333333), (1, 0x55555555)):
        x = (x | (x << np.uint64(shift))) & np.uint64(mask)
    return x


def z_order(q: np.ndarray) -> np.ndarray:
    """Indices of the points ``q`` (``(n, 2)``, finite) in Z (Morton) order over a grid of about
    one point per cell on their bounding square (at most ``2^16`` cells a side); stable, so
    points of one cell keep their order."""
    n = q.shape[0]
    lo = q.min(axis=0)
    extent = float((q.max(axis=0) - lo).max())
    if n < 2 or not extent > 0:
        return np.arange(n)
    side = (1 << int(np.clip(np.ceil(np.log2(n) / 2), 1, 16))) - 1
    cells = np.minimum((q - lo) * (side / extent), side).astype(np.uint64)
    key = _spread_bits(cells[:, 0]) | (_spread_bits(cells[:, 1]) << np.uint64(1))
    return np.argsort(key, kind="stable")


def repair(p, q, lossy, simplices, neighbors):
    """Qhull's triangulation (``simplices`` in ids of ``p``) made exactly Delaunay over all the
    distinct points ``p``: ``(faces, None)``; ``(None, corners)`` when Qhull inverted triangles
    (their corners); ``(None, None)`` when it cannot be mended otherwise (a hull that is not one
    convex cycle)."""
    m = _Mesh(p, q, lossy, simplices, neighbors)
    signs = _orientations(m, m.v)
    if (signs < 0).any():
        return None, np.unique(m.v[signs < 0])
    if not m.remove_flat(np.flatnonzero(signs == 0)):
        return None, None
    m.fill_reflex_hull()
    if not m.hull_is_convex():
        return None, None
    _make_delaunay(m)
    _insert_unused(m)  # each insertion legalised around its point
    faces = m.faces()
    if (_orientations(m, faces) <= 0).any() or not m.hull_is_convex():
        return None, None
    used = np.zeros(p.shape[0], bool)
    used[faces.ravel()] = True
    return (faces, None) if used.all() else (None, None)


def _insert_unused(m: _Mesh) -> None:
    """Insert the points in no triangle, each walk starting at a triangle of its nearest used
    point."""
    faces = m.faces()
    used = np.zeros(m.p.shape[0], bool)
    used[faces.ravel()] = True
    missing = np.flatnonzero(~used)
    if not missing.size:
        return
    from scipy.spatial import cKDTree

    have = np.flatnonzero(used)
    near = have[cKDTree(m.qa[have]).query(m.qa[missing])[1]]
    live = np.flatnonzero(m.v[:m.count, 0] >= 0)
    at = np.full(m.p.shape[0], -1, np.int64)
    at[m.v[live].ravel()] = np.repeat(live, 3)
    for x, y in zip(missing.tolist(), near.tolist()):
        t = int(at[y])
        if m.v[t, 0] < 0:
            t = int(live[0])
        at[x] = m.insert(x, t)
