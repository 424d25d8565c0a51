"""Sharding a structure and its queries across devices with JAX's own SPMD partitioner.

Nothing here distributes work by hand: the structure's arrays and the query batch are placed on
a :class:`jax.sharding.Mesh` with :class:`~jax.sharding.NamedSharding` (split along their first
axis, ``PartitionSpec(axis)``), and the ordinary jitted operators and reductions run on them;
XLA's partitioner inserts the collectives. For a gather ``table[ids]`` with both sides sharded it
all-gathers the *ids* (not the table), gathers locally with a mask and all-reduces the answers, so
no device ever holds more than ``1/D`` of the structure (checked in ``tests/test_sharding.py``).

JAX only shards an axis that the device count divides, so every array is padded at its end to a
multiple of ``D`` (with ``PAD``, an id no structure stores). Padding must not change what the
structure means, so the padded structure is wrapped in :class:`ShardedStructure`, which keeps the
logical ``num_darts`` and refuses padded darts in ``dart_valid`` (every operator on a valid id
reads only unpadded entries; reductions over the dart space skip the rest).

Memory per device for an ``n``-vertex closed mesh: ``4 * R / D`` bytes of structure (``R`` the
structure's references: 19n half-edge, 13n corner table, 6n CDS6n...) plus ``4 * Q`` bytes of
query ids and answers during a query (the all-gathered batch) and ``12 n / D`` of positions when
they are sharded too.
"""

from __future__ import annotations

from typing import Any, Optional, Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from jaxcds import errors
from jaxcds._arrays import native_order, to_device
from jaxcds._args import number_array, refuse_non_real
from jaxcds._dataclass import pytree_dataclass, replace, static_field
from jaxcds.structures.base import Int, MeshStructure, integer_array, one_pass_queries

__all__ = ["device_mesh", "ShardedStructure", "shard_structure", "shard_rows", "sharded_query",
           "sharded_vertex_normals", "PAD"]

#: padding value of structure arrays: far outside every id space, small enough that the
#: arithmetic of the operators (``3 * (c // 3)``...) cannot overflow int32
PAD = 1 << 29


def device_mesh(devices: Optional[Sequence] = None, axis: str = "d") -> Mesh:
    """A one-axis :class:`~jax.sharding.Mesh` over ``devices`` (all devices by default).

    Raises:
      ArgumentError: no device, or a device listed twice (JAX builds such a Mesh, and the
        entry points then failed untyped: a modulo by a zero device count, a zip of mismatched
        lengths), or ``devices`` are not jax devices (``"cpu"`` raised an AttributeError)."""
    if isinstance(devices, (str, bytes)) or (devices is not None and not hasattr(devices, "__iter__")):
        raise errors.ArgumentError(f"device_mesh: devices must be a list of jax devices (e.g. "
                                   f"jax.devices('cpu')), got {type(devices).__name__} {devices!r}")
    try:  # a list or an array raised TypeError 'unhashable type' from jax's Mesh
        hash(axis)
    except TypeError:
        raise errors.ArgumentError(f"device_mesh: axis must be a name (a str), got {type(axis).__name__}") from None
    devs = list(jax.devices() if devices is None else devices)
    bad = [d for d in devs if not isinstance(d, jax.Device)]
    if bad:
        raise errors.ArgumentError(f"device_mesh: devices must be jax devices (e.g. jax.devices('cpu')), "
                                   f"got {type(bad[0]).__name__} {bad[0]!r}")
    _check_devices(devs, "device_mesh")
    return Mesh(np.array(devs), (axis,))


def _check_devices(devs: Sequence, where: str) -> None:
    if not devs:
        raise errors.ArgumentError(f"{where}: no devices; give at least one (None: all devices)")
    if len(set(devs)) != len(devs):
        raise errors.ArgumentError(f"{where}: a device is listed twice ({len(devs)} entries, "
                                   f"{len(set(devs))} distinct devices)")


def _row_sharding(mesh: Mesh, ndim: int) -> NamedSharding:
    axis = mesh.axis_names[0]
    return NamedSharding(mesh, PartitionSpec(axis, *([None] * (ndim - 1))))


