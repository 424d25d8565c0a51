"""Succinct building blocks against plain-numpy oracles on random bit strings.

Lengths are drawn from a few fixed sizes (around word and block boundaries, and long enough for
the min-max tree to be searched several levels deep) so jitted queries compile once per size.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from jaxcds import errors
from jaxcds.structures.succinct import BalancedParens, BitVector, excess_oracle
from jaxcds.structures.succinct.bp import matches_by_level as by_level

# Each length is one XLA compilation of every operation; the quick set keeps the word and block
# boundaries (32, 256 bits), the slow set adds the others.
SIZES = [1, 33, 256, 257, 2600]
PAIRS = [1, 16, 129, 3000]
SIZES_ALL = [1, 31, 32, 33, 255, 256, 257, 1000, 2600]
PAIRS_ALL = [1, 2, 16, 128, 129, 700, 3000]


@jax.jit
def _bv_all(bv, i, k):
    return bv.rank1(i), bv.rank0(i), bv.select1(k), bv.select0(k), bv.access(jnp.minimum(i, bv.size - 1))


@jax.jit
def _bp_all(bp, i):
    return bp.match(i), bp.find_close(i), bp.find_open(i), bp.enclose(i)


def _bits(draw_seed: int, n: int, p: float) -> np.ndarray:
    return (np.random.default_rng(draw_seed).random(n) < p).astype(np.uint8)


def _balanced(seed: int, pairs: int, deep: bool) -> np.ndarray:
    """A random balanced sequence; ``deep`` biases towards long matches (far blocks)."""
    rng = np.random.default_rng(seed)
    out = np.empty(2 * pairs, np.uint8)
    d = o = 0
    p_open = 0.8 if deep else 0.5
    for k in range(2 * pairs):
        rem = 2 * pairs - k
        if o < pairs and (d == 0 or (d < rem and rng.random() < p_open and d + 1 <= rem - 1)):
            out[k], d, o = 1, d + 1, o + 1
        else:
            out[k], d = 0, d - 1
        if deep and k == pairs:  # then close a lot
            p_open = 0.2
    return out


def _bp_oracle(b: np.ndarray):
    n = b.size
    match = np.full(n, -1)
    enclose = np.full(n, n)
    stack = []
    for i, x in enumerate(b):
        if x:
            enclose[i] = stack[-1] if stack else n
            stack.append(i)
        else:
            j = stack.pop()
            match[i], match[j] = j, i
    return match, enclose


@settings(max_examples=12, deadline=None)
@given(size=st.sampled_from(SIZES), seed=st.integers(0, 2**31), p=st.sampled_from([0.02, 0.5, 0.98]))
def test_rank_select_against_numpy(size, seed, p):
    _check_rank_select(size, seed, p)


@pytest.mark.slow
@settings(max_examples=40, deadline=None)
@given(size=st.sampled_from(SIZES_ALL), seed=st.integers(0, 2**31), p=st.sampled_from([0.02, 0.5, 0.98]))
def test_rank_select_against_numpy_all_sizes(size, seed, p):
    _check_rank_select(size, seed, p)


def _check_rank_select(size, seed, p):
    b = _bits(seed, size, p)
    bv = BitVector.from_bits(b)
    ones, zeros = np.nonzero(b)[0], np.nonzero(b == 0)[0]
    i = np.arange(size + 1)
    k = np.arange(size + 1)  # includes out-of-range ranks: answer is `size`
    r1, r0, s1, s0, acc = map(np.asarray, _bv_all(bv, jnp.asarray(i), jnp.asarray(k)))
    cum = np.concatenate([[0], np.cumsum(b)])
    np.testing.assert_array_equal(r1, cum)
    np.testing.assert_array_equal(r0, i - cum)
    want1 = np.full(size + 1, size)
    want1[: ones.size] = ones
    want0 = np.full(size + 1, size)
    want0[: zeros.size] = zeros
    np.testing.assert_array_equal(s1, want1)
    np.testing.assert_array_equal(s0, want0)
    np.testing.assert_array_equal(acc[:size], b)
    assert int(bv.ones) == ones.size and str(bv) == "".join(map(str, b))


@settings(max_examples=6, deadline=None)  # 10 took 34 s of CI; the slow test draws 40 of all sizes
@given(pairs=st.sampled_from(PAIRS), seed=st.integers(0, 2**31), deep=st.booleans())
def test_balanced_parentheses_against_stack(pairs, seed, deep):
    _check_balanced(pairs, seed, deep)


@pytest.mark.slow
@settings(max_examples=40, deadline=None)
@given(pairs=st.sampled_from(PAIRS_ALL), seed=st.integers(0, 2**31), deep=st.booleans())
def test_balanced_parentheses_against_stack_all_sizes(pairs, seed, deep):
    _check_balanced(pairs, seed, deep)


def _check_balanced(pairs, seed, deep):
    b = _balanced(seed, pairs, deep)
    bp = BalancedParens.from_bits(b)
    match, enclose = _bp_oracle(b)
    i = jnp.arange(b.size)
    m, fc, fo, enc = map(np.asarray, _bp_all(bp, i))
    op = b == 1
    np.testing.assert_array_equal(m, match)
    np.testing.assert_array_equal(fc[op], match[op])
    np.testing.assert_array_equal(fo[~op], match[~op])
    np.testing.assert_array_equal(enc[op], enclose[op])
    np.testing.assert_array_equal(np.asarray(bp.excess(jnp.arange(b.size + 1))), excess_oracle(b))


def test_fwd_bwd_searches_against_brute_force():
    b = _balanced(7, 900, True)
    bp = BalancedParens.from_bits(b)
    e = excess_oracle(b)
    rng = np.random.default_rng(1)
    i = rng.integers(0, b.size + 1, 400)
    t = e[i] + rng.integers(-40, 3, i.size)
    got_f = np.asarray(jax.jit(lambda s, i, t: s.fwd(i, t))(bp, jnp.asarray(i), jnp.asarray(t)))
    got_b = np.asarray(jax.jit(lambda s, i, t: s.bwd(i, t))(bp, jnp.asarray(i), jnp.asarray(t)))
    for k in range(i.size):
        hits = np.nonzero(e[i[k] + 1:] <= t[k])[0]  # bits k' >= i with E(k' + 1) <= t
        want = i[k] + hits[0] if hits.size else b.size
        assert got_f[k] == min(want, b.size), (i[k], t[k])
        back = np.nonzero(e[: i[k] + 1] <= t[k])[0]
        assert got_b[k] == (back[-1] if back.size else b.size), (i[k], t[k])


def test_jit_and_vmap_agree_with_eager():
    b = _balanced(3, 300, False)
    bp = BalancedParens.from_bits(b)
    i = jnp.arange(b.size)
    eager = np.asarray(bp.match(i))
    # vmap under jit: an eager vmap dispatches (and compiles) every batched primitive on its own
    vm = np.asarray(jax.jit(jax.vmap(lambda x: bp.match(x)))(i))
    np.testing.assert_array_equal(eager, vm)
    np.testing.assert_array_equal(eager, np.asarray(jax.jit(lambda s, x: s.match(x))(bp, i)))
    # batched shapes: any shape of ids
    np.testing.assert_array_equal(np.asarray(bp.match(i[:600].reshape(20, 30))), eager[:600].reshape(20, 30))


def test_unbalanced_input_is_refused_with_offset():
    with pytest.raises(errors.EncodingError, match="offset 2"):
        BalancedParens.from_bits("())(")
    with pytest.raises(errors.EncodingError, match="left open"):
        BalancedParens.from_bits("(()")
    with pytest.raises(errors.EncodingError, match="offset 1"):
        BitVector.from_bits("0x1")


def test_support_is_small():
    b = _balanced(5, 50_000, False)
    bp = BalancedParens.from_bits(b)
    # rank directory (1/8) + min-max tree (about 2 ints per 256 bits) + padding
    assert bp.bits_support / bp.size < 0.45, bp.bits_support / bp.size


@settings(max_examples=4, deadline=None)
@given(pairs=st.lists(st.integers(0, 300), min_size=1, max_size=4), seed=st.integers(0, 2**31),
       deep=st.booleans())
def test_matches_by_level_equal_the_stack(pairs, seed, deep):
    """The sort route (bp.matches_by_level, the GPU candidate of MATCH_BY_SORT): every match of
    a concatenation of balanced blocks == a stack's; with ``member``, blocks interleaved with
    stray parentheses (a packed pemb chunk window that starts inside another mesh) give the
    members' matches; odd lengths included."""
    matches_by_level = by_level
    blocks = [_balanced(seed + k, p, deep) for k, p in enumerate(pairs)]
    b = np.concatenate(blocks)
    if b.size:
        np.testing.assert_array_equal(np.asarray(matches_by_level(jnp.asarray(b == 1))), _bp_oracle(b)[0])
    rng = np.random.default_rng(seed)
    parts, member = [], []
    for blk in blocks:  # strays before every block (unbalanced on their own)
        stray = rng.integers(0, 2, int(rng.integers(0, 4))).astype(np.uint8)
        parts += [stray, blk]
        member += [np.zeros(stray.size, bool), np.ones(blk.size, bool)]
    x, member = np.concatenate(parts), np.concatenate(member)
    got = np.asarray(matches_by_level(jnp.asarray(x == 1), jnp.asarray(member)))
    pos = np.flatnonzero(member)
    want = pos[_bp_oracle(x[member])[0]] if pos.size else pos  # the members' own matches, as positions of x
    np.testing.assert_array_equal(got[member], want)


