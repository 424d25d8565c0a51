"""Local search on the LR ring: fewer references per triangle than RING-EXPANDER alone.

This goes beyond the paper. RING-EXPANDER (Gurung et al. 2011, Sec. 4.2) is one greedy pass; on
irregular meshes its ring leaves many T0 triangles, and each T0 that wart skipping cannot absorb
costs about 15 references (Sec. 5: 6 in ``VO`` plus 3 per irregular neighbour in ``VO*``). Here
simulated annealing moves the ring while keeping the invariant RING-EXPANDER guarantees: the
invaded triangles form a disk whose vertices all lie on its boundary, the ring (Sec. 4.2, "no
interior vertices ... bounded by a single manifold loop").

Why the search is cheap: the Sec. 8 reference count ``2 m_r + 6 n0 + 3 n^i + m_i`` is a sum of
local terms. With ``k(t)`` the number of ring edges of triangle ``t`` (T0, T1, T2 for 0, 1, 2):

* wart skipping (Sec. 5) absorbs exactly the T0 triangles that have a T2 neighbour (each T2 has
  one non-ring edge, so it can serve one T0; which T2 serves is a tie that does not change the
  count), so a triangle is a stored T0 iff ``k(t) = 0`` and no neighbour has ``k = 2``;
* a triangle that fills a ring slot (T1, T2, or an absorbed T0^w) is irregular (Sec. 4.5) iff a
  neighbour is a stored T0;
* ``2 m_r + m_i = m_r + (m - dummies)``.

So toggling one triangle changes the terms of the triangles within three edge-adjacent steps only
(at most 22 of them): every move is O(1), and ``sweeps * n`` moves take linear time. The moves:

* *grow*: invade a non-invaded triangle with exactly one invaded neighbour whose apex is not on
  the ring (RING-EXPANDER's own step; it puts an isolated vertex back on the ring);
* *relocate*: un-invade an ear (an invaded triangle with two ring edges: its tip leaves the ring)
  and, nine times out of ten, invade another triangle at the tip across a ring edge (the tip
  rejoins the ring there); otherwise the tip stays isolated (``m_i`` grows, which can pay off);
* *relocate on the other side*: the mirror image for an ear of the non-invaded side (a
  non-invaded triangle with two ring edges whose tip has no other non-invaded triangle): invade
  it, which puts its tip inside the disk, and give back another triangle at the tip that faces
  the non-invaded side, which puts the tip back on the ring. Without this move the search only
  reshapes the invaded side's triangle tree and stalls about halfway (decimated bunny: 1.17 rpt
  instead of 1.05).

All three keep the invaded region a disk with no interior vertex and never invade a dummy triangle
(Sec. 4.6). The result is a valid ring for :func:`jaxcds.construct.ring_expander.lr_tables`;
:func:`ring_cost` recomputes the count from scratch (tests compare the two).
"""

from __future__ import annotations

from typing import Optional

import numba
import numpy as np

from jaxcds import errors
from jaxcds._args import is_integer
from jaxcds._progress import Progress, want_progress
from jaxcds.construct.ring_expander import _extract_ring, _n, _tables, check_corner_table

__all__ = ["improve_ring", "ring_cost", "check_sweeps"]


