"""Vertex degrees on any structure (CDS paper Table 3, first column)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["vertex_degrees"]


@jax.jit
def vertex_degrees(s):
    """``(num_vertices,)`` int32 degree of every vertex.

    A structure with a faster route (e.g. CDS: 3 outgoing edges + incoming counts) provides a
    ``vertex_degrees()`` method; otherwise every valid dart counts once at its origin, one
    ``segment_sum`` over the dart space (invalid ids go to a dropped extra segment).
    """
    if hasattr(s, "vertex_degrees"):
        return s.vertex_degrees()
    e = jnp.arange(s.num_darts, dtype=jnp.int32)
    valid = s.dart_valid(e)
    seg = jnp.where(valid, s.origin(e), s.num_vertices)
    ones = jnp.ones(e.shape, jnp.int32)
    return jax.ops.segment_sum(ones, seg, num_segments=s.num_vertices + 1)[: s.num_vertices]
