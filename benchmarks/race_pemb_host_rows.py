"""pemb normals with the face rows decoded on the host (a numba walk of ``A`` and ``B B*`` through
``jax.pure_callback``), raced in turn beside the default route (per-call tables by parenthesis
searches) and the plain-JAX face list. An experiment, not a library route (RESULTS.md, stop 48).

Why it was tried: issue 5's packed pemb misses 1.5x of the face-list batch (4.7-5.7x) because
its rows need the match of every parenthesis, and XLA:CPU's searches cost about 150 ns per vertex
at 100K. A sequential decoder needs no search: one pass over the darts in walk order with two
stacks (``B``'s and ``B*``'s) gives every dart's origin and twin and every face's entering dart,
and a pass over the faces walks ``next`` three times (:func:`decode_rows`, the same rows as
``face_vertices()``, bit for bit; checked below).

Why it is not the library's route: the decode alone costs 80-90 ns per vertex (branchy stack
updates on random bits, then random reads of the twin table per face), so pemb normals stay
about 3x the face list (2.8x packed), short of 1.5x; ``pure_callback`` adds about 75 us per call
(a 1,000-element +1: 87 us against 11), and programs with host callbacks leave the persistent
compilation cache. A branch-free first pass ran slower (132 against about 42 ns per vertex).

    .venv/bin/python benchmarks/race_pemb_host_rows.py --vertices 100000 --meshes 300
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time

import jax
import jax.numpy as jnp
import numba
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from script_errors import at_least_one, clean_exit  # noqa: E402

from jaxcds.algorithms.normals import (corner_sums, face_list_vertex_normals, face_normals,  # noqa: E402
                                       normalize, vertex_normals)

from race_lf_words import race_in_turn  # noqa: E402
from race_pemb_match import _packed, _single  # noqa: E402


@numba.njit(cache=True, nogil=True)
def _bit(words, i):
    return (words[i >> 5] >> np.uint32(i & 31)) & np.uint32(1)


@numba.njit(cache=True, nogil=True)
def decode_rows(a_words, p_words, num_darts, p_size, ntp, dart_offsets, holes, num_faces,
                num_pfaces):
    """``((num_faces, 3) int32 rows, ok)``: ``face_vertices()`` of a pemb (or a packed union:
    ``dart_offsets`` are the meshes' first darts and the total) from its bits alone. ``ok`` is
    False (rows unspecified) when the bits are not a pemb's walk."""
    rows = np.zeros((num_faces, 3), np.int32)
    org = np.empty(num_darts, np.int32)  # origin of every dart (preorder vertex id)
    tw = np.empty(num_darts, np.int32)  # twin of every dart
    fe = np.full(num_pfaces, -1, np.int32)  # first_dual of every pemb face
    vstack = np.empty(max(ntp // 2 + 1, 1), np.int32)
    tstack = np.empty(max(ntp // 2 + 1, 1), np.int32)
    sstack = np.empty(max((p_size - ntp) // 2 + 1, 1), np.int32)
    tb = 0
    ts = 0
    vcount = 0
    gcount = 0
    for m in range(dart_offsets.size - 1):
        cur = vcount  # the mesh's root
        vcount += 1
        root_face = gcount
        gcount += 1
        vt = 0
        tt = 0
        st = 0
        first_open = -1
        for i in range(dart_offsets[m], dart_offsets[m + 1]):
            org[i] = cur
            if _bit(a_words, i):  # a tree dart: B
                if tb >= ntp:
                    return rows, False
                b = _bit(p_words, tb)
                tb += 1
                if b:  # down to a new child
                    vstack[vt] = cur
                    vt += 1
                    tstack[tt] = i
                    tt += 1
                    cur = vcount
                    vcount += 1
                else:  # back up to the parent
                    if vt == 0:
                        return rows, False
                    vt -= 1
                    cur = vstack[vt]
                    tt -= 1
                    j = tstack[tt]
                    tw[i] = j
                    tw[j] = i
            else:  # a crossing: B*
                if ntp + ts >= p_size:
                    return rows, False
                b = _bit(p_words, ntp + ts)
                ts += 1
                if b:  # enters a new face
                    if gcount >= num_pfaces:
                        return rows, False
                    fe[gcount] = i
                    gcount += 1
                    if first_open < 0:
                        first_open = i
                    sstack[st] = i
                    st += 1
                else:
                    if st == 0:
                        return rows, False
                    st -= 1
                    j = sstack[st]
                    tw[i] = j
                    tw[j] = i
                    if j == first_open:  # the root face's first_dual
                        fe[root_face] = i
        if vt != 0 or st != 0:
            return rows, False
    h = 0
    m = 0
    for g in range(num_pfaces):
        while h < holes.size and holes[h] < g:
            h += 1
        if h < holes.size and holes[h] == g:
            continue  # a border loop
        f = g - h
        e = fe[g]
        if f >= num_faces or e < 0:
            return rows, False
        while dart_offsets[m + 1] <= e:
            m += 1
        d0, d1 = dart_offsets[m], dart_offsets[m + 1]
        for c in range(3):  # next(e) = prev_p(mate(e)) within the mesh's walk
            rows[f, c] = org[e]
            x = tw[e]
            j = d1 - 1 if x == d0 else x - 1
            e = tw[j] if _bit(a_words, j) else j
    return rows, True


def host_rows(s, dart_offsets):
    """``face_vertices()`` of pemb ``s`` decoded on the host (``jax.pure_callback``)."""
    nd, ps, ntp, nf, npf = s.num_darts, s.P.size, s.num_tree_parens, s.num_faces, s._num_pemb_faces

    def decode(aw, pw, doff, holes):
        rows, ok = decode_rows(np.asarray(aw), np.asarray(pw), nd, ps, ntp, np.asarray(doff),
                               np.asarray(holes), nf, npf)
        assert ok, "not a pemb walk"
        return rows

    doff = jnp.concatenate([jnp.asarray(dart_offsets, jnp.int32), jnp.array([nd], jnp.int32)])
    return jax.pure_callback(decode, jax.ShapeDtypeStruct((nf, 3), jnp.int32), s.A.words,
                             s.P.bits.words, doff, s.holes, vmap_method="sequential")


def host_normals(s, pos, dart_offsets):
    fv = host_rows(s, dart_offsets)
    return normalize(corner_sums(face_normals(pos, fv), fv, pos.shape[0]))


def race(label, s, pos, faces, nv, rounds):
    union = getattr(s, "structure", s)  # a PackedBatch's union structure
    offs = getattr(union, "mesh_dart_offsets", None)
    offs = jnp.zeros((1,), jnp.int32) if offs is None else offs
    got = np.asarray(jax.jit(host_rows)(union, offs))
    assert np.array_equal(got, np.asarray(union.face_vertices())), f"{label}: rows differ"
    progs = {"searches": (jax.jit(vertex_normals.__wrapped__).lower(s, pos).compile(), (s, pos)),
             "host rows": (jax.jit(host_normals).lower(union, pos, offs).compile(), (union, pos, offs)),
             "face list": (jax.jit(face_list_vertex_normals.__wrapped__).lower(pos, faces).compile(),
                           (pos, faces))}
    want = np.asarray(progs["face list"][0](pos, faces))
    for k in ("searches", "host rows"):
        err = float(np.max(np.abs(np.asarray(progs[k][0](*progs[k][1])) - want)))
        assert err < 1e-2, f"{label} {k}: normals differ from the face list by {err}"
    times = race_in_turn(progs, rounds)
    for k, ts in times.items():
        paired = statistics.median(t / f for t, f in zip(ts, times["face list"]))
        print(f"{label:>14} {k:>9}: {statistics.median(ts) / nv * 1e9:8.1f} ns/vertex median, "
              f"paired {paired:.2f}x the face list", flush=True)


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vertices", type=int, default=100_000, help="single pemb (0: skip)")
    ap.add_argument("--meshes", type=int, default=300, help="packed pemb batch (0: skip)")
    ap.add_argument("--rounds", type=at_least_one, default=11)
    a = ap.parse_args(argv)
    print(f"jax {jax.__version__}, {jax.devices()}, {platform.processor() or platform.machine()}", flush=True)
    if a.vertices:
        race(f"random:{a.vertices}", *_single(a.vertices), a.rounds)
    if a.meshes:
        race(f"packed:{a.meshes}", *_packed(a.meshes), a.rounds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
