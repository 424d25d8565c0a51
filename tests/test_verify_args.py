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


@pytest.mark.parametrize("kw,want", [
    ({"chunk": -1}, "chunk must be a positive integer, got -1"),
    ({"chunk": 0}, "chunk must be a positive integer, got 0"),
    ({"chunk": 1.5}, "chunk must be a positive integer, got 1.5"),
    ({"adjacency_samples": -1}, "adjacency_samples must be a non-negative integer, got -1"),
    ({"adjacency_samples": 2.5}, "adjacency_samples must be a non-negative integer, got 2.5"),
    ({"seed": "a"}, "seed must be a non-negative integer, got 'a'"),
    ({"seed": -1}, "seed must be a non-negative integer, got -1")])
def test_verify_refuses_chunk_samples_and_seed_out_of_range(built, kw, want):
    """chunk=-1 made range(0, darts, -1) empty: no dart was checked and the report said 0
    mismatches (ok); chunk=0, a float and the others raised Python's / numpy's untyped errors
    (range's ValueError, 'negative dimensions', SeedSequence's TypeError)."""
    s, m = built
    with pytest.raises(errors.ArgumentError, match=f"verify: {want}"):
        verify(s, m, **kw)
    assert verify(s, m, chunk=7, adjacency_samples=0, seed=None).ok  # small values still work


def test_verify_refuses_a_reference_that_is_not_a_halfedge(built):
    """reference=<a TriMesh> raised AttributeError 'all_darts'; another structure an IndexError."""
    s, m = built
    with pytest.raises(errors.ArgumentError, match="verify: reference must be the mesh's HalfEdge .*got TriMesh"):
        verify(s, m, reference=m)


def test_verify_refuses_a_mesh_of_another_size(built):
    """A structure checked against another mesh than its own: named before any comparison."""
    s, _ = built  # the icosahedron's
    with pytest.raises(errors.ArgumentError, match=r"verify: the halfedge has 12 vertices, the mesh 42: pass the "
                                                   "mesh the structure was built from"):
        verify(s, icosphere(1))