@pytest.mark.slow  # eager searches: 9 s (the packed route's switch is checked quick, test_batch)
def test_match_all_takes_the_sort_route_when_asked(monkeypatch):
    """MATCH_BY_SORT switches BalancedParens.match_all to the sort (read at trace time: eager
    calls here); same answers as the searches."""
    from jaxcds.structures.succinct import bp as bp_mod

    b = np.concatenate([_balanced(3, 700, True), _balanced(4, 500, False)])
    P = BalancedParens.from_bits(b)
    searched = np.asarray(P.match_all())
    calls = []
    monkeypatch.setattr(bp_mod, "MATCH_BY_SORT", True)
    monkeypatch.setattr(bp_mod, "matches_by_level", lambda *a: calls.append(1) or by_level(*a))
    np.testing.assert_array_equal(np.asarray(P.match_all()), searched)
    assert calls == [1]


@pytest.mark.parametrize("bad", [1.7, [1.5], True, [True, False], "3"])
def test_succinct_queries_refuse_non_integer_ids(bad):
    """Positions and ranks were cast with ``jnp.asarray(i, int32)``: 1.7 read as 1, ``True`` as 1,
    the string ``'3'`` as 3 (silently wrong answers); now InvalidIndexError naming the query."""
    from jaxcds import errors
    from jaxcds.structures.succinct import BalancedParens, BitVector

    bv = BitVector.from_bits("0110100111")
    p = BalancedParens.from_bits("(()(()))")
    assert int(bv.rank1(3)) == 2 and int(p.match(3)) == 6
    for name, call in [("BitVector.access", bv.access), ("BitVector.rank1", bv.rank1),
                       ("BitVector.rank0", bv.rank0), ("BitVector.select", bv.select1),
                       ("BitVector.select", bv.select0), ("BalancedParens.match", p.match),
                       ("BalancedParens.enclose", p.enclose), ("BalancedParens.excess", p.excess),
                       ("BalancedParens.find_close", p.find_close),
                       ("BalancedParens.find_open", p.find_open),
                       ("BalancedParens.rank_open", p.rank_open),
                       ("BalancedParens.select_open", p.select_open)]:
        with pytest.raises(errors.InvalidIndexError, match=name):
            call(bad)