def _pad_rows(x: np.ndarray, multiple: int, value) -> np.ndarray:
    n = x.shape[0]
    extra = (-n) % multiple
    if not extra:
        return x
    pad = np.full((extra,) + x.shape[1:], value, dtype=x.dtype)
    return np.concatenate([x, pad])


def _mesh_arg(mesh, where: str) -> Mesh:
    """``mesh``, or all devices for ``None``; anything else an ArgumentError (it had been an
    AttributeError on ``mesh.devices``)."""
    if mesh is None:
        return device_mesh()
    if not isinstance(mesh, Mesh):
        raise errors.ArgumentError(f"{where}: mesh must be a jax.sharding.Mesh (device_mesh(), or "
                                   f"None for all devices), got {type(mesh).__name__}")
    _check_devices(list(mesh.devices.flat), where)
    return mesh


def _structure_mesh(s) -> Optional[Mesh]:
    """The mesh ``s``'s arrays were placed on by :func:`shard_structure` (its first named-sharded
    leaf's), or None for a structure that was not sharded."""
    for x in jax.tree_util.tree_leaves(s):
        sharding = getattr(x, "sharding", None)
        if isinstance(sharding, NamedSharding):
            return sharding.mesh
    return None


def _same_devices(a: Mesh, b: Mesh) -> bool:
    """The same devices in the same order (what a jitted call with arrays placed on both takes;
    the same devices in another order are "incompatible" to JAX)."""
    return list(a.devices.flat) == list(b.devices.flat)


def _on_mesh(x: jax.Array, mesh: Mesh) -> bool:
    """``x`` is placed on ``mesh``'s devices in ``mesh``'s order (:func:`_same_devices`)."""
    return isinstance(x.sharding, NamedSharding) and _same_devices(x.sharding.mesh, mesh)


def _is_numeric(dtype) -> bool:
    """The dtypes JAX holds: booleans, integers, floats (bfloat16 too), complex numbers."""
    return bool(jnp.issubdtype(dtype, jnp.number) or jnp.issubdtype(dtype, jnp.bool_))


def _host_rows(x, where: str) -> np.ndarray:
    """``x`` as a numpy array of a dtype JAX holds (booleans, integers, floats, complex numbers),
    in native byte order (read by value: JAX refuses big-endian arrays), or
    :class:`~jaxcds.errors.ArgumentError` naming ``where``: ragged nested lists, masked arrays
    (the mask would be dropped), strings, objects, dates, records (JAX's TypeError "not a valid
    JAX array type" before). :func:`~jaxcds._args.number_array` checks."""
    a = number_array(x, where, error=errors.ArgumentError, bools=True, complex_ok=True)
    return native_order(np.asarray(a))


def _fill_value(value, dtype: np.dtype, where: str):
    """``value`` as a scalar of ``dtype`` if it is a number that ``dtype`` holds (any real for a
    floating dtype; exactly for integers and booleans: 1.5 or 1000 in int8 were truncated or
    wrapped), else :class:`~jaxcds.errors.ArgumentError`."""
    try:
        v = np.asarray(value)
    except (TypeError, ValueError):
        v = np.asarray(None)
    ok = v.ndim == 0 and _is_numeric(v.dtype)
    if ok and jnp.issubdtype(v.dtype, jnp.complexfloating) and not jnp.issubdtype(
            dtype, jnp.complexfloating):
        ok, v = bool(v.imag == 0), v.real  # 1j in a float array lost its imaginary part
    if ok:
        with np.errstate(all="ignore"):
            cast = v.astype(dtype)
        if not jnp.issubdtype(dtype, jnp.inexact):
            ok = bool(cast == v)
    if not ok:
        raise errors.ArgumentError(f"{where}: the padding value {value!r} is not a number that "
                                   f"dtype {dtype} holds exactly")
    return cast


