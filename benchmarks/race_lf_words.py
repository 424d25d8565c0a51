"""CDS normals with the slot rows' LeftFronts read two ways, raced in turn against the plain-JAX
face list in one process (ns per vertex, medians, ratio to the face list, fastest run):

* ``words``: the library's route from 2^22 (``cds._WORD_MIN_VERTICES``) to 2^28 vertices: the
  three LeftFronts of every vertex written once as one shift-decoded word each
  (``cds._lf_word``; forced here on any size);
* ``parts``: the route outside that range: every consumer reads the dart's parts off the table
  rows again (forced here with ``cds._WORD_VERTICES = 0``).

Before both, the slot rows decoded packed darts ``2(3 src + col) + r`` with a division by 3
(separate div/rem kernels on XLA:CPU); RESULTS.md, "CDS: slot rows without divisions", has that
comparison.

    .venv/bin/python benchmarks/race_lf_words.py --meshes armadillo.obj,bunny.off,random:200000
    flock /tmp/jaxcds_big.lock .venv/bin/python benchmarks/race_lf_words.py --meshes packed:10000 \\
        --structures cds6n,cds4n --rounds 5

``--meshes``: files of ``$JAXCDS_SHARED_MESHES``, ``random:N`` or ``packed:K`` (K random
triangulations of 500-5,000 vertices, packed).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from script_errors import at_least_one, clean_exit  # noqa: E402

from bench_lr_normals import _mesh  # noqa: E402

from jaxcds import batch as B  # noqa: E402
from jaxcds.algorithms import normals as N  # noqa: E402
from jaxcds.generators import random_planar_triangulation  # noqa: E402
from jaxcds.structures import cds, registry  # noqa: E402

# route -> the (_WORD_MIN_VERTICES, _WORD_VERTICES) it traces with
ROUTES = {"words": (0, cds._WORD_VERTICES), "parts": (0, 0)}


def _meshes(spec):
    """``(mesh, parts or None)``."""
    if spec.startswith("packed:"):
        sizes = np.random.default_rng(0).integers(500, 5001, int(spec[7:]))
        parts = [random_planar_triangulation(int(n), seed=i) for i, n in enumerate(sizes)]
        return B._union(parts), parts
    return _mesh(spec), None


def _structure(name, mesh, parts):
    """Structure ``name`` of ``mesh``, or the packed batch of ``parts`` when given."""
    return B.concatenate([registry.build(name, q) for q in parts]) if parts else registry.build(name, mesh)


def _in_order(s, *arrays):
    """Each of ``arrays`` (rows per input vertex: positions, reference normals) in structure
    ``s``'s vertex order (``s.vertex_order``; as they are when it keeps the input order)."""
    if s.vertex_order is None:
        return arrays
    order = np.asarray(s.vertex_order)
    return tuple(x[order] for x in arrays)


def face_list_baseline(m, public: bool = False):
    """``(positions, faces, normals, runs)`` of mesh ``m`` for a race: float32 positions, int32
    faces, the face list's normals (the reference every route is checked against) and the run
    table holding the face list itself (``{"face_list": (fn, args)}``).

    The face list runs as a compiled program (``jit(...).lower(...).compile()``), as the races
    run every structure's normals: program against program. ``public``: the public
    ``face_list_vertex_normals`` instead, with its argument checks (for races against the peers'
    public calls). Until stop 49 the races paired the public face list with compiled structure
    programs: its checks cost 4 us per call (paired: knight 1.13x, bunny 1.04x, armadillo 1.02x
    the compiled program), a few percent in the structures' favour on small meshes."""
    faces = jnp.asarray(np.asarray(m.faces, np.int32))
    pos = jnp.asarray(np.asarray(m.vertices, np.float32))
    want = np.asarray(N.face_list_vertex_normals(pos, faces))
    fn = (N.face_list_vertex_normals if public else
          jax.jit(N.face_list_vertex_normals.__wrapped__).lower(pos, faces).compile())
    return pos, faces, want, {"face_list": (fn, (pos, faces))}


def race_in_turn(runs, rounds: int, seed: int = 0):
    """``{name: [seconds per run]}``: every ``(f, args)`` of ``runs`` once per round, in an order
    shuffled each round (seeded). A rotated order kept each route's cyclic neighbours: a cheap
    program that always followed one with large temporaries read up to 2.5x slower than the
    same program compiled twice and timed elsewhere in the round (2026-11-30 evening)."""
    keys, times = list(runs), {k: [] for k in runs}
    rng = np.random.default_rng(seed)
    for _ in range(rounds):
        for i in rng.permutation(len(keys)):
            k = keys[i]
            f, args = runs[k]
            t0 = time.perf_counter()
            jax.block_until_ready(f(*args))
            times[k].append(time.perf_counter() - t0)
    return times


def _compiled(limits, s, pos):
    saved = cds._WORD_MIN_VERTICES, cds._WORD_VERTICES
    # read while tracing: each route is compiled under its own values
    cds._WORD_MIN_VERTICES, cds._WORD_VERTICES = limits
    try:
        return jax.jit(lambda s, p: N.normalize(N._scatter_sums(s, p))).lower(s, pos).compile()
    finally:
        cds._WORD_MIN_VERTICES, cds._WORD_VERTICES = saved


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", default="armadillo.obj,bunny.off,random:200000")
    ap.add_argument("--structures", default="cds6n,cds5n,cds4n,cds5n-o1")
    ap.add_argument("--rounds", type=at_least_one, default=15)
    a = ap.parse_args(argv)
    for spec in a.meshes.split(","):
        mesh, parts = _meshes(spec)
        fpos = jnp.asarray(np.asarray(mesh.vertices), jnp.float32)
        faces = jnp.asarray(mesh.faces, jnp.int32)
        want = np.asarray(N.face_list_vertex_normals(fpos, faces))
        for name in a.structures.split(","):
            s = _structure(name, mesh, parts)
            pos, ref = _in_order(s, fpos, want)
            runs = {"face_list": (jax.jit(N.face_list_vertex_normals), (fpos, faces))}
            for route, limits in ROUTES.items():
                f = _compiled(limits, s, pos)
                # summation orders differ: near-cancelling vertex sums of large batches move most
                err = float(np.max(np.abs(np.asarray(f(s, pos)) - ref)))
                assert err < 2e-2, f"{name}/{route}: normals differ from the face list's by {err}"
                runs[route] = (f, (s, pos))
            times = race_in_turn(runs, a.rounds)
            base = statistics.median(times["face_list"])
            cols = "  ".join(f"{k}={1e9 * statistics.median(t) / mesh.num_vertices:.1f} "
                             f"({statistics.median(t) / base:.2f}x, fastest {1e9 * min(t) / mesh.num_vertices:.1f})"
                             for k, t in times.items())
            print(f"{spec} {name}: {cols}", flush=True)
            del s, runs
    return 0


if __name__ == "__main__":
    sys.exit(main())