@pytest.mark.parametrize("bits", [[0, 2, 1, 0], [1, -1, 0, 0], [1, 0.5, 1, 0], ["1", "0"], [[1, 0], [1]],
                                  None, [1, None, 0, 0]])
def test_succinct_builders_refuse_non_bits(bits):
    """A cast to bool read 2, -1 and 0.5 as 1 (BalancedParens: 0.5 as 0), the strings '0' and
    '1' both as 1 and None as one 0 bit; ragged lists raised numpy's ValueError."""
    from jaxcds import errors
    from jaxcds.structures.succinct import BalancedParens, BitVector

    with pytest.raises(errors.EncodingError, match="BitVector.from_bits"):
        BitVector.from_bits(bits)
    with pytest.raises(errors.EncodingError, match="BalancedParens.from_bits"):
        BalancedParens.from_bits(bits)


@pytest.mark.parametrize("check", ["no", 0, None])
def test_balanced_parens_check_must_be_bool(check):
    from jaxcds import errors
    from jaxcds.structures.succinct import BalancedParens

    with pytest.raises(errors.ArgumentError, match="check"):
        BalancedParens.from_bits("(", check=check)


@pytest.mark.parametrize("bits", [[[1, 0], [1, 0]], np.ones((2, 2), np.uint8), 1, np.bool_(True)])
def test_succinct_builders_refuse_anything_but_one_sequence(bits):
    """Stop 49 left: a 2-D array was flattened row by row and a lone 0 or 1 read as one bit."""
    from jaxcds import errors
    from jaxcds.structures.succinct import BalancedParens, BitVector

    with pytest.raises(errors.EncodingError, match=r"BitVector.from_bits: bits must be one sequence of bits \(1-D\), got shape"):
        BitVector.from_bits(bits)
    with pytest.raises(errors.EncodingError, match="BalancedParens.from_bits: bits must be one sequence"):
        BalancedParens.from_bits(bits)


