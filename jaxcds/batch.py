"""Packed batches: many meshes as ONE structure over their disjoint union.

The convention is jraph's ``GraphsTuple`` and PyTorch3D's *packed* meshes: the arrays of every
mesh are concatenated, ids are shifted so that mesh ``i`` owns a contiguous range of global
vertex, face and dart ids, and per-mesh counts and offsets say which range. Because the result
is an ordinary structure (several connected components are allowed by the navigation
protocol), every operator and every generic algorithm (:func:`jaxcds.algorithms.vertex_normals`,
:func:`~jaxcds.algorithms.vertex_degrees`, :func:`~jaxcds.algorithms.adjacent`) runs on the whole
batch in one jitted call, and gradients flow to the positions of every mesh. This is the
"scene of thousands of small objects" of the CDS paper (Sec. 4.5).

Building (:func:`pack`):

* HalfEdge and CornerTable accept several components, so the batch is built ONCE on the union
  face list (one numba pass for all meshes); the result is id-for-id the concatenation of the
  per-mesh builds (tested).
* Structures that need a connected mesh are built per mesh and joined by the class's
  ``concatenate(parts)`` classmethod. Two ways, decided by the id layout of each paper:

  - *Shift* (CDS6n, CDS5n, CDS4n, CDS5n-O(1); :mod:`jaxcds.structures.cds_packed`): every table
    entry is a vertex id in 30 bits plus service bits (CDS Sec. 2.1), edges are ``3u + c``, so
    mesh ``i``'s ids shifted by its vertex offset keep every formula. The three outer vertices
    and the four unused Thm 7 face slots, static ints of one structure, become per-mesh tables;
    each operator reads them for the mesh of each query element.
  - *Local evaluation* (LR, lr-bits; :mod:`jaxcds.structures.lr_packed`): an LR's ids are its
    ring (``v.n = v + 1 mod m_r``, corners ``8v + i``, T0 corners from ``8 m_r``, lr-bits'
    offsets mod ``m_r``, LR Sec. 4.2/4.7/6.1), and a union of rings is not a ring, so nothing is
    shifted: arrays are concatenated as they are and each operator runs on the mesh-local ids of
    each element, answers mapped back to global ids.

  - *Concatenated walks* (pemb; :mod:`jaxcds.structures.pemb_packed`): the bit vectors ``A``
    and the balanced sequences ``B``, ``B*`` of the meshes are concatenated; balanced blocks keep
    every ``match`` and ``enclose`` inside their mesh, a dart is its position in ``A``, and only
    each mesh's roots (tree root, root face: no parenthesis pair) and the wrap of its walk are
    read from per-mesh tables.

  A class without ``concatenate`` is refused with :class:`UnsupportedTopologyError`
  (:data:`REFUSED` names structures refused with a reason; none at present). :func:`shift_ids` / :func:`shift_darts` are the helpers
  for id-valued fields of a shifted layout.

Dart blocks. Most structures number the darts of a mesh contiguously, but the HalfEdge puts its
border darts after all inner darts (``3F ... 3F + B - 1``), which must stay true of the union.
So a mesh's dart range is split into a *primary* block ``[0, P_i)`` (a structure's
``num_primary_darts`` attribute; ``num_darts`` when absent) mapped to
``dart_offsets[i] + d``, and an *extra* block ``[P_i, P_i + X_i)`` mapped after every primary
dart, to ``sum(P) + extra_dart_offsets[i] + (d - P_i)``. For a closed mesh the extra block is
empty and a dart id is simply ``dart_offsets[i] + d``.

On CPU, normals of a batch of several chunks are summed chunk by chunk (:meth:`PackedBatch.normal_sums`:
a loop over groups of whole meshes whose temporaries stay in cache; the plan, :func:`chunk_plan`,
is made here on the host), the rows still derived once by the union structure.

Absent ids ("one past the end") map to one past the end: a border dart's face ``n_face[i]`` in
mesh ``i`` is ``num_faces`` in the batch, and back.
"""

from __future__ import annotations

from typing import Any, Optional, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from jaxcds import errors
from jaxcds._arrays import to_device, traced_for_cpu
from jaxcds._args import flag_arg, number_array, refuse_non_real, shown
from jaxcds._dataclass import pytree_dataclass, static_field
from jaxcds.mesh import TriMesh, load_mesh, trusted_faces, validate
from jaxcds.structures.base import Int, MeshStructure, id_arg

__all__ = ["PackedBatch", "pack", "concatenate", "shift_ids", "shift_darts", "OPERATOR_KINDS",
           "pack_positions", "chunk_plan", "chunks_pay_off", "NORMALS_CHUNK_VERTICES"]

#: operator -> (kind of its argument, kind of its result); kinds: dart, vertex, face, bool
OPERATOR_KINDS = {
    **{op: ("dart", "dart") for op in (
        "twin", "next", "prev", "left_front", "left_back", "right_front", "right_back",
        "ccw_vertex_edge", "cw_vertex_edge", "corner_next", "corner_prev", "corner_opposite",
        "corner_swing")},
    **{op: ("dart", "vertex") for op in ("origin", "source", "target", "corner_vertex")},
    **{op: ("dart", "face") for op in ("face", "face_left", "face_right")},
    **{op: ("dart", "bool") for op in ("is_border", "dart_valid")},
    "edge_of_vertex": ("vertex", "dart"),
    "edge_of_face": ("face", "dart"),
}

# protocol methods the batch forwards to its union structure (so a structure's faster
# overrides, e.g. CDS Target in O(1), are the ones that run)
_FORWARDED = tuple(OPERATOR_KINDS) + ("face_vertices", "face_vertices_padded")


