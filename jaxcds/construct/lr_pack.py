"""Packing and construction check of the LR structures (Gurung, Luffel, Lindstrom, Rossignac,
*LR: Compact connectivity representation for triangle meshes*, ACM TOG 2011), numba, linear time.

:func:`jaxcds.construct.ring_expander.lr_tables` classifies triangles against the ring; this
module turns those tables into the arrays of :class:`jaxcds.structures.lr.LR` and
:class:`~jaxcds.structures.lr.LRBits` in a few O(n) passes, no Python loop over elements:

* :func:`pack_common` -- vertex renumbering (ring first, isolated vertices, dummies last,
  Sec. 4.6), T0 corner table ``V0, O0`` (real T0 first), ``C`` for isolated vertices, the ring
  slots' apexes and their *true* opposites read from the corner table, and the irregular slots:
  the ring case analysis of Sec. 4.5 / Fig. 6 / Sec. 5 is run on every corner of every regular
  slot and a transversal corner it cannot resolve makes its slot irregular (stored in ``VO*``);
* :func:`pack_lr` / :func:`pack_lr_bits` -- the 32-bit ``L, R`` entries with service bits
  (Sec. 6.2) and ``VO*`` triplets (Sec. 4.5); the 16-bit relative offsets with long references
  through ``VO*`` records (Sec. 6.1);
* :func:`check_lr` / :func:`check_lr_bits` -- the construction-time invariant: ``c.v`` and
  ``c.o`` of every canonical corner, decoded from the packed arrays exactly as the jitted
  operators of :mod:`jaxcds.structures.lr` decode them, equal the corner table's.

**Internal.** These are the LR builders' unchecked numba kernels, called on arrays
:mod:`jaxcds.structures.lr` made itself: an array out of range reads and writes out of bounds
(numba checks no index), so none of them is exported (``__all__`` is empty since stop 50; sweep
50c found them listed there). Build through :meth:`LR.from_mesh <jaxcds.structures.lr.LR.from_mesh>`
or ``from_corner_table``, which check their input.

The scalar functions below (``_ring_vertex``, ``_canonical``, ``_find``, ``_cheap_opposite``)
are line-by-line twins of the ``xp`` functions of :mod:`jaxcds.structures.lr` (which remain the
structure's operators); ``tests/structures/test_lr.py`` checks the twins against the jitted
operators on every corner.
"""

from __future__ import annotations

import numba
import numpy as np

__all__: list[str] = []  # internal kernels: see the module docstring

_VALUE_BITS = 29
_VALUE_MASK = (1 << _VALUE_BITS) - 1
_SKIP_BIT = 29
_IRR_BIT = 30
FAIL = 2**31 - 1  # "no cheap opposite" (lr._FAIL)


