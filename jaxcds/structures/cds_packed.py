"""Packed batches of CDS structures: many Schnyder-wood structures as ONE structure over the
disjoint union of their meshes (the ``concatenate`` hook of :mod:`jaxcds.batch`).

Paper: ``../shared/seeds/000_db4616a06e23a922.txt`` (Castelli Aleardi & Devillers), Sec. 2.1-2.6;
the "scene of many small objects" is Sec. 4.5's motivation.

What shifts, what does not
--------------------------
Every reference of a CDS table is a *vertex* id in the low 30 bits of an int32 with at most two
service bits (``I_c``, ``C``) in bits 30-31 (Sec. 2.1), ``F_blue`` holds vertex ids (Thm 7), and
edge/dart ids are ``3u + c`` / ``2(3u + c) + r``. So mesh ``i`` shifted by its vertex offset
``o_i`` keeps every formula: its edges become ``3(u + o_i) + c`` and its darts
``6 o_i + (local dart)`` -- one contiguous dart block per mesh, as :mod:`jaxcds.batch` wants.
The concatenation shifts the low 30 bits of every table entry and leaves the service bits as
they are; the cwBFS order of CDS4n / CDS5n-O(1) (Sec. 2.3: siblings are consecutive, ``w = u + 1``)
survives a shift, and ``vertex_order`` is composed with the per-mesh input offsets.

What is per mesh and cannot be shifted into one structure: the three outer vertices ``V_red,
V_blue, V_black`` (the "special manner" of the exterior edges, Thm 4), which a single structure
keeps as three static ints, and the four unused face slots of Thm 7 (``face`` compacts slots to
dense ids with them). A union of ``B`` Schnyder woods is not one Schnyder wood, so the union
structure keeps them as per-mesh tables (``mesh_roots``, ``mesh_unused_slots``: ``7B`` int32) and
every operator evaluates the class's own code on a *view* whose roots are arrays: the roots of
the mesh owning each query element (one binary search over the ``B`` vertex offsets per query;
navigation never leaves a component, so every id reached from a query shares its mesh). The
whole-mesh routes (``face_vertices``, ``vertex_degrees``) use per-vertex roots and no search.

Face ids: a view computes Thm 7 slots over the union (red slot ``u``, black/blue slot
``N + u`` for ``N`` union vertices) and compacts them per mesh (mesh ``i``'s faces are
``face_offsets[i] + 0 .. 2 n_i - 5``, local order = the single structure's).
"""

from __future__ import annotations

import dataclasses
from typing import Sequence

import jax.numpy as jnp
import numpy as np

from jaxcds import errors
from jaxcds._arrays import to_device
from jaxcds._dataclass import pytree_dataclass
from jaxcds.structures.base import (_chunk_queries, _jit_whole_mesh, check_id_space, interleave_rows,
                                    parts_of_one_class)
from jaxcds.structures.cds import slot_blocks

__all__ = ["concatenate_cds", "packed_class"]

_IDX = (1 << 30) - 1


# ---------------------------------------------------------------------------------- views
class _ViewMixin:
    """Per-query (or per-vertex) evaluation of a CDS class's own operators: ``v_red``,
    ``v_blue``, ``v_black`` are arrays shaped like the query (the roots of each element's mesh),
    ``_voff``, ``_nv``, ``_foff``, ``_un`` the element's mesh vertex offset, vertex count, face
    offset and its four unused local Thm 7 slots. Never flattened (built inside traced code)."""

    chunked_queries = frozenset()  # views carry per-query arrays; the entries build the views
    table_queries = {}  # likewise: a view's arrays are per query, not the union's tables

    def _compact(self, slot):
        # union slot (red u, black/blue N + u) -> local Thm 7 slot -> dense local face -> global
        n = self.num_vertices
        loc = jnp.where(slot < n, slot - self._voff, self._nv + slot - n - self._voff)
        k = jnp.zeros_like(loc)
        for x in self._un:
            k = k + (loc > x).astype(k.dtype)  # explicit: strict dtype promotion (sweep 52c)
        return (self._foff + loc - k).astype(jnp.int32)

    def _expand(self, f):
        return _expand_union(f - self._foff, self._un, self._voff, self._nv, self.num_vertices)

    def _rf_red_r(self, u, row):
        # CDS4n (Thm 5): the sibling test ``u >= 2`` is on cwBFS labels, i.e. mesh-local ids
        r = super()._rf_red_r(u, row)
        if not hasattr(type(self), "order"):  # CDS5n stores RightFront(u_red): nothing local
            return r
        return jnp.where(u - self._voff < 2, self._lf_black_r(row), r)


