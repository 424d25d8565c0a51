"""Argument checks shared by the builders, generators and algorithms (host side, before any
work)."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxcds import errors


def shown(value) -> str:
    """``value`` as an error message shows it: its repr if a scalar (a name, a number, None),
    else ``a <type>`` -- the repr of an array or a structure put where a name goes runs to pages
    (sweep 53c found several such arguments)."""
    if value is None or isinstance(value, (str, bytes, int, float, np.generic)):
        return repr(value)
    return f"a {type(value).__name__}"


def is_integer(x) -> bool:
    """True for a Python or numpy integer; False for booleans (``True`` is an ``int`` to Python,
    and a seed count of ``True`` is a mistake, not 1) and for everything else."""
    return isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_))


def number_array(values, what: str, *, error: type = errors.MeshError, bools: bool = False,
                 complex_ok: bool = False):
    """``values`` checked to hold numbers JAX computes with, or ``error`` naming ``what``: a JAX
    array or tracer as it is (only its dtype is read: traced values pass through), anything else
    as a numpy array (not copied when it is one; byte order as given).

    Refused: masked arrays (``np.asarray`` drops the mask: the masked entries' data would be
    used silently), ragged nested lists, and dtypes other than integers and floats (booleans too
    with ``bools``, complex numbers too with ``complex_ok``): strings and objects raise TypeError
    inside ``jax.jit``, and complex numbers lose their imaginary part in a float conversion.
    The one core of the library's "an array of numbers" checks (positions, per-mesh values,
    rows to shard), which differ only in ``error`` and in the dtypes they take."""
    if isinstance(values, np.ma.MaskedArray):
        raise error(f"{what} are a masked array (its mask would be ignored); pass "
                    "values.filled(...) or the kept rows' values")
    if isinstance(values, jax.Array):  # tracers too
        a = values
    else:
        try:
            a = np.asarray(values)
        except (TypeError, ValueError) as exc:  # ragged nested lists
            raise error(f"{what} are not an array of numbers: {exc}") from None
    dtype = a.dtype
    ok = (jnp.issubdtype(dtype, jnp.floating) or jnp.issubdtype(dtype, jnp.integer)
          or (bools and jnp.issubdtype(dtype, jnp.bool_))
          or (complex_ok and jnp.issubdtype(dtype, jnp.complexfloating)))
    if not ok:
        kind = "numbers" if complex_ok else "real numbers"
        raise error(f"{what} must be {kind}, got dtype {dtype}")
    return a


def refuse_non_real(values, what: str, *, bools: bool = False) -> None:
    """:class:`~jaxcds.errors.MeshError` naming ``what`` unless ``values`` (an array, a jax
    array or tracer, or nested lists, not a masked array) hold real numbers: integers or floats,
    booleans too with ``bools`` (:func:`number_array`)."""
    number_array(values, what, bools=bools)


def flag_arg(value, what: str, *, none_ok: bool = False) -> bool:
    """``value`` as a bool, or :class:`~jaxcds.errors.ArgumentError` naming ``what`` unless it is
    ``True`` or ``False`` (a numpy bool too; ``None`` too with ``none_ok``, returned as it is):
    to Python ``'no'`` is truthy and ``0`` or ``[]`` falsy, so ``check='no'`` validated and
    ``check=0`` silently skipped the validation."""
    if none_ok and value is None:
        return value
    if not isinstance(value, (bool, np.bool_)):
        allowed = "True, False or None" if none_ok else "True or False"
        raise errors.ArgumentError(f"{what} must be {allowed}, got {value!r}")
    return bool(value)
