"""LR benchmarks (Gurung, Luffel, Lindstrom, Rossignac, ACM TOG 2011): the paper's Table 1 on the
shared meshes, construction throughput (Sec. 8: "two million triangles per second" from a corner
table) and the Fig. 10 timings, for the CornerTable, ``lr`` and ``lr-bits``.

* **Table 1**: every shared mesh that LR accepts (connected, manifold; holes closed by a dummy
  vertex each, Sec. 4.6, dummies never on the ring and not counted in ``n`` or ``m_i``): ``n``
  real triangles, % valence-6 vertices, standard LR (``m_i``, % T0, % T0^w, % T1^i and % T2^i --
  irregular ring slots holding a T1 / a T2 --, references per triangle ``rpt = (2 m_r + 6 n0 + 3 n^i +
  m_i) / n``), the Sec. 7 renderable index list (rpt), and ``lr-bits`` (chosen ``k``, % T0,
  % T^i, % long entries T^l, bits per triangle ``32 (m_r + 6 n0 + |VO*| + m_i) / n``). Median
  rpt / bpt over the closed (no dummy) meshes and over all of them.
* **Construction** on a random planar triangulation (Poulalhon--Schaeffer) of ``>= 1M``
  triangles or a subdivided shared mesh (``--construction-mesh subdiv:NAME:K``): RING-EXPANDER
  alone, ring + tables + packed ``LR`` / ``lr-bits`` from a ``CornerTable`` (one seed, the
  paper's input; with and without the construction check; and the defaults, 4 seeds), and end
  to end from the ``(F, 3)`` face array (validation, corner table, ring, tables, packing),
  validation timed apart; millions of triangles per second of wall time and of CPU time
  (``process_time``: the steadier figure on a shared machine), medians of repeats after a
  warm-up (numba compiled and cached before).
* **Fig. 10**: ``c.v`` and ``c.o`` over every corner, vertex valence and area-weighted vertex
  normal by swinging around ``v.c`` (every vertex at once, a ``while_loop`` of max-degree
  steps), and the plane-contour walk (``B`` contours walked ``S`` steps each, one ``c.o`` per
  triangle crossed), ns per element, jitted, compile time apart, median of repeats, on a
  random triangulation of ``>= 2M`` triangles (random positions on the sphere: the geometry only
  drives the walk).

Usage::

    .venv/bin/python -m benchmarks.bench_lr            # full (minutes)
    .venv/bin/python -m benchmarks.bench_lr --quick    # seconds, smoke test
    .venv/bin/python -m benchmarks.bench_lr --json out.json
    .venv/bin/python -m benchmarks.bench_lr --no-table1 --no-fig10 --construction-faces 2000000
    .venv/bin/python -m benchmarks.bench_lr --no-table1 --no-fig10 --construction-mesh subdiv:armadillo.obj:2

Writes markdown tables to stdout. Timings on a shared machine are noisy: the JSON records the
load average before and after each part.
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

from benchmarks.harness import time_wall_cpu  # noqa: E402

SHARED = os.environ.get("JAXCDS_SHARED", os.path.join(HERE, "..", "..", "shared"))
MESH_DIR = os.path.join(SHARED, "meshes")

# the shared meshes LR accepts (README of ../shared/meshes): closed ones, then holed ones
CLOSED = ["cube.off", "decimated-knight.off", "bunny.off", "spot.obj", "cheburashka.obj",
          "elephant.obj", "fandisk.off", "bumpy-cube.obj", "armadillo.obj", "rocker-arm.obj",
          "3holes.off"]
HOLED = ["stanford-bunny.obj", "face.obj", "camelhead.off", "grid.off", "2triangles.off"]
PAPER_BUNNY = {"n": 69451, "rpt": 1.062, "bpt": 20.27}


def _log(msg: str) -> None:
    print(f"[bench_lr] {msg}", file=sys.stderr, flush=True)


def _load() -> list:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:  # pragma: no cover
        return []


def _median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


# ------------------------------------------------------------------------------ Table 1
def _valence6(mesh) -> float:
    f = mesh.faces
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    e = np.unique(e, axis=0)
    deg = np.bincount(e.ravel(), minlength=mesh.num_vertices)
    return 100.0 * float(np.mean(deg == 6))


def table1(names: Sequence[str], *, seeds: int = 4, ks=None, ring_sweeps: int = 100) -> list:
    from jaxcds.mesh import load_mesh
    from jaxcds.structures.lr import LR, LRBits, renderable_index_list, stats

    rows = []
    for name in names:
        path = os.path.join(MESH_DIR, name)
        if not os.path.exists(path):
            _log(f"skip {name}: not found under {MESH_DIR}")
            continue
        mesh = load_mesh(path)
        t0 = time.perf_counter()
        lr = LR.from_mesh(mesh, seeds=seeds, check=False)
        lr_s = time.perf_counter() - t0
        st = stats(lr)
        n = lr.num_faces
        _, rst = renderable_index_list(lr)
        t0 = time.perf_counter()
        bits = LRBits.from_mesh(mesh, check=False, **({} if ks is None else {"k": ks}))
        bits_s = time.perf_counter() - t0
        sb = stats(bits)
        rows.append({
            "mesh": name, "n": n, "holes_closed": st["m_dummy"], "pct_v6": _valence6(mesh),
            "m_i": st["m_i"], "pct_T0": 100.0 * lr.num_t0 / n, "pct_T0w": 100.0 * st["T0w"] / n,
            "pct_Ti": 100.0 * st["irregular"] / n,
            # T^i split (Sec. 4.3): T_2^i from the ring classification, the rest T_1^i (wart
            # skipping absorbs every T_2 next to a T_0, so T_2^i is 0 unless skipping is off)
            "pct_T1i": 100.0 * (st["irregular"] - st["T2i"]) / n, "pct_T2i": 100.0 * st["T2i"] / n,
            "rpt": lr.references / n,
            "render_rpt": rst["rpt"], "build_s": lr_s,
            "bits_k": bits.k, "bits_m_i": sb["m_i"], "bits_pct_T0": 100.0 * bits.num_t0 / n,
            "bits_pct_T0w": 100.0 * sb["T0w"] / n, "bits_pct_Ti": 100.0 * sb["irregular"] / n,
            "bits_pct_T1i": 100.0 * (sb["irregular"] - sb["T2i"]) / n,
            "bits_pct_T2i": 100.0 * sb["T2i"] / n,
            "bits_pct_Tl": 100.0 * bits.num_long * 2 / n, "bpt": bits.bits / n,
            "bits_build_s": bits_s})
        if ring_sweeps:
            rows[-1].update(_searched(mesh, lr, seeds, ks, ring_sweeps))
        _log(f"{name}: n={n} rpt={rows[-1]['rpt']:.3f} bpt={rows[-1]['bpt']:.2f}")
    return rows


def _searched(mesh, plain, seeds: int, ks, sweeps: int) -> dict:
    """The same mesh with the ring search (:mod:`jaxcds.construct.ring_search`, beyond the
    paper) after RING-EXPANDER: ``sweeps`` sweeps, same seeds; its time is the build's extra."""
    from jaxcds.structures.lr import LR, LRBits, stats

    n = plain.num_faces
    t0 = time.perf_counter()
    lr = LR.from_mesh(mesh, seeds=seeds, check=False, ring_sweeps=sweeps)
    lr_s = time.perf_counter() - t0
    st = stats(lr)
    bits = LRBits.from_mesh(mesh, check=False, ring_sweeps=sweeps,
                            **({} if ks is None else {"k": ks}))
    return {"ring_sweeps": sweeps, "s_rpt": lr.references / n, "s_m_i": st["m_i"],
            "s_pct_T0": 100.0 * lr.num_t0 / n, "s_pct_T0w": 100.0 * st["T0w"] / n,
            "s_pct_Ti": 100.0 * st["irregular"] / n, "s_build_s": lr_s,
            "s_bits_k": bits.k, "s_bpt": bits.bits / n}


