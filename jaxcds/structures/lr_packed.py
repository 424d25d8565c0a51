"""Packed batches of LR / lr-bits structures (the ``concatenate`` hook of :mod:`jaxcds.batch`).

Paper: Gurung, Luffel, Lindstrom, Rossignac, *LR* (ACM TOG 2011), Sec. 4.2-4.7 and Sec. 6.

Why the union is not one LR (no shift, no global renumbering)
-------------------------------------------------------------
An LR's ids *are* its ring: ring vertices are ``0 .. m_r - 1`` with ``v.n = v + 1 mod m_r``
(Sec. 4.2), ring corners are ``8v + i`` and the T0 corners start at ``8 m_r`` (Sec. 4.7), the
dense face ids come from a popcount directory over the ``2 m_r`` ring slots, and lr-bits stores
``v.l``, ``v.r`` as 15-bit offsets *modulo* ``m_r`` (Sec. 6.1). The union of ``B`` meshes has
``B`` rings, i.e. ``B`` different moduli: shifting mesh ``i``'s ids by an offset breaks
``v.n`` at the end of its ring (it must wrap to the ring's own start), and one global renumbering
(all rings first, then all T0) would need a per-ring modulus and base in every ``v.n`` anyway,
while separating each mesh's corners into two ranges (so per-mesh dart ids are no longer one
contiguous block, as :mod:`jaxcds.batch` wants). A union of rings is not a ring.

So the union *keeps every mesh's ids local*: the arrays of all meshes are concatenated
**unshifted** (lr-bits' relative offsets stay valid: they are differences inside one ring) with
per-mesh start offsets of every array and per-mesh sizes (``m_r``, ``n0``, ...). Each operator
takes global ids, finds the mesh of each element (one binary search over ``B`` offsets), runs the
class's own code on a *view* whose array reads add the element's segment start and whose sizes
are the element's mesh's, and maps the local answer back to a global id (a local sentinel --
a dummy vertex, a border face -- to the global one). Global ids are jraph's packed layout: mesh
``i``'s vertex ``v`` is ``vertex_offsets[i] + v``, dart ``c`` is ``dart_offsets[i] + c`` with
``8 m_r + 4 n0`` darts per mesh, face ``f`` is ``face_offsets[i] + f``.
"""

from __future__ import annotations

import dataclasses
from typing import Optional, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from jaxcds import errors
from jaxcds._arrays import to_device
from jaxcds._dataclass import pytree_dataclass
from jaxcds.structures.base import (_chunk_queries, _jit_whole_mesh, interleave_windows, materialize_loop,
                                    parts_of_one_class, take_nonnegative)
from jaxcds.structures.lr import _slot_triangles

__all__ = ["concatenate_lr", "packed_class"]

#: static sizes of one LR that become per-mesh arrays (columns of ``mesh_sizes``)
_SIZES = ("num_vertices", "num_faces", "num_ring", "num_t0", "num_vos", "num_ring_faces",
          "num_closed_vertices", "num_closed_faces")


class _Seg:
    """The segment ``a[off : off + n]`` of a concatenated array, per query element (``off``,
    ``n`` broadcast with the index): what an LR operator sees as its own array."""

    def __init__(self, a, off, n):
        self.a, self.off, self.n = a, off, n

    def __getitem__(self, i):
        return take_nonnegative(self.a, self.off + i)

    @property
    def shape(self):
        return (self.n,)


def _pair_blocks(x, m: int):
    """Rows of ``x`` with its first two blocks of ``m`` rows side by side: ``x[0], x[m], x[1],
    x[m + 1], ..., x[m - 1], x[2m - 1]``, then ``x[2m:]`` as they are."""
    a, b = x[:m], x[m:2 * m]
    return jnp.concatenate([jnp.stack([a, b], axis=1).reshape((2 * m,) + x.shape[1:]), x[2 * m:]])


def _excl(c):
    """Exclusive cumulative sum of a small ``(B,)`` count array."""
    return jnp.concatenate([jnp.zeros(1, jnp.int32), jnp.cumsum(c)[:-1]]).astype(jnp.int32)


