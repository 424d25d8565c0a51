"""LR, the Laced Ring (Gurung, Luffel, Lindstrom, Rossignac, ACM TOG 2011), and its bit-efficient
variant ``lr-bits`` (Sec. 6).

A *ring* (Sec. 4.2, built by :mod:`jaxcds.construct.ring_expander`) visits most vertices; ring
vertices are renumbered ``0 .. m_r - 1`` in ring order (``v.n = v + 1 mod m_r``) and come first,
isolated vertices after them (:attr:`LR.vertex_order`). Every ring edge ``(v, v.n)`` has a left
triangle ``v.t_L = 2v = (v, v.l, v.n)`` and a right triangle ``v.t_R = 2v + 1 = (v.n, v.r, v)``
(Sec. 4.4, Fig. 5) whose only stored vertex is ``L[v]`` / ``R[v]``; their corners are
``8v + i``: ``v.0, v.1, v.2`` at ``v, v.l, v.n`` and ``v.4, v.5, v.6`` at ``v.n, v.r, v``.
Triangles with no ring edge (T0) keep a plain corner table ``V0, O0`` with corner ids
``8 m_r + 4j + i`` (Sec. 4.7). Irregular triangles (adjacent to a T0, T^i) store their apex and two
opposite corners in ``VO*`` (Sec. 4.5). Wart skipping (Sec. 5): a T0 next to a T2 wart is stored
in the wart's redundant slot as a T1 whose ring edge skips the wart tip (``v.n* = v.n.n``).

Corner ids are darts of the navigation protocol (:mod:`jaxcds.structures.base`): corner ``c`` is
the dart leaving ``c.v`` counter-clockwise in ``c.t``. The redundant copy of a T2 (Sec. 4.4,
"associate the T2 with its second ring edge") is not a valid dart; every operator returns
canonical corners. Protocol faces are numbered densely (``face(c)`` = rank of the slot ``c >> 2``
among non-redundant slots, a popcount directory of ``2 ceil(2 m_r / 32)`` words kept outside the
paper's reference count, see :attr:`LR.aux_references`).

Both classes share one implementation of the operators (:class:`_LRNavigation`); they differ only
in how a ring vertex's entry is decoded (:meth:`_dec`): 32-bit entries with service bits (``LR``)
or 16-bit relative offsets with long references through ``VO*`` (``LRBits``, Sec. 6.1-6.2).
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple, Optional

import jax
import jax.numpy as jnp
import numpy as np

from jaxcds import _mappings, errors
from jaxcds._arrays import to_device
from jaxcds._args import flag_arg, is_integer
from jaxcds._dataclass import pytree_dataclass, static_field
from jaxcds.construct import lr_pack
from jaxcds.construct.ring_expander import (LRTables, _best_ring_trusted, _extract_ring_trusted,
                                            _lr_tables_trusted, check_seeds)
from jaxcds.construct.ring_search import _improve_ring_trusted, check_sweeps
from jaxcds.mesh import load_mesh, validate, validate_and_close
from jaxcds.structures.base import (Int, MeshStructure, check_id_space, checked_ids, id_table_route,
                                    interleave_rows, take_nonnegative)
from jaxcds.structures.corner_table import CornerTable

__all__ = ["LR", "LRBits", "build_lr", "stats", "render_list", "expand_render_list",
           "renderable_index_list", "expand_renderable_index_list"]

_VALUE_BITS = 29
_VALUE_MASK = (1 << _VALUE_BITS) - 1
_SKIP_BIT = 29  # service bit: wart skip (Sec. 5, Sec. 6.2 "L_w")
_IRR_BIT = 30  # service bit: irregular T^i, the value is a VO* triplet index (Sec. 4.5)
_FAIL = np.int32(2**31 - 1)  # "no cheap opposite" (only ever seen at construction)


class _Slot(NamedTuple):
    """Decoded LR entry of ring vertex ``v``: apexes ``l = v.l``, ``r = v.r``; wart-skip flags;
    irregular flags; ``VO*`` positions of the two stored opposites of the left / right slot."""

    l: Int
    r: Int
    skl: Int
    skr: Int
    irl: Int
    irr: Int
    lo: Int
    ro: Int


# --------------------------------------------------------------------------------- operators
# Written for any array module (``xp``: jax.numpy for the structure, numpy works too), ``dec``
# decodes ring vertices, ``m`` = m_r. Construction runs their scalar numba twins
# (:mod:`jaxcds.construct.lr_pack`), which the tests compare with these on every corner.


def _nx(xp, x, m):
    """``v.n = v + 1 mod m_r``."""
    return xp.where(x + 1 >= m, x + 1 - m, x + 1)


def _pv(xp, x, m):
    """``v.p = v - 1 mod m_r``."""
    return xp.where(x == 0, m - 1, x - 1)


def _ring_vertex(xp, dec, m, c):
    """``c.v`` for ring corners ``c < 8 m_r`` (Sec. 4.7): offset ``c mod 8`` selects among
    ``v, v.l, v.n*, v.r`` (``v.n* = v.n.n`` in a wart-skipping T0^w, Sec. 5)."""
    v = c >> 3
    i = c & 7
    d = dec(v)
    vn = _nx(xp, v, m)
    vnn = _nx(xp, vn, m)
    nl = xp.where(d.skl, vnn, vn)
    nr = xp.where(d.skr, vnn, vn)
    # Fig. 5: v.0 = v.6 = v; v.1 = v.l; v.2 = v.n (L side); v.4 = v.n (R side); v.5 = v.r
    return xp.where(i == 1, d.l, xp.where(i == 5, d.r,
                    xp.where(i == 2, nl, xp.where(i == 4, nr, v))))


def _canonical(xp, dec, m, c):
    """Map a redundant T2 corner to its canonical copy (Sec. 4.4, Fig. 5 right): slot ``L(v)`` is
    redundant when ``v.l = v.n.n`` (the T2 lives on its second ring edge, slot ``L(v.n)``),
    likewise ``R(v)`` when ``v.r = v.n.n``."""
    ok = (c >= 0) & (c < 8 * m)  # T0 corners and _FAIL pass through
    w = xp.where(ok, c >> 3, 0)
    i = c & 7
    d = dec(w)
    wn = _nx(xp, w, m)
    wnn = _nx(xp, wn, m)
    left = i < 4
    red = xp.where(left, (d.skl == 0) & (d.l == wnn), (d.skr == 0) & (d.r == wnn))
    # L(v) = (v, v.n.n, v.n) == L(v.n) = (v.n, v, v.n.n): 0 -> 1, 1 -> 2, 2 -> 0
    # R(v) = (v.n, v.n.n, v) == R(v.n) = (v.n.n, v, v.n): 4 -> 6, 5 -> 4, 6 -> 5
    j = xp.where(left, (i + 1) % 3, 4 + (i + 1) % 3)
    return xp.where(ok & red, 8 * wn + j, c)


def _find(xp, dec, m, right, x, y):
    """The corner facing the transversal edge of the slot triangle that holds the dart
    ``x -> y`` (left side) or ``y -> x`` (right side), found from the ring alone (Sec. 4.5, Fig. 6):

    * case "v.n.l = v.l": the dart starts at ring vertex ``x`` of a slot ``L(x)`` with apex ``y``
      (right side: ``R(x)`` with apex ``y``) -> ``x.2`` (``x.4``);
    * case "v.l.p.l = v.n": slot ``L(y.p)`` (``R(y.p)``) with apex ``x`` -> ``y.p.0`` (``y.p.6``);
    * the same through a wart-skipping slot (Sec. 5, "we let v.p.n = v.n when accessing a T0^w"):
      ``L(y.p.p)`` with the skip bit -> ``y.p.p.0`` (``.6``).

    Returns ``_FAIL`` when none holds (the neighbour is a T0: the slot is irregular)."""
    okx = (x >= 0) & (x < m)
    oky = (y >= 0) & (y < m)
    x_ = xp.where(okx, x, 0)
    y_ = xp.where(oky, y, 0)
    dx = dec(x_)
    a = okx & (xp.where(right, dx.r, dx.l) == y)
    w1 = _pv(xp, y_, m)
    d1 = dec(w1)
    b = oky & (xp.where(right, d1.skr, d1.skl) == 0) & (xp.where(right, d1.r, d1.l) == x)
    w2 = _pv(xp, w1, m)
    d2 = dec(w2)
    b2 = oky & (xp.where(right, d2.skr, d2.skl) == 1) & (xp.where(right, d2.r, d2.l) == x)
    off_a = xp.where(right, 4, 2)
    off_b = xp.where(right, 6, 0)
    return xp.where(a, 8 * x_ + off_a,
                    xp.where(b, 8 * w1 + off_b, xp.where(b2, 8 * w2 + off_b, _FAIL)))


def _cheap_opposite(xp, dec, m, c):
    """``c.o`` for a canonical ring corner ``c < 8 m_r`` of a regular triangle (Sec. 4.5, Fig. 6,
    Sec. 5), before canonicalisation. Irregular slots take their opposites from ``VO*``."""
    v = c >> 3
    i = c & 7
    d = dec(v)
    vn = _nx(xp, v, m)
    vp = _pv(xp, v, m)
    dp = dec(vp)
    vnn = _nx(xp, vn, m)
    nl = xp.where(d.skl, vnn, vn)
    nr = xp.where(d.skr, vnn, vn)
    # quad opposites across ring edge (w, w.n): v.1.o = v.5 and v.5.o = v.1 (Sec. 4.5); when the
    # other side of the edge is a wart (its T0^w sits in this slot's partner), the wart's corner
    # facing the ring edge: (w.n).4 for a right wart, (w.n).2 for a left one (Sec. 5).
    quad_l = xp.where(d.skr, 8 * vn + 4, 8 * v + 5)  # v.1.o
    quad_r = xp.where(d.skl, 8 * vn + 2, 8 * v + 1)  # v.5.o
    # T0^w apex faces the wart: "conversely for T0^w tip corners" v.p.1.o = v.0 (Sec. 5)
    o1 = xp.where(d.skl, 8 * vn + 0, quad_l)
    o5 = xp.where(d.skr, 8 * vn + 6, quad_r)
    # canonical T2 (v.l = v.p): v.2 faces ring edge (v.p, v): "remap v.2 to v.p.1" and take the
    # quad opposite of v.p (Sec. 4.5); same for v.4 -> v.p.5
    t2l = (d.skl == 0) & (d.l == vp)
    t2r = (d.skr == 0) & (d.r == vp)
    quad_lp = xp.where(dp.skr, 8 * v + 4, 8 * vp + 5)
    quad_rp = xp.where(dp.skl, 8 * v + 2, 8 * vp + 1)
    # transversal corners (Fig. 6): one _find with the dart chosen by the offset
    right = i >= 4
    x = xp.where(i == 0, nl, xp.where(i == 2, d.l, xp.where(i == 4, d.r, nr)))
    y = xp.where(i == 0, d.l, xp.where(i == 2, v, xp.where(i == 4, v, d.r)))
    f = _find(xp, dec, m, right, x, y)
    # wart tips (Sec. 5): "v.0.o = v.p.1 and v.6.o = v.p.5" when slot v.p holds the T0^w
    o0 = xp.where(dp.skl == 1, 8 * vp + 1, f)
    o2 = xp.where(t2l, quad_lp, f)
    o4 = xp.where(t2r, quad_rp, f)
    o6 = xp.where(dp.skr == 1, 8 * vp + 5, f)
    return xp.where(i == 0, o0, xp.where(i == 1, o1, xp.where(i == 2, o2,
                    xp.where(i == 4, o4, xp.where(i == 5, o5, o6)))))


def _slot_triangles(xp, dec, m, nv, v):
    """Both slot triangles of ring vertices ``v`` from ONE decode each (the whole-mesh face list,
    Sec. 4.4 / Sec. 7: "the ring edges are implicit, one reference per slot"): ``(left, right,
    ok_l, ok_r)``, rows in the corner order of Fig. 5 / :func:`_ring_vertex`, ``L(v)`` = corners
    ``8v + 0, 1, 2`` = ``(v, v.l, v.n*)`` and ``R(v)`` = ``8v + 4, 5, 6`` = ``(v.n*, v.r, v)``
    (``v.n* = v.n.n`` in a wart-skipping T0^w, Sec. 5). ``ok`` is False for the redundant copy
    of a T2 (Sec. 4.4: it is kept in the slot of its second ring edge) and, when ``nv`` is given,
    for a triangle across a border (Sec. 4.6: its apex is a dummy vertex, numbered from ``nv``
    on; ring vertices are never dummies); such apexes are clamped to ``v`` so every row holds
    vertex ids. ``m``, ``nv``: ints, or arrays broadcast with ``v`` (packed batches)."""
    d = dec(v)
    vn = _nx(xp, v, m)
    vnn = _nx(xp, vn, m)
    nl = xp.where(d.skl == 1, vnn, vn)
    nr = xp.where(d.skr == 1, vnn, vn)
    # a T0^w (skip bit set) is a face of its own even when v.l = v.n.n: only a plain T2 copy hides
    ok_l = ~((d.skl == 0) & (d.l == vnn))
    ok_r = ~((d.skr == 0) & (d.r == vnn))
    al, ar = d.l, d.r
    if nv is not None:
        real_l = al < nv
        real_r = ar < nv
        ok_l = ok_l & real_l
        ok_r = ok_r & real_r
        al = xp.where(real_l, al, v)
        ar = xp.where(real_r, ar, v)
    left = xp.stack([v, al, nl], axis=-1)
    right = xp.stack([nr, ar, v], axis=-1)
    return left, right, ok_l, ok_r


def _wrap(x, m):
    """``x mod m`` for ``-m <= x < 2m``."""
    return jnp.where(x < 0, x + m, jnp.where(x >= m, x - m, x))


def _popcount32(x):
    return jax.lax.population_count(x)


class _LRNavigation(MeshStructure):
    """Operators shared by :class:`LR` and :class:`LRBits` (Sec. 4.7); subclasses provide
    ``_dec``, ``VOs``, ``V0``, ``O0``, ``C``, the slot directory and the static sizes."""

    # the decoding operators run by chunks on CPU (base._chunked_query); next, prev, face,
    # origin and edge_of_vertex are one or two gathers and measured 1.5-3.5x slower by chunks
    chunked_queries = frozenset({"target", "twin", "face_right", "right_front", "right_back",
                                 "corner_opposite"})
    # eager calls as one jitted program per power-of-two size (base._bucketed): 12 eager calls of
    # new sizes on a 2,000-vertex LR 6.5 -> 2.5 s, a warm call 30 -> 1.1 ms (stop 43)
    eager_buckets = True
    jit_when_eager = frozenset(("face_vertices", "face_vertices_padded", "dart_faces"))
    # batches of twice the darts' worth of ids or more: the operators whose per-query route
    # decodes an opposite corner (Sec. 4.7's case analysis, 16-37 ns per id; the chunked ones)
    # computed for every dart once, then one gather per id (base.id_table_route, set below the
    # class; RESULTS.md, "stop 47": 10M ids on 100K vertices, Target 25 -> 3 ns per id)
    table_queries = {op: f"_{op}_by_id_table" for op in chunked_queries}
    table_batch_ratio = 2

    closed_triangles = True

    # ---------------------------------------------------------------- paper operators (Fig. 2)
    def _dec(self, v) -> _Slot:  # pragma: no cover - abstract
        raise NotImplementedError

    def _dec_all(self) -> _Slot:
        """:meth:`_dec` of every ring vertex ``0 .. m_r - 1`` (subclasses read their tables
        whole instead of gathering them through an ``arange``)."""
        return self._dec(jnp.arange(self.num_ring, dtype=jnp.int32))

    def _t0_index(self, c):
        # "i = c - floor(c/4) - 6 m_r restores the base to six" (Sec. 4.7)
        i = c - (c >> 2) - 6 * self.num_ring
        return jnp.clip(i, 0, max(3 * self.num_t0 - 1, 0))

    @checked_ids
    def v(self, c: Int) -> Int:
        """``c.v`` (Sec. 4.7): ``V0`` for T0 corners ``c >= 8 m_r``, else from ``v = c / 8``, the
        offset ``c mod 8`` and the L/R entry of ``v``."""
        c = jnp.asarray(c, jnp.int32)
        m = self.num_ring
        t0 = c >= 8 * m
        ring = _ring_vertex(jnp, self._dec, m, jnp.where(t0, 0, c))
        return jnp.where(t0, self.V0[self._t0_index(c)], ring).astype(jnp.int32)

    @checked_ids
    def o(self, c: Int) -> Int:
        """``c.o`` (Sec. 4.7, Fig. 6): ``O0`` for T0 corners; the ``VO*`` record of an irregular
        slot (Sec. 4.5); otherwise the ring case analysis of :func:`_cheap_opposite`, canonicalised."""
        c = jnp.asarray(c, jnp.int32)
        m = self.num_ring
        t0 = c >= 8 * m
        cr = jnp.where(t0, 0, c)
        i = cr & 7
        d = self._dec(cr >> 3)
        cheap = _canonical(jnp, self._dec, m, _cheap_opposite(jnp, self._dec, m, cr))
        # T^i (Sec. 4.5): "VO* holds triplets (v.l, v.0.o, v.2.o) and (v.r, v.4.o, v.6.o)"
        irr_l = (d.irl == 1) & ((i == 0) | (i == 2))
        irr_r = (d.irr == 1) & ((i == 4) | (i == 6))
        # the second triplet's index as an explicit int: users may run with strict dtype promotion
        k = jnp.where(irr_l, d.lo + (i == 2).astype(d.lo.dtype), jnp.where(irr_r, d.ro + (i == 6).astype(d.ro.dtype), 0))
        k = jnp.clip(k, 0, self.VOs.shape[0] - 1)
        ring = jnp.where(irr_l | irr_r, take_nonnegative(self.VOs, k), cheap)
        return jnp.where(t0, self.O0[self._t0_index(c)], ring).astype(jnp.int32)

    @checked_ids
    def n(self, c: Int) -> Int:
        """``c.n = c - 2`` if ``c mod 4 = 2`` else ``c + 1`` (Sec. 4.7)."""
        c = jnp.asarray(c, jnp.int32)
        return jnp.where((c & 3) == 2, c - 2, c + 1).astype(jnp.int32)

    @checked_ids
    def p(self, c: Int) -> Int:
        """``c.p = c + 2`` if ``c mod 4 = 0`` else ``c - 1``."""
        c = jnp.asarray(c, jnp.int32)
        return jnp.where((c & 3) == 0, c + 2, c - 1).astype(jnp.int32)

    @checked_ids
    def s(self, c: Int) -> Int:
        """``c.s = c.n.o.n``: next corner around ``c.v``."""
        return self.n(self.o(self.n(c)))

    @checked_ids
    def l(self, c: Int) -> Int:  # noqa: E743 - the paper's name
        """``c.l = c.n.o``."""
        return self.o(self.n(c))

    @checked_ids
    def r(self, c: Int) -> Int:
        """``c.r = c.p.o``."""
        return self.o(self.p(c))

    @checked_ids
    def t(self, c: Int) -> Int:
        """``c.t = c / 4``: the paper's triangle id (``2v``, ``2v + 1``, ``2 m_r + j``), with the
        redundant T2 slots as holes (see :meth:`face` for the dense protocol id)."""
        return (jnp.asarray(c, jnp.int32) >> 2).astype(jnp.int32)

    @checked_ids
    def tc(self, t: Int) -> Int:
        """``t.c = 4t``: first corner of paper triangle ``t``."""
        return (4 * jnp.asarray(t, jnp.int32)).astype(jnp.int32)

    @checked_ids
    def vc(self, v: Int) -> Int:
        """``v.c`` (Sec. 4.7): ``C[v - m_r]`` for isolated vertices, else ``v.0 = 8v``
        canonicalised ("if v.l = v.n.n then v.c = 8 v.n + 1")."""
        v = jnp.asarray(v, jnp.int32)
        m = self.num_ring
        iso = v >= m
        vr = jnp.where(iso, 0, v)
        ring = _canonical(jnp, self._dec, m, 8 * vr)
        ci = jnp.clip(v - m, 0, self.C.shape[0] - 1)
        return jnp.where(iso, self.C[ci], ring).astype(jnp.int32)

    # ---------------------------------------------------------------- protocol core
    @property
    def num_darts(self) -> int:
        return 8 * self.num_ring + 4 * self.num_t0

    def _redundant_slot(self, t):
        """True where paper triangle ``t < 2 m_r`` is the redundant copy of a T2."""
        m = self.num_ring
        w = t >> 1
        d = self._dec(w)
        wnn = _nx(jnp, _nx(jnp, w, m), m)
        left = (t & 1) == 0
        return jnp.where(left, (d.skl == 0) & (d.l == wnn), (d.skr == 0) & (d.r == wnn))

    def _dummy_face(self, e):
        """True where ``e``'s triangle has a dummy vertex (Sec. 4.6: "non-existent triangles
        across mesh borders"); dummy vertices are numbered last, from ``num_vertices`` on."""
        nv = self.num_vertices
        return (self.v(e) >= nv) | (self.v(self.n(e)) >= nv) | (self.v(self.p(e)) >= nv)

    def dart_valid(self, e: Int) -> Int:
        e = jnp.asarray(e, jnp.int32)
        inr = (e >= 0) & (e < self.num_darts) & ((e & 3) != 3)
        ring = e < 8 * self.num_ring
        t = jnp.where(ring & inr, e >> 2, 0)
        ok = inr & ~(ring & self._redundant_slot(t))
        if self.has_border:
            # in a dummy triangle only the border dart (both ends real) is a dart
            ec = jnp.where(ok, e, 0)
            ok = ok & (self.v(ec) < self.num_vertices) & (self.v(self.n(ec)) < self.num_vertices)
        return ok

    def origin(self, e: Int) -> Int:
        return self.v(e)

    def next(self, e: Int) -> Int:
        if not self.has_border:
            return self.n(e)
        # border dart (u, v) of dummy triangle (u, v, d): the next one is (v, w) of (v, w, d)
        return jnp.where(self._dummy_face(e), self.n(self.twin(self.n(e))), self.n(e))

    def prev(self, e: Int) -> Int:
        if not self.has_border:
            return self.p(e)
        return jnp.where(self._dummy_face(e), self.p(self.twin(self.p(e))), self.p(e))

    def twin(self, e: Int) -> Int:
        # dart c = (c.v, c.n.v); across it lies c.p.o, whose next corner starts at c.n.v
        return self.n(self.o(self.p(e)))

    def corner_opposite(self, c: Int) -> Int:
        if self.has_border:  # across a border the protocol's answer is a border dart
            return self.prev(self.twin(self.next(c)))
        return self.o(c)

    def corner_swing(self, c: Int) -> Int:
        if self.has_border:
            return self.twin(self.prev(c))
        return self.s(c)

    def face(self, e: Int) -> Int:
        """Dense face id: rank of slot ``e >> 2`` among the non-redundant real slots (popcount
        directory), real T0 triangles after the ring slots; ``num_faces`` for border darts."""
        e = jnp.asarray(e, jnp.int32)
        t = e >> 2
        two_m = 2 * self.num_ring
        _, rank = self._slot_rank(jnp.clip(t, 0, two_m - 1))
        f = jnp.where(t < two_m, rank, t - two_m + self.num_ring_faces)
        if self.has_border:
            f = jnp.where(self._dummy_face(e), self.num_faces, f)
        return f.astype(jnp.int32)

    def _slot_rank(self, t):
        """``(bit, rank)`` of ring slots ``0 <= t < 2 m_r`` in the dense-face directory: ``bit``
        True where the slot is a face of its own, ``rank`` = faces in the slots before it (the
        dense face id of a face slot)."""
        word = jax.lax.bitcast_convert_type(self.slot_words[t >> 5], jnp.uint32)
        sh = (t & 31).astype(jnp.uint32)
        below = word & ((jnp.uint32(1) << sh) - jnp.uint32(1))
        bit = ((word >> sh) & jnp.uint32(1)) == 1
        return bit, self.slot_rank[t >> 5] + _popcount32(below).astype(jnp.int32)

    def _slot_rows(self):
        """``(left, right, ok_l, ok_r)`` of :func:`_slot_triangles` over every ring vertex (one
        decode each) and the T0 rows ``(n0, 3)`` of ``V0`` with their mask (dummy triangles of
        Sec. 4.6 masked and clamped)."""
        m, nv = self.num_ring, self.num_vertices
        v = jnp.arange(m, dtype=jnp.int32)
        left, right, ok_l, ok_r = _slot_triangles(jnp, lambda _: self._dec_all(), m,
                                                  nv if self.has_border else None, v)
        t0 = self.V0[: 3 * self.num_t0].reshape(self.num_t0, 3)
        if self.has_border:
            ok0 = jnp.all(t0 < nv, axis=1)
            t0 = jnp.minimum(t0, nv - 1)
        else:
            ok0 = jnp.ones((self.num_t0,), bool)
        return left, right, ok_l, ok_r, t0, ok0

    def face_vertices_padded(self):
        """Every face once, in slot order, no navigation (Sec. 4.4, Sec. 7): the ``2 m_r`` slot
        triangles from one decode per ring vertex (left slots, then right slots), the redundant
        T2 copies and border triangles masked, then the T0 triangles of ``V0``, the rows read in
        16 interleaved blocks (:func:`~jaxcds.structures.base.interleave_rows`: no run of one apex
        for the sums).
        Rows are ``(R, 3)`` with ``R = 2 m_r + n0``; see
        :meth:`MeshStructure.face_vertices_padded`."""
        left, right, ok_l, ok_r, t0, ok0 = self._slot_rows()
        faces = jnp.concatenate([left, right, t0], axis=0).astype(jnp.int32)
        ok = jnp.concatenate([ok_l, ok_r, ok0])
        return interleave_rows(faces), interleave_rows(ok)

    def face_vertices(self) -> Int:
        """``(num_faces, 3)`` in dense face-id order, equal to the protocol route
        (``edge_of_face`` + ``next`` + ``origin``): the rows of :meth:`face_vertices_padded`
        scattered to their face ids (a face slot's id is its directory rank; real T0 triangles
        come first in ``V0`` and follow the ring faces), the others dropped."""
        left, right, ok_l, ok_r, t0, ok0 = self._slot_rows()
        m, nf = self.num_ring, self.num_faces
        v = jnp.arange(m, dtype=jnp.int32)
        bl, rl = self._slot_rank(2 * v)
        br, rr = self._slot_rank(2 * v + 1)
        j = jnp.arange(self.num_t0, dtype=jnp.int32)
        loc = jnp.concatenate([jnp.where(bl, rl, -1), jnp.where(br, rr, -1),
                               jnp.where(j < nf - self.num_ring_faces, self.num_ring_faces + j, -1)])
        # rows that are no face go past the end, each to its own index (the indices stay unique)
        dest = jnp.where(loc >= 0, loc, nf + jnp.arange(loc.shape[0], dtype=jnp.int32))
        rows = jnp.concatenate([left, right, t0], axis=0).astype(jnp.int32)
        out = jnp.zeros((nf, 3), jnp.int32)
        return out.at[dest].set(rows, mode="drop", unique_indices=True)

    def edge_of_face(self, f: Int) -> Int:
        """Corner ``4t`` of the slot of dense face ``f`` (select by binary search on the rank
        directory, then in-word binary lifting with popcounts: O(log n))."""
        f = jnp.asarray(f, jnp.int32)
        ring = f < self.num_ring_faces
        fr = jnp.where(ring, f, 0)
        w = jnp.searchsorted(self.slot_rank, fr, side="right").astype(jnp.int32) - 1
        w = jnp.clip(w, 0, self.slot_rank.shape[0] - 1)
        k = (fr - self.slot_rank[w]).astype(jnp.uint32)
        word = jax.lax.bitcast_convert_type(self.slot_words[w], jnp.uint32)
        pos = jnp.zeros_like(k)
        for step in (16, 8, 4, 2, 1):
            cand = pos + jnp.uint32(step)
            low = _popcount32(word & ((jnp.uint32(1) << cand) - jnp.uint32(1)))
            pos = jnp.where(low <= k, cand, pos)
        slot = 32 * w + pos.astype(jnp.int32)
        t0 = f - self.num_ring_faces + 2 * self.num_ring
        return (4 * jnp.where(ring, slot, t0)).astype(jnp.int32)

    def edge_of_vertex(self, v: Int) -> Int:
        c = self.vc(v)
        if not self.has_border:
            return c
        # a corner of v in a dummy triangle (u, v, d) leaves v towards d: swing once to (v, u)
        return jnp.where(self.v(self.n(c)) >= self.num_vertices, self.s(c), c)

    @property
    def vertex_order(self) -> np.ndarray:
        return np.asarray(self.order)

    # ---------------------------------------------------------------- statistics
    @property
    def num_isolated(self) -> int:
        """``m_i``: real vertices off the ring (dummy vertices have a null index, Sec. 4.6)."""
        return self.num_vertices - self.num_ring

    @property
    def has_border(self) -> bool:
        return self.num_closed_vertices > self.num_vertices

    @property
    def aux_references(self) -> int:
        """Words of the dense-face directory (protocol adapter, not in the paper's count)."""
        return int(self.slot_words.shape[0] + self.slot_rank.shape[0])

    # ---- packed batches (jaxcds.batch): one block, the machinery lives in lr_packed
    @classmethod
    def concatenate(cls, parts):
        """One structure over the disjoint union of ``parts`` (all of class ``cls``, one per mesh)
        for :func:`jaxcds.batch.pack`. The union of rings is not a ring (``v.n = v + 1 mod m_r``,
        corners ``8v + i``, T0 corners from ``8 m_r``, lr-bits offsets mod ``m_r``): the arrays
        are concatenated unshifted and every operator runs on each element's mesh-local ids
        (:mod:`jaxcds.structures.lr_packed`)."""
        from jaxcds.structures.lr_packed import concatenate_lr

        return concatenate_lr(cls, parts)


