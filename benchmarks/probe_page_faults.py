"""Page faults and time per call of the normals, for the face list and each structure: how much
of a large call is the kernel mapping XLA's temporaries in again.

XLA:CPU allocates a jitted call's temporaries with ``malloc`` and frees them at its end; glibc
serves blocks over 32 MiB with a fresh ``mmap`` and returns them with ``munmap``, so each call on
a large mesh faults its temporaries in page by page (4 KiB, zeroed). Run it twice, the second
time with glibc told to keep freed memory (no ``mmap`` for large blocks, no trimming, one arena,
so XLA's worker threads allocate from the heap too)::

    .venv/bin/python benchmarks/probe_page_faults.py --mesh packed:1000
    GLIBC_TUNABLES=glibc.malloc.mmap_max=0:glibc.malloc.trim_threshold=-1:glibc.malloc.arena_max=1 \\
        .venv/bin/python benchmarks/probe_page_faults.py --mesh packed:1000

Prints, per route, the compiled program's temporaries (bytes per vertex, XLA's memory analysis)
and per call the time (ns per vertex) and minor page faults (as bytes per vertex). Calls run in
turn (every route once per round), after one warm-up call each. The glibc setting is not a
library feature: its steady state is not reliable (a small probe kept faulting on some calls
while the heap grew), see RESULTS.md, "Page faults".
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from script_errors import at_least_one, clean_exit  # noqa: E402

from race_lf_words import _in_order, _meshes, _structure  # noqa: E402

from jaxcds.algorithms import normals as N  # noqa: E402


def _faults() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default="packed:1000")
    ap.add_argument("--structures", default="lr,cds5n-o1,cds6n")
    ap.add_argument("--rounds", type=at_least_one, default=5)
    a = ap.parse_args(argv)
    mesh, parts = _meshes(a.mesh)
    n = mesh.num_vertices
    fpos = jnp.asarray(np.asarray(mesh.vertices), jnp.float32)
    faces = jnp.asarray(mesh.faces, jnp.int32)
    runs = {"face_list": (jax.jit(N.face_list_vertex_normals).lower(fpos, faces).compile(), (fpos, faces))}
    for name in a.structures.split(","):
        s = _structure(name, mesh, parts)
        pos, = _in_order(s, fpos)
        runs[name] = (jax.jit(lambda s, p: N.normalize(N._scatter_sums(s, p))).lower(s, pos).compile(), (s, pos))
    print(f"{a.mesh}: {n} vertices; GLIBC_TUNABLES={os.environ.get('GLIBC_TUNABLES', '')!r}")
    for f, args in runs.values():
        jax.block_until_ready(f(*args))
    times = {k: [] for k in runs}
    faults = {k: [] for k in runs}
    for _ in range(a.rounds):
        for k, (f, args) in runs.items():
            r0, t0 = _faults(), time.perf_counter()
            jax.block_until_ready(f(*args))
            times[k].append(time.perf_counter() - t0)
            faults[k].append(_faults() - r0)
    base = statistics.median(times["face_list"])
    for k, (f, _) in runs.items():
        temp = f.memory_analysis().temp_size_in_bytes / n
        print(f"{k}: temporaries {temp:.0f} B/vertex; {1e9 * statistics.median(times[k]) / n:.1f} ns/vertex "
              f"({statistics.median(times[k]) / base:.2f}x the face list); faults per call "
              f"{[round(x * 4096 / n) for x in faults[k]]} B/vertex", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
