"""Polylla: polygonal meshes from terminal-edge regions, written once against the navigation protocol.

Salinas-Fernández, Hitschfeld-Kahler, Ortiz-Bernardin, Si, *POLYLLA: polygonal meshing algorithm
based on terminal-edge regions*, Engineering with Computers 38(5), 2022 (Alg. 1-4); IMR 2023 slides
(``../shared/seeds/004_*``): "label phase, traversal phase, polygon reparation phase".

Vocabulary (paper Sec. 2). The *longest-edge propagation path* Lepp(t) of a triangle walks to the
neighbour across the longest edge until the longest edge is shared by both triangles (a *terminal
edge*) or lies on the border (a *border terminal edge*). A *terminal-edge region* is the union of
the triangles whose Lepp ends at the same terminal edge; every region becomes one polygon. An edge
is a *frontier edge* when it lies on the border or is the longest edge of neither of its triangles
(Def. 4: its two triangles are in different regions, or it is a *barrier edge*: both triangles in
the same region); a *barrier-edge tip* is the end of a barrier edge with no other frontier edge.

Every phase is a set of elementwise or gather operations on dart arrays, jitted, and calls only
the protocol operators (``origin``, ``target``, ``twin``, ``next``, ``prev``, ``is_border``,
``cw_vertex_edge``, ``ccw_vertex_edge``, ``dart_valid``), so it runs unchanged on every structure
that accepts borders (HalfEdge, pemb). A structure whose operators are searches may offer
per-run navigation tables (``with_tables``: pemb tabulates ``twin``, ``origin`` and
``edge_of_face`` of every dart / face once, in the label phase, and the later phases navigate the
tabulated structure through the same protocol; :func:`_tabulated`):

1. :func:`label_phase` (Alg. 1 lines 1-9, elementwise): longest edge of each triangle, frontier
   edges, seed edges (one dart per terminal / border terminal edge).
2. :func:`traversal_phase` (Alg. 2): the reference walks each polygon from its seed turning
   clockwise around vertices until it meets a frontier edge (``search_frontier_edge``). Here that
   walk is a *successor map* on frontier darts: ``succ(f)`` = first frontier dart met turning
   clockwise (``cw_vertex_edge``) from ``next(f)``; the polygons are its cycles. The "turn until
   frontier" table is computed for all darts at once by pointer doubling (``O(log deg)`` gathers).
3. :func:`barrier_tips` / :func:`middle_edges` / :func:`repair_phase` (Alg. 3-4): a tip is a dart
   whose successor is its own twin (the walk goes up a barrier edge and straight back); the edge in
   the middle of the tip's fan (reference ``search_middle_edge``: ``deg // 2`` clockwise turns from
   the barrier edge) becomes frontier, and only the successors around the new frontier darts
   change (two short rotations per new dart).
4. :func:`cycles_to_csr`: the cycles of the successor map become CSR arrays by pointer doubling
   (smallest directed edge of each cycle, then list ranking), ``O(log L)`` gathers for polygons
   of up to ``L`` vertices; no per-polygon loop. That suits a GPU; on a CPU device
   :func:`polylla` lists the cycles on the host instead, one walk per cycle
   (:mod:`jaxcds.algorithms.polylla_cycles`, O(N): 1M points 0.99 s of doubling on two cores),
   with the same arrays as a result.

Output is canonical and independent of the structure's dart numbering: every polygon starts at
its lexicographically smallest directed edge ``(origin, target)`` (input vertex ids) and the
polygons are sorted by that edge, so HalfEdge and pemb give identical arrays.

Two modes (:func:`polylla`, ``mode``). The phases above are ``"canonical"``: every barrier-edge
tip of a region is repaired and the result does not depend on how the input is numbered.
``"reference"`` -- the default whenever the input's rows are known (``corners``; :func:`run` and
the CLI always pass them) -- keeps phase 1 and replaces phases 2-4 by the reference
implementation's own sequential walk and repair on the input's numbering
(:mod:`jaxcds.algorithms.polylla_reference`, one numba pass over the structure's darts read
into host arrays): the output is then the reference's file, polygon for polygon and vertex for
vertex, including where the reference's walk stops early at its starting vertex (a tip can stay
in a polygon) and where its tips are repaired in turn from ``edge_of_vertex`` (the split
depends on the numbering). Against the reference port of the tests, 3,000 random points: the
modes differ in 4 to 15 polygons in 6 of 8 sets; reference mode equals the port in all.

Host-side parts (said here, as the issue asks): reading back the tip darts (a ``nonzero``) and
the number of frontier darts to size the compacted arrays between phases, on a CPU device the
polygon lists (phase 4, above), sorting the polygons
by their first edge (numpy ``lexsort``, optional), and counting the repaired polygons (connected
components of the pieces joined by the new middle edges, scipy, one graph edge per tip).

Lengths are Euclidean, ``sqrt(dx^2 + dy^2)`` as the reference's ``distance()`` (in the dtype
of ``positions``; :func:`polylla` uses float64, ``jax.enable_x64``). Ties between equally long
edges of a triangle go, as in the reference, to the first of ``c0c1, c1c2, c2c0`` in the input's
corner order (``corners``, :func:`polylla`; without it, to the smaller input vertex-id pair
``(min id, max id)``, a rule that needs no face order). The reference keeps the input's
orientation: on an input of clockwise triangles its polygons run clockwise and its repair turns
the other way (:func:`middle_edges`); :func:`polylla` does the same (``clockwise``).
"""

from __future__ import annotations

import dataclasses
import functools
import time
from typing import Optional

import jax
import jax.numpy as jnp
import numpy as np

from jaxcds import errors
from jaxcds._args import flag_arg, refuse_non_real
from jaxcds._arrays import to_device
from jaxcds.polylla_io import BORDER_STRUCTURES  # (re-exported: the structures Polylla runs on)

__all__ = ["PolyllaMesh", "polylla", "label_phase", "traversal_phase", "barrier_tips",
           "middle_edges", "repair_phase", "cycles_to_csr", "polygons_as_cycles",
           "canonical_cycle"]

_BIG = np.int32(np.iinfo(np.int32).max)


def _darts(s):
    return jnp.arange(s.num_darts, dtype=jnp.int32)


def _tabulated(s, **tables):
    """The structure a phase navigates: ``s.with_tables(**tables)`` where the structure offers
    per-phase navigation tables (pemb: ``twin`` / ``origin`` of every dart, so its ``next``,
    ``prev``, ``cw``... become gathers instead of one or two parenthesis searches each), else
    ``s`` itself (the HalfEdge's arrays already are those tables). The phases still ask only
    the protocol operators, of the structure this returns.

    :func:`polylla` tabulates once, in the label phase (which returns the tables), and runs the
    later phases on the tabulated structure (a structure that already holds the tables asked for
    returns itself). The public :func:`traversal_phase`, :func:`middle_edges`... navigate the
    structure they are given: pass them ``s.with_tables()`` for table speed.
    The tables are temporaries of one run (pemb: 32 bits per dart and 64 per vertex, against
    the structure's 5.25 bits per edge; they go when the run returns)."""
    f = getattr(s, "with_tables", None)
    return s if f is None else f(**tables)


# ------------------------------------------------------------------------------ 1. label
@functools.partial(jax.jit, static_argnames=("tabulate",))
def _label_phase(s, positions, vertex_ids, corners=None, tabulate: bool = True):
    """:func:`label_phase` plus ``is_border`` of every dart (the traversal reuses it instead of
    asking the structure again: a parenthesis search per dart on pemb), the navigation tables
    of :func:`_tabulated` (None on a structure without them, or with ``tabulate=False``), for
    the later phases, and two flags for ``corners`` (see :func:`_label_body`)."""
    if not tabulate:  # the structure's own operators only (pemb: a search per query)
        return _label_body(s, positions, vertex_ids, corners) + (None,)
    # every dart's twin and origin are asked (most several times): tabulate them once
    t = _tabulated(s, twin=True, origin=True)
    return _label_body(t, positions, vertex_ids, corners) + (getattr(t, "tables", None),)


def _corner_index(x, corners):
    """Index of input vertex ``x`` in each row of ``corners`` (3 where it is not there)."""
    return jnp.where(x == corners[:, 0], 0, jnp.where(x == corners[:, 1], 1,
                                                      jnp.where(x == corners[:, 2], 2, 3)))