@pytree_dataclass
class PackedBatch(MeshStructure):
    """``B`` meshes packed as one structure (jraph ``GraphsTuple`` / PyTorch3D packed layout).

    Fields (``B`` meshes; all ``int32`` arrays of shape ``(B,)``):
      structure: the structure over the disjoint union (HalfEdge, CornerTable, ...): a pytree.
      n_vertex, n_face: vertices and faces of each mesh.
      n_dart: darts of each mesh's primary block (all its darts, except HalfEdge border darts).
      n_extra_dart: darts of each mesh's extra block (HalfEdge border darts; else 0).
      vertex_offsets, face_offsets, dart_offsets, extra_dart_offsets: exclusive cumulative sums
        of the counts: mesh ``i``'s local vertex ``v`` is global ``vertex_offsets[i] + v``.
      num_meshes, num_vertices, num_faces, num_primary_darts: static totals (shapes).

    Every protocol operator takes and returns *global* ids (it is the union structure's);
    :meth:`query` takes ``(mesh, local id)`` pairs and answers with local ids.
    """

    structure: Any
    n_vertex: jnp.ndarray
    n_face: jnp.ndarray
    n_dart: jnp.ndarray
    n_extra_dart: jnp.ndarray
    vertex_offsets: jnp.ndarray
    face_offsets: jnp.ndarray
    dart_offsets: jnp.ndarray
    extra_dart_offsets: jnp.ndarray
    num_meshes: int = static_field()
    num_vertices: int = static_field()
    num_faces: int = static_field()
    num_primary_darts: int = static_field()
    #: the chunk plan of :meth:`normal_sums` (``None``: one pass over the whole union)
    chunk_starts: Any = None
    chunk_caps: tuple = static_field(default=())

    name = "packed"

    # ------------------------------------------------------------------ protocol: forwarded
    @property
    def num_darts(self) -> int:
        return self.structure.num_darts

    @property
    def references(self) -> int:
        return self.structure.references

    @property
    def vertex_order(self) -> Optional[np.ndarray]:
        return self.structure.vertex_order

    @property
    def closed_triangles(self) -> bool:  # type: ignore[override]
        return type(self.structure).closed_triangles

    def dummy_vertex_mask(self):
        """The union structure's mask (each part's dummy vertices, at their global ids)."""
        return self.structure.dummy_vertex_mask()

    def __getattr__(self, attr):
        # structure-specific extras (a fast ``vertex_degrees()``, ``adjacent``...) are the
        # union structure's; guard the dataclass's own fields against recursion while unpickling
        if attr.startswith("__") or attr == "structure":
            raise AttributeError(attr)
        return getattr(self.structure, attr)

    @property
    def num_extra_darts(self) -> int:
        return self.num_darts - self.num_primary_darts

    # ------------------------------------------------------------------ chunked normals
    def normal_sums(self, positions):
        """``(num_vertices, 3)`` area-weighted face normals summed at the corners, computed
        chunk by chunk (a ``fori_loop`` over groups of whole meshes of about
        :data:`NORMALS_CHUNK_VERTICES` vertices), or ``None`` when the batch has no chunk plan
        (one chunk, or a structure without row blocks): then the whole-union route runs.

        Why: over a whole union of millions of vertices every temporary of the sums (the
        ``(F, 3, 3)`` corner positions, the face normals, the accumulator) is a fresh buffer
        of tens of bytes per vertex, paged in on every call and read back from memory; a
        chunk's temporaries fit in cache. The face rows are still derived once over the whole
        union (the structure's own route); only their sums are chunked. Measured in
        ``benchmarks/RESULTS.md`` ("stop 39"). Meshes never share a vertex, so a chunk's sums
        are final. Differentiable (the loop has a static trip count).

        On a GPU (the platform the call is traced for, :func:`chunks_pay_off`) the whole-union
        route runs: the loop's trips run one after the other there, each a few small kernels
        and a predicate read back by the host."""
        if self.chunk_starts is None or not _chunkable(self.structure):
            return None  # a sharded union (jaxcds.sharding) takes the partitioned whole route
        if not chunks_pay_off():
            return None
        return _chunked_sums(self, positions)

    # ------------------------------------------------------------------ mesh of each id
    def vertex_mesh(self) -> Int:
        """``(num_vertices,)`` int32: the mesh of every global vertex (jraph's node graph index)."""
        return _segment_ids(self.n_vertex, self.num_vertices)

    def face_mesh(self) -> Int:
        """``(num_faces,)`` int32: the mesh of every global face."""
        return _segment_ids(self.n_face, self.num_faces)

    def dart_mesh(self) -> Int:
        """``(num_darts,)`` int32: the mesh of every global dart (primary darts, then extra)."""
        return jnp.concatenate([_segment_ids(self.n_dart, self.num_primary_darts),
                                _segment_ids(self.n_extra_dart, self.num_extra_darts)])

    def mesh_of(self, kind: str, g: Int) -> Int:
        """Mesh owning global id(s) ``g`` of ``kind`` (``"vertex"``, ``"face"``, ``"dart"``);
        ``num_meshes`` for an absent id (one past the end, or any id out of range: a negative
        one too)."""
        self._check_kind(kind, "mesh_of")
        g = _id_arg(g, "mesh_of: ids")
        if kind == "dart":
            extra = g >= self.num_primary_darts
            m1 = _owner(self.dart_offsets, self.n_dart, g)
            m2 = _owner(self.extra_dart_offsets, self.n_extra_dart, g - self.num_primary_darts)
            m = jnp.where(extra, m2, m1)
            return jnp.where((g < 0) | (g >= self.num_darts), self.num_meshes, m)
        off, cnt, total = self._table(kind)
        return jnp.where((g < 0) | (g >= total), self.num_meshes, _owner(off, cnt, g))

    # ------------------------------------------------------------------ local <-> global
    def to_global(self, kind: str, mesh: Int, local: Int) -> Int:
        """Global id of mesh ``mesh``'s local id ``local`` (``kind``: vertex, face, dart).
        The local sentinel (the mesh's own count) maps to the global one, and so does every id
        out of range: a negative local id, one past the count, a mesh index outside the batch
        (JAX would wrap or clamp them into another mesh's ids), an integer past int32 included
        (a cast would wrap it into range). Broadcasts; floats, strings and shapes that do not
        broadcast are refused (:class:`~jaxcds.errors.InvalidIndexError`, ``ArgumentError``)."""
        self._check_kind(kind, "to_global")
        mesh, local = _id_pair(mesh, local, f"to_global({kind!r})")
        out = (local < 0) | (mesh < 0) | (mesh >= self.num_meshes)
        mesh = jnp.clip(mesh, 0, max(self.num_meshes - 1, 0))
        if kind == "dart" and self.num_extra_darts == 0:  # static: one contiguous block per mesh
            return jnp.where(out | (local >= self.n_dart[mesh]), self.num_darts,
                             self.dart_offsets[mesh] + local).astype(jnp.int32)
        if kind == "dart":
            p = self.n_dart[mesh]
            primary = self.dart_offsets[mesh] + local
            extra = self.num_primary_darts + self.extra_dart_offsets[mesh] + (local - p)
            g = jnp.where(local < p, primary, extra)
            return jnp.where(out | (local >= p + self.n_extra_dart[mesh]), self.num_darts,
                             g).astype(jnp.int32)
        off, cnt, total = self._table(kind)
        return jnp.where(out | (local >= cnt[mesh]), total, off[mesh] + local).astype(jnp.int32)

    def to_local(self, kind: str, mesh: Int, g: Int) -> Int:
        """Local id in mesh ``mesh`` of global id ``g``; the global sentinel maps to the mesh's
        own count (its one past the end). ``mesh`` must own ``g`` (see :meth:`mesh_of`); a mesh
        index outside the batch reads as the nearest mesh (:meth:`query` sends only the
        sentinel then). Broadcasts; floats, strings and shapes that do not broadcast are refused
        (:class:`~jaxcds.errors.InvalidIndexError`, ``ArgumentError``: a cast read 1.9 as 1)."""
        self._check_kind(kind, "to_local")
        mesh, g = _id_pair(mesh, g, f"to_local({kind!r})")
        mesh = jnp.clip(mesh, 0, max(self.num_meshes - 1, 0))
        if kind == "dart" and self.num_extra_darts == 0:
            return jnp.where(g >= self.num_darts, self.n_dart[mesh], g - self.dart_offsets[mesh])
        if kind == "dart":
            p = self.n_dart[mesh]
            extra = g >= self.num_primary_darts
            local = jnp.where(extra, g - self.num_primary_darts - self.extra_dart_offsets[mesh] + p,
                              g - self.dart_offsets[mesh])
            return jnp.where(g >= self.num_darts, p + self.n_extra_dart[mesh], local)
        off, cnt, total = self._table(kind)
        return jnp.where(g >= total, cnt[mesh], g - off[mesh]).astype(jnp.int32)

    def _table(self, kind: str):
        # a kind that is no str (an array: kind == "vertex" compared elementwise) raised numpy's
        # untyped "truth value of an array is ambiguous" ValueError
        if isinstance(kind, str) and kind == "vertex":
            return self.vertex_offsets, self.n_vertex, self.num_vertices
        if isinstance(kind, str) and kind == "face":
            return self.face_offsets, self.n_face, self.num_faces
        raise errors.ArgumentError(f"unknown id kind {shown(kind)}: 'vertex' or 'face' here "
                                   "('dart' only for mesh_of / to_global / to_local)")

    @staticmethod
    def _check_kind(kind, where: str) -> None:
        """An id kind of :meth:`mesh_of` / :meth:`to_global` / :meth:`to_local` that is no string
        (ids where the kind goes) raised numpy's untyped 'truth value of an array is
        ambiguous' ValueError from ``kind == "dart"``."""
        if not isinstance(kind, str) or kind not in ("vertex", "face", "dart"):
            raise errors.ArgumentError(f"{where}: unknown id kind {shown(kind)}: 'vertex', 'face' or 'dart' "
                                       "(the kind comes first)")

    # ------------------------------------------------------------------ batched local queries
    def query(self, op: str, mesh: Int, local: Int) -> Int:
        """Operator ``op`` (``"target"``, ``"twin"``, ``"face_left"``, ``"edge_of_vertex"``...)
        on mesh-local ids: ``mesh`` and ``local`` broadcast together, the answer is local to the
        same mesh (ids never leave their component). Jittable; ``op`` must be static.

        Raises:
          ArgumentError: an unknown ``op`` (a list raised TypeError: unhashable), ``mesh`` and
            ``local`` that do not broadcast.
          InvalidIndexError: ids that are not integers."""
        if not isinstance(op, str) or op not in OPERATOR_KINDS:
            raise errors.ArgumentError(f"PackedBatch.query: unknown operator {op!r}; one of "
                                       f"{sorted(OPERATOR_KINDS)}")
        arg_kind, res_kind = OPERATOR_KINDS[op]
        mesh, local = _id_pair(mesh, local, f"PackedBatch.query({op!r})")
        g = self.to_global(arg_kind, mesh, local)
        r = getattr(self.structure, op)(g)
        # an id out of range (or a mesh index outside the batch) answers "absent" (False for a
        # test), not what the structure reads one past its arrays
        absent = g >= self._absent(arg_kind)
        if res_kind == "bool":
            return r & ~absent
        return self.to_local(res_kind, mesh, jnp.where(absent, self._absent(res_kind), r))

    def _absent(self, kind: str) -> int:
        """The global sentinel of ``kind`` (one past the end)."""
        return self.num_darts if kind == "dart" else self._table(kind)[2]

    def adjacent(self, u: Int, v: Int) -> Int:  # noqa: D401 - forwarded, global ids
        """``Adjacent(u, v)`` on global vertex ids (the union structure's, or the generic one)."""
        from jaxcds.algorithms.adjacency import adjacent

        return adjacent(self.structure, u, v)

    def adjacent_local(self, mesh: Int, u: Int, v: Int) -> Int:
        """``Adjacent(u, v)`` for vertices local to mesh ``mesh``; False when ``u`` or ``v`` is
        not a vertex of that mesh (out of range, or ``mesh`` outside the batch): the union
        structure would read the sentinel's row (an unchecked adjacent answered True)."""
        gu = self.to_global("vertex", mesh, u)
        gv = self.to_global("vertex", mesh, v)
        ok = (gu < self.num_vertices) & (gv < self.num_vertices)
        return self.adjacent(jnp.where(ok, gu, 0), jnp.where(ok, gv, 0)) & ok

    # ------------------------------------------------------------------ per-mesh reductions
    def per_mesh_sum(self, values, kind: str = "vertex"):
        """``(num_meshes, ...)`` sums of per-vertex (or per-face) ``values`` over each mesh:
        the input meshes' sums, the rows of a structure's dummy vertices (holes closed,
        :meth:`dummy_vertex_mask`) and of their fans' faces left out.

        Booleans and integers narrower than 32 bits are summed as int32 (uint8 sums wrapped at
        256); host arrays of either byte order and nested lists are read by value.

        Raises:
          ArgumentError: not one row per vertex (face); not real numbers; a masked array (fill
            it first: its mask would be ignored)."""
        values = _values_arg(values, "per_mesh_sum")
        self._check_length("per_mesh_sum", values, kind)
        return self._sum_own(values, kind, self._dummy_rows(kind))

    def _sum_own(self, values, kind: str, dummy):
        """Per-mesh sums of ``values`` with the rows flagged in ``dummy`` (or none) left out."""
        seg = self.vertex_mesh() if kind == "vertex" else self.face_mesh()
        if dummy is not None:
            values = to_device(values, copy=True)
            values = jnp.where(dummy.reshape((-1,) + (1,) * (values.ndim - 1)), 0, values)
        return jax.ops.segment_sum(values, seg, num_segments=self.num_meshes)

    def _dummy_rows(self, kind: str):
        """Rows of ``kind`` that are not the input meshes': a structure's dummy vertices, or
        the faces of their fans (a face with a dummy corner); ``None`` if there are none."""
        from jaxcds.algorithms.normals import faces_with_dummy_corner

        dummy = self.dummy_vertex_mask()
        if dummy is None or kind == "vertex":
            return dummy
        return faces_with_dummy_corner(dummy, self.face_vertices())

    def _check_length(self, what: str, values, kind: str) -> None:
        """Raise :class:`~jaxcds.errors.ArgumentError` unless ``values`` has one row per
        ``kind`` (vertex or face) of the batch (segment sums would drop or misassign rows)."""
        total = self._table(kind)[2]
        rows = np.shape(values)[0] if np.ndim(values) else None
        if rows != total:
            raise errors.ArgumentError(
                f"PackedBatch.{what}: values must have one row per {kind} of the batch ({total}), "
                f"got shape {tuple(np.shape(values))}")

    def per_mesh_mean(self, values, kind: str = "vertex"):
        """Per-mesh means (0 for an empty mesh): the input meshes' (a structure's dummy vertices
        and fan faces neither summed nor counted, as in :meth:`per_mesh_sum`)."""
        values = _values_arg(values, "per_mesh_mean")
        self._check_length("per_mesh_mean", values, kind)
        dummy = self._dummy_rows(kind)  # once: for faces it reads the union's face list
        s = self._sum_own(values, kind, dummy)
        if dummy is not None:  # the rows kept, per mesh
            cnt = self._sum_own(jnp.ones(dummy.shape, jnp.int32), kind, dummy)
        else:
            cnt = self.n_vertex if kind == "vertex" else self.n_face
        c = jnp.maximum(cnt, 1).astype(s.dtype).reshape((-1,) + (1,) * (s.ndim - 1))
        return s / c

    # ------------------------------------------------------------------ host side
    def split(self, values, kind: str = "vertex") -> list:
        """Host-side list of per-mesh slices of a per-vertex (per-face) array, in each mesh's
        structure vertex order (use :meth:`unpermute` first for input order)."""
        values = np.asarray(values)
        self._check_length("split", values, kind)
        off = np.asarray(self._table(kind)[0])
        cnt = np.asarray(self._table(kind)[1])
        return [values[o:o + c] for o, c in zip(off.tolist(), cnt.tolist())]

    def unpermute(self, values):
        """Per-vertex ``values`` in structure order -> input (packed) order."""
        self._check_length("unpermute", values, "vertex")
        order = self.vertex_order
        if order is None:
            return values
        out = jnp.zeros_like(values) if isinstance(values, jax.Array) else np.zeros_like(values)
        if isinstance(out, jax.Array):
            return out.at[jnp.asarray(order)].set(values)
        out[np.asarray(order)] = values
        return out

    def __repr__(self) -> str:
        return (f"PackedBatch[{type(self.structure).__name__}](num_meshes={self.num_meshes}, "
                f"num_vertices={self.num_vertices}, num_faces={self.num_faces}, "
                f"num_darts={self.num_darts}, references={self.references})")


