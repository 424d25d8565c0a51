"""LR and lr-bits (Gurung et al., ACM TOG 2011): every corner operator of Sec. 4.7 on every corner
against the CornerTable, the Sec. 7 renderable index list, ring/classification invariants,
generic algorithms (degrees, normals and their gradient) against the HalfEdge, typed refusals.

``tests/structures/test_protocol.py`` already runs ``verify`` (every protocol operator, every
dart, vs the HalfEdge) for the registered ``lr`` / ``lr-bits`` builds on the shared meshes and on
random triangulations; here ``verify`` only runs on what it does not build: the icosphere in
the quick set; wart skipping off, chosen hybrid periods and ``borders=False`` in slow cases
(one ``verify`` compiles for 7-15 s of CPU).

Cost: every structure instance compiles the jitted checks once (its static sizes differ), so
structures are built once per module (``_built``) and each is checked by one jitted call.
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from jaxcds import errors
from jaxcds.algorithms import vertex_degrees, vertex_normals
from jaxcds.construct.ring_expander import best_ring, lr_tables
from jaxcds.generators import icosphere, random_planar_triangulation
from jaxcds.mesh import TriMesh, close_boundaries, load_mesh
from jaxcds.structures.corner_table import CornerTable
from jaxcds.structures.halfedge import HalfEdge
from jaxcds.structures.lr import (LR, LRBits, build_lr, expand_renderable_index_list,
                                  renderable_index_list, stats)
from jaxcds.verify import verify

from conftest import load_shared

# name -> (mesh key, builder). Mesh keys: shared file names, or "icosphere3".
CONFIGS = {
    "cube": ("cube.off", lambda m: LR.from_mesh(m, check=False)),
    "3holes": ("3holes.off", lambda m: LR.from_mesh(m, check=False)),
    "rocker-arm": ("rocker-arm.obj", lambda m: LR.from_mesh(m, check=False)),
    "grid": ("grid.off", lambda m: LR.from_mesh(m, check=False)),
    "camelhead": ("camelhead.off", lambda m: LR.from_mesh(m, check=False)),
    "icosphere3": ("icosphere3", lambda m: LR.from_mesh(m, check=False)),
    "3holes-no-warts": ("3holes.off", lambda m: LR.from_mesh(m, wart_skipping=False, check=False)),
    "3holes-bits-k1": ("3holes.off", lambda m: LRBits.from_mesh(m, k=1, check=False)),
    "3holes-bits-k16": ("3holes.off", lambda m: LRBits.from_mesh(m, k=16, check=False)),
    "rocker-arm-bits-dfs": ("rocker-arm.obj", lambda m: LRBits.from_mesh(m, k=0, check=False)),
    "camelhead-bits-auto": ("camelhead.off", lambda m: LRBits.from_mesh(m, check=False)),
    # rings moved by the local search (jaxcds.construct.ring_search): genus 3, holes
    "3holes-searched": ("3holes.off", lambda m: LR.from_mesh(m, check=False, ring_sweeps=20)),
    "camelhead-bits-searched": ("camelhead.off",
                                lambda m: LRBits.from_mesh(m, k=0, check=False, ring_sweeps=20)),
    "bunny-searched": ("bunny.off", lambda m: LR.from_mesh(m, check=False, ring_sweeps=20)),
}


@functools.lru_cache(maxsize=None)
def _mesh(key: str) -> TriMesh:
    if key == "icosphere3":
        return icosphere(3)
    return load_shared(key)


@functools.lru_cache(maxsize=None)
def _built(name: str):
    key, build = CONFIGS[name]
    return build(_mesh(key))


# ------------------------------------------------------------------ helpers
@jax.jit
def _corner_ops(s, c, v, t):
    """The paper's corner operators (Sec. 4.7, Fig. 2) on corner ids ``c``, ``v.c`` on vertices
    ``v``, ``t.c`` on triangles ``t``, and which ring slots are redundant T2 copies: one compiled
    call per structure."""
    ring = c < 8 * s.num_ring
    red = ring & s._redundant_slot(jnp.where(ring, c >> 2, 0))
    return {"v": s.v(c), "o": s.o(c), "n": s.n(c), "p": s.p(c), "s": s.s(c), "l": s.l(c),
            "r": s.r(c), "t": s.t(c), "nv": s.v(s.n(c)), "red": red, "vc": s.vc(v),
            "vc_v": s.v(s.vc(v)), "tc": s.tc(t)}


def _closed_order(s, mesh: TriMesh) -> np.ndarray:
    """Input id (of the closed mesh) of every LR vertex, dummy vertices (null index, numbered
    after the real ones, Sec. 4.6) included."""
    order = np.asarray(s.vertex_order)
    if s.num_closed_vertices == s.num_vertices:
        return order
    return np.concatenate([order, np.nonzero(mesh.dummy_vertices)[0]])


def _closed(mesh: TriMesh) -> TriMesh:
    return mesh if mesh.dummy_vertices is not None else close_boundaries(mesh)


def check_corner_operators(s, mesh: TriMesh) -> dict:
    """Every corner operator on every canonical corner of ``s`` against the CornerTable of the
    closed mesh (dummy triangles included): corners are matched through the dart they stand for,
    ``(c.v, c.n.v)`` in input ids, which is unique on a closed manifold."""
    closed = _closed(mesh)
    ct = CornerTable.from_faces(closed.faces, closed.num_vertices)
    V, O = np.asarray(ct.V), np.asarray(ct.O)
    nf, nv = closed.num_faces, closed.num_vertices
    assert s.num_closed_faces == nf and s.num_closed_vertices == nv
    order = _closed_order(s, closed)
    assert sorted(order.tolist()) == list(range(nv))  # a permutation of the closed mesh's vertices

    ids = np.arange(s.num_darts, dtype=np.int32)
    ids = ids[(ids & 3) != 3]
    nvert = s.num_vertices if s.has_border else nv  # dummies have no v.c (null index)
    t_all = ids[(ids & 3) == 0] >> 2  # every paper triangle id, redundant slots included
    res = {k: np.asarray(x) for k, x in _corner_ops(
        s, jnp.asarray(ids), jnp.arange(nvert, dtype=jnp.int32), jnp.asarray(t_all)).items()}
    red = res["red"]
    canon, redundant = ids[~red], ids[red]
    out = {k: res[k][~red] for k in ("v", "o", "n", "p", "s", "l", "r", "t", "nv")}
    out.update(vc=res["vc"], vc_v=res["vc_v"])
    keep_t = ~red[(ids & 3) == 0]
    t_all, out["tc"] = t_all[keep_t], res["tc"][keep_t]

    # LR corner -> corner-table corner, through the dart (c.v, c.n.v)
    key = lambda a, b: a.astype(np.int64) * nv + b  # noqa: E731
    ct_key = key(V, V[3 * (np.arange(3 * nf) // 3) + (np.arange(3 * nf) + 1) % 3])
    srt = np.argsort(ct_key)
    lr_key = key(order[out["v"]], order[out["nv"]])
    pos = np.clip(np.searchsorted(ct_key, lr_key, sorter=srt), 0, 3 * nf - 1)
    to_ct = srt[pos]
    assert np.array_equal(ct_key[to_ct], lr_key), "an LR corner names no dart of the mesh"
    # a bijection: as many canonical corners as corner-table corners, each dart once
    assert canon.size == 3 * nf and np.unique(to_ct).size == 3 * nf

    lookup = np.full(s.num_darts + 1, -1, np.int64)
    lookup[canon] = to_ct

    def ct_of(c):
        c = np.asarray(c, np.int64)
        ok = (c >= 0) & (c < s.num_darts)
        got = np.where(ok, lookup[np.where(ok, c, s.num_darts)], -1)
        assert np.all(got >= 0), "an operator returned a non-canonical corner"
        return got

    x = to_ct
    nx = 3 * (x // 3) + (x + 1) % 3
    px = 3 * (x // 3) + (x + 2) % 3
    np.testing.assert_array_equal(order[out["v"]], V[x], err_msg="c.v")
    np.testing.assert_array_equal(ct_of(out["o"]), O[x], err_msg="c.o")
    np.testing.assert_array_equal(ct_of(out["n"]), nx, err_msg="c.n")
    np.testing.assert_array_equal(ct_of(out["p"]), px, err_msg="c.p")
    np.testing.assert_array_equal(ct_of(out["l"]), O[nx], err_msg="c.l = c.n.o")
    np.testing.assert_array_equal(ct_of(out["r"]), O[px], err_msg="c.r = c.p.o")
    s_ct = 3 * (O[nx] // 3) + (O[nx] + 1) % 3
    np.testing.assert_array_equal(ct_of(out["s"]), s_ct, err_msg="c.s = c.n.o.n")
    # c.t: one id per triangle, the same on its three corners; t.c lands in the same triangle
    tri = x // 3
    t = out["t"]
    tri_of_t = np.full(int(t.max()) + 1, -1, np.int64)
    tri_of_t[t] = tri
    np.testing.assert_array_equal(tri_of_t[t], tri, err_msg="c.t")
    assert np.unique(t).size == nf
    tc = out["tc"]
    np.testing.assert_array_equal(ct_of(tc) // 3, tri_of_t[t_all], err_msg="t.c")
    # v.c: a canonical corner of v
    np.testing.assert_array_equal(out["vc_v"], np.arange(nvert), err_msg="v.c")
    ct_of(out["vc"])
    # redundant T2 copies (Sec. 4.4) name the same darts as their canonical corners
    if redundant.size:
        rkey = key(order[res["v"][red]], order[res["nv"][red]])
        assert np.isin(rkey, lr_key).all()
    return {"corners": int(canon.size), "redundant": int(redundant.size)}


def _triangle_set(f: np.ndarray) -> np.ndarray:
    """Triangles as rows rotated so the smallest id comes first (orientation kept), sorted."""
    f = np.asarray(f, np.int64)
    k = np.argmin(f, axis=1)
    rot = np.stack([f[np.arange(len(f)), (k + j) % 3] for j in range(3)], axis=1)
    return rot[np.lexsort(rot.T[::-1])]


# ------------------------------------------------------------------ corner operators
@pytest.mark.parametrize("name", list(CONFIGS))
def test_corner_operators_equal_corner_table(name):
    s = _built(name)
    mesh = _mesh(CONFIGS[name][0])
    got = check_corner_operators(s, mesh)
    assert got["corners"] == 3 * s.num_closed_faces
    st_ = stats(s)
    # ring invariants reported by the builder: m_i = m - m_r (real vertices), T0 counts
    assert st_["m_i"] == s.num_isolated == s.num_vertices - s.num_ring
    assert st_["T0"] == s.num_t0
    assert s.references == (2 * s.num_ring + 6 * s.num_t0 + s.num_vos + s.num_isolated
                            if isinstance(s, LR) else
                            s.num_ring + 6 * s.num_t0 + s.num_vos + s.num_isolated)
    if "no-warts" in name:
        assert st_["T0w"] == 0


def test_wart_skipping_lowers_the_reference_count():
    """Sec. 5: wart skipping turns T0 triangles into T1 (T0^w): fewer VO references."""
    with_, without = _built("3holes"), _built("3holes-no-warts")
    assert stats(with_)["T0w"] > 0
    assert with_.num_t0 < without.num_t0
    assert with_.references < without.references


@pytest.mark.parametrize("bits", [False, True])
def test_a_lone_triangle_is_refused_naming_the_mesh(bits):
    """A lone triangle's ring has 3 vertices: the refusal came from the ring code without the
    mesh's name, where every other refusal starts with it (sweep 50a, CGAL's triangle.off:
    "the ring from seed corner 0 has 3 vertices ..."). The mesh is named once."""
    m = load_mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), np.array([[0, 1, 2]]))
    m = TriMesh(vertices=m.vertices, faces=m.faces, source="lone.off")
    build = LRBits.from_mesh if bits else LR.from_mesh
    with pytest.raises(errors.UnsupportedTopologyError,
                       match=r"^lone\.off: the ring from seed corner \d+ has 3 vertices") as info:
        build(m)
    assert str(info.value).count("lone.off") == 1, info.value


def test_a_trapped_seed_draws_more_seeds():
    """Sec. 4.2 keeps the seed with the fewest isolated vertices; on a uniform random planar
    triangulation the one default seed here traps RING-EXPANDER inside a separating triangle
    (975 of 1,000 vertices isolated), so the builder draws more seeds until one is not trapped."""
    m = random_planar_triangulation(1000, seed=1)
    ct = CornerTable.from_faces(m.faces, m.num_vertices)
    V, O = np.asarray(ct.V), np.asarray(ct.O)
    first = int(3 * np.random.default_rng(0).choice(np.arange(m.num_faces), size=1, replace=False)[0])
    assert best_ring(V, O, m.num_vertices, seeds=[first]).num_isolated > 900
    s = LR.from_mesh(m, seeds=1, check=False)
    assert stats(s)["m_i"] <= m.num_vertices // 4 and stats(s)["seed"] != first
    # the caller's own seed list is used as given
    assert stats(LR.from_mesh(m, seeds=[first], check=False))["m_i"] > 900


def test_lr_bits_periods_and_auto_choice():
    """Sec. 6.1/8: the hybrid period changes the ring; ``k="auto"`` keeps the fewest bits."""
    m = _mesh("3holes.off")
    k1, k16 = _built("3holes-bits-k1"), _built("3holes-bits-k16")
    assert (k1.k, k16.k) == (1, 16)
    auto = LRBits.from_mesh(m, k=(1, 16), check=False)
    assert auto.bits == min(k1.bits, k16.bits) and auto.k in (1, 16)
    # 16 bits per ring entry pair + 32 per other reference (Sec. 8)
    for s in (k1, k16):
        assert s.bits == 32 * (s.num_ring + 6 * s.num_t0 + s.num_vos + s.num_isolated)


@settings(max_examples=3, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.sampled_from([24, 60]), seed=st.integers(0, 2**31 - 1),
       bits=st.booleans(), warts=st.booleans(), sweeps=st.sampled_from([0, 10]))
def test_corner_operators_on_random_triangulations(n, seed, bits, warts, sweeps):
    # two size buckets: the CornerTable side never recompiles; the LR's static sizes (m_r, n0)
    # still depend on the ring found, so each example costs about one compilation. ``sweeps``:
    # the ring search (it runs only with wart skipping)
    m = random_planar_triangulation(n, seed=seed)
    s = build_lr(m, bits=bits, k=4, wart_skipping=warts, check=False, ring_sweeps=sweeps)
    assert isinstance(s, LRBits if bits else LR)
    check_corner_operators(s, m)


# ------------------------------------------------------------------ construction invariants
@pytest.mark.parametrize("key", ["3holes.off", "grid.off"])
def test_every_triangle_classified_once(key):
    """Sec. 4.3: each triangle is in exactly one non-redundant ring slot (T1, T2, T0^w) or in
    the T0 list; 2 m_r slots = T1 + 2 T2 (+ warts: a T0^w takes a T2's redundant slot); the
    invaded triangles form a disk bounded by the ring (m_r - 2 of them)."""
    closed = close_boundaries(_mesh(key))
    ct = CornerTable.from_faces(closed.faces, closed.num_vertices)
    V, O = np.asarray(ct.V), np.asarray(ct.O)
    ring = best_ring(V, O, closed.num_vertices, seeds=2, dummy=closed.dummy_vertices)
    m_r = ring.order.size
    assert np.unique(ring.order).size == m_r  # a simple loop
    assert not closed.dummy_vertices[ring.order].any()  # Sec. 4.6: dummies never on the ring
    assert ring.num_isolated == closed.num_vertices - m_r
    # consecutive ring vertices are mesh edges, and right_corner faces them
    a, b = ring.order, np.roll(ring.order, -1)
    rc = ring.right_corner
    nxt = lambda c: 3 * (c // 3) + (c + 1) % 3  # noqa: E731
    np.testing.assert_array_equal(V[nxt(rc)], a)
    np.testing.assert_array_equal(V[nxt(nxt(rc))], b)
    for warts in (False, True):
        tb = lr_tables(V, O, ring, closed.num_vertices, wart_skipping=warts)
        held = np.concatenate([(tb.left_corner // 3)[~tb.red_left],
                               (tb.right_corner // 3)[~tb.red_right], tb.t0])
        np.testing.assert_array_equal(np.sort(held), np.arange(closed.num_faces))
        nw = int(tb.skip_left.sum() + tb.skip_right.sum())
        nred = int(tb.red_left.sum() + tb.red_right.sum())
        assert nred == tb.num_t2 - nw and (nw == 0 or warts)
        # canonical LR corner numbering covers every corner once
        assert np.unique(tb.lr_corner).size == 3 * closed.num_faces and tb.lr_corner.min() >= 0
    # invaded = the right slots' triangles of the RING-EXPANDER disk: m_r - 2 triangles
    from jaxcds.construct.ring_expander import ring_expander

    tm, _ = ring_expander(V, O, closed.num_vertices, ring.seed, closed.dummy_vertices)
    assert int(tm.sum()) == m_r - 2


# ------------------------------------------------------------------ Sec. 7 renderable list
@pytest.mark.parametrize("name", ["3holes", "grid", "camelhead-bits-auto", "3holes-no-warts"])
def test_renderable_index_list_expands_to_the_mesh(name):
    s = _built(name)
    mesh = _mesh(CONFIGS[name][0])
    idx, st_ = renderable_index_list(s)
    assert idx.dtype == np.int32 and st_["references"] == idx.size
    tri = expand_renderable_index_list(idx, s.num_ring)
    assert tri.shape == (s.num_faces, 3)
    real = mesh.faces if mesh.dummy_faces is None else mesh.faces[~mesh.dummy_faces]
    got = _triangle_set(np.asarray(s.vertex_order)[tri])
    np.testing.assert_array_equal(got, _triangle_set(real))
    # about one reference per triangle (paper: mean 1.03 with wart skips, 1.10 without)
    assert st_["rpt"] == idx.size / s.num_faces
    assert st_["references"] == 2 * s.num_ring + 3 * st_["num_t0"]
    if s.num_faces > 1000:  # tiny meshes (the cube: 16 slots, 12 triangles) are far from it
        assert 1.0 <= st_["rpt"] < 1.15, st_
    with pytest.raises(errors.StructureError):
        expand_renderable_index_list(idx[:-1], s.num_ring)


# ------------------------------------------------------------------ protocol, generic algorithms
def test_verify_icosphere():
    """Protocol vs HalfEdge on a mesh test_protocol does not build (one compile)."""
    rep = verify(_built("icosphere3"), _mesh("icosphere3"))
    assert rep.mismatches == 0 and rep.checked > 10 * 1280, str(rep)


def test_verify_searched_ring():
    """Protocol vs HalfEdge on every dart of an LR whose ring the local search moved (the decimated
    bunny: the search changes most of its T0 / T^i triangles)."""
    s = _built("bunny-searched")
    assert stats(s)["ring_search_gain"] > 0
    rep = verify(s, _mesh("bunny.off"))
    assert rep.mismatches == 0 and rep.checked > 10 * 6966, str(rep)


@pytest.mark.slow
def test_verify_wart_skipping_off():
    g = _mesh("grid.off")
    s = LR.from_mesh(g, wart_skipping=False)
    assert stats(s)["T0w"] == 0
    rep = verify(s, g)
    assert rep.mismatches == 0 and rep.checked > 10 * g.num_faces, str(rep)


@pytest.mark.slow
@pytest.mark.parametrize("k", [1, 16, 0])
def test_verify_lr_bits_periods(k):
    m = _mesh("camelhead.off")
    rep = verify(LRBits.from_mesh(m, k=k), m)
    assert rep.mismatches == 0, str(rep)


@pytest.mark.slow
def test_verify_closed_grid_borders_false():
    g = _mesh("grid.off")
    closed = close_boundaries(g)
    s = LR.from_mesh(g, borders=False)
    assert not s.has_border and s.num_vertices == closed.num_vertices
    rep = verify(s, closed)
    assert rep.mismatches == 0, str(rep)


def test_degrees_normals_and_gradient_equal_halfedge():
    """Generic algorithms run unchanged: degrees, area-weighted normals and their gradient
    w.r.t. positions on the holed grid (border darts of LR = HalfEdge's)."""
    g = _mesh("grid.off")
    s = _built("grid")
    he = HalfEdge.from_faces(g.faces, g.num_vertices)
    order = np.asarray(s.vertex_order)
    np.testing.assert_array_equal(np.asarray(vertex_degrees(s)),
                                  np.asarray(vertex_degrees(he))[order])
    pos = jnp.asarray(g.vertices, jnp.float32)
    w = jnp.asarray(np.random.default_rng(0).normal(size=(g.num_vertices, 3)), jnp.float32)

    def loss(structure, perm):
        return lambda p: jnp.sum(vertex_normals(structure, p[perm]) * w[perm])

    want_n = np.asarray(vertex_normals(he, pos))[order]
    np.testing.assert_allclose(np.asarray(vertex_normals(s, pos[order])), want_n, atol=2e-5)
    g_he = np.asarray(jax.grad(loss(he, np.arange(g.num_vertices)))(pos))
    g_lr = np.asarray(jax.grad(loss(s, order))(pos))
    assert np.abs(g_he).max() > 0
    np.testing.assert_allclose(g_lr, g_he, atol=1e-4)


# ------------------------------------------------------------------ refusals
def _tetra(offset=0):
    return np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]) + offset


