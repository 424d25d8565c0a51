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
