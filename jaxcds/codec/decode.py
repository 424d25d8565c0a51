"""Linear-time decoding of the 4n-bit words (CDS paper, Sec. 3.2, Fig. 10-13).

The decoder follows the paper's three procedures, written without recursion (numba):

1. ``ConstructRedTree`` + ``ConstructBlackTree`` (Fig. 10, 11): one scan of the red word (and,
   in parallel, of the black word -- or one scan of the mixed word, Sec. 3.3) fills the red and
   black columns ``S_c^{left/right}``, ``C_c^{left/right}``, ``I_c``. The red stack and the black
   stack live in the two *blue* columns ``S_blue^left`` / ``S_blue^right``, which are not used
   yet at that step: no memory beyond the target arrays (Sec. 3.2).
2. ``ConstructBlueTree`` (Fig. 12): for every vertex ``x``, its incoming blue edges are found
   clockwise around ``x`` from the red and black columns only.

The result is the paper's Thm 2 (CDS6n) table, :class:`Paper6n`: for a vertex ``u`` and colour
``c`` (``0 = red, 1 = blue, 2 = black``, ``next(c) = c + 1 mod 3``), with ``u_c`` the outgoing edge
of colour ``c`` at ``u``,

* ``S[c, 0, u] = Source(LeftFront(u_c))``, ``C[c, 0, u]`` = ``LeftFront`` has colour ``c``
  (else ``next(c)``);
* ``S[c, 1, u] = Source(RightFront(u_c))``, ``C[c, 1, u]`` = ``RightFront`` has colour ``c``
  (else ``prev(c)``);
* ``I[c, u]`` = ``u`` has an incoming edge of colour ``c``.

Outer face. The paper leaves the three outer vertices to "a special manner". We use the same
definitions on the outer face ``(V_red, V_black, V_blue) = (0, n-1, 1)`` as everywhere else, so
``S[red, left, 1] = n - 1`` with ``C = True`` (Fig. 10 writes ``0`` / ``False`` there), and the blue
children of ``V_blue`` (absent from the loop of Fig. 12, which runs over ``x = 2 .. n-2``) are
enumerated by the same clockwise walk, which ends at ``V_black``.

Optionally (``targets=True``) the decoder also records ``T[c, u] = Target(u_c)`` (``n`` where
``u_c`` does not exist): 3n extra int32, used to list the faces in O(1) each. Decoding into the
CDS6n table alone does not need them.
"""

from __future__ import annotations

import dataclasses
from typing import Optional

import numba
import numpy as np

from jaxcds import errors
from jaxcds.codec.words import Words, num_bits

__all__ = ["Paper6n", "decode_paper6n", "decode_faces", "faces_from_paper6n", "RED", "BLUE", "BLACK"]

RED, BLUE, BLACK = 0, 1, 2
LEFT, RIGHT = 0, 1


@dataclasses.dataclass(frozen=True)
class Paper6n:
    """The CDS6n table of Thm 2, exactly as the decoder of Sec. 3.2 fills it (host numpy).

    Attributes:
      S: ``(3, 2, n)`` int32, ``S[c, side, u]`` = source of the front edge on ``side``
        (0 left, 1 right) of ``u_c``; ``S_c^{left/right}[u]`` in the paper.
      C: ``(3, 2, n)`` bool, ``C_c^{left/right}[u]`` (front edge has the colour of ``u_c``).
      I: ``(3, n)`` bool, ``I_c[u]`` (incoming edge of colour ``c`` at ``u``).
      T: ``(3, n)`` int32 targets ``Target(u_c)`` (``n`` if absent), or ``None``.
    Vertices: ``0 = V_red``, ``1 = V_blue``, ``n - 1 = V_black``, others in ccw DFS order of
    ``T_red``. Entries of edges that do not exist (``0_red``, ``0_blue``, ``1_blue``, ``u_black``
    for ``u in {0, 1, n-1}``) are 0/False.
    """

    S: np.ndarray
    C: np.ndarray
    I: np.ndarray
    T: Optional[np.ndarray]

    @property
    def num_vertices(self) -> int:
        return int(self.S.shape[2])

    @property
    def nbytes(self) -> int:
        return int(self.S.nbytes + self.C.nbytes + self.I.nbytes + (0 if self.T is None else self.T.nbytes))


