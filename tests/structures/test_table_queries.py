"""Batches as large as a fraction of the mesh: the CDS family answers Target, Origin,
Face_left / Face_right and Next / Prev (the Fronts and Backs) from a whole-mesh table computed once per call
(``MeshStructure.table_queries``); smaller batches run the paper's per-query operator (Thm 2's
walk, Thm 6's two reads, Thm 7's slot rules, Thm 2's Back cases). Both routes give the same
answers on every dart; :func:`jaxcds.verify.verify` checks both against the half-edge on every
dart of every shared mesh (``test_protocol.py``), and catches either route when it is wrong."""

from __future__ import annotations

import contextlib
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from jaxcds.generators import random_planar_triangulation
from jaxcds.structures import base, registry
from jaxcds.verify import verify

KINDS = ["cds6n", "cds5n-o1", pytest.param("cds5n", marks=pytest.mark.slow),
         pytest.param("cds4n", marks=pytest.mark.slow)]
OPS = ("target", "origin", "source", "face", "face_left", "face_right", "next", "prev",
       "left_front", "left_back", "right_front", "right_back")


@pytest.fixture(scope="module")
def mesh():
    return random_planar_triangulation(300, seed=5)


def _answers(s, ids, per_query: bool, ops=OPS):
    # a fresh jit per call: the route is chosen at trace time; the operators' common searches
    # traced once (pemb's, as verify does: half the compile time)
    def run(s, d):
        with (base.per_query_routes() if per_query else contextlib.nullcontext()), \
                base.shared_subexpressions():
            return tuple(getattr(s, op)(d) for op in ops)
    return [np.asarray(x) for x in jax.jit(run)(s, ids)]


@pytest.fixture
def fresh_traces():
    """The tests that patch a class re-trace: ``verify``'s jitted programs are cached per
    structure type and shape, not per class attribute."""
    jax.clear_caches()
    yield
    jax.clear_caches()


class _Spy:
    """Counts the calls of a class's table routes (at trace time)."""

    def __init__(self, cls, monkeypatch):
        self.calls = 0
        for name in set(cls.table_queries.values()):
            inner = getattr(cls, name)

            def spied(s, d, inner=inner):
                self.calls += 1
                return inner(s, d)
            monkeypatch.setattr(cls, name, spied)


@pytest.mark.parametrize("kind", KINDS)
def test_table_route_equals_per_query_route(kind, mesh):
    s = registry.build(kind, mesh)
    assert set(type(s).table_queries) == {"target", "origin", "face", "face_left", "face_right",
                                          "next", "prev", "left_front", "left_back",
                                          "right_front", "right_back"}
    assert all(type(s).table_ratio(op) <= 1 for op in type(s).table_queries)  # all darts: tables
    darts = s.all_darts()
    for ids in (darts, np.resize(darts, (3, darts.size))):
        by_table, per_query = _answers(s, ids, False), _answers(s, ids, True)
        for op, a, b in zip(OPS, by_table, per_query):
            assert a.shape == ids.shape
            np.testing.assert_array_equal(a, b, err_msg=f"{kind}.{op}")


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("op, alias", [("target", "source"), ("face_left", "face_right"),
                                       ("next", "right_back"), ("prev", "right_front")])
def test_the_route_follows_the_batch_size(kind, op, alias, mesh, monkeypatch):
    """The table from ``ceil(table_ratio(op) * num_darts)`` ids up, not one id fewer, not
    under ``per_query_routes``, not for ids passed by keyword (Target); ``alias`` (Source: Origin;
    Face_right: the twin's face) likewise."""
    s = registry.build(kind, mesh)
    cls = type(s)
    spy = _Spy(cls, monkeypatch)
    at = math.ceil(cls.table_ratio(op) * s.num_darts)
    assert at == math.ceil(cls.table_ratio({"source": "origin"}.get(alias, alias)) * s.num_darts)
    darts = jnp.asarray(np.resize(s.all_darts(), at))
    jax.jit(lambda s, d: getattr(s, op)(d))(s, darts)
    assert spy.calls == 1
    jax.jit(lambda s, d: getattr(s, op)(d))(s, darts[:-1])
    assert spy.calls == 1
    with base.per_query_routes():
        jax.jit(lambda s, d: getattr(s, op)(d))(s, darts)
    if op == "target":  # (Face_left by keyword calls Face with the ids positionally)
        s.target(d=darts)
    assert spy.calls == 1
    jax.jit(lambda s, d: getattr(s, alias)(d))(s, darts)
    assert spy.calls == 2



