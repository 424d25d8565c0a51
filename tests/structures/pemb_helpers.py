"""Small pemb test meshes and the stack oracle for balanced parentheses (shared by
``test_pemb.py`` and ``test_pemb_tables.py``)."""

import numpy as np
from scipy.spatial import Delaunay


def delaunay_faces(n: int, seed: int, hole: bool = False):
    """``(faces, num_vertices)``: the Delaunay triangulation of ``n`` uniform random points of the
    unit square (``default_rng(seed)``), faces turned counter-clockwise, vertices renumbered to
    the used ones. ``hole``: the triangles whose centroid lies within 0.2 of the middle are
    dropped, leaving one inner border loop."""
    pts = np.random.default_rng(seed).random((n, 2))
    faces = Delaunay(pts).simplices.astype(np.int32)
    if hole:
        faces = faces[np.linalg.norm(pts[faces].mean(axis=1) - 0.5, axis=1) > 0.2]
    a, b, c = (pts[faces[:, k]] for k in range(3))
    ccw = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) > 0
    faces[~ccw] = faces[~ccw][:, [0, 2, 1]]
    used = np.unique(faces)
    remap = np.full(n, -1)
    remap[used] = np.arange(used.size)
    return remap[faces].astype(np.int32), int(used.size)


def stack_match(bits: np.ndarray) -> np.ndarray:
    """The matching position of every parenthesis (1 = open) of a balanced sequence, by a stack."""
    match = np.full(bits.size, -1, np.int64)
    stack = []
    for i, x in enumerate(bits):
        if x:
            stack.append(i)
        else:
            j = stack.pop()
            match[i], match[j] = j, i
    return match
