"""Packed-batch face rows (``face_vertices_padded`` of the compact batches, issue 5): the
row-building helpers against independent references, and the rows of a batch == every
mesh's faces once, shifted by its vertex offset (multiset of rotated triangles)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxcds import batch as B
from jaxcds.algorithms import face_list_vertex_normals, vertex_normals
from jaxcds.generators import icosphere, random_planar_triangulation
from jaxcds.mesh import load_mesh
from jaxcds.structures import registry
from jaxcds.structures.base import interleave_windows
from jaxcds.structures.lr_packed import _chunk_plan, _pair_blocks, _segment_ids

from conftest import load_shared, octahedron

COUNTS = [
    [5],
    [0, 3, 0, 0, 7, 1, 0],  # empty segments, first one included
    [300, 2, 2, 2, 2, 900, 0, 1, 513],
    list(np.random.default_rng(4).integers(0, 6, 400)),  # many tiny ones: chunk 1 or small
    list(np.random.default_rng(5).integers(200, 2000, 60)),
]


@pytest.mark.parametrize("counts", COUNTS)
def test_segment_ids_equal_repeat(counts):
    """The chunked mesh search == ``np.repeat(arange(B), counts)`` for the pack-time plan, the
    repeat fallback and other plans whose span bound holds (a plan is only right when it
    covers every chunk: checked against the reference too)."""
    counts = np.asarray(counts, np.int64)
    total = int(counts.sum())
    starts = jnp.asarray(np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int32))
    want = np.repeat(np.arange(counts.size), counts)
    plan = _chunk_plan(counts)
    assert plan[1] <= 2 and plan[0] >= 1
    for p in (plan, None, (1, 0), (plan[0], plan[1] + 1)):
        got = np.asarray(jax.jit(_segment_ids, static_argnums=(1, 2))(starts, total, p))
        np.testing.assert_array_equal(got, want, err_msg=str(p))


def _rotated(rows):
    """Rows as triangles rotated to start at their smallest vertex (orientation kept), sorted."""
    rows = np.asarray(rows)
    k = np.argmin(rows, axis=1)
    r = np.stack([rows[np.arange(len(rows)), (k + i) % 3] for i in range(3)], axis=1)
    return r[np.lexsort(r.T[::-1])]


@pytest.mark.parametrize("m", [0, 5, 64, 100, 129, 1000])
def test_interleave_windows_is_a_local_permutation(m):
    """Every row once; inside each full window of 64 rows, rows 8 apart follow each other; the
    tail (m mod 64 rows) stays in place; works on (m, 3) rows as on masks."""
    x = np.asarray(interleave_windows(jnp.arange(m)))
    assert sorted(x.tolist()) == list(range(m))
    full = m - m % 64
    for w in range(0, full, 64):
        want = (w + np.arange(64).reshape(8, 8).T.reshape(-1)).tolist()
        assert x[w:w + 64].tolist() == want
    assert x[full:].tolist() == list(range(full, m))
    rows = np.arange(3 * m).reshape(m, 3)
    np.testing.assert_array_equal(np.asarray(interleave_windows(jnp.asarray(rows))), rows[x])
    a, b, tail = np.arange(m), -np.arange(m) - 1, np.arange(7) + 10 * m
    assert np.asarray(_pair_blocks(jnp.asarray(np.concatenate([a, b, tail])), m)).tolist() == \
        [v for pair in zip(a.tolist(), b.tolist()) for v in pair] + tail.tolist()


@pytest.mark.parametrize("name", ["lr", "lr-bits"])
def test_packed_lr_rows_are_the_meshes_faces(name):
    """Valid rows of the packed LR == the faces of every part (its own ``face_vertices``,
    shifted by the vertex offset), each once; with a holed mesh (border rows masked), meshes of
    different sizes, and normals equal to the face list's on the union (parts' vertex order)."""
    ms = [load_shared("grid.off"), icosphere(1), load_mesh(*octahedron()),
          random_planar_triangulation(60, seed=2)]
    b = B.pack(ms, name)
    parts = [registry.build(name, m) for m in ms]
    fv, ok = jax.jit(lambda s: s.face_vertices_padded())(b)
    fv, ok = np.asarray(fv), np.asarray(ok)
    vo = np.asarray(b.vertex_offsets)
    want = np.concatenate([np.asarray(p.face_vertices()) + o for p, o in zip(parts, vo)])
    np.testing.assert_array_equal(_rotated(fv[ok]), _rotated(want))
    assert fv.min() >= 0 and fv.max() < b.num_vertices
    pos = jnp.asarray(np.random.default_rng(0).normal(size=(b.num_vertices, 3)), jnp.float32)
    np.testing.assert_allclose(np.asarray(vertex_normals(b, pos)),
                               np.asarray(face_list_vertex_normals(pos, jnp.asarray(want))), atol=1e-5)


@pytest.mark.parametrize("fast", [True, False])
def test_packed_lr_t0_rows_both_routes(fast):
    """A part with no T0 triangle keeps a one-entry dummy ``V0``: the union's ``V0`` is then
    longer than ``3 N0`` and the T0 rows take the gather route; when every part has T0s they are
    the union's ``V0`` as it is. Same faces either way."""
    ms = [random_planar_triangulation(30, seed=3), random_planar_triangulation(45, seed=7)]
    if not fast:
        ms.insert(1, load_mesh(*octahedron()))  # no T0 (checked below)
    parts = [registry.build("lr", m) for m in ms]
    b = B.pack(ms, "lr")
    s = b.structure
    assert (s.V0.shape[0] == 3 * s.num_t0) == fast and s.num_t0 > 0
    fv, ok = jax.jit(lambda s: s.face_vertices_padded())(b)
    want = np.concatenate([np.asarray(p.face_vertices()) + o for p, o in zip(parts, np.asarray(b.vertex_offsets))])
    np.testing.assert_array_equal(_rotated(np.asarray(fv)[np.asarray(ok)]), _rotated(want))
