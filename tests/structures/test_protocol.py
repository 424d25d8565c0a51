"""Every registered structure, every operator, every dart, against the HalfEdge.

New structures join automatically by registering in :mod:`jaxcds.structures.registry`.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from jaxcds import errors
from jaxcds.algorithms import vertex_degrees, vertex_normals
from jaxcds.mesh import close_boundaries
from jaxcds.structures import registry
from jaxcds.structures.halfedge import HalfEdge
from jaxcds.verify import verify

from conftest import (BORDER_AWARE, CLOSED_GENUS0, HIGHER_GENUS, HOLED_GENUS0, LARGE, as_accepted,
                      load_shared, mesh_params, slow_params)

STRUCTURES = registry.names()


def prepared(name, structure):
    return as_accepted(load_shared(name), structure)


# The quick set (CI) covers each kind of input: a tiny closed genus-0 mesh, borders (closed by a
# dummy vertex, or shown as borders) and genus 3; mid-size closed genus 0 comes from the random
# triangulations below (and bunny.off in the degrees/normals test). Every other accepted shared
# mesh runs in the slow set (`make test-all`): each (structure, mesh) pair costs one XLA
# compilation of every operator (10-45 s, pemb 100 s), whatever the mesh size. bunny.off,
# camelhead.off and rocker-arm.obj left the quick set on 2026-12-01 (CI read 27.5 min on a slow
# box with them: 690 s of the suite's 2,850 CPU seconds were this test).
QUICK_MESHES = {"cube.off", "grid.off", "3holes.off"}
# pemb compiles the largest programs (~35K HLO lines, 40-110 s per mesh on a loaded 2-core box):
# its quick set keeps the mesh with borders; closed genus-0 inputs reach every pemb operator in
# the quick set through test_every_structure_on_random_planar_triangulations[pemb] (CI time).
QUICK_MESHES_PEMB = {"grid.off"}


# cube.off, a closed genus-0 shared mesh, is quick again since stop 56 for every structure but
# pemb (about 40 s of worker time for the eight; stops 54-55 had moved it to the slow set when
# CI read 16.9-19.8 min on their AMD host, and the suite now compiles with XLA:CPU's elemental
# emitters: 11.9 min on that host kind). pemb meets closed genus-0 meshes in the random
# triangulations below (one of n = 4, 6, 300 per run).


def _protocol_params():
    out = []
    for structure in STRUCTURES:
        quick = QUICK_MESHES_PEMB if structure == "pemb" else QUICK_MESHES
        for name in CLOSED_GENUS0 + HOLED_GENUS0 + HIGHER_GENUS:
            slow = name not in quick or name in LARGE
            out.append(pytest.param(name, structure, marks=pytest.mark.slow) if slow
                       else pytest.param(name, structure))
    return out


@pytest.mark.parametrize("name,structure", _protocol_params())
def test_every_operator_on_every_dart(structure, name):
    m = prepared(name, structure)
    try:
        s = registry.build(structure, m)
    except errors.UnsupportedTopologyError as exc:
        if name in HIGHER_GENUS:
            assert "genus" in str(exc)
            pytest.skip(f"{structure} refuses genus > 0 ({exc})")
        raise
    rep = verify(s, m)
    assert rep.checked > 10 * m.num_faces
    assert rep.mismatches == 0, str(rep)


def _normals_params():
    # pemb on bunny.off compiles for ~30 s: slow (pemb keeps grid.off and 3holes.off here)
    return [pytest.param(n, s, marks=pytest.mark.slow) if (s, n) == ("pemb", "bunny.off") else (n, s)
            for n in ["bunny.off", "3holes.off", "grid.off"] for s in STRUCTURES]


@pytest.mark.parametrize("name,structure", _normals_params())
def test_degrees_and_normals_equal_halfedge(structure, name):
    m = prepared(name, structure)
    try:
        s = registry.build(structure, m)
    except errors.UnsupportedTopologyError:
        pytest.skip("structure refuses this mesh")
    # The CDS family closes holes itself (Sec. 4.5): the dummy vertex and fan are structure,
    # not surface, and its degrees and normals are the open mesh's (the dummy is a vertex in no
    # face of the reference: 0 and a zero normal). The corner table holds the closed mesh it
    # was given.
    holed = m.dummy_faces is not None and bool(m.dummy_faces.any())
    drops_fans = s.dummy_vertex_mask() is not None
    assert drops_fans == (holed and structure.startswith("cds"))
    own = ~m.dummy_faces if drops_fans else np.ones(m.num_faces, bool)
    he = HalfEdge.from_faces(m.faces[own], m.num_vertices)
    order = np.arange(m.num_vertices) if s.vertex_order is None else np.asarray(s.vertex_order)
    deg = np.asarray(vertex_degrees(s))
    np.testing.assert_array_equal(deg, np.asarray(vertex_degrees(he))[order])
    pos = m.vertices.astype(np.float32)
    want = np.asarray(vertex_normals(he, pos))[order]
    for method in ("scatter", "gather"):
        got = np.asarray(vertex_normals(s, pos[order], method=method))
        np.testing.assert_allclose(got, want, atol=2e-5)


@pytest.mark.parametrize("structure", STRUCTURES)
def test_refusals_are_typed(structure):
    with pytest.raises(errors.MeshError):
        registry.build(structure, load_shared("cow.off"))


# the paper vocabularies' own corner operators, where a structure has them
PAPER_OPS = ("v", "n", "p", "o", "s", "l", "r", "t", "tc", "vc", "corner_index", "corner_dart")


@pytest.mark.parametrize("structure", STRUCTURES)
def test_is_border_and_corner_operators_check_their_ids_by_name(structure):
    """``is_border``, ``corner_vertex`` / ``corner_next`` / ``corner_prev`` and the paper ops
    (the corner table's and LR's ``v n p o s``, CDS ``corner_index``) refuse floats, bools and
    strings with an InvalidIndexError naming themselves: before, ``is_border`` was refused as
    ``face``, the corner ops as ``origin`` / ``next`` / ``prev``, and ``v n p o s`` cast 1.5
    and ``'1'`` to corner 1 (a silently wrong answer) or raised JAX's TypeError / IndexError."""
    from conftest import octahedron

    s = registry.build(structure, octahedron())
    ops = ("is_border", "corner_vertex", "corner_next", "corner_prev") + tuple(
        op for op in PAPER_OPS if hasattr(s, op))
    for op in ops:
        for bad in (1.5, True, "1", ["a"], np.array([1.0, 2.0]), np.array([True, False])):
            with pytest.raises(errors.InvalidIndexError, match=f"^{op}: ids"):
                getattr(s, op)(bad)
    if structure == "pemb":  # every pemb program takes seconds to compile: refusals only
        return
    d = s.all_darts()[:4]
    for op in ops:
        want = np.asarray(getattr(s, op)(d.astype(np.int32)))
        for ids in (list(map(int, d)), tuple(map(int, d)), d.astype(">i8"), d.astype(np.uint8)):
            np.testing.assert_array_equal(np.asarray(getattr(s, op)(ids)), want, err_msg=op)
        assert np.asarray(getattr(s, op)(int(d[1]))).shape == ()