def _expand_union(f_local, un, voff, nv, n):
    """Dense local face id -> local Thm 7 slot (skipping the 4 unused ones, sorted) -> union
    slot (red ``voff + s``; black/blue ``N + voff + s - n_i``)."""
    s = f_local
    for x in un:
        s = s + (s >= x).astype(s.dtype)
    return jnp.where(s < nv, voff + s, n + voff + s - nv).astype(jnp.int32)


# ---------------------------------------------------------------------------------- packed
_ARG = {  # entry point -> kind of its argument (decides the mesh of each element)
    **{op: "dart" for op in ("origin", "target", "next", "prev", "dart_valid", "face_slot", "face")},
    **{op: "edge" for op in ("edge_target", "_edge_target", "_target_walk", "left_front_edge",
                             "right_front_edge", "left_back_edge", "right_back_edge",
                             "edge_valid", "_lf", "_rf")},
    **{op: "vertex" for op in ("edge_of_vertex", "_out_targets")},
    "edge_of_face": "face",
}


class _PackedMixin:
    """Operators of the union: each entry point finds the mesh of every query element and runs
    the class's own code on a view with that mesh's roots (see the module docstring)."""

    packed = True

    def _mesh_of_vertex(self, u):
        u = jnp.clip(jnp.asarray(u, jnp.int32), 0, self.num_vertices - 1)
        return (jnp.searchsorted(self.mesh_vertex_offsets, u, side="right") - 1).astype(jnp.int32)

    def _mesh_of_face(self, f):
        f = jnp.clip(jnp.asarray(f, jnp.int32), 0, max(self.num_faces - 1, 0))
        return (jnp.searchsorted(self.mesh_face_offsets, f, side="right") - 1).astype(jnp.int32)

    def _view_of(self, m):
        """A view of the union whose per-element parameters are those of meshes ``m``."""
        base = type(self)._base
        kw = {f.name: getattr(self, f.name) for f in dataclasses.fields(base)}
        roots = self.mesh_roots[m]
        kw.update(v_red=roots[..., 0], v_blue=roots[..., 1], v_black=roots[..., 2], unused_slots=())
        v = type(self)._view_cls(**kw)
        un = self.mesh_unused_slots[m]
        for name, val in (("_voff", self.mesh_vertex_offsets[m]), ("_nv", self.mesh_vertex_counts[m]),
                          ("_foff", self.mesh_face_offsets[m]),
                          ("_un", tuple(un[..., k] for k in range(4)))):
            object.__setattr__(v, name, val)
        return v

    def _whole_view(self):
        """View for the whole-mesh routes (``face_vertices``, degrees, all targets), where element
        ``u`` is always the row of vertex ``u`` and every root test reads ``u == V_c`` (then the
        roots of ``u``'s mesh): per-vertex roots are -1 (no vertex) except AT each mesh's three
        roots, which hold their mesh's three roots. Three scatters of ``3B`` entries, no
        per-vertex mesh lookup; the face-slot fields are unused there (``None``)."""
        base = type(self)._base
        kw = {f.name: getattr(self, f.name) for f in dataclasses.fields(base)}
        at = self.mesh_roots.reshape(-1)  # (3B,): the roots of mesh 0, mesh 1, ...
        for c, name in enumerate(("v_red", "v_blue", "v_black")):
            val = jnp.repeat(self.mesh_roots[:, c], 3)  # mesh i's root c, at each of its 3 roots
            # a fill of its own per colour (-1, -2, -3: no vertex either way): one shared fill
            # would be copied three times before the in-place scatters, 24 B per vertex
            kw[name] = jnp.full(self.num_vertices, -1 - c, jnp.int32).at[at].set(val)
        kw["unused_slots"] = ()
        v = type(self)._view_cls(**kw)
        for name in ("_voff", "_nv", "_foff", "_un"):
            object.__setattr__(v, name, None)
        return v

    def _entry(self, kind, x):
        x = jnp.asarray(x, jnp.int32)
        if kind == "dart":
            m = self._mesh_of_vertex((x >> 1) // 3)
        elif kind == "edge":
            m = self._mesh_of_vertex(x // 3)
        elif kind == "vertex":
            m = self._mesh_of_vertex(x)
        else:
            m = self._mesh_of_face(x)
        return self._view_of(m), x

    # ---- whole mesh
    def face_vertices(self):
        """``(F, 3)``: the class's O(1)-per-face route (Thm 7) on the union's slots, then each
        mesh's faces picked in its own dense order."""
        full = type(self)._base._slot_faces(self._whole_view())  # (2N, 3): union slots
        b = self.mesh_vertex_counts.shape[0]
        fc = 2 * self.mesh_vertex_counts - 4
        m = jnp.repeat(jnp.arange(b, dtype=jnp.int32), fc, total_repeat_length=self.num_faces)
        g = jnp.arange(self.num_faces, dtype=jnp.int32)
        un = self.mesh_unused_slots[m]
        row = _expand_union(g - self.mesh_face_offsets[m], tuple(un[:, k] for k in range(4)),
                            self.mesh_vertex_offsets[m], self.mesh_vertex_counts[m], self.num_vertices)
        return full[row]

    def _slot_valid(self):
        """``(2N,)`` bool over the union's slots: False at each mesh's four unused Thm 7 slots
        (one scatter of ``4B`` entries)."""
        n = self.num_vertices
        loc = self.mesh_unused_slots  # (B, 4) local slots
        nv, voff = self.mesh_vertex_counts[:, None], self.mesh_vertex_offsets[:, None]
        at = jnp.where(loc < nv, voff + loc, n + voff + loc - nv).reshape(-1)
        return jnp.ones(2 * n, bool).at[at].set(False)

    def face_vertices_padded(self):
        """The union's ``2N`` Thm 7 slots as they are, each mesh's four unused ones masked (set
        to vertex 0): no per-face mesh lookup, no compaction gather (for the normals)."""
        valid = self._slot_valid()
        full = type(self)._base._slot_faces(self._whole_view())
        faces = jnp.where(valid[:, None], full, 0).astype(jnp.int32)
        b = slot_blocks(self.num_vertices)  # as the single CDS, by the union's size
        return interleave_rows(faces, b), interleave_rows(valid, b)

    def normal_row_blocks(self):
        """The union's Thm 7 slots as two blocks of rows in vertex order, for the chunked sums
        of :mod:`jaxcds.batch` (``[(red slots (N, 3), valid), (black/blue slots (N, 3),
        valid)]``): mesh ``i``'s rows are rows ``o_i .. o_i + n_i - 1`` of each block, and every
        vertex of a row lies in the row's mesh (a face and its ``F_blue`` owner share a
        component). Not interleaved: the chunks reorder their own rows."""
        n = self.num_vertices
        valid = self._slot_valid()
        full = type(self)._base._slot_faces(self._whole_view())
        return [(full[:n], valid[:n]), (full[n:], valid[n:])]

    def normal_row_counts(self):
        """Host-side rows per mesh of each :meth:`normal_row_blocks` block: ``n_i`` twice."""
        nv = np.asarray(self.mesh_vertex_counts, np.int64)
        return [nv, nv]

    def vertex_degrees(self):
        return type(self)._base.vertex_degrees(self._whole_view())

    def all_edge_targets(self):
        return type(self)._base.all_edge_targets(self._whole_view())

    def _target_start(self, lfs=None):
        return type(self)._base._target_start(self._whole_view(), lfs)

    def _targets_cols(self, lfs=None):
        return type(self)._base._targets_cols(self._whole_view(), lfs)

    def _valid_cols(self):
        return type(self)._base._valid_cols(self._whole_view())

    # ---- adjacency: each endpoint with its own mesh's roots
    def adjacent(self, u, v):
        """``Adjacent(u, v)`` on global ids: the class's rule (6 Targets), each endpoint's three
        outgoing targets read with its own mesh's roots; vertices of two meshes are never
        adjacent (their targets lie in their own mesh)."""
        u, v = jnp.asarray(u, jnp.int32), jnp.asarray(v, jnp.int32)
        vu, _ = self._entry("vertex", u)
        vv, _ = self._entry("vertex", v)
        hit = jnp.zeros(jnp.broadcast_shapes(u.shape, v.shape), bool)
        for t in vu._out_targets(u):
            hit = hit | (t == v)
        for t in vv._out_targets(v):
            hit = hit | (t == u)
        return hit & (u != v)

    @property
    def references(self) -> int:
        """Tables + face map of every mesh (the per-mesh roots and unused slots, ``7B`` ints, are
        batch metadata like :class:`jaxcds.batch.PackedBatch`'s counts and are not counted)."""
        return int(np.prod(self.refs.shape)) + int(self.F_blue.shape[0])


def _make_entry(name, kind):
    def method(self, x):
        view, x = self._entry(kind, x)
        return getattr(view, name)(x)

    method.__name__ = name
    method.__doc__ = f"The class's ``{name}``, evaluated with the roots of each element's mesh."
    return method


for _name, _kind in _ARG.items():
    setattr(_PackedMixin, _name, _make_entry(_name, _kind))
# the union's chunked queries: each chunk finds its elements' meshes and builds its own view
_chunk_queries(_PackedMixin)
_jit_whole_mesh(_PackedMixin)

_FIELDS = ("mesh_vertex_offsets", "mesh_vertex_counts", "mesh_face_offsets", "mesh_roots",
           "mesh_unused_slots")
_CLASSES: dict = {}


def packed_class(base):
    """The packed (union) class of CDS class ``base``: ``base``'s fields plus the per-mesh tables
    ``mesh_vertex_offsets``, ``mesh_vertex_counts``, ``mesh_face_offsets`` (``(B,)``),
    ``mesh_roots`` (``(B, 3)``: ``V_red, V_blue, V_black`` as union ids) and
    ``mesh_unused_slots`` (``(B, 4)``: Thm 7's unused slots, local, sorted)."""
    if base not in _CLASSES:
        ns = {"__annotations__": {f: jnp.ndarray for f in _FIELDS}, **{f: None for f in _FIELDS},
              "_base": base, "chunked_queries": base.chunked_queries, "__module__": __name__,
              "table_queries": {},  # entries take mesh-local ids, not the class's darts
              "__doc__": packed_class.__doc__.replace("``base``", base.__name__)}
        cls = pytree_dataclass(type(f"Packed{base.__name__}", (_PackedMixin, base), ns))
        cls._view_cls = type(f"_View{base.__name__}", (_ViewMixin, base), {"__module__": __name__})
        _CLASSES[base] = cls
    return _CLASSES[base]


def __getattr__(name: str):
    """``PackedCDS6n``... and their views by name, made on first use (PEP 562): pickle finds a
    class by module attribute, and these are made by :func:`packed_class`, not defined here
    (a packed CDS batch raised PicklingError "attribute lookup PackedCDS6n ... failed", also in
    a fresh process that had made no packed class yet; sweep 14)."""
    from jaxcds.structures.cds import CDS4n, CDS5n, CDS5nO1, CDS6n

    for base in (CDS6n, CDS5n, CDS4n, CDS5nO1):
        if name == f"Packed{base.__name__}":
            return packed_class(base)
        if name == f"_View{base.__name__}":
            return packed_class(base)._view_cls
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def concatenate_cds(cls, parts: Sequence) -> object:
    """Join CDS structures of class ``cls`` (one per mesh) into one :func:`packed_class` structure
    over the disjoint union: mesh ``i``'s vertex ``u`` is ``o_i + u`` (``o_i`` = vertices of the
    previous meshes), its dart ``d`` is ``6 o_i + d``, its face ``f`` is ``sum_{j<i} (2 n_j - 4) + f``.

    Raises:
      UnsupportedTopologyError: a part of another class, or more than ``2^30`` union vertices
        (the 30-bit reference fields of Sec. 2.1).
    """
    parts = parts_of_one_class(cls, parts)
    nv = np.array([p.num_vertices for p in parts], np.int64)
    total = int(nv.sum())
    if total > _IDX + 1:
        raise errors.UnsupportedTopologyError(
            f"{cls.__name__}.concatenate: {total} vertices in all; the packed references hold at most "
            "2^30 (Sec. 2.1): pack fewer meshes per batch")
    check_id_space(f"{cls.__name__}.concatenate of {total:,} vertices (6 dart ids each)", 6 * total)
    voff = np.concatenate([[0], np.cumsum(nv)[:-1]])
    nf = np.array([p.num_faces for p in parts], np.int64)
    if np.any(nf != 2 * nv - 4):
        i = int(np.argmax(nf != 2 * nv - 4))
        raise errors.StructureError(f"{cls.__name__}.concatenate: part {i} has F = {int(nf[i])} faces for "
                                    f"n = {int(nv[i])} vertices, not 2n - 4 = {2 * int(nv[i]) - 4}")
    foff = np.concatenate([[0], np.cumsum(nf)[:-1]])
    # refs: shift the 30-bit vertex field, keep the service bits 30-31 (Sec. 2.1)
    refs = []
    for p, o in zip(parts, voff):
        x = np.asarray(p.refs).view(np.uint32).astype(np.int64)
        refs.append(((x & _IDX) + o) | (x & ~_IDX & 0xFFFFFFFF))
    refs = np.concatenate(refs).astype(np.uint32).view(np.int32)
    fblue = np.concatenate([np.asarray(p.F_blue, np.int64) + o for p, o in zip(parts, voff)]).astype(np.int32)
    roots = np.array([[p.v_red, p.v_blue, p.v_black] for p in parts], np.int64) + voff[:, None]
    # counted before the array is made: a part with 3 made np.array's untyped "inhomogeneous shape"
    # ValueError, and this refusal was never reached
    counts = [len(p.unused_slots) for p in parts]
    if any(c != 4 for c in counts):
        i = next(k for k, c in enumerate(counts) if c != 4)
        raise errors.StructureError(f"{cls.__name__}.concatenate: every part must have 4 unused face slots; "
                                    f"part {i} has {counts[i]}")
    unused = np.array([sorted(p.unused_slots) for p in parts], np.int64)
    kw = {f.name: getattr(parts[0], f.name) for f in dataclasses.fields(cls)}
    kw.update(refs=to_device(refs), F_blue=to_device(fblue), num_vertices=total,
              num_faces=int(nf.sum()), v_red=-1, v_blue=-1, v_black=-1, unused_slots=(),
              boundaries_closed=any(p.boundaries_closed for p in parts))
    if "target_rounds" in kw:  # chains stay in their mesh: the union needs the most rounds of a part
        rounds = [p.target_rounds for p in parts]
        kw["target_rounds"] = -1 if min(rounds) < 0 else max(rounds)
    dummies = [np.asarray(p.dummy_ids, np.int64) + o for p, o in zip(parts, voff)
               if p.dummy_ids is not None]
    kw["dummy_ids"] = (to_device(np.concatenate(dummies).astype(np.int32)) if dummies else None)
    if "order" in kw:  # cwBFS labels (Sec. 2.3) -> union input ids
        kw["order"] = to_device(np.concatenate(
            [np.asarray(p.order, np.int64) + o for p, o in zip(parts, voff)]).astype(np.int32))
    i32 = lambda a: to_device(np.asarray(a).astype(np.int32))  # noqa: E731
    kw.update(mesh_vertex_offsets=i32(voff), mesh_vertex_counts=i32(nv), mesh_face_offsets=i32(foff),
              mesh_roots=i32(roots), mesh_unused_slots=i32(unused))
    return packed_class(cls)(**kw)
