"""Packed batches of pemb structures (the ``concatenate`` hook of :mod:`jaxcds.batch`).

Paper: Ferres, Fuentes-Sepúlveda, Gagie, He, Navarro, *Fast and Compact Planar Embeddings*
(WADS 2017, CGTA 2020), Sec. 3; the half-edge facade of Salinas-Fernández et al. (IMR 2023).

Why the union of pembs is (almost) a pemb
-----------------------------------------
A pemb is the walk around a spanning tree: ``A`` (``2m`` bits, 1 = tree half-edge) and the
balanced sequence ``B B*`` (tree, then dual tree), read with rank/select on ``A`` and ``match`` /
``enclose`` on ``B B*``. For ``B`` meshes take

    ``A = A_1 A_2 ... A_B``    and    ``P = B_1 B_2 ... B_B  B*_1 B*_2 ... B*_B``.

Every ``B_i`` and ``B*_i`` is balanced, so a ``match`` or an ``enclose`` that starts inside one of
them ends inside it (or finds no enclosing pair: depth 0, the excess of the whole prefix before a
balanced block is 0), and ``rank1(A, i)`` of a half-edge of mesh ``i`` is exactly the offset of
its parenthesis in ``B_1 ... B_B`` (the ones of the earlier meshes are their ``B``'s symbols),
``rank0(A, i)`` that in ``B*_1 ... B*_B``. So ``mate`` (twin) runs on the union unchanged, and
the global dart id is the position in ``A``: mesh ``i``'s local dart ``d`` is
``dart_offsets[i] + d`` (jraph's packed layout).

What is per mesh (each case found by the mesh of the query's dart, vertex or face: one binary
search over the ``B`` offsets). :class:`~jaxcds.structures.pemb.PEMB`'s own queries read these
through hooks (``_dart_mesh``, ``_walk_start``, ``_root_vertex``...), constants for one pemb;
:class:`PackedPEMB` only answers the hooks:

* the *roots*: each mesh's tree root (local vertex 0) and root face (local pemb face 0) have no
  parenthesis pair, so they are ``vertex_offsets[i]`` / ``pface_offsets[i]``; every other node
  opened by a ``(`` of ``B`` has preorder ``rank_open(q) + 1`` in its mesh, i.e. the global id
  ``rank_open(q) + 1 + i`` (the ``i`` earlier roots are the only vertices without a ``(``); faces
  the same with ``B*``;
* the cyclic ``next``/``prev`` around a vertex wrap at the ends of the mesh's own walk
  (``dart_offsets[i]`` and ``dart_offsets[i + 1] - 1``), not of the union's;
* ``first_dual`` of a root face (the ``)`` matching the first ``(`` of that mesh's ``B*``), one
  entry per mesh computed when the batch is built.

Border loops are pemb faces read as "no face" (:class:`~jaxcds.structures.pemb.PEMB`): their
global ids sorted make the union's ``holes``, and the dense face renumbering of a single pemb
(``g`` minus the border loops before it) then gives mesh ``i``'s face ``f`` the global id
``face_offsets[i] + f`` unchanged. The union keeps pemb's memory: ``4m`` bits plus support, and
``5`` int32 per *mesh* of batch metadata.
"""

from __future__ import annotations

import dataclasses
from typing import Optional, Sequence

import jax.numpy as jnp
import numba
import numpy as np

from jaxcds import errors
from jaxcds._args import is_integer
from jaxcds._arrays import to_device
from jaxcds._dataclass import pytree_dataclass, static_field
from jaxcds.structures.base import Int, parts_of_one_class
from jaxcds.structures.lr_packed import _chunk_plan, _segment_ids, _window_segment_ids
from jaxcds.structures.pemb import PEMB, TableOperators, chain_ends
from jaxcds.structures.succinct import BalancedParens, BitVector
from jaxcds.structures.succinct import bp as _bp

__all__ = ["PackedPEMB", "PackedPEMBTables", "concatenate_pemb"]


def _owner(offsets, x):
    """Mesh whose range starting at ``offsets`` holds ``x`` (``offsets`` nondecreasing): the last
    ``i`` with ``offsets[i] <= x``; ids out of range read as the first or the last mesh."""
    m = jnp.searchsorted(offsets, x, side="right") - 1
    return jnp.clip(m, 0, offsets.shape[0] - 1).astype(jnp.int32)


