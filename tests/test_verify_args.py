"""verify()'s mesh argument: anything but a TriMesh is an ArgumentError naming the type received
and what is expected (a (vertices, faces) tuple or None had been an AttributeError)."""
import pytest

from jaxcds import errors
from jaxcds.generators import icosphere
from jaxcds.structures import registry
from jaxcds.verify import verify


@pytest.fixture(scope="module")
def built():
    m = icosphere(0)
    return registry.build("halfedge", m), m


@pytest.mark.parametrize("name", ["tuple", "NoneType", "str", "ndarray"])
def test_verify_refuses_a_mesh_that_is_not_a_trimesh(built, name):
    s, m = built
    bad = {"tuple": (m.vertices, m.faces), "NoneType": None, "str": "mesh.off",
           "ndarray": m.vertices}[name]
    with pytest.raises(errors.ArgumentError, match=rf"mesh must be a jaxcds.mesh.TriMesh.*got {name}.*load_mesh"):
        verify(s, bad)


def test_verify_still_takes_a_trimesh(built):
    s, m = built
    assert verify(s, m).ok


@pytest.mark.parametrize("name", ["NoneType", "TriMesh", "str", "dict"])
def test_verify_refuses_a_structure_that_is_not_one(built, name):
    """verify()'s first argument: anything but a jaxcds structure is an ArgumentError naming the
    type received and what is expected (None had been an AttributeError on num_vertices, a
    TriMesh -- the arguments swapped -- one on vertex_order)."""
    s, m = built
    bad = {"NoneType": None, "TriMesh": m, "str": "halfedge", "dict": {"num_vertices": 12}}[name]
    with pytest.raises(errors.ArgumentError,
                       match=rf"structure must be a jaxcds structure .*MeshStructure.*registry.build.*got {name}"):
        verify(bad, m)
    with pytest.raises(errors.ArgumentError, match="arguments are swapped"):
        verify(m, s)
