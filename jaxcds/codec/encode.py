"""Encoding a triangulation endowed with a Schnyder wood into 4n-3 bits (CDS paper, Sec. 3.1).

Only two pieces of the wood are needed: the red tree (its ccw depth-first traversal gives the red
word, ``2n`` bits, and the vertex order) and the incoming black degrees (the black word,
``2n - 3`` bits). The ccw order around vertices is taken from the faces: for a dart ``e = (u, v)``
of face ``(u, v, w)``, the next dart ccw around ``u`` is ``twin(prev(e)) = (u, w)``. Twins are
found with two counting-sort passes (linear time, no hashing).

The traversal (Sec. 3.1): start at ``V_red``, whose children in ccw order run from ``V_blue``
(first) to ``V_black`` (last); at every other vertex ``u`` turn ccw starting from its outgoing
red edge; a neighbour ``v`` whose red parent is ``u`` is a child. Vertex ``i`` of the decoded
mesh is the ``i``-th vertex reached (preorder).
"""

from __future__ import annotations

import numba
import numpy as np

from jaxcds import errors
from jaxcds.codec.words import MAX_VERTICES, Words, num_bits, pack

__all__ = ["encode_wood", "encode_schnyder", "encode_faces", "dart_twins"]


@numba.njit(cache=True, nogil=True)
def _twins(faces, n, twin):
    """twin[e] for the 3F darts e = 3f + i (faces[f, i] -> faces[f, i+1]). Returns -1 if ok,
    else a dart without a unique opposite (border / non-manifold)."""
    E = faces.shape[0] * 3
    lo = np.empty(E, dtype=np.int32)
    hi = np.empty(E, dtype=np.int32)
    for f in range(faces.shape[0]):
        for i in range(3):
            a = faces[f, i]
            b = faces[f, (i + 1) % 3]
            e = 3 * f + i
            if a < b:
                lo[e] = a
                hi[e] = b
            else:
                lo[e] = b
                hi[e] = a
    # counting sort by hi, then stable counting sort by lo
    cnt = np.zeros(n + 1, dtype=np.int64)
    for e in range(E):
        cnt[hi[e] + 1] += 1
    for k in range(n):
        cnt[k + 1] += cnt[k]
    p1 = np.empty(E, dtype=np.int32)
    for e in range(E):
        p1[cnt[hi[e]]] = e
        cnt[hi[e]] += 1
    cnt[:] = 0
    for e in range(E):
        cnt[lo[e] + 1] += 1
    for k in range(n):
        cnt[k + 1] += cnt[k]
    p2 = np.empty(E, dtype=np.int32)
    for k in range(E):
        e = p1[k]
        p2[cnt[lo[e]]] = e
        cnt[lo[e]] += 1
    if E % 2:
        return p2[E - 1]
    for k in range(0, E, 2):
        a = p2[k]
        b = p2[k + 1]
        if lo[a] != lo[b] or hi[a] != hi[b]:
            return a
        if k + 2 < E and lo[p2[k + 2]] == lo[a] and hi[p2[k + 2]] == hi[a]:
            return a
        fa, ia = a // 3, a % 3
        fb, ib = b // 3, b % 3
        if faces[fa, ia] == faces[fb, ib]:  # same direction: inconsistent orientation
            return a
        twin[a] = b
        twin[b] = a
    return -1


def dart_twins(faces: np.ndarray, num_vertices: int) -> np.ndarray:
    """``(3F,)`` int32 twins of the darts ``3f + i`` of a closed, oriented, manifold mesh.
    ``faces`` must be an integer ``(F, 3)`` array of ids in ``[0, num_vertices)``
    (:func:`jaxcds.mesh.trusted_faces`: an id out of range crashed the counting sort's kernel)."""
    from jaxcds.mesh import trusted_faces

    faces = trusted_faces(faces, num_vertices, "dart_twins")
    twin = np.empty(faces.shape[0] * 3, dtype=np.int32)
    bad = _twins(faces, int(num_vertices), twin)
    if bad >= 0:
        f, i = divmod(int(bad), 3)
        a, b = int(faces[f, i]), int(faces[f, (i + 1) % 3])
        raise errors.UnsupportedTopologyError(
            f"edge ({a}, {b}) of face {f} has no unique opposite half-edge: the 4n-bit encoding "
            "needs a closed, consistently oriented, manifold genus-0 triangulation "
            "(call jaxcds.mesh.close_boundaries first)")
    return twin