def test_refusals_are_typed():
    rng = np.random.default_rng(0)
    # two tetrahedra: several components
    two = load_mesh(rng.normal(size=(8, 3)), np.concatenate([_tetra(), _tetra(4)]))
    for build in (LR.from_mesh, LRBits.from_mesh):
        with pytest.raises(errors.UnsupportedTopologyError, match="component"):
            build(two)
    # three triangles on one edge: non-manifold
    nm = load_mesh(rng.normal(size=(5, 3)), np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]]))
    with pytest.raises(errors.NonManifoldEdgeError):
        LR.from_mesh(nm)
    # one triangle, closed by a dummy vertex that may not be on the ring: a 3-vertex ring
    with pytest.raises(errors.UnsupportedTopologyError, match="ring"):
        LR.from_mesh(load_mesh(rng.normal(size=(3, 3)), np.array([[0, 1, 2]])))


# ------------------------------------------------------------------ large meshes (slow)
@pytest.mark.slow
@pytest.mark.parametrize("key", ["stanford-bunny.obj", "face.obj", "armadillo.obj"])
def test_large_meshes_corner_operators(key):
    m = load_shared(key)
    for s in (LR.from_mesh(m), LRBits.from_mesh(m, k=(64, 256)), LR.from_mesh(m, ring_sweeps=20)):
        check_corner_operators(s, m)
        idx, _ = renderable_index_list(s)
        tri = expand_renderable_index_list(idx, s.num_ring)
        real = m.faces if m.dummy_faces is None else m.faces[~m.dummy_faces]
        np.testing.assert_array_equal(_triangle_set(np.asarray(s.vertex_order)[tri]),
                                      _triangle_set(real))


