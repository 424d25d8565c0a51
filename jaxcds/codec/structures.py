"""Decoding the words straight into the packed CDS6n / CDS5n arrays (CDS paper, Sec. 3.2).

The target arrays are the structures' own ``refs`` (``(n, 6)`` / ``(n, 5)`` int32, vertex index in
the low 30 bits, service bits 30 and 31, see :mod:`jaxcds.structures.cds`). The decoder writes
them in place and uses no other O(n) memory:

* CDS6n: ``ConstructRedTree`` / ``ConstructBlackTree`` (Fig. 10, 11) with the red stack in the
  ``S_blue^left`` column and the black stack in the ``S_blue^right`` column, then
  ``ConstructBlueTree`` (Fig. 12) overwrites both blue columns.
* CDS5n: the same first phase with ``S_red^toleft`` in place of ``S_red^left`` (``C`` = red or
  blue), both stacks in the single ``S_blue`` column (the red stack from the bottom, the black
  stack from the top: a vertex is never in both, Sec. 3.2), then ``ConstructBlueTree5n``
  (Fig. 13) writes ``S_blue``/``C_blue`` and turns some ``S_red^toleft`` into black references.

The face map ``F_blue`` of Thm 7 (one more reference per vertex) is then derived from the table
in linear time (a few temporary boolean/index arrays of size n, reported by the benchmark).
"""

from __future__ import annotations

import functools

import numba
import numpy as np

from jaxcds import errors
from jaxcds._arrays import to_device
from jaxcds.codec.decode import _MESSAGES, _bit, _raise, _check_size
from jaxcds.codec.words import Words

__all__ = ["decode_refs6n", "decode_refs5n", "decode_refs4n", "build_cds", "decode_cds6n", "decode_cds5n",
           "decode_cds4n"]

RED, BLUE, BLACK = 0, 1, 2
_IDX = (1 << 30) - 1
_B30 = 1 << 30
_B31 = 1 << 31
_U30 = np.uint32(_B30)  # the same bits as uint32 constants: stores into the uint32 view stay 32-bit
_U31 = np.uint32(_B31)

# column layouts: (red left/toleft, red right, red I col, black left, black right, black I col,
#                  stack col A, stack col B (== A: one two-ended stack column))
_L6 = (0, 1, 0, 4, 5, 4, 2, 3)
_L5 = (0, 1, 1, 3, 4, 3, 2, 2)


@numba.njit(cache=True, nogil=True, inline="always")
def _gs(r, u, col):
    return np.int64(r[u, col]) & _IDX


@numba.njit(cache=True, nogil=True, inline="always")
def _ss(r, u, col, val):
    r[u, col] = np.uint32((np.int64(r[u, col]) & ~np.int64(_IDX)) | val)


@numba.njit(cache=True, nogil=True, inline="always")
def _gb(r, u, col, bit):
    return (np.int64(r[u, col]) >> bit) & 1


@numba.njit(cache=True, nogil=True, inline="always")
def _sb(r, u, col, bit, flag):
    x = np.int64(r[u, col])
    if flag:
        x |= np.int64(1) << bit
    else:
        x &= ~(np.int64(1) << bit)
    r[u, col] = np.uint32(x)


