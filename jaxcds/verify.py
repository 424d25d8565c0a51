"""Compare any structure with the HalfEdge, every operator on every dart.

Darts of different structures have different ids, so each dart is compared through what it
*means*: its ``(origin, target)`` pair in input vertex ids (through ``vertex_order``). Faces are
compared as the set of their vertices. This is what ``jaxcds build --verify`` runs and what the
tests run on every shared mesh.
"""

from __future__ import annotations

import dataclasses
import os
from concurrent.futures import ThreadPoolExecutor
from typing import Dict, Optional

import jax
import jax.numpy as jnp
import numpy as np

from jaxcds import errors
from jaxcds._arrays import to_device
from jaxcds.mesh import TriMesh
from jaxcds.structures.base import per_query_routes, shared_subexpressions
from jaxcds.structures.halfedge import HalfEdge

__all__ = ["VerifyReport", "verify", "DART_OPERATORS"]

#: operators dart -> dart checked on every dart
DART_OPERATORS = ("twin", "next", "prev", "left_front", "left_back", "right_front", "right_back",
                  "ccw_vertex_edge", "cw_vertex_edge", "corner_opposite", "corner_swing")


@dataclasses.dataclass
class VerifyReport:
    """Outcome of :func:`verify`: ``checked`` comparisons, ``mismatches`` among them, and the
    mismatch count per operator (with one example dart each in ``examples``)."""

    structure: str
    checked: int = 0
    mismatches: int = 0
    by_operator: Dict[str, int] = dataclasses.field(default_factory=dict)
    examples: Dict[str, str] = dataclasses.field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.mismatches == 0 and self.checked > 0

    def add(self, op: str, bad: np.ndarray, total: int, example: str = "") -> None:
        n = int(np.sum(bad))
        self.checked += int(total)
        self.mismatches += n
        self.by_operator[op] = self.by_operator.get(op, 0) + n
        if n and op not in self.examples:
            self.examples[op] = example

    def __str__(self) -> str:
        bad = {k: v for k, v in self.by_operator.items() if v}
        return (f"{self.structure}: {self.checked} checks, {self.mismatches} mismatches"
                + (f" {bad} e.g. {self.examples}" if bad else ""))


def _pair_keys(u: np.ndarray, v: np.ndarray, n: int) -> np.ndarray:
    return u.astype(np.int64) * n + v.astype(np.int64)


@jax.jit
def _apply_all(s, e):
    # every operator of the same darts: their common first steps traced once (pemb's mate(e)
    # begins a dozen of them; see shared_subexpressions)
    with shared_subexpressions():
        out = {op: getattr(s, op)(e) for op in DART_OPERATORS}
        out["origin"] = s.origin(e)
        out["target"] = s.target(e)
        out["face"] = s.face(e)
        out["face_left"] = s.face_left(e)
        out["face_right"] = s.face_right(e)
        out["is_border"] = s.is_border(e)
    return out


@jax.jit
def _endpoints(s, e):
    return s.origin(e), s.target(e)


@jax.jit
def _other_routes(s, e):
    """``{(op, route): answers}`` for every operator the structure answers from a whole-mesh
    table for large batches (``MeshStructure.table_queries``): the route that
    :func:`_apply_all` did *not* take for a batch this large (decided, as there, from its static
    size), forced, so that both routes are checked on every dart."""
    out = {}
    with shared_subexpressions():  # pemb's per-query routes begin with the same searches
        for op, method in s.table_queries.items():
            if s.takes_table(op, jnp.size(e)):
                with per_query_routes():
                    out[(op, "per-query")] = getattr(s, op)(e)
            else:
                out[(op, "table")] = getattr(s, method)(e)
    return out


