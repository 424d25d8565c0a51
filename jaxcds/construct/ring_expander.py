"""RING-EXPANDER and the LR tables (Gurung, Luffel, Lindstrom, Rossignac, *LR: Compact connectivity
representation for triangle meshes*, ACM TOG 2011), numba, linear time.

Everything here works on a corner table (``V``, ``O`` of length ``3n``, corner ``c`` in triangle
``c // 3``, ``c.n = 3(c//3) + (c+1)%3``, counter-clockwise faces; see
:class:`jaxcds.structures.corner_table.CornerTable`):

* :func:`ring_expander` -- the stackless depth-first invasion of Sec. 4.2 (Fig. 3);
* :func:`hybrid_ring_expander` -- the deque version of Sec. 6.1 that restarts breadth-first every
  ``k`` invasions (``k = 1`` breadth-first, ``k = 0`` meaning infinity: depth-first);
* :func:`extract_ring` -- the ring (boundary of the invaded disk) in order, oriented so that the
  invaded triangle of ring edge ``(v, v.n)`` is its right triangle ``v.t_R`` (Sec. 4.4, Fig. 5);
* :func:`best_ring` -- several seeds, keeping the ring with the fewest isolated vertices (Sec. 4.2);
* :func:`lr_tables` -- triangle classification (Sec. 4.3: T0, T1, T2, T^i), wart skipping (Sec. 5:
  T0^w stored in the redundant slot of its T2 wart), corner ids ``8v + i`` (Fig. 5) and the
  canonical LR corner of every corner-table corner.

Dummy vertices (holes closed by :func:`jaxcds.mesh.close_boundaries`) are marked visited before the
invasion (Sec. 4.6) so they are never on the ring and no dummy triangle is invaded.
"""

from __future__ import annotations

import dataclasses
from typing import Optional

import numba
import numpy as np

from jaxcds import errors
from jaxcds._args import is_integer

__all__ = ["ring_expander", "hybrid_ring_expander", "extract_ring", "best_ring", "Ring",
           "lr_tables", "LRTables", "reference_ring_expander"]


