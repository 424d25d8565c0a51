"""``RESULTS.md`` and PNG plots from the results of :func:`benchmarks.harness.run`."""

from __future__ import annotations

import os
from typing import List

__all__ = ["markdown", "write_report"]

_OPS_WHOLE = ["vertex_degrees", "vertex_normals[scatter]", "vertex_normals[gather]", "vertex_normals"]
_OPS_QUERY = ["target", "face_left", "adjacent"]


def _fmt(x, digits=1):
    if x is None:
        return "–"
    if isinstance(x, float):
        if x == 0:
            return "0"
        if abs(x) >= 100:
            return f"{x:,.0f}"
        if abs(x) < 0.01:
            return f"{x:.1e}"
        return f"{x:.{digits}f}"
    return str(x)


def _mb(b):
    return "–" if b is None else f"{b / 2**20:,.1f}"


def markdown(res: dict, plots: List[str] = ()) -> str:
    m = res["machine"]
    L = ["# jaxcds benchmarks", "",
         f"- command: `{res.get('command') or 'jaxcds bench'}`",
         f"- date: {m['date']}",
         f"- machine: {m['cpu']}, {m['cores']} usable cores"
         + (f", {m['memory_bytes'] / 2**30:.0f} GiB" if m.get("memory_bytes") else "")
         + f"; {m['platform']}",
         f"- software: Python {m['python']}, jax {m['jax']} ({m['jax_backend']}), numpy {m['numpy']}, "
         f"numba {m['numba']}",
         f"- settings: positions {res['settings']['dtype']}, median of {res['settings']['repeats']} runs "
         f"after one warm-up run, `block_until_ready`; jitted ops compiled ahead of time (compile "
         f"time apart); {res['settings']['queries']:,} random queries per batched op "
         "(adjacent: half true edges, half random pairs); slow ops get fewer runs "
         f"(about {res['settings'].get('budget_s')} s of timed runs at most)",
         "- `max_err`: largest absolute difference of the unit normals with a float64 area-weighted "
         "reference (trimesh uses its own weighting, hence its larger value); `degrees`: checked "
         "against the face list", ""]
    for mesh in res["meshes"]:
        name = mesh["name"]
        L += [f"## {name}: {mesh['vertices']:,} vertices, {mesh['faces']:,} faces", ""]
        rows = [r for r in res["timings"] if r["mesh"] == name]
        impls = []
        for r in rows:
            if r["kind"] != "formulation" and r["impl"] not in impls:
                impls.append(r["impl"])
        # whole-mesh ops: ns per vertex
        L += ["### Whole-mesh operations (ns per vertex; compile s in parentheses)", "",
              "| implementation | " + " | ".join(o for o in _OPS_WHOLE) + " | normals max_err | degrees |",
              "|---|" + "---:|" * (len(_OPS_WHOLE) + 2)]
        for impl in impls:
            cells, err, deg_ok = [], None, ""
            for op in _OPS_WHOLE:
                r = next((x for x in rows if x["impl"] == impl and x["op"] == op and x["kind"] != "formulation"), None)
                if r is None:
                    cells.append("")
                    continue
                cells.append(f"{_fmt(r['ns_per_item'])} ({_fmt(r['compile_s'], 2)})")
                if op.startswith("vertex_normals") and r.get("max_err") is not None:
                    err = max(err or 0.0, r["max_err"])
                if op == "vertex_degrees" and r.get("max_err") is not None:
                    deg_ok = "ok" if r["max_err"] == 0 else f"WRONG (off by {r['max_err']:.0f})"
            kind = next(x["kind"] for x in rows if x["impl"] == impl)
            label = impl if kind == "structure" else f"{impl} (peer)"
            L.append(f"| {label} | " + " | ".join(cells) + f" | {_fmt(err)} | {deg_ok} |")
        L.append("")
        q = [r for r in rows if r["op"] in _OPS_QUERY]
        if q:
            L += ["### Batched queries (ns per query; compile s in parentheses)", "",
                  "| structure | " + " | ".join(_OPS_QUERY) + " |", "|---|" + "---:|" * len(_OPS_QUERY)]
            for impl in [i for i in impls if any(r["impl"] == i for r in q)]:
                cells = []
                for op in _OPS_QUERY:
                    r = next((x for x in q if x["impl"] == impl and x["op"] == op), None)
                    cells.append("" if r is None else f"{_fmt(r['ns_per_item'])} ({_fmt(r['compile_s'], 2)})")
                L.append(f"| {impl} | " + " | ".join(cells) + " |")
            L.append("")
        f = [r for r in rows if r["kind"] == "formulation"]
        if f:
            L += ["### Face-list normals: scatter vs gather formulations (plain JAX)", "",
                  "| formulation | ns/vertex | compile s | max_err | how |", "|---|---:|---:|---:|---|"]
            for r in sorted(f, key=lambda r: r["ns_per_item"]):
                L.append(f"| {r['op']} | {_fmt(r['ns_per_item'])} | {_fmt(r['compile_s'], 2)} | "
                         f"{_fmt(r.get('max_err'))} | {r['note']} |")
            L.append("")
        s = res.get("summary", {}).get(name)
        if s:
            L.append(f"Fastest normals here: **{s['fastest_normals']}** "
                     f"({_fmt(s['fastest_normals_ns_per_vertex'])} ns/vertex).")
            for st, best in s["faster_structure_formulation"].items():
                d = s["structure_normals_ns_per_vertex"][st]
                L.append(f"{st}: {best} is faster ("
                         + ", ".join(f"{k} {_fmt(v)}" for k, v in d.items()) + " ns/vertex).")
            L.append("")
    if res["memory"]:
        L += ["## Memory and construction", "",
              "| mesh | structure | references | refs/vertex | bytes/vertex | MiB | build s | "
              "peak RSS during build (MiB) |", "|---|---|---:|---:|---:|---:|---:|---:|"]
        for r in res["memory"]:
            L.append(f"| {r['mesh']} | {r['structure']} | {r['references']:,} | "
                     f"{r['references_per_vertex']:.2f} | {r['bytes_per_vertex']:.1f} | {_mb(r['bytes'])} | "
                     f"{r['build_s']:.3f} | {_mb(r['peak_rss_build_bytes'])} |")
        how = {r.get("rss_measured", "in-process") for r in res["memory"]}
        if how == {"fresh process"}:
            L += ["", "Build time and peak RSS measured in a fresh process per structure and mesh "
                  "(`registry.build` from the TriMesh, validation included; builder warmed up on a "
                  "100-vertex mesh first): peak RSS is the rise of the high-water mark during the "
                  "build (`/proc/self/clear_refs`).", ""]
        else:
            L += ["", "Build time: second build in the benchmark process (the first pays numba "
                  "compilation). Peak RSS: rise of the process's high-water mark during that build "
                  "(`/proc/self/clear_refs`); memory freed earlier and reused is not counted, so "
                  "this underestimates.", ""]
    if res.get("generators"):
        L += ["## Generator: Poulalhon-Schaeffer uniform random planar triangulations", "",
              "Fresh process per size; peak RSS: rise of the high-water mark while sampling the faces.", "",
              "| vertices | faces only (s) | TriMesh with positions (s) | peak RSS, faces (MiB) | "
              "degree-6 share | CDS Sec. 4.4 law |", "|---:|---:|---:|---:|---:|---:|"]
        for g in res["generators"]:
            L.append(f"| {g['vertices']:,} | {g['faces_s']:.2f} | {g['mesh_s']:.2f} | "
                     f"{_mb(g['peak_rss_faces_bytes'])} | {100 * g['degree6_share']:.2f}% | "
                     f"{100 * g['degree6_law']:.2f}% |")
        L.append("")
    if res["skipped"]:
        L += ["## Skipped", ""]
        seen = set()
        for r in res["skipped"]:
            key = (r["impl"], r.get("op"), r["reason"])
            if key in seen:
                continue
            seen.add(key)
            L.append(f"- {r['impl']}{' ' + r['op'] if r.get('op') else ''}: {r['reason']}")
        L.append("")
    for p in plots:
        L += [f"![{os.path.splitext(os.path.basename(p))[0]}]({os.path.basename(p)})", ""]
    return "\n".join(L)


