"""Packed LR / lr-bits normals with the decoded ring block written to memory two ways, raced in
one process against the plain-JAX face list (ns per vertex, medians, ratio to the face list;
every route once per round in a shuffled order, ``race_lf_words.race_in_turn``):

* ``loop``: the library's route, ``base.materialize_loop`` (the block as the state of a
  ``while_loop`` that runs once);
* ``scatter``: the route before 2026-12-01, an identity scatter of the five stacked columns
  (rebuilt here; a scatter is never fused with the computation of its updates).

Measured 2026-12-01 (RESULTS.md, "Packed LR: the ring block written by a one-trip loop"):
10,000 meshes lr 1.82x -> 1.42x, lr-bits 2.07x -> 1.51x; 300 meshes 1.33x -> 1.29x and
1.34x -> 1.26x. Writing the interleaved rows once more before the face normals (tried in the same
races) was slower on both sizes.

    .venv/bin/python benchmarks/race_lr_block.py --meshes packed:300 --rounds 25
    flock /tmp/jaxcds_big.lock .venv/bin/python benchmarks/race_lr_block.py --meshes packed:10000 --rounds 7
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

from race_lf_words import _in_order, _meshes, _structure, race_in_turn  # noqa: E402

from jaxcds.algorithms import normals as N  # noqa: E402
from jaxcds.structures import lr_packed  # noqa: E402


def _identity_scatter(xs):
    """The route before: the ``(m,)`` columns stacked and written by an identity scatter."""
    x = jnp.stack(xs, axis=1)
    i = jnp.arange(x.shape[0], dtype=jnp.int32)
    x = jnp.zeros_like(x).at[i].set(x, indices_are_sorted=True, unique_indices=True,
                                    mode="promise_in_bounds")
    return tuple(x[:, k] for k in range(len(xs)))


ROUTES = {"loop": lr_packed.materialize_loop, "scatter": _identity_scatter}


def _compiled(route, s, pos):
    saved = lr_packed.materialize_loop
    lr_packed.materialize_loop = ROUTES[route]  # read while tracing _packed_rows
    try:
        return jax.jit(lambda s, p: N.normalize(N._scatter_sums(s, p))).lower(s, pos).compile()
    finally:
        lr_packed.materialize_loop = saved


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", default="packed:300")
    ap.add_argument("--structures", default="lr,lr-bits")
    ap.add_argument("--rounds", type=at_least_one, default=15)
    a = ap.parse_args(argv)
    for spec in a.meshes.split(","):
        if not spec.startswith("packed:"):
            ap.error(f"{spec}: the block is the packed batches' (packed:K)")
        mesh, parts = _meshes(spec)
        fpos = jnp.asarray(np.asarray(mesh.vertices), jnp.float32)
        faces = jnp.asarray(mesh.faces, jnp.int32)
        want = np.asarray(N.face_list_vertex_normals(fpos, faces))
        runs = {"face_list": (jax.jit(N.face_list_vertex_normals), (fpos, faces))}
        for name in a.structures.split(","):
            s = _structure(name, mesh, parts)
            pos, ref = _in_order(s, fpos, want)
            for route in ROUTES:
                f = _compiled(route, s, pos)
                err = float(np.max(np.abs(np.asarray(f(s, pos)) - ref)))
                assert err < 2e-2, f"{name}/{route}: normals differ from the face list's by {err}"
                runs[f"{name}/{route}"] = (f, (s, pos))
        times = race_in_turn(runs, a.rounds)
        base = statistics.median(times["face_list"])
        for k, t in times.items():
            print(f"{spec} {k}: {1e9 * statistics.median(t) / mesh.num_vertices:.1f} ns/vertex "
                  f"({statistics.median(t) / base:.2f}x, fastest {1e9 * min(t) / mesh.num_vertices:.1f})",
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
