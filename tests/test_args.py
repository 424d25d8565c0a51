"""The shared argument predicate (``jaxcds._args``): every builder's count, seed, period and
sweep check relies on it to refuse booleans and non-integers alike."""
import numpy as np
import pytest

from jaxcds._args import is_integer


@pytest.mark.parametrize("x", [0, 7, -3, np.int64(5), np.uint8(3), np.int32(-1), 10**20])
def test_integers_are_integers(x):
    assert is_integer(x)


@pytest.mark.parametrize("x", [True, False, np.bool_(True), 1.0, np.float32(2), "3", None,
                               [1], np.array([1]), 1 + 0j])
def test_everything_else_is_not(x):
    assert not is_integer(x)
