"""The CDS family against the paper's claims (Castelli Aleardi & Devillers, JoCG 2018, Sec. 2):
exact reference counts (Thm 2/4/5/6, +1 with the face map of Thm 7), the cwBFS numbering of
Thm 5, the 2n face slots with four unused ones (Thm 7), the 6n corner numbering (Thm 8), O(1)
Target and Adjacent for Thm 6 (no loop in the traced program), the whole-mesh routes (every
target, face_vertices, degrees) against the wood and the half-edge, jit == no-jit, no retracing,
holed meshes through ``close_boundaries``, typed refusals, and gradients of the normals.

Cost: every structure is built once per module on one 300-vertex random triangulation, and each
test checks many claims on it (few shapes, few compilations). Every operator on every dart
against the half-edge runs in ``test_protocol.py`` (all registered structures); the large holed
meshes here are ``slow``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxcds import errors
from jaxcds.algorithms import adjacent, vertex_degrees, vertex_normals
from jaxcds.algorithms.normals import face_list_vertex_normals
from jaxcds.construct.schnyder import RED, check_schnyder_wood, schnyder_wood
from jaxcds.generators import icosphere, random_planar_triangulation
from jaxcds.mesh import close_boundaries
from jaxcds.structures import cds, registry
from jaxcds.structures.halfedge import HalfEdge
from jaxcds.verify import verify

from conftest import CDS_FAMILY as CDS, load_shared, octahedron

K = {"cds6n": 6, "cds5n": 5, "cds4n": 4, "cds5n-o1": 5}
PERMUTED = {"cds4n", "cds5n-o1"}
CLASSES = {c.name: c for c in (cds.CDS6n, cds.CDS5n, cds.CDS4n, cds.CDS5nO1)}


@pytest.fixture(scope="module")
def rnd():
    return random_planar_triangulation(300, seed=3)


@pytest.fixture(scope="module")
def built(rnd):
    """Every CDS on ``rnd`` and the maximal wood it comes from (input numbering)."""
    wood = schnyder_wood(rnd.faces, rnd.num_vertices)
    return wood, {name: registry.build(name, rnd) for name in CDS}


def _order(s, n):
    return np.arange(n) if s.vertex_order is None else np.asarray(s.vertex_order)


def _has_loop(fn, *args):
    """A ``while`` anywhere in the traced program, except inside ``base.materialize_loop`` or
    ``base.computed_in_loop`` (nested jits of those names whose loop runs once: a
    materialisation point, not navigation)."""
    def walk(jaxpr):
        for eqn in jaxpr.eqns:
            if eqn.primitive.name == "while":
                return True
            if eqn.params.get("name") in ("materialize_loop", "computed_in_loop"):
                continue
            for v in eqn.params.values():
                for sub in (v if isinstance(v, (tuple, list)) else (v,)):
                    inner = getattr(sub, "jaxpr", sub)
                    if hasattr(inner, "eqns") and walk(inner):
                        return True
        return False
    return walk(jax.make_jaxpr(fn)(*args).jaxpr)


def test_has_loop_sees_loops_but_not_the_materialisation_point():
    from jaxcds.structures.base import materialize_loop
    x = jnp.arange(5, dtype=jnp.int32)
    assert _has_loop(lambda a: jax.lax.while_loop(lambda v: v[0] < 3, lambda v: v + 1, a), x)
    assert _has_loop(lambda a: jax.jit(lambda b: jax.lax.fori_loop(0, b[0], lambda i, c: c + i, b))(a), x)
    assert not _has_loop(lambda a: materialize_loop((a + 1,))[0] * 2, x)
    np.testing.assert_array_equal(np.asarray(materialize_loop((x + 1, x * 2))[1]), np.arange(5) * 2)


def test_computed_in_loop_computes_in_the_body():
    from jaxcds.structures.base import computed_in_loop
    x = jnp.arange(7, dtype=jnp.int32)
    fn = lambda a, b: (a * 3 + b, jnp.where(a > 2, b, -a))  # noqa: E731
    # the first element negative too (a CDS reference with bit 31 set): still one trip
    for first in (x, x - 3, x.at[0].set(jnp.iinfo(jnp.int32).min), x.at[0].set(-1)):
        got = computed_in_loop(fn, first, x[::-1])
        for g, w in zip(got, fn(first, x[::-1])):
            np.testing.assert_array_equal(np.asarray(g), np.asarray(w))
    small = jnp.asarray([65535, 1, 2], jnp.uint16)  # another integer dtype sets the trip count
    np.testing.assert_array_equal(np.asarray(computed_in_loop(lambda a: (a + 1,), small)[0]),
                                  np.asarray(small + 1))
    assert not _has_loop(lambda a: computed_in_loop(fn, a, a)[0], x)
    # the multiply is traced in the loop body (the point of the helper; XLA cannot hoist it, its
    # inputs depend on the loop counter)
    loop = jax.make_jaxpr(lambda a: computed_in_loop(fn, a, a)[0])(x).jaxpr
    (outer,) = [e for e in loop.eqns if e.params.get("name") == "computed_in_loop"]
    (w,) = [e for e in outer.params["jaxpr"].eqns if e.primitive.name == "while"]
    assert any(e.primitive.name == "mul" for e in w.params["body_jaxpr"].eqns)


# ---------------------------------------------------------------- one structure, many claims
@pytest.mark.parametrize("name", CDS)
def test_paper_claims(name, rnd, built):
    wood, structures = built
    s = structures[name]
    n = rnd.num_vertices
    order = _order(s, n)
    inv = np.empty(n, np.int64)
    inv[order] = np.arange(n)

    # memory (Thm 2/4/5/6, Thm 7): exactly k int32 per vertex + F_blue, no hidden arrays
    assert s.core_references == K[name] * n and s.navigation_references == K[name] * n
    assert s.references == (K[name] + 1) * n
    assert s.navigation_references_per_vertex == K[name]
    assert s.refs.dtype == jnp.int32 and s.F_blue.dtype == jnp.int32
    stored = sum(int(np.prod(x.shape)) for x in jax.tree_util.tree_leaves(s))
    assert stored == (K[name] + 1) * n + (n if name in PERMUTED else 0)  # + the permutation

    # every target at once (pointer jumping, or Thm 6 column by column) == the wood's out table
    t = np.asarray(s.all_edge_targets()).reshape(n, 3)
    out = wood.out[order]  # structure numbering of the rows, input numbering of the values
    has = out < n
    np.testing.assert_array_equal(order[t[has]], out[has])
    # ... and the batched Target on the same edges
    e = np.nonzero(has.reshape(-1))[0].astype(np.int32)
    np.testing.assert_array_equal(np.asarray(s.edge_target(jnp.asarray(e))), t.reshape(-1)[e])

    # whole-mesh routes (O(1) per face / edge) vs the half-edge: faces as sets, degrees
    he = HalfEdge.from_faces(rnd.faces, n)
    fv = np.asarray(s.face_vertices())
    assert fv.shape == (s.num_faces, 3) and fv.dtype == np.int32
    got = {tuple(np.roll(r, -np.argmin(r))) for r in order[fv]}
    want = {tuple(np.roll(r, -np.argmin(r))) for r in rnd.faces}
    assert got == want  # same triangles, same ccw orientation
    # row f of face_vertices is face f: the origin of Edge(f) is on row f
    f = jnp.arange(s.num_faces, dtype=jnp.int32)
    assert np.all(np.any(fv == np.asarray(s.origin(s.edge_of_face(f)))[:, None], axis=1))
    np.testing.assert_array_equal(np.asarray(vertex_degrees(s)),
                                  np.asarray(vertex_degrees(he))[order])

    # faces (Thm 7): 2n slots, exactly four unused, dense ids a bijection, Edge(f) on f
    d = s.all_darts()
    slots = np.asarray(s.face_slot(jnp.asarray(d)))
    faces = np.asarray(s.face(jnp.asarray(d)))
    assert slots.min() >= 0 and slots.max() < 2 * n
    assert np.unique(slots).size == 2 * n - 4
    unused = sorted(set(range(2 * n)) - set(slots.tolist()))
    # V_red's red slot and three black/blue slots (which ones depends on the F_blue matching)
    assert len(unused) == 4 and s.v_red in unused and sum(x >= n for x in unused) == 3
    assert list(s.unused_slots) == unused
    assert np.unique(np.stack([slots, faces], 1), axis=0).shape[0] == 2 * n - 4
    assert faces.max() == 2 * n - 5
    u = np.array([x for x in range(n) if x != s.v_red])
    np.testing.assert_array_equal(np.asarray(s.face_slot(jnp.asarray(2 * (3 * u + RED)))), u)
    np.testing.assert_array_equal(np.asarray(s.face(s.edge_of_face(f))), np.arange(s.num_faces))

    # corners (Thm 8): u + n (c + 3 r), a bijection onto the 6n - 12 darts, inverse O(1)
    k = np.asarray(s.corner_index(jnp.asarray(d)))
    assert k.min() >= 0 and k.max() < 6 * n and np.unique(k).size == d.size == 6 * n - 12
    np.testing.assert_array_equal(np.asarray(s.corner_dart(jnp.asarray(k))), d)
    np.testing.assert_array_equal(k, (d >> 1) // 3 + n * ((d >> 1) % 3 + 3 * (d & 1)))

    # cwBFS (Thm 5): V_red is label 0, parents non-decreasing, siblings consecutive
    if name in PERMUTED:
        assert sorted(order.tolist()) == list(range(n)) and s.v_red == 0
        parent = t[:, RED].copy()
        parent[0] = -1
        assert np.all(np.diff(parent[1:]) >= 0) and np.all(parent[1:] < np.arange(1, n))
        for x in np.unique(parent[1:]):
            kids = np.nonzero(parent == x)[0]
            assert kids.max() - kids.min() + 1 == kids.size

    # O(1) operators: no loop in the traced program (Target only for Thm 6)
    e64 = jnp.asarray(d[:64])
    for op in ("next", "prev", "twin", "left_front", "left_back", "right_front", "right_back",
               "face_left", "face_right", "corner_opposite", "corner_swing"):
        assert not _has_loop(lambda s, e: getattr(s, op)(e), s, e64), op
    assert not _has_loop(lambda s: s.face_vertices(), s) or name != "cds5n-o1"
    u8 = jnp.arange(8, dtype=jnp.int32)
    o1 = name == "cds5n-o1"
    assert _has_loop(lambda s, e: s.target(e), s, e64) != o1
    assert _has_loop(lambda s, u, v: s.adjacent(u, v), s, u8, u8[::-1]) != o1

    # Adjacent == the wood's edges (half true pairs)
    src, dst = np.nonzero(has)[0], t[has]
    rng = np.random.default_rng(0)
    a = np.concatenate([src[:100], rng.integers(0, n, 100)]).astype(np.int32)
    b = np.concatenate([dst[:100], rng.integers(0, n, 100)]).astype(np.int32)
    edges = set(zip(src.tolist(), dst.tolist()))
    want_adj = [(x, y) in edges or (y, x) in edges for x, y in zip(a.tolist(), b.tolist())]
    np.testing.assert_array_equal(np.asarray(adjacent(s, a, b)), want_adj)

    # jit == eager, no retrace on new ids or a rebuilt structure with the same static fields
    traces = []

    @jax.jit
    def ops(s, e):
        traces.append(1)
        return (s.next(e), s.prev(e), s.origin(e), s.target(e), s.face(e), s.twin(e))

    q = jnp.asarray(rng.choice(d, 200))
    for g, w in zip(ops(s, q), (s.next(q), s.prev(q), s.origin(q), s.target(q), s.face(q), s.twin(q))):
        np.testing.assert_array_equal(np.asarray(g), np.asarray(w))
    ops(s, jnp.asarray(rng.choice(d, 200)))
    s2 = CLASSES[name].from_wood(wood)  # the builder straight from the wood == registry.build
    for x, y in zip(jax.tree_util.tree_leaves(s), jax.tree_util.tree_leaves(s2)):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    ops(s2, q)
    assert len(traces) == 1


# ---------------------------------------------------------------- fused builder == numpy route
@pytest.mark.parametrize("mesh", ["rnd", "octahedron", "icosphere", "random-5", "grid.off"])
def test_fused_builder_equals_numpy_route(mesh, rnd):
    """``from_wood`` (one numba pass, cwBFS labels applied on the fly) writes exactly the tables of
    the vectorised numpy route (explicitly relabelled wood, fronts from the rotation system,
    Thm 7 matching by sorted free slots), on several roots."""
    if mesh == "rnd":
        f, n = rnd.faces, rnd.num_vertices
    elif mesh == "octahedron":
        _, f = octahedron()
        n = 6
    elif mesh == "icosphere":
        m = icosphere(1)
        f, n = m.faces, m.num_vertices
    elif mesh == "random-5":
        m = random_planar_triangulation(5, seed=4)
        f, n = m.faces, m.num_vertices
    else:
        m = close_boundaries(load_shared(mesh))
        f, n = m.faces, m.num_vertices
    for root in sorted({0, 1, len(f) // 2, len(f) - 1}):
        wood = schnyder_wood(f, n, root_face=root)
        for name in CDS:
            s = CLASSES[name].from_wood(wood)
            refs, fblue, order, static = cds.tables_reference(name, wood)
            np.testing.assert_array_equal(np.asarray(s.refs), refs, err_msg=f"{name} root {root}")
            np.testing.assert_array_equal(np.asarray(s.F_blue), fblue, err_msg=f"{name} root {root}")
            assert s.refs.dtype == jnp.int32 and s.F_blue.dtype == jnp.int32
            if order is None:
                assert s.vertex_order is None
            else:
                np.testing.assert_array_equal(s.vertex_order, order)
            assert {k: getattr(s, k) for k in static} == static, (name, root)


@pytest.mark.slow
def test_fused_builder_equals_numpy_route_200k():
    """As above on a 200K-vertex random triangulation (high-degree vertices, deep red tree)."""
    m = random_planar_triangulation(200_000, seed=9)
    wood = schnyder_wood(m.faces, m.num_vertices)
    for name in CDS:
        s = CLASSES[name].from_wood(wood)
        refs, fblue, order, static = cds.tables_reference(name, wood)
        np.testing.assert_array_equal(np.asarray(s.refs), refs, err_msg=name)
        np.testing.assert_array_equal(np.asarray(s.F_blue), fblue, err_msg=name)
        if order is not None:
            np.testing.assert_array_equal(s.vertex_order, order)
        assert {k: getattr(s, k) for k in static} == static, name


# ---------------------------------------------------------------- hand-checked fixtures
def test_octahedron_by_hand():
    """The octahedron wood worked by hand in tests/construct/test_schnyder.py (root face
    (0, 2, 4): V_red = 0, V_black = 2, V_blue = 4): every structure's targets are that table,
    every vertex has degree 4 and the 8 faces come back ccw."""
    v, f = octahedron()
    want = np.array([[6, 6, 6], [5, 4, 2], [0, 4, 6], [0, 4, 1], [0, 6, 6], [0, 3, 2]])
    faces = {tuple(np.roll(r, -np.argmin(r))) for r in f}
    for name in CDS:
        s = CLASSES[name].from_wood(schnyder_wood(f, 6, root_face=0))
        order = _order(s, 6)
        t = np.asarray(s.all_edge_targets()).reshape(6, 3)
        got = np.where(want[order] < 6, order[t], 6)
        np.testing.assert_array_equal(got, want[order], err_msg=name)
        np.testing.assert_array_equal(np.asarray(vertex_degrees(s)), 4)
        assert {tuple(np.roll(r, -np.argmin(r))) for r in order[np.asarray(s.face_vertices())]} == faces


# Sec. 3.1 prints the words of Fig. 9, "the same triangulation of the example in Figure 3, where
# vertices are re-ordered according to the ccw-depth-first traversal of T_red", decorated with the
# vertex indices (the undecorated red word there has a typo, 22 symbols). n = 10, 4n - 3 = 37 bits.
PAPER_RED = "(0 (1)1 (2)2 (3)3 (4)4 (5 (6 (7)7 (8)8)6)5 (9)9)0"
PAPER_BLACK = "00000011010101110"
# The wood, read off the words by hand (rows: out red, blue, black; 10 = absent): red parents from
# the parentheses (1..5 and 9 under V_red = 0, 6 under 5, 7 and 8 under 6), black in-degrees
# 0,0,0,0,0,0,2,1,1,3 from the unary blocks (6 <- 3, 4; 7 <- 2; 8 <- 7; 9 <- 5, 6, 8), blue
# edges by the local rule; V_red = 0, V_blue = 1, V_black = 9 (Sec. 3.2).
PAPER_WOOD = [[10, 10, 10], [0, 10, 10], [0, 1, 7], [0, 2, 6], [0, 3, 6], [0, 4, 9], [5, 2, 9],
              [6, 1, 8], [6, 1, 9], [0, 1, 10]]


def test_paper_example_fig3_fig5_fig9():
    """The paper's 10-vertex example, from the words of Sec. 3.1 (the only form in which the text
    pins the triangulation down; Fig. 1/3/5 are images). Our maximal wood *is* the paper's wood,
    our cwBFS labels give Fig. 5's ccw triangle (2, 3, 7) and no cw triangle, and every table our
    builder writes equals the one the paper's decoder (Fig. 10-13, jaxcds.codec) fills."""
    from jaxcds.codec import decode
    from jaxcds.codec.decode import decode_faces
    from jaxcds.codec.words import from_strings

    words = from_strings("".join(c for c in PAPER_RED if c in "()"), PAPER_BLACK)
    n = words.num_vertices
    assert n == 10 and words.num_bits == 37
    faces, table = decode_faces(words)
    assert faces.shape == (16, 3)
    want = np.array(PAPER_WOOD)
    np.testing.assert_array_equal(table.T.T, want)  # the decoder reads the words as we did
    # our construction (Appendix A) on the decoded triangle soup, rooted at (V_red, V_black, V_blue)
    f = faces.copy()
    root = next(i for i, r in enumerate(f.tolist()) if sorted(r) == [0, 1, 9])
    f[root] = (0, 9, 1)  # the same triangle, read from V_red
    assert tuple(np.roll(faces[root], -int(np.argmin(faces[root])))) == (0, 9, 1)  # orientation kept
    wood = schnyder_wood(f, n, root_face=root)
    assert (wood.v_red, wood.v_blue, wood.v_black) == (0, 1, 9)
    np.testing.assert_array_equal(wood.out, want)
    assert check_schnyder_wood(wood, f) == []  # Definition 1 and no cw facial triangle

    def oriented(out, labels):  # facial triangles oriented (ccw list, cw list), in ``labels``
        fwd = lambda a, b: b in out[a]  # noqa: E731
        ccw = [r for r in f.tolist() if fwd(r[0], r[1]) and fwd(r[1], r[2]) and fwd(r[2], r[0])]
        cw = [r for r in f.tolist() if fwd(r[1], r[0]) and fwd(r[2], r[1]) and fwd(r[0], r[2])]
        canon = lambda r: tuple(np.roll(labels[r], -int(np.argmin(labels[r]))))  # noqa: E731
        return {canon(np.array(r)) for r in ccw}, {canon(np.array(r)) for r in cw}

    ccw, cw = oriented(want.tolist(), np.arange(n))
    assert cw == set() and ccw == {(2, 7, 6), (4, 6, 5)}
    # Fig. 5 (Sec. 2.2): "the Schnyder wood is maximal because there is no cw oriented triangle
    # (but there is a ccw oriented triangle (2,3,7))", vertices labelled by cwBFS (Sec. 2.3)
    s4 = CLASSES["cds4n"].from_wood(wood)
    label = np.empty(n, np.int64)
    label[s4.vertex_order] = np.arange(n)
    ccw5, cw5 = oriented(want.tolist(), label)
    assert cw5 == set() and (2, 3, 7) in ccw5

    # hand-checked CDS6n entries (Sec. 2.1 definitions on the faces above):
    s6 = CLASSES["cds6n"].from_wood(wood)
    refs = np.asarray(s6.refs).view(np.uint32)
    # 7_red = (7, 6), left face (7, 6, 2): LeftFront {6, 2} = 6_blue, colour next(red): S = 6,
    # C = false; no red edge enters 7: I_red[7] = false
    assert refs[7, 0] == 6
    # right face (6, 7, 8): RightFront {6, 8} = 8_red, same colour: S = 8, C = true
    assert refs[7, 1] == 8 | 1 << 30
    # 8_red = (8, 6), left face (8, 6, 7): LeftFront = 7_red, its red sibling cw around 6 (the
    # pattern of Fig. 3's caption for its vertices 8, 9, 5): S = 7, C = true, I_red[8] = false
    assert refs[8, 0] == 7 | 1 << 30
    # 6 has red children 7, 8: I_red[6] true (bit 31 of column 0); 6_red = (6, 5)
    assert refs[6, 0] >> 31 == 1

    # every table our builder writes == the paper's decoder filling it from the words
    for name in ("cds6n", "cds5n", "cds4n"):
        ours, dec = CLASSES[name].from_wood(wood), decode(words, structure=name)
        for x, y in zip(jax.tree_util.tree_leaves(ours), jax.tree_util.tree_leaves(dec)):
            np.testing.assert_array_equal(np.asarray(x), np.asarray(y), err_msg=name)
        assert (ours.v_red, ours.v_blue, ours.v_black, ours.unused_slots) == \
            (dec.v_red, dec.v_blue, dec.v_black, dec.unused_slots), name


