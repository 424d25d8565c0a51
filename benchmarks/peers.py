"""Peers timed in the same process as the jaxcds structures, on the same face list.

Each peer factory takes ``(vertices float64 (V, 3), faces int32 (F, 3))`` and returns a dict
``op -> (callable, note)``; the callable takes no argument, recomputes from scratch, and returns
something to block on. A missing peer raises :class:`PeerUnavailable` with the reason, and the
harness lists it as skipped.

Normal weightings differ between peers: jaxcds, plain JAX and the numba loop sum unnormalised
face normals (area weighting); libigl is called with ``AREA`` weighting; trimesh's
``vertex_normals`` is trimesh's own (angle weighted in trimesh 4) -- timed as users call it.
"""

from __future__ import annotations

import functools
from typing import Callable, Dict, Tuple

import numpy as np

__all__ = ["PeerUnavailable", "PEERS", "plain_jax", "plain_jax_variants", "numba_loop", "trimesh_peer",
           "libigl_peer", "openmesh_peer"]


class PeerUnavailable(RuntimeError):
    """The peer library is not installed (or cannot run here); the message says why."""


Ops = Dict[str, Tuple[Callable[[], object], str]]


# ---------------------------------------------------------------------------------- plain JAX
def plain_jax(vertices: np.ndarray, faces: np.ndarray, dtype=np.float32) -> Ops:
    """Plain JAX on the ``(F, 3)`` face list: scatter-based normals (``segment_sum``) and
    degrees (``bincount`` of the corners' vertices: on a closed manifold mesh the number of
    incident faces equals the degree)."""
    import jax
    import jax.numpy as jnp

    from jaxcds.algorithms.normals import face_list_vertex_normals

    p = jnp.asarray(vertices, dtype=dtype)
    f = jnp.asarray(faces, dtype=jnp.int32)
    nv = int(vertices.shape[0])

    @jax.jit
    def degrees(f):
        return jax.ops.segment_sum(jnp.ones(f.size, jnp.int32), f.reshape(-1), num_segments=nv)

    return {
        "vertex_normals": (functools.partial(face_list_vertex_normals, p, f), "segment_sum scatter"),
        "vertex_degrees": (functools.partial(degrees, f), "segment_sum of corners (closed meshes)"),
    }


def plain_jax_variants(vertices: np.ndarray, faces: np.ndarray, dtype=np.float32) -> Ops:
    """Three formulations of face-list vertex normals, to pick the fastest on XLA:CPU
    (scatter-add is its slow spot, jax-ml/jax#39959):

    * ``scatter``: ``segment_sum`` over the 3F corners in face order (the baseline);
    * ``sorted_scatter``: corners pre-sorted by vertex once (host), then ``segment_sum`` with
      ``indices_are_sorted=True``;
    * ``padded_gather``: a ``(V, max_degree)`` table of incident faces (padded with a zero face)
      built once on the host; each vertex gathers and sums its face normals -- no scatter at all;
    * ``flat_gather``: the corner positions fetched by one 1-D gather of ``9F`` floats from the
      flattened positions (XLA:CPU gathers of 3-float rows are several times slower per float
      than 1-D gathers), then the baseline scatter.
    """
    import jax
    import jax.numpy as jnp

    from jaxcds.algorithms.normals import face_normals, normalize

    nv = int(vertices.shape[0])
    nf = int(faces.shape[0])
    p = jnp.asarray(vertices, dtype=dtype)
    f = jnp.asarray(faces, dtype=jnp.int32)
    corners_v = faces.reshape(-1).astype(np.int64)
    order = np.argsort(corners_v, kind="stable")
    sorted_v = jnp.asarray(corners_v[order], jnp.int32)
    sorted_face = jnp.asarray(order // 3, jnp.int32)
    deg = np.bincount(corners_v, minlength=nv)
    maxdeg = int(deg.max())
    start = np.concatenate([[0], np.cumsum(deg)[:-1]])
    slot = np.arange(corners_v.size) - np.repeat(start, deg)
    table = np.full((nv, maxdeg), nf, dtype=np.int32)  # nf = the padding (zero) face
    table[corners_v[order], slot] = (order // 3).astype(np.int32)
    table = jnp.asarray(table)

    @jax.jit
    def scatter(p, f):
        fn = face_normals(p, f)
        return normalize(jax.ops.segment_sum(jnp.repeat(fn, 3, axis=0), f.reshape(-1), num_segments=nv))

    @jax.jit
    def sorted_scatter(p, f, sv, sf):
        fn = face_normals(p, f)
        return normalize(jax.ops.segment_sum(fn[sf], sv, num_segments=nv, indices_are_sorted=True))

    @jax.jit
    def padded_gather(p, f, table):
        fn = jnp.concatenate([face_normals(p, f), jnp.zeros((1, 3), p.dtype)])
        return normalize(jnp.sum(fn[table], axis=1))

    idx9 = jnp.asarray((3 * faces.astype(np.int64)[:, :, None] + np.arange(3)).reshape(-1), jnp.int32)

    @jax.jit
    def flat_gather(p, f, idx9):
        q = p.reshape(-1)[idx9].reshape(-1, 3, 3)
        fn = jnp.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0])
        return normalize(jax.ops.segment_sum(jnp.repeat(fn, 3, axis=0), f.reshape(-1), num_segments=nv))

    return {
        "vertex_normals[scatter]": (functools.partial(scatter, p, f), "segment_sum, face order"),
        "vertex_normals[flat_gather]": (functools.partial(flat_gather, p, f, idx9),
                                        "one 1-D gather of the 9F corner coordinates + segment_sum"),
        "vertex_normals[sorted_scatter]": (functools.partial(sorted_scatter, p, f, sorted_v, sorted_face),
                                           "segment_sum, corners pre-sorted by vertex"),
        "vertex_normals[padded_gather]": (functools.partial(padded_gather, p, f, table),
                                          f"(V, {maxdeg}) incident-face table, gather + sum"),
    }


