"""Packed batches of many meshes: time per vertex against a Python loop and the face-list batch.

    .venv/bin/python benchmarks/bench_batch.py                    # 300 meshes (2-core default)
    .venv/bin/python benchmarks/bench_batch.py --meshes 10000     # the issue's size (~27M vertices)

Meshes: uniform random planar triangulations (Poulalhon-Schaeffer, ``jaxcds.generators``) with a
vertex count drawn uniformly in ``[--min, --max]`` (500 to 5,000). Timed, per vertex of the batch
(median of ``--repeat`` runs after a warm-up; compile time reported apart):

* ``normals``: area-weighted vertex normals of the whole batch in ONE jitted call:
  - ``face-list``: the plain-JAX baseline ``face_list_vertex_normals(positions, union_faces)``;
  - ``packed/<structure>``: ``vertex_normals(PackedBatch, positions)`` (scatter route); its
    ratio to the face list comes from runs interleaved with face-list runs (same machine load);
  - ``loop/<structure>``: a Python loop calling ``vertex_normals`` mesh by mesh (jitted, warm
    cache: every distinct mesh size is one compilation, counted apart), timed on the first
    ``--loop-meshes`` meshes and reported per vertex of those meshes (and against the face-list
    batch of those same meshes: small meshes stay in cache, so per-vertex times of a small
    subset and of the whole batch are not comparable).
* ``target``: ``--queries`` Target queries given as (mesh, local dart) pairs:
  - ``face-list``: ``faces[(c // 3), (c + 1) % 3]`` after shifting ids (plain JAX);
  - ``packed/<structure>``: ``PackedBatch.query("target", mesh, local)`` (ratio from runs
    interleaved with face-list runs).
* ``build``: ``pack(check=False)`` (one numba pass on the union) against building per mesh;
  the validation ``pack(check=True)`` adds is timed on its own.
* compact kinds (``--structures cds5n,lr``): built per mesh and joined by ``concatenate`` on the
  first ``--compact-meshes`` meshes; ``normals`` against the face-list batch of those same
  meshes (interleaved), a Python loop, and ``target`` on valid local darts.

Prints a JSON line per measurement and a markdown table for benchmarks/RESULTS.md.
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

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from script_errors import at_least_one, clean_exit  # noqa: E402
from paired import paired_summary  # noqa: E402

from jaxcds import batch as B
from jaxcds.algorithms import face_list_vertex_normals, vertex_normals
from jaxcds.generators import random_planar_triangulation
from jaxcds.mesh import validate
from jaxcds.structures import CornerTable, HalfEdge


def timeit(fn, repeat: int):
    """(compile+first run seconds, median seconds of ``repeat`` warm runs)."""
    t0 = time.perf_counter()
    jax.block_until_ready(fn())
    first = time.perf_counter() - t0
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        ts.append(time.perf_counter() - t0)
    return first, statistics.median(ts)


def timepair_runs(fa, fb, repeat: int):
    """``(runs a, runs b)``: seconds of ``fa`` and ``fb`` timed in turn after one warm-up each, so
    that both see the same machine load (the ratio is what the target is about). The order flips every round (a b,
    b a, ...): with a fixed order, the 10,000-mesh run of 2026-11-30 timed the face list at
    104-118 ns per vertex next to the CDS kinds, against 66-82 in races of rotating order, which
    made those ratios look better than they are (cause not found). The fastest runs give
    ``vs_face_list_min`` in the rows, the runs paired round by round ``vs_face_list_paired``
    (``benchmarks/paired.py``)."""
    jax.block_until_ready(fa())
    jax.block_until_ready(fb())
    ta, tb = [], []
    for r in range(repeat):
        pair = ((fa, ta), (fb, tb)) if r % 2 == 0 else ((fb, tb), (fa, ta))
        for fn, acc in pair:
            t0 = time.perf_counter()
            jax.block_until_ready(fn())
            acc.append(time.perf_counter() - t0)
    return ta, tb


def timepair(fa, fb, repeat: int):
    """``(median a, median b, fastest a, fastest b)`` of :func:`timepair_runs`."""
    ta, tb = timepair_runs(fa, fb, repeat)
    return statistics.median(ta), statistics.median(tb), min(ta), min(tb)


def against_face_list(face_list, packed, repeat: int):
    """``(median seconds of packed, row fields)``: the two timed in turn (:func:`timepair_runs`);
    the fields are the ratio of the medians (``vs_face_list``), of the fastest runs, the median of
    the ratios paired run by run with its 95% interval and its verdict against issue 5's 1.5x
    (``benchmarks/paired.py``; no interval under 6 runs), and the face list's median."""
    runs_fl, runs = timepair_runs(face_list, packed, repeat)
    t_fl, t = statistics.median(runs_fl), statistics.median(runs)
    p = paired_summary(runs, runs_fl, target=1.5)
    return t, dict(vs_face_list=t / t_fl, vs_face_list_min=min(runs) / min(runs_fl),
                   vs_face_list_paired=p.median, vs_face_list_paired_low=p.low,
                   vs_face_list_paired_high=p.high, verdict_at_1_5x=p.verdict,
                   face_list_interleaved_s=t_fl)