def test_cube_by_hand():
    """cube.off (8 vertices, 12 faces, 18 edges): 6/5/4/5 references per vertex (+1), the
    half-edge's degrees, the 12 faces ccw (verify() on the cube: test_protocol.py)."""
    m = load_shared("cube.off")
    he = HalfEdge.from_faces(m.faces, 8)
    for name in CDS:
        s = registry.build(name, m)
        assert s.navigation_references == 8 * K[name] and s.references == 8 * (K[name] + 1)
        order = _order(s, 8)
        np.testing.assert_array_equal(np.asarray(vertex_degrees(s)), np.asarray(vertex_degrees(he))[order])
        assert np.asarray(vertex_degrees(s)).sum() == 2 * 18
        got = {tuple(np.roll(r, -np.argmin(r))) for r in order[np.asarray(s.face_vertices())]}
        assert got == {tuple(np.roll(r, -np.argmin(r))) for r in m.faces}


def test_face_slot_assignment_by_hand():
    """Thm 7's slots (``cds.assign_face_slots``, shared by the builders and the codec): a blue
    triangle whose own black slot is taken moves to the first free one and the two name each
    other; the three left-over black slots and V_red's red slot are the unused four; too few free
    slots is the typed error of the caller, with its hint."""
    t, f = True, False
    black = np.array([f, t, t, f, f, f, f])
    blue = np.array([f, t, f, t, f, f, f])
    fb, unused = cds.assign_face_slots(black, blue, 0)
    np.testing.assert_array_equal(fb, [1, 0, 0, 3, 0, 0, 0])  # 1 -> slot of 0, 3 keeps its own
    assert unused == (0, 11, 12, 13)
    with pytest.raises(errors.EncodingError, match=r"1 blue triangles but 3 free slots \(words\)"):
        cds.assign_face_slots(np.array([t, t, t, t, f, f, f]), np.array([f, t, f, f, f, f, f]), 0,
                              errors.EncodingError, " (words)")