def _make_forward(op):
    def method(self, x):
        return getattr(self.structure, op)(x)

    method.__name__ = op
    method.__doc__ = f"The union structure's ``{op}`` on global ids."
    return method


for _op in _FORWARDED:
    if _op == "face_vertices":
        PackedBatch.face_vertices = lambda self: self.structure.face_vertices()  # type: ignore
    elif _op == "face_vertices_padded":
        PackedBatch.face_vertices_padded = lambda self: self.structure.face_vertices_padded()  # type: ignore
    else:
        setattr(PackedBatch, _op, _make_forward(_op))


_id_arg = id_arg  # kept for the callers below (jaxcds.structures.base.id_arg)


def _values_arg(values, what: str):
    """Per-row ``values`` for the per-mesh reductions: a jax array as it is (narrow integers and
    booleans widened to int32), host values checked (:func:`~jaxcds._args.number_array`), in
    native byte order, on the device."""
    values = number_array(values, f"PackedBatch.{what}: values", error=errors.ArgumentError,
                          bools=True)
    dtype = values.dtype
    if jnp.issubdtype(dtype, jnp.bool_) or (jnp.issubdtype(dtype, jnp.integer) and dtype.itemsize < 4):
        return to_device(values, jnp.int32)
    return to_device(values)  # native byte order: JAX refuses big-endian data