def test_eager_calls_follow_per_query_routes(monkeypatch, fresh_traces):
    """An eager call runs a cached jitted program per power-of-two batch size
    (``base._bucketed``); inside ``per_query_routes`` it is the per-query route's program,
    whichever route an earlier eager call compiled (sweep 48: the table route's was reused)."""
    from jaxcds.structures.cds import CDS6n

    s = registry.build("cds6n", random_planar_triangulation(60, seed=1))
    d = s.all_darts()
    with base.per_query_routes():
        want = np.asarray(jax.jit(lambda s, d: s.target(d))(s, d))
    real = CDS6n._edge_target_table
    monkeypatch.setattr(CDS6n, "_edge_target_table",
                        lambda self: (real(self) + 1) % self.num_vertices)  # a broken table
    assert not np.array_equal(np.asarray(s.target(d)), want)  # eager: the table route
    with base.per_query_routes():
        np.testing.assert_array_equal(np.asarray(s.target(d)), want)

def test_each_operator_has_its_own_threshold():
    """CDS6n's Face_left table pays from half the darts (its per-query Fronts are single
    reads), its Target table from 1/16; CDS5n-O(1)'s Target (Thm 6, O(1)) from half."""
    from jaxcds.structures.cds import CDS5n, CDS5nO1, CDS6n

    assert CDS6n.table_ratio("target") < CDS6n.table_ratio("face_left") <= 1
    assert CDS5nO1.table_ratio("target") > CDS5n.table_ratio("target")
    assert CDS5n.table_ratio("face_left") == CDS5nO1.table_ratio("face_left") < 1
    assert CDS6n.table_ratio("twin") == math.inf  # not a table operator (one xor)


@pytest.mark.parametrize("ratio", [0.0, math.inf])
def test_every_class_ratio_gives_the_half_edge_answers(ratio, monkeypatch, fresh_traces):
    """The ratio set to always / never take the table: ``verify`` finds no mismatch either way."""
    m = random_planar_triangulation(120, seed=2)
    s = registry.build("cds6n", m)
    monkeypatch.setattr(type(s), "table_batch_ratio", ratio)
    rep = verify(s, m)
    assert rep.mismatches == 0, str(rep)


# (method to break, how, operators verify must flag, operators it must not): a broken table
# shows up as a per-query route that disagrees with the table's answers; a broken per-query
# route likewise, and the table route's answers stay right
_BREAKS = {
    "target table": ("_edge_target_table", lambda real: lambda self: (real(self) + 1) % self.num_vertices,
                     ["target (per-query route)"], []),
    "per-query target": ("_dart_end", lambda real: lambda self, d, t: real(self, d, t) + 1,
                         ["target (per-query route)"], ["dart_exists"]),
    "face table": ("dart_faces", lambda real: lambda self: (real(self) + 1) % self.num_faces,
                   ["face_left (per-query route)", "face_right (per-query route)"], []),
    "per-query face": ("face_slot", lambda real: lambda self, d: real(self, d ^ 1),
                       ["face_left (per-query route)"], ["face_left"]),
    "step tables": ("_step_table", lambda real: lambda self, forward: real(self, forward) ^ 1,
                    [f"{op} (per-query route)" for op in ("next", "prev", "left_front", "right_back")],
                    []),
}


@pytest.mark.parametrize("case", list(_BREAKS))
def test_verify_catches_a_wrong_route(case, monkeypatch, fresh_traces):
    """A broken table route and a broken per-query route each show up in ``verify``."""
    m = random_planar_triangulation(120, seed=2)
    s = registry.build("cds5n-o1", m)
    method, breaker, flagged, clean = _BREAKS[case]
    monkeypatch.setattr(type(s), method, breaker(getattr(type(s), method)))
    rep = verify(s, m)
    for op in flagged:
        assert rep.by_operator.get(op, 0) > 0, (op, str(rep))
    for op in clean:
        assert rep.by_operator.get(op, 0) == 0, (op, str(rep))


def test_packed_batches_take_no_table_route(monkeypatch):
    """A packed union's entries take mesh-local ids: no whole-union table there."""
    from jaxcds.batch import pack

    meshes = [random_planar_triangulation(n, seed=k) for k, n in enumerate((60, 90))]
    s = pack(meshes, "cds6n").structure
    assert type(s).table_queries == {}
    assert registry.build("cds6n", meshes[0]).table_queries


@pytest.mark.slow
@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(4, 2000), seed=st.integers(0, 2**31 - 1))
def test_both_routes_on_random_triangulations(n, seed):
    m = random_planar_triangulation(n, seed=seed)
    for kind in ("cds6n", "cds5n", "cds4n", "cds5n-o1"):
        s = registry.build(kind, m)
        d = s.all_darts()
        for op, a, b in zip(OPS, _answers(s, d, False), _answers(s, d, True)):
            np.testing.assert_array_equal(a, b, err_msg=f"{kind}.{op} n={n} seed={seed}")


# ------------------------------------------------------------------------------------ pemb
PEMB_OPS = ("target", "origin", "twin", "next", "prev", "face", "is_border", "ccw_vertex_edge",
            "cw_vertex_edge")


