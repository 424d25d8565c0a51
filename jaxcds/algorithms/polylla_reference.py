"""Polylla's traversal and repair as the reference implementation runs them (``mode="reference"``).

The reference (Polylla-Mesh-DCEL, ``polylla.hpp``; its output is ``../shared/polylla/
points50.1.off``) walks each terminal-edge region once, sequentially, and three of its details
make its output depend on the input's numbering and differ from the order-free phases of
:mod:`jaxcds.algorithms.polylla` (``mode="canonical"``):

1. **The walk stops at its starting vertex.** ``travel_triangles`` starts at the first frontier
   dart ``e_init`` met turning clockwise from the seed and stops the first time it reaches
   ``origin(e_init)`` again (``while (e_curr != e_init && v_curr != v_init)``; the first test
   hardly ever ends the loop). A region whose boundary passes that vertex twice (the base of a
   barrier edge) is cut short there: barrier-edge tips beyond the cut are not seen, and the
   polygon is output with its tip left in.
2. **Tips are repaired one after the other.** For the tips of one polygon, in the order of its
   vertex list, ``search_middle_edge`` starts from ``edge_of_vertex(v)`` -- the last half-edge
   with origin ``v`` in the input's numbering, ``3 i + j`` for corner ``j`` of triangle ``i`` --
   turns clockwise to the first frontier dart, and marks the middle edge frontier at once, so a
   later tip whose vertex an earlier middle edge reached may start from that edge instead.
3. **Repaired pieces** are walked from the middle-edge darts in reverse order of their listing;
   a dart the walks pass is crossed off (``seed_bet_mark``), so each piece is output once (the
   reference's own comment calls the crossing-off incomplete: a piece can come out twice).

This module runs that sequential algorithm on the structure's navigation (``next``, ``twin``,
``origin``, ``is_border``, ``face`` of every dart, read once into host arrays) with the input's
numbering attached to the darts (``rid``: the reference's half-edge id), in one numba pass:
O(darts), like the reference. The label phase (longest edges, frontier, ties by the input's
corner order) is the jitted one of :mod:`jaxcds.algorithms.polylla`. On an input of clockwise
triangles the structure holds them turned counter-clockwise; the reference's half-edges are
then the structure's darts read backwards (``next`` = the structure's ``prev``, ``origin`` = its
``target``), so the walk is the reference's on the input as given.
"""

from __future__ import annotations

import numba
import numpy as np

from jaxcds import errors

__all__ = ["reference_walks", "dart_rows", "corners_in_structure_ids"]

# status codes of the kernel (0: fine)
_OK, _NO_FRONTIER, _OPEN_WALK, _BAD_CORNER = 0, 1, 2, 3


# one row of 4 int32 per dart (the reference's array of structs): next, twin, the clockwise turn
# next(twin) (a turn step reads one row, not two), and the origin with two flags in its top bits
_NXT, _TWIN, _CW, _OF = 0, 1, 2, 3
_ORG_BITS = (1 << 30) - 1
_FRONTIER = 1 << 30  # and the sign bit (bit 31) marks a border dart: its row word is negative


@numba.njit(cache=True, inline="always")
def _org(H, e):
    return H[e, _OF] & _ORG_BITS


@numba.njit(cache=True, inline="always")
def _frontier(H, e):
    return (H[e, _OF] & _FRONTIER) != 0


@numba.njit(cache=True, inline="always")
def _border(H, e):
    return H[e, _OF] < 0


@numba.njit(cache=True)
def _search(e, H, budget):
    """``search_frontier_edge``: turn clockwise (``next(twin(e))``) until a frontier dart; -1
    after ``budget`` turns (a vertex with no frontier dart: a tie cycle or a broken table)."""
    k = 0
    while not _frontier(H, e):
        e = H[e, _CW]
        k += 1
        if k > budget:
            return -1
    return e


@numba.njit(cache=True)
def _grown(buf, n):
    """``buf`` (holding ``n`` values) copied into one twice as large. Called only when full: the
    hot loops store in place and test the size, so no array crosses a call per value."""
    big = np.empty(2 * buf.size + 16, buf.dtype)
    big[:n] = buf[:n]
    return big


@numba.njit(cache=True)
def _push(buf, n, x):
    """Append ``x`` to the growable buffer ``buf`` holding ``n`` values (cold paths only)."""
    if n == buf.size:
        buf = _grown(buf, n)
    buf[n] = x
    return buf, n + 1