# --------------------------------------------------------------------------- error codes
_OK = 0
_E_RED_FIRST = 1      # first red symbol is not '('
_E_RED_UNBALANCED = 2  # ')' closes nothing / word continues after the root closed
_E_RED_TOO_MANY = 3   # more than n '('
_E_RED_SHORT = 4      # red word ended before the root closed
_E_BLACK_SHORT = 5    # black word ended inside a unary block
_E_BLACK_OUTER = 6    # V_red or V_blue with incoming black edges
_E_BLACK_UNDERFLOW = 7  # black stack underflow: vertex pops more black children than exist
_E_BLACK_LEFT = 8     # black children left unclaimed at the end
_E_OUTER = 9          # V_blue / V_black are not leaves of T_red at the right places
_E_BLUE = 10          # blue closure inconsistent (not a valid Schnyder wood)
_E_COUNT = 11         # too few vertices / trailing bits
_E_FACES = 12         # face listing inconsistent


@numba.njit(cache=True, nogil=True, inline="always")
def _bit(buf, i):
    return (buf[i >> 3] >> (7 - (i & 7))) & 1


@numba.njit(cache=True, nogil=True)
def _red_black_trees(buf, n, base, mixed, S, C, I, T, want_t):
    """ConstructRedTree + ConstructBlackTree (Fig. 10, 11), iterative.

    Returns ``(status, bit, vertex)``; ``bit`` is an offset in the word (from ``base``)."""
    rstack = S[BLUE, LEFT]   # red stack: lives in a blue column (Sec. 3.2)
    bstack = S[BLUE, RIGHT]  # black stack: the other blue column
    end_r = base + (4 * n - 3 if mixed else 2 * n)
    pr = base
    pb = base + 2 * n  # black word cursor (separate form)
    end_b = base + 4 * n - 3
    if _bit(buf, pr) != 0:
        return _E_RED_FIRST, 0, 0
    pr += 1
    rtop = 1
    rstack[0] = 0
    btop = 0
    N = 0
    u = 0
    prev_open = True
    last_closed = 0
    root_last = 0
    while True:
        # ---- readBlackInDegree() for the vertex u just opened, then ConstructBlackTree(u, d)
        if prev_open:
            d = 0
            while True:
                if mixed:
                    if pr >= end_b:
                        return _E_BLACK_SHORT, pr - base, u
                    x = _bit(buf, pr)
                    pr += 1
                else:
                    if pb >= end_b:
                        return _E_BLACK_SHORT, pb - base, u
                    x = _bit(buf, pb)
                    pb += 1
                if x == 0:
                    break
                d += 1
            if d > 0:
                if u <= 1:  # V_red and V_blue have no incoming black edge
                    return _E_BLACK_OUTER, (pr if mixed else pb) - base - 1, u
                if d > btop:
                    return _E_BLACK_UNDERFLOW, (pr if mixed else pb) - base - 1, u
                I[BLACK, u] = True
                # first black child: LeftFront is u's outgoing red edge (next(black) = red)
                btop -= 1
                x = bstack[btop]
                S[BLACK, LEFT, x] = u
                C[BLACK, LEFT, x] = False
                if want_t:
                    T[BLACK, x] = u
                for _ in range(d - 1):
                    y = x
                    btop -= 1
                    x = bstack[btop]
                    S[BLACK, LEFT, x] = y
                    C[BLACK, LEFT, x] = True
                    S[BLACK, RIGHT, y] = x
                    C[BLACK, RIGHT, y] = True
                    if want_t:
                        T[BLACK, x] = u
                # last black child: RightFront is u's outgoing blue edge (prev(black) = blue)
                S[BLACK, RIGHT, x] = u
                C[BLACK, RIGHT, x] = False
            else:
                I[BLACK, u] = False
        # ---- readNextRedSymbol()
        if pr >= end_r:
            return _E_RED_SHORT, pr - base, u
        s = _bit(buf, pr)
        pr += 1
        if s == 0:  # '(' : a new red child v of the top of the red stack
            if N + 1 >= n:
                return _E_RED_TOO_MANY, pr - base - 1, N
            N += 1
            v = N
            top = rstack[rtop - 1]
            if prev_open:  # first red child of top: LeftFront is top's blue edge
                I[RED, top] = True
                S[RED, LEFT, v] = top
                C[RED, LEFT, v] = False
            else:  # next sibling of last_closed, ccw around top
                w = last_closed
                S[RED, LEFT, v] = w
                C[RED, LEFT, v] = True
                S[RED, RIGHT, w] = v
                C[RED, RIGHT, w] = True
            if want_t:
                T[RED, v] = top
            rstack[rtop] = v
            rtop += 1
            u = v
            prev_open = True
        else:  # ')' : close the top vertex
            rtop -= 1
            u = rstack[rtop]
            if prev_open:
                I[RED, u] = False  # leaf of T_red
            else:  # last_closed is the last red child of u
                if u == 0:  # V_black -> V_red: RightFront is (V_blue, V_red), red
                    root_last = last_closed
                    S[RED, RIGHT, last_closed] = 1
                    C[RED, RIGHT, last_closed] = True
                else:  # RightFront is u's black edge (prev(red) = black)
                    S[RED, RIGHT, last_closed] = u
                    C[RED, RIGHT, last_closed] = False
            if u > 1:  # V_red and V_blue have no outgoing black edge
                bstack[btop] = u
                btop += 1
            last_closed = u
            prev_open = False
            if rtop == 0:
                break
    if N != n - 1:
        return _E_COUNT, pr - base, N
    if pr != end_r or ((not mixed) and pb != end_b):
        return _E_COUNT, pr - base, N
    if btop != 1 or bstack[0] != n - 1:
        return _E_BLACK_LEFT, pr - base, bstack[0] if btop > 0 else n - 1
    # V_blue = 1 is the first child of V_red and a leaf; V_black = n-1 the last child, a leaf
    if I[RED, 1] or I[RED, n - 1] or root_last != n - 1:
        return _E_OUTER, pr - base, 1 if I[RED, 1] else n - 1
    # outer face (0, n-1, 1): LeftFront(1_red) = (n-1 -> 0), red (Fig. 10 leaves it as 0/False)
    S[RED, LEFT, 1] = n - 1
    C[RED, LEFT, 1] = True
    # the stacks are done: clear the blue columns for ConstructBlueTree
    for k in range(n):
        rstack[k] = 0
        bstack[k] = 0
    return _OK, pr - base, 0


