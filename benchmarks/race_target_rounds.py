"""The CDS all-targets pointer jumping (``_CDS._targets_cols``) alone, three loop forms raced in
turn on the same start values (ns per vertex, medians; every route checked equal first):

* ``data_driven``: a ``while_loop`` on ``any(pending)`` (the route before ``target_rounds``,
  ``cds.pointer_jump`` without a round count);
* ``static_one``: ``target_rounds`` rounds, one per trip of a static ``fori_loop``;
* ``static_two``: two rounds per trip, the first's result written to memory in between
  (``materialize_loop``): the library's route, ``cds.pointer_jump``.

    .venv/bin/python benchmarks/race_target_rounds.py --meshes armadillo.obj,random:200000
    flock /tmp/jaxcds_big.lock .venv/bin/python benchmarks/race_target_rounds.py --meshes random:2000000
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import jax
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from script_errors import at_least_one, clean_exit  # noqa: E402

from bench_lr_normals import _mesh  # noqa: E402

from jaxcds.structures import registry  # noqa: E402
from jaxcds.structures.cds import jump_round, pointer_jump  # noqa: E402


def data_driven(v, rounds):
    return pointer_jump(v, -1)  # no static rounds: the data-driven loop alone


def static_one(v, rounds):
    return jax.lax.fori_loop(0, rounds, lambda _, v: jump_round(v), v)


def static_two(v, rounds):
    return pointer_jump(v, rounds)  # the library's route (its safety net runs no trip)


ROUTES = {"data_driven": data_driven, "static_one": static_one, "static_two": static_two}


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", default="armadillo.obj,random:200000")
    ap.add_argument("--structure", default="cds6n")
    ap.add_argument("--rounds", type=at_least_one, default=40, help="race rounds")
    a = ap.parse_args(argv)
    for spec in a.meshes.split(","):
        s = registry.build(a.structure, _mesh(spec))
        v = s._target_start()
        want = np.asarray(s.all_edge_targets())
        fns = {k: jax.jit(lambda v, f=f: f(v, s.target_rounds)) for k, f in ROUTES.items()}
        ok = np.stack(s._valid_cols(), axis=1).reshape(-1)
        for k, f in fns.items():
            got = np.asarray(f(v))
            assert np.array_equal(got[ok], want[ok]), f"{k}: targets differ"
        times = {k: [] for k in fns}
        for r in range(a.rounds):
            for k, f in fns.items():
                t0 = time.perf_counter()
                f(v).block_until_ready()
                times[k].append(time.perf_counter() - t0)
        n = s.num_vertices
        cols = " ".join(f"{k}={statistics.median(t) / n * 1e9:.1f}" for k, t in times.items())
        print(f"{spec} {a.structure} n={n} target_rounds={s.target_rounds} {cols} ns/vertex")
    return 0


if __name__ == "__main__":
    sys.exit(main())