#: chunks from which the packed normals derive each chunk's rows apart
#: (:meth:`PackedPEMB.normal_row_chunks`). Every chunk's windows have the largest chunk's size
#: (static shapes), so a plan of few chunks repeats work; races of 2026-12-06 (Zen 3 host,
#: random meshes of 500-5,000 vertices, chunked / whole-union rows, paired medians): 3 chunks
#: 1.21x, 7 chunks 1.00x, 14 chunks 1.06x; 44 chunks (5.6M vertices) 0.93x, and 0.14 GB
#: instead of 1.9 GB of peak for the normals.
CHUNKED_ROWS_FROM = 16


@pytree_dataclass
class PackedPEMB(PEMB):
    """``B`` pembs as one (module docstring): ``A`` and ``B B*`` of the meshes concatenated, the
    protocol on global ids (a dart is its position in ``A``).

    Fields (besides :class:`~jaxcds.structures.pemb.PEMB`'s, which hold the union; ``(B,)``
    int32 each):
      mesh_dart_offsets, mesh_vertex_offsets, mesh_face_offsets: first global dart, vertex,
        face (triangle) of each mesh.
      mesh_pface_offsets: first global pemb face (triangles and border loops) of each mesh.
      mesh_root_dual: ``first_dual`` of each mesh's root face, a global dart.
    """

    mesh_dart_offsets: Optional[jnp.ndarray] = None
    mesh_vertex_offsets: Optional[jnp.ndarray] = None
    mesh_face_offsets: Optional[jnp.ndarray] = None
    mesh_pface_offsets: Optional[jnp.ndarray] = None
    mesh_root_dual: Optional[jnp.ndarray] = None
    #: chunk plans of the segment searches (lr_packed._chunk_plan) over B, B* and the faces
    plans: tuple = static_field(default=((1, 0), (1, 0), (1, 0)))

    packed = True

    # ------------------------------------------------------------------ the mesh of an id
    # (PEMB's hooks: every pemb query reads its roots, walk ends and shift from these)
    def _dart_mesh(self, i):
        return _owner(self.mesh_dart_offsets, i)

    def _vertex_mesh(self, v):
        return _owner(self.mesh_vertex_offsets, v)

    def _pface_mesh(self, g):
        return _owner(self.mesh_pface_offsets, g)

    def _walk_start(self, m):
        return self.mesh_dart_offsets[m]

    def _walk_end(self, m):
        nxt = self.mesh_dart_offsets[jnp.minimum(m + 1, self.mesh_dart_offsets.shape[0] - 1)]
        return jnp.where(m + 1 < self.mesh_dart_offsets.shape[0], nxt, self.num_darts)

    def _root_vertex(self, m):
        return self.mesh_vertex_offsets[m]

    def _root_face(self, m):
        return self.mesh_pface_offsets[m]

    def _root_dual(self, m):
        return self.mesh_root_dual[m]

    # ------------------------------------------------------------------ with_tables hooks
    _VB_ROOT = -1  # a depth-0 prefix of B: the root of the DART's mesh (resolved in vertex)

    def _table_classes(self):
        return PackedPEMB, PackedPEMBTables

    @property
    def _num_pemb_faces(self) -> int:
        # each mesh's B* pairs plus its root face
        return (self.P.size - self.num_tree_parens) // 2 + int(self.mesh_pface_offsets.shape[0])

    def _faces_opened_at(self, P, q):
        # q: every position of B*, in order: the mesh of each by the chunked segment search
        # (a jnp.searchsorted per element cost about 120-150 ns per vertex at 100 meshes)
        m = _segment_ids(self._dual_starts(), q.shape[0], self.plans[1])
        return P.rank_open(q) - self.num_tree_parens // 2 + 1 + m

    def _vertices_opened_before(self, P, q):
        # q: every prefix length 0 .. ntp of B; q - 1 (a '(' of B) lies in mesh m, whose B starts
        # after the 2 (n_j - 1) parentheses of the earlier meshes
        ntp = self.num_tree_parens
        m = _segment_ids(self._tree_starts(), ntp, self.plans[0])
        m = jnp.concatenate([jnp.zeros((1,), jnp.int32), m])
        return P.rank_open(jnp.maximum(q - 1, 0)) + 1 + m

    def _tree_block_starts(self, q):
        # each mesh's B starts a chain of its own (else the pointer doubling of vb ran through the
        # top-level subtrees of every earlier mesh: more rounds)
        return jnp.zeros(q.shape, bool).at[self._tree_starts()].set(True, mode="drop")

    def _tree_starts(self):
        """Where each mesh's ``B`` starts in ``P``: after the ``2 (n_j - 1)`` parentheses of the
        earlier meshes."""
        return 2 * (self.mesh_vertex_offsets - self._mesh_index())

    def _dual_starts(self):
        """Where each mesh's ``B*`` starts in the ``B*`` part of ``P``: after the
        ``2 (f_j - 1)`` parentheses of the earlier meshes (``f_j`` pemb faces)."""
        return 2 * (self.mesh_pface_offsets - self._mesh_index())

    def _mesh_index(self):
        return jnp.arange(self.mesh_vertex_offsets.shape[0], dtype=jnp.int32)

    def _root_faces(self):
        return self.mesh_pface_offsets, self.mesh_root_dual

    # ------------------------------------------------------------------ whole-mesh work
    def face_vertices(self) -> Int:
        """``(num_faces, 3)``, mesh by mesh: as :meth:`PEMB.face_vertices` (per-call tables),
        but the mesh of each face is known (faces come in mesh order), so the walk's wrap and
        the roots are read per face instead of a search over the mesh offsets per dart."""
        t = self.with_tables()
        f = jnp.arange(self.num_faces, dtype=jnp.int32)
        m = _segment_ids(self.mesh_face_offsets, self.num_faces, self.plans[2])
        return t._faces_walked(f, m, lambda e: t.tw[e], t.first_dual, lambda r: t.vb[r])

    def _faces_walked(self, f, m, twin, first_dual, vb):
        """``(len(f), 3)`` vertices of faces ``f`` (of meshes ``m``), ccw: each face's first
        dart, two ``next`` (``prev_p(mate(e))`` within the mesh's walk), three origins, read
        through tables: ``twin(dart)``, ``first_dual(pemb face)``, ``vb(prefix of B)``."""
        A = self.A
        lo, hi = self._walk_start(m), self._walk_end(m)

        def nxt(e):
            x = twin(e)
            j = jnp.where(x == lo, hi - 1, x - 1)
            return jnp.where(A.access(j) == 1, twin(j), j)

        e0 = first_dual(self._from_mesh_face(f))
        e1 = nxt(e0)
        e2 = nxt(e1)
        root = self._root_vertex(m)
        org = [jnp.where(v < 0, root, v) for v in (vb(A.rank1(e)) for e in (e0, e1, e2))]
        return jnp.stack(org, axis=-1).astype(jnp.int32)

    # ------------------------------------------------------------------ batch hooks
    def normal_row_blocks(self):
        """The faces, mesh by mesh (one block): the whole-union rows (:meth:`face_vertices`).
        The chunked sums of :mod:`jaxcds.batch` derive them chunk by chunk instead
        (:meth:`normal_row_chunks`)."""
        return [(self.face_vertices(), None)]

    def normal_row_counts(self):
        """Per mesh (host): faces (the rows), then what :meth:`normal_row_chunks` reads of each
        chunk: darts, ``B`` parentheses, ``B*`` parentheses, pemb faces."""
        def counts(off, total):
            return np.diff(np.concatenate([np.asarray(off, np.int64), [total]]))

        nv = counts(self.mesh_vertex_offsets, self.num_vertices)
        npf = counts(self.mesh_pface_offsets, self._num_pemb_faces)
        return [counts(self.mesh_face_offsets, self.num_faces),
                counts(self.mesh_dart_offsets, self.num_darts), 2 * (nv - 1), 2 * (npf - 1), npf]

    def normal_row_chunks(self, num_chunks: int):
        """``rows_of_chunk(lo, hi, caps) -> [(rows, ok)]``: the faces of one chunk of whole meshes
        (:func:`jaxcds.batch.chunk_plan` over :meth:`normal_row_counts`), derived from that
        chunk alone: :meth:`face_vertices`'s route on tables of the chunk's darts, parentheses
        and faces instead of the whole union's. ``None`` (the whole-union rows) under
        :data:`CHUNKED_ROWS_FROM` chunks.

        Why: the twin and vertex tables of the whole union and their search temporaries are
        tens of bytes per vertex (16 GB at 10,000 meshes, 27.5M vertices, stop 40); a chunk's are
        dropped with it. Every ``match`` of a chunk's parenthesis stays in its mesh (balanced
        blocks), so a chunk's tables are complete for its own darts; the searches read the
        union's bits and min-max tree, which are not copied. The word ranks (1 bit per bit) are
        built once, before the loop."""
        if num_chunks < CHUNKED_ROWS_FROM:
            return None
        A, P = self._word_ranked()
        s = dataclasses.replace(self, A=A, P=P)
        return lambda lo, hi, caps: s._rows_of_chunk(lo, hi, caps)

    def _rows_of_chunk(self, lo, hi, caps):
        """The chunk's faces (``[(rows, ok)]``) from tables of its own ids: ``lo`` / ``hi`` are
        the chunk's first / one-past-last vertex, face, dart, ``B`` and ``B*`` parenthesis and
        pemb face (the columns of :meth:`normal_row_counts`), ``caps`` the static window sizes."""
        A, ntp = self.A, self.num_tree_parens
        _, fcap, dcap, tcap, scap, gcap = caps
        if min(fcap, dcap, tcap, scap, gcap) == 0:  # no such chunk in a plan (every mesh has faces)
            raise errors.StructureError("packed pemb: a chunk without faces or parentheses")
        w = _ChunkWindows(
            face=jnp.minimum(lo[1], self.num_faces - fcap),
            dart=jnp.minimum(lo[2], self.num_darts - dcap),
            tree=jnp.minimum(lo[3], ntp - tcap),
            dual=jnp.minimum(lo[4], self.P.size - ntp - scap),
            pface=jnp.minimum(lo[5], self._num_pemb_faces - gcap), caps=caps, ntp=ntp)
        match, is_open_mine = self._chunk_matches(w, lo, hi)
        d = w.dart + jnp.arange(dcap, dtype=jnp.int32)
        t1 = A.rank1(d)
        par = w.local(jnp.where(A.access(d) == 1, t1, ntp + d - t1))  # each dart's parenthesis
        mine = (d >= lo[2]) & (d < hi[2])
        pos_of = jnp.zeros((tcap + scap,), jnp.int32).at[jnp.where(mine, par, tcap + scap)].set(
            d, mode="drop")
        tw = pos_of[match[par]]  # the twin of every dart of the chunk
        fe = self._chunk_first_duals(w, pos_of, is_open_mine[tcap:])
        vb = self._chunk_vertex_table(w, match)
        f = w.face + jnp.arange(fcap, dtype=jnp.int32)
        m = _window_segment_ids(self.mesh_face_offsets, w.face, fcap, self.plans[2])

        def first_dual(g):  # roots have no '(' in B*: read apart, as with_tables' fe does
            return jnp.where(g == self._root_face(m), self._root_dual(m), fe[g - w.pface])

        rows = self._faces_walked(f, m, lambda e: tw[e - w.dart], first_dual,
                                  lambda r: vb[r - w.tree])
        return [(rows, (f >= lo[1]) & (f < hi[1]))]

    def _chunk_matches(self, w, lo, hi):
        """``(match, open & mine)`` over the chunk's parenthesis windows (``B``'s, then
        ``B*``'s; chunk indices): :meth:`~BalancedParens.match_all` of those positions only (a
        search from each ``(`` of the chunk, its ``)`` written by a scatter). Entries of other
        meshes (a window that starts before the chunk) are unspecified. With
        :data:`~jaxcds.structures.succinct.bp.MATCH_BY_SORT`, one sort by level over the
        window's own positions (each mesh's ``B`` and ``B*`` are balanced blocks)."""
        P, ntp, tcap = self.P, self.num_tree_parens, w.caps[3]
        size = tcap + w.caps[4]
        r = jnp.arange(size, dtype=jnp.int32)
        q = jnp.where(r < tcap, w.tree + r, ntp + w.dual + r - tcap)
        mine = jnp.where(r < tcap, (q >= lo[3]) & (q < hi[3]),
                         (q - ntp >= lo[4]) & (q - ntp < hi[4]))
        if _bp.MATCH_BY_SORT:  # one sort by level over the window (the GPU candidate)
            return _bp.matches_by_level(P.is_open(q), mine), P.is_open(q) & mine
        op = P.is_open(q) & mine
        match = w.local(P.closes_of(q, op))
        return match.at[jnp.where(op, match, size)].set(r, mode="drop"), op

    def _chunk_first_duals(self, w, pos_of, opens):
        """``first_dual`` of the chunk's pemb faces (window ``w.pface``): the crossing that enters
        a face is the dart of its ``(`` in ``B*`` (PEMB.with_tables); roots are read apart."""
        ntp, scap, gcap = self.num_tree_parens, w.caps[4], w.caps[5]
        u = jnp.arange(scap, dtype=jnp.int32)
        m = _window_segment_ids(self._dual_starts(), w.dual, scap, self.plans[1])
        g = self.P.rank_open(ntp + w.dual + u) - ntp // 2 + 1 + m
        return jnp.zeros((gcap,), jnp.int32).at[jnp.where(opens, g - w.pface, gcap)].set(
            pos_of[w.caps[3] + u], mode="drop")

    def _chunk_vertex_table(self, w, match):
        """``vb`` (PEMB.with_tables) for the prefixes ``w.tree .. w.tree + tcap`` of ``B``: after
        a ``(`` the vertex it opens, at a mesh's start its root (``-1``), after a ``)`` the
        entry before its ``(`` (pointer doubling over the chunk)."""
        P, ntp, tcap = self.P, self.num_tree_parens, w.caps[3]
        k = jnp.arange(tcap + 1, dtype=jnp.int32)
        q = w.tree + k
        starts = self._tree_starts()
        m_q = _window_segment_ids(starts, w.tree, tcap + 1, self.plans[0], ntp)
        m_before = _window_segment_ids(starts, jnp.maximum(w.tree - 1, 0), 1, self.plans[0], ntp)
        m_p = jnp.concatenate([m_before, m_q[:-1]])  # the mesh of the parenthesis at q - 1
        start = (q == 0) | (m_q != m_p)
        prev_open = P.is_open(jnp.maximum(q - 1, 0)) & ~start
        val = jnp.where(prev_open, P.rank_open(jnp.maximum(q - 1, 0)) + 1 + m_p, self._VB_ROOT)
        back = match[jnp.maximum(k - 1, 0)]  # the '(' of the ')' at q - 1, as a prefix index
        # chains go back over earlier siblings only; anything else (other meshes' entries) stops
        ptr = jnp.where(~start & ~prev_open & (back >= 0) & (back < k), back, k)
        return val[chain_ends(ptr)].astype(jnp.int32)

    def __repr__(self) -> str:
        return (f"PackedPEMB(meshes={int(self.mesh_dart_offsets.shape[0])}, "
                + super().__repr__()[len("PEMB("):])


