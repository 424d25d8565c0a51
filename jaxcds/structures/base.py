"""The navigation protocol shared by every structure.

Every structure (HalfEdge, CornerTable, the CDS family, LR, pemb) exposes the mesh through
*darts*: oriented edges, identified by ``int32`` ids in ``[0, num_darts)``. The id space is the
structure's own (``3u + colour`` for CDS6n, ``8v + i`` corners for LR, half-edge slots for
HalfEdge...) and may contain holes, reported by :meth:`MeshStructure.dart_valid`.

Vocabulary (CDS paper, Sec. 1.3, Fig. 2). Let ``e = (u, v)`` be a dart oriented toward ``v``,
incident to ``(u, v, w)`` (its left triangle, counter-clockwise) and to ``(v, u, z)`` (its right
triangle)::

            w
           / \\
    lb    /   \\  lf          lf = left_front(e)  = (v, w) = next(e)
         /  L  \\             lb = left_back(e)   = (w, u) = prev(e)
        u ----> v  e          rf = right_front(e) = (z, v) = prev(twin(e))
         \\  R  /             rb = right_back(e)  = (u, z) = next(twin(e))
    rb    \\   /  rf
           \\ /
            z

The paper's operators return *unoriented* edges; ours return the dart of that edge that runs
counter-clockwise around the face it is named after (left face for ``left_*``, right face for
``right_*``), so the answer is unique and comparable across structures.

A structure implements the **core** set (``origin``, ``twin``, ``next``, ``face``,
``edge_of_vertex``, ``edge_of_face``, ``dart_valid``, ``references``); everything else is derived
here once, and a structure overrides a derived operator only when it has a faster route.
All operators take arrays of ids of any shape, are branch-free and jittable.

"Absent" is the sentinel one past the end, never ``-1`` (JAX wraps negative indices): the face of
a border dart is ``num_faces``; a vertex with no dart maps to ``num_darts``.

Corners (Rossignac's corner table vocabulary) are darts too: corner ``c`` at vertex ``c.v`` of a
triangle is the dart leaving ``c.v`` counter-clockwise in that triangle, so ``c.n = next(c)``,
``c.p = prev(c)``, ``c.o = prev(twin(next(c)))`` and ``c.s = c.n.o.n = twin(prev(c))``.
"""

from __future__ import annotations

import contextlib
import functools
import os
import threading
from typing import ClassVar, Optional, Union

import jax
import jax.numpy as jnp
import numpy as np

from jaxcds import errors
from jaxcds._args import shown
from jaxcds._arrays import Tracer as _Tracer
from jaxcds._arrays import to_device, traced_for_cpu

__all__ = ["MeshStructure", "Int", "as_ids", "interleave_rows", "interleave_windows",
           "materialize_loop", "computed_in_loop", "QUERY_CHUNK", "CHUNKED_QUERIES", "one_pass_queries",
           "checked_ids",
           "by_table", "per_query_routes", "shared_subexpressions", "shared_subexpression"]

Int = jnp.ndarray  # int32 array of ids, any shape
Bool = jnp.ndarray  # bool array, any shape


#: the largest dart id space an int32 reference holds: ids ``0 .. 2^31 - 2`` and the "absent"
#: sentinel ``num_darts`` itself (``2^31 - 1``)
MAX_DARTS = 2**31 - 1


def check_id_space(what: str, num_darts: int) -> None:
    """Raise :class:`~jaxcds.errors.UnsupportedTopologyError` naming ``what`` when ``num_darts``
    ids and their sentinel do not fit int32 (every reference of jaxcds is int32; past it the ids
    wrap to negative values and every answer is wrong)."""
    if num_darts > MAX_DARTS:
        raise errors.UnsupportedTopologyError(
            f"{what}: {num_darts:,} dart ids do not fit int32 references (at most {MAX_DARTS:,}, "
            "the 'absent' sentinel included): split the mesh or pack fewer meshes per batch")


def integer_array(ids, what: str) -> np.ndarray:
    """``ids`` as a numpy array of any integer dtype (an empty one of any dtype), or
    :class:`~jaxcds.errors.InvalidIndexError` naming ``what``: ragged nested lists, floats,
    strings (a cast would truncate 1.7 to 1), booleans, masked arrays (their mask would be
    dropped)."""
    if isinstance(ids, np.ma.MaskedArray):
        raise errors.InvalidIndexError(f"{what} are a masked array: fill or drop the masked "
                                       "entries first (np.ma.compressed, .filled)")
    try:
        a = np.asarray(ids)
    except ValueError as exc:  # ragged nested lists
        raise errors.InvalidIndexError(f"{what} are not an array: {exc}") from None
    if a.size and not np.issubdtype(a.dtype, np.integer):
        raise errors.InvalidIndexError(f"{what} must be integers, got dtype {a.dtype}")
    return a


def structure_arg(s, what: str) -> None:
    """:class:`~jaxcds.errors.ArgumentError` naming ``what`` unless ``s`` is a jaxcds structure
    (a :class:`MeshStructure`: a registry build, a packed batch, a sharded structure). The
    generic algorithms read ``s.num_vertices`` inside ``jit``: a ``TriMesh``, an array or a
    path failed there with an ``AttributeError`` about a tracer."""
    if not isinstance(s, MeshStructure):
        from jaxcds.mesh import TriMesh

        hint = (" (build one first: jaxcds.build(name, mesh))" if isinstance(s, TriMesh)
                else "")
        raise errors.ArgumentError(
            f"{what}: expected a jaxcds structure (jaxcds.build(name, mesh), a packed batch), "
            f"got {type(s).__name__}{hint}")


