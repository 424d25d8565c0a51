"""Balanced parentheses with a range min-max tree: ``find_close``, ``find_open``, ``match``,
``enclose``, all branch-free, batched and jittable.

Sequence convention (sdsl's): bit 1 = ``(``, bit 0 = ``)``. The *excess* of a prefix is
``E(p) = #( - #)`` over the first ``p`` symbols, ``E(p) = 2 rank1(p) - p`` (so it costs one rank).
Every operation reduces to two searches (Navarro & Sadakane's range min-max tree, in its
simplest two-level form; sdsl's ``bp_support_sada`` has the same shape):

* ``fwd(i, t)``: the first bit ``k >= i`` whose prefix excess ``E(k + 1) <= t``;
* ``bwd(p, t)``: the last prefix position ``q <= p`` with ``E(q) <= t``.

and, with the unit steps of ``E``, ``find_close(i) = fwd(i, E(i))``,
``find_open(j) = bwd(j, E(j + 1))``, ``enclose(i) = bwd(i, E(i) - 1)``.

Structure: blocks of 256 bits (those of the :class:`BitVector` rank directory);
``M[b] = min { E(k + 1) : k in block b }``; a binary min-tree over ``M`` (one int32 per node,
the levels stored one after the other, about ``2 * blocks`` ints = 0.25 bit per parenthesis).
A search scans its own block (its 8 words one after the other: a 64K-entry table gives the
minimum prefix excess of each 16-bit half, then the 16 bits of the winning half), climbs the tree
to the nearest block whose minimum reaches the target, descends to it, and scans it. Every loop
has a static trip count and elementwise state only (no ``(queries, 16)`` intermediate): the word
scan is a fully unrolled ``fori_loop`` (:data:`SCAN_UNROLL`: on the compacted chunks of the
two-stage searches it runs a third faster than unrolled by 2, 2.7-3.0 vs 4.0-4.5 ms per 32K
searches, measured, for a few tenths of a second more compilation), the bit finish is unrolled, the tree climb and descent are ``fori_loop`` s carrying one
int32 per query. Everything is computed for every
query (both the near and the far candidate) and selected with ``jnp.where``: no data-dependent
branch, so ``vmap`` and ``jit`` see a fixed program of ``O(log blocks)`` gathers.

``match`` and ``enclose`` (the two searches pemb makes, on every dart) go through two stages
(:meth:`BalancedParens._two_stage`): first every query looks for its answer in its own word and
the next one (forward) or the previous one (backward), relative to ``E(i)`` (no rank, no loop:
two word gathers, four ``CHUNK_MIN`` lookups and the bit finish); the queries that miss are
compacted and run through the full block / min-tree route above in chunks of at most
:data:`COMPACT_CHUNK` lanes (a ``while_loop`` over the chunks, so any miss rate is correct; a chunk's
loop state stays in cache), then scattered back. With pemb's BFS spanning tree 75-93% of the
queries are answered in the first stage (measured: ``benchmarks/profile_pemb_ops.py``).
"""

from __future__ import annotations

from typing import Optional

import jax
import jax.numpy as jnp
import numba
import numpy as np

from jaxcds import errors
from jaxcds._args import flag_arg
from jaxcds._arrays import to_device
from jaxcds._dataclass import pytree_dataclass, static_field
from jaxcds.structures.base import id_arg, integer_array
from jaxcds.structures.succinct.bitvector import (BLOCK_BITS, BLOCK_WORDS, COMPACT_CHUNK, UNROLL_FROM,
                                                  BitVector, _low_mask, bits_array, broadcast_args,
                                                  chunk_arg, compacted, mask_arg, popcount)

__all__ = ["BalancedParens", "excess_oracle", "unbalanced_at", "matches_by_level", "CHUNK_MIN",
           "COMPACT_CHUNK", "MATCH_BY_SORT"]

_INF = np.int32(1 << 30)
UNROLL = 1
#: unrolling of the 8-word block scan on batches of at least ``UNROLL_FROM`` lanes (True: fully;
#: smaller batches: by 2, a smaller program)
SCAN_UNROLL = True

#: how the whole-sequence matches are found (:meth:`BalancedParens.match_all`, the packed pemb's
#: chunk tables): ``False``, the two-stage searches; ``True``, one stable sort of the
#: parentheses by level (:func:`matches_by_level`: no search, no data-dependent loop). Read at
#: trace time (``jax.clear_caches()`` after changing it). On XLA:CPU the sort measured 4.1x
#: slower than the searches (RESULTS.md, stop 44: 2,157 against 524 ns per vertex at 100K), so
#: the searches are the default; XLA's GPU sort is a radix sort and the searches are loops
#: there, so the sort is the GPU candidate, raced by ``benchmarks/race_pemb_match.py``
#: (``benchmarks/gpu_lease.sh`` with ``MATCH=1``), not yet measured on one.
MATCH_BY_SORT = False


