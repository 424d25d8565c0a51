"""Mesh validation benchmark (issues 3 and 6): ``validate_and_close`` -- the first step of every
builder -- on uniform random planar triangulations (Poulalhon--Schaeffer, ``2n - 4`` faces).

Rows, each the median of ``--repeats`` runs after a warm-up (numba compiled and cached):

* ``fast``: :func:`jaxcds.mesh.validate_and_close` as the builders call it (the one-kernel
  fast path, :func:`jaxcds._mesh_kernels.manifold_twins`, twins returned);
* ``full``: the same call forced through the full checks (edge table, duplicate faces,
  union-find fans and components, boundary loops) that a defective mesh takes and that every
  mesh took before the fast path (``--no-full`` skips it);
* ``edge_table``: :func:`jaxcds.mesh.edge_table` alone (used by ``topology`` and the full path);
* ``corner_table_from_twins`` / ``corner_table_from_faces``: ``CornerTable.from_faces`` with the
  twins validation found and without them (matching twins again).

Wall and CPU seconds (``process_time``: the steadier figure on the shared 2-core machine) and
the process's peak RSS (``VmHWM``, absolute: the mesh included). Sizes above 2M vertices must
run under ``flock /tmp/jaxcds_big.lock``::

    .venv/bin/python -m benchmarks.bench_validation --vertices 1000000
    flock /tmp/jaxcds_big.lock .venv/bin/python -m benchmarks.bench_validation \\
        --vertices 10000000 --repeats 2 --json /tmp/validation_10m.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from typing import Optional, Sequence

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
if os.path.dirname(HERE) not in sys.path:  # run as a script from anywhere
    sys.path.insert(0, os.path.dirname(HERE))
from benchmarks.script_errors import at_least_one, clean_exit  # noqa: E402

from benchmarks.harness import time_wall_cpu  # noqa: E402


def _peak_rss() -> Optional[int]:
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:  # pragma: no cover - not Linux
        pass
    return None


def run(n: int, repeats: int, full: bool = True) -> dict:
    from jaxcds import mesh as M
    from jaxcds.generators import random_planar_triangulation_faces
    from jaxcds.structures.corner_table import CornerTable

    t0 = time.perf_counter()
    f = random_planar_triangulation_faces(n, seed=0)
    v = np.random.default_rng(0).normal(size=(n, 3))
    mesh = M.TriMesh(vertices=v, faces=f, source=f"random:{n}")
    gen_s = time.perf_counter() - t0
    small = M.TriMesh(vertices=np.eye(4, 3), faces=np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]],
                                                        np.int32))
    M.validate_and_close(small, return_twins=True)  # warm-up: numba kernels (cached on disk)
    M.edge_table(small.faces)
    CornerTable.from_faces(small.faces, 4)
    nf = mesh.num_faces
    out = {"vertices": n, "faces": nf, "repeats": repeats, "generate_s": gen_s,
           "load_before": list(os.getloadavg())}
    rows = {}
    _, twins = M.validate_and_close(mesh, return_twins=True)
    rows["fast"] = time_wall_cpu(lambda: M.validate_and_close(mesh, return_twins=True), repeats)
    rows["corner_table_from_twins"] = time_wall_cpu(
        lambda: CornerTable.from_faces(f, n, twins=twins), repeats)
    del twins
    rows["corner_table_from_faces"] = time_wall_cpu(lambda: CornerTable.from_faces(f, n), repeats)
    rows["edge_table"] = time_wall_cpu(lambda: M.edge_table(f), repeats)
    if full:
        keep = M._fast_check
        M._fast_check = lambda *a, **k: None  # the full checks, as a defective mesh takes them
        try:
            rows["full"] = time_wall_cpu(lambda: M.validate_and_close(mesh), repeats)
        finally:
            M._fast_check = keep
    for key, (w, c) in rows.items():
        out[key + "_s"] = w
        out[key + "_cpu_s"] = c
        out[key + "_mfaces_per_s"] = nf / w / 1e6
        out[key + "_mfaces_per_cpu_s"] = nf / c / 1e6
    out["peak_rss_bytes"] = _peak_rss()
    out["load_after"] = list(os.getloadavg())
    return out


def markdown(r: dict) -> str:
    lines = [f"random:{r['vertices']} ({r['faces']:,} faces), median of {r['repeats']}, load "
             f"{r['load_before'][0]:.2f} -> {r['load_after'][0]:.2f}, peak RSS "
             f"{(r['peak_rss_bytes'] or 0) / 2**30:.2f} GiB", "",
             "| step | wall s | CPU s | M faces/s | M faces/CPU s |", "|---|---|---|---|---|"]
    for key in ("fast", "full", "edge_table", "corner_table_from_twins", "corner_table_from_faces"):
        if key + "_s" in r:
            lines.append(f"| {key} | {r[key + '_s']:.3f} | {r[key + '_cpu_s']:.3f} | "
                         f"{r[key + '_mfaces_per_s']:.2f} | {r[key + '_mfaces_per_cpu_s']:.2f} |")
    return "\n".join(lines)


@clean_exit
def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--vertices", type=int, nargs="+", default=[1_000_000])
    ap.add_argument("--repeats", type=at_least_one, default=3)
    ap.add_argument("--no-full", action="store_true", help="skip the full-check path")
    ap.add_argument("--quick", action="store_true", help="20,000 vertices (smoke test)")
    ap.add_argument("--json", help="write the results as JSON here")
    args = ap.parse_args(argv)
    sizes = [20_000] if args.quick else args.vertices
    res = {"command": " ".join(sys.argv), "runs": []}
    for n in sizes:
        r = run(n, args.repeats, full=not args.no_full)
        res["runs"].append(r)
        print(markdown(r) + "\n", flush=True)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(res, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