def _nonempty(a, dtype=np.int32, size: int = 1):
    """``a`` padded to at least ``size`` entries (gathers on empty arrays do not trace); the
    padding is not counted in :attr:`references`."""
    a = np.asarray(a, dtype=dtype)
    return a if a.size >= size else np.concatenate([a, np.zeros(size - a.size, dtype=dtype)])


# --------------------------------------------------------------------------------- structures
for _op in _LRNavigation.chunked_queries:
    setattr(_LRNavigation, f"_{_op}_by_id_table", id_table_route(_op))


@pytree_dataclass
class LR(_LRNavigation):
    """Standard LR (Sec. 4): about 1.08 references per triangle.

    Fields (``m_r`` ring vertices, ``n0`` T0 triangles, ``n_i`` irregular triangles):
      L, R: ``(m_r,)`` int32 entries of ``L[v] = v.l`` / ``R[v] = v.r`` (bits 0-28), service bits
        (Sec. 6.2): bit 29 wart skip (``L_w`` / ``R_w``), bit 30 irregular (bits 0-28 are then a
        ``VO*`` triplet index).
      VOs: ``(3 n_i,)`` int32 ``VO*`` triplets ``(v.l, v.0.o, v.2.o)`` / ``(v.r, v.4.o, v.6.o)``.
      V0, O0: ``(3 n0,)`` int32 corner table of the T0 triangles (corner ``8 m_r + 4j + i`` at
        index ``3j + i``).
      C: ``(m_i,)`` int32 a corner of each isolated vertex ``m_r + k`` (``v.c``).
      slot_words, slot_rank: dense-face directory over the ``2 m_r`` slots (protocol adapter).
      order: ``(m,)`` int32 input vertex id of each LR vertex (:attr:`vertex_order`).
    """

    L: jnp.ndarray
    R: jnp.ndarray
    VOs: jnp.ndarray
    V0: jnp.ndarray
    O0: jnp.ndarray
    C: jnp.ndarray
    slot_words: jnp.ndarray
    slot_rank: jnp.ndarray
    order: jnp.ndarray
    num_vertices: int = static_field()
    num_faces: int = static_field()
    num_ring: int = static_field()
    num_t0: int = static_field()
    num_vos: int = static_field()
    num_ring_faces: int = static_field()
    num_closed_vertices: int = static_field()
    num_closed_faces: int = static_field()

    name = "lr"

    def _dec(self, v) -> _Slot:
        return self._dec_entries(self.L[v], self.R[v])

    def _dec_all(self) -> _Slot:
        # every ring vertex in order: the arrays themselves, no gather
        return self._dec_entries(self.L[: self.num_ring], self.R[: self.num_ring])

    def _dec_entries(self, a, b) -> _Slot:
        skl = (a >> _SKIP_BIT) & 1
        skr = (b >> _SKIP_BIT) & 1
        irl = (a >> _IRR_BIT) & 1
        irr = (b >> _IRR_BIT) & 1
        ia = a & _VALUE_MASK
        ib = b & _VALUE_MASK
        top = self.VOs.shape[0] - 1
        la = jnp.clip(3 * ia, 0, top)
        lb = jnp.clip(3 * ib, 0, top)
        return _Slot(l=jnp.where(irl == 1, take_nonnegative(self.VOs, la), ia), r=jnp.where(irr == 1, take_nonnegative(self.VOs, lb), ib),
                     skl=skl, skr=skr, irl=irl, irr=irr, lo=3 * ia + 1, ro=3 * ib + 1)

    @property
    def references(self) -> int:
        """``2 m_r + 6 n0 + 3 n^i + m_i`` (Sec. 8)."""
        return 2 * self.num_ring + 6 * self.num_t0 + self.num_vos + self.num_isolated

    @property
    def bits(self) -> int:
        return 32 * self.references

    @classmethod
    def from_mesh(cls, mesh, *, seeds=4, check: bool = True, wart_skipping: bool = True,
                  borders: bool = True, ring_sweeps: int = 0) -> "LR":
        """Build from a mesh; holes are closed with dummy vertices first (Sec. 4.6), see
        :func:`build_lr` (``ring_sweeps``: local search on the ring, beyond the paper)."""
        return build_lr(mesh, bits=False, seeds=seeds, check=check, wart_skipping=wart_skipping,
                        borders=borders, ring_sweeps=ring_sweeps)

    @classmethod
    def from_corner_table(cls, ct: CornerTable, *, dummy=None, seeds=4, check: bool = True,
                          wart_skipping: bool = True, ring_sweeps: int = 0) -> "LR":
        """Ring and tables from a :class:`CornerTable` (the paper's input, Sec. 8.1);
        ``dummy``: mask of dummy vertices (shown as borders). The table is trusted (a closed
        manifold): only its ids are checked (:func:`_check_table`)."""
        check, wart_skipping = _check_table(ct, "LR.from_corner_table", dummy=dummy, check=check,
                                            wart_skipping=wart_skipping)
        seeds = check_seeds(seeds, ct.V, dummy)  # a count of 0 or -1 was numpy's ValueError
        return _from_corner_table(cls, ct, dummy=dummy, seeds=seeds, k=None, check=check,
                                  wart_skipping=wart_skipping, ring_sweeps=ring_sweeps)