@numba.njit(cache=True, nogil=True)
def _blue_tree(n, S, C, I, T, want_t):
    """ConstructBlueTree (Fig. 12), plus the blue children of V_blue. Returns (status, vertex)."""
    budget = n  # there are n - 2 blue edges; a longer walk means an invalid word
    for x in range(1, n - 1):
        if x == 1:
            # V_blue: every neighbour but V_red is a blue child; the first one cw from V_red is
            # the second red child of V_red, the last one is V_black.
            if not C[RED, RIGHT, 1]:
                return _E_OUTER, 1
            u = S[RED, RIGHT, 1]
        else:
            if S[RED, RIGHT, x] == S[BLACK, LEFT, x] and C[RED, RIGHT, x] != C[BLACK, LEFT, x]:
                I[BLUE, x] = False  # x has no blue child
                continue
            if C[RED, RIGHT, x]:  # RightFront(x_red) is red: its source is the first blue child
                u = S[RED, RIGHT, x]
            else:  # RightFront(x_red) is black, out of z = red parent of x
                z = S[RED, RIGHT, x]
                u = S[BLACK, RIGHT, z]
        I[BLUE, x] = True
        if u <= 1 or u >= n:
            return _E_BLUE, x
        # (u, x) is the first blue edge towards x: RightFront is x's red edge
        S[BLUE, RIGHT, u] = x
        C[BLUE, RIGHT, u] = False
        if want_t:
            T[BLUE, u] = x
        while True:
            budget -= 1
            if budget < 0:
                return _E_BLUE, x
            if x == 1 and u == n - 1:  # (V_black, V_blue): last blue child of V_blue
                S[BLUE, LEFT, u] = 1
                C[BLUE, LEFT, u] = False
                break
            # {v, x} is the next edge cw around x
            if I[RED, u]:  # (v, u) is red: v is the first red child of u
                v = u + 1
                if x != 1 and S[BLACK, LEFT, x] == v and not C[BLACK, LEFT, x]:
                    S[BLUE, LEFT, u] = x  # (u, x) last blue edge
                    C[BLUE, LEFT, u] = False
                    break
            else:  # (u, v) is black
                if x != 1 and S[BLACK, LEFT, x] == u:
                    S[BLUE, LEFT, u] = x  # (u, x) last blue edge
                    C[BLUE, LEFT, u] = False
                    break
                if u == n - 1:
                    return _E_BLUE, x
                v = S[BLACK, RIGHT, u]
            if v <= 1 or v >= n:
                return _E_BLUE, x
            S[BLUE, LEFT, u] = v
            C[BLUE, LEFT, u] = True
            S[BLUE, RIGHT, v] = u
            C[BLUE, RIGHT, v] = True
            if want_t:
                T[BLUE, v] = x
            u = v
    if budget != 2:  # exactly n - 2 blue edges
        return _E_BLUE, n - 1
    return _OK, 0


