"""pemb queries on both spanning trees (issue 7) against brute-force oracles on the host.

The default spanning tree is BFS (near parentheses, fast two-stage searches); the ccw DFS tree
stays available. On a closed mesh (the cube) and a small random planar triangulation with a
border, for both trees: ``mate`` against the pairing the walk recorded (oracle: the stack of
each parenthesis sequence), ``vertex`` / ``first`` / ``last`` against the walk order (a vertex's
positions, ccw), ``get_face(first_dual(g)) == g`` for every pemb face including the root
(``first_dual(0)`` used to be ``2m - 1``, a dart of another face when a BFS walk ends on a tree
half-edge), and the rotation ``next_p`` / ``prev_p`` closing ``last(v) -> first(v)``.
"""

from __future__ import annotations

import os
import pathlib

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxcds import errors
from jaxcds.structures.pemb import PEMB

from pemb_helpers import delaunay_faces, stack_match

SHARED = pathlib.Path(os.environ.get("JAXCDS_SHARED",
                                     pathlib.Path(__file__).resolve().parents[2].parent / "shared"))


def _mate_oracle(A, P, ntp):
    """``mate`` from the bits alone: stack matching in ``B`` and ``B*``, mapped through ``A``."""
    match = stack_match(P)
    ones, zeros = np.nonzero(A == 1)[0], np.nonzero(A == 0)[0]
    r1 = np.cumsum(A) - A
    r0 = np.cumsum(1 - A) - (1 - A)
    out = np.empty(A.size, np.int64)
    for i in range(A.size):
        if A[i]:
            out[i] = ones[match[r1[i]]]
        else:
            out[i] = zeros[match[ntp + r0[i]] - ntp]
    return out


def _vertex_oracle(A, P, ntp):
    """``vertex(i)``: walk order, a stack of tree nodes (preorder ids) driven by ``A`` and ``B``."""
    out = np.empty(A.size, np.int64)
    stack = [0]
    nxt = 1
    b = 0
    for i in range(A.size):
        if A[i] and P[b]:  # down: the half-edge leaves the parent
            out[i] = stack[-1]
            stack.append(nxt)
            nxt += 1
        elif A[i]:  # up: the half-edge leaves the child
            out[i] = stack.pop()
        else:
            out[i] = stack[-1]
        b += int(A[i])
    return out


@jax.jit
def _queries(s, i, v, g):
    return (s.mate(i), s.vertex(i), s.next_p(i), s.prev_p(i), s.first(v), s.last(v),
            s.get_face(s.first_dual(g)))


def _meshes():
    cube = SHARED / "meshes" / "cube.off"
    out = []
    if cube.exists():
        import jaxcds

        m = jaxcds.load_mesh(str(cube))
        out.append(("cube", m.faces, m.num_vertices))
    out.append(("random60",) + delaunay_faces(60, 3))  # 60 points, all used, already ccw
    return out


@pytest.mark.parametrize("tree", ["bfs", "dfs", "stack"])
@pytest.mark.parametrize("name,faces,nv", _meshes(), ids=lambda x: x if isinstance(x, str) else "")
def test_queries_against_walk_oracles(tree, name, faces, nv):
    s = PEMB.from_faces(faces, nv, tree=tree)
    A = s.A.to_numpy().astype(np.int64)
    P = s.P.bits.to_numpy().astype(np.int64)
    ntp = s.num_tree_parens
    nf = s.P.size // 2 - ntp // 2 + 1  # pemb faces, holes included
    i = jnp.arange(s.num_darts, dtype=jnp.int32)
    v = jnp.arange(s.num_vertices, dtype=jnp.int32)
    g = jnp.arange(nf, dtype=jnp.int32)
    mate, vert, nxt, prv, first, last, gf = map(np.asarray, _queries(s, i, v, g))
    np.testing.assert_array_equal(mate, _mate_oracle(A, P, ntp))
    vo = _vertex_oracle(A, P, ntp)
    np.testing.assert_array_equal(vert, vo)
    for u in range(s.num_vertices):  # first / last = the vertex's first / last position
        pos = np.nonzero(vo == u)[0]
        assert first[u] == pos.min() and last[u] == pos.max(), (u, first[u], last[u], pos)
    np.testing.assert_array_equal(nxt[last], first)  # the rotation closes
    np.testing.assert_array_equal(prv[first], last)
    np.testing.assert_array_equal(prv[nxt], np.arange(s.num_darts))
    np.testing.assert_array_equal(gf, np.arange(nf))