@numba.njit(cache=True)
def _walk(e_init, H, poly, budget):
    """``travel_triangles`` from frontier dart ``e_init``: the vertices it lists (from the
    vertex after ``origin(e_init)``, up to the first return to it) into ``poly`` (grown when
    full). ``(poly, L)``; ``L = -1``: no frontier dart met, ``-2``: the walk does not close."""
    v_init = _org(H, e_init)
    e = H[e_init, _NXT]
    v = _org(H, e)
    poly[0] = v
    L = 1
    while e != e_init and v != v_init:
        k = 0
        while not _frontier(H, e):  # search_frontier_edge, inlined: the hot loop
            e = H[e, _CW]
            k += 1
            if k > budget:
                return poly, -1
        e = H[e, _NXT]
        v = _org(H, e)
        if L == poly.size:
            if L > budget:
                return poly, -2
            poly = _grown(poly, L)
        poly[L] = v
        L += 1
    return poly, L


@numba.njit(cache=True)
def _leaving(e_init, H, via, L):
    """The darts by which the walk from ``e_init`` reaches its ``L`` listed vertices (each the
    dart leaving its vertex into the region), into ``via`` (grown when short). Walked again,
    before any middle edge is marked, only for the few polygons with tips: the walk itself
    keeps one list."""
    if via.size < L:
        via = np.empty(2 * L, via.dtype)
    e = H[e_init, _NXT]
    via[0] = e
    for i in range(1, L):
        while not _frontier(H, e):
            e = H[e, _CW]
        e = H[e, _NXT]
        via[i] = e
    return via


@numba.njit(cache=True)
def _is_tip(poly, L, i):
    """Listed vertex ``i + 1`` is a barrier-edge tip: the walk comes back the way it went
    (``poly[i] == poly[i + 2]``, indices cyclic; no division in the test)."""
    j = i + 2
    if j >= L:
        j -= L
        if j >= L:  # L == 1
            j -= L
    return poly[i] == poly[j]


@numba.njit(cache=True)
def _half_edge_id(d, H, face, row, row_id, corners):
    """The reference's id ``3 i + j`` of inner dart ``d``: row ``i`` of its face, ``j`` the
    corner of that row its origin is (-1: none, the corners do not match)."""
    r = row[face[d]]
    o = _org(H, d)
    for j in range(3):
        if corners[r, j] == o:
            return 3 * row_id[r] + j
    return -1


@numba.njit(cache=True)
def _edge_of_vertex(e, H, face, row, row_id, corners, budget):
    """``edge_of_vertex(v)`` as the reference stores it, for ``v`` the origin of dart ``e``: of
    the inner darts leaving ``v``, the one whose half-edge id is the highest (the one written
    last). Turns once around ``v``: only the tips' vertices ask."""
    best, arg, d, k = np.int64(-1), e, e, 0
    while True:
        if not _border(H, d):
            r = _half_edge_id(d, H, face, row, row_id, corners)
            if r > best:
                best, arg = r, d
        d = H[d, _CW]
        k += 1
        if d == e or k > budget:
            return arg


@numba.njit(cache=True)
def _seeds_in_order(cand, H, face, row, row_id, corners):
    """The label phase's seed darts (one per terminal or border terminal edge) as the reference
    takes them: the half with the smaller half-edge id (a border terminal edge: its inner half),
    in half-edge id order. ``(darts, ids)``; an id of -1 when the corners do not match."""
    n = cand.size
    ids = np.empty(n, np.int64)
    darts = np.empty(n, np.int32)
    for k in range(n):
        d = cand[k]
        rd = _half_edge_id(d, H, face, row, row_id, corners)
        t = H[d, _TWIN]
        if rd < 0:
            return darts, np.full(n, -1, np.int64), d
        if not _border(H, t):
            rt = _half_edge_id(t, H, face, row, row_id, corners)
            if rt < 0:
                return darts, np.full(n, -1, np.int64), t
            if rt < rd:
                d, rd = t, rt
        ids[k] = rd
        darts[k] = d
    order = np.argsort(ids, kind="mergesort")
    return darts[order], ids[order], -1