def id_arg(x, what: str) -> Int:
    """Ids handed to an operator, as int32: a traced or int32 jax array as it is (inside ``jit``
    the caller's dtype is fixed already; other integer dtypes converted); host values (numpy
    arrays of any byte order, lists, tuples, Python ints) checked first, so that floats, bools,
    strings and masked arrays are refused with :class:`~jaxcds.errors.InvalidIndexError` (a
    cast truncates 1.7 to 1, a bool array would index as a mask) and integers past int32 read
    as out of range (-1 or int32 max: "absent" where the caller checks) instead of wrapping
    onto a valid id."""
    if isinstance(x, jax.Array) and (isinstance(x, _Tracer) or x.dtype.itemsize <= 4):
        if not jnp.issubdtype(x.dtype, jnp.integer):
            raise errors.InvalidIndexError(f"{what} must be integers, got dtype {x.dtype}")
        if x.dtype == jnp.int32 or jnp.can_cast(x.dtype, jnp.int32):
            return x if x.dtype == jnp.int32 else x.astype(jnp.int32)
        # traced uint32 / int64 / uint64 (x64 on): clamped as the host route clamps, so an id
        # past int32 reads as out of range instead of wrapping onto a valid id
        top = jnp.asarray(np.iinfo(np.int32).max, x.dtype)
        if jnp.issubdtype(x.dtype, jnp.unsignedinteger):
            return jnp.minimum(x, top).astype(jnp.int32)
        low = jnp.asarray(np.iinfo(np.int32).min, x.dtype)
        return jnp.where(x < low, -1, jnp.minimum(x, top)).astype(jnp.int32)
    a = integer_array(x, what)
    if a.size == 0:
        return to_device(np.zeros(a.shape, np.int32))
    info = np.iinfo(np.int32)
    if np.can_cast(a.dtype, np.int32):  # int8/16/32, uint8/16: every value fits
        return to_device(a.astype(np.int32))  # a fresh array: the device may share its buffer
    if a.dtype.kind == "u":
        a = np.minimum(a, np.asarray(info.max, a.dtype))
    else:
        a = np.where(a < info.min, -1, np.minimum(a, info.max))
    return to_device(a.astype(np.int32))


def take_nonnegative(table, i):
    """``table[i]`` for indices known not to be negative (vertex ids read off a structure's
    tables, clipped offsets, ``jnp.where(..., 0, id)``): without the wrap of negative indices
    that ``table[i]`` adds, three operations per read, each of which counts in XLA:CPU's choice
    to split a kernel over its threads (``cds._CDS._target_start``). Out-of-range indices are
    clamped, as XLA's gather does. ``table`` may also be any object read by ``[]`` alone (a
    packed LR's segment view, ``lr_packed._Seg``, which reads its array this way).

    Normals x the face list with and without the wrap, raced (2026-12-02, Intel host): CDS5n-O(1)
    bunny 1.36 -> 1.32x, cheburashka 1.59 -> 1.47x, armadillo 1.43 -> 1.33x; CDS5n cheburashka
    1.61 -> 1.46x; packed 3,000 meshes LR 1.33 -> 1.28x, LR-bits 1.38 -> 1.30x; CDS6n, and LR on
    armadillo and 200K, level."""
    if not hasattr(table, "at"):
        return table[i]
    return table.at[i].get(mode="promise_in_bounds", wrap_negative_indices=False)


def as_ids(x) -> jnp.ndarray:
    """Ids as an int32 jnp array (the dtype of every reference in jaxcds)."""
    return jnp.asarray(x, dtype=jnp.int32)


#: ids per chunk of a large batched query on CPU (see :func:`_chunked_query`)
QUERY_CHUNK = 1 << 16

#: let the operators a class names in ``chunk_answers_apart`` write each chunk's answers to a
#: buffer of their own (read at trace time; see :func:`_chunked_query`; ``False`` only to race
#: the fused write, ``benchmarks/race_chunked_queries.py``)
WRITE_CHUNK_ANSWERS_APART = True

#: the batched queries whose ids are checked (:func:`id_arg`) and which may run chunk by chunk:
#: one or two id arrays in, one array out (``dart_valid`` is never chunked: no class names it).
#: ``is_border`` and ``corner_vertex`` / ``corner_next`` / ``corner_prev`` joined the list late:
#: outside the list, a float or string id was refused in the name of the operator they call
#: (``face``, ``origin``, ``next``, ``prev``), and pemb's declared ``is_border`` table route
#: (``table_queries``) was never taken
CHUNKED_QUERIES = ("dart_valid", "origin", "source", "target", "twin", "next", "prev", "face", "face_left",
                   "face_right", "edge_of_vertex", "edge_of_face", "left_front", "left_back",
                   "right_front", "right_back", "ccw_vertex_edge", "cw_vertex_edge", "is_border",
                   "corner_vertex", "corner_next", "corner_prev", "corner_opposite", "corner_swing",
                   "adjacent")


def checked_ids(method):
    """``method(self, *ids, **kwargs)`` with its positional ids checked and made int32 by
    :func:`id_arg`, named after ``method``: for public operators outside :data:`CHUNKED_QUERIES`
    (the papers' own vocabulary: the corner table's and LR's ``v``, ``n``, ``p``, ``o``, ``s``,
    the CDS corner numbering). They cast their ids with ``jnp.asarray(c, int32)`` (corner 1.5
    read as 1, ``True`` as 1, the string ``'1'`` as 1: silently wrong answers) or indexed a
    table with them (a list as a tuple of indices, a bool array as a mask, floats raised JAX's
    TypeError). Traced int32 ids pass through unchanged (no cost inside ``jit``)."""
    name = method.__name__

    @functools.wraps(method)
    def run(self, *ids, **kwargs):
        return method(self, *(id_arg(x, f"{name}: ids") for x in ids), **kwargs)

    return run


class _TraceFlag(threading.local):
    """A per-thread switch that nested ``with`` blocks turn on (a depth count, so an inner block
    leaving does not turn it off for the outer one); read while tracing."""

    depth = 0

    @contextlib.contextmanager
    def on(self):
        self.depth += 1
        try:
            yield
        finally:
            self.depth -= 1

    def __bool__(self):
        return self.depth > 0


_ONE_PASS = _TraceFlag()
_NO_TABLE = _TraceFlag()


class _SharedTraces(threading.local):
    """Per thread: the traced results of :func:`shared_subexpression` methods while a
    :func:`shared_subexpressions` block is open (``None`` otherwise)."""

    memo = None


_SHARED = _SharedTraces()


@contextlib.contextmanager
def shared_subexpressions():
    """Within this block, a method marked :func:`shared_subexpression` that is traced twice on
    the same structure with the same traced ids (the same tracer objects) returns its first
    traced result instead of tracing its body again.

    For one program that asks many operators of the same darts: pemb's ``twin``, ``next``,
    ``target``, ``right_front``, ``face_right`` ... each begin with ``mate(e)``, two parenthesis
    searches, and :func:`jaxcds.verify.verify`'s every-operator program traced it a dozen times.
    XLA's common-subexpression pass merged the copies, so answers and run time do not change;
    tracing and compilation do (pemb on the bunny: 104K -> 44K lines of HLO, tracing 6.6 -> 2.5
    s, compilation 26.7 -> 12.3 s; stop 46). Eager calls (concrete ids) are not shared. Nested
    blocks share the outer block's results."""
    saved = _SHARED.memo
    if saved is None:
        _SHARED.memo = {}
    try:
        yield
    finally:
        _SHARED.memo = saved