def make_meshes(k: int, lo: int, hi: int, seed: int):
    rng = np.random.default_rng(seed)
    sizes = rng.integers(lo, hi + 1, k)
    return [random_planar_triangulation(int(n), seed=seed * 100_003 + i) for i, n in enumerate(sizes)]


def run(args) -> list[dict]:
    rows = []

    def emit(**kw):
        rows.append(kw)
        print(json.dumps(kw), flush=True)

    t0 = time.perf_counter()
    ms = make_meshes(args.meshes, args.min, args.max, args.seed)
    nv = sum(m.num_vertices for m in ms)
    emit(what="generate", meshes=len(ms), vertices=nv, seconds=time.perf_counter() - t0)

    union = B._union(ms)
    if not args.no_check:  # pack(check=True) validates the union once: timed apart
        t0 = time.perf_counter()
        validate(union, closed=True)
        emit(what="build", impl="validate union (pack check=True)", vertices=nv,
             seconds=time.perf_counter() - t0)
    faces = jnp.asarray(union.faces)
    pos = jnp.asarray(union.vertices, jnp.float32)

    # ---- normals: face-list baseline on the union
    first, t = timeit(lambda: face_list_vertex_normals(pos, faces), args.repeat)
    emit(what="normals", impl="face-list", vertices=nv, seconds=t, ns_per_vertex=1e9 * t / nv,
         first_call_s=first)
    base_normals = t

    qrng = np.random.default_rng(1)
    qm = qrng.integers(0, len(ms), args.queries).astype(np.int32)
    nd = np.array([3 * m.num_faces for m in ms], np.int64)
    qd = (qrng.random(args.queries) * nd[qm]).astype(np.int32)
    qm_j, qd_j = jnp.asarray(qm), jnp.asarray(qd)
    foff = jnp.asarray(np.concatenate([[0], np.cumsum([m.num_faces for m in ms])[:-1]]).astype(np.int32))
    voff = jnp.asarray(np.concatenate([[0], np.cumsum([m.num_vertices for m in ms])[:-1]]).astype(np.int32))

    @jax.jit
    def face_list_target(faces, foff, voff, m, c):
        g = 3 * foff[m] + c
        return faces[g // 3, (g + 1) % 3] - voff[m]

    first, t = timeit(lambda: face_list_target(faces, foff, voff, qm_j, qd_j), args.repeat)
    emit(what="target", impl="face-list", queries=args.queries, seconds=t,
         ns_per_query=1e9 * t / args.queries, first_call_s=first)
    want_target = np.asarray(face_list_target(faces, foff, voff, qm_j, qd_j))

    for name, cls in (("corner-table", CornerTable), ("halfedge", HalfEdge)):
        t0 = time.perf_counter()
        b = B.pack(ms, name, check=False)
        emit(what="build", impl=f"packed/{name}", vertices=nv, seconds=time.perf_counter() - t0)
        k = min(args.loop_meshes, len(ms))
        t0 = time.perf_counter()
        parts = [cls.from_faces(m.faces, m.num_vertices) for m in ms[:k]]
        tb = time.perf_counter() - t0
        nv_loop = sum(m.num_vertices for m in ms[:k])
        emit(what="build", impl=f"loop/{name}", vertices=nv_loop, seconds=tb,
             seconds_scaled_to_batch=tb * nv / nv_loop)

        f = jax.jit(lambda s, p: vertex_normals(s, p))
        t0 = time.perf_counter()
        jax.block_until_ready(f(b, pos))
        first = time.perf_counter() - t0
        # face-list timed again, interleaved with the packed runs: same load for both
        t, vs = against_face_list(lambda: face_list_vertex_normals(pos, faces), lambda: f(b, pos),
                                  args.repeat)
        err = float(jnp.max(jnp.abs(f(b, pos) - face_list_vertex_normals(pos, faces))))
        emit(what="normals", impl=f"packed/{name}", vertices=nv, seconds=t, ns_per_vertex=1e9 * t / nv,
             **vs, first_call_s=first, max_abs_diff_vs_face_list=err)

        # Python loop over meshes (warm: compile every distinct size first, timed apart)
        ppos = [jnp.asarray(m.vertices, jnp.float32) for m in ms[:k]]
        t0 = time.perf_counter()
        jax.block_until_ready([vertex_normals(s, p) for s, p in zip(parts, ppos)])
        compile_loop = time.perf_counter() - t0
        ts = []
        for _ in range(max(1, args.repeat // 2)):
            t0 = time.perf_counter()
            jax.block_until_ready([vertex_normals(s, p) for s, p in zip(parts, ppos)])
            ts.append(time.perf_counter() - t0)
        t = statistics.median(ts)
        # the loop's meshes are small (cache-resident): also compare with the face-list batch of
        # the SAME meshes, not only with the big batch's per-vertex time
        sub = B._union(ms[:k])
        sp, sf = jnp.asarray(sub.vertices, jnp.float32), jnp.asarray(sub.faces)
        t_sub, *_ = timepair(lambda: face_list_vertex_normals(sp, sf), lambda: sp, args.repeat)
        emit(what="normals", impl=f"loop/{name}", meshes=k, vertices=nv_loop, seconds=t,
             ns_per_vertex=1e9 * t / nv_loop, vs_face_list=(t / nv_loop) / (base_normals / nv),
             vs_face_list_same_meshes=t / t_sub, face_list_same_meshes_s=t_sub,
             first_pass_with_compiles_s=compile_loop)

        q = jax.jit(lambda s, m, c: s.query("target", m, c))
        t0 = time.perf_counter()
        jax.block_until_ready(q(b, qm_j, qd_j))
        first = time.perf_counter() - t0
        t_fl, t, *_ = timepair(lambda: face_list_target(faces, foff, voff, qm_j, qd_j),
                           lambda: q(b, qm_j, qd_j), args.repeat)
        same = bool(np.array_equal(np.asarray(q(b, qm_j, qd_j)), want_target))
        emit(what="target", impl=f"packed/{name}", queries=args.queries, seconds=t,
             ns_per_query=1e9 * t / args.queries, vs_face_list=t / t_fl, face_list_interleaved_s=t_fl,
             first_call_s=first, equal_to_face_list=same)
        del b, parts
    if args.structures:
        run_compact(args, ms, emit)
    return rows


def run_compact(args, ms, emit):
    """Compact kinds (``--structures``: CDS family shifted, LR local evaluation): built per mesh
    and joined with ``concatenate`` on the first ``--compact-meshes`` meshes (per-mesh builds are
    sequential numba/numpy: the whole 10,000-mesh batch takes too long to build for LR on a
    2-core box); normals on the packed batch against the face-list batch of the SAME meshes
    (interleaved), and against a Python loop; Target on valid local darts."""
    from jaxcds.structures import registry

    k = len(ms) if args.compact_meshes <= 0 else min(args.compact_meshes, len(ms))
    sub = ms[:k]
    u = B._union(sub)
    nv = u.num_vertices
    faces = jnp.asarray(u.faces)
    upos = np.asarray(u.vertices)
    fl_pos = jnp.asarray(upos, jnp.float32)
    for name in args.structures.split(","):
        t0 = time.perf_counter()
        parts = [registry.build(name, m) for m in sub]
        t_parts = time.perf_counter() - t0
        t0 = time.perf_counter()
        b = B.concatenate(parts)
        t_cat = time.perf_counter() - t0
        emit(what="build", impl=f"per-mesh/{name}", meshes=k, vertices=nv, seconds=t_parts)
        emit(what="build", impl=f"concatenate/{name}", meshes=k, vertices=nv, seconds=t_cat)
        order = b.vertex_order
        pos = jnp.asarray(upos if order is None else upos[np.asarray(order)], jnp.float32)
        f = jax.jit(lambda s, p: vertex_normals(s, p))
        t0 = time.perf_counter()
        got = jax.block_until_ready(f(b, pos))
        first = time.perf_counter() - t0
        t, vs = against_face_list(lambda: face_list_vertex_normals(fl_pos, faces), lambda: f(b, pos),
                                  args.repeat)
        want = np.asarray(face_list_vertex_normals(fl_pos, faces))
        want = want if order is None else want[np.asarray(order)]
        err = float(np.max(np.abs(np.asarray(got) - want)))
        emit(what="normals", impl=f"packed/{name}", meshes=k, vertices=nv, seconds=t,
             ns_per_vertex=1e9 * t / nv, **vs, first_call_s=first, max_abs_diff_vs_face_list=err)
        # Python loop over the first --loop-meshes meshes (each mesh's static roots / sizes are
        # jit-static: one compilation per mesh, timed apart)
        kl = min(args.loop_meshes, k)
        lp = [jnp.asarray(m.vertices if p.vertex_order is None else m.vertices[p.vertex_order], jnp.float32)
              for p, m in zip(parts[:kl], sub[:kl])]
        t0 = time.perf_counter()
        jax.block_until_ready([vertex_normals(p, x) for p, x in zip(parts[:kl], lp)])
        compile_loop = time.perf_counter() - t0
        ts = []
        for _ in range(max(1, args.repeat // 2)):
            t0 = time.perf_counter()
            jax.block_until_ready([vertex_normals(p, x) for p, x in zip(parts[:kl], lp)])
            ts.append(time.perf_counter() - t0)
        tl = statistics.median(ts)
        nvl = sum(p.num_vertices for p in parts[:kl])
        emit(what="normals", impl=f"loop/{name}", meshes=kl, vertices=nvl, seconds=tl,
             ns_per_vertex=1e9 * tl / nvl, vs_face_list=(tl / nvl) / (vs["face_list_interleaved_s"] / nv),
             first_pass_with_compiles_s=compile_loop)
        # Target on valid local darts (edge_of_vertex of random local vertices)
        qrng = np.random.default_rng(2)
        qm = qrng.integers(0, k, args.queries).astype(np.int32)
        nvs = np.array([p.num_vertices for p in parts])
        qv = (qrng.random(args.queries) * nvs[qm]).astype(np.int32)
        qm_j = jnp.asarray(qm)
        qd_j = jax.jit(lambda s, m, v: s.query("edge_of_vertex", m, v))(b, qm_j, jnp.asarray(qv))
        q = jax.jit(lambda s, m, c: s.query("target", m, c))
        t0 = time.perf_counter()
        jax.block_until_ready(q(b, qm_j, qd_j))
        first = time.perf_counter() - t0
        _, t = timeit(lambda: q(b, qm_j, qd_j), args.repeat)
        emit(what="target", impl=f"packed/{name}", meshes=k, queries=args.queries, seconds=t,
             ns_per_query=1e9 * t / args.queries, first_call_s=first)
        del b, parts


def table(rows, args) -> str:
    lines = [f"Packed batches: {args.meshes} random planar triangulations of {args.min}-{args.max} "
             f"vertices ({rows[0]['vertices']:,} vertices), {platform.processor() or platform.machine()}, "
             f"{os.cpu_count()} cores, jax {jax.__version__} {jax.default_backend()}; "
             f"`python benchmarks/bench_batch.py --meshes {args.meshes}`", "",
             "| measure | implementation | time | per vertex / query | vs face-list |", "|---|---|---|---|---|"]
    for r in rows:
        if r["what"] in ("normals", "target"):
            per = r.get("ns_per_vertex", r.get("ns_per_query"))
            vs = r.get("vs_face_list")
            same = r.get("vs_face_list_same_meshes")
            fastest = r.get("vs_face_list_min")
            pm, plo, phi = (r.get(k) for k in ("vs_face_list_paired", "vs_face_list_paired_low",
                                               "vs_face_list_paired_high"))
            lines.append(f"| {r['what']} | {r['impl']} | {r['seconds'] * 1e3:.1f} ms | {per:.2f} ns | "
                         f"{'' if vs is None else f'{vs:.2f}x'}"
                         f"{'' if fastest is None else f' (fastest runs {fastest:.2f}x)'}"
                         f"{'' if pm is None else f'; paired {pm:.2f}x'}"
                         f"{'' if plo is None else f' ({plo:.2f}-{phi:.2f})'}"
                         f"{'' if same is None else f' ({same:.2f}x vs face-list of the same meshes)'} |")
        elif r["what"] == "build":
            lines.append(f"| build | {r['impl']} | {r['seconds']:.2f} s "
                         f"({r['vertices']:,} vertices) | {1e9 * r['seconds'] / r['vertices']:.0f} ns | |")
    return "\n".join(lines)


@clean_exit
def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--meshes", type=at_least_one, default=300)
    p.add_argument("--min", type=int, default=500)
    p.add_argument("--max", type=int, default=5000)
    p.add_argument("--loop-meshes", type=int, default=100, help="meshes timed in the Python loop")
    p.add_argument("--queries", type=int, default=1_000_000)
    p.add_argument("--repeat", type=at_least_one, default=5)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-check", action="store_true", help="do not time the validation of the union")
    p.add_argument("--structures", default="cds5n,lr",
                   help="compact kinds packed with concatenate (comma list; '' for none)")
    p.add_argument("--compact-meshes", type=int, default=0,
                   help="meshes in the compact batches (the first K; 0: all)")
    p.add_argument("--json", help="also write the rows to this file")
    args = p.parse_args(argv)
    rows = run(args)
    print(table(rows, args))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"args": vars(args), "rows": rows}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