def shard_rows(x, mesh: Optional[Mesh], value=0) -> jax.Array:
    """``x`` padded along axis 0 to a multiple of the device count (with ``value``) and placed
    with ``NamedSharding(mesh, P(axis))``: each device holds ``ceil(len / D)`` rows. ``mesh``
    ``None``: all devices (:func:`device_mesh`). ``x`` is read by value (big-endian arrays,
    lists); 64-bit dtypes become 32-bit ones unless x64 is on, as ``jnp.asarray`` does.

    Raises:
      ArgumentError: ``x`` 0-d, ragged, masked, or not numeric (strings, objects...), or 64-bit
        integers past the 32-bit dtype JAX holds them in (x64 off); ``value`` a number that dtype
        does not hold; ``mesh`` not a Mesh."""
    mesh = _mesh_arg(mesh, "shard_rows")
    x = _host_rows(x, "shard_rows: rows x")
    if x.ndim == 0:  # _pad_rows read shape[0]: IndexError
        raise errors.ArgumentError("shard_rows: a 0-d value has no rows to split; give an array "
                                   "of at least one axis (or device_put it replicated)")
    dt = np.dtype(jax.dtypes.canonicalize_dtype(x.dtype))
    if dt != x.dtype and x.dtype.kind in "iu" and x.size:  # device_put wrapped 2^40 to 0
        info = np.iinfo(dt)
        wide = (x > info.max) if x.dtype.kind == "u" else (x < info.min) | (x > info.max)
        if np.any(wide):
            i = int(np.argmax(np.ravel(wide)))
            raise errors.ArgumentError(
                f"shard_rows: x's value {np.ravel(x)[i]} at flat position {i} does not fit {dt}, "
                f"the dtype JAX holds {x.dtype} in (enable jax_enable_x64 for 64-bit values)")
    fill = _fill_value(value, dt, "shard_rows")
    a = np.asarray(x, dt)
    out = _pad_rows(a, mesh.devices.size, fill)
    if out is a:  # the caller's array (no padding): device_put may share its buffer on CPU
        out = np.array(a, order="C", copy=True)
    return jax.device_put(out, _row_sharding(mesh, x.ndim))


@pytree_dataclass
class ShardedStructure(MeshStructure):
    """A structure whose arrays are padded to a multiple of the device count and sharded.

    Fields:
      structure: the padded structure (same class as the input; its arrays are sharded).
      order: always ``None`` (kept for compatibility): a structure that renumbers vertices holds
        its ``order`` as one of its own leaves (CDS4n, CDS5n-O(1), LR, pemb), row-sharded with
        the rest; :attr:`vertex_order` reads it and slices the padding off. It used to be a
        second, replicated copy: ``4 n`` bytes on every device for host-side metadata.
      num_vertices, num_faces: the input structure's sizes (static, unpadded).
      logical_darts: the input structure's ``num_darts`` (darts past it are padding).
      logical_references: the input structure's ``references``.
      num_devices: devices of the mesh the arrays are sharded over.
      leaf_rows: the unpadded length of every leaf of ``structure`` (flatten order; ``-1`` for
        a 0-d leaf), so :meth:`unpadded` can cut the padding off inside a jitted function.
    """

    structure: Any
    order: Any
    num_vertices: int = static_field()
    num_faces: int = static_field()
    logical_darts: int = static_field()
    logical_references: int = static_field()
    num_devices: int = static_field()
    leaf_rows: tuple = static_field(default=())

    name = "sharded"

    @property
    def num_darts(self) -> int:
        return self.logical_darts

    @property
    def references(self) -> int:
        return self.logical_references

    @property
    def vertex_order(self):
        order = self.structure.vertex_order if self.order is None else np.asarray(self.order)
        return None if order is None else np.asarray(order)[: self.num_vertices]

    @property
    def closed_triangles(self) -> bool:  # type: ignore[override]
        return type(self.structure).closed_triangles

    def dart_valid(self, e: Int) -> Int:
        return (e >= 0) & (e < self.logical_darts) & self.structure.dart_valid(e)

    def unpadded(self):
        """The input structure again, its arrays the padded ones sliced to their logical length
        (inside ``jit`` the slices stay partitioned: XLA shards uneven shapes itself)."""
        leaves, treedef = jax.tree_util.tree_flatten(self.structure)
        if len(self.leaf_rows) != len(leaves):
            raise ValueError("ShardedStructure without leaf_rows: build it with shard_structure")
        return jax.tree_util.tree_unflatten(
            treedef, [x if r < 0 else x[:r] for x, r in zip(leaves, self.leaf_rows)])

    def face_vertices(self) -> Int:
        """The structure's own ``face_vertices`` (the CDS face map of Thm 7, the half-edge's
        reshape...) on the :meth:`unpadded` arrays. Those fast routes read whole arrays, which
        padding has lengthened; the protocol's generic route (``edge_of_face``, ``next``,
        ``origin`` per face) gives the same faces but costs a navigation per corner (a CDS
        ``next`` is a ``LeftFront`` and a ``Target``: the sharded CDS normals were 60x slower)."""
        return self.unpadded().face_vertices()

    def face_vertices_padded(self):
        """The structure's own ``face_vertices_padded`` on the :meth:`unpadded` arrays (as
        :meth:`face_vertices`: the padded arrays would add rows that are not faces)."""
        return self.unpadded().face_vertices_padded()

    def dummy_vertex_mask(self):
        """The structure's own mask, from the :meth:`unpadded` arrays (sized ``num_vertices``)."""
        return self.unpadded().dummy_vertex_mask()

    @property
    def table_queries(self) -> dict:
        """The input structure's table routes (``MeshStructure.table_queries``), so that
        :func:`jaxcds.verify.verify` checks both routes of each on a sharded structure too (it
        read the class's empty dict and checked one route only)."""
        return self.structure.table_queries

    def takes_table(self, op: str, batch_size: int) -> bool:
        """As the input structure decides (the sharded operators forward to its routes)."""
        return self.structure.takes_table(op, batch_size)

    def __getattr__(self, attr):
        if attr.startswith("__") or attr == "structure":
            raise AttributeError(attr)
        if attr in _WHOLE_MESH_ROUTES or attr in self.structure.table_queries.values():
            # these read whole arrays (a CDS's degrees: its n rows): on the padded ones their
            # shapes disagreed with num_vertices (an uneven split crashed); so does a table
            # route (every dart's answer, then one gather), which verify calls by its name
            return getattr(self.unpadded(), attr)
        if attr == "adjacent":
            return self._adjacent(getattr(self.structure, attr))
        return getattr(self.structure, attr)

    def _adjacent(self, padded_adjacent):
        """The structure's own ``adjacent``; a batch large enough for its whole-mesh Target
        table (CDS6n/5n/4n: ``n / 16`` pairs, ``adjacent_takes_table``) on the unpadded arrays,
        as :func:`_forward`'s table routes: on the padded ones the table's pointer jumping never
        ended (a 45-vertex CDS4n over 4 devices hung on one pair, padded to 4), sweep 48b."""
        takes_table = getattr(self.structure, "adjacent_takes_table", None)

        def adjacent(u, v):
            size = max(_batch_seen(self.structure, u), _batch_seen(self.structure, v))
            if takes_table is not None and takes_table(size):
                return self.unpadded().adjacent(u, v)
            return padded_adjacent(u, v)

        return adjacent