@jax.jit
def _whole_mesh(s):
    """The whole-mesh answers that :func:`verify` checks, in one program: every face's
    vertices; ``edge_of_vertex`` of every vertex with its origin and validity; the face of
    ``edge_of_face`` of every face. (Called eagerly one by one, a succinct structure's operators
    re-traced their loops on every call: 25 s for a 30-vertex pemb.)"""
    vs = jnp.arange(s.num_vertices, dtype=jnp.int32)
    ev = s.edge_of_vertex(vs)
    fs = jnp.arange(s.num_faces, dtype=jnp.int32)
    return s.face_vertices(), s.origin(ev), s.dart_valid(ev), s.face(s.edge_of_face(fs))


def _compile_ahead(programs) -> Optional[list]:
    """Compile and run every ``(jitted fn, args)`` of ``programs``, a few at a time on worker
    threads, and return their results in order (``None`` where it did not run): the programs
    are independent, XLA releases the GIL while it compiles, and verify then finds each in
    jit's cache and takes the results it can use as they are. Compilation is verify's cost
    on a mesh of a few thousand vertices: on 2 cores (stop 55's AMD host) pemb on the bunny took
    32 s so, against 43-48 s one program after the other. On an error (or Ctrl-C) the programs
    not yet started are dropped, not waited for; those already compiling finish in the
    background (XLA cannot be stopped mid-compilation: a script interrupted there exits when
    they are done, a few seconds to half a minute).

    Skipped under ``jax.disable_jit()``: verify's calls then run op by op and would use none
    of it (JAX's settings blocks are per thread, so the workers would compile anyway)."""
    workers = min(4, os.cpu_count() or 1, len(programs))
    if workers < 2 or jax.config.jax_disable_jit:
        return None
    pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="jaxcds-verify")
    try:
        futures = [pool.submit(fn, *args) for fn, args in programs]
        # in order: the first error, as a serial run would raise it
        return [jax.block_until_ready(f.result()) for f in futures]
    finally:
        pool.shutdown(wait=False, cancel_futures=True)


def _open_surface(mesh: TriMesh) -> TriMesh:
    """``mesh`` without its flagged dummy vertices and fan faces, the others renumbered in
    order (as LR numbers a mesh the user closed)."""
    keep = ~np.asarray(mesh.dummy_vertices, bool)
    remap = np.cumsum(keep) - 1
    faces = remap[mesh.faces[~np.asarray(mesh.dummy_faces, bool)]].astype(np.int32)
    return TriMesh(vertices=mesh.vertices[keep], faces=faces, source=mesh.source)


