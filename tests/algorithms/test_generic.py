"""Generic algorithms (degrees, normals, adjacency, one-ring) on the reference structures."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import trimesh

from jaxcds import errors
from jaxcds.algorithms import adjacent, face_list_vertex_normals, one_ring, vertex_degrees, vertex_normals
from jaxcds.algorithms.normals import normalize
from jaxcds.generators import icosphere
from jaxcds.mesh import close_boundaries, load_mesh
from jaxcds.structures import CornerTable, HalfEdge

from conftest import CDS_FAMILY, load_shared, octahedron

MESHES = ["bunny.off", "grid.off", "3holes.off", "spot.obj", "camelhead.off"]


def trimesh_area_weighted(m):
    tm = trimesh.Trimesh(m.vertices, m.faces, process=False)
    weighted = tm.face_normals * tm.area_faces[:, None]
    return trimesh.geometry.mean_vertex_normals(len(m.vertices), m.faces, weighted)


@pytest.mark.parametrize("name", MESHES)
def test_normals_match_trimesh(name):
    m = load_shared(name)
    he = HalfEdge.from_mesh(m)
    got = np.asarray(vertex_normals(he, m.vertices.astype(np.float32)))
    np.testing.assert_allclose(got, trimesh_area_weighted(m), atol=1e-4)


@pytest.mark.parametrize("name", MESHES)
def test_degrees_match_trimesh(name):
    m = load_shared(name)
    tm = trimesh.Trimesh(m.vertices, m.faces, process=False)
    want = np.bincount(tm.edges_unique.ravel(), minlength=m.num_vertices)
    np.testing.assert_array_equal(np.asarray(vertex_degrees(HalfEdge.from_mesh(m))), want)
    c = close_boundaries(m)
    deg_ct = np.asarray(vertex_degrees(CornerTable.from_mesh(c)))
    tmc = trimesh.Trimesh(c.vertices, c.faces, process=False)
    np.testing.assert_array_equal(deg_ct, np.bincount(tmc.edges_unique.ravel()))


def test_normal_gradient_matches_finite_differences(x64):
    m = load_shared("decimated-knight.off")
    he = HalfEdge.from_mesh(m)
    pos = jnp.asarray(m.vertices, jnp.float64)
    w = jnp.asarray(np.random.default_rng(0).normal(size=pos.shape))

    def loss(p):
        return jnp.sum(vertex_normals(he, p) * w)

    g = np.asarray(jax.grad(loss)(pos))
    rng = np.random.default_rng(1)
    h = 1e-6
    for _ in range(12):
        i, k = int(rng.integers(m.num_vertices)), int(rng.integers(3))
        dp = jnp.zeros_like(pos).at[i, k].set(h)
        fd = (loss(pos + dp) - loss(pos - dp)) / (2 * h)
        assert abs(float(fd) - g[i, k]) < 1e-6 * max(1.0, abs(g[i, k]))


def test_gradients_equal_face_list_version(x64):
    m = load_shared("bunny.off")
    ct = CornerTable.from_mesh(m)
    pos = jnp.asarray(m.vertices, jnp.float64)
    faces = jnp.asarray(m.faces)
    g1 = jax.grad(lambda p: jnp.sum(vertex_normals(ct, p, method="gather") ** 3))(pos)
    g2 = jax.grad(lambda p: jnp.sum(face_list_vertex_normals(p, faces) ** 3))(pos)
    np.testing.assert_allclose(g1, g2, atol=1e-9)


def test_normalize_is_finite_at_zero():
    x = jnp.zeros((2, 3))
    assert np.all(np.asarray(normalize(x)) == 0)
    g = jax.grad(lambda y: jnp.sum(normalize(y)))(x)
    assert np.all(np.isfinite(np.asarray(g)))


def test_degenerate_face_gives_finite_normals():
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]], float)  # a collinear face
    f = np.array([[0, 1, 2], [0, 1, 3]])
    n = np.asarray(face_list_vertex_normals(jnp.asarray(v, jnp.float32), jnp.asarray(f)))
    assert np.all(np.isfinite(n))


@pytest.mark.parametrize("name", ["bunny.off", "grid.off"])
def test_adjacent_and_one_ring(name):
    m = load_shared(name)
    he = HalfEdge.from_mesh(m)
    tm = trimesh.Trimesh(m.vertices, m.faces, process=False)
    edges = tm.edges_unique
    assert np.all(np.asarray(adjacent(he, edges[:, 0], edges[:, 1])))
    assert np.all(np.asarray(adjacent(he, edges[:, 1], edges[:, 0])))
    rng = np.random.default_rng(0)
    u, v = rng.integers(0, m.num_vertices, (2, 5000))
    known = set(map(tuple, edges.tolist())) | set(map(tuple, edges[:, ::-1].tolist()))
    want = np.array([(a, b) in known for a, b in zip(u.tolist(), v.tolist())])
    np.testing.assert_array_equal(np.asarray(adjacent(he, u, v)), want)
    deg = np.asarray(vertex_degrees(he))
    ring, d = one_ring(he, np.arange(m.num_vertices), int(deg.max()))
    np.testing.assert_array_equal(np.asarray(d), deg)
    ring = np.asarray(ring)
    nbrs = tm.vertex_neighbors
    for i in range(0, m.num_vertices, 37):
        assert sorted(ring[i, : deg[i]].tolist()) == sorted(nbrs[i])


def test_one_ring_width_is_checked():
    """``max_degree`` is a static width: a negative, fractional, string or boolean one is an
    ArgumentError naming it (a negative one failed inside XLA, 1.7 was cut to 1); 0 gives empty
    rings and the degrees 0."""
    he = HalfEdge.from_mesh(load_shared("cube.off"))
    for bad in (-1, 1.7, "3", True, None):
        with pytest.raises(errors.ArgumentError, match="max_degree"):
            one_ring(he, jnp.arange(3, dtype=jnp.int32), bad)
    ring, deg = one_ring(he, jnp.arange(3, dtype=jnp.int32), np.int64(0))
    assert ring.shape == (3, 0) and np.asarray(deg).tolist() == [0, 0, 0]


def test_algorithms_are_jitted_once():
    v, f = octahedron()
    he = HalfEdge.from_mesh(load_mesh(v, f))
    pos = jnp.asarray(v, jnp.float32)
    vertex_normals(he, pos)
    n_before = vertex_normals._cache_size()
    vertex_normals(he, pos + 1.0)
    assert vertex_normals._cache_size() == n_before


def test_positions_that_are_not_real_numbers_are_refused():
    """Strings, objects and complex numbers are a MeshError before the jitted call (jit raised
    TypeError on strings; complex positions lost their imaginary part); lists, integers and
    traced positions (under jit and grad) still work."""
    from jaxcds import errors

    v, f = octahedron()
    he = HalfEdge.from_mesh(load_mesh(v, f))
    want = np.asarray(vertex_normals(he, jnp.asarray(v, jnp.float32)))
    for bad in (v.astype(str), v.astype(object), v.astype(np.complex64) + 1j, [["a", "b", "c"]] * len(v)):
        with pytest.raises(errors.MeshError, match="real numbers|array of numbers"):
            vertex_normals(he, bad)
    np.testing.assert_allclose(np.asarray(vertex_normals(he, v.tolist())), want, atol=1e-6)
    np.testing.assert_allclose(np.asarray(vertex_normals(he, (v * 2).astype(np.int32))), want, atol=1e-6)
    traced = jax.jit(lambda p: vertex_normals(he, p))(jnp.asarray(v, jnp.float32))
    np.testing.assert_allclose(np.asarray(traced), want, atol=1e-6)
    g = jax.grad(lambda p: vertex_normals(he, p)[:, 0].sum())(jnp.asarray(v, jnp.float32))
    assert g.shape == v.shape and np.isfinite(np.asarray(g)).all()


def test_positions_of_wrong_shape_are_refused():
    from jaxcds import errors

    v, f = octahedron()
    he = HalfEdge.from_mesh(load_mesh(v, f))
    with pytest.raises(errors.MeshError, match=r"positions must have shape \(6, 3\)"):
        vertex_normals(he, jnp.zeros((5, 3)))


@pytest.mark.parametrize("cls", [HalfEdge, CornerTable])
def test_a_vertex_in_no_face_from_trusted_faces(cls):
    """``from_faces`` (not validated; Polylla builds from a Triangle .node that may have an
    unused node) with vertex 4 in no face: ``edge_of_vertex`` is the protocol's "absent"
    (``num_darts``), it is adjacent to nothing, its ring is empty and its normal zero."""
    v = np.r_[np.eye(3), [[0, 0, 0], [5, 5, 5]]].astype(np.float32)
    f = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]], np.int32)
    s = cls.from_faces(f, 5)
    assert int(s.edge_of_vertex(jnp.int32(4))) == s.num_darts
    others = jnp.arange(4, dtype=jnp.int32)
    assert not np.asarray(adjacent(s, jnp.full(4, 4, jnp.int32), others)).any()
    assert not np.asarray(adjacent(s, others, jnp.full(4, 4, jnp.int32))).any()
    ring, deg = one_ring(s, jnp.arange(5, dtype=jnp.int32), 4)
    assert np.asarray(deg).tolist() == [3, 3, 3, 3, 0]
    assert (np.asarray(ring)[4] == 5).all()
    assert np.asarray(vertex_degrees(s)).tolist() == [3, 3, 3, 3, 0]
    for method in ("scatter", "gather"):
        n = np.asarray(vertex_normals(s, v, method=method))
        np.testing.assert_array_equal(n[4], 0.0)
        np.testing.assert_allclose(np.linalg.norm(n[:4], axis=1), 1.0, rtol=1e-5)


@pytest.mark.parametrize("scale", [1e10, 1e-10, 1e-11, 1e20, 1e30, 1e-25, 1e-30])
def test_normals_and_gradients_at_extreme_coordinate_scales(scale):
    """Squared in float32, the sums of face normals overflowed near 1e10 (every normal came out
    zero) and flushed to zero near 1e-10; the normals are scale invariant and now say so, with
    finite gradients (of size 1 / scale), on both routes. Past 1e17 (and under 1e-17) the face
    cross products themselves overflow (NaN normals at 1e20) or underflow (zero ones at 1e-25)
    in float32: ``within_range`` (documented for such positions) rescales them exactly."""
    from jaxcds.algorithms.normals import within_range

    v, f = octahedron()
    he = HalfEdge.from_mesh(load_mesh(v, f))
    unit = np.asarray(vertex_normals(he, jnp.asarray(v, jnp.float32)))
    p = jnp.asarray(np.asarray(v) * scale, jnp.float32)
    far = not 1e-17 < scale < 1e17
    prep = within_range if far else (lambda q: q)
    if far:  # a power of two: the largest coordinate in [2^49, 2^50)
        assert 2.0**49 <= float(jnp.abs(within_range(p)).max()) < 2.0**50
    np.testing.assert_allclose(np.asarray(vertex_normals(he, prep(p))), unit, atol=1e-6)
    np.testing.assert_allclose(np.asarray(vertex_normals(he, prep(p), method="gather")), unit, atol=1e-6)
    np.testing.assert_allclose(np.asarray(face_list_vertex_normals(prep(p), jnp.asarray(f))), unit, atol=1e-6)
    g = jax.grad(lambda q: jnp.sum(vertex_normals(he, prep(q))[:, 2]))(p)
    g1 = jax.grad(lambda q: jnp.sum(vertex_normals(he, q)[:, 2]))(jnp.asarray(v, jnp.float32))
    assert np.isfinite(np.asarray(g)).all()
    np.testing.assert_allclose(np.asarray(g) * scale, np.asarray(g1), rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize("far", [1e20, 1e30, 1e-25])
def test_within_range_keeps_small_features_of_mixed_scale_meshes(far):
    """Sweep 15a: within_range brought the largest coordinate into [0.5, 1), so the unit-size
    faces of a mesh with one vertex at 1e20 or 1e30 underflowed (36 of 42 normals zero, worse
    than the raw positions); a NaN coordinate made it skip the rescaling altogether. Now the
    largest finite coordinate goes just under 2^50: every normal is finite and nonzero, and
    those away from the far vertex equal float64's."""
    from jaxcds.algorithms.normals import within_range

    m = icosphere(1)
    v, f = np.asarray(m.vertices, np.float64) * (1e-25 if far < 1 else 1.0), np.asarray(m.faces)
    v[0] *= far if far > 1 else 1e3  # one vertex far out (or, at 1e-25, a mesh far too small)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    want = np.zeros_like(v)
    for k in range(3):
        np.add.at(want, f[:, k], fn / np.abs(fn).max())
    want /= np.linalg.norm(want, axis=1, keepdims=True)
    # vertex 0's one-ring: faces spanning both scales, which float32 cannot resolve (its unit
    # offsets vanish next to 1e20); the rest of the mesh must keep float64's normals
    away = np.setdiff1d(np.arange(len(v)), np.unique(f[(f == 0).any(axis=1)]))
    p = within_range(v.astype(np.float32))
    got = np.asarray(face_list_vertex_normals(p, f))
    assert np.isfinite(got).all() and (np.abs(got).sum(axis=1) > 0.5).all()
    np.testing.assert_allclose(got[away], want[away], atol=2e-5)
    he = HalfEdge.from_faces(f, len(v))
    np.testing.assert_allclose(np.asarray(vertex_normals(he, p))[away], want[away], atol=2e-5)
    g = jax.grad(lambda q: jnp.sum(vertex_normals(he, within_range(q))[:, 2]))(jnp.asarray(v, jnp.float32))
    assert np.isfinite(np.asarray(g)).all()
    nan = v.astype(np.float32)
    nan[5, 1] = np.nan  # NaN out at vertex 5's one-ring only; the rest still rescaled
    got = np.asarray(face_list_vertex_normals(within_range(nan), f))
    ring = np.unique(f[(f == 5).any(axis=1)])
    rest = np.setdiff1d(away, ring)
    assert np.isnan(got[ring]).all(axis=1).all()
    np.testing.assert_allclose(got[rest], want[rest], atol=2e-5)


