"""Words decoded straight into the packed CDS6n / CDS5n arrays (Sec. 3.2, Fig. 10-13): equal, bit
for bit, to the structures built from the Schnyder wood of the decoded mesh, and every protocol
operator agrees with the half-edge (jaxcds.verify)."""

import numpy as np
import pytest

from jaxcds import errors
from jaxcds.codec import decode, decode_faces, encode_mesh, encode_schnyder
from jaxcds.construct.schnyder import schnyder_wood
from jaxcds.generators import random_planar_triangulation
from jaxcds.mesh import TriMesh
from jaxcds.verify import verify

from codec_helpers import fig9, random_words
from conftest import CLOSED_GENUS0, load_shared, mesh_params

cds = pytest.importorskip("jaxcds.structures.cds")


def _reference(words):
    """CDS6n/CDS5n built by issue 3's builders on the decoded mesh, rooted at (0, n-1, 1)."""
    n = words.num_vertices
    faces, _ = decode_faces(words)
    faces = faces.copy()
    k = np.argmin(faces, axis=1)
    rows = np.arange(len(faces))
    rot = np.stack([faces[rows, k], faces[rows, (k + 1) % 3], faces[rows, (k + 2) % 3]], axis=1)
    root = int(np.nonzero((rot == (0, n - 1, 1)).all(axis=1))[0][0])
    faces[root] = (0, n - 1, 1)
    wood = schnyder_wood(faces, n, root_face=root)
    return faces, cds.CDS6n.from_wood(wood), cds.CDS5n.from_wood(wood), cds.CDS4n.from_wood(wood)


def _same(a, b):
    if hasattr(b, "order") and not np.array_equal(np.asarray(a.order), np.asarray(b.order)):
        return False
    return ((a.v_red, a.v_blue, a.v_black) == (b.v_red, b.v_blue, b.v_black)
            and np.array_equal(np.asarray(a.refs), np.asarray(b.refs))
            and np.array_equal(np.asarray(a.F_blue), np.asarray(b.F_blue))
            and a.unused_slots == b.unused_slots
            # the decoders measure the round count on the tables, the builders count fans
            and a.target_rounds == b.target_rounds >= 0)


@pytest.mark.parametrize("n", [4, 5, 7, 30, 400])
@pytest.mark.parametrize("mixed", [False, True])
def test_decode_into_cds_equals_builders(n, mixed):
    m = random_planar_triangulation(n, seed=11 * n)
    w, _ = encode_schnyder(schnyder_wood(m.faces, n))
    if mixed:
        from jaxcds.codec import to_mixed
        w = to_mixed(w)
    faces, ref6, ref5, ref4 = _reference(w)
    assert _same(decode(w, structure="cds6n"), ref6)
    assert _same(decode(w, structure="cds5n"), ref5)
    # beyond the paper (Sec. 5.2): CDS4n via CDS5n + cwBFS relabelling (not memory-free)
    assert _same(decode(w, structure="cds4n"), ref4)


@pytest.mark.parametrize("structure", ["cds6n", "cds5n"])
def test_decoded_cds_passes_the_operator_check(structure):
    """Every protocol operator on every dart against the half-edge of the decoded mesh (one
    size: each verify jit-compiles every operator, ~30 s on the shared machine)."""
    from jaxcds.codec import to_mixed

    n = 200
    m = random_planar_triangulation(n, seed=5)
    w, _ = encode_schnyder(schnyder_wood(m.faces, n))
    faces, _ = decode_faces(w)
    rep = verify(decode(to_mixed(w), structure=structure), TriMesh(vertices=np.zeros((n, 3)), faces=faces))
    assert rep.checked > 0 and rep.mismatches == 0, str(rep)


@pytest.mark.parametrize("name", mesh_params(CLOSED_GENUS0[:4]))
def test_shared_meshes_decode_into_cds(name):
    enc = encode_mesh(load_shared(name))
    faces, ref6, ref5, ref4 = _reference(enc.words)
    assert _same(decode(enc.words, structure="cds6n"), ref6)
    assert _same(decode(enc.words, structure="cds5n"), ref5)
    assert _same(decode(enc.words, structure="cds4n"), ref4)


def test_fig9_words_decode_into_cds6n():
    """The words of Fig. 9 / Sec. 3.1 decode into the packed CDS6n references exactly as into the
    unpacked Thm 2 table. (Fig. 9's wood is the maximal one -- see
    tests/structures/test_cds_paper.py; Fig. 3 draws another wood of the same triangulation, with
    the cw cycle (1, 4, 9) of Sec. 2.2.)"""
    w = fig9()
    faces, _ = decode_faces(w)
    refs = __import__("jaxcds.codec.structures", fromlist=["x"]).decode_refs6n(w)
    # compare with the unpacked table of decode.py
    p = __import__("jaxcds.codec.decode", fromlist=["x"]).decode_paper6n(w)
    for c in range(3):
        assert np.array_equal(refs[:, 2 * c] & ((1 << 30) - 1), p.S[c, 0])
        assert np.array_equal(refs[:, 2 * c + 1] & ((1 << 30) - 1), p.S[c, 1])
        assert np.array_equal(((refs[:, 2 * c].view(np.uint32) >> 30) & 1).astype(bool), p.C[c, 0])
        assert np.array_equal(((refs[:, 2 * c].view(np.uint32) >> 31) & 1).astype(bool), p.I[c])