@pytest.mark.slow
def test_bench_lr_quick_smoke(tmp_path, capsys):
    """benchmarks/bench_lr.py --quick: Table 1 rows and construction numbers come out."""
    import json

    from benchmarks import bench_lr

    out = tmp_path / "lr.json"
    assert bench_lr.main(["--quick", "--no-fig10", "--meshes", "cube.off", "grid.off",
                          "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    assert [r["mesh"] for r in res["table1"]] == ["cube.off", "grid.off"]
    grid = res["table1"][1]
    assert grid["n"] == 256 and grid["holes_closed"] == 1 and grid["rpt"] > 1
    assert res["construction"]["triangles"] == 20_000
    assert "| grid.off | 256 |" in capsys.readouterr().out


# ------------------------------------------------------------------ construction check (numba)
def _decoded(s):
    """The numba decoder of the construction check (:mod:`jaxcds.construct.lr_pack`)."""
    from jaxcds.construct import lr_pack

    VOs = np.asarray(s.VOs, np.int32)
    if isinstance(s, LR):
        E, X = lr_pack.decode_lr(np.asarray(s.L), np.asarray(s.R), VOs)
    else:
        E, X = lr_pack.decode_lr_bits(np.asarray(s.LR16), VOs, np.int64(s.num_ring))
    return E, X, VOs


@pytest.mark.parametrize("name", ["3holes", "camelhead", "3holes-no-warts", "3holes-bits-k16",
                                  "camelhead-bits-auto"])
def test_construction_check_decodes_as_the_operators(name):
    """The linear numba check decodes the packed arrays as the jitted ``c.v`` / ``c.o`` do
    (Sec. 4.7): equal on every corner id, redundant T2 copies and T0 corners included (same
    call as ``check_corner_operators``: its compilation is shared)."""
    from jaxcds.construct import lr_pack

    s = _built(name)
    ids = np.arange(s.num_darts, dtype=np.int32)
    ids = ids[(ids & 3) != 3]
    nvert = s.num_vertices if s.has_border else s.num_closed_vertices
    t_all = ids[(ids & 3) == 0] >> 2
    res = _corner_ops(s, jnp.asarray(ids), jnp.arange(nvert, dtype=jnp.int32), jnp.asarray(t_all))
    E, X, VOs = _decoded(s)
    gv, go = lr_pack.corner_vo(ids.astype(np.int64), np.int64(s.num_ring), np.int64(s.num_t0),
                               E, X, VOs, np.asarray(s.V0), np.asarray(s.O0))
    np.testing.assert_array_equal(gv, np.asarray(res["v"]), err_msg="c.v")
    np.testing.assert_array_equal(go, np.asarray(res["o"]), err_msg="c.o")


def _corrupt(s, rng):
    """A copy of ``s`` with one packed entry changed (an apex, an offset, a VO* or T0 entry)."""
    from jaxcds._dataclass import replace

    m = s.num_ring
    E, _, _ = _decoded(s)
    # a slot that holds a triangle of its own (not the redundant copy of a T2, Sec. 4.4)
    own = np.nonzero((E[:, 0] & ((1 << 29) - 1)) != (np.arange(m) + 2) % m)[0]
    if isinstance(s, LR):
        L = np.asarray(s.L).copy()
        v = int(own[rng.integers(own.size)])
        if (L[v] >> 30) & 1:  # irregular: the value indexes VO*; change a stored opposite
            vos = np.asarray(s.VOs).copy()
            vos[3 * (L[v] & ((1 << 29) - 1)) + 1] += 8
            return replace(s, VOs=jnp.asarray(vos))
        L[v] = (L[v] & ~((1 << 29) - 1)) | (((L[v] & ((1 << 29) - 1)) + 1) % m)
        return replace(s, L=jnp.asarray(L))
    lr16 = np.asarray(s.LR16).copy()
    short = np.intersect1d(np.nonzero((lr16[0::2] & lr16[1::2] & 1) == 0)[0], own)
    v = int(short[rng.integers(short.size)])
    lr16[2 * v] ^= 2  # the offset's lowest bit: another apex
    return replace(s, LR16=jnp.asarray(lr16))


@pytest.mark.parametrize("bits", [False, True])
def test_construction_check_refuses_corrupted_tables(bits):
    """``check=True`` is a real check: one changed entry of the packed arrays (or of the T0
    table) is reported as a typed error naming the corner."""
    from jaxcds.structures import lr as lrmod

    mesh = _mesh("3holes.off")
    s = (LRBits.from_mesh(mesh, k=16) if bits else LR.from_mesh(mesh))  # check=True passes
    st_ = s._stats
    ct = CornerTable.from_faces(mesh.faces, mesh.num_vertices)
    V, O = np.asarray(ct.V), np.asarray(ct.O)
    lrmod._check(s, V, O, st_["_lrc"], st_["_new_of_old"])
    rng = np.random.default_rng(1)
    for _ in range(5):
        with pytest.raises(errors.StructureError, match="corners wrong"):
            lrmod._check(_corrupt(s, rng), V, O, st_["_lrc"], st_["_new_of_old"])
    if s.num_t0:
        from jaxcds._dataclass import replace

        o0 = np.asarray(s.O0).copy()
        o0[0] = (o0[0] + 1) % s.num_darts
        with pytest.raises(errors.StructureError, match="corners wrong"):
            lrmod._check(replace(s, O0=jnp.asarray(o0)), V, O, st_["_lrc"], st_["_new_of_old"])


def test_lr_bits_from_corner_table_equals_from_mesh():
    """``LRBits.from_corner_table`` (the paper's input, Sec. 8.1) builds the same arrays as
    ``from_mesh`` on the same closed mesh, one hybrid period, one seed."""
    import dataclasses

    mesh = _mesh("3holes.off")
    ct = CornerTable.from_faces(mesh.faces, mesh.num_vertices)
    a = LRBits.from_corner_table(ct, k=16)
    b = LRBits.from_mesh(mesh, k=16, seeds=1)
    assert a.k == b.k == 16
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if f.metadata.get("static"):
            assert x == y, f.name
        else:
            np.testing.assert_array_equal(np.asarray(x), np.asarray(y), err_msg=f.name)


def test_lr_bits_entries_round_trip_with_both_wart_skips():
    """Sec. 6.2: a short 16-bit pair carries its two wart-skip bits in the flags, and flags
    (1, 1) mean *long*; a ring vertex whose two slots both skip a wart is therefore stored long
    (through VO*). Packing then decoding gives back every apex and skip bit."""
    from jaxcds.construct import lr_pack

    m = 12
    v = np.arange(m)
    lv, rv = (v + 3) % m, (v - 2) % m  # near apexes: short offsets
    skl = np.zeros(m, np.int64)
    skr = np.zeros(m, np.int64)
    skl[[4, 6]] = 1
    skr[[4, 9]] = 1
    E = np.stack([lv | (skl << 29), rv | (skr << 29)], axis=1).astype(np.int32)
    zeros = np.zeros(m, np.uint8)
    lr16, vos, num_vos, nlong = lr_pack.pack_lr_bits(E, zeros, zeros, np.zeros((m, 4), np.int32))
    assert nlong == 1 and num_vos == 2  # vertex 4 only: [v.l, v.r]
    E2, X = lr_pack.decode_lr_bits(lr16, vos, np.int64(m))
    np.testing.assert_array_equal(E2, E)
    assert not X[:, :2].any()  # no irregular slot


def test_packing_finds_a_wrong_quad_opposite():
    """The quad opposites ``v.1.o = v.5`` (Sec. 4.5) never go to VO*: with ``check=True`` the
    packing pass reports a wrong one (here a corner table corrupted at one slot's apex corner)
    as a typed error; without the check it is not looked for."""
    from jaxcds.construct import lr_pack
    from jaxcds.structures import lr as lrmod

    mesh = _mesh("3holes.off")
    ct = CornerTable.from_faces(mesh.faces, mesh.num_vertices)
    V, O = np.asarray(ct.V), np.asarray(ct.O).copy()
    ring = best_ring(V, O, mesh.num_vertices, seeds=1)
    tb = lr_tables(V, O, ring, mesh.num_vertices)
    dm = np.zeros(mesh.num_vertices, bool)
    assert lr_pack.pack_common(V, O, ct.vertex_corner, tb, dm)["bad_quad"] is None
    v = int(np.nonzero(~tb.red_left & ~tb.skip_left & ~tb.skip_right)[0][3])
    a = int(tb.left_corner[v])
    O[a] = O[3 * (a // 3) + (a + 1) % 3]  # the apex corner now "faces" another edge
    assert lr_pack.pack_common(V, O, ct.vertex_corner, tb, dm)["bad_quad"] == (1, v)
    assert lr_pack.pack_common(V, O, ct.vertex_corner, tb, dm, quad_check=False)["bad_quad"] is None
    with pytest.raises(errors.StructureError, match="quad opposite"):
        lrmod._pack(LR, tb, V, O, np.asarray(ct.vertex_corner), mesh.num_vertices, check=True, k=0)


def test_seed_and_period_arguments_are_checked_by_name():
    """An out-of-range seed corner crashed the numba RING-EXPANDER (segfault); counts, lists
    and periods of the wrong kind were plain ValueError / AttributeError or silently cast."""
    m = icosphere(1)  # 240 corners
    bad_seeds = [(0, "count >= 1"), (True, "count >= 1"), ("x", "count >= 1"), ([], "empty list"),
                 ([240], r"seeds\[0\] = 240 is not a corner id in \[0, 240\)"), ([5, -3], r"seeds\[1\] = -3"),
                 ([1.0], r"seeds\[0\] = 1.0")]
    for seeds, msg in bad_seeds:
        with pytest.raises(errors.ArgumentError, match=msg):
            build_lr(m, seeds=seeds)
    for k in ([], "x", -1, 1.5, True):
        with pytest.raises(errors.ArgumentError, match="k must be 'auto'"):
            build_lr(m, bits=True, k=k)
    ct = CornerTable.from_mesh(m)
    with pytest.raises(errors.ArgumentError, match="seeds"):
        LR.from_corner_table(ct, seeds=[10**6])
    with pytest.raises(errors.ArgumentError, match="one period"):
        LRBits.from_corner_table(ct, k=[2, 4])
    # a seed on a hole-closing triangle is refused too (the ring starts on the mesh)
    grid = close_boundaries(load_shared("grid.off"))
    fan = int(np.flatnonzero(grid.dummy_faces)[0])
    with pytest.raises(errors.ArgumentError, match="dummy"):
        build_lr(grid, seeds=[3 * fan])
    assert verify(build_lr(m, seeds=[3, 9]), m).mismatches == 0


# (sweep 14b) LR / LRBits.from_corner_table take a trusted table: one that
# CornerTable.from_faces built on a mesh with a border side (its ``c.o`` there is a border dart,
# past the corners) crashed RING-EXPANDER (a segfault). Probed in a child.
_LR_TABLE_CHILD = r"""
import numpy as np
from jaxcds.structures import CornerTable
from jaxcds.structures.lr import LR, LRBits

tet = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
cases = {"duplicate_face": (tet + [[0, 2, 1]], 4), "degenerate": ([[0, 0, 0]], 1)}
for name, (f, nv) in cases.items():
    ct = CornerTable.from_faces(np.array(f, np.int32), nv)
    for cls in (LR, LRBits):
        record(cls.__name__ + ":" + name, lambda cls, ct: cls.from_corner_table(ct, check=False), cls, ct)
"""


def test_lr_from_corner_table_refuses_a_table_with_borders():
    from conftest import crash_probe

    out = crash_probe(_LR_TABLE_CHILD)
    for cls in ("LR", "LRBits"):
        for name in ("duplicate_face", "degenerate"):
            got, msg = out[f"{cls}:{name}"]
            assert got == "UnsupportedTopologyError", (cls, name, got, msg)
            assert msg.startswith(f"{cls}.from_corner_table: corner ") and "has no opposite" in msg


def test_builder_flags_and_corner_table_arguments_are_checked():
    """``check``, ``wart_skipping``, ``borders`` must be bools (``check='no'`` was truthy: it
    validated; ``borders=0`` silently showed the closed mesh); ``from_corner_table`` names a
    TriMesh given for the table (AttributeError about ``.V``), a bad ``dummy`` mask (numpy's
    IndexError) and, for LR, a seed count of 0 or -1 (numpy's ValueError)."""
    from conftest import octahedron

    m = octahedron()
    for cls in (LR, LRBits):
        for flag in ("check", "wart_skipping", "borders"):
            if cls is LRBits and flag == "wart_skipping":
                continue  # not one of LRBits.from_mesh's arguments
            for bad in ("no", 0, None):
                with pytest.raises(errors.ArgumentError, match=f"{cls.__name__}.from_mesh: {flag} must be"):
                    cls.from_mesh(m, **{flag: bad})
    ct = CornerTable.from_mesh(m)
    for cls in (LR, LRBits):
        where = f"{cls.__name__}.from_corner_table"
        with pytest.raises(errors.ArgumentError, match=f"{where}: expected a CornerTable"):
            cls.from_corner_table(load_mesh(m))
        for dummy in ("x", np.zeros(3, bool), np.zeros(6, np.float32)):
            with pytest.raises(errors.ArgumentError, match=f"{where}: dummy must be"):
                cls.from_corner_table(ct, dummy=dummy)
        for flag in ("check", "wart_skipping"):
            with pytest.raises(errors.ArgumentError, match=f"{where}: {flag} must be"):
                cls.from_corner_table(ct, **{flag: "no"})
    for seeds in (0, -1, "x"):
        with pytest.raises(errors.ArgumentError, match="seeds must be a count"):
            LR.from_corner_table(ct, seeds=seeds)
    assert LR.from_corner_table(ct, dummy=np.zeros(6, bool), check=np.True_).num_vertices == 6


def test_lr_operators_under_strict_dtype_promotion():
    """Users of a JAX library may run with ``jax.numpy_dtype_promotion("strict")``: LR's
    opposite corner added a bool (second corner of a VO* triplet) to an int32 index, so every
    operator through ``c.o`` raised JAX's TypePromotionError there (sweep 52c). Every operator
    on every dart agrees with the half-edge under that setting."""
    from jaxcds.structures import registry
    from jaxcds.verify import verify

    m = random_planar_triangulation(40, seed=3)
    s = registry.build("lr", m)
    assert s.VOs.shape[0] > 0  # irregular triangles: the VO* route is taken
    with jax.numpy_dtype_promotion("strict"):
        rep = verify(s, m)
    assert rep.checked > 10 * m.num_faces
    assert rep.mismatches == 0, str(rep)


def _icosahedron_table():
    from jaxcds.generators import icosphere
    from jaxcds.structures.corner_table import CornerTable

    return np.asarray(icosphere(0).faces), CornerTable.from_faces(np.asarray(icosphere(0).faces), 12)


@pytest.mark.parametrize("cls_name,change,error,msg", [
    ("LR", lambda f, ct: dataclasses.replace(ct, V=ct.V[:-3]), errors.ArgumentError,
     r"LR.from_corner_table: V and O must have 3F = 60 entries, got \(57,\) and \(60,\)"),
    ("LR", lambda f, ct: dataclasses.replace(ct, V=ct.V.at[4].set(12)), errors.InvalidIndexError,
     r"LR.from_corner_table: corner 4 \(face 1\) has vertex 12, outside \[0, 12\)"),
    ("LRBits", lambda f, ct: dataclasses.replace(ct, O=ct.O.at[4].set(-1)), errors.UnsupportedTopologyError,
     r"LRBits.from_corner_table: corner 4 \(vertex \d+, face 1\) has no opposite corner \(c.o = -1, "
     r"outside \[0, 60\)\): the table has a border"),
])
def test_from_corner_table_names_a_table_it_cannot_take(cls_name, change, error, msg):
    """Checks before RING-EXPANDER's kernels, which read the table unchecked; no test ran them."""
    from jaxcds.structures.lr import LR, LRBits

    cls = {"LR": LR, "LRBits": LRBits}[cls_name]
    with pytest.raises(error, match=msg):
        cls.from_corner_table(change(*_icosahedron_table()))


def test_from_corner_table_of_an_open_mesh_names_its_border():
    """CornerTable.from_faces takes an open mesh; its border corners have no opposite inside the
    table, which the ring's kernel read out of bounds."""
    from jaxcds.structures.corner_table import CornerTable
    from jaxcds.structures.lr import LR

    f, _ = _icosahedron_table()
    with pytest.raises(errors.UnsupportedTopologyError, match=r"has no opposite corner .*LR needs a closed mesh"):
        LR.from_corner_table(CornerTable.from_faces(f[1:], 12))


def test_from_corner_table_with_every_vertex_dummy_has_no_seed():
    from jaxcds.structures.lr import LR

    _, ct = _icosahedron_table()
    with pytest.raises(errors.UnsupportedTopologyError, match="no triangle without a dummy vertex to seed the ring"):
        LR.from_corner_table(ct, dummy=np.ones(12, bool))


def test_build_lr_and_render_list_name_arguments_of_the_wrong_kind():
    """``build_lr(bits=array)`` raised numpy's untyped 'truth value' ValueError, ``render_list``
    of another structure an AttributeError about ``num_ring``."""
    from jaxcds.generators import icosphere
    from jaxcds.structures import registry
    from jaxcds.structures.lr import build_lr, render_list

    m = icosphere(0)
    with pytest.raises(errors.ArgumentError, match=r"build_lr: bits must be True or False, got array"):
        build_lr(m, bits=np.array([True, False]))
    with pytest.raises(errors.ArgumentError, match=r"render_list: expected an LR or LRBits structure .*got HalfEdge"):
        render_list(registry.build("halfedge", m))
