"""pemb: a planar embedding in ``4m`` bits plus support, navigated as a half-edge.

Ferres, Fuentes-Sepúlveda, Gagie, He, Navarro, *Fast and Compact Planar Embeddings* (WADS 2017,
CGTA 2020), wrapped as a half-edge as in Salinas-Fernández, Fuentes-Sepúlveda, Hitschfeld-Kahler,
*Generation of polygonal meshes in compact space* (IMR 2023, the slides in
``../shared/seeds/004_*``).

Encoding (paper Sec. 3, slides "Pemb construction"). Take a spanning tree ``T`` of the connected
plane graph and walk around it counter-clockwise from a root corner, visiting the edges around
each vertex in ccw order. Every one of the ``2m`` half-edges is met once, in walk order, and gets
the next *position* ``i`` of the bit vector ``A``:

* ``A[i] = 1`` for an edge of ``T`` and a parenthesis in ``B``: ``(`` going down (the half-edge
  parent -> child), ``)`` coming back (child -> parent);
* ``A[i] = 0`` for an edge not in ``T`` and a parenthesis in ``B*``: ``(`` the first time the edge
  is met (the walk enters a new face: ``B*`` is the walk around the complementary dual tree),
  ``)`` the second time.

``B`` is the tree in balanced parentheses (``2(n-1)`` bits; the root has no pair), ``B*`` the dual
tree (``2(f-1)`` bits; the root face, where the walk starts and ends, has no pair). Vertices are
numbered in preorder of ``T`` (root 0), faces in preorder of the dual tree (root face 0).

Queries on positions (slides "Pemb queries", "Pemb extra queries"; all branch-free, O(1) rank/
select plus one parenthesis search each):

* ``mate(i)``: the other half-edge of the edge, via ``match`` in ``B`` or ``B*``;
* ``vertex(i)``: the innermost tree node open before the ``rank1(A, i)``-th symbol of ``B``;
* ``next(i)`` / ``prev(i)``: ccw / cw around ``vertex(i)``, *cyclic*:
  ``next(i) = (mate(i) + 1 if A[i] else i + 1) mod 2m`` and
  ``prev(i) = mate(j) if A[j] else j`` with ``j = (i - 1) mod 2m`` (the reference C code stops at
  the last half-edge of a vertex instead of wrapping, the "prev/last on borders" bug);
* ``first(v)`` / ``last(v)``, ``degree(v)``, ``first_dual(f)``, ``get_face(i)``.

Half-edge facade (slides "Pemb encapsulation as Half-edge"): the dart id *is* the position and
its origin is ``vertex(i)``; ``twin = mate``, ``next(e) = prev_p(mate(e))`` (cw after the twin
around the target), ``prev(e) = mate(next_p(e))``, ``ccw_vertex_edge = next_p``,
``cw_vertex_edge = prev_p``, ``face = get_face`` renumbered so that the faces of the mesh are
``0..F-1`` and every border loop (a pemb face that is not a triangle) reads ``num_faces``.
(The slides orient a half-edge towards ``vertex(i)``; orienting it away is the same data and
saves a ``mate`` in ``origin``.)

Batch work over every dart (Polylla's phases ask ``twin``, ``next``, ``prev``, ``cw``,
``origin`` of all darts) can first call :meth:`PEMB.with_tables`: one
:meth:`~jaxcds.structures.succinct.BalancedParens.match_all` (a search from each ``(`` only) gives
the twin of every dart, ``first_dual`` of every face and, by pointer doubling over ``B``, the
vertex before every tree parenthesis; the returned :class:`PEMBTables` answers the same protocol
with gathers. The tables are temporaries of that work (about 110 bits per edge, 41 bytes per
vertex on a triangulation; the HalfEdge keeps 76 bytes per vertex all the time), never part of
the structure.

Memory: ``A`` ``2m`` bits, ``B`` + ``B*`` ``2(n - 1) + 2(f - 1) = 2m`` bits (Euler), stored as one
balanced sequence ``B B*`` so ``mate`` needs a single search; support: rank directories (1/8 bit
per bit) and the min-max tree (about 1/4 bit per parenthesis). :attr:`PEMB.bits_per_edge` counts
it all. The preorder permutation (``vertex_order``) is per-vertex data like the coordinates, which
pemb does not compress either, and is left out of that count.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Optional

import jax
import jax.numpy as jnp
import numba
import numpy as np

from jaxcds import _mappings, errors
from jaxcds._args import flag_arg, is_integer, shown
from jaxcds._arrays import to_device
from jaxcds._dataclass import pytree_dataclass, static_field
from jaxcds.mesh import load_mesh, trusted_faces, validate
from jaxcds.structures.base import Int, MeshStructure, _jit_when_eager, by_table, id_arg, shared_subexpression
from jaxcds.structures.succinct import BalancedParens, BitVector
from jaxcds.structures.succinct.bitvector import bits_array
from jaxcds.structures.succinct.bp import _unbalanced_at

__all__ = ["PEMB", "encode_rotation_system", "rotation_system_from_faces", "from_mesh"]


def chain_ends(ptr):
    """Pointer doubling: where each chain of ``ptr`` (``(k,)`` int32, every chain ending at an
    entry that points to itself) ends. ``log2`` (longest chain) rounds of one gather."""
    return jax.lax.while_loop(lambda p: jnp.any(p[p] != p), lambda p: p[p], ptr)


# ---------------------------------------------------------------------------------- encoder
@numba.njit(cache=True)
def _walk(opp, ccw, vert, start, num_vertices, in_tree, use_tree):
    """Walk around the spanning tree from dart ``start`` (paper Sec. 3). Returns the bit
    sequences, the position of every dart, the preorder and the pemb face of every position.
    The tree is ``in_tree`` (a mask on darts, both halves set) if ``use_tree``, else built on the
    fly (the first edge that reaches an unvisited vertex is a tree edge: a ccw DFS tree)."""
    h = opp.size
    A = np.zeros(h, np.uint8)
    B = np.zeros(2 * max(num_vertices - 1, 0), np.uint8)
    Bs = np.zeros(max(h - 2 * (num_vertices - 1), 0), np.uint8)
    pos = np.full(h, -1, np.int64)
    visited = np.zeros(num_vertices, np.bool_)
    up = np.full(num_vertices, -1, np.int64)
    down_pos = np.full(num_vertices, -1, np.int64)
    down_face = np.zeros(num_vertices, np.int64)
    order = np.full(num_vertices, -1, np.int64)
    pface = np.zeros(h, np.int64)
    fstack = np.zeros(h + 1, np.int64)
    top = 0
    cur = 0
    nextface = 1
    root = vert[start]
    visited[root] = True
    order[0] = root
    nvis = 1
    nb = 0
    ns = 0
    e = start
    for i in range(h):
        if pos[e] >= 0 or nb > B.size or ns > Bs.size:
            return A, B, Bs, pos, order, pface, -1 - i  # not a planar walk
        v = vert[e]
        w = vert[opp[e]]
        pos[e] = i
        if e == up[v]:  # back up to the parent: ')' in B
            A[i] = 1
            if nb >= B.size:
                return A, B, Bs, pos, order, pface, -1 - i
            B[nb] = 0
            nb += 1
            # the walk runs along a tree edge on its right side: the face met going down is
            # the left face of child -> parent, the one met coming back that of parent -> child
            pface[i] = down_face[v]
            pface[down_pos[v]] = cur
            e = ccw[opp[e]]
        elif (use_tree and in_tree[e]) or (not use_tree and not visited[w]):
            if visited[w] or nb >= B.size:
                return A, B, Bs, pos, order, pface, -1 - i
            A[i] = 1  # down to a child: '(' in B
            B[nb] = 1
            nb += 1
            visited[w] = True
            up[w] = opp[e]
            down_pos[w] = i
            down_face[w] = cur
            order[nvis] = w
            nvis += 1
            e = ccw[opp[e]]
        else:  # not in T: a parenthesis of the dual tree
            if ns >= Bs.size:
                return A, B, Bs, pos, order, pface, -1 - i
            if pos[opp[e]] < 0:  # first crossing: enter a new face
                Bs[ns] = 1
                fstack[top] = cur
                top += 1
                cur = nextface
                nextface += 1
            else:
                Bs[ns] = 0
                if top == 0:
                    return A, B, Bs, pos, order, pface, -1 - i
                top -= 1
                cur = fstack[top]
            ns += 1
            pface[i] = cur
            e = ccw[e]
    return A, B, Bs, pos, order, pface, nvis


def encode_rotation_system(opp, ccw, vert, num_vertices: int, start: int = 0, tree=None):
    """Encode a connected plane graph given as a rotation system on darts.

    Args:
      opp: ``(H,)`` the twin of each dart.
      ccw: ``(H,)`` the next dart counter-clockwise around the dart's origin.
      vert: ``(H,)`` the origin of each dart.
      start: the first dart of the walk (its origin is the root; the walk starts in the face
        clockwise of it, which becomes the root face 0).
      tree: optional ``(H,)`` bool mask of the spanning tree's darts (both halves); default: the
        ccw DFS tree grown during the walk.

    Returns a dict with ``A``, ``B``, ``B_star`` (uint8 0/1 arrays; 1 = ``(`` in ``B``/``B*``),
    ``position`` (dart -> position), ``order`` (preorder -> input vertex) and ``face`` (position ->
    pemb face id). Raises :class:`~jaxcds.errors.UnsupportedTopologyError` if the walk shows the
    graph is not a connected plane graph.

    The arguments are checked first (:class:`~jaxcds.errors.ArgumentError` naming the first bad
    entry; the walk's kernel indexed by them unchecked, and a dart or vertex out of range crashed
    it): ``opp``, ``ccw``, ``vert`` 1-D integer arrays of one length ``H > 0``, ``opp`` an
    involution without fixed points and ``ccw`` a permutation of the darts, both on ``[0, H)``,
    keeping each dart's origin (``vert[ccw[d]] == vert[d]``); ``vert`` in ``[0, num_vertices)``;
    ``start`` a dart id; ``tree`` ``H`` booleans."""
    opp, ccw, vert, start, num_vertices, tree = _rotation_args(opp, ccw, vert, num_vertices, start, tree)
    return _encode_rotation_system(opp, ccw, vert, num_vertices, start, tree)


def _rotation_args(opp, ccw, vert, num_vertices, start, tree):
    """:func:`encode_rotation_system`'s arguments checked (see there)."""
    w = "encode_rotation_system"
    if not is_integer(num_vertices) or not 0 < num_vertices < 2 ** 31:
        raise errors.ArgumentError(f"{w}: num_vertices must be an integer in [1, 2^31), got {num_vertices!r}")
    arrs = []
    for name, a in (("opp", opp), ("ccw", ccw), ("vert", vert)):
        try:
            a = np.asarray(a)
        except ValueError as exc:  # ragged nested lists
            raise errors.ArgumentError(f"{w}: {name} is not an array: {exc}") from None
        if a.ndim != 1 or a.dtype.kind not in "iu" or a.size == 0:
            raise errors.ArgumentError(f"{w}: {name} must be a non-empty 1-D integer array (one entry per "
                                       f"dart), got dtype {a.dtype} shape {a.shape}")
        arrs.append(a)
    opp, ccw, vert = arrs
    H = opp.size
    if ccw.size != H or vert.size != H:
        raise errors.ArgumentError(f"{w}: opp, ccw and vert must have one length, got {H}, {ccw.size}, "
                                   f"{vert.size}")
    for name, a, top in (("opp", opp, H), ("ccw", ccw, H), ("vert", vert, int(num_vertices))):
        bad = np.nonzero((a < 0) | (a >= top))[0]
        if bad.size:
            d = int(bad[0])
            raise errors.ArgumentError(f"{w}: {name}[{d}] = {int(a[d])} is outside [0, {top})")
    opp, ccw, vert = (np.ascontiguousarray(a, np.int64) for a in (opp, ccw, vert))
    d = np.arange(H)
    bad = np.nonzero((opp[opp] != d) | (opp == d))[0]
    if bad.size:
        e = int(bad[0])
        raise errors.ArgumentError(f"{w}: opp[{e}] = {int(opp[e])}: opp must be an involution without "
                                   "fixed points (each dart's twin)")
    seen = np.zeros(H, bool)
    seen[ccw] = True
    bad = np.nonzero(~seen | (vert[ccw] != vert))[0]
    if bad.size:
        e = int(bad[0])
        raise errors.ArgumentError(f"{w}: ccw is not a permutation of the darts around their origins "
                                   f"(at dart {e})")
    if not is_integer(start) or not 0 <= start < H:
        raise errors.ArgumentError(f"{w}: start must be a dart id in [0, {H}), got {start!r}")
    if tree is not None:
        t = np.asarray(tree)
        if t.shape != (H,) or t.dtype != np.bool_:
            raise errors.ArgumentError(f"{w}: tree must be {H} booleans (a dart mask), got dtype {t.dtype} "
                                       f"shape {t.shape}")
    return opp, ccw, vert, int(start), int(num_vertices), tree


def _encode_rotation_system(opp, ccw, vert, num_vertices: int, start: int = 0, tree=None):
    """:func:`encode_rotation_system` on a rotation system the library built (unchecked)."""
    opp = np.ascontiguousarray(opp, np.int64)
    ccw = np.ascontiguousarray(ccw, np.int64)
    vert = np.ascontiguousarray(vert, np.int64)
    use_tree = tree is not None
    mask = np.ascontiguousarray(tree if use_tree else np.zeros(opp.size, bool), np.bool_)
    A, B, Bs, pos, order, pface, status = _walk(opp, ccw, vert, int(start), int(num_vertices), mask,
                                                use_tree)
    if status < 0:
        i = -1 - status
        raise errors.UnsupportedTopologyError(
            f"pemb: the ccw walk around the spanning tree breaks at position {i} (dart met twice or "
            "parentheses unbalanced): the embedding is not planar (genus > 0?) or the tree is not "
            "spanning; pemb needs a connected planar embedding (use 'halfedge' instead)")
    if status != num_vertices:
        missing = int(np.nonzero(order < 0)[0][0]) if np.any(order < 0) else -1
        raise errors.UnsupportedTopologyError(
            f"pemb: the walk reached {status} of {num_vertices} vertices (preorder slot {missing} "
            "empty): the mesh is not connected; split it with jaxcds.mesh.split_components")
    exc = np.cumsum(2 * Bs.astype(np.int64) - 1)
    if Bs.size and (exc.min() < 0 or exc[-1] != 0):
        bad = int(np.argmax(exc < 0)) if exc.min() < 0 else Bs.size
        raise errors.UnsupportedTopologyError(
            f"pemb: dual parentheses B* unbalanced at offset {bad}: the embedding is not planar")
    return {"A": A, "B": B, "B_star": Bs, "position": pos, "order": order.astype(np.int32),
            "face": pface}


def rotation_system_from_faces(faces: np.ndarray, num_vertices: int):
    """``(opp, ccw, vert, is_border)`` for the darts of a triangle mesh, numbered as the
    HalfEdge numbers them (``3f + k`` inner, then border darts). The face ids are checked
    (:func:`~jaxcds.mesh.trusted_faces`)."""
    from jaxcds.mesh import trusted_faces

    return _rotation_system(trusted_faces(faces, num_vertices, "pemb"), num_vertices)


def _rotation_system(f: np.ndarray, num_vertices: int):
    """:func:`rotation_system_from_faces` on faces ``trusted_faces`` returned already
    (``PEMB.from_faces`` checks them once, before its own empty-mesh test)."""
    from jaxcds.structures.halfedge import _halfedge_arrays

    nxt, opp, vert, _vedge, bprev = _halfedge_arrays(f, int(num_vertices), None, "pemb")
    nf3 = 3 * f.shape[0]
    prev = np.empty_like(nxt)
    prev[:nf3] = nxt[nxt[:nf3]]
    prev[nf3:] = bprev
    ccw = opp[prev]  # ccw_vertex_edge = twin(prev(e))
    is_border = np.arange(nxt.size) >= nf3
    return opp, ccw, vert, is_border


# ---------------------------------------------------------------------------------- structure
def _id_list(values, name: str, top: int, what: str) -> np.ndarray:
    """``values`` as a 1-D int32 array of ids in ``[0, top)``, or
    :class:`~jaxcds.errors.EncodingError` naming ``name`` and the first bad entry (a cast to int32
    read 1.5 as 1 and kept ids out of range)."""
    a = np.asarray(values) if not isinstance(values, (str, bytes)) else np.asarray([values])
    if a.ndim != 1 or (a.size and (a.dtype.kind not in "iu")):
        raise errors.EncodingError(f"pemb: {name} must be a sequence of {what} (integers), got "
                                   f"dtype {a.dtype} shape {a.shape}")
    bad = (a < 0) | (a >= top)
    if bad.any():
        k = int(np.argmax(bad))
        raise errors.EncodingError(f"pemb: {name}[{k}] = {int(a[k])} is outside [0, {top}) ({what})")
    return a.astype(np.int32)


@pytree_dataclass
class PEMB(MeshStructure):
    """Succinct planar embedding (Ferres et al. 2017) exposed through the half-edge protocol.

    Fields (``m`` edges, ``n`` vertices, ``f`` faces of the plane graph, ``f = F + h``: ``F``
    triangles and ``h`` border loops):
      A: :class:`BitVector` of ``2m`` bits, 1 = tree edge (paper's ``A``).
      P: :class:`BalancedParens` ``B B*``: ``2(n-1)`` tree parentheses then ``2(f-1)`` dual ones.
      holes: ``(h,)`` int32, sorted pemb face ids that are border loops (read as ``num_faces``).
      order: ``(n,)`` int32, preorder -> input vertex id (``vertex_order``).
      num_vertices, num_faces (triangles ``F``), num_edges ``m``, num_tree_parens ``2(n-1)``.
    """

    A: BitVector
    P: BalancedParens
    holes: jnp.ndarray
    order: jnp.ndarray
    num_vertices: int = static_field()
    num_faces: int = static_field()
    num_edges: int = static_field()
    num_tree_parens: int = static_field()
    root_border: bool = static_field(default=False)

    name = "pemb"
    closed_triangles = False
    # the searches are while_loops: run eagerly, each compiled and kept for every batch size
    eager_buckets = True
    jit_when_eager = frozenset(("with_tables",))
    # A batch of at least table_ratio(op) * num_darts ids is answered from per-call tables
    # (with_tables: one match_all, then gathers; face and is_border from every dart's face)
    # instead of one or two parenthesis searches per id; only the tables the operator reads are
    # built ("twin": mate, "origin": vertex). The ratios are where the tables ran faster (100K
    # vertices, random darts; RESULTS.md, "stop 47"): at 16 darts' worth of ids Target 94 -> 16
    # ns per id, Next 93 -> 5, Face 72 -> 3; Origin, one search, from 4 darts' worth
    _TABLE_OPS = {"target": ("twin", "origin"), "next": ("twin",), "prev": ("twin",),
                  "twin": ("twin",), "ccw_vertex_edge": ("twin",), "cw_vertex_edge": ("twin",),
                  "face": ("twin",), "origin": ("origin",), "is_border": ("twin",)}
    table_queries = {op: "_tabled_" + op for op in _TABLE_OPS}
    table_batch_ratio = {"target": 1 / 2, "next": 1 / 2, "prev": 1 / 2, "twin": 1, "face": 1,
                         "is_border": 1, "ccw_vertex_edge": 2, "cw_vertex_edge": 2, "origin": 4}
    # jaxcds.sharding pads arrays by rows; the bit vectors' rank/select/match directories read
    # their own lengths, so padded words changed every answer (found by an adversarial sweep)
    row_sharding_refused = ("pemb cannot be split by rows over devices: its succinct bit "
                            "vectors and their rank/select/match directories read their own "
                            "lengths, and padding them changes the answers; shard a 'halfedge' "
                            "(same protocol), or keep the pemb on every device and split the "
                            "query batch")

    # -------------------------------------------------------------- construction
    @classmethod
    def from_mesh(cls, mesh, *, check: bool = True, tree: str = "bfs") -> "PEMB":
        """Build from a connected, planar (genus 0, any number of border loops) triangle mesh.

        The walk starts at the first border vertex in the outer face (so border loop 0 is the
        root face), or at vertex ``faces[0, 0]`` on a closed mesh. ``tree``: ``"bfs"`` (default)
        or ``"dfs"`` (the ccw DFS tree grown by the walk), or ``"stack"``: the original
        implementation's tree (jfuentess/pemb's sequential ``seq_dfs_spanning_tree``, see
        :func:`_stack_tree`). With ``"stack"`` and the same rotation system and first dart, ``A``
        is the original's bit for bit and ``B``, ``B*`` are the original's without the outer
        pair ``1 ... 0`` it wraps each in (checked against the compiled original on 32 meshes,
        2026-12-06; ``tests/data/pemb_original``).

        Any spanning tree gives the same ``4m`` bits (paper Sec. 3); the tree decides how far
        apart matching parentheses lie. A DFS tree of a triangulation is a few long paths: its
        ``B`` nests deeply, and only 5-8% of ``mate`` / 47-54% of ``vertex`` searches end within
        64 bits; with a BFS tree 55-93% do (100K random points, ``B`` 73%, ``B*`` 55% of the
        matches in the query's own word), which the two-stage searches of
        :class:`~jaxcds.structures.succinct.BalancedParens` answer without the min-max tree.

        ``check=False`` skips the validation and the genus test (trusted input, the checks of
        :meth:`from_faces` only: answers unspecified on a defective mesh, never a crash);
        ``check`` must be a bool (``ArgumentError``)."""
        check = flag_arg(check, "PEMB.from_mesh: check")
        mesh = load_mesh(mesh)
        if check:
            # refuses vertices in no face too (UnreferencedVertexError): the spanning tree
            # could not reach them
            validate(mesh, connected=True, structure="pemb")
            from jaxcds.mesh import topology

            top = topology(mesh)
            if top["genus"] != 0:
                raise errors.UnsupportedTopologyError(
                    f"{mesh.source}: pemb needs a planar (genus 0) mesh, this one has genus "
                    f"{top['genus']} (chi = {top['euler_characteristic']}, "
                    f"{top['boundary_loops']} boundary loops); use 'halfedge'")
        return cls.from_faces(mesh.faces, mesh.num_vertices, tree=tree)

    @classmethod
    def from_faces(cls, faces, num_vertices: int, *, tree: str = "bfs") -> "PEMB":
        """Build from an ``(F, 3)`` ccw face array, not validated (:meth:`from_mesh` is the
        checked route). Checked here, O(F): ids in range (``InvalidIndexError``), at least one
        face (``EmptyMeshError``), border sides that chain into loops; a walk that breaks on a
        non-planar or disconnected input is ``UnsupportedTopologyError``. Other defects give
        answers that are unspecified, never a crash."""
        _mappings.relieve()  # many meshes in one process (_mappings); from_mesh relieves here
        # before any work; an array here raised numpy's untyped "truth value" ValueError
        if not isinstance(tree, str) or tree not in ("bfs", "dfs", "stack"):
            raise errors.ArgumentError(f"pemb: unknown spanning tree {shown(tree)} (bfs, dfs or stack)")
        f = trusted_faces(faces, num_vertices, "PEMB.from_faces")
        nf = int(f.shape[0])
        if nf == 0:  # the walk's first dart would not exist
            raise errors.EmptyMeshError(f"PEMB.from_faces: no faces ({int(num_vertices)} "
                                        "vertices); nothing to build")
        opp, ccw, vert, is_border = _rotation_system(f, num_vertices)
        if is_border.any():
            b = int(np.argmax(is_border))
            start = int(ccw[b])  # first dart after the border corner: the walk starts outside
        else:
            start = 0
        mask = None
        if tree == "bfs":
            mask = _bfs_tree(opp, ccw, vert, start, int(num_vertices))
        elif tree == "stack":
            mask = _stack_tree(opp, ccw, vert, start, int(num_vertices))
        enc = _encode_rotation_system(opp, ccw, vert, num_vertices, start, mask)
        pf = enc["face"][enc["position"][is_border]]
        holes = np.unique(pf).astype(np.int32)
        return cls.from_bits(enc["A"], enc["B"], enc["B_star"], order=enc["order"], holes=holes,
                             num_faces=nf)

    @classmethod
    def from_bits(cls, A, B, B_star, *, order=None, holes=None, num_faces=None) -> "PEMB":
        """Wrap the three bit vectors (1 = tree edge in ``A``; 1 = ``(`` in ``B``, ``B*``; also
        accepted: strings in the slides' convention, where ``0`` is ``(``). Without ``holes``
        every pemb face is a face of the structure (``num_faces = f``).

        Raises:
          EncodingError: a sequence holds anything but 0 and 1 (named, with its offset) or is not
            one sequence; the counts of ``A``, ``B`` and ``B*`` disagree; ``B`` or ``B*`` is
            unbalanced; no edge at all; ``holes`` are not distinct pemb face ids; ``order`` is not a
            permutation of the ``n`` vertices; ``num_faces`` is not the count of triangles."""
        def parse(x, paren, name):
            if isinstance(x, str):
                arr = np.frombuffer(x.encode(), np.uint8) - ord("0")
                if np.any(arr > 1):
                    k = int(np.argmax(arr > 1))
                    rule = " (the slides' convention: 0 is '(' and 1 is ')')" if paren else ""
                    raise errors.EncodingError(f"pemb: bit string {name} has {x[k]!r} at offset {k}: a bit "
                                               f"string holds the characters 0 and 1 only{rule}")
                return (1 - arr) if paren else arr  # slides: 0 = '('
            # a cast to uint8 read 0.5 as 0 and 2.0 as 2, and a 2-D array was flattened
            return bits_array(x, f"pemb: the bits of {name}").astype(np.uint8)

        a, b, bs = parse(A, False, "A"), parse(B, True, "B"), parse(B_star, True, "B*")
        m2 = a.size
        if m2 % 2 or int(a.sum()) != b.size or m2 - int(a.sum()) != bs.size:
            raise errors.EncodingError(
                f"pemb: A has {m2} bits with {int(a.sum())} ones and {m2 - int(a.sum())} zeros, but "
                f"B has {b.size} and B* {bs.size} parentheses (they must match the ones and zeros)")
        if m2 == 0:  # no dart: with_tables (every batch operator's route) gathered from empty B B*
            raise errors.EncodingError("pemb: A, B and B* are empty (no edge); a pemb has at least "
                                       "one edge")
        n = b.size // 2 + 1
        f_total = bs.size // 2 + 1
        for name, seq in (("B", b), ("B*", bs)):
            k = _unbalanced_at(seq)  # parse checked the bits
            if k is not None:
                raise errors.EncodingError(f"pemb: {name} is unbalanced at offset {k}")
        holes = (np.zeros(0, np.int32) if holes is None
                 else np.sort(_id_list(holes, "holes", f_total, "pemb face ids (B*)")))
        if holes.size > 1 and np.any(holes[1:] == holes[:-1]):
            k = int(np.argmax(holes[1:] == holes[:-1]))
            raise errors.EncodingError(f"pemb: holes name face {int(holes[k])} twice")
        if num_faces is None:
            num_faces = f_total - holes.size
        if not is_integer(num_faces) or num_faces != f_total - holes.size:
            raise errors.EncodingError(
                f"pemb: {f_total} faces in B* but {num_faces!r} triangles + {holes.size} border loops")
        if order is None:
            order = np.arange(n, dtype=np.int32)
        else:  # per-vertex data is read through it: a repeat or a gap would misplace vertices
            order = _id_list(order, "order", n, "input vertex ids")
            if order.size != n:
                raise errors.EncodingError(f"pemb: order has {order.size} entries for {n} vertices")
            seen = np.zeros(n, bool)
            seen[order] = True
            if not seen.all():
                raise errors.EncodingError(f"pemb: order is not a permutation of the {n} vertices "
                                           f"(vertex {int(np.argmin(seen))} is missing)")
        # parse checked the bits, and B and B* are balanced (above): no second scan of either
        P = BalancedParens._from_valid_bits(np.concatenate([b, bs]), check=False)
        return cls(A=BitVector._from_valid_bits(a), P=P, holes=to_device(holes, copy=True), order=to_device(order, copy=True),
                   num_vertices=int(n), num_faces=int(num_faces), num_edges=m2 // 2,
                   num_tree_parens=int(b.size), root_border=holes.tolist() == [0])

    @classmethod
    def concatenate(cls, parts) -> "PEMB":
        """Join pembs, one per mesh, into one packed union (:mod:`jaxcds.batch`'s hook; see
        :mod:`jaxcds.structures.pemb_packed`)."""
        from jaxcds.structures.pemb_packed import concatenate_pemb

        return concatenate_pemb(cls, parts)

    # -------------------------------------------------------------- memory
    @property
    def bits(self) -> int:
        """Bits of the structure: ``A``, ``B B*`` and all their support (rank directories,
        min-max tree, word padding) and the border-loop list; not the vertex permutation."""
        return (self.A.size + self.A.bits_support + self.P.size + self.P.bits_support
                + 32 * int(self.holes.shape[0]))

    @property
    def bits_payload(self) -> int:
        """The ``4m`` bits of the paper: ``|A| + |B| + |B*|`` (the original implementation wraps
        ``B`` and ``B*`` in an outer pair each: ``4m + 4``)."""
        return self.A.size + self.P.size

    @property
    def bits_per_edge(self) -> float:
        return self.bits / max(self.num_edges, 1)

    @property
    def references(self) -> int:
        """Equivalent 32-bit words of :attr:`bits` (pemb stores no integer references)."""
        return -(-self.bits // 32)

    @property
    def vertex_order(self) -> np.ndarray:
        return np.asarray(self.order)

    # -------------------------------------------------------------- pemb queries (positions)
    @property
    def num_darts(self) -> int:
        return 2 * self.num_edges

    @shared_subexpression(masks=("where",))
    def mate(self, i: Int, where=None) -> Int:
        """The other half-edge of ``i``'s edge (slides, "Example of Pemb query"). Lanes outside
        ``where`` (a mask, default all) get an unspecified value and skip the slow routes of the
        two-stage searches (callers that select the mate on some lanes only pass it)."""
        i = id_arg(i, "mate: i")
        a = self.A.access(i)
        t = self.A.rank(i, a)
        j = jnp.where(a == 1, t, self.num_tree_parens + t)  # in B, or in B* after B
        k = self.P.match(j, active=where)
        # the mate is usually a few bits away: a select near i (i is the t-th a-bit) first
        return self.A.select_near(jnp.where(a == 1, k, k - self.num_tree_parens), a, i, t,
                                  active=where)

    @shared_subexpression
    def vertex(self, i: Int) -> Int:
        """The vertex (preorder id) the half-edge at position ``i`` leaves: the innermost tree node
        open before its ``rank1(A, i)``-th parenthesis of ``B`` (root 0 if none)."""
        i = id_arg(i, "vertex: i")
        m = self._dart_mesh(i)
        q = self.P.enclose(self.A.rank1(i))
        return jnp.where(q >= self.P.size, self._root_vertex(m),
                         self.P.rank_open(q) + 1 + m).astype(jnp.int32)

    def _vertex_paren(self, v):
        """``(mesh, root?, the ( of v in B)`` of vertices ``v``."""
        v = jnp.asarray(v, jnp.int32)
        m = self._vertex_mesh(v)
        return m, v == self._root_vertex(m), self.P.select_open(jnp.maximum(v - 1 - m, 0))

    def first(self, v: Int) -> Int:
        """First position of vertex ``v`` (the one after its ``(``; 0 for the root)."""
        m, root, q = self._vertex_paren(id_arg(v, "first: v"))
        return jnp.where(root, self._walk_start(m), self.A.select1(q) + 1).astype(jnp.int32)

    def last(self, v: Int) -> Int:
        """Last position of vertex ``v`` (its ``)`` back to the parent). For the root: ``2m - 1``
        if that is a non-tree half-edge (the root's own), else the walk ended coming back up
        from the root's last child and the root's last half-edge is the one going down to it,
        ``mate(2m - 1)`` (that is ``prev_p(0)``)."""
        v = id_arg(v, "last: v")
        m, root, q = self._vertex_paren(v)
        root_last = self.prev_p(jnp.zeros(jnp.shape(v), jnp.int32) + self._walk_start(m))
        return jnp.where(root, root_last, self.A.select1(self.P.find_close(q))).astype(jnp.int32)

    @shared_subexpression
    def next_p(self, i: Int) -> Int:
        """pemb ``next``: the next half-edge ccw around ``vertex(i)`` (cyclic)."""
        i = id_arg(i, "next_p: i")
        m = self._dart_mesh(i)
        # a tree half-edge is followed by the walk of a subtree (down) or ends the vertex (up):
        # both continue after the mate; a non-tree one by the next position
        tree = self.A.access(i) == 1
        nxt = jnp.where(tree, self.mate(i, where=tree) + 1, i + 1)
        return jnp.where(nxt >= self._walk_end(m), self._walk_start(m), nxt).astype(jnp.int32)

    @shared_subexpression
    def prev_p(self, i: Int) -> Int:
        """pemb ``prev``: the previous half-edge around ``vertex(i)`` (cw, cyclic). Fixes the
        reference code's border bug: ``prev(first(v)) = last(v)`` for every ``v``."""
        i = id_arg(i, "prev_p: i")
        m = self._dart_mesh(i)
        j = jnp.where(i == self._walk_start(m), self._walk_end(m) - 1, i - 1)
        tree = self.A.access(j) == 1
        return jnp.where(tree, self.mate(j, where=tree), j).astype(jnp.int32)

    def degree(self, v: Int) -> Int:
        """Number of half-edges leaving ``v`` (counted ccw from ``first(v)``, as the reference
        does; a ``while_loop`` bounded by the degree, batched)."""
        v = id_arg(v, "degree: v")
        f0 = self.first(v)

        limit = 2 * self.num_edges + 1  # a safety net for ids that are not vertices

        def cond(c):
            return jnp.any(c[1] != f0) & (c[2] < limit)

        def body(c):
            d, e, k = c
            more = e != f0
            return jnp.where(more, d + 1, d), jnp.where(more, self.next_p(e), e), k + 1

        d, _, _ = jax.lax.while_loop(cond, body, (jnp.ones_like(v), self.next_p(f0), jnp.int32(0)))
        return d

    @shared_subexpression
    def get_face(self, i: Int) -> Int:
        """pemb face (dual preorder, root face 0) at the left of the half-edge at ``i`` (slides'
        extra query ``get_face``). The walk crosses a non-tree half-edge from its right to its
        left face, so that face is the innermost dual node open just after ``i``; it runs along a
        tree edge on the edge's right side, so the left face of a tree half-edge is the face the
        walk is in when it passes the other half, at ``mate(i)``."""
        i = id_arg(i, "get_face: i")
        m = self._dart_mesh(i)
        tree = self.A.access(i) == 1
        x = jnp.where(tree, self.mate(i, where=tree), i)
        j = self.num_tree_parens + self.A.rank0(x + 1)  # prefix of B*, inside B B*
        q = self.P.enclose(j)
        return jnp.where(q >= self.P.size, self._root_face(m),
                         self.P.rank_open(q) - self.num_tree_parens // 2 + 1 + m).astype(jnp.int32)

    def first_dual(self, g: Int) -> Int:
        """First position (in walk order) with pemb face ``g`` on its left: the crossing that
        enters ``g`` (slides' extra query ``first_dual``). The root face 0 is entered by no
        crossing: for it, the crossing that comes back to it from face 1 (the ``)`` matching the
        first ``(`` of ``B*``; the walk crosses a non-tree half-edge from its right to its left
        face). (Position ``2m - 1`` holds a dart of the root face only when the walk ends on a
        non-tree half-edge, as the ccw DFS tree's does; after a BFS tree's last subtree it ends
        on a tree half-edge.)"""
        g = id_arg(g, "first_dual: g")
        m = self._pface_mesh(g)
        ntp = self.num_tree_parens
        q = self.P.select_open(ntp // 2 + jnp.maximum(g - 1 - m, 0))
        pos = self.A.select0(q - ntp)
        return jnp.where(g == self._root_face(m), self._root_dual(m), pos).astype(jnp.int32)

    # -------------------------------------------------------------- the mesh of an id
    # One pemb is one mesh: these are constants here. A packed union of pembs (pemb_packed)
    # answers them per mesh; every other id is the same formula plus the mesh index m (each
    # earlier mesh's root vertex and root face have no parenthesis).
    def _dart_mesh(self, i):
        return 0

    def _vertex_mesh(self, v):
        return 0

    def _pface_mesh(self, g):
        return 0

    def _walk_start(self, m):
        """First position of mesh ``m``'s walk (the cyclic ``next_p`` / ``prev_p`` wrap there)."""
        return 0

    def _walk_end(self, m):
        """One past the last position of mesh ``m``'s walk."""
        return self.num_darts

    def _root_vertex(self, m):
        return 0

    def _root_face(self, m):
        return 0

    def _root_dual(self, m):
        """``first_dual`` of mesh ``m``'s root face."""
        ntp = self.num_tree_parens
        if self.P.size > ntp:  # one scalar search (not one per lane: all lanes ask the same)
            return self.A.select0(self.P.match(jnp.int32(ntp)) - ntp)
        return jnp.int32(self.num_darts - 1)  # no dual parentheses (no face but the root)

    # -------------------------------------------------------------- per-phase tables
    def for_queries(self, num_queries: int) -> "PEMB":
        """Itself with its navigation tables (:meth:`with_tables`) when ``num_queries`` ids would
        take them one operator at a time (Target's ratio, ``table_batch_ratio``), else itself
        (``MeshStructure.for_queries``)."""
        return self.with_tables() if self.takes_table("target", num_queries) else self

    @functools.partial(_jit_when_eager, static_argnames=("twin", "origin"))
    def with_tables(self, *, twin: bool = True, origin: bool = True,
                    tables: Optional[dict] = None) -> "PEMBTables":
        """This structure with ``mate`` (``twin``) and/or ``vertex`` (``origin``) tabulated for
        every dart, as :class:`PEMBTables` (jittable; an algorithm calls it inside a jitted
        phase, which may return :attr:`PEMBTables.tables` for its later phases). Every other
        operator (``next``, ``prev``, ``cw``/``ccw``, ``face``, ``is_border``...) is composed
        from ``mate`` and ``vertex`` and becomes rank-and-gather work; ``rank`` itself reads
        per-word counters (:meth:`BitVector.with_word_rank`, 1 bit per bit, also temporary).

        Cost: the twin table is one :meth:`~BalancedParens.match_all` (a search from every ``(``
        only, then a scatter) plus a scatter inverting ``position -> parenthesis`` (so no
        ``select`` per dart), and gives ``first_dual`` of every face by one more scatter; the
        vertex table is read off the same matches by pointer doubling over ``B`` (no search at
        all: a few gather rounds over ``2(n-1)`` entries). An algorithm that asks ``twin``, ``next``,
        ``prev``, ``cw`` of all darts (Polylla's label and traversal) otherwise pays one to two
        ``mate`` searches per operator and dart.

        ``tables``: the :attr:`PEMBTables.tables` of an earlier call on this structure (a later
        phase of the same run reuses them: nothing is computed).

        Called eagerly (no traced array), the tables are computed by one jitted program (once
        per mesh shape): run primitive by primitive, they took 4-8 s per new shape and 1.2 s
        per call after that, for any mesh size (stop 46)."""
        tables = dict(tables or {})
        A, P = self._word_ranked(tables.get("ra"), tables.get("rp"))
        tw, vb, fe = tables.get("tw"), tables.get("vb"), tables.get("fe")
        twin, origin = twin and tw is None, origin and vb is None
        M = P.match_all() if twin or origin else None  # the match of every parenthesis
        if twin:
            n = self.num_darts
            i = jnp.arange(n, dtype=jnp.int32)
            a = A.access(i) == 1
            t1 = A.rank1(i)
            j = jnp.where(a, t1, self.num_tree_parens + i - t1)  # parenthesis of every position
            pos_of = jnp.zeros((P.size,), jnp.int32).at[j].set(i)  # its inverse
            tw = pos_of[M[j]]
            # first_dual(g) for every face g: the crossing that enters g is the position of g's
            # '(' in B*, and g - 1 is the rank of that '(' among B*'s (one scatter; the root
            # face, entered by no crossing, as first_dual says)
            q = jnp.arange(self.num_tree_parens, P.size, dtype=jnp.int32)
            g = self._faces_opened_at(P, q)
            fe = jnp.zeros((self._num_pemb_faces,), jnp.int32)
            fe = fe.at[jnp.where(P.is_open(q), g, fe.shape[0])].set(pos_of[q], mode="drop")
            roots, root_pos = self._root_faces()
            fe = fe.at[roots].set(root_pos)
        if origin:
            # vb[q], the innermost node open before q, without enclose searches: after a '(' it
            # is that node; after a ')' it is the same as before the matching '(' (the closed
            # subtree is a child of it): vb[q] = vb[M[q - 1]]. Those pointers go back over the
            # earlier siblings only, so pointer doubling ends in log2(most children) rounds.
            ntp = self.num_tree_parens
            q = jnp.arange(ntp + 1, dtype=jnp.int32)
            start = self._tree_block_starts(q)  # depth 0 by construction: the chains end there
            prev_open = P.is_open(jnp.maximum(q - 1, 0)) & ~start
            val = jnp.where(prev_open, self._vertices_opened_before(P, q),
                            self._VB_ROOT).astype(jnp.int32)
            ptr = jnp.where(~start & ~prev_open, M[jnp.clip(q - 1, 0, max(ntp - 1, 0))], q)
            vb = val[chain_ends(ptr.astype(jnp.int32))]
        base, tables_cls = self._table_classes()
        kw = {f.name: getattr(self, f.name) for f in dataclasses.fields(base)}
        kw.update(A=A, P=P)
        return tables_cls(**kw, tw=tw, vb=vb, fe=fe)

    def _word_ranked(self, ra=None, rp=None):
        """``(A, P)`` with per-word rank counters (:meth:`BitVector.with_word_rank`; ``ra`` /
        ``rp``, those of an earlier call, are reused; counters already held are kept)."""
        A, P = self.A, self.P
        if A.word_rank is None:
            A = A.with_word_rank() if ra is None else dataclasses.replace(A, word_rank=ra)
        if P.bits.word_rank is None:
            bits = P.bits.with_word_rank() if rp is None else dataclasses.replace(P.bits, word_rank=rp)
            P = dataclasses.replace(P, bits=bits)
        return A, P

    # hooks of with_tables that a packed union of pembs (pemb_packed) answers per mesh
    _VB_ROOT = 0  # vb's value for a prefix at depth 0 in B (the root; packed: -1, see vertex)

    def _table_classes(self):
        """``(this structure's class, its class with tables)``."""
        return PEMB, PEMBTables

    @property
    def _num_pemb_faces(self) -> int:
        """Faces of the plane graph, border loops included: ``f = |B*| / 2 + 1``."""
        return (self.P.size - self.num_tree_parens) // 2 + 1

    def _faces_opened_at(self, P, q):
        """pemb face (dual preorder) opened by the ``(`` at each position ``q`` of ``B*``
        (``q = ntp, ..., |P| - 1``, all of them; garbage at a ``)``)."""
        return P.rank_open(q) - self.num_tree_parens // 2 + 1

    def _tree_block_starts(self, q):
        """Prefix lengths ``q`` (``0 .. ntp``) that start a tree's parentheses: ``q = 0``."""
        return q == 0

    def _vertices_opened_before(self, P, q):
        """Vertex (preorder) opened by the ``(`` at ``q - 1`` of ``B``, for every prefix length
        ``q = 0, ..., ntp`` (garbage where ``q = 0`` or ``q - 1`` is a ``)``)."""
        return P.rank_open(jnp.maximum(q - 1, 0)) + 1

    def _root_faces(self):
        """``(root face ids, first_dual of each)``: the faces no crossing enters."""
        return jnp.zeros((1,), jnp.int32), PEMB.first_dual(self, jnp.zeros((1,), jnp.int32))

    # -------------------------------------------------------------- face renumbering
    def _to_mesh_face(self, g: Int) -> Int:
        h = int(self.holes.shape[0])
        if h == 0:
            return g
        k = jnp.searchsorted(self.holes, g, side="left").astype(jnp.int32)
        hole = self.holes[jnp.minimum(k, h - 1)] == g
        return jnp.where(hole, self.num_faces, g - k).astype(jnp.int32)

    def _from_mesh_face(self, f: Int) -> Int:
        h = int(self.holes.shape[0])
        if h == 0:
            return f
        shifted = self.holes - jnp.arange(h, dtype=jnp.int32)
        return (f + jnp.searchsorted(shifted, f, side="right")).astype(jnp.int32)

    def __repr__(self) -> str:
        return (f"PEMB(num_vertices={self.num_vertices}, num_faces={self.num_faces}, "
                f"num_edges={self.num_edges}, holes={int(self.holes.shape[0])}, "
                f"bits_per_edge={self.bits_per_edge:.2f})")

    # -------------------------------------------------------------- protocol
    def dart_valid(self, e: Int) -> Int:
        return (e >= 0) & (e < self.num_darts)

    def origin(self, e: Int) -> Int:
        return self.vertex(e)

    def target(self, e: Int) -> Int:
        return self.vertex(self.mate(e))

    def twin(self, e: Int) -> Int:
        return self.mate(e)

    def next(self, e: Int) -> Int:
        # (u, v) -> (v, w): cw after (v, u) around v. (Two trips of one loop body would compile
        # one search program instead of two, but ran 20% slower: measured, 100K points.)
        return self.prev_p(self.mate(e))

    def prev(self, e: Int) -> Int:
        # (u, v) -> (w, u): the twin of the ccw successor (u, w) of e around u
        return self.mate(self.next_p(e))

    def face(self, e: Int) -> Int:
        return self._to_mesh_face(self.get_face(e))

    def is_border(self, e: Int) -> Int:
        """Left face is a border loop. When the only border loop is the root face 0 (one
        boundary, the walk starts on it: every Polylla input without holes), that is "depth 0 in
        ``B*``" after the half-edge's crossing, an excess (one rank) instead of ``get_face``'s
        ``enclose`` search."""
        if not self.root_border:
            return self.face(e) == self.num_faces
        i = jnp.asarray(e, jnp.int32)
        tree = self.A.access(i) == 1
        # the mate of every lane, not only of tree lanes (where=tree): alone that costs more, but
        # next to twin(e) on the same darts (Polylla's label phase) XLA computes the search once
        # (CSE): twin + is_border 0.066 s instead of 0.081 s on 600K darts (100K points)
        x = jnp.where(tree, self.mate(i), i)
        j = self.num_tree_parens + self.A.rank0(x + 1)
        return self.P.excess(j) == 0

    def ccw_vertex_edge(self, e: Int) -> Int:
        return self.next_p(e)

    def cw_vertex_edge(self, e: Int) -> Int:
        return self.prev_p(e)

    def edge_of_vertex(self, v: Int) -> Int:
        return self.first(v)

    def edge_of_face(self, f: Int) -> Int:
        return self.first_dual(self._from_mesh_face(jnp.asarray(f, jnp.int32)))

    def face_vertices(self) -> Int:
        """``(num_faces, 3)`` vertices of every triangle, ccw: the protocol's route (first dart,
        two ``next``, three ``origin``) on per-call navigation tables (:meth:`with_tables`: one
        :meth:`~BalancedParens.match_all`, then gathers), dropped when the call returns.

        A whole-mesh question asks every dart anyway; per dart, the route costs five ``mate``
        searches and three ``enclose``-free vertex lookups, and each search inlines the whole
        min-max-tree program: traced as it is, the route took 14-30 s to compile for a 30-vertex
        mesh (every shape anew), against about 2 s on the tables."""
        return MeshStructure.face_vertices(self.with_tables())


def _table_route(op: str, needs: tuple):
    """``PEMB._tabled_<op>(ids)``: operator ``op`` of :meth:`PEMB.with_tables` holding the
    tables ``needs`` names, built for this call (``MeshStructure.table_queries``)."""

    @by_table
    def route(self, d: Int) -> Int:
        tabled = self.with_tables(twin="twin" in needs, origin="origin" in needs)
        return getattr(tabled, op)(d)

    route.__name__ = route.__qualname__ = "_tabled_" + op
    return route


def _face_route(op: str, needs: tuple):
    """``PEMB._tabled_face`` / ``_tabled_is_border``: every dart's face tabulated once
    (:meth:`TableOperators.dart_face_table`: no ``enclose`` search per id), then one gather per
    id (``is_border``: the face is a border loop's, ``num_faces``)."""

    @by_table
    def route(self, d: Int) -> Int:
        tabled = self.with_tables(twin="twin" in needs, origin="origin" in needs)
        f = tabled.dart_face_table()[jnp.asarray(d, jnp.int32)]
        return f == self.num_faces if op == "is_border" else f

    route.__name__ = route.__qualname__ = "_tabled_" + op
    return route


for _op, _needs in PEMB._TABLE_OPS.items():
    _route = _face_route if _op in ("face", "is_border") else _table_route
    setattr(PEMB, "_tabled_" + _op, _route(_op, _needs))


class TableOperators:
    """The operators of a pemb with per-phase tables (:class:`PEMBTables`, and the packed
    union's :class:`~jaxcds.structures.pemb_packed.PackedPEMBTables`): ``mate``, ``vertex`` and
    ``first_dual`` read from ``tw``, ``vb``, ``fe`` when set, searched otherwise."""

    table_queries: dict = {}  # the tables are here already (one missing is searched per id)

    @property
    def tables(self) -> dict:
        """The tables held (``{"tw": ..., "vb": ...}``, those that are set): a jitted phase
        returns them so a later phase can reuse them (:meth:`PEMB.with_tables`)."""
        out = {"ra": self.A.word_rank, "rp": self.P.bits.word_rank, "tw": self.tw,
               "vb": self.vb, "fe": self.fe}
        return {k: v for k, v in out.items() if v is not None}

    def with_tables(self, *, twin: bool = True, origin: bool = True,
                    tables: Optional[dict] = None) -> "PEMBTables":
        """Itself when it holds the tables asked for, else the missing ones added."""
        if not tables and (not twin or self.tw is not None) and (not origin or self.vb is not None):
            return self
        return PEMB.with_tables(self, twin=twin, origin=origin,
                                tables=dict(self.tables, **(tables or {})))

    def mate(self, i: Int, where=None) -> Int:
        if self.tw is None:
            return super().mate(i, where)
        return self.tw[id_arg(i, "mate: i")]

    def first_dual(self, g: Int) -> Int:
        if self.fe is None:
            return super().first_dual(g)
        return self.fe[id_arg(g, "first_dual: g")]

    def vertex(self, i: Int) -> Int:
        if self.vb is None:
            return super().vertex(i)
        i = id_arg(i, "vertex: i")
        return self._vb_answer(self.vb[self.A.rank1(i)], i)

    def dart_face_table(self) -> Int:
        """``(num_darts,)`` ``face`` of every dart, from ``fe`` and ``tw``: a triangle's first
        dart ``first_dual(g)`` and the two ``next`` of it carry its face id, a border loop's
        darts ``num_faces`` (three scatters over the faces; ``get_face`` searched ``enclose``
        per dart)."""
        g = jnp.arange(self._num_pemb_faces, dtype=jnp.int32)
        f = self._to_mesh_face(g)
        triangle = f < self.num_faces  # the border loops map to num_faces
        table = jnp.full((self.num_darts,), self.num_faces, jnp.int32)
        d = self.first_dual(g)
        for _ in range(3):
            table = table.at[jnp.where(triangle, d, self.num_darts)].set(f, mode="drop")
            d = self.next(d)
        return table

    def _vb_answer(self, v, i):
        """``vertex(i)`` from ``v = vb[rank1(A, i)]``: a negative entry (a packed union's depth-0
        prefix, :attr:`_VB_ROOT`) is the root of the dart's mesh."""
        return jnp.where(v < 0, self._root_vertex(self._dart_mesh(i)), v)

    def __repr__(self) -> str:
        return (super().__repr__()[:-1] + f", tables={'tw' if self.tw is not None else ''}"
                f"{'+vb' if self.vb is not None else ''})")


@pytree_dataclass
class PEMBTables(TableOperators, PEMB):
    """A :class:`PEMB` carrying per-phase navigation tables (:meth:`PEMB.with_tables`): the same
    structure and protocol, with ``mate`` and ``vertex`` read from arrays instead of searched.

    Fields (besides :class:`PEMB`'s; ``None`` = not tabulated, searched as in :class:`PEMB`):
      tw: ``(2m,)`` int32, ``mate`` of every position (``twin`` of every dart).
      vb: ``(2(n-1) + 1,)`` int32, for every prefix length ``r`` of ``B``, the vertex whose
        parenthesis is the innermost open one after ``r`` symbols (``vertex(i) = vb[rank1(A, i)]``).
      fe: ``(f,)`` int32, ``first_dual`` of every pemb face (``edge_of_face`` without selects).

    Meant to live inside one jitted phase of an algorithm that asks the same operators of every
    dart (Polylla): built there, dropped with the phase's other temporaries. ``tw`` is 32 bits per
    dart (64 per edge, against the 5.25 of the structure), ``vb`` 64 bits per vertex; both are
    transient and not counted in :attr:`~PEMB.bits`."""

    tw: Optional[jnp.ndarray] = None
    vb: Optional[jnp.ndarray] = None
    fe: Optional[jnp.ndarray] = None


@numba.njit(cache=True)
def _tree_kernel(opp, ccw, vert, start, num_vertices, lifo):
    h = opp.size
    first = np.full(num_vertices, -1, np.int64)  # one dart leaving each vertex: the lowest
    for e in range(h):
        if first[vert[e]] < 0:
            first[vert[e]] = e
    root = vert[start]
    if lifo:
        first[root] = start  # the original scans its root from the walk's first dart
    mask = np.zeros(h, np.bool_)
    seen = np.zeros(num_vertices, np.bool_)
    queue = np.empty(num_vertices, np.int64)
    seen[root] = True
    queue[0] = root
    head, tail = 0, 1
    while head < tail:
        if lifo:  # a stack: the last vertex found is scanned next
            tail -= 1
            v = queue[tail]
        else:
            v = queue[head]
            head += 1
        e0 = first[v]
        e = e0
        for _ in range(h):  # the darts around v, ccw
            w = vert[opp[e]]
            if not seen[w]:  # marked when found: its parent is the first vertex that saw it
                seen[w] = True
                mask[e] = True
                mask[opp[e]] = True
                queue[tail] = w
                tail += 1
            e = ccw[e]
            if e == e0:
                break
    return mask


def _bfs_tree(opp, ccw, vert, start, num_vertices):
    """Dart mask of a BFS spanning tree from ``vert[start]`` (both halves of each tree edge;
    neighbours met ccw around each vertex). Linear, one numba pass (the walk refuses a mask that
    is not a spanning tree, e.g. on a disconnected mesh, with a typed error)."""
    return _tree_kernel(*_i64(opp, ccw, vert), int(start), int(num_vertices), False)


def _stack_tree(opp, ccw, vert, start, num_vertices):
    """Dart mask of the original implementation's spanning tree (jfuentess/pemb,
    ``seq_dfs_spanning_tree``): a stack from ``vert[start]``, a vertex marked when it is pushed
    (so its parent is the first vertex that met it: not a depth-first tree), neighbours met ccw
    from the lowest dart leaving each vertex (the first one its input file lists), the root's
    from ``start``. Linear, one numba pass."""
    return _tree_kernel(*_i64(opp, ccw, vert), int(start), int(num_vertices), True)


def _i64(*arrays):
    return tuple(np.ascontiguousarray(a, np.int64) for a in arrays)


def from_mesh(mesh) -> PEMB:
    """Registry builder: :meth:`PEMB.from_mesh`."""
    return PEMB.from_mesh(mesh)


from jaxcds.structures import registry as _registry  # noqa: E402

_registry.register("pemb", from_mesh,
                   description="succinct planar embedding (Ferres et al. 2017): 4m bits + support, "
                               "connected genus-0 meshes, borders allowed")
