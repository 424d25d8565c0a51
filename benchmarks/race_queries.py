"""Batched queries of several structures raced in turn: every compiled program runs once per
round, rounds repeated, min and median reported (ns per query).

Why a second query benchmark beside ``bench_cds``: ``bench_cds`` times each structure's ops in
sequence, and on this shared 2-core box a program timed after others (other structures built,
other buffers freed) can read 1.5x slower than the same program timed alone. Racing the routes in
turn puts them under the same conditions. Example (the CDS5n-O(1) Target against the half-edge,
``RESULTS.md``, "CDS: materialisation loop")::

    flock /tmp/jaxcds_big.lock .venv/bin/python benchmarks/race_queries.py \\
        --vertices 2500000 --queries 10000000 --structures halfedge cds5n-o1 --ops target
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks.script_errors import at_least_one, clean_exit  # noqa: E402

from benchmarks.paired import paired_summary  # noqa: E402
from jaxcds.algorithms import adjacent  # noqa: E402
from jaxcds.generators import random_planar_triangulation  # noqa: E402
from jaxcds.structures import registry  # noqa: E402
from jaxcds.structures.base import MeshStructure, per_query_routes  # noqa: E402


def race(items, n_items: int, rounds: int) -> dict:
    """``items``: ``(name, fn, args)``. AOT-compile each, warm up once, then run every program
    once per round for ``rounds`` rounds; returns ``{name: (min, median)}`` in ns per item."""
    times = race_times(items, rounds)
    return {k: (min(v) / n_items * 1e9, float(np.median(v)) / n_items * 1e9) for k, v in times.items()}


def race_times(items, rounds: int) -> dict:
    """:func:`race`'s ``{name: [seconds per round]}``, the rounds aligned across names."""
    compiled = []
    for name, fn, args in items:
        c = jax.jit(fn).lower(*args).compile()
        jax.block_until_ready(c(*args))
        compiled.append((name, c, args))
    times = {name: [] for name, _, _ in compiled}
    for _ in range(rounds):
        for name, c, args in compiled:
            t0 = time.perf_counter()
            jax.block_until_ready(c(*args))
            times[name].append(time.perf_counter() - t0)
    return times


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vertices", type=int, default=100_000)
    ap.add_argument("--queries", type=int, default=1_000_000)
    ap.add_argument("--structures", nargs="+", default=["halfedge", "cds5n-o1"])
    ap.add_argument("--ops", nargs="+", default=["target"], help="dart operators (target, origin, "
                    "face_left, next, ...) or adjacent (vertex pairs: half of them edges)")
    ap.add_argument("--rounds", type=at_least_one, default=7)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--target", type=float, default=2.0, help="ratio against the first structure's "
                    "same op that the paired verdict is against (issue 3: 2x the half-edge)")
    ap.add_argument("--per-query", action="store_true", help="also race the per-query route of "
                    "each op that the structure answers from a whole-mesh table for batches this "
                    "large (MeshStructure.table_queries; adjacent: the loop on tables, "
                    "MeshStructure.for_queries), named 'NAME OP/per-query', and pair the two routes")
    ap.add_argument("--table-ratio", type=float, default=None, help="override each structure's "
                    "table_batch_ratio while tracing (0: the table route for any batch size; "
                    "the threshold sweeps of RESULTS 'stop 33')")
    a = ap.parse_args(argv)
    mesh = random_planar_triangulation(a.vertices, seed=1)
    rng = np.random.default_rng(a.seed)
    items = []
    for name in a.structures:
        s = registry.build(name, mesh)
        d = random_darts(s, rng, a.queries)
        for op in a.ops:
            if op == "adjacent":
                pairs = (s,) + random_pairs(s, rng, a.queries)
                items.append((f"{name} {op}", adjacent, pairs))
                if a.per_query and type(s).for_queries is not MeshStructure.for_queries:
                    items.append((f"{name} {op}/per-query", per_query_adjacent, pairs))
            elif callable(getattr(s, op, None)):
                items.append((f"{name} {op}", with_table_ratio(op, a.table_ratio), (s, d)))
                if a.per_query and op in s.table_queries:
                    items.append((f"{name} {op}/per-query", per_query(op), (s, d)))
            else:
                ap.error(f"--ops {op}: {name} has no dart operator {op!r} (nor is it 'adjacent')")
    times = race_times(items, a.rounds)
    res = {k: (min(v) / a.queries * 1e9, float(np.median(v)) / a.queries * 1e9) for k, v in times.items()}
    report(res, a.vertices, a.queries, a.rounds)
    first = a.structures[0]
    for k, v in times.items():
        name, op = k.split(" ", 1)
        op = op.split("/")[0]
        if name != first or k != f"{first} {op}":
            print(f"{k} / {first} {op}: {paired_summary(v, times[f'{first} {op}'], a.target)}")
        if k.endswith("/per-query"):
            print(f"{name} {op} / {k}: {paired_summary(times[f'{name} {op}'], v, 1.0)}")
    return 0


def with_table_ratio(op: str, ratio=None):
    """``op``, traced with the structure's class ``table_batch_ratio`` set to ``ratio`` (None:
    as the class has it), so a threshold can be raced from either side."""
    def run(s, d):
        if ratio is None:
            return getattr(s, op)(d)
        cls = type(s)
        old = cls.__dict__.get("table_batch_ratio")
        cls.table_batch_ratio = ratio
        try:
            return getattr(s, op)(d)
        finally:
            if old is None:
                del cls.table_batch_ratio
            else:
                cls.table_batch_ratio = old
    return run


def per_query(op: str):
    """``op`` traced with the table routes off (:func:`jaxcds.structures.base.per_query_routes`)."""
    def run(s, d):
        with per_query_routes():
            return getattr(s, op)(d)
    return run


def per_query_adjacent(s, u, v):
    """``adjacent`` traced with the table routes off: a structure whose loops would navigate
    per-call tables (``for_queries``: pemb) searches every turn instead."""
    from jaxcds.algorithms.adjacency import _adjacent

    with per_query_routes():  # the unjitted body: jit's cache would hand back the other route
        return _adjacent.__wrapped__(s, u, v)


def random_darts(s, rng, n: int):
    """``n`` darts of ``s`` drawn uniformly (holes of its id space left out), int32."""
    darts = np.asarray(s.all_darts())
    return jnp.asarray(darts[rng.integers(0, darts.size, n)], jnp.int32)


def random_pairs(s, rng, n: int):
    """``(u, v)``: ``n`` vertex pairs of ``s``, the even ones the two ends of a random dart (an
    edge), the odd ones ``u`` with a vertex drawn uniformly (mostly not adjacent), int32."""
    e = random_darts(s, rng, n)
    # the structure as an argument: a bound method (``jax.jit(s.origin)``) closes over its
    # tables, which XLA then constant-folds (minutes of compilation at 2.5M vertices)
    ends = jax.jit(lambda s, e: (s.origin(e), s.target(e)))
    u, t = ends(s, e)
    other = jnp.asarray(rng.integers(0, s.num_vertices, n), jnp.int32)
    v = jnp.where(jnp.arange(n) % 2 == 0, t, other)
    return u, v


def report(res: dict, vertices: int, queries: int, rounds: int) -> None:
    """Print :func:`race`'s ``{name: (min, median)}`` with the run's setting and load."""
    print(f"random:{vertices}, {queries} random queries, {rounds} rounds, load average "
          f"{os.getloadavg()[0]:.2f}")
    for k, (lo, med) in res.items():
        print(f"{k:32s} min {lo:8.2f}  median {med:8.2f} ns/query")


if __name__ == "__main__":
    raise SystemExit(main())
