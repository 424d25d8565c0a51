"""Vertex normals with and without the thread-split padding (``base.split_padding``), raced in
one process against the plain-JAX face list (ns per vertex, medians, ratio to the face list;
every route once per round in a shuffled order, ``race_lf_words.race_in_turn``).

XLA:CPU splits a long loop over its threads; when the thread count does not divide the length
it emits a scalar loop instead of the vector one, and a select on a gathered value becomes a
mispredicted branch. The library pads the CDS all-targets pointer jumping (``3n`` entries) so the
count divides it; ``off`` traces the same code with ``split_padding`` returning 0. (The record
``split_padding_2026-12-01.jsonl`` was taken while the scatter normals' rows were padded too:
its lr / lr-bits / halfedge columns are that experiment, not kept: the rows got slower. It was
also taken with the order rotated each round, before this script used ``race_in_turn``, and with
``pack`` where it now concatenates per-mesh builds, as the other races do.)

    .venv/bin/python benchmarks/race_split_padding.py --meshes armadillo.obj,packed:300 --structures cds6n,cds4n,lr
"""

from __future__ import annotations

import argparse
import json
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

from jaxcds.algorithms import normals  # noqa: E402
from jaxcds.errors import ArgumentError  # noqa: E402
from jaxcds.structures import base, cds, registry  # noqa: E402

_USERS = (cds,)  # the modules that call split_padding


def _compiled(s, p, padding: bool):
    """A fresh trace of the normals with the padding on or off (decided at trace time)."""
    real = base.split_padding
    use = real if padding else (lambda length: 0)
    for module in _USERS:
        module.split_padding = use
    try:
        return jax.jit(lambda s, p: normals._vertex_normals.__wrapped__(s, p)).lower(s, p).compile()
    finally:
        for module in _USERS:
            module.split_padding = real


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", default="armadillo.obj,packed:300")
    ap.add_argument("--structures", default="cds6n,cds4n,lr,lr-bits,halfedge")
    ap.add_argument("--rounds", type=at_least_one, default=25)
    a = ap.parse_args(argv)
    # a typo'd name would fall into the skip below (a structure that refuses the mesh) and the
    # run would time the face list alone
    unknown = sorted(set(a.structures.split(",")) - set(registry.names()))
    if unknown:
        raise ArgumentError(f"--structures: unknown structure(s) {unknown}; available: {', '.join(registry.names())}")
    for spec in a.meshes.split(","):
        m, parts = _meshes(spec)
        faces = jnp.asarray(np.asarray(m.faces, np.int32))
        pos = jnp.asarray(np.asarray(m.vertices, np.float32))
        # a compiled program, as the structures' (race_lf_words.face_list_baseline)
        runs = {"face_list": (jax.jit(normals.face_list_vertex_normals.__wrapped__).lower(pos, faces).compile(),
                              (pos, faces))}
        sizes = {}
        for name in a.structures.split(","):
            try:
                s = _structure(name, m, parts)
            except Exception as exc:  # noqa: BLE001 (a structure that refuses the mesh: skipped)
                print(f"# {spec} {name}: skipped ({type(exc).__name__})", flush=True)
                continue
            if s.num_vertices != m.num_vertices:
                print(f"# {spec} {name}: skipped (holes closed by dummy vertices)", flush=True)
                continue
            p, = _in_order(s, pos)
            on, off = _compiled(s, p, True), _compiled(s, p, False)
            np.testing.assert_allclose(np.asarray(on(s, p)), np.asarray(off(s, p)), atol=1e-5)
            runs[f"{name}/on"], runs[f"{name}/off"] = (on, (s, p)), (off, (s, p))
            rows = int(normals.surface_faces_padded(s)[0].shape[0])
            sizes[name] = {"rows": rows, "rows_pad": base.split_padding(rows),
                           "targets_pad": base.split_padding(3 * s.num_vertices) if name.startswith("cds") else None}
        times = race_in_turn(runs, a.rounds)
        n = m.num_vertices
        fl = statistics.median(times["face_list"])
        row = {"mesh": spec, "vertices": n, "threads": base.split_multiple(), "sizes": sizes,
               "ns_per_vertex": {k: round(statistics.median(v) / n * 1e9, 1) for k, v in times.items()},
               "x_face_list": {k: round(statistics.median(v) / fl, 3) for k, v in times.items() if k != "face_list"}}
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