def test_from_bits_names_the_unbalanced_sequence_and_offset():
    """B and B* are checked apart (B B* can be balanced while neither is): the sequence and the
    offset of its first ')' that closes nothing, or its length when '(' are left open."""
    a = np.array([1, 1, 0, 0], np.uint8)
    with pytest.raises(errors.EncodingError, match=r"pemb: B is unbalanced at offset 0"):
        PEMB.from_bits(a, np.array([0, 1], np.uint8), np.array([1, 0], np.uint8))
    with pytest.raises(errors.EncodingError, match=r"pemb: B\* is unbalanced at offset 2"):
        PEMB.from_bits(a, np.array([1, 0], np.uint8), np.array([1, 1], np.uint8))
    with pytest.raises(errors.EncodingError, match=r"pemb: B is unbalanced at offset 2"):
        PEMB.from_bits(a, np.array([1, 1], np.uint8), np.array([0, 0], np.uint8))


def test_from_bits_refuses_an_embedding_without_edges():
    """Sweep 51b: empty A, B and B* were taken as one vertex, no edge and one face; every
    batch operator (origin, face, is_border of the empty id array: the per-call tables) and
    ``with_tables`` then raised JAX's TypeError (a gather from the empty B B*), and so did a
    packed batch holding one. One edge or one loop is still a pemb."""
    for empty in ([], "", np.zeros(0, np.uint8)):
        with pytest.raises(errors.EncodingError, match=r"pemb: A, B and B\* are empty \(no edge\)"):
            PEMB.from_bits(empty, empty, empty)
    assert PEMB.from_bits([1, 1], [1, 0], []).num_vertices == 2
    assert PEMB.from_bits([0, 0], [], [1, 0], holes=[1]).num_faces == 1



def _bits_of(s):
    """``(A, B, B*)`` of a built PEMB as host uint8 arrays (1 = tree edge, 1 = '(')."""
    a = np.asarray(s.A.access(jnp.arange(s.A.size))).astype(np.uint8)
    p = np.asarray(s.P.is_open(jnp.arange(s.P.size))).astype(np.uint8)
    return a, p[:s.num_tree_parens], p[s.num_tree_parens:]


@pytest.mark.parametrize("change, message", [
    (dict(A="half"), r"pemb: the bits of A hold 0.5 at offset \d+, expected 0 or 1"),
    (dict(B="minus"), r"pemb: the bits of B hold -1 at offset 1"),
    (dict(A="2d"), r"pemb: the bits of A must be one sequence of bits \(1-D\)"),
    (dict(A=None), r"pemb: the bits of A must be 0/1 values"),
    (dict(holes=[99]), r"pemb: holes\[0\] = 99 is outside \[0, 20\)"),
    (dict(holes=[-1]), r"pemb: holes\[0\] = -1 is outside"),
    (dict(holes=[0.5]), r"pemb: holes must be a sequence of pemb face ids"),
    (dict(holes=[0, 0], num_faces=18), r"pemb: holes name face 0 twice"),
    (dict(order="repeat"), r"pemb: order is not a permutation of the 12 vertices \(vertex 1 is missing\)"),
    (dict(order=[0, 1]), r"pemb: order has 2 entries for 12 vertices"),
    (dict(order="half"), r"pemb: order must be a sequence of input vertex ids"),
    (dict(num_faces=2.5), r"pemb: 20 faces in B\* but 2.5 triangles"),
    (dict(num_faces=True), r"pemb: 20 faces in B\* but True triangles"),
])
def test_from_bits_refuses_what_it_would_misread(change, message):
    """Stop 50: ``from_bits`` cast its sequences to uint8 (0.5 read as 0, a 2-D array
    flattened), and took ``holes`` out of range or repeated and an ``order`` that is not a
    permutation (per-vertex data read through it would be misplaced), 1.5 read as 1; ``None``
    raised Python's TypeError. Each is an EncodingError naming the argument and the entry."""
    from jaxcds.generators import icosphere

    m = icosphere(0)
    s = PEMB.from_faces(np.asarray(m.faces), m.num_vertices)
    a, b, bs = _bits_of(s)
    assert PEMB.from_bits(a, b, bs).num_faces == 20  # the unchanged bits are taken
    args = dict(A=a, B=b, B_star=bs)
    for key, value in change.items():
        if value == "half":
            value = (np.arange(s.num_vertices) + 0.5) if key == "order" else np.where(a == 0, 0.5, 1.0)
        elif value == "minus":
            value = b.astype(np.int64) * 1
            value[1] = -1
        elif value == "2d":
            value = a.reshape(2, -1)
        elif value == "repeat":
            value = np.zeros(s.num_vertices, np.int64)
        args[key] = value
    with pytest.raises(errors.EncodingError, match=message):
        PEMB.from_bits(args.pop("A"), args.pop("B"), args.pop("B_star"), **args)

