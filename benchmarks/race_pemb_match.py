"""pemb normals with the parenthesis matches found by the searches (the default) or by one sort
by level (``bp.MATCH_BY_SORT``, :func:`jaxcds.structures.succinct.bp.matches_by_level`), raced in
turn beside the plain-JAX face list (ns per vertex, min and median over the rounds; the normals
checked equal first). The sort measured 4.1x slower than the searches on XLA:CPU (RESULTS.md,
stop 44); it is the GPU candidate (XLA's GPU sort is a radix sort, the searches are loops there).

    .venv/bin/python benchmarks/race_pemb_match.py --vertices 100000 --meshes 300
    python3 benchmarks/race_pemb_match.py --vertices 5000000 --meshes 1000 --json out.json   # a GPU

``--meshes 0`` skips the packed batch (500-5,000-vertex random planar triangulations; on CPU its
rows are derived chunk by chunk, each chunk's matches searched or sorted over its windows; on a
GPU the whole union's). Every route is traced with its own value of the switch
(``jax.clear_caches()`` before each: the jitted normals read it while tracing).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from script_errors import at_least_one, clean_exit  # noqa: E402

from jaxcds import batch as B  # noqa: E402
from jaxcds.algorithms import face_list_vertex_normals, vertex_normals  # noqa: E402
from jaxcds.generators import random_planar_triangulation  # noqa: E402
from jaxcds.structures import registry  # noqa: E402
from jaxcds.structures.succinct import bp  # noqa: E402

from bench_batch import make_meshes  # noqa: E402
from race_lf_words import race_in_turn  # noqa: E402


def _compiled(fn, args, by_sort: bool):
    """``fn`` jitted and compiled with ``bp.MATCH_BY_SORT = by_sort`` while it is traced."""
    saved = bp.MATCH_BY_SORT
    jax.clear_caches()  # the inner jitted normals would otherwise reuse the other route's trace
    bp.MATCH_BY_SORT = by_sort
    try:
        return jax.jit(fn).lower(*args).compile()
    finally:
        bp.MATCH_BY_SORT = saved


def _single(n: int):
    """``(structure, positions, face-list faces)`` of a random planar triangulation as pemb."""
    mesh = random_planar_triangulation(n, seed=1)
    s = registry.build("pemb", mesh)
    order = np.asarray(s.vertex_order)
    inv = np.empty_like(order)
    inv[order] = np.arange(order.size)
    pos = jnp.asarray(mesh.vertices[order], jnp.float32)
    return s, pos, jnp.asarray(inv[mesh.faces], jnp.int32), n


def _packed(k: int):
    """``(batch, positions, face-list faces)`` of ``k`` random meshes packed as pemb."""
    ms = make_meshes(k, 500, 5000, 0)
    b = B.pack(ms, "pemb", check=False)
    pos = B.pack_positions(b, ms)
    order = np.asarray(b.vertex_order)
    inv = np.empty_like(order)
    inv[order] = np.arange(order.size)
    voff = np.concatenate([[0], np.cumsum([m.num_vertices for m in ms])[:-1]])
    faces = inv[np.concatenate([m.faces + o for m, o in zip(ms, voff)])]
    return b, pos, jnp.asarray(faces, jnp.int32), int(pos.shape[0])


def race(label: str, s, pos, faces, nv: int, rounds: int) -> list[dict]:
    t0 = time.perf_counter()
    progs = {"search": (_compiled(vertex_normals, (s, pos), False), (s, pos)),
             "sort": (_compiled(vertex_normals, (s, pos), True), (s, pos)),
             "face list": (jax.jit(face_list_vertex_normals).lower(pos, faces).compile(), (pos, faces))}
    compile_s = time.perf_counter() - t0
    want = np.asarray(progs["face list"][0](pos, faces))
    for k in ("search", "sort"):
        got = np.asarray(progs[k][0](*progs[k][1]))
        err = float(np.max(np.abs(got - want)))
        assert err < 1e-2, f"{label} {k}: normals differ from the face list by {err}"
    times = race_in_turn(progs, rounds)
    fl = statistics.median(times["face list"])
    rows = []
    for k, ts in times.items():
        med = statistics.median(ts)
        rows.append(dict(case=label, route=k, ns_per_vertex_median=med / nv * 1e9,
                         ns_per_vertex_min=min(ts) / nv * 1e9, vs_face_list=med / fl,
                         vs_face_list_paired=statistics.median(t / f for t, f in zip(ts, times["face list"])),
                         vertices=nv, rounds=rounds))
        print(f"{label:>16} {k:>9}: {rows[-1]['ns_per_vertex_median']:9.1f} ns/vertex median "
              f"({rows[-1]['ns_per_vertex_min']:.1f} min), {rows[-1]['vs_face_list']:.2f}x the face list "
              f"(paired {rows[-1]['vs_face_list_paired']:.2f}x)", flush=True)
    print(f"{label:>16} compiled in {compile_s:.1f} s", flush=True)
    return rows


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vertices", type=int, default=100_000, help="single pemb (0: skip)")
    ap.add_argument("--meshes", type=int, default=300, help="packed pemb batch (0: skip)")
    ap.add_argument("--rounds", type=at_least_one, default=7)
    ap.add_argument("--json", help="write the rows here")
    a = ap.parse_args(argv)
    rows = []
    print(f"jax {jax.__version__}, {jax.devices()}, {platform.processor() or platform.machine()}", flush=True)
    if a.vertices:
        rows += race(f"random:{a.vertices}", *_single(a.vertices), a.rounds)
    if a.meshes:
        rows += race(f"packed:{a.meshes}", *_packed(a.meshes), a.rounds)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(dict(jax=jax.__version__, devices=[str(d) for d in jax.devices()], rows=rows),
                      fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