@pytree_dataclass
class LRBits(_LRNavigation):
    """Bit-efficient LR (Sec. 6): HYBRID-RING-EXPANDER ring, 16-bit entries.

    Fields:
      LR16: ``(2 m_r,)`` int16, ``L`` at ``2v`` and ``R`` at ``2v + 1``: bit 0 is the flag
        (``L_w``, ``R_w`` of Sec. 6.2), bits 1-15 a signed offset ``v.l - v`` (mod ``m_r``).
        Flags (1, 0) / (0, 1): wart skip on the left / right; (1, 1): *long*: the 30 offset bits
        of the pair hold ``a << 4 | skip_l | skip_r << 1 | irr_l << 2 | irr_r << 3``, ``a`` a
        26-bit index of the ``VO*`` record ``[v.l, v.r, (v.0.o, v.2.o), (v.4.o, v.6.o)]``.
      VOs: ``VO*`` records (32-bit). V0, O0, C, slot directory, order: as in :class:`LR`.
    """

    LR16: jnp.ndarray
    VOs: jnp.ndarray
    V0: jnp.ndarray
    O0: jnp.ndarray
    C: jnp.ndarray
    slot_words: jnp.ndarray
    slot_rank: jnp.ndarray
    order: jnp.ndarray
    num_vertices: int = static_field()
    num_faces: int = static_field()
    num_ring: int = static_field()
    num_t0: int = static_field()
    num_vos: int = static_field()
    num_ring_faces: int = static_field()
    num_closed_vertices: int = static_field()
    num_closed_faces: int = static_field()
    num_long: int = static_field()
    k: int = static_field()

    name = "lr-bits"

    def _dec(self, v) -> _Slot:
        return self._dec_entries(v, self.LR16[2 * v].astype(jnp.int32),
                                 self.LR16[2 * v + 1].astype(jnp.int32))

    def _dec_all(self) -> _Slot:
        # every ring vertex in order: the two strided halves of LR16, no gather
        m = self.num_ring
        return self._dec_entries(jnp.arange(m, dtype=jnp.int32),
                                 self.LR16[0:2 * m:2].astype(jnp.int32),
                                 self.LR16[1:2 * m:2].astype(jnp.int32))

    def _dec_entries(self, v, el, er) -> _Slot:
        m = self.num_ring
        fl = el & 1
        fr = er & 1
        long_ = (fl & fr) == 1
        payload = (((el >> 1) & 0x7FFF) << 15) | ((er >> 1) & 0x7FFF)
        a = jnp.where(long_, payload >> 4, 0)
        a = jnp.clip(a, 0, self.VOs.shape[0] - 2)
        one = jnp.int32(1)
        irl = jnp.where(long_, (payload >> 2) & 1, 0)
        irr = jnp.where(long_, (payload >> 3) & 1, 0)
        # 15-bit signed offsets modulo m_r (Sec. 6.1); packing keeps them in (-m_r/2, m_r/2], so
        # v + offset is at most one ring length off: one conditional wrap instead of a floor
        # modulo (a division when m_r is per element, as in a packed batch). Long entries compute
        # garbage here and take VO* below.
        lv = jnp.where(long_, take_nonnegative(self.VOs, a), _wrap(v + (el >> 1), m))
        rv = jnp.where(long_, take_nonnegative(self.VOs, a + 1), _wrap(v + (er >> 1), m))
        return _Slot(l=lv, r=rv,
                     skl=jnp.where(long_, payload & 1, fl & (one - fr)),
                     skr=jnp.where(long_, (payload >> 1) & 1, fr & (one - fl)),
                     irl=irl, irr=irr, lo=a + 2, ro=a + 2 + 2 * irl)

    @property
    def references(self) -> int:
        """Entries (16-bit LR entries count as half a reference)."""
        return self.num_ring + 6 * self.num_t0 + self.num_vos + self.num_isolated

    @property
    def bits(self) -> int:
        """``16 * 2 m_r + 32 (6 n0 + |VO*| + m_i)`` (Sec. 8: 32(m_r + 6 n0 + 3 n^i + n^l + m_i))."""
        return 32 * self.references

    @classmethod
    def from_mesh(cls, mesh, *, k="auto", seeds=1, check: bool = True,
                  borders: bool = True, ring_sweeps: int = 0) -> "LRBits":
        """Build with HYBRID-RING-EXPANDER; ``k="auto"`` keeps the period with the fewest bits
        (``ring_sweeps``: local search on each ring, see :func:`build_lr`)."""
        return build_lr(mesh, bits=True, k=k, seeds=seeds, check=check, borders=borders,
                        ring_sweeps=ring_sweeps)

    @classmethod
    def from_corner_table(cls, ct: CornerTable, *, k: int = 64, dummy=None, seeds=1,
                          check: bool = True, wart_skipping: bool = True) -> "LRBits":
        """HYBRID-RING-EXPANDER of period ``k`` (Sec. 6.1; 0 = depth-first) and the 16-bit tables
        from a :class:`CornerTable`; ``dummy``: mask of dummy vertices (shown as borders). The
        table is trusted (a closed manifold): only its ids are checked (:func:`_check_table`)."""
        check, wart_skipping = _check_table(ct, "LRBits.from_corner_table", dummy=dummy,
                                            check=check, wart_skipping=wart_skipping)
        ks = _check_k(k)
        if len(ks) != 1:
            raise errors.ArgumentError(f"LRBits.from_corner_table takes one period k, got {k!r}")
        seeds = check_seeds(seeds, ct.V, dummy)
        return _from_corner_table(cls, ct, dummy=dummy, seeds=seeds, k=ks[0], check=check,
                                  wart_skipping=wart_skipping)


