"""Rossignac's Corner Table: the baseline of the LR paper (Sec. 2) and of the CDS paper's Table 1.

Two tables of ``3F = 6n`` entries: ``V[c]``, the vertex of corner ``c``, and ``O[c]``, its opposite
corner; plus one corner per vertex: ``13n`` references on a closed triangulation. ``c.n`` and
``c.p`` are implicit (``c.t = c // 3``). Corner ids *are* the protocol's dart ids: corner ``c``
is the dart leaving ``c.v`` ccw in triangle ``c.t`` (see :mod:`jaxcds.structures.base`).

Closed, consistently oriented manifold meshes only (close holes with
:func:`jaxcds.mesh.close_boundaries`): the corner table has no dart for the outside.
"""

from __future__ import annotations

from typing import Optional

import jax.numpy as jnp
import numba
import numpy as np

from jaxcds import _mappings, errors
from jaxcds._args import flag_arg
from jaxcds._arrays import to_device
from jaxcds._dataclass import pytree_dataclass, static_field
from jaxcds.mesh import TriMesh, Twins, load_mesh, trusted_faces, validate
from jaxcds.structures.base import Int, MeshStructure, checked_ids, parts_of_one_class
from jaxcds.structures.halfedge import _check_twins, _halfedge_arrays, _match_twins, twins_arg

__all__ = ["CornerTable"]


