"""Sharded structures on simulated CPU devices: correctness, memory per device, overhead.

    .venv/bin/python benchmarks/bench_sharding.py                       # 1M vertices, D = 1, 2, 4
    .venv/bin/python benchmarks/bench_sharding.py --vertices 200000 --devices 1 4

For every device count ``D`` one child process is started with
``XLA_FLAGS=--xla_force_host_platform_device_count=D`` (the flag must be set before JAX starts).
The child builds each structure (``--structures``: halfedge, corner-table, cds5n, lr by default)
on one uniform random planar triangulation (``jaxcds.generators.random_planar_triangulation``),
shards it with :func:`jaxcds.sharding.shard_structure` and times, after a warm-up (median of
``--repeat`` runs, ``block_until_ready``; compile time reported apart):

* ``normals``: :func:`jaxcds.sharding.sharded_vertex_normals` (scatter route), positions sharded;
* ``target``: ``--queries`` Target queries on valid darts, the batch sharded like the structure;
* ``adjacent``: ``--queries`` Adjacent(u, v) pairs (half of them edges of the mesh), sharded.

Every sharded answer is compared with the unsharded run of the same structure in the same child
(exact for ids, max abs difference for normals). Memory per device is read from the arrays
themselves: for every leaf of the sharded structure, the bytes of the shard each device holds
(``x.addressable_shards``), split into *row-sharded* leaves and *replicated* ones; compared with
``s.nbytes`` of the unsharded structure.

Caveat, printed with the table: simulated devices share the host's cores (2 on the shared
development machine), so D = 4 cannot be faster than D = 1; the numbers show correctness, memory
per device and the partitioner's overhead (collectives and padding), not a speed-up.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import statistics
import subprocess
import sys
import time
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # run as a script too
from benchmarks.script_errors import at_least_one, clean_exit  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
DEFAULT_STRUCTURES = ("halfedge", "corner-table", "cds5n", "lr")


def _timeit(fn, repeat: int):
    import jax

    t0 = time.perf_counter()
    out = jax.block_until_ready(fn())
    first = time.perf_counter() - t0
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        ts.append(time.perf_counter() - t0)
    return out, first, statistics.median(ts)


def child(args) -> list[dict]:
    """Runs inside a process whose device count is fixed; one JSON line per structure."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxcds import sharding as S
    from jaxcds.algorithms import vertex_normals
    from jaxcds.algorithms.adjacency import adjacent
    from jaxcds.generators import random_planar_triangulation
    from jaxcds.structures import registry

    d = len(jax.devices())
    dmesh = S.device_mesh()
    t0 = time.perf_counter()
    m = random_planar_triangulation(args.vertices, seed=args.seed)
    gen_s = time.perf_counter() - t0
    rng = np.random.default_rng(args.seed + 1)
    nq = args.queries
    # Adjacent pairs: half are edges (u, v) of a face, half random pairs (mostly not adjacent)
    f = m.faces[rng.integers(0, m.num_faces, nq // 2)]
    k = rng.integers(0, 3, nq // 2)
    eu, ev = f[np.arange(nq // 2), k], f[np.arange(nq // 2), (k + 1) % 3]
    ru, rv = rng.integers(0, m.num_vertices, (2, nq - nq // 2))
    au_in = np.concatenate([eu, ru]).astype(np.int32)
    av_in = np.concatenate([ev, rv]).astype(np.int32)

    rows = []
    for name in args.structures:
        r = {"devices": d, "structure": name, "vertices": m.num_vertices, "queries": nq,
             "generate_s": gen_s}
        try:
            t0 = time.perf_counter()
            s = registry.build(name, m)
            r["build_s"] = time.perf_counter() - t0
            order = s.vertex_order
            if order is None:
                pos_np, au, av = m.vertices, au_in, av_in
            else:  # structure numbering: positions permuted, query vertices relabelled
                inv = np.empty_like(np.asarray(order))
                inv[np.asarray(order)] = np.arange(order.size, dtype=inv.dtype)
                pos_np, au, av = m.vertices[np.asarray(order)], inv[au_in], inv[av_in]
            pos = jnp.asarray(pos_np, jnp.float32)
            darts = s.all_darts()
            qd = darts[rng.integers(0, darts.size, nq)].astype(np.int32)

            # unsharded reference, same process (D devices exist, arrays on device 0)
            want_n, _, r["normals_unsharded_s"] = _timeit(lambda: vertex_normals(s, pos), args.repeat)
            tq = jax.jit(lambda s, e: s.target(e))
            qd_j = jnp.asarray(qd)
            want_t, _, r["target_unsharded_s"] = _timeit(lambda: tq(s, qd_j), args.repeat)
            au_j, av_j = jnp.asarray(au), jnp.asarray(av)
            want_a, _, r["adjacent_unsharded_s"] = _timeit(lambda: adjacent(s, au_j, av_j), args.repeat)

            t0 = time.perf_counter()
            ss = jax.block_until_ready(S.shard_structure(s, dmesh))
            r["shard_s"] = time.perf_counter() - t0
            leaves = [x for x in jax.tree_util.tree_leaves(ss)]
            # by PartitionSpec, not by is_fully_replicated (with D = 1 every array is "replicated")
            split = [x for x in leaves if x.ndim > 0 and len(x.sharding.spec) and x.sharding.spec[0] is not None]
            rep = [x for x in leaves if not (x.ndim > 0 and len(x.sharding.spec) and x.sharding.spec[0] is not None)]
            per_dev = [0] * d
            for x in leaves:
                for sh in x.addressable_shards:
                    per_dev[sh.device.id % d] += sh.data.nbytes
            r.update(
                unsharded_bytes=int(s.nbytes), references=int(s.references),
                refs_per_vertex=round(s.references / s.num_vertices, 3),
                sharded_leaves=len(split), replicated_leaves=len(rep),
                sharded_bytes_per_device=int(sum(x.addressable_shards[0].data.nbytes for x in split)),
                replicated_bytes_per_device=int(sum(x.nbytes for x in rep)),
                bytes_per_device_max=int(max(per_dev)),
                bytes_per_device_vs_unsharded=max(per_dev) / max(int(s.nbytes), 1),
                replicated_leaf_shapes=sorted({str(tuple(x.shape)) for x in rep}))

            ps = S.shard_rows(pos_np.astype(np.float32), dmesh)
            got_n, r["normals_first_s"], r["normals_s"] = _timeit(
                lambda: S.sharded_vertex_normals(ss, ps), args.repeat)
            r["normals_max_abs_diff"] = float(np.abs(np.asarray(got_n)[: m.num_vertices]
                                                     - np.asarray(want_n)).max())
            qs = S.shard_rows(qd, dmesh)
            got_t, r["target_first_s"], r["target_s"] = _timeit(lambda: S._query(ss, qs, "target"),
                                                                args.repeat)
            r["target_equal"] = bool(np.array_equal(np.asarray(got_t)[:nq], np.asarray(want_t)))
            us, vs = S.shard_rows(au, dmesh), S.shard_rows(av, dmesh)
            got_a, r["adjacent_first_s"], r["adjacent_s"] = _timeit(lambda: adjacent(ss, us, vs),
                                                                    args.repeat)
            r["adjacent_equal"] = bool(np.array_equal(np.asarray(got_a)[:nq], np.asarray(want_a)))
            r["adjacent_true"] = int(np.sum(np.asarray(want_a)))
            r["answers_sharded"] = bool(not got_t.sharding.is_fully_replicated) if d > 1 else True
            for k_ in ("normals", "target"):
                r[f"{k_}_vs_unsharded"] = r[f"{k_}_s"] / r[f"{k_}_unsharded_s"]
            r["adjacent_vs_unsharded"] = r["adjacent_s"] / r["adjacent_unsharded_s"]
            r["ns_per_vertex_normals"] = 1e9 * r["normals_s"] / m.num_vertices
            r["ns_per_query_target"] = 1e9 * r["target_s"] / nq
            r["ns_per_query_adjacent"] = 1e9 * r["adjacent_s"] / nq
            del ss, s
        except Exception as exc:  # report and go on with the next structure
            r["error"] = f"{type(exc).__name__}: {exc}"[:500]
        print(json.dumps(r), flush=True)
        rows.append(r)
    return rows


def parent(args) -> list[dict]:
    rows = []
    for d in args.devices:
        env = dict(os.environ)
        env["XLA_FLAGS"] = (env.get("XLA_FLAGS", "") + f" --xla_force_host_platform_device_count={d}").strip()
        env["JAX_PLATFORMS"] = "cpu"
        env["PYTHONPATH"] = f"{ROOT}{os.pathsep}" + env.get("PYTHONPATH", "")
        cmd = [sys.executable, __file__, "--child", "--vertices", str(args.vertices), "--queries",
               str(args.queries), "--repeat", str(args.repeat), "--seed", str(args.seed),
               "--structures", *args.structures]
        t0 = time.perf_counter()
        p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=args.timeout)
        for line in p.stdout.splitlines():
            if line.startswith("{"):
                r = json.loads(line)
                rows.append(r)
                print(line, flush=True)
        if p.returncode != 0:
            print(f"# child D={d} exited {p.returncode}: {p.stderr[-2000:]}", file=sys.stderr)
        print(f"# child D={d}: {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)
    return rows


def table(rows, args) -> str:
    head = (f"Sharding: random planar triangulation of {args.vertices:,} vertices, {args.queries:,} "
            f"queries, CPU with simulated devices (`--xla_force_host_platform_device_count=D`), "
            f"{os.cpu_count()} cores ({platform.machine()}), shared machine: D devices share the "
            f"same cores, so no speed-up is expected; "
            f"`python benchmarks/bench_sharding.py --vertices {args.vertices} --queries {args.queries}`")
    lines = [head, "",
             "| structure | D | refs/vertex | MiB/device (sharded + replicated) | vs unsharded | "
             "normals ms (x unsharded) | Target ns/query (x) | Adjacent ns/query (x) | equal |",
             "|---|---|---|---|---|---|---|---|---|"]
    mib = 1 / 2**20
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['structure']} | {r['devices']} | error: {r['error'][:120]} |||||||")
            continue
        eq = r["target_equal"] and r["adjacent_equal"] and r["normals_max_abs_diff"] < 1e-4
        lines.append(
            f"| {r['structure']} | {r['devices']} | {r['refs_per_vertex']:.2f} | "
            f"{r['sharded_bytes_per_device'] * mib:.1f} + {r['replicated_bytes_per_device'] * mib:.3f} | "
            f"{r['bytes_per_device_vs_unsharded']:.3f} | "
            f"{r['normals_s'] * 1e3:.0f} ({r['normals_vs_unsharded']:.2f}x) | "
            f"{r['ns_per_query_target']:.0f} ({r['target_vs_unsharded']:.2f}x) | "
            f"{r['ns_per_query_adjacent']:.0f} ({r['adjacent_vs_unsharded']:.2f}x) | "
            f"{'yes' if eq else 'NO'} |")
    return "\n".join(lines)


@clean_exit
def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--vertices", type=int, default=1_000_000)
    p.add_argument("--queries", type=int, default=1_000_000)
    p.add_argument("--devices", type=int, nargs="+", default=[1, 2, 4])
    p.add_argument("--structures", nargs="+", default=list(DEFAULT_STRUCTURES))
    p.add_argument("--repeat", type=at_least_one, default=3)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--timeout", type=int, default=600, help="seconds per child process")
    p.add_argument("--json", help="also write the rows to this file")
    p.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        child(args)
        return 0
    rows = parent(args)
    print(table(rows, args))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"args": vars(args), "rows": rows}, fh, indent=1)
    return 0 if rows and not any("error" in r for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
