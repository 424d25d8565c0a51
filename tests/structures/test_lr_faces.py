"""LR / lr-bits whole-mesh faces without navigation (``face_vertices_padded``: one decode per ring
vertex, both slot triangles, redundant T2 copies and border triangles masked, then the T0 rows;
``face_vertices``: the same rows in dense face order), single structures and packed batches.

Oracles are independent of the LR: the input mesh's own face list (what the CornerTable and the
HalfEdge are built from) as a multiset of triangles rotated to start at their smallest id, the
plain-JAX face-list normals (:func:`face_list_vertex_normals`) and their gradient w.r.t.
positions; the dense order is compared with the protocol route (``edge_of_face`` + ``next`` +
``origin``, :meth:`MeshStructure.face_vertices`).

Cost: one jitted program per structure (its static sizes differ), 2-6 s each on a loaded box.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxcds import batch as B
from jaxcds.algorithms import face_list_vertex_normals, vertex_normals
from jaxcds.structures.base import MeshStructure
from jaxcds.structures.base import interleave_rows
from jaxcds.structures.lr import build_lr

from conftest import load_shared, slow_params

# closed genus 0, genus 1, genus 3, holed (dummy vertices: border slots and dummy T0 rows)
# bunny.off and rocker-arm.obj (genus 1) in the slow set: 3holes.off is the quick set's closed
# mesh (genus 3), grid.off its border (CI time)
MESHES = slow_params(["bunny.off", "rocker-arm.obj", "3holes.off", "grid.off"], {"bunny.off", "rocker-arm.obj"})
PACKED = ["grid.off", "3holes.off", "decimated-knight.off"]


@functools.lru_cache(maxsize=None)
def _built(key: str, bits: bool, warts: bool):
    return build_lr(load_shared(key), bits=bits, k=16, seeds=1, check=False, wart_skipping=warts)


def _triangle_multiset(f) -> np.ndarray:
    """Rows rotated to start at their smallest id (orientation kept), sorted lexicographically."""
    f = np.asarray(f, np.int64)
    k = np.argmin(f, axis=1)
    rot = np.stack([f[np.arange(len(f)), (k + j) % 3] for j in range(3)], axis=1)
    return rot[np.lexsort(rot.T[::-1])]


@functools.partial(jax.jit, static_argnames="generic")
def _everything(s, pos, faces_in, w, order, generic=True):
    """Padded and dense faces, the protocol route (``generic``), normals and gradients (LR and
    face list) in ONE program. ``pos``, ``faces_in``, ``w`` in input vertex ids; ``order`` =
    s.vertex_order."""
    fv, ok = s.face_vertices_padded()

    def loss_s(p):
        return jnp.sum(vertex_normals(s, p[order]) * w[order])

    def loss_fl(p):
        return jnp.sum(face_list_vertex_normals(p, faces_in) * w)

    return dict(fv=fv, ok=ok, dense=s.face_vertices(),
                generic=MeshStructure.face_vertices(s) if generic else None,
                n=vertex_normals(s, pos[order]), n_fl=face_list_vertex_normals(pos, faces_in)[order],
                g=jax.grad(loss_s)(pos), g_fl=jax.grad(loss_fl)(pos))


def _check(s, faces_in, vertices, order, generic=True):
    nv = vertices.shape[0]
    assert s.num_vertices == nv and s.num_faces == faces_in.shape[0]
    pos = jnp.asarray(vertices, jnp.float32)
    w = jnp.asarray(np.random.default_rng(0).normal(size=(nv, 3)), jnp.float32)
    out = jax.device_get(_everything(s, pos, jnp.asarray(faces_in, jnp.int32), w,
                                     jnp.asarray(order, jnp.int32), generic=generic))
    fv, ok = out["fv"], out["ok"]
    assert fv.dtype == np.int32 and fv.shape[0] == ok.shape[0]
    # padding rows hold vertex ids too (they are gathered, then masked)
    assert fv.min() >= 0 and fv.max() < nv
    # every input face exactly once among the valid rows, orientation kept
    assert int(ok.sum()) == s.num_faces
    np.testing.assert_array_equal(_triangle_multiset(order[fv[ok]]), _triangle_multiset(faces_in))
    np.testing.assert_array_equal(_triangle_multiset(order[out["dense"]]), _triangle_multiset(faces_in))
    if generic:  # dense order == the protocol route
        np.testing.assert_array_equal(out["dense"], out["generic"])
    np.testing.assert_allclose(out["n"], out["n_fl"], atol=2e-5)
    assert np.abs(out["g_fl"]).max() > 0
    # float32 sums in another order: gradients reach ~200 on the bunny
    np.testing.assert_allclose(out["g"], out["g_fl"], rtol=1e-4, atol=1e-4)
    return out


@pytest.mark.parametrize("bits", [False, True], ids=["lr", "lr-bits"])
@pytest.mark.parametrize("warts", [True, False], ids=["warts", "no-warts"])
@pytest.mark.parametrize("key", MESHES)
def test_slot_faces_equal_mesh_faces(key, bits, warts):
    mesh = load_shared(key)
    s = _built(key, bits, warts)
    out = _check(s, np.asarray(mesh.faces), np.asarray(mesh.vertices), np.asarray(s.vertex_order))
    ok = out["ok"]
    m = s.num_ring
    d = jax.device_get(s._dec(jnp.arange(m, dtype=jnp.int32)))
    skips = int(d.skl.sum() + d.skr.sum())
    # the cases the plan has to get right do occur here: T0^w slots, masked T2 copies
    assert (skips > 0) == warts
    # the padded rows are the slot rows (left slots, right slots, T0) in 16 interleaved blocks
    _, _, ok_l, ok_r, _, ok0 = jax.device_get(s._slot_rows())
    np.testing.assert_array_equal(np.asarray(interleave_rows(jnp.concatenate([ok_l, ok_r, ok0]))), ok)
    assert not (ok_l.all() and ok_r.all())
    # slot mask == the dense-face directory (bit set = a face of its own), slot t = 2v + side
    bit, _ = s._slot_rank(jnp.arange(2 * m, dtype=jnp.int32))
    np.testing.assert_array_equal(np.stack([ok_l, ok_r], axis=1).reshape(-1), np.asarray(bit))
    if s.has_border:  # dummy vertices: border slots and dummy T0 rows are masked
        assert (d.l >= s.num_vertices).any() or (d.r >= s.num_vertices).any()
        t0 = np.asarray(s.V0)[: 3 * s.num_t0].reshape(-1, 3)
        assert (t0 >= s.num_vertices).any(axis=1).sum() == (~ok0).sum() > 0


@pytest.mark.parametrize("bits", [False, True], ids=["lr", "lr-bits"])
@pytest.mark.parametrize("warts", [True, False], ids=["warts", "no-warts"])
def test_packed_slot_faces_equal_mesh_faces(bits, warts):
    """A packed batch of a holed, a genus-3 and a closed genus-0 mesh: the union's padded rows
    (mesh-local decode, offsets added) are the union's faces, the dense ones are the parts' dense
    faces (each equal to its protocol route, test above) shifted mesh by mesh, normals and
    gradient equal the face list's on the union."""
    ms = [load_shared(k) for k in PACKED]
    parts = [_built(k, bits, warts) for k in PACKED]
    b = B.concatenate(parts)
    vo = np.concatenate([[0], np.cumsum([m.num_vertices for m in ms])[:-1]])
    faces_in = np.concatenate([np.asarray(m.faces) + o for m, o in zip(ms, vo)])
    order = np.concatenate([np.asarray(p.vertex_order) + o for p, o in zip(parts, vo)])
    np.testing.assert_array_equal(np.asarray(b.vertex_order), order)
    out = _check(b, faces_in, np.concatenate([np.asarray(m.vertices) for m in ms]), order,
                 generic=False)
    np.testing.assert_array_equal(
        out["dense"], np.concatenate([np.asarray(MeshStructure.face_vertices(p)) + o
                                      for p, o in zip(parts, vo)]))
