"""The fast encoder (Schnyder-wood ``out`` table + positional red children, packed bits written
directly) against the independent twin-based encoder :func:`encode_wood` (Sec. 3.1, 3.3)."""

import numpy as np
import pytest

from jaxcds import errors
from jaxcds.codec import encode_schnyder, encode_wood, to_mixed
from jaxcds.codec.encode import encode_faces
from jaxcds.construct.schnyder import label_wood, schnyder_out, schnyder_wood
from jaxcds.generators import icosphere, random_planar_triangulation


@pytest.mark.parametrize("n", [4, 5, 7, 60, 1500])
@pytest.mark.parametrize("maximal", [True, False])
def test_encode_faces_equals_the_twin_encoder(n, maximal):
    m = random_planar_triangulation(n, seed=n)
    for root in sorted({0, 1, 2 * n - 5}):
        wood = schnyder_wood(m.faces, n, root_face=root, maximal=maximal)
        ref, ref_order = encode_wood(m.faces, n, wood.out[:, 0], wood.out[:, 2], wood.outer)
        sep, o1 = encode_faces(m.faces, n, mixed=False, maximal=maximal, root_face=root)
        mix, o2 = encode_faces(m.faces, n, mixed=True, maximal=maximal, root_face=root)
        ws, o3 = encode_schnyder(wood, mixed=True)
        assert np.array_equal(sep.bits, ref.bits) and not sep.mixed
        assert np.array_equal(mix.bits, to_mixed(ref).bits) and mix.mixed
        assert np.array_equal(ws.bits, mix.bits)
        for o in (o1, o2, o3):
            assert o.dtype == np.int32 and np.array_equal(o, ref_order)


def test_lean_wood_is_the_labelled_wood():
    m = icosphere(2)
    n = m.num_vertices
    lean = schnyder_out(m.faces, n)
    full = schnyder_wood(m.faces, n)
    assert np.array_equal(lean.out, full.out) and np.array_equal(lean.offsets, full.offsets)
    again = label_wood(lean)
    for k in ("neighbors", "colour", "outgoing", "conquest_order"):
        assert np.array_equal(getattr(again, k), getattr(full, k)), k
    # the unlabelled rotations hold the same neighbours, in the same cyclic order
    for u in range(n):
        a, b = lean.offsets[u], lean.offsets[u + 1]
        x, y = list(lean.neighbors[a:b]), list(full.neighbors[a:b])
        i = x.index(y[0])
        assert x[i:] + x[:i] == y


def test_a_broken_wood_is_refused_not_misencoded():
    n = 200
    m = random_planar_triangulation(n, seed=5)
    wood = schnyder_wood(m.faces, n)
    deg = np.diff(wood.offsets)
    u = next(u for u in range(n) if u not in wood.outer and deg[u] >= 5)
    out = wood.out.copy()
    # give u another neighbour as red parent: the local Schnyder rule no longer holds
    nbrs = wood.neighbors[wood.offsets[u]:wood.offsets[u + 1]]
    out[u, 0] = next(int(x) for x in nbrs if x not in (out[u, 0], out[u, 1], out[u, 2]))
    bad = type(wood)(**{**wood.__dict__, "out": out})
    with pytest.raises(errors.StructureError):
        encode_schnyder(bad)


def test_bad_indices_and_open_fans_are_typed_errors():
    m = random_planar_triangulation(30, seed=1)
    f = m.faces.copy()
    f[3, 1] = 30
    with pytest.raises(errors.InvalidIndexError):
        encode_faces(f, 30)
    f = m.faces.copy()
    f[3] = f[3, ::-1]  # one face flipped: its vertices' fans no longer close
    with pytest.raises(errors.UnsupportedTopologyError):
        encode_faces(f, 30)


