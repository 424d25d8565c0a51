"""jaxcds: compact connectivity structures for triangle meshes, in JAX.

Structures are immutable pytrees of int32 arrays; navigation operators are branch-free,
batched and jittable; per-vertex reductions (degrees, normals) run on every structure and
normals are differentiable with respect to positions.
"""

from jaxcds import errors
from jaxcds.mesh import TriMesh, close_boundaries, load_mesh, topology, validate
from jaxcds.structures import CornerTable, HalfEdge, MeshStructure
from jaxcds.structures.registry import build
from jaxcds.algorithms import adjacent, one_ring, vertex_degrees, vertex_normals

__version__ = "0.1.0"

__all__ = ["errors", "TriMesh", "load_mesh", "validate", "topology", "close_boundaries",
           "MeshStructure", "HalfEdge", "CornerTable", "build", "adjacent", "one_ring",
           "vertex_degrees", "vertex_normals", "__version__"]
