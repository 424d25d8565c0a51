"""Maximal Schnyder woods by vertex conquest (Castelli Aleardi & Devillers, JoCG 2018, Appendix A).

Conventions (the paper's Definition 1 and Sec. 2.1, used by every CDS structure and by the codec):

* Colours are ints: ``RED = 0``, ``BLUE = 1``, ``BLACK = 2``; ``next(c) = (c + 1) % 3``
  (next(red) = blue, next(blue) = black, next(black) = red), ``prev(c) = (c + 2) % 3``.
* Orientation: the mesh is a closed genus-0 triangle mesh whose faces are counter-clockwise seen
  from outside. The root face ``root_face = (a, b, c)`` of the mesh (ccw) becomes the outer face of
  the planar drawing, where it reads clockwise; hence ``V_red = a``, ``V_black = b``,
  ``V_blue = c`` so that the outer vertices are ``V_red, V_blue, V_black`` in ccw order of the
  drawing, and "ccw around a vertex" in the drawing is the mesh's ccw (``twin(prev(e))``).
* Every inner vertex ``u`` has one outgoing edge of each colour (``out[u, c]`` is its target) and
  the local Schnyder rule holds: turning ccw around ``u`` one meets
  ``out red, in black*, out blue, in red*, out black, in blue*``.
* Outer edges follow Sec. 2.1 (trees T̄_red and T_blue): ``(V_blue, V_red)`` and
  ``(V_black, V_red)`` are red, ``(V_black, V_blue)`` is blue. So ``V_red`` has no outgoing edge,
  ``V_blue`` only a red one, ``V_black`` a red and a blue one, and the edges incident to the outer
  vertices are all incoming (red at V_red, blue at V_blue, black at V_black), as Definition 1 asks.
  There are ``3n - 6`` edges: ``3n`` slots ``(u, c)`` minus the 6 absent ones.
* "Absent" is ``n`` (one past the end).

The construction conquers vertices from ``V_black`` inwards keeping a simple boundary path
``B = V_blue ... V_red``; the conquered vertex ``v`` gets a blue edge to its neighbour ``v_r``
on ``B`` toward V_blue, a red edge to its neighbour ``v_l`` toward V_red, and the new boundary
vertices get their black edge to ``v``. Always conquering the free vertex closest to V_blue
gives the *maximal* wood (no clockwise oriented cycle, Lemma 3). The free vertices are kept in a
stack in B order with lazy deletion (only ``v_r``, ``v_l`` and new boundary vertices can become
free), so the whole construction is linear: O(sum of degrees).
"""

from __future__ import annotations

import dataclasses
from typing import Optional

import numba
import numpy as np

from jaxcds import errors

__all__ = [
    "RED", "BLUE", "BLACK", "COLOUR_NAMES",
    "SchnyderWood", "schnyder_wood", "check_schnyder_wood", "check_wood_arrays", "schnyder_wood_reference",
    "mesh_darts", "prepare_mesh", "WoodOut", "schnyder_out", "label_wood",
]

RED, BLUE, BLACK = 0, 1, 2
COLOUR_NAMES = ("red", "blue", "black")


@dataclasses.dataclass(frozen=True)
class _WoodFields:
    """What :class:`SchnyderWood` and :class:`WoodOut` share: the outer vertices, the outgoing
    edges, the ccw rotations (CSR) and the conquest order (see their docstrings)."""

    num_vertices: int
    v_red: int
    v_blue: int
    v_black: int
    out: np.ndarray
    offsets: np.ndarray
    neighbors: np.ndarray
    conquest_order: np.ndarray
    root_face: int = -1
    maximal: bool = True

    @property
    def outer(self) -> tuple[int, int, int]:
        """``(V_red, V_blue, V_black)``."""
        return (self.v_red, self.v_blue, self.v_black)


@dataclasses.dataclass(frozen=True)
class SchnyderWood(_WoodFields):
    """A Schnyder wood of a planar triangulation (numpy, host side).

    Attributes:
      num_vertices: ``n``.
      v_red, v_blue, v_black: the three outer vertices (the root face is ``(v_red, v_black,
        v_blue)`` ccw in the mesh, i.e. ``V_red, V_blue, V_black`` ccw in the planar drawing).
      out: ``(n, 3)`` int32; ``out[u, c]`` = target of the outgoing edge of colour ``c`` of
        ``u`` (``u_c^↗`` in the paper), ``n`` where absent (the 6 outer slots).
      offsets: ``(n + 1,)`` int64 CSR offsets into the rotation arrays below.
      neighbors: ``(6n - 12,)`` int32; ``neighbors[offsets[u]:offsets[u+1]]`` are the neighbours
        of ``u`` in ccw order, starting at ``out[u, RED]`` (at ``V_red``: starting at ``V_blue``).
      colour: ``(6n - 12,)`` int8 colour of the edge to that neighbour.
      outgoing: ``(6n - 12,)`` bool, True if the edge is oriented from ``u`` to that neighbour.
      conquest_order: ``(n - 2,)`` int32, the vertices in conquest order (V_black first); its
        reverse is a canonical ordering.
      root_face: index of the root face in the input face array (``-1`` if not built from faces).
      maximal: whether it was built with the "closest to V_blue" rule (no cw cycle).
    """

    # keyword-only: they follow the defaulted fields of _WoodFields
    colour: np.ndarray = dataclasses.field(kw_only=True)
    outgoing: np.ndarray = dataclasses.field(kw_only=True)

    @property
    def num_edges(self) -> int:
        return int(np.sum(self.out < self.num_vertices))

    def degrees(self) -> np.ndarray:
        return np.diff(self.offsets).astype(np.int32)

    def in_degree(self, c: int) -> np.ndarray:
        """``(n,)`` number of incoming edges of colour ``c`` at every vertex."""
        u = np.repeat(np.arange(self.num_vertices), np.diff(self.offsets))
        m = (~self.outgoing) & (self.colour == c)
        return np.bincount(u[m], minlength=self.num_vertices).astype(np.int32)

    def edges(self) -> np.ndarray:
        """``(3n - 6, 3)`` int32 rows ``(source, target, colour)``."""
        u, c = np.nonzero(self.out < self.num_vertices)
        return np.stack([u, self.out[u, c], c], axis=1).astype(np.int32)