def test_face_list_normals_and_within_range_read_host_arrays_by_value():
    """Sweep 13: the jitted face list read big-endian arrays, after a native call of the same
    shape, as native bytes (wrong normals); float faces were truncated. within_range raised
    numpy/jax errors on integer positions and lists, and judged float64 host positions by
    float64's range though JAX computes them in float32 (NaN normals at 1e20)."""
    from jaxcds.algorithms.normals import within_range

    v, f = octahedron()
    p, f = np.asarray(v, np.float32) + 0.25, np.asarray(f, np.int32)
    want = np.asarray(face_list_vertex_normals(p, f))
    np.testing.assert_array_equal(np.asarray(face_list_vertex_normals(p.astype(">f4"), f.astype(">i4"))), want)
    np.testing.assert_array_equal(np.asarray(face_list_vertex_normals(p.tolist(), f.tolist())), want)
    with pytest.raises(errors.InvalidIndexError, match="faces must be integers, got dtype float64"):
        face_list_vertex_normals(p, f.astype(np.float64))
    with pytest.raises(errors.MeshError, match="positions must be real numbers"):
        face_list_vertex_normals(p.astype(complex), f)
    big = p.astype(np.float64) * 1e20
    for q in (big, big.astype(">f8"), big.tolist()):
        np.testing.assert_allclose(np.asarray(face_list_vertex_normals(within_range(q), f)), want, atol=1e-6)
    assert within_range(np.arange(6, dtype=np.int32).reshape(2, 3)).dtype == jnp.float32
    with pytest.raises(errors.MeshError, match="within_range: positions must be real numbers"):
        within_range(np.array([["a", "b", "c"]]))
    # masked positions: the mask was dropped silently (the sharded normals refused them)
    masked = np.ma.masked_array(p, p > 0.5)
    with pytest.raises(errors.MeshError, match="face_list_vertex_normals: positions are a masked array"):
        face_list_vertex_normals(masked, f)
    with pytest.raises(errors.MeshError, match="within_range: positions are a masked array"):
        within_range(masked)
    s = HalfEdge.from_faces(f, num_vertices=len(v))
    with pytest.raises(errors.MeshError, match="positions are a masked array"):
        vertex_normals(s, np.ma.masked_array(np.asarray(v, np.float32), False))