# ------------------------------------------------------- the original implementation's bits
PEMB_ORIGINAL = pathlib.Path(__file__).resolve().parents[1] / "data" / "pemb_original"


def _read_original_graph(path):
    """A graph file of the original implementation -> ``(opp, ccw, vert, n)``: a dart per line in
    file order, each vertex's lines its ccw rotation, twins paired by their endpoints."""
    lines = path.read_text().split()
    n, m = int(lines[0]), int(lines[1])
    ends = np.array(lines[2:], np.int64).reshape(2 * m, 2)
    vert = ends[:, 0]
    first = np.searchsorted(vert, np.arange(n))
    last = np.searchsorted(vert, np.arange(n), side="right")
    e = np.arange(2 * m)
    ccw = np.where(e + 1 < last[vert], e + 1, first[vert])
    index = {(int(a), int(b)): i for i, (a, b) in enumerate(ends)}
    opp = np.array([index[(int(b), int(a))] for a, b in ends], np.int64)
    return opp, ccw, vert, n


@pytest.mark.parametrize("name", sorted(p.stem for p in PEMB_ORIGINAL.glob("*.graph")))
def test_stack_tree_gives_the_original_implementations_bits(name):
    """tests/data/pemb_original/README.md: with the original's tree (``tree="stack"``) the walk
    writes its ``A`` and its ``B``, ``B*`` inside their outer pairs, bit for bit; the BFS tree
    (the default) gives other bits of the same length."""
    from jaxcds.structures.pemb import _bfs_tree, _stack_tree, encode_rotation_system

    opp, ccw, vert, n = _read_original_graph(PEMB_ORIGINAL / f"{name}.graph")
    want = dict(line.split() for line in (PEMB_ORIGINAL / f"{name}.orig_bits").read_text().splitlines())
    bits = lambda a: "".join(map(str, np.asarray(a, np.uint8).tolist()))  # noqa: E731
    enc = encode_rotation_system(opp, ccw, vert, n, 0, _stack_tree(opp, ccw, vert, 0, n))
    assert bits(enc["A"]) == want["A"]
    assert "1" + bits(enc["B"]) + "0" == want["B"]
    assert "1" + bits(enc["B_star"]) + "0" == want["Bs"]
    other = encode_rotation_system(opp, ccw, vert, n, 0, _bfs_tree(opp, ccw, vert, 0, n))
    assert len(bits(other["A"])) == len(want["A"])
    if n > 5:  # K4 and small wheels: both trees are the star around the root
        assert bits(other["A"]) != want["A"]


def test_from_faces_takes_the_stack_tree():
    """``tree="stack"`` through the builder: the same 4m bits in other places (its operators are
    checked against the walk oracles in test_queries_against_walk_oracles), and an unknown tree
    named."""
    from jaxcds.generators import random_planar_triangulation

    mesh = random_planar_triangulation(300, seed=4)
    s = PEMB.from_faces(mesh.faces, mesh.num_vertices, tree="stack")
    b = PEMB.from_faces(mesh.faces, mesh.num_vertices, tree="bfs")
    assert s.bits_payload == b.bits_payload == 4 * s.num_edges
    assert not np.array_equal(s.A.to_numpy(), b.A.to_numpy())
    with pytest.raises(errors.ArgumentError, match="unknown spanning tree 'bfss'"):
        PEMB.from_faces(mesh.faces, mesh.num_vertices, tree="bfss")


# (sweep 14b) PEMB.from_faces and from_mesh(check=False) skip validation: a face id out of range
# and a mesh without faces crashed the builders (segfault, SIGBUS), and a non-manifold edge read
# border_prev slots that were never written (a raw IndexError at a garbage index). Probed in a
# child.
_PEMB_TRUSTED_CHILD = r"""
import numpy as np
from jaxcds.mesh import TriMesh
from jaxcds.structures.pemb import PEMB

cases = {"id_big": ([[0, 1, 2], [0, 2, 7]], 4), "id_negative": ([[0, 1, 2], [0, 2, -1]], 4),
         "no_faces": (np.zeros((0, 3), np.int32), 4), "nm_edge": ([[0, 1, 2], [1, 0, 3], [0, 1, 4]], 5)}
for name, (f, nv) in cases.items():
    for route, build in (("faces", lambda f, nv: PEMB.from_faces(f, nv)),
                         ("mesh", lambda f, nv: PEMB.from_mesh(TriMesh(np.zeros((nv, 3)), f), check=False))):
        record(route + ":" + name, build, np.asarray(f, np.int32), nv)
"""