@pytest.mark.parametrize("cls_name", ["HalfEdge", "CornerTable", "PEMB"])
def test_builders_take_check_as_a_bool(cls_name):
    """``from_mesh(check=...)`` names a non-bool (``check='no'`` was truthy: it validated;
    ``check=0`` silently skipped the validation); LR's flags: tests/structures/test_lr.py."""
    from conftest import octahedron
    from jaxcds.structures.corner_table import CornerTable
    from jaxcds.structures.pemb import PEMB

    cls = {"HalfEdge": HalfEdge, "CornerTable": CornerTable, "PEMB": PEMB}[cls_name]
    for bad in ("no", 0, 1, None, [True]):
        with pytest.raises(errors.ArgumentError, match=f"{cls_name}.from_mesh: check must be True or False"):
            cls.from_mesh(octahedron(), check=bad)
    assert cls.from_mesh(octahedron(), check=np.False_).num_faces == 8


# ---------------------------------------------------------------- random triangulations
from hypothesis import HealthCheck, given, settings, strategies as st  # noqa: E402


# Sizes come from a few buckets: a structure's array shapes depend on n (and, for LR, on the
# ring), and every new shape recompiles every operator; seeds are free. One example per
# structure in the quick set (five took 21-62 s per structure, three 21-37 s, two 17-31 s; CI
# read 27.5 min on 2026-12-01 with two); the slow test below draws 25 of any size for every
# structure.
# pemb is slow here: its verify program takes 60-75 s to compile per shape on the CI box, and
# the quick set checks it on a random Delaunay triangulation against walk oracles
# (tests/structures/test_pemb.py) and dart by dart on the small shared meshes.
@pytest.mark.parametrize("structure", slow_params(STRUCTURES, {"pemb"}))
@settings(max_examples=1, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.sampled_from([4, 6, 300]), seed=st.integers(0, 2**31 - 1))
def test_every_structure_on_random_planar_triangulations(structure, n, seed):
    from jaxcds.generators import random_planar_triangulation

    if structure == "pemb":
        n = 30  # one shape for pemb (its compilation per shape: see above)
    m = random_planar_triangulation(n, seed=seed)
    s = registry.build(structure, m)
    rep = verify(s, m)
    assert rep.mismatches == 0, f"n={n} seed={seed}: {rep}"


# Every example compiles every structure's verify program anew (new shapes, and a CDS's roots
# are static): about 50 s per example on 2 cores (2 in 112 s), 25 in about 20 minutes. On
# 2026-12-03 those 25 crashed the process (segmentation fault in XLA) twice at example 12: the
# compiled programs had filled the kernel's memory-mapping limit (vm.max_map_count, 64,517 of
# 65,530 held). jaxcds.build now clears JAX's caches near it (jaxcds/_mappings.py), which this
# test exercises. JAXCDS_ANY_SIZE_EXAMPLES draws another number.
ANY_SIZE_EXAMPLES = int(os.environ.get("JAXCDS_ANY_SIZE_EXAMPLES", "25"))