def _chunk_plan(counts, cap: int = 256):
    """``(chunk, span)`` for :func:`_segment_ids` over segments of sizes ``counts`` (numpy, at
    pack time): the largest power-of-two chunk ``<= cap`` in which at most two segments start
    after the chunk's first element (``span`` = that most), else ``(1, 0)`` (one search per
    element: always right)."""
    counts = np.asarray(counts, np.int64)
    total = int(counts.sum())
    if total == 0:
        return (1, 0)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    k = cap
    while k > 1:
        first = np.arange(0, total, k)
        last = np.minimum(first + k - 1, total - 1)
        span = int((np.searchsorted(starts, last, side="right") - np.searchsorted(starts, first, side="right")).max())
        if span <= 2:
            return (k, span)
        k //= 2
    return (1, 0)


def _segment_ids(starts, total: int, plan):
    """Segment (mesh) of every element ``0 .. total - 1`` of a concatenation whose ``B`` segments
    start at ``starts`` (nondecreasing, ``starts[0] = 0``; empty segments allowed): the last ``i``
    with ``starts[i] <= g``.

    ``jnp.repeat(arange(B), counts)`` does this with a cumsum over all ``total`` elements (an
    associative scan on XLA:CPU, about 7 ns per element: 10 ns per vertex for both LR row kinds
    of a random batch). Here one binary search per *chunk* of ``chunk`` elements (``total /
    chunk`` searches over ``B``), then per element the chunk's first segment plus at most
    ``span`` comparisons with the next starts (``plan = (chunk, span)`` from :func:`_chunk_plan`
    at pack time; ``None``: the repeat)."""
    if plan is None:
        b = starts.shape[0]
        counts = jnp.diff(jnp.concatenate([starts, jnp.full((1,), total, starts.dtype)]))
        return jnp.repeat(jnp.arange(b, dtype=jnp.int32), counts, total_repeat_length=total)
    return _window_segment_ids(starts, 0, total, plan)


