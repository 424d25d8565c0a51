"""LR / lr-bits vertex normals: the slot plan (``face_vertices_padded``: one decode per ring
vertex) against the generic per-face route (``edge_of_face`` + two ``next`` + three ``origin``,
what ``vertex_normals`` ran before) and the plain-JAX face-list normals, in one process.

    .venv/bin/python benchmarks/bench_lr_normals.py --meshes armadillo.obj,bunny.off,random:200000
    flock /tmp/jaxcds_big.lock .venv/bin/python benchmarks/bench_lr_normals.py --meshes random:2500000
    .venv/bin/python benchmarks/bench_lr_normals.py --packed 1000      # packed batch, 500-5,000 v/mesh

Columns (ns per vertex, medians of ``--repeat`` rounds, or the fastest with ``--min``; in each
round every route runs once, in turn, so all see the same machine load):

* ``face_list``: :func:`face_list_vertex_normals` on the input faces (the target's peer);
* ``normals``: ``vertex_normals(s, positions)`` as the library runs it: the rows of
  ``face_vertices_padded`` summed by ``normals.corner_sums``, one scatter-add per corner column;
* ``generic``: the protocol route through ``MeshStructure.face_vertices`` (LR before the slot
  plan), summed with one ``segment_sum`` over the rows repeated three times.

A ``three_scatter`` column (the padded rows summed with three scatter-adds instead of one
``segment_sum``: on XLA:CPU, jaxlib 0.10.2, a ``segment_sum`` whose indices are computed in the
same program measured 2-4x slower than with the same indices passed in) was dropped: since
46e600a ``normals.corner_sums`` sums that way, so it timed the very program ``normals`` times.
``segment_sum`` stays measured in ``generic`` here and ``dense`` in :mod:`bench_cds_normals`.

:func:`bench_main` is the command line of this script and of :mod:`bench_cds_normals` (each
passes its own default structures, builder and extra routes).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks.script_errors import at_least_one, clean_exit  # noqa: E402

from jaxcds import batch as B  # noqa: E402
from jaxcds.algorithms.normals import (face_list_vertex_normals, face_normals, normalize,  # noqa: E402
                                       vertex_normals)
from jaxcds.errors import ArgumentError  # noqa: E402
from jaxcds.generators import random_planar_triangulation  # noqa: E402
from jaxcds.mesh import load_mesh  # noqa: E402
from jaxcds.structures.base import MeshStructure  # noqa: E402
from jaxcds.structures.lr import build_lr  # noqa: E402

SHARED = os.environ.get("JAXCDS_SHARED_MESHES", "/work/shared/meshes")


@jax.jit
def generic_normals(s, positions):
    """``vertex_normals`` as it ran before the slot plan: the protocol's per-face route."""
    fv = MeshStructure.face_vertices(s)
    fn = face_normals(positions, fv)
    acc = jax.ops.segment_sum(jnp.repeat(fn, 3, axis=0), fv.reshape(-1), num_segments=s.num_vertices)
    return normalize(acc)


def rounds(fns: dict, repeat: int, stat=statistics.median) -> dict:
    """``stat`` (median; ``min`` with ``--min``: on a box shared with other jobs the fastest round
    is the least disturbed one) of each function's seconds, timed in turn ``repeat`` times after
    one warm-up."""
    for f in fns.values():
        jax.block_until_ready(f())
    ts = {k: [] for k in fns}
    for _ in range(repeat):
        for k, f in fns.items():
            t0 = time.perf_counter()
            jax.block_until_ready(f())
            ts[k].append(time.perf_counter() - t0)
    return {k: stat(v) for k, v in ts.items()}


def _mesh(spec: str):
    if spec.startswith("random:"):
        return random_planar_triangulation(int(spec.split(":")[1]), seed=1)
    return load_mesh(os.path.join(SHARED, spec))


def _emit(label, name, nv, nf, t, err):
    fl = t["face_list"]
    row = {"mesh": label, "structure": name, "vertices": nv, "faces": nf}
    for k, v in t.items():
        row[f"{k}_ns_v"] = round(1e9 * v / nv, 1)
        if k != "face_list":
            row[f"{k}_ratio"] = round(v / fl, 3)
    row["max_abs_diff"] = err
    print(json.dumps(row), flush=True)