@numba.njit(cache=True, nogil=True)
def _phase1(buf, n, mixed, r, L, five):
    """Fig. 10 + 11 into packed refs ``r`` (uint32 view). Returns (status, bit, vertex).

    Each reference is written with one store (value, colour bit 30, and bit 31 kept where it
    holds an ``I`` flag) instead of a read-modify-write per field; a leaf's ``I_red`` is not
    cleared (the table starts zeroed and only a first child sets it)."""
    c_rl, c_rr, c_ri, c_kl, c_kr, c_ki, c_sa, c_sb = L
    shared = c_sa == c_sb
    end_r = 4 * n - 3 if mixed else 2 * n
    pr = 0
    pb = 2 * n
    end_b = 4 * n - 3
    if _bit(buf, pr) != 0:
        return 1, 0, 0
    pr += 1
    r[0, c_sa] = 0  # red stack bottom: V_red
    rtop = 1
    btop = 0
    N = 0
    u = 0
    prev_open = True
    last_closed = 0
    root_last = 0
    while True:
        if prev_open:
            d = 0
            while True:
                if mixed:
                    if pr >= end_b:
                        return 5, pr, u
                    x = _bit(buf, pr)
                    pr += 1
                else:
                    if pb >= end_b:
                        return 5, pb, u
                    x = _bit(buf, pb)
                    pb += 1
                if x == 0:
                    break
                d += 1
            if d > 0:
                if u <= 1:
                    return 6, (pr if mixed else pb) - 1, u
                if d > btop:
                    return 7, (pr if mixed else pb) - 1, u
                r[u, c_ki] |= _U31  # I_black[u]
                btop -= 1
                x = np.int64(r[n - 1 - btop, c_sb]) if shared else np.int64(r[btop, c_sb])
                r[x, c_kl] = (r[x, c_kl] & _U31) | np.uint32(u)  # first black child: LeftFront = u_red
                for _ in range(d - 1):
                    y = x
                    btop -= 1
                    x = np.int64(r[n - 1 - btop, c_sb]) if shared else np.int64(r[btop, c_sb])
                    r[x, c_kl] = (r[x, c_kl] & _U31) | np.uint32(y) | _U30
                    r[y, c_kr] = np.uint32(x) | _U30
                r[x, c_kr] = np.uint32(u)  # last black child: RightFront = u_blue
        if pr >= end_r:
            return 4, pr, u
        s = _bit(buf, pr)
        pr += 1
        if s == 0:
            if N + 1 >= n:
                return 3, pr - 1, N
            N += 1
            v = N
            top = np.int64(r[rtop - 1, c_sa])
            if shared and rtop + btop >= n:
                return 3, pr - 1, N
            if prev_open:  # first red child: LeftFront = top_blue
                r[top, c_ri] |= _U31
                r[v, c_rl] = np.uint32(top) | (_U30 if five else np.uint32(0))
            else:  # next sibling of last_closed
                w = last_closed
                r[v, c_rl] = np.uint32(w) | (np.uint32(0) if five else _U30)
                r[w, c_rr] = (r[w, c_rr] & _U31) | np.uint32(v) | _U30
            r[rtop, c_sa] = np.uint32(v)
            rtop += 1
            u = v
            prev_open = True
        else:
            rtop -= 1
            u = np.int64(r[rtop, c_sa])
            if not prev_open:
                if u == 0:
                    root_last = last_closed
                    r[last_closed, c_rr] = (r[last_closed, c_rr] & _U31) | np.uint32(1) | _U30
                else:
                    r[last_closed, c_rr] = (r[last_closed, c_rr] & _U31) | np.uint32(u)
            if u > 1:
                if shared:
                    if rtop + btop >= n:
                        return 7, pr - 1, u
                    r[n - 1 - btop, c_sb] = np.uint32(u)
                else:
                    r[btop, c_sb] = np.uint32(u)
                btop += 1
            last_closed = u
            prev_open = False
            if rtop == 0:
                break
    if N != n - 1 or pr != end_r or ((not mixed) and pb != end_b):
        return 11, pr, N
    top_b = np.int64(r[n - 1, c_sb]) if shared else np.int64(r[0, c_sb])
    if btop != 1 or top_b != n - 1:
        return 8, pr, n - 1
    if _gb(r, 1, c_ri, 31) or _gb(r, n - 1, c_ri, 31) or root_last != n - 1:
        return 9, pr, 1
    # outer face (0, n-1, 1): LeftFront(1_red) = (n-1 -> 0), red
    _ss(r, 1, c_rl, n - 1)
    if five:
        _sb(r, 1, c_rl, 30, False)
        _sb(r, 1, c_rl, 31, False)
    else:
        _sb(r, 1, c_rl, 30, True)
    # the stacks are done: clear the blue column(s) for the blue phase
    for k in range(n):
        r[k, c_sa] = 0
        r[k, c_sb] = 0
    return 0, pr, 0