def _id_pair(mesh, local, what: str):
    """``_id_arg`` of a (mesh, local id) pair that must broadcast together."""
    m = _id_arg(mesh, f"{what}: mesh indices")
    loc = _id_arg(local, f"{what}: local ids")
    try:
        np.broadcast_shapes(m.shape, loc.shape)
    except ValueError:
        raise errors.ArgumentError(f"{what}: mesh indices of shape {tuple(m.shape)} and local ids "
                                   f"of shape {tuple(loc.shape)} do not broadcast") from None
    return m, loc


def _segment_ids(counts, total: int) -> Int:
    """``[0]*counts[0] + [1]*counts[1] + ...`` of static length ``total`` (jittable)."""
    b = counts.shape[0]
    return jnp.repeat(jnp.arange(b, dtype=jnp.int32), counts, total_repeat_length=total)


def _owner(offsets, counts, g) -> Int:
    """Mesh whose range ``[offset, offset + count)`` holds ``g``: the last mesh whose offset is
    <= ``g`` (an empty mesh shares its offset with the next mesh, which is the one found)."""
    del counts  # offsets alone decide: kept in the signature for readability at call sites
    return (jnp.searchsorted(offsets, g, side="right") - 1).astype(jnp.int32)


# ---------------------------------------------------------------------------------- id shifting
def shift_ids(arrays: Sequence[np.ndarray], counts: Sequence[int]) -> np.ndarray:
    """Concatenate per-part arrays of *ids* (vertex, face or any contiguous id space), shifting
    part ``i``'s ids by the sum of the previous ``counts``; a part's sentinel (its own count,
    one past the end) becomes the total. The helper ``concatenate`` classmethods use for
    vertex- and face-valued fields."""
    counts = np.asarray(counts, np.int64)
    _same_parts(arrays, counts, "shift_ids")
    off = np.concatenate([[0], np.cumsum(counts)[:-1]])
    lens = [int(np.asarray(a).size) for a in arrays]
    cat = np.concatenate([np.asarray(a, np.int64).ravel() for a in arrays]) if arrays else np.zeros(0, np.int64)
    o = np.repeat(off, lens)
    c = np.repeat(counts, lens)
    out = np.where(cat >= c, counts.sum(), cat + o)
    return _int32(out)


