"""Argument checks shared by the builders, generators and algorithms (host side, before any
work)."""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from jaxcds import errors


def is_integer(x) -> bool:
    """True for a Python or numpy integer; False for booleans (``True`` is an ``int`` to Python,
    and a seed count of ``True`` is a mistake, not 1) and for everything else."""
    return isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_))


def refuse_non_real(values, what: str, *, bools: bool = False) -> None:
    """:class:`~jaxcds.errors.MeshError` naming ``what`` unless ``values`` (an array, a jax
    array or tracer, or nested lists) hold real numbers: integers or floats, booleans too with
    ``bools``. Strings and objects would raise TypeError inside ``jax.jit``, and complex numbers
    would lose their imaginary part in a float conversion. Only the dtype is read: traced values
    pass through."""
    dtype = getattr(values, "dtype", None)
    if dtype is None:
        try:
            dtype = np.asarray(values).dtype
        except (TypeError, ValueError) as exc:  # ragged nested lists
            raise errors.MeshError(f"{what} are not an array of numbers: {exc}") from exc
    if not (jnp.issubdtype(dtype, jnp.floating) or jnp.issubdtype(dtype, jnp.integer)
            or (bools and jnp.issubdtype(dtype, jnp.bool_))):
        raise errors.MeshError(f"{what} must be real numbers, got dtype {dtype}")