@numba.njit(cache=True, nogil=True)
def _blue6(n, r):
    """ConstructBlueTree (Fig. 12) on the CDS6n refs; V_blue's children by the same walk.

    The walk cw around ``x`` picks the next blue child ``v`` of ``x`` by the colour of the edge
    ``{v, u}`` (red: ``v = u + 1``; black: ``v = S_black^right[u]``) -- a coin flip for the
    branch predictor, so both candidates and both stop tests are computed and selected
    instead. Column 3 (``S_blue^right``, bit 31 unused) is written once per vertex by a plain
    store; column 2 keeps ``I_blue`` in bit 31."""
    budget = n
    for x in range(1, n - 1):
        rx1 = r[x, 1]
        rx4 = r[x, 4]
        sx1 = np.int64(rx1 & _IDX)
        sx4 = np.int64(rx4 & _IDX)
        cx1 = (rx1 >> 30) & 1
        cx4 = (rx4 >> 30) & 1
        if x == 1:
            if not cx1:
                return 9, 1
            u = sx1
        else:
            if sx1 == sx4 and cx1 != cx4:
                continue  # x has no blue child (I_blue stays false)
            if cx1:  # RightFront(x_red) is red: its source is the first blue child
                u = sx1
            else:  # RightFront(x_red) is black, out of z = red parent of x
                u = np.int64(r[sx1, 5] & _IDX)
        r[x, 2] |= np.uint32(_B31)  # I_blue[x]
        if u <= 1 or u >= n:
            return 10, x
        r[u, 3] = np.uint32(x)  # (u, x) first blue edge: S_blue^right[u] = x, C false (x's red edge)
        # stop tests of the walk: (v, u) red and v = S_black^left[x] with C false, or (u, v)
        # black and u = S_black^left[x] (V_blue: only at (V_black, V_blue), below)
        stop_red = sx4 if (x != 1 and cx4 == 0) else -1
        stop_blk = sx4 if x != 1 else -1
        while True:
            budget -= 1
            if budget < 0:
                return 10, x
            ired = (r[u, 0] >> 31) & 1  # I_red[u]: (v, u) red, v its first red child
            vb = np.int64(r[u, 5] & _IDX)
            v = u + 1 if ired else vb
            last = (v == stop_red) if ired else (u == stop_blk)
            if x == 1 and u == n - 1:  # (V_black, V_blue): last blue child of V_blue
                last = True
            if last:  # (u, x) last blue edge: LeftFront = x's black edge (V_blue: (V_blue, V_red))
                r[u, 2] = (r[u, 2] & np.uint32(_B31)) | np.uint32(x)
                break
            if (not ired) and u == n - 1:
                return 10, x
            if v <= 1 or v >= n:
                return 10, x
            r[u, 2] = (r[u, 2] & np.uint32(_B31)) | np.uint32(v) | np.uint32(_B30)
            r[v, 3] = np.uint32(u) | np.uint32(_B30)
            u = v
    if budget != 2:
        return 10, n - 1
    return 0, 0


