"""Frozen dataclasses registered as JAX pytrees (in the manner of jax-md's ``dataclasses``).

Array fields are pytree leaves; fields declared with :func:`static_field` are part of the tree
structure (hashed into the jit cache), so changing them triggers a recompilation -- use them for
sizes that fix array shapes (``num_vertices``, ``num_faces``...).

Two of them are equal when they are of one class with the same static fields and equal arrays
(compared on the host; not inside ``jit``, where the arrays have no values); the hash is that of
the class and static fields, so a structure may be a dict key or a static argument.
"""

from __future__ import annotations

import dataclasses
from typing import Any, TypeVar

import jax
import numpy as np

from jaxcds import errors
from jaxcds._arrays import Tracer as _Tracer

__all__ = ["pytree_dataclass", "static_field", "replace"]

T = TypeVar("T")


def static_field(**kwargs: Any) -> Any:
    """A dataclass field that is static metadata, not a pytree leaf."""
    metadata = dict(kwargs.pop("metadata", {}) or {})
    metadata["static"] = True
    return dataclasses.field(metadata=metadata, **kwargs)


def pytree_dataclass(cls: type[T]) -> type[T]:
    """Make ``cls`` a frozen dataclass and register it with ``jax.tree_util``."""
    # a __repr__ written by hand in a base (MeshStructure's short one) is kept: the generated one
    # replaced it and printed every array of a structure (sweep 14)
    inherited = cls.__repr__
    keep_repr = "__repr__" in cls.__dict__ or (
        inherited is not object.__repr__ and not getattr(inherited, "_generated", False))
    # eq=False: the generated __eq__ compared array fields as a tuple, which raised JAX's
    # "truth value of an array ... is ambiguous" for two structures, and its __hash__ raised
    # "unhashable type" (sweep 14); _eq / _hash below compare values
    cls = dataclasses.dataclass(frozen=True, repr=not keep_repr, eq=False)(cls)
    if not keep_repr:
        cls.__repr__._generated = True
    if "__eq__" not in cls.__dict__:
        cls.__eq__, cls.__hash__ = _eq, _hash
    fields = dataclasses.fields(cls)
    data = [f.name for f in fields if not f.metadata.get("static", False)]
    meta = [f.name for f in fields if f.metadata.get("static", False)]
    jax.tree_util.register_dataclass(cls, data_fields=data, meta_fields=meta)
    return cls


def _eq(self, other) -> bool:
    """Same class, same static fields and ``None`` fields (the tree structure), equal arrays
    (shape, dtype and values).

    Raises:
      ArgumentError: inside a JAX transformation (the arrays are traced: no values to compare).
    """
    if type(other) is not type(self):
        return NotImplemented
    if self is other:
        return True
    a, ta = jax.tree_util.tree_flatten(self)
    b, tb = jax.tree_util.tree_flatten(other)
    if ta != tb:
        return False
    if any(isinstance(x, _Tracer) for x in a + b):
        raise errors.ArgumentError(
            f"== on two {type(self).__name__} inside jit / vmap / grad: their arrays are traced "
            "and have no values to compare; compare them outside the transformation, or "
            "compare the leaves (jax.tree_util.tree_leaves) as arrays")
    for x, y in zip(a, b):
        x, y = np.asarray(x), np.asarray(y)
        if x.shape != y.shape or x.dtype != y.dtype or not np.array_equal(x, y):
            return False
    return True


def _hash(self) -> int:
    # the class and static fields only (equal objects have one hash; no array read)
    return hash((type(self), jax.tree_util.tree_structure(self)))


def replace(obj: T, **changes: Any) -> T:
    """A copy of a pytree dataclass with some fields replaced."""
    return dataclasses.replace(obj, **changes)
