"""pemb queries on both spanning trees (issue 7) against brute-force oracles on the host.

The default spanning tree is BFS (near parentheses, fast two-stage searches); the ccw DFS tree
stays available. On a closed mesh (the cube) and a small random planar triangulation with a
border, for both trees: ``mate`` against the pairing the walk recorded (oracle: the stack of
each parenthesis sequence), ``vertex`` / ``first`` / ``last`` against the walk order (a vertex's
positions, ccw), ``get_face(first_dual(g)) == g`` for every pemb face including the root
(``first_dual(0)`` used to be ``2m - 1``, a dart of another face when a BFS walk ends on a tree
half-edge), and the rotation ``next_p`` / ``prev_p`` closing ``last(v) -> first(v)``.
"""

from __future__ import annotations

import os
import pathlib

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxcds import errors
from jaxcds.structures.pemb import PEMB

from pemb_helpers import delaunay_faces, stack_match

SHARED = pathlib.Path(os.environ.get("JAXCDS_SHARED",
                                     pathlib.Path(__file__).resolve().parents[2].parent / "shared"))


def _mate_oracle(A, P, ntp):
    """``mate`` from the bits alone: stack matching in ``B`` and ``B*``, mapped through ``A``."""
    match = stack_match(P)
    ones, zeros = np.nonzero(A == 1)[0], np.nonzero(A == 0)[0]
    r1 = np.cumsum(A) - A
    r0 = np.cumsum(1 - A) - (1 - A)
    out = np.empty(A.size, np.int64)
    for i in range(A.size):
        if A[i]:
            out[i] = ones[match[r1[i]]]
        else:
            out[i] = zeros[match[ntp + r0[i]] - ntp]
    return out


def _vertex_oracle(A, P, ntp):
    """``vertex(i)``: walk order, a stack of tree nodes (preorder ids) driven by ``A`` and ``B``."""
    out = np.empty(A.size, np.int64)
    stack = [0]
    nxt = 1
    b = 0
    for i in range(A.size):
        if A[i] and P[b]:  # down: the half-edge leaves the parent
            out[i] = stack[-1]
            stack.append(nxt)
            nxt += 1
        elif A[i]:  # up: the half-edge leaves the child
            out[i] = stack.pop()
        else:
            out[i] = stack[-1]
        b += int(A[i])
    return out


@jax.jit
def _queries(s, i, v, g):
    return (s.mate(i), s.vertex(i), s.next_p(i), s.prev_p(i), s.first(v), s.last(v),
            s.get_face(s.first_dual(g)))


def _meshes():
    cube = SHARED / "meshes" / "cube.off"
    out = []
    if cube.exists():
        import jaxcds

        m = jaxcds.load_mesh(str(cube))
        out.append(("cube", m.faces, m.num_vertices))
    out.append(("random60",) + delaunay_faces(60, 3))  # 60 points, all used, already ccw
    return out


@pytest.mark.parametrize("tree", ["bfs", "dfs"])
@pytest.mark.parametrize("name,faces,nv", _meshes(), ids=lambda x: x if isinstance(x, str) else "")
def test_queries_against_walk_oracles(tree, name, faces, nv):
    s = PEMB.from_faces(faces, nv, tree=tree)
    A = s.A.to_numpy().astype(np.int64)
    P = s.P.bits.to_numpy().astype(np.int64)
    ntp = s.num_tree_parens
    nf = s.P.size // 2 - ntp // 2 + 1  # pemb faces, holes included
    i = jnp.arange(s.num_darts, dtype=jnp.int32)
    v = jnp.arange(s.num_vertices, dtype=jnp.int32)
    g = jnp.arange(nf, dtype=jnp.int32)
    mate, vert, nxt, prv, first, last, gf = map(np.asarray, _queries(s, i, v, g))
    np.testing.assert_array_equal(mate, _mate_oracle(A, P, ntp))
    vo = _vertex_oracle(A, P, ntp)
    np.testing.assert_array_equal(vert, vo)
    for u in range(s.num_vertices):  # first / last = the vertex's first / last position
        pos = np.nonzero(vo == u)[0]
        assert first[u] == pos.min() and last[u] == pos.max(), (u, first[u], last[u], pos)
    np.testing.assert_array_equal(nxt[last], first)  # the rotation closes
    np.testing.assert_array_equal(prv[first], last)
    np.testing.assert_array_equal(prv[nxt], np.arange(s.num_darts))
    np.testing.assert_array_equal(gf, np.arange(nf))


def test_from_bits_names_the_unbalanced_sequence_and_offset():
    """B and B* are checked apart (B B* can be balanced while neither is): the sequence and the
    offset of its first ')' that closes nothing, or its length when '(' are left open."""
    a = np.array([1, 1, 0, 0], np.uint8)
    with pytest.raises(errors.EncodingError, match=r"pemb: B is unbalanced at offset 0"):
        PEMB.from_bits(a, np.array([0, 1], np.uint8), np.array([1, 0], np.uint8))
    with pytest.raises(errors.EncodingError, match=r"pemb: B\* is unbalanced at offset 2"):
        PEMB.from_bits(a, np.array([1, 0], np.uint8), np.array([1, 1], np.uint8))
    with pytest.raises(errors.EncodingError, match=r"pemb: B is unbalanced at offset 2"):
        PEMB.from_bits(a, np.array([1, 1], np.uint8), np.array([0, 0], np.uint8))
