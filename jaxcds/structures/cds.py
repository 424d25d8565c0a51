"""Compact data structures from Schnyder woods (Castelli Aleardi & Devillers, JoCG 2018).

Paper: ``../shared/seeds/000_db4616a06e23a922.txt``, Sec. 2.1-2.6. Four structures, one family:

=============  ===========  =====================================================  =============
class          registry     paper                                                  references
=============  ===========  =====================================================  =============
CDS6n          ``cds6n``    Thm 2 (Sec. 2.1, Fig. 3): S/C of both front edges      6n (+n faces)
CDS5n          ``cds5n``    Thm 4 (Sec. 2.2, Fig. 4): maximal wood, S_red^toleft   5n (+n faces)
CDS4n          ``cds4n``    Thm 5 (Sec. 2.3, Fig. 5): cwBFS order, no red RF       4n (+n faces)
CDS5nO1        ``cds5n-o1`` Thm 6 (Sec. 2.4, Fig. 6): D, W; Target/Adjacent O(1)   5n (+n faces)
=============  ===========  =====================================================  =============

Edges and darts
---------------
An edge is named by its Schnyder source ``u`` and colour ``c`` (``u_c`` in the paper, colours
``RED = 0, BLUE = 1, BLACK = 2``, :mod:`jaxcds.construct.schnyder`): edge id ``e = 3u + c``. The
protocol works on darts: **dart** ``d = 2e + r``; ``r = 0`` is the edge in its Schnyder orientation
``u -> v``, ``r = 1`` the reverse ``v -> u``. So ``twin(d) = d ^ 1`` and

* ``next(2e) = LeftFront(e)``, ``prev(2e) = LeftBack(e)``,
* ``next(2e + 1) = RightBack(e)``, ``prev(2e + 1) = RightFront(e)``

(reversing an edge swaps left and right: ``left_front(twin e) = right_back(e)`` ...). The paper's
operators return unoriented edges; ours return the dart that runs ccw around the named face, and
the orientation is read off the colour case analysis, in O(1), from the Schnyder local rule
(Definition 1) -- e.g. ``LeftFront(u_c)`` has colour ``c`` (then it is the edge ``w_c`` entering
``v``: ``r = 1``) or ``next(c)`` (then it is ``v_next(c)``: ``r = 0``). Ids of the six absent edges
(every colour at ``V_red``, blue/black at ``V_blue``, black at ``V_black``) are holes:
``dart_valid`` is False there. ``num_darts = 6n``.

The three outer darts (the root face ``(V_red, V_black, V_blue)``, ccw in the mesh) are
``D0 = V_blue -> V_red`` (``2(3 V_blue + red)``), ``D1 = V_red -> V_black``
(``2(3 V_black + red) + 1``), ``D2 = V_black -> V_blue`` (``2(3 V_black + blue)``); the proofs
leave the exterior edges to "a special manner" (Thm 4, last paragraph): the four outer cases that
the local rule does not cover are written as explicit ``jnp.where`` (``_EXTERIOR`` comments).

References encoding (Sec. 2.1): each table row stores vertex indices in the low 30 bits of an int32
and at most two service bits (``I_c``, ``C``) in bits 30 and 31, so a structure is exactly
``k`` int32 per vertex (``k = 6, 5, 4, 5``) plus ``F_blue`` (one per vertex) for the face map of
Thm 7. Up to ``2^30`` vertices.

Faces (Thm 7) and corners (Thm 8)
---------------------------------
Face *slots* follow Thm 7: the red triangle of ``u`` (left of ``u_red``) is slot ``u``, the black
triangle of ``u`` is ``n + u``, the blue triangle of ``u`` is ``n + F_blue[u]``; 4 of the ``2n``
slots are unused (``V_red``'s red slot and three black slots). The protocol wants dense face ids
``0 .. 2n-5``, so ``face(d)`` returns the slot minus the number of unused slots below it (4 static
ints, O(1)), and :meth:`face_slot` the raw Thm 7 slot (index of the paper's size-``2n`` face array).
``F_blue`` is filled so that it is also its own inverse where needed (``edge_of_face`` is O(1)):
``F_blue[u] = u`` when ``u``'s black slot is free, otherwise ``F_blue[u] = v`` and
``F_blue[v] = u`` for a free slot ``v`` whose own blue triangle is not blue.

Corners: a corner is a dart (the dart leaving the corner's vertex ccw in its triangle, as in
:mod:`jaxcds.structures.base`); :meth:`corner_index` maps it to Thm 8's numbering
``u + n (c + 3 r)`` (source-corner of ``u_c``: ``u + cn``; target-corner: ``u + (3 + c) n``) and
:meth:`corner_dart` back, both O(1) and with no extra reference.

Target
------
CDS6n / CDS5n / CDS4n: ``Target(u_c)`` turns cw around the target with ``LeftFront`` until an
edge leaving it shows up (Thm 2, "Operator Target"), a masked ``while_loop`` over the batch: O(d).
CDS5nO1: O(1) (Thm 6), two table-row reads, the first's answer written to memory in between
(``base.materialize_loop``: XLA would fuse the two and re-read the first inside the second).
Whole-mesh queries (``face_vertices``, used by the normals, and ``vertex_degrees``) read the
tables column by column (slices, no gather), compute all ``3n`` targets at once -- by pointer
jumping along the same ``LeftFront`` chains (one gather per round, ``ceil(log2(longest fan))``
rounds) or, for CDS5nO1, by Thm 6 in O(1) per edge -- and assemble every face from its Thm 7 slot
in O(1) (no navigation operator is called). The normals
read the ``2n`` slots as they are (``face_vertices_padded``: the four unused slots masked), with
no compaction into dense face ids; ``face_vertices`` cuts the unused slots out.

Construction
------------
``build_cds``: mesh checks (:func:`jaxcds.construct.schnyder.prepare_mesh`: one edge table for
defects, components and holes; genus from the Euler count), the maximal Schnyder wood (Appendix
A, numba), then ``from_wood``: for CDS4n / CDS5n-O(1) the cwBFS of the red tree (Sec. 2.3, which
also yields Thm 6's depth parity ``D``), and every table row by one numba kernel
(:func:`_cds_rows`, three linear passes: ``I_c``; the fronts of every edge read once in its
target's rotation; the packed rows, cwBFS labels applied as they are written, and the Thm 7
matching). No sort, no relabelled copy of the wood. :func:`tables_reference` is the previous
vectorised numpy route, kept as the tests' oracle.
"""

from __future__ import annotations

from typing import Optional

import jax
import jax.numpy as jnp
import numba
import numpy as np

from jaxcds import _mappings, errors
from jaxcds._arrays import to_device, traced_for_cpu
from jaxcds._dataclass import pytree_dataclass, static_field
from jaxcds._progress import PROGRESS_MIN_VERTICES  # noqa: F401  (re-exported)
from jaxcds._progress import Progress as _Progress
from jaxcds._progress import want_progress as _want_progress
from jaxcds.construct.schnyder import BLACK, BLUE, RED, SchnyderWood, check_wood_arrays, schnyder_wood
from jaxcds.structures import registry
from jaxcds.structures.base import Int, MeshStructure, check_id_space, interleave_rows, split_padding
from jaxcds.structures import base as _base
from jaxcds.structures.base import materialize_loop as _materialize_loop
from jaxcds.structures.base import take_nonnegative as _take

__all__ = ["CDS6n", "CDS5n", "CDS4n", "CDS5nO1", "build_cds", "cw_bfs_order", "relabel_wood",
           "edge_fronts", "face_slots", "assign_face_slots", "tables_reference", "target_rounds", "with_target_rounds"]

_IDX = (1 << 30) - 1
_MAX_VERTICES = 1 << 30


# ====================================================================================== builder
@numba.njit(cache=True)
def _dart_at(x, j, nbr, col, outg):
    y = nbr[j]
    c = col[j]
    if outg[j]:
        return 2 * (3 * x + c)
    return 2 * (3 * y + c) + 1


@numba.njit(cache=True)
def _fronts(offsets, nbr, col, outg, out, n):
    lf = np.full((n, 3), -1, dtype=np.int64)
    rf = np.full((n, 3), -1, dtype=np.int64)
    lf2 = np.full((n, 3), -1, dtype=np.int64)
    for u in range(n):
        for c in range(3):
            v = out[u, c]
            if v >= n:
                continue
            a = offsets[v]
            d = offsets[v + 1] - a
            j = -1
            for k in range(d):
                if nbr[a + k] == u:
                    j = k
                    break
            # w: cw of u around v (LeftFront = v -> w); z: ccw of u (RightFront = z -> v)
            lf[u, c] = _dart_at(v, a + (j - 1) % d, nbr, col, outg)
            rf[u, c] = _dart_at(v, a + (j + 1) % d, nbr, col, outg) ^ 1
            lf2[u, c] = _dart_at(v, a + (j - 2) % d, nbr, col, outg)
    return lf, rf, lf2


def edge_fronts(wood: SchnyderWood):
    """Ground truth from the rotation system: ``(LF, RF, LF2)``, ``(n, 3)`` int64 darts
    (``-1`` for absent edges): ``LF[u, c]`` = the dart ``(v, w)`` of ``LeftFront(u_c)``,
    ``RF[u, c]`` = the dart ``(z, v)`` of ``RightFront(u_c)``, ``LF2[u, c]`` = the dart ``(v, q)``
    one more step cw around ``v`` (Sec. 2.2's ``q``)."""
    check_wood_arrays(wood, "edge_fronts")
    return _fronts(wood.offsets, wood.neighbors, wood.colour, wood.outgoing, wood.out,
                   wood.num_vertices)


def _src(d):
    return (d >> 1) // 3


def _col(d):
    return (d >> 1) % 3


def _pack(s, b30=None, b31=None) -> np.ndarray:
    x = np.asarray(s, dtype=np.int64) & _IDX
    if b30 is not None:
        x = x | (np.asarray(b30, dtype=np.int64) << 30)
    if b31 is not None:
        x = x | (np.asarray(b31, dtype=np.int64) << 31)
    return x.astype(np.uint32).view(np.int32)


@numba.njit(cache=True)
def _cwbfs(offsets, nbr, col, outg, n, v_red):
    """``(order, label, count, even)``: the cwBFS of the red tree (int32 ids: the wood's ids are
    int32) and, for free, the depth parity ``D`` of Thm 6 (``even[u]``: depth of ``u`` even)."""
    label = np.full(n, -1, dtype=np.int32)
    order = np.empty(n, dtype=np.int32)
    even = np.zeros(n, dtype=np.bool_)
    label[v_red] = 0
    order[0] = v_red
    even[v_red] = True
    head = 0
    tail = 1
    while head < tail:
        v = order[head]
        head += 1
        # children: incoming red edges, cw (= reverse of the ccw rotation)
        for j in range(offsets[v + 1] - 1, offsets[v] - 1, -1):
            if col[j] == 0 and not outg[j]:
                x = nbr[j]
                label[x] = tail
                order[tail] = x
                even[x] = not even[v]
                tail += 1
    return order, label, tail, even


def cw_bfs_order(wood: SchnyderWood) -> np.ndarray:
    """cwBFS of the red tree (Sec. 2.3): ``order[i]`` = vertex with label ``i``. The children of a
    vertex get consecutive labels, cw around it starting after its outgoing black edge (at
    ``V_red``: ``V_black`` first, ``V_blue`` last)."""
    check_wood_arrays(wood, "cw_bfs_order")
    order, _, count, _ = _cwbfs(wood.offsets, wood.neighbors, wood.colour, wood.outgoing,
                                wood.num_vertices, wood.v_red)
    if count != wood.num_vertices:
        raise errors.StructureError(f"cwBFS reached {count} of {wood.num_vertices} vertices: the red "
                                    "tree does not span the mesh")
    return order.astype(np.int32)


def relabel_wood(wood: SchnyderWood, order: np.ndarray) -> SchnyderWood:
    """The same wood with vertex ``order[i]`` renamed ``i`` (rotation arrays permuted too);
    ``order`` must be a permutation of the vertices (``StructureError`` otherwise)."""
    import dataclasses

    check_wood_arrays(wood, "relabel_wood")
    n = wood.num_vertices
    o = np.asarray(order)
    if o.shape != (n,) or o.dtype.kind not in "iu":
        raise errors.StructureError(f"relabel_wood: order must be a permutation of the {n} vertices "
                                    f"(integers), got dtype {o.dtype} shape {o.shape}")
    seen = np.zeros(n, bool)
    seen[o[(o >= 0) & (o < n)]] = True
    if not seen.all():  # the right shape: say which vertex it lacks (the message gave the shape)
        raise errors.StructureError(f"relabel_wood: order must be a permutation of the {n} vertices; "
                                    f"vertex {int(np.argmin(seen))} is missing from it")
    order = o.astype(np.int64)
    label = np.empty(n, dtype=np.int64)
    label[order] = np.arange(n)
    out = np.full((n, 3), n, dtype=np.int32)
    has = wood.out < n
    relab = np.where(has, label[np.minimum(wood.out, n - 1)], n)
    out[:] = relab[order]
    deg = np.diff(wood.offsets)[order]
    offsets = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(deg, out=offsets[1:])
    src = np.repeat(wood.offsets[:-1][order] - offsets[:-1], deg) + np.arange(offsets[-1])
    return dataclasses.replace(
        wood, out=out, offsets=offsets, neighbors=label[wood.neighbors[src]].astype(np.int32),
        colour=wood.colour[src], outgoing=wood.outgoing[src],
        v_red=int(label[wood.v_red]), v_blue=int(label[wood.v_blue]), v_black=int(label[wood.v_black]),
        conquest_order=label[wood.conquest_order].astype(np.int32))


def _incoming(wood: SchnyderWood) -> np.ndarray:
    """``(n, 3)`` bool ``I_c[u]``: ``u`` has an incoming edge of colour ``c`` (a scatter of the
    ``out`` table, O(n))."""
    n = wood.num_vertices
    inc = np.zeros((n, 3), dtype=bool)
    for c in range(3):
        t = wood.out[:, c]
        inc[t[t < n], c] = True
    return inc


def face_slots(wood: SchnyderWood, lf: np.ndarray, rf: np.ndarray, inc: Optional[np.ndarray] = None):
    """Thm 7's face map from the ground truth: ``(F_blue, unused)``.

    Every face gets the slot of the first rule that applies: red (left of a red edge, slot of its
    source), black (left of a black edge, ``n +`` source), blue (``n + F_blue[source]``)."""
    check_wood_arrays(wood, "face_slots")
    n = wood.num_vertices
    lfc = np.where(lf >= 0, _col(lf), -1)
    vk, vr = wood.v_black, wood.v_red
    has_black = wood.out[:, BLACK] < n
    # black triangle of u: left face of u_black is not red (its LeftFront is not red, Thm 7)
    black_matched = has_black & (lfc[:, BLACK] == BLACK)
    # blue triangle of u: left face of u_blue neither red (LeftBack red) nor black (LeftFront black)
    has_blue = wood.out[:, BLUE] < n
    # LeftBack(u_blue) is red iff u has an incoming red edge (local rule: ccw after out blue)
    ired = (_incoming(wood) if inc is None else inc)[:, RED]
    blue_matched = has_blue & ~ired & (lfc[:, BLUE] == BLUE)
    blue_matched[vk] = False  # the left face of (V_black, V_blue) is the outer face, red slot V_blue
    return assign_face_slots(black_matched, blue_matched, vr)