@numba.njit(cache=True, nogil=True)
def _blue5(n, r):
    """ConstructBlueTree5n (Fig. 13) on the CDS5n refs: S_blue is LeftFront when I_red[u], else
    RightFront; S_red^toleft becomes a black reference (C = 2) to the second left neighbour.

    As in :func:`_blue6`, the next blue child and the stop test are selected rather than
    branched on, and each reference is written with one store."""
    budget = n
    for x in range(1, n - 1):
        rx1 = r[x, 1]
        rx3 = r[x, 3]
        sx1 = np.int64(rx1 & _IDX)
        sx3 = np.int64(rx3 & _IDX)
        cx1 = (rx1 >> 30) & 1
        cx3 = (rx3 >> 30) & 1
        if x == 1:
            if not cx1:
                return 9, 1
            u = sx1
        else:
            if sx1 == sx3 and cx1 != cx3:
                continue  # x has no blue child
            # RightFront of x_red must be red (no cw triangles in the maximal wood, Fig. 13)
            if not cx1:
                return 10, x
            u = sx1
        r[x, 2] |= _U31  # I_blue[x]
        if u <= 1 or u >= n:
            return 10, x
        stop_red = sx3 if (x != 1 and cx3 == 0) else -1
        stop_blk = sx3 if x != 1 else -1
        last_black = False  # ColorLastEdge = red
        z = x
        while True:
            budget -= 1
            if budget < 0:
                return 10, x
            ired = (r[u, 1] >> 31) & 1
            if x == 1 and u == n - 1:
                # (V_black, V_blue): I_red false, S_blue = RightFront (Thm 4, exterior edge)
                r[u, 2] = (r[u, 2] & _U31) | (np.uint32(z) | _U30 if z != x else np.uint32(1))
                break
            vb = np.int64(r[u, 4] & _IDX)
            v = u + 1 if ired else vb
            if ired and last_black:  # modified red reference: second left neighbour is black
                r[v, 0] = np.uint32(z) | _U31
            stop = (v == stop_red) if ired else (u == stop_blk)
            if ired:
                val = np.uint32(x) if stop else (np.uint32(v) | _U30)
            else:
                val = np.uint32(x) if z == x else (np.uint32(z) | _U30)
            r[u, 2] = (r[u, 2] & _U31) | val
            last_black = not ired
            if stop:
                break
            if (not ired) and u == n - 1:
                return 10, x
            if v <= 1 or v >= n:
                return 10, x
            rv2 = r[v, 2]
            if not ((r[v, 1] >> 31) & 1):  # I_red[v] false: v stores its RightFront = u_blue
                rv2 = (rv2 & _U31) | np.uint32(u) | _U30
            r[v, 2] = rv2
            z = u
            u = v
    if budget != 2:
        return 10, n - 1
    return 0, 0


def _run_phase1(words: Words, k: int, L, five: bool) -> np.ndarray:
    _check_size(words)
    n = words.num_vertices
    from jaxcds.structures.base import MAX_DARTS

    if 6 * n > MAX_DARTS:  # also below the 30-bit fields' 2^30 (Sec. 2.1)
        raise errors.EncodingError(f"n = {n:,}: a CDS holds at most {MAX_DARTS // 6:,} vertices (its 6n "
                                   "dart ids are int32; decode the faces instead)")
    refs = np.zeros((n, k), dtype=np.int32)
    r = refs.view(np.uint32)
    buf = np.ascontiguousarray(words.bits, dtype=np.uint8)
    status, bit, vertex = _phase1(buf, n, bool(words.mixed), r, L, five)
    if status:
        _raise(status, bit, vertex, words, "red/black trees")
    return refs


def decode_refs6n(words: Words) -> np.ndarray:
    """The ``(n, 6)`` int32 refs of :class:`~jaxcds.structures.cds.CDS6n` (Fig. 10-12), no
    memory beyond them."""
    refs = _run_phase1(words, 6, _L6, False)
    status, vertex = _blue6(words.num_vertices, refs.view(np.uint32))
    if status:
        raise errors.EncodingError(f"blue tree: {_MESSAGES[status]} (around vertex {vertex}, n = {words.num_vertices})")
    return refs


def decode_refs5n(words: Words) -> np.ndarray:
    """The ``(n, 5)`` int32 refs of :class:`~jaxcds.structures.cds.CDS5n` (Fig. 10, 11, 13), no
    memory beyond them (words of the maximal Schnyder wood)."""
    refs = _run_phase1(words, 5, _L5, True)
    status, vertex = _blue5(words.num_vertices, refs.view(np.uint32))
    if status:
        raise errors.EncodingError(
            f"blue tree (5n): {_MESSAGES[status]} (around vertex {vertex}, n = {words.num_vertices}); "
            "CDS5n needs the words of the maximal Schnyder wood")
    return refs


