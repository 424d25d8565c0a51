"""verify() itself: it finds a wrong operator, and it compiles each of its programs once, ahead,
on worker threads (stop 55: pemb on the bunny 43-48 -> 32 s on 2 cores)."""
import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest

from jaxcds import verify as V
from jaxcds.generators import random_planar_triangulation
from jaxcds.structures import registry


def test_verify_names_a_wrong_operator_and_its_dart():
    """A half-edge whose ``next`` of two darts is swapped: verify reports mismatches under
    ``next`` (and the operators built on it), with an example dart, and is not ok. (Darts are
    compared by their ``(origin, target)``, and Target is the origin of Next: the darts named
    are those whose meaning moved, not only the two edited.)"""
    m = random_planar_triangulation(30, seed=1)
    s = registry.build("halfedge", m)
    nxt = np.asarray(s.next_).copy()
    nxt[[0, 3]] = nxt[[3, 0]]  # darts 0 and 3 lie in different faces
    bad = dataclasses.replace(s, next_=jnp.asarray(nxt))
    rep = V.verify(bad, m)
    assert not rep.ok and rep.by_operator["next"] > 0 and rep.mismatches >= rep.by_operator["next"]
    assert rep.examples["next"].startswith("dart [") and "next" in str(rep)
    assert V.verify(s, m).ok  # the same check passes on the structure as built


# pemb's programs take 34 s to compile in CI (the quick set keeps lr-bits: table routes too)
@pytest.mark.parametrize("kind", ["lr-bits", pytest.param("pemb", marks=pytest.mark.slow)])
def test_verify_compiles_every_program_ahead_and_once(kind, monkeypatch):
    """Every program verify runs is compiled by ``_compile_ahead`` (chunks of two sizes
    included): none compiles after it, and a second verify compiles nothing. A program warmed
    with arguments of another shape or dtype than the later call would compile twice."""
    m = random_planar_triangulation(37, seed=4)
    s = registry.build(kind, m)
    programs = (V._apply_all, V._endpoints, V._other_routes, V._whole_mesh)
    after_ahead = {}
    compile_ahead = V._compile_ahead

    def recorded(todo):
        results = compile_ahead(todo)
        after_ahead.update({f: f._cache_size() for f in programs})
        return results

    monkeypatch.setattr(V, "_compile_ahead", recorded)
    monkeypatch.setattr(V.os, "cpu_count", lambda: 2)  # threads even on a 1-core runner
    chunk = 100
    assert s.num_darts % chunk  # a last chunk of another size
    assert V.verify(s, m, chunk=chunk).ok
    assert {f: f._cache_size() for f in programs} == after_ahead
    assert V.verify(s, m, chunk=chunk).ok
    assert {f: f._cache_size() for f in programs} == after_ahead


def test_verify_compiles_nothing_ahead_under_disable_jit(monkeypatch):
    """Under ``jax.disable_jit()`` verify runs op by op: no worker threads compiling programs
    it would not use (sweep 55a: JAX's settings blocks are per thread, so workers compiled)."""
    import jax

    def no_pool(*args, **kwargs):
        raise AssertionError("a thread pool under disable_jit")

    monkeypatch.setattr(V, "ThreadPoolExecutor", no_pool)
    monkeypatch.setattr(V.os, "cpu_count", lambda: 2)
    m = random_planar_triangulation(6, seed=0)
    s = registry.build("halfedge", m)
    with jax.disable_jit():
        assert V.verify(s, m, adjacency_samples=10).ok
    with pytest.raises(AssertionError, match="a thread pool"):
        V.verify(s, m)  # the pool is asked for where jit is on