#: a structure's own whole-mesh routes that generic code looks up by name; a sharded structure
#: runs them on its unpadded arrays (like face_vertices above)
_WHOLE_MESH_ROUTES = frozenset({"vertex_degrees", "all_edge_targets", "target_table"})


def _batch_seen(inner, x) -> int:
    """The batch ``inner``'s operators see for a call on ``x`` (``base.eager_batch_size``: an
    eager call runs bucketed to the next power of two, and its table routes decide on that
    size; sweep 48b: 100 eager Targets of a 301-vertex CDS4n over 4 devices, bucketed to 128,
    took the table on the padded arrays: 32 wrong)."""
    from jaxcds.structures.base import eager_batch_size

    return eager_batch_size(inner, (x,))


def _forward(op):
    def method(self, x):
        inner = self.structure
        size = _batch_seen(inner, x)
        if any(inner.takes_table(t, size) for t in inner.table_queries):
            # a whole-mesh table route (CDS Target / Origin from every edge's target, a batch
            # of 1/16 of the darts or more) reads whole arrays, as _WHOLE_MESH_ROUTES do: on
            # the padded ones 70 of 240 targets of a sharded CDS6n icosphere were wrong (PAD
            # read as a vertex; verify, one_ring), sweep 16a. Any operator of a batch that
            # large: one that is no table operator itself may call one (CDS Source and
            # Corner_vertex call Origin), whose table on the padded arrays read padding as
            # targets or never ended its pointer jumping (sweep 48: a 45-vertex CDS4n hung)
            return getattr(self.unpadded(), op)(x)
        return getattr(inner, op)(x)

    method.__name__ = op
    return method


