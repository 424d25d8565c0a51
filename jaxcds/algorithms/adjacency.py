"""Rotations around vertices: adjacency tests and one-rings, on any structure."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from jaxcds import errors
from jaxcds._args import is_integer
from jaxcds.structures.base import id_arg, structure_arg

__all__ = ["adjacent", "one_ring", "rotate_until"]


def rotate_until(s, start, stop_fn, max_steps: int):
    """Turn ccw around ``origin(start)`` (batched) until ``stop_fn(e)`` or back at ``start``.

    Returns ``(e, hit)``: the dart where the rotation stopped and whether ``stop_fn`` held there.
    Written as a ``while_loop`` whose body is branch-free: lanes that are done keep their state,
    and the loop ends when every lane is done (after at most the largest degree in the batch).
    """
    hit0 = stop_fn(start)
    e, hit, _ = _turn(s, start, start, hit0, hit0, stop_fn, max_steps)
    return e, hit


def _turn(s, start, e, hit, done, stop_fn, max_steps: int):
    """:func:`rotate_until`'s loop from the state ``(e, hit, done)`` (``e`` tested already),
    for at most ``max_steps`` turns: ``(e, hit, done)``."""

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

    e, hit, done, _ = jax.lax.while_loop(cond, body, (e, hit, done, jnp.int32(0)))
    return e, hit, done


#: turns every query of a batched :func:`adjacent` makes together; the queries still turning
#: then go on compacted, a chunk of them at a time (:func:`~jaxcds.structures.succinct.bitvector.
#: compacted`): in one loop a batch waited for its slowest lane, queries x the largest degree
#: asked about (sweep 17b: 100K queries around a degree-1,000 hub, lr 9-12 s)
ADJACENT_FIRST_TURNS = 16
#: lanes per chunk of those (few lanes: the chunk turns as long as its longest rotation)
ADJACENT_CHUNK = 1024
#: turns a query of :func:`adjacent` makes on average (half a triangulation's mean degree 6 when
#: the pair is an edge, all of it when not): its batch asks about this many times its size of
#: each operator, which decides whether the structure tabulates them first (``for_queries``)
ADJACENT_MEAN_TURNS = 4


def adjacent(s, u, v):
    """``Adjacent(u, v)`` (CDS Sec. 1.3): True where ``u`` and ``v`` share an edge. O(deg u).

    Edges of the structure's surface: where it closed holes with dummy vertices (the CDS
    family), a dummy is adjacent to its hole's border vertices (mask with
    ``s.dummy_vertex_mask()``); between the input's vertices the answer is the input mesh's.

    ``u`` and ``v`` broadcast against each other (a scalar against an array); the answer has
    their broadcast shape.

    Raises:
      InvalidIndexError: ``u`` or ``v`` are not integers (floats, bools, strings: a cast would
        truncate 1.7 to 1); any integer kind and byte order is read as int32.
      ArgumentError: ``s`` is not a structure, or ``u`` and ``v`` have shapes that do not
        broadcast (JAX's untyped ValueError / TypeError from inside the jitted query before)."""
    structure_arg(s, "adjacent")
    u, v = id_arg(u, "adjacent: u"), id_arg(v, "adjacent: v")
    try:
        np.broadcast_shapes(np.shape(u), np.shape(v))
    except ValueError:
        raise errors.ArgumentError(
            f"adjacent: u and v must have shapes that broadcast together, got "
            f"{tuple(np.shape(u))} and {tuple(np.shape(v))}") from None
    return _adjacent(s, u, v)


@jax.jit
def _adjacent(s, u, v):
    if hasattr(s, "adjacent"):
        return s.adjacent(u, v)
    from jaxcds.structures.succinct.bitvector import finish_pending

    u, v = jnp.broadcast_arrays(u, v)
    shape = u.shape
    u, v = u.reshape(-1), v.reshape(-1)
    s = s.for_queries(u.size * ADJACENT_MEAN_TURNS)
    start = s.edge_of_vertex(u)
    valid = s.dart_valid(start)  # false for a vertex in no face (edge_of_vertex: "absent")

    def stop(v, valid):
        return lambda e: valid & (s.target(e) == v)

    hit0 = stop(v, valid)(start)
    e, hit, done = _turn(s, start, start, hit0, hit0, stop(v, valid), ADJACENT_FIRST_TURNS)

    def rest(start, e, v, valid, hit, done):  # the lanes still turning, to the end
        return _turn(s, start, e, hit, done, stop(v, valid), s.num_vertices + 1)[1]

    hit = finish_pending(rest, ~done, hit, (start, e, v, valid, hit, done), ADJACENT_CHUNK)
    return (hit & (u != v) & valid).reshape(shape)


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
        otherwise be cut or parsed quietly, and a negative size fails inside XLA), or ``s`` is
        not a structure."""
    structure_arg(s, "one_ring")
    if not is_integer(max_degree) or max_degree < 0:
        raise errors.ArgumentError(
            f"one_ring: max_degree must be a non-negative integer (the ring's static width), "
            f"got {max_degree!r}")
    return _one_ring(s, id_arg(v, "one_ring: vertices"), int(max_degree))


@functools.partial(jax.jit, static_argnums=2)
def _one_ring(s, v, max_degree):
    n = s.num_vertices
    s = s.for_queries(jnp.size(v) * (max_degree + 1))  # the scan's steps ask each operator once
    start = s.edge_of_vertex(v)
    alone = ~s.dart_valid(start)  # a vertex in no face: an empty ring
    dummy = s.dummy_vertex_mask()
    if dummy is not None:  # a dummy vertex is no vertex of the input: an empty ring
        alone = alone | dummy[jnp.clip(v, 0, n - 1)]
    # one more turn where dummies are: a border vertex has one dummy neighbour at most (its
    # faces form one fan, validated), which takes a slot of the closed ring
    width = max_degree + (dummy is not None)

    # a finished lane stops turning and asks Target of the twin of its first dart, which points
    # back at the vertex itself: on CDS6n/5n/4n (Thm 2, O(d)) a lane that went on turning walked
    # the fan of every neighbour it passed, again and again up to max_degree turns (a degree-4,000
    # hub's one_ring took 6-7 s on cds6n; sweep 17a)
    parked = s.twin(start)

    def step(carry, _):
        e, done = carry
        t = jnp.where(done, n, s.target(jnp.where(done, parked, e)))
        e2 = jnp.where(done, e, s.ccw_vertex_edge(e))
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
    # a row of the ring's rank (not a bare vector): rank promotion may be set to raise
    pos = jnp.arange(ring.shape[-1], dtype=jnp.int32).reshape((1,) * (ring.ndim - 1) + (-1,))
    after = jnp.argmax(is_dummy, axis=-1, keepdims=True).astype(jnp.int32) + 1
    rotate = whole[..., None] & jnp.any(is_dummy, axis=-1, keepdims=True)
    key = jnp.where(rotate, (pos - after) % jnp.maximum(count, 1), pos)
    key = jnp.where(real & ~is_dummy, key, ring.shape[-1])  # dummies and padding last
    order = jnp.argsort(key, axis=-1, stable=True)[..., :max_degree]
    out = jnp.take_along_axis(ring, order, axis=-1)
    return jnp.where(jnp.take_along_axis(key, order, axis=-1) < ring.shape[-1], out, n)
