"""The array-based half-edge: the reference every other structure is checked against.

Memory exactly as the CDS paper counts it (Sec. 1.1, Table 1): per half-edge ``next``,
``opposite`` and ``vertex``; one half-edge per vertex: ``3 * 6n + n = 19n`` references on a closed
triangulation (``6n`` half-edges). Faces are implicit: half-edge ``3f + k`` runs from corner ``k``
to corner ``k+1`` of face ``f``.

Borders: every face side without a neighbour gets a *border* half-edge (ids ``3F ... 3F+B-1``)
whose left face is the outside (``face == num_faces``); border half-edges chain along their loop
with ``next``, and ``border_prev`` stores their ``prev`` (``next∘next`` only holds in triangles).
"""

from __future__ import annotations

import jax.numpy as jnp
import numba
import numpy as np

from jaxcds import _mesh_kernels as _kernels
from jaxcds import _mappings, errors
from jaxcds._args import flag_arg
from jaxcds._arrays import to_device
from jaxcds._dataclass import pytree_dataclass, static_field
from jaxcds.mesh import TriMesh, Twins, load_mesh, trusted_faces, twin_defects, validate
from jaxcds.structures.base import Int, MeshStructure, parts_of_one_class

__all__ = ["HalfEdge", "halfedge_arrays"]