@pytest.mark.parametrize("structure", CDS_FAMILY)
def test_cds_gather_normals_on_vertices_of_high_degree(structure):
    """The gather route asked Thm 2's O(d) Target inside its turn around every vertex: O(n d^2)
    (a bipyramid with poles of degree 800: 6 s; 2,000: no end). It now reads every dart's target
    from one pass (``target_table``); the table equals Target on every valid dart."""
    from jaxcds.structures import registry

    k = 300
    t = 2 * np.pi * np.arange(k) / k
    v = np.concatenate([np.c_[np.cos(t), np.sin(t), np.zeros(k)], [[0, 0, 1.0], [0, 0, -1.0]]])
    a = np.arange(k)
    f = np.concatenate([np.c_[a, (a + 1) % k, np.full(k, k)], np.c_[(a + 1) % k, a, np.full(k, k + 1)]])
    m = load_mesh(v, f)
    s = registry.build(structure, m)
    if s.target_table is not None:
        d = jnp.asarray(s.all_darts())
        np.testing.assert_array_equal(np.asarray(s.target_table())[np.asarray(d)], np.asarray(s.target(d)))
    p = jnp.asarray(v if s.vertex_order is None else v[np.asarray(s.vertex_order)], jnp.float32)
    np.testing.assert_allclose(np.asarray(vertex_normals(s, p, method="gather")),
                               np.asarray(vertex_normals(s, p)), atol=1e-5)


