"""Rotations around vertices: adjacency tests and one-rings, on any structure."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

from jaxcds import errors
from jaxcds._args import is_integer
from jaxcds.structures.base import id_arg

__all__ = ["adjacent", "one_ring", "rotate_until"]


def rotate_until(s, start, stop_fn, max_steps: int):
    """Turn ccw around ``origin(start)`` (batched) until ``stop_fn(e)`` or back at ``start``.

    Returns ``(e, hit)``: the dart where the rotation stopped and whether ``stop_fn`` held there.
    Written as a ``while_loop`` whose body is branch-free: lanes that are done keep their state,
    and the loop ends when every lane is done (after at most the largest degree in the batch).
    """
    hit0 = stop_fn(start)

    def cond(state):
        e, hit, done, k = state
        return jnp.any(~done) & (k < max_steps)

    def body(state):
        e, hit, done, k = state
        e2 = s.ccw_vertex_edge(e)
        back = e2 == start
        h2 = stop_fn(e2) & ~back
        e = jnp.where(done, e, e2)
        hit = jnp.where(done, hit, h2)
        done = done | h2 | back
        return e, hit, done, k + 1

    e, hit, _, _ = jax.lax.while_loop(cond, body, (start, hit0, hit0, jnp.int32(0)))
    return e, hit


def adjacent(s, u, v):
    """``Adjacent(u, v)`` (CDS Sec. 1.3): True where ``u`` and ``v`` share an edge. O(deg u).

    Edges of the structure's surface: where it closed holes with dummy vertices (the CDS
    family), a dummy is adjacent to its hole's border vertices (mask with
    ``s.dummy_vertex_mask()``); between the input's vertices the answer is the input mesh's.

    Raises:
      InvalidIndexError: ``u`` or ``v`` are not integers (floats, bools, strings: a cast would
        truncate 1.7 to 1); any integer kind and byte order is read as int32."""
    return _adjacent(s, id_arg(u, "adjacent: u"), id_arg(v, "adjacent: v"))


@jax.jit
def _adjacent(s, u, v):
    if hasattr(s, "adjacent"):
        return s.adjacent(u, v)
    start = s.edge_of_vertex(u)
    valid = s.dart_valid(start)  # false for a vertex in no face (edge_of_vertex: "absent")
    _, hit = rotate_until(s, start, lambda e: valid & (s.target(e) == v), s.num_vertices + 1)
    return hit & (u != v) & valid


def one_ring(s, v, max_degree: int):
    """Neighbours of each vertex in ``v``, ccw, as a ``(len(v), max_degree)`` array padded with
    ``num_vertices`` (absent), and the degrees. ``max_degree`` is static (shapes depend on it);
    vertices of larger degree are truncated to their first ``max_degree`` neighbours.

    The ring starts at ``target(edge_of_vertex(v))``, so structures list the same ccw cycle
    from different first neighbours (compare rings up to rotation). Rings and degrees are the
    input mesh's, as :func:`~jaxcds.algorithms.vertex_degrees` answers: on a structure that
    closed holes with dummy vertices (``s.dummy_vertex_mask()``, the CDS family) a border
    vertex's ring leaves its dummy out and starts just after it, running from one border
    neighbour through the mesh to the other (as LR lists it), and a dummy's ring is empty.
    Before, the dummy was in the ring and its count (sweep 16a). :func:`adjacent` still walks
    the closed surface: a dummy is adjacent to its hole's border vertices.

    Raises:
      ArgumentError: ``max_degree`` is not a non-negative integer (``1.7`` or ``"3"`` would
        otherwise be cut or parsed quietly, and a negative size fails inside XLA)."""
    if not is_integer(max_degree) or max_degree < 0:
        raise errors.ArgumentError(
            f"one_ring: max_degree must be a non-negative integer (the ring's static width), "
            f"got {max_degree!r}")
    return _one_ring(s, id_arg(v, "one_ring: vertices"), int(max_degree))


@functools.partial(jax.jit, static_argnums=2)
def _one_ring(s, v, max_degree):
    n = s.num_vertices
    start = s.edge_of_vertex(v)
    alone = ~s.dart_valid(start)  # a vertex in no face: an empty ring
    dummy = s.dummy_vertex_mask()
    if dummy is not None:  # a dummy vertex is no vertex of the input: an empty ring
        alone = alone | dummy[jnp.clip(v, 0, n - 1)]
    # one more turn where dummies are: a border vertex has one dummy neighbour at most (its
    # faces form one fan, validated), which takes a slot of the closed ring
    width = max_degree + (dummy is not None)

    def step(carry, _):
        e, done = carry
        t = jnp.where(done, n, s.target(e))
        e2 = s.ccw_vertex_edge(e)
        return (e2, done | (e2 == start)), t

    (_, whole), ring = jax.lax.scan(step, (start, alone), None, length=width)
    ring = jnp.moveaxis(ring, 0, -1)
    if dummy is not None:
        ring = _without_dummies(ring, dummy, whole, n, max_degree)
    return ring, jnp.sum(ring < n, axis=-1).astype(jnp.int32)


def _without_dummies(ring, dummy, whole, n, max_degree):
    """``ring`` (closed-surface rings, one slot wider than ``max_degree``) without its dummy
    neighbours, rotated to start just after the dummy where the whole ring was read (``whole``):
    the border vertex's ring of the input mesh, from one border neighbour ccw to the other (one
    sort of ``max_degree + 1`` slots per vertex). Left in place (the dummy only dropped) where it was truncated."""
    real = ring < n
    is_dummy = real & dummy[jnp.where(real, ring, 0)]
    count = jnp.sum(real, axis=-1, keepdims=True)
    pos = jnp.arange(ring.shape[-1], dtype=jnp.int32)
    after = jnp.argmax(is_dummy, axis=-1, keepdims=True).astype(jnp.int32) + 1
    rotate = whole[..., None] & jnp.any(is_dummy, axis=-1, keepdims=True)
    key = jnp.where(rotate, (pos - after) % jnp.maximum(count, 1), pos)
    key = jnp.where(real & ~is_dummy, key, ring.shape[-1])  # dummies and padding last
    order = jnp.argsort(key, axis=-1, stable=True)[..., :max_degree]
    out = jnp.take_along_axis(ring, order, axis=-1)
    return jnp.where(jnp.take_along_axis(key, order, axis=-1) < ring.shape[-1], out, n)