for _op in ("origin", "source", "target", "twin", "next", "prev", "face", "face_left",
            "face_right", "is_border", "edge_of_vertex", "edge_of_face", "left_front", "left_back",
            "right_front", "right_back", "ccw_vertex_edge", "cw_vertex_edge", "corner_vertex",
            "corner_next", "corner_prev", "corner_opposite", "corner_swing"):
    setattr(ShardedStructure, _op, _forward(_op))
# face_vertices: see ShardedStructure.face_vertices (the unpadded view)


def shard_structure(s: MeshStructure, mesh: Optional[Mesh] = None):
    """Every array of ``s`` padded to a multiple of the device count and split along its first
    axis over ``mesh`` (``NamedSharding(mesh, P(axis))``); 0-d leaves are replicated.

    Works for any structure whose sizes are static fields or array lengths and whose operators
    read, for a valid id, only entries of the unpadded arrays (true of every structure in the
    registry but pemb: padding lies past every id they store). A :class:`jaxcds.batch.PackedBatch`
    keeps its per-mesh tables replicated and gets its union structure sharded.

    Raises:
      UnsupportedTopologyError: a class that names why its arrays cannot be split by rows
        (``row_sharding_refused``: pemb, whose bit vectors read their own lengths)."""
    from jaxcds.batch import PackedBatch

    if isinstance(s, ShardedStructure) or (isinstance(s, PackedBatch)
                                           and isinstance(s.structure, ShardedStructure)):
        raise errors.ArgumentError("shard_structure: this structure is sharded already (its "
                                   "arrays padded); shard the original structure")
    if not isinstance(s, MeshStructure):  # a TriMesh, None...: AttributeError / TypeError deep in
        raise errors.ArgumentError(f"shard_structure: expected a structure (jaxcds.build(name, mesh) "
                                   f"or a packed batch), got {type(s).__name__}")
    mesh = _mesh_arg(mesh, "shard_structure")
    d = int(mesh.devices.size)

    if getattr(s, "row_sharding_refused", None):
        raise errors.UnsupportedTopologyError(s.row_sharding_refused)

    if isinstance(s, PackedBatch):
        # the union structure is split; the per-mesh tables (B entries) are replicated
        rep = NamedSharding(mesh, PartitionSpec())
        tables = {f: jax.device_put(getattr(s, f), rep) for f in (
            "n_vertex", "n_face", "n_dart", "n_extra_dart", "vertex_offsets", "face_offsets",
            "dart_offsets", "extra_dart_offsets")}
        return replace(s, structure=shard_structure(s.structure, mesh), **tables)
    def place(x):
        x = np.asarray(x)
        if x.ndim == 0:
            return jax.device_put(x, NamedSharding(mesh, PartitionSpec()))
        # integer leaves are padded past every id (narrow ones, e.g. lr-bits' int16 fields,
        # with their largest value); others with 0
        fill = min(PAD, int(np.iinfo(x.dtype).max)) if x.dtype.kind in "iu" else 0
        return jax.device_put(_pad_rows(x, d, fill), _row_sharding(mesh, x.ndim))

    padded = jax.tree_util.tree_map(place, s)
    return ShardedStructure(
        structure=padded,
        order=None,
        num_vertices=s.num_vertices, num_faces=s.num_faces, logical_darts=s.num_darts,
        logical_references=s.references, num_devices=d,
        leaf_rows=tuple(-1 if np.ndim(x) == 0 else int(np.shape(x)[0])
                        for x in jax.tree_util.tree_leaves(s)))


