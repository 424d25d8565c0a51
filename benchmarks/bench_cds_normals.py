"""CDS-family vertex normals (CDS6n, CDS5n, CDS4n, CDS5n-O(1)): the padded Thm 7 slots
(``face_vertices_padded``: the ``2n`` slots, four masked) against the dense route (the faces
compacted to face ids, ``face_vertices``: what ``vertex_normals`` summed before) and the plain-JAX
face-list normals, in one process.

    .venv/bin/python benchmarks/bench_cds_normals.py --meshes armadillo.obj,bunny.off,random:200000 --min
    flock /tmp/jaxcds_big.lock .venv/bin/python benchmarks/bench_cds_normals.py --meshes random:2500000
    .venv/bin/python benchmarks/bench_cds_normals.py --packed 150 --min   # packed batch, 500-5,000 v/mesh

Columns as in :mod:`bench_lr_normals` (ns per vertex, ratio to ``face_list``; every route runs
once per round, in turn): ``face_list``, ``normals`` (the library), ``three_scatter`` (the padded
rows summed with one scatter-add per corner column) and ``dense`` (``segment_sum`` over the
repeated rows of ``face_vertices``).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_lr_normals import _emit, _mesh, rounds, three_scatter_normals  # noqa: E402

from jaxcds import batch as B  # noqa: E402
from jaxcds.algorithms.normals import (face_list_vertex_normals, face_normals, normalize,  # noqa: E402
                                       vertex_normals)
from jaxcds.generators import random_planar_triangulation  # noqa: E402
from jaxcds.structures import registry  # noqa: E402

CDS = "cds6n,cds5n,cds4n,cds5n-o1"


@jax.jit
def dense_normals(s, positions):
    """The faces compacted to dense face ids (``face_vertices``), one ``segment_sum`` over the
    repeated rows: ``vertex_normals`` before the padded slots."""
    fv = s.face_vertices()
    fn = face_normals(positions, fv)
    acc = jax.ops.segment_sum(jnp.repeat(fn, 3, axis=0), fv.reshape(-1), num_segments=s.num_vertices)
    return normalize(acc)


def _routes(s, pos, fl_pos, faces):
    return {"face_list": lambda: face_list_vertex_normals(fl_pos, faces),
            "normals": lambda: vertex_normals(s, pos),
            "three_scatter": lambda: three_scatter_normals(s, pos),
            "dense": lambda: dense_normals(s, pos)}


def _err(fns, want):
    return max(float(np.abs(np.asarray(fns[k]()) - want).max()) for k in fns if k != "face_list")


def single(args):
    stat = min if args.min else statistics.median
    for spec in args.meshes.split(","):
        mesh = _mesh(spec)
        pos_in = jnp.asarray(mesh.vertices, jnp.float32)
        faces = jnp.asarray(mesh.faces, jnp.int32)
        for name in args.structures.split(","):
            s = registry.build(name, mesh)
            order = np.arange(mesh.num_vertices) if s.vertex_order is None else np.asarray(s.vertex_order)
            fns = _routes(s, pos_in[order], pos_in, faces)
            want = np.asarray(face_list_vertex_normals(pos_in, faces))[order]
            _emit(spec, name, mesh.num_vertices, mesh.num_faces, rounds(fns, args.repeat, stat), _err(fns, want))
            del s, fns


def packed(args):
    stat = min if args.min else statistics.median
    rng = np.random.default_rng(args.seed)
    sizes = rng.integers(500, 5001, args.packed)
    ms = [random_planar_triangulation(int(n), seed=args.seed * 100_003 + i) for i, n in enumerate(sizes)]
    u = B._union(ms)
    faces = jnp.asarray(u.faces)
    upos = np.asarray(u.vertices)
    fl_pos = jnp.asarray(upos, jnp.float32)
    for name in args.structures.split(","):
        b = B.pack(ms, name, check=False)
        order = np.arange(u.num_vertices) if b.vertex_order is None else np.asarray(b.vertex_order)
        fns = _routes(b, jnp.asarray(upos[order], jnp.float32), fl_pos, faces)
        want = np.asarray(face_list_vertex_normals(fl_pos, faces))[order]
        _emit(f"packed:{args.packed}", name, u.num_vertices, u.num_faces, rounds(fns, args.repeat, stat), _err(fns, want))
        del b, fns


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", default="armadillo.obj,bunny.off,random:200000")
    ap.add_argument("--structures", default=CDS)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--packed", type=int, default=0,
                    help="instead: a packed batch of this many random meshes (500-5,000 vertices)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--min", action="store_true", help="fastest round instead of the median")
    args = ap.parse_args(argv)
    packed(args) if args.packed else single(args)


if __name__ == "__main__":
    main()
