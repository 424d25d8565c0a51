"""How much of a cwBFS-ordered structure's normals ratio is its vertex order: the plain-JAX face
list in the mesh's own order and in the structure's order (faces and positions relabelled by
``vertex_order``), raced in turn against the structure's normals (ns per vertex, medians, ratio
to the face list in the mesh's own order).

CDS4n and CDS5n-O(1) renumber the vertices by the cwBFS of the red tree (Sec. 2.3); the random
triangulations of the benchmarks come in a very local generator order (median label gap over the
edges 4 at 200K vertices, against 80 in cwBFS order; on armadillo the file order's median gap is
1,026 and cwBFS's 7), so their face list is favoured.

    .venv/bin/python benchmarks/race_vertex_order.py --mesh random:200000
    flock /tmp/jaxcds_big.lock .venv/bin/python benchmarks/race_vertex_order.py --mesh random:2500000 --rounds 9
    flock /tmp/jaxcds_big.lock .venv/bin/python benchmarks/race_vertex_order.py --mesh packed:10000 --rounds 5
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
from script_errors import at_least_one, clean_exit  # noqa: E402

from race_lf_words import _meshes, _structure, race_in_turn  # noqa: E402

from jaxcds.algorithms import normals as N  # noqa: E402


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default="random:200000", help="random:N, packed:K or a shared mesh file")
    ap.add_argument("--structure", default="cds4n", help="a structure with a vertex_order")
    ap.add_argument("--rounds", type=at_least_one, default=15)
    a = ap.parse_args(argv)
    mesh, parts = _meshes(a.mesh)
    s = _structure(a.structure, mesh, parts)
    if s.vertex_order is None:
        raise SystemExit(f"{a.structure} keeps the mesh's vertex order: nothing to compare")
    n = mesh.num_vertices
    order = np.asarray(s.vertex_order)  # structure label -> mesh vertex
    label = np.empty_like(order)
    label[order] = np.arange(n, dtype=order.dtype)
    pos, faces = np.asarray(mesh.vertices, np.float32), np.asarray(mesh.faces)
    face_list = jax.jit(N.face_list_vertex_normals)
    normals = jax.jit(lambda s, p: N.normalize(N._scatter_sums(s, p)))
    runs = {"face_list_own_order": (face_list, (jnp.asarray(pos), jnp.asarray(faces))),
            "face_list_structure_order": (face_list, (jnp.asarray(pos[order]), jnp.asarray(label[faces]))),
            a.structure: (normals, (s, jnp.asarray(pos[order])))}
    outs = {k: np.asarray(f(*args)) for k, (f, args) in runs.items()}
    want = outs["face_list_own_order"][order]
    for k in list(runs)[1:]:
        err = float(np.max(np.abs(outs[k] - want)))
        assert err < 2e-2, f"{k}: normals differ from the face list's by {err}"
    times = race_in_turn(runs, a.rounds)
    base = statistics.median(times["face_list_own_order"])
    print(f"{a.mesh} ({n} vertices): " + "  ".join(
        f"{k}={1e9 * statistics.median(t) / n:.1f} ({statistics.median(t) / base:.2f}x)" for k, t in times.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