def _memo_key(value):
    """A hashable stand-in for an argument: tracers by identity, other values as they are."""
    return ("tracer", id(value)) if isinstance(value, _Tracer) else value


def _trace_state():
    """The trace being built now (compared by ``==``), or ``None`` where this JAX does not say:
    a result traced inside a loop body or a branch belongs to that inner trace, and must not be
    handed out again outside it."""
    try:
        from jax.extend.core import get_opaque_trace_state
        return get_opaque_trace_state()
    except Exception:  # noqa: BLE001 -- not available: nothing is shared
        return None


def shared_subexpression(method=None, *, masks: tuple = ()):
    """Mark ``method(self, ids, ...)`` (ids traced) as shared inside :func:`shared_subexpressions`.

    ``masks``: keyword arguments that only restrict which lanes must be right (pemb's
    ``where``): a result traced without them is right on every lane and serves any mask."""
    if method is None:
        return functools.partial(shared_subexpression, masks=masks)

    @functools.wraps(method)
    def shared(self, *args, **kwargs):
        memo = _SHARED.memo
        if memo is None or not args or not all(isinstance(a, _Tracer) for a in args):
            return method(self, *args, **kwargs)
        state = _trace_state()
        if state is None:
            return method(self, *args, **kwargs)
        try:
            head = (method.__qualname__, id(self), tuple(id(a) for a in args))
            given = sorted((k, _memo_key(v)) for k, v in kwargs.items()
                           if not (k in masks and v is None))  # no mask = the None default
            key = head + (tuple(given),)
            unmasked = head + (tuple((k, v) for k, v in given if k not in masks),)
            hash((key, unmasked))
        except TypeError:  # an unhashable keyword value: not shared
            return method(self, *args, **kwargs)
        for k in (key, unmasked):
            for traced_in, out, *_ in memo.get(k, ()):
                if traced_in == state:
                    return out
        out = method(self, *args, **kwargs)
        # the arguments are kept with the result: their ids then name no other object while the
        # block is open
        memo.setdefault(key, []).append((state, out, self, args, kwargs))
        return out

    return shared


def id_table_route(op: str):
    """A table route (``MeshStructure.table_queries``) for operator ``op`` of a structure whose
    per-query route costs tens of nanoseconds: ``op`` of every id of the id space once (its own
    per-query route, over ``arange(num_darts)``), written to memory, then one gather per id;
    ids out of range read a clamped entry (garbage, as the per-query route gives them). Worth it
    from about twice the darts' worth of ids (LR's Target, ``RESULTS.md`` "stop 47")."""

    @by_table
    def route(self, d: Int) -> Int:
        everything = getattr(self, op)(jnp.arange(self.num_darts, dtype=jnp.int32))
        # written once: fused into the gather, the per-query route would run once per id
        (table,) = materialize_loop((everything.astype(jnp.int32),))
        return table.at[jnp.asarray(d, jnp.int32)].get(mode="clip")

    route.__name__ = route.__qualname__ = f"_{op}_by_id_table"
    return route


def per_query_routes():
    """Within this block, operators traced take no whole-mesh table route (``table_queries``):
    every batch runs the per-query route of the paper's operator. Used inside a table's own
    computation (which may ask the operators for a batch as large as the mesh), by tests that
    check both routes and by benchmarks that race them."""
    return _NO_TABLE.on()


def by_table(method):
    """Mark ``method(self, ids)`` as a whole-mesh table route of a :class:`MeshStructure`
    (see ``table_queries``): its body runs with table routes off (:func:`per_query_routes`)."""

    @functools.wraps(method)
    def run(self, *args, **kwargs):
        with per_query_routes():
            return method(self, *args, **kwargs)

    return run


def one_pass_queries():
    """Within this block, operators traced run every batch in one pass (no chunks): for batches
    sharded over devices (:func:`jaxcds.sharding.sharded_query`), where chunks along the sharded
    axis would make the partitioner gather the batch."""
    return _ONE_PASS.on()