@numba.njit(cache=True, nogil=True)
def _faces(n, S, C, T, out):
    """Every face once: the face is emitted by its edge opposite its largest vertex.

    Left face of ``u_c = (u, v)`` is ``(u, v, w)``: ``w = S`` if ``LeftFront`` has colour ``c``
    (it is ``(w, v)``), else ``LeftFront = v_next(c)`` and ``w = Target(v_next(c))``.
    Right face is ``(v, u, z)`` likewise with ``prev(c)``. Returns the count written or -1-u."""
    f = 0
    nf = out.shape[0]
    for u in range(n):
        for c in range(3):
            v = T[c, u]
            if v >= n:
                continue
            if c == BLUE and u == n - 1:
                # (V_black, V_blue): its left face is the outer face, emitted by (V_blue, V_red)
                w = 0
            elif C[c, LEFT, u]:
                w = S[c, LEFT, u]
            else:
                if S[c, LEFT, u] != v:
                    return -1 - u
                w = T[(c + 1) % 3, v]
            if w >= n:
                return -1 - u
            if w > u and w > v:
                if f >= nf:
                    return -1 - u
                out[f, 0] = u
                out[f, 1] = v
                out[f, 2] = w
                f += 1
            if C[c, RIGHT, u]:
                z = S[c, RIGHT, u]
            else:
                if S[c, RIGHT, u] != v:
                    return -1 - u
                z = T[(c + 2) % 3, v]
            if z >= n:
                return -1 - u
            if z > u and z > v:
                if f >= nf:
                    return -1 - u
                out[f, 0] = v
                out[f, 1] = u
                out[f, 2] = z
                f += 1
    return f


_MESSAGES = {
    _E_RED_FIRST: "red word must start with '(' (the root V_red)",
    _E_RED_UNBALANCED: "red word: unbalanced parentheses",
    _E_RED_TOO_MANY: "red word opens more than n vertices",
    _E_RED_SHORT: "red word ends before the root V_red is closed: unbalanced parentheses",
    _E_BLACK_SHORT: "black word ends inside a unary block",
    _E_BLACK_OUTER: "V_red and V_blue (vertices 0, 1) cannot have incoming black edges",
    _E_BLACK_UNDERFLOW: "black in-degree larger than the number of open black subtrees (wrong black count)",
    _E_BLACK_LEFT: "black word leaves vertices without a black parent (black counts sum to less than n-3)",
    _E_OUTER: "V_blue must be the first and V_black the last child of V_red, both leaves of the red tree",
    _E_BLUE: "blue edges cannot be closed: the words are not a Schnyder wood",
    _E_COUNT: "red word: unbalanced parentheses (the root V_red closes before n vertices are opened)",
}


def _check_size(words: Words) -> None:
    n = words.num_vertices
    if n < 4:
        raise errors.EncodingError(f"a triangulation needs n >= 4 vertices, got n = {n}")
    need = (num_bits(n) + 7) // 8
    if np.asarray(words.bits).size < need:
        raise errors.EncodingError(f"word buffer holds {np.asarray(words.bits).size} bytes, "
                                   f"{need} needed for 4n-3 = {num_bits(n)} bits")


def _raise(status: int, bit: int, vertex: int, words: Words, where: str) -> None:
    n = words.num_vertices
    if words.mixed:
        loc = f"bit {bit} of the mixed word"
    elif bit >= 2 * n:
        loc = f"bit {bit - 2 * n} of the black word (bit {bit} of the connectivity)"
    else:
        loc = f"bit {bit} of the red word"
    exc = errors.EncodingError(f"{where}: {_MESSAGES.get(status, 'invalid word')} at {loc} "
                               f"(vertex {vertex}, n = {n})")
    exc.bit = int(bit)  # offset in the connectivity bits (red ++ black, or mixed)
    raise exc