def _label_body(s, positions, vertex_ids, corners=None):
    """Label phase; returns ``(max_edge, frontier, seed, border_any, misplaced, tied,
    clockwise_rows)``.

    Lengths are Euclidean (``sqrt``, in the dtype of ``positions``), as the reference computes
    them: its published outputs (``points50.1.off``, ``pikachu.1.off``) were made so, and two
    edges 1 ulp apart squared can be equal after the square root (a tie there).

    Ties between equally long edges of a triangle go, as in the reference, to the first of its
    edges ``c0c1, c1c2, c2c0`` in the input's corner order, given by ``corners`` (``(F, 3)``
    input vertex ids of face ``f`` of ``s`` as the input listed them); without ``corners``, to
    the smaller ``(min id, max id)`` input vertex pair (a rule that needs no face order).
    ``misplaced``: some face of ``s`` is not the triangle of its ``corners`` row (the caller maps
    them and runs again, if ``tied``: some triangle has a tie for its longest edge).
    ``clockwise_rows``: every ``corners`` row turns clockwise (negative signed area; read off
    the faces' positions and the rows' corner order, meaningful when not ``misplaced``)."""
    # longest edge, per triangle: its three darts from edge_of_face / next, lengths from origins
    f = jnp.arange(s.num_faces, dtype=jnp.int32)
    e0 = s.edge_of_face(f)
    e1 = s.next(e0)
    e2 = s.next(e1)
    v0, v1, v2 = s.origin(e0), s.origin(e1), s.origin(e2)
    p0, p1, p2 = positions[v0], positions[v1], positions[v2]
    i0, i1, i2 = vertex_ids[v0], vertex_ids[v1], vertex_ids[v2]

    def length(a, b):
        # each square rounded before the sum, as the reference's pow(dx, 2) + pow(dy, 2): XLA:CPU
        # contracted the product into the add (one fused multiply-add) in its scalar loops (a
        # short array, a remainder), 1 ulp off the reference in about 8% of lengths, and a
        # near-tie for the longest edge then went the other way (sweep 52b's pinch search).
        # The select of max() stands between the multiply and the add: no contraction
        d = a - b
        return jnp.sqrt(jnp.sum(jnp.maximum(d * d, 0.0), axis=-1))

    l0, l1, l2 = length(p0, p1), length(p1, p2), length(p2, p0)
    top = jnp.maximum(jnp.maximum(l0, l1), l2)
    # each flag converted explicitly: users may run with strict dtype promotion
    i32 = jnp.int32
    tied = jnp.any(((l0 == top).astype(i32) + (l1 == top).astype(i32) + (l2 == top).astype(i32)) > 1)
    if corners is None:
        k0 = (jnp.minimum(i0, i1), jnp.maximum(i0, i1))
        k1 = (jnp.minimum(i1, i2), jnp.maximum(i1, i2))
        k2 = (jnp.minimum(i2, i0), jnp.maximum(i2, i0))
        misplaced = jnp.bool_(False)
        clockwise_rows = jnp.bool_(False)
    else:
        # edge {v_j, v_j+1} is the input's edge c_k c_k+1 with c_k+2 = v_j+2 opposite it: its
        # rank in the reference's order is k = (index of the opposite corner + 1) mod 3
        c = jnp.asarray(corners, jnp.int32)
        x0, x1, x2 = (_corner_index(i, c) for i in (i0, i1, i2))
        misplaced = jnp.any((x0 == 3) | (x1 == 3) | (x2 == 3))
        k0, k1, k2 = (((x + 1) % 3, 0) for x in (x2, x0, x1))
        # a row listing the face's corners the other way round has the opposite signed area
        a, b = p1 - p0, p2 - p0
        area = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
        turned = (x1 - x0) % 3 == 2
        clockwise_rows = (s.num_faces > 0) & jnp.all(jnp.where(turned, area > 0, area < 0))

    def beats(la, ka, lb, kb):
        # a is longer than b, or as long and with the smaller key
        return (la > lb) | ((la == lb) & ((ka[0] < kb[0]) | ((ka[0] == kb[0]) & (ka[1] < kb[1]))))

    first = beats(l0, k0, l1, k1) & beats(l0, k0, l2, k2)
    second = ~first & beats(l1, k1, l2, k2)
    longest = jnp.where(first, e0, jnp.where(second, e1, e2))
    E = s.num_darts
    max_edge = jnp.zeros((E,), bool).at[longest].set(True, mode="drop")

    e = _darts(s)
    valid = s.dart_valid(e)
    border_any = s.is_border(e)
    border = border_any & valid
    inner = valid & ~border
    tw = s.twin(e)
    # is_border(twin(e)) read from the array of all darts' flags (a gather, not a second
    # is_border per dart: on pemb that is a parenthesis search each)
    border_t = border_any[jnp.clip(tw, 0, E - 1)]
    max_t = max_edge[tw]
    # Def. 4: frontier = border edge, or an edge that is the longest of neither triangle
    frontier = valid & (border | border_t | ~(max_edge | max_t))
    # Def. 3 case "terminal edge": longest of both triangles (one dart kept, the smaller id);
    # case "border terminal edge": longest of its only triangle
    seed = inner & max_edge & (border_t | (max_t & (e < tw)))
    return max_edge, frontier, seed, border_any, misplaced, tied, clockwise_rows



@jax.jit
def label_phase(s, positions, vertex_ids, corners=None):
    """Label phase (paper Alg. 1; slides "Label Phase"), elementwise over all darts.

    Args:
      s: a structure with borders (``MeshStructure``).
      positions: ``(V, 2)`` (or ``(V, 3)``) float coordinates in the structure's vertex numbering.
      vertex_ids: ``(V,)`` int32 input id of every structure vertex (tie-breaking only).
      corners: optional ``(F, 3)`` input vertex ids of each face of ``s`` in the input's corner
        order: ties between equally long edges go to the first of ``c0c1, c1c2, c2c0``, as in
        the reference; else to the smaller ``(min id, max id)`` pair.

    Returns:
      ``(max_edge, frontier, seed)``: ``(num_darts,)`` bool arrays. ``max_edge[e]``: ``e`` is the
      longest edge of its left triangle; ``frontier[e]``: border edge, or longest edge of neither
      triangle (Def. 4); ``seed[e]``: one dart per terminal edge (the one with the smaller id) and
      the inner dart of every border terminal edge (Def. 3). Jittable.
    """
    return _label_phase(s, positions, vertex_ids, corners)[:3]


# ------------------------------------------------------------------------------ 2. traversal
def _turn_to_frontier(s, frontier, queries, inner, max_rounds):
    """``first frontier dart in the clockwise turn (cw_vertex_edge) starting at q`` for every dart,
    by pointer doubling: ``p0(e) = e`` on frontier darts and non-inner darts (fixed points),
    ``cw(e)`` elsewhere; ``p <- p[p]`` until every pointer's target is a frontier dart or a
    fixed point (a ``while_loop``: ``ceil(log2(longest run of non-frontier darts))`` rounds, at
    most ``max_rounds``; no degree count needed). The pointer and the "stopped" flag of its
    target travel packed in one int32 (``2 p + flag``), so a round is one gather. Returns
    ``(p, converged)`` (every query on a frontier dart)."""
    e = _darts(s)
    fixed = frontier | ~inner
    p = jnp.where(fixed, e, s.cw_vertex_edge(e)).astype(jnp.int32)
    pf = 2 * p + fixed[p].astype(jnp.int32)

    def cond(c):
        pf, k = c
        return (k < max_rounds) & ~jnp.all((pf & 1) == 1)

    def body(c):
        pf, k = c
        return pf[pf >> 1], k + 1

    pf, _ = jax.lax.while_loop(cond, body, (pf, jnp.int32(0)))
    p = pf >> 1
    qmask = queries < s.num_darts
    qs = jnp.where(qmask, queries, 0)
    ok = jnp.all(~qmask | frontier[p[qs]])
    return p, ok


@functools.partial(jax.jit, static_argnames=("tabulate",))
def _traversal_and_tips(s, frontier, border, tabulate: bool = True):
    """:func:`traversal_phase` and :func:`barrier_tips` on one tabulated structure (both ask
    ``twin`` of every dart, the traversal ``next`` and ``cw_vertex_edge`` of every dart too;
    ``tabulate=False``: on ``s`` as it is)."""
    if tabulate:
        s = _tabulated(s, twin=True, origin=False)
    succ, ok = traversal_phase(s, frontier, border)
    return succ, ok, barrier_tips(s, succ)