@pytree_dataclass
class HalfEdge(MeshStructure):
    """Array-based half-edge (19n references on a closed triangulation).

    Fields (``H = 3F + B`` half-edges, ``B`` border half-edges):
      next_: ``(H,)`` int32, next half-edge ccw around the left face.
      opposite: ``(H,)`` int32, the twin half-edge.
      vertex: ``(H,)`` int32, the origin vertex.
      vertex_edge: ``(V,)`` int32, a half-edge leaving each vertex (the border one on borders).
      border_prev: ``(B,)`` int32, ``prev`` of border half-edge ``3F + j``.
      num_vertices, num_faces: static sizes.
    """

    next_: jnp.ndarray
    opposite: jnp.ndarray
    vertex: jnp.ndarray
    vertex_edge: jnp.ndarray
    border_prev: jnp.ndarray
    num_vertices: int = static_field()
    num_faces: int = static_field()

    name = "halfedge"
    closed_triangles = False

    # -------------------------------------------------------------- construction
    @classmethod
    def from_mesh(cls, mesh: TriMesh, *, check: bool = True) -> "HalfEdge":
        """Build from a validated mesh (borders allowed, several components allowed).
        ``check=False``: trusted input, not validated (the checks of :meth:`from_faces` only);
        ``check`` must be a bool (``ArgumentError``: ``check='no'`` validated, ``check=0`` did not)."""
        check = flag_arg(check, "HalfEdge.from_mesh: check")
        mesh = load_mesh(mesh)
        twins = None
        if check:
            mesh, twins = validate(mesh, structure="halfedge", return_twins=True)
        return cls._from_faces(mesh.faces, mesh.num_vertices, twins, check_twins=False)

    @classmethod
    def from_faces(cls, faces, num_vertices: int, *, twins=None) -> "HalfEdge":
        """Build from an ``(F, 3)`` ccw face array of a manifold, consistently oriented mesh
        (not re-validated here: use :meth:`from_mesh` for untrusted input). ``twins``: the
        :class:`jaxcds.mesh.Twins` validation returned for these faces (no second matching).

        Trusted input: only the vertex ids are checked (O(F): ``InvalidIndexError`` naming the
        face), that there is a face (``EmptyMeshError``), and border sides that do not chain
        into loops (``MeshError`` naming the defect). Other defects (non-manifold edges,
        duplicated or degenerate faces, flipped faces whose borders still chain) give a
        structure whose answers are unspecified, never a crash. Given ``twins`` are checked to
        be those of ``faces`` (:func:`_check_twins`, O(F))."""
        return cls._from_faces(faces, num_vertices, twins, check_twins=True)

    @classmethod
    def _from_faces(cls, faces, num_vertices, twins, *, check_twins: bool) -> "HalfEdge":
        """:meth:`from_faces`; ``check_twins=False`` for twins validation has just returned."""
        _mappings.relieve()  # many meshes in one process (_mappings); from_mesh relieves here
        twins_arg(twins, "HalfEdge.from_faces")
        f = trusted_faces(faces, num_vertices, "HalfEdge.from_faces")
        if twins is not None and check_twins:
            _check_twins(twins, f, num_vertices, "HalfEdge.from_faces")
        if f.shape[0] == 0:  # no dart: every query's gather would index an empty table
            raise errors.EmptyMeshError(f"HalfEdge.from_faces: no faces ({int(num_vertices)} "
                                        "vertices); nothing to build")
        nxt, opp, vert, vedge, bprev = _halfedge_arrays(f, int(num_vertices), twins,
                                                        "HalfEdge.from_faces")
        return cls(next_=to_device(nxt), opposite=to_device(opp), vertex=to_device(vert),
                   vertex_edge=to_device(vedge), border_prev=to_device(bprev),
                   num_vertices=int(num_vertices), num_faces=int(f.shape[0]))

    # -------------------------------------------------------------- protocol core
    @property
    def num_darts(self) -> int:
        return int(self.next_.shape[0])

    @property
    def num_border_darts(self) -> int:
        return int(self.border_prev.shape[0])

    def dart_valid(self, e: Int) -> Int:
        return (e >= 0) & (e < self.num_darts)

    def origin(self, e: Int) -> Int:
        return self.vertex[e]

    def twin(self, e: Int) -> Int:
        return self.opposite[e]

    def next(self, e: Int) -> Int:
        return self.next_[e]

    def prev(self, e: Int) -> Int:
        inner = e < 3 * self.num_faces
        # the border index is clamped so the gather stays in range for inner darts
        j = jnp.clip(e - 3 * self.num_faces, 0, max(self.num_border_darts - 1, 0))
        border = self.border_prev[j] if self.num_border_darts else e
        return jnp.where(inner, self.next_[self.next_[e]], border)

    def target(self, e: Int) -> Int:
        return self.vertex[self.next_[e]]

    def face(self, e: Int) -> Int:
        return jnp.where(e < 3 * self.num_faces, e // 3, self.num_faces).astype(jnp.int32)

    def dart_faces(self) -> Int:
        return self.face(jnp.arange(self.num_darts, dtype=jnp.int32))  # arithmetic: no scatter

    def edge_of_vertex(self, v: Int) -> Int:
        return self.vertex_edge[v]

    def edge_of_face(self, f: Int) -> Int:
        return (3 * jnp.asarray(f, jnp.int32)).astype(jnp.int32)

    def face_vertices(self) -> Int:
        return self.vertex[: 3 * self.num_faces].reshape(self.num_faces, 3)

    @property
    def references(self) -> int:
        return 3 * self.num_darts + self.num_vertices + self.num_border_darts

    # -------------------------------------------------------------- packed batches (jaxcds.batch)
    @property
    def num_primary_darts(self) -> int:
        """Inner darts ``[0, 3F)``; border darts come after them (``jaxcds.batch`` dart blocks)."""
        return 3 * self.num_faces

    @classmethod
    def concatenate(cls, parts) -> "HalfEdge":
        """Disjoint union of half-edge structures with ids shifted, for
        :func:`jaxcds.batch.concatenate`: the inner darts of every part, then the border darts
        of every part (so ``face(e) = e // 3`` for ``e < 3F`` stays true)."""
        from jaxcds.batch import shift_darts, shift_ids

        # no part: numpy's untyped broadcast ValueError; a part of another class: its fields read
        parts = parts_of_one_class(cls, parts)
        p = [3 * h.num_faces for h in parts]
        x = [h.num_border_darts for h in parts]
        nv = [h.num_vertices for h in parts]

        def per_dart(field, shift):  # inner rows of every part, then border rows of every part
            arrs = [np.asarray(getattr(h, field)) for h in parts]
            return np.concatenate([shift([a[:q] for a, q in zip(arrs, p)]),
                                   shift([a[q:] for a, q in zip(arrs, p)])])

        darts = lambda arrs: shift_darts(arrs, p, x)  # noqa: E731
        return cls(next_=to_device(per_dart("next_", darts)),
                   opposite=to_device(per_dart("opposite", darts)),
                   vertex=to_device(per_dart("vertex", lambda arrs: shift_ids(arrs, nv))),
                   vertex_edge=to_device(darts([np.asarray(h.vertex_edge) for h in parts])),
                   border_prev=to_device(darts([np.asarray(h.border_prev) for h in parts])),
                   num_vertices=int(sum(nv)), num_faces=int(sum(h.num_faces for h in parts)))


# ------------------------------------------------------------------ numba builder
def twins_arg(twins, where: str) -> None:
    """:class:`~jaxcds.errors.ArgumentError` naming ``where`` unless ``twins`` is ``None`` or a
    :class:`jaxcds.mesh.Twins` (``twins=1`` raised an AttributeError about ``.opp``)."""
    if twins is not None and not isinstance(twins, Twins):
        raise errors.ArgumentError(f"{where}: twins must be None or the jaxcds.mesh.Twins that "
                                   f"validate(..., return_twins=True) returned, got "
                                   f"{type(twins).__name__}")


def _check_twins(twins, faces: np.ndarray, num_vertices: int, where: str) -> None:
    """:class:`~jaxcds.errors.ArgumentError` naming ``where`` and the first bad entry unless
    ``twins`` are those of ``faces`` (int32 ``(F, 3)``, ids checked): ``opp`` a ``(3F,)``
    involution on the darts (-1 on a border) pairing ``u -> v`` with ``v -> u``, and
    ``vertex_corner`` ``(n,)`` corners of their vertex (-1: unreferenced). O(F) numpy; the
    builders' own ``from_mesh`` skip it for the twins validation just returned. Hand-made twins
    were copied into the structure as given: a wrong table, silently (sweep 50c)."""
    nd = 3 * faces.shape[0]
    opp, vc = np.asarray(twins.opp), np.asarray(twins.vertex_corner)
    for name, a, size in (("opp", opp, nd), ("vertex_corner", vc, int(num_vertices))):
        if a.shape != (size,) or a.dtype.kind not in "iu":
            raise errors.ArgumentError(f"{where}: twins.{name} must be ({size},) integers for these "
                                       f"faces, got {a.dtype} {a.shape}")
    outside, unpaired = twin_defects(opp, faces)
    bad = outside | unpaired
    if bad.any():
        d = int(np.argmax(bad))
        f, k = divmod(d, 3)
        raise errors.ArgumentError(
            f"{where}: twins.opp[{d}] = {int(opp[d])} is not the twin of dart {d} "
            f"({int(faces[f, k])} -> {int(faces[f, (k + 1) % 3])}) in these faces: pass the Twins that "
            "validate(mesh, return_twins=True) returned for them, or none")
    v = vc.astype(np.int64)
    ref = v >= 0
    corner_vertex = faces.reshape(-1)
    bad = (v < -1) | (v >= nd) | (ref & (corner_vertex[np.where(ref & (v < nd), v, 0)] != np.arange(v.size)))
    if bad.any():
        k = int(np.argmax(bad))
        raise errors.ArgumentError(f"{where}: twins.vertex_corner[{k}] = {int(v[k])} is not a corner "
                                   f"of vertex {k} in these faces")


def halfedge_arrays(faces: np.ndarray, num_vertices: int, twins=None, *,
                    source: str = "halfedge_arrays"):
    """``(next, opposite, vertex, vertex_edge, border_prev)`` int32 arrays for a face list.

    Linear time: darts are bucketed by their smaller endpoint (a counting sort), and each dart
    finds its twin inside its bucket, whose size is the vertex degree -- or the twins come from
    validation (``twins``, :class:`jaxcds.mesh.Twins` of these faces).

    Raises (the unvalidated route's checks, ``source`` names the caller):
      InvalidIndexError: a face id outside ``[0, num_vertices)``.
      MeshError: border sides that do not chain into loops (a pinched vertex, flipped faces...):
        the mesh's first defect as :func:`jaxcds.mesh.validate` names it.
    """
    twins_arg(twins, source)  # twins=1 raised an AttributeError about .opp
    f = trusted_faces(faces, num_vertices, source)
    if twins is not None:
        _check_twins(twins, f, num_vertices, source)
    return _halfedge_arrays(f, int(num_vertices), twins, source)


def _halfedge_arrays(f: np.ndarray, num_vertices: int, twins, source: str):
    """:func:`halfedge_arrays` on faces :func:`~jaxcds.mesh.trusted_faces` already returned
    (the builders check them once, before their own empty-mesh test)."""
    if twins is not None and twins.opp.shape[0] == 3 * f.shape[0]:
        opp = twins.opp.copy()  # _link writes the border half-edges into it
    else:
        opp = _match_twins(f, int(num_vertices))
    out = _link(f, opp, int(num_vertices), f.shape[0])
    if out[-1] >= 0:
        _broken_borders(f, int(num_vertices), int(out[-1]), source)
    return out[:-1]


def _broken_borders(f: np.ndarray, num_vertices: int, vertex: int, source: str):
    """Raise the defect behind a border chain that :func:`_link` could not close at ``vertex``
    (the unvalidated route; the validation runs on this failure only)."""
    mesh = TriMesh(vertices=np.zeros((num_vertices, 3)), faces=f, source=source)
    validate(mesh, unreferenced_ok=True)  # raises the first defect, named
    raise errors.MeshError(f"{source}: the border sides at vertex {vertex} do not chain into "
                           "loops (a non-manifold or inconsistently oriented mesh there)")


# ``_match_twins(faces, num_vertices)`` -> ``opp[d]``: the twin of dart ``d`` among the face darts,
# or -1 (a border side). The darts of each undirected edge, in increasing id, are paired two by
# two (one counting sort by the smaller endpoint, each bucket sorted by the other endpoint; a
# vertex of degree k costs k log k). The kernel itself, not a jitted wrapper: numba's on-disk
# cache of a wrapper would keep calling an old version of a callee from another module.
_match_twins = _kernels.match_twins


@numba.njit(cache=True)
def _link(faces, opp, num_vertices, nf):
    n3 = 3 * nf
    nb = 0
    for d in range(n3):
        if opp[d] < 0:
            nb += 1
    h = n3 + nb
    nxt = np.empty(h, dtype=np.int32)
    opposite = np.empty(h, dtype=np.int32)
    vert = np.empty(h, dtype=np.int32)
    bprev = np.full(nb, -1, dtype=np.int32)
    vedge = np.full(num_vertices, -1, dtype=np.int32)
    border_out = np.full(num_vertices, -1, dtype=np.int64)
    for d in range(n3):
        f = d // 3
        k = d % 3
        nxt[d] = 3 * f + (k + 1) % 3
        vert[d] = faces[f, k]
        if vedge[faces[f, k]] < 0:
            vedge[faces[f, k]] = d
    j = n3
    for d in range(n3):
        if opp[d] < 0:
            # border dart runs target(d) -> origin(d)
            f = d // 3
            k = d % 3
            u = faces[f, (k + 1) % 3]
            opp[d] = j
            opposite[j] = d
            vert[j] = u
            border_out[u] = j
            vedge[u] = j  # start rotations at the border
            j += 1
    for d in range(n3):
        opposite[d] = opp[d]
    # ``bad``: a vertex where the border darts do not chain (-1: none). On a manifold,
    # consistently oriented mesh, one border dart leaves each border vertex and ``next`` is a
    # permutation of the border darts; on unvalidated input a vertex may have none (``-1``
    # would index ``bprev`` out of range) or two (a ``bprev`` slot never written)
    bad = -1
    for j in range(n3, h):
        # next border dart leaves the target of j, which is origin of its twin
        t = vert[opposite[j]]
        nxt[j] = border_out[t]
        if nxt[j] < 0:
            nxt[j] = j
            if bad < 0:
                bad = t
        elif bprev[nxt[j] - n3] >= 0:
            if bad < 0:
                bad = t
        else:
            bprev[nxt[j] - n3] = j
    for v in range(num_vertices):
        if vedge[v] < 0:  # a vertex in no face: the protocol's "absent", one past the darts
            vedge[v] = h
    return nxt, opposite, vert, vedge, bprev, bad
