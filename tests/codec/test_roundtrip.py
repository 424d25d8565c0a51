"""Decode -> encode -> decode identity, mesh -> words -> mesh, and the decoded Thm 2 table against
its definitions (CDS paper Sec. 2.1, 3.1, 3.2)."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from jaxcds.codec import (decode, decode_faces, decode_paper6n, encode_mesh, encode_schnyder,
                          encode_wood, to_mixed, to_separate)
from jaxcds.construct.schnyder import schnyder_wood
from jaxcds.generators import icosphere, random_planar_triangulation

from codec_helpers import brute_table, canon_faces, fig9, is_closed_sphere, random_words


@settings(max_examples=60, deadline=None)
@given(n=st.integers(4, 60), seed=st.integers(0, 2**31 - 1))
def test_random_valid_words_decode_to_spheres_and_reencode(n, seed):
    """Every word passing the stack conditions is a Schnyder wood: it decodes to a closed
    sphere, and re-encoding the decoded wood gives back the same bits (decode-encode identity)."""
    w = random_words(n, np.random.default_rng(seed))
    faces, table = decode_faces(w)
    assert is_closed_sphere(faces, n)
    w2, order = encode_wood(faces, n, table.T[0], table.T[2], (0, 1, n - 1))
    assert w2 == w and np.array_equal(order, np.arange(n))
    faces_m, _ = decode_faces(to_mixed(w))
    assert np.array_equal(faces, faces_m)


@pytest.mark.parametrize("n", [4, 5, 10, 200])
@pytest.mark.parametrize("maximal", [True, False])
def test_mesh_words_mesh(n, maximal):
    """mesh -> (any / maximal) Schnyder wood -> words -> faces equals the mesh re-indexed by order,
    and the decoded wood is the encoded one."""
    m = random_planar_triangulation(n, seed=n + 7)
    wood = schnyder_wood(m.faces, n, maximal=maximal)
    words, order = encode_schnyder(wood)
    assert words.num_bits == 4 * n - 3
    w2, o2 = encode_wood(m.faces, n, wood.out[:, 0], wood.out[:, 2], wood.outer)
    assert w2 == words and np.array_equal(o2, order)
    wm, om = encode_schnyder(wood, mixed=True)  # the streamable word written directly
    assert wm == to_mixed(words) and np.array_equal(om, order)
    faces, table = decode_faces(words)
    inv = np.empty(n, np.int64)
    inv[order] = np.arange(n)
    assert canon_faces(inv[m.faces]) == canon_faces(faces)
    for c in range(3):
        tgt = wood.out[order, c]
        expect = np.where(tgt < n, inv[np.minimum(tgt, n - 1)], n)
        assert np.array_equal(table.T[c], expect), c
    # decode -> encode -> decode
    w3, o3 = encode_wood(faces, n, table.T[0], table.T[2], (0, 1, n - 1))
    assert w3 == words and np.array_equal(o3, np.arange(n))


@pytest.mark.parametrize("case", ["fig9", "ico", "random-max", "random-any"])
def test_decoded_table_matches_definitions(case):
    if case == "fig9":
        w = fig9()
    elif case == "ico":
        m = icosphere(1)
        w = encode_mesh(m, mixed=False).words
    else:
        m = random_planar_triangulation(120, seed=3)
        w, _ = encode_schnyder(schnyder_wood(m.faces, 120, maximal=case == "random-max"))
    n = w.num_vertices
    faces, p = decode_faces(w)
    S, C, I = brute_table(faces, p.T, n)
    exists = p.T < n
    for c in range(3):
        for side in range(2):
            ok = exists[c].copy()
            if c == 1 and side == 0:
                ok[n - 1] = False  # LeftFront of (V_black, V_blue) is on the outer face (Thm 4 proof)
            assert np.array_equal(p.S[c, side][ok], S[c, side][ok]), (c, side)
            assert np.array_equal(p.C[c, side][ok], C[c, side][ok]), (c, side)
        assert np.array_equal(p.I[c], I[c]), c
    # the table alone (no targets: the red and black stacks in the blue columns) is the same
    q = decode_paper6n(w, targets=False)
    assert q.T is None and np.array_equal(q.S, p.S) and np.array_equal(q.C, p.C) and np.array_equal(q.I, p.I)


def test_mixed_and_separate_agree_on_a_real_mesh():
    m = icosphere(3)
    enc = encode_mesh(m, mixed=True)
    assert enc.words.mixed and enc.bits_per_vertex < 4
    sep = to_separate(enc.words)
    assert np.array_equal(decode(sep), decode(enc.words))
    assert to_mixed(sep) == enc.words


def test_codec_api_arguments_are_typed():
    """Eighth sweep: encode_mesh(root_face=1.5) encoded from face 1 (int() truncated), mixed='no'
    gave the mixed word (a truthy string); decode(bytes) raised AttributeError and
    Words(20.0, ...) a TypeError inside the decoder."""
    from jaxcds import errors
    from jaxcds.codec.words import Words

    m = random_planar_triangulation(20, seed=1)
    with pytest.raises(errors.InvalidIndexError, match="root_face must be a face index.*1.5"):
        encode_mesh(m, root_face=1.5)
    assert encode_mesh(m, root_face=np.int64(3)).words.num_vertices == 20
    for flag in ("mixed", "maximal", "check", "close"):
        with pytest.raises(errors.ArgumentError, match=f"encode_mesh: {flag} must be True or False"):
            encode_mesh(m, **{flag: "no"})
    w = encode_mesh(m).words
    with pytest.raises(errors.ArgumentError, match="decode: expected jaxcds.codec.Words, got bytes"):
        decode(b"\x89CDS")
    with pytest.raises(errors.EncodingError, match="num_vertices must be an integer, got 20.0"):
        Words(20.0, w.bits, mixed=True)
    assert decode(Words(np.int32(20), w.bits, mixed=True)).shape == (36, 3)


# (sweep 14b) encode_mesh(check=False) closed the holes of an unvalidated mesh: a face id past
# the vertices was a raw IndexError of numpy, a large negative one a segfault. Probed in a child.
_ENCODE_TRUSTED_CHILD = r"""
import numpy as np
from jaxcds.codec import encode_mesh
from jaxcds.mesh import TriMesh

