"""Bit words of the 4n-bit Schnyder-wood encoding (CDS paper, Sec. 3.1 and 3.3).

A planar triangulation on ``n`` vertices endowed with a Schnyder wood is encoded by

* the **red word** (``2n`` bits): the balanced parentheses of the counter-clockwise depth-first
  traversal of the red tree ``T_red`` (rooted at ``V_red``, with the two outer edges
  ``(V_blue, V_red)`` and ``(V_black, V_red)`` added); ``(`` is written ``0`` and ``)`` is ``1``;
* the **black word** (``2n - 3`` bits): for every vertex, in that depth-first order, its incoming
  black degree in unary (``d`` one bits) followed by a ``0`` separator.

Together: ``4n - 3`` bits (Sec. 3.1). The **mixed** (streamable) word of Sec. 3.3 interleaves
them: right after the red ``0`` that opens vertex ``v`` comes the black block of ``v``
(``1^d 0``). It has the same length and is decoded with one linear scan.

In memory and on disk a word is a numpy ``uint8`` array of *packed* bits, most significant bit
first (``np.packbits`` order); bit ``i`` of the word is ``(buf[i >> 3] >> (7 - (i & 7))) & 1``.
A :class:`Words` holds both words of one triangulation in one bit string: red word then black
word (``mixed=False``), or the mixed word (``mixed=True``).
"""

from __future__ import annotations

import dataclasses

import numba
import numpy as np

from jaxcds import errors

__all__ = [
    "Words",
    "MAX_VERTICES",
    "num_bits",
    "pack",
    "unpack",
    "from_strings",
    "red_string",
    "black_string",
    "mixed_string",
    "to_mixed",
    "to_separate",
]


#: the most vertices a word (and a ``.cds`` file) can describe: vertex ids are int32 everywhere in
#: the codec (faces, rotations, the Thm 2 table) and ``n`` itself is the "absent" sentinel
MAX_VERTICES = 2**31 - 1


def num_bits(n: int) -> int:
    """Connectivity bits of a triangulation on ``n`` vertices: ``4n - 3`` (Sec. 3.1)."""
    return 4 * int(n) - 3


@dataclasses.dataclass(frozen=True)
class Words:
    """The 4n-3 connectivity bits of a triangulation endowed with a Schnyder wood.

    Attributes:
      num_vertices: ``n`` (vertex ``0`` is ``V_red``, ``1`` is ``V_blue``, ``n - 1`` is
        ``V_black``; vertices are numbered in the ccw depth-first order of ``T_red``).
      bits: packed ``uint8`` buffer (MSB first) of at least ``4n - 3`` bits.
      mixed: ``False``: red word (``2n`` bits) then black word (``2n - 3`` bits);
        ``True``: the streamable mixed word of Sec. 3.3.

    The constructor raises :class:`~jaxcds.errors.EncodingError` for a ``num_vertices`` that is
    not an integer in ``[1, MAX_VERTICES]`` and for ``bits`` that are not a 1-d ``uint8`` array
    (the buffer's length is checked by the decoder).
    """

    num_vertices: int
    bits: np.ndarray
    mixed: bool = False

    def __post_init__(self):
        from jaxcds._args import is_integer

        if not is_integer(self.num_vertices):  # 20.0 raised TypeError deep in the decoder
            raise errors.EncodingError(f"Words: num_vertices must be an integer, got "
                                       f"{self.num_vertices!r}")
        if not 1 <= self.num_vertices <= MAX_VERTICES:  # 4n - 3 bits: n = 0 has a negative length
            raise errors.EncodingError(f"Words: num_vertices {int(self.num_vertices)} out of range "
                                       f"[1, {MAX_VERTICES}]")
        # a 2-d buffer raised numpy's ValueError in the decoder, a wider dtype was cut to bytes
        try:
            a = np.asarray(self.bits)
        except ValueError as exc:  # ragged nested lists
            raise errors.EncodingError(f"Words: bits must be a 1-d uint8 array of packed bytes, got "
                                       f"{type(self.bits).__name__} ({exc})") from None
        if a.ndim != 1 or a.dtype != np.uint8:
            raise errors.EncodingError(
                f"Words: bits must be a 1-d uint8 array of packed bytes, shape (ceil((4n - 3) / 8),) "
                f"= ({(num_bits(self.num_vertices) + 7) // 8},) for n = {int(self.num_vertices)}; got "
                f"dtype {a.dtype}, shape {a.shape} (pack 0/1 bits with jaxcds.codec.words.pack)")

    @property
    def num_bits(self) -> int:
        return num_bits(self.num_vertices)

    @property
    def bits_per_vertex(self) -> float:
        return self.num_bits / max(self.num_vertices, 1)

    def unpacked(self) -> np.ndarray:
        """The ``4n - 3`` bits as a ``uint8`` array of 0/1."""
        return unpack(self.bits, self.num_bits)

    def __eq__(self, other) -> bool:  # compare the meaningful bits only
        if not isinstance(other, Words):
            return NotImplemented
        return (self.num_vertices == other.num_vertices and self.mixed == other.mixed
                and np.array_equal(self.unpacked(), other.unpacked()))

    def __hash__(self):  # pragma: no cover - frozen dataclass with an array field
        return hash((self.num_vertices, self.mixed, self.unpacked().tobytes()))


# --------------------------------------------------------------------------- packing
def pack(bits: np.ndarray) -> np.ndarray:
    """Pack a 0/1 array into ``uint8`` bytes, most significant bit first."""
    return np.packbits(np.asarray(bits, dtype=np.uint8))


