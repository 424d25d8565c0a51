"""CDS5n-O(1) normals with the whole-mesh Target plans computed inside a one-trip loop
(``base.computed_in_loop``, the route under ``base.IN_LOOP_MAX_VERTICES``) and outside it (as
above that size), raced in one process against the plain-JAX face list (ns per vertex, medians,
ratio to the face list; every route once per round in a shuffled order,
``race_lf_words.race_in_turn``). Each program's count of kernels XLA:CPU splits over threads
(``outer_dimension_partitions`` in the compiled HLO) is printed beside it.

    .venv/bin/python benchmarks/race_in_loop.py --meshes decimated-knight.off,bunny.off,spot.obj,armadillo.obj --rounds 60
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys

import jax
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from script_errors import at_least_one, clean_exit  # noqa: E402

from race_lf_words import _in_order, _meshes, _structure, face_list_baseline, race_in_turn  # noqa: E402

from jaxcds.algorithms import normals  # noqa: E402
from jaxcds.structures import base  # noqa: E402


def _compiled(s, p, in_loop: bool):
    """A fresh trace of the normals with the in-loop route on or off (read at trace time)."""
    saved = base.IN_LOOP_MAX_VERTICES
    base.IN_LOOP_MAX_VERTICES = (1 << 31) if in_loop else 0
    try:
        return jax.jit(lambda s, p: normals._vertex_normals.__wrapped__(s, p)).lower(s, p).compile()
    finally:
        base.IN_LOOP_MAX_VERTICES = saved


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", default="decimated-knight.off,bunny.off,spot.obj,armadillo.obj")
    ap.add_argument("--structures", default="cds5n-o1")
    ap.add_argument("--rounds", type=at_least_one, default=60)
    a = ap.parse_args(argv)
    for spec in a.meshes.split(","):
        m, parts = _meshes(spec)
        pos, _, want, runs = face_list_baseline(m)
        splits = {}
        for name in a.structures.split(","):
            s = _structure(name, m, parts)
            if s.num_vertices != m.num_vertices:
                print(f"# {spec} {name}: skipped (holes closed by dummy vertices)", flush=True)
                continue
            p, ref = _in_order(s, pos, want)
            for key, on in ((f"{name}/in_loop", True), (f"{name}/outside", False)):
                f = _compiled(s, p, on)
                err = float(np.abs(np.asarray(f(s, p)) - ref).max())
                if not err < 1e-4:
                    raise SystemExit(f"{spec} {key}: normals differ from the face list's by {err}")
                runs[key] = (f, (s, p))
                splits[key] = f.as_text().count("outer_dimension_partitions")
        times = race_in_turn(runs, a.rounds)
        n = m.num_vertices
        fl = statistics.median(times["face_list"])
        row = {"mesh": spec, "vertices": n, "rounds": a.rounds, "load": round(os.getloadavg()[0], 2),
               "split_kernels": splits,
               "ns_per_vertex": {k: round(statistics.median(v) / n * 1e9, 1) for k, v in times.items()},
               "x_face_list": {k: round(statistics.median(v) / fl, 3) for k, v in times.items() if k != "face_list"}}
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
