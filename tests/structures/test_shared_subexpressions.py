"""``base.shared_subexpressions``: operators of the same traced darts traced once per program.

The sharing changes what is traced (and so the program's size), never an answer: the tests
check both, and that a result traced in an inner trace (a loop body, a branch) is never handed
out to another trace."""

import jax
import jax.numpy as jnp
import numpy as np

from jaxcds import verify as V
from jaxcds.generators import random_planar_triangulation
from jaxcds.structures import registry
from jaxcds.structures.base import per_query_routes, shared_subexpression, shared_subexpressions


class _Counting:
    """A stand-in structure: counts how often each marked method's body is traced."""

    def __init__(self):
        self.calls = {"double": 0, "masked": 0}

    @shared_subexpression
    def double(self, x):
        self.calls["double"] += 1
        return 2 * x

    @shared_subexpression(masks=("where",))
    def masked(self, x, where=None):
        self.calls["masked"] += 1
        return x + 1 if where is None else jnp.where(where, x + 1, 0)


def test_one_trace_per_argument_inside_the_block_only():
    c = _Counting()

    def f(x, y):
        with shared_subexpressions():
            a, b, d = c.double(x), c.double(x), c.double(y)
        return a + b + d + c.double(x)  # outside the block: traced again

    out = jax.jit(f)(jnp.arange(3), jnp.ones(3, jnp.int32))
    np.testing.assert_array_equal(out, 6 * np.arange(3) + 2)
    assert c.calls["double"] == 3  # x once in the block, y once, x again outside


def test_eager_calls_are_not_shared():
    c = _Counting()
    x = jnp.arange(3)
    with shared_subexpressions():
        c.double(x), c.double(x)
    assert c.calls["double"] == 2


def test_an_unmasked_result_serves_a_masked_call_not_the_reverse():
    c = _Counting()

    def g(x, m):
        with shared_subexpressions():
            full = c.masked(x)
            masked = c.masked(x, where=m)  # the full result serves it: not traced again
        return full, masked

    x, m = jnp.arange(4), jnp.array([True, False, True, False])
    full, masked = jax.jit(g)(x, m)
    np.testing.assert_array_equal(masked, full)
    assert c.calls["masked"] == 1
    c.calls["masked"] = 0

    def f(x, m):
        with shared_subexpressions():
            masked_first = c.masked(x, where=m)  # right on m's lanes only: not shared below
            full = c.masked(x)
            again = c.masked(x, where=m)  # shared: right on m's lanes
            none = c.masked(x, where=None)  # None is no mask: the full result
        return masked_first, full, again, none

    masked_first, full, again, none = jax.jit(f)(x, m)
    np.testing.assert_array_equal(masked_first, [1, 0, 3, 0])
    np.testing.assert_array_equal(full, np.arange(4) + 1)
    np.testing.assert_array_equal(np.asarray(again)[np.asarray(m)], np.asarray(full)[np.asarray(m)])
    np.testing.assert_array_equal(none, full)
    assert c.calls["masked"] == 2


def test_a_result_traced_in_a_loop_body_stays_there():
    """First asked inside ``fori_loop``'s body (of a tracer closed over from outside), then
    outside it: shared, the loop body's tracer would escape (UnexpectedTracerError)."""
    c = _Counting()

    def f(x):
        with shared_subexpressions():
            inner = jax.lax.fori_loop(0, 2, lambda i, acc: acc + c.double(x), jnp.zeros_like(x))
            outer = c.double(x)
            branch = jax.lax.cond(x[0] == 0, lambda: c.double(x), lambda: x)
        return inner, outer, branch

    inner, outer, branch = jax.jit(f)(jnp.arange(3))
    np.testing.assert_array_equal(inner, 4 * np.arange(3))
    np.testing.assert_array_equal(outer, 2 * np.arange(3))
    np.testing.assert_array_equal(branch, 2 * np.arange(3))


def _hlo_lines(fn, *args):
    return jax.jit(fn).lower(*args).as_text().count("\n")


def test_pemb_every_operator_program_is_traced_at_half_the_size():
    """verify's every-operator program on a pemb (its ``mate`` begins a dozen operators) is
    well under the program it was (104K -> 44K lines of HLO on the bunny). Its answers are
    checked against the half-edge dart by dart by every ``verify`` of a pemb
    (tests/structures/test_protocol.py)."""
    s = registry.build("pemb", random_planar_triangulation(40, seed=3))
    e = jnp.arange(s.num_darts, dtype=jnp.int32)

    def unshared(s, e):
        out = {op: getattr(s, op)(e) for op in V.DART_OPERATORS}
        for op in ("origin", "target", "face", "face_left", "face_right", "is_border"):
            out[op] = getattr(s, op)(e)
        return out

    shared = V._apply_all.__wrapped__
    # the searches (a batch of all darts would read per-call tables instead: verify checks
    # those routes against the searches in another program, with the same sharing)
    with per_query_routes():
        assert sorted(jax.eval_shape(shared, s, e)) == sorted(jax.eval_shape(unshared, s, e))
        assert _hlo_lines(shared, s, e) < 0.6 * _hlo_lines(unshared, s, e)