@pytree_dataclass
class PackedPEMBTables(TableOperators, PackedPEMB):
    """:class:`PackedPEMB` with per-phase tables (as :class:`~jaxcds.structures.pemb.PEMBTables`);
    ``vb`` holds ``-1`` for a depth-0 prefix of ``B``, read as the root of the dart's mesh."""

    tw: Optional[jnp.ndarray] = None
    vb: Optional[jnp.ndarray] = None
    fe: Optional[jnp.ndarray] = None


@dataclasses.dataclass(frozen=True)
class _ChunkWindows:
    """Where a chunk's windows start (traced scalars) in the union's faces, darts, ``B`` and
    ``B*`` parentheses and pemb faces; ``caps`` their static sizes (the chunk plan's)."""

    face: jnp.ndarray
    dart: jnp.ndarray
    tree: jnp.ndarray
    dual: jnp.ndarray
    pface: jnp.ndarray
    caps: tuple
    ntp: int

    def local(self, x):
        """A parenthesis of ``B B*`` -> its index in the chunk's windows (``B``'s, then ``B*``'s)."""
        return jnp.where(x < self.ntp, x - self.tree, self.caps[3] + x - self.ntp - self.dual)


def concatenate_pemb(cls, parts: Sequence) -> PackedPEMB:
    """Join pembs, one per mesh, into one :class:`PackedPEMB` (module docstring).

    Raises:
      UnsupportedTopologyError: a part of another class, or ids over int32.
    """
    if cls is not PEMB:  # a packed union's roots are per mesh: joining unions loses them
        what = ("a packed batch cannot be packed again" if getattr(cls, "packed", False)
                else "a pemb with tables cannot be packed: pack the pembs it was made from")
        raise errors.UnsupportedTopologyError(
            f"{cls.__name__}.concatenate: pack the single pembs ({what})")
    parts = parts_of_one_class(PEMB, parts)
    bits = [_part_bits(i, p) for i, p in enumerate(parts)]  # before any count is read
    nd = np.array([p.num_darts for p in parts], np.int64)
    nv = np.array([p.num_vertices for p in parts], np.int64)
    nf = np.array([p.num_faces for p in parts], np.int64)
    ntp = np.array([p.num_tree_parens for p in parts], np.int64)
    npf = np.array([p._num_pemb_faces for p in parts], np.int64)
    if max(int(nd.sum()), int(nv.sum()), int(npf.sum())) >= 2**31 - 1:
        raise errors.UnsupportedTopologyError(
            f"{cls.__name__}.concatenate: {int(nd.sum())} darts, ids over int32; pack fewer meshes "
            "per batch")
    excl = lambda c: np.concatenate([[0], np.cumsum(c)[:-1]])  # noqa: E731
    doff, voff, foff, pfoff = excl(nd), excl(nv), excl(nf), excl(npf)
    a = np.concatenate([x for x, _ in bits])
    pb = [x for _, x in bits]
    seq = np.concatenate([b[:t] for b, t in zip(pb, ntp)] + [b[t:] for b, t in zip(pb, ntp)])
    P = BalancedParens._from_valid_bits(seq, check=False)  # the parts' bits: balanced blocks
    holes = np.concatenate([np.asarray(p.holes, np.int64) + o for p, o in zip(parts, pfoff)])
    order = np.concatenate([np.asarray(p.order, np.int64) + o for p, o in zip(parts, voff)])
    i32 = lambda x: to_device(np.asarray(x).astype(np.int32))  # noqa: E731
    s = PackedPEMB(
        A=BitVector._from_valid_bits(a), P=P, holes=i32(holes), order=i32(order),
        num_vertices=int(nv.sum()), num_faces=int(nf.sum()), num_edges=int(nd.sum()) // 2,
        num_tree_parens=int(ntp.sum()), root_border=all(p.root_border for p in parts),
        mesh_dart_offsets=i32(doff), mesh_vertex_offsets=i32(voff), mesh_face_offsets=i32(foff),
        mesh_pface_offsets=i32(pfoff), mesh_root_dual=i32(np.zeros(len(parts))),
        plans=(_chunk_plan(ntp), _chunk_plan(2 * (npf - 1)), _chunk_plan(nf)))
    # first_dual of each root face: the ')' matching the first '(' of the mesh's B* (PEMB.first_dual),
    # or the mesh's last dart when it has no dual parenthesis; one host pass over the meshes' own
    # B* and A (a jitted match on the union compiled a search program per pack: about 1.2 s)
    root_dual = _root_duals(seq, int(ntp.sum()) + excl(2 * (npf - 1)).astype(np.int64),
                            (2 * (npf - 1)).astype(np.int64), a, doff.astype(np.int64), nd.astype(np.int64))
    return dataclasses.replace(s, mesh_root_dual=i32(root_dual))