@numba.njit(cache=True)
def _opposites(opp, nf):
    """``O[c] = prev(twin(next(c)))``: the corner facing the edge ``(c.n.v, c.p.v)``, one pass."""
    O = np.empty(3 * nf, np.int32)
    for c in range(3 * nf):
        t = opp[3 * (c // 3) + (c + 1) % 3]
        O[c] = 3 * (t // 3) + (t + 2) % 3
    return O


def _closed_corner_table(faces, num_vertices):
    """``(O, vertex_corner, closed)`` of a face list in O(F + V) (O(k log k) more at a vertex of
    degree k): the half-edge's own twin matching (``_match_twins``: darts bucketed by their
    smaller endpoint, paired by the other), without the border half-edges a corner table has no
    use for (same pairs, same ``vertex_corner``: the first corner of each vertex). ``closed`` is
    False when a dart has no twin (the caller falls back to the half-edge route).

    A Python function on purpose: numba's on-disk cache of a jitted caller is not invalidated
    when a jitted callee in another module changes, so the kernels are called from here."""
    opp = _match_twins(faces, num_vertices)
    O, closed = _opposite_corners(opp)
    return O, _first_corners(faces, num_vertices), closed


@numba.njit(cache=True)
def _first_corners(faces, num_vertices):
    """``vertex_corner[v]``: the smallest corner ``3f + k`` of ``v`` (-1 if unreferenced)."""
    vertex_corner = np.full(num_vertices, -1, dtype=np.int32)
    for d in range(3 * faces.shape[0]):
        a = faces[d // 3, d % 3]
        if vertex_corner[a] < 0:
            vertex_corner[a] = d
    return vertex_corner


@numba.njit(cache=True)
def _opposite_corners(opp):
    """``(O, closed)`` from the dart twins ``opp``: dart ``d = 3f + k`` runs ``faces[f, k] ->
    faces[f, k+1]`` and faces corner ``3f + (k+2) % 3``, so ``O`` of that corner is the corner
    its twin faces. ``closed`` is False (and ``O`` unfinished) when a dart has no twin."""
    n3 = opp.shape[0]
    O = np.empty(n3, dtype=np.int32)
    for d in range(n3):
        t = opp[d]
        if t < 0:
            return O, False
        O[3 * (d // 3) + (d + 2) % 3] = 3 * (t // 3) + (t + 2) % 3
    return O, True


@pytree_dataclass
class CornerTable(MeshStructure):
    """Corner table (13n references).

    Fields:
      V: ``(3F,)`` int32, ``c.v``.
      O: ``(3F,)`` int32, ``c.o``.
      vertex_corner: ``(n,)`` int32, a corner of each vertex (``v.c``).
    """

    V: jnp.ndarray
    O: jnp.ndarray
    vertex_corner: jnp.ndarray
    num_vertices: int = static_field()
    num_faces: int = static_field()

    name = "corner-table"

    @classmethod
    def from_mesh(cls, mesh: TriMesh, *, check: bool = True) -> "CornerTable":
        """Build from a closed manifold mesh, validated first (typed errors); ``check=False``:
        trusted input, not validated (the checks of :meth:`from_faces` only); ``check`` must be a
        bool (``ArgumentError``: ``check='no'`` validated, ``check=0`` did not)."""
        check = flag_arg(check, "CornerTable.from_mesh: check")
        mesh = load_mesh(mesh)
        twins = None
        if check:
            mesh, twins = validate(mesh, closed=True, structure="corner-table", return_twins=True)
        return cls._from_faces(mesh.faces, mesh.num_vertices, twins, check_twins=False)

    @classmethod
    def from_faces(cls, faces, num_vertices: int, *, twins: Optional[Twins] = None) -> "CornerTable":
        """Build from an ``(F, 3)`` face array of a closed manifold (not re-validated).
        ``twins``: the :class:`jaxcds.mesh.Twins` that validation returned for these faces
        (``validate(..., return_twins=True)``); then no twin is matched again, only ``O`` is
        derived from them (one pass).

        Trusted input: only the vertex ids are checked (O(F): ``InvalidIndexError`` naming the
        face), that there is a face (``EmptyMeshError``), and border sides that do not chain
        into loops (``MeshError``). Other defects give a table whose answers are unspecified,
        never a crash: use :meth:`from_mesh` for untrusted input. Given ``twins`` are checked
        to be those of ``faces`` (O(F); hand-made ones were used as given: a wrong table)."""
        return cls._from_faces(faces, num_vertices, twins, check_twins=True)

    @classmethod
    def _from_faces(cls, faces, num_vertices, twins, *, check_twins: bool) -> "CornerTable":
        """:meth:`from_faces`; ``check_twins=False`` for twins validation has just returned."""
        _mappings.relieve()  # many meshes in one process (_mappings); from_mesh relieves here
        twins_arg(twins, "CornerTable.from_faces")
        f = trusted_faces(faces, num_vertices, "CornerTable.from_faces")
        if twins is not None and check_twins:
            _check_twins(twins, f, num_vertices, "CornerTable.from_faces")
        if f.shape[0] == 0:  # no dart: every query's gather would index an empty table
            raise errors.EmptyMeshError(f"CornerTable.from_faces: no faces ({int(num_vertices)} "
                                        "vertices); nothing to build")
        nf = f.shape[0]
        closed = False
        if twins is not None:  # checked to be these faces' (from_faces) or validation's own
            O, closed = _opposite_corners(twins.opp)
            vedge = twins.vertex_corner
        if not closed:
            O, vedge, closed = _closed_corner_table(f, int(num_vertices))
        if closed:
            vert = f.reshape(-1)
        else:  # a dart without twin: the half-edge route (border half-edges), as it always did
            _, opp, vert, vedge, _ = _halfedge_arrays(f, int(num_vertices), None,
                                                      "CornerTable.from_faces")
            O = _opposites(opp, nf)
        # a vertex in no face: the protocol's "absent", one past the corners
        vedge = np.where(np.asarray(vedge) < 0, 3 * nf, vedge).astype(np.int32)
        # to_device: jnp.asarray would compile a copy per new array shape (jaxcds._arrays)
        return cls(V=to_device(vert[: 3 * nf]), O=to_device(O),
                   vertex_corner=to_device(vedge), num_vertices=int(num_vertices), num_faces=nf)

    # Rossignac's operators, named as in the LR paper (Sec. 2)
    @checked_ids
    def n(self, c: Int) -> Int:
        """``c.n``: next corner in the triangle."""
        c = jnp.asarray(c, jnp.int32)  # a Python int too
        return (3 * (c // 3) + (c + 1) % 3).astype(jnp.int32)

    @checked_ids
    def p(self, c: Int) -> Int:
        """``c.p``: previous corner in the triangle."""
        c = jnp.asarray(c, jnp.int32)
        return (3 * (c // 3) + (c + 2) % 3).astype(jnp.int32)

    @checked_ids
    def v(self, c: Int) -> Int:
        return self.V[c]

    @checked_ids
    def o(self, c: Int) -> Int:
        return self.O[c]

    @checked_ids
    def s(self, c: Int) -> Int:
        """``c.s = c.n.o.n`` (swing around ``c.v``)."""
        return self.n(self.O[self.n(c)])

    # -------------------------------------------------------------- protocol core
    @property
    def num_darts(self) -> int:
        return 3 * self.num_faces

    def dart_valid(self, e: Int) -> Int:
        return (e >= 0) & (e < self.num_darts)

    def origin(self, e: Int) -> Int:
        return self.V[e]

    def next(self, e: Int) -> Int:
        return self.n(e)

    def prev(self, e: Int) -> Int:
        return self.p(e)

    def twin(self, e: Int) -> Int:
        # dart c = (c.v, c.n.v); across it lies c.p.o, whose next corner starts at c.n.v
        return self.n(self.O[self.p(e)])

    def target(self, e: Int) -> Int:
        return self.V[self.n(e)]

    def face(self, e: Int) -> Int:
        return (e // 3).astype(jnp.int32)

    def dart_faces(self) -> Int:
        return self.face(jnp.arange(self.num_darts, dtype=jnp.int32))  # arithmetic: no scatter

    def edge_of_vertex(self, v: Int) -> Int:
        return self.vertex_corner[v]

    def edge_of_face(self, f: Int) -> Int:
        return (3 * jnp.asarray(f, jnp.int32)).astype(jnp.int32)

    def corner_opposite(self, c: Int) -> Int:
        return self.O[c]

    def corner_swing(self, c: Int) -> Int:
        return self.s(c)

    def face_vertices(self) -> Int:
        return self.V.reshape(self.num_faces, 3)

    @property
    def references(self) -> int:
        return 2 * self.num_darts + self.num_vertices

    # -------------------------------------------------------------- packed batches (jaxcds.batch)
    @classmethod
    def concatenate(cls, parts) -> "CornerTable":
        """Disjoint union of corner tables with ids shifted, for :func:`jaxcds.batch.concatenate`."""
        from jaxcds.batch import shift_ids

        # no part: numpy's untyped broadcast ValueError; a part of another class: its fields read
        parts = parts_of_one_class(cls, parts)
        nc = [3 * c.num_faces for c in parts]
        nv = [c.num_vertices for c in parts]
        return cls(V=to_device(shift_ids([np.asarray(c.V) for c in parts], nv)),
                   O=to_device(shift_ids([np.asarray(c.O) for c in parts], nc)),
                   vertex_corner=to_device(shift_ids([np.asarray(c.vertex_corner) for c in parts], nc)),
                   num_vertices=int(sum(nv)), num_faces=int(sum(c.num_faces for c in parts)))