def test_giant_vertex_count_is_refused_before_allocating():
    """Sweep: encode_faces(faces, 2**40) raised MemoryError (a 6n + 16 scratch was allocated
    before any check); the codec's vertex ids are int32, so at most 2**31 - 1 vertices."""
    f = random_planar_triangulation(30, seed=1).faces
    for n in (2**40, 2**31):
        with pytest.raises(errors.UnsupportedTopologyError, match=f"num_vertices {n:,} is past the 2,147,483,647"):
            encode_faces(f, n)
    # representable, but not the faces' vertex count: refused before the scratch is allocated
    with pytest.raises(errors.UnsupportedTopologyError, match="F = 2n - 4 faces; got n = 1073741829"):
        encode_faces(f, 2**30 + 5)
    with pytest.raises(errors.ArgumentError, match="num_vertices must be an integer, got 30.0"):
        encode_faces(f, 30.0)


def test_float_faces_are_refused_not_truncated():
    """Sweep: float faces (faces + 0.5, even integral floats) were cast to int32 and encoded."""
    m = random_planar_triangulation(30, seed=1)
    for f in (m.faces.astype(float) + 0.5, m.faces.astype(float), m.faces.astype(np.float32)):
        with pytest.raises(errors.InvalidIndexError, match=f"face indices must be integers, got dtype {f.dtype}"):
            encode_faces(f, 30)
    with pytest.raises(errors.InvalidIndexError, match=r"faces must be \(F, 3\), got shape \(56, 2\)"):
        encode_faces(m.faces[:, :2], 30)
    # int64 ids past int32 would wrap onto valid vertices in the cast
    with pytest.raises(errors.InvalidIndexError, match=r"face 0 refers to vertex 4294967\d+, outside \[0, 30\)"):
        encode_faces(m.faces.astype(np.int64) + 2**32, 30)
    ref = encode_faces(m.faces, 30)[0]
    for f in (m.faces.astype(np.int64), m.faces.astype(np.uint16), m.faces.tolist()):
        assert encode_faces(f, 30)[0] == ref


def test_encode_wood_and_dart_twins_check_their_arrays():
    """Sweep 50c: ``dart_twins`` and ``encode_wood`` handed their faces, parents, ``outer`` and
    ``twin=`` to the numba kernels unchecked (a face id out of range or a twin out of range: a
    segmentation fault). Run in a child interpreter, so the old crash fails this test instead
    of ending the run."""
    from conftest import crash_probe_lines

    code = ("import numpy as np\nfrom jaxcds import errors\n"
            "from jaxcds.codec import dart_twins, encode_wood\n"
            "from jaxcds.construct.schnyder import schnyder_wood\n"
            "from jaxcds.generators import icosphere\n"
            "m = icosphere(1)\nf = np.asarray(m.faces)\nw = schnyder_wood(f, 42)\n"
            "r, k = w.out[:, 0], w.out[:, 2]\ntw = dart_twins(f, 42)\n"
            "assert encode_wood(f, 42, r, k, w.outer, twin=tw)[0] == encode_wood(f, 42, r, k, w.outer)[0]\n"
            "big = f.copy()\nbig[3, 1] = 10 ** 6\nt1 = tw.copy()\nt1[5] = 10 ** 6\n"
            "t2 = tw.copy()\nt2[[0, 1]] = t2[[1, 0]]\n"
            "for call in (lambda: dart_twins(big, 42), lambda: dart_twins(f.ravel(), 42),\n"
            "             lambda: encode_wood(big, 42, r, k, w.outer, twin=np.arange(240)),\n"
            "             lambda: encode_wood(f, 42, r, k, w.outer, twin=t1),\n"
            "             lambda: encode_wood(f, 42, r, k, w.outer, twin=t2),\n"
            "             lambda: encode_wood(f, 42, r[:5], k, w.outer),\n"
            "             lambda: encode_wood(f, 42, r, k, (10 ** 6, 1, 2))):\n"
            "    try:\n        call()\n        print('accepted')\n"
            "    except errors.JaxcdsError as exc:\n        print(type(exc).__name__, exc)\n")
    lines = crash_probe_lines(code)
    assert lines[:2] == [
        "InvalidIndexError dart_twins: face 3 refers to vertex 1000000, outside [0, 42) (1 bad indices in all)",
        "UnreadableMeshError dart_twins: faces must have shape (F, 3), got (240,)"], lines
    assert lines[2].startswith("InvalidIndexError encode_wood: face 3 refers to vertex 1000000"), lines
    assert lines[3] == "ArgumentError encode_wood: twin[5] = 1000000 is not a dart id in [0, 240)", lines
    assert lines[4].startswith("ArgumentError encode_wood: twin[0] = "), lines
    assert "is not the opposite of dart 0" in lines[4], lines
    assert lines[5] == ("ArgumentError encode_wood: red_parent must have shape (42,) (one entry per vertex), "
                        "got (5,)"), lines
    assert lines[6].startswith("ArgumentError encode_wood: outer must be three distinct vertex ids"), lines