def matches_by_level(is_open, member=None) -> jnp.ndarray:
    """``(k,)`` int32: the match of every parenthesis of a balanced sequence given as its
    ``(k,)`` bool ``is_open`` (indices are positions in it), by sorting instead of searching.

    Why it works: a ``(`` at excess ``d`` before it and its ``)`` (excess ``d`` after it) share
    the *level* ``d``, and within one level of a balanced sequence the parentheses alternate
    ``( ) ( ) ...`` in position order (between a ``(`` at level ``d`` and its ``)`` the excess
    stays above ``d``). So a stable sort of the positions by level lists every pair side by
    side: one ``cumsum``, one sort, two scatters.

    ``member``: ``(k,)`` bool, the positions that form the balanced sequence (a concatenation of
    balanced blocks, as a packed pemb's chunk window holds); the others are left out of the
    levels and sorted last, and their entries are unspecified."""
    is_open = _bool_vector(is_open, "matches_by_level: is_open")
    k = is_open.shape[0]
    if member is not None:
        member = _bool_vector(member, "matches_by_level: member")
        if member.shape != is_open.shape:
            raise errors.ArgumentError(f"matches_by_level: member has shape {member.shape}, "
                                       f"is_open {is_open.shape} (one flag per parenthesis)")
    i32 = jnp.int32
    step = jnp.where(is_open, 1, -1).astype(i32)
    if member is not None:
        step = jnp.where(member, step, 0)
    after = jnp.cumsum(step)
    level = jnp.where(is_open, after - 1, after)
    if member is not None:
        level = jnp.where(member, level, jnp.iinfo(i32).max)
    pos = jnp.arange(k, dtype=i32)
    if k % 2:  # an even count to pair (the extra key sorts last, among unspecified entries)
        level = jnp.concatenate([level, jnp.full((1,), jnp.iinfo(i32).max, i32)])
        pos = jnp.concatenate([pos, jnp.full((1,), k, i32)])
    _, order = jax.lax.sort((level, pos), num_keys=1, is_stable=True)
    a, b = order[0::2], order[1::2]
    out = jnp.zeros((k,), i32)
    return out.at[a].set(b, mode="drop").at[b].set(a, mode="drop")


def _bool_vector(x, what: str):
    """``x`` as a 1-D bool array (numpy, jax or a tracer), else
    :class:`~jaxcds.errors.ArgumentError` naming ``what`` (a list raised AttributeError, a 2-D
    or 0-d array JAX's shape errors, and 0/1 integers or floats were read by truth value)."""
    try:
        x = jnp.asarray(x)
    except (TypeError, ValueError) as exc:
        raise errors.ArgumentError(f"{what} must be a 1-D bool array, got {type(x).__name__} "
                                   f"({exc})") from None
    if x.ndim != 1 or x.dtype != jnp.bool_:
        raise errors.ArgumentError(f"{what} must be a 1-D bool array, got dtype {x.dtype} shape "
                                   f"{x.shape}")
    return x


def _level_arg(t, what: str) -> jnp.ndarray:
    """An excess target of :meth:`BalancedParens.fwd` / ``bwd`` (any integer, negative too) as
    int32, or :class:`~jaxcds.errors.InvalidIndexError` naming ``what``: floats (0.5 read as 0),
    booleans, strings and ``None`` (JAX's TypeError / ValueError); host integers past int32
    are clamped to it (no excess lies beyond: the same answers), not Python's OverflowError."""
    if isinstance(t, jax.Array):
        if not jnp.issubdtype(t.dtype, jnp.integer):
            raise errors.InvalidIndexError(f"{what} must be integers, got dtype {t.dtype}")
        return t.astype(jnp.int32)  # traced wider integers: the caller's values
    a = integer_array(t, what)
    if a.dtype.kind == "u":
        a = np.minimum(a, np.iinfo(np.int32).max)
    info = np.iinfo(np.int32)
    return jnp.asarray(np.clip(a, info.min, info.max).astype(np.int32))


def _chunk_min_table() -> np.ndarray:
    """``CHUNK_MIN[c]`` = min over ``q = 1..16`` of the excess of the first ``q`` bits of the
    16-bit chunk ``c`` (least significant bit first)."""
    c = np.arange(1 << 16, dtype=np.int32)
    bits = (c[:, None] >> np.arange(16)) & 1
    return np.min(np.cumsum(2 * bits - 1, axis=1), axis=1).astype(np.int8)