def unpack(buf: np.ndarray, nbits: int) -> np.ndarray:
    """The first ``nbits`` bits of a packed buffer, as ``uint8`` 0/1."""
    return np.unpackbits(np.asarray(buf, dtype=np.uint8), count=int(nbits))


# --------------------------------------------------------------------------- strings
def _red_bits(red: str) -> np.ndarray:
    chars = [c for c in red if not c.isspace()]
    bad = [i for i, c in enumerate(chars) if c not in "()"]
    if bad:
        raise errors.EncodingError(f"red word: symbol {chars[bad[0]]!r} at bit {bad[0]} is not a parenthesis")
    return np.array([0 if c == "(" else 1 for c in chars], dtype=np.uint8)


def _black_bits(black: str) -> np.ndarray:
    chars = [c for c in black if not c.isspace()]
    bad = [i for i, c in enumerate(chars) if c not in "01"]
    if bad:
        raise errors.EncodingError(f"black word: symbol {chars[bad[0]]!r} at bit {bad[0]} is not 0/1")
    return np.array([int(c) for c in chars], dtype=np.uint8)


def from_strings(red: str, black: str) -> Words:
    """Words from the paper's notation, e.g. ``from_strings("(()()...)", "0000...")``
    (spaces ignored). Checks the lengths (``2n`` and ``2n - 3``); full validity is checked by
    the decoder."""
    r, b = _red_bits(red), _black_bits(black)
    if r.size % 2 or r.size < 6:
        raise errors.EncodingError(f"red word: length {r.size} is not 2n for some n >= 3")
    n = r.size // 2
    if b.size != 2 * n - 3:
        raise errors.EncodingError(
            f"black word: length {b.size}, expected 2n-3 = {2 * n - 3} for n = {n} (red word of {r.size} bits)")
    return Words(n, pack(np.concatenate([r, b])), mixed=False)


def red_string(w: Words) -> str:
    """The red word as parentheses (separate form only)."""
    w = to_separate(w)
    return "".join("(" if x == 0 else ")" for x in w.unpacked()[: 2 * w.num_vertices])


def black_string(w: Words) -> str:
    """The black word as 0/1 characters (separate form only)."""
    w = to_separate(w)
    return "".join(str(int(x)) for x in w.unpacked()[2 * w.num_vertices:])


def mixed_string(w: Words) -> str:
    """The mixed word of Sec. 3.3 as 0/1 characters."""
    return "".join(str(int(x)) for x in to_mixed(w).unpacked())


# --------------------------------------------------------------------------- mixing
@numba.njit(cache=True, nogil=True)
def _mix(bits, n, out):
    """Separate (red ++ black) -> mixed. Returns (status, bit offset); status 0 = ok."""
    pr, pb, po = 0, 2 * n, 0
    end_r, end_b = 2 * n, 4 * n - 3
    while pr < end_r:
        s = bits[pr]
        out[po] = s
        po += 1
        pr += 1
        if s == 0:  # '(' : the black block of the vertex just opened follows
            while True:
                if pb >= end_b:
                    return 1, pb
                x = bits[pb]
                out[po] = x
                po += 1
                pb += 1
                if x == 0:
                    break
    if pb != end_b:
        return 2, pb
    return 0, po


@numba.njit(cache=True, nogil=True)
def _split(bits, n, out):
    """Mixed -> separate (red ++ black). Returns (status, bit offset)."""
    pi, pr, pb = 0, 0, 2 * n
    end = 4 * n - 3
    while pi < end:
        s = bits[pi]
        pi += 1
        if pr >= 2 * n:
            return 3, pi - 1
        out[pr] = s
        pr += 1
        if s == 0:
            while True:
                if pi >= end:
                    return 1, pi
                if pb >= end:  # more black bits than the 2n - 3 a black word holds
                    return 4, pi
                x = bits[pi]
                pi += 1
                out[pb] = x
                pb += 1
                if x == 0:
                    break
    if pr != 2 * n or pb != end:
        return 2, pi
    return 0, pi


def to_mixed(w: Words) -> Words:
    """The streamable mixed word (Sec. 3.3) of ``w``. Only the interleaving is checked here
    (every red ``(`` is followed by a complete unary block); validity is the decoder's job."""
    if w.mixed:
        return w
    n = w.num_vertices
    out = np.zeros(num_bits(n), dtype=np.uint8)
    status, pos = _mix(w.unpacked(), n, out)
    if status == 1:
        raise errors.EncodingError(f"black word ends inside a unary block (bit {pos - 2 * n} of the black word)")
    if status == 2:
        raise errors.EncodingError(f"black word has {4 * n - 3 - pos} unused bits from bit {pos - 2 * n} on "
                                   f"(the red word's {n} vertices read {pos - 2 * n} of its {2 * n - 3} bits)")
    return Words(n, pack(out), mixed=True)


def to_separate(w: Words) -> Words:
    """The red word followed by the black word, from a mixed word."""
    if not w.mixed:
        return w
    n = w.num_vertices
    out = np.zeros(num_bits(n), dtype=np.uint8)
    status, pos = _split(w.unpacked(), n, out)
    if status == 1:
        raise errors.EncodingError(f"mixed word ends inside a black unary block (bit {pos})")
    if status == 2:  # not reached: 4n - 3 bits, at most 2n red and 2n - 3 black (statuses 3, 4)
        raise errors.EncodingError(f"mixed word: wrong red/black bit counts at the end (bit {pos})")
    if status == 4:
        raise errors.EncodingError(f"mixed word: the black blocks run past the 2n - 3 = {2 * n - 3} bits of a "
                                   f"black word (bit {pos})")
    if status == 3:
        raise errors.EncodingError(f"mixed word: more than 2n = {2 * n} red symbols (bit {pos})")
    return Words(n, pack(out), mixed=False)
