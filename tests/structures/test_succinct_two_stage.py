"""The two-stage parenthesis searches (issue 7): the two-word first stage and the compacted,
chunked slow route, against a stack oracle, on sequences whose matches are near (most answered in
the first stage) and far (most compacted), with chunks small enough to loop several times."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxcds.structures.succinct import BalancedParens, BitVector
from jaxcds.structures.succinct import bitvector as bvmod
from jaxcds.structures.succinct import bp as bpmod

from parens_helpers import random_balanced

# batches must be larger than SELECT_ALL_BELOW to take the two stages and the compaction
PAIRS = bvmod.SELECT_ALL_BELOW // 2 + 500


def _oracle(b: np.ndarray):
    n = b.size
    match = np.full(n, -1)
    enclose = np.full(n + 1, n)
    stack = []
    for i, x in enumerate(b):
        enclose[i] = stack[-1] if stack else n
        if x:
            stack.append(i)
        else:
            j = stack.pop()
            match[i], match[j] = j, i
    return match, enclose  # enclose[n] = n: depth 0 at the end


@functools.partial(jax.jit, static_argnames=("chunk",))
def _ops(bp, i, chunk):
    return bp.match(jnp.minimum(i, bp.size - 1), chunk=chunk), bp.enclose(i, chunk=chunk)


@pytest.mark.parametrize("p_open,seed", [(0.5, 0), (0.5, 1), (0.95, 2), (0.3, 3)])
@pytest.mark.parametrize("chunk", [64, 1000])
def test_two_stage_against_stack(p_open, seed, chunk):
    b = random_balanced(seed, PAIRS, p_open)
    bp = BalancedParens.from_bits(b)
    match, enclose = _oracle(b)
    i = jnp.arange(b.size + 1, dtype=jnp.int32)
    m, enc = map(np.asarray, _ops(bp, i, chunk))
    np.testing.assert_array_equal(m[:-1], match)
    np.testing.assert_array_equal(enc, enclose)


def test_first_stage_answers_are_exact_and_misses_are_flagged():
    """``_near`` alone: every answer it claims is the oracle's; on a near sequence it claims most,
    on a deep one few (so the slow route is really exercised by the test above)."""
    for p_open, lo, hi in ((0.5, 0.6, 1.0), (0.97, 0.0, 0.5)):
        b = random_balanced(5, PAIRS, p_open)
        bp = BalancedParens.from_bits(b)
        match, enclose = _oracle(b)
        i = jnp.arange(b.size, dtype=jnp.int32)
        op = bp.is_open(i)
        f, r = jax.jit(lambda s, i, op: s._near(i, jnp.where(op, 0, -1), op))(bp, i, op)
        f, r = np.asarray(f), np.asarray(r)
        np.testing.assert_array_equal(r[f], match[f])
        fe, re = jax.jit(lambda s, i: s._near(i, jnp.full_like(i, -1), jnp.zeros(i.shape, bool)))(bp, i)
        fe, re = np.asarray(fe), np.asarray(re)
        np.testing.assert_array_equal(re[fe], enclose[:-1][fe])
        assert lo <= f.mean() <= hi, f.mean()


def test_compacted_handles_every_miss_rate():
    rng = np.random.default_rng(0)
    n = bvmod.SELECT_ALL_BELOW + 1000
    x = jnp.asarray(rng.integers(0, 100, n), jnp.int32)
    for rate in (0.0, 0.1, 0.5, 1.0):
        miss = jnp.asarray(rng.random(n) < rate)
        out = jax.jit(lambda m, x: bpmod.compacted(lambda v: 3 * v + 1, m, -x, (x,), 64))(miss, x)
        want = np.where(np.asarray(miss), 3 * np.asarray(x) + 1, -np.asarray(x))
        np.testing.assert_array_equal(np.asarray(out), want)


@pytest.mark.parametrize("p", [0.02, 0.5, 0.98])
def test_select_near_against_numpy(p):
    """``select_near(k, bit, i, rank(i, bit))`` = the k-th ``bit``, for hints near and far from
    the answer (near: first stage; far: the compacted binary-search select), both polarities."""
    rng = np.random.default_rng(int(100 * p))
    n = 3000
    b = (rng.random(n) < p).astype(np.uint8)
    bv = BitVector.from_bits(b)
    q = bvmod.SELECT_ALL_BELOW + 1000
    bit = rng.integers(0, 2, q)
    pos = [np.nonzero(b == v)[0] for v in (0, 1)]
    cnt = np.array([pos[0].size, pos[1].size])
    k = rng.integers(0, np.maximum(cnt[bit], 1)) + np.where(rng.random(q) < 0.02, 10**6, 0)
    i = np.where(rng.random(q) < 0.5, rng.integers(0, n + 1, q),  # anywhere
                 np.clip(np.array([pos[v][min(kk, max(cnt[v] - 1, 0))] if cnt[v] else 0
                                   for v, kk in zip(bit, k)]) + rng.integers(-40, 41, q), 0, n))
    cum = np.stack([np.concatenate([[0], np.cumsum(1 - b)]), np.concatenate([[0], np.cumsum(b)])])
    r = cum[bit, i]
    want = np.array([pos[v][kk] if kk < cnt[v] else n for v, kk in zip(bit, k)])
    f = jax.jit(lambda s, k, o, i, r: s.select_near(k, o, i, r, chunk=256))
    got = np.asarray(f(bv, *(jnp.asarray(x, jnp.int32) for x in (k, bit, i, r))))
    np.testing.assert_array_equal(got, want)