@numba.njit(cache=True)
def _kernel(H, face, row, row_id, corners, cand):
    """The reference's ``Polylla`` constructor after its labels, on the dart rows ``H``: for
    each seed in half-edge order ``travel_triangles``, ``has_BarrierEdgeTip`` on the vertex list,
    and for a polygon with tips ``barrieredge_tip_reparation`` (``search_middle_edge`` per tip,
    marked at once; pieces by ``generate_repaired_polygon`` from the last middle-edge dart).
    Returns ``(status, where, offsets, indices, seed ids, tips, polygons repaired)``."""
    E = H.shape[0]
    budget = E + 1
    seeds, seed_ids, bad = _seeds_in_order(cand, H, face, row, row_id, corners)
    ns = seeds.size
    nothing = np.zeros(0, np.int64)
    if bad >= 0:
        return _BAD_CORNER, bad, nothing, nothing, nothing, 0, 0
    mark = np.zeros(E, np.bool_)
    off = np.zeros(ns + 16, np.int64)
    idx = np.empty(E // 2 + 16, np.int32)
    seed_of = np.empty(ns + 16, np.int64)
    npoly = 0
    nidx = 0
    tips = 0
    to_repair = 0
    poly = np.empty(64, np.int32)
    via = np.empty(64, np.int32)  # the dart the walk leaves each listed vertex by
    stack = np.empty(64, np.int32)
    for s_i in range(ns):
        # travel_triangles
        e_init = _search(seeds[s_i], H, budget)
        if e_init < 0:
            return _NO_FRONTIER, seeds[s_i], nothing, nothing, nothing, 0, 0
        poly, L = _walk(e_init, H, poly, budget)
        if L < 0:
            return _OPEN_WALK, seeds[s_i], nothing, nothing, nothing, 0, 0
        tip = False
        for i in range(L):
            if _is_tip(poly, L, i):
                tip = True
                break
        if not tip:  # written from its starting vertex (listed last), as the reference's files
            while nidx + L > idx.size:
                idx = _grown(idx, nidx)
            idx[nidx] = poly[L - 1]
            idx[nidx + 1: nidx + L] = poly[: L - 1]
            nidx += L
            off, _ = _push(off, npoly + 1, nidx)
            seed_of, npoly = _push(seed_of, npoly, s_i)
            continue
        via = _leaving(e_init, H, via, L)
        # barrieredge_tip_reparation: middle edges one after the other, marked at once
        to_repair += 1
        ntop = 0
        for i in range(L):
            if not _is_tip(poly, L, i):
                continue
            tips += 1
            d_tip = via[i + 1 if i + 1 < L else 0]  # a dart leaving the tip
            fe = _search(_edge_of_vertex(d_tip, H, face, row, row_id, corners, budget), H, budget)
            if fe < 0:
                return _NO_FRONTIER, d_tip, nothing, nothing, nothing, 0, 0
            n_ = H[fe, _CW]
            adv = 1
            while n_ != fe:  # the degree of the tip (every dart leaving it)
                n_ = H[n_, _CW]
                adv += 1
                if adv > E:
                    return _OPEN_WALK, fe, nothing, nothing, nothing, 0, 0
            adv -= 1
            adv = adv // 2 - 1 if adv % 2 == 0 else adv // 2
            if adv < 0:  # degree 1: the reference's unsigned count wraps (no valid input has it)
                return _OPEN_WALK, fe, nothing, nothing, nothing, 0, 0
            m = H[fe, _CW]
            while adv != 0:
                m = H[m, _CW]
                adv -= 1
            tm = H[m, _TWIN]
            H[m, _OF] |= _FRONTIER
            H[tm, _OF] |= _FRONTIER
            stack, ntop = _push(stack, ntop, m)
            stack, ntop = _push(stack, ntop, tm)
            mark[m] = True
            mark[tm] = True
        while ntop:  # the pieces, from the last middle-edge dart listed
            ntop -= 1
            t = stack[ntop]
            if not mark[t]:
                continue
            mark[t] = False
            # generate_repaired_polygon (t is frontier: no turn before the walk)
            e_init = t
            v_init = _org(H, e_init)
            e = H[e_init, _NXT]
            v = _org(H, e)
            mark[e] = False
            start = nidx
            idx, nidx = _push(idx, nidx, v_init)  # the list from its starting vertex (see above)
            if v != v_init:
                idx, nidx = _push(idx, nidx, v)
            while e != e_init and v != v_init:
                k = 0
                while not _frontier(H, e):
                    e = H[e, _CW]
                    mark[e] = False
                    k += 1
                    if k > budget:
                        return _NO_FRONTIER, e, nothing, nothing, nothing, 0, 0
                mark[e] = False
                e = H[e, _NXT]
                v = _org(H, e)
                mark[e] = False
                if v != v_init:
                    idx, nidx = _push(idx, nidx, v)
                if nidx - start > E:
                    return _OPEN_WALK, t, nothing, nothing, nothing, 0, 0
            off, _ = _push(off, npoly + 1, nidx)
            seed_of, npoly = _push(seed_of, npoly, s_i)
    ids = np.empty(npoly, np.int64)
    for p in range(npoly):
        ids[p] = seed_ids[seed_of[p]]
    return _OK, -1, off[: npoly + 1].copy(), idx[:nidx].astype(np.int64), ids, tips, to_repair


def dart_rows(nxt, twin, org, frontier, border):
    """``(E, 4)`` int32, the kernel's row per dart: ``next``, ``twin``, the clockwise turn
    ``next(twin)``, and the origin (below ``2^30``) with the frontier flag in bit 30 and the
    border flag in bit 31 (jittable; the caller builds it inside its jitted dart pass)."""
    import jax.numpy as jnp

    nxt, twin = jnp.asarray(nxt, jnp.int32), jnp.asarray(twin, jnp.int32)
    cw = nxt[jnp.clip(twin, 0, nxt.shape[0] - 1)]
    word = (jnp.asarray(org, jnp.int32) | jnp.where(frontier, _FRONTIER, 0).astype(jnp.int32)
            | jnp.where(border, jnp.int32(-(1 << 31)), 0).astype(jnp.int32))
    return jnp.stack([nxt, twin, cw, word], axis=1)


def corners_in_structure_ids(corners, vid) -> np.ndarray:
    """``(F, 3)`` int32: the input rows ``corners`` (input vertex ids) in a structure's vertex
    ids, ``vid`` the input id of each structure vertex (the rows as they are when the structure
    keeps the input's numbering). One inverse table and one gather; the walks compare origins
    with these rows, and :func:`jaxcds.algorithms.polylla._rows_of_faces` matches faces in them.

    Raises:
      PolyllaError: a row holds a vertex the structure does not have.
    """
    vid = np.asarray(vid)
    corners = np.asarray(corners)
    if np.array_equal(vid, np.arange(vid.size)):
        return corners.astype(np.int32, copy=False)
    inv = np.full(int(max(vid.max(initial=0), corners.max(initial=0))) + 1, -1, np.int32)
    inv[vid] = np.arange(vid.size, dtype=np.int32)
    out = inv[corners]
    if out.size and out.min() < 0:
        bad = int(np.nonzero((out < 0).any(axis=1))[0][0])
        raise errors.PolyllaError(f"corners row {bad} {corners[bad].tolist()} holds a vertex "
                                  "the structure does not have")
    return out


def reference_walks(H, face, seed, row_of_face, corners, num_vertices: int, row_id=None):
    """The reference's traversal and repair on dart arrays (see the module docstring).

    Args (host arrays over the ``E`` darts of a structure, in the reference's orientation):
      H: ``(E, 4)`` :func:`dart_rows` (``next``, ``twin``, ``next(twin)``, ``origin`` in
        structure vertex ids with the flags: frontier as the label phase found it, border darts
        frontier; border: on the outer face or not a dart). Changed in place (a read-only array is copied first): the
        repair's middle edges become frontier.
      face: the dart's face id (anything on border darts); ``row_of_face``: the input row of
        each face; ``corners``: ``(F, 3)`` input rows as listed, in structure vertex ids
        (:func:`corners_in_structure_ids`); ``num_vertices``: the structure's; ``row_id``: the
        reference's triangle index of each
        row, increasing (default: the row's own index; a piece of a larger input passes its
        rows' indices there, so the half-edge ids are the whole input's).
      seed: one dart per terminal or border terminal edge (the label phase's).

    Returns ``(offsets, indices, seed_ids, tips, repaired, regions)``: CSR polygons in the
    reference's order with structure vertex ids, each in the reference's vertex order (from the
    origin of its first frontier dart, as the reference's OFF files list them; its tips are
    looked for from the next vertex on, as ``travel_triangles`` lists them); ``seed_ids`` the
    reference half-edge id of each polygon's seed (its output order); tips found, polygons sent
    to repair, seed edges.

    Raises:
      StructureError: a walk meets no frontier dart or does not close (tables that are not
        those of a triangulation), or a dart's origin is not a corner of its face's row.
      ArgumentError: arrays of the wrong shape or kind, or ids out of range (named): the
        kernel indexes by them unchecked, and a dart id out of range crashed the interpreter
        (stop 50). :func:`jaxcds.algorithms.polylla.polylla` passes its own arrays unchecked.
    """
    _check_walk_inputs(H, face, seed, row_of_face, corners, num_vertices, row_id)
    return _reference_walks(H, face, seed, row_of_face, corners, num_vertices, row_id)


def _check_walk_inputs(H, face, seed, row_of_face, corners, num_vertices, row_id) -> None:
    """:func:`reference_walks`' argument checks, O(E + F) numpy passes."""
    from jaxcds._args import is_integer

    def refuse(msg):
        raise errors.ArgumentError(f"reference_walks: {msg}")

    def ints(a, name, shape_ok, want):
        a = np.asarray(a)
        if a.dtype.kind not in "iu" or not shape_ok(a.shape):
            refuse(f"{name} must be {want} integers, got {a.dtype} {a.shape}")
        return a.astype(np.int64)

    if not is_integer(num_vertices) or num_vertices < 0:
        refuse(f"num_vertices must be a non-negative integer, got {num_vertices!r}")
    H = ints(H, "H", lambda s: len(s) == 2 and s[1] == 4, "(E, 4)")
    e = H.shape[0]
    for k, name in enumerate(("next", "twin", "next(twin)")):
        bad = (H[:, k] < 0) | (H[:, k] >= e)
        if bad.any():
            d = int(np.argmax(bad))
            refuse(f"H[{d}] {name} = {int(H[d, k])} is not a dart in [0, {e})")
    border = H[:, 3] < 0
    org = H[:, 3] & _ORG_BITS
    bad = org >= num_vertices
    if bad.any():
        d = int(np.argmax(bad))
        refuse(f"H[{d}] origin {int(org[d])} is not a vertex in [0, {num_vertices})")
    corners = ints(corners, "corners", lambda s: len(s) == 2 and s[1] == 3, "(R, 3)")
    rows = corners.shape[0]
    row_of_face = ints(row_of_face, "row_of_face", lambda s: len(s) == 1, "(F,)")
    faces = row_of_face.shape[0]
    face = ints(face, "face", lambda s: s == (e,), f"({e},)")
    for name, a, top, mask in (("face", face, faces, ~border), ("row_of_face", row_of_face, rows, None),
                               ("corners", corners.reshape(-1), num_vertices, None)):
        bad = (a < 0) | (a >= top)
        if mask is not None:
            bad &= mask
        if bad.any():
            k = int(np.argmax(bad))
            where = f"[{k // 3}]" if name == "corners" else f"[{k}]"
            refuse(f"{name}{where} = {int(a[k])} is outside [0, {top})")
    sd = np.asarray(seed)
    if sd.shape != (e,) or sd.dtype.kind not in "biu":
        refuse(f"seed must be ({e},) flags (one per dart), got {sd.dtype} {sd.shape}")
    if row_id is not None:
        r = ints(row_id, "row_id", lambda s: s == (rows,), f"({rows},)")
        if rows and (r[0] < 0 or np.any(np.diff(r) <= 0)):
            refuse("row_id must be increasing non-negative integers")


def _reference_walks(H, face, seed, row_of_face, corners, num_vertices: int, row_id=None):
    """:func:`reference_walks` on arrays :func:`~jaxcds.algorithms.polylla.polylla` made
    (unchecked)."""
    if num_vertices > _ORG_BITS:
        raise errors.PolyllaError(f"Polylla (reference mode) holds vertex ids in 30 bits: "
                                  f"{num_vertices} vertices are too many")
    H = np.ascontiguousarray(H, np.int32)
    if not H.flags.writeable:  # a view of a jax array: the repair marks middle edges in it
        H = H.copy()
    corners = np.asarray(corners)
    row_id = np.arange(len(corners), dtype=np.int64) if row_id is None else np.asarray(row_id, np.int64)
    cand = np.flatnonzero(np.asarray(seed)).astype(np.int32)
    status, where, off, idx, seed_ids, tips, repaired = _kernel(
        H, np.ascontiguousarray(face, np.int32), np.ascontiguousarray(row_of_face, np.int32),
        row_id, np.ascontiguousarray(corners, np.int32), cand)
    if status == _BAD_CORNER:
        raise errors.StructureError(
            f"Polylla (reference mode): dart {where} leaves a vertex that is not a corner of "
            "its face's input row (the corners do not match the structure)")
    if status == _NO_FRONTIER:
        raise errors.StructureError(
            f"Polylla (reference mode): turning clockwise from dart {where} meets no frontier "
            "dart (a vertex whose every edge is a longest edge: inconsistent tables or ties)")
    if status == _OPEN_WALK:
        raise errors.StructureError(
            f"Polylla (reference mode): the walk from dart {where} does not close "
            "(inconsistent twin/next in the structure)")
    return off, idx, seed_ids, int(tips), int(repaired), int(cand.size)
