"""Where a structure's normals lose against the plain-JAX face list: the row order, or deriving the
faces. Three programs per structure, raced in one process (``race_lf_words.race_in_turn``):

* ``face_list``: the baseline, on the mesh's own ``(F, 3)`` faces in file order;
* ``<structure>/given_rows``: the same face-list program on the structure's own rows
  (``surface_faces_padded``, computed once, outside the timing, unused rows set to vertex 0):
  what the structure's row order alone costs (gathers and scatter-adds in another order);
* ``<structure>``: ``vertex_normals`` on the structure, which derives those rows every call.

``given_rows / face_list`` is the row order's share of the ratio, ``structure / given_rows`` the
derivation's. Each line gives the ratio of the medians and the median of the ratios paired round
by round with its 95% interval and its verdict against ``--target`` (issue 3: 1.5x;
``benchmarks/paired.py``: the pairing cancels the host's drift between rounds). Meshes with holes are skipped for structures that close them (dummy
vertices). Each route's normals are checked against the face list's before timing.

    .venv/bin/python benchmarks/race_face_derivation.py --meshes random:200000,armadillo.obj --structures cds6n,cds5n-o1,lr
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

from race_lf_words import _in_order, _meshes, _structure, face_list_baseline, race_in_turn  # noqa: E402

from paired import paired_summary  # noqa: E402

from jaxcds.algorithms import normals  # noqa: E402


def _given_rows(s):
    """The structure's padded rows (``normals.surface_faces_padded``: hole-closing fans masked too),
    once, with the masked rows pointing at vertex 0: their face normal is then zero, as in the
    structure's own sum."""
    fv, valid = jax.jit(normals.surface_faces_padded)(s)  # masks a packed batch's fans too
    return fv if valid is None else jnp.where(valid[:, None], fv, 0)


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", default="random:200000,armadillo.obj")
    ap.add_argument("--structures", default="cds6n,cds5n-o1")
    ap.add_argument("--rounds", type=at_least_one, default=15)
    ap.add_argument("--target", type=float, default=1.5, help="ratio the paired verdict is against")
    a = ap.parse_args(argv)
    for spec in a.meshes.split(","):
        m, parts = _meshes(spec)
        pos, _, want, runs = face_list_baseline(m)
        for name in a.structures.split(","):
            s = _structure(name, m, parts)
            if s.num_vertices != pos.shape[0]:  # holes closed by dummy vertices: other positions
                print(f"# {spec} {name}: skipped (its {s.num_vertices - pos.shape[0]} hole-closing "
                      "vertices have no positions here)", flush=True)
                continue
            p, ref = _in_order(s, pos, want)
            rows = _given_rows(s)
            own = jax.jit(lambda s, p: normals._vertex_normals.__wrapped__(s, p)).lower(s, p).compile()
            for key, (f, args) in {f"{name}/given_rows": (normals.face_list_vertex_normals, (p, rows)),
                                   name: (own, (s, p))}.items():
                err = float(np.abs(np.asarray(f(*args)) - ref).max())
                if not err < 1e-4:
                    raise SystemExit(f"{spec} {key}: normals differ from the face list's by {err}")
                print(f"# {spec} {key}: largest difference {err:.2e}", flush=True)
                runs[key] = (f, args)
        t = race_in_turn(runs, a.rounds)
        n = pos.shape[0]
        base = statistics.median(t["face_list"])
        for key, v in t.items():
            med = statistics.median(v)
            pair = "" if key == "face_list" else f"; {paired_summary(v, t['face_list'], a.target)}"
            print(f"{spec} {key}: {med / n * 1e9:.1f} ns/vertex, {med / base:.2f}x the face list{pair}",
                  flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
