"""Batched queries by chunks (``base._chunked_query``) against the same operators in one pass,
raced in turn (ns per query, min and median over the rounds; the answers checked equal first).

    .venv/bin/python benchmarks/race_chunked_queries.py --vertices 100000 --queries 4000000 \\
        --structures cds6n,cds5n-o1,lr --ops target,origin,face_left,twin,next
    flock /tmp/jaxcds_big.lock .venv/bin/python benchmarks/race_chunked_queries.py --vertices 2500000
    .venv/bin/python benchmarks/race_chunked_queries.py --packed 300 --structures cds5n-o1,cds6n,lr

``one-pass`` traces the operator under :func:`jaxcds.structures.base.one_pass_queries`;
``fused`` chunks it with each chunk's answers fused into the output's in-place update
(``base.WRITE_CHUNK_ANSWERS_APART = False``, the form before 2026-11-30 evening). An operator the
structure does not chunk gives the same program every way.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from script_errors import at_least_one, clean_exit  # noqa: E402

from jaxcds.batch import pack  # noqa: E402
from jaxcds.errors import ArgumentError  # noqa: E402
from jaxcds.generators import random_planar_triangulation  # noqa: E402
from jaxcds.structures import base, registry  # noqa: E402

from race_lf_words import race_in_turn  # noqa: E402


def _compiled(s, op, d, route: str):
    """``route``: ``chunked`` (as shipped), ``fused`` (chunked, each chunk's answers fused into
    the output's in-place update: ``base.WRITE_CHUNK_ANSWERS_APART = False``) or ``one-pass``."""
    fn = jax.jit(lambda s, d: getattr(s, op)(d))
    if route == "one-pass":
        with base.one_pass_queries():
            return fn.lower(s, d).compile()
    saved = base.WRITE_CHUNK_ANSWERS_APART
    base.WRITE_CHUNK_ANSWERS_APART = route != "fused"  # read while tracing
    try:
        return fn.lower(s, d).compile()
    finally:
        base.WRITE_CHUNK_ANSWERS_APART = saved


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vertices", type=int, default=100_000)
    ap.add_argument("--queries", type=int, default=4_000_000)
    ap.add_argument("--structures", default="cds5n-o1,lr")
    ap.add_argument("--ops", default="target,origin,face_left")
    ap.add_argument("--rounds", type=at_least_one, default=5)
    ap.add_argument("--packed", type=int, default=0,
                    help="instead of one mesh: a packed batch of this many random meshes (500-5,000 vertices)")
    a = ap.parse_args(argv)
    rng = np.random.default_rng(0)
    if a.packed:
        meshes = [random_planar_triangulation(int(n), seed=k)
                  for k, n in enumerate(rng.integers(500, 5001, a.packed))]
    else:
        mesh = random_planar_triangulation(a.vertices, seed=1)
    progs = {}
    for name in a.structures.split(","):
        s = pack(meshes, name).structure if a.packed else registry.build(name, mesh)
        darts = np.asarray(s.all_darts())
        d = jnp.asarray(darts[rng.integers(0, darts.size, a.queries)], jnp.int32)
        for op in a.ops.split(","):
            if not callable(getattr(s, op, None)):
                raise ArgumentError(f"--ops {op}: {name} has no dart operator {op!r}")
            routes = [(f"{name} {op} {k}", _compiled(s, op, d, k), (s, d))
                      for k in ("chunked", "fused", "one-pass")]
            got = [np.asarray(c(*args)) for _, c, args in routes]
            assert all(np.array_equal(g, got[-1]) for g in got), f"{name}.{op}: chunked answers differ"
            progs.update({k: (c, args) for k, c, args in routes})
    raced = race_in_turn(progs, a.rounds)  # the order shuffled each round
    times = {k: [t / a.queries * 1e9 for t in v] for k, v in raced.items()}
    what = f"packed:{a.packed}" if a.packed else f"random:{a.vertices}"
    print(f"{what}, {a.queries} random darts, chunks of {base.QUERY_CHUNK}, "
          f"{a.rounds} rounds")
    for k, t in times.items():
        print(f"{k:36s} min {min(t):8.2f}  median {statistics.median(t):8.2f} ns/query")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