#: minimum prefix excess of every 16-bit chunk (64 KiB, shared by all sequences)
CHUNK_MIN = _chunk_min_table()
_CHUNKS = BLOCK_BITS // 16


def excess_oracle(bits) -> np.ndarray:
    """Host reference: ``E(p)`` for ``p = 0..n`` (length ``n + 1``) of the 0/1 sequence ``bits``
    (1 = ``(``); anything else is :class:`~jaxcds.errors.EncodingError` (:func:`bits_array`)."""
    b = bits_array(bits, "excess_oracle: bits").astype(np.int64)
    return np.concatenate([[0], np.cumsum(2 * b - 1)])


@numba.njit(cache=True)
def _block_minima(b, nb, block_bits):
    """``(M, first negative offset or -1, final excess)`` of the 0/1 sequence ``b``: ``M[k]`` is
    the minimum of ``E(j + 1)`` over block ``k``'s bits, the padding past ``b`` read as ``(``."""
    level = np.empty(nb, np.int32)
    e, first_negative = 0, -1
    for k in range(nb):
        lo = k * block_bits
        m = e + 1 + max(lo - b.size, 0)  # a block of padding only: its first '(' past the end
        for j in range(lo, min(lo + block_bits, b.size)):
            e += 1 if b[j] else -1
            if e < m:
                m = e
            if e < 0 and first_negative < 0:
                first_negative = j
        level[k] = m
    return level, first_negative, e


def unbalanced_at(bits) -> Optional[int]:
    """Host: ``None`` if the 0/1 sequence ``bits`` (1 = ``(``) is balanced, else the offset of
    its first ``)`` that closes nothing, or its length when ``(`` are left open (one numba pass,
    no array per symbol).

    Raises:
      EncodingError: ``bits`` is not one sequence of 0/1 values (:func:`bits_array`: a cast
        read 0.5 as ``)`` and 2 as ``(``, flattened a 2-D array, took a lone 0 as a one-symbol
        sequence; ``None`` or a string raised Python's TypeError / ValueError)."""
    return _unbalanced_at(bits_array(bits, "unbalanced_at: bits").astype(np.uint8))


