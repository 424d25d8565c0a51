"""Bit vectors packed in ``uint32`` words with constant-size rank and binary-search select.

Layout (in the manner of sdsl's ``rank_support_v`` with one level): bit ``i`` is bit ``i % 32``
(least significant first) of word ``i // 32``; words are grouped in *blocks* of
:data:`BLOCK_BITS` = 256 bits (8 words) and ``block_rank[b]`` holds the number of ones before
block ``b``. So the rank support costs 32 bits per 256 (0.125 bit per bit).

* ``rank1(i)`` = ones in ``[0, i)``: one block counter plus the popcounts of at most 8 words.
* ``select1(k)`` / ``select0(k)`` = position of the ``k``-th (0-based) one / zero: the blocks of
  every 512-th one and zero are sampled (``sel1``, ``sel0``: 32 bits per 512 ones or zeros, 1/16
  bit per bit), a branch-free binary search over ``block_rank`` between two samples
  (``select_steps`` halvings, the most any sample gap needs), then the word inside the block
  (prefix popcounts), then the bit inside the word (5 halving steps).

Every query takes arrays of any shape, is branch-free (``jnp.where``) and jittable; its
positions and ranks are integers (floats, booleans and strings are refused with
:class:`~jaxcds.errors.InvalidIndexError`, :func:`jaxcds.structures.base.id_arg`); the
structure is a pytree (``words``, ``block_rank`` leaves; ``size`` static).
"""

from __future__ import annotations

import dataclasses
from typing import Optional

import jax
import jax.numpy as jnp
import numba
import numpy as np

from jaxcds import errors
from jaxcds._arrays import to_device
from jaxcds._dataclass import pytree_dataclass, static_field
from jaxcds.structures.base import id_arg

__all__ = ["BitVector", "BLOCK_BITS", "BLOCK_WORDS", "COMPACT_CHUNK", "compacted", "pack_bits", "popcount"]

BLOCK_WORDS = 8
BLOCK_BITS = 32 * BLOCK_WORDS
#: select sampling: the block of every SELECT_SAMPLE-th one (and zero) is stored
SELECT_SAMPLE = 512
#: lanes per chunk of the slow route of a two-stage query (:func:`compacted`; batches of at most
#: this many queries run the slow route on every lane instead: no compaction)
COMPACT_CHUNK = 1 << 15
#: batches of at most this many lanes skip the first stage and the compaction (and use the loop
#: forms that compile to smaller programs): the verifier composes ~30 operators (~60 searches) in
#: one program over a small mesh's darts, and with both stages and the compaction loops in every
#: search its compilation went past 5 GB. (The quick pemb protocol tests' process still peaks at
#: 5.0 GB against 4.0 GB before the two-stage searches, measured; 16384 here did not lower it.)
SELECT_ALL_BELOW = 4096
#: batches of at least this many lanes use the unrolled (faster, larger) loop forms
UNROLL_FROM = 4096


def popcount(w: jnp.ndarray) -> jnp.ndarray:
    """Number of set bits of each ``uint32`` word, as int32."""
    return jax.lax.population_count(w).astype(jnp.int32)


def _low_mask(r: jnp.ndarray) -> jnp.ndarray:
    """``uint32`` mask of the ``r`` low bits, ``0 <= r <= 32`` (no shift by 32: XLA would give 0,
    but we do not rely on it)."""
    r = jnp.asarray(r, jnp.uint32)
    full = jnp.uint32(0xFFFFFFFF)
    return jnp.where(r >= 32, full, (jnp.uint32(1) << jnp.minimum(r, 31)) - jnp.uint32(1))


