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
from jaxcds.codec.words import Words, num_bits, pack

__all__ = ["encode_wood", "encode_schnyder", "dart_twins"]


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
    """``(3F,)`` int32 twins of the darts ``3f + i`` of a closed, oriented, manifold mesh."""
    faces = np.ascontiguousarray(faces, dtype=np.int32)
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
    n = int(num_vertices)
    faces = np.ascontiguousarray(faces, dtype=np.int32)
    if n < 4 or faces.shape != (2 * n - 4, 3):
        raise errors.UnsupportedTopologyError(
            f"the 4n-bit encoding needs a genus-0 triangulation with n >= 4 and 2n - 4 faces; got "
            f"n = {n}, {faces.shape[0]} faces")
    if twin is None:
        twin = dart_twins(faces, n)
    bits = np.zeros(num_bits(n), dtype=np.uint8)
    order = np.empty(n, dtype=np.int32)
    v_red, v_blue, v_black = (int(x) for x in outer)
    status, vertex = _encode(faces, twin, n, np.asarray(red_parent, dtype=np.int64),
                             np.asarray(black_parent, dtype=np.int64), v_red, v_blue, v_black, bits, order)
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


@numba.njit(cache=True, nogil=True)
def _encode_rot(offsets, neighbors, out, n, v_red, v_blue, v_black, bits, order, mixed):
    """As :func:`_encode`, from the ccw rotations of a :class:`SchnyderWood` (neighbours of
    ``u`` ccw starting at its red parent; at ``V_red`` starting at ``V_blue``). With ``mixed``
    the black block of a vertex is written right after its red ``0`` (Sec. 3.3)."""
    indeg = np.zeros(n, dtype=np.int32)
    tot = 0
    for u in range(n):
        p = out[u, 2]
        if 0 <= p < n:
            indeg[p] += 1
            tot += 1
    if tot != n - 3:
        return 4, n
    vstack = np.empty(n, dtype=np.int32)
    cur = np.empty(n, dtype=np.int64)
    pr = 0
    pb = 2 * n
    nv = 0
    sp = 0
    v = v_red
    while True:
        # open v
        if nv >= n:
            return 1, v
        order[nv] = v
        nv += 1
        bits[pr] = 0
        pr += 1
        if mixed:
            for _ in range(indeg[v]):
                bits[pr] = 1
                pr += 1
            bits[pr] = 0
            pr += 1
        else:
            for _ in range(indeg[v]):
                bits[pb] = 1
                pb += 1
            bits[pb] = 0
            pb += 1
        vstack[sp] = v
        cur[sp] = offsets[v] if v == v_red else offsets[v] + 1
        sp += 1
        # advance to the next child, closing finished vertices
        v = -1
        while sp > 0:
            u = vstack[sp - 1]
            k = cur[sp - 1]
            while k < offsets[u + 1]:
                w = neighbors[k]
                k += 1
                if out[w, 0] == u:
                    v = w
                    break
            cur[sp - 1] = k
            if v >= 0:
                break
            bits[pr] = 1
            pr += 1
            sp -= 1
        if v < 0:
            break
    if nv != n or (mixed and pr != 4 * n - 3) or ((not mixed) and (pr != 2 * n or pb != 4 * n - 3)):
        return 2, nv
    if order[1] != v_blue or order[n - 1] != v_black:
        return 3, order[1]
    return 0, 0


def encode_schnyder(wood, *, mixed: bool = False) -> tuple[Words, np.ndarray]:
    """Words of a :class:`jaxcds.construct.schnyder.SchnyderWood` (Sec. 3.1), using its ccw
    rotations (no twin computation); ``mixed`` writes the streamable word of Sec. 3.3 directly.
    Returns ``(words, order)`` as :func:`encode_wood`."""
    n = int(wood.num_vertices)
    if n < 4:
        raise errors.UnsupportedTopologyError(f"the 4n-bit encoding needs n >= 4 vertices, got {n}")
    bits = np.zeros(num_bits(n), dtype=np.uint8)
    order = np.empty(n, dtype=np.int32)
    status, vertex = _encode_rot(np.asarray(wood.offsets, dtype=np.int64), np.asarray(wood.neighbors, dtype=np.int32),
                                 np.asarray(wood.out, dtype=np.int32), n, int(wood.v_red), int(wood.v_blue),
                                 int(wood.v_black), bits, order, bool(mixed))
    if status:
        raise errors.StructureError(f"Schnyder wood is not a valid encoding input (status {status}, vertex {vertex}): "
                                    "red tree not spanning, outer vertices misplaced, or black tree without n-3 edges")
    return Words(n, pack(bits), mixed=bool(mixed)), order