# --------------------------------------------------------------------------- face map (Thm 7)
def _face_map(n: int, black_matched: np.ndarray, ired: np.ndarray, blue_left_blue: np.ndarray,
              outer: tuple = None):
    """``(F_blue, unused_slots)`` of Thm 7, as ``jaxcds.structures.cds.face_slots`` computes
    them, from the table's bits (``outer = (V_red, V_blue, V_black)``, default ``(0, 1, n-1)``)."""
    from jaxcds.structures.cds import assign_face_slots

    v_red, v_blue, v_black = outer or (0, 1, n - 1)
    u = np.arange(n)
    has_blue = (u != v_red) & (u != v_blue)
    blue_matched = has_blue & ~ired & blue_left_blue
    blue_matched[v_black] = False  # left face of (V_black, V_blue) is the outer face
    return assign_face_slots(black_matched, blue_matched, v_red, errors.EncodingError,
                             " (the words are not those of a maximal Schnyder wood)")


def _bits(col, bit):
    return ((col.view(np.uint32) >> np.uint32(bit)) & np.uint32(1)).astype(bool)


def face_map6n(refs: np.ndarray):
    n = refs.shape[0]
    has_black = (np.arange(n) >= 2) & (np.arange(n) < n - 1)
    return _face_map(n, has_black & _bits(refs[:, 4], 30), _bits(refs[:, 0], 31), _bits(refs[:, 2], 30))


def face_map5n(refs: np.ndarray):
    n = refs.shape[0]
    has_black = (np.arange(n) >= 2) & (np.arange(n) < n - 1)
    # LeftFront(u_blue) for I_red[u] false is RightFront(u_black) (Thm 4 Case 1): blue iff not black
    return _face_map(n, has_black & _bits(refs[:, 3], 30), _bits(refs[:, 1], 31), ~_bits(refs[:, 4], 30))


# --------------------------------------------------------------------------- structures
def decode_cds6n(words: Words, *, boundaries_closed: bool = False):
    """Words -> :class:`~jaxcds.structures.cds.CDS6n` (vertex ``i`` = ``i``-th vertex of the ccw
    DFS of ``T_red``; ``V_red = 0``, ``V_blue = 1``, ``V_black = n - 1``)."""
    from jaxcds.structures.cds import CDS6n, with_target_rounds

    refs = decode_refs6n(words)
    fb, unused = face_map6n(refs)
    n = words.num_vertices
    s = CDS6n(refs=to_device(refs), F_blue=to_device(fb), num_vertices=n, num_faces=2 * n - 4,
              v_red=0, v_blue=1, v_black=n - 1, unused_slots=unused, boundaries_closed=boundaries_closed)
    s = with_target_rounds(s)  # the static round count of the all-Targets pass (no wood here)
    _refuse_clockwise_triangles(s)
    return s


@functools.cache
def _jitted_edge_targets():
    """``s -> (Target, edge_valid)`` of every edge id ``3u + c``, jitted once (one program per
    shape)."""
    import jax
    import jax.numpy as jnp

    return jax.jit(lambda s: (s.all_edge_targets(),
                              s.edge_valid(jnp.arange(3 * s.num_vertices, dtype=jnp.int32))))


def _refuse_clockwise_triangles(s) -> None:
    """Raise :class:`EncodingError` where the decoded wood has a clockwise triangle (a cycle
    ``u ->red a ->black b ->blue u``): not the maximal wood (Lemma 3), and the Thm 7 face map
    read off the table bits (:func:`face_map6n`) is only right for the maximal one. CDS6n's own
    tables (Thm 2) decode from any wood's words; CDS5n/4n refuse other woods while decoding.
    One all-Targets pass (pointer jumping) and three gathers: about a tenth of the decode."""
    from jaxcds.construct.schnyder import BLACK, BLUE, RED

    n = s.num_vertices
    t, ok = (np.asarray(x).reshape(n, 3) for x in _jitted_edge_targets()(s))
    t = np.vstack([np.where(ok, t, n), np.full((1, 3), n)])  # row n: "absent"
    u = np.arange(n)
    a = t[u, RED]
    b = t[a, BLACK]
    cw = np.flatnonzero(t[b, BLUE] == u)
    if cw.size:
        x = int(cw[0])
        raise errors.EncodingError(
            f"the words encode a Schnyder wood with a clockwise triangle (decoded vertices {x}, "
            f"{int(a[x])}, {int(b[x])}; {cw.size} such): not the maximal wood, and CDS6n's face map "
            "(Thm 7) is decoded for the maximal one; encode with maximal=True (the default), or "
            "decode to a mesh (read_cds), which any wood's words give")


