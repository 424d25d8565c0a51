"""CDS5n-O(1) batched Target: its first read as whole-row gathers (before 2026-12-02) against
column-by-column scalar gathers (``cds._RowColumns``, now), raced in turn with the half-edge.

``python benchmarks/race_o1_first_read.py --vertices 100000 --rounds 21`` (10M random darts per
call; ns per query, min and median over the rounds; RESULTS.md, "CDS5n-O(1) Target: the first
read by columns").
"""

from __future__ import annotations

import argparse
import os
import sys

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks.script_errors import at_least_one, clean_exit  # noqa: E402

from benchmarks.race_queries import race, random_darts, report  # noqa: E402
from jaxcds.generators import random_planar_triangulation  # noqa: E402
from jaxcds.structures import base, cds, registry  # noqa: E402


def _rows_first_read(self, d, want_target):
    """``CDS5nO1._dart_end`` as it was: the first read gathers whole rows."""
    d = cds._ids(d)
    e = d >> 1
    u, c = e // 3, e % 3
    own = ((d & 1) == 0) != want_target
    y, second = self._target_plan_r(u, c, self.refs[jnp.where(own, 0, u)])
    y, second = base.materialize_loop((jnp.where(own, u, y), jnp.where(own, 0, second)))
    return self._target_finish_r(y, second, self._second_row(y, second))


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vertices", type=int, default=100_000)
    ap.add_argument("--queries", type=int, default=10_000_000)
    ap.add_argument("--rounds", type=at_least_one, default=21)
    a = ap.parse_args(argv)
    mesh = random_planar_triangulation(a.vertices, seed=1)
    rng = np.random.default_rng(0)
    he, o1 = registry.build("halfedge", mesh), registry.build("cds5n-o1", mesh)
    dh, do = random_darts(he, rng, a.queries), random_darts(o1, rng, a.queries)
    now = cds.CDS5nO1._dart_end

    def before(s, d):  # traced with the old first read, then the class restored
        cds.CDS5nO1._dart_end = _rows_first_read
        try:
            return s.target(d)
        finally:
            cds.CDS5nO1._dart_end = now

    items = [("halfedge target", lambda s, d: s.target(d), (he, dh)),
             ("cds5n-o1 target, rows", before, (o1, do)),
             ("cds5n-o1 target, columns", lambda s, d: s.target(d), (o1, do))]
    old, new = (np.asarray(jax.jit(f)(o1, do)) for f in (before, items[2][1]))
    if not np.array_equal(old, new):  # the two routes must answer alike
        raise SystemExit("cds5n-o1 Target: the column route disagrees with the row route")
    report(race(items, a.queries, a.rounds), a.vertices, a.queries, a.rounds)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