@jax.jit
def traversal_phase(s, frontier, border=None):
    """Traversal phase as a successor map (paper Alg. 2, reference ``travel_triangles``).

    Returns:
      ``(succ, ok)``: ``succ`` ``(num_darts,)`` int32, for every frontier dart ``f``
      with an inner left face the next frontier dart of its polygon (first frontier dart turning
      clockwise around ``target(f)`` from ``next(f)``), ``num_darts`` elsewhere; ``ok`` False if
      some turn met no frontier dart (impossible on a valid mesh: ``twin(f)`` is frontier).
      ``border``: optional ``is_border`` of every dart (from the label phase), else asked here.
      Jittable.
    """
    e = _darts(s)
    valid = s.dart_valid(e)
    inner = valid & ~(s.is_border(e) if border is None else border)
    active = inner & frontier
    q = jnp.where(active, s.next(e), s.num_darts)
    # at most ceil(log2(num_darts)) doubling rounds; the loop stops as soon as every pointer
    # has stopped (log2 of the longest clockwise run of non-frontier darts, about 4)
    turn, ok = _turn_to_frontier(s, frontier, q, inner, max(1, int(s.num_darts).bit_length()))
    succ = jnp.where(active, turn[jnp.minimum(q, s.num_darts - 1)], s.num_darts)
    return succ.astype(jnp.int32), ok


@jax.jit
def barrier_tips(s, succ):
    """``(num_darts,)`` bool: darts ``f`` arriving at a barrier-edge tip (paper Def. 5).

    The reference detects ``poly[i] == poly[i+2]`` in a polygon's vertex list: the walk goes up a
    barrier edge to its tip and straight back, i.e. ``succ(f) == twin(f)``."""
    e = _darts(s)
    return (succ < s.num_darts) & (succ == s.twin(e))


def _rotate(s, start, stop, step, mask, max_steps):
    """Turn every lane with ``step`` from ``start`` until ``stop(e)``, at least one step (the
    first dart strictly after ``start``; lanes not in ``mask`` stay). The first step is a trip of
    the loop, not a call of its own: ``step`` is compiled once (on pemb a step is a parenthesis
    search, the largest program of the phase)."""

    def cond(c):
        d, done, k = c
        return jnp.any(~done) & (k < max_steps)

    def body(c):
        d, done, k = c
        d2 = jnp.where(done, d, step(d))
        return d2, done | stop(d2), k + 1

    d, _, _ = jax.lax.while_loop(cond, body, (start, ~mask, jnp.int32(0)))
    return d


