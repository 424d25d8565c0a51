"""Vertex degrees on any structure (CDS paper Table 3, first column)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxcds.structures.base import structure_arg

__all__ = ["vertex_degrees"]


def vertex_degrees(s):
    """``(num_vertices,)`` int32 degree of every vertex. Jitted.

    A structure with a faster route (e.g. CDS: 3 outgoing edges + incoming counts) provides a
    ``vertex_degrees()`` method; otherwise :func:`dart_count_degrees`.

    Degrees are those of the input mesh: a structure that closed holes with dummy vertices
    (``s.dummy_vertex_mask()``, the CDS family) answers 0 for a dummy and leaves it out of
    its neighbours' degrees, as LR (which shows holes as borders) and the half-edge do. (A
    structure's own route does this itself.)

    Raises:
      ArgumentError: ``s`` is not a structure (an ``AttributeError`` on a tracer before).
    """
    structure_arg(s, "vertex_degrees")
    return _vertex_degrees(s)


@jax.jit
def _vertex_degrees(s):
    if hasattr(s, "vertex_degrees"):
        return s.vertex_degrees()
    return dart_count_degrees(s)


def dart_count_degrees(s):
    """The generic route: every valid dart counts once at its origin, one ``segment_sum`` over
    the dart space (invalid ids go to a dropped extra segment); dummy vertices then left out
    (:func:`_without_dummy_neighbours`)."""
    e = jnp.arange(s.num_darts, dtype=jnp.int32)
    valid = s.dart_valid(e)
    seg = jnp.where(valid, s.origin(e), s.num_vertices)
    ones = jnp.ones(e.shape, jnp.int32)
    deg = jax.ops.segment_sum(ones, seg, num_segments=s.num_vertices + 1)[: s.num_vertices]
    dummy = s.dummy_vertex_mask()
    return deg if dummy is None else _without_dummy_neighbours(s, deg, dummy)


def _without_dummy_neighbours(s, deg, dummy):
    """Degrees in the input mesh of a structure that closed its holes with dummy vertices (CDS
    Sec. 4.5): a dummy vertex has degree 0, and a border vertex loses its dummy neighbour. A
    border vertex lies on two fan faces of each dummy it is adjacent to (the fan triangles
    before and after it on the hole's loop; a vertex met twice on one loop is non-manifold and
    refused by validation), so it has ``(fan faces at it) / 2`` dummy neighbours."""
    from jaxcds.algorithms.normals import corner_sums, faces_with_dummy_corner

    fv, valid = s.face_vertices_padded()
    fan = faces_with_dummy_corner(dummy, fv)
    if valid is not None:  # padding rows are not fan faces
        fan = fan & valid
    fans_at = corner_sums(fan.astype(jnp.int32), fv, s.num_vertices)
    return jnp.where(dummy, 0, deg - fans_at // 2)


vertex_degrees.__wrapped__ = _vertex_degrees.__wrapped__  # the unjitted body