def assign_face_slots(black_matched: np.ndarray, blue_matched: np.ndarray, v_red: int,
                      error=errors.StructureError, hint: str = ""):
    """Thm 7's slot assignment, ``(F_blue, unused)``, from which vertices have a black triangle
    (``black_matched``: it takes the black slot ``n + u``) and a blue one (``blue_matched``).

    A blue triangle stays in its own vertex's black slot when that slot is free
    (``F_blue[u] = u``); the others take the free slots in order, and each taken slot names its
    vertex back (``F_blue[u] = o``, ``F_blue[o] = u``). The slots left over (3 black ones) and the
    red slot of ``V_red`` are the four unused slots. Too few free slots means the inputs are no
    maximal Schnyder wood: ``error`` (with ``hint`` appended to the message).
    Shared by :func:`face_slots` (from the wood) and the codec's decoders (from the table bits)."""
    n = black_matched.shape[0]
    u = np.arange(n)
    avail = ~black_matched
    fb = np.zeros(n, dtype=np.int64)
    own = blue_matched & avail
    fb[own] = u[own]
    need = np.nonzero(blue_matched & ~avail)[0]
    free = np.nonzero(avail & ~blue_matched)[0]
    if free.size < need.size + 3:
        raise error(f"face map: {need.size} blue triangles but {free.size} free slots{hint}")
    fb[need] = free[: need.size]
    fb[free[: need.size]] = need
    unused = np.sort(np.concatenate([[v_red], n + free[need.size:]])).astype(np.int64)
    return fb.astype(np.int32), tuple(int(x) for x in unused)


# ---------------------------------------------------------------- fused table builder (numba)
# Kinds of the fused builder: the column layout of each structure's ``refs`` (see the classes).
_KIND_6N, _KIND_5N, _KIND_4N, _KIND_5N_O1 = 0, 1, 2, 3


@numba.njit(cache=True, inline="always")
def _pk(s, b30, b31):
    """One packed reference (Sec. 2.1, "References Encoding"): index in bits 0-29, service bits
    30 and 31 (as uint32; the host views the table as int32)."""
    return np.uint32((s & _IDX) | (np.int64(b30) << 30) | (np.int64(b31) << 31))


@numba.njit(cache=True)
def _cds_rows(offsets, nbr, col, outg, out, n, v_red, v_black, kind, label, even):
    """Every table row of a CDS in three linear passes, no search and no sort.

    Row ``i = label[u]`` holds vertex ``u`` of the wood (``label`` empty: no renumbering,
    ``i = u``) and every stored vertex index ``x`` is written as ``label[x]``: the cwBFS
    relabelling of Sec. 2.3 applied on the fly, without building a relabelled wood. Pass 1 scatters
    ``out`` into ``I_c``; pass 2 walks every rotation once and, at each edge ``x_c`` entering ``v``,
    reads its fronts around ``x``'s entry (``LeftFront`` = cw neighbour, ``RightFront`` = ccw
    neighbour, Sec. 2.2's ``q`` = two steps cw) into one packed word per edge -- sequential
    reads, scattered writes, which is faster at 1M+ vertices than searching ``u`` in the rotation
    of ``out[u, c]`` row by row; pass 3 writes the rows. The Thm 7 face map then pairs, in row
    order, each blue triangle whose own slot is taken with the next free black slot. Absent
    edges store 0 with clear service bits. ``even`` (CDS5n-O(1)'s depth parity ``D``, from
    :func:`_cwbfs`) may be empty for the other kinds.

    Returns ``(refs uint32 (n, k), F_blue int32 (n,), free int64 (n,), n_need, n_free, bad)``:
    ``free[n_need:n_free]`` are the unused black slots (rows), ``bad`` a vertex one of whose
    edges is missing from its target's rotation (-1: none).
    """
    width = 6 if kind == _KIND_6N else (4 if kind == _KIND_4N else 5)
    relab = label.shape[0] == n
    refs = np.zeros((n, width), dtype=np.uint32)
    fblue = np.zeros(n, dtype=np.int32)
    need = np.empty(n, dtype=np.int64)
    free = np.empty(n, dtype=np.int64)
    n_need = 0
    n_free = 0
    # I_c[u]: u has an incoming edge of colour c
    inc = np.zeros((n, 3), dtype=np.bool_)
    for x in range(n):
        for c in range(3):
            t = out[x, c]
            if t < n:
                inc[t, c] = True
    # fronts of every edge, read once in its target's rotation (sequential over v, no search):
    # F[x, c] = Source(LeftFront) | Source(RightFront) << 30 | C^left << 60 | C^right << 61 |
    # Color(LeftFront) << 62; Q[x] = q | ({v, q} black toward v) << 62 for red edges
    F = np.full((n, 3), _IDX, dtype=np.int64)  # _IDX: not written (indices are < 2^30 - 1)
    Q = np.zeros(n, dtype=np.int64)
    for v in range(n):
        a = offsets[v]
        d = offsets[v + 1] - a
        for k in range(d):
            j = a + k
            if outg[j]:
                continue
            x = nbr[j]
            c = col[j]
            # a dart (v, y) of v's rotation: source v if the edge leaves v, else y (reversed)
            jl = a + (k - 1) % d
            jr = a + (k + 1) % d
            y = v if outg[jl] else nbr[jl]
            ls = label[y] if relab else y
            y = v if outg[jr] else nbr[jr]
            rs = label[y] if relab else y
            F[x, c] = (np.int64(ls) | (np.int64(rs) << 30) | (np.int64(not outg[jl]) << 60)
                       | (np.int64(not outg[jr]) << 61) | (np.int64(col[jl]) << 62))
            if c == RED:
                j2 = a + (k - 2) % d
                y = v if outg[j2] else nbr[j2]
                qs = label[y] if relab else y
                Q[x] = np.int64(qs) | (np.int64(col[j2] == BLACK and not outg[j2]) << 62)
    has = np.zeros(3, dtype=np.bool_)
    lsrc = np.zeros(3, dtype=np.int64)   # Source(LeftFront(u_c))
    lsame = np.zeros(3, dtype=np.bool_)  # C^left: LeftFront has colour c
    lcol = np.zeros(3, dtype=np.int64)   # colour of LeftFront(u_c), -1 if absent
    rsrc = np.zeros(3, dtype=np.int64)   # Source(RightFront(u_c))
    rsame = np.zeros(3, dtype=np.bool_)  # C^right: RightFront has colour c
    tgt = np.zeros(3, dtype=np.int64)    # Target(u_c), 0 if absent
    status = np.zeros(n, dtype=np.int8)  # Thm 7 slot status of row i: 1 own, 2 need, 3 free
    for u in range(n):
        i = label[u] if relab else u
        for c in range(3):
            v = out[u, c]
            if v >= n:
                has[c] = False
                lsrc[c] = 0
                lsame[c] = False
                lcol[c] = -1
                rsrc[c] = 0
                rsame[c] = False
                tgt[c] = 0
                continue
            e = F[u, c]
            if (e & _IDX) == _IDX:
                return refs, fblue, free, n_need, n_free, u
            has[c] = True
            lsrc[c] = e & _IDX
            rsrc[c] = (e >> 30) & _IDX
            lsame[c] = (e >> 60) & 1
            rsame[c] = (e >> 61) & 1
            lcol[c] = (e >> 62) & 3
            tgt[c] = label[v] if relab else v
        q_src = Q[u] & _IDX
        q_black_in = (Q[u] >> 62) & 1 == 1
        if kind == _KIND_6N:
            for c in range(3):
                refs[i, 2 * c] = _pk(lsrc[c], lsame[c], inc[u, c])
                refs[i, 2 * c + 1] = _pk(rsrc[c], rsame[c], False)
        else:
            # S_red^toleft / C_red^toleft (Sec. 2.2): 0 red, 1 blue, 2 black (then S = q)
            s_tl = 0
            c_tl = 0
            if has[RED]:
                if lcol[RED] == RED:
                    s_tl = lsrc[RED]
                elif q_black_in:
                    s_tl = q_src
                    c_tl = 2
                else:
                    s_tl = lsrc[RED]
                    c_tl = 1
            # S_blue / C_blue (Sec. 2.2): LeftFront if I_red[u], else RightFront
            if inc[u, RED]:
                s_b = lsrc[BLUE]
                c_b = lsame[BLUE]
            else:
                s_b = rsrc[BLUE]
                c_b = rsame[BLUE]
            if kind == _KIND_5N:
                refs[i, 0] = _pk(s_tl, c_tl & 1, c_tl >> 1)
                refs[i, 1] = _pk(rsrc[RED], rsame[RED], inc[u, RED])
                refs[i, 2] = _pk(s_b, c_b, inc[u, BLUE])
                refs[i, 3] = _pk(lsrc[BLACK], lsame[BLACK], inc[u, BLACK])
                refs[i, 4] = _pk(rsrc[BLACK], rsame[BLACK], False)
            else:
                s0 = s_tl
                if kind == _KIND_5N_O1 and c_tl != 2:
                    s0 = tgt[RED]  # Thm 6: S_red^left = Target(u_red)
                refs[i, 0] = _pk(s0, c_tl & 1, c_tl >> 1)
                refs[i, 1] = _pk(s_b, c_b, inc[u, RED])
                refs[i, 2] = _pk(lsrc[BLACK], lsame[BLACK], inc[u, BLUE])
                refs[i, 3] = _pk(rsrc[BLACK], rsame[BLACK], inc[u, BLACK])
                if kind == _KIND_5N_O1:
                    # W (Thm 6): a leaf of the red tree stores Target(u_blue) if LeftFront(u_blue)
                    # is blue, else Target(u_black); an inner vertex Target(u_black) at even
                    # depth, Target(u_blue) at odd depth
                    if not inc[u, RED]:
                        w = tgt[BLUE] if lcol[BLUE] == BLUE else tgt[BLACK]
                    else:
                        w = tgt[BLACK] if even[u] else tgt[BLUE]
                    refs[i, 4] = _pk(w, even[u], False)
        # Thm 7 face map (see face_slots): black triangle of u is its left face of u_black
        # unless LeftFront(u_black) is red; blue triangle left of u_blue unless LeftBack is red
        # (I_red[u]) or LeftFront black; (V_black, V_blue) borders the outer face
        black_matched = has[BLACK] and lcol[BLACK] == BLACK
        blue_matched = has[BLUE] and not inc[u, RED] and lcol[BLUE] == BLUE and u != v_black
        if blue_matched:
            status[i] = 1 if not black_matched else 2
        elif not black_matched:
            status[i] = 3
    for i in range(n):
        st = status[i]
        if st == 1:
            fblue[i] = i
        elif st == 2:
            need[n_need] = i
            n_need += 1
        elif st == 3:
            free[n_free] = i
            n_free += 1
    for k in range(min(n_need, n_free)):
        fblue[need[k]] = free[k]
        fblue[free[k]] = need[k]
    return refs, fblue, free, n_need, n_free, -1


def _check_size(n: int) -> None:
    """Refuse ``n`` vertices past the 30-bit reference fields (Sec. 2.1) or past int32 dart ids
    (``6n``: from 357,913,942 vertices on, below 2^30), naming the limit."""
    if n >= _MAX_VERTICES:
        raise errors.UnsupportedTopologyError(f"{n} vertices: the packed references hold at most 2^30")
    check_id_space(f"CDS of {n:,} vertices (dart ids 2(3u + c) + r, 6n in all)", 6 * n)


def _build_rows(wood: SchnyderWood, kind: int, label=None, even=None):
    """``(refs int32 (n, k), F_blue, static fields)`` of a CDS from ``wood``, by
    :func:`_cds_rows`; ``label``: the cwBFS renumbering (Sec. 2.3), or ``None``; ``even``: the
    depth parity (CDS5n-O(1))."""
    n = wood.num_vertices
    _check_size(n)
    if label is None:
        label = np.empty(0, dtype=np.int32)
    if even is None:
        even = np.empty(0, dtype=np.bool_)
    refs, fblue, free, n_need, n_free, bad = _cds_rows(
        wood.offsets, wood.neighbors, wood.colour, wood.outgoing, wood.out, n, wood.v_red,
        wood.v_black, kind, label, even)
    if bad >= 0:
        raise errors.StructureError(f"Schnyder wood: an edge of vertex {bad} is missing from its "
                                    "target's rotation")
    if n_free < n_need + 3:
        raise errors.StructureError(f"face map: {n_need} blue triangles but {n_free} free slots")
    relab = (lambda x: int(label[x])) if label.size else int
    unused = (relab(wood.v_red),) + tuple(int(n + x) for x in free[n_need:n_free])
    static = dict(num_vertices=n, num_faces=2 * n - 4, v_red=relab(wood.v_red),
                  v_blue=relab(wood.v_blue), v_black=relab(wood.v_black), unused_slots=unused,
                  target_rounds=_target_rounds(wood))
    return refs.view(np.int32), fblue, static


def _checked_wood(cls, wood, check) -> None:
    """``from_wood``'s argument checks: ``check`` a bool and, when True, ``wood`` through
    :func:`~jaxcds.construct.schnyder.check_wood_arrays` (a hand-made wood out of range crashed
    the interpreter in the numba kernels). ``build_cds`` passes its own wood with
    ``check=False``."""
    from jaxcds._args import flag_arg

    if flag_arg(check, f"{cls.__name__}.from_wood: check"):
        check_wood_arrays(wood, f"{cls.__name__}.from_wood")


def _put(x: np.ndarray):
    """A host table as a device array: keeps the int32 dtype and, unlike ``jnp.asarray``,
    compiles nothing per new shape (30-150 ms per array on a small mesh; :mod:`jaxcds._arrays`)."""
    return to_device(x)


def _cwbfs_checked(wood: SchnyderWood):
    """``(order, label, even)`` of the cwBFS of the red tree (Sec. 2.3), see :func:`_cwbfs`."""
    order, label, count, even = _cwbfs(wood.offsets, wood.neighbors, wood.colour, wood.outgoing,
                                       wood.num_vertices, wood.v_red)
    if count != wood.num_vertices:
        raise errors.StructureError(f"cwBFS reached {count} of {wood.num_vertices} vertices: the red "
                                    "tree does not span the mesh")
    return order, label, even


@numba.njit(cache=True)
def _longest_fan(out, n):
    """The most edges of one colour entering one vertex (``out[u, c] == n``: absent edge)."""
    cnt = np.zeros(n + 1, dtype=np.int32)
    best = 0
    for c in range(3):
        cnt[:] = 0
        for u in range(n):
            cnt[out[u, c]] += 1
        for v in range(n):
            best = max(best, cnt[v])
    return best


def target_rounds(wood: SchnyderWood) -> int:
    """Pointer-jumping rounds that resolve every Target at once (:meth:`_CDS._targets_cols`):
    ``bit_length(F - 1)`` for ``F`` the longest incoming fan of one colour (exterior edges
    included). A chain of ``LeftFront`` steps stays in one fan, so it is at most ``F - 1`` steps
    long, and ``r`` rounds resolve every chain of at most ``2^r - 1`` steps."""
    check_wood_arrays(wood, "target_rounds")
    return _target_rounds(wood)


