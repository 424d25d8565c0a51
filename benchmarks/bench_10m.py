"""Every structure of the registry end to end on one big mesh (default 10M vertices), one fresh
child process per structure: build, degrees, normals, their gradient and batched Target, with
wall time and peak RSS per step. The project brief: "A 10M-vertex mesh must fit (24 GiB): watch
peak memory."

    /usr/bin/time -v python benchmarks/bench_10m.py --json benchmarks/bench_10m_DATE.json
    python benchmarks/bench_10m.py --vertices 200000 --structures halfedge cds5n   # minutes

The parent draws one uniform random planar triangulation (Poulalhon-Schaeffer,
``random_planar_triangulation(N, seed=0)``: float64 positions, int32 faces, as
:class:`jaxcds.mesh.TriMesh` holds them) once, saves it as ``.npy`` files in a temporary folder,
and runs ``python bench_10m.py --child NAME`` for each structure: peak RSS is then that
structure's alone, and a child that dies (OOM killer, exception, ``--timeout``) is reported with
its exit status and the last lines of its stderr while the others go on. Each child:

1. loads the mesh (``TriMesh`` of the saved arrays, no copy);
2. ``build``: ``registry.build(name, mesh)`` (mesh checks included), ``block_until_ready``;
   the mesh's faces are then dropped (the degree reference, a ``bincount`` of them, is kept),
   positions kept as float32 in the structure's vertex order (``s.vertex_order``);
3. ``degrees``: ``vertex_degrees(s)``, checked against the face count of each vertex (the mesh
   is closed);
4. ``normals``: ``vertex_normals(s, positions)`` (scatter route), checked finite and of unit
   length;
5. ``grad``: ``jax.grad(lambda p: sum(vertex_normals(s, p) * w))(positions)`` for a fixed
   random ``w``;
6. ``darts``: ``--queries`` random valid darts (``s.all_darts()``, as ``race_queries.py`` draws
   them);
7. ``target``: ``s.target(darts)`` jitted, checked against ``origin(next(e))`` on the first
   10,000 darts; ns per query = median of ``--repeats`` runs after the first.

Steps 3-5 and 7 are compiled ahead of time (``jax.jit(f).lower(...).compile()``): "first" is
compile + first run, "second" a second run; the compiled program's ``memory_analysis()``
(argument / output / temporary bytes XLA planned) is recorded with them. Before each step the
peak RSS is reset (``5`` written to ``/proc/self/clear_refs``); after it the absolute ``VmHWM``
(everything the child holds: structure, positions, JAX's buffers, compiled code) and its
increase over the ``VmRSS`` before the step are recorded; the child's peak is the largest of
them (its ``ru_maxrss`` at exit, also kept, is only the last step's: ``clear_refs`` resets it).
Results go to ``--json`` (rewritten after each structure) and a markdown table to stdout.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import pathlib
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from typing import Optional, Sequence

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:  # run as a script from anywhere
    sys.path.insert(0, str(HERE.parent))
from benchmarks.script_errors import at_least_one, clean_exit  # noqa: E402

from benchmarks.harness import _proc_status, _reset_peak_rss, machine_info  # noqa: E402

__all__ = ["main", "run", "to_markdown"]

GIB, MIB = 2.0 ** 30, 2.0 ** 20
STEPS = ("load", "build", "degrees", "normals", "grad", "darts", "target")


def _log(msg: str) -> None:
    print(f"[bench_10m] {msg}", file=sys.stderr, flush=True)


# ------------------------------------------------------------------------------------- child
def _peak_during(fn):
    """Run ``fn`` once; ``(result, seconds, absolute VmHWM bytes, VmHWM - VmRSS before)``
    (``None`` for the last two where ``/proc/self/clear_refs`` cannot be written)."""
    before = _proc_status().get("VmRSS")
    ok = _reset_peak_rss()
    t0 = time.perf_counter()
    res = fn()
    dt = time.perf_counter() - t0
    hwm = _proc_status().get("VmHWM") if ok else None
    inc = (hwm - before) if (hwm is not None and before is not None) else None
    return res, dt, hwm, inc


def _memory_analysis(compiled) -> Optional[dict]:
    try:
        ma = compiled.memory_analysis()
    except Exception:  # pragma: no cover - backends without it
        return None
    if ma is None:
        return None
    keys = ("argument_size_in_bytes", "output_size_in_bytes", "temp_size_in_bytes",
            "alias_size_in_bytes", "generated_code_size_in_bytes")
    return {k: int(getattr(ma, k)) for k in keys if hasattr(ma, k)}


def _compiled_step(fn, args, repeats: int = 1) -> tuple[dict, object]:
    """``fn`` compiled ahead of time on ``args``: first call (compile + run) and ``repeats``
    later runs, each with its own peak RSS; returns ``(row, result)``."""
    import jax

    def first():
        t0 = time.perf_counter()
        c = jax.jit(fn).lower(*args).compile()
        compile_s = time.perf_counter() - t0
        return c, compile_s, jax.block_until_ready(c(*args))

    (c, compile_s, out), first_s, hwm1, inc1 = _peak_during(first)
    row = {"compile_s": compile_s, "first_s": first_s, "peak_first_bytes": hwm1,
           "peak_first_increase_bytes": inc1, "xla_memory": _memory_analysis(c)}
    del out
    times, hwm2, inc2 = [], None, None
    for _ in range(max(repeats, 1)):
        out, dt, h, i = _peak_during(lambda: jax.block_until_ready(c(*args)))
        times.append(dt)
        hwm2 = h if hwm2 is None or (h is not None and h > hwm2) else hwm2
        inc2 = i if inc2 is None or (i is not None and i > inc2) else inc2
    row.update(second_s=times[0], median_s=statistics.median(times), min_s=min(times),
               runs=len(times), peak_second_bytes=hwm2, peak_second_increase_bytes=inc2)
    peaks = [p for p in (hwm1, hwm2) if p is not None]
    row["peak_bytes"] = max(peaks) if peaks else None
    return row, out


def child(name: str, folder: str, queries: int, repeats: int, seed: int) -> int:
    """One structure, every step; the row is rewritten to ``folder/NAME.json`` after each step
    (a child killed mid-way leaves the steps it finished)."""
    out_path = pathlib.Path(folder) / f"{name}.json"
    row = {"structure": name, "pid": os.getpid(), "steps": {}, "done": False}

    def save():
        tmp = out_path.with_suffix(".tmp")
        tmp.write_text(json.dumps(row, indent=1))
        os.replace(tmp, out_path)

    def step(what, rec):
        row["steps"][what] = rec
        save()
        peak = rec.get("peak_bytes")
        _log(f"{name}: {what} " + ", ".join(
            f"{k} {v:.3f}" for k, v in rec.items()
            if (k == "seconds" or k.endswith("_s")) and isinstance(v, float))
             + (f", peak {peak / GIB:.2f} GiB" if peak else ""))

    save()
    import jax
    import jax.numpy as jnp

    from jaxcds.algorithms import vertex_degrees, vertex_normals
    from jaxcds.mesh import TriMesh
    from jaxcds.structures import registry

    def load():
        v = np.load(os.path.join(folder, "vertices.npy"))
        f = np.load(os.path.join(folder, "faces.npy"))
        return TriMesh(vertices=v, faces=f, source="bench_10m")

    mesh, dt, hwm, inc = _peak_during(load)
    n = mesh.num_vertices
    row.update(vertices=n, faces=mesh.num_faces)
    step("load", {"seconds": dt, "peak_bytes": hwm, "peak_increase_bytes": inc,
                  "positions_dtype": str(mesh.vertices.dtype), "faces_dtype": str(mesh.faces.dtype)})

    s, dt, hwm, inc = _peak_during(lambda: jax.block_until_ready(registry.build(name, mesh)))
    row.update(nbytes=int(s.nbytes), references=int(s.references),
               references_per_vertex=float(s.references_per_vertex), bytes_per_vertex=s.nbytes / n,
               num_darts=int(s.num_darts))
    step("build", {"seconds": dt, "peak_bytes": hwm, "peak_increase_bytes": inc,
                   "structure_bytes": int(s.nbytes)})

    order = s.vertex_order
    o = None if order is None else np.asarray(order)
    deg_ref = np.bincount(mesh.faces.ravel(), minlength=n).astype(np.int32)
    pos = np.ascontiguousarray(mesh.vertices, np.float32)
    w = np.random.default_rng(seed + 1).standard_normal((n, 3)).astype(np.float32)
    if o is not None:
        deg_ref, pos, w = deg_ref[o], pos[o], w[o]
    del mesh  # from here on the child holds the structure, positions, w and the reference
    pos, w = jnp.asarray(pos), jnp.asarray(w)

    rec, deg = _compiled_step(lambda s: vertex_degrees(s), (s,))
    rec["ok"] = bool(np.array_equal(np.asarray(deg), deg_ref))
    del deg, deg_ref
    step("degrees", rec)

    rec, nrm = _compiled_step(lambda s, p: vertex_normals(s, p), (s, pos))
    nrm = np.asarray(nrm)
    lengths = np.sqrt(np.sum(nrm.astype(np.float64) ** 2, axis=1))
    rec["ok"] = bool(np.isfinite(nrm).all() and np.max(np.abs(lengths - 1)) < 1e-4)
    del nrm, lengths
    step("normals", rec)

    grad = jax.grad(lambda p, s, w: jnp.sum(vertex_normals(s, p) * w))
    rec, g = _compiled_step(grad, (pos, s, w))
    g = np.asarray(g)
    rec["ok"] = bool(np.isfinite(g).all() and g.shape == (n, 3))
    del g
    step("grad", rec)

    def draw():
        darts = np.asarray(s.all_darts())
        rng = np.random.default_rng(seed + 2)
        return jnp.asarray(darts[rng.integers(0, darts.size, queries)].astype(np.int32))

    e, dt, hwm, inc = _peak_during(draw)
    step("darts", {"seconds": dt, "peak_bytes": hwm, "peak_increase_bytes": inc, "queries": queries})

    rec, t = _compiled_step(lambda s, e: s.target(e), (s, e), repeats)
    k = min(10_000, queries)
    want = np.asarray(s.origin(s.next(e[:k])))
    rec["ok"] = bool(np.array_equal(np.asarray(t)[:k], want))
    rec["ns_per_query"] = 1e9 * rec["median_s"] / queries
    rec["queries"] = queries
    step("target", rec)
    row["done"] = True
    save()
    return 0


# ------------------------------------------------------------------------------------ parent
def _run_child(name: str, folder: str, args) -> dict:
    """``--child NAME`` in a fresh interpreter; its row (as far as it got), exit status, last
    stderr lines, lifetime peak RSS (``ru_maxrss``) and wall seconds."""
    cmd = [sys.executable, str(pathlib.Path(__file__).resolve()), "--child", name, "--workdir", folder,
           "--queries", str(args.queries), "--repeats", str(args.repeats), "--seed", str(args.seed)]
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(HERE.parent), env.get("PYTHONPATH")) if p)
    tail: collections.deque = collections.deque(maxlen=args.tail)
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env, text=True,
                         errors="replace")

    def pump():  # echo the child's log and keep its last lines
        for line in p.stderr:
            sys.stderr.write(line)
            sys.stderr.flush()
            tail.append(line.rstrip("\n"))

    reader = threading.Thread(target=pump, daemon=True)
    reader.start()
    killed = []
    timer = None
    if args.timeout:
        def kill():
            killed.append(True)
            try:
                os.kill(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        timer = threading.Timer(args.timeout, kill)
        timer.start()
    _, status, usage = os.wait4(p.pid, 0)
    p.returncode = os.waitstatus_to_exitcode(status)  # reaped here: Popen must not wait again
    if timer is not None:
        timer.cancel()
    reader.join(timeout=10)
    wall = time.perf_counter() - t0
    path = pathlib.Path(folder) / f"{name}.json"
    try:
        row = json.loads(path.read_text())
    except (OSError, ValueError):
        row = {"structure": name, "steps": {}, "done": False}
    rc = p.returncode
    # ru_maxrss of a child is its mm's high-water mark at exit, which clear_refs resets: the peak
    # since the last step began, not of the lifetime; the lifetime peak is the largest step peak
    peaks = [st.get("peak_bytes") for st in row.get("steps", {}).values()]
    peaks = [x for x in peaks if x is not None]
    row.update(exit_status=rc, child_wall_s=wall, peak_bytes=max(peaks) if peaks else None,
               maxrss_at_exit_bytes=usage.ru_maxrss * 1024)
    if rc != 0 or not row.get("done"):
        steps = row.get("steps", {})
        failed = next((st for st in STEPS if st not in steps), None)
        if killed:
            why = f"killed after --timeout {args.timeout:g} s"
        elif rc < 0:
            oom = ", the OOM killer's signal" if rc == -signal.SIGKILL else ""
            why = f"killed by signal {-rc} ({signal.Signals(-rc).name}{oom})"
        else:
            why = f"exit status {rc}"
        row.update(failed_step=failed, failure=why, stderr_tail=list(tail))
        _log(f"{name}: FAILED in step {failed!r}: {why}")
    return row


def run(vertices: int, structures: Sequence[str], args, json_path=None) -> dict:
    from jaxcds.generators import random_planar_triangulation

    t_start = time.perf_counter()
    doc = {"machine": machine_info(), "command": " ".join(sys.argv),
           "settings": {"vertices": vertices, "structures": list(structures), "queries": args.queries,
                        "repeats": args.repeats, "seed": args.seed, "timeout": args.timeout},
           "rows": []}
    folder = args.workdir or tempfile.mkdtemp(prefix="bench_10m_")
    os.makedirs(folder, exist_ok=True)
    try:
        m, dt, hwm, inc = _peak_during(lambda: random_planar_triangulation(vertices, seed=args.seed))
        t0 = time.perf_counter()
        np.save(os.path.join(folder, "vertices.npy"), m.vertices)
        np.save(os.path.join(folder, "faces.npy"), m.faces)
        doc["generate"] = {"vertices": m.num_vertices, "faces": m.num_faces, "seconds": dt,
                           "save_s": time.perf_counter() - t0, "peak_bytes": hwm,
                           "peak_increase_bytes": inc, "positions_dtype": str(m.vertices.dtype),
                           "faces_dtype": str(m.faces.dtype), "folder": folder}
        _log(f"generated {m.num_vertices} vertices, {m.num_faces} faces in {dt:.2f} s "
             f"({m.vertices.dtype} positions, {m.faces.dtype} faces), saved in {folder}")
        del m
        for name in structures:
            _log(f"--- {name}")
            doc["rows"].append(_run_child(name, folder, args))
            doc["total_s"] = time.perf_counter() - t_start
            if json_path:
                _write(json_path, doc)
    finally:
        if not args.workdir and not args.keep:
            shutil.rmtree(folder, ignore_errors=True)
    doc["total_s"] = time.perf_counter() - t_start
    if json_path:
        _write(json_path, doc)
    return doc


def _write(path, doc) -> None:
    path = pathlib.Path(path)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(doc, indent=1) + "\n")
    os.replace(tmp, path)


def _gib(x) -> str:
    return "-" if x is None else f"{x / GIB:.2f}"


def _s(x) -> str:
    return "-" if x is None else (f"{x:.2f}" if x >= 0.1 else f"{x:.3f}")


def _two(rec) -> str:
    if not rec:
        return "-"
    return f"{_s(rec.get('first_s'))} / {_s(rec.get('second_s'))}"


def to_markdown(doc: dict) -> str:
    g = doc.get("generate", {})
    lines = [f"{g.get('vertices', '?'):,} vertices, {g.get('faces', '?'):,} faces; "
             f"{doc['machine'].get('cpu')}, {doc['machine'].get('cores')} cores; "
             f"total {doc.get('total_s', 0):.0f} s. Times first (compile + run) / second run; "
             "peaks are absolute VmHWM of the structure's own process.", "",
             "| structure | build s | build peak GiB | degrees s | normals s | normals peak GiB "
             "| grad s | grad peak GiB | Target ns/query | structure MiB | refs/vertex "
             "| child peak GiB | status |",
             "|---|" + "---:|" * 11 + "---|"]
    for r in doc["rows"]:
        st = r.get("steps", {})
        b, d, nm, gr, t = (st.get(k, {}) for k in ("build", "degrees", "normals", "grad", "target"))
        checks = [k for k in ("degrees", "normals", "grad", "target") if st.get(k, {}).get("ok") is False]
        if r.get("failure"):
            status = f"FAILED in {r.get('failed_step')}: {r['failure']}"
        elif checks:
            status = "wrong: " + ", ".join(checks)
        else:
            status = "ok"
        nb = r.get("nbytes")
        rpv = r.get("references_per_vertex")
        lines.append(
            f"| {r['structure']} | {_s(b.get('seconds'))} | {_gib(b.get('peak_bytes'))} | {_two(d)} "
            f"| {_two(nm)} | {_gib(nm.get('peak_bytes'))} | {_two(gr)} | {_gib(gr.get('peak_bytes'))} "
            f"| {'-' if 'ns_per_query' not in t else format(t['ns_per_query'], '.1f')} "
            f"| {'-' if nb is None else format(nb / MIB, '.1f')} "
            f"| {'-' if rpv is None else format(rpv, '.2f')} "
            f"| {_gib(r.get('peak_bytes'))} | {status} |")
    return "\n".join(lines)


@clean_exit
def main(argv: Optional[Sequence[str]] = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--vertices", type=int, default=10_000_000)
    p.add_argument("--structures", nargs="+", default=None, help="registry names (default: all)")
    p.add_argument("--queries", type=int, default=1_000_000, help="random darts for Target")
    p.add_argument("--repeats", type=at_least_one, default=5, help="timed Target runs after the first")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--timeout", type=float, default=0, help="seconds per structure (0: none)")
    p.add_argument("--json", help="write the results here")
    p.add_argument("--workdir", help="folder for the mesh files (default: a temporary one)")
    p.add_argument("--keep", action="store_true", help="keep the temporary folder")
    p.add_argument("--tail", type=int, default=25, help="stderr lines kept of a failed child")
    p.add_argument("--child", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        return child(args.child, args.workdir, args.queries, args.repeats, args.seed)
    from jaxcds.structures import registry

    names = registry.names()
    structures = args.structures or names
    unknown = [s for s in structures if s not in names]
    if unknown:
        p.error(f"--structures: unknown {', '.join(unknown)}; available: {', '.join(names)}")
    if args.vertices < 4:
        p.error("--vertices must be >= 4")
    if args.queries < 1 or args.repeats < 1:
        p.error("--queries and --repeats must be >= 1")
    doc = run(args.vertices, structures, args, args.json)
    print(to_markdown(doc))
    return 0 if all(r.get("exit_status") == 0 and r.get("done") for r in doc["rows"]) else 1


if __name__ == "__main__":
    sys.exit(main())