def _unbalanced_at(b: np.ndarray) -> Optional[int]:
    """:func:`unbalanced_at` of a 1-D uint8 0/1 array already checked (:func:`bits_array`)."""
    _, first_negative, final = _block_minima(b, -(-b.size // BLOCK_BITS), BLOCK_BITS)
    if first_negative >= 0:
        return int(first_negative)
    return None if final == 0 else int(b.size)


@pytree_dataclass
class BalancedParens:
    """A balanced parentheses sequence with rank/select and a range min-max tree.

    Fields:
      bits: the sequence as a :class:`BitVector` (1 = ``(``).
      tree: ``(T,)`` int32, the min-tree levels one after the other: level 0 is ``M`` (one value
        per 256-bit block: the minimum of ``E(k + 1)`` over the block's bits, padding bits counted
        as ``(``), level ``h + 1`` holds the minima of pairs of level ``h`` (``2**30`` for a missing
        child).
      level_offsets, level_sizes: static tuples locating each level in ``tree``.
    """

    bits: BitVector
    tree: jnp.ndarray
    level_offsets: tuple = static_field()
    level_sizes: tuple = static_field()

    @classmethod
    def from_bits(cls, bits, *, check: bool = True) -> "BalancedParens":
        """Build from a host 0/1 sequence (1 = ``(``) or a string of ``(``/``)`` or ``1``/``0``.

        Raises :class:`~jaxcds.errors.EncodingError` naming the offending offset if the
        sequence is not balanced or holds a value other than 0/1 (``check=False``, a bool, skips
        the balance test for prefixes of sequences)."""
        if isinstance(bits, str):
            table = {"(": 1, ")": 0, "1": 1, "0": 0}
            bad = [i for i, c in enumerate(bits) if c not in table]
            if bad:
                raise errors.EncodingError(f"BalancedParens.from_bits: parenthesis string has {bits[bad[0]]!r} "
                                           f"at offset {bad[0]}, expected '(', ')', '1' or '0'")
            bits = np.array([table[c] for c in bits], dtype=np.uint8)
        check = flag_arg(check, "BalancedParens.from_bits: check")
        return cls._from_valid_bits(bits_array(bits, "BalancedParens.from_bits: bits"), check=check)

    @classmethod
    def _from_valid_bits(cls, b: np.ndarray, *, check: bool) -> "BalancedParens":
        """:meth:`from_bits` of a 1-D 0/1 array already checked (:func:`bits_array`, or made by
        the library; ``check``, a bool: the balance test): no second scan for values other
        than 0 and 1."""
        b = np.asarray(b).astype(np.uint8, copy=False)
        bv = BitVector._from_valid_bits(b)
        nb = bv.num_blocks
        # one pass, O(blocks) memory: the excess of every prefix as an int64 array (and its
        # cumsum temporaries) took about 5 GB at 165M parentheses (a 10,000-mesh pemb batch)
        level, first_negative, final = _block_minima(b, nb, BLOCK_BITS)
        if check:
            if first_negative >= 0:
                raise errors.EncodingError(
                    f"unbalanced parentheses: ')' at offset {first_negative} closes nothing")
            if final != 0:
                raise errors.EncodingError(
                    f"unbalanced parentheses: {final} '(' left open at the end (length {b.size})")
        levels = [level]
        while levels[-1].size > 1:
            prev = levels[-1]
            if prev.size % 2:
                prev = np.concatenate([prev, [_INF]])
            levels.append(prev.reshape(-1, 2).min(axis=1).astype(np.int32))
        sizes = tuple(int(x.size) for x in levels)
        offsets = tuple(int(x) for x in np.concatenate([[0], np.cumsum(sizes)[:-1]]))
        return cls(bits=bv, tree=to_device(np.concatenate(levels)), level_offsets=offsets,
                   level_sizes=sizes)

    # ------------------------------------------------------------------ sizes
    @property
    def size(self) -> int:
        return self.bits.size

    @property
    def bits_support(self) -> int:
        """Rank directory + padding + min-tree, in bits."""
        return self.bits.bits_support + 32 * int(self.tree.shape[0])

    # ------------------------------------------------------------------ basic
    def excess(self, p) -> jnp.ndarray:
        """``E(p)``: opening minus closing parentheses among the first ``p`` symbols."""
        p = id_arg(p, "BalancedParens.excess: positions")
        return 2 * self.bits.rank1(p) - p

    def is_open(self, i) -> jnp.ndarray:
        return self.bits.access(id_arg(i, "BalancedParens.is_open: positions")) == 1

    def rank_open(self, i) -> jnp.ndarray:
        """Opening parentheses in ``[0, i)`` (preorder rank of the node opened at ``i``)."""
        return self.bits.rank1(id_arg(i, "BalancedParens.rank_open: positions"))

    def select_open(self, k) -> jnp.ndarray:
        """Position of the ``k``-th (0-based) ``(``; ``size`` if none."""
        return self.bits.select1(id_arg(k, "BalancedParens.select_open: ranks"))

    # ------------------------------------------------------------------ block scan
    def _scan_words(self, blk, lo, hi, t, fw):
        """Within block ``blk``, among bits ``k`` in ``[lo, hi)`` (block-relative), the first
        (where ``fw``) or last *word* holding a bit with ``E(256 blk + k + 1) <= t``.

        Elementwise state only (no ``(..., 16)`` intermediates): the 8 words one after the other
        (a ``fori_loop`` unrolled by 2), each word's minimum prefix excess from two ``CHUNK_MIN``
        lookups. Returns ``(found, w, s, n, k)``: the word shifted to its first bit in range
        (``'('`` past its ``n`` bits in range), ``E`` before that bit, and its block offset."""
        table = jnp.asarray(CHUNK_MIN)
        e = 2 * self.bits.block_rank[blk] - BLOCK_BITS * blk  # E(256 blk)
        zero = jnp.zeros(jnp.shape(blk), jnp.int32)
        found = jnp.zeros(jnp.shape(blk), bool)
        wJ, sJ, nJ, kJ = jnp.zeros(jnp.shape(blk), jnp.uint32), zero, zero, zero
        full = jnp.uint32(0xFFFFFFFF)
        def word(j, c):
            e, found, wJ, sJ, nJ, kJ = c
            w = self.bits.words[blk * BLOCK_WORDS + j]
            valid = jnp.clip(self.size - (blk * BLOCK_BITS + 32 * j), 0, 32)
            w = w | ~_low_mask(valid)  # padding bits read as '('
            a = jnp.clip(lo - 32 * j, 0, 32)
            n = jnp.clip(hi - 32 * j, 0, 32) - a
            s_a = e + 2 * popcount(w & _low_mask(a)) - a
            sw = jnp.where(a >= 32, full, w >> jnp.minimum(a, 31).astype(jnp.uint32)) | ~_low_mask(n)
            lo16 = (sw & jnp.uint32(0xFFFF)).astype(jnp.int32)
            hi16 = (sw >> jnp.uint32(16)).astype(jnp.int32)
            m = jnp.minimum(table[lo16].astype(jnp.int32),
                            2 * popcount(lo16.astype(jnp.uint32)) - 16 + table[hi16].astype(jnp.int32))
            hit = (n > 0) & (s_a + m <= t)
            # not ~fw: fw is often a Python bool, whose ~ is an int (-1, -2) that met bool
            # arrays by promotion (a TypePromotionError under strict dtype promotion)
            take = hit & (~found | jnp.logical_not(fw))  # forward: the first hit word; backward: the last
            wJ = jnp.where(take, sw, wJ)
            sJ = jnp.where(take, s_a, sJ)
            nJ = jnp.where(take, n, nJ)
            kJ = jnp.where(take, 32 * j + a, kJ)
            found = found | hit
            e = e + 2 * popcount(w) - 32
            return e, found, wJ, sJ, nJ, kJ

        e, found, wJ, sJ, nJ, kJ = jax.lax.fori_loop(0, BLOCK_WORDS, word,
                                                     (e, found, wJ, sJ, nJ, kJ),
                                                     unroll=SCAN_UNROLL if blk.size >= UNROLL_FROM else 2)
        return found, wJ, sJ, nJ, kJ

    @staticmethod
    def _scan_word(w, s, n, t, fw):
        """Offset in the word ``w`` (from :meth:`_scan_words`: ``n`` bits in range, ``E = s``
        before them) of the first (``fw``) / last bit whose prefix excess is ``<= t``: its
        16-bit half, then its byte (``CHUNK_MIN`` of the byte padded with ``'('``), then 8
        unrolled bit steps. Past the ``n`` bits in range everything reads ``'('``: it never
        lowers a minimum, but backward it could be a false last hit, so a half or byte is taken
        backward only if it holds a bit in range."""
        table = jnp.asarray(CHUNK_MIN)
        off = jnp.zeros(jnp.shape(s), jnp.int32)
        for width in (16, 8):
            mask = jnp.uint32((1 << width) - 1)
            low = w & mask
            pad = jnp.uint32(0xFFFF & ~((1 << width) - 1))  # '(' above a byte in the table index
            m_low = table[(low | pad).astype(jnp.int32)].astype(jnp.int32)
            s_up = s + 2 * popcount(low) - width
            up = w >> jnp.uint32(width)
            m_up = table[((up & mask) | pad).astype(jnp.int32)].astype(jnp.int32)
            hit_low = s + m_low <= t
            hit_up = (n > width) & (s_up + m_up <= t)
            use_up = jnp.where(fw, ~hit_low, hit_up)
            w = jnp.where(use_up, up, low)
            s = jnp.where(use_up, s_up, s)
            n = jnp.where(use_up, n - width, n)
            off = jnp.where(use_up, off + width, off)
        fq = jnp.zeros(jnp.shape(s), bool)
        qq = jnp.zeros(jnp.shape(s), jnp.int32)
        for q in range(8):
            s = s + 2 * ((w >> jnp.uint32(q)) & jnp.uint32(1)).astype(jnp.int32) - 1
            ok = (q < n) & (s <= t)
            qq = jnp.where(ok & (~fq | jnp.logical_not(fw)), q, qq)
            fq = fq | ok
        return off + qq

    def _scan(self, blk, lo, hi, t, fw):
        """Within block ``blk``, among bits ``k`` in ``[lo, hi)`` (block-relative), the first
        (where ``fw``) or last bit with ``E(256 blk + k + 1) <= t``. Returns ``(found, k)``."""
        found, w, s, n, k = jax.lax.optimization_barrier(self._scan_words(blk, lo, hi, t, fw))
        return found, (k + self._scan_word(w, s, n, t, fw)).astype(jnp.int32)

    # ------------------------------------------------------------------ tree search
    def _tree_get(self, level, node):
        off = jnp.asarray(np.asarray(self.level_offsets, np.int32))[level]
        size = jnp.asarray(np.asarray(self.level_sizes, np.int32))[level]
        val = self.tree[off + jnp.clip(node, 0, size - 1)]
        return jnp.where((node >= 0) & (node < size), val, _INF)

    def _tree_search(self, blk, t, fw):
        """Nearest block after (where ``fw``) / before ``blk`` whose minimum ``M <= t``; found
        flag and block. Two ``fori_loop`` s over the levels (climb, then descend)."""
        nlev = len(self.level_sizes)
        # one int32 of carry per query and loop (a loop's carry is written and read back at every
        # step): the climb carries ``32 cand + level`` (-1: none yet; the node at step h is
        # blk >> h), the descent ``32 node + level``
        def climb(h, c):  # the first sibling on the search side whose subtree reaches t
            node = blk >> h
            sib = jnp.where(fw, node + 1, node - 1)
            side = (node & 1) == jnp.where(fw, 0, 1)
            ok = (c < 0) & side & (self._tree_get(h, sib) <= t)
            return jnp.where(ok, 32 * sib + h, c)

        c = jax.lax.fori_loop(0, nlev - 1, climb, jnp.full(jnp.shape(blk), -1, jnp.int32),
                              unroll=UNROLL)
        found = c >= 0

        def descend(_, c):  # the nearest child that reaches t (else the other one does)
            node, lvl = c >> 5, c & 31
            go = lvl > 0
            child_lvl = jnp.maximum(lvl - 1, 0)
            near = jnp.where(fw, 2 * node, 2 * node + 1)
            far = jnp.where(fw, 2 * node + 1, 2 * node)
            take_near = self._tree_get(child_lvl, near) <= t
            return jnp.where(go, 32 * jnp.where(take_near, near, far) + child_lvl, c)

        c = jax.lax.fori_loop(0, nlev - 1, descend, jnp.where(found, c, 0), unroll=UNROLL)
        node = c >> 5
        return found, node.astype(jnp.int32)

    # ------------------------------------------------------------------ two-word stage
    def _word(self, j):
        """Word ``j`` with the bits at or past ``size`` read as ``'('`` (as the block scan reads
        them)."""
        nw = self.bits.words.shape[0]
        w = self.bits.words[jnp.clip(j, 0, nw - 1)]
        return w | ~_low_mask(jnp.clip(self.size - 32 * j, 0, 32))

    @staticmethod
    def _word_min(w):
        """Minimum prefix excess over the 32 prefixes of ``w`` (two ``CHUNK_MIN`` lookups)."""
        table = jnp.asarray(CHUNK_MIN)
        lo16 = (w & jnp.uint32(0xFFFF)).astype(jnp.int32)
        hi16 = (w >> jnp.uint32(16)).astype(jnp.int32)
        return jnp.minimum(table[lo16].astype(jnp.int32),
                           2 * popcount(lo16.astype(jnp.uint32)) - 16 + table[hi16].astype(jnp.int32))

    def _near(self, i, d, fw):
        """First stage of a search, relative to ``E(i)``: where ``fw``, the first bit ``k >= i``
        with ``E(k + 1) - E(i) <= d`` among the rest of ``i``'s word and the next word; elsewhere
        the last bit ``k < i`` with ``E(k + 1) - E(i) <= d`` among the bits of ``i - 1``'s word
        before ``i`` and the previous word, returned as ``k + 1``. Returns ``(found, result)``;
        a found answer is the answer of the full search (the first / last hit overall).

        Every excess is relative, so no rank is needed: the excess at the start of a word is
        the popcount of the bits between it and ``i``. Backward, the bits of the first word from
        ``i`` on read ``'('`` (relative excess ``1, 2, ...`` past ``i``): a hit there is only
        trusted for ``d <= 0`` (pemb's backward searches have ``d = -1``)."""
        j = jnp.where(fw, i >> 5, (i - 1) >> 5)
        wj = self._word(j)
        a = i & 31
        n_fw = 32 - a
        n_bw = i - 32 * j
        w1 = jnp.where(fw, (wj >> a.astype(jnp.uint32)) | ~_low_mask(n_fw), wj | ~_low_mask(n_bw))
        n1 = jnp.where(fw, n_fw, n_bw)
        ones1 = popcount(w1) - (32 - n1)  # ones among the word's n1 bits in range
        s1 = jnp.where(fw, 0, n1 - 2 * ones1)  # relative excess before the first bit in range
        hit1 = (s1 + self._word_min(w1) <= d) & (fw | ((i >= 1) & (i <= self.size) & (d <= 0)))
        j2 = jnp.where(fw, j + 1, j - 1)
        w2 = self._word(j2)
        s2 = jnp.where(fw, 2 * ones1 - n1, s1 - 2 * popcount(w2) + 32)
        hit2 = (s2 + self._word_min(w2) <= d) & (fw | ((j2 >= 0) & (i <= self.size)))
        # forward the first word wins (earlier bits); backward too (later bits)
        w = jnp.where(hit1, w1, w2)
        s = jnp.where(hit1, s1, s2)
        n = jnp.where(hit1, n1, 32)
        base = jnp.where(hit1, jnp.where(fw, i, 32 * j), 32 * j2)
        k = base + self._scan_word(w, s, n, d, fw)
        return hit1 | hit2, jnp.where(fw, k, k + 1).astype(jnp.int32)

    def _two_stage(self, i, d, fw, slow, chunk: Optional[int] = None, active=None):
        """``slow(i, d, fw)`` (an operation's full answer) where :meth:`_near` finds nothing;
        :meth:`_near`'s answer elsewhere; lanes outside ``active`` (default: all) get an
        unspecified answer and no slow-route work. Any shapes (flattened, then restored)."""
        i = jnp.asarray(i, jnp.int32)
        shape = jnp.broadcast_shapes(i.shape, jnp.shape(d), jnp.shape(fw))
        i = jnp.broadcast_to(i, shape).reshape(-1)
        d = jnp.broadcast_to(jnp.asarray(d, jnp.int32), shape).reshape(-1)
        fw = jnp.broadcast_to(jnp.asarray(fw, bool), shape).reshape(-1)
        found, res = self._near(i, d, fw)
        if active is not None:
            found = found | ~mask_arg(active, shape, "BalancedParens.match: active").reshape(-1)
        out = compacted(slow, ~found, res, (i, d, fw), chunk)
        return out.reshape(shape)

    # ------------------------------------------------------------------ searches
    def _search(self, i, t, fw):
        """One search in either direction (elementwise ``fw``): where ``fw``, the first bit
        ``k >= i`` with ``E(k + 1) <= t``; elsewhere the last bit ``k < i`` with
        ``E(k + 1) <= t``, returned as the prefix position ``k + 1``. ``size`` if none.

        The near block (the query's own) and the far block (from the min-tree) are both scanned
        (two elementwise word scans, then one bit-level finish on the chosen word)."""
        i = jnp.asarray(i, jnp.int32)
        shape = jnp.broadcast_shapes(i.shape, jnp.shape(t), jnp.shape(fw))
        i = jnp.broadcast_to(i, shape)
        t = jnp.broadcast_to(jnp.asarray(t, jnp.int32), shape)
        fw = jnp.broadcast_to(jnp.asarray(fw, bool), shape)
        last = jnp.maximum(i - 1, 0)
        anchor = jnp.where(fw, i, last)
        blk = anchor >> 8
        lo = jnp.where(fw, anchor & (BLOCK_BITS - 1), 0)
        hi = jnp.where(fw, BLOCK_BITS, (anchor & (BLOCK_BITS - 1)) + 1)
        f2, b2 = self._tree_search(blk, t, fw)
        b2 = jnp.clip(b2, 0, self.level_sizes[0] - 1)
        fa, wa, sa, na, ka = self._scan_words(blk, lo, hi, t, fw)
        fb, wb, sb, nb, kb = self._scan_words(b2, jnp.zeros_like(i), jnp.full_like(i, BLOCK_BITS),
                                              t, fw)
        ok = fw | (i >= 1)
        f1 = fa & ok
        f2 = f2 & fb & ok
        # one bit-level finish, on the word chosen (near block first)
        k = self._scan_word(jnp.where(f1, wa, wb), jnp.where(f1, sa, sb), jnp.where(f1, na, nb),
                            t, fw) + jnp.where(f1, ka, kb)
        kk = jnp.where(f1, BLOCK_BITS * blk, BLOCK_BITS * b2) + k
        res = jnp.where(fw, kk, kk + 1)
        res = jnp.where(f1 | f2, res, self.size)
        return jnp.where(fw & (res >= self.size), self.size, res).astype(jnp.int32)

    def fwd(self, i, t) -> jnp.ndarray:
        """First bit ``k >= i`` with ``E(k + 1) <= t``; ``size`` if none."""
        i = id_arg(i, "BalancedParens.fwd: positions")
        t = _level_arg(t, "BalancedParens.fwd: targets")
        broadcast_args("BalancedParens.fwd", i, t)
        return self._search(i, t, True)

    def bwd(self, p, t) -> jnp.ndarray:
        """Last prefix position ``q <= p`` with ``E(q) <= t``; ``size`` if none."""
        p = id_arg(p, "BalancedParens.bwd: positions")
        t = _level_arg(t, "BalancedParens.bwd: targets")
        broadcast_args("BalancedParens.bwd", p, t)
        r = self._search(p, t, False)
        r = jnp.where(r == self.size, jnp.where(t >= 0, 0, self.size), r)  # E(0) = 0
        return jnp.where(self.excess(p) <= t, p, r).astype(jnp.int32)

    # ------------------------------------------------------------------ tree operations
    def find_close(self, i) -> jnp.ndarray:
        """Position of the ``)`` matching the ``(`` at ``i``."""
        i = id_arg(i, "BalancedParens.find_close: positions")
        return self.fwd(i, self.excess(i))

    def find_open(self, j) -> jnp.ndarray:
        """Position of the ``(`` matching the ``)`` at ``j``."""
        j = id_arg(j, "BalancedParens.find_open: positions")
        return self.bwd(j, self.excess(j + 1))

    def match(self, i, *, active=None, chunk: Optional[int] = None) -> jnp.ndarray:
        """The matching parenthesis of ``i``, whichever way it opens (one search: the two
        directions share one program, chosen elementwise; two stages, :meth:`_two_stage`).
        Lanes outside ``active`` (default: all) get an unspecified answer, cheaply."""
        i = id_arg(i, "BalancedParens.match: positions")
        op = self.is_open(i)
        # '(' at i: fwd(i, E(i)); ')' at i: bwd(i, E(i + 1)) = bwd(i, E(i) - 1), never at i itself
        return self._two_stage(i, jnp.where(op, 0, -1), op, self._match_slow, chunk, active)

    def match_all(self, *, chunk: Optional[int] = None) -> jnp.ndarray:
        """``(size,)`` int32: the match of every parenthesis, ``match(arange(size))``, in about
        half the work of asking each one: only the ``(`` need a search (forward, relative to
        ``E(i)``: :meth:`_near`, with ``fw`` a constant so the backward half of the first stage
        compiles away), and each ``)`` is then written by one scatter from its ``(``. The first
        stage misses a pair exactly when its ``)`` is more than one word past its ``(``'s word,
        the same condition seen from either end, so only those ``(`` take the min-max tree route
        (compacted, :func:`compacted`). Used by structures that build a per-phase table of all
        matches (pemb's :meth:`~jaxcds.structures.pemb.PEMB.with_tables`). With
        :data:`MATCH_BY_SORT`, one sort by level instead (:func:`matches_by_level`)."""
        chunk_arg(chunk)  # checked on the sort route too, which does not use it
        n = self.size
        i = jnp.arange(n, dtype=jnp.int32)
        op = self.is_open(i)
        if MATCH_BY_SORT:
            return matches_by_level(op)
        close = self.closes_of(i, op, chunk=chunk)
        # every ')' is the match of exactly one '(': one scatter fills them all
        return close.at[jnp.where(op, close, n)].set(i, mode="drop")

    def closes_of(self, i, opens, *, chunk: Optional[int] = None) -> jnp.ndarray:
        """int32, the shape of ``i``: the ``)`` matching the ``(`` at each position ``i`` where
        ``opens`` (flags broadcast to ``i``); other lanes unspecified and spared the slow route.
        The forward half of :meth:`match`'s two stages (``fw`` a constant): :meth:`_near`, then
        the min-max tree for the misses only (compacted, :func:`compacted`)."""
        i = id_arg(i, "BalancedParens.closes_of: positions")
        shape = i.shape
        opens = mask_arg(opens, shape, "BalancedParens.closes_of: opens").reshape(-1)
        i = i.reshape(-1)
        found, near = self._near(i, jnp.zeros_like(i), True)
        return compacted(lambda i: self._search(i, self.excess(i), True), opens & ~found, near,
                         (i,), chunk).reshape(shape)

    def _match_slow(self, i, d, op):
        r = self._search(i, self.excess(i) + d, op)
        # a ')' whose pair opens at 0: the backward scan covers prefix positions >= 1 only
        return jnp.where(~op & (r == self.size), 0, r).astype(jnp.int32)

    def enclose(self, i, *, chunk: Optional[int] = None) -> jnp.ndarray:
        """Opening parenthesis of the innermost pair still open just before position ``i``
        (for ``(`` at ``i``: its parent); ``size`` if none (``i`` at depth 0). Two stages
        (:meth:`_two_stage`): ``bwd(i, E(i) - 1)`` is a backward search with ``d = -1``."""
        i = id_arg(i, "BalancedParens.enclose: positions")
        return self._two_stage(i, -1, False, self._enclose_slow, chunk)

    def _enclose_slow(self, i, d, fw):
        return self.bwd(i, self.excess(i) + d)

    def __str__(self) -> str:
        return "".join("(" if x else ")" for x in self.bits.to_numpy().tolist())