@pytest.mark.parametrize("seed", range(6))
def test_random_words_into_cds6n_match_the_table(seed):
    from jaxcds.codec.decode import decode_paper6n
    from jaxcds.codec.structures import decode_refs6n

    w = random_words(25 + seed, np.random.default_rng(seed))
    refs, p = decode_refs6n(w), decode_paper6n(w, targets=False)
    for c in range(3):
        for side in range(2):
            assert np.array_equal(refs[:, 2 * c + side] & ((1 << 30) - 1), p.S[c, side])


def test_invalid_words_into_cds_raise():
    w = fig9()
    bits = w.unpacked().copy()
    bits[3] ^= 1
    from jaxcds.codec.words import Words, pack
    for s in ("cds6n", "cds5n"):
        with pytest.raises(errors.EncodingError, match="bit"):
            decode(Words(10, pack(bits)), structure=s)


@pytest.mark.parametrize("n", [6, 200])
def test_non_maximal_words_into_cds6n_are_refused_not_mis_decoded(n):
    """Any wood's words decode to a mesh, but the Thm 7 face map decoded into CDS6n is the
    maximal wood's: a non-maximal wood's words used to give a CDS6n whose face_left /
    face_right / edge_of_face disagreed with the half-edge (exit 0 without --verify). Now the
    clockwise triangle is named; CDS5n refuses those words while decoding."""
    from jaxcds.codec.structures import build_cds

    m = random_planar_triangulation(n, seed=4)
    loose = encode_mesh(m, maximal=False).words
    faces, _ = decode_faces(loose)  # the mesh itself decodes
    assert faces.shape == (2 * n - 4, 3)
    with pytest.raises(errors.EncodingError, match="clockwise triangle"):
        build_cds("cds6n", loose)
    with pytest.raises(errors.EncodingError, match="maximal Schnyder wood"):
        build_cds("cds5n", loose)
    # the maximal wood's words decode (test_decoded_cds_passes_the_operator_check verifies them)
    assert build_cds("cds6n", encode_mesh(m).words).num_vertices == n


@pytest.mark.parametrize("structure", ["cds6n", "cds4n"])
def test_decoded_cds_of_a_holed_mesh_keeps_its_dummies(structure, tmp_path):
    """A ``.cds`` file of a holed mesh: the dummy mask, passed to ``decode``, makes the decoded
    structure's degrees and normals the open surface's (as the builders' structures)."""
    import jax.numpy as jnp

    from jaxcds.algorithms import vertex_degrees, vertex_normals
    from jaxcds.codec import read_cds, write_cds
    from jaxcds.structures.halfedge import HalfEdge

    path = tmp_path / "grid.cds"
    write_cds(path, load_shared("grid.off"))
    mesh, _, words = read_cds(path, original_order=False, drop_dummies=False, return_words=True)
    assert mesh.dummy_vertices.sum() >= 1
    s = decode(words, structure=structure, dummy=mesh.dummy_vertices)
    order = np.arange(s.num_vertices) if s.vertex_order is None else np.asarray(s.vertex_order)
    np.testing.assert_array_equal(np.asarray(s.dummy_vertex_mask()), mesh.dummy_vertices[order])
    he = HalfEdge.from_faces(mesh.faces[~mesh.dummy_faces], mesh.num_vertices)  # the open surface
    pos = jnp.asarray(mesh.vertices, jnp.float32)
    np.testing.assert_allclose(np.asarray(vertex_normals(s, pos[order])),
                               np.asarray(vertex_normals(he, pos))[order], atol=2e-5)
    np.testing.assert_array_equal(np.asarray(vertex_degrees(s)), np.asarray(vertex_degrees(he))[order])
    with pytest.raises(errors.ArgumentError, match="dummy mask of shape"):
        decode(words, structure=structure, dummy=mesh.dummy_vertices[:-1])
    # a mask no hole closing can have written is refused by name (it gave degrees of 0 before)
    wrong = np.zeros_like(mesh.dummy_vertices)
    wrong[list(mesh.faces[0][:2])] = True  # two corners of one face
    with pytest.raises(errors.ArgumentError, match="never share a face"):
        decode(words, structure=structure, dummy=wrong)
    with pytest.raises(errors.ArgumentError, match="never share a face|no face without a dummy"):
        decode(words, structure=structure, dummy=np.ones_like(mesh.dummy_vertices))
    with pytest.raises(errors.ArgumentError, match="booleans"):
        decode(words, structure=structure, dummy=mesh.dummy_vertices * 0.5)
    with pytest.raises(errors.ArgumentError, match="not an array"):
        decode(words, structure=structure, dummy=[True, [False]])
    s01 = decode(words, structure=structure, dummy=mesh.dummy_vertices.astype(np.int8))  # 0/1 ints
    np.testing.assert_array_equal(np.asarray(s01.dummy_vertex_mask()), mesh.dummy_vertices[order])
    with pytest.raises(errors.ArgumentError, match="for the CDS structures"):
        decode(words, structure="faces", dummy=mesh.dummy_vertices)
    with pytest.raises(errors.ArgumentError, match="unknown structure 'bogus'"):
        decode(words, structure="bogus")


@pytest.mark.parametrize("structure", [np.array(["faces", "cds6n"]), ["faces"], 6])
def test_decode_names_a_structure_that_is_no_name(structure):
    """An array as ``structure`` raised numpy's untyped 'truth value of an array is ambiguous'
    ValueError."""
    with pytest.raises(errors.ArgumentError, match=r"unknown structure .*: faces, paper6n, wood, cds6n, cds5n, cds4n"):
        decode(fig9(), structure=structure)