def _searched_md(rows: list) -> str:
    out = ["| mesh | n | rpt (RING-EXPANDER) | rpt searched | m_i | %T0 | %T0^w | %T^i | "
           "build s | bpt | bpt searched | bits k |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if "s_rpt" not in r:
            continue
        out.append(f"| {r['mesh']} | {r['n']:,} | {r['rpt']:.3f} | {r['s_rpt']:.3f} | "
                   f"{r['s_m_i']} | {r['s_pct_T0']:.2f} | {r['s_pct_T0w']:.2f} | "
                   f"{r['s_pct_Ti']:.2f} | {r['s_build_s']:.2f} | {r['bpt']:.2f} | "
                   f"{r['s_bpt']:.2f} | {r['s_bits_k'] or 'DFS'} |")
    return "\n".join(out)


def _table1_md(rows: list) -> str:
    out = ["| mesh | n | holes closed | %v6 | m_i | %T0 | %T0^w | %T1^i | %T2^i | rpt | render rpt | "
           "bits k | bits m_i | bits %T0 | bits %T1^i | bits %T2^i | bits %T^l | bpt |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['mesh']} | {r['n']:,} | {r['holes_closed']} | {r['pct_v6']:.1f} | "
                   f"{r['m_i']} | {r['pct_T0']:.2f} | {r['pct_T0w']:.2f} | {r['pct_T1i']:.2f} | "
                   f"{r['pct_T2i']:.2f} | {r['rpt']:.3f} | {r['render_rpt']:.3f} | "
                   f"{r['bits_k'] or 'DFS'} | {r['bits_m_i']} | {r['bits_pct_T0']:.2f} | "
                   f"{r['bits_pct_T1i']:.2f} | {r['bits_pct_T2i']:.2f} | {r['bits_pct_Tl']:.2f} | "
                   f"{r['bpt']:.2f} |")
    return "\n".join(out)


def _median(rows: list, key: str):
    vals = [r[key] for r in rows if key in r]
    return statistics.median(vals) if vals and len(vals) == len(rows) else None


def _summary(rows: list) -> dict:
    closed = [r for r in rows if r["holes_closed"] == 0 and r["n"] >= 100]
    big = [r for r in rows if r["n"] >= 100]
    out = {
        "median_rpt_closed": statistics.median([r["rpt"] for r in closed]) if closed else None,
        "median_bpt_closed": statistics.median([r["bpt"] for r in closed]) if closed else None,
        "median_rpt_all": statistics.median([r["rpt"] for r in big]) if big else None,
        "median_bpt_all": statistics.median([r["bpt"] for r in big]) if big else None,
        "mean_render_rpt": statistics.mean([r["render_rpt"] for r in big]) if big else None,
        "median_rpt_closed_searched": _median(closed, "s_rpt"),
        "median_bpt_closed_searched": _median(closed, "s_bpt"),
        "median_rpt_all_searched": _median(big, "s_rpt"),
        "meshes_in_medians": "n >= 100 triangles (cube, grid... excluded when tiny)",
    }
    b = next((r for r in rows if r["mesh"] == "stanford-bunny.obj"), None)
    if b is not None:
        out["bunny"] = {"n": b["n"], "rpt": b["rpt"], "bpt": b["bpt"], "paper": PAPER_BUNNY,
                        "rpt_rel_diff": b["rpt"] / PAPER_BUNNY["rpt"] - 1,
                        "bpt_rel_diff": b["bpt"] / PAPER_BUNNY["bpt"] - 1}
    return out


# ------------------------------------------------------------------------------ construction
def construction(num_faces: int, repeats: int, mesh_spec: Optional[str] = None,
                 bits_k: int = 64) -> dict:
    """Construction times (median of ``repeats`` after a warm-up) on a random triangulation of
    ``num_faces`` triangles or a ``subdiv:NAME:K`` mesh, one seed corner. The seed is chosen
    once, untimed, as the best of 4 random seeds (``best_ring``): RING-EXPANDER from an unlucky
    seed can stay inside a separating triangle of a random triangulation (a few dozen
    triangles invaded, almost every triangle a T0), which would time a different structure.
    ``seeds=4`` (the default of ``LR.from_corner_table``) is timed too."""
    from jaxcds.construct.ring_expander import best_ring, ring_expander
    from jaxcds.structures import lr as lrmod
    from jaxcds.structures.corner_table import CornerTable
    from jaxcds.structures.lr import LR, LRBits, build_lr, stats

    bits_from_ct = getattr(LRBits, "from_corner_table", None)
    if bits_from_ct is None:  # versions before LRBits.from_corner_table (before/after runs)
        def bits_from_ct(ct, **kw):
            return lrmod._from_corner_table(LRBits, ct, **kw)

    mesh = fig10_mesh(mesh_spec, num_faces)
    nf = mesh.num_faces
    # warm up the numba kernels (cached on disk), for both variants, checks included
    small = fig10_mesh(None, 2000)
    LR.from_mesh(small, seeds=1)
    LRBits.from_mesh(small, k=bits_k)
    ct = CornerTable.from_faces(mesh.faces, mesh.num_vertices)
    V, O = np.asarray(ct.V), np.asarray(ct.O)
    seed = best_ring(V, O, mesh.num_vertices, seeds=4).seed
    seeds = [seed]
    load0 = _load()
    t = {}
    t["ring_expander_s"] = time_wall_cpu(lambda: ring_expander(V, O, mesh.num_vertices, seed), repeats)
    t["lr_from_corner_table_s"] = time_wall_cpu(
        lambda: LR.from_corner_table(ct, seeds=seeds, check=False), repeats)
    t["lr_from_corner_table_checked_s"] = time_wall_cpu(
        lambda: LR.from_corner_table(ct, seeds=seeds, check=True), repeats)
    t["lr_from_corner_table_defaults_s"] = time_wall_cpu(  # seeds=4, check=True
        lambda: LR.from_corner_table(ct), repeats)
    t["lr_bits_from_corner_table_s"] = time_wall_cpu(
        lambda: bits_from_ct(ct, k=bits_k, seeds=seeds, check=False), repeats)
    t["lr_bits_from_corner_table_checked_s"] = time_wall_cpu(
        lambda: bits_from_ct(ct, k=bits_k, seeds=seeds, check=True), repeats)
    t["validation_s"] = time_wall_cpu(lambda: lrmod._prepare(mesh), repeats)
    t["corner_table_from_faces_s"] = time_wall_cpu(
        lambda: CornerTable.from_faces(mesh.faces, mesh.num_vertices), repeats)
    prep = lrmod._prepare(mesh)
    if isinstance(prep, tuple) and prep[1] is not None:  # validation hands its twins over
        pm, twins = prep
        t["corner_table_from_twins_s"] = time_wall_cpu(
            lambda: CornerTable.from_faces(pm.faces, pm.num_vertices, twins=twins), repeats)
    del prep
    t["lr_end_to_end_s"] = time_wall_cpu(lambda: build_lr(mesh, seeds=seeds, check=False), repeats)
    t["lr_end_to_end_checked_s"] = time_wall_cpu(
        lambda: build_lr(mesh, seeds=seeds, check=True), repeats)
    t["lr_bits_end_to_end_checked_s"] = time_wall_cpu(
        lambda: build_lr(mesh, bits=True, k=bits_k, seeds=seeds, check=True), repeats)
    s = LR.from_corner_table(ct, seeds=seeds, check=False)
    st = stats(s)
    out = {"mesh": mesh_spec or f"random:{mesh.num_vertices}", "triangles": nf,
           "repeats": repeats, "seed_corner": seed, "bits_k": bits_k,
           "m_i_pct": 100.0 * st["m_i"] / mesh.num_vertices, "rpt": s.references / nf}
    for key, (sec, cpu) in t.items():
        out[key] = sec
        out[key[:-2] + "_cpu_s"] = cpu
        if key not in ("validation_s", "corner_table_from_faces_s", "corner_table_from_twins_s"):
            out[key[:-2] + "_Mtps"] = nf / sec / 1e6
            out[key[:-2] + "_cpu_Mtps"] = nf / cpu / 1e6
    out["targets_Mtps"] = {"from_corner_table": 5.0, "end_to_end": 2.0}
    out["load_before"], out["load_after"] = load0, _load()
    return out


def _construction_md(c: dict) -> str:
    rows = [("RING-EXPANDER (one seed)", "ring_expander"),
            ("LR from CornerTable, check=False", "lr_from_corner_table"),
            ("LR from CornerTable, check=True", "lr_from_corner_table_checked"),
            ("LR from CornerTable, defaults (4 seeds, check)", "lr_from_corner_table_defaults"),
            (f"lr-bits (k={c['bits_k']}) from CornerTable, check=False", "lr_bits_from_corner_table"),
            (f"lr-bits (k={c['bits_k']}) from CornerTable, check=True",
             "lr_bits_from_corner_table_checked"),
            ("LR end to end (faces), check=False", "lr_end_to_end"),
            ("LR end to end (faces), check=True", "lr_end_to_end_checked"),
            (f"lr-bits (k={c['bits_k']}) end to end, check=True", "lr_bits_end_to_end_checked")]
    out = [f"{c['mesh']}: {c['triangles']:,} triangles, m_i {c['m_i_pct']:.1f}% of the vertices, "
           f"{c['rpt']:.3f} rpt; validation (validate_and_close) {c['validation_s']:.3f} s, "
           f"CornerTable from faces {c['corner_table_from_faces_s']:.3f} s (CPU "
           f"{c['validation_cpu_s']:.3f} s, {c['corner_table_from_faces_cpu_s']:.3f} s)"
           + (f", from the validation's twins {c['corner_table_from_twins_s']:.3f} s (CPU "
              f"{c['corner_table_from_twins_cpu_s']:.3f} s)" if "corner_table_from_twins_s" in c
              else "")
           + f"; load {c['load_before']} -> {c['load_after']}\n",
           "| step | wall s | M triangles/s | CPU s | M triangles per CPU s |",
           "|---|---|---|---|---|"]
    for label, key in rows:
        out.append(f"| {label} | {c[key + '_s']:.3f} | {c[key + '_Mtps']:.2f} | "
                   f"{c[key + '_cpu_s']:.3f} | {c[key + '_cpu_Mtps']:.2f} |")
    return "\n".join(out)


# ------------------------------------------------------------------------------ Fig. 10
def _ops():
    import jax
    import jax.numpy as jnp

    def vc(s, v):
        return s.vc(v) if hasattr(s, "vc") else s.edge_of_vertex(v)

    @jax.jit
    def corner_v(s, c):
        return s.v(c)

    @jax.jit
    def corner_o(s, c):
        return s.o(c)

    def _swing(s, pos, with_normals):
        v = jnp.arange(s.num_vertices, dtype=jnp.int32)
        c0 = vc(s, v)

        def cond(st):
            return jnp.any(st[1])

        def body(st):
            c, live, deg, nrm = st
            deg = deg + live.astype(jnp.int32)
            if with_normals:
                p0 = pos[v]
                a = pos[s.v(s.n(c))] - p0
                b = pos[s.v(s.p(c))] - p0
                nrm = nrm + jnp.where(live[:, None], jnp.cross(a, b), 0.0)
            cn = s.s(c)
            return cn, live & (cn != c0), deg, nrm

        nrm0 = jnp.zeros((s.num_vertices, 3), pos.dtype)
        st = jax.lax.while_loop(cond, body, (c0, jnp.ones_like(v, bool),
                                             jnp.zeros_like(v), nrm0))
        return st[2], st[3]

    @jax.jit
    def valence(s, pos):
        return _swing(s, pos, False)[0]

    @jax.jit
    def normals(s, pos):
        n = _swing(s, pos, True)[1]
        ln = jnp.sqrt(jnp.sum(n * n, axis=-1, keepdims=True))
        return n / jnp.where(ln > 0, ln, 1.0)

    @jax.jit
    def contour(s, pos, c0, h, steps):
        """Walk ``B`` contours (plane z = h[b]) from corner c0[b] whose opposite edge crosses
        the plane; returns the corners reached (one ``c.o`` per triangle crossed)."""
        def body(_, c):
            z = pos[s.v(c), 2] - h
            zn = pos[s.v(s.n(c)), 2] - h
            # entered across (c.n, c.p): leave across the other crossing edge
            return jnp.where((z > 0) == (zn > 0), s.o(s.n(c)), s.o(s.p(c)))
        return jax.lax.fori_loop(0, steps, body, c0)

    return corner_v, corner_o, valence, normals, contour


def _timeit(fn, args, repeats):
    import jax

    t0 = time.perf_counter()
    compiled = fn.lower(*args).compile()
    comp = time.perf_counter() - t0
    jax.block_until_ready(compiled(*args))
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(compiled(*args))
        times.append(time.perf_counter() - t0)
    return statistics.median(times), comp


def fig10_mesh(spec: Optional[str], num_faces: int):
    """``None``: a random planar triangulation of ``num_faces`` triangles (very irregular: few
    valence-6 vertices, so LR is far from 1 rpt on it); ``subdiv:NAME:K``: the closed shared mesh
    ``NAME`` after ``K`` 1:4 midpoint subdivisions (regular like the paper's scans)."""
    from jaxcds.errors import ArgumentError
    from jaxcds.generators import random_planar_triangulation
    from jaxcds.mesh import load_mesh

    if spec is None:
        return random_planar_triangulation(num_faces // 2 + 2, seed=3)
    parts = spec.split(":")
    if len(parts) != 3 or parts[0] != "subdiv" or not parts[1] or not parts[2].isdigit():
        raise ArgumentError(f"--construction-mesh / --fig10-mesh: expected subdiv:NAME:K, got {spec!r}")
    _, name, k = parts
    import trimesh

    m = load_mesh(os.path.join(MESH_DIR, name))
    v, f = m.vertices, m.faces
    for _ in range(int(k)):
        v, f = trimesh.remesh.subdivide(v, f)
    return load_mesh(v, f)


def fig10(num_faces: int, repeats: int, contours: int, steps: int,
          mesh_spec: Optional[str] = None) -> list:
    import jax
    import jax.numpy as jnp

    from jaxcds.structures.corner_table import CornerTable
    from jaxcds.structures.lr import LR, LRBits

    mesh = fig10_mesh(mesh_spec, num_faces)
    _log(f"fig10 mesh: {mesh.num_faces} triangles; building structures")
    structs = {"corner-table": CornerTable.from_faces(mesh.faces, mesh.num_vertices),
               "lr": LR.from_mesh(mesh, seeds=1, check=False),
               "lr-bits": LRBits.from_mesh(mesh, k=(64, 256), check=False)}
    corner_v, corner_o, valence, normals, contour = _ops()
    rows = []
    ref_val = ref_nrm = None
    for name, s in structs.items():
        order = np.arange(mesh.num_vertices) if s.vertex_order is None else np.asarray(s.vertex_order)
        pos = jnp.asarray(mesh.vertices[order], jnp.float32)
        c = jnp.asarray(s.all_darts())
        nc = int(c.shape[0])
        row = {"structure": name, "mesh": mesh.source if mesh_spec is None else mesh_spec,
               "triangles": mesh.num_faces, "references": int(s.references),
               "load_before": _load()}
        t, comp = _timeit(corner_v, (s, c), repeats)
        row["c.v_ns"], row["c.v_compile_s"] = 1e9 * t / nc, comp
        t, comp = _timeit(corner_o, (s, c), repeats)
        row["c.o_ns"], row["c.o_compile_s"] = 1e9 * t / nc, comp
        t, comp = _timeit(valence, (s, pos), repeats)
        row["valence_ns"], row["valence_compile_s"] = 1e9 * t / s.num_vertices, comp
        t, comp = _timeit(normals, (s, pos), repeats)
        row["normal_ns"], row["normal_compile_s"] = 1e9 * t / s.num_vertices, comp
        # results agree across structures (in input vertex order)
        val = np.empty(mesh.num_vertices, np.int64)
        val[order] = np.asarray(valence(s, pos))
        nrm = np.empty((mesh.num_vertices, 3))
        nrm[order] = np.asarray(normals(s, pos))
        if ref_val is None:
            ref_val, ref_nrm = val, nrm
        row["valence_equal_ct"] = bool(np.array_equal(val, ref_val))
        row["normal_max_diff_ct"] = float(np.abs(nrm - ref_nrm).max())
        # contour walk: start corners whose opposite edge crosses z = h (host-side set-up)
        rng = np.random.default_rng(0)
        h = rng.uniform(-0.8, 0.8, contours).astype(np.float32)
        zc = np.asarray(pos[:, 2])
        cv = np.asarray(s.v(c))
        cn = np.asarray(s.v(s.n(c)))
        cp = np.asarray(s.v(s.p(c)))
        cc = np.asarray(c)
        starts = np.empty(contours, np.int32)
        for b in range(contours):
            cross = (zc[cn] > h[b]) != (zc[cp] > h[b])
            starts[b] = cc[np.nonzero(cross)[0][0]]
        t, comp = _timeit(contour, (s, pos, jnp.asarray(starts), jnp.asarray(h), steps), repeats)
        row["contour_ns_per_triangle"], row["contour_compile_s"] = 1e9 * t / (contours * steps), comp
        row["load_after"] = _load()
        rows.append(row)
        _log(f"{name}: {row}")
    return rows


def _fig10_md(rows: list) -> str:
    out = ["| structure | mesh | triangles | refs | c.v ns | c.o ns | valence ns/vertex | "
           "normal ns/vertex | contour ns/triangle | valence = CT | normal max diff |",
           "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['structure']} | {r['mesh']} | {r['triangles']:,} | {r['references']:,} | "
                   f"{r['c.v_ns']:.2f} | "
                   f"{r['c.o_ns']:.2f} | {r['valence_ns']:.1f} | {r['normal_ns']:.1f} | "
                   f"{r['contour_ns_per_triangle']:.1f} | {r['valence_equal_ct']} | "
                   f"{r['normal_max_diff_ct']:.1e} |")
    return "\n".join(out)


# ------------------------------------------------------------------------------ main
@clean_exit
def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="tiny sizes (smoke test)")
    ap.add_argument("--json", help="write the results as JSON here")
    ap.add_argument("--meshes", nargs="+", help="Table 1 meshes (shared file names)")
    ap.add_argument("--construction-faces", type=int, default=1_000_000)
    ap.add_argument("--construction-mesh", help="subdiv:NAME:K (a subdivided shared mesh) "
                    "instead of the random triangulation for the construction timings")
    ap.add_argument("--fig10-faces", type=int, default=2_000_000)
    ap.add_argument("--fig10-mesh", help="subdiv:NAME:K (a subdivided shared mesh) instead of "
                    "the random triangulation")
    ap.add_argument("--repeats", type=at_least_one, default=3)
    ap.add_argument("--no-table1", action="store_true")
    ap.add_argument("--ring-sweeps", type=int, default=100,
                    help="Table 1 again with the ring search (0: skip)")
    ap.add_argument("--no-construction", action="store_true")
    ap.add_argument("--no-fig10", action="store_true")
    args = ap.parse_args(argv)
    if args.quick:
        meshes = args.meshes or ["cube.off", "grid.off", "3holes.off"]
        cf, ff, rep, contours, steps = 20_000, 20_000, 2, 16, 64
    else:
        meshes = args.meshes or CLOSED + HOLED
        cf, ff, rep, contours, steps = (args.construction_faces, args.fig10_faces, args.repeats,
                                        64, 2048)
    from benchmarks.harness import machine_info

    res = {"machine": machine_info(), "command": " ".join(sys.argv), "quick": args.quick,
           "note": "shared machine (other jobs running): see load_before/load_after"}
    if not args.no_table1:
        rows = table1(meshes, ring_sweeps=args.ring_sweeps)
        res["table1"] = rows
        res["table1_summary"] = _summary(rows)
        print("## LR Table 1 (our meshes)\n")
        print(_table1_md(rows))
        if args.ring_sweeps:
            print(f"\n## Table 1 with the ring search ({args.ring_sweeps} sweeps, beyond the paper)\n")
            print(_searched_md(rows))
        print("\n```\n" + json.dumps(res["table1_summary"], indent=1) + "\n```\n")
    if not args.no_construction:
        c = construction(cf, rep, args.construction_mesh)
        res["construction"] = c
        print("## LR construction\n")
        print(_construction_md(c) + "\n")
    if not args.no_fig10:
        rows = fig10(ff, rep, contours, steps, args.fig10_mesh)
        res["fig10"] = rows
        print("## Fig. 10 timings (ns per element)\n")
        print(_fig10_md(rows))
        print()
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(res, fh, indent=1, default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