def _same_parts(arrays, counts: np.ndarray, where: str) -> None:
    """One count per part: a mismatch raised numpy's untyped "operands could not be broadcast"."""
    if counts.ndim != 1 or counts.shape[0] != len(arrays):
        raise errors.ArgumentError(f"{where}: {len(arrays)} arrays but {counts.size} counts; give one "
                                   "count per part")


def shift_darts(arrays: Sequence[np.ndarray], primary: Sequence[int], extra: Sequence[int]) -> np.ndarray:
    """Concatenate per-part arrays of *dart* ids into the batch's dart numbering: part ``i``'s
    primary darts ``[0, P_i)`` follow the previous parts' primary darts, its extra darts
    ``[P_i, P_i + X_i)`` come after ALL primary darts (see the module docstring); the sentinel
    ``P_i + X_i`` becomes the total."""
    p = np.asarray(primary, np.int64)
    x = np.asarray(extra, np.int64)
    _same_parts(arrays, p, "shift_darts")
    _same_parts(arrays, x, "shift_darts")
    poff = np.concatenate([[0], np.cumsum(p)[:-1]])
    xoff = np.concatenate([[0], np.cumsum(x)[:-1]])
    lens = [int(np.asarray(a).size) for a in arrays]
    d = np.concatenate([np.asarray(a, np.int64).ravel() for a in arrays]) if arrays else np.zeros(0, np.int64)
    pi, xi, po, xo = (np.repeat(t, lens) for t in (p, x, poff, xoff))
    out = np.where(d < pi, po + d, p.sum() + xo + (d - pi))
    out = np.where(d >= pi + xi, p.sum() + x.sum(), out)
    return _int32(out)


def split_darts(values: np.ndarray, primary: Sequence[int], extra: Sequence[int]) -> list[np.ndarray]:
    """Inverse layout of :func:`shift_darts` for per-dart arrays: the per-part slices, each the
    part's primary rows followed by its extra rows (values are not shifted)."""
    p = np.asarray(primary, np.int64)
    x = np.asarray(extra, np.int64)
    pe = np.cumsum(p)
    xe = p.sum() + np.cumsum(x)
    out = []
    for i in range(p.size):
        out.append(np.concatenate([values[pe[i] - p[i]:pe[i]], values[xe[i] - x[i]:xe[i]]]))
    return out


def _int32(a: np.ndarray) -> np.ndarray:
    if a.size and a.max() > np.iinfo(np.int32).max:
        raise errors.StructureError(
            f"packed batch: id {int(a.max())} exceeds int32; pack fewer meshes per batch")
    return a.astype(np.int32)


def primary_darts(s) -> int:
    """Darts of ``s``'s primary block (``num_primary_darts`` if the class defines it)."""
    return int(getattr(s, "num_primary_darts", s.num_darts))


# ---------------------------------------------------------------------------------- building
#: structures built once on the union face list (they accept several components)
_UNION_BUILDERS = {"halfedge", "corner-table"}


def pack(meshes: Sequence[Any], structure: str = "halfedge", *, check: bool = True) -> PackedBatch:
    """Pack ``meshes`` (paths, ``TriMesh``, ``(vertices, faces)`` pairs, trimesh objects) into
    one :class:`PackedBatch` of structure ``structure`` (a registry name).

    HalfEdge and CornerTable are built once on the union faces; other structures are built per
    mesh through the registry and joined with their class's ``concatenate`` classmethod (CDS
    family, LR, lr-bits, pemb). Structures that renumber vertices
    get the union ``vertex_order`` (each mesh's order shifted by its vertex offset):
    :func:`pack_positions` applies it.

    ``check=False`` (``halfedge``, ``corner-table``; the other builders always validate): trusted
    meshes, not validated. Only their face ids are checked (O(F), ``InvalidIndexError`` naming
    the mesh and the face) and border sides that do not chain into loops (the mesh's defect,
    named); on other defects the batch's answers are unspecified, never a crash.

    Raises:
      MeshError: a defective mesh; the message names the mesh index and the defect.
      UnsupportedTopologyError: the structure refuses a mesh, or has no ``concatenate``.
      ArgumentError: an unknown ``structure``, ``meshes`` that are not a list, or ``check`` not
        a bool (``check='no'`` was truthy: the meshes were validated).
    """
    from jaxcds.structures import registry

    check = flag_arg(check, "pack: check")
    ms = [_load(m) for m in _mesh_list(meshes, "pack")]
    if not ms:
        raise errors.EmptyMeshError("pack: no meshes given")
    names = registry.names()
    if not isinstance(structure, str) or structure not in names:
        raise errors.ArgumentError(f"pack: unknown structure {structure!r}; available: {', '.join(names)}")
    if structure in _UNION_BUILDERS:
        return _pack_union(ms, structure, check)
    if structure in REFUSED:  # before building anything
        raise errors.UnsupportedTopologyError(f"pack: {structure} cannot be packed: {REFUSED[structure]}")
    parts = []
    for i, m in enumerate(ms):
        try:
            parts.append(registry.build(structure, m))
        except errors.JaxcdsError as exc:
            raise type(exc)(f"pack: mesh {i} ({m.source}): {exc}") from exc
        if i == 0:
            _check_hook(type(parts[0]))  # refuse before building the other meshes
    return concatenate(parts)


