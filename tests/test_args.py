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


def test_number_array_refuses_by_name_and_keeps_arrays():
    """The one core of the "an array of numbers" checks (positions, per-mesh values, rows to
    shard): masked arrays were refused by some entry points and silently unmasked by others."""
    import jax
    import jax.numpy as jnp

    from jaxcds import errors
    from jaxcds._args import number_array

    a = np.arange(6.0).reshape(2, 3)
    assert number_array(a, "p") is a  # no copy of a numpy array
    assert number_array(a.astype(">f8"), "p").dtype == np.dtype(">f8")  # byte order as given
    x = jnp.ones(3)
    assert number_array(x, "p") is x
    assert jax.jit(lambda t: number_array(t, "p") * 2)(x).shape == (3,)  # tracers pass
    np.testing.assert_array_equal(number_array([[1, 2]], "p"), [[1, 2]])
    with pytest.raises(errors.MeshError, match="p are a masked array"):
        number_array(np.ma.masked_array(a, a > 2), "p")
    with pytest.raises(errors.ArgumentError, match="q are not an array of numbers"):
        number_array([[1, 2], [3]], "q", error=errors.ArgumentError)
    for bad in (a.astype(complex), a.astype(str), a.astype(object), a > 1):
        with pytest.raises(errors.MeshError, match="p must be real numbers, got dtype"):
            number_array(bad, "p")
    assert number_array(a > 1, "p", bools=True).dtype == bool
    assert number_array(a.astype(complex), "p", complex_ok=True).dtype == complex
    with pytest.raises(errors.MeshError, match="p must be numbers, got dtype <U"):
        number_array(a.astype(str), "p", complex_ok=True)