def _bipyramid(k):
    t = 2 * np.pi * np.arange(k) / k
    v = np.concatenate([np.c_[np.cos(t), np.sin(t), np.zeros(k)], [[0, 0, 1.0], [0, 0, -1.0]]])
    a = np.arange(k)
    f = np.concatenate([np.c_[a, (a + 1) % k, np.full(k, k)], np.c_[(a + 1) % k, a, np.full(k, k + 1)]])
    return v, f


@pytest.mark.parametrize("structure", ["halfedge", "lr",
                                       pytest.param("pemb", marks=pytest.mark.slow)])  # pemb: 22 s
def test_adjacent_around_a_hub_finishes_its_long_rotations_compacted(structure, monkeypatch):
    """A batch of adjacency queries turned in one loop as long as its longest rotation: queries x
    the largest degree (sweep 17b: 100K queries around a degree-1,000 hub, lr 9-12 s, pemb 79
    s). After 16 turns the queries still turning go on compacted, 1,024 at a time: the long
    rotations run on those chunks only (recorded here), and the answers are the edge set's."""
    from jaxcds.algorithms import adjacency
    from jaxcds.structures import registry
    from jaxcds.structures.succinct import bitvector

    seen = []
    compacted = bitvector.compacted

    def recording(slow, miss, fast, args, chunk=None):
        seen.append((miss.shape[0], chunk))
        return compacted(slow, miss, fast, args, chunk)

    monkeypatch.setattr(bitvector, "compacted", recording)
    v, f = _bipyramid(300)
    s = registry.build(structure, load_mesh(v, f))
    rng = np.random.default_rng(1)
    q = 20_000
    u, w = rng.integers(0, 302, q), rng.integers(0, 302, q)
    u[:50] = 300  # the poles asked about: rotations of 300 turns
    edges = {(int(a), int(b)) for x in f for a, b in ((x[0], x[1]), (x[1], x[2]), (x[2], x[0]))}
    want = np.array([(int(a), int(b)) in edges or (int(b), int(a)) in edges for a, b in zip(u, w)])
    if s.vertex_order is not None:
        inv = np.argsort(np.asarray(s.vertex_order))
        u, w = inv[u], inv[w]
    got = np.asarray(adjacency._adjacent.__wrapped__(s, jnp.asarray(u, jnp.int32), jnp.asarray(w, jnp.int32)))
    np.testing.assert_array_equal(got, want)
    assert (q, adjacency.ADJACENT_CHUNK) in seen  # (pemb compacts its searches too)


def test_cds_one_ring_of_a_hub_walks_only_the_darts_it_needs(monkeypatch):
    """one_ring of a hub on CDS6n was quadratic (a degree-4,000 hub: 6-7 s; sweep 17a): Target
    of a reversed dart (its edge's source, no walk) computed Thm 2's walk anyway (a select's two
    sides), and a finished lane kept turning up to max_degree, walking the fans it passed. Run
    eagerly, the walks' lanes are counted: only darts leaving their origin walk, once each."""
    from jaxcds.structures import cds, registry

    walked = []
    walk = cds._CDS._target_walk
    monkeypatch.setattr(cds._CDS, "_target_walk",
                        lambda self, e: walked.append(int(np.sum(np.asarray(e) >= 0))) or walk(self, e))
    v, f = _bipyramid(40)
    s = registry.build("cds6n", load_mesh(v, f))
    assert 41 not in (s.v_red, s.v_blue, s.v_black) and 5 not in (s.v_red, s.v_blue, s.v_black)
    with jax.disable_jit():  # (eager bucketing recursed under disable_jit before stop 45)
        ring, deg = one_ring(s, jnp.asarray([41, 5], jnp.int32), 60)
    assert np.asarray(deg).tolist() == [40, 4]
    assert set(np.asarray(ring)[0][:40].tolist()) == set(range(40))
    # 3 edges leave each inner vertex; before: both lanes walked at each of the 60 turns (120)
    assert sum(walked) <= 8, walked


@pytest.mark.parametrize("structure", ["cds6n", "cds4n"])
def test_cds_adjacent_of_a_large_batch_reads_every_target_once(structure, monkeypatch):
    """CDS6n/5n/4n's Adjacent asks 6 Targets (Thm 2: walks of O(d), in lockstep over a batch:
    queries x the largest fan; sweep 17b: 100K queries around a degree-1,000 hub, cds5n 4.8 s).
    A batch of at least n / 16 pairs reads them from every edge's Target computed once (pointer
    jumping, O(n log d)): no walk is traced; a small batch walks. Answers: the edge set's."""
    from jaxcds.structures import cds, registry

    walks = []
    walk = cds._CDS._target_walk
    monkeypatch.setattr(cds._CDS, "_target_walk", lambda self, e: walks.append(e.shape) or walk(self, e))
    v, f = _bipyramid(300)
    s = registry.build(structure, load_mesh(v, f))
    rng = np.random.default_rng(2)
    u, w = rng.integers(0, 302, 2000), rng.integers(0, 302, 2000)
    u[:40], w[40:80] = 300, 301
    edges = {(int(a), int(b)) for x in f for a, b in ((x[0], x[1]), (x[1], x[2]), (x[2], x[0]))}
    want = np.array([(int(a), int(b)) in edges or (int(b), int(a)) in edges for a, b in zip(u, w)])
    if s.vertex_order is not None:
        inv = np.argsort(np.asarray(s.vertex_order))
        u, w = inv[u], inv[w]
    u, w = jnp.asarray(u, jnp.int32), jnp.asarray(w, jnp.int32)
    np.testing.assert_array_equal(np.asarray(jax.jit(lambda s, a, b: s.adjacent(a, b))(s, u, w)), want)
    assert walks == []  # the table route
    np.testing.assert_array_equal(np.asarray(jax.jit(lambda s, a, b: s.adjacent(a, b))(s, u[:10], w[:10])),
                                  want[:10])
    assert walks  # ten pairs walk (Thm 2 as the paper has it)