@numba.njit(cache=True, nogil=True)
def _encode(faces, twin, n, red_parent, black_parent, v_red, v_blue, v_black, bits, order):
    """ccw DFS of the red tree writing the red word (bits[0:2n]) and the black word
    (bits[2n:4n-3]). Returns (status, vertex): 0 ok; 1 missing red edge; 2 wrong vertex count;
    3 outer vertices misplaced; 4 black degrees do not sum to n - 3."""
    E = twin.shape[0]
    deg = np.zeros(n, dtype=np.int32)
    out_red = np.full(n, -1, dtype=np.int32)  # dart u -> red_parent[u]
    root_black = -1
    for e in range(E):
        u = faces[e // 3, e % 3]
        v = faces[e // 3, (e % 3 + 1) % 3]
        deg[u] += 1
        if red_parent[u] == v:
            out_red[u] = e
        if u == v_red and v == v_black:
            root_black = e
    indeg = np.zeros(n, dtype=np.int32)
    tot = 0
    for u in range(n):
        p = black_parent[u]
        if 0 <= p < n:
            indeg[p] += 1
            tot += 1
    if tot != n - 3:
        return 4, n
    if root_black < 0:
        return 3, v_black
    vstack = np.empty(n, dtype=np.int32)
    cur = np.empty(n, dtype=np.int32)
    left = np.empty(n, dtype=np.int32)
    pr = 0
    pb = 2 * n
    nv = 0
    # open the root
    order[nv] = v_red
    nv += 1
    bits[pr] = 0
    pr += 1
    for _ in range(indeg[v_red]):
        bits[pb] = 1
        pb += 1
    bits[pb] = 0
    pb += 1
    sp = 1
    vstack[0] = v_red
    cur[0] = root_black   # first candidate: rot(V_red -> V_black) = V_red -> V_blue
    left[0] = deg[v_red]  # every neighbour of V_red is a red child
    while sp > 0:
        u = vstack[sp - 1]
        if left[sp - 1] == 0:  # close u
            bits[pr] = 1
            pr += 1
            sp -= 1
            continue
        left[sp - 1] -= 1
        e = cur[sp - 1]
        pe = 3 * (e // 3) + (e % 3 + 2) % 3
        e = twin[pe]  # next dart ccw around u
        cur[sp - 1] = e
        v = faces[e // 3, (e % 3 + 1) % 3]
        if red_parent[v] != u:
            continue
        if nv >= n or out_red[v] < 0:
            return 1, v
        order[nv] = v
        nv += 1
        bits[pr] = 0
        pr += 1
        for _ in range(indeg[v]):
            bits[pb] = 1
            pb += 1
        bits[pb] = 0
        pb += 1
        vstack[sp] = v
        cur[sp] = out_red[v]
        left[sp] = deg[v] - 1
        sp += 1
    if nv != n or pr != 2 * n or pb != 4 * n - 3:
        return 2, nv
    if order[1] != v_blue or order[n - 1] != v_black:
        return 3, order[1]
    return 0, 0


def encode_wood(faces: np.ndarray, num_vertices: int, red_parent: np.ndarray, black_parent: np.ndarray,
                outer: tuple[int, int, int], *, twin: np.ndarray | None = None) -> tuple[Words, np.ndarray]:
    """Words of a triangulation endowed with a Schnyder wood (Sec. 3.1).

    Args:
      faces: ``(2n - 4, 3)`` ccw triangles of a closed genus-0 triangulation.
      red_parent: ``(n,)`` target of each vertex's outgoing red edge in the red tree extended
        with ``(V_blue, V_red)`` and ``(V_black, V_red)``; anything outside ``[0, n)`` for ``V_red``.
      black_parent: ``(n,)`` target of the outgoing black edge; outside ``[0, n)`` for the
        three outer vertices.
      outer: ``(V_red, V_blue, V_black)``, with ``(V_red, V_black, V_blue)`` a face.
      twin: optional precomputed :func:`dart_twins`.

    Returns:
      ``(words, order)``: the separate words (red then black) and ``order[i]`` = input id of the
      vertex numbered ``i`` by the traversal (decoded vertex ``i`` is input vertex ``order[i]``).
    """
    from jaxcds.mesh import trusted_faces

    faces = trusted_faces(faces, num_vertices, "encode_wood")
    n = int(num_vertices)
    if n < 4 or faces.shape != (2 * n - 4, 3):
        raise errors.UnsupportedTopologyError(
            f"the 4n-bit encoding needs a genus-0 triangulation with n >= 4 and 2n - 4 faces; got "
            f"n = {n}, {faces.shape[0]} faces")
    red_parent, black_parent, outer = _wood_args(n, red_parent, black_parent, outer)
    if twin is None:
        twin = dart_twins(faces, n)
    else:
        twin = _twin_arg(faces, twin)
    bits = np.zeros(num_bits(n), dtype=np.uint8)
    order = np.empty(n, dtype=np.int32)
    v_red, v_blue, v_black = outer
    status, vertex = _encode(faces, twin, n, red_parent, black_parent, v_red, v_blue, v_black, bits, order)
    if status == 1:
        raise errors.StructureError(f"Schnyder wood: vertex {vertex} is reached twice or has no red edge")
    if status == 2:
        raise errors.StructureError(f"Schnyder wood: the red tree spans {vertex} of {n} vertices")
    if status == 3:
        raise errors.StructureError(
            f"Schnyder wood: outer vertices misplaced (V_red={v_red}, V_blue={v_blue}, V_black={v_black} "
            f"must be a clockwise outer face (V_red, V_black, V_blue), V_blue the first red child)")
    if status == 4:
        raise errors.StructureError(f"Schnyder wood: black tree does not have n - 3 = {n - 3} edges")
    return Words(n, pack(bits), mixed=False), order


def _wood_args(n: int, red_parent, black_parent, outer):
    """:func:`encode_wood`'s wood arguments checked (the kernel indexes by them unchecked: a short
    parent array or an outer vertex out of range read outside its arrays): the parents as
    ``(n,)`` int64 arrays of integers (entries outside ``[0, n)`` mean "no edge"), ``outer`` as
    three distinct vertex ids in ``[0, n)``. :class:`~jaxcds.errors.ArgumentError` otherwise."""
    from jaxcds.structures.base import integer_array

    parents = []
    for name, p in (("red_parent", red_parent), ("black_parent", black_parent)):
        try:
            a = integer_array(p, f"encode_wood: {name}")
        except errors.InvalidIndexError as exc:
            raise errors.ArgumentError(str(exc)) from None
        if a.shape != (n,):
            raise errors.ArgumentError(f"encode_wood: {name} must have shape ({n},) (one entry per "
                                       f"vertex), got {a.shape}")
        parents.append(np.ascontiguousarray(a, dtype=np.int64))  # a wrapped uint64: negative, no edge
    from jaxcds._args import is_integer

    try:
        o = tuple(outer)
    except TypeError:
        o = ()
    if len(o) != 3 or not all(is_integer(x) and 0 <= x < n for x in o) or len(set(int(x) for x in o)) != 3:
        raise errors.ArgumentError(f"encode_wood: outer must be three distinct vertex ids "
                                   f"(V_red, V_blue, V_black) in [0, {n}), got {outer!r}")
    return parents[0], parents[1], tuple(int(x) for x in o)


def _twin_arg(faces: np.ndarray, twin) -> np.ndarray:
    """:func:`encode_wood`'s ``twin=`` checked against ``faces`` (the kernel follows it unchecked:
    a dart id out of range read outside the faces): a ``(3F,)`` integer array, an involution on
    ``[0, 3F)``, each dart ``u -> v`` paired with a dart ``v -> u``. O(F) numpy;
    :class:`~jaxcds.errors.ArgumentError` naming the first bad dart
    (:func:`jaxcds.mesh.twin_defects`)."""
    from jaxcds.mesh import twin_defects
    from jaxcds.structures.base import integer_array

    E = 3 * faces.shape[0]
    try:
        t = integer_array(twin, "encode_wood: twin")
    except errors.InvalidIndexError as exc:
        raise errors.ArgumentError(str(exc)) from None
    if t.shape != (E,):
        raise errors.ArgumentError(f"encode_wood: twin must have shape ({E},) (one entry per dart "
                                   f"3f + i), got {t.shape}")
    outside, unpaired = twin_defects(t, faces)
    bad = np.nonzero(outside | (t == -1))[0]  # a closed mesh: no border, so -1 is no dart either
    if bad.size:
        e = int(bad[0])
        raise errors.ArgumentError(f"encode_wood: twin[{e}] = {int(t[e])} is not a dart id in [0, {E})")
    bad = np.nonzero(unpaired)[0]
    if bad.size:
        e = int(bad[0])
        f, k = divmod(e, 3)
        raise errors.ArgumentError(
            f"encode_wood: twin[{e}] = {int(t[e])} is not the opposite of dart {e} "
            f"({int(faces[f, k])} -> {int(faces[f, (k + 1) % 3])}): twin must be an involution pairing "
            "each dart u -> v with a dart v -> u (jaxcds.codec.dart_twins computes it)")
    return np.ascontiguousarray(t, dtype=np.int32)


@numba.njit(cache=True, nogil=True, inline="always")
def _set1(buf, i):
    # bit i of a zeroed, packed MSB-first buffer (np.packbits order) := 1
    buf[i >> 3] |= np.uint8(0x80 >> (i & 7))


@numba.njit(cache=True, nogil=True)
def _encode_pos(offsets, nb, out, n, v_red, v_blue, v_black, buf, order, mixed, work, blk, have_blk):
    """ccw DFS of the red tree from the ccw rotations (any starting neighbour) and ``out``,
    writing the words straight into the zeroed packed buffer ``buf`` (MSB first): red word at
    bits ``[0, 2n)`` and black word at ``[2n, 4n - 3)``, or the mixed word of Sec. 3.3.

    Two sequential passes over the vertices first build the red tree as a compact children
    table (CSR, ccw order) with the black in-degrees beside it, so that the DFS -- the only
    pass in random vertex order -- touches two cache lines per vertex (its record and its
    children) instead of its whole rotation and ``out`` row. The red children of an inner
    vertex ``u`` are found by position: by the local Schnyder rule (Definition 1) they are the
    neighbours strictly between ``u``'s outgoing blue and outgoing black edge, ccw (``V_red``:
    all neighbours from ``V_blue`` on; ``V_blue``, ``V_black``: none). Each one is checked
    (``out[w, RED] == u``; ``w`` is a neighbour, so this read is near) and the tree must span
    the ``n`` vertices, so an input breaking the rule is refused rather than mis-encoded.

    ``work``: int32 scratch of ``>= 5n + 2`` words (e.g. the Schnyder-wood kernels' scratch):
    ``rec[u] = (first child slot, black in-degree)``, the children, and the DFS stack. With
    ``have_blk``, ``blk`` (``(n, 3)``: first red-child slot, red-child count, black in-degree)
    was filled by the vertex conquest (:func:`jaxcds.construct.schnyder._conquest_csr`) while
    each rotation was in cache, and the first two passes below are skipped.

    Returns (status, vertex): 0 ok; 1 a block entry is not a red child / vertex reached twice /
    outgoing edge missing from the rotation; 2 wrong vertex count; 3 outer vertices misplaced;
    4 black degrees do not sum to n - 3."""
    rec = work[:2 * n + 2].reshape((n + 1, 2))
    kids = work[2 * n + 2:3 * n + 2]
    scur = work[3 * n + 2:4 * n + 2]   # DFS frame: next child slot (pass A: block start)
    send = work[4 * n + 2:5 * n + 2]   # DFS frame: end of the children slots
    rec[0, 0] = 0
    if have_blk:
        tot = 0
        for v in range(n):
            scur[v] = blk[v, 0]
            rec[v + 1, 0] = blk[v, 1]
            rec[v, 1] = blk[v, 2]
            tot += blk[v, 2]
        if tot != n - 3:
            return 4, n
    else:
        tot = _block_pass(offsets, nb, out, n, v_red, v_blue, v_black, rec, scur)
        if tot < 0:
            return 1, -1 - tot
        if tot != n - 3:
            return 4, n
    for v in range(n):
        rec[v + 1, 0] += rec[v, 0]
    if rec[n, 0] != n - 1:
        return 2, rec[n, 0]
    # pass B: copy the children, checking each is a red child
    for v in range(n):
        a = offsets[v]
        deg = offsets[v + 1] - a
        k = scur[v]
        for i in range(rec[v, 0], rec[v + 1, 0]):
            w = nb[a + k]
            if out[w, 0] != v:
                return 1, w
            kids[i] = w
            k += 1
            if k == deg:
                k = 0
    return _dfs(n, v_red, v_blue, v_black, buf, order, mixed, rec, kids, scur, send)


@numba.njit(cache=True, nogil=True)
def _block_pass(offsets, nb, out, n, v_red, v_blue, v_black, rec, scur):
    """Black in-degrees (``rec[:, 1]``, counted from ``out``: the truth, not by position) and
    each vertex's block of red children in its rotation (``scur`` = first slot, relative;
    ``rec[v + 1, 0]`` = count). Returns the number of black edges, or ``-1 - v`` if an outgoing
    edge of ``v`` is missing from its rotation."""
    for u in range(n + 1):
        rec[u, 0] = 0
        rec[u, 1] = 0
    tot = 0
    for u in range(n):
        p = out[u, 2]
        if 0 <= p < n:
            rec[p, 1] += 1
            tot += 1
    # pass A: each vertex's block of red children in its rotation (start, count)
    for v in range(n):
        a = offsets[v]
        b = offsets[v + 1]
        if v == v_red:
            q = a
            while q < b and nb[q] != v_blue:
                q += 1
            if q == b:
                return -1 - v
            start = q - a
            cnt = b - a
        elif v == v_blue or v == v_black:
            start = 0
            cnt = 0
        else:
            o1 = out[v, 1]
            o2 = out[v, 2]
            q1 = -1
            q2 = -1
            for q in range(a, b):
                x = nb[q]
                if x == o1:
                    q1 = q
                elif x == o2:
                    q2 = q
            if q1 < 0 or q2 < 0:
                return -1 - v
            start = q1 + 1 - a
            if start == b - a:
                start = 0
            cnt = q2 - q1 - 1
            if cnt < 0:
                cnt += b - a
        scur[v] = start
        rec[v + 1, 0] = cnt
    return tot


@numba.njit(cache=True, nogil=True)
def _dfs(n, v_red, v_blue, v_black, buf, order, mixed, rec, kids, scur, send):
    """The ccw DFS of the red tree over the children table, writing the packed words; the only
    pass in random vertex order (two cache lines per vertex: ``rec[v]`` and its children).
    Returns (status, vertex) as :func:`_encode_pos`."""
    # the DFS (preorder = decoded vertex ids)
    pr = 0          # red (or mixed) cursor; '(' = 0 is written by skipping (buf is zeroed)
    pb = 2 * n      # black cursor (separate form)
    nv = 0
    sp = 0
    v = v_red
    while True:
        # ---- open v
        if nv >= n:
            return 1, v
        order[nv] = v
        nv += 1
        pr += 1
        d = rec[v, 1]
        if mixed:
            for _ in range(d):
                _set1(buf, pr)
                pr += 1
            pr += 1
        else:
            for _ in range(d):
                _set1(buf, pb)
                pb += 1
            pb += 1
        scur[sp] = rec[v, 0]
        send[sp] = rec[v + 1, 0]
        sp += 1
        # ---- advance to the next red child, closing finished vertices
        v = -1
        while sp > 0:
            c = scur[sp - 1]
            if c < send[sp - 1]:
                scur[sp - 1] = c + 1
                v = kids[c]
                break
            _set1(buf, pr)  # ')'
            pr += 1
            sp -= 1
        if v < 0:
            break
    if nv != n or (mixed and pr != 4 * n - 3) or ((not mixed) and (pr != 2 * n or pb != 4 * n - 3)):
        return 2, nv
    if order[1] != v_blue or order[n - 1] != v_black:
        return 3, order[1]
    return 0, 0


def _encode_lean(offsets, neighbors, out, n, v_red, v_blue, v_black, mixed, work=None,
                 blk=None) -> tuple[Words, np.ndarray]:
    buf = np.zeros((num_bits(n) + 7) // 8, dtype=np.uint8)
    order = np.empty(n, dtype=np.int32)
    if work is None or work.size < 5 * n + 2:
        work = np.empty(5 * n + 2, dtype=np.int32)
    have_blk = blk is not None
    if not have_blk:
        blk = np.zeros((1, 3), dtype=np.int32)
    status, vertex = _encode_pos(np.asarray(offsets, dtype=np.int64), np.asarray(neighbors, dtype=np.int32),
                                 np.ascontiguousarray(out, dtype=np.int32), n, int(v_red), int(v_blue),
                                 int(v_black), buf, order, bool(mixed), work, blk, have_blk)
    if status:
        raise errors.StructureError(f"Schnyder wood is not a valid encoding input (status {status}, vertex {vertex}): "
                                    "red tree not spanning, outer vertices misplaced, or black tree without n-3 edges")
    return Words(n, buf, mixed=bool(mixed)), order


def encode_schnyder(wood, *, mixed: bool = False) -> tuple[Words, np.ndarray]:
    """Words of a :class:`jaxcds.construct.schnyder.SchnyderWood` (Sec. 3.1) -- or of the lean
    :class:`~jaxcds.construct.schnyder.WoodOut` -- from its ccw rotations and ``out`` (no twin
    computation); ``mixed`` writes the streamable word of Sec. 3.3 directly. One linear pass
    writes the packed bits (no 0/1 byte array, no ``np.packbits``). Returns ``(words, order)``
    as :func:`encode_wood`. A wood it did not make is checked first
    (:func:`~jaxcds.construct.schnyder.check_wood_arrays`: ``StructureError`` naming the entry;
    one out of range crashed the encoder's kernel)."""
    from jaxcds._args import is_integer
    from jaxcds.construct.schnyder import check_wood_arrays

    n = getattr(wood, "num_vertices", None)
    if is_integer(n) and n < 4:  # before the wood check, whose refusal of n = 3 did not say this
        raise errors.UnsupportedTopologyError(f"the 4n-bit encoding needs n >= 4 vertices, got {n}")
    check_wood_arrays(wood, "encode_schnyder")
    n = int(wood.num_vertices)
    return _encode_lean(wood.offsets, wood.neighbors, wood.out, n, wood.v_red, wood.v_blue, wood.v_black, mixed)


def encode_faces(faces: np.ndarray, num_vertices: int, *, mixed: bool = True, maximal: bool = True,
                 root_face: int | None = None, timings: dict | None = None) -> tuple[Words, np.ndarray]:
    """Words of a closed genus-0 triangulation, Schnyder wood included (Appendix A + Sec. 3.1):
    the vertex conquest (:func:`~jaxcds.construct.schnyder.schnyder_out`) then one DFS pass that
    writes the packed words; the colour labels of a full :class:`SchnyderWood` are never built
    (the encoder reads the local Schnyder rule by position). The words equal
    ``encode_schnyder(schnyder_wood(faces, n, ...))``. ``timings``, if given, receives
    ``wood_s`` and ``words_s``. Returns ``(words, order)`` as :func:`encode_wood`.

    The arguments are checked before anything sized by ``num_vertices`` is allocated:
    :class:`~jaxcds.errors.ArgumentError` for a ``num_vertices`` that is not an integer,
    :class:`~jaxcds.errors.UnsupportedTopologyError` for one outside ``[4, MAX_VERTICES]`` or
    not matching ``2n - 4`` faces, :class:`~jaxcds.errors.InvalidIndexError` for faces that are
    not an integer ``(F, 3)`` array (floats are refused, not truncated) or out of ``[0, n)``."""
    import time

    from jaxcds._args import is_integer
    from jaxcds.construct.schnyder import schnyder_out
    from jaxcds.structures.base import integer_array

    if not is_integer(num_vertices):  # int() truncated 30.5 to 30
        raise errors.ArgumentError(f"encode_faces: num_vertices must be an integer, got {num_vertices!r}")
    n = int(num_vertices)
    if n < 4:
        raise errors.UnsupportedTopologyError(f"the 4n-bit encoding needs n >= 4 vertices, got {n}")
    if n > MAX_VERTICES:  # checked before the 6n + 16 scratch below (2**40 raised MemoryError)
        raise errors.UnsupportedTopologyError(
            f"encode_faces: num_vertices {n:,} is past the {MAX_VERTICES:,} vertices the 4n-bit codec "
            "holds (int32 vertex ids)")
    faces = integer_array(faces, "encode_faces: face indices")  # float faces were truncated
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise errors.InvalidIndexError(f"encode_faces: faces must be (F, 3), got shape {faces.shape}")
    if faces.shape[0] != 2 * n - 4:  # schnyder_out names the genus, before allocating anything
        schnyder_out(faces, n, root_face=root_face, maximal=maximal)
        raise errors.UnsupportedTopologyError(  # not reached
            f"encode_faces: num_vertices = {n:,} needs 2n - 4 = {2 * n - 4:,} faces, got {faces.shape[0]:,}")
    if not np.can_cast(faces.dtype, np.int32):  # int64 / uint ids would wrap in the int32 cast
        bad = np.nonzero((faces < 0) | (faces >= n))
        if bad[0].size:
            f, k = int(bad[0][0]), int(bad[1][0])
            raise errors.InvalidIndexError(f"encode_faces: face {f} refers to vertex {int(faces[f, k])}, "
                                           f"outside [0, {n})")
    t0 = time.perf_counter()
    work = np.empty(6 * n + 16, dtype=np.int32)  # one scratch for rotations, conquest and words
    blk = np.empty((n, 3), dtype=np.int32)       # red-children blocks + black in-degrees, from the conquest
    w = schnyder_out(faces, n, root_face=root_face, maximal=maximal, work=work, blk=blk)
    t1 = time.perf_counter()
    out = _encode_lean(w.offsets, w.neighbors, w.out, n, w.v_red, w.v_blue, w.v_black, mixed, work, blk)
    if timings is not None:
        timings["wood_s"] = t1 - t0
        timings["words_s"] = time.perf_counter() - t1
    return out