def decode_cds5n(words: Words, *, boundaries_closed: bool = False):
    """Words of a maximal Schnyder wood -> :class:`~jaxcds.structures.cds.CDS5n`."""
    from jaxcds.structures.cds import CDS5n, with_target_rounds

    refs = decode_refs5n(words)
    fb, unused = face_map5n(refs)
    n = words.num_vertices
    s = CDS5n(refs=to_device(refs), F_blue=to_device(fb), num_vertices=n, num_faces=2 * n - 4,
              v_red=0, v_blue=1, v_black=n - 1, unused_slots=unused, boundaries_closed=boundaries_closed)
    return with_target_rounds(s)  # the static round count of the all-Targets pass (no wood here)


# --------------------------------------------------------------------------- CDS4n (Sec. 5.2)
@numba.njit(cache=True, nogil=True)
def _cwbfs5(r, n, order, label):
    """cwBFS of the red tree read off the CDS5n refs (Sec. 2.3): the children of ``v`` are
    ``v + 1`` (first, ccw) and its red RightFront siblings; cwBFS lists them last to first
    (at V_red: V_black first, V_blue last). ``order`` doubles as the BFS queue."""
    order[0] = 0
    label[0] = 0
    head = 0
    tail = 1
    while head < tail:
        v = order[head]
        head += 1
        if not _gb(r, v, 1, 31):  # I_red[v]: no children
            continue
        k = 0
        c = v + 1
        while True:  # count the children, ccw
            k += 1
            if c == n - 1 or not _gb(r, c, 1, 30):
                break
            c = _gs(r, c, 1)
        c = v + 1
        for i in range(k):  # the ccw i-th child gets the (k - 1 - i)-th cw label
            if tail + k - 1 - i >= n:
                return -1
            order[tail + k - 1 - i] = c
            label[c] = tail + k - 1 - i
            if i + 1 < k:
                c = _gs(r, c, 1)
        tail += k
    return tail


@numba.njit(cache=True, nogil=True)
def _refs4(r5, n, order, label, r4):
    lab = lambda x: label[x]  # noqa: E731
    for i in range(n):
        u = order[i]
        x0 = np.int64(r5[u, 0])
        r4[i, 0] = np.uint32((x0 & ~np.int64(_IDX)) | lab(x0 & _IDX))           # toleft, C (2 bits)
        x2 = np.int64(r5[u, 2])
        r4[i, 1] = np.uint32((x2 & _B30) | ((np.int64(r5[u, 1]) >> 31) << 31) | lab(x2 & _IDX))  # S_blue, I_red
        x3 = np.int64(r5[u, 3])
        r4[i, 2] = np.uint32((x3 & _B30) | ((x2 >> 31) << 31) | lab(x3 & _IDX))  # S_black^left, I_blue
        x4 = np.int64(r5[u, 4])
        r4[i, 3] = np.uint32((x4 & _B30) | ((x3 >> 31) << 31) | lab(x4 & _IDX))  # S_black^right, I_black