# ------------------------------------------------------------------------------ case analysis
# The ring case analysis reads, for a few ring vertices around the corner, the apex and the
# wart-skip bit of a slot. The case-analysis functions are inlined at numba IR level (about 20%
# faster) and each has ONE call site per kernel: inlined into every call site, the packing
# kernel took ~40 s to compile with a cold cache. They live in one int32 pair per ring vertex, ``E[v, 0] = v.l | skl << 29``
# and ``E[v, 1] = v.r | skr << 29`` (the LR entry layout without the irregular bit), so each
# (random) ring vertex touched costs one cache line.
@numba.njit(cache=True, inline="always")
def _ctn(c):
    return 3 * (c // 3) + (c + 1) % 3


@numba.njit(cache=True, inline="always")
def _ctp(c):
    return 3 * (c // 3) + (c + 2) % 3


@numba.njit(cache=True, inline="always")
def _nx(x, m):
    """``v.n = v + 1 mod m_r``."""
    return x + 1 - m if x + 1 >= m else x + 1


@numba.njit(cache=True, inline="always")
def _pv(x, m):
    """``v.p = v - 1 mod m_r``."""
    return m - 1 if x == 0 else x - 1


@numba.njit(cache=True, inline="always")
def _ap(E, v, side):
    """Apex ``v.l`` (side 0) or ``v.r`` (side 1)."""
    return np.int64(E[v, side]) & _VALUE_MASK


@numba.njit(cache=True, inline="always")
def _sk(E, v, side):
    """Wart-skip bit of slot ``L(v)`` (side 0) or ``R(v)`` (side 1)."""
    return (np.int64(E[v, side]) >> _SKIP_BIT) & 1


@numba.njit(cache=True, inline="always")
def _ring_vertex(c, m, E):
    """``c.v`` of a ring corner (Sec. 4.7, Fig. 5): twin of ``lr._ring_vertex``."""
    v = c >> 3
    i = c & 7
    vn = _nx(v, m)
    if i == 1:
        return _ap(E, v, 0)
    if i == 5:
        return _ap(E, v, 1)
    if i == 2:
        return _nx(vn, m) if _sk(E, v, 0) else vn
    if i == 4:
        return _nx(vn, m) if _sk(E, v, 1) else vn
    return v


@numba.njit(cache=True, inline="always")
def _canonical(c, m, E):
    """Redundant T2 corner -> its canonical copy (Sec. 4.4): twin of ``lr._canonical``."""
    if c < 0 or c >= 8 * m:
        return c
    w = c >> 3
    i = c & 7
    side = 0 if i < 4 else 1
    wn = _nx(w, m)
    if _sk(E, w, side) == 0 and _ap(E, w, side) == _nx(wn, m):
        return 8 * wn + 4 * side + (i + 1) % 3
    return c


@numba.njit(cache=True, inline="always")
def _find(m, side, x, y, E):
    """Transversal opposite from the ring alone (Sec. 4.5, Fig. 6, Sec. 5): twin of ``lr._find``
    (``side`` 1 = right)."""
    okx = x >= 0 and x < m
    oky = y >= 0 and y < m
    if okx and _ap(E, x, side) == y:
        return 8 * x + (4 if side else 2)
    if not oky:
        return FAIL
    off_b = 6 if side else 0
    w1 = _pv(y, m)
    if _sk(E, w1, side) == 0 and _ap(E, w1, side) == x:
        return 8 * w1 + off_b
    w2 = _pv(w1, m)
    if _sk(E, w2, side) == 1 and _ap(E, w2, side) == x:
        return 8 * w2 + off_b
    return FAIL


@numba.njit(cache=True, inline="always")
def _cheap_opposite(c, m, E):
    """``c.o`` of a ring corner of a regular triangle before canonicalisation (Sec. 4.5, Fig. 6,
    Sec. 5): twin of ``lr._cheap_opposite`` (same cases, evaluated lazily; one ``_find`` call
    site so that inlining stays small)."""
    v = c >> 3
    i = c & 7
    vn = _nx(v, m)
    skl = _sk(E, v, 0)
    skr = _sk(E, v, 1)
    if i == 1:  # quad opposite across the ring edge, or the wart a T0^w apex faces
        if skl:
            return 8 * vn
        return 8 * vn + 4 if skr else 8 * v + 5
    if i == 5:
        if skr:
            return 8 * vn + 6
        return 8 * vn + 2 if skl else 8 * v + 1
    vp = _pv(v, m)
    if i == 0:
        if _sk(E, vp, 0) == 1:  # wart tip: v.0.o = v.p.1
            return 8 * vp + 1
        side, x, y = 0, (_nx(vn, m) if skl else vn), _ap(E, v, 0)
    elif i == 2:
        if skl == 0 and _ap(E, v, 0) == vp:  # canonical T2: v.2 -> v.p.1's quad opposite
            return 8 * v + 4 if _sk(E, vp, 1) else 8 * vp + 5
        side, x, y = 0, _ap(E, v, 0), v
    elif i == 4:
        if skr == 0 and _ap(E, v, 1) == vp:
            return 8 * v + 2 if _sk(E, vp, 0) else 8 * vp + 1
        side, x, y = 1, _ap(E, v, 1), v
    else:  # i == 6 (and the unused offsets 3, 7, as the jnp version's last branch)
        if _sk(E, vp, 1) == 1:
            return 8 * vp + 5
        side, x, y = 1, (_nx(vn, m) if skr else vn), _ap(E, v, 1)
    return _find(m, side, x, y, E)


@numba.njit(cache=True, inline="always")
def _opposite(c, m, E):
    return _canonical(_cheap_opposite(c, m, E), m, E)


# ------------------------------------------------------------------------------ packing
@numba.njit(cache=True)
def _pack_common(V, O, vertex_corner, ring, cL, cR, redl, redr, skl, skr, irl_in, irr_in,
                 t0_in, lrc_in, dmask, quad_check):
    nc = V.shape[0]
    nf = nc // 3
    nv = dmask.shape[0]
    m = ring.shape[0]
    # vertex renumbering: ring order first, then isolated vertices (increasing input id), dummy
    # vertices last (null index, Sec. 4.6)
    new_of_old = np.full(nv, -1, np.int32)
    for i in range(m):
        new_of_old[ring[i]] = i
    k = m
    nv_real = nv
    for u in range(nv):
        nv_real -= dmask[u]
        if new_of_old[u] < 0 and dmask[u] == 0:
            new_of_old[u] = k
            k += 1
    for u in range(nv):
        if new_of_old[u] < 0:
            new_of_old[u] = k
            k += 1
    order = np.empty(nv, np.int32)
    for u in range(nv):
        order[new_of_old[u]] = u
    # T0 triangles: real ones first (dense face ids), dummy ones after them, each group in the
    # tables' order; corner 3t + q of the j-th T0 becomes 8 m_r + 4j + q (Sec. 4.7)
    n0 = t0_in.shape[0]
    has_dummy = nv_real < nv
    nf_real = nf
    if has_dummy:
        t0 = np.empty(n0, np.int32)
        j = 0
        for jj in range(n0):
            t = t0_in[jj]
            if not (dmask[V[3 * t]] or dmask[V[3 * t + 1]] or dmask[V[3 * t + 2]]):
                t0[j] = t
                j += 1
        for jj in range(n0):
            t = t0_in[jj]
            if dmask[V[3 * t]] or dmask[V[3 * t + 1]] or dmask[V[3 * t + 2]]:
                t0[j] = t
                j += 1
        for t in range(nf):
            if dmask[V[3 * t]] or dmask[V[3 * t + 1]] or dmask[V[3 * t + 2]]:
                nf_real -= 1
        lrc = lrc_in.copy()
        base = 8 * m
        for jj in range(n0):
            for q in range(3):
                lrc[3 * t0[jj] + q] = base + 4 * jj + q
    else:  # no dummy triangle: the tables' T0 order and corner ids stand as they are
        t0 = t0_in
        lrc = lrc_in
    V0 = np.zeros(max(3 * n0, 1), np.int32)
    O0 = np.zeros(max(3 * n0, 1), np.int32)
    for jj in range(n0):
        for q in range(3):
            c = 3 * t0[jj] + q
            V0[3 * jj + q] = new_of_old[V[c]]
            O0[3 * jj + q] = lrc[O[c]]
    # C: a corner of each real isolated vertex
    ni = nv_real - m
    C = np.zeros(max(ni, 1), np.int32)
    for q in range(ni):
        C[q] = lrc[vertex_corner[order[m + q]]]
    # ring slots: apex and skip bit (E, see the case analysis above) and the true opposites of
    # the transversal corners v.0.o, v.2.o, v.4.o, v.6.o (what VO* stores for an irregular slot)
    E = np.empty((m, 2), np.int32)
    truth = np.empty((m, 4), np.int32)
    hidden = np.empty(2 * m, np.uint8)  # redundant T2 copies and dummy triangles
    for v in range(m):
        a = cL[v]
        b = cR[v]
        E[v, 0] = new_of_old[V[a]] | (np.int32(skl[v]) << _SKIP_BIT)
        E[v, 1] = new_of_old[V[b]] | (np.int32(skr[v]) << _SKIP_BIT)
        truth[v, 0] = lrc[O[_ctp(a)]]
        truth[v, 1] = lrc[O[_ctn(a)]]
        truth[v, 2] = lrc[O[_ctp(b)]]
        truth[v, 3] = lrc[O[_ctn(b)]]
        hl = redl[v]
        hr = redr[v]
        if has_dummy:
            ta = 3 * (a // 3)
            tb = 3 * (b // 3)
            hl = hl or dmask[V[ta]] or dmask[V[ta + 1]] or dmask[V[ta + 2]]
            hr = hr or dmask[V[tb]] or dmask[V[tb + 1]] or dmask[V[tb + 2]]
        hidden[2 * v] = 1 if hl else 0
        hidden[2 * v + 1] = 1 if hr else 0
    # construction-time check of the ring case analysis (Sec. 4.5, Fig. 6) on every regular
    # corner; a transversal corner it cannot resolve makes its slot irregular (stored in VO*).
    # The quad opposites (offsets 1, 5) never need VO*: a wrong one is a bug (bad1/bad5; only
    # looked for with ``quad_check``: the full check covers them too).
    irl = np.empty(m, np.uint8)
    irr = np.empty(m, np.uint8)
    unexpected = 0
    bad1 = -1
    bad5 = -1
    for v in range(m):
        for side in range(2):  # L(v): corners 8v + 0..2; R(v): 8v + 4..6
            if (redr[v] if side else redl[v]) != 0:
                continue
            ir = irr_in[v] if side else irl_in[v]
            quad = quad_check and (bad5 if side else bad1) < 0
            bad = False
            for q in range(3):  # one _opposite call site: it is inlined
                if q == 1:
                    if not quad:
                        continue
                    want = lrc[O[cR[v] if side else cL[v]]]
                elif ir != 0 or bad:
                    continue  # irregular already: VO* stores its opposites
                else:
                    want = truth[v, 2 * side + q // 2]
                if _opposite(8 * v + 4 * side + q, m, E) != want:
                    if q != 1:
                        bad = True
                    elif side:
                        bad5 = v
                    else:
                        bad1 = v
            if bad:
                unexpected += 1
                ir = 1
            if side:
                irr[v] = ir
            else:
                irl[v] = ir
        if redl[v] != 0:
            irl[v] = irl_in[v]
        if redr[v] != 0:
            irr[v] = irr_in[v]
    return (new_of_old, order, lrc, t0, V0, O0, C, E, truth, irl, irr, hidden,
            nv_real, nf_real, unexpected, bad1, bad5)


def pack_common(V, O, vertex_corner, tb, dmask, quad_check: bool = True):
    """Everything both LR variants share, from the :class:`~jaxcds.construct.ring_expander.LRTables`
    ``tb`` of corner table ``V, O`` (``dmask``: dummy vertices). Returns a dict of arrays and
    counts (see :func:`_pack_common`); ``bad_quad`` is ``(offset, ring vertex)`` of a wrong quad
    opposite (a construction bug; looked for with ``quad_check``) or None."""
    out = _pack_common(_i32(V), _i32(O), _i32(vertex_corner), _i32(tb.order),
                       _i32(tb.left_corner), _i32(tb.right_corner),
                       _u8(tb.red_left), _u8(tb.red_right), _u8(tb.skip_left), _u8(tb.skip_right),
                       _u8(tb.irr_left), _u8(tb.irr_right), _i32(tb.t0), _i32(tb.lr_corner),
                       _u8(dmask), bool(quad_check))
    keys = ("new_of_old", "order", "lrc", "t0", "V0", "O0", "C", "E", "truth", "irl", "irr",
            "hidden", "nv_real", "nf_real", "unexpected")
    d = dict(zip(keys, out[:15]))
    d["nv_real"], d["nf_real"], d["unexpected"] = int(d["nv_real"]), int(d["nf_real"]), int(d["unexpected"])
    bad1, bad5 = int(out[15]), int(out[16])
    d["bad_quad"] = (1, bad1) if bad1 >= 0 else ((5, bad5) if bad5 >= 0 else None)
    return d


def _i32(a):
    return np.ascontiguousarray(np.asarray(a), dtype=np.int32)


def _u8(a):
    a = np.asarray(a)
    return np.ascontiguousarray(a.view(np.uint8) if a.dtype == np.bool_ else a.astype(np.uint8))


@numba.njit(cache=True)
def pack_lr(E, irl, irr, truth):
    """Standard LR entries (Sec. 4.5, 6.2): ``L[v] = v.l`` (bits 0-28), bit 29 wart skip, bit 30
    irregular with bits 0-28 then a ``VO*`` triplet index; ``VO*`` triplets ``(v.l, v.0.o, v.2.o)``
    for the irregular left slots in ring order, then ``(v.r, v.4.o, v.6.o)`` for the right ones."""
    m = E.shape[0]
    nl = 0
    nr = 0
    for v in range(m):
        nl += irl[v]
        nr += irr[v]
    vos = np.empty(3 * (nl + nr), np.int32)
    L = np.empty(m, np.int32)
    R = np.empty(m, np.int32)
    a = 0
    b = nl
    skip = np.int32(1) << _SKIP_BIT
    irrb = np.int32(1) << _IRR_BIT
    for v in range(m):
        x = E[v, 0]
        if irl[v]:
            vos[3 * a] = x & _VALUE_MASK
            vos[3 * a + 1] = truth[v, 0]
            vos[3 * a + 2] = truth[v, 1]
            x = (x & skip) | irrb | a
            a += 1
        y = E[v, 1]
        if irr[v]:
            vos[3 * b] = y & _VALUE_MASK
            vos[3 * b + 1] = truth[v, 2]
            vos[3 * b + 2] = truth[v, 3]
            y = (y & skip) | irrb | b
            b += 1
        L[v] = x
        R[v] = y
    return L, R, vos


@numba.njit(cache=True)
def pack_lr_bits(E, irl, irr, truth):
    """``lr-bits`` entries (Sec. 6.1-6.2): per ring vertex two 16-bit words ``L`` at ``2v``,
    ``R`` at ``2v + 1``: bit 0 the flag, bits 1-15 a signed offset ``v.l - v`` (mod ``m_r``, 15
    bits). An entry whose apex is far (or a dummy vertex), or an irregular slot, is *long*: flags
    (1, 1) and the 30 offset bits hold ``a << 4 | skl | skr << 1 | irl << 2 | irr << 3``, ``a``
    the index of its ``VO*`` record ``[v.l, v.r, (v.0.o, v.2.o), (v.4.o, v.6.o)]``.
    Returns ``(LR16 int16 (2 m_r,), VO* int32 (padded to 2 entries), its length, number of long
    entries)``; ``-1`` long entries when ``VO*`` exceeds the 26-bit index."""
    m = E.shape[0]
    half = m // 2
    lim = 1 << 14
    lr16 = np.empty(2 * m, np.uint16)
    total = 0
    nlong = 0
    for v in range(m):
        lv = _ap(E, v, 0)
        rv = _ap(E, v, 1)
        d = (lv - v) % m
        if d > half:
            d -= m
        e = (rv - v) % m
        if e > half:
            e -= m
        fit_l = lv < m and d >= -lim and d < lim
        fit_r = rv < m and e >= -lim and e < lim
        # both skip bits of a short entry would read as the long flags (1, 1): long as well
        if irl[v] or irr[v] or not fit_l or not fit_r or (_sk(E, v, 0) & _sk(E, v, 1)) == 1:
            nlong += 1
            total += 2 + 2 * irl[v] + 2 * irr[v]
            lr16[2 * v] = 1  # long: filled below
            lr16[2 * v + 1] = 1
        else:
            lr16[2 * v] = ((d & 0x7FFF) << 1) | _sk(E, v, 0)
            lr16[2 * v + 1] = ((e & 0x7FFF) << 1) | _sk(E, v, 1)
    if total >= 1 << 26:
        return lr16.view(np.int16), np.zeros(2, np.int32), 0, -1
    vos = np.zeros(max(total, 2), np.int32)
    start = 0
    for v in range(m):
        if (lr16[2 * v] & lr16[2 * v + 1] & 1) == 0:
            continue
        skl = _sk(E, v, 0)
        skr = _sk(E, v, 1)
        vos[start] = _ap(E, v, 0)
        vos[start + 1] = _ap(E, v, 1)
        off = start + 2
        if irl[v]:
            vos[off] = truth[v, 0]
            vos[off + 1] = truth[v, 1]
            off += 2
        if irr[v]:
            vos[off] = truth[v, 2]
            vos[off + 1] = truth[v, 3]
        payload = ((np.int64(start) << 4) | skl | (skr << 1)
                   | (np.int64(irl[v]) << 2) | (np.int64(irr[v]) << 3))
        lr16[2 * v] = (((payload >> 15) & 0x7FFF) << 1) | 1
        lr16[2 * v + 1] = ((payload & 0x7FFF) << 1) | 1
        start += 2 + 2 * irl[v] + 2 * irr[v]
    return lr16.view(np.int16), vos, total, nlong


@numba.njit(cache=True)
def directory(hidden):
    """Popcount rank directory over the ``2 m_r`` ring slots (bit set = a face of its own):
    ``(words int32, rank int32 (set bits in the words before), number of set bits)``."""
    nbits = hidden.shape[0]
    nw = (nbits + 31) // 32
    words = np.zeros(nw, np.uint32)
    rank = np.empty(nw, np.int32)
    total = 0
    for w in range(nw):
        rank[w] = total
        x = np.uint32(0)
        for b in range(32):
            i = 32 * w + b
            if i < nbits and hidden[i] == 0:
                x |= np.uint32(1) << np.uint32(b)
                total += 1
        words[w] = x
    return words.view(np.int32), rank, total


# ------------------------------------------------------------------------------ decoding + check
# Decoded slot of ring vertex v, as the jitted ``_dec`` computes it: E[v] (apexes and skip bits,
# for the case analysis) and X[v] = (irl, irr, lo, ro) (irregular flags and VO* positions).
@numba.njit(cache=True)
def _clamp_vertex(x):
    # decoded apexes are vertex ids (< 2^29); a corrupted one is clamped to an id that is never
    # a ring vertex, so it still fails the comparison (the check is for corrupted tables)
    return x if (x >= 0 and x < _VALUE_MASK) else _VALUE_MASK


@numba.njit(cache=True)
def decode_lr(L, R, VOs):
    """Decoded slots ``(E, X)`` of an ``LR`` (``LR._dec``, same index clipping)."""
    m = L.shape[0]
    top = VOs.shape[0] - 1
    E = np.empty((m, 2), np.int32)
    X = np.empty((m, 4), np.int32)
    for v in range(m):
        a = np.int64(L[v])
        b = np.int64(R[v])
        irl = (a >> _IRR_BIT) & 1
        irr = (b >> _IRR_BIT) & 1
        ia = a & _VALUE_MASK
        ib = b & _VALUE_MASK
        lv = np.int64(VOs[min(max(3 * ia, 0), top)]) if irl == 1 else ia
        rv = np.int64(VOs[min(max(3 * ib, 0), top)]) if irr == 1 else ib
        E[v, 0] = _clamp_vertex(lv) | (((a >> _SKIP_BIT) & 1) << _SKIP_BIT)
        E[v, 1] = _clamp_vertex(rv) | (((b >> _SKIP_BIT) & 1) << _SKIP_BIT)
        X[v, 0] = irl
        X[v, 1] = irr
        X[v, 2] = 3 * ia + 1
        X[v, 3] = 3 * ib + 1
    return E, X


@numba.njit(cache=True)
def decode_lr_bits(LR16, VOs, m):
    """Same for an ``LRBits`` (``LRBits._dec``): 16-bit offsets, long entries through ``VO*``."""
    E = np.empty((m, 2), np.int32)
    X = np.empty((m, 4), np.int32)
    top = VOs.shape[0] - 2
    for v in range(m):
        el = np.int64(LR16[2 * v])  # sign-extended, as astype(int32) in the jnp version
        er = np.int64(LR16[2 * v + 1])
        fl = el & 1
        fr = er & 1
        if fl & fr:
            payload = (((el >> 1) & 0x7FFF) << 15) | ((er >> 1) & 0x7FFF)
            a = min(max(payload >> 4, 0), top)
            irl = (payload >> 2) & 1
            lv = np.int64(VOs[a])
            rv = np.int64(VOs[a + 1])
            skl = payload & 1
            skr = (payload >> 1) & 1
            X[v, 0] = irl
            X[v, 1] = (payload >> 3) & 1
            X[v, 2] = a + 2
            X[v, 3] = a + 2 + 2 * irl
        else:
            lv = (v + (el >> 1)) % m
            rv = (v + (er >> 1)) % m
            skl = fl & (1 - fr)
            skr = fr & (1 - fl)
            X[v, 0] = 0
            X[v, 1] = 0
            X[v, 2] = 2
            X[v, 3] = 2
        E[v, 0] = _clamp_vertex(lv) | (skl << _SKIP_BIT)
        E[v, 1] = _clamp_vertex(rv) | (skr << _SKIP_BIT)
    return E, X


@numba.njit(cache=True)
def _corner_vo(c, m, n0, E, X, VOs, V0, O0):
    """``(c.v, c.o)`` of LR corner ``c`` from the decoded slots (Sec. 4.7), as the jitted ``v`` /
    ``o`` compute them (same index clipping)."""
    if c >= 8 * m:
        i = c - (c >> 2) - 6 * m
        i = min(max(i, 0), max(3 * n0 - 1, 0))
        return np.int64(V0[i]), np.int64(O0[i])
    v = c >> 3
    i = c & 7
    cv = _ring_vertex(c, m, E)
    top = VOs.shape[0] - 1
    if X[v, 0] == 1 and (i == 0 or i == 2):
        k = X[v, 2] + (1 if i == 2 else 0)
        return cv, np.int64(VOs[min(max(k, 0), top)])
    if X[v, 1] == 1 and (i == 4 or i == 6):
        k = X[v, 3] + (1 if i == 6 else 0)
        return cv, np.int64(VOs[min(max(k, 0), top)])
    return cv, _opposite(c, m, E)


@numba.njit(cache=True)
def corner_vo(cs, m, n0, E, X, VOs, V0, O0):
    """``(c.v, c.o)`` of every corner in ``cs`` (tests compare them with the jitted operators)."""
    gv = np.empty(cs.shape[0], np.int64)
    go = np.empty(cs.shape[0], np.int64)
    for q in range(cs.shape[0]):
        gv[q], go[q] = _corner_vo(np.int64(cs[q]), m, n0, E, X, VOs, V0, O0)
    return gv, go


@numba.njit(cache=True)
def _check(V, O, lrc, new_of_old, m, n0, E, X, VOs, V0, O0):
    """Every corner-table corner ``ct`` with an LR corner ``c = lrc[ct]``: ``c.v`` must be the LR
    id of ``ct.v`` and ``c.o`` the LR corner of ``ct.o``. Returns ``(number wrong, first wrong
    ct, its c.v, its c.o)``."""
    nbad = 0
    first = -1
    fv = np.int64(0)
    fo = np.int64(0)
    for ct in range(V.shape[0]):
        c = np.int64(lrc[ct])
        if c < 0:
            continue
        gv, go = _corner_vo(c, m, n0, E, X, VOs, V0, O0)
        if gv != new_of_old[V[ct]] or go != lrc[O[ct]]:
            if first < 0:
                first = ct
                fv = gv
                fo = go
            nbad += 1
    return nbad, first, fv, fo


def check_lr(L, R, VOs, V0, O0, n0, V, O, lrc, new_of_old):
    """Construction check of an ``LR`` (see :func:`_check`)."""
    VOs = _i32(VOs)
    E, X = decode_lr(_i32(L), _i32(R), VOs)
    return _check(_i32(V), _i32(O), _i32(lrc), _i32(new_of_old), np.int64(E.shape[0]),
                  np.int64(n0), E, X, VOs, _i32(V0), _i32(O0))


def check_lr_bits(LR16, VOs, V0, O0, m, n0, V, O, lrc, new_of_old):
    """Construction check of an ``LRBits`` (see :func:`_check`)."""
    VOs = _i32(VOs)
    E, X = decode_lr_bits(np.ascontiguousarray(LR16, dtype=np.int16), VOs, np.int64(m))
    return _check(_i32(V), _i32(O), _i32(lrc), _i32(new_of_old), np.int64(m), np.int64(n0),
                  E, X, VOs, _i32(V0), _i32(O0))