# --------------------------------------------------------------------------------- construction
def _check_table(ct: CornerTable, where: str, *, dummy=None, check=True,
                 wart_skipping=True) -> tuple:
    """The ids of a corner table handed to the LR builders: ``c.v`` in ``[0, n)`` and ``c.o`` in
    ``[0, 3F)`` (O(F)). RING-EXPANDER's numba kernels read them unchecked: a table built by
    ``CornerTable.from_faces`` on a mesh with borders has ``c.o`` past the corners there (the
    half-edge's border darts), which read outside the arrays (a segfault). Other defects of a
    trusted table give a typed refusal from the ring or tables of unspecified meaning.

    Also the builders' other arguments (:class:`~jaxcds.errors.ArgumentError` naming them):
    ``ct`` a :class:`CornerTable` (a ``TriMesh`` raised an AttributeError about ``.V``),
    ``dummy`` ``None`` or ``num_vertices`` booleans (a string or a short mask raised numpy's
    IndexError), ``check`` and ``wart_skipping`` bools (returned)."""
    if not isinstance(ct, CornerTable):
        raise errors.ArgumentError(f"{where}: expected a CornerTable (CornerTable.from_mesh), got "
                                   f"{type(ct).__name__}")
    check = flag_arg(check, f"{where}: check")
    wart_skipping = flag_arg(wart_skipping, f"{where}: wart_skipping")
    if dummy is not None:
        d = np.asarray(dummy)
        if d.dtype != np.bool_ or d.shape != (ct.num_vertices,):
            raise errors.ArgumentError(f"{where}: dummy must be None or a ({ct.num_vertices},) "
                                       f"bool mask of the dummy vertices, got dtype {d.dtype} "
                                       f"and shape {d.shape}")
    V, O = np.asarray(ct.V), np.asarray(ct.O)
    nc, nv = 3 * ct.num_faces, ct.num_vertices
    if V.shape != (nc,) or O.shape != (nc,):
        raise errors.ArgumentError(f"{where}: V and O must have 3F = {nc} entries, got "
                                   f"{V.shape} and {O.shape}")
    if nc and (O.min() < 0 or O.max() >= nc):
        c = int(np.flatnonzero((O < 0) | (O >= nc))[0])
        raise errors.UnsupportedTopologyError(
            f"{where}: corner {c} (vertex {int(V[c])}, face {c // 3}) has no opposite corner "
            f"(c.o = {int(O[c])}, outside [0, {nc})): the table has a border; LR needs a closed "
            "mesh (LR.from_mesh closes holes with dummy vertices)")
    if nc and (V.min() < 0 or V.max() >= nv):
        c = int(np.flatnonzero((V < 0) | (V >= nv))[0])
        raise errors.InvalidIndexError(f"{where}: corner {c} (face {c // 3}) has vertex "
                                       f"{int(V[c])}, outside [0, {nv})")
    return check, wart_skipping