@pytest.mark.parametrize("chunk", [0, -4, 2.5, True, "8"])
def test_succinct_chunk_must_be_a_positive_integer(chunk, monkeypatch):
    """Stop 49 left: ``chunk=0`` raised Python's ZeroDivisionError, a negative chunk or 2.5 JAX's
    shape errors, and True ran as a chunk of 1 (the sort route of ``match_all`` did not look)."""
    from jaxcds import errors
    from jaxcds.structures.succinct import BalancedParens, BitVector
    from jaxcds.structures.succinct import bp as bp_mod

    b = np.concatenate([_balanced(3, 300, True), _balanced(4, 200, False)])
    P = BalancedParens.from_bits(b)
    i = np.arange(P.size, dtype=np.int32)
    for call in (lambda: P.match_all(chunk=chunk), lambda: P.match(i, chunk=chunk),
                 lambda: P.enclose(i, chunk=chunk)):
        with pytest.raises(errors.ArgumentError, match="chunk must be None or a positive integer"):
            call()
    monkeypatch.setattr(bp_mod, "MATCH_BY_SORT", True)
    with pytest.raises(errors.ArgumentError, match="chunk must be None or a positive integer"):
        P.match_all(chunk=chunk)
    assert BitVector.from_bits([1, 0, 1]).size == 3 and P.size == b.size


@pytest.mark.parametrize("bits", [[0, 2, 1, 0], [1, 0.5, 0, 0], [1, -1], None, "0110", "(())",
                                  np.ones((2, 2), np.uint8), 1, [1, None, 0, 0], [[1, 0], [1]],
                                  np.ma.masked_array([1, 2, 0, 0], mask=[0, 1, 0, 0])])
def test_succinct_host_helpers_refuse_non_bits(bits):
    """Sweep 51b: ``pack_bits``, ``unbalanced_at`` and ``excess_oracle`` cast their sequence
    (2, -1 and 0.5 read as one bit or the other, a 2-D array flattened, a lone 1 read as one
    bit, the string '0110' packed as four ones) or raised Python's TypeError / ValueError on
    ``None``, strings and ragged lists; now EncodingError naming the helper, as the builders."""
    from jaxcds.structures.succinct import pack_bits
    from jaxcds.structures.succinct.bp import unbalanced_at

    for name, helper in (("pack_bits", pack_bits), ("unbalanced_at", unbalanced_at),
                         ("excess_oracle", excess_oracle)):
        with pytest.raises(errors.EncodingError, match=f"{name}: bits"):
            helper(bits)


def test_bit_builders_refuse_masked_bits():
    """A masked array's mask was dropped: its masked entries read as bits (stop 51; ids already
    refused them, ``id_arg``)."""
    masked = np.ma.masked_array([1, 1, 0, 0], mask=[0, 1, 0, 0])
    for build in (BitVector.from_bits, BalancedParens.from_bits):
        with pytest.raises(errors.EncodingError, match="masked array"):
            build(masked)


def test_succinct_host_helpers_on_bits():
    from jaxcds.structures.succinct import pack_bits
    from jaxcds.structures.succinct.bp import unbalanced_at

    assert pack_bits([1, 0, 1, 1]).tolist()[:2] == [13, 0] and pack_bits([]).size == 16
    assert pack_bits(np.array([True] * 257)).tolist()[:9] == [2**32 - 1] * 8 + [1]
    assert [unbalanced_at(b) for b in ([], [1, 0], [0, 1], [1, 1, 0], np.array([True, False]))] == \
        [None, None, 0, 3, None]
    assert excess_oracle([1, 1, 0]).tolist() == [0, 1, 2, 1]