def _time_routes(label, name, s, fl_pos, faces, args, routes: dict):
    """Time ``face_list`` (on ``fl_pos`` / ``faces``, the input order), ``normals`` and every
    ``routes`` entry (column -> jitted ``f(s, positions)``) on structure ``s``, in turn; print the
    row with the largest difference from the face-list normals over the structure's routes."""
    nv = fl_pos.shape[0]
    order = np.arange(nv) if s.vertex_order is None else np.asarray(s.vertex_order)
    pos = fl_pos[order]
    fns = {"face_list": lambda: face_list_vertex_normals(fl_pos, faces),
           "normals": lambda: vertex_normals(s, pos)}
    fns.update({k: (lambda f=f: f(s, pos)) for k, f in routes.items()})
    want = np.asarray(face_list_vertex_normals(fl_pos, faces))[order]
    err = max(float(np.abs(np.asarray(fns[k]()) - want).max()) for k in fns if k != "face_list")
    stat = min if args.min else statistics.median
    _emit(label, name, nv, faces.shape[0], rounds(fns, args.repeat, stat), err)


def single(args, build, routes: dict):
    for spec in args.meshes.split(","):
        mesh = _mesh(spec)
        pos_in = jnp.asarray(mesh.vertices, jnp.float32)
        faces = jnp.asarray(mesh.faces, jnp.int32)
        for name in args.structures.split(","):
            _time_routes(spec, name, build(name, mesh), pos_in, faces, args, routes)


def packed(args, pack, routes: dict):
    rng = np.random.default_rng(args.seed)
    sizes = rng.integers(500, 5001, args.packed)
    ms = [random_planar_triangulation(int(n), seed=args.seed * 100_003 + i) for i, n in enumerate(sizes)]
    u = B._union(ms)
    faces = jnp.asarray(u.faces)
    fl_pos = jnp.asarray(np.asarray(u.vertices), jnp.float32)
    for name in args.structures.split(","):
        _time_routes(f"packed:{args.packed}", name, pack(ms, name), fl_pos, faces, args, routes)


def bench_main(argv, *, description: str, structures: str, build, pack, routes,
               no_generic: bool = False):
    """The command line shared by the normals benchmarks: ``build(name, mesh)`` and
    ``pack(meshes, name)`` make the structures, ``routes(args)`` the extra columns (column ->
    jitted ``f(s, positions)``); ``no_generic`` adds the ``--no-generic`` flag."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--meshes", default="armadillo.obj,bunny.off,random:200000")
    ap.add_argument("--structures", default=structures)
    ap.add_argument("--repeat", type=at_least_one, default=7)
    if no_generic:
        ap.add_argument("--no-generic", action="store_true", help="skip the old per-face route")
    ap.add_argument("--packed", type=int, default=0,
                    help="instead: a packed batch of this many random meshes (500-5,000 vertices)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--min", action="store_true", help="fastest round instead of the median")
    args = ap.parse_args(argv)
    packed(args, pack, routes(args)) if args.packed else single(args, build, routes(args))


def _build(name, mesh):
    # any other name built an LR and labelled its row with that name
    if name not in ("lr", "lr-bits"):
        raise ArgumentError(f"--structures {name}: this script times lr and lr-bits only "
                            "(bench_cds_normals.py: the CDS family)")
    # lr-bits: one hybrid period (k=64) instead of "auto" (8 builds): construction is not timed
    return build_lr(mesh, bits=name == "lr-bits", seeds=1, check=False,
                    **({"k": 64} if name == "lr-bits" else {}))


def _pack(ms, name):
    return B.concatenate([_build(name, m) for m in ms])


@clean_exit
def main(argv=None):
    bench_main(argv, description=__doc__.splitlines()[0], structures="lr,lr-bits", build=_build,
               pack=_pack, routes=lambda a: {} if a.no_generic else {"generic": generic_normals},
               no_generic=True)


if __name__ == "__main__":
    sys.exit(main())