_AUTO_K = (16, 32, 64, 128, 256, 512, 1024, 0)


def _prepare(mesh, name: str = "lr"):
    """``(mesh, twins)``: the validated mesh, holes closed, and the dart twins validation found
    for its faces (:class:`jaxcds.mesh.Twins`; ``None`` if it took the full path), so the corner
    table does not match twins a second time."""
    mesh = load_mesh(mesh)
    if mesh.dummy_vertices is not None and np.any(mesh.dummy_vertices):
        # already closed by close_boundaries: keep its dummy flags
        return validate(mesh, closed=True, connected=True, structure=name, return_twins=True)
    # validation and hole closing (Sec. 4.6: one dummy vertex per hole) in one pass over the
    # faces; a closed mesh comes back unchanged
    return validate_and_close(mesh, connected=True, structure=name, return_twins=True)


def build_lr(mesh, *, bits: bool = False, k="auto", seeds=4, check: bool = True,
             wart_skipping: bool = True, borders: bool = True, ring_sweeps: int = 0):
    """``LR`` (``bits=False``) or ``LRBits`` from a mesh.

    Holes are closed with one dummy vertex each (Sec. 4.6), never on the ring. With ``borders``
    (default) the structure shows the mesh *with* its borders: dummy vertices get a null index
    (numbered past ``num_vertices``), dummy triangles are the outside (border darts, ``face ==
    num_faces``), as the HalfEdge of the input; with ``borders=False`` it is the closed mesh.
    ``k``: hybrid period for ``LRBits`` (``"auto"`` tries several and keeps the fewest bits, as
    the paper does, Sec. 8; 0 = depth-first). ``seeds``: number of random seed corners (or a list).
    ``ring_sweeps``: after RING-EXPANDER, anneal the ring for ``ring_sweeps * n`` local moves
    towards fewer references (:mod:`jaxcds.construct.ring_search`; beyond the paper, 0 = the
    paper's ring; about 0.2 us per triangle per sweep)."""
    _mappings.relieve()  # many meshes in one process: compiled programs pile up (_mappings)
    # flags as bools (ArgumentError): check='no' was truthy, borders=0 falsy; bits first (an
    # array raised numpy's "truth value" ValueError from `if bits`)
    bits = flag_arg(bits, "build_lr: bits")
    where = "LRBits.from_mesh" if bits else "LR.from_mesh"
    check = flag_arg(check, f"{where}: check")
    wart_skipping = flag_arg(wart_skipping, f"{where}: wart_skipping")
    borders = flag_arg(borders, f"{where}: borders")
    ring_sweeps = check_sweeps(ring_sweeps)
    ks = _check_k(k) if bits else None
    mesh, twins = _prepare(mesh, "lr-bits" if bits else "lr")
    try:
        return _build_lr_prepared(mesh, twins, bits=bits, ks=ks, seeds=seeds, check=check,
                                  wart_skipping=wart_skipping, borders=borders,
                                  ring_sweeps=ring_sweeps)
    except errors.UnsupportedTopologyError as exc:
        # the ring's refusals (a lone triangle: 3 ring vertices) come from code that does not
        # know the mesh: named here as every other refusal is (sweep 50a: CGAL's triangle.off)
        if str(exc).startswith(f"{mesh.source}: "):
            raise
        raise errors.UnsupportedTopologyError(f"{mesh.source}: {exc}") from exc