@pytest.mark.parametrize("args, message", [
    ((np.ones((2, 2), bool),), r"is_open must be a 1-D bool array, got dtype bool shape \(2, 2\)"),
    ((np.bool_(True),), r"is_open must be a 1-D bool array, got dtype bool shape \(\)"),
    ((np.array([1, 0]),), r"is_open must be a 1-D bool array, got dtype int"),
    ((np.array([True, False]), np.array([True])), r"member has shape \(1,\), is_open \(2,\)"),
    ((np.array([True, False]), np.array([1, 1])), r"member must be a 1-D bool array, got dtype int"),
    (([None],), r"is_open must be a 1-D bool array"),
])
def test_matches_by_level_checks_its_arrays(args, message):
    """Sweep 51b: a list raised AttributeError, a 2-D or 0-d array JAX's shape errors, integer
    flags were read by truth value and a ``member`` of another length was broadcast."""
    with pytest.raises(errors.ArgumentError, match="matches_by_level: " + message):
        by_level(*args)
    got = by_level(jnp.array([True, True, False, False]), jnp.ones(4, bool))
    assert np.asarray(got).tolist() == [3, 2, 1, 0]
    assert np.asarray(by_level([True, False])).tolist() == [1, 0]  # a list of flags is taken


def test_succinct_query_arguments_besides_ids_are_checked():
    """Sweep 51b: ``bit`` of ``rank`` / ``select`` / ``select_near``, the targets ``t`` of ``fwd`` /
    ``bwd`` and the masks ``active`` / ``opens`` went to ``jnp.asarray`` as they were: a string or
    None raised JAX's TypeError / ValueError, 0.5 read as bit 1 or target 0, 2 and -1 as bit 1,
    a target past int32 raised Python's OverflowError, a mask of another shape JAX's broadcast
    error; ``closes_of`` of a 0-d position raised IndexError. Now typed errors naming the query;
    bits broadcast against the ranks (a list of bits for one rank), closes_of takes any shape."""
    bv = BitVector.from_bits([1, 0, 1, 1, 0])
    P = BalancedParens.from_bits("(()(()))")
    for bad, msg in ((2, "must be 0 or 1, got 2"), (-1, "must be 0 or 1, got -1"),
                     (0.5, "must be 0/1 integers or booleans"), ("1", "must be 0/1 integers"),
                     (None, "must be 0/1 integers"), ([[1], [0, 1]], "are not an array")):
        for name, call in (("rank", lambda: bv.rank(1, bad)), ("select", lambda: bv.select(1, bad)),
                           ("select_near", lambda: bv.select_near(1, bad, 0, 0))):
            with pytest.raises(errors.InvalidIndexError, match=f"BitVector.{name}: bit {msg}"):
                call()
    for bad in (0.5, "1", None, True):
        for name in ("fwd", "bwd"):
            with pytest.raises(errors.InvalidIndexError, match=f"BalancedParens.{name}: targets must be integers"):
                getattr(P, name)(1, bad)
    with pytest.raises(errors.ArgumentError, match=r"BalancedParens.fwd: shapes \(2,\), \(3,\) do not broadcast"):
        P.fwd([1, 2], [0, 0, 0])
    with pytest.raises(errors.ArgumentError, match=r"BitVector.select: shapes \(2,\), \(3,\)"):
        bv.select([1, 2], [0, 1, 1])
    for name, call in (("BalancedParens.match: active", lambda: P.match([0, 1], active=np.ones((3, 3), bool))),
                       ("BalancedParens.closes_of: opens", lambda: P.closes_of(np.array([0, 1]), np.ones(3, bool))),
                       ("BitVector.select_near: active", lambda: bv.select_near([0, 1], 1, 0, 0, active=[1, 0, 1]))):
        with pytest.raises(errors.ArgumentError, match=rf"{name} has shape \([\d, ]+\), which does not broadcast"):
            call()
    # the valid forms answer as before
    assert np.asarray(bv.select(1, [0, 1, 1])).tolist() == [4, 2, 2]
    assert int(bv.rank(5, np.bool_(True))) == 3 and int(bv.select(0, 0)) == 1
    assert int(P.fwd(1, 2**40)) == 1 and int(P.bwd(8, -2**40)) == P.size
    assert int(P.closes_of(np.int32(3), True)) == 6
    assert np.asarray(P.closes_of(np.array([[0, 1], [3, 4]]), True)).tolist() == [[7, 2], [6, 5]]