def _icosahedron_wood():
    m = icosphere(0)
    f = np.asarray(m.faces)
    w = schnyder_wood(f, 12)
    return f, w.out[:, 0].copy(), w.out[:, 2].copy(), w.outer


def test_dart_twins_names_an_edge_without_its_opposite():
    import re

    from jaxcds.codec import dart_twins

    f = _icosahedron_wood()[0][1:]  # one face gone: its three neighbours' edges lose their twins
    with pytest.raises(errors.UnsupportedTopologyError, match="has no unique opposite half-edge") as exc:
        dart_twins(f, 12)
    a, b, face = (int(x) for x in re.match(r"edge \((\d+), (\d+)\) of face (\d+)", str(exc.value)).groups())
    assert {a, b} <= set(f[face].tolist())


def _swap_outer(outer):
    return (outer[0], outer[2], outer[1])


@pytest.mark.parametrize("change,error,msg", [
    (lambda f, r, k, o: (f[1:], r, k, o), errors.UnsupportedTopologyError,
     r"needs a genus-0 triangulation with n >= 4 and 2n - 4 faces; got n = 12, 19 faces"),
    (lambda f, r, k, o: (f, r + 0.5, k, o), errors.ArgumentError, "encode_wood: red_parent must be integers"),
    (lambda f, r, k, o: (f, r, k + 0.5, o), errors.ArgumentError, "encode_wood: black_parent must be integers"),
    (lambda f, r, k, o: (f, np.full(12, -1), k, o), errors.StructureError,
     "the red tree spans 1 of 12 vertices"),
    (lambda f, r, k, o: (f, r, np.full(12, -1), o), errors.StructureError,
     r"black tree does not have n - 3 = 9 edges"),
    (lambda f, r, k, o: (f, r, k, _swap_outer(o)), errors.StructureError,
     r"outer vertices misplaced \(V_red=\d+, V_blue=\d+, V_black=\d+ must be a clockwise outer face"),
])
def test_encode_wood_refuses_a_wood_that_is_not_one(change, error, msg):
    """Parents of the wrong kind, or parents and outer vertices that are no Schnyder wood of
    the faces: typed errors naming what is wrong (none of these ran in a test)."""
    f, r, k, outer = change(*_icosahedron_wood())
    with pytest.raises(error, match=msg):
        encode_wood(f, 12, r, k, outer)


def test_encode_wood_refuses_a_twin_array_of_floats():
    f, r, k, outer = _icosahedron_wood()
    with pytest.raises(errors.ArgumentError, match="encode_wood: twin must be integers, got dtype float64"):
        encode_wood(f, 12, r, k, outer, twin=np.zeros(60) + 0.5)


@pytest.mark.parametrize("lean", [False, True])
def test_encode_schnyder_of_three_vertices_says_the_encoding_needs_four(lean):
    """The wood check ran first and refused n = 3 as 'offsets[0] = 0: offsets must run from 0 to 6',
    which did not say that the 4n-bit encoding needs n >= 4 (encode_faces says so)."""
    f = np.array([[0, 1, 2], [0, 2, 1]])
    wood = schnyder_out(f, 3) if lean else schnyder_wood(f, 3)
    with pytest.raises(errors.UnsupportedTopologyError, match="the 4n-bit encoding needs n >= 4 vertices, got 3"):
        encode_schnyder(wood)


def test_encode_faces_of_three_vertices_says_the_encoding_needs_four():
    with pytest.raises(errors.UnsupportedTopologyError, match="the 4n-bit encoding needs n >= 4 vertices, got 3"):
        encode_faces(np.array([[0, 1, 2], [0, 2, 1]]), 3)