def _build_lr_prepared(mesh, twins, *, bits, ks, seeds, check, wart_skipping, borders,
                       ring_sweeps):
    """:func:`build_lr` after its arguments are checked and the mesh validated and closed."""
    ct = CornerTable._from_faces(mesh.faces, mesh.num_vertices, twins, check_twins=False)  # validate's
    dummy = mesh.dummy_vertices
    seeds = check_seeds(seeds, ct.V, dummy)
    if not bits:
        return _from_corner_table(LR, ct, dummy=dummy, seeds=seeds, k=None, check=check,
                                  wart_skipping=wart_skipping, borders=borders,
                                  ring_sweeps=ring_sweeps)
    V, O, nv = np.asarray(ct.V), np.asarray(ct.O), ct.num_vertices
    best = None
    for kk in ks:
        tb = _best_tables(V, O, nv, seeds=seeds, k=int(kk), dummy=dummy,
                          wart_skipping=wart_skipping)
        # the ring search counts references, not bits: keep the unsearched ring where it packs
        # smaller (both rings come from this period's seeds, RING-EXPANDER runs once)
        rings = [tb]
        if ring_sweeps and wart_skipping:
            rings.append(_searched(V, O, nv, tb, dummy=dummy, sweeps=ring_sweeps))
        for t in rings:
            s = _from_corner_table(LRBits, ct, dummy=dummy, k=int(kk), check=False,
                                   borders=borders, tables=t, device=False)
            if best is None or s.bits < best.bits:
                best = s
    best = _on_device(best)  # only the kept period's tables (8 periods tried by default)
    if check:
        _check_against(best, ct)
    return best


def _check_k(k) -> list:
    """The hybrid periods to try for ``LRBits``: ``"auto"`` (:data:`_AUTO_K`), an integer >= 0
    or a non-empty list of them; else :class:`~jaxcds.errors.ArgumentError` naming the value."""
    if isinstance(k, str) and k == "auto":
        return list(_AUTO_K)
    ks = [k] if np.isscalar(k) or k is None else (list(k) if hasattr(k, "__iter__") else [k])
    ok = bool(ks) and all(is_integer(x) and x >= 0 for x in ks)
    if not ok:
        raise errors.ArgumentError(f"k must be 'auto', an integer >= 0 (0: depth-first) or a "
                                   f"non-empty list of them, got {k!r}")
    return [int(x) for x in ks]


