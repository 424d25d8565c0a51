"""Vertex normals of the compact structures against the C++ and Python peers (libigl, OpenMesh,
trimesh, the numba loop) and the plain-JAX face list, raced in turn in one process: every program
once per round, in an order shuffled each round (``race_lf_words.race_in_turn``), each ratio
paired round by round with its 95% interval (``benchmarks/paired.py``).

Issue 3 asks for every CDS's normals "faster than libigl, OpenMesh and trimesh on the same mesh";
``jaxcds bench`` times one program after the other (medians of separate runs, under whatever load
each one met), where this race pairs each structure with each peer a few milliseconds apart.
A ratio under 1 is the structure faster; the verdict is against 1.0 for the peers (``met`` when
the whole interval is under it) and against ``--target`` (issue 3's 1.5x) for the face list. Each structure's normals are checked against the face list's before
timing; peers are timed as ``benchmarks/peers.py`` calls them (libigl area weighted, float64:
their APIs) and skipped, by name, when not installed. Every side is its public call, argument
checks included (``vertex_normals``, ``face_list_vertex_normals``, the peers' functions): a
user's call against a user's call.

    .venv/bin/python benchmarks/race_normals_peers.py --meshes bunny.off,cheburashka.obj \\
        --structures cds6n,cds5n,cds4n,cds5n-o1 --peers libigl,openmesh,trimesh --rounds 40
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys

import jax
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from script_errors import at_least_one, clean_exit  # noqa: E402

from paired import paired_summary  # noqa: E402
from peers import PEERS, PeerUnavailable  # noqa: E402
from race_lf_words import _in_order, _meshes, _structure, face_list_baseline, race_in_turn  # noqa: E402

from jaxcds.algorithms import normals  # noqa: E402
from jaxcds.errors import ArgumentError  # noqa: E402


def _peer_runs(names, mesh):
    """``{peer: (callable, ())}`` for the peers of ``names`` that run here; the others are named
    as skipped (:class:`PeerUnavailable`)."""
    runs = {}
    v, f = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int32)
    for name in names:
        try:
            op = PEERS[name](v, f).get("vertex_normals")
        except PeerUnavailable as exc:
            print(f"# {name}: skipped ({exc})", flush=True)
            continue
        if op is not None:
            runs[name] = (op[0], ())
    return runs


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", default="bunny.off,cheburashka.obj,armadillo.obj")
    ap.add_argument("--structures", default="cds6n,cds5n,cds4n,cds5n-o1")
    ap.add_argument("--peers", default="libigl,openmesh,trimesh")
    ap.add_argument("--rounds", type=at_least_one, default=40)
    ap.add_argument("--target", type=float, default=1.5, help="the face list's verdict (issue 3: 1.5x)")
    a = ap.parse_args(argv)
    peers = [p for p in a.peers.split(",") if p]
    unknown = sorted(set(peers) - set(PEERS))
    if unknown:
        raise ArgumentError(f"--peers: unknown peer(s) {unknown}; known: {sorted(PEERS)}")
    for spec in a.meshes.split(","):
        m, parts = _meshes(spec)
        pos, _, want, runs = face_list_baseline(m, public=True)
        structures = []
        for name in a.structures.split(","):
            s = _structure(name, m, parts)
            if s.num_vertices != pos.shape[0]:  # holes closed by dummy vertices: other positions
                print(f"# {spec} {name}: skipped (closes holes with dummy vertices)", flush=True)
                continue
            p, ref = _in_order(s, pos, want)
            own = normals.vertex_normals  # public calls on every side, as users (and the peers) call
            err = float(np.abs(np.asarray(own(s, p)) - ref).max())
            if not err < 1e-4:
                raise SystemExit(f"{spec} {name}: normals differ from the face list's by {err}")
            runs[name] = (own, (s, p))
            structures.append(name)
        runs.update(_peer_runs(peers, m))
        for f, args in runs.values():  # warm: compiled, caches filled, peers' first-call costs paid
            jax.block_until_ready(f(*args))
        t = race_in_turn(runs, a.rounds)
        n = pos.shape[0]
        for key, v in t.items():
            print(f"{spec} {key}: {statistics.median(v) / n * 1e9:.1f} ns/vertex (median)", flush=True)
        for name in structures:
            for other in [k for k in runs if k not in structures]:
                target = a.target if other == "face_list" else 1.0
                print(f"{spec} {name} / {other}: {paired_summary(t[name], t[other], target)}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
