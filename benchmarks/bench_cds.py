"""CDS benchmarks (Castelli Aleardi & Devillers, JoCG 2018): the paper's Table 2 (construction)
and Table 3 / Fig. 14 (navigation) in our setting, for every Schnyder-wood structure of the
registry (``cds*``), the half-edge and the corner table as peers, and the plain-JAX face list.

Measured per mesh, each a median of ``--repeats`` runs after a warm-up (numba and XLA
compilation reported apart, ``block_until_ready`` on every JAX result):

* construction from the ``(F, 3)`` face array: the maximal Schnyder wood (Appendix A), then each
  structure from the wood (``from_wood``), in seconds and faces per second (end to end = wood +
  structure); peak RSS increase during the build (Linux ``VmHWM`` after ``clear_refs``);
* memory: navigation references per vertex (Thm 2/4/5/6: 6, 5, 4, 5) and with the face map
  (Thm 7: +1), bytes per vertex;
* vertex degrees and vertex normals (``scatter`` formulation) in ns per vertex, and the normals'
  ratio to the plain-JAX face-list normals measured in the same run;
* batched queries on random darts / vertex pairs: Target, Adjacent (half true pairs),
  Face_left, in ns per query, and the ratio to the half-edge.
* ``--stages``: ``build_cds`` stage by stage per structure -- mesh checks (validation, holes,
  genus), maximal wood, tables -- in wall seconds, faces per wall second with and without the
  checks, faces per CPU second of wood + tables (the stable figure on a shared, loaded machine)
  and the process's absolute peak RSS.

Usage::

    .venv/bin/python -m benchmarks.bench_cds --meshes random:100000 bunny.off --repeats 5
    .venv/bin/python -m benchmarks.bench_cds --quick          # seconds, for smoke tests
    .venv/bin/python -m benchmarks.bench_cds --json out.json  # machine-readable
    # build_cds stage by stage (checks / wood / tables, absolute peak RSS), e.g. 10M vertices:
    .venv/bin/python -m benchmarks.bench_cds --meshes random:10000000:1 --stages \
        --no-construction --no-navigation --repeats 1

Meshes: ``random:N[:SEED]`` (Poulalhon--Schaeffer uniform random planar triangulation),
``icosphere:S``, or a path (holed genus-0 meshes are closed with dummy vertices first).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from typing import Optional, Sequence

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
if os.path.dirname(HERE) not in sys.path:  # run as a script from anywhere
    sys.path.insert(0, os.path.dirname(HERE))
from benchmarks.script_errors import at_least_one, clean_exit  # noqa: E402

from benchmarks.harness import (_proc_status, _reset_peak_rss, load_bench_mesh,  # noqa: E402
                                machine_info, time_compiled)

__all__ = ["main", "run", "bench_construction", "bench_navigation"]

PEERS = ("halfedge", "corner-table")


def _log(msg: str) -> None:
    print(f"[bench_cds] {msg}", file=sys.stderr, flush=True)


def _cds_classes():
    from jaxcds.structures import cds, registry

    out = {}
    for name in registry.names():
        if not name.startswith("cds"):
            continue
        for cls_name in ("CDS6n", "CDS5n", "CDS4n", "CDS5nO1"):
            cls = getattr(cds, cls_name, None)
            if cls is not None and getattr(cls, "name", None) == name:
                out[name] = cls
    return out


def _median_time(fn, repeats: int) -> tuple[float, float, object]:
    """(first call seconds, median seconds of ``repeats`` later calls, last result)."""
    t0 = time.perf_counter()
    res = fn()
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = fn()
        times.append(time.perf_counter() - t0)
    return first, statistics.median(times), res


def _peak_during(fn):
    """Run ``fn`` once; return (result, seconds, peak RSS increase in bytes or None)."""
    before = _proc_status().get("VmRSS")
    ok = _reset_peak_rss()
    t0 = time.perf_counter()
    res = fn()
    dt = time.perf_counter() - t0
    after = _proc_status().get("VmHWM")
    peak = (after - before) if (ok and before is not None and after is not None) else None
    return res, dt, peak


def _prepare(mesh):
    from jaxcds.mesh import close_boundaries, boundary_loops

    if boundary_loops(mesh):
        return close_boundaries(mesh), True
    return mesh, False


def bench_construction(mesh_name: str, mesh, repeats: int) -> list[dict]:
    """Table 2: face array -> maximal Schnyder wood -> each CDS."""
    from jaxcds.construct.schnyder import schnyder_wood

    f = np.ascontiguousarray(mesh.faces, np.int32)
    n, nf = mesh.num_vertices, mesh.num_faces
    first, wood_s, wood = _median_time(lambda: schnyder_wood(f, n), repeats)
    _, _, wood_peak = _peak_during(lambda: schnyder_wood(f, n))
    rows = [{"mesh": mesh_name, "step": "schnyder_wood", "vertices": n, "faces": nf,
             "median_s": wood_s, "first_call_s": first, "mfaces_per_s": nf / wood_s / 1e6,
             "peak_rss_bytes": wood_peak}]
    _log(f"{mesh_name}: wood {wood_s:.3f} s ({nf / wood_s / 1e6:.2f} M faces/s)")
    for name, cls in _cds_classes().items():
        first, s_time, s = _median_time(lambda: cls.from_wood(wood), repeats)

        def end_to_end():
            return cls.from_wood(schnyder_wood(f, n))

        s2, total_once, peak = _peak_during(end_to_end)
        total = wood_s + s_time
        rows.append({"mesh": mesh_name, "step": f"{name}.from_wood", "vertices": n, "faces": nf,
                     "median_s": s_time, "first_call_s": first, "end_to_end_s": total,
                     "mfaces_per_s": nf / total / 1e6, "peak_rss_bytes": peak,
                     "navigation_refs_per_vertex": _nav_refs(s) / n,
                     "refs_per_vertex": s.references / n, "bytes_per_vertex": s.nbytes / n})
        _log(f"  {name}: from_wood {s_time:.3f} s, face array -> {name} {total:.3f} s "
             f"({nf / total / 1e6:.2f} M faces/s), {s.references / n:.2f} refs/vertex")
    return rows


def bench_build_stages(mesh_name: str, mesh, repeats: int = 1) -> list[dict]:
    """``build_cds`` stage by stage, per structure: mesh checks (``prepare_mesh``: validation,
    holes, genus), the maximal Schnyder wood, the tables (``from_wood``); faces per second with
    and without the mesh checks, and the process's peak RSS (``VmHWM``, absolute: mesh included)
    over the build, reset before each structure. Medians of ``repeats`` runs (after a warm-up on
    a small mesh: numba compilation excluded)."""
    from jaxcds.construct.schnyder import check_wood_arrays, prepare_mesh, schnyder_wood
    from jaxcds.generators import random_planar_triangulation

    small = random_planar_triangulation(64, seed=0)
    for cls in _cds_classes().values():  # compile every kernel first
        cls.from_wood(schnyder_wood(small.faces, small.num_vertices))
    prepare_mesh(small)
    nf = mesh.num_faces
    rows = []
    for name, cls in _cds_classes().items():
        rss0 = _proc_status().get("VmRSS")
        t_chk, t_wood, t_tab, c_build, t_wcheck, peaks = [], [], [], [], [], []
        for _ in range(max(1, repeats)):
            _reset_peak_rss()
            t0 = time.perf_counter()
            m, closed = prepare_mesh(mesh, structure=name)
            t1 = time.perf_counter()
            c1 = time.process_time()
            wood = schnyder_wood(m.faces, m.num_vertices, maximal=True)
            t2 = time.perf_counter()
            # as build_cds: its own wood needs no check_wood_arrays (timed apart, below)
            s = cls.from_wood(wood, boundaries_closed=closed, check=False)
            s.refs.block_until_ready()
            t3 = time.perf_counter()
            c3 = time.process_time()
            t_chk.append(t1 - t0)
            t_wood.append(t2 - t1)
            t_tab.append(t3 - t2)
            # process CPU time of wood + tables: the figure to trust on a loaded machine
            c_build.append(c3 - c1)
            del s
            peaks.append(_proc_status().get("VmHWM"))  # the build's, before the check below
            # what a caller's own wood costs on top: from_wood(check=True)'s O(n log n) check
            t4 = time.perf_counter()
            check_wood_arrays(wood)
            t_wcheck.append(time.perf_counter() - t4)
            del wood
        peak = max(peaks) if all(peaks) else None
        chk, wd, tab, cpu, wchk = (statistics.median(x)
                                   for x in (t_chk, t_wood, t_tab, c_build, t_wcheck))
        row = {"mesh": mesh_name, "structure": name, "vertices": mesh.num_vertices, "faces": nf,
               "checks_s": chk, "wood_s": wd, "tables_s": tab, "cpu_s": cpu,
               "wood_check_s": wchk,
               "mfaces_per_s": nf / (wd + tab) / 1e6,
               "mfaces_per_cpu_s": nf / max(cpu, 1e-9) / 1e6,
               "mfaces_per_s_with_checks": nf / (chk + wd + tab) / 1e6,
               "rss_before_bytes": rss0, "peak_rss_bytes": peak}
        rows.append(row)
        _log(f"  {name}: checks {chk:.2f} s, wood {wd:.2f} s, tables {tab:.2f} s (CPU {cpu:.2f} s): "
             f"{row['mfaces_per_s']:.2f} M faces/s ({row['mfaces_per_s_with_checks']:.2f} with the "
             f"checks), peak RSS {peak / 2**30 if peak else float('nan'):.2f} GiB; a caller's own "
             f"wood's check (from_wood(check=True)) {wchk:.2f} s more")
    return rows


def stages_markdown(rows: list[dict]) -> str:
    out = ["| mesh | structure | faces | checks s | wood s | tables s | M faces/s (wood + tables) "
           "| M faces/CPU s (wood + tables) | M faces/s (with checks) | peak RSS GiB "
           "| a caller's wood's check s |",
           "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        peak = f"{r['peak_rss_bytes'] / 2**30:.2f}" if r.get("peak_rss_bytes") else ""
        out.append(f"| {r['mesh']} | {r['structure']} | {r['faces']} | {r['checks_s']:.2f} | "
                   f"{r['wood_s']:.2f} | {r['tables_s']:.2f} | {r['mfaces_per_s']:.2f} | "
                   f"{r['mfaces_per_cpu_s']:.2f} | "
                   f"{r['mfaces_per_s_with_checks']:.2f} | {peak} | "
                   f"{r.get('wood_check_s', float('nan')):.2f} |")
    return "\n".join(out)


def _nav_refs(s) -> int:
    for attr in ("navigation_references", "core_references"):
        if hasattr(s, attr):
            return int(getattr(s, attr))
    return int(s.references)


NAVIGATION_OPS = ("vertex_degrees", "vertex_normals", "target", "adjacent", "face_left")


def bench_navigation(mesh_name: str, mesh, repeats: int, queries: int, structures=None,
                     only_ops=None) -> list[dict]:
    """Table 3 / Fig. 14: degrees, normals, batched Target / Adjacent / Face_left."""
    import jax
    import jax.numpy as jnp

    from jaxcds.algorithms import adjacent, vertex_degrees, vertex_normals
    from jaxcds.algorithms.normals import face_list_vertex_normals
    from jaxcds.structures import registry

    n = mesh.num_vertices
    rows = []
    pos = np.asarray(mesh.vertices, np.float32)
    # the public function checks its host arguments before its jitted body; time_compiled
    # lowers what it is given, so the baseline is jitted whole, as bench_gpu does
    fl = time_compiled(jax.jit(face_list_vertex_normals), (jnp.asarray(pos), jnp.asarray(mesh.faces)), repeats)
    base = fl["median_s"]
    rows.append({"mesh": mesh_name, "impl": "face-list (plain JAX)", "op": "vertex_normals",
                 "ns_per_item": base / n * 1e9, "compile_s": fl["compile_s"], "ratio": 1.0})
    ops = {
        "vertex_degrees": jax.jit(lambda s: vertex_degrees(s)),
        "vertex_normals": jax.jit(lambda s, p: vertex_normals(s, p, method="scatter")),
        "target": jax.jit(lambda s, e: s.target(e)),
        "adjacent": jax.jit(lambda s, u, v: adjacent(s, u, v)),
        "face_left": jax.jit(lambda s, e: s.face_left(e)),
    }
    names = list(structures) if structures else list(PEERS) + list(_cds_classes())
    he_q = {}
    for name in names:
        s = registry.build(name, mesh)
        order = s.vertex_order
        p = jnp.asarray(pos if order is None else pos[np.asarray(order)])
        rng = np.random.default_rng(0)
        darts = s.all_darts()
        e = jnp.asarray(darts[rng.integers(0, darts.size, queries)], jnp.int32)
        e2 = jnp.asarray(darts[rng.integers(0, darts.size, queries)], jnp.int32)
        u = s.origin(e2)
        v = jnp.where(jnp.arange(queries) % 2 == 0, s.target(e2),
                      jnp.asarray(rng.integers(0, n, queries), jnp.int32))
        plan = {"vertex_degrees": ((s,), n), "vertex_normals": ((s, p), n),
                "target": ((s, e), queries), "adjacent": ((s, u, v), queries),
                "face_left": ((s, e), queries)}
        for op, (args, items) in plan.items():
            if only_ops and op not in only_ops:
                continue
            t = time_compiled(ops[op], args, repeats)
            per = t["median_s"] / items
            row = {"mesh": mesh_name, "impl": name, "op": op, "ns_per_item": per * 1e9,
                   "compile_s": t["compile_s"]}
            if op == "vertex_normals":
                row["ratio"] = t["median_s"] / base
            if name == "halfedge":
                he_q[op] = per
            elif op in he_q:
                row["ratio_to_halfedge"] = per / he_q[op]
            rows.append(row)
        _log(f"  {name}: " + ", ".join(f"{r['op']} {r['ns_per_item']:.1f} ns"
                                      for r in rows if r["impl"] == name and r["mesh"] == mesh_name))
    return rows


def run(meshes: Sequence[str], repeats: int = 5, queries: int = 1_000_000,
        navigation: bool = True, construction: bool = True, structures=None, ops=None,
        stages: bool = False) -> dict:
    res = {"machine": machine_info(), "command": " ".join(sys.argv), "construction": [],
           "navigation": [], "build_stages": []}
    try:
        res["machine"]["load_average"] = os.getloadavg()
    except OSError:
        pass
    for spec in meshes:
        name, mesh = load_bench_mesh(spec)
        mesh, closed = _prepare(mesh)
        if closed:
            name += " (holes closed)"
        _log(f"{name}: {mesh.num_vertices} vertices, {mesh.num_faces} faces")
        if stages:
            rows = bench_build_stages(name, mesh, repeats)
            res["build_stages"] += rows
            print(stages_markdown(rows), flush=True)
        if construction:
            res["construction"] += bench_construction(name, mesh, repeats)
        if navigation:
            res["navigation"] += bench_navigation(name, mesh, repeats, queries, structures, ops)
        print(to_markdown({"construction": [r for r in res["construction"] if r["mesh"] == name],
                           "navigation": [r for r in res["navigation"] if r["mesh"] == name]}),
              flush=True)
    return res


def to_markdown(res: dict) -> str:
    out = []
    if res["construction"]:
        out.append("| mesh | step | faces | median s | end-to-end s | M faces/s | refs/vertex (nav + faces) | peak RSS MiB |")
        out.append("|---|---|---|---|---|---|---|---|")
        for r in res["construction"]:
            refs = (f"{r['navigation_refs_per_vertex']:.2f} + {r['refs_per_vertex'] - r['navigation_refs_per_vertex']:.2f}"
                    if "refs_per_vertex" in r else "")
            peak = f"{r['peak_rss_bytes'] / 2**20:.0f}" if r.get("peak_rss_bytes") else ""
            out.append(f"| {r['mesh']} | {r['step']} | {r['faces']} | {r['median_s']:.3f} | "
                       f"{r.get('end_to_end_s', r['median_s']):.3f} | {r['mfaces_per_s']:.2f} | {refs} | {peak} |")
        out.append("")
    if res["navigation"]:
        out.append("| mesh | impl | op | ns/item | vs face list | vs half-edge |")
        out.append("|---|---|---|---|---|---|")
        for r in res["navigation"]:
            out.append(f"| {r['mesh']} | {r['impl']} | {r['op']} | {r['ns_per_item']:.2f} | "
                       f"{r.get('ratio', '') and format(r['ratio'], '.2f')} | "
                       f"{r.get('ratio_to_halfedge', '') and format(r['ratio_to_halfedge'], '.2f')} |")
    return "\n".join(out)


@clean_exit
def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--meshes", nargs="+", default=["random:100000", "../shared/meshes/bunny.off"])
    ap.add_argument("--repeats", type=at_least_one, default=5)
    ap.add_argument("--queries", type=int, default=1_000_000)
    ap.add_argument("--quick", action="store_true", help="tiny sizes (smoke test)")
    ap.add_argument("--no-navigation", action="store_true")
    ap.add_argument("--no-construction", action="store_true")
    ap.add_argument("--structures", nargs="+", help="navigation: these registry names only "
                    "(default: halfedge, corner-table and every cds*)")
    ap.add_argument("--ops", nargs="+", choices=NAVIGATION_OPS,
                    help="navigation: these ops only (default: all; --quick: vertex_normals target)")
    ap.add_argument("--stages", action="store_true", help="build_cds stage by stage (mesh "
                    "checks, wood, tables) with the absolute peak RSS; combine with "
                    "--no-construction --no-navigation for large meshes")
    ap.add_argument("--json", help="write the results as JSON here")
    a = ap.parse_args(argv)
    if a.quick:
        a.meshes, a.repeats, a.queries = ["random:2000"], 2, 10_000
        a.structures = a.structures or ["cds6n"]
        a.ops = a.ops or ["vertex_normals", "target"]
    res = run(a.meshes, a.repeats, a.queries, navigation=not a.no_navigation,
              construction=not a.no_construction, structures=a.structures, ops=a.ops,
              stages=a.stages)
    m = res["machine"]
    print(f"\n{m['cpu']}, {m['cores']} cores, jax {m['jax']} ({m['jax_backend']}), "
          f"load average {m.get('load_average')}, {m['date']}; command: {res['command']}")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(res, fh, indent=1, default=float)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
