"""Where a jitted normals call spends its time, kernel by kernel (XLA:CPU), from a JAX profiler
trace: each kernel's total microseconds per call, its median per launch, and launches per call.

    .venv/bin/python benchmarks/profile_kernels.py --mesh armadillo.obj --structure cds6n
    .venv/bin/python benchmarks/profile_kernels.py --mesh random:200000 --structure face-list

XLA:CPU records kernel events only with ``--xla_cpu_enable_xprof_traceme=true``; this script adds
the flag to ``XLA_FLAGS`` before JAX starts. Used for ``RESULTS.md``, "CDS: a static round
count" (the per-round body, state copy and loop test of the pointer jumping).
"""

from __future__ import annotations

import argparse
import collections
import glob
import gzip
import json
import os
import statistics
import sys
import tempfile

os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " --xla_cpu_enable_xprof_traceme=true").strip()

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from script_errors import clean_exit  # noqa: E402

from bench_lr_normals import _mesh  # noqa: E402

from jaxcds.algorithms.normals import face_list_vertex_normals, vertex_normals  # noqa: E402
from jaxcds.structures import registry  # noqa: E402


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default="armadillo.obj")
    ap.add_argument("--structure", default="cds6n", help="a registry name, or face-list")
    ap.add_argument("--calls", type=int, default=20)
    ap.add_argument("--top", type=int, default=25)
    a = ap.parse_args(argv)
    m = _mesh(a.mesh)
    pos = jnp.asarray(m.vertices, jnp.float32)
    if a.structure == "face-list":
        f, args = jax.jit(face_list_vertex_normals), (pos, jnp.asarray(m.faces, jnp.int32))
    else:
        s = registry.build(a.structure, m)
        order = s.vertex_order
        f, args = vertex_normals, (s, pos if order is None else pos[np.asarray(order)])
    for _ in range(5):
        jax.block_until_ready(f(*args))
    with tempfile.TemporaryDirectory() as tmp:
        with jax.profiler.trace(tmp, create_perfetto_trace=True):
            for _ in range(a.calls):
                jax.block_until_ready(f(*args))
        path = glob.glob(os.path.join(tmp, "**", "*.trace.json.gz"), recursive=True)[0]
        events = json.load(gzip.open(path))["traceEvents"]
    per_name = collections.defaultdict(list)
    for e in events:
        name = e.get("name", "")
        # kernels and runtime spans; not the Python frames ("$file:line") nor end markers
        if e.get("ph") == "X" and not name.startswith(("end:", "$")) and "Listener" not in name:
            per_name[e["name"]].append(e["dur"])
    rows = sorted(per_name.items(), key=lambda kv: -sum(kv[1]))[: a.top]
    print(f"{a.mesh} {a.structure}: {a.calls} calls; us per call, median us per launch, launches per call")
    for name, durs in rows:
        print(f"{sum(durs) / a.calls:9.1f} {statistics.median(durs):9.1f} {len(durs) / a.calls:6.1f}  {name[:90]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
