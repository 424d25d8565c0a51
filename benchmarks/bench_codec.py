"""Codec benchmark: the 4n-bit format of the CDS paper (Sec. 3) -- Table 2's compression and
decompression columns in our setting.

Per mesh (each time the median of ``--repeats`` runs after one warm-up run, so numba
compilation is excluded):

* ``bits_per_vertex``: connectivity bits / n (exactly ``4 - 3/n``);
* sizes: the ``.cds`` file as the paper stores it (connectivity + float32 geometry, no
  permutation), with the original vertex order (+4 bytes/vertex), binary OFF (float32 xyz and
  3 int32 per face, Table 2 footnote 6), and gzip (level 6) of that binary OFF;
* encode: maximal Schnyder wood (Appendix A: ccw rotations + vertex conquest, the ``out``
  table) + the mixed word (Sec. 3.1, 3.3) written in one DFS pass -- ``encode_faces``, what
  ``encode_mesh`` runs after validation -- in seconds and vertices per second (Schnyder wood
  included); ``encode_wood_s`` / ``encode_words_s`` split the median run;
* decode: container check (CRC-32 of every section), words -> packed CDS6n refs (Fig. 10-12),
  -> packed CDS5n refs (Fig. 13), -> face list (Thm 2 table with targets), -> Thm 2 table alone;
  vertices per second;
* peak memory of each decoder (``tracemalloc``: numpy allocations, including those the numba
  kernels receive) against the size of what it returns, and of the encoder;
* ``*_cpu_s``: the same medians in CPU seconds of the (single) working thread: on the shared
  2-core box the wall-clock figures move by 2x with the load, these much less.

Usage::

    .venv/bin/python -m benchmarks.bench_codec                      # default sizes
    .venv/bin/python -m benchmarks.bench_codec --meshes random:10000000 --repeats 3
    .venv/bin/python -m benchmarks.bench_codec --quick --json out.json

Meshes: ``random:N[:SEED]`` (Poulalhon--Schaeffer uniform random planar triangulation) or a path
to a mesh file (holes closed with dummy vertices first).
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import platform
import statistics
import sys
import time
import tracemalloc
import zlib
from typing import Optional, Sequence

import numpy as np
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # run as a script too
from benchmarks.script_errors import at_least_one, clean_exit  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
SHARED = os.path.join(os.path.dirname(os.path.dirname(HERE)), "shared", "meshes")
DEFAULT_MESHES = ["random:8000", "random:100000", "random:1000000", "bunny.off", "armadillo.obj"]
QUICK_MESHES = ["random:2000", "cube.off"]


def _log(msg: str) -> None:
    print(f"[bench_codec] {msg}", file=sys.stderr, flush=True)


def load(spec: str):
    from jaxcds.mesh import boundary_loops, close_boundaries, load_mesh

    if spec.startswith("random:"):
        from jaxcds.generators import random_planar_triangulation

        from jaxcds.errors import ArgumentError

        parts = spec.split(":")
        try:  # N may be written 1e7
            n, seed = int(float(parts[1])), int(parts[2]) if len(parts) > 2 else 0
        except ValueError:
            raise ArgumentError(f"--meshes {spec}: expected random:N[:SEED] with whole numbers") from None
        return random_planar_triangulation(n, seed=seed)
    path = spec if os.path.exists(spec) else os.path.join(SHARED, spec)
    m = load_mesh(path)
    if boundary_loops(m):
        m = close_boundaries(m)
    return m


CPU = {}  # id(fn) -> median thread CPU seconds of the last timed() call on it


def timed(fn, repeats: int):
    """(result of the last run, median seconds, all times) after one warm-up run. The median
    thread CPU time is left in ``CPU[id(fn)]``."""
    out = fn()
    times, cpu = [], []
    for _ in range(repeats):
        gc.collect()
        c0 = time.thread_time()
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
        cpu.append(time.thread_time() - c0)
    CPU[id(fn)] = statistics.median(cpu)
    return out, statistics.median(times), times


def timed_cpu(fn, repeats: int):
    """``timed`` plus the median thread CPU seconds."""
    out, med, times = timed(fn, repeats)
    return out, med, CPU.pop(id(fn))


def peak_bytes(fn):
    """Peak traced allocation (bytes) while running ``fn`` and the result's retained size."""
    gc.collect()
    tracemalloc.start()
    tracemalloc.reset_peak()
    base = tracemalloc.get_traced_memory()[0]
    out = fn()
    cur, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return out, peak - base, cur - base