# ---------------------------------------------------------------------------------- numba
def numba_loop(vertices: np.ndarray, faces: np.ndarray, dtype=np.float32) -> Ops:
    """A plain numba loop over faces (area-weighted normals) and corners (degrees)."""
    import numba

    @numba.njit(cache=True)
    def normals(v, f, out):
        out[:] = 0
        for i in range(f.shape[0]):
            a, b, c = f[i, 0], f[i, 1], f[i, 2]
            e1x = v[b, 0] - v[a, 0]
            e1y = v[b, 1] - v[a, 1]
            e1z = v[b, 2] - v[a, 2]
            e2x = v[c, 0] - v[a, 0]
            e2y = v[c, 1] - v[a, 1]
            e2z = v[c, 2] - v[a, 2]
            nx = e1y * e2z - e1z * e2y
            ny = e1z * e2x - e1x * e2z
            nz = e1x * e2y - e1y * e2x
            for k in (a, b, c):
                out[k, 0] += nx
                out[k, 1] += ny
                out[k, 2] += nz
        for j in range(out.shape[0]):
            s = (out[j, 0] ** 2 + out[j, 1] ** 2 + out[j, 2] ** 2) ** 0.5
            if s > 0:
                out[j, 0] /= s
                out[j, 1] /= s
                out[j, 2] /= s
        return out

    @numba.njit(cache=True)
    def degrees(f, out):
        out[:] = 0
        for i in range(f.shape[0]):
            for k in range(3):
                out[f[i, k]] += 1
        return out

    v = np.ascontiguousarray(vertices, dtype=dtype)
    f = np.ascontiguousarray(faces, dtype=np.int32)
    nout = np.empty_like(v)
    dout = np.empty(v.shape[0], np.int32)
    normals(v, f, nout)  # compile outside the timing
    degrees(f, dout)
    return {
        "vertex_normals": (functools.partial(normals, v, f, nout), "face loop, area weighted"),
        "vertex_degrees": (functools.partial(degrees, f, dout), "corner loop"),
    }


# ---------------------------------------------------------------------------------- libraries
def trimesh_peer(vertices: np.ndarray, faces: np.ndarray, dtype=np.float64) -> Ops:
    """trimesh: ``vertex_normals`` and ``vertex_degree`` recomputed from scratch (cache cleared),
    as a user of a fresh ``Trimesh`` pays them."""
    try:
        import trimesh
    except ImportError as exc:  # pragma: no cover - core dependency
        raise PeerUnavailable(f"trimesh not importable: {exc}") from None
    m = trimesh.Trimesh(vertices=np.asarray(vertices, np.float64), faces=np.asarray(faces), process=False)

    def normals():
        m._cache.clear()
        return m.vertex_normals

    def degree():
        m._cache.clear()
        return m.vertex_degree

    return {"vertex_normals": (normals, "Trimesh.vertex_normals (its weighting), float64"),
            "vertex_degrees": (degree, "Trimesh.vertex_degree, float64")}


def libigl_peer(vertices: np.ndarray, faces: np.ndarray, dtype=np.float64) -> Ops:
    """libigl (Python bindings): ``per_vertex_normals`` with area weighting, float64 (its API)."""
    try:
        import igl
    except ImportError as exc:
        raise PeerUnavailable(f"libigl not installed ({exc}); `pip install libigl`") from None
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int64)
    area = igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_AREA
    return {"vertex_normals": (lambda: igl.per_vertex_normals(v, f, area), "per_vertex_normals AREA, float64")}


def openmesh_peer(vertices: np.ndarray, faces: np.ndarray, dtype=np.float64) -> Ops:
    """OpenMesh (openmesh-python): ``update_vertex_normals`` on a TriMesh built once."""
    try:
        import openmesh
    except ImportError as exc:
        raise PeerUnavailable(
            f"openmesh not installed ({exc}); it has no wheel for this Python: `pip install "
            "-e '.[openmesh]'` builds it from source with CMake (about 10 min)") from None
    m = openmesh.TriMesh(np.asarray(vertices, np.float64), np.asarray(faces, np.int32))
    m.request_face_normals()
    m.request_vertex_normals()

    def normals():
        m.update_face_normals()
        m.update_vertex_normals()
        return m.vertex_normals()

    return {"vertex_normals": (normals, "update_face_normals + update_vertex_normals, float64")}


#: name -> factory; the harness runs them in this order
PEERS = {
    "plain-jax": plain_jax,
    "numba-loop": numba_loop,
    "trimesh": trimesh_peer,
    "libigl": libigl_peer,
    "openmesh": openmesh_peer,
}