def _mesh_list(meshes, what: str) -> list:
    """``meshes`` as a list, or :class:`~jaxcds.errors.ArgumentError` for one mesh given where a
    sequence of meshes is asked for (a path string was iterated character by character, a
    ``TriMesh`` or ``None`` raised TypeError)."""
    import os

    one = isinstance(meshes, (str, bytes, os.PathLike, TriMesh)) or type(meshes).__name__ == "Trimesh"
    pair = (isinstance(meshes, tuple) and len(meshes) == 2
            and all(isinstance(x, (np.ndarray, jax.Array)) for x in meshes))
    if one or pair:
        raise errors.ArgumentError(f"{what}: give a list of meshes (one mesh is [mesh]), got "
                                   f"a single {type(meshes).__name__}")
    try:
        return list(meshes)
    except TypeError:
        raise errors.ArgumentError(f"{what}: give a list of meshes, got {type(meshes).__name__}") from None


def _load(m) -> TriMesh:
    if isinstance(m, tuple) and len(m) == 2:
        return load_mesh(*m)
    return load_mesh(m)


def _union(ms: Sequence[TriMesh]) -> TriMesh:
    nv = np.array([m.num_vertices for m in ms], np.int64)
    voff = np.concatenate([[0], np.cumsum(nv)[:-1]])
    faces = np.concatenate([m.faces.astype(np.int64) + o for m, o in zip(ms, voff)])
    verts = np.concatenate([m.vertices for m in ms])
    return TriMesh(vertices=verts, faces=_int32(faces), source=f"union of {len(ms)} meshes")


def _pack_union(ms: Sequence[TriMesh], structure: str, check: bool) -> PackedBatch:
    from jaxcds.structures import CornerTable, HalfEdge

    u = _union(ms)
    closed = structure == "corner-table"
    if check:
        # one validation of the union (fast); on failure, find the mesh to name it
        try:
            validate(u, closed=closed, structure=structure)
        except errors.MeshError:
            _raise_for_mesh(ms, closed=closed, structure=structure)
            raise
    else:  # trusted: ids only (one beyond its own mesh would reach into the next one's vertices)
        for i, m in enumerate(ms):
            trusted_faces(m.faces, m.num_vertices, f"pack: mesh {i} ({m.source})")
    cls = HalfEdge if structure == "halfedge" else CornerTable
    try:
        s = cls.from_faces(u.faces, u.num_vertices)
    except errors.MeshError:  # border sides that do not chain (from_faces): name the mesh
        _raise_for_mesh(ms, structure=structure, unreferenced_ok=True)
        raise
    nf = np.array([m.num_faces for m in ms], np.int64)
    if structure == "halfedge":
        # border darts of mesh i: one per border side of its faces, in face order (the builder
        # numbers border darts by increasing inner dart, i.e. mesh by mesh)
        nb_total = s.num_border_darts
        if nb_total:
            opp = np.asarray(s.opposite[: 3 * s.num_faces])
            border_face = np.nonzero(opp >= 3 * s.num_faces)[0] // 3
            fmesh = np.repeat(np.arange(len(ms)), nf)
            nx = np.bincount(fmesh[border_face], minlength=len(ms))
        else:
            nx = np.zeros(len(ms), np.int64)
        return _assemble(s, [m.num_vertices for m in ms], nf, 3 * nf, nx)
    return _assemble(s, [m.num_vertices for m in ms], nf, 3 * nf, np.zeros(len(ms), np.int64))


def _raise_for_mesh(ms: Sequence[TriMesh], **checks) -> None:
    """The first mesh of ``ms`` that ``validate(mesh, **checks)`` refuses, its error re-raised
    naming the mesh (a union failed: which part); returns if every mesh passes."""
    for i, m in enumerate(ms):
        try:
            validate(m, **checks)
        except errors.MeshError as exc:
            raise type(exc)(f"pack: mesh {i} ({m.source}): {exc}") from exc


#: vertices per chunk of the chunked normal sums (:meth:`PackedBatch.normal_sums`): a chunk's
#: rows, positions, face normals and sums (about 200 bytes per vertex) stay in a 32 MiB L3.
#: 10,000 random meshes (27M vertices), Zen 3 host of stop 39, ns per vertex (medians of 7,
#: runs spread about 10%): cds6n 64K 92, 128K 82, 256K 105, 512K 85, whole union 178; lr 32K
#: 100, 64K 82, 128K 91, 256K 105, whole 213; the plain face list 87-95 (``/tmp`` probes,
#: RESULTS.md "stop 39"). Rows interleaved inside a chunk (as the whole-union route does)
#: cost more than they saved: cds6n 98 -> 129.
NORMALS_CHUNK_VERTICES = 1 << 17


def chunks_pay_off() -> bool:
    """Whether the chunked normal sums run: on CPU only (:func:`jaxcds._arrays.traced_for_cpu`,
    the platform a call is traced for).

    Why: the chunks exist for a CPU's cache. On an H100 (RESULTS.md, "GPU: an H100, stop 43"),
    1,000 random meshes (2.8M vertices), chunked: the packed corner table 2.18x the face-list
    batch, the half-edge 2.33x, while the same structures unchunked on one 5M-vertex mesh read
    1.12x and 1.01x."""
    return traced_for_cpu()


def _row_blocks(s, num_chunks: int = 1):
    """The union structure's face rows as blocks in mesh order, ``[(rows, valid or None)]``; or,
    for a structure that derives them chunk by chunk (``normal_row_chunks(num_chunks)``: the
    packed pemb, whose whole-union tables are the large temporaries), its
    ``rows_of_chunk(lo, hi, caps)`` (the hook answers None to keep the whole-union rows)."""
    chunks = getattr(s, "normal_row_chunks", None)
    rows_of_chunk = None if chunks is None else chunks(num_chunks)
    if rows_of_chunk is not None:
        return rows_of_chunk
    hook = getattr(s, "normal_row_blocks", None)
    if hook is not None:
        return hook()
    fv, valid = s.face_vertices_padded()  # HalfEdge / CornerTable: faces in union order
    return [(fv, valid)]


def _chunkable(s) -> bool:
    """Whether ``s``'s rows come in the blocks :func:`_row_counts` planned for."""
    from jaxcds.structures import CornerTable, HalfEdge
    return hasattr(type(s), "normal_row_blocks") or type(s) in (HalfEdge, CornerTable)


