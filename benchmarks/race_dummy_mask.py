"""What leaving the hole-closing fans out costs: CDS degrees and normals of a holed mesh with its
dummy vertices known (``dummy_ids``, the library's behaviour) and forgotten (``dummy_ids=None``:
the closed surface's answers, fans included), raced in shuffled turn in one process with the
plain-JAX face list (ns per vertex, medians).

The meshes are Delaunay triangulations of random points in a square, their hull closed by one
dummy vertex (``delaunay_square(n, closed=True)``: the ``square:N`` meshes of ``jaxcds bench``).
Each route checks its answers before it is timed: with the mask, the open surface's degrees and
normals; without it, the closed surface's.

    .venv/bin/python benchmarks/race_dummy_mask.py --vertices 20000,200000,1000000
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks.script_errors import at_least_one, clean_exit  # noqa: E402

from benchmarks.harness import _edge_degrees  # noqa: E402
from benchmarks.race_lf_words import race_in_turn  # noqa: E402
from jaxcds.algorithms import face_list_vertex_normals, vertex_degrees, vertex_normals  # noqa: E402
from jaxcds.generators import delaunay_square  # noqa: E402
from jaxcds.structures import registry  # noqa: E402


def runs_for(n: int, structures, seed: int = 1):
    """``{name: (f, args)}`` for one mesh, every route checked first."""
    m = delaunay_square(n, seed=seed, closed=True)
    own = m.faces[~m.dummy_faces]
    normals = jax.jit(lambda s, p: vertex_normals(s, p))
    degrees = jax.jit(lambda s: vertex_degrees(s))
    runs = {}
    for name in structures:
        s = registry.build(name, m)
        forgot = dataclasses.replace(s, dummy_ids=None)
        order = np.arange(m.num_vertices) if s.vertex_order is None else np.asarray(s.vertex_order)
        p = jnp.asarray(m.vertices[order], jnp.float32)
        for label, x, faces in (("mask", s, own), ("no mask", forgot, m.faces)):
            want_n = face_list_vertex_normals(jnp.asarray(m.vertices, jnp.float32), jnp.asarray(faces))
            got_n = np.asarray(normals(x, p))
            back = np.empty_like(got_n)
            back[order] = got_n
            assert np.abs(back - np.asarray(want_n)).max() < 1e-4, (name, label, "normals")
            got_d = np.asarray(degrees(x))
            back_d = np.empty_like(got_d)
            back_d[order] = got_d
            assert np.array_equal(back_d, _edge_degrees(faces, m.num_vertices)), (name, label, "degrees")
            runs[f"{name} normals, {label}"] = (normals, (x, p))
            runs[f"{name} degrees, {label}"] = (degrees, (x,))
    runs["face list normals (closed)"] = (face_list_vertex_normals,
                                          (jnp.asarray(m.vertices, jnp.float32), jnp.asarray(m.faces)))
    return runs, m.num_vertices


def _vertex_counts(text: str) -> list:
    """``--vertices``: comma-separated whole numbers (argparse's one-line error otherwise)."""
    try:
        return [int(x) for x in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of whole numbers") from None


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--vertices", type=_vertex_counts, default="20000,200000,1000000")
    ap.add_argument("--structures", default="cds6n,cds4n")
    ap.add_argument("--rounds", type=at_least_one, default=15)
    a = ap.parse_args(argv)
    for n in a.vertices:
        runs, nv = runs_for(n, a.structures.split(","))
        for f, args in runs.values():
            jax.block_until_ready(f(*args))  # compile outside the race
        times = race_in_turn(runs, a.rounds)
        print(f"## {nv:,} vertices (square:{n}, closed by one dummy vertex), {a.rounds} rounds")
        print("| route | ns per vertex (median) |")
        print("|---|---|")
        for k, v in times.items():
            print(f"| {k} | {1e9 * float(np.median(v)) / nv:.1f} |")
        print(flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