for name, bad in (("past", 7), ("negative", -1), ("negative_huge", -(1 << 30))):
    m = TriMesh(np.zeros((4, 3)), np.array([[0, 1, 2], [0, 2, bad]], np.int32))
    record(name, lambda m: encode_mesh(m, check=False), m)
"""


def test_encode_mesh_unchecked_refuses_ids_out_of_range():
    from conftest import crash_probe

    out = crash_probe(_ENCODE_TRUSTED_CHILD)
    for name, bad in (("past", 7), ("negative", -1), ("negative_huge", -(1 << 30))):
        assert out[name][0] == "InvalidIndexError", out
        assert out[name][1].startswith(f"encode_mesh: arrays: face 1 refers to vertex {bad}, "
                                       "outside [0, 4)"), out


def test_faces_from_paper6n_checks_a_table_it_did_not_decode():
    """Sweep 50c: ``faces_from_paper6n`` indexed by a hand-made table's ``S`` and ``T``
    unchecked (out of range: reads outside the arrays), raised a bare ValueError without targets
    and numpy's "negative dimensions" for n = 1; now an EncodingError / ArgumentError naming the
    entry. Run in a child interpreter, so a crash fails this test instead of ending the run."""
    from conftest import crash_probe_lines

    code = ("import dataclasses, numpy as np\nfrom jaxcds import errors\n"
            "from jaxcds.codec import decode_faces, encode_mesh, faces_from_paper6n\n"
            "from jaxcds.generators import icosphere\n"
            "f, p = decode_faces(encode_mesh(icosphere(1)).words)\n"
            "assert np.array_equal(faces_from_paper6n(p), f)\n"
            "S = p.S.copy()\nS[0, 1, 5] = -10 ** 6\nT = p.T.copy()\nT[2, 7] = 10 ** 6\n"
            "for q in (dataclasses.replace(p, S=S), dataclasses.replace(p, T=T),\n"
            "          dataclasses.replace(p, T=p.T[:, :3]), dataclasses.replace(p, T=p.T + 0.5),\n"
            "          dataclasses.replace(p, T=None)):\n"
            "    try:\n        faces_from_paper6n(q)\n        print('accepted')\n"
            "    except errors.JaxcdsError as exc:\n        print(type(exc).__name__, exc)\n")
    lines = crash_probe_lines(code)
    assert lines == [
        "EncodingError faces_from_paper6n: S[0, 1, 5] = -1000000 is outside [0, 41]",
        "EncodingError faces_from_paper6n: T[2, 7] = 1000000 is outside [0, 42]",
        "EncodingError faces_from_paper6n: S, C, T must have shapes (3, 2, n), (3, 2, n), (3, n) with "
        "n >= 4, got (3, 2, 42), (3, 2, 42), (3, 3)",
        "EncodingError faces_from_paper6n: S and T must be integers and C booleans, got dtypes int32, "
        "bool, float64",
        "ArgumentError faces_from_paper6n needs a table decoded with targets=True"], lines