def _row_counts(s, nf):
    """Host-side rows per mesh of each block of :func:`_row_blocks` (None: no chunking)."""
    if not _chunkable(s):
        return None
    hook = getattr(s, "normal_row_counts", None)
    return hook() if hook is not None else [np.asarray(nf, np.int64)]


def chunk_plan(vertex_counts, row_counts, chunk: Optional[int] = None):
    """Group consecutive meshes into chunks of at most ``chunk`` vertices (a larger mesh is a
    chunk of its own). Returns ``(starts (K + 1, 1 + len(row_counts)) int32, caps)``: the first
    vertex and the first row of each block of every chunk, then the totals; ``caps`` the
    largest chunk's vertices and rows per block (static shapes of the loop body). ``None``
    when there would be a single chunk."""
    chunk = NORMALS_CHUNK_VERTICES if chunk is None else chunk
    nv = np.asarray(vertex_counts, np.int64)
    cols = [nv] + [np.asarray(c, np.int64) for c in row_counts]
    cut, acc = [0], 0
    for i, n in enumerate(nv.tolist()):
        if acc and acc + n > chunk:
            cut.append(i)
            acc = 0
        acc += n
    cut.append(len(nv))
    if len(cut) <= 2:
        return None
    offs = [np.concatenate([[0], np.cumsum(c)]) for c in cols]
    starts = np.stack([o[cut] for o in offs], axis=1)
    sizes = np.diff(starts, axis=0)
    if starts[-1].max() >= 2**31:
        return None
    return starts.astype(np.int32), tuple(int(x) for x in sizes.max(axis=0))


def _window(x, start, size: int, total: int):
    """``(x[w : w + size], w)`` with ``w = min(start, total - size)``: a slice that stays
    inside ``x`` (no padded copy), starting at ``start`` or before it near the end."""
    w = jnp.minimum(start, total - size)
    return jax.lax.dynamic_slice_in_dim(x, w, size), w


def _chunk_rows(k, starts, caps, w, blocks):
    """``[(rows local to the vertex window at w, ok)]`` of chunk ``k``: windows of the union's
    row blocks (:func:`_row_blocks`), each row kept where it belongs to the chunk's meshes."""
    if callable(blocks):  # rows derived for this chunk alone
        return [(r - w, ok) for r, ok in blocks(starts[k], starts[k + 1], caps)]
    out = []
    for j, (rows, valid) in enumerate(blocks):
        r0, r1, cap = starts[k, j + 1], starts[k + 1, j + 1], caps[j + 1]
        if cap == 0:
            continue
        total = rows.shape[0]
        r, rw = _window(rows, r0, cap, total)
        i = jnp.arange(cap) + rw
        ok = (i >= r0) & (i < r1)
        if valid is not None:
            ok = ok & _window(valid, r0, cap, total)[0]
        out.append((r - w, ok))
    return out


def _chunked_sums(b: "PackedBatch", positions):
    from jaxcds.algorithms.normals import corner_sums, face_normals, faces_with_dummy_corner
    s = b.structure
    starts, caps = b.chunk_starts, b.chunk_caps
    n, vcap = b.num_vertices, caps[0]
    num_chunks = starts.shape[0] - 1  # static: the plan's shape
    blocks = _row_blocks(s, num_chunks)
    dummy = s.dummy_vertex_mask()

    def body(k, out):
        a, a1 = starts[k, 0], starts[k + 1, 0]
        p, w = _window(positions, a, vcap, n)
        mine = (jnp.arange(vcap) + w >= a) & (jnp.arange(vcap) + w < a1)
        dm = None if dummy is None else _window(dummy, a, vcap, n)[0]
        acc = jnp.zeros((vcap, 3), positions.dtype)
        for r, ok in _chunk_rows(k, starts, caps, w, blocks):
            loc = jnp.where(ok[:, None], r, 0)
            if dm is not None:  # the fans that closed holes (see normals.surface_faces_padded)
                ok = ok & ~faces_with_dummy_corner(dm, loc)
            fn = face_normals(p, loc, ok)  # masked corners: no 0 * NaN in the derivative
            acc = corner_sums(fn, loc, vcap, acc)
        old = jax.lax.dynamic_slice_in_dim(out, w, vcap)
        return jax.lax.dynamic_update_slice_in_dim(out, jnp.where(mine[:, None], acc, old), w, 0)

    out = jnp.zeros((n, 3), positions.dtype)
    return jax.lax.fori_loop(0, num_chunks, body, out)


def _assemble(s, nv, nf, nd, nx) -> PackedBatch:
    nv, nf, nd, nx = (np.asarray(a, np.int64) for a in (nv, nf, nd, nx))

    def off(c):
        return to_device(np.concatenate([[0], np.cumsum(c)[:-1]]).astype(np.int32))

    i32 = lambda a: to_device(a.astype(np.int32))  # noqa: E731
    if int(nv.sum()) != s.num_vertices or int(nf.sum()) != s.num_faces or \
            int(nd.sum() + nx.sum()) != s.num_darts:
        raise errors.StructureError(
            f"packed batch: counts (V={nv.sum()}, F={nf.sum()}, darts={nd.sum() + nx.sum()}) do not "
            f"match the union structure (V={s.num_vertices}, F={s.num_faces}, darts={s.num_darts})")
    counts = _row_counts(s, nf)
    plan = None if counts is None else chunk_plan(nv, counts)
    return PackedBatch(structure=s, n_vertex=i32(nv), n_face=i32(nf), n_dart=i32(nd),
                       n_extra_dart=i32(nx), vertex_offsets=off(nv), face_offsets=off(nf),
                       dart_offsets=off(nd), extra_dart_offsets=off(nx), num_meshes=int(nv.size),
                       num_vertices=int(nv.sum()), num_faces=int(nf.sum()),
                       num_primary_darts=int(nd.sum()),
                       chunk_starts=None if plan is None else to_device(plan[0]),
                       chunk_caps=() if plan is None else plan[1])