@jax.jit
def middle_edges(s, tip_darts, mask, mirror=False):
    """Middle edge of each barrier-edge tip (reference ``search_middle_edge``, paper Alg. 4).

    Args:
      tip_darts: ``(T,)`` darts arriving at the tips (from :func:`barrier_tips`), padded.
      mask: ``(T,)`` bool, the real lanes.
      mirror: the input's triangles were all clockwise (``s`` holds them turned
        counter-clockwise). The reference turns ``next(twin)`` on the input as it is, which on
        such an input is a counter-clockwise turn: at a tip of odd degree it then picks the other
        one of the two middle edges.

    Returns ``(T,)`` int32: the dart leaving the tip after ``deg // 2`` clockwise turns from the
    barrier edge (``deg`` = degree of the tip; the reference's even/odd cases both reduce to it);
    with ``mirror``, ``deg // 2`` counter-clockwise turns (``deg - deg // 2`` clockwise ones).
    """
    fe = s.twin(tip_darts)  # the barrier edge, leaving the tip
    limit = s.num_darts
    mirror = jnp.asarray(mirror, bool)

    def turns(deg):
        return jnp.where(mirror, deg - deg // 2, deg // 2)

    # one loop, one clockwise step per trip (one copy of cw_vertex_edge to compile): first turn
    # until back at the barrier edge counting the tip's degree, then from it again deg // 2 turns
    def cond(c):
        d, deg, k, counting, j = c
        return jnp.any(mask & (counting | (k < turns(deg)))) & (j < 2 * limit)

    def body(c):
        d, deg, k, counting, j = c
        turning = mask & ~counting & (k < turns(deg))
        d2 = s.cw_vertex_edge(d)
        back = counting & (d2 == fe)  # a full turn: deg known, start again at the barrier edge
        deg = jnp.where(counting, deg + 1, deg)
        d = jnp.where(back, fe, jnp.where(counting | turning, d2, d))
        k = k + turning.astype(jnp.int32)
        return d, deg, k, counting & ~back, j + 1

    zeros = jnp.zeros(fe.shape, jnp.int32)
    d, _, _, _, _ = jax.lax.while_loop(cond, body, (fe, zeros, zeros, mask, jnp.int32(0)))
    return d.astype(jnp.int32)


@jax.jit
def repair_phase(s, frontier, succ, middle, mask):
    """Make the middle edges frontier and update the successor map (paper Alg. 3).

    For every new frontier dart ``m`` leaving ``v``: ``succ(twin(m))`` becomes the first frontier
    dart clockwise after ``m`` around ``v``, and the frontier dart ``g`` met first turning
    counter-clockwise from ``m`` now continues into ``m``: ``succ(twin(g)) = m``. Both rotations
    use the updated frontier, so several new darts at one vertex agree (writes of one target carry
    the same value). Returns ``(frontier, succ, new_darts)``; ``new_darts`` ``(2T,)`` padded with
    ``num_darts``.
    """
    E = s.num_darts
    mid = jnp.where(mask, middle, 0).astype(jnp.int32)
    m = jnp.concatenate([mid, s.twin(mid)])
    mk = jnp.concatenate([mask, mask])
    m = jnp.where(mk, m, 0).astype(jnp.int32)
    frontier2 = frontier.at[jnp.where(mk, m, E)].set(True, mode="drop")
    isf = lambda d: frontier2[d]  # noqa: E731
    after = _rotate(s, m, isf, s.cw_vertex_edge, mk, E)
    before = _rotate(s, m, isf, s.ccw_vertex_edge, mk, E)
    n = m.shape[0]
    tw = s.twin(jnp.concatenate([m, before]))  # one twin program for both
    succ2 = succ.at[jnp.where(mk, tw[:n], E)].set(after, mode="drop")
    succ2 = succ2.at[jnp.where(mk, tw[n:], E)].set(m, mode="drop")
    return frontier2, succ2, jnp.where(mk, m, E).astype(jnp.int32)


# ------------------------------------------------------------------------------ 4. polygons
@functools.partial(jax.jit, static_argnames=("size",))
def cycles_to_csr(s, succ, vertex_ids, size: int):
    """The cycles of ``succ`` (the polygons) as CSR arrays, by pointer doubling (jittable).

    Frontier darts are first compacted to ``size`` lanes (a static bound >= their number). Then
    (a) every lane finds the smallest directed edge ``(origin, target)`` (input vertex ids) of its
    cycle, the polygon's *head*, with ``O(log L)`` doubling rounds (a round that changes nothing
    means the windows cover every cycle: the lane ``2^k`` steps before the head would change);
    (b) list ranking: distance of every lane to the head's predecessor, again by doubling; its
    position in the polygon follows, and one scatter writes the vertex ids.

    Packed int64 keys: call it under ``jax.enable_x64(True)`` (as :func:`polylla` does).

    Returns ``(offsets (size+1,), indices (size,), num_polygons, total, polygon_of_lane (size,),
    lane_of_dart (num_darts,), is_permutation)``: polygons in the order of their head darts'
    ids, each starting at its head; ``is_permutation`` False flags a broken successor map.
    """
    E = s.num_darts
    active = succ < E
    na = jnp.sum(active).astype(jnp.int32)
    lane_of_dart = (jnp.cumsum(active) - 1).astype(jnp.int32)
    idx = jnp.nonzero(active, size=size, fill_value=0)[0].astype(jnp.int32)
    lanes = jnp.arange(size, dtype=jnp.int32)
    valid = lanes < na
    cs = jnp.where(valid, lane_of_dart[succ[idx]], lanes)  # padding lanes are fixed points
    indeg = jnp.zeros((size,), jnp.int32).at[cs].add(1)
    is_perm = jnp.all(indeg == 1)
    vo = jnp.where(valid, vertex_ids[s.origin(idx)], _BIG).astype(jnp.int32)
    vt = vo[cs]

    # (a) head = smallest (origin, target) of the cycle, the pair packed in one int64 key
    key = (vo.astype(jnp.int64) << 32) | vt.astype(jnp.int64)

    def cond_a(c):
        return c[2] & (c[3] < 64)

    def body_a(c):
        m, p, _, k = c
        mp = m[p]
        return jnp.minimum(m, mp), p[p], jnp.any(mp < m), k + 1

    m, _, _, _ = jax.lax.while_loop(cond_a, body_a, (key, cs, jnp.bool_(True), jnp.int32(0)))
    head = valid & (key == m)

    # (b) list ranking: w = steps to the last lane of the cycle (the head's predecessor);
    # pointer and weight packed in one int64 (q << 32 | w): one gather per round
    last = head[cs] | ~valid
    q0 = jnp.where(last, lanes, cs).astype(jnp.int64)
    w0 = jnp.where(last, 0, 1).astype(jnp.int64)
    low = jnp.int64(0xFFFFFFFF)

    def cond_b(c):
        return c[1] & (c[2] < 64)

    def body_b(c):
        qw, _, k = c
        g = qw[qw >> 32]
        new = (g & ~low) | ((qw & low) + (g & low))
        return new, jnp.any((g >> 32) != (qw >> 32)), k + 1

    qw, _, _ = jax.lax.while_loop(cond_b, body_b, ((q0 << 32) | w0, jnp.bool_(True), jnp.int32(0)))
    q = (qw >> 32).astype(jnp.int32)
    w = (qw & low).astype(jnp.int32)
    length = jnp.where(head, w + 1, 0)
    start = (jnp.cumsum(length) - length).astype(jnp.int32)  # exclusive, in head order
    pid = (jnp.cumsum(head) - 1).astype(jnp.int32)
    npoly = jnp.sum(head).astype(jnp.int32)
    hd = cs[q]  # the head of every lane's cycle
    position = start[hd] + length[hd] - 1 - w
    out = jnp.zeros((size,), jnp.int32).at[jnp.where(valid, position, size)].set(vo, mode="drop")
    offsets = jnp.full((size + 1,), na, jnp.int32).at[jnp.where(head, pid, size + 1)].set(
        start, mode="drop")
    polygon_of_lane = jnp.where(valid, pid[hd], size)
    return offsets, out, npoly, na, polygon_of_lane, lane_of_dart, is_perm


def _canonical_order(offsets: np.ndarray, indices: np.ndarray):
    """Polygons sorted by their first directed edge (host numpy; each polygon starts at its
    smallest directed edge already)."""
    first = indices[offsets[:-1]]
    second = indices[offsets[:-1] + 1]
    return _reordered(offsets, indices, np.lexsort((second, first)))


def _reordered(offsets: np.ndarray, indices: np.ndarray, order: np.ndarray):
    """The CSR polygons in the order ``order`` (host numpy): ``(offsets, indices, order)``."""
    sizes = np.diff(offsets)[order]
    new_off = np.zeros(offsets.size, np.int64)
    np.cumsum(sizes, out=new_off[1:])
    src = np.repeat(offsets[:-1][order] - new_off[:-1], sizes) + np.arange(new_off[-1])
    return new_off, indices[src], order


# ------------------------------------------------------------------------------ driver
@dataclasses.dataclass(frozen=True)
class PolyllaMesh:
    """A Polylla polygon mesh (host arrays, CSR in the manner of jraph's per-graph counts).

    Attributes:
      points: ``(V, 2)`` float64 coordinates (input numbering).
      offsets: ``(P + 1,)`` int64; polygon ``i`` is ``indices[offsets[i]:offsets[i+1]]``.
      indices: ``(N,)`` int32 input vertex ids, each polygon counter-clockwise (clockwise when
        every input triangle was, as the reference's) from its smallest directed edge; polygons
        sorted by that edge.
      barrier_edge_tips: number of barrier-edge tips found (before repair).
      repaired_polygons: number of terminal-edge-region polygons that had tips and were split.
      regions: number of terminal-edge regions (= seed edges = polygons before repair).
      frontier_edges: number of frontier edges (undirected, before repair).
      triangles: number of input triangles.
      timings: seconds per phase (``label``, ``traversal``, ``repair``, ``polygons``).
      seed_edges: reference mode: ``(P,)`` the reference's half-edge id (``3 i + j``) of the
        seed edge each polygon came from; the polygons are in its order (None otherwise).
    """

    points: np.ndarray
    offsets: np.ndarray
    indices: np.ndarray
    barrier_edge_tips: int
    repaired_polygons: int
    regions: int
    frontier_edges: int
    triangles: int
    timings: dict
    seed_edges: Optional[np.ndarray] = None

    @property
    def num_polygons(self) -> int:
        return int(self.offsets.shape[0] - 1)

    def polygons(self) -> list[list[int]]:
        """The polygons as Python lists of vertex ids."""
        idx = self.indices.tolist()
        off = self.offsets.tolist()
        return [idx[off[i]:off[i + 1]] for i in range(len(off) - 1)]

    def summary(self) -> dict:
        return {"polygons": self.num_polygons, "barrier_edge_tips": self.barrier_edge_tips,
                "repaired_polygons": self.repaired_polygons, "regions": self.regions,
                "frontier_edges": self.frontier_edges, "vertices": int(self.points.shape[0]),
                "triangles": self.triangles}


def _bucket(n: int) -> int:
    """Lane counts rounded up to a power of two (>= 64), to bound recompilations."""
    return max(64, 1 << max(int(n) - 1, 0).bit_length())


def _bucket_fine(n: int) -> int:
    """Sizes rounded up to 1/16 of their power of two (>= 64): < 7% padding, few recompiles."""
    step = max(64, 1 << max(int(n).bit_length() - 4, 0))
    return max(step, -(-int(n) // step) * step)


def _pad(x: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    out = np.zeros(size, np.int32)
    out[: x.size] = x
    mask = np.zeros(size, bool)
    mask[: x.size] = True
    return out, mask


def polylla(s, positions, *, corners=None, clockwise: Optional[bool] = None,
            sync_timings: bool = True, canonical: Optional[bool] = None, tables: bool = True,
            mode: Optional[str] = None, row_ids=None) -> PolyllaMesh:
    """Run Polylla on structure ``s`` (any structure with borders) and 2D ``positions``.

    Args:
      s: e.g. ``HalfEdge.from_faces(faces, V)`` or the ``pemb`` structure of the same mesh.
      positions: ``(V, 2)`` or ``(V, 3)`` coordinates in the *input* numbering (permuted here
        through ``s.vertex_order`` when the structure renumbers vertices).
      corners: optional ``(F, 3)`` input triangles as the input lists them (corner order and
        orientation as read, e.g. a ``.ele`` file's rows; :attr:`Triangulation2D.input_faces`).
        With them the output is the reference's: ties between equally long edges of a triangle
        go to the first of ``c0c1, c1c2, c2c0`` (without: to the smaller ``(min id, max id)``
        input vertex pair), and an input of clockwise triangles gives clockwise polygons and the
        reference's middle edges (``clockwise``, below). Rows in the face order of ``s`` when it
        keeps the input's (``HalfEdge.from_faces``); otherwise matched to its faces here (a host
        sort: in canonical mode only when some triangle has a tie, in reference mode always).
      clockwise: every input triangle is clockwise (default: read off ``corners``; False
        without them). Given, it is taken as the caller's word (``run`` passes what it read).
        The reference keeps the input's orientation: its polygons are then clockwise, and its
        barrier-edge repair turns the other way round (:func:`middle_edges`).
      mode: ``"reference"`` (the default when ``corners`` are given) runs the traversal and
        repair as the reference implementation does, sequentially, on the input's numbering
        (:mod:`jaxcds.algorithms.polylla_reference`): its walk stops at its starting vertex and
        its tips are repaired one after the other from ``edge_of_vertex``, so the output is the
        reference's polygon for polygon (order and vertex order included), its order dependence
        and the tips it leaves in included. ``"canonical"`` (the default without ``corners``)
        runs the order-free vectorised phases: every tip of a region is repaired, every polygon
        walked to its starting dart, the output independent of the numbering (sorted, each
        polygon from its smallest directed edge). Without ``corners``, ``"reference"`` takes
        the structure's faces as the input rows.
      canonical: sort the polygons by their first directed edge (canonical mode; default
        True). Reference mode keeps the reference's order and ignores it.
      row_ids: reference mode: the input index of each row of ``corners`` (default: its own),
        for a piece of a larger input (the reference's half-edge ids are the whole input's):
        ``(F,)`` integers, increasing, non-negative (else :class:`~jaxcds.errors.PolyllaError`).

    ``tables``: let the structure build per-run navigation tables (:func:`_tabulated`; pemb:
    twin, origin and first dart of every face, 41.5 bytes per vertex while the run lasts, its
    stored 5.25 bits per edge unchanged). ``False`` navigates the structure as it is (pemb: one
    or two parenthesis searches per operator; slower, no O(darts) int32 table at any time).
    Same polygons either way.

    Lengths are compared in float64 (``jax.enable_x64`` around the label phase). Returns a
    :class:`PolyllaMesh`; raises :class:`~jaxcds.errors.StructureError` if the successor map
    does not close into cycles covering every frontier dart, or a reference-mode walk does not
    close (a structure bug), and :class:`~jaxcds.errors.PolyllaError` for ``positions`` that are
    not ``(V, 2)`` or ``(V, 3)`` real numbers or hold a NaN / inf (naming the vertex), ``corners``
    that are not the structure's triangles or an unknown ``mode``;
    :class:`~jaxcds.errors.ArgumentError` for an ``s`` that is no jaxcds structure and flags
    (``tables``, ``sync_timings``, ``canonical``) that are not bools.
    """
    from jaxcds.polylla_io import length_scale
    from jaxcds.structures.base import structure_arg

    # a Triangulation2D or TriMesh raised an AttributeError; flags of the wrong kind were read
    # as truthy ('no') or falsy (0, None)
    structure_arg(s, "polylla: s")
    tables = flag_arg(tables, "polylla: tables")
    sync_timings = flag_arg(sync_timings, "polylla: sync_timings")
    canonical = flag_arg(canonical, "polylla: canonical", none_ok=True)
    _refuse_closed_holes(s)
    # as given, the reference's own lengths; scaled by a power of two only where its squares
    # would overflow or the coordinates are tiny (length_scale)
    pos = length_scale(_checked_positions(positions, s.num_vertices))
    order = s.vertex_order
    vids = np.arange(s.num_vertices, dtype=np.int32) if order is None else np.asarray(order, np.int32)
    pos_s = pos if order is None else pos[vids]
    vids_j = to_device(vids)
    t = {}
    marks = [(time.perf_counter(), time.process_time())]

    def clock():
        marks.append((time.perf_counter(), time.process_time()))
        return marks[-1][0]

    def done(x):
        if sync_timings:
            jax.block_until_ready(x)
        return clock()

    cs = None
    mode = _mode_arg(("canonical" if corners is None else "reference") if mode is None else mode)
    if mode == "reference" and corners is None:  # the structure's own faces are the input rows
        corners = vids[np.asarray(_faces_of(s))]
    if clockwise is not None and not isinstance(clockwise, (bool, np.bool_)):
        raise errors.PolyllaError(f"clockwise must be True, False or None, got {clockwise!r}")
    if corners is not None:
        cs = _checked_corners(corners, s.num_faces, pos.shape[0])
    if row_ids is not None:
        row_ids = _checked_row_ids(row_ids, s.num_faces)
    t0 = marks[0][0]
    with jax.enable_x64(True):
        pos_j = jnp.asarray(pos_s, jnp.float64)
        cs_j = None if cs is None else jnp.asarray(cs, jnp.int32)
        max_edge, frontier, seed, border, misplaced, tied, cw_rows, nav_tables = _label_phase(
            s, pos_j, vids_j, cs_j, tabulate=bool(tables))
        in_row_order = cs is None or not bool(misplaced)  # face f of s is row f of corners
        if clockwise is None and cs is not None:  # read off the rows (a host pass if misplaced)
            clockwise = bool(cw_rows) if in_row_order else _all_clockwise(pos, cs)
        clockwise = bool(clockwise)
        # the row of each face: matched once (a numba pass) where the structure numbers its
        # faces its own way (pemb) and a later step needs it, read through the label phase's
        # tables; the rows in structure vertex ids once, for the match and the walks
        rows = cs_s = None
        if cs is not None and (mode == "reference" or (not in_row_order and bool(tied))):
            from jaxcds.algorithms.polylla_reference import corners_in_structure_ids

            cs_s = corners_in_structure_ids(cs, vids)
        if cs is not None and in_row_order:
            rows = np.arange(s.num_faces)
        elif cs is not None and (mode == "reference" or bool(tied)):
            tabulated = None if nav_tables is None else s.with_tables(tables=nav_tables)
            rows = _rows_of_faces(s, cs_s, vids, tabulated)
        if not in_row_order and bool(tied):  # ties follow the rows: label again in face order
            cs_j = jnp.asarray(cs[rows], jnp.int32)
            max_edge, frontier, seed, border, misplaced, tied, _, nav_tables = _label_phase(
                s, pos_j, vids_j, cs_j, tabulate=bool(tables))
        t1 = done(seed)
    # the later phases navigate the same structure with the label phase's tables (pemb: twin and
    # origin of every dart, 32 bits per dart and 64 per vertex, alive until the run ends)
    nav = s if nav_tables is None else s.with_tables(tables=nav_tables)
    t["label"] = t1 - t0

    n_frontier = int(jnp.sum(frontier)) // 2  # undirected, before repair
    regions = int(jnp.sum(seed))
    if mode == "reference":
        return _reference_run(s, nav, pos, vids, cs_s, rows, row_ids, seed, frontier, clockwise,
                              n_frontier, t, clock, marks)
    succ, ok, tips = _traversal_and_tips(nav, frontier, border, tabulate=bool(tables))
    del border
    tip_darts = np.nonzero(np.asarray(tips))[0].astype(np.int32)
    if not bool(ok):
        raise errors.StructureError("Polylla: a clockwise turn from a frontier dart met no "
                                    "frontier dart (inconsistent twin/next in the structure)")
    t2 = done(succ)
    t["traversal"] = t2 - t1

    T = tip_darts.size
    new_darts = np.zeros(0, np.int32)
    if T:
        td, tm = _pad(tip_darts, _bucket(T))
        mid = middle_edges(nav, to_device(td), to_device(tm), clockwise)
        frontier, succ, new = repair_phase(nav, frontier, succ, mid, to_device(tm))
        new_darts = np.asarray(new)
        new_darts = np.concatenate([new_darts[:T], new_darts[td.size: td.size + T]])
    t3 = done(succ)
    t["repair"] = t3 - t2

    if _on_cpu(succ):  # one O(N) walk per cycle on the host (polylla_cycles), not doubling
        from jaxcds.algorithms.polylla_cycles import cycles_csr_host

        offsets, indices, pod, is_perm = cycles_csr_host(
            np.asarray(succ), np.asarray(_dart_vertex_ids(nav, vids_j)))
        npoly, total = offsets.size - 1, indices.size
        pol_new = pod[new_darts]  # the polygons of the middle edges' darts
    else:
        size = _bucket_fine(int(jnp.sum(succ < s.num_darts)))
        with jax.enable_x64(True):  # int64 packed keys in the doubling rounds
            offsets, out, npoly, total, pol, lane_of_dart, is_perm = cycles_to_csr(
                nav, succ, vids_j, size)
        npoly, total = int(npoly), int(total)
        offsets = np.asarray(offsets[: npoly + 1]).astype(np.int64)
        indices = np.asarray(out[:total]).astype(np.int32)
        pol_new = np.asarray(pol)[np.asarray(lane_of_dart)[new_darts]]
    if not bool(is_perm):
        raise errors.StructureError(
            "Polylla: the successor map on frontier darts is not a permutation "
            f"({total} frontier darts, {regions} seeds, {T} barrier-edge tips)")
    if clockwise:  # the reference's polygons run the input's way round
        indices = _reversed_cycles(offsets, indices, s.num_vertices)
    t4 = clock()
    t["polygons"] = t4 - t3
    if canonical is None or canonical:
        offsets, indices, _ = _canonical_order(offsets, indices)
    t5 = clock()
    t["order"] = t5 - t4

    repaired = 0
    if T:
        repaired = _count_components(pol_new[:T], pol_new[T:])
    t["repair_count"] = clock() - t5
    _cpu_times(t, marks, ["label", "traversal", "repair", "polygons", "order", "repair_count"])
    return PolyllaMesh(points=pos, offsets=offsets, indices=indices, barrier_edge_tips=int(T),
                       repaired_polygons=int(repaired), regions=regions,
                       frontier_edges=n_frontier, triangles=int(s.num_faces), timings=t)


def _on_cpu(x) -> bool:
    """``x`` (a jax array) lives on a CPU device: host kernels beat XLA's loops there."""
    try:
        return all(d.platform == "cpu" for d in x.devices())
    except AttributeError:  # a numpy array
        return True


@jax.jit
def _dart_vertex_ids(s, vertex_ids):
    """Input vertex id of every dart's origin."""
    return vertex_ids[s.origin(_darts(s))]


def _cpu_times(t: dict, marks: list, names: list) -> None:
    """Process CPU seconds of the phases between ``marks`` (all threads; a load-independent
    companion of the wall times on a shared machine) as ``t["cpu_" + name]``."""
    for name, (a, b) in zip(names, zip(marks[:-1], marks[1:])):
        t["cpu_" + name] = b[1] - a[1]


@functools.partial(jax.jit, static_argnames=("mirror",))
def _reference_darts(s, frontier, mirror: bool):
    """``(H, face)``: :func:`~jaxcds.algorithms.polylla_reference.dart_rows` of every dart of
    ``s`` in the reference's orientation (on a clockwise input, ``mirror``, the reference's
    half-edge is the structure's dart read backwards: its ``next`` is the structure's ``prev``,
    its origin the target), and each dart's face."""
    from jaxcds.algorithms.polylla_reference import dart_rows

    d = _darts(s)
    tw = s.twin(d)
    fwd = s.next(d)
    nxt = s.prev(d) if mirror else fwd
    org = s.origin(tw) if mirror else s.origin(d)
    border = s.is_border(d) | ~s.dart_valid(d)
    return dart_rows(nxt, tw, org, frontier, border), s.dart_faces()


def _reference_run(s, nav, pos, vids, cs_s, rows, row_ids, seed, frontier, clockwise, n_frontier,
                   t, clock, marks):
    """Reference mode of :func:`polylla` after its label phase: the sequential traversal and
    repair of :mod:`jaxcds.algorithms.polylla_reference` on ``nav``'s darts (``cs_s``: the
    input rows in the structure's vertex ids; ``rows``: the row holding each face of ``s``)."""
    from jaxcds.algorithms.polylla_reference import _reference_walks

    t1 = marks[-1][0]
    H, face = (np.asarray(x) for x in _reference_darts(nav, frontier, bool(clockwise)))
    off, idx, seeds, tips, repaired, regions = _reference_walks(
        H, face, np.asarray(seed), rows, cs_s, s.num_vertices, row_id=row_ids)
    t2 = clock()
    t["traversal"] = t2 - t1  # the walks and the repair are one sequential pass here
    t["repair"] = 0.0
    indices = vids[idx].astype(np.int32)
    t["polygons"] = clock() - t2
    t["order"] = t["repair_count"] = 0.0
    _cpu_times(t, marks, ["label", "traversal", "polygons"])
    for k in ("repair", "order", "repair_count"):  # done inside the traversal's pass
        t["cpu_" + k] = 0.0
    return PolyllaMesh(points=pos, offsets=off, indices=indices, barrier_edge_tips=tips,
                       repaired_polygons=repaired, regions=regions, frontier_edges=n_frontier,
                       triangles=int(s.num_faces), timings=t, seed_edges=seeds)


def _refuse_closed_holes(s) -> None:
    """:class:`PolyllaError` for a structure that closed the triangulation's holes with dummy
    vertices (the CDS family, Sec. 4.5): its fan triangles are no input triangles and its border
    darts are gone, so the regions would run across the holes. Refused by name; before, the
    error was "60 positions for a structure of 61 vertices", and positions for the closed mesh
    gave polygons through the dummies (sweep 16a)."""
    dummy = s.dummy_vertex_mask()
    count = 0 if dummy is None else int(np.count_nonzero(np.asarray(dummy)))
    if count == 0:
        return
    raise errors.PolyllaError(
        f"Polylla needs the triangulation's border: this {getattr(s, 'name', type(s).__name__)} "
        f"closed its holes ({count} dummy vertices, CDS Sec. 4.5), "
        f"whose fan triangles are not the input's; build one of {', '.join(BORDER_STRUCTURES)}, "
        "which keep the border")


def _checked_positions(positions, num_vertices: int) -> np.ndarray:
    """The ``(V, 2)`` float64 x, y of ``positions`` (``(V, 2)`` or ``(V, 3)`` real numbers, all
    finite), or :class:`PolyllaError` naming the dtype, the shape or the first vertex with a NaN
    or inf. On the host, before any work: a NaN length makes no edge the longest and the run
    returns polygons all the same."""
    try:
        refuse_non_real(positions, "Polylla positions")
    except errors.MeshError as exc:
        raise errors.PolyllaError(str(exc)) from None
    p = np.asarray(positions)
    if p.ndim != 2 or p.shape[1] not in (2, 3):
        raise errors.PolyllaError(
            f"Polylla positions must be ({num_vertices}, 2) or ({num_vertices}, 3) coordinates "
            f"(one row per vertex), got shape {p.shape}")
    if p.shape[0] != num_vertices:
        raise errors.PolyllaError(
            f"{p.shape[0]} positions for a structure of {num_vertices} vertices")
    p = np.asarray(p, dtype=np.float64)
    if not np.isfinite(p).all():
        bad = int(np.nonzero(~np.isfinite(p).all(axis=1))[0][0])
        raise errors.PolyllaError(
            f"Polylla positions: vertex {bad} has a non-finite coordinate {p[bad].tolist()}")
    return p[:, :2]


def _checked_corners(corners, num_faces: int, num_vertices: int) -> np.ndarray:
    """``corners`` as an ``(F, 3)`` int64 array of vertex ids, or :class:`PolyllaError`."""
    try:
        c = np.asarray(corners)
    except ValueError as exc:
        raise errors.PolyllaError(f"corners are not an array: {exc}") from None
    if c.shape != (num_faces, 3) or (c.size and not np.issubdtype(c.dtype, np.integer)):
        raise errors.PolyllaError(f"corners must be ({num_faces}, 3) integer vertex ids (one row per "
                                  f"triangle), got shape {c.shape} of {c.dtype}")
    if c.size and (c.min() < 0 or c.max() >= num_vertices):  # two reductions, no mask
        bad = np.nonzero((c < 0) | (c >= num_vertices))[0]
        raise errors.PolyllaError(f"corners row {int(bad[0])} {c[bad[0]].tolist()} refers to a vertex "
                                  f"outside [0, {num_vertices})")
    return c if c.dtype in (np.int32, np.int64) else c.astype(np.int64)


def _mode_arg(mode) -> str:
    """``mode`` if ``'reference'`` or ``'canonical'``, else :class:`PolyllaError` naming it."""
    if not isinstance(mode, str) or mode not in ("reference", "canonical"):
        raise errors.PolyllaError(f"unknown Polylla mode {mode!r}: 'reference' or 'canonical'")
    return mode


def _checked_row_ids(row_ids, num_faces: int) -> np.ndarray:
    """``row_ids`` as an ``(F,)`` int64 array of increasing, non-negative input row indices, or
    :class:`PolyllaError` naming the first bad one. Unchecked, the reference walks' numba kernel
    read past a short array (a wrong answer or a misleading "corners do not match"), truncated
    floats, took booleans as 0/1, and failed with numba's TypingError on a scalar or 2-D array;
    a negative or huge id (``3 id + 2`` past int64) collided with the kernel's ``-1``."""
    try:
        r = np.asarray(row_ids)
    except ValueError as exc:  # ragged nested lists
        raise errors.PolyllaError(f"row_ids are not an array: {exc}") from None
    if r.shape != (num_faces,) or (r.size and not np.issubdtype(r.dtype, np.integer)):
        raise errors.PolyllaError(f"row_ids must be ({num_faces},) integer input row indices (one "
                                  f"per row of corners), got shape {r.shape} of {r.dtype}")
    top = (np.iinfo(np.int64).max - 2) // 3  # the reference's half-edge id 3 i + j in int64
    if r.size and (r.min() < 0 or r.max() > top):
        k = int(np.argmax((r < 0) | (r > top)))
        raise errors.PolyllaError(f"row_ids[{k}] = {int(r[k])} is outside [0, {top}]")
    r = r.astype(np.int64)
    if r.size > 1 and not bool(np.all(r[1:] > r[:-1])):
        k = int(np.argmax(r[1:] <= r[:-1])) + 1
        raise errors.PolyllaError(f"row_ids must be increasing: row_ids[{k}] = {int(r[k])} "
                                  f"after row_ids[{k - 1}] = {int(r[k - 1])}")
    return r


def _all_clockwise(pos: np.ndarray, corners: np.ndarray) -> bool:
    """Every triangle of ``corners`` turns clockwise (negative signed area); one numba pass
    that stops at the first one that does not."""
    from jaxcds._mesh_kernels import all_clockwise

    return bool(all_clockwise(np.ascontiguousarray(pos[:, :2], np.float64),
                              np.ascontiguousarray(corners)))


_faces_of = jax.jit(lambda s: s.face_vertices())


@jax.jit
def _face_triples(s):
    """``(F, 3)`` origins of each face's three darts (``edge_of_face``, then ``next``): on a
    structure with per-run tables these are gathers (``face_vertices`` of pemb searches)."""
    e0 = s.edge_of_face(jnp.arange(s.num_faces, dtype=jnp.int32))
    e1 = s.next(e0)
    return jnp.stack([s.origin(e0), s.origin(e1), s.origin(s.next(e1))], axis=1)


def _rows_of_faces(s, corners_s: np.ndarray, vids: np.ndarray, nav=None) -> np.ndarray:
    """``(F,)`` the row of ``corners_s`` (the input rows in the structure's vertex ids,
    :func:`~jaxcds.algorithms.polylla_reference.corners_in_structure_ids`) holding each face of
    ``s``: matched by vertex set in one numba pass (:func:`jaxcds._mesh_kernels.
    match_triangles`; one read of the rows when the structure keeps their order, as the
    half-edge). Matched in the structure's ids because its faces come in an order local in
    those (pemb: a traversal), so the buckets are read nearly in order; in the input's ids (of
    points in any order) every lookup would be a cache miss. ``vids`` names a face in the error;
    ``nav``: the same structure with per-run tables, to read the faces from."""
    from jaxcds._mesh_kernels import match_triangles

    fs = np.asarray(_face_triples(s if nav is None else nav))
    n = int(max(fs.max(initial=0), corners_s.max(initial=0))) + 1
    perm, where = match_triangles(np.ascontiguousarray(fs), np.ascontiguousarray(corners_s), n)
    if where >= 0:
        raise errors.PolyllaError(
            f"corners are not the triangles of the structure: its face {int(where)} "
            f"{vids[fs[where]].tolist()} is no row of corners")
    return perm


def _reversed_cycles(offsets: np.ndarray, indices: np.ndarray, n: int) -> np.ndarray:
    """Every cycle of the CSR reversed, then rotated to start at its smallest directed edge."""
    sizes = np.diff(offsets)
    start = np.repeat(offsets[:-1], sizes)
    end = np.repeat(offsets[1:], sizes)
    pos = np.arange(indices.size)
    rev = indices[start + end - 1 - pos]
    nxt = np.where(pos + 1 < end, pos + 1, start)
    key = rev.astype(np.int64) * n + rev[nxt]
    lowest = np.repeat(np.minimum.reduceat(key, offsets[:-1]), sizes)
    first = pos[key == lowest]  # one per cycle: a cycle passes each directed edge once
    rot = start + (pos - start + np.repeat(first - offsets[:-1], sizes)) % np.maximum(end - start, 1)
    return rev[rot]


def _count_components(a: np.ndarray, b: np.ndarray) -> int:
    """Connected components of the graph on polygon ids with edges ``a[i] - b[i]``: the pieces
    of one repaired region are joined by its middle edges, so this counts repaired regions."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    nodes, inv = np.unique(np.concatenate([a, b]), return_inverse=True)
    k = a.size
    g = coo_matrix((np.ones(k, np.int8), (inv[:k], inv[k:])), shape=(nodes.size, nodes.size))
    return int(connected_components(g, directed=False)[0])


# ------------------------------------------------------------------------------ comparison
def canonical_cycle(cycle) -> tuple:
    """The rotation of a vertex cycle that starts at its lexicographically smallest position
    (as a tuple): two polygons are equal up to rotation iff their canonical cycles are equal."""
    c = list(cycle)
    n = len(c)
    return min(tuple(c[i:] + c[:i]) for i in range(n)) if n else ()


def polygons_as_cycles(polys) -> list:
    """Sorted list of canonical cycles (a multiset of polygons up to rotation)."""
    return sorted(canonical_cycle(p) for p in polys)


# ------------------------------------------------------------------------------ file to file
def _as_trimesh(tri):
    """``tri`` as a :class:`~jaxcds.mesh.TriMesh` (``z = 0``)."""
    from jaxcds.mesh import TriMesh

    return TriMesh(vertices=np.column_stack([tri.points, np.zeros(tri.num_vertices)]),
                   faces=tri.faces, source=tri.source)


def _checked_mesh(tri, structure: str, check: bool):
    """``tri`` as a :class:`~jaxcds.mesh.TriMesh`, validated when ``check`` (typed errors)."""
    from jaxcds.mesh import validate

    mesh = _as_trimesh(tri)
    if check:  # a point in no triangle (in a hole) is fine for the half-edge, not for others
        try:
            validate(mesh, structure=f"Polylla on {structure}", unreferenced_ok=structure == "halfedge")
        except errors.UnreferencedVertexError as exc:  # load_mesh's hint does not apply here
            raise errors.UnreferencedVertexError(
                str(exc).split("; jaxcds.mesh.load_mesh")[0] + f"; {structure} needs every point "
                "in a triangle: remove it from the input, or run Polylla on the half-edge "
                "(--structure halfedge), which accepts points in holes") from None
        except errors.InconsistentOrientationError as exc:
            from jaxcds.polylla_io import twice_signed_areas, unit_scale

            if not (twice_signed_areas(unit_scale(tri.points), tri.faces) > 0).all():
                raise  # a hand-made Triangulation2D with clockwise rows: their orientation
            # every triangle was turned counter-clockwise by its area (polylla_io): two that
            # still run along an edge the same way lie on one side of it, on top of each other.
            # "orient faces consistently" asked for what the input cannot change
            msg = str(exc).replace("; orient faces consistently", "")
            raise errors.InconsistentOrientationError(
                f"{msg}: each triangle is taken counter-clockwise (by the sign of its area), so "
                "these two lie on the same side of that edge and overlap: the triangulation "
                "folds over itself there (a misplaced point or a wrong corner in the .ele / OFF "
                "faces)") from None
    return mesh


def build_structure(tri, structure: str = "halfedge", *, check: bool = True):
    """The structure ``structure`` (``halfedge``, ``pemb``, any registered name accepting borders)
    of a :class:`~jaxcds.polylla_io.Triangulation2D`, input vertex numbering kept.

    With ``check`` the triangulation is validated first (typed :class:`~jaxcds.errors.MeshError`
    naming the bad face, edge or vertex: non-manifold edges, bow-tie vertices, duplicates...)."""
    from jaxcds.polylla_io import Triangulation2D
    from jaxcds.structures import registry
    from jaxcds.structures.halfedge import HalfEdge

    if not isinstance(tri, Triangulation2D):  # an AttributeError about .points before
        raise errors.ArgumentError(
            f"build_structure: tri must be a jaxcds.polylla_io.Triangulation2D (read_input, "
            f"from_points), got {type(tri).__name__}")
    check = flag_arg(check, "build_structure: check")
    mesh = _checked_mesh(tri, structure, check)
    if structure == "halfedge":
        return HalfEdge.from_faces(tri.faces, tri.num_vertices)
    if structure not in registry.names():
        raise errors.PolyllaError(
            f"unknown structure {structure!r} for Polylla; available: {', '.join(registry.names())}")
    try:
        s = registry.build(structure, mesh)
    except errors.UnsupportedTopologyError as exc:
        if structure in BORDER_STRUCTURES:
            raise
        # a structure for closed meshes (corner-table) advised close_boundaries, which Polylla
        # cannot use: its regions need the border
        raise errors.UnsupportedTopologyError(
            f"Polylla on {structure}: {str(exc).split('; call ')[0]}; Polylla needs the "
            f"triangulation's border: build one of {', '.join(BORDER_STRUCTURES)}") from None
    _refuse_closed_holes(s)
    return s


def _components_of(tri):
    """``(count, face label)`` of the connected components of ``tri`` when it has several, else
    None (the triangles of one piece share edges with each other only)."""
    from jaxcds.mesh import _components

    ncomp, label = _components(_as_trimesh(tri))
    return (ncomp, label) if ncomp > 1 else None


def _run_by_component(tri, parts, structure: str, *, check: bool, tables: bool,
                      mode: str = "reference"):
    """Polylla on each connected piece of ``tri`` (its own structure, vertices renumbered in
    order, which keeps every polygon's smallest directed edge first), the polygons merged in
    input ids and ordered as one run's (canonical: sorted; reference: by seed half-edge id, the
    pieces' rows keeping their input indices). Returns ``(PolyllaMesh, build seconds)``."""
    from jaxcds import polylla_io
    from jaxcds.mesh import component_pieces

    ncomp, label = parts
    _checked_mesh(tri, structure, check)  # the whole input, as one structure would check it
    cw = None if tri.clockwise is None else np.asarray(tri.clockwise, bool)
    offs, idx, seeds, t, t_build = [np.zeros(1, np.int64)], [], [], {}, 0.0
    counts = dict(barrier_edge_tips=0, repaired_polygons=0, regions=0, frontier_edges=0)
    # each piece's rows, vertices and renumbered faces by slices of one sort (a mask and a remap
    # over the whole input per piece was O(pieces x size), as split_components' was)
    pieces = component_pieces(np.asarray(tri.faces), tri.num_vertices, ncomp, label)
    for c, (rows, used, faces) in enumerate(pieces):
        part_cw = None if cw is None else cw[rows]
        flipped = 0 if part_cw is None else int(part_cw.sum())
        sub = polylla_io.Triangulation2D(
            points=tri.points[used], faces=faces, source=f"{tri.source}[component {c}]",
            flipped=flipped, clockwise=part_cw if flipped else None)
        t0 = time.perf_counter()
        try:
            s = build_structure(sub, structure, check=False)  # a piece of a valid input
        except errors.JaxcdsError as exc:  # a piece the structure refuses (lr: a lone triangle)
            raise type(exc)(_piece_refused(c, ncomp, rows, structure, exc)) from exc
        t_build += time.perf_counter() - t0
        m = polylla(s, sub.points, corners=sub.input_faces, clockwise=tri.all_clockwise,
                    tables=tables, canonical=False, mode=mode, row_ids=rows)
        offs.append(m.offsets[1:] + offs[-1][-1])
        idx.append(used[m.indices].astype(np.int32))
        seeds.append(m.seed_edges)
        for k in counts:
            counts[k] += getattr(m, k)
        for k, v in m.timings.items():
            t[k] = t.get(k, 0.0) + v
    offsets, indices = np.concatenate(offs), np.concatenate(idx)
    seed_edges = None
    if mode == "reference":  # the reference walks the seeds in half-edge order, all pieces at once
        seed_edges = np.concatenate(seeds)
        offsets, indices, order = _reordered(offsets, indices, np.argsort(seed_edges, kind="stable"))
        seed_edges = seed_edges[order]
    else:
        offsets, indices, _ = _canonical_order(offsets, indices)
    mesh = PolyllaMesh(points=tri.points, offsets=offsets, indices=indices,
                       triangles=tri.num_faces, timings=t, seed_edges=seed_edges, **counts)
    return mesh, t_build


def _run_whole(tri, structure: str, *, check: bool, tables: bool, mode: str):
    """``(PolyllaMesh, build seconds)`` of :func:`run` on a read triangulation ``tri``."""
    t0 = time.perf_counter()
    parts = _components_of(tri) if structure != "halfedge" else None
    if parts is not None:  # pemb is one connected planar embedding: one run per piece
        return _run_by_component(tri, parts, structure, check=check, tables=tables, mode=mode)
    s = build_structure(tri, structure, check=check)
    t_build = time.perf_counter() - t0
    # the input's corner order and orientation: ties and clockwise inputs as the reference
    mesh = polylla(s, tri.points, corners=tri.input_faces, clockwise=tri.all_clockwise,
                   tables=tables, mode=mode)
    return mesh, t_build


def _split_pinch_vertices(tri):
    """``(tri', copy_of)``: ``tri`` with every pinch vertex (a point where separate fans of
    triangles touch: a hole's corner on the outer border, two pieces meeting at a corner) made
    one point per fan, the copies appended after the input's points (their positions the
    same), and ``copy_of[v]`` the input point of every point of ``tri'``; ``(tri, None)`` when
    there is none or an edge is shared by more than two triangles (validation names it).

    Why: the structures need a manifold vertex, but Triangle and gmsh mesh such domains and the
    reference meshes them; its walks stay in one fan at a pinch (a border edge there is a
    frontier edge, so no clockwise turn crosses the outside), so the fans can be walked apart
    and the polygons given back in the input's ids (checked against the compiled reference on
    1,444 such inputs, stop 52). Only the refused input pays for the split."""
    from jaxcds import polylla_io
    from jaxcds.mesh import split_nonmanifold_vertices

    try:
        split = split_nonmanifold_vertices(_as_trimesh(tri))
    except errors.MeshError:
        return tri, None
    if split.num_vertices == tri.num_vertices:
        return tri, None
    copy_of = np.arange(split.num_vertices, dtype=np.int64)
    copy_of[split.faces.reshape(-1)] = tri.faces.reshape(-1)  # a copy's corners name its point
    out = polylla_io.Triangulation2D(
        points=np.ascontiguousarray(split.vertices[:, :2]), faces=split.faces, source=tri.source,
        flipped=tri.flipped, clockwise=tri.clockwise)
    return out, copy_of


def _without_repeats(tri, structure: str):
    """``(tri', kept)``: a point set's triangulation without the exact repeats it leaves in no
    triangle (``tri.duplicates``, :func:`jaxcds.polylla_io.from_points`), ``kept`` the input id
    of every point of ``tri'`` (increasing, so vertex order and ties are kept); ``(tri, None)``
    when there are none or ``structure`` is the half-edge, which takes points in no triangle.

    Why: pemb, lr and lr-bits need every point in a triangle and refuse a triangulation's
    unused point by name (a point in a hole), but a repeat is left out by the triangulator
    itself, as Triangle leaves it, so the user has nothing to remove."""
    from jaxcds import polylla_io

    if not tri.duplicates or structure == "halfedge":
        return tri, None
    used = np.zeros(tri.num_vertices, bool)
    used[tri.faces.ravel()] = True
    kept = np.flatnonzero(used)
    local = np.full(tri.num_vertices, -1, np.int64)
    local[kept] = np.arange(kept.size)
    return polylla_io.Triangulation2D(
        points=np.ascontiguousarray(tri.points[kept]), faces=local[tri.faces].astype(np.int32),
        source=tri.source, flipped=tri.flipped, clockwise=tri.clockwise), kept


def _piece_refused(c: int, ncomp: int, rows: np.ndarray, structure: str, exc) -> str:
    """The message for connected piece ``c`` (input triangles ``rows``) that ``structure``
    refused: which piece, by its input triangles, then the structure's own reason."""
    shown = ", ".join(str(int(r)) for r in rows[:5]) + (", ..." if rows.size > 5 else "")
    return (f"Polylla on {structure}: connected piece {c} of {ncomp} (input triangle(s) {shown}; "
            f"{rows.size} in all) cannot be built: {exc}")


def run(source, output: Optional[str] = None, *, structure: str = "halfedge",
        check: bool = True, tables: bool = True, mode: str = "reference") -> dict:
    """Read ``source``, run Polylla on ``structure``, write ``output`` (OFF, atomically).

    Args:
      source: a path (``.node``/``.ele``/``.neigh`` or their stem, 2D ``.off`` triangulation,
        point list ``.xy``/``.txt``/``.csv``/``.npy`` triangulated by Delaunay), an ``(N, 2)``
        array of points, or a :class:`~jaxcds.polylla_io.Triangulation2D`.
      output: OFF path for the polygons, or None.
      structure: ``halfedge`` (default) or ``pemb`` (or any registered structure with borders).
      tables: per-run navigation tables (see :func:`polylla`); ``False`` for the structure's
        own operators only.
      mode: ``"reference"`` (default: the reference implementation's polygons, on the input's
        numbering) or ``"canonical"`` (order-free phases, every tip repaired); see
        :func:`polylla`.

    Returns a dict: ``polygons``, ``barrier_edge_tips``, ``repaired_polygons``, ``regions``,
    ``frontier_edges``, ``vertices``, ``triangles``, ``structure``, ``input``, ``output``,
    ``timings`` (seconds per phase, first call includes compilation); where the input says so,
    ``duplicate_points`` (a point set's exact repeats, in no triangle) and ``notes`` (one
    sentence per such fact: the repeats, a lone ``.node`` triangulated as a point set).

    Raises:
      PolyllaError (unreadable or degenerate input, naming file and line/triangle; an unknown
      ``mode``), MeshError (an edge of more than two triangles, overlapping triangles... naming
      the edge or vertex; a pinch vertex, where fans of triangles touch at one point, is meshed
      fan by fan, see :func:`_split_pinch_vertices`), OutputError
      (``output`` cannot be written: checked before any work), ArgumentError (``output`` not a
      path, ``check`` or ``tables`` not a bool).
    """
    from jaxcds import polylla_io
    from jaxcds.codec.fileformat import check_writable

    # before any work: an output that is no path was written as str(output) (a file named '5'
    # in the working folder), a missing folder was found after the run; tables='no' ran with
    # tables, mode=None ran the reference mode and reported mode None
    check = flag_arg(check, "run: check")
    tables = flag_arg(tables, "run: tables")
    mode = _mode_arg(mode)
    if output is not None:
        output = check_writable(output)

    if isinstance(source, polylla_io.Triangulation2D):
        tri, name = source, source.source
    elif isinstance(source, (str, bytes)) or hasattr(source, "__fspath__"):
        name = str(source)
        tri = polylla_io.read_input(name)
    else:
        tri, name = polylla_io.from_points(source), "points"
    try:
        run_tri, kept = _without_repeats(tri, structure)
        mesh, t_build = _run_whole(run_tri, structure, check=check, tables=tables, mode=mode)
        if kept is not None:
            mesh = dataclasses.replace(mesh, points=tri.points,
                                       indices=kept[mesh.indices].astype(np.int32))
    except errors.NonManifoldVertexError:
        split, copy_of = _split_pinch_vertices(tri)
        if copy_of is None:
            raise
        mesh, t_build = _run_whole(split, structure, check=check, tables=tables, mode=mode)
        mesh = dataclasses.replace(mesh, points=tri.points,
                                   indices=copy_of[mesh.indices].astype(np.int32))
    if output is not None:
        polylla_io.write_polygon_off(output, tri.points, mesh.offsets, mesh.indices)
    out = mesh.summary()
    out.update(structure=structure, mode=mode, tables=tables, input=name, output=output,
               timings={"build": t_build, **mesh.timings})
    if tri.duplicates:  # a point set's exact repeats, left in no triangle (from_points)
        out["duplicate_points"] = tri.duplicates
    if tri.notes:
        out["notes"] = list(tri.notes)
    return out