# ---------------------------------------------------------------------------------- darts
@numba.njit(cache=True)
def _twins(faces, num_vertices):
    """Twin of every dart ``3f + k`` (``faces[f,k] -> faces[f,(k+1)%3]``), ``-1`` on borders,
    via a CSR of darts by origin (linear time, no sort)."""
    nf = faces.shape[0]
    n3 = 3 * nf
    cnt = np.zeros(num_vertices + 1, dtype=np.int64)
    for d in range(n3):
        cnt[faces[d // 3, d % 3] + 1] += 1
    for i in range(num_vertices):
        cnt[i + 1] += cnt[i]
    pos = cnt[:-1].copy()
    by_origin = np.empty(n3, dtype=np.int64)
    for d in range(n3):
        a = faces[d // 3, d % 3]
        by_origin[pos[a]] = d
        pos[a] += 1
    twin = np.full(n3, -1, dtype=np.int64)
    for d in range(n3):
        f = d // 3
        k = d % 3
        a = faces[f, k]
        b = faces[f, (k + 1) % 3]
        for j in range(cnt[b], cnt[b + 1]):
            d2 = by_origin[j]
            f2 = d2 // 3
            if faces[f2, (d2 % 3 + 1) % 3] == a:
                twin[d] = d2
                break
    first = np.full(num_vertices, -1, dtype=np.int64)
    for v in range(num_vertices):
        if cnt[v + 1] > cnt[v]:
            first[v] = by_origin[cnt[v]]
    return twin, first


def mesh_darts(faces: np.ndarray, num_vertices: int):
    """``(twin, vertex_dart)`` of the mesh darts ``3f + k`` (linear time, numba)."""
    f = np.ascontiguousarray(faces, dtype=np.int32)
    return _twins(f, int(num_vertices))


# ---------------------------------------------------------------------------------- conquest
@numba.njit(cache=True, inline="always")
def _tgt(faces, d):
    return faces[d // 3, (d % 3 + 1) % 3]


@numba.njit(cache=True, inline="always")
def _ccw(twin, d):
    # ccw around origin(d): twin(prev(d))
    return twin[3 * (d // 3) + (d % 3 + 2) % 3]


@numba.njit(cache=True, inline="always")
def _cw(twin, d):
    # cw around origin(d): next(twin(d))
    t = twin[d]
    return 3 * (t // 3) + (t % 3 + 1) % 3


@numba.njit(cache=True)
def _conquest(faces, twin, first, n, v_red, v_blue, v_black, maximal):
    out = np.full((n, 3), n, dtype=np.int32)
    removed = np.zeros(n, dtype=np.bool_)
    on_b = np.zeros(n, dtype=np.bool_)
    chords = np.zeros(n, dtype=np.int64)
    bnext = np.full(n, -1, dtype=np.int64)
    bprev = np.full(n, -1, dtype=np.int64)
    in_stack = np.zeros(n, dtype=np.bool_)
    cap = 3 * faces.shape[0] + n + 8
    stack = np.empty(cap, dtype=np.int64)
    order = np.empty(max(n - 2, 0), dtype=np.int32)
    new = np.empty(n, dtype=np.int64)
    # B = V_blue, V_black, V_red
    on_b[v_blue] = True
    on_b[v_black] = True
    on_b[v_red] = True
    bnext[v_blue] = v_black
    bprev[v_black] = v_blue
    bnext[v_black] = v_red
    bprev[v_red] = v_black
    top = 0
    stack[top] = v_black
    top += 1
    in_stack[v_black] = True
    done = 0
    while done < n - 2:
        if top == 0:
            return out, order, done  # stuck: not a planar triangulation
        # pop the free vertex closest to V_blue (maximal) -- or the latest pushed otherwise
        v = stack[top - 1]
        top -= 1
        in_stack[v] = False
        if removed[v] or (not on_b[v]) or chords[v] != 0 or v == v_red or v == v_blue:
            continue
        vr = bprev[v]
        vl = bnext[v]
        # dart v -> vr
        d = first[v]
        guard = 0
        while _tgt(faces, d) != vr:
            d = _ccw(twin, d)
            guard += 1
            if guard > 3 * faces.shape[0]:
                return out, order, -1
        removed[v] = True
        on_b[v] = False
        order[done] = v
        done += 1
        out[v, BLUE] = vr
        out[v, RED] = vl
        # cw from (v, vr) to (v, vl): the fan of v in the unconquered region
        k = 0
        d = _cw(twin, d)
        w = _tgt(faces, d)
        while w != vl:
            new[k] = w
            k += 1
            out[w, BLACK] = v
            d = _cw(twin, d)
            w = _tgt(faces, d)
        # splice the new vertices between vr and vl
        prev = vr
        for i in range(k):
            u = new[i]
            bprev[u] = prev
            bnext[prev] = u
            prev = u
        bnext[prev] = vl
        bprev[vl] = prev
        if k == 0:
            # the chord {vr, vl} becomes a boundary edge
            if not (vr == v_blue and vl == v_red):
                chords[vr] -= 1
                chords[vl] -= 1
        else:
            for i in range(k):
                u = new[i]
                left = bprev[u]
                right = bnext[u]
                e = first[u]
                e0 = e
                while True:
                    x = _tgt(faces, e)
                    if on_b[x] and x != left and x != right:
                        chords[u] += 1
                        chords[x] += 1
                    e = _ccw(twin, e)
                    if e == e0:
                        break
                on_b[u] = True
        # push candidates so that the top of the stack is the leftmost (closest to V_blue)
        if maximal:
            if vl != v_red and not in_stack[vl] and chords[vl] == 0:
                stack[top] = vl
                top += 1
                in_stack[vl] = True
            for i in range(k - 1, -1, -1):
                u = new[i]
                if chords[u] == 0:
                    stack[top] = u
                    top += 1
                    in_stack[u] = True
            if vr != v_blue and not in_stack[vr] and chords[vr] == 0:
                stack[top] = vr
                top += 1
                in_stack[vr] = True
        else:
            # any free vertex: last-in first-out from the right side (a different valid wood)
            if vr != v_blue and not in_stack[vr] and chords[vr] == 0:
                stack[top] = vr
                top += 1
                in_stack[vr] = True
            for i in range(k):
                u = new[i]
                if chords[u] == 0:
                    stack[top] = u
                    top += 1
                    in_stack[u] = True
            if vl != v_red and not in_stack[vl] and chords[vl] == 0:
                stack[top] = vl
                top += 1
                in_stack[vl] = True
        if top + k + 2 >= cap:
            return out, order, -1
    out[v_blue, RED] = v_red
    return out, order, done


@numba.njit(cache=True)
def _rotations(faces, twin, first, out, n, v_red, v_blue):
    nf = faces.shape[0]
    offsets = np.zeros(n + 1, dtype=np.int64)
    for d in range(3 * nf):
        offsets[faces[d // 3, d % 3] + 1] += 1
    for i in range(n):
        offsets[i + 1] += offsets[i]
    m = offsets[n]
    nb = np.empty(m, dtype=np.int32)
    col = np.empty(m, dtype=np.int8)
    og = np.empty(m, dtype=np.bool_)
    bad = -1
    for u in range(n):
        start_t = out[u, RED] if u != v_red else v_blue
        d = first[u]
        g = 0
        while _tgt(faces, d) != start_t:
            d = _ccw(twin, d)
            g += 1
            if g > offsets[u + 1] - offsets[u]:
                return offsets, nb, col, og, u
        j = offsets[u]
        d0 = d
        while True:
            x = _tgt(faces, d)
            nb[j] = x
            c = -1
            o = False
            for cc in range(3):
                if out[u, cc] == x:
                    c = cc
                    o = True
                elif out[x, cc] == u:
                    c = cc
            if c < 0 and bad < 0:
                bad = u
            col[j] = c
            og[j] = o
            j += 1
            d = _ccw(twin, d)
            if d == d0:
                break
    return offsets, nb, col, og, bad


# Memory note. On the shared box a fresh page costs more than the work done on it (a 4 KiB page
# fault is ~2-3 us, i.e. ~0.7 ms per MB first touched), so the kernels below allocate nothing
# large themselves: their outputs and one int32 scratch of 6n + 16 words are numpy arrays made
# by the caller (numpy asks for transparent huge pages on big arrays, numba's allocator does
# not), and the scratch is reused by every phase of the encoder (rotations, conquest, words).
_SCAN_MAX = 32  # _rotation_csr: degrees up to this scan, higher ones sort (see there)


@numba.njit(cache=True, nogil=True)
def _rotation_csr(faces, n, offsets, nb, first):
    """Neighbours of every vertex in ccw order (CSR), straight from the corners: the corner of
    face ``(a, b, c)`` at ``a`` says that ``c`` follows ``b`` ccw around ``a``. No twin table,
    per-vertex contiguous work: a scan of the vertex's corners per step up to degree
    ``_SCAN_MAX`` (tiny constants), a binary search in its corners sorted by ``b`` above it (the
    scan made this O(sum deg^2): 4 s for the two poles of a 64K-vertex bipyramid, and 16x per 4x).

    Fills ``offsets`` (``(n + 1,)`` int64, zeroed) and ``nb`` (``(3F,)`` int32); ``first``
    (``>= 3F`` int32) is scratch. The corner pairs ``(b, c)`` are scattered as ``first = b`` and
    ``nb = c`` at the vertex's slots, then each vertex's cycle is chained through a small local
    copy and written back over ``nb``. Returns ``bad``: the first vertex whose corners do not
    form one cycle, -2 for an index outside ``[0, n)``, else -1."""
    nf = faces.shape[0]
    for f in range(nf):
        for k in range(3):
            x = faces[f, k]
            if x < 0 or x >= n:  # index check folded into the counting pass (no f.min/f.max)
                return -2
            offsets[x + 1] += 1
    maxdeg = 0
    for i in range(n):
        d = offsets[i + 1]
        if d > maxdeg:
            maxdeg = d
        offsets[i + 1] += offsets[i]
    # scatter with offsets[v] as the moving cursor of v (no separate position array); afterwards
    # offsets[v] is v's end = (v + 1)'s start, shifted back below
    for f in range(nf):
        a = faces[f, 0]
        b = faces[f, 1]
        c = faces[f, 2]
        j = offsets[a]
        first[j] = b
        nb[j] = c
        offsets[a] = j + 1
        j = offsets[b]
        first[j] = c
        nb[j] = a
        offsets[b] = j + 1
        j = offsets[c]
        first[j] = a
        nb[j] = b
        offsets[c] = j + 1
    for i in range(n, 0, -1):
        offsets[i] = offsets[i - 1]
    offsets[0] = 0
    lf = np.empty(max(maxdeg, 1), dtype=np.int32)
    ls = np.empty(max(maxdeg, 1), dtype=np.int32)
    for v in range(n):
        a = offsets[v]
        deg = offsets[v + 1] - a
        if deg == 0:
            return v
        for j in range(deg):
            lf[j] = first[a + j]
            ls[j] = nb[a + j]
        start = lf[0]
        cur = start
        nb[a] = cur
        if deg <= _SCAN_MAX:
            for k in range(1, deg):
                nxt = -1
                for j in range(deg):
                    if lf[j] == cur:
                        nxt = ls[j]
                        break
                if nxt < 0:
                    return v
                cur = nxt
                nb[a + k] = cur
            # the cycle must close on the start
            closes = False
            for j in range(deg):
                if lf[j] == cur and ls[j] == start:
                    closes = True
                    break
            if not closes:
                return v
            continue
        # a stable sort keeps, among equal b (a defect), the first corner the scan would find
        order = np.argsort(lf[:deg], kind="mergesort")
        keys = lf[:deg][order]
        for k in range(1, deg):
            j = np.searchsorted(keys, cur)
            if j == deg or keys[j] != cur:
                return v
            cur = ls[order[j]]
            nb[a + k] = cur
        closes = False
        j = np.searchsorted(keys, cur)
        while j < deg and keys[j] == cur:
            if ls[order[j]] == start:
                closes = True
                break
            j += 1
        if not closes:
            return v
    return -1


_ONB, _REM, _INS, _CH = 1, 2, 4, 8  # conquest state word: on B, removed, in stack; chords * 8


@numba.njit(cache=True, nogil=True)
def _conquest_csr(offsets, nb, n, v_red, v_blue, v_black, maximal, out, order, work, blk, want_blk):
    """The vertex conquest of Appendix A on the ccw rotations (see :func:`_conquest`).

    Writes ``out`` (``(n, 3)`` int32, filled with ``n``) and ``order`` (``(n - 2,)``); ``work``
    (int32, ``>= 6n + 8``) holds the per-vertex state -- one word per vertex packing the three
    flags and the chord count, so a neighbour test reads one word -- the boundary path
    (prev/next side by side) and the candidate stack (at most ``3n - 6`` pushes: the start, the
    ``n - 3`` fan vertices and two per conquest). Returns the number of conquered vertices
    (``-1``: inconsistent rotations).

    With ``want_blk`` it also fills ``blk`` (``(n, 3)`` int32) with what the 4n-bit encoder
    needs of each vertex ``v``, while ``v``'s rotation is in cache: the slot (relative to
    ``offsets[v]``) of its first red child, the number of red children (the neighbours ccw
    strictly between its outgoing blue and black edges, Definition 1) and its black in-degree
    (the fan it conquers)."""
    st = work[:n]
    bl = work[n:3 * n].reshape((n, 2))  # bl[u, 0] = prev (toward V_blue), bl[u, 1] = next
    stack = work[3 * n:]
    cap = stack.shape[0]
    for u in range(n):
        st[u] = 0
    new = np.empty(n, dtype=np.int32)  # the current fan (only its first pages are touched)
    st[v_blue] = _ONB
    st[v_black] = _ONB
    st[v_red] = _ONB
    bl[v_blue, 1] = v_black
    bl[v_black, 0] = v_blue
    bl[v_black, 1] = v_red
    bl[v_red, 0] = v_black
    top = 0
    stack[top] = v_black
    top += 1
    st[v_black] |= _INS
    done = 0
    while done < n - 2:
        if top == 0:
            return done
        v = stack[top - 1]
        top -= 1
        s = st[v] & ~_INS
        st[v] = s
        # free: on B, not removed, no chord (the state word is exactly _ONB), not V_red / V_blue
        if s != _ONB or v == v_red or v == v_blue:
            continue
        vr = bl[v, 0]
        vl = bl[v, 1]
        a = offsets[v]
        b = offsets[v + 1]
        p = a
        while p < b and nb[p] != vr:
            p += 1
        if p == b:
            return -1
        st[v] = _REM
        order[done] = v
        done += 1
        out[v, BLUE] = vr
        out[v, RED] = vl
        # cw from vr to vl around v (backwards in the ccw list): the fan still to conquer
        k = 0
        j = p - 1 if p > a else b - 1
        w = nb[j]
        steps = 0
        deg = b - a
        while w != vl:
            new[k] = w
            k += 1
            out[w, BLACK] = v
            j = j - 1 if j > a else b - 1
            w = nb[j]
            steps += 1
            if steps > deg:
                return -1
        if want_blk:
            blk[v, 2] = k  # the fan gets its black edges to v: v's black in-degree
            q = p + 1 if p + 1 < b else a
            blk[v, 0] = q - a
            c = 0
            if v != v_black:  # V_black has no red child (its rotation: V_red, in black*, V_blue)
                ob = out[v, BLACK]  # set when v joined the boundary as a fan vertex
                while nb[q] != ob:
                    c += 1
                    q = q + 1 if q + 1 < b else a
                    if c > deg:
                        return -1
            blk[v, 1] = c
        prev = vr
        for i in range(k):
            u = new[i]
            bl[u, 0] = prev
            bl[prev, 1] = u
            prev = u
        bl[prev, 1] = vl
        bl[vl, 0] = prev
        if k == 0:
            # the chord {vr, vl} becomes a boundary edge
            if not (vr == v_blue and vl == v_red):
                st[vr] -= _CH
                st[vl] -= _CH
        else:
            for i in range(k):
                u = new[i]
                left = bl[u, 0]
                right = bl[u, 1]
                # chords of u: neighbours on B other than its two path neighbours. Branch-free
                # (the test is a coin flip for the predictor; this loop is ~1/8 of the conquest)
                c = 0
                for jj in range(offsets[u], offsets[u + 1]):
                    x = nb[jj]
                    sx = st[x]
                    hit = (sx & _ONB) & np.int32(x != left) & np.int32(x != right)
                    c += hit
                    st[x] = sx + hit * _CH
                st[u] += c * _CH + _ONB
        if top + k + 2 > cap:  # cannot happen on a triangulation (3n - 6 pushes in all)
            return -1
        # push candidates so that the top of the stack is the leftmost (closest to V_blue)
        if maximal:
            if vl != v_red and (st[vl] & _INS) == 0 and (st[vl] >> 3) == 0:
                stack[top] = vl
                top += 1
                st[vl] |= _INS
            for i in range(k - 1, -1, -1):
                u = new[i]
                if (st[u] >> 3) == 0:
                    stack[top] = u
                    top += 1
                    st[u] |= _INS
            if vr != v_blue and (st[vr] & _INS) == 0 and (st[vr] >> 3) == 0:
                stack[top] = vr
                top += 1
                st[vr] |= _INS
        else:
            # any free vertex: last-in first-out from the right side (a different valid wood)
            if vr != v_blue and (st[vr] & _INS) == 0 and (st[vr] >> 3) == 0:
                stack[top] = vr
                top += 1
                st[vr] |= _INS
            for i in range(k):
                u = new[i]
                if (st[u] >> 3) == 0:
                    stack[top] = u
                    top += 1
                    st[u] |= _INS
            if vl != v_red and (st[vl] & _INS) == 0 and (st[vl] >> 3) == 0:
                stack[top] = vl
                top += 1
                st[vl] |= _INS
    out[v_blue, RED] = v_red
    if want_blk:  # the two vertices never conquered: V_red (all neighbours from V_blue on), V_blue
        a = offsets[v_red]
        b = offsets[v_red + 1]
        q = a
        while q < b and nb[q] != v_blue:
            q += 1
        if q == b:
            return -1
        blk[v_red, 0] = q - a
        blk[v_red, 1] = b - a
        blk[v_red, 2] = 0
        blk[v_blue, 0] = 0
        blk[v_blue, 1] = 0
        blk[v_blue, 2] = 0
    return done


@numba.njit(cache=True, nogil=True)
def _finish_rotations(offsets, nb, out, n, v_red, v_blue):
    """Rotate every ccw list to start at the outgoing red edge (V_red: at V_blue) and label each
    entry with its colour and direction. Returns ``(nb2, colour, outgoing, bad)``."""
    m = offsets[n]
    nb2 = np.empty(m, dtype=np.int32)
    col = np.empty(m, dtype=np.int8)
    og = np.empty(m, dtype=np.bool_)
    bad = -1
    for u in range(n):
        a = offsets[u]
        deg = offsets[u + 1] - a
        start_t = out[u, RED] if u != v_red else v_blue
        p = -1
        for j in range(deg):
            if nb[a + j] == start_t:
                p = j
                break
        if p < 0:
            return nb2, col, og, u
        o0 = out[u, 0]
        o1 = out[u, 1]
        o2 = out[u, 2]
        q = a + p  # source slot, wrapping at the end of u's list (no integer division per entry)
        for j in range(deg):
            x = nb[q]
            q += 1
            if q == a + deg:
                q = a
            nb2[a + j] = x
            if x == o0:
                col[a + j] = 0
                og[a + j] = True
            elif x == o1:
                col[a + j] = 1
                og[a + j] = True
            elif x == o2:
                col[a + j] = 2
                og[a + j] = True
            else:
                og[a + j] = False
                if out[x, 0] == u:
                    col[a + j] = 0
                elif out[x, 1] == u:
                    col[a + j] = 1
                elif out[x, 2] == u:
                    col[a + j] = 2
                else:
                    col[a + j] = -1
                    if bad < 0:
                        bad = u
    return nb2, col, og, bad


def _default_root(faces: np.ndarray) -> int:
    return 0


@dataclasses.dataclass(frozen=True)
class WoodOut(_WoodFields):
    """The outgoing edges of a Schnyder wood and the unlabelled ccw rotations it was built on:
    what the 4n-bit encoder needs (Sec. 3.1), without the colour / orientation labels and the
    rotated neighbour lists of :class:`SchnyderWood` (one linear pass, :func:`label_wood`, away).

    Attributes:
      num_vertices, v_red, v_blue, v_black, out, offsets, conquest_order, root_face, maximal: as
        in :class:`SchnyderWood`.
      neighbors: ``(6n - 12,)`` int32; ``neighbors[offsets[u]:offsets[u+1]]`` are the neighbours
        of ``u`` in ccw order, starting at an arbitrary one (the mesh's first corner at ``u``).
    """


def schnyder_out(faces, num_vertices: int, root_face: Optional[int] = None,
                 maximal: bool = True, work: Optional[np.ndarray] = None,
                 blk: Optional[np.ndarray] = None) -> WoodOut:
    """The Schnyder wood of :func:`schnyder_wood` as its ``out`` table plus the unlabelled ccw
    rotations (:class:`WoodOut`): the vertex conquest of Appendix A without the final labelling
    pass. Same arguments, checks and errors as :func:`schnyder_wood`; ``out`` is identical.
    ``work``: optional int32 scratch of ``6n + 16`` words, for a caller that reuses it after
    (the encoder does); its content on return is garbage. ``blk``: optional ``(n, 3)`` int32
    filled with each vertex's red-children block and black in-degree (see
    :func:`_conquest_csr`; the encoder's input)."""
    from jaxcds.mesh import trusted_faces

    # the mesh's own checks of ids and shape: a cast to int32 read a face (0.5, 1.5, 2.5) as
    # (0, 1, 2) and int(num_vertices) 42.9 as 42
    f = trusted_faces(faces, num_vertices, "schnyder_wood")
    n = int(num_vertices)
    nf = int(f.shape[0])
    if n < 3 or nf != 2 * n - 4:
        chi = n - 3 * nf // 2 + nf
        genus = f"genus {(2 - chi) // 2} if closed and connected, " if chi % 2 == 0 and chi <= 2 else ""
        raise errors.UnsupportedTopologyError(
            f"a Schnyder wood needs a closed genus-0 triangulation with F = 2n - 4 faces; got "
            f"n = {n} vertices and F = {nf} faces ({genus}Euler characteristic {chi}); "
            "use the 'lr' or 'halfedge' structure for other topologies")
    from jaxcds._args import is_integer

    if root_face is not None and not is_integer(root_face):  # int() truncated 1.5 to face 1
        raise errors.InvalidIndexError(f"root_face must be a face index (an integer), got {root_face!r}")
    root = 0 if root_face is None else int(root_face)
    if not 0 <= root < nf:
        raise errors.InvalidIndexError(f"root_face {root} out of range [0, {nf})")
    offsets0 = np.zeros(n + 1, dtype=np.int64)
    nb0 = np.empty(3 * nf, dtype=np.int32)
    if work is None or work.dtype != np.int32 or work.size < 6 * n + 16:
        work = np.empty(6 * n + 16, dtype=np.int32)  # scratch of both kernels (3F < 6n + 16)
    bad = _rotation_csr(f, n, offsets0, nb0, work)
    if bad == -2:
        raise errors.InvalidIndexError(f"face indices must lie in [0, {n})")
    if bad >= 0:
        raise errors.UnsupportedTopologyError(
            f"vertex {bad}: its faces do not form a single closed fan (a boundary or a non-manifold "
            "vertex); close holes with jaxcds.mesh.close_boundaries, or use 'halfedge'")
    v_red, v_black, v_blue = (int(x) for x in f[root])
    out = np.full((n, 3), n, dtype=np.int32)
    order = np.empty(n - 2, dtype=np.int32)
    want_blk = blk is not None
    if not want_blk:
        blk = np.zeros((1, 3), dtype=np.int32)
    elif (not isinstance(blk, np.ndarray) or blk.shape != (n, 3) or blk.dtype != np.int32
          or not blk.flags.c_contiguous or not blk.flags.writeable):  # the kernel writes (n, 3) int32 rows
        got = f"{blk.dtype} {blk.shape}" if isinstance(blk, np.ndarray) else type(blk).__name__
        raise errors.ArgumentError(f"schnyder_out: blk must be a writable C-contiguous ({n}, 3) int32 "
                                   f"array, got {got}")
    done = _conquest_csr(offsets0, nb0, n, v_red, v_blue, v_black, bool(maximal), out, order, work, blk, want_blk)
    if done != n - 2:
        raise errors.UnsupportedTopologyError(
            f"the vertex conquest stopped after {max(done, 0)} of {n - 2} vertices: the mesh is not a "
            "planar (genus-0, simple) triangulation; use the 'lr' or 'halfedge' structure")
    if n == 3:
        out[v_blue, RED] = v_red
    return WoodOut(num_vertices=n, v_red=v_red, v_blue=v_blue, v_black=v_black, out=out, offsets=offsets0,
                   neighbors=nb0, conquest_order=order, root_face=root, maximal=bool(maximal))


def label_wood(w: WoodOut) -> SchnyderWood:
    """The :class:`SchnyderWood` of a :class:`WoodOut`: every rotation turned to start at the
    outgoing red edge and each entry labelled with its colour and direction (one linear pass).
    A ``WoodOut`` it did not make is checked first (:func:`check_wood_arrays`; a neighbour out of
    range crashed the kernel); :func:`schnyder_wood` labels its own unchecked."""
    check_wood_arrays(w, "label_wood")
    return _label_wood(w)


def _label_wood(w: WoodOut) -> SchnyderWood:
    """:func:`label_wood` of a wood this module made (unchecked)."""
    n = w.num_vertices
    nb, col, og, bad = _finish_rotations(w.offsets, w.neighbors, w.out, n, w.v_red, w.v_blue)
    if bad >= 0:
        raise errors.StructureError(f"Schnyder wood: an edge at vertex {bad} got no colour")
    return SchnyderWood(num_vertices=n, v_red=w.v_red, v_blue=w.v_blue, v_black=w.v_black, out=w.out,
                        offsets=w.offsets, neighbors=nb, colour=col, outgoing=og,
                        conquest_order=w.conquest_order, root_face=w.root_face, maximal=w.maximal)


def schnyder_wood(faces, num_vertices: int, root_face: Optional[int] = None,
                  maximal: bool = True) -> SchnyderWood:
    """Schnyder wood of a closed genus-0 triangle mesh, in linear time (Appendix A).

    Args:
      faces: ``(F, 3)`` int ccw faces of a closed, connected, genus-0 manifold triangle mesh
        (``F = 2n - 4``; validate untrusted input with :func:`jaxcds.mesh.validate` first).
      num_vertices: ``n >= 3``.
      root_face: index of the root face (default 0); ``faces[root_face] = (V_red, V_black, V_blue)``.
      maximal: conquer the free vertex closest to V_blue (the maximal wood, no cw cycle);
        ``False`` uses another valid choice (a Schnyder wood that may have cw cycles).

    Raises:
      UnsupportedTopologyError: the faces do not form a planar triangulation (wrong Euler count,
        border edges, or the conquest got stuck), naming what failed.
    """
    return _label_wood(schnyder_out(faces, num_vertices, root_face=root_face, maximal=maximal))


# ---------------------------------------------------------------------------------- checker
# Local Schnyder rule (Definition 1) as a cyclic pattern of (outgoing, colour) groups, ccw,
# starting at the outgoing red edge: out red, in black*, out blue, in red*, out black, in blue*.
_PATTERN = ((True, RED), (False, BLACK), (True, BLUE), (False, RED), (True, BLACK), (False, BLUE))


def _entry_edges(out, u, nb, bad):
    """For the unlabelled rotations of a :class:`WoodOut`: whether each entry ``u -> x`` is the
    outgoing side of an edge of ``out`` (``out[u, c] == x``) or its incoming side (``out[x, c] ==
    u``), and that edge's colour ``c``. An entry that is neither, or both (an edge listed in both
    directions), is refused by name."""
    columns = [np.ascontiguousarray(out[:, c]) for c in (RED, BLUE, BLACK)]
    is_out = [t[u] == nb for t in columns]  # u -> x is out's edge of colour c
    is_in = [t[nb] == u for t in columns]  # x -> u is
    hit_out, hit_in = is_out[0] | is_out[1] | is_out[2], is_in[0] | is_in[1] | is_in[2]
    # at most one colour matches each way (out's three edges of a vertex have three targets,
    # checked before), so the colour is a sum of the masks (np.where chains took 2x longer)
    col_out, col_in = (m[1].view(np.uint8) + (m[2].view(np.uint8) << 1) for m in (is_out, is_in))
    col = np.where(hit_out, col_out, col_in).astype(np.int32)
    w = hit_out == hit_in
    if w.any():
        k = int(np.argmax(w))
        bad(f"rotation entry {k} of vertex {int(u[k])}: the edge to {int(nb[k])} is "
            + ("in out both ways" if hit_out[k] else "no edge of out"))
    return hit_out, col


def check_wood_arrays(wood, what: str = "Schnyder wood") -> None:
    """Raise :class:`~jaxcds.errors.StructureError` naming the first entry of ``wood`` that the
    CDS builders' kernels cannot take (``ArgumentError`` if it is not a :class:`SchnyderWood`
    or a :class:`WoodOut`; of a ``WoodOut``, without colours, the checks up to the rotations
    listing both sides of every edge of ``out``).

    Vectorised and linear (the two sides of every edge are counted, not sorted), so the public
    ``from_wood`` constructors can afford it on a wood they did not make; the builders skip it
    on their own. Checked: the outer vertices, ``out`` (``n`` exactly at the six absent slots
    of Sec. 2.1), the CSR rotations (offsets, every neighbour and colour in range, each rotation
    starting at ``out[u, red]``, at ``V_red`` at ``V_blue``), each edge's two sides agreeing on
    its colour and orientation, and the local Schnyder rule at every inner vertex (Definition
    1). A hand-made wood out of range made the numba kernels read and write out of bounds:
    interpreter crashes (stop 50). Not checked: planarity of the rotations and maximality (no
    clockwise triangle); :func:`check_schnyder_wood` (with the faces) checks the latter."""
    if not isinstance(wood, (SchnyderWood, WoodOut)):
        raise errors.ArgumentError(f"{what}: expected a SchnyderWood (jaxcds.construct.schnyder."
                                   f"schnyder_wood), got {type(wood).__name__}")
    lean = isinstance(wood, WoodOut)  # no colours: rotations start anywhere, the rule unchecked

    def bad(msg):
        raise errors.StructureError(f"{what}: {msg}")

    n, outer, absent, arrays = _wood_in_range(wood, lean, bad)
    # From here on int32 (every value is in range, and 6n - 12 < 2^31 for any n a CDS takes):
    # half the memory traffic of int64 at 10M vertices, where this check is 60M entries long.
    out, off, nb = (arrays[k].astype(np.int32) for k in ("out", "offsets", "neighbors"))
    u = np.repeat(np.arange(n, dtype=np.int32), np.diff(off))
    if lean:  # no labels: each entry's edge is the one of out that joins it, either way
        og, col = _entry_edges(out, u, nb, bad)
    else:
        og, col = arrays["outgoing"], arrays["colour"].astype(np.int32)
    _check_both_sides(out, absent, u, nb, og, col, check_labels=not lean, bad=bad)
    if not lean:
        _check_rotation_order(out, off, u, nb, og, col, outer, bad)


def _wood_in_range(wood, lean: bool, bad):
    """:func:`check_wood_arrays`' first part: ``num_vertices``, the outer vertices, every
    array's type and shape, ``out`` (absent exactly at the six outer slots of Sec. 2.1, three
    distinct targets per vertex), the offsets, and every neighbour and colour in range. Returns
    ``(n, (R, Bl, Bk), absent, arrays)``, the arrays as given (offsets as int64)."""
    from jaxcds._args import is_integer

    n = wood.num_vertices
    if not is_integer(n) or n < 3:
        bad(f"num_vertices must be an integer >= 3, got {n!r}")
    outer = (wood.v_red, wood.v_blue, wood.v_black)
    for name, v in zip(("v_red", "v_blue", "v_black"), outer):
        if not is_integer(v) or not 0 <= v < n:
            bad(f"{name} = {v!r} is not a vertex in [0, {n})")
    if len(set(int(v) for v in outer)) != 3:
        bad(f"the outer vertices {tuple(int(v) for v in outer)} are not distinct")
    m = 6 * n - 12  # rotation entries: both sides of the 3n - 6 edges
    arrays = {}
    for name, shape in (("out", (n, 3)), ("offsets", (n + 1,)), ("neighbors", (m,)),
                        ("colour", (m,)), ("outgoing", (m,)))[:3 if lean else 5]:
        a = getattr(wood, name)
        if not isinstance(a, np.ndarray) or a.shape != shape or a.dtype.kind not in ("b" if name == "outgoing" else "iu"):
            got = (f"{a.dtype} {a.shape}" if isinstance(a, np.ndarray) else type(a).__name__)
            kind = "bool" if name == "outgoing" else "integer"
            bad(f"{name} must be a numpy {kind} array of shape {shape}, got {got}")
        arrays[name] = a.astype(bool) if name == "outgoing" else a  # range checks first, below
    arrays["offsets"] = off = arrays["offsets"].astype(np.int64)  # (np.diff of unsigned ones wraps)
    out = arrays["out"]
    R, Bl, Bk = (int(v) for v in outer)
    absent = np.zeros((n, 3), bool)
    absent[R, :] = True
    absent[Bl, [BLUE, BLACK]] = True
    absent[Bk, BLACK] = True
    wrong = (out < 0) | (out > n) | ((out == n) != absent)
    if wrong.any():
        u, c = np.argwhere(wrong)[0]
        # in range but absent where an edge must be, or an edge where Sec. 2.1 has none: say which
        slot = (f"must be absent (n = {n}): V_red has no outgoing edge, V_blue no blue or black "
                "one, V_black no black one (Sec. 2.1)" if absent[u, c]
                else f"must be a vertex in [0, {n}): only the six outer slots of Sec. 2.1 are absent (n)")
        bad(f"out[{u}, {COLOUR_NAMES[c]}] = {int(out[u, c])}: "
            + (slot if 0 <= out[u, c] <= n else f"outside [0, {n}]"))
    for c1, c2 in ((RED, BLUE), (RED, BLACK), (BLUE, BLACK)):  # a simple graph: no double edge
        w = (out[:, c1] == out[:, c2]) & (out[:, c1] != n)
        if w.any():
            k = int(np.argmax(w))
            bad(f"out[{k}] = {out[k].tolist()}: vertex {k}'s {COLOUR_NAMES[c1]} and "
                f"{COLOUR_NAMES[c2]} edges lead to the same vertex")
    if off[0] != 0 or off[-1] != m:
        k = 0 if off[0] != 0 else n
        bad(f"offsets[{k}] = {int(off[k])}: offsets must run from 0 to {m} (6n - 12), each vertex "
            "holding at least 3 neighbours")
    if np.any(np.diff(off) < 3):  # named by its vertex: "offsets[0] = 0" (right) was named before
        k = int(np.argmax(np.diff(off) < 3))
        bad(f"vertex {k} holds {int(off[k + 1] - off[k])} neighbours (offsets[{k}:{k + 2}] = "
            f"{int(off[k])}, {int(off[k + 1])}): each vertex of a triangulation holds at least 3")
    for name, top in (("neighbors", n), ("colour", 3))[:1 if lean else 2]:
        a = arrays[name]
        w = (a < 0) | (a >= top)
        if w.any():
            k = int(np.argmax(w))
            bad(f"{name}[{k}] = {int(a[k])} is outside [0, {top})")
    return n, (R, Bl, Bk), absent, arrays


def _check_both_sides(out, absent, u, nb, og, col, *, check_labels: bool, bad) -> None:
    """Every rotation entry ``u -> x`` (``og``: outgoing, colour ``col``) is one side of an edge
    of ``out`` -- id ``3 * source + colour`` -- and the rotations list both sides of every edge
    exactly once. ``check_labels``: first check each labelled entry against ``out`` (the lean
    entries were matched to ``out``'s edges by :func:`_entry_edges`). Linear: the sides are
    counted per edge, not sorted."""
    edge = 3 * np.where(og, u, nb) + col
    if check_labels:  # u -> x outgoing of colour c: out[u, c] == x; x -> u incoming: out[x, c] == u
        w = out.ravel()[edge] != np.where(og, nb, u)
        if w.any():
            k = int(np.argmax(w))
            bad(f"rotation entry {k} of vertex {int(u[k])}: edge to {int(nb[k])} marked "
                f"{'outgoing' if og[k] else 'incoming'} {COLOUR_NAMES[int(col[k])]} disagrees with out")
    # each present edge listed once from its source and once from its target accounts for all
    # 6n - 12 entries
    sides = np.bincount(2 * edge + og, minlength=2 * out.size).reshape(out.size, 2)
    once = sides == (~absent).reshape(-1, 1)  # (no entry names an absent slot: checked above)
    if not once.all():
        e, at_source = (int(x) for x in np.argwhere(~once)[0])
        v, c = divmod(e, 3)
        where = f"vertex {v}" if at_source else f"vertex {int(out[v, c])} (its target)"
        bad(f"the rotation of {where} lists the {COLOUR_NAMES[c]} edge {v} -> {int(out[v, c])} "
            f"{'nowhere' if sides[e, at_source] == 0 else f'{int(sides[e, at_source])} times'}: "
            "the rotations must list both sides of every edge of out exactly once")


def _check_rotation_order(out, off, u, nb, og, col, outer, bad) -> None:
    """Each rotation starts at the vertex's outgoing red edge (``V_red``'s at ``V_blue``), the
    local Schnyder rule holds at every inner vertex (Definition 1), and every edge of an outer
    vertex to an inner one is incoming, of the outer vertex's colour."""
    R, Bl, Bk = outer
    n, first = out.shape[0], off[:-1]
    start = np.where(np.arange(n) == R, Bl, out[:, RED])
    w = nb[first] != start
    if w.any():
        k = int(np.argmax(w))
        bad(f"the rotation of vertex {k} starts at {int(nb[first[k]])}, not at "
            f"{'V_blue' if k == R else 'its outgoing red edge'} ({int(start[k])})")
    # local rule at inner vertices: codes out red 0, in black 1, out blue 2, in red 3, out black
    # 4, in blue 5 never decrease along a rotation (the three outgoing are there once, by out)
    code = np.array([3, 5, 1, 0, 2, 4], np.int8)[3 * og + col]  # [incoming c, outgoing c]
    w = np.zeros(u.size, bool)
    w[1:] = code[1:] < code[:-1]
    w[first] = False  # each rotation starts afresh
    outer_rows = [(v, c, slice(int(off[v]), int(off[v + 1])))
                  for v, c in sorted(((R, RED), (Bl, BLUE), (Bk, BLACK)))]
    for _, _, rows in outer_rows:
        w[rows] = False
    if w.any():
        k = int(np.argmax(w))
        bad(f"vertex {int(u[k])}: its ccw rotation breaks the local Schnyder rule (Definition 1) "
            f"at entry {k - int(off[u[k]])}")
    # outer vertices: every edge to an inner vertex incoming, of the vertex's own colour
    for v, own, rows in outer_rows:
        x = nb[rows]
        w = (x != R) & (x != Bl) & (x != Bk) & (og[rows] | (col[rows] != own))
        if w.any():
            k = int(np.argmax(w))
            bad(f"outer vertex {v}: its edge to {int(x[k])} is not incoming {COLOUR_NAMES[own]}")


def check_schnyder_wood(wood: SchnyderWood, faces: Optional[np.ndarray] = None,
                        *, maximal: bool = True) -> list[str]:
    """Problems of ``wood`` as messages (empty list: valid). Checks Definition 1 -- one outgoing
    edge per colour at each inner vertex, the local ccw rule, edges at the outer vertices
    incoming and of their colour (with the Sec. 2.1 outer edges), edge colours and
    orientations agreeing on both sides -- and, if ``maximal``, that the wood has no clockwise
    oriented cycle (Lemma 3): every clockwise facial triangle of ``faces`` is named, and any other
    clockwise cycle (a separating triangle, a longer one) is found by planar duality
    (:func:`_clockwise_cycle_problems`; before stop 51 only the faces were checked). A wood whose
    edges are not those of ``faces`` is named as such. A plain Python loop: the slow,
    obviously-correct reference.
    A wood that :func:`check_wood_arrays` refuses is one problem, its message (arrays out of
    range or mis-shaped raised numpy's IndexError here); the loop below then lists what remains
    of Definition 1 on the woods it takes, and the clockwise triangles."""
    try:
        check_wood_arrays(wood, "check_schnyder_wood")
    except errors.StructureError as exc:
        return [str(exc)]
    n = wood.num_vertices
    R, Bl, Bk = wood.v_red, wood.v_blue, wood.v_black
    probs: list[str] = []
    out = wood.out
    want_absent = {(R, RED), (R, BLUE), (R, BLACK), (Bl, BLUE), (Bl, BLACK), (Bk, BLACK)}
    for u in range(n):
        for c in range(3):
            absent = out[u, c] >= n
            if absent != ((u, c) in want_absent):
                probs.append(f"vertex {u}: outgoing {COLOUR_NAMES[c]} edge "
                             f"{'missing' if absent else 'present at an outer vertex'}")
    if out[Bl, RED] != R or out[Bk, RED] != R or out[Bk, BLUE] != Bl:
        probs.append("outer edges are not (V_blue,V_red) red, (V_black,V_red) red, (V_black,V_blue) blue")
    nbrs = {}
    for u in range(n):
        a, b = wood.offsets[u], wood.offsets[u + 1]
        rot = [(bool(wood.outgoing[j]), int(wood.colour[j]), int(wood.neighbors[j])) for j in range(a, b)]
        nbrs[u] = rot
        for og, c, x in rot:
            if c < 0:
                probs.append(f"edge {u}-{x} has no colour")
            elif og and out[u, c] != x:
                probs.append(f"edge {u}->{x} marked outgoing {COLOUR_NAMES[c]} but out[{u}] = {out[u].tolist()}")
            elif not og and out[x, c] != u:
                probs.append(f"edge {x}->{u} marked incoming {COLOUR_NAMES[c]} but out[{x}] = {out[x].tolist()}")
        if u in (R, Bl, Bk):
            own = {R: RED, Bl: BLUE, Bk: BLACK}[u]
            for og, c, x in rot:
                if x in (R, Bl, Bk):
                    continue
                if og or c != own:
                    probs.append(f"outer vertex {u}: edge to {x} is not incoming {COLOUR_NAMES[own]}")
            continue
        # group consecutive entries and match the pattern
        groups = []
        for og, c, _ in rot:
            if groups and groups[-1] == (og, c) and not og:
                continue
            groups.append((og, c))
        pat = [g for g in _PATTERN]
        # incoming groups may be empty: drop them from the pattern when absent
        gi = 0
        ok = True
        for p in pat:
            if gi < len(groups) and groups[gi] == p:
                gi += 1
            elif p[0]:  # an outgoing edge is mandatory
                ok = False
                break
        if not ok or gi != len(groups):
            names = [("out " if g[0] else "in ") + COLOUR_NAMES[g[1]] for g in groups]
            probs.append(f"vertex {u}: ccw order {names} breaks the local Schnyder rule")
    if maximal and faces is not None:
        f = np.asarray(faces)
        root, arcs, problem = _face_sides(wood, f)
        if problem:  # the cw tests below would read a wood of other faces as clockwise everywhere
            return probs + [problem]
        def forward(a, b):  # edge a -> b oriented so in the wood
            return bool(np.any(out[a] == b))
        for i, (a, b, c) in enumerate(f.tolist()):
            if not forward(a, b) and not forward(b, c) and not forward(c, a):
                probs.append(f"face {i} ({a}, {b}, {c}) is a clockwise oriented triangle")
        if not probs:
            probs += _clockwise_cycle_problems(root, arcs, len(f))
    return probs


def _face_sides(wood: SchnyderWood, faces: np.ndarray):
    """``(root, arcs, problem)``: the index of the root face ``(V_red, V_black, V_blue)`` (ccw),
    and ``(left face, right face, u, v)`` of every wood edge ``u -> v``; ``problem`` names an
    edge of the wood that is not an edge of ``faces`` with a face on each side, or a missing
    root face."""
    face_of = {}
    for i, (a, b, c) in enumerate(faces.tolist()):
        face_of[(a, b)] = face_of[(b, c)] = face_of[(c, a)] = i
    root = face_of.get((wood.v_red, wood.v_black))  # the root face (V_red, V_black, V_blue), ccw
    if root is None or face_of.get((wood.v_black, wood.v_blue)) != root:
        return root, [], (f"no face of the faces is the root face ({wood.v_red}, {wood.v_black}, "
                             f"{wood.v_blue}) of the wood: not a wood of these faces")
    arcs = []
    for u in range(wood.num_vertices):
        for v in wood.out[u].tolist():
            if v >= wood.num_vertices:
                continue
            if (u, v) not in face_of or (v, u) not in face_of:
                return root, [], (f"the wood's edge {u} -> {v} is not an edge with a face on each "
                                     "side in the faces: not a wood of these faces")
            arcs.append((face_of[(u, v)], face_of[(v, u)], u, v))
    return root, arcs, ""


def _clockwise_cycle_problems(root: int, arcs: list, num_faces: int) -> list[str]:
    """Maximality itself (Lemma 3: no clockwise oriented *cycle*), of which "no clockwise facial
    triangle" is only a part: a non-maximal wood can have a clockwise cycle -- a separating
    triangle, a longer cycle -- with no clockwise face (stop 51: of 960 non-maximal woods of random
    triangulations with 4 to 15 vertices, 426 had a clockwise cycle and 99 of those no clockwise
    face; found by enumerating every directed cycle).

    Exact, in O(n), by planar duality: give every wood edge ``u -> v`` (``arcs``, from
    :func:`_face_sides`) the dual arc from its left face (the one holding ``u -> v`` ccw) to its
    right face. A clockwise cycle (its inside on its right) has every dual arc across it pointing
    inside, so the faces inside cannot reach the ``root`` (outer) face; conversely the faces that
    cannot reach it form a region whose boundary edges all have it on their right: a clockwise
    cycle. So the wood is maximal iff every face reaches the root face along dual arcs (a search
    backwards from the root face). Checked against the enumeration of every directed cycle in
    ``tests/construct/test_schnyder.py``."""
    back = [[] for _ in range(num_faces)]
    for left, right, _, _ in arcs:
        back[right].append(left)
    reached = np.zeros(num_faces, bool)
    reached[root] = True
    stack = [root]
    while stack:
        for g in back[stack.pop()]:
            if not reached[g]:
                reached[g] = True
                stack.append(g)
    if reached.all():
        return []
    # name one clockwise cycle: walk the edges with an unreached face on the right and a
    # reached one on the left (the boundary of the unreached region) until a vertex repeats
    step = {}
    for left, right, u, v in arcs:
        if reached[left] and not reached[right]:
            step.setdefault(u, v)
    u = next(iter(step))
    walk, at = [u], {u: 0}
    while step[u] not in at:
        u = step[u]
        at[u] = len(walk)
        walk.append(u)
    cycle = walk[at[step[u]]:]
    shown = " -> ".join(map(str, cycle[:12])) + (" -> ..." if len(cycle) > 12 else "")
    return [f"the wood is not maximal: {int((~reached).sum())} faces (e.g. face "
            f"{int(np.flatnonzero(~reached)[0])}) lie inside a clockwise oriented cycle, "
            f"{shown} -> {cycle[0]} (Lemma 3: a maximal wood has none; no face is a clockwise triangle)"]


def schnyder_wood_reference(faces, num_vertices: int, root_face: int = 0) -> np.ndarray:
    """Slow, obviously-correct Python version of the maximal conquest (for tests): rescans the
    boundary path from V_blue at each step and recounts chords from scratch. Returns ``out``."""
    f = np.asarray(faces, dtype=np.int64)
    n = int(num_vertices)
    adj = {u: set() for u in range(n)}
    for a, b, c in f.tolist():
        for x, y in ((a, b), (b, c), (c, a)):
            adj[x].add(y)
            adj[y].add(x)
    # ccw rotation: for each dart (a, b) in face (a, b, c), the next ccw neighbour of a after b
    # is the origin of the previous dart of the twin... simpler: ccw successor of b around a is c'
    # where (a, c', b) is a face, i.e. face (b, a, ?) -> see below
    ccw_next = {}
    for a, b, c in f.tolist():
        # face (a, b, c) ccw: around a, c follows b ccw; around b, a follows c; around c, b follows a
        ccw_next[(a, b)] = c
        ccw_next[(b, c)] = a
        ccw_next[(c, a)] = b
    cw_next = {(u, y): x for (u, x), y in ccw_next.items()}
    v_red, v_black, v_blue = (int(x) for x in f[root_face])
    out = np.full((n, 3), n, dtype=np.int32)
    B = [v_blue, v_black, v_red]
    removed = set()
    while len(removed) < n - 2:
        onb = set(B)
        pos = {x: i for i, x in enumerate(B)}
        # faces of the unconquered region: those with no removed vertex
        chosen = None
        for i in range(1, len(B) - 1):
            v = B[i]
            chord = any(x in onb and abs(pos[x] - i) > 1 and not (x in (v_blue, v_red) and False)
                        for x in adj[v] if x not in removed)
            if not chord:
                chosen = i
                break
        assert chosen is not None, "stuck"
        v = B[chosen]
        vr, vl = B[chosen - 1], B[chosen + 1]
        out[v, BLUE] = vr
        out[v, RED] = vl
        fan = []
        x = cw_next[(v, vr)]
        while x != vl:
            fan.append(x)
            out[x, BLACK] = v
            x = cw_next[(v, x)]
        B = B[:chosen] + fan + B[chosen + 1:]
        removed.add(v)
    out[v_blue, RED] = v_red
    return out


def prepare_mesh(mesh, structure: str = "a Schnyder wood"):
    """Validate a mesh for Schnyder woods: manifold, consistently oriented, connected, closed
    (holes are closed with :func:`jaxcds.mesh.close_boundaries`, CDS paper Sec. 4.5), genus 0.

    Returns ``(mesh, closed)``; ``closed`` says whether holes were filled here (the dummy vertices
    and faces are flagged on the returned mesh).

    Raises:
      UnsupportedTopologyError: genus > 0 (naming the genus, suggesting ``lr`` / ``halfedge``),
        several components, fewer than 4 vertices.
      MeshError: the defects of :func:`jaxcds.mesh.validate` (non-manifold edge or vertex...).
    """
    from jaxcds import mesh as _mesh

    m0 = _mesh.load_mesh(mesh)
    # defects, components and holes from one edge table (the cost of this step at 1M+ vertices)
    m = _mesh.validate_and_close(m0, connected=True, structure=structure)
    closed = m is not m0
    loops = m.num_vertices - m0.num_vertices  # one dummy vertex per closed loop
    # No full topology report (it rebuilds the edge table and reruns the defect checks): the mesh
    # is now a connected, consistently oriented (so orientable), closed manifold, every edge has
    # two faces, E = 3F/2 and the Euler characteristic is V - E + F = V - F/2 = 2 - 2 genus.
    chi = m.num_vertices - m.num_faces // 2
    if chi != 2:
        holes = f" after closing {loops} boundary loop(s)" if loops else ""
        raise errors.UnsupportedTopologyError(
            f"{m.source}: {structure} needs a genus-0 surface (a planar triangulation); this mesh has "
            f"genus {(2 - chi) // 2} (Euler characteristic {chi}{holes}); "
            + ("it has no such form: keep it as a mesh file (the 'lr' and 'halfedge' structures "
               "take it)" if "encoding" in structure else "use the 'lr' or 'halfedge' structure for it"))
    if m.num_vertices < 4:
        raise errors.UnsupportedTopologyError(
            f"{m.source}: {structure} needs at least 4 vertices, got {m.num_vertices}")
    return m, closed