def sharded_query(s: ShardedStructure, op: str, ids, mesh: Optional[Mesh] = None) -> jax.Array:
    """Operator ``op`` on a batch of ``ids``, the batch split over the devices like the
    structure (padded with id 0, the padding answers dropped). Equal to ``getattr(s, op)(ids)``
    unsharded. Answers are left sharded (``P(axis)``). ``mesh`` ``None``: the mesh ``s`` was
    sharded over (all devices for a structure that was not).

    Raises:
      ArgumentError: ``mesh`` holds other devices than the ones ``s`` was sharded over (the
        jitted query failed with JAX's untyped "incompatible devices"; a structure sharded
        over 3 of 4 devices met that with the default mesh of all 4)."""
    from jaxcds.batch import OPERATOR_KINDS

    if not isinstance(s, MeshStructure):  # AttributeError inside jit before
        raise errors.ArgumentError(f"sharded_query: expected a structure (shard_structure(jaxcds."
                                   f"build(name, mesh))), got {type(s).__name__}")
    if not isinstance(op, str) or op not in OPERATOR_KINDS:
        raise errors.ArgumentError(f"sharded_query: unknown operator {op!r}; one of {sorted(OPERATOR_KINDS)}")
    own = _structure_mesh(s)
    mesh = own if mesh is None and own is not None else _mesh_arg(mesh, "sharded_query")
    if own is not None and not _same_devices(own, mesh):
        raise errors.ArgumentError(
            f"sharded_query: the structure is sharded over {own.devices.size} device(s), the "
            f"mesh given holds {mesh.devices.size}, not the same ones in the same order; pass "
            f"the mesh given to shard_structure (or None)")
    ids = _int32_ids(ids, op)
    if ids.ndim == 0:  # one id: a batch of one (shard_rows has no rows to split in a 0-d id)
        return sharded_query(s, op, ids.reshape(1), mesh)[0]
    q = shard_rows(ids, mesh, value=0)
    out = _query(s, q, op)
    return out[: ids.shape[0]]


def _int32_ids(ids, op: str) -> np.ndarray:
    """``ids`` as int32, or :class:`~jaxcds.errors.InvalidIndexError` for non-integers and
    values int32 cannot hold (a cast would truncate 1.7 to 1 or wrap 2^63 silently)."""
    a = integer_array(ids, f"sharded_query({op!r}): ids")
    info = np.iinfo(np.int32)
    wide = (a > info.max) if a.dtype.kind == "u" else (a < info.min) | (a > info.max)
    if np.any(wide):
        i = int(np.argmax(np.ravel(wide)))
        raise errors.InvalidIndexError(
            f"sharded_query({op!r}): id {np.ravel(a)[i]} at flat position {i} does not fit int32")
    return a.astype(np.int32)


def _query_impl(s, q, op):
    # one pass: chunks (base._chunked_query) along the sharded axis would gather the batch
    with one_pass_queries():
        return getattr(s, op)(q)


_query = jax.jit(_query_impl, static_argnums=2)


def sharded_vertex_normals(s: ShardedStructure, positions, method: str = "scatter"):
    """:func:`jaxcds.algorithms.vertex_normals` on a sharded structure; ``positions`` may be
    replicated or sharded (``shard_rows`` pads them; the padding rows are sliced off before the
    call). Per-vertex sums run as a partitioned ``segment_sum`` (an all-reduce of the sums)."""
    from jaxcds.algorithms import vertex_normals
    from jaxcds.batch import PackedBatch

    inner = s.structure if isinstance(s, PackedBatch) else s
    if not isinstance(inner, ShardedStructure):  # AttributeError on num_devices before
        what = (f"an unsharded {getattr(s, 'name', type(s).__name__)}: shard it with "
                "shard_structure(s, mesh) first (or call vertex_normals)"
                if isinstance(s, MeshStructure) else type(s).__name__)
        raise errors.ArgumentError(f"sharded_vertex_normals: expected a structure from "
                                   f"shard_structure, got {what}")
    refuse_non_real(positions, "sharded_vertex_normals: positions")
    positions = to_device(positions, copy=True)  # the caller's array: no shared buffer
    own = _structure_mesh(inner)
    if (own is not None and not isinstance(positions, jax.core.Tracer) and positions.committed
            and not _on_mesh(positions, own)):
        # rows placed on other devices (shard_rows with another mesh, device_put): the jitted
        # normals failed with JAX's untyped "incompatible devices"; replicated on the structure's
        positions = jax.device_put(positions, NamedSharding(own, PartitionSpec()))
    n, d = s.num_vertices, s.num_devices
    padded = -(-n // d) * d  # shard_rows' length for n rows
    if positions.ndim != 2 or positions.shape[0] not in (n, padded):
        raise errors.MeshError(
            f"sharded_vertex_normals: positions must have {n} rows (or {padded}, padded by "
            f"shard_rows), got shape {tuple(positions.shape)}")
    p = positions[:n] if positions.shape[0] != n else positions
    return vertex_normals(s, p, method=method)