# ------------------------------------------------------------------------------ invasion
@numba.njit(cache=True, inline="always")
def _n(c):
    return 3 * (c // 3) + (c + 1) % 3


@numba.njit(cache=True, inline="always")
def _p(c):
    return 3 * (c // 3) + (c + 2) % 3


@numba.njit(cache=True)
def _walk(V, O, s, vm, tm):
    """The do-while loop of the Sec. 4.2 listing from seed corner ``s`` (``c.r = c.p.o``)."""
    c = s
    so = O[s]
    invaded = 0
    limit = 4 * V.shape[0] + 16
    steps = 0
    while True:
        if vm[V[c]] == 0:  # invade c.t
            vm[V[c]] = 1
            tm[c // 3] = 1
            invaded += 1
        elif tm[c // 3] == 0:  # c.v visited, c.t not invaded: go back one triangle
            c = O[c]
        c = O[_p(c)]  # advance to next ring edge on the right: c = c.r
        if c == so:
            break
        steps += 1
        if steps > limit:
            return -1
    return invaded


@numba.njit(cache=True)
def _ring_expander(V, O, seed, vm, tm):
    """Sec. 4.2 listing. The listing stops at ``s.o`` without trying to invade ``s.o.t``; a vertex
    reachable only through ``s.o.t`` would stay isolated (e.g. a lone quad closed by a dummy),
    so when ``s.o.v`` is still unvisited a second walk runs from ``s.o`` (it stops back at ``s``).
    Returns the number of invaded triangles, or -1 if a walk does not come back (not a closed
    manifold)."""
    vm[V[_n(seed)]] = 1
    vm[V[_p(seed)]] = 1
    a = _walk(V, O, seed, vm, tm)
    if a < 0:
        return -1
    s2 = O[seed]
    if vm[V[s2]] == 0:
        b = _walk(V, O, s2, vm, tm)
        if b < 0:
            return -1
        a += b
    return a


@numba.njit(cache=True)
def _hybrid_ring_expander(V, O, seed, k, vm, tm):
    """Sec. 6.1 listing (HYBRID-RING-EXPANDER): deque ``d`` of backtracking corners, pop from the
    front every ``k`` invasions (breadth-first restart), from the back otherwise (depth-first).
    ``k <= 0`` means infinity. The seed's third neighbour ``s.o`` is pushed first (the listing
    starts inside the loop; without it ``s.o.t`` could never be invaded)."""
    nc = V.shape[0]
    d = np.empty(nc + 8, dtype=np.int32)  # at most 2 pushes per invasion + 1: never wraps
    head = 0
    tail = 0
    c = seed
    vm[V[_n(c)]] = 1
    vm[V[_p(c)]] = 1
    d[tail] = O[c]
    tail += 1
    n = 0
    while True:
        if vm[V[c]] == 0:  # has c.v been visited?
            vm[V[c]] = 1  # invade c.t
            tm[c // 3] = 1
            d[tail] = O[_n(c)]  # push c.l
            tail += 1
            d[tail] = O[_p(c)]  # push c.r
            tail += 1
            n += 1
        if head == tail:
            break
        if k > 0 and n % k == 0:
            c = d[head]  # breadth-first
            head += 1
        else:
            tail -= 1  # depth-first
            c = d[tail]
    return n


def _marks(num_vertices: int, num_faces: int, dummy: Optional[np.ndarray]):
    vm = np.zeros(num_vertices, dtype=np.uint8)
    if dummy is not None:
        vm[np.asarray(dummy, dtype=bool)] = 1  # Sec. 4.6: the dummy vertex is never on the ring
    return vm, np.zeros(num_faces, dtype=np.uint8)


def check_corner_table(V, O, num_vertices, where: str, *, tm=None, dummy=None):
    """The corner table the ring functions take from a caller, checked before any numba kernel
    walks it (they index by ``V``, ``O``, corner ids and ``tm`` unchecked: an id out of range
    read and wrote outside the arrays, a segmentation fault). O(F) numpy. Returns ``(V, O, n,
    tm, dummy)``: int32 C-contiguous ``V`` and ``O``, ``tm`` as uint8 and ``dummy`` as bool
    (``None`` where not given).

    Raises:
      ArgumentError: ``num_vertices`` not an integer >= 0; ``V``, ``O`` not 1-D integer arrays of
        one length ``3F > 0``; ``tm`` not ``F`` flags 0/1; ``dummy`` not ``n`` flags 0/1.
      StructureError: ``V`` out of ``[0, n)``, or ``O`` not a corner table's opposites (an
        involution on ``[0, 3F)`` pairing each corner with one of another triangle facing the
        same edge reversed), naming the first bad corner; or the table not one connected
        manifold surface using every vertex (a vertex in no triangle, two parts, a pinch vertex).
    """
    if not is_integer(num_vertices) or not 0 <= num_vertices < 2 ** 31:
        raise errors.ArgumentError(f"{where}: num_vertices must be an integer in [0, 2^31), got "
                                   f"{num_vertices!r}")
    n = int(num_vertices)
    arrs = []
    for name, a in (("V", V), ("O", O)):
        try:
            a = np.asarray(a)
        except ValueError as exc:  # ragged nested lists
            raise errors.ArgumentError(f"{where}: {name} is not an array: {exc}") from None
        if a.ndim != 1 or a.dtype.kind not in "iu" or a.size == 0 or a.size % 3:
            raise errors.ArgumentError(f"{where}: {name} must be a 1-D integer array of 3F > 0 corners, "
                                       f"got dtype {a.dtype} shape {a.shape}")
        arrs.append(a)
    V, O = arrs
    if O.shape != V.shape:
        raise errors.ArgumentError(f"{where}: V and O must have one length (3F), got {V.size} and {O.size}")
    nc = V.size
    bad = np.nonzero((V < 0) | (V >= n))[0]
    if bad.size:
        c = int(bad[0])
        raise errors.StructureError(f"{where}: V[{c}] = {int(V[c])} is outside [0, {n})")
    bad = np.nonzero((O < 0) | (O >= nc))[0]
    if bad.size:
        c = int(bad[0])
        raise errors.StructureError(f"{where}: O[{c}] = {int(O[c])} is not a corner id in [0, {nc})")
    V = np.ascontiguousarray(V, np.int32)
    O = np.ascontiguousarray(O, np.int32)
    c = np.arange(nc, dtype=np.int32)
    nx = 3 * (c // 3) + (c + 1) % 3
    pv = 3 * (c // 3) + (c + 2) % 3
    bad = np.nonzero((O[O] != c) | (O // 3 == c // 3) | (V[nx] != V[pv[O]]) | (V[pv] != V[nx[O]]))[0]
    if bad.size:
        c = int(bad[0])
        raise errors.StructureError(
            f"{where}: O[{c}] = {int(O[c])} is not the opposite of corner {c}: O must be an involution "
            "pairing each corner with the corner of the other triangle on the edge it faces (the "
            "O of a closed jaxcds CornerTable)")
    _check_one_surface(V, O, nx, n, where)
    if tm is not None:
        t = np.asarray(tm)
        if t.shape != (nc // 3,) or t.dtype.kind not in "biu" or (t.size and not np.isin(t, (0, 1)).all()):
            raise errors.ArgumentError(f"{where}: tm must be {nc // 3} flags 0/1 (one per triangle), got "
                                       f"dtype {t.dtype} shape {t.shape}")
        tm = np.ascontiguousarray(t, np.uint8)
    if dummy is not None:
        d = np.asarray(dummy)
        if d.shape != (n,) or d.dtype.kind not in "biu" or (d.size and not np.isin(d, (0, 1)).all()):
            raise errors.ArgumentError(f"{where}: dummy must be {n} flags 0/1 (one per vertex), got "
                                       f"dtype {d.dtype} shape {d.shape}")
        dummy = d.astype(bool)
    return V, O, n, tm, dummy


def _check_one_surface(V, O, nx, num_vertices: int, where: str) -> None:
    """One connected manifold surface using every vertex: a ring (Sec. 4.2) is one loop through
    one surface, and RING-EXPANDER marks vertices as visited, so it stops at the first fan of a
    pinch vertex, never reaches a second part, and leaves a vertex in no triangle "isolated" with
    no corner for the C table. Each returned a ring without a word. O(F) through scipy's
    connected components (of the swing ``c.s = c.n.o.n``, LR Sec. 2, and of the triangles)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    nc = V.size
    counts = np.bincount(V, minlength=num_vertices)
    if not counts.all():
        v = int(np.argmin(counts))
        raise errors.StructureError(f"{where}: vertex {v} is in no triangle (num_vertices = "
                                    f"{num_vertices}); a ring passes every vertex of a closed mesh")

    def parts(rows, cols, size):
        graph = coo_matrix((np.ones(rows.size, np.int8), (rows, cols)), shape=(size, size))
        return connected_components(graph, directed=True, connection="weak")

    corner = np.arange(nc)
    num_parts, part = parts(corner // 3, O // 3, nc // 3)  # triangle to the one across each edge
    if num_parts > 1:
        t = int(np.nonzero(part != part[0])[0][0])
        raise errors.StructureError(
            f"{where}: the corner table has {num_parts} connected parts (triangles 0 and {t} are "
            "in different ones); a ring covers one connected surface: build one per part "
            "(jaxcds.batch packs several)")
    _, fan = parts(corner, nx[O[nx]], nc)  # corner to the next one around its vertex
    first_fan = np.full(num_vertices, -1, np.int64)
    first_fan[V[::-1]] = fan[::-1]  # the fan of each vertex's first corner
    bad = np.nonzero(fan != first_fan[V])[0]
    if bad.size:
        c = int(bad[0])
        v = int(V[c])
        other = int(np.nonzero(V == v)[0][0])
        raise errors.StructureError(
            f"{where}: vertex {v} has two fans of triangles (corners {other} and {c} do not swing "
            "into each other): a pinch (non-manifold) vertex, which a ring cannot pass; split it "
            "first (jaxcds.mesh.split_nonmanifold_vertices) or build from a validated mesh")


def _seed_arg(seed, nc: int, where: str) -> int:
    if not is_integer(seed) or not 0 <= seed < nc:
        raise errors.ArgumentError(f"{where}: seed must be a corner id in [0, {nc}), got {seed!r}")
    return int(seed)


def ring_expander(V, O, num_vertices: int, seed: int, dummy=None):
    """Run RING-EXPANDER (Sec. 4.2) from seed corner ``seed``.

    Returns ``(tm, vm)``: ``(n,)`` uint8 invaded-triangle flags and ``(m,)`` uint8 visited flags
    (dummy vertices are pre-marked; they are visited but not on the ring). The arguments are
    checked (:func:`check_corner_table`, ``seed`` a corner id)."""
    V, O, n, _, dummy = check_corner_table(V, O, num_vertices, "ring_expander", dummy=dummy)
    return _ring_expander_trusted(V, O, n, _seed_arg(seed, V.size, "ring_expander"), dummy)


def _ring_expander_trusted(V, O, num_vertices: int, seed: int, dummy=None):
    V = np.asarray(V, dtype=np.int32)
    O = np.asarray(O, dtype=np.int32)
    vm, tm = _marks(num_vertices, V.shape[0] // 3, dummy)
    if _ring_expander(V, O, np.int32(seed), vm, tm) < 0:
        raise errors.StructureError(
            f"RING-EXPANDER from corner {seed} did not return to s.o: the corner table is not a "
            "closed manifold")
    return tm, vm


def hybrid_ring_expander(V, O, num_vertices: int, seed: int, k: int, dummy=None):
    """Run HYBRID-RING-EXPANDER (Sec. 6.1) with period ``k`` (0: depth-first). Same outputs and
    checks as :func:`ring_expander`; ``k`` an integer >= 0."""
    V, O, n, _, dummy = check_corner_table(V, O, num_vertices, "hybrid_ring_expander", dummy=dummy)
    if not is_integer(k) or k < 0:
        raise errors.ArgumentError(f"hybrid_ring_expander: k must be an integer >= 0, got {k!r}")
    return _hybrid_trusted(V, O, n, _seed_arg(seed, V.size, "hybrid_ring_expander"), k, dummy)


def _hybrid_trusted(V, O, num_vertices: int, seed: int, k: int, dummy=None):
    V = np.asarray(V, dtype=np.int32)
    O = np.asarray(O, dtype=np.int32)
    vm, tm = _marks(num_vertices, V.shape[0] // 3, dummy)
    _hybrid_ring_expander(V, O, np.int32(seed), np.int64(k), vm, tm)
    return tm, vm


def reference_ring_expander(V, O, num_vertices: int, seed: int, dummy=None):
    """Slow, obviously-correct Python twin of :func:`ring_expander` (tests only)."""
    V = [int(x) for x in V]
    O = [int(x) for x in O]
    vm = [False] * num_vertices
    if dummy is not None:
        for i, d in enumerate(dummy):
            vm[i] = bool(d)
    tm = [False] * (len(V) // 3)
    nx = lambda c: 3 * (c // 3) + (c + 1) % 3  # noqa: E731
    pv = lambda c: 3 * (c // 3) + (c + 2) % 3  # noqa: E731
    vm[V[nx(seed)]] = vm[V[pv(seed)]] = True

    def walk(s):
        c = s
        while True:
            if not vm[V[c]]:
                vm[V[c]] = tm[c // 3] = True
            elif not tm[c // 3]:
                c = O[c]
            c = O[pv(c)]
            if c == O[s]:
                break

    walk(seed)
    if not vm[V[O[seed]]]:
        walk(O[seed])
    return np.array(tm, np.uint8), np.array(vm, np.uint8)


@numba.njit(cache=True)
def _extract_ring(V, O, tm, num_vertices):
    """Ring = boundary of the invaded disk. Each boundary dart ``a -> b`` of an invaded triangle
    (corner ``c`` facing it, ``c.t`` invaded, ``c.o.t`` not) gives ``succ[a] = b`` and the
    right-slot apex corner ``rc[a] = c``. Returns (order, rc_in_order) or empty arrays when the
    boundary is not a single simple loop."""
    nc = V.shape[0]
    succ = np.full(num_vertices, -1, dtype=np.int32)
    rc = np.full(num_vertices, -1, dtype=np.int32)
    count = 0
    start = -1
    for c in range(nc):
        if tm[c // 3] == 1 and tm[O[c] // 3] == 0:
            a = V[_n(c)]
            if succ[a] != -1:  # a vertex twice on the boundary: not a simple loop
                return np.empty(0, np.int32), np.empty(0, np.int32)
            succ[a] = V[_p(c)]
            rc[a] = c
            count += 1
            start = a
    order = np.empty(count, dtype=np.int32)
    corners = np.empty(count, dtype=np.int32)
    v = start
    for i in range(count):
        order[i] = v
        corners[i] = rc[v]
        v = succ[v]
        if v < 0:
            return np.empty(0, np.int32), np.empty(0, np.int32)
    if v != start:
        return np.empty(0, np.int32), np.empty(0, np.int32)
    return order, corners


@dataclasses.dataclass(frozen=True)
class Ring:
    """A ring (Sec. 4.2).

    Attributes:
      order: ``(m_r,)`` int32 input vertex ids in ring order (ring edge ``(order[i], order[i+1])``).
      right_corner: ``(m_r,)`` int32 corner-table corner facing ring edge ``i`` inside the invaded
        triangle ``v.t_R`` (its vertex is ``v.r``).
      seed: seed corner; k: hybrid period (None: the stackless RING-EXPANDER, 0: depth-first deque).
      num_isolated: ``m_i = m - m_r`` (dummy vertices included).
      invaded: ``(n,)`` uint8 the invaded triangles the ring bounds (for
        :func:`jaxcds.construct.ring_search.improve_ring`).
      search_gain: references the ring search saved against RING-EXPANDER's ring (0: none ran).
    """

    order: np.ndarray
    right_corner: np.ndarray
    seed: int
    k: Optional[int]
    num_isolated: int
    invaded: Optional[np.ndarray] = dataclasses.field(default=None, repr=False)
    search_gain: int = 0


def extract_ring(V, O, tm, num_vertices: int, seed: int = -1, k=None) -> Ring:
    """The ring bounding the invaded triangles ``tm`` (see :func:`_extract_ring`); the arguments
    checked (:func:`check_corner_table`)."""
    V, O, n, tm, _ = check_corner_table(V, O, num_vertices, "extract_ring", tm=tm)
    return _extract_ring_trusted(V, O, tm, n, seed, k)


def _extract_ring_trusted(V, O, tm, num_vertices: int, seed: int = -1, k=None) -> Ring:
    order, corners = _extract_ring(np.asarray(V, np.int32), np.asarray(O, np.int32),
                                   np.asarray(tm, np.uint8), int(num_vertices))
    if order.size < 4:
        raise errors.UnsupportedTopologyError(
            f"the ring from seed corner {seed} has {order.size} vertices (need >= 4): mesh too "
            "small for LR (use halfedge or corner-table)" if order.size else
            f"the invaded region from seed corner {seed} is not bounded by one simple loop")
    return Ring(order=order, right_corner=corners, seed=int(seed), k=k,
                num_isolated=int(num_vertices) - int(order.size),
                invaded=np.asarray(tm, np.uint8))


def check_seeds(seeds, V, dummy=None):
    """``seeds`` as given to the ring builders, checked: a count (an integer >= 1) or a list of
    seed corners, each an integer corner id in ``[0, 3F)`` of a triangle without a dummy vertex.
    Returns an int or a list of ints; :class:`~jaxcds.errors.ArgumentError` names a bad value
    (an out-of-range corner crashed the numba kernel)."""
    if np.isscalar(seeds) or seeds is None:
        if not is_integer(seeds) or seeds < 1:
            raise errors.ArgumentError(f"seeds must be a count >= 1 or a list of corner ids, got {seeds!r}")
        return int(seeds)
    try:
        lst = list(seeds)
    except TypeError:
        raise errors.ArgumentError(f"seeds must be a count >= 1 or a list of corner ids, got {seeds!r}") from None
    if not lst:
        raise errors.ArgumentError("seeds: an empty list of seed corners")
    tris = np.asarray(V).reshape(-1, 3)
    nc = 3 * tris.shape[0]
    dm = None if dummy is None else np.asarray(dummy, bool)
    for i, c in enumerate(lst):
        if not is_integer(c) or not 0 <= c < nc:
            raise errors.ArgumentError(f"seeds[{i}] = {c!r} is not a corner id in [0, {nc})")
        if dm is not None and dm[tris[int(c) // 3]].any():
            raise errors.ArgumentError(f"seeds[{i}] = corner {c} is on a hole-closing (dummy) triangle; "
                                       "the ring starts on a triangle of the mesh")
    return [int(c) for c in lst]


def best_ring(V, O, num_vertices: int, *, seeds=4, k=None, dummy=None, rng_seed: int = 0) -> Ring:
    """Run RING-EXPANDER (``k is None``) or HYBRID-RING-EXPANDER (period ``k``) from ``seeds``
    random seed corners (or the given list) and keep the ring with the fewest isolated vertices
    (Sec. 4.2: "we run RING-EXPANDER several times with random seed corners and retain the seed
    leading to the smallest m_i"). Seeds are corners of non-dummy triangles. The corner table is
    checked (:func:`check_corner_table`)."""
    V, O, n, _, dummy = check_corner_table(V, O, num_vertices, "best_ring", dummy=dummy)
    return _best_ring_trusted(V, O, n, seeds=seeds, k=k, dummy=dummy, rng_seed=rng_seed)


def _best_ring_trusted(V, O, num_vertices: int, *, seeds=4, k=None, dummy=None, rng_seed: int = 0) -> Ring:
    """:func:`best_ring` on a corner table the library built (unchecked)."""
    V = np.asarray(V, dtype=np.int32)
    O = np.asarray(O, dtype=np.int32)
    nf = V.shape[0] // 3
    seeds = check_seeds(seeds, V, dummy)
    if np.isscalar(seeds):
        rng = np.random.default_rng(rng_seed)
        ok = np.ones(nf, dtype=bool)
        if dummy is not None:
            dm = np.asarray(dummy, dtype=bool)
            ok = ~dm[V.reshape(-1, 3)].any(axis=1)
        cand = np.nonzero(ok)[0]
        if cand.size == 0:
            raise errors.UnsupportedTopologyError("no triangle without a dummy vertex to seed the ring")
        tris = rng.choice(cand, size=min(int(seeds), cand.size), replace=False)
        seed_list = [int(3 * t) for t in tris]
    else:
        seed_list = [int(s) for s in seeds]
    best = None
    for s in seed_list:
        if k is None:
            tm, _ = _ring_expander_trusted(V, O, num_vertices, s, dummy)
        else:
            tm, _ = _hybrid_trusted(V, O, num_vertices, s, k, dummy)
        r = _extract_ring_trusted(V, O, tm, num_vertices, s, k)
        if best is None or r.num_isolated < best.num_isolated:
            best = r
        if best.num_isolated == (0 if dummy is None else int(np.sum(dummy))):
            break  # cannot do better
    return best


# ------------------------------------------------------------------------------ tables
@numba.njit(cache=True)
def _tables(V, O, order, rcorner, num_vertices, wart_skipping):
    nc = V.shape[0]
    nf = nc // 3
    m = order.shape[0]
    cR = rcorner.copy()
    cL = np.empty(m, np.int32)
    for i in range(m):
        cL[i] = O[cR[i]]
    cnt = np.zeros(nf, np.int8)  # number of ring slots holding each triangle (T0: 0, T1: 1, T2: 2)
    for i in range(m):
        cnt[cL[i] // 3] += 1
        cnt[cR[i] // 3] += 1
    redL = np.zeros(m, np.uint8)
    redR = np.zeros(m, np.uint8)
    for i in range(m):
        j = (i + 1) % m
        # T2 canonical on its second ring edge (Sec. 4.4): slot i redundant if slot i+1 holds it too
        if cL[i] // 3 == cL[j] // 3:
            redL[i] = 1
        if cR[i] // 3 == cR[j] // 3:
            redR[i] = 1
    t2 = 0
    for i in range(m):
        t2 += redL[i] + redR[i]
    # Sec. 5 wart skipping: a T2 (tip v, canonical in slot v) adjacent across its transversal edge
    # to a T0 lends its redundant slot v.p to that T0 (now T0^w, a T1 of the ring that skips v).
    claimed = np.zeros(nf, np.uint8)
    skL = np.zeros(m, np.uint8)
    skR = np.zeros(m, np.uint8)
    if wart_skipping:
        for i in range(m):
            ip = (i - 1 + m) % m
            if redL[ip] == 1:
                tip = _p(cL[i])  # corner v.0 (at the tip v) of L(v) = (v, v.p, v.n)
                x = O[tip] // 3
                if cnt[x] == 0 and claimed[x] == 0:
                    claimed[x] = 1
                    skL[ip] = 1
                    redL[ip] = 0
                    cL[ip] = O[tip]  # apex corner (at u) of T0^w = (v.p, u, v.n)
            if redR[ip] == 1:
                tip = _n(cR[i])  # corner v.6 (at the tip v) of R(v) = (v.n, v.p, v)
                x = O[tip] // 3
                if cnt[x] == 0 and claimed[x] == 0:
                    claimed[x] = 1
                    skR[ip] = 1
                    redR[ip] = 0
                    cR[ip] = O[tip]
    n0 = 0
    for t in range(nf):
        if cnt[t] == 0 and claimed[t] == 0:
            n0 += 1
    t0 = np.empty(n0, np.int32)
    j = 0
    for t in range(nf):
        if cnt[t] == 0 and claimed[t] == 0:
            t0[j] = t
            j += 1
    # canonical LR corner of each corner-table corner: L(v) = (v.0, v.1, v.2) at (v, v.l, v.n*),
    # R(v) = (v.4, v.5, v.6) at (v.n*, v.r, v) (Fig. 5); T0 corners 8 m_r + 4 j + i (Sec. 4.7)
    lrc = np.full(nc, -1, np.int32)
    for i in range(m):
        if redL[i] == 0:
            d = cL[i]
            lrc[_p(d)] = 8 * i
            lrc[d] = 8 * i + 1
            lrc[_n(d)] = 8 * i + 2
        if redR[i] == 0:
            c = cR[i]
            lrc[_p(c)] = 8 * i + 4
            lrc[c] = 8 * i + 5
            lrc[_n(c)] = 8 * i + 6
    for jj in range(n0):
        t = t0[jj]
        for q in range(3):
            lrc[3 * t + q] = 8 * m + 4 * jj + q
    # which triangles are T0 after wart skipping; irregular slots: a neighbour is a T0 (Sec. 4.5)
    is_t0 = np.zeros(nf, np.uint8)
    for jj in range(n0):
        is_t0[t0[jj]] = 1
    irL = np.zeros(m, np.uint8)
    irR = np.zeros(m, np.uint8)
    for i in range(m):
        if redL[i] == 0:
            d = cL[i]
            if is_t0[O[d] // 3] or is_t0[O[_n(d)] // 3] or is_t0[O[_p(d)] // 3]:
                irL[i] = 1
        if redR[i] == 0:
            c = cR[i]
            if is_t0[O[c] // 3] or is_t0[O[_n(c)] // 3] or is_t0[O[_p(c)] // 3]:
                irR[i] = 1
    return cL, cR, redL, redR, skL, skR, irL, irR, t0, lrc, t2


@dataclasses.dataclass(frozen=True)
class LRTables:
    """Everything the LR structure is packed from (input vertex ids, corner-table corners).

    Attributes:
      order: ``(m_r,)`` ring vertices in ring order (input ids).
      left_corner / right_corner: ``(m_r,)`` corner-table corner at the apex ``v.l`` / ``v.r`` of
        slot ``L(v)`` (triangle ``2v``) / ``R(v)`` (triangle ``2v + 1``); for a wart-skipping slot
        it is the apex of the T0^w.
      red_left / red_right: ``(m_r,)`` slot holds the redundant copy of a T2 (Sec. 4.4).
      skip_left / skip_right: ``(m_r,)`` slot holds a T0^w whose ring edge skips the wart tip
        ``v.n`` (Sec. 5).
      irr_left / irr_right: ``(m_r,)`` slot triangle is irregular: adjacent to a T0 (T^i, Sec. 4.5).
      t0: ``(n0,)`` corner-table triangles left as T0 after wart skipping.
      lr_corner: ``(3n,)`` canonical LR corner id (``8v + i`` / ``8 m_r + 4j + i``) of each
        corner-table corner (ring vertex ids, not input ids).
      num_t2: number of T2 triangles (before wart skipping), num_t0_initial: T0 before it.
    """

    order: np.ndarray
    left_corner: np.ndarray
    right_corner: np.ndarray
    red_left: np.ndarray
    red_right: np.ndarray
    skip_left: np.ndarray
    skip_right: np.ndarray
    irr_left: np.ndarray
    irr_right: np.ndarray
    t0: np.ndarray
    lr_corner: np.ndarray
    num_t2: int
    ring: Ring

    @property
    def num_ring(self) -> int:
        return int(self.order.size)

    def stats(self, num_faces: int, num_real_faces: Optional[int] = None) -> dict:
        """Table 1 percentages (of ``num_real_faces`` triangles when given)."""
        n = num_real_faces or num_faces
        n0 = int(self.t0.size)
        nw = int(self.skip_left.sum() + self.skip_right.sum())
        ni = int(self.irr_left.sum() + self.irr_right.sum())
        ni2 = int(self._irregular_t2().sum())
        return {"m_r": self.num_ring, "m_i": self.ring.num_isolated, "T0": n0, "T0w": nw,
                "Ti": ni, "T1i": ni - ni2, "T2i": ni2, "T2": self.num_t2,
                "pct_T0": 100.0 * n0 / n, "pct_T0w": 100.0 * nw / n, "pct_Ti": 100.0 * ni / n,
                "pct_T1i": 100.0 * (ni - ni2) / n, "pct_T2i": 100.0 * ni2 / n}

    def _irregular_t2(self) -> np.ndarray:
        """``(2 m_r,)`` irregular slots holding a T2 (T_2^i, Sec. 4.3): a T2 fills two
        consecutive slots of one side and is canonical in the second one (Sec. 4.4), so slot
        ``v`` holds a T2 iff slot ``v - 1`` of the same side holds its redundant copy, or holds
        the T_0^w that wart skipping put there in its place (Sec. 5). A T_0^w slot counts as
        T_1 (it is stored as one)."""
        out = []
        for irr, red, skip in ((self.irr_left, self.red_left, self.skip_left),
                               (self.irr_right, self.red_right, self.skip_right)):
            out.append(irr & np.roll(red | skip, 1))
        return np.concatenate(out)


def lr_tables(V, O, ring: Ring, num_vertices: int, *, wart_skipping: bool = True) -> LRTables:
    """Classify triangles against ``ring``, skip warts and number corners (Sec. 4.3-4.5, 5).
    The corner table is checked (:func:`check_corner_table`), and the ring: a :class:`Ring`
    whose ``order`` holds distinct vertex ids and ``right_corner`` corners of those vertices'
    ring edges, one per vertex (the kernel indexed by them unchecked)."""
    V, O, n, _, _ = check_corner_table(V, O, num_vertices, "lr_tables")
    if not isinstance(ring, Ring):
        raise errors.ArgumentError(f"lr_tables: ring must be a Ring (best_ring, extract_ring), got "
                                   f"{type(ring).__name__}")
    order, rc = np.asarray(ring.order), np.asarray(ring.right_corner)
    if (order.ndim != 1 or rc.shape != order.shape or order.size < 4 or order.dtype.kind not in "iu"
            or rc.dtype.kind not in "iu"):
        raise errors.StructureError(f"lr_tables: ring.order and ring.right_corner must be 1-D integer "
                                    f"arrays of one length >= 4, got {order.dtype} {order.shape} and "
                                    f"{rc.dtype} {rc.shape}")
    bad = np.nonzero((order < 0) | (order >= n) | (rc < 0) | (rc >= V.size))[0]
    if bad.size == 0:  # corner rc[i] faces ring edge (order[i], order[i + 1])
        cc = rc.astype(np.int64)
        bad = np.nonzero((V[3 * (cc // 3) + (cc + 1) % 3] != order)
                         | (V[3 * (cc // 3) + (cc + 2) % 3] != np.roll(order, -1)))[0]
    if bad.size:
        i = int(bad[0])
        raise errors.StructureError(f"lr_tables: ring entry {i} (order {int(order[i])}, right_corner "
                                    f"{int(rc[i])}) is not a ring edge of this corner table")
    if np.unique(order).size != order.size:
        raise errors.StructureError("lr_tables: ring.order repeats a vertex (a ring is a simple loop)")
    ring = dataclasses.replace(ring, order=np.ascontiguousarray(order, np.int32),
                               right_corner=np.ascontiguousarray(rc, np.int32))
    return _lr_tables_trusted(V, O, ring, n, wart_skipping=wart_skipping)


def _lr_tables_trusted(V, O, ring: Ring, num_vertices: int, *, wart_skipping: bool = True) -> LRTables:
    """:func:`lr_tables` on a corner table and ring the library built (unchecked)."""
    V = np.asarray(V, dtype=np.int32)
    O = np.asarray(O, dtype=np.int32)
    cL, cR, redL, redR, skL, skR, irL, irR, t0, lrc, t2 = _tables(
        V, O, ring.order, ring.right_corner, int(num_vertices), bool(wart_skipping))
    return LRTables(order=ring.order, left_corner=cL, right_corner=cR,
                    red_left=redL.astype(bool), red_right=redR.astype(bool),
                    skip_left=skL.astype(bool), skip_right=skR.astype(bool),
                    irr_left=irL.astype(bool), irr_right=irR.astype(bool), t0=t0,
                    lr_corner=lrc, num_t2=int(t2), ring=ring)