@numba.njit(cache=True, inline="always")
def _is_stored_t0(O, k, x):
    """T0 after wart skipping: no ring edge and no T2 neighbour to absorb it."""
    b = 3 * x
    return (k[x] == 0 and k[O[b] // 3] != 2 and k[O[b + 1] // 3] != 2
            and k[O[b + 2] // 3] != 2)


@numba.njit(cache=True)
def _term(O, k, t):
    """References ``t`` adds beyond its ring slot: 6 for a stored T0 (``VO``), 3 for a slot
    triangle next to a stored T0 (its ``VO*`` triplet), else 0."""
    if _is_stored_t0(O, k, t):
        return 6
    b = 3 * t
    if (_is_stored_t0(O, k, O[b] // 3) or _is_stored_t0(O, k, O[b + 1] // 3)
            or _is_stored_t0(O, k, O[b + 2] // 3)):
        return 3
    return 0


@numba.njit(cache=True)
def _ball(O, x, stamp, mark, buf):
    """Triangles within three edge-adjacent steps of ``x`` into ``buf``; returns their count."""
    buf[0] = x
    stamp[x] = mark
    n = 1
    start = 0
    for _ in range(3):
        end = n
        for i in range(start, end):
            t = buf[i]
            for q in range(3):
                u = O[3 * t + q] // 3
                if stamp[u] != mark:
                    stamp[u] = mark
                    buf[n] = u
                    n += 1
        start = end
    return n


@numba.njit(cache=True)
def _ball_terms(O, k, buf, n):
    s = 0
    for i in range(n):
        s += _term(O, k, buf[i])
    return s


@numba.njit(cache=True)
def _ring_edges(O, tm, t):
    b = 3 * t
    return ((tm[t] != tm[O[b] // 3]) + (tm[t] != tm[O[b + 1] // 3])
            + (tm[t] != tm[O[b + 2] // 3]))


@numba.njit(cache=True)
def _flip(V, O, tm, k, cnt, x):
    """Toggle ``tm[x]``, update ``k`` (ring edges per triangle) and ``cnt`` (invaded triangles per
    vertex); returns the change of ``m_r``."""
    tm[x] ^= 1
    s = 1 if tm[x] else -1
    b = 3 * x
    k[x] = _ring_edges(O, tm, x)
    dm = 0
    for q in range(3):
        u = O[b + q] // 3
        k[u] = _ring_edges(O, tm, u)
        v = V[b + q]
        was = cnt[v] > 0
        cnt[v] += s
        dm += int(cnt[v] > 0) - int(was)
    return dm


@numba.njit(cache=True)
def _flip_delta(V, O, tm, k, cnt, x, stamp, mark, buf):
    """Toggle ``tm[x]`` and return the change of the reference count (local, see module doc)."""
    n = _ball(O, x, stamp, mark, buf)
    before = _ball_terms(O, k, buf, n)
    dm = _flip(V, O, tm, k, cnt, x)
    return _ball_terms(O, k, buf, n) - before + dm


@numba.njit(cache=True)
def _odd_neighbour(O, tm, x):
    """Corner of ``x`` facing its only neighbour on the other side of the ring from the
    majority: the only invaded neighbour of a non-invaded ``x`` with one invaded neighbour, the
    only non-invaded neighbour of a non-invaded ``x`` with two, the only invaded neighbour of an
    invaded ``x`` with one (an ear); -1 otherwise. Second value: invaded neighbours."""
    c1 = -1
    c0 = -1
    ninv = 0
    for q in range(3):
        if tm[O[3 * x + q] // 3]:
            ninv += 1
            c1 = 3 * x + q
        else:
            c0 = 3 * x + q
    if ninv == 1:
        return c1, ninv
    if ninv == 2 and tm[x] == 0:
        return c0, ninv
    return -1, ninv


@numba.njit(cache=True)
def _pick_at(O, tm, cin, want):
    """A random triangle around ``V[cin]`` (other than ``cin``'s) whose edge opposite that vertex
    borders a triangle with invaded flag ``want`` (reservoir pick while swinging)."""
    u = -1
    seen = 0
    c = cin
    for _ in range(4096):
        c = _n(O[_n(c)])  # swing around the vertex (c.s = c.n.o.n)
        if c == cin:
            break
        if tm[O[c] // 3] == want:
            seen += 1
            if np.random.randint(seen) == 0:
                u = c // 3
    return u


@numba.njit(cache=True)
def _accept(d, temp):
    return d <= 0 or np.random.random() < np.exp(-d / temp)


@numba.njit(cache=True)
def _seed(seed):
    np.random.seed(seed)


@numba.njit(cache=True)
def _state(V, O, tm, num_vertices):
    """``k`` (ring edges per triangle), ``cnt`` / ``deg`` (invaded / all triangles per vertex),
    and the search's counters ``[invaded triangles, stamp mark]``."""
    nf = tm.shape[0]
    k = np.zeros(nf, np.int8)
    cnt = np.zeros(num_vertices, np.int32)
    deg = np.zeros(num_vertices, np.int32)
    inv = 0
    for t in range(nf):
        k[t] = _ring_edges(O, tm, t)
        for q in range(3):
            deg[V[3 * t + q]] += 1
        if tm[t]:
            inv += 1
            for q in range(3):
                cnt[V[3 * t + q]] += 1
    ctr = np.zeros(2, np.int64)
    ctr[0] = inv
    return k, cnt, deg, ctr


@numba.njit(cache=True)
def _anneal(V, O, tm, dummy, k, cnt, deg, stamp, ctr, moves, temp, ratio):
    """``moves`` random triangle picks of simulated annealing on ``tm`` in place (most picks are
    not a legal move and cost a few reads), the temperature multiplied by ``ratio`` per pick.
    Returns ``(change of the reference count, final temperature)``; the state arrays and
    counters carry over between calls (a long search runs in chunks, for the progress bar)."""
    nf = tm.shape[0]
    buf = np.empty(32, np.int64)
    inv = ctr[0]
    mark = ctr[1]
    total = 0
    for _ in range(moves):
        temp *= ratio
        x = np.random.randint(nf)
        cin, ninv = _odd_neighbour(O, tm, x)
        if cin < 0:
            continue
        tip = V[cin]
        if tm[x] == 0 and ninv == 1:  # grow: RING-EXPANDER's step onto a vertex off the ring
            if cnt[tip] != 0 or dummy[tip]:
                continue
            mark += 1
            d = _flip_delta(V, O, tm, k, cnt, x, stamp, mark, buf)
            if _accept(d, temp):
                total += d
                inv += 1
            else:
                _flip(V, O, tm, k, cnt, x)
            continue
        if tm[x] == 0:
            # relocate an ear of the other side: invade it (its tip is then inside the disk) and
            # give back another triangle at the tip that faces the other side (tip back on the ring)
            if cnt[tip] != deg[tip] - 1:
                continue
            u = _pick_at(O, tm, cin, 0)
            if u < 0:
                continue
            mark += 1
            d = _flip_delta(V, O, tm, k, cnt, x, stamp, mark, buf)
            mark += 1
            d += _flip_delta(V, O, tm, k, cnt, u, stamp, mark, buf)
            if _accept(d, temp):
                total += d
            else:
                _flip(V, O, tm, k, cnt, u)
                _flip(V, O, tm, k, cnt, x)
            continue
        # relocate an ear: keep at least 2 invaded triangles (a ring of >= 4 vertices)
        if inv <= 2 or cnt[tip] != 1:
            continue
        mark += 1
        d = _flip_delta(V, O, tm, k, cnt, x, stamp, mark, buf)
        u = _pick_at(O, tm, cin, 1) if np.random.random() < 0.9 else -1
        if u >= 0:
            mark += 1
            d += _flip_delta(V, O, tm, k, cnt, u, stamp, mark, buf)
        if _accept(d, temp):
            total += d
            if u < 0:
                inv -= 1
        else:
            if u >= 0:
                _flip(V, O, tm, k, cnt, u)
            _flip(V, O, tm, k, cnt, x)
    ctr[0] = inv
    ctr[1] = mark
    return total, temp


def _search(V, O, tm, dummy, num_vertices, moves, t_hi, t_lo, seed, chunks=1, bar=None) -> int:
    """Anneal ``tm`` in place for ``moves`` picks, temperature ``t_hi -> t_lo``, in ``chunks``
    calls (``bar.step()`` after each); returns the change of the reference count."""
    _seed(seed)
    k, cnt, deg, ctr = _state(V, O, tm, num_vertices)
    stamp = np.zeros(tm.shape[0], np.int64)
    ratio = (t_lo / t_hi) ** (1.0 / max(moves, 1))
    temp, total = float(t_hi), 0
    for i in range(chunks):
        part = moves * (i + 1) // chunks - moves * i // chunks
        d, temp = _anneal(V, O, tm, dummy, k, cnt, deg, stamp, ctr, part, temp, ratio)
        total += int(d)
        if bar is not None:
            bar.step()
    return total


@numba.njit(cache=True)
def _full_cost(V, O, tm, num_vertices, num_dummy):
    order, rc = _extract_ring(V, O, tm, num_vertices)
    m = order.shape[0]
    if m < 4:
        return -1
    _, _, _, _, _, _, irL, irR, t0, _, _ = _tables(V, O, order, rc, num_vertices, True)
    return 2 * m + 6 * t0.shape[0] + 3 * (int(irL.sum()) + int(irR.sum())) + (
        num_vertices - m - num_dummy)


def ring_cost(V, O, tm, num_vertices: int, dummy: Optional[np.ndarray] = None) -> int:
    """The Sec. 8 count ``2 m_r + 6 n0 + 3 n^i + m_i`` of the ring bounding the invaded triangles
    ``tm``, from scratch (ring extraction and :func:`lr_tables`'s classification); -1 if ``tm``
    is not bounded by one simple loop of at least 4 vertices. The arguments are checked
    (:func:`~jaxcds.construct.ring_expander.check_corner_table`)."""
    V, O, num_vertices, tm, dummy = check_corner_table(V, O, num_vertices, "ring_cost", tm=tm, dummy=dummy)
    nd = 0 if dummy is None else int(np.sum(dummy))
    return int(_full_cost(np.asarray(V, np.int32), np.asarray(O, np.int32),
                          np.asarray(tm, np.uint8), int(num_vertices), nd))


#: the most sweeps accepted: ``sweeps * n`` moves, 100 already gives the figures in RESULTS;
#: beyond 64-bit move counts the kernel failed with a numba typing error
MAX_SWEEPS = 100_000


def check_sweeps(sweeps) -> int:
    """``sweeps`` as an int, or the typed error (booleans, floats, strings, negatives and more
    than :data:`MAX_SWEEPS` refused)."""
    if not is_integer(sweeps) or sweeps < 0 or sweeps > MAX_SWEEPS:
        raise errors.ArgumentError(
            f"ring_sweeps must be an integer in [0, {MAX_SWEEPS}], got {sweeps!r}")
    return int(sweeps)


def improve_ring(V, O, tm, num_vertices: int, *, dummy: Optional[np.ndarray] = None,
                 sweeps: int = 50, t_hi: float = 3.0, t_lo: float = 0.05, seed: int = 0,
                 progress: Optional[bool] = None):
    """Anneal the invaded triangles ``tm`` (RING-EXPANDER's output) towards fewer LR references.

    ``sweeps * n`` random moves (see the module doc), temperature ``t_hi -> t_lo`` references.
    Returns ``(tm, delta)``: a new ``(n,)`` uint8 array and the change of the Sec. 8 count
    (``<= 0``: the input comes back unchanged if the search ends worse). ``progress``: a text
    progress bar on stderr (``None``: for meshes of a million vertices or more on a terminal).
    The arrays are checked (:func:`~jaxcds.construct.ring_expander.check_corner_table`)."""
    V, O, num_vertices, tm, dummy = check_corner_table(V, O, num_vertices, "improve_ring", tm=tm,
                                                       dummy=dummy)
    return _improve_ring_trusted(V, O, tm, num_vertices, dummy=dummy, sweeps=sweeps, t_hi=t_hi,
                                 t_lo=t_lo, seed=seed, progress=progress)


def _improve_ring_trusted(V, O, tm, num_vertices: int, *, dummy: Optional[np.ndarray] = None,
                          sweeps: int = 50, t_hi: float = 3.0, t_lo: float = 0.05, seed: int = 0,
                          progress: Optional[bool] = None):
    """:func:`improve_ring` on arrays the library built (unchecked)."""
    sweeps = check_sweeps(sweeps)
    for name, t in (("t_hi", t_hi), ("t_lo", t_lo)):  # a str raised TypeError, an array ValueError
        if isinstance(t, (bool, np.bool_)) or not isinstance(t, (int, float, np.integer, np.floating)):
            raise errors.ArgumentError(f"improve_ring: {name} must be a number (a temperature in "
                                       f"references), got {type(t).__name__} {t!r}")
    if not (0 < t_lo <= t_hi):
        raise errors.StructureError(f"temperatures must satisfy 0 < t_lo <= t_hi, got {t_lo}, {t_hi}")
    V = np.asarray(V, np.int32)
    O = np.asarray(O, np.int32)
    tm0 = np.asarray(tm, np.uint8)
    nv = int(num_vertices)
    dm = np.zeros(nv, np.uint8) if dummy is None else np.asarray(dummy).astype(np.uint8)
    out = tm0.copy()
    moves = int(sweeps) * int(out.shape[0])
    show = want_progress(progress, nv)
    chunks = min(20, max(sweeps, 1)) if show else 1
    bar = Progress([f"{sweeps} sweeps"] * chunks, "LR ring search", show) if show else None
    delta = _search(V, O, out, dm, nv, moves, float(t_hi), float(t_lo), int(seed), chunks, bar)
    if delta > 0:
        return tm0.copy(), 0
    return out, delta