# ---------------------------------------------------------------- holed meshes, refusals
# default set: test_protocol.py already verifies every CDS on grid.off and 2triangles.off
@pytest.mark.slow
@pytest.mark.parametrize("mesh", ["2triangles.off", "grid.off", "camelhead.off", "face.obj",
                                  "stanford-bunny.obj"])
def test_every_cds_on_closed_holed_meshes(mesh):
    m = load_shared(mesh)
    closed = close_boundaries(m)
    for name in CDS:
        s = registry.build(name, m)
        assert s.boundaries_closed and s.num_vertices == closed.num_vertices
        rep = verify(s, closed)
        assert rep.checked > 10 * closed.num_faces and rep.mismatches == 0, (name, str(rep))


def test_refusals_are_typed_and_named():
    for name in CDS:
        for mesh, genus in (("rocker-arm.obj", 1), ("3holes.off", 3)):
            with pytest.raises(errors.UnsupportedTopologyError, match=f"genus {genus}") as exc:
                registry.build(name, load_shared(mesh))
            assert "'lr'" in str(exc.value) and "'halfedge'" in str(exc.value)
        with pytest.raises(errors.NonManifoldEdgeError):
            registry.build(name, load_shared("cow.off"))


# ---------------------------------------------------------------- gradients
def test_normal_gradients_equal_face_list(x64):
    m = icosphere(1)
    rng = np.random.default_rng(1)
    pos = jnp.asarray(m.vertices + 0.05 * rng.standard_normal(m.vertices.shape))
    w = jnp.asarray(rng.standard_normal(m.vertices.shape))
    faces = jnp.asarray(m.faces)

    def loss_fl(p):
        return jnp.sum(face_list_vertex_normals(p, faces) * w)

    want, gwant = float(loss_fl(pos)), np.asarray(jax.grad(loss_fl)(pos))
    for name in CDS:
        s = registry.build(name, m)
        order = _order(s, m.num_vertices)

        def loss_s(p):  # p in input numbering
            return jnp.sum(vertex_normals(s, p[order]) * w[order])

        np.testing.assert_allclose(float(loss_s(pos)), want, rtol=1e-12, err_msg=name)
        np.testing.assert_allclose(np.asarray(jax.grad(loss_s)(pos)), gwant, rtol=1e-9, atol=1e-12,
                                   err_msg=name)