def verify(structure, mesh: TriMesh, reference: Optional[HalfEdge] = None,
           *, chunk: int = 1 << 20, adjacency_samples: int = 10_000, seed: int = 0) -> VerifyReport:
    """Check every protocol operator of ``structure`` on every valid dart against the HalfEdge
    of ``mesh`` (the mesh the structure was built from, dummy vertices included; an open mesh
    given with a CDS that closed its holes is closed here the same way).

    ``mesh`` must be a :class:`~jaxcds.mesh.TriMesh` (``(vertices, faces)`` arrays or a path:
    :func:`jaxcds.mesh.load_mesh` first, as the builder was given).

    ``reference``: the mesh's :class:`HalfEdge`, if already built. ``chunk``: darts per batch of
    operator calls (a positive integer); ``adjacency_samples``: how many edges and how many
    random vertex pairs ``adjacent`` is checked on (a non-negative integer); ``seed``: the random
    pairs' seed (a non-negative integer, or ``None``).

    Raises:
      ArgumentError: ``structure`` is not a jaxcds structure, ``mesh`` is not a
        :class:`~jaxcds.mesh.TriMesh`, or the structure and the mesh do not have the same number
        of vertices; ``reference`` is not a :class:`HalfEdge`; ``chunk``, ``adjacency_samples``
        or ``seed`` out of the above (``chunk=-1`` checked no dart at all and reported no
        mismatch; ``chunk=0`` and the others raised Python's or numpy's untyped errors)."""
    from jaxcds._args import is_integer
    from jaxcds.structures.base import MeshStructure

    for what, value, low in (("chunk", chunk, 1), ("adjacency_samples", adjacency_samples, 0),
                             ("seed", 0 if seed is None else seed, 0)):
        if not is_integer(value) or value < low:
            kind = "a positive" if low else "a non-negative"
            raise errors.ArgumentError(f"verify: {what} must be {kind} integer, got "
                                       f"{(seed if what == 'seed' else value)!r}")
    if reference is not None and not isinstance(reference, HalfEdge):
        raise errors.ArgumentError(f"verify: reference must be the mesh's HalfEdge (or None), got "
                                   f"{type(reference).__name__}")

    if not isinstance(structure, MeshStructure):  # AttributeError on num_vertices before
        swapped = " (the arguments are swapped?)" if isinstance(structure, TriMesh) else ""
        raise errors.ArgumentError(
            f"verify: structure must be a jaxcds structure (a MeshStructure, e.g. from "
            f"jaxcds.structures.registry.build(name, mesh)), got "
            f"{type(structure).__name__}{swapped}")
    if not isinstance(mesh, TriMesh):
        raise errors.ArgumentError(
            f"verify: mesh must be a jaxcds.mesh.TriMesh (the mesh the structure was built "
            f"from), got {type(mesh).__name__}; load (vertices, faces) arrays or a file with "
            f"jaxcds.mesh.load_mesh")
    s = structure
    if s.num_vertices != mesh.num_vertices and s.dummy_vertex_mask() is not None and reference is None:
        from jaxcds.mesh import close_boundaries

        mesh = close_boundaries(mesh)  # as the builder did (Sec. 4.5): dummies appended
    elif (s.num_vertices != mesh.num_vertices and mesh.dummy_vertices is not None and reference is None
          and int((~mesh.dummy_vertices).sum()) == s.num_vertices):
        mesh = _open_surface(mesh)  # a closed mesh given to LR, which drops flagged dummies
    if s.num_vertices != mesh.num_vertices:
        raise errors.ArgumentError(
            f"verify: the {getattr(s, 'name', type(s).__name__)} has {s.num_vertices} vertices, the "
            f"mesh {mesh.num_vertices}: pass the mesh the structure was built from")
    he = reference if reference is not None else HalfEdge.from_faces(mesh.faces, mesh.num_vertices)
    rep = VerifyReport(structure=getattr(s, "name", type(s).__name__))
    n = mesh.num_vertices
    order = s.vertex_order
    to_input = (lambda x: np.asarray(order)[x]) if order is not None else (lambda x: x)
    from_input = None
    if order is not None:
        from_input = np.empty(n, dtype=np.int64)
        from_input[np.asarray(order)] = np.arange(n)

    he_darts = he.all_darts()
    s_darts = s.all_darts()
    tables = bool(getattr(s, "table_queries", None))
    programs = [(_apply_all, (he, to_device(he_darts))), (_whole_mesh, (s,))]
    for size in sorted({min(chunk, len(s_darts)), len(s_darts) % chunk} - {0}):  # the chunks' sizes
        e = to_device(s_darts[:size])  # any darts of that size compile its programs
        programs += [(_apply_all, (s, e)), (_endpoints, (s, e))]
        if tables:
            programs.append((_other_routes, (s, e)))
    ahead = _compile_ahead(programs)
    # the two whole-mesh results as the threads left them (not computed a second time)
    he_out, whole = ahead[:2] if ahead else (fn(*args) for fn, args in programs[:2])
    del ahead

    # reference: key (u, v) -> results
    he_res = {k: np.asarray(v) for k, v in he_out.items()}
    he_keys = _pair_keys(he_res["origin"], he_res["target"], n)
    srt = np.argsort(he_keys)
    he_faces = np.sort(np.asarray(he.face_vertices()), axis=1)

    def he_lookup(keys):
        pos = np.searchsorted(he_keys, keys, sorter=srt)
        pos = np.clip(pos, 0, len(srt) - 1)
        idx = srt[pos]
        return idx, he_keys[idx] == keys

    rep.add("dart_count", np.array([len(s_darts) != len(he_darts)]), 1,
            f"{len(s_darts)} darts vs {len(he_darts)}")
    s_faces, ev_origin, ev_valid, ef_face = (np.asarray(x) for x in whole)
    s_faces = np.sort(to_input(s_faces), axis=1)
    he_fkey, s_fkey = _face_ids(he_faces, s_faces)

    for lo in range(0, len(s_darts), chunk):
        e = s_darts[lo: lo + chunk]
        res = {k: np.asarray(v) for k, v in _apply_all(s, to_device(e)).items()}
        u, v = to_input(res["origin"]), to_input(res["target"])
        idx, found = he_lookup(_pair_keys(u, v, n))
        rep.add("dart_exists", ~found, len(e), f"dart {e[~found][:1]} = {u[~found][:1]}->{v[~found][:1]}")
        if tables:
            for (op, route), got in _other_routes(s, to_device(e)).items():
                bad = np.asarray(got) != res[op]
                rep.add(f"{op} ({route} route)", bad, len(e), f"dart {e[bad][:1]}")
        for op in DART_OPERATORS:
            r = res[op]
            ru, rv = _endpoints(s, to_device(r))
            got = _pair_keys(to_input(np.asarray(ru)), to_input(np.asarray(rv)), n)
            want_d = he_res[op][idx]
            want = _pair_keys(he_res["origin"][_he_index(he_darts, want_d)],
                              he_res["target"][_he_index(he_darts, want_d)], n)
            bad = found & (got != want)
            rep.add(op, bad, len(e), f"dart {e[bad][:1]}")
        for op in ("face_left", "face_right"):
            f_s = np.where(res[op] >= s.num_faces, -1, res[op])
            f_h = np.where(he_res[op][idx] >= he.num_faces, -1, he_res[op][idx])
            got = np.where(f_s < 0, -1, s_fkey[f_s])
            want = np.where(f_h < 0, -1, he_fkey[f_h])
            bad = found & (got != want)
            rep.add(op, bad, len(e), f"dart {e[bad][:1]}")
        bad = found & (res["is_border"] != he_res["is_border"][idx])
        rep.add("is_border", bad, len(e), f"dart {e[bad][:1]}")

    # edge_of_vertex: a dart leaving v
    rep.add("edge_of_vertex", ~ev_valid | (ev_origin != np.arange(n)), n, "")
    # edge_of_face: a dart with face f on its left
    rep.add("edge_of_face", ef_face != np.arange(s.num_faces), s.num_faces, "")
    rep.add("face_count", np.array([s.num_faces != he.num_faces]), 1, f"{s.num_faces} vs {he.num_faces}")
    # adjacency: every edge (true) and random pairs (mostly false)
    from jaxcds.algorithms.adjacency import adjacent

    rng = np.random.default_rng(seed)
    uu = np.concatenate([he_res["origin"][:adjacency_samples], rng.integers(0, n, adjacency_samples)])
    vv = np.concatenate([he_res["target"][:adjacency_samples], rng.integers(0, n, adjacency_samples)])
    want = _adjacent_reference(he_keys, uu, vv, n)
    su = from_input[uu] if from_input is not None else uu
    sv = from_input[vv] if from_input is not None else vv
    got = np.asarray(adjacent(s, jnp.asarray(su, jnp.int32), jnp.asarray(sv, jnp.int32)))
    rep.add("adjacent", got != want, len(uu), "")
    return rep


def _he_index(he_darts: np.ndarray, d: np.ndarray) -> np.ndarray:
    # HalfEdge darts are 0..H-1 without holes: the dart is its own row
    return d


def _face_ids(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Common ids for two lists of sorted vertex triples (equal triples, equal ids)."""
    _, inv = np.unique(np.concatenate([a, b]), axis=0, return_inverse=True)
    inv = inv.ravel()
    return inv[: len(a)], inv[len(a):]


def _adjacent_reference(he_keys: np.ndarray, u: np.ndarray, v: np.ndarray, n: int) -> np.ndarray:
    keys = np.sort(he_keys)
    q = _pair_keys(u, v, n)
    pos = np.clip(np.searchsorted(keys, q), 0, len(keys) - 1)
    return keys[pos] == q
