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
A search scans its own block (16 chunks of 16 bits: a 64K-entry table gives each chunk's minimum
prefix excess, then the 16 bits of the winning chunk), climbs the tree to the nearest block whose
minimum reaches the target, descends to it, and scans it. Everything is computed for every
query (both the near and the far candidate) and selected with ``jnp.where``: no data-dependent
branch, so ``vmap`` and ``jit`` see a fixed program of ``O(log blocks)`` gathers.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxcds import errors
from jaxcds._dataclass import pytree_dataclass, static_field
from jaxcds.structures.succinct.bitvector import BLOCK_BITS, BLOCK_WORDS, BitVector, popcount

__all__ = ["BalancedParens", "excess_oracle", "CHUNK_MIN"]

_INF = np.int32(1 << 30)


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
    """Host reference: ``E(p)`` for ``p = 0..n`` (length ``n + 1``)."""
    b = np.asarray(bits, dtype=np.int64)
    return np.concatenate([[0], np.cumsum(2 * b - 1)])


def _first_or_last(hit, fw):
    """Index of the first (where ``fw``) or last True along the last axis (0 if none)."""
    w = hit.shape[-1]
    idx = jnp.arange(w, dtype=jnp.int32)
    first = jnp.min(jnp.where(hit, idx, w), axis=-1)
    last = jnp.max(jnp.where(hit, idx, -1), axis=-1)
    return jnp.clip(jnp.where(fw, first, last), 0, w - 1).astype(jnp.int32)


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
        sequence is not balanced (``check=False`` skips the test for prefixes of sequences)."""
        if isinstance(bits, str):
            table = {"(": 1, ")": 0, "1": 1, "0": 0}
            bad = [i for i, c in enumerate(bits) if c not in table]
            if bad:
                raise errors.EncodingError(f"parenthesis string has {bits[bad[0]]!r} at offset {bad[0]}")
            bits = np.array([table[c] for c in bits], dtype=np.uint8)
        b = np.asarray(bits).astype(np.uint8).ravel()
        exc = excess_oracle(b)
        if check:
            if np.any(exc < 0):
                k = int(np.argmax(exc < 0)) - 1
                raise errors.EncodingError(f"unbalanced parentheses: ')' at offset {k} closes nothing")
            if exc[-1] != 0:
                raise errors.EncodingError(
                    f"unbalanced parentheses: {int(exc[-1])} '(' left open at the end (length {b.size})")
        bv = BitVector.from_bits(b)
        nb = bv.num_blocks
        # E(k + 1) for every bit of every block; padding bits are '(' (never a false hit)
        e = np.empty(nb * BLOCK_BITS, dtype=np.int64)
        e[: b.size] = exc[1:]
        e[b.size:] = exc[-1] + np.arange(1, nb * BLOCK_BITS - b.size + 1)
        level = e.reshape(nb, BLOCK_BITS).min(axis=1).astype(np.int32)
        levels = [level]
        while levels[-1].size > 1:
            prev = levels[-1]
            if prev.size % 2:
                prev = np.concatenate([prev, [_INF]])
            levels.append(prev.reshape(-1, 2).min(axis=1).astype(np.int32))
        sizes = tuple(int(x.size) for x in levels)
        offsets = tuple(int(x) for x in np.concatenate([[0], np.cumsum(sizes)[:-1]]))
        return cls(bits=bv, tree=jnp.asarray(np.concatenate(levels)), level_offsets=offsets,
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
        p = jnp.asarray(p, jnp.int32)
        return 2 * self.bits.rank1(p) - p

    def is_open(self, i) -> jnp.ndarray:
        return self.bits.access(i) == 1

    def rank_open(self, i) -> jnp.ndarray:
        """Opening parentheses in ``[0, i)`` (preorder rank of the node opened at ``i``)."""
        return self.bits.rank1(i)

    def select_open(self, k) -> jnp.ndarray:
        """Position of the ``k``-th (0-based) ``(``; ``size`` if none."""
        return self.bits.select1(k)

    # ------------------------------------------------------------------ block scan
    def _scan(self, blk, lo, hi, t, fw):
        """Within block ``blk``, among bits ``k`` in ``[lo, hi)`` (block-relative), the first
        (where ``fw``) or last bit with ``E(256 blk + k + 1) <= t``. Returns ``(found, k)``."""
        words = self.bits._block_words(blk)  # (..., 8)
        # padding bits (at or past size) read as '('
        gbit = (blk[..., None] * BLOCK_BITS + 32 * jnp.arange(BLOCK_WORDS, dtype=jnp.int32))
        valid = jnp.clip(self.size - gbit, 0, 32).astype(jnp.uint32)
        low = jnp.where(valid >= 32, jnp.uint32(0xFFFFFFFF),
                        (jnp.uint32(1) << jnp.minimum(valid, 31)) - jnp.uint32(1))
        words = words | ~low
        chunks = jnp.stack([words & jnp.uint32(0xFFFF), words >> jnp.uint32(16)], axis=-1)
        chunks = chunks.reshape(*words.shape[:-1], _CHUNKS)  # chunk j = bits 16j..16j+15
        tot = 2 * popcount(chunks) - 16
        base = 2 * self.bits.block_rank[blk] - BLOCK_BITS * blk  # E(256 blk)
        start = base[..., None] + jnp.cumsum(tot, axis=-1) - tot  # E at each chunk start
        j16 = 16 * jnp.arange(_CHUNKS, dtype=jnp.int32)
        a = jnp.clip(lo[..., None] - j16, 0, 16)  # valid bits of chunk j: [a, b)
        b = jnp.clip(hi[..., None] - j16, 0, 16)
        au = a.astype(jnp.uint32)
        # excess before bit a of the chunk; the chunk shifted by a, '(' past its b - a valid
        # bits ('(' only raises later prefixes, so the table minimum is that of the valid bits)
        lowa = (jnp.uint32(1) << au) - jnp.uint32(1)
        base_a = start + 2 * popcount(chunks & lowa) - a
        width = (b - a).astype(jnp.uint32)
        keep = (jnp.uint32(1) << width) - jnp.uint32(1)
        shifted = ((chunks >> au) & keep) | (~keep & jnp.uint32(0xFFFF))
        cmin = jnp.asarray(CHUNK_MIN)[shifted.astype(jnp.int32)].astype(jnp.int32)
        hit = (b > a) & (base_a + cmin <= t[..., None])
        found = jnp.any(hit, axis=-1)
        J = _first_or_last(hit, fw)
        sel = jnp.arange(_CHUNKS, dtype=jnp.int32) == J[..., None]  # one-hot pick of chunk J
        c = jnp.max(jnp.where(sel, chunks, jnp.uint32(0)), axis=-1)
        s = jnp.sum(jnp.where(sel, start, 0), axis=-1)
        aJ = jnp.sum(jnp.where(sel, a, 0), axis=-1)[..., None]
        bJ = jnp.sum(jnp.where(sel, b, 0), axis=-1)[..., None]
        q = jnp.arange(16, dtype=jnp.int32)
        step = 2 * ((c[..., None] >> q.astype(jnp.uint32)) & jnp.uint32(1)).astype(jnp.int32) - 1
        exc = s[..., None] + jnp.cumsum(step, axis=-1)  # E after bit q of the chunk
        ok = (q >= aJ) & (q < bJ) & (exc <= t[..., None])
        qq = _first_or_last(ok, fw)
        return found, (16 * J + qq).astype(jnp.int32)

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

        def climb(h, c):  # the first sibling on the search side whose subtree reaches t
            node, found, cand, cand_lvl = c
            sib = jnp.where(fw, node + 1, node - 1)
            side = (node & 1) == jnp.where(fw, 0, 1)
            ok = ~found & side & (self._tree_get(h, sib) <= t)
            return (node >> 1, found | ok, jnp.where(ok, sib, cand), jnp.where(ok, h, cand_lvl))

        zero = jnp.zeros_like(blk)
        _, found, node, lvl = jax.lax.fori_loop(
            0, nlev - 1, climb, (blk, jnp.zeros(jnp.shape(blk), bool), zero, zero))

        def descend(_, c):  # the nearest child that reaches t (else the other one does)
            node, lvl = c
            go = lvl > 0
            child_lvl = jnp.maximum(lvl - 1, 0)
            near = jnp.where(fw, 2 * node, 2 * node + 1)
            far = jnp.where(fw, 2 * node + 1, 2 * node)
            take_near = self._tree_get(child_lvl, near) <= t
            return (jnp.where(go, jnp.where(take_near, near, far), node),
                    jnp.where(go, child_lvl, lvl))

        node, _ = jax.lax.fori_loop(0, nlev - 1, descend, (node, lvl))
        return found, node.astype(jnp.int32)

    # ------------------------------------------------------------------ searches
    def _search(self, i, t, fw):
        """One search in either direction (elementwise ``fw``): where ``fw``, the first bit
        ``k >= i`` with ``E(k + 1) <= t``; elsewhere the last bit ``k < i`` with
        ``E(k + 1) <= t``, returned as the prefix position ``k + 1``. ``size`` if none.

        The near block (the query's own) and the far block (from the min-tree) are scanned by
        one stacked call."""
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
        two = lambda x, y: jnp.stack([x, y])  # noqa: E731
        f, k = self._scan(two(blk, b2), two(lo, jnp.zeros_like(i)),
                          two(hi, jnp.full_like(i, BLOCK_BITS)), two(t, t), two(fw, fw))
        ok = fw | (i >= 1)
        f1 = f[0] & ok
        f2 = f2 & f[1] & ok
        kk = jnp.where(f1, BLOCK_BITS * blk + k[0], BLOCK_BITS * b2 + k[1])
        res = jnp.where(fw, kk, kk + 1)
        res = jnp.where(f1 | f2, res, self.size)
        return jnp.where(fw & (res >= self.size), self.size, res).astype(jnp.int32)

    def fwd(self, i, t) -> jnp.ndarray:
        """First bit ``k >= i`` with ``E(k + 1) <= t``; ``size`` if none."""
        return self._search(i, t, True)

    def bwd(self, p, t) -> jnp.ndarray:
        """Last prefix position ``q <= p`` with ``E(q) <= t``; ``size`` if none."""
        p = jnp.asarray(p, jnp.int32)
        t = jnp.asarray(t, jnp.int32)
        r = self._search(p, t, False)
        r = jnp.where(r == self.size, jnp.where(t >= 0, 0, self.size), r)  # E(0) = 0
        return jnp.where(self.excess(p) <= t, p, r).astype(jnp.int32)

    # ------------------------------------------------------------------ tree operations
    def find_close(self, i) -> jnp.ndarray:
        """Position of the ``)`` matching the ``(`` at ``i``."""
        i = jnp.asarray(i, jnp.int32)
        return self.fwd(i, self.excess(i))

    def find_open(self, j) -> jnp.ndarray:
        """Position of the ``(`` matching the ``)`` at ``j``."""
        j = jnp.asarray(j, jnp.int32)
        return self.bwd(j, self.excess(j + 1))

    def match(self, i) -> jnp.ndarray:
        """The matching parenthesis of ``i``, whichever way it opens (one search: the two
        directions share one scan/tree program, chosen elementwise)."""
        i = jnp.asarray(i, jnp.int32)
        op = self.is_open(i)
        # '(' at i: fwd(i, E(i)); ')' at i: bwd(i, E(i + 1)), never at i itself nor at 0
        e_i = self.excess(i)
        t = jnp.where(op, e_i, e_i - 1)
        r = self._search(i, t, op)
        # a ')' whose pair opens at 0: the backward scan covers prefix positions >= 1 only
        return jnp.where(~op & (r == self.size), 0, r).astype(jnp.int32)

    def enclose(self, i) -> jnp.ndarray:
        """Opening parenthesis of the innermost pair still open just before position ``i``
        (for ``(`` at ``i``: its parent); ``size`` if none (``i`` at depth 0)."""
        i = jnp.asarray(i, jnp.int32)
        return self.bwd(i, self.excess(i) - 1)

    def __str__(self) -> str:
        return "".join("(" if x else ")" for x in self.bits.to_numpy().tolist())