def _select_in_word(w: jnp.ndarray, r: jnp.ndarray) -> jnp.ndarray:
    """Position of the ``r``-th (0-based) set bit of ``w`` (``r < popcount(w)``): five halving
    steps, each comparing ``r`` with the popcount of the low half of the remaining window."""
    pos = jnp.zeros(jnp.shape(r), jnp.int32)
    w = jnp.asarray(w, jnp.uint32)
    r = jnp.asarray(r, jnp.int32)
    for width in (16, 8, 4, 2, 1):
        low = popcount(w & jnp.uint32((1 << width) - 1))
        up = r >= low  # the bit is in the high half of the window
        r = jnp.where(up, r - low, r)
        w = jnp.where(up, w >> jnp.uint32(width), w)
        pos = jnp.where(up, pos + width, pos)
    return pos


def _compact_indices(mask, size: int):
    """``(idx, count)``: the lanes where ``mask`` (1-D), in order, padded with ``n`` to ``size``
    entries, and their number. ``jnp.nonzero(mask, size=...)`` does the same, three times
    slower on CPU (measured, 600K lanes: 15 vs 5 ms): here the mask is packed in ``uint32``
    words, a prefix sum runs on the word popcounts only (1/32 of the lanes), each lane's slot is
    a rank (popcount of its word below it), and one scatter writes the lane ids."""
    n = mask.shape[0]
    n32 = -(-n // 32) * 32
    m = jnp.pad(mask, (0, n32 - n)).reshape(-1, 32).astype(jnp.uint32)
    # the bit column as a row, explicitly: rank promotion may be set to raise (sweep 52c)
    words = jnp.sum(m << jnp.arange(32, dtype=jnp.uint32)[None, :], axis=1)  # distinct bits: sum = or
    cnt = popcount(words)
    before = jnp.cumsum(cnt, dtype=jnp.int32) - cnt  # int32 also under enable_x64 (Polylla)
    lane = jnp.arange(n, dtype=jnp.int32)
    slot = before[lane >> 5] + popcount(words[lane >> 5] & _low_mask(lane & 31))
    idx = jnp.full((size,), n, jnp.int32).at[jnp.where(mask, slot, size)].set(lane, mode="drop")
    return idx, jnp.sum(cnt, dtype=jnp.int32)


def bit_arg(bit, what: str) -> jnp.ndarray:
    """``bit`` (which bit a query counts, per query: 0/1 integers or booleans) as a bool array,
    or :class:`~jaxcds.errors.InvalidIndexError` naming ``what``: floats (0.5 read as 1),
    strings and ``None`` (JAX's TypeError / ValueError), and host values other than 0 and 1
    (2 and -1 read as 1; traced values cannot be looked at: nonzero is 1)."""
    if isinstance(bit, jax.Array):
        if bit.dtype != jnp.bool_ and not jnp.issubdtype(bit.dtype, jnp.integer):
            raise errors.InvalidIndexError(f"{what} must be 0/1 integers or booleans, got dtype {bit.dtype}")
        # a bool as it is (compared with 0 it raised under strict dtype promotion)
        return bit if bit.dtype == jnp.bool_ else bit != 0
    try:
        a = np.asarray(bit)
    except ValueError as exc:  # ragged nested lists
        raise errors.InvalidIndexError(f"{what} are not an array: {exc}") from None
    if isinstance(bit, np.ma.MaskedArray) or (a.size and a.dtype.kind not in "biu"):
        raise errors.InvalidIndexError(f"{what} must be 0/1 integers or booleans, got "
                                       f"{type(bit).__name__} of dtype {a.dtype}")
    bad = (a != 0) & (a != 1)
    if bad.any():
        raise errors.InvalidIndexError(f"{what} must be 0 or 1, got {a.ravel()[np.argmax(bad.ravel())].item()!r}")
    return jnp.asarray(a.astype(bool))


def broadcast_args(what: str, *xs):
    """The common shape of the arrays ``xs`` (:func:`jnp.broadcast_shapes`), or
    :class:`~jaxcds.errors.ArgumentError` naming ``what`` and the shapes (JAX's ValueError)."""
    shapes = tuple(jnp.shape(x) for x in xs)
    try:
        return jnp.broadcast_shapes(*shapes)
    except ValueError:
        raise errors.ArgumentError(f"{what}: shapes {', '.join(map(str, shapes))} do not "
                                   "broadcast to one shape") from None


def mask_arg(x, shape, what: str) -> jnp.ndarray:
    """A per-query mask (``active``, ``opens``) as a bool array of ``shape`` (flags read by truth
    value), or :class:`~jaxcds.errors.ArgumentError` naming ``what`` for a shape that does not
    broadcast to it, or no array of flags (JAX's TypeError / ValueError)."""
    try:
        m = jnp.asarray(x, bool)
    except (TypeError, ValueError) as exc:
        raise errors.ArgumentError(f"{what} must be an array of flags, got {type(x).__name__} "
                                   f"({exc})") from None
    # a str or any object converted to True: active="no" selected every query
    dtype = x.dtype if isinstance(x, jax.Array) else np.asarray(x).dtype
    if dtype.kind not in "biuf":
        raise errors.ArgumentError(f"{what} must be an array of flags, got {type(x).__name__} "
                                   f"of dtype {dtype}")
    shape = tuple(shape)
    try:
        fits = jnp.broadcast_shapes(m.shape, shape) == shape
    except ValueError:
        fits = False
    if not fits:
        raise errors.ArgumentError(f"{what} has shape {m.shape}, which does not broadcast to the "
                                   f"queries' shape {shape}")
    return jnp.broadcast_to(m, shape)


def chunk_arg(chunk):
    """``chunk`` if ``None`` or a positive integer, else :class:`~jaxcds.errors.ArgumentError`."""
    from jaxcds._args import is_integer

    if chunk is not None and (not is_integer(chunk) or chunk < 1):
        raise errors.ArgumentError(f"chunk must be None or a positive integer (lanes per batch of "
                                   f"the slow route), got {chunk!r}")
    return chunk


def compacted(slow, miss, fast, args, chunk: Optional[int] = None):
    """``fast`` where ``~miss``; ``slow(*args)`` on the lanes where ``miss`` (1-D arrays).

    The missed lanes are compacted (:func:`_compact_indices`) and ``slow`` runs on ``chunk`` of
    them at a time in a ``while_loop`` (as many chunks as there are misses, so no cap on the miss
    rate; a chunk's loop state stays in cache), the answers scattered back. ``chunk`` defaults to
    :data:`COMPACT_CHUNK`, or a quarter of the batch (power of two) for smaller batches; a batch
    of at most :data:`SELECT_ALL_BELOW` lanes runs ``slow`` alone (one fixed program: what
    ``vmap`` of a scalar query sees).

    Raises:
      ArgumentError: ``chunk`` is not ``None`` or a positive integer (the public ``chunk=`` of
        ``match_all``, ``enclose``, ``select``... all reach here: 0 raised Python's
        ZeroDivisionError, a negative chunk or 2.5 JAX's shape errors, True ran as 1)."""
    chunk = chunk_arg(chunk)
    n = miss.shape[0]
    if n <= SELECT_ALL_BELOW:
        # tiny batches (scalars under vmap, the verifier's compositions of dozens of operators):
        # the slow route alone, so the first stage is dead code and the program stays small
        return slow(*args).astype(fast.dtype)
    if chunk is None:
        chunk = min(COMPACT_CHUNK, max(16, 1 << max(n // 4 - 1, 0).bit_length()))
    if n <= chunk:
        return jnp.where(miss, slow(*args), fast)
    nch = -(-n // chunk)
    idx, count = _compact_indices(miss, nch * chunk)

    def cond(c):
        return c[0] * chunk < count

    def body(c):
        k, out = c
        ids = jax.lax.dynamic_slice(idx, (k * chunk,), (chunk,))
        safe = jnp.minimum(ids, n - 1)
        r = slow(*(a[safe] for a in args))
        return k + 1, out.at[ids].set(r.astype(out.dtype), mode="drop")

    _, out = jax.lax.while_loop(cond, body, (jnp.int32(0), fast))
    return out


def finish_pending(slow, pending, fast, args, chunk: int):
    """:func:`compacted` (``slow`` on the ``pending`` lanes, ``chunk`` at a time, ``fast``
    elsewhere) behind one ``cond`` that skips it, compaction pass included, when no lane is
    pending: the second stage of a batched loop whose first stage ran every lane a bounded number
    of steps and usually finished them all (``adjacent``'s rotations, the gather normals)."""
    return jax.lax.cond(jnp.any(pending), lambda: compacted(slow, pending, fast, args, chunk),
                        lambda: fast)


@numba.njit(cache=True)
def _select_samples(b, sample, block_bits):
    """Blocks of the ``(j * sample)``-th one and of the ``(j * sample)``-th zero of ``b``, in one
    pass (the positions of every one and zero, as int64 arrays, took 1.3 GB at 165M bits)."""
    n1 = 0
    for j in range(b.size):
        n1 += b[j]
    n0 = b.size - n1
    ones = np.empty((n1 + sample - 1) // sample, np.int64)
    zeros = np.empty((n0 + sample - 1) // sample, np.int64)
    c1 = c0 = 0
    for j in range(b.size):
        if b[j]:
            if c1 % sample == 0:
                ones[c1 // sample] = j // block_bits
            c1 += 1
        else:
            if c0 % sample == 0:
                zeros[c0 // sample] = j // block_bits
            c0 += 1
    return ones, zeros


def pack_bits(bits) -> np.ndarray:
    """Host: a 0/1 sequence -> ``uint32`` words (bit ``i`` = bit ``i % 32`` of word ``i // 32``),
    padded with zero words to whole blocks plus one spare block (so gathers of a block that
    starts at ``size`` stay in range).

    Raises:
      EncodingError: ``bits`` is not one sequence of 0/1 values (:func:`bits_array`: a cast to
        bool read 2, 0.5 and the strings ``'0'`` and ``'1'`` as 1, ``None`` as one 0 bit, and a
        2-D array was flattened)."""
    return _pack_bits(bits_array(bits, "pack_bits: bits"))


def _pack_bits(b: np.ndarray) -> np.ndarray:
    """:func:`pack_bits` of a 1-D 0/1 array already checked (:func:`bits_array`)."""
    nblocks = b.size // BLOCK_BITS + 1
    padded = np.zeros(nblocks * BLOCK_BITS + BLOCK_BITS, dtype=bool)
    padded[: b.size] = b
    return np.packbits(padded.reshape(-1, 8), axis=1, bitorder="little").reshape(-1).view("<u4").astype(
        np.uint32)


def bits_array(bits, what: str) -> np.ndarray:
    """Host: ``bits`` (a list or a 1-D array of integers, booleans or floats) as a bool array, or
    :class:`~jaxcds.errors.EncodingError` naming ``what`` and the first offset that holds
    anything but 0 or 1 (a cast to bool read 2, -1, 0.5 and NaN as 1, the strings ``'0'`` and
    ``'1'`` both as 1, and ``None`` as one 0 bit), or the shape of anything but one sequence (a
    2-D array was flattened row by row, a lone 0 or 1 read as a one-bit sequence), or a numpy
    masked array (its mask was dropped: the masked entries read as bits, as ``id_arg`` refuses
    masked ids)."""
    if isinstance(bits, np.ma.MaskedArray):
        raise errors.EncodingError(f"{what} must be plain bits, got a masked array (its mask would "
                                   "be dropped; fill it first: bits.filled(0))")
    try:
        a = np.asarray(bits)
    except ValueError as exc:  # ragged nested lists
        raise errors.EncodingError(f"{what} are not an array of bits: {exc}") from None
    if a.size and a.dtype.kind not in "biuf":
        raise errors.EncodingError(f"{what} must be 0/1 values, got dtype {a.dtype}")
    if a.ndim != 1:
        raise errors.EncodingError(f"{what} must be one sequence of bits (1-D), got shape {a.shape}")
    bad = (a != 0) & (a != 1)
    if bad.any():
        k = int(np.argmax(bad))
        raise errors.EncodingError(f"{what} hold {a[k].item()!r} at offset {k}, expected 0 or 1")
    return a.astype(bool)


def _block_lanes(ndim: int) -> jnp.ndarray:
    """``(1, ..., 1, 8)``: a block's word lanes as a row of rank ``ndim + 1``, to meet queries
    of rank ``ndim`` widened by ``[..., None]``. Written out rather than left to broadcasting:
    users may run with ``jax.numpy_rank_promotion("raise")`` (sweep 52c); same program."""
    return jnp.arange(BLOCK_WORDS, dtype=jnp.int32).reshape((1,) * ndim + (BLOCK_WORDS,))


@pytree_dataclass
class BitVector:
    """A static bit vector with rank and select.

    Fields:
      words: ``(W,)`` uint32, the bits (least significant first), zero-padded to ``W = 8 (B + 1)``
        words, ``B = size // 256 + 1`` blocks (the last block is spare).
      block_rank: ``(B + 1,)`` int32, ``block_rank[b]`` = ones in ``[0, 256 b)`` (one per block, spare included).
      size: number of bits (static; the count of ones is ``block_rank[-1]``, a leaf, so bit
        vectors of one length share their compiled queries).
    """

    words: jnp.ndarray
    block_rank: jnp.ndarray
    sel1: jnp.ndarray
    sel0: jnp.ndarray
    size: int = static_field()
    select_steps: int = static_field()
    #: optional ``(W,)`` int32 ones before every word (:meth:`with_word_rank`; None: not built)
    word_rank: Optional[jnp.ndarray] = None

    @classmethod
    def from_bits(cls, bits) -> "BitVector":
        """Build from a host 0/1 sequence (list, numpy array or a ``"0110..."`` string);
        any other value is :class:`~jaxcds.errors.EncodingError` naming its offset."""
        if isinstance(bits, str):
            bad = [i for i, c in enumerate(bits) if c not in "01"]
            if bad:
                raise errors.EncodingError(
                    f"BitVector.from_bits: bit string has {bits[bad[0]]!r} at offset {bad[0]}, expected '0' or '1'")
            bits = np.frombuffer(bits.encode(), dtype=np.uint8) - ord("0")
        return cls._from_valid_bits(bits_array(bits, "BitVector.from_bits: bits"))

    @classmethod
    def _from_valid_bits(cls, b: np.ndarray) -> "BitVector":
        """:meth:`from_bits` of a 1-D 0/1 array (bool or integers) already checked
        (:func:`bits_array`, or made by the library): no scan for values other than 0 and 1
        (the builders check each sequence once, not once per layer)."""
        b = np.asarray(b).astype(bool, copy=False)  # the select kernel's one specialization
        words = _pack_bits(b)
        nblocks = words.size // BLOCK_WORDS
        counts = np.bitwise_count(words).reshape(nblocks, BLOCK_WORDS).sum(axis=1)
        block_rank = np.concatenate([[0], np.cumsum(counts)])[: nblocks].astype(np.int32)
        # select samples: block of the (j * SELECT_SAMPLE)-th one / zero, then the spare block;
        # a select searches only between two consecutive samples (select_steps halvings)
        steps = 1
        samples = []
        for s in _select_samples(b, SELECT_SAMPLE, BLOCK_BITS):  # ones, zeros
            s = np.concatenate([s, [nblocks - 1]]).astype(np.int32)
            samples.append(s)
            steps = max(steps, int(np.ceil(np.log2(int(np.max(np.diff(s), initial=0)) + 2))))
        return cls(words=to_device(words), block_rank=to_device(block_rank),
                   sel1=to_device(samples[0]), sel0=to_device(samples[1]), size=int(b.size),
                   select_steps=steps)

    # ------------------------------------------------------------------ sizes
    @property
    def ones(self) -> jnp.ndarray:
        """Number of ones (the spare last block starts after every bit)."""
        return self.block_rank[-1]

    @property
    def zeros(self) -> jnp.ndarray:
        return self.size - self.ones

    @property
    def num_blocks(self) -> int:
        return int(self.block_rank.shape[0])

    @property
    def bits_payload(self) -> int:
        """Bits of the sequence itself."""
        return self.size

    @property
    def bits_support(self) -> int:
        """Bits of the rank directory, the select samples and the word padding (what a compact
        count charges)."""
        return (32 * (self.num_blocks + int(self.sel1.shape[0]) + int(self.sel0.shape[0]))
                + (32 * int(self.words.shape[0]) - self.size))

    # ------------------------------------------------------------------ queries
    def access(self, i) -> jnp.ndarray:
        """Bit ``i`` as int32 0/1."""
        i = id_arg(i, "BitVector.access: positions")
        w = self.words[i >> 5]
        return ((w >> (i & 31).astype(jnp.uint32)) & jnp.uint32(1)).astype(jnp.int32)

    def _block_words(self, b) -> jnp.ndarray:
        """``(..., 8)`` words of block ``b``."""
        idx = b[..., None] * BLOCK_WORDS + _block_lanes(jnp.ndim(b))
        return self.words[idx]

    def with_word_rank(self) -> "BitVector":
        """A copy holding :attr:`word_rank`, the ones before every word (jittable: a prefix sum
        over the word popcounts, 1/32 of the bits): ``rank1`` then reads one counter and one
        word instead of a block counter and the block's 8 words. 1 bit per bit: a temporary of
        batch work that ranks every position (pemb's :meth:`~jaxcds.structures.pemb.PEMB.with_tables`),
        not part of the compact structure (:attr:`bits_support` does not count it)."""
        c = popcount(self.words)
        return dataclasses.replace(self, word_rank=jnp.cumsum(c, dtype=jnp.int32) - c)

    def rank1(self, i) -> jnp.ndarray:
        """Number of ones in ``[0, i)``, ``0 <= i <= size``."""
        i = id_arg(i, "BitVector.rank1: positions")
        if self.word_rank is not None:
            w = i >> 5
            return self.word_rank[w] + popcount(self.words[w] & _low_mask(i & 31))
        b = i >> 8
        words = self._block_words(b)
        k = _block_lanes(jnp.ndim(i))
        wi = (i >> 5) & (BLOCK_WORDS - 1)
        # whole words before the word of i, then the low (i % 32) bits of that word
        r = jnp.where(k == wi[..., None], jnp.asarray(i & 31, jnp.int32)[..., None],
                      jnp.where(k < wi[..., None], 32, 0))
        # dtype: int32 also under enable_x64 (Polylla's label phase), where a plain sum of int32
        # would promote to int64 and carry every later index computation with it
        return self.block_rank[b] + jnp.sum(popcount(words & _low_mask(r)), axis=-1, dtype=jnp.int32)

    def rank0(self, i) -> jnp.ndarray:
        """Number of zeros in ``[0, i)``."""
        i = id_arg(i, "BitVector.rank0: positions")
        return i - self.rank1(i)

    def rank(self, i, bit) -> jnp.ndarray:
        """``rank1`` where ``bit`` is 1, ``rank0`` where it is 0 (elementwise)."""
        i = id_arg(i, "BitVector.rank: positions")
        one = bit_arg(bit, "BitVector.rank: bit")
        broadcast_args("BitVector.rank", i, one)
        r1 = self.rank1(i)
        return jnp.where(one, r1, i - r1)

    def select(self, k, bit) -> jnp.ndarray:
        """Position of the ``k``-th (0-based) ``bit`` (elementwise 0/1). Out of range -> ``size``.

        Binary search for the last block ``b`` with ``count_bit([0, 256 b)) <= k`` between the
        blocks of the samples ``k // 512`` and ``k // 512 + 1`` (``select_steps`` halvings, fixed
        at construction), then the word and the bit inside it."""
        k = id_arg(k, "BitVector.select: ranks")
        one = bit_arg(bit, "BitVector.select: bit")
        shape = broadcast_args("BitVector.select", k, one)
        k, one = jnp.broadcast_to(k, shape), jnp.broadcast_to(one, shape)
        total = jnp.where(one, self.ones, self.zeros)
        nb = self.num_blocks

        def count_before(b):  # ones or zeros before block b
            r1 = self.block_rank[b]
            return jnp.where(one, r1, BLOCK_BITS * b - r1)

        def halve(_, c):  # invariant: count_before(lo) <= k < count_before(hi) (nb: +inf)
            lo, hi = c
            mid = (lo + hi) >> 1
            go = count_before(jnp.minimum(mid, nb - 1)) <= k
            ok = mid < hi
            return jnp.where(ok & go, mid, lo), jnp.where(ok & ~go, mid, hi)

        js = jnp.clip(k, 0, jnp.maximum(total - 1, 0)) // SELECT_SAMPLE
        n1 = self.sel1.shape[0]
        n0 = self.sel0.shape[0]
        lo0 = jnp.where(one, self.sel1[jnp.minimum(js, n1 - 1)], self.sel0[jnp.minimum(js, n0 - 1)])
        hi0 = jnp.where(one, self.sel1[jnp.minimum(js + 1, n1 - 1)],
                        self.sel0[jnp.minimum(js + 1, n0 - 1)]) + 1
        big = k.size >= UNROLL_FROM
        lo, _ = jax.lax.fori_loop(0, self.select_steps, halve, (lo0, jnp.minimum(hi0, nb)),
                                  unroll=True if big else 1)
        r = k - count_before(lo)
        if not big:  # small batches: the compact (..., 8) form, a smaller program
            words = self._block_words(lo)
            words = jnp.where(one[..., None], words, ~words)
            cnt = popcount(words)
            incl = jnp.cumsum(cnt, axis=-1, dtype=jnp.int32)
            j = jnp.minimum(jnp.sum((incl <= r[..., None]).astype(jnp.int32), axis=-1,
                                    dtype=jnp.int32), BLOCK_WORDS - 1)
            sel = _block_lanes(jnp.ndim(j)) == j[..., None]  # one-hot pick
            before = jnp.sum(jnp.where(sel, incl - cnt, 0), axis=-1, dtype=jnp.int32)
            w = jnp.max(jnp.where(sel, words, jnp.uint32(0)), axis=-1)
            pos = BLOCK_BITS * lo + 32 * j + _select_in_word(w, jnp.clip(r - before, 0, 31))
            return jnp.where((k >= 0) & (k < total), pos, self.size).astype(jnp.int32)
        # the word holding it: the block's 8 words one after the other, elementwise state only
        # (a (..., 8) gather with a cumsum over the last axis ran 2-3x slower: 104 vs 29-50 ns
        # per query on 2M queries, measured)
        acc = jnp.zeros(k.shape, jnp.int32)
        before, j = acc, acc
        w = jnp.zeros(k.shape, jnp.uint32)
        found = jnp.zeros(k.shape, bool)
        for jj in range(BLOCK_WORDS):
            x = self.words[lo * BLOCK_WORDS + jj]
            x = jnp.where(one, x, ~x)
            c = popcount(x)
            take = ~found & (r < acc + c)
            w = jnp.where(take, x, w)
            before = jnp.where(take, acc, before)
            j = jnp.where(take, jj, j)
            found = found | take
            acc = acc + c
        pos = BLOCK_BITS * lo + 32 * j + _select_in_word(w, jnp.clip(r - before, 0, 31))
        return jnp.where((k >= 0) & (k < total) & found, pos, self.size).astype(jnp.int32)

    def select_near(self, k, bit, i, r, *, active=None, chunk: Optional[int] = None) -> jnp.ndarray:
        """``select(k, bit)`` given a nearby position ``i`` and ``r = rank(i, bit)``: the answer is
        first looked for among the bits from ``i`` on in ``i``'s word and the next one (``k >= r``)
        or the bits before ``i`` in its word and the previous one (``k < r``): popcounts and one
        in-word select, no binary search. The lanes it misses take :meth:`select` (compacted,
        :func:`compacted`). pemb's ``mate`` knows ``i`` (the other half-edge) and ``r``, and its
        answer is within one word for about 3 darts in 4 (BFS tree). Lanes outside ``active``
        (default: all) get an unspecified position without any slow-route work."""
        k = id_arg(k, "BitVector.select_near: ranks")
        i = id_arg(i, "BitVector.select_near: positions")
        r = id_arg(r, "BitVector.select_near: ranks of the positions")
        one = bit_arg(bit, "BitVector.select_near: bit")
        shape = broadcast_args("BitVector.select_near", k, one, i, r)
        k, i, r = (jnp.broadcast_to(jnp.asarray(x, jnp.int32), shape).reshape(-1) for x in (k, i, r))
        one = jnp.broadcast_to(one, shape).reshape(-1)
        nw = self.words.shape[0]

        def word(j):  # word j in the polarity of `bit`, bits at or past `size` cleared
            w = self.words[jnp.clip(j, 0, nw - 1)]
            w = jnp.where(one, w, ~w)
            return w & _low_mask(jnp.clip(self.size - 32 * j, 0, 32))

        fw = k >= r
        j = i >> 5
        a = (i & 31).astype(jnp.uint32)
        wj = word(j)
        w1 = jnp.where(fw, wj >> a, wj & _low_mask(a))  # from i on / before i
        c1 = popcount(w1)
        x = jnp.where(fw, k - r, r - 1 - k)  # 0-based, counted away from i
        j2 = jnp.where(fw, j + 1, j - 1)
        w2 = word(j2)
        c2 = popcount(w2)
        in1 = (x < c1) & (i >= 0) & (i <= self.size)
        in2 = ~in1 & (x - c1 < c2) & (j2 >= 0) & (i >= 0) & (i <= self.size)
        w = jnp.where(in1, w1, w2)
        c = jnp.where(in1, c1, c2)
        y = jnp.where(in1, x, x - c1)
        q = jnp.where(fw, y, c - 1 - y)  # forward rank inside the chosen word
        base = jnp.where(in1, jnp.where(fw, i, 32 * j), 32 * j2)
        pos = base + _select_in_word(w, jnp.clip(q, 0, 31))
        found = (in1 | in2) & (k >= 0)
        if active is not None:
            found = found | ~mask_arg(active, shape, "BitVector.select_near: active").reshape(-1)
        out = compacted(lambda k, o: self.select(k, o), ~found, pos.astype(jnp.int32), (k, one),
                        chunk)
        return out.reshape(shape)

    def select1(self, k) -> jnp.ndarray:
        """Position of the ``k``-th (0-based) one; ``size`` if ``k >= ones``."""
        return self.select(k, 1)

    def select0(self, k) -> jnp.ndarray:
        """Position of the ``k``-th (0-based) zero; ``size`` if ``k >= zeros``."""
        return self.select(k, 0)

    def to_numpy(self) -> np.ndarray:
        """Host copy of the bits as a ``(size,)`` uint8 array."""
        w = np.asarray(self.words).view(np.uint8)
        return np.unpackbits(w, bitorder="little")[: self.size]

    def __str__(self) -> str:
        return "".join(map(str, self.to_numpy().tolist()))