def _chunked_query(method):
    """``method(self, *ids)`` over a large batch, run :data:`QUERY_CHUNK` ids at a time (a
    ``fori_loop`` over the chunks, each chunk's answers written in place into the output) on the
    CPU backend, for the operators a class names in ``chunked_queries``.

    Why: a compact structure's operator is several passes over the batch (a row read, a case
    analysis, a second read; :func:`materialize_loop` between them), each writing a temporary as
    large as the batch. For 10M queries every temporary is 40 MB, out of cache; by chunks of 64K
    ids they stay in L2. Measured (``benchmarks/race_chunked_queries.py``, 100K vertices, 4M
    random darts, medians): CDS5n-O(1) Target 15.2 -> 10.6 ns per query, LR Target 40 -> 27,
    CDS6n Face_left 23 -> 10; at 2.5M vertices CDS5n-O(1) Target 20.6 -> 17.1. An operator that
    is one or two gathers (HalfEdge, CornerTable, LR's ``next``, every ``twin`` of the CDS family)
    runs 2-5x slower by chunks (the loop's fixed cost), so each class names the operators
    it chunks, as measured (``benchmarks/RESULTS.md``, "Batched queries by chunks"); packed
    batches chunk their class's operators at their entry points. Off for batches under two
    chunks, for id arrays of different shapes or passed by keyword, for the per-query views
    inside packed batches, and on accelerators, where a chunk of 64K ids would leave most of the
    device idle. Nested calls (an operator written with others) see at most one chunk and run
    as they are: one loop, at the outermost call."""

    name = method.__name__

    @functools.wraps(method)
    def run(self, *ids, **kwargs):
        chunk = QUERY_CHUNK
        # int32 from here on; floats, bools, strings and masked arrays refused by name (a list
        # indexed a corner table's array as a tuple, a bool array as a mask, int8 overflowed)
        ids = tuple(id_arg(x, f"{name}: ids") for x in ids)
        if kwargs or _ONE_PASS:
            return method(self, *ids, **kwargs)
        if self.eager_buckets and _eager(self, ids):
            return _bucketed(run, self, ids)
        if len(ids) == 1 and self.takes_table(name, jnp.size(ids[0])):
            return getattr(self, self.table_queries[name])(ids[0])
        if name not in self.chunked_queries or not traced_for_cpu():
            return method(self, *ids)
        shape, size = ids[0].shape, ids[0].size  # device arrays already (id_arg above)
        if size < 2 * chunk or any(x.shape != shape for x in ids):
            return method(self, *ids)
        flat = [x.reshape(-1) for x in ids]
        dtype = jax.eval_shape(lambda: method(self, *(f[:chunk] for f in flat))).dtype
        apart = (WRITE_CHUNK_ANSWERS_APART and name in self.chunk_answers_apart
                 and jnp.issubdtype(dtype, jnp.integer))

        def one_chunk(i, out):
            # the last chunk ends at the batch's end and overlaps the one before (same answers
            # twice): every chunk has the static size, and the answers are written in place
            start = jnp.minimum(i * chunk, size - chunk)
            cs = [jax.lax.dynamic_slice(f, (start,), (chunk,)) for f in flat]
            res = method(self, *cs).astype(dtype)
            if apart:
                # fused into the in-place update of the output, the operator's last pass runs
                # on one thread; written apart it is split over both cores, at the cost of one
                # more loop and copy per chunk (worth it only for a heavy last pass)
                (res,) = materialize_loop((res,))
            return jax.lax.dynamic_update_slice(out, res, (start,))

        out = jax.lax.fori_loop(0, -(-size // chunk), one_chunk, jnp.zeros(size, dtype))
        return out.reshape(shape)

    run.chunked_query = True
    return run


def _eager(structure, ids) -> bool:
    """Whether an operator call runs eagerly: no traced id nor traced structure array, and jit
    enabled (under ``jax.disable_jit()`` the bucket's jitted call ran the operator with concrete
    ids again, which asked for the bucket again: a RecursionError on every CDS, LR and pemb
    operator; found on stop 45)."""
    if jax.config.jax_disable_jit or any(isinstance(x, _Tracer) for x in ids):
        return False
    leaves = jax.tree_util.tree_leaves(structure)
    if len(leaves) == 1 and leaves[0] is structure:
        return False  # not a pytree (a structure's internal views): no jitted program takes it
    return not any(isinstance(leaf, _Tracer) for leaf in leaves)


def _bucket(size: int) -> int:
    """The next power of two from ``size`` (``size >= 1``): the batch :func:`_bucketed` pads to."""
    return 1 << (size - 1).bit_length()


def eager_batch_size(structure, ids) -> int:
    """The batch size ``structure``'s operators see for a call on ``ids`` (a tuple of id
    arrays): an eager call of an :attr:`MeshStructure.eager_buckets` class runs padded to the
    next power of two (:func:`_bucketed`; nested operators too: CDS Corner_vertex calls Origin
    eagerly), and its table routes decide on that size; otherwise the batch's own size.
    :mod:`jaxcds.sharding` reads it to send table-size batches to its unpadded arrays."""
    size = int(jnp.size(ids[0]))
    if size > 1 and structure.eager_buckets and not _ONE_PASS and _eager(structure, ids):
        return _bucket(size)
    return size


def _bucketed(run, structure, ids):
    """An eager call of ``run`` (an operator's wrapper) as one jitted program, its ids padded on
    the host to the next power of two (with copies of the first id: answers about a real dart)
    and the answers cut back. For :attr:`MeshStructure.eager_buckets` classes.

    Why: run eagerly, every ``while_loop`` of an operator (pemb's parenthesis searches) is
    compiled for the batch's exact size and kept: 24 eager calls of 100-5,000 random darts on a
    2,000-vertex pemb took 119 s and 2.4 GB that stayed (stop 43). Here a size costs at most one
    compilation per power of two, and whole operators compile once instead of loop by loop."""
    # one program per route choice: jit's cache does not key on per_query_routes(), so an
    # eager call inside that block ran the table route compiled by an earlier call outside it
    # (sweep 48)
    key = "_jitted_per_query" if _NO_TABLE else "_jitted"
    jitted = getattr(run, key, None)
    if jitted is None:
        # the per-query program wraps run in a function of its own: jit caches by function
        jitted = jax.jit(lambda structure, *ids: run(structure, *ids)) if _NO_TABLE else jax.jit(run)
        setattr(run, key, jitted)
    shape = ids[0].shape
    size = int(np.prod(shape, dtype=np.int64))
    if size == 0 or any(x.shape != shape for x in ids):
        return jitted(structure, *ids)
    cap = _bucket(size)
    if cap == size and len(shape) == 1:
        return jitted(structure, *ids)
    padded = []
    for x in ids:
        h = np.asarray(x).reshape(-1)
        padded.append(to_device(np.concatenate([h, np.full(cap - size, h[0], h.dtype)])))
    # cut and shaped on the host: an eager slice or reshape compiles a program per size too
    return to_device(np.asarray(jitted(structure, *padded))[:size].reshape(shape))


#: whole-mesh methods (``method(self)``, arrays out) that a class may run as one jitted program
#: when they are called eagerly (:attr:`MeshStructure.jit_when_eager`, :func:`_jit_when_eager`)
WHOLE_MESH_METHODS = ("face_vertices", "face_vertices_padded", "dart_faces", "vertex_degrees",
                      "target_table", "all_edge_targets")


def _jit_when_eager(method, static_argnames: tuple = ()):
    """``method(self, ...)`` run as one jitted program when called eagerly (no traced array in
    the structure or the arguments) on a class that names it in
    :attr:`~MeshStructure.jit_when_eager`; as it is elsewhere (traced, or jit disabled).
    ``static_argnames``: keyword arguments that are options, not arrays."""
    jitted = jax.jit(method, static_argnames=static_argnames)
    name = method.__name__

    @functools.wraps(method)
    def run(self, *args, **kwargs):
        arrays = jax.tree_util.tree_leaves(
            (args, {k: v for k, v in kwargs.items() if k not in static_argnames}))
        if name in self.jit_when_eager and _eager(self, arrays):
            return jitted(self, *args, **kwargs)
        return method(self, *args, **kwargs)

    run.jitted_when_eager = True
    return run


def _jit_whole_mesh(cls) -> None:
    """Wrap the :data:`WHOLE_MESH_METHODS` that ``cls`` itself defines (not inherited ones)."""
    for name in WHOLE_MESH_METHODS:
        fn = cls.__dict__.get(name)
        if callable(fn) and not getattr(fn, "jitted_when_eager", False):
            setattr(cls, name, _jit_when_eager(fn))


def _chunk_queries(cls) -> None:
    """Wrap the :data:`CHUNKED_QUERIES` that ``cls`` itself defines (not inherited ones): every
    :class:`MeshStructure` subclass, and the mixins that add entry points (packed batches)."""
    for name in CHUNKED_QUERIES:
        fn = cls.__dict__.get(name)
        if callable(fn) and not getattr(fn, "chunked_query", False):
            setattr(cls, name, _chunked_query(fn))


class MeshStructure:
    """Mixin for connectivity structures. Subclasses are :func:`pytree_dataclass` es with static
    ``num_vertices`` and ``num_faces`` fields (and any array fields they need)."""

    #: registry name (``halfedge``, ``corner-table``, ``cds6n`` ...)
    name: ClassVar[str] = "abstract"
    #: whether every face is a triangle and every dart has a face (closed triangle mesh)
    closed_triangles: ClassVar[bool] = True
    #: the operators whose large batches run :data:`QUERY_CHUNK` ids at a time on CPU
    #: (:func:`_chunked_query`)
    chunked_queries: ClassVar[frozenset] = frozenset()
    #: eager calls of the operators run as one jitted program per power-of-two batch size
    #: (:func:`_bucketed`): for classes whose operators hold loops (compiled per exact size)
    eager_buckets: ClassVar[bool] = False
    #: the :data:`WHOLE_MESH_METHODS` that an eager call runs as one jitted program (one per
    #: structure: its static fields are part of the cache key). Run primitive by primitive, the
    #: CDS kinds' ``face_vertices()``, ``vertex_degrees()`` or ``target_table()`` took 0.12-0.19 s
    #: per call on a 3,000-vertex mesh (dispatch around the pointer-jumping loop; jitted: under
    #: 1 ms), LR's first ``face_vertices()`` 1.3-1.4 s (jitted: 0.14-0.16 s). pemb names only
    #: ``with_tables`` (4-8 s per new mesh shape primitive by primitive, then 1.2 s a call; its
    #: eager operators are bucketed, and a program of its whole ``dart_faces`` took 4.6 s to
    #: compile against 2.9 s for its parts); the arithmetic half-edge and corner table none
    #: (stop 46). Methods other than :data:`WHOLE_MESH_METHODS` are wrapped where they are
    #: defined (:func:`_jit_when_eager`).
    jit_when_eager: ClassVar[frozenset] = frozenset()
    #: why :func:`jaxcds.sharding.shard_structure` cannot split this class's arrays by rows
    #: (``None``: it can)
    row_sharding_refused: ClassVar[Optional[str]] = None
    #: those of them whose chunks write their answers apart before the in-place update
    #: (:data:`WRITE_CHUNK_ANSWERS_APART`), as measured per class
    chunk_answers_apart: ClassVar[frozenset] = frozenset()
    #: operators (of :data:`CHUNKED_QUERIES`) that answer a batch of at least
    #: ``table_ratio(op) * num_darts`` ids (one id array, any backend) from a whole-mesh table
    #: computed once per call: ``{operator: name of a method(ids) marked with by_table}``.
    #: Why: an operator of O(d) per query (Thm 2's Target walk) or of several dependent reads
    #: (Thm 6's Target, Thm 2's Backs, Thm 7's slot rules) costs more per query than one entry
    #: of the table costs to compute, so a batch as large as a fraction of the mesh is answered
    #: faster by computing every answer once, then one gather per query. The cost is memory
    #: while the call runs (1M vertices, a 6M-dart batch): the Target table's temporaries are
    #: about the structure's own size (24 bytes per vertex for CDS6n / CDS5n / CDS4n, 52 for
    #: CDS5n-O(1)), the face table's 132-156, Next / Prev's 84-120, against 2-5 for the chunked
    #: per-query routes (Target, Face_left) and 216-384 for the unchunked ones (Next, Prev: every
    #: pass as large as the batch); trace under :func:`per_query_routes` to keep the per-query
    #: route (``benchmarks/RESULTS.md``, "stop 33: batched Target by a table", "stop 35: batched
    #: Face_left, Next and Prev by tables")
    table_queries: ClassVar[dict] = {}
    #: the batch size, per dart of the id space, from which ``table_queries`` take the table:
    #: one ratio for all of them, or ``{operator: ratio}`` (see :meth:`table_ratio`)
    table_batch_ratio: ClassVar[Union[float, dict]] = float("inf")

    @classmethod
    def table_ratio(cls, op: str) -> float:
        """The batch size, per dart, from which operator ``op`` of ``table_queries`` takes its
        table route (``inf``: never)."""
        r = cls.table_batch_ratio
        return float(r.get(op, float("inf"))) if isinstance(r, dict) else float(r)

    def takes_table(self, op: str, batch_size: int) -> bool:
        """Whether operator ``op``, traced here for ``batch_size`` ids, takes its table route:
        it has one (``table_queries``), the batch reaches :meth:`table_ratio`, and the trace is
        not inside :func:`per_query_routes`."""
        return (op in self.table_queries and not _NO_TABLE
                and batch_size >= self.table_ratio(op) * self.num_darts)

    def for_queries(self, num_queries: int) -> "MeshStructure":
        """The structure a loop should navigate when it asks operators of about ``num_queries``
        ids in all (every step's batch together): itself here. A structure whose operators
        search per id and can tabulate them for the call (pemb) returns itself holding its
        tables once that many ids would pay for them, so the loop's every step reads the tables
        rather than computing them anew or searching (a pemb's ``one_ring`` of every vertex
        computed them in each of its steps: slower than the searches)."""
        return self

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        _chunk_queries(cls)
        _jit_whole_mesh(cls)

    num_vertices: int
    num_faces: int

    # ------------------------------------------------------------------ core: to implement
    @property
    def num_darts(self) -> int:
        """Size of the dart id space (valid ids are a subset, see :meth:`dart_valid`)."""
        raise NotImplementedError

    def dart_valid(self, e: Int) -> Int:
        """True where ``e`` names a dart of the mesh."""
        raise NotImplementedError

    def origin(self, e: Int) -> Int:
        """Source vertex ``u`` of ``e = (u, v)``."""
        raise NotImplementedError

    def twin(self, e: Int) -> Int:
        """The opposite dart ``(v, u)``."""
        raise NotImplementedError

    def next(self, e: Int) -> Int:
        """Next dart counter-clockwise around the left face: ``(v, w)``."""
        raise NotImplementedError

    def face(self, e: Int) -> Int:
        """Face at the left of ``e``; ``num_faces`` for a border dart."""
        raise NotImplementedError

    def edge_of_vertex(self, v: Int) -> Int:
        """A dart leaving vertex ``v``."""
        raise NotImplementedError

    def edge_of_face(self, f: Int) -> Int:
        """A dart whose left face is ``f``."""
        raise NotImplementedError

    @property
    def references(self) -> int:
        """Number of stored integer references (the papers' memory measure)."""
        raise NotImplementedError

    # ------------------------------------------------------------------ metadata
    @property
    def vertex_order(self) -> Optional[np.ndarray]:
        """``vertex_order[i]`` = input vertex id of structure vertex ``i``; ``None`` if the
        structure keeps the input numbering. Positions and per-vertex data must be permuted with
        it (``positions[vertex_order]``) before being used with the structure."""
        return None

    def dummy_vertex_mask(self) -> Optional[Bool]:
        """``(num_vertices,)`` bool: the vertices this structure holds that the input mesh does
        not (one per hole closed by :func:`jaxcds.mesh.close_boundaries`, CDS Sec. 4.5, when the
        structure keeps them as vertices of its own), or ``None`` if there are none.

        Whole-mesh reductions (:func:`jaxcds.algorithms.vertex_degrees`,
        :func:`jaxcds.algorithms.vertex_normals`) leave their fans out, so they answer for the
        input mesh: a border vertex's degree and normal are the open mesh's, a dummy's are 0.
        Navigation still walks the closed surface."""
        return None

    @property
    def references_per_vertex(self) -> float:
        return self.references / max(self.num_vertices, 1)

    @property
    def nbytes(self) -> int:
        """Bytes of every array held by the structure."""
        return int(sum(np.asarray(x).nbytes for x in jax.tree_util.tree_leaves(self)))

    def check_ids(self, kind: str, ids) -> np.ndarray:
        """Host-side guard for ids from outside (files, user input): ``ids`` as an int32 numpy
        array if every one names a ``kind`` (``"dart"``, ``"vertex"`` or ``"face"``) of this
        structure, else :class:`~jaxcds.errors.InvalidIndexError` naming the first bad id and
        its position.

        The jitted operators take valid ids as a precondition, as a C++ mesh library does (no
        test per query): an id out of range, or a dart id in a hole of the id space
        (``dart_valid`` False: an LR slot that is no corner, a CDS root's missing edge), answers
        an arbitrary value. Call this once on untrusted ids, or mask with :meth:`dart_valid`."""
        # an array as kind (the arguments swapped: check_ids(ids, "dart")) raised numpy's
        # "truth value of an array is ambiguous" ValueError from the membership test
        if not isinstance(kind, str) or kind not in ("dart", "vertex", "face"):
            raise errors.ArgumentError(f"unknown id kind {shown(kind)}: 'dart', 'vertex' or 'face' "
                                       "(check_ids(kind, ids): the kind comes first)")
        a = integer_array(ids, f"{kind} ids")
        size = {"dart": self.num_darts, "vertex": self.num_vertices, "face": self.num_faces}[kind]
        # compared in their own dtype: a uint64 past 2^63 must not wrap to a negative int64
        bad = (a >= size) if a.dtype.kind == "u" else (a < 0) | (a >= size)
        if kind == "dart" and a.size:
            inside = np.where(bad, 0, a).astype(np.int32)
            bad = bad | ~np.asarray(self.dart_valid(to_device(inside)))
        if bad.any():
            pos = np.unravel_index(int(np.argmax(bad)), a.shape) if a.ndim else ()
            x = int(a[pos]) if a.ndim else int(a)
            why = (f"outside [0, {size})" if not 0 <= x < size
                   else "inside the id space but not a dart (dart_valid is False)")
            where = f" at position {tuple(int(i) for i in pos)}" if a.ndim else ""
            raise errors.InvalidIndexError(
                f"{self.name}: {kind} id {x}{where} is {why}; {int(bad.sum())} of {a.size} ids are bad")
        return a.astype(np.int32)

    def all_darts(self) -> np.ndarray:
        """Host-side array of every valid dart id (for checks, not for hot loops)."""
        ids = jnp.arange(self.num_darts, dtype=jnp.int32)
        return np.nonzero(np.asarray(self.dart_valid(ids)))[0].astype(np.int32)

    # ------------------------------------------------------------------ derived: half-edge
    def source(self, e: Int) -> Int:
        """Alias of :meth:`origin` (CDS vocabulary)."""
        return self.origin(e)

    def target(self, e: Int) -> Int:
        """Target vertex ``v`` of ``e = (u, v)``."""
        return self.origin(self.twin(e))

    def prev(self, e: Int) -> Int:
        """Previous dart around the left face: ``(w, u)``. Triangles: ``next(next(e))``."""
        return self.next(self.next(e))

    def is_border(self, e: Int) -> Int:
        """True where the left face of ``e`` is the outside (a border dart)."""
        return self.face(e) == self.num_faces

    def ccw_vertex_edge(self, e: Int) -> Int:
        """Next dart counter-clockwise around ``origin(e)``: ``twin(prev(e))``."""
        return self.twin(self.prev(e))

    def cw_vertex_edge(self, e: Int) -> Int:
        """Next dart clockwise around ``origin(e)``: ``next(twin(e))``."""
        return self.next(self.twin(e))

    # ------------------------------------------------------------------ derived: CDS vocabulary
    def left_front(self, e: Int) -> Int:
        """``{v, w}`` as the dart ``(v, w)`` of the left face."""
        return self.next(e)

    def left_back(self, e: Int) -> Int:
        """``{u, w}`` as the dart ``(w, u)`` of the left face."""
        return self.prev(e)

    def right_front(self, e: Int) -> Int:
        """``{v, z}`` as the dart ``(z, v)`` of the right face."""
        return self.prev(self.twin(e))

    def right_back(self, e: Int) -> Int:
        """``{u, z}`` as the dart ``(u, z)`` of the right face."""
        return self.next(self.twin(e))

    def face_left(self, e: Int) -> Int:
        return self.face(e)

    def face_right(self, e: Int) -> Int:
        return self.face(self.twin(e))

    # ------------------------------------------------------------------ derived: corners
    def corner_vertex(self, c: Int) -> Int:
        """``c.v``."""
        return self.origin(c)

    def corner_next(self, c: Int) -> Int:
        """``c.n``."""
        return self.next(c)

    def corner_prev(self, c: Int) -> Int:
        """``c.p``."""
        return self.prev(c)

    def corner_opposite(self, c: Int) -> Int:
        """``c.o``: the corner facing ``c`` across the edge ``(c.n.v, c.p.v)``."""
        return self.prev(self.twin(self.next(c)))

    def corner_swing(self, c: Int) -> Int:
        """``c.s = c.n.o.n``: the next corner around ``c.v``."""
        return self.twin(self.prev(c))

    # ------------------------------------------------------------------ derived: whole mesh
    def face_vertices(self) -> Int:
        """``(num_faces, 3)`` int32 array of every triangle's vertices, counter-clockwise."""
        f = jnp.arange(self.num_faces, dtype=jnp.int32)
        e0 = self.edge_of_face(f)
        e1 = self.next(e0)
        e2 = self.next(e1)
        return jnp.stack([self.origin(e0), self.origin(e1), self.origin(e2)], axis=-1)

    def dart_faces(self) -> Int:
        """``(num_darts,)`` int32, :meth:`face` of every dart (``num_faces`` on a border or
        unused dart), all at once. The default writes each face's id to its three darts (three
        scatters from :meth:`edge_of_face`), which beats one :meth:`face` per dart where that is
        a search (pemb: an ``enclose`` each); a structure whose ``face`` is arithmetic answers
        with it."""
        f = jnp.arange(self.num_faces, dtype=jnp.int32)
        e0 = self.edge_of_face(f)
        e1 = self.next(e0)
        out = jnp.full((self.num_darts,), self.num_faces, jnp.int32)
        for e in (e0, e1, self.next(e1)):
            out = out.at[e].set(f, mode="drop")
        return out

    def face_vertices_padded(self):
        """``(faces (R, 3) int32, valid (R,) bool or None)``: every face exactly once among the
        rows where ``valid`` holds, in *any* order, plus padding rows (any ids in
        ``[0, num_vertices)``) where it does not; ``valid`` None means every row is a face.

        For whole-mesh sums (:func:`jaxcds.algorithms.vertex_normals`) that do not care about face
        ids: a structure whose faces live in slots with holes (LR's redundant T2 slots, the CDS
        face map's unused slots) answers here without compacting the slots into the dense face
        order. The default is :meth:`face_vertices` itself."""
        return self.face_vertices(), None

    def __repr__(self) -> str:  # short: printing arrays of millions of ids helps nobody
        return (f"{type(self).__name__}(num_vertices={self.num_vertices}, "
                f"num_faces={self.num_faces}, references={self.references})")


_chunk_queries(MeshStructure)
_jit_whole_mesh(MeshStructure)

SUM_BLOCKS = 16


#: XLA:CPU leaves a loop over fewer elements than this on one thread (measured on 2 cores for a
#: pointer-jumping round: 65,001 entries unsplit, 70,001 split in two), so shorter arrays are never
#: padded for the split (:func:`split_padding`)
SPLIT_MIN = 32_768


def split_multiple() -> int:
    """How many parts XLA:CPU may split a long elementwise loop into: the CPUs this process may
    run on (XLA sizes its thread pool so)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # not Linux
        return max(1, os.cpu_count() or 1)


def split_padding(length: int) -> int:
    """Entries to append to an array of ``length`` so that the thread count divides it.

    XLA:CPU splits a long loop over its threads and, when the parts are unequal, emits a scalar
    loop instead of the 8-wide one; a select on a gathered value then becomes a branch,
    mispredicted wherever the selection has no pattern (HLO and LLVM IR of one pointer-jumping
    round, 2026-12-01: 129,729 entries in two parts gave no vector instruction and seven
    branches, 129,730 the vector loop). Used by the CDS all-targets pointer jumping
    (``cds.pointer_jump``), whose selection pattern (the pending entries) is irregular. Tried
    and not kept for the rows of the scatter normals (odd for LR and open meshes): their mask is
    nearly all true, and the padding copy cost LR 0.04-0.28x the face list in one-process races
    (``benchmarks/race_split_padding.py``, 2026-12-01). Short arrays (under :data:`SPLIT_MIN`)
    and divisible lengths get none: padding those only costs a copy."""
    return (-length) % split_multiple() if length >= SPLIT_MIN else 0


def interleave_rows(x, blocks: int = SUM_BLOCKS):
    """Rows of ``x`` reordered ``0, n/b, 2n/b, ..., 1, n/b + 1, ...`` (``b = blocks`` contiguous
    blocks read in turn; the ``n mod b`` last rows stay last), for the rows of
    :meth:`MeshStructure.face_vertices_padded`, whose order is free.

    Why: a structure's slot rows come in its own order (LR's ring order, the CDS slots in vertex
    order), where consecutive rows often share a vertex (a fan of T1s around one apex, Sec. 4.2
    of the LR paper; siblings of one red parent in cwBFS order). Summed by a scatter-add, a run of
    one vertex is a chain of dependent read-modify-writes on one address. Measured with
    ``normals.corner_sums``: armadillo LR normals 55 -> 27 ns per vertex, CDS 10-30% faster;
    each block is still read sequentially."""
    # one window of the whole block-divisible head: depth = blocks rows, stride = n // blocks
    return interleave_windows(x, blocks, x.shape[0] // blocks) if x.shape[0] >= blocks else x


def interleave_windows(x, depth: int = 8, stride: int = 8):
    """Rows of ``x`` reordered inside consecutive windows of ``depth * stride`` rows: window rows
    ``0, s, 2s, ..., 1, s + 1, ...`` (``s = stride``; the last ``n mod (depth * stride)`` rows stay
    last). Consecutive output rows were ``stride`` apart, so a run of one apex (see
    :func:`interleave_rows`) no longer chains its scatter-adds, while the rows stay where they
    were to within one window: the sums keep the input's locality.

    For very large row sets whose order is local (a packed batch, mesh by mesh), where each of
    :func:`interleave_rows`'s blocks streams another part of the positions and sums: packed LR
    normals of 3,000 random meshes (8.2M vertices) 1.21x the face list with windows of 8 x 8 and
    each ring vertex's two slot rows side by side, against 1.36x with 8 blocks
    (``benchmarks/RESULTS.md``, "Packed batches at 10,000 meshes")."""
    w = depth * stride
    n = x.shape[0] - x.shape[0] % w
    if n == 0:
        return x
    head = jnp.swapaxes(x[:n].reshape((n // w, depth, stride) + x.shape[1:]), 1, 2)
    head = head.reshape((n,) + x.shape[1:])
    return jnp.concatenate([head, x[n:]]) if n < x.shape[0] else head


def materialize_loop(xs):
    """``xs`` (a tuple of integer arrays of one shape), unchanged, each written once to memory as
    the state of a ``while_loop`` that runs once.

    Why: XLA:CPU fuses a producer into every consumer and re-evaluates it per consumer element,
    table gathers included (``optimization_barrier`` is expanded away before fusion and does not
    stop it): the CDS Thm 6 targets fused into the face assembly's gathers cost 2-3x the targets
    themselves, and the packed LR decode fused into the interleaved rows re-ran per column. The
    values a ``while_loop`` carries live in buffers, so XLA computes each of ``xs`` in one pass
    and its consumers read it. The trip count is read from the data
    (``min(xs[0][0], 0) + 1``: 1 for the non-negative ids passed here, 0 or less otherwise, same
    result), so XLA cannot unroll the loop away, and the body rewrites the first element of every
    value (unchanged, by a ``where`` on the counter: an O(1) body) so the values are not hoisted
    out as loop invariants. Measured on the CDS5n-O(1) batched Target (1M queries, 1M
    vertices): 16 ns per query with it, 26 without. It replaced the other materialisation point,
    an identity scatter of the stacked columns (a scatter is never fused with its updates), which
    was slower: the stacked ``(m, k)`` concatenate is slow under XLA:CPU's fusion emitters, and the
    packed LR normals at 10,000 meshes read 1.82x / 2.07x (lr / lr-bits) the face list with it
    against 1.42x / 1.51x with this loop (2026-12-01). Integer structure
    data only: ``while_loop`` has no reverse-mode derivative (the values here never depend on
    positions).

    Traced as a nested ``jit`` named ``materialize_loop``, so a reader of the program (and
    ``tests/structures/test_cds_paper.py``, which checks that the O(1) operators have no loop)
    can tell this one-trip loop from a navigation loop."""
    xs = tuple(xs)
    if not xs or xs[0].size == 0:
        return xs
    return _loop_once(xs)


@jax.jit
def _loop_once(xs):
    trips = jnp.minimum(xs[0].reshape(-1)[0], 0) + 1

    def body(state):
        k, *vals = state
        # one element touched per trip: O(1) body, yet the values are not loop invariants
        return (k + 1,) + tuple(_touch_first(v, k < 0) for v in vals)

    out = jax.lax.while_loop(lambda state: state[0] < trips, body, (jnp.int32(0),) + xs)
    return tuple(out[1:])


#: under this many vertices the CDS5n-O(1) whole-mesh Targets compute their first reads inside
#: a one-trip loop on CPU (:func:`computed_in_loop`; ``cds.CDS5nO1._targets_cols``: faster up to 7K
#: vertices, level or slower from 20K); read at trace time
IN_LOOP_MAX_VERTICES = 16_384


def computed_in_loop(fn, *xs):
    """``fn(*xs)`` (integer arrays in, a tuple of integer arrays out), computed in the body of a
    ``while_loop`` that runs once, and written to memory as its state (as :func:`materialize_loop`).

    Why: XLA:CPU decides how many threads run each kernel from a cost model of the entry
    computation (``ParallelTaskAssigner``: a kernel with more flops than bytes is split once its
    cost passes "100 us of work on a 2 GHz core", an estimate far above its real time for a few
    thousand elements); a kernel in a loop body is split by its output size only (256 KB per
    thread), since the cost analysis covers the entry computation only (XLA's
    ``parallel_task_assignment.cc``). On this 2-core VM a split kernel waits for the second
    thread: a CDS5n-O(1) Target plan over 3,485 entries took 95 us split against 16 us for a
    like kernel unsplit (profiler trace, bunny, 2026-12-02). Used under
    :data:`IN_LOOP_MAX_VERTICES` vertices.

    ``xs`` are offset by the loop counter (0 on the one trip) inside the body, so XLA cannot hoist
    ``fn`` out as a loop invariant; the trip count, always 1, is read from the data as in
    :func:`materialize_loop`. Integer arrays only (no reverse-mode derivative)."""
    def computed_in_loop(*xs):  # a nested jit of this name: readers can tell it from navigation
        # 1 for every value, but read from the data (XLA cannot unroll the loop away); unlike
        # materialize_loop's count, a negative first element (a packed reference with bit 31
        # set) must still give one trip: the loop's initial state is zeros, not the values
        trips = jnp.minimum(xs[0].reshape(-1)[0].astype(jnp.int32) & 0x7FFFFFFF, 0) + 1
        shapes = jax.eval_shape(fn, *xs)

        def body(state):
            k, _ = state
            return k + 1, tuple(fn(*(x + k.astype(x.dtype) for x in xs)))

        init = tuple(jnp.zeros(sh.shape, sh.dtype) for sh in shapes)
        return jax.lax.while_loop(lambda state: state[0] < trips, body, (jnp.int32(0), init))[1]

    return jax.jit(computed_in_loop)(*xs)


def _touch_first(v, cond):
    flat = v.reshape(-1)
    return flat.at[0].set(jnp.where(cond, flat[0] + 1, flat[0])).reshape(v.shape)


_loop_once.__wrapped__.__name__ = "materialize_loop"


def parts_of_one_class(cls, parts) -> list:
    """``list(parts)`` for a class's ``concatenate(parts)`` (packed batches, :mod:`jaxcds.batch`),
    after checking that there is at least one part and that every part is a ``cls``.

    Raises:
      EmptyMeshError: no parts. UnsupportedTopologyError: a part of another class.
    """
    parts = list(parts)
    if not parts:
        raise errors.EmptyMeshError("concatenate: no structures given")
    for i, p in enumerate(parts):
        if type(p) is not cls:
            raise errors.UnsupportedTopologyError(
                f"{cls.__name__}.concatenate: part {i} is a {type(p).__name__}; pack one structure kind "
                "(a packed batch cannot be packed again)")
    return parts