def _part_bits(i: int, p) -> tuple:
    """Host ``(A, B B*)`` of part ``i``, after checking that its fields agree as
    :meth:`PEMB.from_bits` makes them: :func:`_root_duals` reads the bits at offsets computed
    from the counts (``num_edges``, ``num_tree_parens``...), and numba checks no index, so a part
    assembled by hand with a count larger than its bits read past them (a segfault), or packed
    quietly with the next mesh's bits.

    Raises:
      StructureError: naming the part and the field that disagrees."""
    def bad(msg):
        raise errors.StructureError(f"PEMB.concatenate: part {i}: {msg} (a pemb assembled by hand? "
                                    "build it with PEMB.from_bits)")

    if not isinstance(p.A, BitVector) or not isinstance(p.P, BalancedParens) \
            or not isinstance(p.P.bits, BitVector):
        bad(f"A must be a BitVector and P a BalancedParens, got {type(p.A).__name__} and "
            f"{type(p.P).__name__}")
    for name in ("num_vertices", "num_faces", "num_edges", "num_tree_parens"):
        x = getattr(p, name)
        if not is_integer(x) or x < 0:
            bad(f"{name} = {x!r} is not a count")
    try:
        a, pb = p.A.to_numpy(), p.P.bits.to_numpy()
    except (TypeError, ValueError) as exc:  # words that are no array of words
        bad(f"the words of A or P are not readable bits ({exc})")
    if a.size != p.A.size or pb.size != p.P.size:
        bad(f"A or P holds fewer words than its size ({p.A.size} and {p.P.size} bits)")
    if a.size != p.num_darts or pb.size != a.size:
        bad(f"A has {a.size} bits and P {pb.size} parentheses for {p.num_edges} edges "
            f"({p.num_darts} darts)")
    ntp = int(np.count_nonzero(a))
    if ntp != p.num_tree_parens or ntp != 2 * (p.num_vertices - 1):
        bad(f"A has {ntp} ones (tree parentheses) but num_tree_parens = {p.num_tree_parens} and "
            f"num_vertices = {p.num_vertices} (2 (n - 1) = {2 * (p.num_vertices - 1)})")
    opens = (int(np.count_nonzero(pb[:ntp])), int(np.count_nonzero(pb[ntp:])))
    if opens != (ntp // 2, (pb.size - ntp) // 2) or (pb.size - ntp) % 2:
        bad(f"B and B* hold {opens[0]} and {opens[1]} '(' in {ntp} and {pb.size - ntp} "
            "parentheses (half of each)")
    for name, seq in (("B", pb[:ntp]), ("B*", pb[ntp:])):
        # the union's P is built unchecked (check=False, below): an unbalanced part's searches
        # ran past its own block into the next mesh's parentheses (another mesh's answers). Its
        # '(' are half of it (above), so the first ')' that closes nothing is the offset named
        k = _bp._unbalanced_at(seq)
        if k is not None:
            bad(f"{name} is unbalanced at offset {k}: ')' closes nothing")
    npf = (pb.size - ntp) // 2 + 1
    for name, ids, top in (("holes", p.holes, npf), ("order", p.order, p.num_vertices)):
        x = np.asarray(ids)
        if x.ndim != 1 or x.dtype.kind not in "iu" or (x.size and (x.min() < 0 or x.max() >= top)):
            bad(f"{name} must be a 1-D array of ids in [0, {top}), got dtype {x.dtype} shape "
                f"{x.shape}")
    if np.asarray(p.order).size != p.num_vertices:
        bad(f"order has {np.asarray(p.order).size} entries for {p.num_vertices} vertices")
    if p.num_faces != npf - np.asarray(p.holes).size:
        bad(f"num_faces = {p.num_faces}, but B* has {npf} faces and holes {np.asarray(p.holes).size}")
    return a, pb


@numba.njit(cache=True)
def _root_duals(seq, bstar_off, bstar_len, a, dart_off, num_darts):
    """Per mesh: the dart of the ``)`` matching the first ``(`` of its ``B*`` (``seq[bstar_off[j]:]``,
    the union's ``B B*``; ``select0`` of
    its ``A`` at that parenthesis' index: the ``k``-th zero of ``A`` is the ``k``-th ``B*``
    parenthesis), or its last dart when its ``B*`` is empty (one pemb face)."""
    out = np.empty(bstar_off.size, np.int64)
    for j in range(bstar_off.size):
        out[j] = dart_off[j] + num_darts[j] - 1
        if bstar_len[j] == 0:
            continue
        e = 0
        k = -1
        for i in range(bstar_len[j]):  # B* is balanced: its first '(' closes where e returns to 0
            e += 1 if seq[bstar_off[j] + i] else -1
            if e == 0:
                k = i
                break
        zeros = 0
        for d in range(num_darts[j]):
            if a[dart_off[j] + d] == 0:
                if zeros == k:
                    out[j] = dart_off[j] + d
                    break
                zeros += 1
    return out