def _from_corner_table(cls, ct: CornerTable, *, dummy=None, seeds=4, k=None, check=True,
                       wart_skipping=True, borders=True, tables: Optional[LRTables] = None,
                       ring_sweeps: int = 0, device: bool = True):
    V = np.asarray(ct.V)
    O = np.asarray(ct.O)
    nv = ct.num_vertices
    if tables is None:
        tables = _best_tables(V, O, nv, seeds=seeds, k=k, dummy=dummy,
                              wart_skipping=wart_skipping, ring_sweeps=ring_sweeps)
    return _pack(cls, tables, V, O, np.asarray(ct.vertex_corner), nv, check=check,
                 k=0 if k is None else int(k), dummy=dummy if borders else None, device=device)


def _on_device(s):
    """A structure packed with host arrays (``_pack(..., device=False)``) on the device, its
    construction statistics kept."""
    stats = getattr(s, "_stats", None)
    out = jax.tree_util.tree_map(to_device, s)
    if stats is not None:
        object.__setattr__(out, "_stats", stats)
    return out


_SPARE_SEEDS = 28  # at most this many more seeds when every ring is trapped (m_i > m / 4)


def _best_tables(V, O, nv, *, seeds, k, dummy, wart_skipping, ring_sweeps=0) -> LRTables:
    """Sec. 4.2: several seeds, keep the fewest isolated vertices; ties broken by the Sec. 8
    reference count ``2 m_r + 6 n0 + 3 n^i + m_i`` (Sec. 8: "explore several k values and seed
    corners per mesh"). ``ring_sweeps > 0``: then anneal that ring (:func:`_searched`)."""
    if np.isscalar(seeds):
        nf = V.shape[0] // 3
        rng = np.random.default_rng(0)
        ok = np.ones(nf, dtype=bool)
        if dummy is not None:
            ok = ~np.asarray(dummy, bool)[V.reshape(-1, 3)].any(axis=1)
        cand = np.nonzero(ok)[0]
        if cand.size == 0:
            raise errors.UnsupportedTopologyError("no triangle without a dummy vertex to seed the ring")
        seeds = [int(3 * t) for t in rng.choice(cand, size=min(int(seeds), cand.size), replace=False)]
        spare = [int(3 * t) for t in rng.choice(cand, size=min(_SPARE_SEEDS, cand.size),
                                                  replace=False) if int(3 * t) not in seeds]
    else:
        spare = []  # the caller's seeds, as given
    rings = [_best_ring_trusted(V, O, nv, seeds=[sd], k=k, dummy=dummy) for sd in seeds]
    # Sec. 4.2 expects few isolated vertices. On meshes with many separating triangles (uniform
    # random planar triangulations) an unlucky seed traps the invasion inside one, leaving most
    # vertices isolated (rpt 4-5): draw more seeds while every ring is trapped.
    ndummy = 0 if dummy is None else int(np.sum(dummy))
    trapped = ndummy + (nv - ndummy) // 4
    while spare and min(r.num_isolated for r in rings) > trapped:
        rings.append(_best_ring_trusted(V, O, nv, seeds=[spare.pop(0)], k=k, dummy=dummy))
    fewest = min(r.num_isolated for r in rings)
    best, key = None, None
    for ring in rings:
        if ring.num_isolated > fewest:
            continue  # cannot win: classify only the rings tied for the fewest m_i
        tb = _lr_tables_trusted(V, O, ring, nv, wart_skipping=wart_skipping)
        st = tb.stats(V.shape[0] // 3)
        kk = (st["m_i"], 2 * st["m_r"] + 6 * st["T0"] + 3 * st["Ti"] + st["m_i"])
        if key is None or kk < key:
            best, key = tb, kk
    if ring_sweeps and wart_skipping:
        best = _searched(V, O, nv, best, dummy=dummy, sweeps=ring_sweeps)
    return best


def _searched(V, O, nv, tb: LRTables, *, dummy, sweeps: int) -> LRTables:
    """The ring of ``tb`` after :func:`jaxcds.construct.ring_search.improve_ring` (the search's
    cost model assumes wart skipping); ``tb`` itself if the search found nothing better."""
    ring = tb.ring
    tm, delta = _improve_ring_trusted(V, O, ring.invaded, nv, dummy=dummy, sweeps=sweeps, seed=ring.seed)
    if delta >= 0:
        return tb
    new = dataclasses.replace(_extract_ring_trusted(V, O, tm, nv, ring.seed, ring.k), search_gain=-delta)
    return _lr_tables_trusted(V, O, new, nv, wart_skipping=True)


def _pack(cls, tb: LRTables, V, O, vertex_corner, nv: int, *, check: bool, k: int, dummy=None,
          device: bool = True):
    """Pack the tables ``tb`` into ``cls`` (Sec. 4.5-4.7, Sec. 6 for ``LRBits``): a few O(n)
    numba passes (:mod:`jaxcds.construct.lr_pack`); the ring case analysis of Sec. 4.5 / Fig. 6
    runs on every regular corner and makes a slot irregular (``VO*``) where it cannot resolve a
    transversal corner. ``check``: verify every canonical corner's ``c.v`` and ``c.o`` against
    the corner table (:func:`_check`, also linear)."""
    m = tb.num_ring
    nf = V.shape[0] // 3
    # jnp.asarray would compile a copy per new shape (jaxcds._arrays); device=False: host
    # arrays, for candidates compared by size before one goes to the device (build_lr)
    _dev = to_device if device else np.asarray
    if nv >= 1 << _VALUE_BITS:
        raise errors.UnsupportedTopologyError(f"{nv} vertices: LR entries hold 29-bit vertex ids")
    # corner ids 8 w + i of the ring (and 4 per T0, checked below): int32 from 2^28 ring vertices
    check_id_space(f"{cls.__name__} with a ring of {int(m):,} vertices (corner ids 8 m_r + 4 n0)", 8 * int(m))
    dmask = np.zeros(nv, bool) if dummy is None else np.asarray(dummy, bool)
    p = lr_pack.pack_common(V, O, vertex_corner, tb, dmask, quad_check=check)
    if p["bad_quad"] is not None:
        i, w = p["bad_quad"]
        raise errors.StructureError(
            f"LR: quad opposite of corner {8 * w + i} (ring vertex {w}) is wrong")
    nv_real, nf_real, n0 = p["nv_real"], p["nf_real"], int(p["t0"].size)
    check_id_space(f"{cls.__name__} with a ring of {m:,} vertices and {n0:,} T0 triangles "
                   "(corner ids 8 m_r + 4 n0)", 8 * int(m) + 4 * n0)
    irl, irr = p["irl"], p["irr"]
    words, rank, nring_faces = lr_pack.directory(p["hidden"])
    order = p["order"]
    common = dict(V0=_dev(p["V0"]), O0=_dev(p["O0"]), C=_dev(p["C"]),
                  slot_words=_dev(words), slot_rank=_dev(rank),
                  order=_dev(order[:nv_real]), num_vertices=nv_real, num_faces=nf_real,
                  num_ring=int(m), num_t0=n0, num_ring_faces=int(nring_faces),
                  num_closed_vertices=int(nv), num_closed_faces=int(nf))
    if cls is LR:
        L, R, vos = lr_pack.pack_lr(p["E"], irl, irr, p["truth"])
        s = LR(L=_dev(L), R=_dev(R), VOs=_dev(_nonempty(vos)),
               num_vos=int(vos.size), **common)
    else:
        lr16, vos, num_vos, nlong = lr_pack.pack_lr_bits(p["E"], irl, irr, p["truth"])
        if nlong < 0:
            raise errors.UnsupportedTopologyError("lr-bits: VO* exceeds the 26-bit long index")
        s = LRBits(LR16=_dev(lr16), VOs=_dev(vos), num_vos=int(num_vos),
                   num_long=int(nlong), k=int(k), **common)
    lrc, new_of_old = p["lrc"], p["new_of_old"]
    object.__setattr__(s, "_stats", dict(tb.stats(nf, nf_real), unexpected_irregular=p["unexpected"],
                                         irregular=int(irl.sum()) + int(irr.sum()), seed=tb.ring.seed,
                                         ring_search_gain=tb.ring.search_gain,
                                         _lrc=lrc, _new_of_old=new_of_old))
    s._stats.update(m_i=nv_real - m, m_dummy=int(nv - nv_real), n=nf_real)
    if check:
        _check(s, V, O, lrc, new_of_old)
    return s


def _check_against(s, ct: CornerTable):
    st = s._stats
    _check(s, np.asarray(ct.V), np.asarray(ct.O), st["_lrc"], st["_new_of_old"])


def _check(s, V, O, lrc, new_of_old):
    """Invariant check at construction (typed error): ``c.v`` and ``c.o`` of every canonical
    corner equal the corner table's. One linear numba pass that decodes the packed arrays exactly
    as the jitted operators do (:func:`jaxcds.construct.lr_pack.check_lr`; the tests compare that
    decoder with the operators on every corner)."""
    if isinstance(s, LR):
        nbad, j, gv, go = lr_pack.check_lr(np.asarray(s.L), np.asarray(s.R), np.asarray(s.VOs),
                                           np.asarray(s.V0), np.asarray(s.O0), s.num_t0, V, O,
                                           lrc, new_of_old)
    else:
        nbad, j, gv, go = lr_pack.check_lr_bits(np.asarray(s.LR16), np.asarray(s.VOs),
                                                np.asarray(s.V0), np.asarray(s.O0), s.num_ring,
                                                s.num_t0, V, O, lrc, new_of_old)
    if nbad:
        j = int(j)
        raise errors.StructureError(
            f"{s.name}: corner {int(lrc[j])} (corner-table corner {j}) has "
            f"c.v={int(gv)}, c.o={int(go)}, expected {int(new_of_old[V[j]])}, "
            f"{int(lrc[O[j]])}; {int(nbad)} corners wrong")


def stats(s) -> dict:
    """Construction statistics of an LR built by :func:`build_lr` (Table 1 quantities)."""
    return {k: v for k, v in getattr(s, "_stats", {}).items() if not k.startswith("_")}


# --------------------------------------------------------------------------------- Sec. 7
def render_list(s: LR) -> dict:
    """The renderable index list of Sec. 7: one vertex reference per ring slot (ring vertices
    implicit), a wart-skip bit per slot, T0 triangles verbatim; redundant T2 copies become
    degenerate (tip ``v``). Vertex ids are the LR's (``positions[s.vertex_order]``).

    Returns ``{"apex": (2 m_r,) int32, "skip": (2 m_r,) bool, "t0": (n0, 3) int32, "rpt": float}``."""
    if not isinstance(s, (LR, LRBits)):  # an AttributeError about num_ring before
        raise errors.ArgumentError(f"render_list: expected an LR or LRBits structure "
                                   f"(jaxcds.build('lr', mesh)), got {type(s).__name__}")
    m = s.num_ring
    v = jnp.arange(m, dtype=jnp.int32)
    d = s._dec(v)
    red = np.asarray(s._redundant_slot(jnp.arange(2 * m, dtype=jnp.int32)))
    apex = np.empty(2 * m, np.int32)
    apex[0::2] = np.asarray(d.l)
    apex[1::2] = np.asarray(d.r)
    vv = np.repeat(np.arange(m, dtype=np.int32), 2)
    # redundant T2 copies and dummy triangles (apex = a dummy vertex, null index) become
    # degenerate: tip = v (Sec. 7)
    apex = np.where(red | (apex >= s.num_vertices), vv, apex)
    skip = np.empty(2 * m, bool)
    skip[0::2] = np.asarray(d.skl) == 1
    skip[1::2] = np.asarray(d.skr) == 1
    t0 = np.asarray(s.V0)[: 3 * s.num_t0].reshape(-1, 3)
    t0 = t0[(t0 < s.num_vertices).all(axis=1)]
    refs = 2 * m + 3 * t0.shape[0]
    return {"apex": apex, "skip": skip, "t0": t0, "rpt": refs / max(s.num_faces, 1)}


def expand_render_list(rl: dict) -> np.ndarray:
    """Triangles ``(F, 3)`` of a :func:`render_list` (what a geometry shader would emit),
    degenerate redundant copies dropped."""
    apex, skip, t0 = rl["apex"], rl["skip"], rl["t0"]
    m = apex.size // 2
    v = np.arange(m)
    nxt = np.where(skip.reshape(m, 2), (v[:, None] + 2) % m, (v[:, None] + 1) % m)
    left = np.stack([v, apex[0::2], nxt[:, 0]], axis=1)
    right = np.stack([nxt[:, 1], apex[1::2], v], axis=1)
    tri = np.empty((2 * m, 3), np.int64)
    tri[0::2] = left
    tri[1::2] = right
    keep = ~((tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2]) | (tri[:, 0] == tri[:, 2]))
    return np.concatenate([tri[keep], np.asarray(t0, np.int64)]).astype(np.int32)