def test_pemb_unchecked_routes_cannot_crash():
    from conftest import crash_probe

    out = crash_probe(_PEMB_TRUSTED_CHILD)
    for route in ("faces", "mesh"):
        assert out[f"{route}:id_big"][0] == "InvalidIndexError", out
        assert out[f"{route}:id_big"][1].startswith("PEMB.from_faces: face 1 refers to vertex 7"), out
        assert out[f"{route}:id_negative"][0] == "InvalidIndexError", out
        assert out[f"{route}:no_faces"][0] == "EmptyMeshError", out
        assert out[f"{route}:nm_edge"][0] == "NonManifoldEdgeError", out
        assert "edge (0, 1)" in out[f"{route}:nm_edge"][1]


@pytest.mark.parametrize("method", ["mate", "vertex", "first", "last", "next_p", "prev_p", "degree",
                                    "get_face", "first_dual"])
def test_pemb_own_queries_refuse_ids_that_are_not_integers(method):
    """Sweep 49d: pemb's own queries (the slides' vocabulary) cast their ids with
    ``jnp.asarray(i, int32)``: 1.7 read as 1, True as 1 (silently wrong), or a refusal named after
    an inner bit-vector method. Now refused by name, with and without the navigation tables."""
    from jaxcds.generators import random_planar_triangulation

    s = PEMB.from_mesh(random_planar_triangulation(12, seed=1))
    for t in (s, s.with_tables()):
        for bad in (1.7, True, "1", [0.5]):
            with pytest.raises(errors.InvalidIndexError, match=rf"{method}: \w+"):
                getattr(t, method)(bad)
    if method in ("mate", "first"):  # lists and other integer kinds read as int32 ids
        f = getattr(s, method)
        np.testing.assert_array_equal(np.asarray(f([1, 2])), np.asarray(f(np.array([1, 2], ">i8"))))


def test_encode_rotation_system_checks_its_arrays():
    """Sweep 50c: ``encode_rotation_system`` handed ``opp``, ``ccw``, ``vert`` and ``start`` to
    its walk kernel unchecked (a dart or vertex out of range: a segmentation fault);
    ``PEMB.from_faces`` keeps the unchecked route. Run in a child interpreter, so the old crash
    fails this test instead of ending the run."""
    from conftest import crash_probe_lines

    code = ("import numpy as np\nfrom jaxcds import errors\n"
            "from jaxcds.structures.pemb import encode_rotation_system, rotation_system_from_faces\n"
            "from jaxcds.generators import icosphere\n"
            "m = icosphere(1)\nopp, ccw, vert, _ = rotation_system_from_faces(m.faces, 42)\n"
            "assert encode_rotation_system(opp, ccw, vert, 42)['order'].size == 42\n"
            "o = opp.copy()\no[3] = 10 ** 7\nv = vert.copy()\nv[3] = 10 ** 7\n"
            "c = ccw.copy()\nc[[0, 1]] = c[[1, 0]]\n"
            "for call in (lambda: encode_rotation_system(o, ccw, vert, 42),\n"
            "             lambda: encode_rotation_system(opp, ccw, v, 42),\n"
            "             lambda: encode_rotation_system(opp, ccw, vert, 42, start=10 ** 7),\n"
            "             lambda: encode_rotation_system(opp, c, vert, 42)):\n"
            "    try:\n        call()\n        print('accepted')\n"
            "    except errors.JaxcdsError as exc:\n        print(type(exc).__name__, exc)\n")
    lines = crash_probe_lines(code)
    assert lines == [
        "ArgumentError encode_rotation_system: opp[3] = 10000000 is outside [0, 240)",
        "ArgumentError encode_rotation_system: vert[3] = 10000000 is outside [0, 42)",
        "ArgumentError encode_rotation_system: start must be a dart id in [0, 240), got 10000000",
        "ArgumentError encode_rotation_system: ccw is not a permutation of the darts around their "
        "origins (at dart 0)"], lines


def test_pemb_build_scans_each_sequence_once(monkeypatch):
    """Sweep 51b: ``PEMB.from_bits`` checked A, B and B* for values other than 0/1
    (``bits_array``, O(bits)), then ``BalancedParens.from_bits`` checked ``B B*`` again and
    ``BitVector.from_bits`` A and ``B B*`` a third time; the layers below now take the checked
    arrays (``_from_valid_bits``), the public builders still check."""
    from jaxcds.structures.succinct import bitvector as bv_mod
    from jaxcds.structures.succinct import bp as bp_mod
    import jaxcds.structures.pemb as pemb_mod

    calls = []
    for mod in (bv_mod, bp_mod, pemb_mod):
        real = mod.bits_array
        monkeypatch.setattr(mod, "bits_array", lambda x, what, real=real: calls.append(what) or real(x, what))
    s = PEMB.from_faces(np.array([[0, 1, 2], [0, 2, 3]], np.int32), 4)
    assert calls == ["pemb: the bits of A", "pemb: the bits of B", "pemb: the bits of B*"], calls
    assert s.num_faces == 2 and s.A.size == 10 and s.P.size == 10
    with pytest.raises(errors.EncodingError, match="BalancedParens.from_bits: bits hold 2"):
        from jaxcds.structures.succinct import BalancedParens
        BalancedParens.from_bits([1, 2])