# ---------------------------------------------------------------- progress bar
def test_progress_bar_only_when_asked_or_large_on_a_tty(rnd, capsys):
    cds.build_cds(cds.CDS6n, rnd)  # small mesh, stderr captured (not a terminal): silent
    assert capsys.readouterr().err == ""
    cds.build_cds(cds.CDS6n, rnd, progress=True)
    err = capsys.readouterr().err
    assert err.count("\r") == 4 and "3/3 done" in err and err.endswith("\n")
    assert cds.PROGRESS_MIN_VERTICES >= 100_000


def test_progress_must_be_a_bool_or_none(rnd, capsys):
    """``progress='no'`` was truthy: the bar was shown."""
    for bad in ("no", 0, [False]):
        with pytest.raises(errors.ArgumentError, match="build_cds: progress must be True, False or None"):
            cds.build_cds(cds.CDS6n, rnd, progress=bad)
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("cls_name,theorem", [("CDS5n", "4"), ("CDS4n", "5"), ("CDS5nO1", "6")])
def test_from_wood_of_a_non_maximal_wood_says_how_to_get_the_maximal_one(cls_name, theorem):
    from jaxcds.structures import cds

    w = schnyder_wood(icosphere(0).faces, 12, maximal=False)
    with pytest.raises(errors.StructureError, match=rf"needs the maximal Schnyder wood \(Thm {theorem}\); this one "
                                                    r"was built with maximal=False: schnyder_wood\(faces, n\)"):
        getattr(cds, cls_name).from_wood(w)


@pytest.mark.parametrize("order,msg", [
    (np.arange(11), r"got dtype int64 shape \(11,\)"),
    (np.arange(12) + 0.0, r"got dtype float64 shape \(12,\)"),
    (np.r_[0, 0, np.arange(2, 12)], "vertex 1 is missing from it"),
    (np.r_[np.arange(11), 12], "vertex 11 is missing from it"),
])
def test_relabel_wood_names_what_is_wrong_with_the_order(order, msg):
    """A permutation of the right shape but with a vertex twice was described by its dtype and
    shape only, which were right."""
    from jaxcds.structures.cds import relabel_wood

    w = schnyder_wood(icosphere(0).faces, 12)
    with pytest.raises(errors.StructureError, match=r"relabel_wood: order must be a permutation of the 12 vertices.*"
                                                    + msg):
        relabel_wood(w, order)