def decode_refs4n(words: Words):
    """``(refs (n, 4) int32, order (n,) int32)`` of :class:`~jaxcds.structures.cds.CDS4n`:
    decode into CDS5n (memory-free), then relabel by cwBFS. Not memory-free: the relabelling
    needs the 5n table, the new 4n table and two n-int permutations at once (11n ints peak)."""
    r5 = decode_refs5n(words)
    n = words.num_vertices
    order = np.empty(n, dtype=np.int32)
    label = np.empty(n, dtype=np.int32)
    if _cwbfs5(r5.view(np.uint32), n, order, label) != n:
        raise errors.EncodingError(f"cwBFS of the decoded red tree does not reach all {n} vertices")
    r4 = np.zeros((n, 4), dtype=np.int32)
    _refs4(r5.view(np.uint32), n, order, label, r4.view(np.uint32))
    return r4, order


def decode_cds4n(words: Words, *, boundaries_closed: bool = False):
    """Words of a maximal Schnyder wood -> :class:`~jaxcds.structures.cds.CDS4n` (Thm 5), its
    ``vertex_order`` mapping cwBFS labels to decoded (DFS) vertex ids."""
    from jaxcds.structures.cds import CDS4n, with_target_rounds

    r4, order = decode_refs4n(words)
    n = words.num_vertices
    label1 = int(np.nonzero(order == 1)[0][0])
    has_black = np.ones(n, dtype=bool)
    has_black[[0, label1, 1]] = False  # V_red = 0, V_blue, V_black = label 1
    fb, unused = _face_map(n, has_black & _bits(r4[:, 2], 30), _bits(r4[:, 1], 31),
                           ~_bits(r4[:, 3], 30), outer=(0, label1, 1))
    s = CDS4n(refs=to_device(r4), F_blue=to_device(fb), order=to_device(order), num_vertices=n,
              num_faces=2 * n - 4, v_red=0, v_blue=label1, v_black=1, unused_slots=unused,
              boundaries_closed=boundaries_closed)
    return with_target_rounds(s)


def _checked_dummy(dummy, words: Words) -> np.ndarray:
    """``dummy`` as an ``(n,)`` bool mask of the decoded vertices, or an ArgumentError: the
    wrong length, values other than 0/1, or a mask no hole closing can have written
    (:func:`~jaxcds.codec.fileformat.check_dummy_mask` on the decoded faces)."""
    from jaxcds.codec.decode import decode_faces
    from jaxcds.codec.fileformat import check_dummy_mask

    try:
        d = np.asarray(dummy)
    except ValueError as exc:  # ragged nested lists
        raise errors.ArgumentError(f"dummy mask is not an array: {exc}") from None
    n = words.num_vertices
    if d.shape != (n,):
        raise errors.ArgumentError(f"dummy mask of shape {d.shape} for {n} decoded vertices")
    if d.dtype != bool:
        if d.dtype.kind not in "iu" or not np.isin(d, (0, 1)).all():
            raise errors.ArgumentError(f"dummy mask must be booleans (or 0/1), got dtype {d.dtype}")
        d = d.astype(bool)
    if d.any():
        check_dummy_mask(d, decode_faces(words)[0], None)
    return d


def build_cds(structure: str, words: Words, *, dummy=None, **kw):
    """``"cds6n"``, ``"cds5n"`` or ``"cds4n"`` from words. ``dummy``: ``(n,)`` bool, the
    dummy vertices that closed holes, in decoded vertex order (the ``.cds`` file's dummy mask):
    kept as the structure's ``dummy_ids`` (degrees and normals of the open surface)."""
    from jaxcds import _mappings
    from jaxcds.structures.cds import with_dummy_vertices

    _mappings.relieve()  # a folder of .cds files decoded in one process: programs pile up
    if dummy is not None:
        dummy = _checked_dummy(dummy, words)
        kw.setdefault("boundaries_closed", bool(dummy.any()))
    if structure == "cds6n":
        s = decode_cds6n(words, **kw)
    elif structure == "cds5n":
        s = decode_cds5n(words, **kw)
    elif structure == "cds4n":
        s = decode_cds4n(words, **kw)
    else:
        raise errors.ArgumentError(f"unknown structure {structure!r}: cds6n, cds5n or cds4n")
    return with_dummy_vertices(s, dummy)
