"""Large batched queries run by chunks on CPU (``base._chunked_query``): the chunked answers equal
the one-pass answers for every operator a class chunks, on every dart (as a flat batch that is
not a multiple of the chunk, and as a 2-D batch), with the chunk size forced small so the small
test meshes reach the chunked path."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from jaxcds.generators import random_planar_triangulation
from jaxcds.structures import base, registry

KINDS = ["cds6n", "cds5n-o1", "lr", pytest.param("cds5n", marks=pytest.mark.slow),
         pytest.param("cds4n", marks=pytest.mark.slow), pytest.param("lr-bits", marks=pytest.mark.slow)]


@pytest.fixture(scope="module")
def mesh():
    return random_planar_triangulation(300, seed=4)


def _loops(fn, ids) -> int:
    """Loops in the traced program (a ``fori_loop`` of static length is a ``scan``), not counting
    the one-trip loops of ``base.materialize_loop`` (materialisation points, not navigation)."""
    def count(jaxpr):
        k = 0
        for eqn in jaxpr.eqns:
            if eqn.params.get("name") == "materialize_loop":
                continue
            k += eqn.primitive.name in ("while", "scan")
            for v in eqn.params.values():
                for sub in (v if isinstance(v, (tuple, list)) else (v,)):
                    inner = getattr(sub, "jaxpr", sub)
                    if hasattr(inner, "eqns"):
                        k += count(inner)
        return k
    return count(jax.make_jaxpr(fn)(ids).jaxpr)


def _has_loop(fn, ids) -> bool:
    return _loops(fn, ids) > 0


def _answers(s, ops, ids):
    # jitted, as users run them; a fresh trace per chunk size (the size is read at trace time).
    # The per-query routes: a batch of every dart would take the CDS family's whole-mesh table
    # for Target/Origin (test_table_queries.py), which runs no chunks
    def run(s, d, op):
        with base.per_query_routes():
            return getattr(s, op)(d)
    return {op: np.asarray(jax.jit(run, static_argnums=2)(s, ids, op)) for op in ops}


@pytest.mark.parametrize("kind", KINDS)
def test_chunked_answers_equal_one_pass(kind, mesh, monkeypatch):
    s = registry.build(kind, mesh)
    ops = sorted(type(s).chunked_queries)
    assert ops, f"{kind} chunks no operator"
    darts = s.all_darts()
    assert darts.size > 4 * 37
    assert darts.size % 37  # a remainder after the last whole chunk
    batches = [darts, np.resize(darts, (37 * 3, 5))]
    for ids in batches:
        monkeypatch.setattr(base, "QUERY_CHUNK", 1 << 30)  # one pass
        want = _answers(s, ops, ids)
        monkeypatch.setattr(base, "QUERY_CHUNK", 37)
        got = _answers(s, ops, ids)
        # each chunk's answers fused into the output's in-place update (the raced alternative)
        monkeypatch.setattr(base, "WRITE_CHUNK_ANSWERS_APART", False)
        fused = _answers(s, ops, ids)
        monkeypatch.setattr(base, "WRITE_CHUNK_ANSWERS_APART", True)
        for op in ops:
            assert got[op].shape == ids.shape
            np.testing.assert_array_equal(got[op], want[op], err_msg=f"{kind}.{op}")
            np.testing.assert_array_equal(fused[op], want[op], err_msg=f"{kind}.{op} (fused)")


def test_chunking_is_really_used_and_only_for_the_named_operators(mesh, monkeypatch):
    """The program of a chunked operator has a loop over the chunks; one of an operator the
    class does not name (LR ``next``: one gather) has none, nor has the half-edge's."""
    monkeypatch.setattr(base, "QUERY_CHUNK", 37)
    s = registry.build("lr", mesh)
    d = s.all_darts()
    assert _has_loop(lambda d: s.target(d), d)
    assert not _has_loop(lambda d: s.next(d), d)
    half = registry.build("halfedge", mesh)
    assert not _has_loop(lambda d: half.target(d), half.all_darts())
    monkeypatch.setattr(base, "QUERY_CHUNK", 1 << 30)
    assert not _has_loop(lambda d: s.target(d), d)


def test_one_pass_block_turns_chunking_off(mesh, monkeypatch):
    monkeypatch.setattr(base, "QUERY_CHUNK", 37)
    s = registry.build("lr", mesh)
    d = s.all_darts()
    with base.one_pass_queries():
        assert not _has_loop(lambda d: s.target(d), d)
    assert _has_loop(lambda d: s.target(d), d)


@pytest.mark.parametrize("kind", ["cds5n-o1", "lr", pytest.param("cds6n", marks=pytest.mark.slow),
                                  pytest.param("lr-bits", marks=pytest.mark.slow)])
def test_packed_batches_chunk_their_queries_too(kind, monkeypatch):
    """A packed union chunks the operators of its class (each chunk finds its elements' meshes
    and builds its own view): same answers as one pass, on every dart of the union."""
    from jaxcds.batch import pack

    meshes = [random_planar_triangulation(n, seed=k) for k, n in enumerate((60, 150, 90))]
    s = pack(meshes, kind).structure
    ops = sorted(type(s).chunked_queries)
    assert ops == sorted(registry.build(kind, meshes[0]).chunked_queries)
    d = s.all_darts()
    assert d.size % 37
    monkeypatch.setattr(base, "QUERY_CHUNK", 1 << 30)
    want = _answers(s, ops, d)
    one_pass_loops = _loops(lambda d: s.target(d), d)
    monkeypatch.setattr(base, "QUERY_CHUNK", 37)
    assert _loops(lambda d: s.target(d), d) == one_pass_loops + 1  # the chunk loop
    got = _answers(s, ops, d)
    for op in ops:
        np.testing.assert_array_equal(got[op], want[op], err_msg=f"packed {kind}.{op}")


def test_ids_by_keyword_run_in_one_pass(mesh, monkeypatch):
    monkeypatch.setattr(base, "QUERY_CHUNK", 37)
    s = registry.build("lr", mesh)
    d = s.all_darts()
    # LR's twin is chunked and calls no chunked operator
    np.testing.assert_array_equal(np.asarray(s.twin(e=d)), np.asarray(s.twin(d)))
    assert _has_loop(lambda d: s.twin(d), d) and not _has_loop(lambda d: s.twin(e=d), d)


def test_answers_written_apart_only_where_the_class_names_them(mesh, monkeypatch):
    """CDS5n-O(1) Target writes each chunk's answers apart (one more materialize_loop per
    chunk); LR's Target (not named) keeps the fused write."""
    monkeypatch.setattr(base, "QUERY_CHUNK", 37)

    def loops_written(kind, apart):
        s = registry.build(kind, mesh)
        monkeypatch.setattr(base, "WRITE_CHUNK_ANSWERS_APART", apart)
        with base.per_query_routes():  # every dart: the table route otherwise (no chunks)
            return str(jax.make_jaxpr(lambda d: s.target(d))(s.all_darts())).count("name=materialize_loop")

    assert "target" in registry.build("cds5n-o1", mesh).chunk_answers_apart
    assert loops_written("cds5n-o1", True) == loops_written("cds5n-o1", False) + 1
    assert loops_written("lr", True) == loops_written("lr", False)
