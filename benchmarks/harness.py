"""The benchmark runner behind ``jaxcds bench`` and ``python -m benchmarks``.

For every mesh and every structure of :mod:`jaxcds.structures.registry` (so structures added
later join automatically) it measures

* memory: stored references (and per vertex), bytes of the arrays, build time, and the peak RSS
  increase while building (Linux: ``/proc/self/clear_refs`` resets the high-water mark);
* jitted operations: vertex degrees, vertex normals (``scatter`` and ``gather`` formulations),
  batched ``target`` / ``face_left`` / ``adjacent`` queries. Each is compiled ahead of time
  (``jit(...).lower(...).compile()``, compile time reported apart), run once to warm up, then
  ``repeats`` times with ``block_until_ready``; the median is reported in ns per vertex (whole
  mesh operations) or ns per query (batched queries);

and the peers of :mod:`benchmarks.peers` in the same process on the same face list (plain JAX,
numba loop, trimesh, libigl, OpenMesh -- skipped with the reason when missing), plus three
face-list formulations of the normals (scatter / sorted scatter / padded gather), since
scatter-add is the slow spot of XLA:CPU (jax-ml/jax#39959).

Every normals result is compared with a float64 area-weighted reference (``max_err``), so a
benchmark of a wrong result shows up in the table.

``main(argv)`` is the CLI entry point; :func:`run` returns the results as a dict (the
``--json`` object), :func:`benchmarks.report.write_report` writes ``RESULTS.md`` and the plots.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import sys
import time
from typing import Callable, Optional, Sequence

import numpy as np

from benchmarks.script_errors import at_least_one

__all__ = ["main", "run", "load_bench_mesh", "machine_info", "time_compiled", "time_call", "time_wall_cpu",
           "DEFAULT_MESHES", "QUICK_MESHES"]

# smallest first: an op far too slow on the first mesh is skipped on the big ones (--max-call)
DEFAULT_MESHES = ["random:10000", "icosphere:8", "random:1000000"]
DEFAULT_GENERATORS = [1_000_000, 10_000_000]
QUICK_MESHES = ["random:1000"]


# ---------------------------------------------------------------------------------- utilities
def _log(msg: str) -> None:
    print(f"[bench] {msg}", file=sys.stderr, flush=True)


def _block(x):
    import jax

    return jax.block_until_ready(x)


def _budgeted(repeats: int, one_run_s: float, budget_s: Optional[float]) -> int:
    """Fewer repeats (at least 1) when ``repeats`` runs would exceed ``budget_s`` seconds."""
    if budget_s is None or one_run_s <= 0:
        return repeats
    return max(1, min(repeats, int(budget_s / one_run_s)))


def time_compiled(jitted, args: tuple, repeats: int, budget_s: Optional[float] = None) -> dict:
    """AOT-compile ``jitted`` for ``args``, warm up once, then time ``repeats`` runs (fewer if
    they would take more than ``budget_s`` seconds, judged from the warm-up run).

    Returns ``compile_s`` (lower + compile), ``median_s``, ``min_s``, ``times``."""
    t0 = time.perf_counter()
    compiled = jitted.lower(*args).compile()
    compile_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    _block(compiled(*args))
    repeats = _budgeted(repeats, time.perf_counter() - t0, budget_s)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        _block(compiled(*args))
        times.append(time.perf_counter() - t0)
    return {"compile_s": compile_s, "median_s": statistics.median(times), "min_s": min(times),
            "times": times}


def time_call(fn: Callable[[], object], repeats: int, budget_s: Optional[float] = None) -> dict:
    """Time a no-argument callable: the first call (``first_call_s``: includes any jit
    compilation) apart, then ``repeats`` runs after it (fewer beyond ``budget_s`` seconds)."""
    t0 = time.perf_counter()
    _block(fn())
    first = time.perf_counter() - t0
    if budget_s is not None:
        t0 = time.perf_counter()
        _block(fn())
        repeats = _budgeted(repeats, time.perf_counter() - t0, budget_s)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        _block(fn())
        times.append(time.perf_counter() - t0)
    med = statistics.median(times)
    return {"compile_s": max(first - med, 0.0), "first_call_s": first, "median_s": med,
            "min_s": min(times), "times": times}


def time_wall_cpu(fn: Callable[[], object], repeats: int) -> tuple:
    """Median wall time and median CPU time (``process_time``, all threads of the process) of
    ``repeats`` calls of ``fn``. For the single-threaded numba construction kernels: on a shared
    machine the CPU time is the steadier figure (wall time includes waiting for a core)."""
    wall, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return statistics.median(wall), statistics.median(cpu)


def _proc_status() -> dict:
    out = {}
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(("VmRSS:", "VmHWM:")):
                    key, val = line.split(":", 1)
                    out[key] = int(val.split()[0]) * 1024
    except OSError:
        pass
    return out


def _reset_peak_rss() -> bool:
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


def machine_info() -> dict:
    """Machine, software versions and date, for the report header."""
    import jax
    import numba

    cpu = platform.processor() or ""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        usable = os.cpu_count()
    mem = None
    try:
        with open("/proc/meminfo") as fh:
            mem = int(fh.readline().split()[1]) * 1024
    except OSError:
        pass
    return {
        "cpu": cpu,
        "cores": usable,
        "memory_bytes": mem,
        "platform": platform.platform(),
        "python": platform.python_version(),
        "jax": jax.__version__,
        "jax_backend": jax.default_backend(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
    }


def _seconds(text: str) -> float:
    """An argparse type: a finite number of seconds > 0 (NaN failed every op, exit 0)."""
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not np.isfinite(x) or x <= 0:
        raise argparse.ArgumentTypeError(f"{text} must be a finite number of seconds > 0")
    return x


#: the op names --ops takes (as prefixes): the structures' ops and the peers' normals
OP_NAMES = ("vertex_degrees", "vertex_normals", "target", "face_left", "adjacent")


def _op_prefix(text: str) -> str:
    """An argparse type: a prefix of one of :data:`OP_NAMES` (comma lists accepted)."""
    for x in (y for y in text.split(",") if y):
        if not any(op.startswith(x) for op in OP_NAMES):
            raise argparse.ArgumentTypeError(f"{x!r} is not (a prefix of) one of {', '.join(OP_NAMES)}")
    return text


# ---------------------------------------------------------------------------------- meshes
def load_bench_mesh(spec: str):
    """A benchmark mesh from a spec: ``icosphere:S``, ``random:N[:SEED]`` (Poulalhon--Schaeffer),
    ``hull:N[:SEED]``, ``square:N[:SEED]`` (Delaunay closed by a dummy vertex), or a mesh file.
    Returns ``(name, TriMesh)``."""
    from jaxcds import generators as gen
    from jaxcds.mesh import load_mesh

    kind, _, rest = spec.partition(":")
    try:
        parts = [int(float(x)) for x in rest.split(":")] if rest and kind in (
            "icosphere", "random", "hull", "square") else []
    except ValueError:
        from jaxcds import errors

        raise errors.MeshError(f"bench mesh {spec!r}: the sizes after '{kind}:' must be numbers "
                               "(icosphere:S, random:N[:SEED], hull:N[:SEED], square:N[:SEED])") from None
    if kind == "icosphere":
        m = gen.icosphere(parts[0] if parts else 3)
    elif kind == "random":
        m = gen.random_planar_triangulation(parts[0], parts[1] if len(parts) > 1 else 0)
    elif kind == "hull":
        m = gen.sphere_hull(parts[0], parts[1] if len(parts) > 1 else 0)
    elif kind == "square":
        m = gen.delaunay_square(parts[0], parts[1] if len(parts) > 1 else 0, closed=True)
    else:
        m = load_mesh(spec)
        return os.path.basename(spec), m
    return spec, m


# ---------------------------------------------------------------------------------- reference
def _reference_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit normals in float64 (numpy, ``np.add.at``): the ground truth."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    acc = np.zeros_like(v)
    for k in range(3):
        np.add.at(acc, f[:, k], fn)
    nrm = np.linalg.norm(acc, axis=1, keepdims=True)
    return np.divide(acc, nrm, out=np.zeros_like(acc), where=nrm > 0)


def _max_err(result, ref: np.ndarray, order: Optional[np.ndarray] = None) -> float:
    r = np.asarray(result, np.float64)
    if order is not None:  # structure numbering -> input numbering
        back = np.empty_like(r)
        back[np.asarray(order)] = r
        r = back
    return float(np.max(np.abs(r - ref)))


# ---------------------------------------------------------------------------------- structures
def _structure_ops():
    import jax

    from jaxcds.algorithms import adjacent, vertex_degrees, vertex_normals

    return {
        "vertex_degrees": jax.jit(lambda s: vertex_degrees(s)),
        "vertex_normals[scatter]": jax.jit(lambda s, p: vertex_normals(s, p, method="scatter")),
        "vertex_normals[gather]": jax.jit(lambda s, p: vertex_normals(s, p, method="gather")),
        "target": jax.jit(lambda s, e: s.target(e)),
        "face_left": jax.jit(lambda s, e: s.face_left(e)),
        "adjacent": jax.jit(lambda s, u, v: adjacent(s, u, v)),
    }


def _bench_structure(name: str, mesh, mesh_name: str, positions: np.ndarray, ref_normals,
                     args, rows: list, memory: list, skipped: list) -> None:
    import jax.numpy as jnp

    from jaxcds import errors
    from jaxcds.structures import registry

    # build twice: the first pays numba compilation; report the second
    try:
        t0 = time.perf_counter()
        registry.build(name, mesh)
        first_build = time.perf_counter() - t0
    except errors.JaxcdsError as exc:  # refuses this mesh (typed error): a skip, not a failure
        skipped.append({"mesh": mesh_name, "impl": name, "reason": str(exc)})
        _log(f"  {name}: skipped ({exc})")
        return
    except Exception as exc:  # a structure under construction must not stop the other tables
        reason = f"build failed: {type(exc).__name__}: {exc}"
        skipped.append({"mesh": mesh_name, "impl": name, "reason": reason})
        _log(f"  {name}: {reason}")
        return
    before = _proc_status().get("VmRSS")
    peak_ok = _reset_peak_rss()
    t0 = time.perf_counter()
    s = registry.build(name, mesh)
    build_s = time.perf_counter() - t0
    after = _proc_status().get("VmHWM")
    peak = (after - before) if (peak_ok and before is not None and after is not None) else None
    rss_how = "in-process"
    if args.rss == "subprocess" and args.mesh_spec is not None:
        probe = _run_probe(["build", args.mesh_spec, name])
        if probe is not None:
            build_s, peak, rss_how = probe["seconds"], probe["peak_rss_bytes"], "fresh process"
    nv = mesh.num_vertices
    memory.append({
        "mesh": mesh_name, "structure": name, "vertices": nv, "faces": mesh.num_faces,
        "references": int(s.references), "references_per_vertex": s.references / nv,
        "bytes": int(s.nbytes), "bytes_per_vertex": s.nbytes / nv,
        "build_s": build_s, "first_build_s": first_build, "peak_rss_build_bytes": peak,
        "rss_measured": rss_how,
    })
    _log(f"  {name}: {s.references / nv:.2f} refs/vertex, build {build_s:.3f} s")

    order = s.vertex_order
    pos = positions if order is None else positions[np.asarray(order)]
    # a CDS built from a mesh whose holes were closed by flagged dummy vertices (square:N)
    # answers for the open surface (Sec. 4.5 dummies left out of degrees and normals)
    open_faces = None
    if s.dummy_vertex_mask() is not None and mesh.dummy_faces is not None:
        open_faces = mesh.faces[~np.asarray(mesh.dummy_faces)]
        ref_normals = _reference_normals(mesh.vertices, open_faces)
    p = jnp.asarray(pos, dtype=args.dtype)
    rng = np.random.default_rng(0)
    darts = s.all_darts()
    q = args.queries
    e = jnp.asarray(darts[rng.integers(0, darts.size, q)], jnp.int32)
    e_adj = jnp.asarray(darts[rng.integers(0, darts.size, q)], jnp.int32)
    u = s.origin(e_adj)
    v_true = s.target(e_adj)
    v_rand = jnp.asarray(rng.integers(0, nv, q), jnp.int32)
    v = jnp.where(jnp.arange(q) % 2 == 0, v_true, v_rand)  # half adjacent, half random pairs
    ops = _structure_ops()
    plan = {
        "vertex_degrees": ((s,), nv, "vertex"),
        "vertex_normals[scatter]": ((s, p), nv, "vertex"),
        "vertex_normals[gather]": ((s, p), nv, "vertex"),
        "target": ((s, e), q, "query"),
        "face_left": ((s, e), q, "query"),
        "adjacent": ((s, u, v), q, "query"),
    }
    for op, (op_args, items, per) in plan.items():
        if args.ops and not any(op.startswith(o) for o in args.ops):
            continue
        per_item = args.seen.get((name, op))
        if per_item is not None and args.max_call_s and per_item * items > args.max_call_s:
            reason = (f"predicted {per_item * items:.3g} s per call from the smaller mesh "
                      f"({per_item * 1e9:,.0f} ns per {per}) > --max-call {args.max_call_s:g} s")
            skipped.append({"mesh": mesh_name, "impl": name, "op": op, "reason": reason})
            _log(f"  {name} {op}: skipped, {reason}")
            continue
        try:
            t = time_compiled(ops[op], op_args, args.repeats, args.budget)
        except Exception as exc:  # a structure missing an operator: report, keep going
            skipped.append({"mesh": mesh_name, "impl": name, "op": op, "reason": f"{type(exc).__name__}: {exc}"})
            _log(f"  {name} {op}: failed ({type(exc).__name__}: {exc})")
            continue
        args.seen[(name, op)] = t["median_s"] / items
        row = _row(mesh_name, name, "structure", op, items, per, t, args)
        if op.startswith("vertex_normals"):
            row["max_err"] = _max_err(ops[op](*op_args), ref_normals, order)
            if row["max_err"] > (1e-2 if args.dtype == np.float32 else 1e-8):
                _log(f"  {name} {op}: WRONG normals, max_err {row['max_err']:.2g}")
        if op == "vertex_degrees":
            deg = np.asarray(ops[op](*op_args))
            if order is not None:
                deg_back = np.empty_like(deg)
                deg_back[np.asarray(order)] = deg
                deg = deg_back
            if open_faces is not None:
                row["max_err"] = float(np.max(np.abs(deg - _edge_degrees(open_faces, nv))))
            elif _is_closed(mesh):
                ref = np.bincount(mesh.faces.ravel(), minlength=nv)  # closed meshes: faces == degree
                row["max_err"] = float(np.max(np.abs(deg - ref)))
            else:
                row["max_err"] = None
            if row["max_err"]:
                _log(f"  {name} vertex_degrees: WRONG, off by up to {row['max_err']:.0f}")
        rows.append(row)


def _edge_degrees(faces: np.ndarray, n: int) -> np.ndarray:
    """Degrees as distinct edge endpoints (open or closed surfaces; a vertex in no face: 0)."""
    f = faces.astype(np.int64)
    d = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    d = np.unique(np.sort(d, axis=1), axis=0)
    return np.bincount(d.ravel(), minlength=n)


def _is_closed(mesh) -> bool:
    f = mesh.faces.astype(np.int64)
    d = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    n = mesh.num_vertices
    return bool(np.all(np.isin(d[:, 1] * n + d[:, 0], d[:, 0] * n + d[:, 1])))


def _row(mesh_name, impl, kind, op, items, per, t, args, note="") -> dict:
    return {
        "mesh": mesh_name, "impl": impl, "kind": kind, "op": op, "per": per, "items": int(items),
        "ns_per_item": t["median_s"] / items * 1e9, "median_s": t["median_s"], "min_s": t["min_s"],
        "compile_s": t["compile_s"], "repeats": len(t["times"]), "dtype": np.dtype(args.dtype).name,
        "note": note,
    }


# ---------------------------------------------------------------------------------- peers
def _bench_peers(mesh, mesh_name, ref_normals, args, rows, skipped) -> None:
    from benchmarks import peers as P

    for pname in args.peers:
        factory = P.PEERS[pname]
        try:
            ops = factory(mesh.vertices, mesh.faces, dtype=args.dtype)
        except P.PeerUnavailable as exc:
            skipped.append({"mesh": mesh_name, "impl": pname, "reason": str(exc)})
            _log(f"  peer {pname}: skipped ({exc})")
            continue
        for op, (fn, note) in ops.items():
            if args.ops and not any(op.startswith(o) for o in args.ops):
                continue
            t = time_call(fn, args.repeats, args.budget)
            dtype_used = "float64" if pname in ("trimesh", "libigl", "openmesh") else np.dtype(args.dtype).name
            row = _row(mesh_name, pname, "peer", op, mesh.num_vertices, "vertex", t, args, note)
            row["dtype"] = dtype_used if op.startswith("vertex_normals") else "int"
            if op.startswith("vertex_normals"):
                row["max_err"] = _max_err(fn(), ref_normals)
            rows.append(row)
    if not args.ops or any("vertex_normals".startswith(o) or o.startswith("vertex_normals") for o in args.ops):
        for op, (fn, note) in P.plain_jax_variants(mesh.vertices, mesh.faces, dtype=args.dtype).items():
            t = time_call(fn, args.repeats, args.budget)
            row = _row(mesh_name, "plain-jax", "formulation", op, mesh.num_vertices, "vertex", t, args, note)
            row["max_err"] = _max_err(fn(), ref_normals)
            rows.append(row)


# ---------------------------------------------------------------------------------- run
def run(meshes: Sequence[str], structures: Optional[Sequence[str]] = None,
        peers: Optional[Sequence[str]] = None, repeats: int = 7, queries: int = 1 << 20,
        dtype: str = "float32", ops: Optional[Sequence[str]] = None, command: str = "",
        budget_s: Optional[float] = 30.0, max_call_s: Optional[float] = 60.0,
        generators: Sequence[int] = (), rss: str = "subprocess") -> dict:
    """Run the benchmarks and return the results (the ``--json`` object).

    Keys: ``machine`` (cpu, cores, versions, date), ``command``, ``settings``, ``meshes``
    (name, vertices, faces, load_s), ``timings`` (one row per mesh x implementation x op:
    ``ns_per_item`` with ``per`` = vertex or query, ``median_s``, ``compile_s``, ``max_err``
    for normals and degrees), ``memory`` (one row per mesh x structure: references,
    references_per_vertex, bytes, bytes_per_vertex, build_s, peak_rss_build_bytes), ``generators``
    (one row per sampler size), ``skipped`` (what could not run, with the reason), ``summary``
    (fastest normals implementation per mesh, scatter vs gather per structure).

    ``budget_s`` caps the timed runs of one op (fewer repeats, at least one, for slow ops);
    an op whose time per item on an earlier (smaller) mesh predicts more than ``max_call_s``
    seconds per call is skipped, with the prediction as reason. ``generators``: sizes at which
    to time the Poulalhon--Schaeffer sampler (``generators`` key of the result). ``rss``:
    ``"subprocess"`` measures build time and peak RSS of each structure in a fresh process (the
    in-process high-water mark misses memory the process already holds), ``"inprocess"`` not."""
    from benchmarks import peers as P
    from jaxcds.structures import registry

    ns = argparse.Namespace(repeats=int(repeats), queries=int(queries), dtype=np.dtype(dtype).type,
                            budget=budget_s, max_call_s=max_call_s, seen={}, rss=rss,
                            mesh_spec=None,
                            ops=list(ops or []),
                            peers=list(P.PEERS) if peers is None else list(peers))
    unknown = [p for p in ns.peers if p not in P.PEERS]
    all_structures = registry.names()
    structures = all_structures if structures is None else list(structures)
    unknown += [s for s in structures if s not in all_structures]
    if unknown:
        from jaxcds import errors

        raise errors.JaxcdsError(
            f"unknown structure or peer {', '.join(unknown)}; structures: {', '.join(all_structures)}; "
            f"peers: {', '.join(P.PEERS)}")
    out = {"machine": machine_info(), "command": command,
           "settings": {"repeats": ns.repeats, "queries": ns.queries, "dtype": np.dtype(dtype).name,
                        "structures": structures, "peers": ns.peers, "ops": ns.ops,
                        "budget_s": budget_s, "max_call_s": max_call_s},
           "meshes": [], "timings": [], "memory": [], "skipped": [], "generators": []}
    for spec in meshes:
        t0 = time.perf_counter()
        name, mesh = load_bench_mesh(spec)
        load_s = time.perf_counter() - t0
        ns.mesh_spec = spec
        _log(f"mesh {name}: {mesh.num_vertices} vertices, {mesh.num_faces} faces ({load_s:.2f} s)")
        out["meshes"].append({"name": name, "vertices": mesh.num_vertices, "faces": mesh.num_faces,
                              "load_s": load_s})
        ref = _reference_normals(mesh.vertices, mesh.faces)
        for sname in structures:
            _bench_structure(sname, mesh, name, mesh.vertices, ref, ns, out["timings"], out["memory"],
                             out["skipped"])
        _bench_peers(mesh, name, ref, ns, out["timings"], out["skipped"])
    for n in generators:
        out["generators"].append(_bench_generator(int(n)))
    out["summary"] = summarize(out)
    return out


def _bench_generator(n: int) -> dict:
    """Time (and peak RSS of) the Poulalhon--Schaeffer sampler at ``n`` vertices, in a fresh
    process (so the peak is not hidden by memory this process already holds): the faces alone,
    then the whole TriMesh with random sphere positions; degree-6 share vs CDS Sec. 4.4."""
    probe = _run_probe(["generator", str(n)])
    if probe is not None:
        _log(f"generator n={n}: faces {probe['faces_s']:.2f} s, mesh {probe['mesh_s']:.2f} s, "
             f"peak RSS {probe['peak_rss_faces_bytes'] / 2**20:.0f} MiB, degree 6: {probe['degree6_share']:.4f}")
        return probe
    return _generator_probe(n)


def _generator_probe(n: int) -> dict:
    from jaxcds import generators as gen

    gen.random_planar_triangulation_faces(16, 0)  # numba compilation / cache load
    before = _proc_status().get("VmRSS")
    ok = _reset_peak_rss()
    t0 = time.perf_counter()
    f = gen.random_planar_triangulation_faces(n, 1)
    faces_s = time.perf_counter() - t0
    after = _proc_status().get("VmHWM")
    deg6 = float(np.mean(np.bincount(f.ravel(), minlength=n) == 6))
    del f
    t0 = time.perf_counter()
    m = gen.random_planar_triangulation(n, 1)
    mesh_s = time.perf_counter() - t0
    del m
    row = {"generator": "random_planar_triangulation", "vertices": n, "faces_s": faces_s,
           "mesh_s": mesh_s, "peak_rss_faces_bytes": (after - before) if ok and before and after else None,
           "degree6_share": deg6, "degree6_law": float(gen.degree_law(6)[0])}
    return row


# ---------------------------------------------------------------------------------- probes
_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _run_probe(argv: list) -> Optional[dict]:
    """Run :func:`_probe` in a fresh interpreter; its JSON result, or None if it failed."""
    import subprocess

    code = (f"import sys; sys.path.insert(0, {_ROOT!r}); "
            f"from benchmarks.harness import _probe; _probe({argv!r})")
    try:
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             timeout=1800, cwd=_ROOT)
    except (OSError, subprocess.TimeoutExpired) as exc:
        _log(f"  probe {argv} failed: {exc}")
        return None
    if out.returncode != 0:
        _log(f"  probe {argv} failed: {out.stderr.strip().splitlines()[-1:]}")
        return None
    return json.loads(out.stdout.strip().splitlines()[-1])


def _probe(argv: list) -> None:
    """Fresh-process measurements (printed as one JSON line):

    * ``build SPEC NAME``: load the mesh, warm the builder up on a 100-vertex mesh (numba and
      jit caches), then time one build of ``NAME`` and the rise of the peak RSS during it;
    * ``generator N``: :func:`_generator_probe`."""
    if argv[0] == "generator":
        print(json.dumps(_generator_probe(int(argv[1]))))
        return
    _, spec, name = argv
    from jaxcds.structures import registry

    _, mesh = load_bench_mesh(spec)
    registry.build(name, load_bench_mesh("random:100")[1])
    before = _proc_status().get("VmRSS")
    ok = _reset_peak_rss()
    t0 = time.perf_counter()
    registry.build(name, mesh)
    seconds = time.perf_counter() - t0
    after = _proc_status().get("VmHWM")
    print(json.dumps({"seconds": seconds,
                      "peak_rss_bytes": (after - before) if ok and before and after else None}))


def summarize(res: dict) -> dict:
    """Fastest vertex-normals implementation per mesh, and scatter vs gather per structure."""
    summary = {}
    for m in res["meshes"]:
        rows = [r for r in res["timings"] if r["mesh"] == m["name"] and r["op"].startswith("vertex_normals")]
        if not rows:
            continue
        best = min(rows, key=lambda r: r["ns_per_item"])
        per_struct = {}
        for r in rows:
            if r["kind"] == "structure":
                per_struct.setdefault(r["impl"], {})[r["op"][len("vertex_normals["):-1]] = r["ns_per_item"]
        summary[m["name"]] = {
            "fastest_normals": f"{best['impl']} {best['op']}", "fastest_normals_ns_per_vertex": best["ns_per_item"],
            "structure_normals_ns_per_vertex": per_struct,
            "faster_structure_formulation": {k: min(v, key=v.get) for k, v in per_struct.items() if v},
        }
    return summary


# ---------------------------------------------------------------------------------- CLI
def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="jaxcds bench",
        description="Time jitted jaxcds operations on every registered structure, and peers.")
    p.add_argument("--quick", action="store_true",
                   help=f"tiny meshes ({', '.join(QUICK_MESHES)}), 3 repeats, 4096 queries: CI smoke test")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--structures", nargs="+", metavar="NAME",
                   help="registered structures to time (default: all; comma lists accepted)")
    p.add_argument("--peers", nargs="*", metavar="PEER",
                   help="peers to run (default: all; `--peers` alone: none)")
    p.add_argument("--mesh", nargs="+", metavar="SPEC",
                   help="icosphere:S, random:N[:SEED], hull:N[:SEED], square:N[:SEED] or a mesh file "
                        f"(default: {' '.join(DEFAULT_MESHES)})")
    p.add_argument("--ops", nargs="+", metavar="OP", type=_op_prefix,
                   help="only these ops (prefixes): vertex_degrees vertex_normals target face_left adjacent")
    p.add_argument("--repeats", type=at_least_one, help="timed runs per op, median reported (default 7, quick 3)")
    p.add_argument("--queries", type=at_least_one, help="batch size of the query ops (default 2^20, quick 4096)")
    p.add_argument("--budget", type=_seconds, default=30.0, metavar="S",
                   help="at most about S seconds of timed runs per op (fewer repeats for slow ops)")
    p.add_argument("--max-call", type=_seconds, default=60.0, metavar="S",
                   help="skip an op predicted (from a smaller mesh) to take more than S s per call")
    p.add_argument("--generators", type=float, nargs="*", metavar="N",
                   help="time the Poulalhon-Schaeffer sampler at these sizes (default: 1e6 1e7; "
                        "quick: none; `--generators` alone: none)")
    p.add_argument("--rss", choices=["subprocess", "inprocess"],
                   help="measure build time / peak RSS of each structure in a fresh process "
                        "(default) or in this one (default with --quick)")
    p.add_argument("--dtype", default="float32", choices=["float32", "float64"],
                   help="positions dtype (float64 enables jax_enable_x64)")
    p.add_argument("--out", metavar="DIR",
                   help="write RESULTS.md and PNG plots there (default: benchmarks/ for a full run; "
                        "a --quick run writes nothing unless --out is given)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    return p


def _split(xs):
    if xs is None:
        return None
    return [y for x in xs for y in x.split(",") if y]


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``jaxcds bench`` / ``python -m benchmarks``; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    a = _parser().parse_args(argv)
    out_dir = a.out if a.out else (None if a.quick else os.path.dirname(os.path.abspath(__file__)))
    if out_dir and os.path.exists(out_dir) and not os.path.isdir(out_dir):  # before any timing
        print(f"jaxcds bench: error: --out {out_dir!r} is a file, not a folder", file=sys.stderr)
        return 2
    if a.dtype == "float64":
        import jax

        jax.config.update("jax_enable_x64", True)
    meshes = a.mesh or (QUICK_MESHES if a.quick else DEFAULT_MESHES)
    repeats = a.repeats or (3 if a.quick else 7)
    queries = a.queries or (4096 if a.quick else 1 << 20)
    command = " ".join(["jaxcds bench"] + argv)
    if a.generators is None:
        gens = [] if a.quick else DEFAULT_GENERATORS
    else:
        gens = [int(x) for x in a.generators]
    from jaxcds import errors

    try:
        res = run(meshes, structures=_split(a.structures), peers=_split(a.peers), repeats=repeats,
                  queries=queries, dtype=a.dtype, ops=_split(a.ops), command=command,
                  budget_s=a.budget, max_call_s=a.max_call, generators=gens,
                  rss=a.rss or ("inprocess" if a.quick else "subprocess"))
    except errors.JaxcdsError as exc:
        print(f"jaxcds bench: error: {exc}", file=sys.stderr)
        return 2
    if out_dir:
        from benchmarks.report import write_report

        written = write_report(res, out_dir, plots=not a.no_plots)
        res["written"] = written
        _log("wrote " + ", ".join(written))
    if a.json:
        print(json.dumps(res, indent=1, default=_json_default))
    else:
        from benchmarks.report import markdown

        print(markdown(res))
    return 0


def _json_default(x):
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.floating,)):
        return float(x)
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)