def _window_segment_ids(starts, w, size: int, plan, total: Optional[int] = None):
    """:func:`_segment_ids` of the elements ``w .. w + size - 1`` only (``w`` may be traced: a
    chunk's window of a packed pemb): one search per ``plan`` chunk the window touches, then
    the plan's ``span`` comparisons per element. Elements at or past ``total`` (when given)
    read as the last one's."""
    b = starts.shape[0]
    chunk, span = plan
    g = w + jnp.arange(size, dtype=jnp.int32)
    if total is not None:
        g = jnp.minimum(g, total - 1)
    c0 = w // chunk
    nc = -(-size // chunk) + 1  # the chunks a window of `size` elements can touch
    first = jnp.searchsorted(starts, (c0 + jnp.arange(nc, dtype=jnp.int32)) * chunk, side="right")
    c = (first - 1).astype(jnp.int32)[jnp.clip(g // chunk - c0, 0, nc - 1)]
    m = c
    for i in range(1, span + 1):
        m = m + ((c + i < b) & (g >= starts[jnp.minimum(c + i, b - 1)])).astype(jnp.int32)
    return m


class _ViewMixin:
    """An LR whose arrays are :class:`_Seg` and whose sizes are arrays (per query element).
    Overrides the three spots of :class:`jaxcds.structures.lr._LRNavigation` that need a Python
    int or a whole array; ``_has_border`` (static) is the union's."""

    chunked_queries = frozenset()  # views carry per-query arrays; the entries build the views
    table_queries = {}  # likewise: a view's sizes are per query, not the union's

    @property
    def has_border(self) -> bool:
        return self._has_border

    def _t0_index(self, c):
        # Sec. 4.7 "i = c - floor(c/4) - 6 m_r", clipped to the mesh's T0 range
        i = c - (c >> 2) - 6 * self.num_ring
        return jnp.clip(i, 0, jnp.maximum(3 * self.num_t0 - 1, 0))

    def edge_of_face(self, f):
        """As the class's (select on the rank directory, then in-word binary lifting), with the
        directory search on the union's cumulative ranks (``_rank_glob``) within the mesh."""
        f = jnp.asarray(f, jnp.int32)
        ring = f < self.num_ring_faces
        fr = jnp.where(ring, f, 0)
        nw = self.slot_rank.shape[0]
        woff = self.slot_rank.off
        w = jnp.searchsorted(self._rank_glob, fr + self._rf_off, side="right").astype(jnp.int32) - 1
        w = jnp.clip(w - woff, 0, nw - 1)
        k = (fr - self.slot_rank[w]).astype(jnp.uint32)
        word = jax.lax.bitcast_convert_type(self.slot_words[w], jnp.uint32)
        pos = jnp.zeros_like(k)
        for step in (16, 8, 4, 2, 1):
            cand = pos + jnp.uint32(step)
            low = jax.lax.population_count(word & ((jnp.uint32(1) << cand) - jnp.uint32(1)))
            pos = jnp.where(low <= k, cand, pos)
        slot = 32 * w + pos.astype(jnp.int32)
        t0 = f - self.num_ring_faces + 2 * self.num_ring
        return (4 * jnp.where(ring, slot, t0)).astype(jnp.int32)


# operator -> (argument kind, result kind); the rest of the protocol is derived from these
_OPS = {
    **{op: ("dart", "vertex") for op in ("origin", "v")},
    **{op: ("dart", "dart") for op in ("twin", "next", "prev", "o", "s", "l", "r", "n", "p",
                                       "corner_opposite", "corner_swing")},
    "dart_valid": ("dart", "bool"),
    "face": ("dart", "face"),
    "edge_of_face": ("face", "dart"),
    **{op: ("vertex", "dart") for op in ("edge_of_vertex", "vc")},
}


class _PackedMixin:
    """Operators of the union (module docstring): global ids in, the class's code on local ids
    of each element's mesh, global ids out."""

    packed = True
    table_queries = {}  # no whole-union table (as the packed CDS kinds)

    def _tables(self, kind):
        if kind == "vertex":
            return self.mesh_vertex_offsets, self.mesh_sizes[:, 0], self.num_vertices
        if kind == "face":
            return self.mesh_face_offsets, self.mesh_sizes[:, 1], self.num_faces
        return self.mesh_dart_offsets, 8 * self.mesh_sizes[:, 2] + 4 * self.mesh_sizes[:, 3], self.num_darts

    def _local(self, kind, x):
        """``(mesh, local id)`` of global ids ``x``; ids out of range stay out of range."""
        off, _, total = self._tables(kind)
        xc = jnp.clip(x, 0, max(total - 1, 0))
        m = (jnp.searchsorted(off, xc, side="right") - 1).astype(jnp.int32)
        return m, (x - off[m]).astype(jnp.int32)

    def _global(self, kind, m, y):
        if kind == "bool":
            return y
        off, cnt, total = self._tables(kind)
        return jnp.where((y < 0) | (y >= cnt[m]), total, off[m] + y).astype(jnp.int32)

    def _view_of(self, m):
        base = type(self)._base
        kw = {f.name: getattr(self, f.name) for f in dataclasses.fields(base)}
        for j, name in enumerate(_SIZES):
            kw[name] = self.mesh_sizes[m, j]
        for j, name in enumerate(self._arrays):
            kw[name] = _Seg(getattr(self, name), self.mesh_array_offsets[m, j],
                            self.mesh_array_lengths[m, j])
        v = type(self)._view_cls(**kw)
        rf = _excl(self.mesh_sizes[:, 5])
        for name, val in (("_has_border", self.has_border), ("_rf_off", rf[m]),
                          ("_rank_glob", self.slot_rank_cumulative)):
            object.__setattr__(v, name, val)
        return v

    @property
    def has_border(self) -> bool:
        return bool(self.union_has_border)

    @property
    def num_darts(self) -> int:
        return self.union_num_darts

    def _packed_rows(self):
        """The slot plan of :meth:`jaxcds.structures.lr._LRNavigation.face_vertices_padded` on the
        union: per ring vertex of the union both slot triangles from one mesh-local decode, per T0
        of the union its ``V0`` row; masks for the redundant T2 copies and border triangles
        (Sec. 4.4, 4.6), plus what the dense order needs. Returns ``(rows (2 M_r + N0, 3) global
        ids, ok, (mesh and local index of each ring vertex, mesh and local index of each T0))``,
        ring rows as left slots then right slots.

        Cost notes (XLA:CPU, measured in ``benchmarks/prof_packed_normals.py``): the mesh of every
        element comes from :func:`_segment_ids` (a chunked search, no cumsum over the rows), the
        per-mesh values (ring start, ``m_r``, vertex offset, ``VO*`` segment, ``n``) are ONE row
        gather of a small ``(B, 6)`` table, and the decoded ring block (five global ids, the two
        masks in their sign bits) is written once (:func:`~jaxcds.structures.base.materialize_loop`)
        before the rows are assembled and interleaved: fused into the interleaved rows instead,
        every column of every row re-ran the mesh lookup and the decode (1.6-1.9x the face list
        before, 1.3x after). The block was first written by an identity scatter of the five
        stacked columns: at 10,000 meshes (27.5M vertices) that route read 1.82x (lr) and 2.07x
        (lr-bits) the face list against 1.42x and 1.51x with the one-trip loop, 1.33x / 1.34x
        against 1.29x / 1.26x at 300 meshes (one-process races, 2026-12-01, RESULTS.md)."""
        nvm, mr, n0 = self.mesh_sizes[:, 0], self.mesh_sizes[:, 2], self.mesh_sizes[:, 3]
        plan = self.row_plan or (None, None)
        rstart = _excl(mr)
        mesh = _segment_ids(rstart, self.num_ring, plan[0])
        jv = self._arrays.index("VOs")
        tab = jnp.stack([rstart, mr, self.mesh_vertex_offsets, self.mesh_array_offsets[:, jv],
                         self.mesh_array_lengths[:, jv], nvm], axis=1)
        meta = take_nonnegative(tab, mesh)  # (M_r, 6): one gather per ring vertex, read by every column below
        v = jnp.arange(self.num_ring, dtype=jnp.int32) - meta[:, 0]
        view = self._ring_view(meta[:, 1], meta[:, 5], _Seg(self.VOs, meta[:, 3], meta[:, 4]))
        # the ring tables are the meshes' own, m_r (LR16: 2 m_r) entries each, in mesh order
        # (checked by concatenate_lr): ring vertex g of the union reads entry g, no gather
        if "LR16" in self._arrays:
            d = view._dec_entries(v, self.LR16[0::2].astype(jnp.int32), self.LR16[1::2].astype(jnp.int32))
        else:
            d = view._dec_entries(self.L, self.R)
        left, right, ok_l, ok_r = _slot_triangles(
            jnp, lambda _: d, view.num_ring, view.num_vertices if self.has_border else None, v)
        voff = meta[:, 2]
        sign = jnp.int32(-2**31)  # ids are < 2^31: the sign bit carries "masked" through the block
        blk = materialize_loop((left[:, 0] + voff, jnp.where(ok_l, 0, sign) | (left[:, 1] + voff),
                                left[:, 2] + voff, right[:, 0] + voff,
                                jnp.where(ok_r, 0, sign) | (right[:, 1] + voff)))
        low = jnp.int32(2**31 - 1)
        lrows = jnp.stack([blk[0], blk[1] & low, blk[2]], axis=1)
        rrows = jnp.stack([blk[3], blk[4] & low, blk[0]], axis=1)
        # T0 rows: the union's V0 as it is plus the mesh's vertex offset when every mesh's V0 is
        # 3 n0 long (V0 has one dummy entry when n0 = 0: then a gather at the mesh's V0 start)
        t0start = _excl(n0)
        mesh0 = _segment_ids(t0start, self.num_t0, plan[1])
        j = jnp.arange(self.num_t0, dtype=jnp.int32) - t0start[mesh0]
        if self.V0.shape[0] == 3 * self.num_t0:
            t0 = self.V0.reshape(self.num_t0, 3)
        else:
            v0_start = self.mesh_array_offsets[mesh0, self._arrays.index("V0")]
            # the column offsets as a row: users may run with rank promotion set to raise
            t0 = self.V0[(v0_start + 3 * j)[:, None] + jnp.arange(3, dtype=jnp.int32)[None, :]]
        if self.has_border:
            nv0 = nvm[mesh0][:, None]
            ok0 = jnp.all(t0 < nv0, axis=1)
            t0 = jnp.minimum(t0, nv0 - 1)
        else:
            ok0 = jnp.ones((self.num_t0,), bool)
        t0 = t0 + self.mesh_vertex_offsets[mesh0][:, None]
        rows = jnp.concatenate([lrows, rrows, t0], axis=0).astype(jnp.int32)
        ok = jnp.concatenate([blk[1] >= 0, blk[4] >= 0, ok0])
        return rows, ok, (mesh, v, mesh0, j)

    def _ring_view(self, num_ring, num_vertices, vos):
        """A view for the ring decode of :meth:`_packed_rows`: sizes and ``VO*`` segment given per
        ring vertex (already gathered), the other arrays the union's (read by union index)."""
        kw = {f.name: getattr(self, f.name) for f in dataclasses.fields(type(self)._base)}
        kw.update(num_ring=num_ring, num_vertices=num_vertices, VOs=vos)
        v = type(self)._view_cls(**kw)
        object.__setattr__(v, "_has_border", self.has_border)
        return v

    def face_vertices_padded(self):
        """Every face of every mesh once (any order; see
        :meth:`jaxcds.structures.base.MeshStructure.face_vertices_padded`): one decode per ring
        vertex of the union, no per-face navigation."""
        rows, ok, _ = self._packed_rows()
        # each ring vertex's two slot rows side by side, then windows of 8 x 8 rows interleaved
        # (base.interleave_windows): no run of one apex for the scatter-adds, and the rows keep
        # the batch's mesh-by-mesh order, where interleave_rows's 8 blocks read 8 far-apart parts
        # of the union at once. Routes in rotated turns, 10 rounds: 3,000 random meshes (8.2M
        # vertices) 1.21x the face list against 1.36x with the blocks, 300 meshes 1.20x / 1.25x;
        # at 10,000 meshes both vary 1.3-2.1x from run to run (benchmarks/RESULTS.md)
        m = self.num_ring
        rows, ok = _pair_blocks(rows, m), _pair_blocks(ok, m)
        return interleave_windows(rows), interleave_windows(ok)

    def normal_row_blocks(self):
        """:meth:`_packed_rows` as three blocks in mesh order (left ring slots, right ring slots,
        T0 rows), for the chunked sums of :mod:`jaxcds.batch`: mesh ``i``'s rows are its
        ``m_r`` ring vertices' (twice) and its ``n0`` T0 triangles, every id in the mesh."""
        rows, ok, _ = self._packed_rows()
        m = self.num_ring
        return [(rows[:m], ok[:m]), (rows[m:2 * m], ok[m:2 * m]), (rows[2 * m:], ok[2 * m:])]

    def normal_row_counts(self):
        """Host-side rows per mesh of each :meth:`normal_row_blocks` block: ``m_r``, ``m_r``,
        ``n0``."""
        sizes = np.asarray(self.mesh_sizes, np.int64)
        return [sizes[:, 2], sizes[:, 2], sizes[:, 3]]

    def face_vertices(self):
        """``(F, 3)`` in the union's face order (mesh by mesh, each in its dense face order): the
        rows of :meth:`face_vertices_padded` scattered to ``face_offsets[mesh]`` + their local
        face id (directory rank of a ring slot; ring faces + index of a real T0)."""
        rows, ok, (mesh, v, mesh0, j) = self._packed_rows()
        meshes = jnp.concatenate([mesh, mesh, mesh0])
        local = jnp.concatenate([2 * v, 2 * v + 1, j])
        nf, nring = self.num_faces, 2 * self.num_ring
        bit, rank = self._view_of(meshes[:nring])._slot_rank(local[:nring])
        nrf = self.mesh_sizes[meshes, 5]
        j = local[nring:]
        real0 = j < self.mesh_sizes[meshes[nring:], 1] - nrf[nring:]
        loc = jnp.concatenate([jnp.where(bit, rank, -1), jnp.where(real0, nrf[nring:] + j, -1)])
        # rows that are no face go past the end, each to its own index (the indices stay unique)
        dest = jnp.where(loc >= 0, self.mesh_face_offsets[meshes] + loc,
                         nf + jnp.arange(loc.shape[0], dtype=jnp.int32))
        out = jnp.zeros((nf, 3), jnp.int32)
        return out.at[dest].set(rows, mode="drop", unique_indices=True)

    @property
    def references(self) -> int:
        """Sum of the meshes' counts (the per-mesh tables are batch metadata, not counted)."""
        return int(self.union_references)

    @property
    def aux_references(self) -> int:
        return int(self.slot_words.shape[0] + self.slot_rank.shape[0])


def _make_entry(name, arg, res):
    def method(self, x):
        m, loc = self._local(arg, jnp.asarray(x, jnp.int32))
        return self._global(res, m, getattr(self._view_of(m), name)(loc))

    method.__name__ = name
    method.__doc__ = f"The class's ``{name}`` on the local ids of each element's mesh (global ids)."
    return method


for _name, (_arg, _res) in _OPS.items():
    setattr(_PackedMixin, _name, _make_entry(_name, _arg, _res))
# the union's chunked queries: each chunk finds its elements' meshes and builds its own view
_chunk_queries(_PackedMixin)
_jit_whole_mesh(_PackedMixin)

_FIELDS = ("mesh_vertex_offsets", "mesh_face_offsets", "mesh_dart_offsets", "mesh_sizes",
           "mesh_array_offsets", "mesh_array_lengths", "slot_rank_cumulative")
_STATIC = ("union_num_darts", "union_has_border", "union_references")
_CLASSES: dict = {}


def packed_class(base):
    """The packed (union) class of ``base`` (``LR`` or ``LRBits``): ``base``'s array fields
    concatenated unshifted, its sizes those of the union, plus per-mesh tables (``(B,)`` offsets
    of vertices, faces, darts; ``mesh_sizes`` ``(B, 8)``; start and length of every array per
    mesh) and ``slot_rank_cumulative`` (the rank directories shifted by the ring faces of the
    previous meshes: the directory search of ``edge_of_face``)."""
    if base not in _CLASSES:
        from jaxcds._dataclass import static_field

        arrays = tuple(f.name for f in dataclasses.fields(base)
                       if not f.metadata.get("static", False) and f.name != "order")
        ns = {"__annotations__": {**{f: jnp.ndarray for f in _FIELDS}, **{f: int for f in _STATIC},
                                  "row_plan": tuple},
              **{f: None for f in _FIELDS}, **{f: static_field(default=0) for f in _STATIC},
              "row_plan": static_field(default=()),
              "_base": base, "_arrays": arrays, "chunked_queries": base.chunked_queries,
              "__module__": __name__}
        cls = pytree_dataclass(type(f"Packed{base.__name__}", (_PackedMixin, base), ns))
        cls._view_cls = type(f"_View{base.__name__}", (_ViewMixin, base), {"__module__": __name__})
        _CLASSES[base] = cls
    return _CLASSES[base]


def __getattr__(name: str):
    """``PackedLR``, ``PackedLRBits`` and their views by name, made on first use (PEP 562):
    pickle finds a class by module attribute, and these are made by :func:`packed_class`, not
    defined here (a packed LR batch raised PicklingError "attribute lookup PackedLR ... failed";
    sweep 14)."""
    from jaxcds.structures.lr import LR, LRBits

    for base in (LR, LRBits):
        if name == f"Packed{base.__name__}":
            return packed_class(base)
        if name == f"_View{base.__name__}":
            return packed_class(base)._view_cls
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def concatenate_lr(cls, parts: Sequence) -> object:
    """Join LR (or LRBits) structures, one per mesh, into one :func:`packed_class` structure.

    Raises:
      UnsupportedTopologyError: a part of another class, or an id over int32.
    """
    parts = parts_of_one_class(cls, parts)
    P = packed_class(cls)
    sizes = np.array([[getattr(p, s) for s in _SIZES] for p in parts], np.int64)
    nd = np.array([p.num_darts for p in parts], np.int64)
    if np.any(nd != 8 * sizes[:, 2] + 4 * sizes[:, 3]):
        raise errors.StructureError(f"{cls.__name__}.concatenate: num_darts != 8 m_r + 4 n0")
    excl = lambda c: np.concatenate([[0], np.cumsum(c)[:-1]])  # noqa: E731
    lens = np.array([[np.asarray(getattr(p, a)).shape[0] for a in P._arrays] for p in parts], np.int64)
    if max(int(nd.sum()), int(sizes[:, 7].sum()) * 3, int(lens.sum(axis=0).max())) >= 2**31 - 1:
        raise errors.UnsupportedTopologyError(
            f"{cls.__name__}.concatenate: ids over int32; pack fewer meshes per batch")
    ring = [a for a in ("L", "R", "LR16") if a in P._arrays]
    per_ring = 2 if ring == ["LR16"] else 1
    for a in ring:  # the slot plan of face_vertices_padded reads these by union ring index
        wrong = lens[:, P._arrays.index(a)] != per_ring * sizes[:, 2]
        if np.any(wrong):
            i = int(np.argmax(wrong))
            raise errors.StructureError(f"{cls.__name__}.concatenate: part {i}'s {a} has "
                                        f"{int(lens[i, P._arrays.index(a)])} entries, not {per_ring} m_r = "
                                        f"{per_ring * int(sizes[i, 2])}")
    kw = {f.name: getattr(parts[0], f.name) for f in dataclasses.fields(cls)}
    for a in P._arrays:
        kw[a] = to_device(np.concatenate([np.asarray(getattr(p, a)) for p in parts]))
    for j, s in enumerate(_SIZES):
        kw[s] = int(sizes[:, j].sum())
    if "num_long" in kw:  # lr-bits: long entries in all; the period k is per mesh (construction only)
        kw["num_long"] = int(sum(p.num_long for p in parts))
        kw["k"] = int(parts[0].k) if len({p.k for p in parts}) == 1 else -1
    kw["order"] = to_device(np.concatenate(
        [np.asarray(p.order, np.int64) + o for p, o in zip(parts, excl(sizes[:, 0]))]).astype(np.int32))
    rf_off = excl(sizes[:, 5])
    rank_cum = np.concatenate([np.asarray(p.slot_rank, np.int64) + o for p, o in zip(parts, rf_off)])
    i32 = lambda a: to_device(np.asarray(a).astype(np.int32))  # noqa: E731
    kw.update(mesh_vertex_offsets=i32(excl(sizes[:, 0])), mesh_face_offsets=i32(excl(sizes[:, 1])),
              mesh_dart_offsets=i32(excl(nd)), mesh_sizes=i32(sizes),
              mesh_array_offsets=i32(np.stack([excl(lens[:, j]) for j in range(lens.shape[1])], axis=1)),
              mesh_array_lengths=i32(lens), slot_rank_cumulative=i32(rank_cum),
              union_num_darts=int(nd.sum()), union_has_border=any(p.has_border for p in parts),
              union_references=int(sum(p.references for p in parts)),
              row_plan=(_chunk_plan(sizes[:, 2]), _chunk_plan(sizes[:, 3])))
    return P(**kw)
