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

import jax
import jax.numpy as jnp
import numpy as np

from jaxcds import errors
from jaxcds._dataclass import pytree_dataclass, static_field
from jaxcds.structures.base import Int, parts_of_one_class
from jaxcds.structures.lr_packed import _chunk_plan, _segment_ids
from jaxcds.structures.pemb import PEMB, TableOperators
from jaxcds.structures.succinct import BalancedParens, BitVector

__all__ = ["PackedPEMB", "PackedPEMBTables", "concatenate_pemb"]


def _owner(offsets, x):
    """Mesh whose range starting at ``offsets`` holds ``x`` (``offsets`` nondecreasing): the last
    ``i`` with ``offsets[i] <= x``; ids out of range read as the first or the last mesh."""
    m = jnp.searchsorted(offsets, x, side="right") - 1
    return jnp.clip(m, 0, offsets.shape[0] - 1).astype(jnp.int32)


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
        m = _segment_ids(2 * (self.mesh_pface_offsets - self._mesh_index()), q.shape[0], self.plans[1])
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
        lo, hi = self._walk_start(m), self._walk_end(m)

        def nxt(e):  # next(e) = prev_p(mate(e)) within the mesh's walk
            x = t.tw[e]
            j = jnp.where(x == lo, hi - 1, x - 1)
            return jnp.where(t.A.access(j) == 1, t.tw[j], j)

        e0 = t.first_dual(self._from_mesh_face(f))
        e1 = nxt(e0)
        e2 = nxt(e1)
        root = self._root_vertex(m)
        org = [jnp.where(v < 0, root, v) for v in (t.vb[t.A.rank1(e)] for e in (e0, e1, e2))]
        return jnp.stack(org, axis=-1).astype(jnp.int32)

    # ------------------------------------------------------------------ batch hooks
    def normal_row_blocks(self):
        """The faces, mesh by mesh (one block), for the chunked sums of :mod:`jaxcds.batch`."""
        return [(self.face_vertices(), None)]

    def normal_row_counts(self):
        off = np.asarray(self.mesh_face_offsets, np.int64)
        return [np.diff(np.concatenate([off, [self.num_faces]]))]

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


def concatenate_pemb(cls, parts: Sequence) -> PackedPEMB:
    """Join pembs, one per mesh, into one :class:`PackedPEMB` (module docstring).

    Raises:
      UnsupportedTopologyError: a part of another class, or ids over int32.
    """
    if cls is not PEMB:  # a packed union's roots are per mesh: joining unions loses them
        raise errors.UnsupportedTopologyError(
            f"{cls.__name__}.concatenate: pack the single pembs (a packed batch cannot be packed again)")
    parts = parts_of_one_class(PEMB, parts)
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
    a = np.concatenate([p.A.to_numpy() for p in parts])
    pb = [p.P.bits.to_numpy() for p in parts]
    seq = np.concatenate([b[:t] for b, t in zip(pb, ntp)] + [b[t:] for b, t in zip(pb, ntp)])
    P = BalancedParens.from_bits(seq, check=False)  # balanced blocks: balanced
    holes = np.concatenate([np.asarray(p.holes, np.int64) + o for p, o in zip(parts, pfoff)])
    order = np.concatenate([np.asarray(p.order, np.int64) + o for p, o in zip(parts, voff)])
    i32 = lambda x: jnp.asarray(np.asarray(x).astype(np.int32))  # noqa: E731
    s = PackedPEMB(
        A=BitVector.from_bits(a), P=P, holes=i32(holes), order=i32(order),
        num_vertices=int(nv.sum()), num_faces=int(nf.sum()), num_edges=int(nd.sum()) // 2,
        num_tree_parens=int(ntp.sum()), root_border=all(p.root_border for p in parts),
        mesh_dart_offsets=i32(doff), mesh_vertex_offsets=i32(voff), mesh_face_offsets=i32(foff),
        mesh_pface_offsets=i32(pfoff), mesh_root_dual=i32(np.zeros(len(parts))),
        plans=(_chunk_plan(ntp), _chunk_plan(2 * (npf - 1)), _chunk_plan(nf)))
    # first_dual of each root face: the ')' matching the first '(' of the mesh's B* (PEMB.first_dual),
    # or the mesh's last dart when it has no dual parenthesis; one vectorised search on the union
    has_dual = npf > 1
    first_dual_open = int(ntp.sum()) + 2 * excl(npf - 1)
    root_dual = doff + nd - 1
    if has_dual.any():
        q = i32(np.where(has_dual, first_dual_open, int(ntp.sum())))
        k = np.asarray(jax.jit(lambda s, q: s.A.select0(s.P.match(q) - s.num_tree_parens))(s, q))
        root_dual = np.where(has_dual, k, root_dual)
    return dataclasses.replace(s, mesh_root_dual=i32(root_dual))
