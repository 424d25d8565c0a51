"""Generic algorithms: each runs unchanged on every structure of the registry."""

from jaxcds.algorithms.adjacency import adjacent, one_ring
from jaxcds.algorithms.degrees import vertex_degrees
from jaxcds.algorithms.normals import face_list_vertex_normals, normalize, vertex_normals


def face_vertices(s):
    """``(num_faces, 3)`` int32 vertices of every face, ccw."""
    return s.face_vertices()


__all__ = ["adjacent", "one_ring", "vertex_degrees", "vertex_normals", "face_vertices",
           "face_list_vertex_normals", "normalize"]