_RENDER_SKIP = 1 << _SKIP_BIT  # the dedicated wart-skip bit of a slot's tip reference (Sec. 7)


def renderable_index_list(s) -> tuple:
    """The renderable index list of Sec. 7 as one flat ``int32`` array, and its statistics.

    ``indices[:2 m_r]`` is one tip reference per ring slot (slot ``2v`` = ``v.t_L``, ``2v + 1`` =
    ``v.t_R``; the ring vertices ``v, v.n`` are implicit), with bit 29 set for a wart-skipping
    T0^w slot (its ring vertex ``v.n`` is then ``v.n.n``); redundant T2 copies and triangles across
    a border get the tip ``v`` (degenerate, dropped when expanded). ``indices[2 m_r:]`` holds the
    remaining (real) T0 triangles verbatim, three references each. Vertex ids are the structure's
    (``positions[s.vertex_order]``). Works for ``LR`` and ``LRBits``.

    Returns ``(indices, stats)``, ``stats`` with ``num_ring``, ``num_t0``, ``references``,
    ``num_triangles`` (real faces), ``degenerate`` (slots holding no triangle) and ``rpt``
    (references per triangle; the paper reports a mean of 1.03 with wart skips, 1.10 without).
    Not jittable (sizes depend on the data); see :func:`expand_renderable_index_list`."""
    rl = render_list(s)
    m = s.num_ring
    tips = rl["apex"].astype(np.int64) | np.where(rl["skip"], _RENDER_SKIP, 0)
    t0 = np.asarray(rl["t0"], np.int64).ravel()
    indices = np.concatenate([tips, t0]).astype(np.int32)
    degenerate = int(np.sum(rl["apex"] == np.repeat(np.arange(m), 2)))
    st = {"num_ring": int(m), "num_t0": int(t0.size // 3), "references": int(indices.size),
          "num_triangles": int(s.num_faces), "degenerate": degenerate,
          "rpt": indices.size / max(int(s.num_faces), 1)}
    return indices, st


def expand_renderable_index_list(indices, num_ring: int) -> np.ndarray:
    """``(F, 3)`` int32 triangles (counter-clockwise) of a :func:`renderable_index_list`: what a
    geometry shader would emit for it (Sec. 7), degenerate slots dropped. Slot ``2v`` gives
    ``(v, tip, v.n)``, slot ``2v + 1`` gives ``(v.n, tip, v)`` (Fig. 5), ``v.n`` skipping the wart
    tip when the slot's bit 29 is set."""
    indices = np.asarray(indices, np.int64)
    m = int(num_ring)
    if indices.size < 2 * m or (indices.size - 2 * m) % 3:
        raise errors.StructureError(
            f"renderable index list: {indices.size} references cannot hold {2 * m} ring slots "
            "followed by whole T0 triangles")
    tips = indices[: 2 * m]
    rl = {"apex": tips & ~np.int64(_RENDER_SKIP), "skip": (tips & _RENDER_SKIP) != 0,
          "t0": indices[2 * m:].reshape(-1, 3)}
    return expand_render_list(rl)


# --------------------------------------------------------------------------------- registry
def _register():
    from jaxcds.structures import registry

    registry.register("lr", lambda mesh: LR.from_mesh(mesh), closes_boundaries=True,
                      description="Laced Ring (Gurung et al. 2011), ~1.08 refs/triangle; any genus")
    registry.register("lr-bits", lambda mesh: LRBits.from_mesh(mesh), closes_boundaries=True,
                      description="bit-efficient LR (Sec. 6), 16-bit offsets, ~26 bits/triangle")


_register()