@pytest.mark.parametrize("structure", ["halfedge", *[pytest.param(n, marks=pytest.mark.slow)
                                                     for n in ("cds5n", "lr")]])  # 7 s each
def test_gather_normals_around_a_hub_turn_in_stages(structure):
    """The gather route turned every vertex's lane as many times as the largest degree: O(n d),
    quadratic around a hub (sweep 17b: poles of degree 16K took 6.1 s on the half-edge). After
    64 turns the vertices still turning go on compacted: the lane turns stay within a few per
    dart (one loop: (k + 2) k = 25M here), and the normals equal the scatter route's; a mesh
    whose degrees all stay under 64 takes the first stage only (lane turns: vertices x largest
    degree)."""
    from jaxcds.algorithms import normals as N
    from jaxcds.structures import registry

    v, f = _bipyramid(5000)  # more than 4,096 vertices: compacted in chunks (else whole)
    s = registry.build(structure, load_mesh(v, f))
    p = jnp.asarray(v if s.vertex_order is None else v[np.asarray(s.vertex_order)], jnp.float32)
    sums, work = jax.jit(N._gather_turns)(s, p)
    assert float(work) <= 20 * s.num_darts, (float(work), s.num_darts)
    np.testing.assert_allclose(np.asarray(N.normalize(sums)), np.asarray(vertex_normals(s, p)), atol=1e-5)
    small = registry.build(structure, icosphere(2))
    q = jnp.asarray(icosphere(2).vertices, jnp.float32)
    q = q if small.vertex_order is None else q[np.asarray(small.vertex_order)]
    assert float(jax.jit(N._gather_turns)(small, q)[1]) == 6 * small.num_vertices  # degrees 5-6