def test_rank_select_and_compaction_under_rank_promotion_raise():
    """Users of a JAX library may run with ``jax.numpy_rank_promotion("raise")``: a block's
    word lanes were a bare ``(8,)`` vector broadcast against ``(..., 1)`` queries, and the
    compaction's bit column against ``(n, 32)`` words, so every pemb operator raised JAX's
    ValueError there (sweep 52c). Same answers as the numpy oracle, 1-D and 2-D ids."""
    from jaxcds.structures.succinct.bitvector import _compact_indices

    bits = _bits(7, 2600, 0.5)
    ones, zeros = np.flatnonzero(bits), np.flatnonzero(bits == 0)
    rank = np.concatenate([[0], np.cumsum(bits)])
    i = np.arange(0, bits.size + 1, 7, dtype=np.int32)[:360].reshape(20, 18)
    k = np.arange(360, dtype=np.int32).reshape(20, 18) % min(ones.size, zeros.size)
    miss = np.random.default_rng(1).random(1000) < 0.3
    with jax.numpy_rank_promotion("raise"):
        bv = BitVector.from_bits(bits)
        r1, r0, s1, s0, _ = _bv_all(bv, jnp.asarray(i), jnp.asarray(k))
        idx, count = jax.jit(_compact_indices, static_argnums=1)(jnp.asarray(miss), 1024)
    np.testing.assert_array_equal(np.asarray(r1), rank[i])
    np.testing.assert_array_equal(np.asarray(r0), i - rank[i])
    np.testing.assert_array_equal(np.asarray(s1), ones[k])
    np.testing.assert_array_equal(np.asarray(s0), zeros[k])
    assert int(count) == miss.sum()
    np.testing.assert_array_equal(np.asarray(idx)[: miss.sum()], np.flatnonzero(miss))


def test_parens_searches_and_bool_bits_under_strict_dtype_promotion():
    """Users may run with ``jax.numpy_dtype_promotion("strict")``: the word scans of the
    parenthesis searches wrote ``~fw`` of a Python bool (an int, -1 or -2, that met bool
    arrays), and ``select(k, bit)`` compared a bool ``bit`` with 0, so pemb's operators raised
    JAX's TypePromotionError there (sweep 52c). Same answers as the stack oracle."""
    b = _balanced(11, 700, True)
    match, enclose = _bp_oracle(b)
    bits = _bits(3, 2600, 0.5)
    k = jnp.arange(100, dtype=jnp.int32)
    with jax.numpy_dtype_promotion("strict"):
        bp = BalancedParens.from_bits(b)
        got = _bp_all(bp, jnp.arange(b.size, dtype=jnp.int32))
        bv = BitVector.from_bits(bits)
        sel = jax.jit(lambda bv, k, bit: bv.select(k, bit))(bv, k, jnp.ones(100, bool))
    np.testing.assert_array_equal(np.asarray(got[0]), match)
    op = b == 1
    np.testing.assert_array_equal(np.asarray(got[3])[op], enclose[op])
    np.testing.assert_array_equal(np.asarray(sel), np.flatnonzero(bits)[:100])


@pytest.mark.parametrize("build,bits,msg", [
    (BitVector.from_bits, "0121", r"BitVector.from_bits: bit string has '2' at offset 2, expected '0' or '1'"),
    (BalancedParens.from_bits, "(()x", r"BalancedParens.from_bits: parenthesis string has 'x' at offset 3, "
                                       r"expected '\(', '\)', '1' or '0'"),
    (BalancedParens.from_bits, "())(", r"unbalanced parentheses: '\)' at offset 2 closes nothing"),
    (BitVector.from_bits, np.ma.array([0, 1, 1], mask=[0, 1, 0]),
     r"BitVector.from_bits: bits must be plain bits, got a masked array"),
    (BalancedParens.from_bits, np.ma.array([1, 0], mask=[0, 1]),
     r"BalancedParens.from_bits: bits must be plain bits, got a masked array"),
    (BitVector.from_bits, [[0, 1], [1]], r"BitVector.from_bits: bits are not an array of bits"),
])
def test_from_bits_names_the_builder_and_what_it_takes(build, bits, msg):
    """The string refusals named neither the builder nor, for parentheses, what a string may
    hold; none of these ran in a test."""
    with pytest.raises(errors.EncodingError, match=msg):
        build(bits)


@pytest.mark.parametrize("mask", ["no", object()])
def test_query_masks_that_are_no_flags_are_refused(mask):
    """A str or any object converted to True: ``active="no"`` selected every query."""
    p = BalancedParens.from_bits("(()())")
    with pytest.raises(errors.ArgumentError, match=r"BalancedParens.match: active must be an array of flags, got"):
        p.match(np.array([0, 1, 2]), active=mask)
    np.testing.assert_array_equal(p.match(np.array([0, 1, 2]), active=[1, 1, 1]), p.match(np.array([0, 1, 2])))
