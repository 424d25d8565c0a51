"""CDS-family vertex normals (CDS6n, CDS5n, CDS4n, CDS5n-O(1)): the padded Thm 7 slots
(``face_vertices_padded``: the ``2n`` slots, four masked) against the dense route (the faces
compacted to face ids, ``face_vertices``: what ``vertex_normals`` summed before) and the plain-JAX
face-list normals, in one process.

    .venv/bin/python benchmarks/bench_cds_normals.py --meshes armadillo.obj,bunny.off,random:200000 --min
    flock /tmp/jaxcds_big.lock .venv/bin/python benchmarks/bench_cds_normals.py --meshes random:2500000
    .venv/bin/python benchmarks/bench_cds_normals.py --packed 150 --min   # packed batch, 500-5,000 v/mesh

Columns as in :mod:`bench_lr_normals` (ns per vertex, ratio to ``face_list``; every route runs
once per round, in turn): ``face_list``, ``normals`` (the library: the padded rows summed with
one scatter-add per corner column) and ``dense`` (``segment_sum`` over the repeated rows of
``face_vertices``). The ``three_scatter`` column was dropped with :mod:`bench_lr_normals`'s: it
had become the same program as ``normals``. The command line is
:func:`bench_lr_normals.bench_main` with the CDS structures as defaults.
"""

from __future__ import annotations

import os
import sys

import jax
import jax.numpy as jnp

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from script_errors import clean_exit  # noqa: E402

from bench_lr_normals import bench_main  # noqa: E402

from jaxcds import batch as B  # noqa: E402
from jaxcds.algorithms.normals import face_normals, normalize  # noqa: E402
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


@clean_exit
def main(argv=None):
    bench_main(argv, description=__doc__.splitlines()[0], structures=CDS, build=registry.build,
               pack=lambda ms, name: B.pack(ms, name, check=False),
               routes=lambda a: {"dense": dense_normals})


if __name__ == "__main__":
    sys.exit(main())
