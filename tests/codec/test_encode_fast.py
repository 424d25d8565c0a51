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