def _target_rounds(wood: SchnyderWood) -> int:
    """:func:`target_rounds` of a wood the builders made (unchecked)."""
    return int(max(_longest_fan(np.ascontiguousarray(wood.out), wood.num_vertices) - 1, 0)).bit_length()


@numba.njit(cache=True)
def _longest_chain(start):
    """``(steps, entry)``: the most pointer steps (``-(i + 1)``: "entry ``i``") from an entry to a
    resolved one; ``steps = -1`` when a chain runs out of range or never ends (``entry``: where).
    Every entry has at most one predecessor in a CDS (one ``LeftFront`` in a fan), so walking
    from the entries nobody points to visits each entry once: linear time."""
    m = start.shape[0]
    has_pred = np.zeros(m, dtype=np.bool_)
    for i in range(m):
        if start[i] < 0:
            j = -np.int64(start[i]) - 1
            if j >= m:
                return -1, i
            has_pred[j] = True
    best = 0
    visited = 0
    for i in range(m):
        if has_pred[i]:
            continue
        j, steps = i, 0
        while start[j] < 0:
            j = -np.int64(start[j]) - 1
            steps += 1
            if steps > m:
                return -1, i
        visited += steps + 1
        best = max(best, steps)
    if visited < m:  # entries on a cycle: nobody outside it points in
        for i in range(m):
            if has_pred[i] and start[i] < 0:
                return -1, i
    return best, -1


_jit_target_start = jax.jit(lambda s: s._target_start())


def with_target_rounds(structure):
    """``structure`` (any CDS, or a packed CDS union) with ``target_rounds`` measured on its own
    tables: the pointer steps of the longest ``LeftFront`` chain of :meth:`_CDS._target_start`
    (one jitted pass and one linear numba pass). For structures built without the Schnyder wood
    (the codec's decoders); the builders count the same rounds from the wood
    (:func:`target_rounds`).
    A chain that never ends (tables that are not a CDS) raises
    :class:`~jaxcds.errors.StructureError` naming the edge id."""
    import dataclasses

    steps, at = _longest_chain(np.asarray(_jit_target_start(structure)))
    if steps < 0:
        raise errors.StructureError(
            f"{type(structure).__name__}: the LeftFront chain from edge id {at} (3u + colour) does not "
            "end at a vertex: the tables are not those of a Schnyder wood")
    return dataclasses.replace(structure, target_rounds=int(steps).bit_length())


def jump_round(v):
    """One pointer-jumping round: every pending entry (``-(i + 1)``: "the value of entry ``i``")
    takes the value of the entry it points to.

    Written lean (``~v`` is ``-v - 1``; the index is never negative, so no wrap,
    :func:`~jaxcds.structures.base.take_nonnegative`): each elementwise operation counts in
    XLA:CPU's thread split (see :meth:`_CDS._target_start`), and the wrap test of a plain ``v[i]``
    took three more per entry than the round itself."""
    pend = v < 0
    return jnp.where(pend, _take(v, jnp.where(pend, ~v, 0)), v)


def _layout(n: int, by_colour: bool):
    """``(scale, step)``: edge ``u_c``'s entry of a ``(3n,)`` per-edge array is ``scale u + step c``
    -- ``c n + u`` by colour, else the edge id ``3u + c``."""
    return (1, n) if by_colour else (3, 1)


def _join(cols, by_colour: bool):
    """``k`` columns of ``(n,)`` (three colours; two sides for the per-dart tables) as one
    ``(k n,)`` array: one block after the other (``by_colour``), else interleaved, entry
    ``k u + c``."""
    return jnp.concatenate(cols) if by_colour else jnp.stack(cols, axis=1).reshape(-1)


def _padded(val, padded: bool):
    """``val`` and, if ``padded``, the zeros :func:`pointer_jump` would append (resolved entries)."""
    pad = split_padding(val.shape[0]) if padded else 0
    return jnp.concatenate([val, jnp.zeros((pad,), val.dtype)]) if pad else val


