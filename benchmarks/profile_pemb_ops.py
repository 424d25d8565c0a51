"""Profile pemb operators one by one on all darts (issue 7): compile and run time per operator.

The ``*_tab`` operators build the per-run tables (``PEMB.with_tables``) and read from them: their
time is the tables' plus the operator's (``tables`` alone is the first).

``python -m benchmarks.profile_pemb_ops [--points 100000] [--repeats 3] [--ops twin next ...]``
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

from jaxcds import polylla_io as io
from jaxcds.algorithms import polylla as P
from benchmarks.script_errors import at_least_one, clean_exit  # noqa: E402

OPS = {
    "access": lambda s, e: s.A.access(e),
    "rank1": lambda s, e: s.A.rank1(e),
    "select1": lambda s, e: s.A.select1(e >> 1),
    "match": lambda s, e: s.P.match(jnp.minimum(e, s.P.size - 1)),
    "enclose": lambda s, e: s.P.enclose(jnp.minimum(e, s.P.size - 1)),
    "twin": lambda s, e: s.twin(e),
    "next": lambda s, e: s.next(e),
    "prev": lambda s, e: s.prev(e),
    "origin": lambda s, e: s.origin(e),
    "face": lambda s, e: s.face(e),
    "is_border": lambda s, e: s.is_border(e),
    "ccw": lambda s, e: s.ccw_vertex_edge(e),
    "cw": lambda s, e: s.cw_vertex_edge(e),
    "edge_of_face": lambda s, e: s.edge_of_face(jnp.minimum(e, s.num_faces - 1)),
    # per-run navigation tables (PEMB.with_tables, what Polylla's label phase builds) and the
    # operators read from them
    "match_all": lambda s, e: s.P.match_all(),
    "tables": lambda s, e: s.with_tables().tables,
    "tables_twin": lambda s, e: s.with_tables(origin=False).tables,
    "tables_origin": lambda s, e: s.with_tables(twin=False).tables,
    "next_tab": lambda s, e: s.with_tables().next(e),
    "is_border_tab": lambda s, e: s.with_tables().is_border(e),
}


@clean_exit
def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=100_000)
    ap.add_argument("--repeats", type=at_least_one, default=3)
    ap.add_argument("--ops", nargs="+", default=list(OPS), choices=list(OPS))
    ap.add_argument("--tree", default=None, choices=["dfs", "bfs"],
                    help="pemb spanning tree (default: PEMB.from_faces's default)")
    ap.add_argument("--check", default=None, help="save (or compare with) results in this .npz")
    a = ap.parse_args(argv)
    pts = np.random.default_rng(0).random((a.points, 2))
    tri = io.from_points(pts, "u")
    if a.tree is None:
        s = P.build_structure(tri, "pemb", check=False)
    else:
        from jaxcds.structures.pemb import PEMB
        s = PEMB.from_faces(tri.faces, tri.num_vertices, tree=a.tree)
    e = jnp.arange(s.num_darts, dtype=jnp.int32)
    print(json.dumps({"darts": s.num_darts, "bits_per_edge": s.bits_per_edge}), flush=True)
    results = {}
    for name in a.ops:
        f = jax.jit(OPS[name])
        t0 = time.perf_counter()
        c = f.lower(s, e).compile()
        tc = time.perf_counter() - t0
        ts, cs = [], []
        for _ in range(a.repeats):
            t0, c0 = time.perf_counter(), time.process_time()
            r = jax.block_until_ready(c(s, e))
            ts.append(time.perf_counter() - t0)
            cs.append(time.process_time() - c0)
        # a dict of tables: keep them all, one array (for --check)
        results[name] = (np.concatenate([np.asarray(r[k]).ravel() for k in sorted(r)])
                         if isinstance(r, dict) else np.asarray(r))
        print(json.dumps({"op": name, "compile_s": round(tc, 2), "run_s": round(statistics.median(ts), 4),
                          "cpu_s": round(statistics.median(cs), 4)}),
              flush=True)
    if a.check:
        import os
        if os.path.exists(a.check):
            ref = np.load(a.check)
            for k in results:
                if k in ref:
                    print(k, "identical" if np.array_equal(ref[k], results[k]) else "DIFFERENT", flush=True)
        else:
            np.savez(a.check, **results)


if __name__ == "__main__":
    sys.exit(main())
