"""Row orders of ``face_vertices_padded`` raced against the face list (issue 5, packed batches):
the same normals program with the structure's slot rows read in different orders, every route
once per round in a rotating order (no route always runs right after another), medians and the
fastest run.

    .venv/bin/python benchmarks/race_row_orders.py --mesh packed:300 --structures lr --orders cur,g8,p8x8
    flock /tmp/jaxcds_big.lock .venv/bin/python benchmarks/race_row_orders.py --mesh packed:3000 \\
        --structures lr,lr-bits --orders cur,g8 --rounds 10
    .venv/bin/python benchmarks/race_row_orders.py --mesh random:2500000 --structures cds4n --orders cur,p8x8

``--mesh``: ``packed:K`` (K random triangulations of 500-5,000 vertices, packed with
``batch.concatenate``), ``random:N`` or a file of ``$JAXCDS_SHARED_MESHES``. Orders:

* ``cur``: the library's own ``face_vertices_padded``;
* ``gB``: the rows in ``B`` interleaved blocks (``base.interleave_rows``);
* ``pDxS``: the two slot rows of each ring vertex (LR) or vertex (CDS: red, then black / blue)
  side by side, then windows of ``D x S`` rows (``base.interleave_windows``);
* ``lDxS``: the windows without the pairing.

Prints one line per route: ns per vertex, x the face list (medians), fastest run, every run.
The normals are compared with the face list's (largest difference printed).
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from script_errors import at_least_one, clean_exit  # noqa: E402

from jaxcds import batch as B  # noqa: E402
from jaxcds.algorithms import normals as N  # noqa: E402
from jaxcds.generators import random_planar_triangulation  # noqa: E402
from jaxcds.mesh import load_mesh  # noqa: E402
from jaxcds.structures import registry  # noqa: E402
from jaxcds.structures.base import interleave_rows, interleave_windows  # noqa: E402
from jaxcds.structures.lr_packed import _pair_blocks  # noqa: E402

from bench_lr_normals import _build as _build_lr  # noqa: E402

SHARED = os.environ.get("JAXCDS_SHARED_MESHES", "/work/shared/meshes")


def arrange(rows, ok, half: int, order: str):
    """``rows`` / ``ok`` (two slot blocks of ``half`` rows first, then the rest) in ``order``."""
    if order.startswith("g"):
        b = int(order[1:])
        return interleave_rows(rows, b), interleave_rows(ok, b)
    depth, stride = (int(t) for t in order[1:].split("x"))
    if order[0] == "p":
        rows, ok = _pair_blocks(rows, half), _pair_blocks(ok, half)
    return interleave_windows(rows, depth, stride), interleave_windows(ok, depth, stride)


def raw_rows(s):
    """``(rows, ok, half)`` of structure ``s`` before any reordering."""
    inner = getattr(s, "structure", s)  # a PackedBatch forwards to its union structure
    if hasattr(inner, "_packed_rows"):  # packed LR
        rows, ok, _ = inner._packed_rows()
        return rows, ok, inner.num_ring
    if hasattr(inner, "_whole_view"):  # packed CDS
        full = type(inner)._base._slot_faces(inner._whole_view())
    elif hasattr(inner, "_slot_faces"):  # one CDS
        full = inner._slot_faces()
    else:  # one LR
        left, right, ok_l, ok_r, t0, ok0 = inner._slot_rows()
        return (jnp.concatenate([left, right, t0]).astype(jnp.int32),
                jnp.concatenate([ok_l, ok_r, ok0]), inner.num_ring)
    valid = inner._slot_valid()
    return jnp.where(valid[:, None], full, 0).astype(jnp.int32), valid, inner.num_vertices


def _orders(text: str) -> list:
    """``--orders``: comma-separated ``cur``, ``gB``, ``pDxS``, ``lDxS`` (a typo was a traceback
    from inside the traced program)."""
    orders = text.split(",")
    bad = [o for o in orders if not re.fullmatch(r"cur|g[1-9][0-9]*|[pl][1-9][0-9]*x[1-9][0-9]*", o)]
    if bad:
        raise argparse.ArgumentTypeError(f"{', '.join(bad)}: expected cur, gB, pDxS or lDxS")
    return orders


def program(order: str):
    if order == "cur":
        return jax.jit(lambda s, p: N.normalize(N._scatter_sums(s, p)))

    def run(s, p):
        rows, ok, half = raw_rows(s)
        fv, valid = arrange(rows, ok, half, order)
        fn = jnp.where(valid[:, None], N.face_normals(p, fv), 0.0)
        return N.normalize(N.corner_sums(fn, fv, s.num_vertices))
    return jax.jit(run)


def _build(name, mesh):
    # LR as the normals benchmarks build it (one hybrid period for lr-bits: builds are not timed)
    return _build_lr(name, mesh) if name in ("lr", "lr-bits") else registry.build(name, mesh)


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default="packed:300")
    ap.add_argument("--structures", default="lr")
    ap.add_argument("--orders", type=_orders, default="cur,g8,p8x8")
    ap.add_argument("--rounds", type=at_least_one, default=5)
    args = ap.parse_args(argv)
    parts = None
    if args.mesh.startswith("packed:"):
        sizes = np.random.default_rng(0).integers(500, 5001, int(args.mesh[7:]))
        parts = [random_planar_triangulation(int(n), seed=i) for i, n in enumerate(sizes)]
        mesh = B._union(parts)
    elif args.mesh.startswith("random:"):
        mesh = random_planar_triangulation(int(args.mesh[7:]), seed=1)
    else:
        mesh = load_mesh(os.path.join(SHARED, args.mesh))
    faces = jnp.asarray(mesh.faces)
    fpos = jnp.asarray(np.asarray(mesh.vertices), jnp.float32)
    nv = mesh.num_vertices
    want = np.asarray(N.face_list_vertex_normals(fpos, faces))
    for name in args.structures.split(","):
        s = B.concatenate([_build(name, m) for m in parts]) if parts else _build(name, mesh)
        order = s.vertex_order
        pos = fpos if order is None else fpos[np.asarray(order)]
        ref = want if order is None else want[np.asarray(order)]
        routes = {"face_list": lambda: N.face_list_vertex_normals(fpos, faces)}
        for o in args.orders:
            f = program(o)
            err = float(np.max(np.abs(np.asarray(f(s, pos)) - ref)))
            print(f"{name}/{o}: largest difference from the face list {err:.2e}", flush=True)
            routes[f"{name}/{o}"] = (lambda f=f: f(s, pos))
        times = {k: [] for k in routes}
        keys = list(routes)
        for r in range(args.rounds):
            for i in range(len(keys)):  # rotating order
                k = keys[(i + r) % len(keys)]
                t0 = time.perf_counter()
                jax.block_until_ready(routes[k]())
                times[k].append(time.perf_counter() - t0)
        base = statistics.median(times["face_list"])
        for k, v in times.items():
            print(f"{k:24s} {1e9 * statistics.median(v) / nv:7.1f} ns/v  {statistics.median(v) / base:.2f}x"
                  f"  fastest {1e9 * min(v) / nv:6.1f}  runs " + " ".join(f"{1e9 * x / nv:.0f}" for x in v),
                  flush=True)
        del s
    return 0


if __name__ == "__main__":
    sys.exit(main())