def pointer_jump(val, rounds: int):
    """``val`` with every pending entry resolved (see :func:`jump_round`): ``rounds`` rounds run
    two per trip of a static loop, then the data-driven loop (``any`` pending) as a safety net,
    which runs no trip when ``rounds`` suffice and every round when ``rounds`` is ``-1``.

    A long ``val`` whose length the thread count does not divide is padded with resolved entries
    first (:func:`~jaxcds.structures.base.split_padding`): split over two threads in unequal
    parts, a round ran as a scalar loop whose select on the gathered value became a branch,
    mispredicted on the pending entries' irregular pattern. On 2 cores that is every CDS with an
    odd vertex count: armadillo (43,243 vertices) cds6n / cds4n normals 1.91-2.02x -> 1.65-1.89x
    the face list, packed 300 meshes 1.34-1.55x -> 1.17-1.40x, in one-process races
    (``benchmarks/race_split_padding.py``, RESULTS.md). A length the thread count divides is
    left as it is (padding a 173K-vertex CDS to a multiple of 64 cost 0.06x)."""
    def two_rounds(_, v):
        # the first round's result written to memory (materialize_loop) and read by the second:
        # no loop-state copy (a round cannot write the buffer it gathers from) and no fusion of
        # the second round's gathers into the first (re-evaluated per element)
        w, = _materialize_loop((jump_round(v),))
        return jump_round(w)

    m = val.shape[0]
    val = _padded(val, True)
    pad = val.shape[0] - m
    rounds = max(rounds, 0)
    val = jax.lax.fori_loop(0, rounds // 2, two_rounds, val)
    if rounds % 2:
        val = jump_round(val)
    val = jax.lax.while_loop(lambda v: jnp.any(v < 0), jump_round, val)
    return val[:m] if pad else val


# ====================================================================================== base
def slot_blocks(num_vertices: int) -> int:
    """How many interleaved blocks the ``2n`` slot rows are read in (:func:`interleave_rows`).

    Many blocks break the runs of siblings that share a target (chains of dependent scatter-adds);
    past the caches, fewer blocks mean fewer concurrent streams for the prefetcher. Measured on
    the normals (ns per vertex, blocks 4 / 8 / 16, raced in turn, 2026-11-30): armadillo (43K)
    cds5n-o1 41 / 36 / 34; random 200K 48 / 42 / 45; 1M 96 / 93 / 99; 2.5M 98 / 104 / 112 (cds6n
    and cds4n alike)."""
    if num_vertices < 300_000:
        return 16
    return 8 if num_vertices < 2_000_000 else 4


def _ids(x):
    return jnp.asarray(x, dtype=jnp.int32)


def _dart(u, c, r=0):
    return (2 * (3 * u + c) + r).astype(jnp.int32)


def _fld(x):
    """vertex index of a packed reference"""
    return x & _IDX


def _bit30(x):
    """bit 30 of an int32 reference: shifted into the sign bit (two operations, where a shift, a
    mask and a compare took three: XLA:CPU's thread split counts each, see _CDS._target_start)"""
    return (x << 1) < 0


def _bit31(x):
    """bit 31 of an int32 reference: its sign"""
    return x < 0


def _parts(src, col, entering):
    """A dart ``2(3 src + col) + r`` kept in its parts ``(src, col, r)`` (int32 arrays): the
    whole-mesh routes read the source and the edge id of every ``LeftFront`` off the parts
    (``_dart`` packs them), where decoding a packed dart divides by 3 -- kernels of their own
    on XLA:CPU (division is not duplicated into consumers). ``r`` stays a bool array when given
    one (a select reads it as it is; converted, each reader paid a convert and a compare)."""
    i32 = jnp.int32
    entering = jnp.asarray(entering)
    return (jnp.asarray(src, i32), jnp.asarray(col, i32),
            entering if entering.dtype == bool else entering.astype(i32))


_WORD_VERTICES = 1 << 28  # below: a LeftFront fits one int32 word (_lf_word)
# ... and from here up the word is worth its pass: under it the three word kernels of the one-trip
# loop cost as much as the consumers' re-reads of the rows or more. Normals x the face list, words
# against parts, raced in turn (benchmarks/race_lf_words.py, Intel Xeon host, 2026-12-02, after
# the lean pointer-jumping start): cheburashka (6.7K) cds6n 1.76 / 1.42x, bumpy-cube (20K) 1.32 /
# 1.30x, armadillo (43K) 1.72 / 1.69x, random 200K 1.12 / 1.04x, 1M 1.24 / 1.16x, packed 1,000
# meshes (2.7M) 1.39 / 1.36x, random 5M 1.29 / 1.29x, packed 3,000 meshes (8.2M) 1.39 / 2.45x
# (medians; the parts' fastest run 1.46x); at 10,000 meshes (27.5M, Zen 3 host, 2026-11-30) the
# parts ran 1.9x the words. Was 8,192 (Zen 3 host, 2026-12-01: bunny to fandisk 0.83-1.0x the
# words with parts, 20K 1.0x)
_WORD_MIN_VERTICES = 1 << 22


def _lf_word(p):
    """A dart in parts ``(src, col, r)`` as one int32 word ``src << 3 | col << 1 | r`` (``src <
    2^28``), decoded by shifts (:func:`_lf_unword`), where the dart ``2(3 src + col) + r`` needs
    a division by 3. The whole-mesh slot rows materialise the three LeftFronts of every vertex
    so (:meth:`_CDS._slot_faces`). Normals x the face list, raced in one process against
    materialised darts decoded by division (2026-11-30): armadillo cds6n 2.13 -> 1.83, cds4n
    2.03 -> 1.65; packed 10,000 meshes (27.5M vertices) cds6n 1.96 -> 1.59, cds4n 1.79 -> 1.80;
    reading the parts off the rows in every consumer instead (no word) was as fast on small
    meshes and 1.9x at 10,000 meshes."""
    # r may be a bool (_parts): converted explicitly for strict dtype promotion (sweep 52c)
    return (p[0] << 3) | (p[1] << 1) | jnp.asarray(p[2], jnp.int32)


def _lf_unword(q):
    return q >> 3, (q >> 1) & 3, q & 1


class _RowColumns:
    """Row ``i`` of ``refs`` read column by column: ``row[..., k]`` is ``refs[i, k]`` gathered
    on its own, so a case analysis asks only the columns it uses, each one scalar gather.

    Why: the batched CDS5n-O(1) Target's first read, a gather of whole ``(5,)`` rows, was its
    slowest pass; four scalar gathers of the columns the plan reads (they hit the row's one
    cache line) ran it faster in races in turn (``halfedge`` / row gather / columns, ns per
    query, 10M random darts, 2026-12-02): 100K vertices 4.9 / 13.8 / 9.4 (min of 15 rounds), 2.5M
    24.1 / 58.4 / 41.2 (9 rounds), 3.5K 2.9 / 9.3 / 9.6 (in L1 it makes no difference). The
    second read keeps the row gather (columns there: 3.5K and 100K slower)."""

    def __init__(self, refs, i):
        # flat ids: ``refs[i, k]`` as a 2-D gather ran slower than ``flat[w i + k]`` (100K: 15.3
        # against 9.5 ns per query)
        self.flat, self.base = refs.reshape(-1), refs.shape[1] * i

    def __getitem__(self, key):
        return self.flat[self.base + key[-1]]


def _psel(cond, a, b):
    """``jnp.where`` over two darts in parts (a bool ``r`` meeting an int32 one is converted
    here, as default promotion would: users may run with strict dtype promotion)."""
    return tuple(jnp.where(cond, *_same_dtype(x, y)) for x, y in zip(a, b))


def _same_dtype(x, y):
    """``x, y`` with a bool one converted to the other's integer dtype."""
    x, y = jnp.asarray(x), jnp.asarray(y)
    if x.dtype == bool and y.dtype != bool:
        return x.astype(y.dtype), y
    if y.dtype == bool and x.dtype != bool:
        return x, y.astype(x.dtype)
    return x, y


class _CDS(MeshStructure):
    """Operators shared by the CDS family: everything is written from three primitives that each
    structure implements with its own tables -- ``_lf(e)`` (dart ``(v, w)`` of ``LeftFront(e)``),
    ``_rf(e)`` (dart ``(z, v)`` of ``RightFront(e)``) and ``_inc(u, c)`` (``I_c[u]``) -- following
    the proof of Thm 2 for ``LeftBack`` / ``RightBack``."""

    num_vertices: int
    num_faces: int
    v_red: int
    v_blue: int
    v_black: int
    unused_slots: tuple
    boundaries_closed: bool
    target_rounds: int

    # ---- subclass primitives
    def _lf(self, e):
        raise NotImplementedError

    def _rf(self, e):
        raise NotImplementedError

    def _inc(self, u, c):
        raise NotImplementedError

    def _edge_target(self, e):
        return self._target_walk(e)

    # _lf_parts_cols reads other rows (a gather: Thm 4's S_red^toleft black case)
    _gathered_lf = True
    # _targets_cols is a loop-free expression XLA would fuse into its consumers (Thm 6)
    _fusible_targets = False
    # several passes over a query batch: chunked on CPU (base._chunked_query; the Front/Back
    # routes measured 1.2-1.4x slower by chunks, twin and edge_of_vertex 3-5x)
    chunked_queries = frozenset({"target", "origin", "source", "face", "face_left", "face_right"})
    # eager calls as one jitted program per power-of-two size (base._bucketed): Thm 2's O(d)
    # walks are while_loops compiled again on every eager call. 2,000-vertex cds5n, 12 eager
    # calls of new sizes 8.7 -> 2.8 s, a warm call 193 -> 0.7 ms (stop 43)
    eager_buckets = True
    jit_when_eager = frozenset(("face_vertices", "face_vertices_padded", "dart_faces", "vertex_degrees",
                                "target_table", "all_edge_targets"))
    # a batch of at least 1/16 of the dart ids (3n/8 darts): Target/Origin from every edge's
    # Target, computed once per call by pointer jumping (~5 ns per edge) instead of Thm 2's O(d)
    # walk per query (120-230 ns); at 1/16 the table route took 0.30x the per-query route's time
    # at 2.5M vertices, 1/32 0.49x (base.MeshStructure.table_queries; RESULTS.md, "stop 33:
    # batched Target by a table"). Transient: 24 bytes per vertex (the structure's own size).
    # Face / Face_left / Face_right likewise from every dart's face (dart_faces: the four
    # Front/Back tables, then the slot rules, 5-7 ns per dart at 100K vertices) from a batch of
    # 1/8 of the dart ids (CDS6n: 1/2): at 100K vertices the table took 0.35x the per-query
    # route's time at 1/4 (cds5n), 1.09x at 1/10; at 2.5M 0.66-0.69x at 1/10 (RESULTS.md,
    # "stop 35: batched Face_left, Next and Prev by tables"). Transient: 132-156 bytes per vertex.
    # Next / Prev (and the Front / Back aliases) from every dart's (_step_table) from 1/2 of the
    # dart ids (Next) and 1/4 (Prev): at 100K vertices the table took 0.57x (cds5n Next) and
    # 0.27x (Prev) the per-query route's time at 1/2, 1.10x / 0.42x at 1/4; at 2.5M 0.49-0.57x /
    # 0.26-0.30x at 1/4 (RESULTS.md, "stop 35: batched Face_left, Next and Prev by tables")
    table_queries = {"target": "_target_by_table", "origin": "_origin_by_table",
                     "face": "_face_by_table", "face_left": "_face_by_table",
                     "face_right": "_face_right_by_table",
                     "next": "_next_by_table", "left_front": "_next_by_table",
                     "prev": "_prev_by_table", "left_back": "_prev_by_table",
                     "right_front": "_right_front_by_table", "right_back": "_right_back_by_table"}
    table_batch_ratio = {"target": 1 / 16, "origin": 1 / 16,
                         "face": 1 / 8, "face_left": 1 / 8, "face_right": 1 / 8,
                         "next": 1 / 2, "left_front": 1 / 2, "right_back": 1 / 2,
                         "prev": 1 / 4, "left_back": 1 / 4, "right_front": 1 / 4}

    # ---- exterior darts
    @property
    def _e_br(self):  # (V_blue, V_red) red
        return 3 * self.v_blue + RED

    @property
    def _e_kr(self):  # (V_black, V_red) red
        return 3 * self.v_black + RED

    @property
    def _e_kb(self):  # (V_black, V_blue) blue
        return 3 * self.v_black + BLUE

    @property
    def _d0(self):
        return 2 * self._e_br

    @property
    def _d1(self):
        return 2 * self._e_kr + 1

    @property
    def _d2(self):
        return 2 * self._e_kb

    # ---- the four front/back routes, edge -> dart
    def left_front_edge(self, e: Int) -> Int:
        """``LeftFront(u_c)`` for edge ids ``e = 3u + c``: the dart ``(v, w)``."""
        e = _ids(e)
        d = self._lf(e)
        # _EXTERIOR: the left faces of (V_black, V_blue) and (V_blue, V_red) are the outer face:
        # LeftFront = (V_blue, V_red), resp. (V_red, V_black) (cwBFS: V_blue is V_red's last child)
        d = jnp.where(e == self._e_br, self._d1, d)
        return jnp.where(e == self._e_kb, self._d0, d).astype(jnp.int32)

    def right_front_edge(self, e: Int) -> Int:
        """``RightFront(u_c)``: the dart ``(z, v)``."""
        e = _ids(e)
        d = self._rf(e)
        # _EXTERIOR: the right face of (V_black, V_red) is the outer face: RightFront = (V_blue, V_red)
        return jnp.where(e == self._e_kr, self._d0, d).astype(jnp.int32)

    def left_back_edge(self, e: Int) -> Int:
        """``LeftBack(u_c)``: the dart ``(w, u)`` -- Thm 2, three cases."""
        e = _ids(e)
        # in memory before Case 3 reads through it (materialize_loop: fused, the second
        # LeftFront would re-evaluate the first in every one of its reads)
        lf, = _materialize_loop((self.left_front_edge(e),))
        return self._left_back_from(e, lf, self.left_front_edge(lf >> 1))

    def _left_back_from(self, e, lf, lf_of_lf):
        """:meth:`left_back_edge` given ``lf = LeftFront(e)`` and ``lf_of_lf =
        LeftFront(lf >> 1)`` (read per query, or from a whole-mesh table: :meth:`_left_sides`)."""
        u, c = e // 3, e % 3
        cn, cp = (c + 1) % 3, (c + 2) % 3
        # Case 1: no incoming edge of colour prev(c) at u: LeftBack is u_next(c), toward w
        case1 = _dart(u, cn, 1)
        # Case 2: LeftFront has colour c (w -> v): LeftBack is w_prev(c), w = Source(LeftFront)
        case2 = _dart(_src(lf), cp, 0)
        # Case 3: LeftFront is v_next(c) (v -> w): LeftBack = LeftFront(LeftFront(e))
        case3 = lf_of_lf
        d = jnp.where(~self._inc(u, cp), case1, jnp.where((lf & 1) == 1, case2, case3))
        # _EXTERIOR: LeftBack((V_blue, V_red)) = (V_black, V_blue); LeftBack((V_black, V_blue)) = (V_red, V_black)
        d = jnp.where(e == self._e_br, self._d2, jnp.where(e == self._e_kb, self._d1, d))
        return d.astype(jnp.int32)

    def right_back_edge(self, e: Int) -> Int:
        """``RightBack(u_c)``: the dart ``(u, z)`` -- Thm 2 by symmetry."""
        e = _ids(e)
        rf, = _materialize_loop((self.right_front_edge(e),))  # as in left_back_edge
        return self._right_back_from(e, rf, self.right_front_edge(rf >> 1))

    def _right_back_from(self, e, rf, rf_of_rf):
        """:meth:`right_back_edge` given ``rf = RightFront(e)`` and ``rf_of_rf =
        RightFront(rf >> 1)``."""
        u, c = e // 3, e % 3
        cn, cp = (c + 1) % 3, (c + 2) % 3
        # Case 1: no incoming edge of colour next(c) at u: RightBack is u_prev(c)
        case1 = _dart(u, cp, 0)
        # Case 2: RightFront has colour c (z -> v): RightBack is z_next(c) entering u, reversed
        case2 = _dart(_src(rf), cn, 1)
        # Case 3: RightFront is v_prev(c) (v -> z): RightBack = RightFront(RightFront(e))
        case3 = rf_of_rf
        d = jnp.where(~self._inc(u, cn), case1, jnp.where((rf & 1) == 0, case2, case3))
        # _EXTERIOR: RightBack((V_black, V_red)) = (V_black, V_blue)
        d = jnp.where(e == self._e_kr, self._d2, d)
        return d.astype(jnp.int32)

    def _left_sides(self, e):
        """``(LeftFront, LeftBack)`` of the edge ids ``e = arange(3n)``: the Front in memory,
        the Back's Case 3 (a Front of a Front) read from it instead of computed again."""
        lf, = _materialize_loop((self.left_front_edge(e),))
        return lf, self._left_back_from(e, lf, lf.at[lf >> 1].get(mode="clip"))

    def _right_sides(self, e):
        """``(RightFront, RightBack)`` of the edge ids ``e = arange(3n)``, as :meth:`_left_sides`."""
        rf, = _materialize_loop((self.right_front_edge(e),))
        return rf, self._right_back_from(e, rf, rf.at[rf >> 1].get(mode="clip"))

    # ---- Target
    def _target_walk(self, e):
        """Thm 2 "Operator Target": turn cw around ``v`` through the incoming edges of colour
        ``c`` (``LeftFront`` of colour ``c``) until ``LeftFront`` leaves ``v``: its source is
        ``v``. O(d): a ``while_loop`` whose lanes stop independently (masked)."""
        e = _ids(e)
        vr, vb = self.v_red, self.v_blue

        def stop(cur):
            lf = self._lf(cur)
            fin = (lf & 1) == 0
            t = _src(lf)
            # _EXTERIOR: walking cw around V_red ends at (V_blue, V_red); around V_blue at (V_black, V_blue)
            t = jnp.where(cur == self._e_br, vr, jnp.where(cur == self._e_kb, vb, t))
            fin = fin | (cur == self._e_br) | (cur == self._e_kb)
            return fin, t, lf >> 1

        # An id that is not an edge (a hole of the id space, or out of range) answers
        # ``num_vertices`` at once: its walk would never meet a stop and the loop would not end.
        valid = (e >= 0) & (e < 3 * self.num_vertices) & self.edge_valid(jnp.clip(e, 0, 3 * self.num_vertices - 1))
        e = jnp.where(valid, e, 0)
        fin0, t0, nxt0 = stop(e)
        fin0 = fin0 | ~valid
        t0 = jnp.where(valid, t0, self.num_vertices)
        limit = self.num_vertices + 3  # no degree exceeds n - 1: a safety net, never reached

        def cond(state):
            return jnp.any(~state[2]) & (state[3] < limit)

        def body(state):
            cur, t, done, k = state
            fin, t2, nxt = stop(cur)
            t = jnp.where(done, t, t2)
            newdone = done | fin
            cur = jnp.where(newdone, cur, nxt)
            return cur, t, newdone, k + 1

        cur0 = jnp.where(fin0, e, nxt0)
        _, t, _, _ = jax.lax.while_loop(cond, body, (cur0, t0, fin0, jnp.int32(0)))
        return t.astype(jnp.int32)

    def _lf_parts_cols(self):
        """``(LeftFront(u_red), LeftFront(u_blue), LeftFront(u_black))`` for every ``u`` at once,
        each a dart in parts ``(src, col, r)`` (:func:`_parts`), as the tables store them (no
        exterior patch), read column by column (no gather)."""
        raise NotImplementedError

    def _valid_cols(self):
        """``edge_valid(3u + c)`` for every ``u``, per colour (three ``(n,)`` masks)."""
        u = jnp.arange(self.num_vertices, dtype=jnp.int32)
        return (u != self.v_red,
                (u != self.v_red) & (u != self.v_blue),
                (u != self.v_red) & (u != self.v_blue) & (u != self.v_black))

    def _target_start(self, lfs=None, padded: bool = False, by_colour: bool = False):
        """``(3n,)`` pointer-jumping start of :meth:`_targets_cols`, edge id ``3u + c``: the
        target where ``LeftFront(u_c)`` leaves it (or the edge is absent), else ``-(w_c + 1)``
        for the edge ``w_c`` whose target it shares (``lfs``: :meth:`_lf_parts_cols`; a
        ``LeftFront`` entering the target is ``w_c``, of colour ``c``, Thm 2).

        ``by_colour``: entry ``c n + u`` for edge ``u_c`` instead (three blocks of ``n``, the
        pointers ``-(c n + w + 1)`` likewise): the three columns are then written one after the
        other, where interleaved (``3u + c``) each entry paid an index division by 3 and a
        select among the columns (armadillo: 197 us, the slowest kernel of the normals).

        With the roots known statically (a single mesh) the exterior and absent edges -- six
        ids -- are patched after one lean pass rather than tested for at every vertex: XLA:CPU
        splits a kernel over its threads once its flops exceed the bytes it moves
        (``ParallelTaskAssigner``, see :func:`~jaxcds.structures.base.computed_in_loop`), and
        the root tests, nine compares and selects per vertex, tipped this one over; on 2 cores
        a split kernel waits for the second thread (bunny: 30 us against 3).

        ``padded``: followed by the entries :func:`pointer_jump` pads with (resolved zeros, see
        :func:`~jaxcds.structures.base.split_padding`), written in the same pass: padded after,
        the whole array was copied once more (armadillo: 150 us of a 2.8 ms call)."""
        n = self.num_vertices
        lfs = self._lf_parts_cols() if lfs is None else lfs
        if not isinstance(self.v_red, int):  # a packed batch's view: per-vertex roots (arrays)
            return _padded(self._target_start_masked(lfs, by_colour), padded)
        scale, step = _layout(n, by_colour)

        def at(u, c):  # entry of edge u_c
            return scale * u + step * c

        # pointer to edge w_c: -(at(w, c) + 1), written src * -scale - (step c + 1): a multiply
        # and an add per entry (the thread split counts them)
        cols = [jnp.where(r if r.dtype == bool else r != 0, src * -scale - (step * c + 1), src)
                for c, (src, _, r) in enumerate(lfs)]
        start = _padded(_join(cols, by_colour), padded)
        ids, vals = [], []
        # absent edges (Definition 1: V_red has no outgoing edge, V_blue only its red one, V_black
        # no black one): any resolved value, here the stored source (garbage, as documented)
        for u0, c in ((self.v_red, RED), (self.v_red, BLUE), (self.v_red, BLACK),
                      (self.v_blue, BLUE), (self.v_blue, BLACK), (self.v_black, BLACK)):
            ids.append(at(u0, c))
            vals.append(lfs[c][0][u0])
        # _EXTERIOR: the walk around V_red ends at (V_blue, V_red), around V_blue at (V_black, V_blue)
        ids += [at(self.v_blue, RED), at(self.v_black, BLUE)]
        vals += [jnp.int32(self.v_red), jnp.int32(self.v_blue)]
        return start.at[np.asarray(ids, np.int32)].set(jnp.stack(vals).astype(start.dtype))

    def _target_start_masked(self, lfs, by_colour: bool = False):
        """:meth:`_target_start` with the root tests at every vertex (roots as arrays)."""
        n = self.num_vertices
        u = jnp.arange(n, dtype=jnp.int32)
        scale, step = _layout(n, by_colour)
        vals = []
        for c, ((src, col, r), ok) in enumerate(zip(lfs, self._valid_cols())):
            leaving = r.astype(jnp.int32) == 0  # r may be a bool: explicit for strict promotion
            val = jnp.where(leaving | ~ok, src, -(scale * src + step * col) - 1)
            # _EXTERIOR: the walk around V_red ends at (V_blue, V_red), around V_blue at (V_black, V_blue)
            if c == RED:
                val = jnp.where(u == self.v_blue, self.v_red, val)
            if c == BLUE:
                val = jnp.where(u == self.v_black, self.v_blue, val)
            vals.append(val)
        return _join(vals, by_colour)

    def _targets_cols(self, lfs=None):
        """``Target(u_c)`` of every edge, per colour (three ``(n,)`` arrays, garbage where the
        edge is absent): Thm 2's walk, all edges at once by pointer jumping.

        ``LeftFront(u_c)`` leaving the target ``v`` gives ``v`` (its source); entering ``v`` (the
        edge ``w_c``), ``Target(u_c) = Target(w_c)``. Every walk is a chain through one incoming
        fan of ``v``; pointer jumping resolves all chains in ``ceil(log2(longest fan))`` rounds of
        one gather each (state: the target where known, else ``-(edge + 1)`` of the edge whose
        target it equals).

        The builders store that round count (``target_rounds``, O(1) metadata, see
        :func:`target_rounds`): the rounds then run two per trip of a loop of static length, with
        no test for pending entries between them, each round reading the other's buffer. On
        XLA:CPU (2 cores) the test -- a compare and a reduction, two kernels per round -- and the
        copy of the loop state that a one-round body needs (a round cannot overwrite the buffer
        it gathers from) cost as much as the gather itself on meshes under 1M vertices. The
        data-driven loop follows as a safety net: it runs no round when ``target_rounds`` is
        right, and all of them when it is ``-1`` (a structure built without it)."""
        n = self.num_vertices
        start = self._target_start(lfs, padded=True, by_colour=True)
        t = pointer_jump(start, self.target_rounds)[:3 * n].reshape(3, n)
        return t[0], t[1], t[2]

    def all_edge_targets(self) -> Int:
        """``(3n,)`` ``Target(u_c)`` of every edge id ``3u + c`` (garbage on absent ids)."""
        return _join(self._targets_cols(), False).astype(jnp.int32)

    def target_table(self) -> Int:
        """``(num_darts,)`` Target of every dart id (garbage on invalid ids), for whole-mesh loops
        that ask Target of the darts around every vertex (the gather normals): one pass of
        :meth:`all_edge_targets` (pointer jumping, O(n log d)) instead of Thm 2's O(d) walk per
        dart and turn, which made such a loop O(n d^2)."""
        d = jnp.arange(self.num_darts, dtype=jnp.int32)
        e = d >> 1
        return jnp.where((d & 1) == 0, self.all_edge_targets()[e], e // 3).astype(jnp.int32)

    def _end_by_table(self, d, want_target: bool):
        """Target (``want_target``) or Origin of a batch of darts as large as a fraction of the
        mesh: every edge's Target once (:meth:`all_edge_targets`, a ``(3n,)`` temporary), then
        one gather per dart (``MeshStructure.table_queries``). Ids out of range read a clamped
        entry (garbage, as the per-query route gives them; never out of bounds)."""
        d = _ids(d)
        e = d >> 1
        # written to memory first: fused into the gather, Thm 6's loop-free targets ran once per
        # query, not once per edge (100K vertices, 10M darts: 12.7 ns per query against 7.7 for
        # the per-query route)
        table = self._edge_target_table()
        t = table.at[e].get(mode="clip")
        own = ((d & 1) == 0) != want_target  # the answer is the edge's source u = e // 3
        return jnp.where(own, jax.lax.div(e, jnp.int32(3)), t).astype(jnp.int32)

    def _edge_target_table(self) -> Int:
        """``(3n,)`` :meth:`all_edge_targets`, in memory (for :meth:`_end_by_table`)."""
        (table,) = _materialize_loop((self.all_edge_targets(),))
        return table

    @_base.by_table
    def _target_by_table(self, d: Int) -> Int:
        return self._end_by_table(d, True)

    @_base.by_table
    def _origin_by_table(self, d: Int) -> Int:
        return self._end_by_table(d, False)

    # ---- whole mesh: faces and degrees in O(1) per face / edge (Thm 7)
    def _slot_faces(self):
        """``(2n, 3)``: the vertices, ccw, of the face in every Thm 7 slot, in O(1) per face from
        the face map (no navigation operator is called); garbage in the four unused slots:

        * slot ``u`` (red triangle of ``u``, left of ``u_red``): ``(u, Target(u_red), w)`` with
          ``w`` the origin of ``LeftFront(u_red)``: its source if it enters the target
          (``w_red``), else ``Target(LeftFront)``;
        * slot ``n + b``: ``b``'s black triangle when ``LeftFront(b_black)`` is black (``w_black``
          entering: ``(b, Target(b_black), w)``), else the blue triangle of ``o = F_blue[b]``,
          whose ``LeftFront(o_blue)`` is blue (``w_blue`` entering): ``(o, Target(o_blue), w)``.
        """
        n = self.num_vertices
        u = jnp.arange(n, dtype=jnp.int32)
        lf_r, lf_b, lf_k = self._lf_parts_cols()
        if _WORD_MIN_VERTICES <= n < _WORD_VERTICES:
            # the three LeftFronts written once, each as one word (src, col, r by shifts): read
            # again from the rows, the slot rows' gathers (F_blue, t_b) re-read the tables, and a
            # packed dart would need a division by 3 per read (see _lf_word)
            qs = _materialize_loop(tuple(_lf_word(p) for p in (lf_r, lf_b, lf_k)))
            lf_r, lf_b, lf_k = (_lf_unword(q) for q in qs)
        elif self._gathered_lf:  # materialised once: XLA would otherwise re-evaluate the red source,
            src_r, = _materialize_loop((lf_r[0],))  # a table gather, in every gather that reads it
            lf_r = (src_r,) + lf_r[1:]
        # the targets' start patches the exterior itself (_target_start): the rows as stored
        t_r, t_b, t_k = self._targets_cols((lf_r, lf_b, lf_k))
        # _EXTERIOR: LeftFront((V_blue, V_red)) = (V_red, V_black): the red slot of V_blue is the
        # outer face (V_blue, V_red, V_black)
        lf_r = _psel(u == self.v_blue, _parts(self.v_black, RED, 1), lf_r)  # self._d1, in parts
        if self._fusible_targets:  # a while_loop's result is in memory already
            t_r, t_b, t_k = _materialize_loop((t_r, t_b, t_k))
        # red triangles: w = Source(LeftFront) when it is w_red entering v, else Target(v_blue)
        # r is a bool or an int32 (_parts): converted explicitly for strict dtype promotion
        entering_r = lf_r[2].astype(jnp.int32) == 1
        w_r = jnp.where(entering_r, lf_r[0], _take(t_b, jnp.where(entering_r, 0, lf_r[0])))
        red = jnp.stack([u, t_r, w_r], axis=1)
        # black triangle of b (LeftFront(b_black) black, entering) or blue triangle of F_blue[b]:
        # the blue triangle of every vertex as one (n, 3) table, so F_blue costs one row gather
        black_matched = (lf_k[2].astype(jnp.int32) == 1) & self._valid_cols()[BLACK]
        blue_o = _take(jnp.stack([u, t_b, lf_b[0]], axis=1), self.F_blue)
        black = jnp.stack([u, t_k, lf_k[0]], axis=1)
        kb = jnp.where(black_matched[:, None], black, blue_o)
        return jnp.concatenate([red, kb], axis=0)

    def _slot_valid(self):
        """``(2n,)`` bool: the Thm 7 slot holds a face (all but the four unused ones)."""
        i = jnp.arange(2 * self.num_vertices, dtype=jnp.int32)
        ok = jnp.ones(i.shape, bool)
        for x in self.unused_slots:
            ok = ok & (i != x)
        return ok

    def face_vertices(self) -> Int:
        """``(F, 3)`` vertices of every face, ccw, row ``f`` = face id ``f``: the Thm 7 slots
        (:meth:`_slot_faces`, O(1) per face) with the four unused ones (static) cut out."""
        slots = self._slot_faces()
        pieces, lo = [], 0
        for x in self.unused_slots:  # sorted, static
            pieces.append(slots[lo:x])
            lo = x + 1
        pieces.append(slots[lo:])
        return jnp.concatenate(pieces, axis=0).astype(jnp.int32)

    def face_vertices_padded(self):
        """The ``2n`` Thm 7 slots (:meth:`_slot_faces`), the four unused ones masked and set to
        vertex 0, read in interleaved blocks: no compaction copy for whole-mesh sums (normals)."""
        valid = self._slot_valid()
        # rows in interleaved blocks: siblings (consecutive labels) share a target, a chain of
        # dependent scatter-adds in slot order (base.interleave_rows)
        faces = jnp.where(valid[:, None], self._slot_faces(), 0).astype(jnp.int32)
        b = slot_blocks(self.num_vertices)
        return interleave_rows(faces, b), interleave_rows(valid, b)

    def dummy_vertex_mask(self):
        """The vertices of ``dummy_ids`` (holes closed by the builder, Sec. 4.5) as a mask."""
        if self.dummy_ids is None:
            return None
        mask = jnp.zeros((self.num_vertices,), bool)
        return mask.at[self.dummy_ids].set(True, mode="drop")

    def vertex_degrees(self) -> Int:
        """``(n,)`` degrees: the edges leaving ``u`` (3 for inner vertices, Definition 1) plus the
        edges entering it, counted at every target (one ``segment_sum`` over the ``3n`` edges).

        With ``dummy_ids`` (holes closed, Sec. 4.5) an edge with a dummy end is not counted: the
        input mesh's degrees, 0 for a dummy vertex. Every edge is one ``u_c``, so no edge is
        counted twice either way."""
        n = self.num_vertices
        ok = jnp.stack(self._valid_cols(), axis=1)
        t = jnp.stack(self._targets_cols(), axis=1)
        dummy = self.dummy_vertex_mask()
        if dummy is not None:
            ok = ok & ~dummy[:, None] & ~dummy[jnp.where(ok, t, 0)]
        inc = jax.ops.segment_sum(ok.reshape(-1).astype(jnp.int32), jnp.where(ok, t, n).reshape(-1),
                                  num_segments=n + 1)[:n]
        return (jnp.sum(ok, axis=1, dtype=jnp.int32) + inc).astype(jnp.int32)

    # ---- protocol core
    @property
    def num_darts(self) -> int:
        return 6 * self.num_vertices

    def edge_valid(self, e: Int) -> Int:
        """True where edge id ``e = 3u + c`` names an edge (``u_c`` exists)."""
        e = _ids(e)
        u, c = e // 3, e % 3
        ok = (e >= 0) & (e < 3 * self.num_vertices)
        roots = ((u == self.v_red)
                 | ((u == self.v_blue) & (c != RED))
                 | ((u == self.v_black) & (c == BLACK)))
        return ok & ~roots

    def dart_valid(self, d: Int) -> Int:
        d = _ids(d)
        return (d >= 0) & self.edge_valid(d >> 1)

    def edge_target(self, e: Int) -> Int:
        """``Target(u_c)`` for edge ids."""
        return self._edge_target(_ids(e))

    def origin(self, d: Int) -> Int:
        d = _ids(d)
        e = d >> 1
        return jnp.where((d & 1) == 0, e // 3, self._edge_target_of(e, (d & 1) == 1)).astype(jnp.int32)

    def target(self, d: Int) -> Int:
        d = _ids(d)
        e = d >> 1
        return jnp.where((d & 1) == 0, self._edge_target_of(e, (d & 1) == 0), e // 3).astype(jnp.int32)

    def _edge_target_of(self, e, need):
        """``Target(e)`` where ``need`` (unspecified elsewhere). A select computes both of its
        sides: with Thm 2's walk every lane walked, so the reversed darts around a hub (whose
        answer is their edge's source) each walked the hub's whole fan; one_ring of a hub of
        degree 4,000 took 6-7 s on cds6n (sweep 17a). The lanes that do not need it are handed
        an id that is no edge, whose walk stops at once (:meth:`_target_walk`)."""
        if self._target_walks:
            e = jnp.where(need, e, -1)
        return self._edge_target(e)

    @property
    def _target_walks(self) -> bool:
        """Whether ``_edge_target`` is Thm 2's O(d) walk (CDS6n/5n/4n), not an O(1) route
        (CDS5n-O(1), Thm 6)."""
        return type(self)._edge_target is _CDS._edge_target

    def twin(self, d: Int) -> Int:
        return _ids(d) ^ 1

    def next(self, d: Int) -> Int:
        d = _ids(d)
        e = d >> 1
        return jnp.where((d & 1) == 0, self.left_front_edge(e), self.right_back_edge(e))

    def prev(self, d: Int) -> Int:
        d = _ids(d)
        e = d >> 1
        return jnp.where((d & 1) == 0, self.left_back_edge(e), self.right_front_edge(e))

    def left_front(self, d: Int) -> Int:
        return self.next(d)

    def left_back(self, d: Int) -> Int:
        return self.prev(d)

    def right_front(self, d: Int) -> Int:
        return self.prev(_ids(d) ^ 1)

    def right_back(self, d: Int) -> Int:
        return self.next(_ids(d) ^ 1)

    def _step_table(self, forward: bool) -> Int:
        """``(6n,)`` :meth:`next` (``forward``) or :meth:`prev` of every dart id (garbage on
        unused ids), in memory: the Front tables of every edge (:meth:`_left_sides`,
        :meth:`_right_sides`; the Backs read the Fronts' tables), the two sides written to
        memory, then interleaved into dart order ``2e + r`` (as :meth:`dart_faces`)."""
        e = jnp.arange(3 * self.num_vertices, dtype=jnp.int32)
        lf, lb = self._left_sides(e)
        rf, rb = self._right_sides(e)
        left, right = (lf, rb) if forward else (lb, rf)
        left, right = _materialize_loop((left, right))
        (table,) = _materialize_loop((_join((left, right), False),))
        return table

    @_base.by_table
    def _next_by_table(self, d: Int) -> Int:
        """Next (LeftFront) of a batch of darts as large as a fraction of the mesh: every dart's
        once (:meth:`_step_table`), then one gather per dart (``MeshStructure.table_queries``).
        Ids out of range read a clamped entry (garbage, as the per-query route gives them)."""
        return self._step_table(True).at[_ids(d)].get(mode="clip")

    @_base.by_table
    def _prev_by_table(self, d: Int) -> Int:
        return self._step_table(False).at[_ids(d)].get(mode="clip")

    @_base.by_table
    def _right_front_by_table(self, d: Int) -> Int:
        return self._step_table(False).at[_ids(d) ^ 1].get(mode="clip")

    @_base.by_table
    def _right_back_by_table(self, d: Int) -> Int:
        return self._step_table(True).at[_ids(d) ^ 1].get(mode="clip")

    def edge_of_vertex(self, v: Int) -> Int:
        """``Edge(u)``: ``u_red`` (Thm 2); ``V_red`` has no outgoing edge: ``(V_red, V_blue)``."""
        v = _ids(v)
        return jnp.where(v == self.v_red, self._d0 ^ 1, _dart(v, RED, 0)).astype(jnp.int32)

    def point(self, positions, v: Int):
        """``Point(u)``: the coordinates of ``u`` (positions in the structure's vertex order)."""
        return positions[_ids(v)]

    # ---- adjacency
    def _out_targets(self, u, table=None):
        target = self._edge_target if table is None else (lambda e: _take(table, e))
        ts = []
        for c in range(3):
            e = 3 * u + c
            ts.append(jnp.where(self.edge_valid(e), target(jnp.where(self.edge_valid(e), e, 3 * self.v_black)),
                                self.num_vertices))
        return ts

    def adjacent_takes_table(self, batch_size: int) -> bool:
        """Whether :meth:`adjacent` of ``batch_size`` pairs reads every edge's Target from a
        whole-mesh table (:meth:`all_edge_targets`) rather than walking per query: where Target
        walks (Thm 2) and the batch asks at least ``n / 16`` pairs. A sharded structure runs
        such a batch on its unpadded arrays (:class:`jaxcds.sharding.ShardedStructure`)."""
        return self._target_walks and batch_size * 16 >= self.num_vertices

    def adjacent(self, u: Int, v: Int) -> Int:
        """``Adjacent(u, v)`` (Sec. 1.3, Thm 6): every edge leaves one of its endpoints, so ``u``
        and ``v`` are adjacent iff ``v`` is the target of one of the 3 edges leaving ``u`` or the
        converse -- 6 Target calls (O(1) each for CDS5n-O(1), O(d) otherwise).

        Where Target walks (Thm 2, O(d)) and the batch asks at least ``n / 16`` pairs, every
        edge's Target is computed once (:meth:`all_edge_targets`, pointer jumping, O(n log d))
        and read: the batch's walks ran in lockstep as long as the longest fan, queries x the
        largest degree (sweep 17b: 100K queries around a degree-1,000 hub, cds5n 4.8 s; a walk's
        lanes into a hub are many, so compacting them did not help: 12 s)."""
        u, v = _ids(u), _ids(v)
        table = self._edge_target_table() if self.adjacent_takes_table(max(u.size, v.size)) else None
        tu = self._out_targets(u, table)
        tv = self._out_targets(v, table)
        hit = jnp.zeros(u.shape if u.ndim >= v.ndim else v.shape, bool)
        for t in tu:
            hit = hit | (t == v)
        for t in tv:
            hit = hit | (t == u)
        return hit & (u != v)

    # ---- faces (Thm 7)
    def _face_left_slot(self, e, lf=None, lb=None):
        u, c = e // 3, e % 3
        n = self.num_vertices
        lf = self.left_front_edge(e) if lf is None else lf
        lb = self.left_back_edge(e) if lb is None else lb
        fb = self.F_blue
        # red: Face_left(u_red) is u_red^tri
        red = u
        # black: LeftFront red -> Source(LeftFront)_red^tri, else u_black^tri
        black = jnp.where(_col(lf) == RED, _src(lf), n + u)
        # blue: LeftBack red -> Source(LeftBack)_red^tri; else LeftFront black ->
        # Source(LeftFront)_black^tri; else u_blue^tri (slot n + F_blue[u])
        blue = jnp.where((_col(lb) == RED) & ((lb & 1) == 0), _src(lb),
                         jnp.where(_col(lf) == BLACK, n + _src(lf), n + fb[u]))
        s = jnp.where(c == RED, red, jnp.where(c == BLACK, black, blue))
        # _EXTERIOR: left of (V_black, V_blue) is the outer face = left of (V_blue, V_red): slot V_blue
        return jnp.where(e == self._e_kb, self.v_blue, s)

    def _face_right_slot(self, e, rf=None, rb=None):
        u, c = e // 3, e % 3
        n = self.num_vertices
        rf = self.right_front_edge(e) if rf is None else rf
        rb = self.right_back_edge(e) if rb is None else rb
        fb = self.F_blue
        # red: RightFront red -> Source(RightFront)_red^tri, else u_black^tri (no cw triangle)
        red = jnp.where(_col(rf) == RED, _src(rf), n + u)
        # black: RightFront black -> Source(RightFront)_black^tri, else Source(RightBack)_blue^tri
        black = jnp.where(_col(rf) == BLACK, n + _src(rf), n + fb[_src(rb)])
        # blue: RightBack red -> Source(RightBack)_red^tri, else Source(RightFront)_blue^tri
        blue = jnp.where(_col(rb) == RED, _src(rb), n + fb[_src(rf)])
        return jnp.where(c == RED, red, jnp.where(c == BLACK, black, blue))

    def _compact(self, slot):
        k = jnp.zeros_like(slot)
        for x in self.unused_slots:
            k = k + (slot > x).astype(k.dtype)  # explicit: strict dtype promotion (sweep 52c)
        return (slot - k).astype(jnp.int32)

    def _expand(self, f):
        s = f
        for x in self.unused_slots:  # sorted
            s = s + (s >= x).astype(s.dtype)
        return s

    def face_slot(self, d: Int) -> Int:
        """Thm 7 slot (index into a size-``2n`` face array) of the left face of dart ``d``."""
        d = _ids(d)
        e = d >> 1
        left = (d & 1) == 0
        # one front and one back per dart, by side (the left face of the twin is the right
        # face of the edge); written to memory before the slot rules read them twice each
        # (materialize_loop: fused, XLA re-evaluated the front/back chains per use)
        front = jnp.where(left, self.left_front_edge(e), self.right_front_edge(e))
        back = jnp.where(left, self.left_back_edge(e), self.right_back_edge(e))
        front, back = _materialize_loop((front, back))
        return jnp.where(left, self._face_left_slot(e, front, back),
                         self._face_right_slot(e, front, back)).astype(jnp.int32)

    def face(self, d: Int) -> Int:
        return self._compact(self.face_slot(d))

    def face_left(self, d: Int) -> Int:
        return self.face(d)

    def face_right(self, d: Int) -> Int:
        return self.face(_ids(d) ^ 1)

    def dart_faces(self) -> Int:
        """``(6n,)`` :meth:`face` of every dart id (``num_faces`` on unused ids), all at once:
        every edge's LeftFront / LeftBack and RightFront / RightBack tables
        (:meth:`_left_sides`, :meth:`_right_sides`), its left and right Thm 7 slot rules, then
        the two interleaved into dart order ``2e + r``. No second Front per Back (as one
        :meth:`face` per dart id computes) and no scatter (the default's three, from
        :meth:`edge_of_face`): 100K vertices, CDS5n 36.7 ns per dart (scatters) / 28.7 (``face``
        of every id) -> 5.0, CDS6n 15.1 / 10.9 -> 4.7. Transient: 132-156 bytes per vertex
        (1M vertices; the right side computed after the left side's tables were dead took
        111-123, but ran CDS6n 1.9x slower: its ids, read back from memory, were no longer
        known to XLA as a sequence)."""
        n = self.num_vertices
        e = jnp.arange(3 * n, dtype=jnp.int32)
        ok = self.edge_valid(e)
        left = jnp.where(ok, self._compact(self._face_left_slot(e, *self._left_sides(e))),
                         self.num_faces)
        right = jnp.where(ok, self._compact(self._face_right_slot(e, *self._right_sides(e))),
                          self.num_faces)
        # in memory before the interleave: fused into it, the slot rules ran 2.4x slower
        # (cds6n, 100K vertices: 9.9 -> 4.1 ms)
        left, right = _materialize_loop((left, right))
        return _join((left, right), False).astype(jnp.int32)

    def _face_table(self) -> Int:
        """:meth:`dart_faces`, in memory (for the ``face`` table route)."""
        (table,) = _materialize_loop((self.dart_faces(),))
        return table

    @_base.by_table
    def _face_by_table(self, d: Int) -> Int:
        """Face_left of a batch of darts as large as a fraction of the mesh: every dart's face once
        (:meth:`dart_faces`), then one gather per dart (``MeshStructure.table_queries``). Ids
        out of range read a clamped entry (garbage, as the per-query route gives them)."""
        return self._face_table().at[_ids(d)].get(mode="clip")

    @_base.by_table
    def _face_right_by_table(self, d: Int) -> Int:
        return self._face_table().at[_ids(d) ^ 1].get(mode="clip")

    def edge_of_face(self, f: Int) -> Int:
        """``Edge(f)`` (Thm 7): the edge matched with the face, as its ``r = 0`` dart."""
        s = self._expand(_ids(f))
        n = self.num_vertices
        b = jnp.clip(s - n, 0, n - 1)
        black_matched = (_col(self._lf(3 * b + BLACK)) == BLACK) & self.edge_valid(3 * b + BLACK)
        owner = self.F_blue[b]
        d = jnp.where(s < n, _dart(s, RED), jnp.where(black_matched, _dart(b, BLACK), _dart(owner, BLUE)))
        return d.astype(jnp.int32)

    # ---- corners (Thm 8)
    @_base.checked_ids
    def corner_index(self, d: Int) -> Int:
        """Thm 8 corner number of dart/corner ``d``: ``u + n (c + 3 r)``."""
        d = _ids(d)
        e = d >> 1
        return (e // 3 + self.num_vertices * (e % 3 + 3 * (d & 1))).astype(jnp.int32)

    @_base.checked_ids
    def corner_dart(self, k: Int) -> Int:
        """Inverse of :meth:`corner_index`."""
        k = _ids(k)
        n = self.num_vertices
        u, q = k % n, k // n
        return _dart(u, q % 3, q // 3)

    # ---- metadata
    @property
    def navigation_references(self) -> int:
        """References the navigation needs (Thm 2/4/5/6: ``6n``, ``5n``, ``4n``, ``5n``), without
        the face map of Thm 7; :attr:`references` counts both."""
        return self.core_references

    @property
    def navigation_references_per_vertex(self) -> float:
        return self.navigation_references / max(self.num_vertices, 1)

    @property
    def face_map_references_per_vertex(self) -> float:
        """``F_blue`` (Thm 7): one reference per vertex."""
        return int(self.F_blue.shape[0]) / max(self.num_vertices, 1)

    @property
    def core_references(self) -> int:
        """References of the connectivity tables alone (``k n``, ``k = 6, 5, 4, 5``)."""
        return int(np.prod(self.refs.shape))

    @property
    def references(self) -> int:
        """Tables + the face map ``F_blue`` (Thm 7, one reference per vertex)."""
        return self.core_references + int(self.F_blue.shape[0])

    # ---- packed batches (jaxcds.batch): one block, the machinery lives in cds_packed
    @classmethod
    def concatenate(cls, parts):
        """One structure over the disjoint union of ``parts`` (all of class ``cls``, one per
        mesh) for :func:`jaxcds.batch.pack`: every 30-bit vertex field of the tables and
        ``F_blue`` shifted by the mesh's vertex offset (service bits kept, Sec. 2.1), the cwBFS
        ``vertex_order`` composed; the outer vertices and unused Thm 7 slots, which a single
        structure keeps static, become per-mesh tables (:mod:`jaxcds.structures.cds_packed`)."""
        from jaxcds.structures.cds_packed import concatenate_cds

        return concatenate_cds(cls, parts)


# ====================================================================================== CDS6n
@pytree_dataclass
class CDS6n(_CDS):
    """Thm 2 (Sec. 2.1, Fig. 3): 6 references per vertex (+1 for faces).

    Fields:
      refs: ``(n, 6)`` int32 packed references, row ``u``: column ``2c`` = ``S_c^left[u]`` (bit 30:
        ``C_c^left[u]``, bit 31: ``I_c[u]``), column ``2c + 1`` = ``S_c^right[u]`` (bit 30:
        ``C_c^right[u]``), where ``S_c^left[u] = Source(LeftFront(u_c))``, ``C_c^left[u]`` = it has
        colour ``c`` (else ``next(c)``), ``S_c^right[u] = Source(RightFront(u_c))``,
        ``C_c^right[u]`` = colour ``c`` (else ``prev(c)``), ``I_c[u]`` = ``u`` has an incoming edge
        of colour ``c``.
      F_blue: ``(n,)`` int32 face map of Thm 7.
      target_rounds: pointer-jumping rounds of the whole-mesh Targets (:func:`target_rounds` from
        the wood, :func:`with_target_rounds` from the tables; static metadata, not a reference;
        ``-1``: not known, the loop tests for pending entries).
      dummy_ids: ``(k,)`` int32 or ``None``: the dummy vertices that closed the input's ``k``
        holes (Sec. 4.5), in this structure's numbering; not references (``k`` is the number of
        holes). :meth:`dummy_vertex_mask` reads them, so degrees and normals are the open mesh's.
    """

    refs: jnp.ndarray
    F_blue: jnp.ndarray
    num_vertices: int = static_field()
    num_faces: int = static_field()
    v_red: int = static_field()
    v_blue: int = static_field()
    v_black: int = static_field()
    unused_slots: tuple = static_field()
    boundaries_closed: bool = static_field(default=False)
    target_rounds: int = static_field(default=-1)
    dummy_ids: jnp.ndarray = None

    name = "cds6n"
    _gathered_lf = False  # column slices of refs
    # its Fronts are one row read each, so the per-query Face_left and Prev are cheap (Face_left
    # 13.7 ns at 100K vertices against 52 for CDS5n): their tables pay from half the dart ids
    # (Prev at 100K: 1.22x the per-query route at 1/4, 0.67x at 1/2)
    table_batch_ratio = {**_CDS.table_batch_ratio, "face": 1 / 2, "face_left": 1 / 2,
                         "face_right": 1 / 2, "prev": 1 / 2, "left_back": 1 / 2,
                         "right_front": 1 / 2}

    def _inc(self, u, c):
        return _bit31(jnp.take_along_axis(self.refs[u], (2 * c)[..., None], axis=-1)[..., 0])

    def _lf(self, e):
        u, c = e // 3, e % 3
        x = self.refs[u, 2 * c]
        s = _fld(x)
        # C_c^left true: LeftFront is w_c entering v (r = 1); false: v_next(c) leaving v (r = 0)
        return jnp.where(_bit30(x), _dart(s, c, 1), _dart(s, (c + 1) % 3, 0))

    def _rf(self, e):
        u, c = e // 3, e % 3
        x = self.refs[u, 2 * c + 1]
        s = _fld(x)
        # C_c^right true: RightFront is z_c entering v (r = 0); false: v_prev(c) leaving v (r = 1)
        return jnp.where(_bit30(x), _dart(s, c, 0), _dart(s, (c + 2) % 3, 1))

    def _lf_parts_cols(self):
        out = []
        for c in range(3):
            x = self.refs[:, 2 * c]
            b = _bit30(x)  # as _lf: w_c entering v (r = 1), else v_next(c) leaving v (r = 0)
            out.append(_parts(_fld(x), jnp.where(b, c, (c + 1) % 3), b))
        return tuple(out)

    @classmethod
    def from_wood(cls, wood: SchnyderWood, *, boundaries_closed: bool = False, check: bool = True) -> "CDS6n":
        """Build from a (maximal, for the face map) Schnyder wood in linear time (one numba
        pass, :func:`_cds_rows`). Every CDS's ``from_wood`` first checks a wood it did not make
        (``check=True``: :func:`~jaxcds.construct.schnyder.check_wood_arrays`, linear,
        ``StructureError`` naming the entry); the builders pass theirs with ``check=False``."""
        _checked_wood(cls, wood, check)
        refs, fblue, static = _build_rows(wood, _KIND_6N)
        return cls(refs=_put(refs), F_blue=_put(fblue),
                   boundaries_closed=bool(boundaries_closed), **static)

    @classmethod
    def from_mesh(cls, mesh, root_face: Optional[int] = None) -> "CDS6n":
        return build_cds(cls, mesh, root_face=root_face)


class _Tables:
    """Host-side ground truth, vectorised numpy (linear time): the previous builders, now the
    oracle of :func:`tables_reference`."""

    def __init__(self, wood: SchnyderWood):
        n = wood.num_vertices
        _check_size(n)
        self.wood = wood
        self.n = n
        self.lf, self.rf, self.lf2 = edge_fronts(wood)
        has = wood.out < n
        self.has = has
        self.lf_same = has & ((self.lf & 1) == 1)
        self.rf_same = has & ((self.rf & 1) == 0)
        self.inc = _incoming(wood)
        self.fblue, self.unused = face_slots(wood, self.lf, self.rf, self.inc)

    @staticmethod
    def src(d):
        return np.where(d >= 0, (d >> 1) // 3, 0)

    @staticmethod
    def col(d):
        return np.where(d >= 0, (d >> 1) % 3, -1)

    def static(self, boundaries_closed):
        w = self.wood
        return dict(num_vertices=w.num_vertices, num_faces=2 * w.num_vertices - 4, v_red=w.v_red,
                    v_blue=w.v_blue, v_black=w.v_black, unused_slots=self.unused,
                    boundaries_closed=bool(boundaries_closed))

    def toleft(self):
        """Sec. 2.2: ``(S_red^toleft, C_red^toleft)`` with ``C`` in {0 red, 1 blue, 2 black}."""
        lf, lf2 = self.lf[:, RED], self.lf2[:, RED]
        red = self.col(lf) == RED
        # {v, q} black (q -> v) when the dart (v, q) is a reversed black edge
        black = ~red & (self.col(lf2) == BLACK) & ((lf2 & 1) == 1)
        s = np.where(red, self.src(lf), np.where(black, self.src(lf2), self.src(lf)))
        ctl = np.where(red, 0, np.where(black, 2, 1))
        ctl = np.where(self.has[:, RED], ctl, 0)
        return s, ctl

    def blue_single(self):
        """Sec. 2.2: ``S_blue``/``C_blue``: LeftFront if ``I_red[u]``, else RightFront."""
        use_left = self.inc[:, RED]
        s = np.where(use_left, self.src(self.lf[:, BLUE]), self.src(self.rf[:, BLUE]))
        cc = np.where(use_left, self.lf_same[:, BLUE], self.rf_same[:, BLUE])
        return s, cc & self.has[:, BLUE]


def tables_reference(name: str, wood: SchnyderWood):
    """The tables of structure ``name`` (``cds6n``, ``cds5n``, ``cds4n``, ``cds5n-o1``) by the
    vectorised numpy route -- ground truth from the rotation system (:func:`edge_fronts`), an
    explicitly relabelled wood (:func:`relabel_wood`) and :func:`face_slots` -- for tests of the
    fused builder :func:`_cds_rows`. Returns ``(refs int32, F_blue int32, order or None, static)``
    with ``static`` the fields ``from_wood`` passes on (without ``boundaries_closed``)."""
    order = None
    if name in ("cds4n", "cds5n-o1"):
        order = cw_bfs_order(wood)
        wood = relabel_wood(wood, order)
    t = _Tables(wood)
    n = wood.num_vertices
    if name == "cds6n":
        cols = []
        for c in range(3):
            cols.append(_pack(t.src(t.lf[:, c]), t.lf_same[:, c], t.inc[:, c]))
            cols.append(_pack(t.src(t.rf[:, c]), t.rf_same[:, c]))
    else:
        s_tl, c_tl = t.toleft()
        s_b, c_b = t.blue_single()
        black = [_pack(t.src(t.lf[:, BLACK]), t.lf_same[:, BLACK], t.inc[:, BLACK]),
                 _pack(t.src(t.rf[:, BLACK]), t.rf_same[:, BLACK])]
        if name == "cds5n":
            cols = [_pack(s_tl, c_tl & 1, c_tl >> 1),
                    _pack(t.src(t.rf[:, RED]), t.rf_same[:, RED], t.inc[:, RED]),
                    _pack(s_b, c_b, t.inc[:, BLUE])] + black
        else:
            tgt = np.where(wood.out < n, wood.out, 0)
            s0 = s_tl if name == "cds4n" else np.where(c_tl == 2, s_tl, tgt[:, RED])
            cols = [_pack(s0, c_tl & 1, c_tl >> 1),
                    _pack(s_b, c_b, t.inc[:, RED]),
                    _pack(t.src(t.lf[:, BLACK]), t.lf_same[:, BLACK], t.inc[:, BLUE]),
                    _pack(t.src(t.rf[:, BLACK]), t.rf_same[:, BLACK], t.inc[:, BLACK])]
            if name == "cds5n-o1":
                even = _depths(wood.out[:, RED].astype(np.int64), n, wood.v_red) % 2 == 0
                lfc_blue = t.col(t.lf[:, BLUE])
                leaf = ~t.inc[:, RED]
                W = np.where(leaf, np.where(lfc_blue == BLUE, tgt[:, BLUE], tgt[:, BLACK]),
                             np.where(even, tgt[:, BLACK], tgt[:, BLUE]))
                cols.append(_pack(W, even))
    static = t.static(False)
    static.pop("boundaries_closed")
    return np.stack(cols, axis=1), t.fblue, order, static


# ====================================================================================== CDS5n
@pytree_dataclass
class CDS5n(_CDS):
    """Thm 4 (Sec. 2.2, Fig. 4): 5 references per vertex (+1 for faces), maximal wood.

    Fields:
      refs: ``(n, 5)`` int32 packed, row ``u``:
        0: ``S_red^toleft[u]``, bits 30-31 ``C_red^toleft[u]`` (0 red, 1 blue, 2 black);
        1: ``S_red^right[u]``, bit 30 ``C_red^right[u]``, bit 31 ``I_red[u]``;
        2: ``S_blue[u]``, bit 30 ``C_blue[u]``, bit 31 ``I_blue[u]`` (LeftFront if ``I_red[u]``,
           else RightFront);
        3: ``S_black^left[u]``, bit 30 ``C_black^left[u]``, bit 31 ``I_black[u]``;
        4: ``S_black^right[u]``, bit 30 ``C_black^right[u]``.
      F_blue: ``(n,)`` int32 face map of Thm 7.
      target_rounds, dummy_ids: as in :class:`CDS6n`.

    Every per-vertex rule below reads one table *row* (``row = refs[u]``, one gather of the
    whole row for batched queries) or, with ``row = refs`` and ``u = arange(n)``, the whole
    table column by column (slices, no gather: :meth:`_lf_parts_cols`, the whole-mesh queries).
    """

    refs: jnp.ndarray
    F_blue: jnp.ndarray
    num_vertices: int = static_field()
    num_faces: int = static_field()
    v_red: int = static_field()
    v_blue: int = static_field()
    v_black: int = static_field()
    unused_slots: tuple = static_field()
    boundaries_closed: bool = static_field(default=False)
    target_rounds: int = static_field(default=-1)
    dummy_ids: jnp.ndarray = None

    name = "cds5n"
    _COL_TOLEFT, _COL_BLUE, _COL_BLACK_L, _COL_BLACK_R = 0, 2, 3, 4
    # I_red, I_blue, I_black are bit 31 of columns 1, 2, 3 (the same columns in CDS4n)
    _COL_INC = {RED: 1, BLUE: 2, BLACK: 3}

    # ---- row readers
    def _inc_r(self, row, c: int):
        """``I_c[u]`` (colour ``c`` static) from ``row``."""
        return _bit31(row[..., self._COL_INC[c]])

    def _inc(self, u, c):
        row = self.refs[u]
        return jnp.where(c == RED, self._inc_r(row, RED),
                         jnp.where(c == BLUE, self._inc_r(row, BLUE), self._inc_r(row, BLACK)))

    def _toleft_r(self, row):
        x = row[..., self._COL_TOLEFT]
        return _fld(x), (x >> 30) & 3

    # black: both fronts stored (Fig. 4 top-left). Each LeftFront reader comes twice: ``_r``,
    # the dart, for the per-query operators, and ``_p``, the dart in parts (_parts), for the
    # whole-mesh routes: built as parts and packed after, the per-query darts measured 1.2-1.4x
    # slower in Face_left / Face_right (100K vertices, 2026-11-30)
    def _lf_black_p(self, row):
        x = row[..., self._COL_BLACK_L]
        b = _bit30(x)
        # C_black^left: LeftFront is w_black entering v; else v_red leaving v
        return _parts(_fld(x), jnp.where(b, BLACK, RED), b)

    def _lf_black_r(self, row):
        x = row[..., self._COL_BLACK_L]
        s = _fld(x)
        return jnp.where(_bit30(x), _dart(s, BLACK, 1), _dart(s, RED, 0))

    def _rf_black_p(self, row):
        x = row[..., self._COL_BLACK_R]
        b = _bit30(x)
        # C_black^right: RightFront is z_black entering v; else v_blue leaving v
        return _parts(_fld(x), jnp.where(b, BLACK, BLUE), ~b)

    def _rf_black_r(self, row):
        x = row[..., self._COL_BLACK_R]
        s = _fld(x)
        return jnp.where(_bit30(x), _dart(s, BLACK, 0), _dart(s, BLUE, 1))

    def _lf_red_p(self, u, row):
        s, ctl = self._toleft_r(row)
        # C_red^toleft = red: LeftFront is w_red entering v, S = w
        # C_red^toleft = blue: LeftFront is v_blue, S = v
        # C_red^toleft = black: S = q, LeftFront = (v, w) = twin(RightFront(q_black)) = v_blue
        q = _fld(_take(self.refs[:, self._COL_BLACK_R], s))
        return _parts(jnp.where(ctl >= 2, q, s), jnp.where(ctl == 0, RED, BLUE), ctl == 0)

    def _lf_red_r(self, u, row):
        s, ctl = self._toleft_r(row)
        red, blue = _dart(s, RED, 1), _dart(s, BLUE, 0)  # the three cases as in _lf_red_p
        black = _dart(_fld(self.refs[s, self._COL_BLACK_R]), BLUE, 0)
        return jnp.where(ctl == 0, red, jnp.where(ctl == 1, blue, black))

    def _rf_red_r(self, u, row):
        x = row[..., 1]
        s = _fld(x)
        # C_red^right: RightFront is z_red entering v; else v_black leaving v
        return jnp.where(_bit30(x), _dart(s, RED, 0), _dart(s, BLACK, 1))

    def _blue_stored_r(self, row):
        x = row[..., self._COL_BLUE]
        return _fld(x), _bit30(x)

    def _lf_blue_p(self, row):
        s, same = self._blue_stored_r(row)
        stored = _parts(s, jnp.where(same, BLUE, BLACK), same)
        # Case 1 (I_red[u] false, {u, w} black toward w): LeftFront = RightFront(u_black)
        return _psel(self._inc_r(row, RED), stored, self._rf_black_p(row))

    def _lf_blue_r(self, row):
        s, same = self._blue_stored_r(row)
        stored = jnp.where(same, _dart(s, BLUE, 1), _dart(s, BLACK, 0))
        # Case 1 (I_red[u] false): LeftFront = RightFront(u_black)
        return jnp.where(self._inc_r(row, RED), stored, self._rf_black_r(row))

    def _rf_blue_r(self, u, row):
        s, same = self._blue_stored_r(row)
        # I_red[u] false: RightFront stored (colour blue -> z_blue, else v_red leaving v)
        stored = jnp.where(same, _dart(s, BLUE, 0), _dart(s, RED, 1))
        # Case 2a ({u, z} red toward z, I_black[u] false): RightFront = LeftFront(u_red)
        case2a = self._lf_red_r(u, row)
        # Case 2b ({u, z} black toward u): z is stored at w_red (C_red^toleft[w] = black);
        # w = Source(LeftFront(LeftFront(e))) if LeftFront(e) is black, else Source(LeftFront(e))
        lf = jnp.where(same, _dart(s, BLUE, 1), _dart(s, BLACK, 0))
        w = jnp.where(_col(lf) == BLACK, _src(self._lf_black_r(self.refs[_src(lf)])), _src(lf))
        w, = _materialize_loop((w,))  # a chain of two row reads: see left_back_edge
        z, _ = self._toleft_r(self.refs[w])
        case2b = _dart(z, BLUE, 0)
        return jnp.where(~self._inc_r(row, RED), stored,
                         jnp.where(~self._inc_r(row, BLACK), case2a, case2b))

    def _lf(self, e):
        u, c = e // 3, e % 3
        row = self.refs[u]
        return jnp.where(c == RED, self._lf_red_r(u, row),
                         jnp.where(c == BLUE, self._lf_blue_r(row), self._lf_black_r(row)))

    def _rf(self, e):
        u, c = e // 3, e % 3
        row = self.refs[u]
        return jnp.where(c == RED, self._rf_red_r(u, row),
                         jnp.where(c == BLUE, self._rf_blue_r(u, row), self._rf_black_r(row)))

    def _lf_parts_cols(self):
        u = jnp.arange(self.num_vertices, dtype=jnp.int32)
        r = self.refs
        return self._lf_red_p(u, r), self._lf_blue_p(r), self._lf_black_p(r)

    @classmethod
    def from_wood(cls, wood: SchnyderWood, *, boundaries_closed: bool = False, check: bool = True) -> "CDS5n":
        """Build from a maximal Schnyder wood in linear time."""
        _checked_wood(cls, wood, check)
        if not wood.maximal:
            raise errors.StructureError("CDS5n needs the maximal Schnyder wood (Thm 4); this one was "
                                        "built with maximal=False: schnyder_wood(faces, n) builds the maximal one")
        refs, fblue, static = _build_rows(wood, _KIND_5N)
        return cls(refs=_put(refs), F_blue=_put(fblue),
                   boundaries_closed=bool(boundaries_closed), **static)

    @classmethod
    def from_mesh(cls, mesh, root_face: Optional[int] = None) -> "CDS5n":
        return build_cds(cls, mesh, root_face=root_face)


# ====================================================================================== CDS4n
@pytree_dataclass
class CDS4n(CDS5n):
    """Thm 5 (Sec. 2.3, Fig. 5): 4 references per vertex (+1 for faces); vertices renumbered by
    the cwBFS of the red tree (``vertex_order``), no RightFront reference for red edges.

    Fields:
      refs: ``(n, 4)`` int32 packed, row ``u`` (cwBFS label):
        0: ``S_red^toleft[u]``, bits 30-31 ``C_red^toleft[u]``;
        1: ``S_blue[u]``, bit 30 ``C_blue[u]``, bit 31 ``I_red[u]``;
        2: ``S_black^left[u]``, bit 30 ``C_black^left[u]``, bit 31 ``I_blue[u]``;
        3: ``S_black^right[u]``, bit 30 ``C_black^right[u]``, bit 31 ``I_black[u]``.
      F_blue: ``(n,)`` int32 face map of Thm 7.
      order: ``(n,)`` int32, ``order[i]`` = input vertex of label ``i`` (the user's map back; not
        a reference of the structure: the paper permutes the input instead).
    """

    order: jnp.ndarray = None

    name = "cds4n"
    _COL_TOLEFT, _COL_BLUE, _COL_BLACK_L, _COL_BLACK_R = 0, 1, 2, 3

    @property
    def vertex_order(self):
        return np.asarray(self.order)

    def _rf_red_r(self, u, row):
        # RightFront(u_red) red => it is (u - 1)_red, which holds iff LeftFront((u-1)_red) = u_red
        um = jnp.maximum(u - 1, 0)
        # LeftFront((u-1)_red) by its red rule only (the colour is known here) and its one
        # exterior case, (V_blue, V_red)
        lf_prev = jnp.where(um == self.v_blue, self._d1, self._lf_red_r(um, self.refs[um]))
        sib = (u >= 2) & (lf_prev == _dart(u, RED, 1))
        # otherwise {v, z} and {u, z} are black (no cw triangle): RightFront = LeftFront(u_black)
        return jnp.where(sib, _dart(um, RED, 0), self._lf_black_r(row))

    @classmethod
    def from_wood(cls, wood: SchnyderWood, *, boundaries_closed: bool = False, check: bool = True) -> "CDS4n":
        """Relabel ``wood`` by cwBFS (Sec. 2.3) and build, in linear time: the labels are applied
        while the rows are written (:func:`_cds_rows`), no relabelled wood is built."""
        _checked_wood(cls, wood, check)
        if not wood.maximal:
            raise errors.StructureError("CDS4n needs the maximal Schnyder wood (Thm 5); this one was "
                                        "built with maximal=False: schnyder_wood(faces, n) builds the maximal one")
        order, label, _ = _cwbfs_checked(wood)
        refs, fblue, static = _build_rows(wood, _KIND_4N, label)
        return cls(refs=_put(refs), F_blue=_put(fblue),
                   order=_put(order),
                   boundaries_closed=bool(boundaries_closed), **static)

    @property
    def references(self) -> int:
        return self.core_references + int(self.F_blue.shape[0])


# ====================================================================================== CDS5n-O(1)
@pytree_dataclass
class CDS5nO1(CDS4n):
    """Thm 6 (Sec. 2.4, Fig. 6): 5 references per vertex (+1 for faces), cwBFS order, Target
    and Adjacent in O(1) worst case.

    Fields: as :class:`CDS4n`, except
      refs[:, 0]: ``S_red^left[u]`` = ``Target(u_red)`` when ``C_red^toleft`` is red or blue (the
        stored ``w`` of the red case is ``u + 1`` by cwBFS, Sec. 2.4), ``q`` when it is black
        (then ``Target(u_red) = Source(RightFront(q_black))``, and Thm 4's Case 2b still reads
        ``q``);
      refs[:, 4]: ``W[u]`` (Thm 6), bit 30 ``D[u]`` (depth of ``u`` in the red tree is even).

    A batched Target reads two rows: ``refs[u]``, then the row of the one vertex the case
    analysis names (``q``, ``w'`` or ``z'``); Adjacent reads four per endpoint.
    """

    name = "cds5n-o1"
    _fusible_targets = True
    target_table = None  # Target is O(1) here (Thm 6): loops ask it directly
    # the second row read and case analysis, fused into the chunk's in-place output update, ran
    # on one core: written apart, Target at 100K vertices 6.1 -> 4.2 ns per query, 2.5M 17.3 ->
    # 12.2 (races in shuffled order). Origin and Face_left showed no clear gain; an operator
    # that costs a gather or two pays the extra loop and copy per chunk for nothing
    chunk_answers_apart = frozenset({"target"})
    # Thm 6's Target is O(1) but two dependent row reads (6-22 ns per query); every edge's at once
    # costs ~4 ns per edge, so a batch of half the dart ids (3n darts) or more takes the table:
    # 0.60x the per-query route's time at 100K vertices, 0.78x at 2.5M; at a quarter, level.
    # Transient: 52 bytes per vertex (the three colours' plans and targets, then the table)
    table_batch_ratio = {**CDS4n.table_batch_ratio, "target": 1 / 2, "origin": 1 / 2}

    def _lf_red_p(self, u, row):
        s, ctl = self._toleft_r(row)
        # C_red^toleft = red: LeftFront is w_red with w = u + 1 (next cw sibling, cwBFS)
        # blue: LeftFront = v_blue with v = Target(u_red) = S
        # black: S = q; LeftFront = v_blue with v = Source(RightFront(q_black))
        q = _fld(_take(self.refs[:, self._COL_BLACK_R], s))
        src = jnp.where(ctl == 0, u + 1, jnp.where(ctl == 1, s, q))
        return _parts(src, jnp.where(ctl == 0, RED, BLUE), ctl == 0)

    def _lf_red_r(self, u, row):
        s, ctl = self._toleft_r(row)
        red, blue = _dart(u + 1, RED, 1), _dart(s, BLUE, 0)  # the three cases as in _lf_red_p
        black = _dart(_fld(self.refs[s, self._COL_BLACK_R]), BLUE, 0)
        return jnp.where(ctl == 0, red, jnp.where(ctl == 1, blue, black))

    def _target_plan_r(self, u, c, row):
        """Thm 6 Target of ``u_c``, first read (``row = refs[u]``): ``(y, second)`` where
        ``second`` says what to read in row ``y`` (a vertex id) for the answer: 0 nothing (``y``
        is the target), 1 ``S_black^right[y]`` (red, ``C_red^toleft`` black: ``y = q``), 2 the
        blue walk end at ``y = w'``, 3 the black walk end at ``y = z'`` (:meth:`_target_finish_r`).

        The proof's cases, with the stored fields of this row (Fig. 6): ``W`` and ``D`` (col 4),
        ``I_red`` (col 1), ``S_black^right`` / ``C_black^right`` (col 3) and, for the leaves
        (``I_red`` false), Thm 4's Case 1 ``LeftFront(u_blue) = RightFront(u_black)``, read off
        ``C_black^right``. ``c`` is a colour array or a static colour."""
        x0, x1 = row[..., self._COL_TOLEFT], row[..., self._COL_BLUE]
        x3, x4 = row[..., self._COL_BLACK_R], row[..., 4]
        s0, toleft_black = _fld(x0), ((x0 >> 30) & 3) == 2
        s1, blue_same, inner = _fld(x1), _bit30(x1), _bit31(x1)
        s3, right_black = _fld(x3), _bit30(x3)
        w, even = _fld(x4), _bit30(x4)
        # red: S_red^left is the target unless C_red^toleft is black: Source(RightFront(q_black))
        y_red, m_red = s0, jnp.where(toleft_black, 1, 0)
        # blue, u inner: D odd: W[u]; D even: LeftFront(u_blue) (col 1) black leaving v -> its
        # source v = S; blue entering (w' -> v) -> Target(w'_blue), w' = S of odd depth.
        # u a leaf: LeftFront(u_blue) = RightFront(u_black) (Thm 4, Case 1): black -> its
        # source S_black^right is the target; blue -> W[u] (Thm 6's leaf rule)
        y_blue = jnp.where(inner, jnp.where(even, s1, w), jnp.where(right_black, s3, w))
        m_blue = jnp.where(inner & even & blue_same, 2, 0)
        # black, u inner: D even: W[u]; odd: RightFront(u_black) blue (v -> z') -> its source v =
        # S; black (z' -> v) -> Target(z'_black), z' = S. Leaf: the converse of the blue rule
        y_black = jnp.where(inner, jnp.where(even, w, s3), jnp.where(right_black, w, s3))
        m_black = jnp.where(inner & ~even & right_black, 3, 0)
        y = jnp.where(c == RED, y_red, jnp.where(c == BLUE, y_blue, y_black))
        second = jnp.where(c == RED, m_red, jnp.where(c == BLUE, m_blue, m_black))
        # _EXTERIOR: Target((V_black, V_blue)) = V_blue
        ext = (u == self.v_black) & (c == BLUE)
        return (jnp.where(ext, self.v_blue, y).astype(jnp.int32),
                jnp.where(ext, 0, second).astype(jnp.int32))

    def _target_finish_r(self, y, second, ry):
        """Thm 6 Target, second read (``ry = refs[y]``, see :meth:`_target_plan_r`). The walk end
        at ``y``: ``W[y]`` if ``y`` has red children (``I_red``), else the leaf rule read off
        ``C_black^right[y]``: blue end ``S_black^right[y]`` when it is black, black end when it
        is blue, ``W[y]`` otherwise."""
        x1, x3, x4 = ry[..., self._COL_BLUE], ry[..., self._COL_BLACK_R], ry[..., 4]
        leaf, s3, right_black = ~_bit31(x1), _fld(x3), _bit30(x3)
        take_s3 = jnp.where(second == 1, True,
                            jnp.where(second == 2, leaf & right_black, leaf & ~right_black))
        return jnp.where(second == 0, y, jnp.where(take_s3, s3, _fld(x4))).astype(jnp.int32)

    def _second_row(self, y, second):
        """Row ``y`` for :meth:`_target_finish_r`; row 0 where no second read is needed
        (``second == 0``): that row stays in cache, a random row would be a cache miss."""
        return _take(self.refs, jnp.where(second == 0, 0, y))

    def _dart_end(self, d, want_target: bool):
        """Target (``want_target``) or Origin of darts ``d``, Thm 6: O(1), no loop; the row of
        ``u`` (``d = 2(3u + c) + r``), then the row of the one vertex the case names, only where
        the answer is not already known (a dart's own source ``u`` needs none).

        The first read's answer ``(y, second)`` is written to memory between the two
        (:func:`~jaxcds.structures.base.materialize_loop`): fused, XLA re-evaluated the first
        read inside the second's loop (2.5M vertices: 55-82 ns per query before, 19-20 after;
        ``benchmarks/RESULTS.md``, "CDS: materialisation loop")."""
        d = _ids(d)
        e = d >> 1
        # truncating division (ids are not negative): jnp's floor division and remainder are
        # two kernels of their own here, each with a sign fix-up, written to memory for their
        # many readers; ``e - 3 u`` fuses into them (100K vertices, 10M darts: 0.93x the time,
        # 95% interval 0.90-0.96, 21 paired rounds, 2026-12-04; 3.5K 0.96x, 0.88-1.04)
        u = jax.lax.div(e, jnp.int32(3))
        c = e - 3 * u
        own = ((d & 1) == 0) != want_target  # the answer is the source u of the edge
        # ... which needs no row: those read row 0, which stays in cache
        y, second = self._target_plan_r(u, c, _RowColumns(self.refs, jnp.where(own, 0, u)))
        # two arrays, not one packed word: with two consumers XLA writes the gathered rows out
        # in a pure gather pass, which keeps many cache misses in flight; packed, the row read
        # fuses into the case analysis and stalls on each miss (2.5M vertices: 22 vs 52 ns;
        # in cache the packed word is faster, 13 vs 16 ns at 100K)
        y, second = _materialize_loop((jnp.where(own, u, y), jnp.where(own, 0, second)))
        return self._target_finish_r(y, second, self._second_row(y, second))

    def _edge_target(self, e):
        """Thm 6 Target of edge ids (see :meth:`_dart_end`)."""
        return self._dart_end(2 * _ids(e), True)

    def target(self, d: Int) -> Int:
        return self._dart_end(d, True)

    def origin(self, d: Int) -> Int:
        return self._dart_end(d, False)

    def _plans(self, u, row):
        """The three first reads (:meth:`_target_plan_r`), flat: ``(y_red, second_red, y_blue, ...)``."""
        return tuple(x for c in (RED, BLUE, BLACK) for x in self._target_plan_r(u, c, row))

    def _three_targets(self, u, row, flat=None):
        """``(Target(u_red), Target(u_blue), Target(u_black))`` from ``row = refs[u]``: the three
        first reads written to memory at once (``flat``: already written), then one second read
        each."""
        flat = _materialize_loop(self._plans(u, row)) if flat is None else flat
        ys, seconds = flat[0::2], flat[1::2]
        return tuple(self._target_finish_r(y, k, self._second_row(y, k)) for y, k in zip(ys, seconds))

    def _targets_cols(self, lfs=None):
        """Every target at once, column by column: O(1) per edge, one row gather per colour (no
        loop; ``lfs`` is not needed).

        Under :data:`~jaxcds.structures.base.IN_LOOP_MAX_VERTICES` vertices the first reads are
        computed in a one-trip loop's body (:func:`~jaxcds.structures.base.computed_in_loop`):
        outside it, XLA:CPU split two of their kernels over both threads at 3,485 vertices, and
        each waited for the second thread. Normals x the face list, raced in one process
        (``benchmarks/race_in_loop.py``, 60-80 rounds, three runs, 2026-12-02): decimated-knight
        (502 vertices) 1.59-1.79 -> 1.12-1.27, spot 1.95-2.41 -> 1.45-1.55, bunny 1.84-2.21 ->
        1.37-1.52, elephant 1.63 -> 1.55, cheburashka 1.50-1.57 -> 1.31-1.50, fandisk 1.59-1.63 ->
        1.45-1.51; from 20K vertices up no gain (bumpy-cube 1.49-1.54 -> 1.52-1.64, armadillo
        1.36-1.39 -> 1.46). The same for CDS6n/5n/4n (their LeftFronts and pointer-jumping start
        in the loop, as parts or as words) gave no consistent gain: not used."""
        u = jnp.arange(self.num_vertices, dtype=jnp.int32)
        flat = None
        # XLA:CPU's thread split only; on a GPU a loop costs a host round trip per trip test
        if self.num_vertices < _base.IN_LOOP_MAX_VERTICES and traced_for_cpu():
            flat = _base.computed_in_loop(lambda refs: self._plans(u, refs), self.refs)
        return self._three_targets(u, self.refs, flat)

    def _out_targets(self, u, table=None):
        """Targets of the three edges leaving ``u`` (``num_vertices`` where absent): one row for
        ``u`` and one for each vertex the three cases name (Thm 6: no table is asked for)."""
        u = _ids(u)
        ts = self._three_targets(u, self.refs[u])
        return [jnp.where(self.edge_valid(3 * u + c), t, self.num_vertices) for c, t in enumerate(ts)]

    @classmethod
    def from_wood(cls, wood: SchnyderWood, *, boundaries_closed: bool = False, check: bool = True) -> "CDS5nO1":
        _checked_wood(cls, wood, check)
        if not wood.maximal:
            raise errors.StructureError("CDS5n-O(1) needs the maximal Schnyder wood (Thm 6); this one was "
                                        "built with maximal=False: schnyder_wood(faces, n) builds the maximal one")
        # cwBFS labels applied while the rows are written, D from the cwBFS itself, W from the
        # targets (:func:`_cds_rows`)
        order, label, even = _cwbfs_checked(wood)
        refs, fblue, static = _build_rows(wood, _KIND_5N_O1, label, even)
        return cls(refs=_put(refs), F_blue=_put(fblue),
                   order=_put(order),
                   boundaries_closed=bool(boundaries_closed), **static)


@numba.njit(cache=True)
def _depths(par, n, root):
    depth = np.full(n, -1, dtype=np.int64)
    depth[root] = 0
    stack = np.empty(n, dtype=np.int64)
    for v in range(n):
        k = 0
        x = v
        while depth[x] < 0:
            stack[k] = x
            k += 1
            x = par[x]
        d = depth[x]
        for i in range(k - 1, -1, -1):
            d += 1
            depth[stack[i]] = d
    return depth


# ====================================================================================== registry
def build_cds(cls, mesh, root_face: Optional[int] = None, progress: Optional[bool] = None):
    """Validate (closing holes if any), compute the maximal Schnyder wood, build ``cls``.

    ``progress``: a text progress bar on stderr, one step per stage (mesh checks, Schnyder wood,
    tables); ``None`` (default) shows it for meshes of at least :data:`PROGRESS_MIN_VERTICES`
    vertices when stderr is a terminal.

    Raises:
      UnsupportedTopologyError: genus > 0 (naming it and suggesting ``lr`` / ``halfedge``),
        several components, or fewer than 4 vertices; other :class:`MeshError` for defects.
    """
    _mappings.relieve()  # many meshes in one process: compiled programs pile up (_mappings)
    from jaxcds._args import flag_arg
    from jaxcds.construct.schnyder import prepare_mesh

    progress = flag_arg(progress, "build_cds: progress", none_ok=True)  # 'no' showed the bar

    n0 = int(getattr(mesh, "num_vertices", 0) or 0)
    bar = _Progress(["mesh checks", "Schnyder wood", f"{cls.name} tables"], f"build {cls.name}",
                    _want_progress(progress, n0))
    m, closed = prepare_mesh(mesh, structure=f"{cls.name} (Schnyder woods)")
    _check_size(m.num_vertices)  # before the wood: refused sizes cost no build
    bar.step()
    wood = schnyder_wood(m.faces, m.num_vertices, root_face=root_face, maximal=True)
    bar.step()
    s = cls.from_wood(wood, boundaries_closed=closed or m.closed_boundaries, check=False)  # its own wood
    bar.step()
    return with_dummy_vertices(s, m.dummy_vertices)


def with_dummy_vertices(s, dummy_vertices: Optional[np.ndarray]):
    """``s`` with ``dummy_ids``: the flagged vertices of ``dummy_vertices`` (``(n,)`` bool in the
    input numbering, ``TriMesh.dummy_vertices``; ``None`` or all False: no change) in the
    structure's own numbering (cwBFS labels for CDS4n / CDS5n-O(1))."""
    import dataclasses

    if dummy_vertices is None or not np.any(dummy_vertices):
        return s
    ids = np.flatnonzero(dummy_vertices)
    order = s.vertex_order
    if order is not None:  # input id -> structure label
        label = np.empty(order.size, np.int64)
        label[order] = np.arange(order.size)
        ids = np.sort(label[ids])
    return dataclasses.replace(s, dummy_ids=jnp.asarray(ids.astype(np.int32)))


for _cls, _desc in ((CDS6n, "Schnyder-wood compact structure, Thm 2 (6n + n references)"),
                    (CDS5n, "Schnyder-wood compact structure, Thm 4 (5n + n references)"),
                    (CDS4n, "Schnyder-wood compact structure, Thm 5, cwBFS order (4n + n references)"),
                    (CDS5nO1, "Thm 6: O(1) Target and Adjacent, cwBFS order (5n + n references)")):
    registry.register(_cls.name, (lambda c: (lambda mesh: build_cds(c, mesh)))(_cls),
                      description=_desc)
