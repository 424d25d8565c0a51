"""Host arrays onto the device without a compilation per shape.

Under jax 0.10, ``jnp.asarray(host_array)`` without a dtype lifts the array with ``lax.stage``:
an eager copy primitive compiled once per shape and dtype (10-14 ms each on this project's
hosts, measured 2026-12-06; every compiled program also holds memory mappings, see
:mod:`jaxcds._mappings`). A builder meets new shapes with every mesh, so a pack of 10,000 pembs
spent most of its per-mesh build compiling copies. ``jax.device_put`` of a host array compiles
nothing (0.1 ms), but on CPU it may share the array's buffer (zero copy): writing to the host
array afterwards would change the device array. So builders pass arrays they made themselves,
and inputs that belong to the caller are copied first (``copy=True``).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["to_device", "native_order", "traced_for_cpu", "Tracer"]

try:  # public in jax <= 0.10; imported once, so a move fails at import, not per call
    from jax.core import Tracer
except ImportError:  # pragma: no cover - newer jax without the alias
    from jax._src.core import Tracer


def to_device(x, dtype=None, *, copy: bool = False) -> jax.Array:
    """``x`` as a device array, ``jnp.asarray``'s dtypes (int64 -> int32 and float64 ->
    float32 unless x64 is on), without compiling anything for a host array.

    ``x`` already a JAX array or a tracer, or lists holding them: ``jnp.asarray`` (nothing to copy).
    ``copy``: copy a host array first, for arrays the caller may write to later (the device array
    may share its buffer otherwise)."""
    if isinstance(x, jax.Array):
        return x if dtype is None or x.dtype == dtype else jnp.asarray(x, dtype)
    if not isinstance(x, np.ndarray) and any(isinstance(leaf, jax.Array)
                                             for leaf in jax.tree_util.tree_leaves(x)):
        return jnp.asarray(x, dtype)  # nested lists of traced values (a list argument under jit)
    a = native_order(np.asarray(x, dtype))  # JAX refuses big-endian data
    dt = jax.dtypes.canonicalize_dtype(a.dtype)
    # np.asarray, not np.ascontiguousarray: that one turns a 0-d array into shape (1,)
    a = np.array(a, dt, order="C", copy=True) if copy else np.asarray(a, dt, order="C")
    return jax.device_put(a)


def native_order(x):
    """``x`` with a big-endian (non-native) numpy dtype converted to native order; anything else
    as it is. ``jax.jit`` refuses such arguments with a message about static arguments; public
    entry points pass user arrays through this before their jitted call."""
    if isinstance(x, np.ndarray) and x.dtype.byteorder not in "=|":
        return x.astype(x.dtype.newbyteorder("="))
    return x


def traced_for_cpu() -> bool:
    """Whether a call traced now runs on a CPU: the platform of ``jax.config.jax_default_device``
    (a device or a platform name, as ``jax.default_device`` sets it), else JAX's default backend.

    The one CPU-or-not decision of the library's cache-shaped routes (chunked queries, chunked
    normal sums, CDS plans in a one-trip loop): they exist for XLA:CPU's caches and thread split,
    and on a GPU a loop's trips run one after the other (RESULTS.md, stop 43). Arrays committed
    to another device than the default one are traced for that device but get the default
    platform's route here: the answers are the same, only the speed differs."""
    d = jax.config.jax_default_device
    platform = d if isinstance(d, str) else getattr(d, "platform", None)
    return (platform or jax.default_backend()) == "cpu"