def concatenate(parts: Sequence[MeshStructure]) -> PackedBatch:
    """Join already built structures of ONE class into a :class:`PackedBatch` through the class's
    ``concatenate(parts)`` classmethod (ids shifted with :func:`shift_ids` / :func:`shift_darts`).

    Raises:
      UnsupportedTopologyError: mixed classes, or a class without ``concatenate``.
      EmptyMeshError: no structures.
      ArgumentError: ``parts`` is not a list of structures (one structure raised TypeError 'not
        subscriptable'; a TriMesh was refused as a class 'without concatenate')."""
    if isinstance(parts, MeshStructure):
        raise errors.ArgumentError(f"concatenate: give a list of structures (one is [s]), got a "
                                   f"single {type(parts).__name__}")
    if parts is None:
        raise errors.ArgumentError("concatenate: give a list of structures, got None")
    if not parts:
        raise errors.EmptyMeshError("concatenate: no structures given")
    try:
        parts = list(parts)
    except TypeError:
        raise errors.ArgumentError(f"concatenate: give a list of structures, got "
                                   f"{type(parts).__name__}") from None
    for i, p in enumerate(parts):
        if not isinstance(p, MeshStructure):
            raise errors.ArgumentError(
                f"concatenate: structure {i} is a {type(p).__name__}, not a jaxcds structure "
                "(build each with jaxcds.build(name, mesh), or pack meshes with pack(meshes, name))")
    cls = type(parts[0])
    for i, p in enumerate(parts):
        if type(p) is not cls:
            raise errors.UnsupportedTopologyError(
                f"concatenate: structure {i} is a {type(p).__name__}, structure 0 a {cls.__name__}; "
                "a packed batch holds one structure kind")
    _check_hook(cls)
    s = cls.concatenate(list(parts))
    pd = [primary_darts(p) for p in parts]
    return _assemble(s, [p.num_vertices for p in parts], [p.num_faces for p in parts], pd,
                     [p.num_darts - q for p, q in zip(parts, pd)])


#: structures that cannot be packed, and why (``pack`` / ``concatenate`` refuse them by name).
#: Empty since pemb packs (stop 40: :mod:`jaxcds.structures.pemb_packed`); kept for a structure
#: whose ids cannot be joined, so that the refusal says why.
REFUSED: dict = {}


def _check_hook(cls) -> None:
    name = getattr(cls, "name", "?")
    if name in REFUSED:
        raise errors.UnsupportedTopologyError(f"{cls.__name__} ({name}) cannot be packed: {REFUSED[name]}")
    if not hasattr(cls, "concatenate"):
        raise errors.UnsupportedTopologyError(
            f"{cls.__name__} ({getattr(cls, 'name', '?')}) cannot be packed: the class has no "
            "`concatenate(parts)` classmethod; pack the meshes as 'halfedge' or 'corner-table', "
            "or build one structure per mesh")


def pack_positions(batch: PackedBatch, meshes: Sequence[Any], dtype=jnp.float32) -> jnp.ndarray:
    """``(num_vertices, 3)`` positions of the packed meshes, in the batch structure's vertex
    order (concatenated, then permuted by ``vertex_order`` when the structure renumbers).

    Structures that close holes with a dummy vertex each and keep it as a vertex (the CDS family,
    CDS paper Sec. 4.5) have more vertices than the mesh: for such a mesh (given as a mesh, not
    as a bare position array) the positions are those of the closed mesh, dummies at their loop's
    centroid, as :func:`jaxcds.mesh.close_boundaries` places them when the structure is built.
    The other way round, a mesh the user closed (dummies flagged) given to a structure that drops
    flagged dummies (LR shows holes as borders) contributes its own vertices only.

    ``dtype``: a floating dtype (float32 by default; float16 and bfloat16 too, which
    ``vertex_normals`` sums in float32; float64 needs jax x64, float32 otherwise), or ``None``
    (float32).

    Raises:
      ArgumentError: ``batch`` is not a :class:`PackedBatch`; not one mesh per mesh of the batch;
        ``dtype`` not a dtype, or not a floating one (integers truncated the coordinates,
        booleans and complex numbers are no positions).
      MeshError: the positions do not match the batch's vertex counts (naming the mesh).
    """
    from jaxcds.mesh import validate_and_close

    if not isinstance(batch, PackedBatch):  # an AttributeError on n_vertex before
        raise errors.ArgumentError(f"pack_positions: batch must be a PackedBatch (from pack or "
                                   f"concatenate), got {type(batch).__name__}")
    if dtype is not None:  # numpy's / jax's TypeError before, or truncated int positions
        try:
            dt = np.dtype(dtype)
        except (TypeError, ValueError) as exc:
            raise errors.ArgumentError(f"pack_positions: dtype {dtype!r} is not a dtype ({exc}); "
                                       "positions take a floating one (float32...)") from None
        if not jnp.issubdtype(dt, jnp.floating):
            raise errors.ArgumentError(f"pack_positions: dtype {dt} is not a floating dtype: "
                                       "positions are coordinates (float32, float64, float16, "
                                       "bfloat16)")
    want = np.asarray(batch.n_vertex)
    meshes = _mesh_list(meshes, "pack_positions")
    if len(meshes) != want.shape[0]:
        raise errors.ArgumentError(
            f"pack_positions: {len(meshes)} meshes for a batch of {want.shape[0]}")
    ps = []
    for i, m in enumerate(meshes):
        if isinstance(m, (np.ndarray, jax.Array)):
            refuse_non_real(m, f"pack_positions: mesh {i}'s positions")
            v = np.asarray(m)
        else:
            tm = _load(m)
            v = tm.vertices
            if v.shape[0] < want[i]:  # the structure closed its holes: dummies are vertices
                v = validate_and_close(tm).vertices
            elif v.shape[0] > want[i] and tm.dummy_vertices is not None:
                # a mesh the user closed, given to a structure that shows holes as borders and
                # drops the flagged dummies (LR, Sec. 4.6): its own vertices, in order
                own = ~np.asarray(tm.dummy_vertices, bool)
                if int(own.sum()) == want[i]:
                    v = v[own]
        if v.ndim != 2 or v.shape[1] != 3:
            raise errors.MeshError(f"pack_positions: mesh {i}'s positions have shape "
                                   f"{tuple(v.shape)}, expected ({int(want[i])}, 3)")
        if v.shape[0] != want[i]:
            raise errors.MeshError(
                f"pack_positions: mesh {i} has {v.shape[0]} positions, the batch holds "
                f"{int(want[i])} vertices for it")
        ps.append(np.asarray(v, np.float64))
    p = np.concatenate(ps)
    order = batch.vertex_order
    if order is not None:
        p = p[np.asarray(order)]
    return to_device(p, dtype)