@pytest.mark.parametrize("call,msg", [
    (lambda enc, o, c, v: enc(o, c, v, 0), r"num_vertices must be an integer in \[1, 2\^31\), got 0"),
    (lambda enc, o, c, v: enc([[1], [1, 2]], c, v, 12), "opp is not an array"),
    (lambda enc, o, c, v: enc(o.astype(float), c, v, 12),
     r"opp must be a non-empty 1-D integer array \(one entry per dart\), got dtype float64 shape \(60,\)"),
    (lambda enc, o, c, v: enc(o, c[:-1], v, 12), "opp, ccw and vert must have one length, got 60, 59, 60"),
    (lambda enc, o, c, v: enc(np.where(np.arange(60) == 0, 0, o), c, v, 12),
     r"opp\[0\] = 0: opp must be an involution without fixed points"),
    (lambda enc, o, c, v: enc(o, c, v, 12, start=1.5), r"start must be a dart id in \[0, 60\), got 1.5"),
    (lambda enc, o, c, v: enc(o, c, v, 12, tree=np.zeros(3, bool)),
     r"tree must be 60 booleans \(a dart mask\), got dtype bool shape \(3,\)"),
])
def test_encode_rotation_system_names_arguments_of_the_wrong_kind(call, msg):
    """Checks no test ran (the child-process test above covers the entries out of range)."""
    from jaxcds.generators import icosphere
    from jaxcds.structures.pemb import encode_rotation_system, rotation_system_from_faces

    opp, ccw, vert, _ = rotation_system_from_faces(icosphere(0).faces, 12)
    with pytest.raises(errors.ArgumentError, match="encode_rotation_system: " + msg):
        call(encode_rotation_system, opp, ccw, vert)


def test_encode_rotation_system_whose_walk_misses_a_vertex():
    """The icosahedron's rotation system said to have 13 vertices: the walk cannot reach all."""
    from jaxcds.generators import icosphere
    from jaxcds.structures.pemb import encode_rotation_system, rotation_system_from_faces

    opp, ccw, vert, _ = rotation_system_from_faces(icosphere(0).faces, 12)
    with pytest.raises(errors.UnsupportedTopologyError, match=r"pemb: the ccw walk around the spanning tree breaks at position \d+"):
        encode_rotation_system(opp, ccw, vert, 13)


@pytest.mark.parametrize("bits,msg", [
    (("1102", "10", "10"), r"bit string A has '2' at offset 3: a bit string holds the characters 0 and 1 only$"),
    # parentheses written as such: the strings are the slides' 0/1 ones
    (("1100", "()", "10"), r"bit string B has '\(' at offset 0: .*0 and 1 only \(the slides' convention: "
                           r"0 is '\(' and 1 is '\)'\)"),
])
def test_from_bits_names_a_character_that_is_no_bit(bits, msg):
    """The message named the character and offset but not what a string holds, and ``"()"``
    is what a user writes for parentheses."""
    with pytest.raises(errors.EncodingError, match="pemb: " + msg):
        PEMB.from_bits(*bits)


@pytest.mark.parametrize("tree", [np.array(["bfs", "dfs"]), "xyz", 3])
def test_from_faces_names_an_unknown_spanning_tree(tree):
    """An array as ``tree`` raised numpy's untyped 'truth value of an array is ambiguous'
    ValueError, after the rotation system was built."""
    from jaxcds.generators import icosphere

    with pytest.raises(errors.ArgumentError, match=r"pemb: unknown spanning tree .* \(bfs, dfs or stack\)"):
        PEMB.from_faces(icosphere(0).faces, 12, tree=tree)


def test_from_bits_names_counts_of_a_and_the_parentheses_that_disagree():
    with pytest.raises(errors.EncodingError, match=r"pemb: A has 4 bits with 2 ones and 2 zeros, but B has 2 and B\* 1 "
                                                   r"parentheses \(they must match the ones and zeros\)"):
        PEMB.from_bits("1100", "10", "1")