def decode_paper6n(words: Words, *, targets: bool = True) -> Paper6n:
    """Decode the words into the Thm 2 table (Sec. 3.2, Fig. 10-12), in linear time.

    Without ``targets`` the only memory used is the table itself (the red and black stacks
    live in the blue columns, Sec. 3.2). Raises :class:`EncodingError` with the bit offset for
    words that are not a valid encoding."""
    _check_size(words)
    n = words.num_vertices
    buf = np.ascontiguousarray(words.bits, dtype=np.uint8)
    S = np.zeros((3, 2, n), dtype=np.int32)
    C = np.zeros((3, 2, n), dtype=np.bool_)
    I = np.zeros((3, n), dtype=np.bool_)
    T = np.full((3, n) if targets else (3, 1), n, dtype=np.int32)
    status, bit, vertex = _red_black_trees(buf, n, 0, bool(words.mixed), S, C, I, T, targets)
    if status != _OK:
        _raise(status, bit, vertex, words, "red/black trees")
    if targets:
        T[BLUE, n - 1] = 1  # (V_black, V_blue)
    status, vertex = _blue_tree(n, S, C, I, T, targets)
    if status != _OK:
        raise errors.EncodingError(f"blue tree: {_MESSAGES[status]} (around vertex {vertex}, n = {n})")
    return Paper6n(S, C, I, T if targets else None)


def faces_from_paper6n(p: Paper6n) -> np.ndarray:
    """The ``2n - 4`` triangles (ccw) of a decoded table with targets. A table it did not
    decode is checked first (:class:`~jaxcds.errors.EncodingError`: shapes ``(3, 2, n)``,
    ``(3, 2, n)``, ``(3, n)``, integer ``S`` in ``[0, n)`` and ``T`` in ``[0, n]``, bool ``C``,
    ``n >= 4``; the kernel indexes by ``S`` and ``T`` unchecked)."""
    if not isinstance(p, Paper6n):
        raise errors.ArgumentError(f"faces_from_paper6n: expected a Paper6n, got {type(p).__name__}")
    if p.T is None:  # was a bare ValueError
        raise errors.ArgumentError("faces_from_paper6n needs a table decoded with targets=True")
    S, C, T = (np.asarray(a) for a in (p.S, p.C, p.T))
    n = int(S.shape[2]) if S.ndim == 3 else -1
    if n < 4 or S.shape != (3, 2, n) or C.shape != (3, 2, n) or T.shape != (3, n):
        raise errors.EncodingError(f"faces_from_paper6n: S, C, T must have shapes (3, 2, n), (3, 2, n), "
                                   f"(3, n) with n >= 4, got {S.shape}, {C.shape}, {T.shape}")
    if S.dtype.kind not in "iu" or T.dtype.kind not in "iu" or C.dtype != np.bool_:
        raise errors.EncodingError(f"faces_from_paper6n: S and T must be integers and C booleans, got "
                                   f"dtypes {S.dtype}, {C.dtype}, {T.dtype}")
    for name, a, hi in (("S", S, n - 1), ("T", T, n)):
        bad = np.argwhere((a < 0) | (a > hi))
        if bad.size:
            at = tuple(int(x) for x in bad[0])
            raise errors.EncodingError(f"faces_from_paper6n: {name}{list(at)} = {int(a[at])} is outside "
                                       f"[0, {hi}]")
    return _faces_from_paper6n(Paper6n(np.ascontiguousarray(S, np.int32), np.ascontiguousarray(C),
                                       p.I, np.ascontiguousarray(T, np.int32)))


def _faces_from_paper6n(p: Paper6n) -> np.ndarray:
    """:func:`faces_from_paper6n` of a table the decoder filled (unchecked)."""
    n = p.num_vertices
    out = np.empty((2 * n - 4, 3), dtype=np.int32)
    f = _faces(n, p.S, p.C, p.T, out)
    if f != 2 * n - 4:
        where = f"vertex {-1 - f}" if f < 0 else f"{f} faces found"
        raise errors.EncodingError(f"faces: the decoded wood is not a triangulation ({where}, n = {n})")
    return out


def decode_faces(words: Words) -> tuple[np.ndarray, Paper6n]:
    """Decode the words into ``(faces, table)``: ``(2n - 4, 3)`` int32 ccw triangles (vertex
    ``i`` = ``i``-th vertex of the ccw DFS of ``T_red``) and the Thm 2 table with targets."""
    p = decode_paper6n(words, targets=True)
    return _faces_from_paper6n(p), p