@pytest.mark.parametrize("packed", [False, True], ids=["one", "packed"])
def test_pemb_tables_route_equals_its_searches(packed):
    """pemb answers batches of a few darts' worth of ids from per-call tables (one
    ``match_all``, then gathers) instead of a parenthesis search per id: the same answers on
    every dart, of one pemb with a border and of a packed union (global ids)."""
    from jaxcds.batch import pack
    from jaxcds.generators import delaunay_square

    meshes = [delaunay_square(150, seed=3), random_planar_triangulation(90, seed=4)]
    s = pack(meshes, "pemb").structure if packed else registry.build("pemb", meshes[0])
    assert set(type(s).table_queries) == set(PEMB_OPS)
    darts = np.tile(s.all_darts(), 4)  # four times the darts: every operator takes its table
    assert all(s.takes_table(op, darts.size) for op in PEMB_OPS)
    for op, a, b in zip(PEMB_OPS, _answers(s, darts, False, PEMB_OPS), _answers(s, darts, True, PEMB_OPS)):
        np.testing.assert_array_equal(a, b, err_msg=f"pemb.{op}")


def test_pemb_is_border_takes_its_table_route(monkeypatch):
    """pemb declares a table route for ``is_border`` (``table_queries``, ratio 1) but the
    operator was not among ``base.CHUNKED_QUERIES``, whose wrapper takes the table routes: a
    whole-mesh batch searched per dart. Traced only (``eval_shape``), nothing compiled."""
    from jaxcds.structures.pemb import PEMB

    s = registry.build("pemb", random_planar_triangulation(30, seed=2))
    taken = []
    real = PEMB._tabled_is_border

    def counted(self, d):
        taken.append(d.shape)
        return real(self, d)

    monkeypatch.setattr(PEMB, "_tabled_is_border", counted)
    darts = jnp.arange(s.num_darts, dtype=jnp.int32)
    assert s.takes_table("is_border", darts.size)
    jax.eval_shape(lambda s, d: s.is_border(d), s, darts)
    assert taken == [(s.num_darts,)]
    with base.per_query_routes():
        jax.eval_shape(lambda s, d: s.is_border(d), s, darts[:8])
    assert len(taken) == 1


def test_pemb_loops_navigate_its_tables(monkeypatch):
    """A loop that asks many ids (``adjacent``, ``one_ring``) builds pemb's tables once, before
    it (``for_queries``), not in every step; a small batch keeps the searches. Same answers."""
    from jaxcds.algorithms import adjacency
    from jaxcds.structures.pemb import PEMB

    m = random_planar_triangulation(400, seed=6)
    s = registry.build("pemb", m)
    built = []
    real = PEMB.with_tables

    def counted(self, **kw):
        built.append(kw)
        return real(self, **kw)

    monkeypatch.setattr(PEMB, "with_tables", counted)
    assert s.for_queries(8) is s
    rng = np.random.default_rng(1)
    u, v = (jnp.asarray(rng.integers(0, m.num_vertices, 2000), jnp.int32) for _ in range(2))
    vs = jnp.arange(400, dtype=jnp.int32)

    def run():  # fresh functions: jit's cache does not know the per-query flag
        adj = jax.jit(lambda s, u, v: adjacency._adjacent.__wrapped__(s, u, v))(s, u, v)
        ring = jax.jit(lambda s, v: adjacency._one_ring.__wrapped__(s, v, 12))(s, vs)[0]
        return np.asarray(adj), np.asarray(ring)

    with base.per_query_routes():
        want = run()
    assert built == []
    got = run()
    assert len(built) == 2  # once per program, not once per step
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a, b)


# -------------------------------------------------------------------------------------- LR
LR_OPS = ("target", "twin", "face_right", "right_front", "right_back", "corner_opposite")


@pytest.mark.parametrize("kind", ["lr", "lr-bits"])
def test_lr_id_tables_equal_its_decoding(kind):
    """LR answers a batch of twice the darts' worth of ids or more from every dart's answer,
    computed once (``base.id_table_route``), where each id decodes an opposite corner: the same
    answers, on a mesh with a border too; a packed union takes no such route."""
    from jaxcds.batch import pack
    from jaxcds.generators import delaunay_square

    m = delaunay_square(200, seed=7)
    s = registry.build(kind, m)
    assert set(type(s).table_queries) == set(LR_OPS)
    darts = np.tile(s.all_darts(), -(-2 * s.num_darts // s.all_darts().size))
    assert s.takes_table("target", darts.size) and not s.takes_table("target", s.num_darts)

    got, want = _answers(s, darts, False, LR_OPS), _answers(s, darts, True, LR_OPS)
    for op, a, b in zip(LR_OPS, got, want):
        np.testing.assert_array_equal(a, b, err_msg=f"{kind}.{op}")
    assert pack([m, random_planar_triangulation(50, seed=1)], kind).structure.table_queries == {}