@pytest.mark.slow
@settings(max_examples=ANY_SIZE_EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(4, 400), seed=st.integers(0, 2**31 - 1))
def test_every_structure_on_random_planar_triangulations_any_size(n, seed):
    from jaxcds.generators import random_planar_triangulation

    m = random_planar_triangulation(n, seed=seed)
    for structure in STRUCTURES:
        rep = verify(registry.build(structure, m), m)
        assert rep.mismatches == 0, f"{structure} n={n} seed={seed}: {rep}"


@pytest.mark.slow
def test_every_structure_on_a_5000_vertex_random_triangulation():
    from jaxcds.generators import random_planar_triangulation

    m = random_planar_triangulation(5000, seed=7)
    for structure in STRUCTURES:
        rep = verify(registry.build(structure, m), m)
        assert rep.mismatches == 0, str(rep)


@pytest.mark.parametrize("structure", slow_params(STRUCTURES, {"pemb"}))  # pemb: 23 s of compilation
def test_ids_that_are_not_darts_terminate(structure):
    """Every id of the id space (holes included), negative and past-the-end ids: the operators
    answer (no hang in the O(d) walks) and agree with the valid darts where the id is one."""
    import jax
    import jax.numpy as jnp

    m = prepared("cube.off", structure)
    s = registry.build(structure, m)
    ids = jnp.arange(-3, s.num_darts + 3, dtype=jnp.int32)
    ops = jax.jit(lambda s, e: (s.dart_valid(e), s.origin(e), s.target(e), s.next(e), s.twin(e)))
    valid, *res = (np.asarray(x) for x in ops(s, ids))
    d = np.asarray(s.all_darts())
    assert set(np.asarray(ids)[valid].tolist()) == set(d.tolist())
    want = [np.asarray(x) for x in ops(s, jnp.asarray(d))[1:]]
    pos = np.searchsorted(np.asarray(ids), d)
    for got, w in zip(res, want):
        np.testing.assert_array_equal(got[pos], w)


@pytest.mark.parametrize("structure", slow_params(
    STRUCTURES, set(STRUCTURES) - {"halfedge", "corner_table", "pemb", "cds6n"}))
def test_dart_faces_is_face_of_every_dart(structure):
    """The whole-mesh ``dart_faces`` (scatters by default, arithmetic where ``face`` is, the
    CDS's from its Front/Back tables) equals the per-query ``face`` on every dart, border darts
    included (``num_faces``), and is ``num_faces`` on the unused ids."""
    import jax
    import jax.numpy as jnp

    from jaxcds.structures.base import per_query_routes

    m = prepared("grid.off" if structure in BORDER_AWARE else "cube.off", structure)
    s = registry.build(structure, m)
    d = np.asarray(s.all_darts())

    def both(s, e):
        with per_query_routes():  # a batch of every dart would read the CDS's face table
            return s.dart_faces(), s.face(e)
    got, want = (np.asarray(x) for x in jax.jit(both)(s, jnp.asarray(d)))
    assert got.shape == (s.num_darts,)
    np.testing.assert_array_equal(got[d], want)
    unused = np.setdiff1d(np.arange(s.num_darts), d)
    assert (got[unused] == s.num_faces).all()
    assert (structure not in BORDER_AWARE) or (want == s.num_faces).any()  # borders were met


@pytest.mark.parametrize("structure", slow_params(["cds6n", "cds4n", "lr"], {"cds4n", "lr"}))  # 14-32 s each
def test_verify_takes_the_open_or_the_user_closed_mesh(structure):
    """verify(s, mesh) with the mesh the user gave the builder, open or closed by the user: a
    CDS keeps dummies (the open mesh is closed again the same way), LR drops flagged ones (the
    closed mesh is opened again); a mesh of another size is an ArgumentError naming both."""
    from jaxcds.generators import icosphere
    from jaxcds.mesh import load_mesh

    ico = icosphere(1)
    keep = np.ones(ico.num_faces, bool)
    keep[[0, 30]] = False
    holed = load_mesh(ico.vertices, ico.faces[keep])
    for m in (holed, close_boundaries(holed)):
        rep = verify(registry.build(structure, m), m)
        assert rep.checked > 10 * holed.num_faces and rep.mismatches == 0, str(rep)
    with pytest.raises(errors.ArgumentError, match="vertices, the mesh 12"):
        verify(registry.build(structure, holed), icosphere(0))


@pytest.mark.parametrize("name", ["nope", ["cds5n"], None])
def test_build_names_an_unknown_structure_as_an_argument_error(name):
    """registry.build raised a bare JaxcdsError for an unknown name (errors.py: an unknown name
    is an ArgumentError, as batch.pack raises) and TypeError 'unhashable type' for a list."""
    from conftest import octahedron

    with pytest.raises(errors.ArgumentError, match=r"unknown structure .*; available: halfedge"):
        registry.build(name, octahedron())
