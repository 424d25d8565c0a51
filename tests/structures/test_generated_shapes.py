"""Every structure on shapes none of the shared meshes has: two hubs of degree 3,000, a strip
whose one hole is 6,000 edges long, poles of a UV sphere (welded seam, slivers), a faceted
cylinder, an icosphere whose vertices, faces and corners are shuffled, a flat annulus (two holes)
and a 3-vertex bipyramid (the smallest closed mesh with two faces per edge pair).

Each shape: every operator on every dart against the half-edge (:func:`jaxcds.verify.verify`),
and degrees and normals against the half-edge of the *open* mesh (the hole-closing fans add
nothing: CDS Sec. 4.5). Structures that refuse a shape must do so with a typed error that names
the genus or the components. Slow: one compilation of every operator per (shape, structure).
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from jaxcds import errors
from jaxcds.algorithms import vertex_degrees, vertex_normals
from jaxcds.mesh import load_mesh
from jaxcds.structures import registry
from jaxcds.structures.halfedge import HalfEdge
from jaxcds.verify import verify

from conftest import as_accepted


def _bipyramid(k):
    """Two poles of degree ``k`` around an equator of ``k`` vertices."""
    t = np.linspace(0, 2 * np.pi, k, endpoint=False)
    v = np.vstack([[0, 0, 1], np.c_[np.cos(t), np.sin(t), np.zeros(k)], [0, 0, -1]])
    i = np.arange(k)
    j = (i + 1) % k
    f = np.vstack([np.c_[np.zeros(k, int), i + 1, j + 1], np.c_[np.full(k, k + 1), j + 1, i + 1]])
    return v, f


def _strip(k):
    """A 2 x k ribbon: one hole of ``2k`` border edges (its dummy vertex has degree ``2k``)."""
    x = np.arange(k, dtype=float)
    v = np.vstack([np.c_[x, np.zeros(k), np.zeros(k)], np.c_[x, np.ones(k), np.zeros(k)]])
    i = np.arange(k - 1)
    return v, np.vstack([np.c_[i, i + 1, i + k], np.c_[i + 1, i + 1 + k, i + k]])


def _flat_annulus(k=64, rings=5):
    t = np.linspace(0, 2 * np.pi, k, endpoint=False)
    v = np.vstack([np.c_[r * np.cos(t), r * np.sin(t), np.zeros(k)] for r in np.linspace(0.5, 1, rings)])
    i = np.arange(k)
    j = (i + 1) % k
    f = [np.vstack([np.c_[a * k + i, (a + 1) * k + i, (a + 1) * k + j],
                    np.c_[a * k + i, (a + 1) * k + j, a * k + j]]) for a in range(rings - 1)]
    return v, np.vstack(f)


def _shuffled(v, f, seed=0):
    """Vertices and faces permuted, each face's corners rotated (orientation kept)."""
    rng = np.random.default_rng(seed)
    p = rng.permutation(len(v))
    inv = np.empty_like(p)
    inv[p] = np.arange(len(p))
    f = inv[f][rng.permutation(len(f))]
    rot = rng.integers(0, 3, len(f))
    return v[p], np.stack([f[np.arange(len(f)), (rot + k) % 3] for k in range(3)], axis=1)


def _trimesh(m):
    return m.vertices, m.faces


SHAPES = {
    "bipyramid-3000": lambda: _bipyramid(3000),
    "bipyramid-3": lambda: _bipyramid(3),
    "strip-3000": lambda: _strip(3000),
    "flat-annulus": _flat_annulus,
    "uv-sphere": lambda: _trimesh(trimesh.creation.uv_sphere(count=[48, 48])),
    "cylinder": lambda: _trimesh(trimesh.creation.cylinder(1.0, 2.0, sections=200)),
    "shuffled-icosphere": lambda: _shuffled(*_trimesh(trimesh.creation.icosphere(3)), seed=3),
    "torus": lambda: _trimesh(trimesh.creation.torus(1.0, 0.3)),
}


@pytest.mark.slow
@pytest.mark.parametrize("structure", registry.names())
@pytest.mark.parametrize("shape", list(SHAPES))
def test_every_structure_on_a_generated_shape(shape, structure):
    v, f = SHAPES[shape]()
    m = load_mesh(np.asarray(v, np.float64), np.asarray(f, np.int64))
    mm = as_accepted(m, structure)
    try:
        s = registry.build(structure, mm)
    except errors.UnsupportedTopologyError as exc:
        assert shape == "torus" and "genus 1" in str(exc), str(exc)
        return
    assert shape != "torus" or structure in ("halfedge", "corner-table", "lr", "lr-bits")
    rep = verify(s, mm)
    assert rep.checked > 10 * m.num_faces and rep.mismatches == 0, str(rep)

    # the reference: the half-edge of the open mesh, dummy vertices (appended by close_boundaries)
    # with degree 0 and a zero normal; the corner table holds the closed mesh it was given
    ref = mm if structure == "corner-table" else m
    he = HalfEdge.from_mesh(ref)
    extra = mm.num_vertices - ref.num_vertices
    pos = np.asarray(mm.vertices, np.float32)
    want_n = np.vstack([np.asarray(vertex_normals(he, pos[:ref.num_vertices])), np.zeros((extra, 3))])
    want_d = np.concatenate([np.asarray(vertex_degrees(he)), np.zeros(extra, np.int32)])
    order = np.arange(mm.num_vertices) if s.vertex_order is None else np.asarray(s.vertex_order)
    np.testing.assert_array_equal(np.asarray(vertex_degrees(s)), want_d[order])
    np.testing.assert_allclose(np.asarray(vertex_normals(s, pos[order])), want_n[order], atol=2e-5)