def _plots(res: dict, out_dir: str) -> List[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    meshes = [m["name"] for m in res["meshes"]]
    # normals: every implementation / formulation, per mesh
    fig, axes = plt.subplots(1, len(meshes), figsize=(6 * len(meshes), 4.5), squeeze=False)
    for ax, name in zip(axes[0], meshes):
        rows = [r for r in res["timings"] if r["mesh"] == name and r["op"].startswith("vertex_normals")]
        rows.sort(key=lambda r: r["ns_per_item"])
        labels = [f"{r['impl']} {r['op'][len('vertex_normals'):]}".strip() for r in rows]
        colors = ["tab:blue" if r["kind"] == "structure" else "tab:gray" if r["kind"] == "peer" else "tab:orange"
                  for r in rows]
        ax.barh(labels, [r["ns_per_item"] for r in rows], color=colors)
        ax.set_xscale("log")
        ax.invert_yaxis()
        ax.set_xlabel("ns per vertex (log)")
        ax.set_title(f"vertex normals, {name}")
    fig.tight_layout()
    p = os.path.join(out_dir, "normals.png")
    fig.savefig(p, dpi=90)
    plt.close(fig)
    written.append(p)
    # queries
    q = [r for r in res["timings"] if r["op"] in _OPS_QUERY + ["vertex_degrees"] and r["kind"] == "structure"]
    if q:
        fig, axes = plt.subplots(1, len(meshes), figsize=(6 * len(meshes), 4), squeeze=False)
        for ax, name in zip(axes[0], meshes):
            rows = [r for r in q if r["mesh"] == name]
            structs = list(dict.fromkeys(r["impl"] for r in rows))
            ops = _OPS_QUERY + ["vertex_degrees"]
            w = 0.8 / max(len(structs), 1)
            for i, st in enumerate(structs):
                vals = [next((r["ns_per_item"] for r in rows if r["impl"] == st and r["op"] == op), 0) for op in ops]
                ax.bar([j + i * w for j in range(len(ops))], vals, width=w, label=st)
            ax.set_xticks([j + 0.4 - w / 2 for j in range(len(ops))])
            ax.set_xticklabels([o if o != "vertex_degrees" else "degrees\n(per vertex)" for o in ops])
            ax.set_ylabel("ns per query")
            ax.set_title(name)
            ax.legend()
        fig.tight_layout()
        p = os.path.join(out_dir, "queries.png")
        fig.savefig(p, dpi=90)
        plt.close(fig)
        written.append(p)
    if res["memory"]:
        fig, ax = plt.subplots(figsize=(6, 3.5))
        seen = {}
        for r in res["memory"]:
            seen.setdefault(r["structure"], r["references_per_vertex"])
        ax.bar(list(seen), list(seen.values()), color="tab:blue")
        ax.set_ylabel("references per vertex")
        ax.set_title(f"memory ({res['memory'][0]['mesh']})")
        fig.tight_layout()
        p = os.path.join(out_dir, "memory.png")
        fig.savefig(p, dpi=90)
        plt.close(fig)
        written.append(p)
    return written


def write_report(res: dict, out_dir: str, plots: bool = True) -> List[str]:
    """Write ``RESULTS.md`` (and ``normals.png``, ``queries.png``, ``memory.png``) in
    ``out_dir``; returns the paths written."""
    os.makedirs(out_dir, exist_ok=True)
    written = _plots(res, out_dir) if plots else []
    path = os.path.join(out_dir, "RESULTS.md")
    with open(path, "w") as fh:
        fh.write(markdown(res, written) + "\n")
    return [path] + written