def bench_mesh(spec: str, repeats: int, gzip_max: int) -> dict:
    from jaxcds.codec import decode_faces, decode_paper6n
    from jaxcds.codec import fileformat as ff
    from jaxcds.codec.encode import encode_faces
    from jaxcds.codec.structures import decode_refs5n, decode_refs6n

    t0 = time.perf_counter()
    mesh = load(spec)
    n, F = mesh.num_vertices, mesh.num_faces
    _log(f"{spec}: n = {n}, F = {F} (loaded in {time.perf_counter() - t0:.2f} s)")
    row = {"mesh": spec, "vertices": n, "faces": F}

    row["load_average_start"] = round(os.getloadavg()[0], 2)
    # ---- encode: wood (rotations + conquest) + mixed word, one call
    faces = np.ascontiguousarray(mesh.faces, dtype=np.int32)
    splits = []

    def enc():
        tm = {}
        res = encode_faces(faces, n, mixed=True, timings=tm)
        splits.append((tm["wood_s"] + tm["words_s"], tm["wood_s"], tm["words_s"]))
        return res

    (mixed, order), t_enc, c_enc = timed_cpu(enc, repeats)
    words = mixed
    mid = sorted(splits[1:])[len(splits[1:]) // 2]  # the median timed run's split
    row.update({
        "connectivity_bits": words.num_bits,
        "bits_per_vertex": round(words.num_bits / n, 4),
        "encode_wood_s": round(mid[1], 4),
        "encode_words_s": round(mid[2], 4),
        "encode_total_s": round(t_enc, 4),
        "encode_vertices_per_s": round(n / t_enc),
        "encode_cpu_s": round(c_enc, 4),
    })
    _, peak, _ = peak_bytes(lambda: encode_faces(faces, n, mixed=True))
    row["encode_peak_bytes"] = int(peak)

    # ---- sizes
    pos = mesh.vertices[order].astype(np.float32)
    blob = ff.pack_cds(mixed, positions=pos)
    blob_order = ff.pack_cds(mixed, positions=pos, order=order)
    off = 12 * n + 12 * F + 3 * 4  # binary OFF: float32 xyz, 3 int32 per face, counts header
    row.update({"cds_bytes": len(blob), "cds_with_order_bytes": len(blob_order), "binary_off_bytes": off,
                "cds_vs_binary_off": round(len(blob) / off, 4)})
    if n <= gzip_max:
        raw = (np.asarray([n, F, 0], "<i4").tobytes() + mesh.vertices.astype("<f4").tobytes()
               + mesh.faces.astype("<i4").tobytes())
        t0 = time.perf_counter()
        gz = len(zlib.compress(raw, 6))
        row.update({"gzip_off_bytes": gz, "cds_vs_gzip_off": round(len(blob) / gz, 4),
                    "gzip_s": round(time.perf_counter() - t0, 3)})

    # ---- decode
    _, t_parse, _ = timed(lambda: ff.unpack_cds(blob), repeats)
    r6, t6, c6 = timed_cpu(lambda: decode_refs6n(mixed), repeats)
    r5, t5, c5 = timed_cpu(lambda: decode_refs5n(mixed), repeats)
    (faces, _tab), tf, _ = timed(lambda: decode_faces(mixed), repeats)
    _, tt, _ = timed(lambda: decode_paper6n(mixed, targets=False), repeats)
    del _tab
    row.update({
        "parse_s": round(t_parse, 4),
        "decode_cds6n_s": round(t6, 4), "decode_cds6n_vertices_per_s": round(n / t6),
        "decode_cds5n_s": round(t5, 4), "decode_cds5n_vertices_per_s": round(n / t5),
        "decode_cds6n_cpu_s": round(c6, 4), "decode_cds5n_cpu_s": round(c5, 4),
        "decode_faces_s": round(tf, 4), "decode_faces_vertices_per_s": round(n / tf),
        "decode_table6n_s": round(tt, 4),
    })

    # ---- peak memory of decoding vs the size of the result
    for name, fn, size in (("cds6n", lambda: decode_refs6n(mixed), r6.nbytes),
                           ("cds5n", lambda: decode_refs5n(mixed), r5.nbytes),
                           ("faces", lambda: decode_faces(mixed)[0], faces.nbytes)):
        _, peak, kept = peak_bytes(fn)
        row[f"decode_{name}_peak_bytes"] = int(peak)
        row[f"decode_{name}_result_bytes"] = int(size)
        row[f"decode_{name}_peak_over_result"] = round(peak / size, 3)
    row["load_average_end"] = round(os.getloadavg()[0], 2)
    _log(f"{spec}: encode {t_enc:.3f} s ({n / t_enc / 1e6:.2f} M v/s), decode cds6n {t6:.3f} s "
         f"({n / t6 / 1e6:.1f} M v/s), faces {tf:.3f} s, {len(blob)} bytes")
    return row


def machine() -> dict:
    import numba

    return {"python": platform.python_version(), "numpy": np.__version__, "numba": numba.__version__,
            "cpu": platform.processor() or platform.machine(), "cores": os.cpu_count(),
            "load_average": os.getloadavg()[0] if hasattr(os, "getloadavg") else None}


@clean_exit
def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--meshes", nargs="*", default=None)
    ap.add_argument("--repeats", type=at_least_one, default=3)
    ap.add_argument("--gzip-max", type=int, default=2_000_000, help="skip gzip above this many vertices")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json", default=None, help="write the rows here")
    a = ap.parse_args(argv)
    meshes = a.meshes or (QUICK_MESHES if a.quick else DEFAULT_MESHES)
    rows = [bench_mesh(m, 1 if a.quick else a.repeats, a.gzip_max) for m in meshes]
    out = {"command": " ".join(["python -m benchmarks.bench_codec"] + list(argv or sys.argv[1:])),
           "machine": machine(), "rows": rows}
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)
    cols = ["mesh", "vertices", "bits_per_vertex", "cds_bytes", "binary_off_bytes", "gzip_off_bytes",
            "encode_total_s", "encode_vertices_per_s", "encode_cpu_s", "decode_cds6n_s",
            "decode_cds6n_vertices_per_s", "decode_cds5n_s", "decode_cds5n_vertices_per_s", "decode_cds6n_cpu_s",
            "decode_faces_s", "decode_cds6n_peak_over_result", "load_average_start"]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for r in rows:
        print("| " + " | ".join(str(r.get(c, "-")) for c in cols) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
