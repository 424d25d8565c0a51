"""Stage profile of packed-batch vertex normals (issue 5): where the time goes between the
packed compact structures and the plain-JAX face-list batch, in one process, stages in turn.

    .venv/bin/python benchmarks/prof_packed_normals.py --packed 300 --structures lr,cds5n
    flock /tmp/jaxcds_big.lock .venv/bin/python benchmarks/prof_packed_normals.py --packed 1000

Stages (ns per union vertex, medians of ``--repeat`` rounds, every stage once per round):

* ``face_list``: :func:`face_list_vertex_normals` on the union's faces (the peer);
* ``normals``: ``vertex_normals(b, positions)`` as the library runs it;
* ``rows``: ``face_vertices_padded()`` alone, jitted (rows and mask written to memory);
* ``sums_given_rows``: the normals on those rows passed in as parameters (cross products, mask,
  three scatter-adds, normalisation): what the rows cost downstream;
* ``face_list_rows``: the face-list normals on ``rows`` (no mask): the face list's cost on this
  many rows;
* ``normals_before`` (with ``--baseline REV``): the normals with the packed rows of
  ``lr_packed.py`` / ``cds_packed.py`` as they were at git revision ``REV`` (loaded from git into
  a scratch module and run on the same batch): before/after in one process.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import types

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from script_errors import at_least_one, clean_exit  # noqa: E402

from bench_lr_normals import rounds  # noqa: E402

from jaxcds import batch as B  # noqa: E402
from jaxcds.algorithms.normals import (corner_sums, face_list_vertex_normals, face_normals,  # noqa: E402
                                       normalize, vertex_normals)
from jaxcds.generators import random_planar_triangulation  # noqa: E402
from jaxcds.structures.lr import build_lr  # noqa: E402


@jax.jit
def rows_only(b):
    return b.face_vertices_padded()


@jax.jit
def sums_given_rows(pos, fv, ok):
    fn = face_normals(pos, fv)
    fn = jnp.where(ok[:, None], fn, 0.0)
    return normalize(corner_sums(fn, fv, pos.shape[0]))


def _before_rows(rev, name):
    """``face_vertices_padded`` of the packed class as it was at ``rev`` (a function of the
    batch's union structure), or None when that file did not change the rows."""
    path = "jaxcds/structures/" + ("lr_packed.py" if name.startswith("lr") else "cds_packed.py")
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    src = subprocess.check_output(["git", "show", f"{rev}:{path}"], cwd=root).decode()
    mod = types.ModuleType(f"before_{rev}_{os.path.basename(path)[:-3]}")
    exec(compile(src, f"{rev}:{path}", "exec"), mod.__dict__)
    mix = mod._PackedMixin
    if name.startswith("lr"):
        from jaxcds.structures.base import interleave_rows

        def rows(s):
            r, ok, _ = mix._packed_rows(s)
            return interleave_rows(r), interleave_rows(ok)
        return rows
    return lambda s: mix.face_vertices_padded(s)


def _pack(name, ms):
    if name in ("lr", "lr-bits"):
        return B.concatenate([build_lr(m, bits=name == "lr-bits", seeds=1, check=False,
                                       **({"k": 64} if name == "lr-bits" else {})) for m in ms])
    return B.pack(ms, name, check=False)


@clean_exit
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--packed", type=int, default=300)
    ap.add_argument("--structures", default="lr,lr-bits,cds6n,cds5n,cds4n,cds5n-o1")
    ap.add_argument("--repeat", type=at_least_one, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--baseline", default="", help="git revision whose packed rows run as normals_before")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    sizes = rng.integers(500, 5001, args.packed)
    ms = [random_planar_triangulation(int(n), seed=args.seed * 100_003 + i) for i, n in enumerate(sizes)]
    u = B._union(ms)
    faces = jnp.asarray(u.faces)
    upos = np.asarray(u.vertices)
    fl_pos = jnp.asarray(upos, jnp.float32)
    nv = u.num_vertices
    for name in args.structures.split(","):
        b = _pack(name, ms)
        order = np.arange(nv) if b.vertex_order is None else np.asarray(b.vertex_order)
        pos = jnp.asarray(upos[order], jnp.float32)
        fv, ok = jax.block_until_ready(rows_only(b))
        fns = {"face_list": lambda: face_list_vertex_normals(fl_pos, faces),
               "normals": lambda: vertex_normals(b, pos),
               "rows": lambda: rows_only(b),
               "sums_given_rows": lambda: sums_given_rows(pos, fv, ok),
               "face_list_rows": lambda: face_list_vertex_normals(pos, fv)}
        if args.baseline:
            before = _before_rows(args.baseline, name)
            f_before = jax.jit(lambda s, p: sums_given_rows(p, *before(s)))
            fns["normals_before"] = lambda: f_before(b.structure, pos)
        want = np.asarray(face_list_vertex_normals(fl_pos, faces))[order]
        err = float(np.abs(np.asarray(vertex_normals(b, pos)) - want).max())
        t = rounds(fns, args.repeat)
        row = {"packed": args.packed, "structure": name, "vertices": nv, "faces": u.num_faces,
               "rows": int(fv.shape[0]), "masked_rows": int((~np.asarray(ok)).sum())}
        row.update({f"{k}_ns_v": round(1e9 * v / nv, 1) for k, v in t.items()})
        row["normals_ratio"] = round(t["normals"] / t["face_list"], 3)
        if args.baseline:
            row["normals_before_ratio"] = round(t["normals_before"] / t["face_list"], 3)
            row["baseline"] = args.baseline
            row["max_abs_diff_before"] = float(np.abs(np.asarray(fns["normals_before"]()) - want).max())
        row["max_abs_diff"] = err
        print(json.dumps(row), flush=True)
        del b, fns, fv, ok


if __name__ == "__main__":
    sys.exit(main())