def test_normalize_derivative_is_the_projection():
    """The custom JVP ``(dx - u (u . dx)) / |x|``, in both modes, against the plain formula."""
    x = jnp.array([[3.0, 4.0, 1.0], [0.5, -2.0, 0.25]], jnp.float32)
    w = jnp.array([1.0, 2.0, 3.0], jnp.float32)
    plain = lambda y: jnp.sum(y / jnp.linalg.norm(y, axis=-1, keepdims=True) * w)  # noqa: E731
    np.testing.assert_allclose(np.asarray(jax.grad(lambda y: jnp.sum(normalize(y) * w))(x)),
                               np.asarray(jax.grad(plain)(x)), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(np.asarray(jax.jacfwd(normalize)(x[0])),
                               np.asarray(jax.jacfwd(lambda y: y / jnp.linalg.norm(y))(x[0])), rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("structure", ["halfedge", "cds5n"])
def test_gather_normals_have_forward_mode_derivatives(structure):
    """The gather route's derivative was a custom VJP: jax.jvp, jacfwd and hessian of it raised
    JAX's TypeError ("can't apply forward-mode autodiff (jvp) to a custom_vjp function"). Now a
    custom JVP (the scatter route's tangent): both modes, and second order, equal the scatter
    route's, on an open mesh (border darts; CDS: the hole's fan left out)."""
    from jaxcds.generators import delaunay_square
    from jaxcds.structures import registry

    m = delaunay_square(12)
    s = registry.build(structure, m if structure == "halfedge" else close_boundaries(m))
    rng = np.random.default_rng(0)
    order = np.arange(s.num_vertices) if s.vertex_order is None else np.asarray(s.vertex_order)
    v = close_boundaries(m).vertices if s.num_vertices > m.num_vertices else m.vertices
    p = jnp.asarray(v[order] + 0.1 * rng.normal(size=(s.num_vertices, 3)), jnp.float32)
    t = jnp.asarray(rng.normal(size=p.shape), jnp.float32)
    gather = lambda q: vertex_normals(s, q, method="gather")  # noqa: E731
    scatter = lambda q: vertex_normals(s, q)  # noqa: E731
    y, dy = jax.jvp(gather, (p,), (t,))
    y_ref, dy_ref = jax.jvp(scatter, (p,), (t,))
    np.testing.assert_allclose(np.asarray(y), np.asarray(y_ref), atol=1e-5)
    np.testing.assert_allclose(np.asarray(dy), np.asarray(dy_ref), atol=1e-4)
    np.testing.assert_allclose(np.asarray(jax.jacfwd(gather)(p)), np.asarray(jax.jacrev(gather)(p)),
                               atol=1e-4)
    z = lambda f: lambda q: jnp.sum(f(q)[:, 2] * t[:, 0])  # noqa: E731
    np.testing.assert_allclose(np.asarray(jax.hessian(z(gather))(p)), np.asarray(jax.hessian(z(scatter))(p)),
                               atol=1e-3)


def test_normals_inputs_lists_ints_and_bad_method():
    """A nested list and integer coordinates are converted (the gather route's float loop
    carry crashed on ints); an unknown method is a jaxcds error, not a plain ValueError."""
    from jaxcds import errors

    v, f = octahedron()
    he = HalfEdge.from_mesh(load_mesh(v, f))
    want = np.asarray(vertex_normals(he, jnp.asarray(v, jnp.float32)))
    ints = np.rint(np.asarray(v) * 2).astype(np.int32)
    for method in ("scatter", "gather"):
        np.testing.assert_allclose(np.asarray(vertex_normals(he, ints, method=method)), want, atol=1e-6)
        np.testing.assert_allclose(np.asarray(vertex_normals(he, np.asarray(v).tolist(), method=method)),
                                   want, atol=1e-6)
    with pytest.raises(errors.JaxcdsError, match="unknown normals method 'foo'"):
        vertex_normals(he, jnp.asarray(v, jnp.float32), method="foo")
    ct = CornerTable.from_mesh(load_mesh(v, f))
    assert int(ct.next(4)) == int(ct.next(jnp.int32(4)))  # a Python int id (n() crashed)


def _flat_strip(nx=12, ny=3, seed=0):
    """A nearly flat open patch (the case where a hole's fan flips border normals): an
    ``nx`` by ``ny`` grid of quads in the plane z = 0, slightly bumped, split into triangles."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.arange(nx + 1, dtype=float), np.arange(ny + 1, dtype=float), indexing="ij")
    v = np.stack([x.ravel(), y.ravel(), 1e-3 * rng.standard_normal(x.size)], axis=1)
    idx = lambda i, j: i * (ny + 1) + j  # noqa: E731
    f = []
    for i in range(nx):
        for j in range(ny):
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
            f += [[a, b, c], [a, c, d]]
    return load_mesh(v, np.asarray(f))


@pytest.mark.parametrize("structure", CDS_FAMILY)
def test_cds_on_an_open_mesh_gives_the_open_meshes_degrees_and_normals(structure):
    """The CDS family closes the hole with a dummy vertex and a fan (Sec. 4.5). Degrees and
    normals are still the open surface's: on a flat strip every normal is about +z (the fan
    flipped the border ones to -z before), the dummy's normal is zero and its degree 0; batched
    and gathered the same, gradients equal the open face list's."""
    from jaxcds import batch
    from jaxcds.structures import registry

    m = _flat_strip()
    s = registry.build(structure, m)
    assert s.num_vertices == m.num_vertices + 1  # one hole, one dummy vertex
    order = np.arange(s.num_vertices) if s.vertex_order is None else np.asarray(s.vertex_order)
    closed = close_boundaries(m)
    dummy = np.asarray(closed.dummy_vertices)[order]
    np.testing.assert_array_equal(np.asarray(s.dummy_vertex_mask()), dummy)
    pos = jnp.asarray(closed.vertices[order], jnp.float32)
    he = HalfEdge.from_mesh(m)
    inv = np.argsort(order)[: m.num_vertices]  # input vertex -> structure label
    want = np.asarray(vertex_normals(he, jnp.asarray(m.vertices, jnp.float32)))
    for method in ("scatter", "gather"):
        got = np.asarray(vertex_normals(s, pos, method=method))
        np.testing.assert_allclose(got[inv], want, atol=1e-5)
        assert got[inv][:, 2].min() > 0.99  # every normal of the flat strip points up
        np.testing.assert_array_equal(got[dummy], 0.0)
    deg = np.asarray(vertex_degrees(s))
    np.testing.assert_array_equal(deg[inv], np.asarray(vertex_degrees(he)))
    assert deg[dummy].tolist() == [0]
    # the generic route (darts counted at their origins, fans subtracted) agrees
    from jaxcds.algorithms.degrees import dart_count_degrees
    np.testing.assert_array_equal(np.asarray(jax.jit(dart_count_degrees)(s)), deg)
    # gradients: the open face list on the same positions (the dummy's gradient is zero)
    w = jnp.asarray(np.random.default_rng(1).normal(size=pos.shape), jnp.float32)
    faces = jnp.asarray(np.argsort(order)[m.faces])
    g = jax.grad(lambda p: jnp.sum(vertex_normals(s, p) * w))(pos)
    g_ref = jax.grad(lambda p: jnp.sum(face_list_vertex_normals(p, faces) * w))(pos)
    np.testing.assert_allclose(np.asarray(g), np.asarray(g_ref), atol=1e-4, rtol=1e-3)
    # a batch of the strip and a closed mesh: the dummy keeps its place in the union
    b = batch.pack([octahedron(), m], structure)
    got_b = np.asarray(vertex_normals(b, batch.pack_positions(b, [octahedron(), closed])))
    np.testing.assert_allclose(got_b[6:][inv], want, atol=1e-5)
    np.testing.assert_array_equal(np.asarray(vertex_degrees(b))[6:][inv], np.asarray(vertex_degrees(he)))


def test_a_nan_coordinate_gives_nan_normals_not_zero_ones():
    """NaN in, NaN out: the NaN vertex and its one-ring (the faces it is on) read NaN, every
    other normal is untouched; a zero sum (a vertex in no face) still reads zero."""
    m = load_mesh(*octahedron())
    he = HalfEdge.from_mesh(m)
    p = np.asarray(m.vertices, np.float32).copy()
    good = np.asarray(vertex_normals(he, jnp.asarray(p)))
    p[0, 1] = np.nan
    ring = {0} | {int(v) for f in m.faces for v in f if 0 in f}
    for method in ("scatter", "gather"):
        n = np.asarray(vertex_normals(he, jnp.asarray(p), method=method))
        nan_rows = set(np.flatnonzero(np.isnan(n).any(axis=1)).tolist())
        assert nan_rows == ring, (method, nan_rows)
        rest = sorted(set(range(m.num_vertices)) - ring)
        np.testing.assert_allclose(n[rest], good[rest], atol=1e-6)
    np.testing.assert_array_equal(np.asarray(normalize(jnp.zeros((2, 3)))), 0.0)
    assert np.isnan(np.asarray(normalize(jnp.asarray([[np.nan, 0.0, 0.0]])))).all()


def _square_with_a_hole(n=30):
    """``delaunay_square(n)`` without the faces around its most central vertex: two border
    loops (the CDS family closes each with a dummy vertex and a fan; LR keeps border slots)."""
    from jaxcds.generators import delaunay_square

    m = delaunay_square(n)
    c = np.argmin(np.linalg.norm(m.vertices[:, :2] - 0.5, axis=1))
    f = m.faces[~(m.faces == c).any(axis=1)]
    used = np.unique(f)
    new = np.full(m.num_vertices, -1)
    new[used] = np.arange(used.size)
    return load_mesh(m.vertices[used], new[f])


@pytest.mark.parametrize("structure", ["cds4n", "lr"])
def test_a_non_finite_position_leaves_gradients_outside_its_rings_finite(structure):
    """Sweep 15a: the masked rows (a CDS hole's fan, LR's border slots, padding) were zeroed
    after their cross products; the zero cotangent ``where`` gives them met the corners'
    positions in the cross product's derivative (0 * NaN): a NaN or inf at a CDS dummy vertex
    (zero normal by design) made the gradient of its whole border NaN, and a NaN vertex reached
    a vertex across LR's hole. Now, for a NaN or inf at any vertex, the vertices with a
    non-finite gradient are the face list's (the open mesh's faces), and a dummy's position
    carries no derivative at all: the gradient equals the one with the dummy at its centroid."""
    from conftest import as_accepted
    from jaxcds.structures import registry

    m = as_accepted(_square_with_a_hole(), structure)
    s = registry.build(structure, m)
    base = close_boundaries(m) if s.num_vertices > m.num_vertices else m
    order = np.arange(s.num_vertices) if s.vertex_order is None else np.asarray(s.vertex_order)
    dummy = np.zeros(s.num_vertices, bool) if s.dummy_vertex_mask() is None else np.asarray(s.dummy_vertex_mask())
    faces = np.argsort(order)[m.faces]
    faces = jnp.asarray(faces[~dummy[faces].any(axis=1)])  # the open mesh's own faces
    p = np.asarray(base.vertices[order], np.float32)
    w = jnp.asarray(np.random.default_rng(0).normal(size=p.shape), jnp.float32)
    grads = {k: jax.jit(jax.vmap(jax.grad(lambda q, f=f: jnp.sum(f(q) * w)))) for k, f in (
        ("scatter", lambda q: vertex_normals(s, q)),
        ("gather", lambda q: vertex_normals(s, q, method="gather")),
        ("faces", lambda q: face_list_vertex_normals(q, faces)))}
    for bad in (np.nan, np.inf):
        ps = np.repeat(p[None], s.num_vertices, axis=0)  # ps[v]: vertex v's x is bad
        ps[np.arange(s.num_vertices), np.arange(s.num_vertices), 0] = bad
        want = ~np.isfinite(np.asarray(grads["faces"](jnp.asarray(ps)))).all(axis=2)
        for method in ("scatter", "gather"):
            got = ~np.isfinite(np.asarray(grads[method](jnp.asarray(ps)))).all(axis=2)
            np.testing.assert_array_equal(got, want, err_msg=f"{method}, {bad}")
    if dummy.any():
        clean = np.asarray(grads["scatter"](jnp.asarray(p[None])))[0]
        for bad in (np.nan, np.inf):
            q = p.copy()
            q[dummy] = bad
            for method in ("scatter", "gather"):
                g = np.asarray(grads[method](jnp.asarray(q[None])))[0]
                np.testing.assert_array_equal(g[dummy], 0.0)
                np.testing.assert_allclose(g, clean, rtol=1e-5, atol=1e-6)


def _cycle(ring):
    """A ccw ring as a rotation-free key (its rotation starting at the smallest id)."""
    k = ring.index(min(ring)) if ring else 0
    return tuple(ring[k:] + ring[:k])


@pytest.mark.parametrize("structure", ["cds6n", "cds5n-o1"])
def test_one_ring_of_a_border_vertex_leaves_the_dummy_out(structure):
    """A CDS closes a hole with a dummy vertex (Sec. 4.5): one_ring walked the closed surface, so
    every border vertex's ring held the dummy and its degree counted it, one more than
    vertex_degrees (sweep 16a). Rings are now the input mesh's: the half-edge's ccw cycle, the
    dummy left out, from the neighbour after the hole to the one before it; a dummy's is empty."""
    from jaxcds.structures import registry

    m = _flat_strip(nx=4, ny=2)
    he, s = HalfEdge.from_mesh(m), registry.build(structure, m)
    order = np.arange(s.num_vertices) if s.vertex_order is None else np.asarray(s.vertex_order)
    dummy = np.asarray(s.dummy_vertex_mask())
    label = np.argsort(order)[: m.num_vertices]  # input vertex -> structure label
    want_deg = np.asarray(vertex_degrees(he))
    width = int(want_deg.max())
    ring_he, _ = (np.asarray(x) for x in one_ring(he, np.arange(m.num_vertices), width))
    ring, deg = (np.asarray(x) for x in one_ring(s, label, width))
    np.testing.assert_array_equal(deg, want_deg)
    np.testing.assert_array_equal(deg, np.asarray(vertex_degrees(s))[label])
    for i in range(m.num_vertices):
        got = order[ring[i, : deg[i]]].tolist()
        assert _cycle(got) == _cycle(ring_he[i, : want_deg[i]].tolist()), i
        assert (ring[i, deg[i]:] == s.num_vertices).all()
    # a border vertex's ring is the open path: its first and last neighbours are on the border
    tm = trimesh.Trimesh(m.vertices, m.faces, process=False)
    border = set(tm.edges[trimesh.grouping.group_rows(tm.edges_sorted, require_count=1)].ravel().tolist())
    for i in sorted(border):
        got = order[ring[i, : deg[i]]]
        assert {int(got[0]), int(got[-1])} <= border and adjacent(he, i, int(got[0]))
    assert np.asarray(one_ring(s, np.flatnonzero(dummy), width)[1]).tolist() == [0]


@pytest.mark.parametrize("call", ["vertex_normals", "vertex_degrees", "adjacent", "one_ring"])
def test_generic_algorithms_name_an_argument_that_is_not_a_structure(call):
    """A TriMesh or an array in the structure's place failed inside jit with an AttributeError on
    a tracer ('DynamicJaxprTracer has no attribute num_vertices'): now ArgumentError naming the
    function and, for a TriMesh, how to build a structure from it."""
    m = load_mesh(*octahedron())
    args = {"vertex_normals": (m.vertices,), "vertex_degrees": (), "adjacent": (0, 1),
            "one_ring": ([0], 4)}[call]
    fn = {"vertex_normals": vertex_normals, "vertex_degrees": vertex_degrees,
          "adjacent": adjacent, "one_ring": one_ring}[call]
    for bad in (m, m.vertices):
        with pytest.raises(errors.ArgumentError) as exc:
            fn(bad, *args)
        msg = str(exc.value)
        assert msg.startswith(f"{call}: expected a jaxcds structure") and type(bad).__name__ in msg, msg
    assert "jaxcds.build(name, mesh)" in msg


def test_adjacent_names_ids_whose_shapes_do_not_broadcast():
    """adjacent(s, [0, 1], [1, 2, 3]) raised JAX's untyped ValueError ('Incompatible shapes for
    broadcasting') or TypeError (the CDS family's own route) from inside the jitted query."""
    s = HalfEdge.from_mesh(load_mesh(*octahedron()))
    with pytest.raises(errors.ArgumentError, match=r"adjacent: u and v .* got \(2,\) and \(3,\)"):
        adjacent(s, [0, 1], [1, 2, 3])
    assert np.asarray(adjacent(s, [[0], [1]], [1, 2, 3])).shape == (2, 3)  # broadcast still works


def test_vertex_normals_names_a_method_that_is_not_a_string():
    """An unhashable method (a list) failed in jit's static-argument hashing with JAX's ValueError
    'Non-hashable static arguments are not supported'."""
    v, f = octahedron()
    s = HalfEdge.from_mesh(load_mesh(v, f))
    with pytest.raises(errors.ArgumentError, match=r"unknown normals method \['gather'\]"):
        vertex_normals(s, v, method=["gather"])


@pytest.mark.parametrize("pos_shape,faces,want", [
    ((6, 2), None, r"positions must have shape \(V, 3\), got \(6, 2\)"),
    ((18,), None, r"positions must have shape \(V, 3\), got \(18,\)"),
    ((6, 3), np.zeros(24, np.int32), r"faces must have shape \(F, 3\), got \(24,\)"),
    ((6, 3), np.zeros((8, 4), np.int32), r"faces must have shape \(F, 3\), got \(8, 4\)")])
def test_face_list_normals_name_misshapen_positions_and_faces(pos_shape, faces, want):
    """face_list_vertex_normals documents (V, 3) positions and (F, 3) faces: a flat array raised
    JAX's untyped ValueError ('Dimension must be either 2 or 3 for cross product'), (V, 2)
    positions answered a (V,) array and (F, 4) faces the normals of their first three columns."""
    v, f = octahedron()
    p = np.resize(v, pos_shape)
    with pytest.raises(errors.MeshError, match=want):
        face_list_vertex_normals(p, f if faces is None else faces)


@pytest.mark.parametrize("bad", [6, 100, -100])
def test_face_list_normals_name_host_face_ids_out_of_range(bad):
    """An id past V made its faces add nothing (zero normals, no error); a negative one wrapped
    onto another vertex. Host faces are checked (the ids are read on the host anyway)."""
    v, f = octahedron()
    f = np.array(f)
    f[3, 1] = bad
    with pytest.raises(errors.InvalidIndexError,
                       match=rf"face_list_vertex_normals: face 3 refers to vertex {bad}, outside \[0, 6\)"):
        face_list_vertex_normals(v, f)


def test_within_range_takes_no_positions():
    """within_range of a (0, 3) array raised numpy's ValueError 'zero-size array to reduction
    operation max which has no identity'; nothing to rescale: it comes back as it is."""
    from jaxcds.algorithms.normals import within_range

    out = within_range(np.zeros((0, 3), np.float32))
    assert out.shape == (0, 3) and out.dtype == jnp.float32


def test_normalize_takes_lists_and_names_non_numbers():
    """normalize (exported by jaxcds.algorithms) raised JAX's TypeError on nested lists ('absolute
    requires ndarray or scalar arguments') and on strings; lists are now read as arrays and
    non-numbers named (ArgumentError). Its custom derivative is unchanged."""
    np.testing.assert_allclose(np.asarray(normalize([[3.0, 0.0, 4.0]])), [[0.6, 0.0, 0.8]], atol=1e-7)
    with pytest.raises(errors.ArgumentError, match="normalize: x must be real numbers"):
        normalize("abc")
    g = jax.grad(lambda x: normalize(x)[0])(jnp.array([3.0, 0.0, 4.0]))
    np.testing.assert_allclose(np.asarray(g), [0.128, 0.0, -0.096], atol=1e-6)


def test_one_ring_of_a_holed_cds_under_rank_promotion_raise():
    """A CDS closes holes with dummy vertices; one_ring drops them with a (slots,) position row
    that met ``(vertices, 1)`` columns by rank promotion, so users running with
    ``jax.numpy_rank_promotion("raise")`` got JAX's ValueError (sweep 52c). The rings and
    degrees are the default setting's, and the degrees the open mesh's."""
    from jaxcds.structures import registry

    m = load_shared("2triangles.off")
    s = registry.build("cds6n", m)
    v = jnp.arange(s.num_vertices, dtype=jnp.int32)
    with jax.numpy_rank_promotion("raise"):
        ring, deg = one_ring(s, v, 4)
    want_ring, want_deg = one_ring(s, v, 4)
    np.testing.assert_array_equal(np.asarray(ring), np.asarray(want_ring))
    np.testing.assert_array_equal(np.asarray(deg)[:4], np.asarray(vertex_degrees(HalfEdge.from_mesh(m))))
    np.testing.assert_array_equal(np.asarray(deg), np.asarray(want_deg))


def test_normalize_of_integers_under_strict_dtype_promotion():
    """``normalize`` takes integers and bools (in the default float dtype): their
    promotion with its float constants was implicit, so users running with
    ``jax.numpy_dtype_promotion("strict")`` got JAX's TypePromotionError (sweep 52c)."""
    x = np.array([[3, 4, 0], [0, 0, 0], [1, 1, 1]], np.int32)
    with jax.numpy_dtype_promotion("strict"):
        got = normalize(jnp.asarray(x)), normalize(x.astype(bool))
    assert got[0].dtype == jnp.result_type(float)  # float32, float64 under enable_x64
    np.testing.assert_allclose(np.asarray(got[0]), np.asarray(normalize(x.astype(np.float32))), rtol=1e-6)
    np.testing.assert_allclose(np.asarray(got[1])[2], np.full(3, 3 ** -0.5), rtol=1e-6)
