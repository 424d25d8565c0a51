"""Polylla benchmark (issue 7): time per phase and memory, HalfEdge vs pemb, uniform random points.

``python -m benchmarks.bench_polylla --sizes 100000 1000000 [--structures halfedge pemb]
[--modes canonical reference] [--repeats 3] [--json out.json]``

Modes (:func:`jaxcds.algorithms.polylla.polylla`): ``canonical``, the order-free vectorised
phases (run without corners, as before 2026-12-02); ``reference``, the reference's sequential
traversal and repair on the input's rows (the default of ``run`` and the CLI): its ``traversal``
phase holds the walks, the repair and the polygon lists at once (``repair`` and ``polygons`` 0).

For each size: uniform random points in the unit square (seed 0), Delaunay by scipy (timed, not
part of the targets), the structure built from the face array (target for the HalfEdge: < 2 s at
1M points), then Polylla: the first call (compilation included) and the median of ``repeats``
further calls per phase (label, traversal, repair, polygons); compile time = first - median.
Memory: bytes and references of the structure, bytes of the per-run navigation tables Polylla
builds on it (``run_tables_bytes``: pemb's twin / first_dual / vertex tables and word ranks, held
from the label phase to the end of the run), bytes of the output, peak RSS of the process.
Every phase also reports its process CPU time (``cpu_*``, all threads): on a shared machine the
wall time grows with the load, the CPU time much less.

Anchors (issue 7, same input kind): the reference C++ Polylla took 4.0 s to build its half-edge
from OFF and 0.66 s for label + traversal + repair at 1M points (322,520 polygons).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import sys
import time

import jax
import numpy as np

from jaxcds import polylla_io as io
from jaxcds.algorithms import polylla as P
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # run as a script too
from benchmarks.script_errors import at_least_one, clean_exit  # noqa: E402

PHASES = ("label", "traversal", "repair", "polygons")


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_tables_bytes(s) -> int:
    """Bytes of the navigation tables :func:`jaxcds.algorithms.polylla.polylla` builds for ``s``
    (``s.with_tables()``, kept from the label phase to the end of the run; 0 if it has none)."""
    if getattr(s, "with_tables", None) is None:
        return 0
    t = jax.jit(lambda s: s.with_tables().tables)(s)
    return int(sum(np.asarray(x).nbytes for x in t.values()))


def bench_one(n: int, structures, repeats: int, seed: int = 0, tables: bool = True,
              modes=("canonical",)) -> list[dict]:
    rng = np.random.default_rng(seed)
    pts = rng.random((n, 2))
    t0 = time.perf_counter()
    tri = io.from_points(pts, f"uniform{n}")
    t_delaunay = time.perf_counter() - t0
    rows = []
    ref_out = {}
    for name in structures:  # one build per structure, each mode run on it
        t0 = time.perf_counter()
        s = P.build_structure(tri, name, check=False)
        jax.block_until_ready(jax.tree_util.tree_leaves(s))
        t_build_first = time.perf_counter() - t0
        builds = []
        for _ in range(max(1, min(repeats, 3))):
            t0 = time.perf_counter()
            s = P.build_structure(tri, name, check=False)
            jax.block_until_ready(jax.tree_util.tree_leaves(s))
            builds.append(time.perf_counter() - t0)
        for mode in modes:
            kw = dict(tables=tables, mode=mode,
                      corners=tri.input_faces if mode == "reference" else None)
            first = P.polylla(s, tri.points, **kw)
            runs = [P.polylla(s, tri.points, **kw) for _ in range(repeats)]
            med = {k: statistics.median(r.timings[k] for r in runs) for k in PHASES}
            med_cpu = {k: statistics.median(r.timings["cpu_" + k] for r in runs) for k in PHASES}
            total = sum(med[k] for k in ("label", "traversal", "repair"))
            mesh = runs[-1]
            first_out = ref_out.setdefault(mode, (mesh.offsets, mesh.indices))
            identical = bool(np.array_equal(first_out[0], mesh.offsets)
                             and np.array_equal(first_out[1], mesh.indices))
            rows.append({
                "points": n, "triangles": tri.num_faces, "structure": name, "mode": mode,
                "tables": tables,
                "delaunay_s": t_delaunay,
                "build_s": statistics.median(builds), "build_first_s": t_build_first,
                **{f"{k}_s": med[k] for k in PHASES},
                **{f"cpu_{k}_s": med_cpu[k] for k in PHASES},
                "label_traversal_repair_s": total,
                "cpu_label_traversal_repair_s": sum(med_cpu[k] for k in ("label", "traversal", "repair")),
                "polylla_total_s": total + med["polygons"],
                "compile_s": {k: max(first.timings[k] - med[k], 0.0) for k in PHASES},
                "polygons": mesh.num_polygons, "barrier_edge_tips": mesh.barrier_edge_tips,
                "repaired_polygons": mesh.repaired_polygons, "regions": mesh.regions,
                "structure_bytes": int(s.nbytes), "structure_references": int(s.references),
                # per-run navigation tables Polylla builds in its label phase and keeps until it
                # returns (pemb: twin/first_dual/vertex tables, word ranks; 0: none)
                "run_tables_bytes": run_tables_bytes(s) if tables else 0,
                "bits_per_edge": 8.0 * s.nbytes / (3 * tri.num_faces / 2),
                "output_bytes": int(mesh.offsets.nbytes + mesh.indices.nbytes),
                "peak_rss_mb": peak_rss_mb(), "identical_to_first_structure": identical,
            })
            print(json.dumps(rows[-1]), flush=True)
            del first, runs, mesh
    return rows


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[100_000, 1_000_000])
    ap.add_argument("--structures", nargs="+", default=["halfedge", "pemb"])
    ap.add_argument("--modes", nargs="+", default=["canonical", "reference"],
                    choices=["canonical", "reference"])
    ap.add_argument("--repeats", type=at_least_one, default=3)
    ap.add_argument("--json", default=None, help="write all rows to this file")
    ap.add_argument("--no-tables", action="store_true",
                    help="run Polylla without per-run navigation tables (pemb searches per operator)")
    args = ap.parse_args(argv)
    from jaxcds.structures import registry

    structures = [s for s in args.structures if s in registry.names()]
    missing = sorted(set(args.structures) - set(structures))
    if missing:
        print(f"skipping unregistered structures: {missing}", file=sys.stderr)
    info = {"machine": platform.machine(), "python": platform.python_version(),
            "jax": jax.__version__, "backend": jax.default_backend(),
            "cpus": os.cpu_count(), "command": " ".join(sys.argv)}
    print(json.dumps(info), flush=True)
    rows = []
    for n in args.sizes:
        try:
            rows += bench_one(n, structures, args.repeats, tables=not args.no_tables,
                              modes=args.modes)
        except Exception as exc:  # report and go on with the next size
            print(f"size {n}: {type(exc).__name__}: {exc}", file=sys.stderr)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"info": info, "rows": rows}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
