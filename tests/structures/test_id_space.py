"""int32 id spaces: sizes whose dart ids (or their 'absent' sentinel) would wrap are refused by
name before anything is built (the meshes themselves would not fit this machine, so the guards
are called with the sizes alone)."""

from __future__ import annotations

import types

import jax.numpy as jnp
import numpy as np

import pytest

from jaxcds import errors
from jaxcds.structures import cds
from jaxcds.structures.base import MAX_DARTS, check_id_space


def test_check_id_space_boundary():
    check_id_space("x", MAX_DARTS)  # ids 0 .. 2^31 - 2 and the sentinel 2^31 - 1
    with pytest.raises(errors.UnsupportedTopologyError, match=r"x: 2,147,483,648 dart ids do not fit int32"):
        check_id_space("x", MAX_DARTS + 1)


def test_cds_refuses_vertices_whose_6n_dart_ids_wrap():
    cds._check_size(357_913_941)  # 6n = 2,147,483,646: fits, sentinel included
    with pytest.raises(errors.UnsupportedTopologyError, match="357,913,942.*6n"):
        cds._check_size(357_913_942)
    with pytest.raises(errors.UnsupportedTopologyError, match="2\\^30"):
        cds._check_size(1 << 30)
    # the table builder checks before it allocates anything
    with pytest.raises(errors.UnsupportedTopologyError, match="dart ids"):
        cds._build_rows(types.SimpleNamespace(num_vertices=400_000_000), 0)


@pytest.mark.parametrize("structure", ["halfedge", "lr", "cds4n"])
def test_check_ids_names_the_first_bad_id(structure):
    import numpy as np

    from jaxcds.generators import random_planar_triangulation
    from jaxcds.structures import registry

    s = registry.build(structure, random_planar_triangulation(60, seed=3))
    darts = s.all_darts()
    np.testing.assert_array_equal(s.check_ids("dart", darts), darts)
    assert s.check_ids("vertex", [0, s.num_vertices - 1]).dtype == np.int32
    with pytest.raises(errors.InvalidIndexError, match=rf"dart id -1 at position \(1,\) is outside \[0, {s.num_darts}\)"):
        s.check_ids("dart", [darts[0], -1, 5])
    with pytest.raises(errors.InvalidIndexError, match=f"face id {s.num_faces} is outside"):
        s.check_ids("face", s.num_faces)
    holes = np.setdiff1d(np.arange(s.num_darts), darts)
    assert (holes.size > 0) == (structure != "halfedge")
    if holes.size:  # LR slots that are no corner, a CDS root's missing edges
        with pytest.raises(errors.InvalidIndexError, match=f"dart id {holes[0]} .*not a dart"):
            s.check_ids("dart", np.stack([darts[:2], [darts[2], holes[0]]]))
    with pytest.raises(errors.InvalidIndexError, match="integers"):
        s.check_ids("vertex", [0.5])
    with pytest.raises(errors.ArgumentError, match="unknown id kind"):
        s.check_ids("edge", [0])


def test_check_ids_ragged_and_huge_unsigned():
    import numpy as np

    from jaxcds.generators import random_planar_triangulation
    from jaxcds.structures import registry

    s = registry.build("cds4n", random_planar_triangulation(30, seed=1))
    with pytest.raises(errors.InvalidIndexError, match="not an array"):
        s.check_ids("vertex", [1, [2]])
    with pytest.raises(errors.InvalidIndexError, match=r"vertex id 9223372036854775808 at position \(1,\)"):
        s.check_ids("vertex", np.array([3, 2**63], np.uint64))
    assert s.check_ids("vertex", np.array([3, 4], np.uint64)).tolist() == [3, 4]


@pytest.mark.parametrize("kind", ["halfedge", "corner-table", "cds5n", "lr"])
def test_operators_read_ids_of_any_integer_kind_and_refuse_the_rest(kind):
    """Lists and tuples, int8 and uint64, big-endian, jax int16: the same answers as int32 ids
    (a corner table indexed its array with a list as a tuple, int8 overflowed in its offsets);
    floats, bools (a mask), strings and masked arrays: InvalidIndexError naming the operator."""
    from jaxcds.generators import icosphere
    from jaxcds.structures import registry

    s = registry.build(kind, icosphere(1))
    want = np.asarray(s.twin(np.arange(6, dtype=np.int32)))
    for ids in ([0, 1, 2, 3, 4, 5], tuple(range(6)), np.arange(6, dtype=np.int8),
                np.arange(6, dtype=np.uint64), np.arange(6, dtype=">i4"), jnp.arange(6, dtype=jnp.int16)):
        np.testing.assert_array_equal(np.asarray(s.twin(ids)), want)
    assert int(s.twin(3)) == want[3]
    for bad in (np.ones(6, bool), np.arange(6.0), jnp.arange(6.0), ["a"],
                np.ma.array([0, 1], mask=[0, 1])):
        with pytest.raises(errors.InvalidIndexError, match="twin: ids"):
            s.twin(bad)


@pytest.mark.parametrize("kind", ["halfedge", "cds5n-o1"])
def test_wide_ids_under_jit_with_x64_read_as_absent(x64, kind):
    """Under ``jit`` with x64 on, int64 / uint32 / uint64 ids reach the operators as tracers of
    their own dtype: they were cast to int32, so ``2**32 + 3`` wrapped onto dart 3 (valid; its
    twin answered) where the eager call reads it as absent. Clamped as the host route clamps."""
    import jax

    from jaxcds.generators import icosphere
    from jaxcds.structures import registry

    s = registry.build(kind, icosphere(1))
    valid = jax.jit(lambda d: s.dart_valid(d))
    d = int(np.asarray(s.all_darts())[3])  # a valid dart (the CDS id space has holes)
    for dtype, big in ((np.int64, 2**32 + d), (np.int64, -(2**32) + d), (np.uint64, 2**32 + d),
                       (np.uint32, 2**31 + d)):
        ids = np.array([d, big], dtype)
        assert jnp.asarray(ids).dtype == dtype  # x64 keeps the dtype
        assert np.asarray(valid(ids)).tolist() == [True, False], dtype
        assert np.asarray(s.dart_valid(ids)).tolist() == [True, False], dtype  # eager, as before
    # within int32 every kind still answers as int32 ids do
    want = np.asarray(s.twin(np.arange(6, dtype=np.int32)))
    np.testing.assert_array_equal(np.asarray(jax.jit(lambda d: s.twin(d))(np.arange(6, dtype=np.int64))), want)


@pytest.mark.parametrize("kind", ["halfedge", "corner-table", "cds5n-o1", "lr", "pemb"])
def test_dart_valid_checks_its_ids(kind):
    """dart_valid was left out of the checked operators: 3.5 was read as dart 3 (True). Ids past
    int32 read as absent (False), never wrapped onto a valid dart."""
    from jaxcds.generators import icosphere
    from jaxcds.structures import registry

    s = registry.build(kind, icosphere(1))
    assert np.asarray(s.dart_valid(s.all_darts())).all()
    assert not np.asarray(s.dart_valid(np.array([2**32 + 3, -(2**40), s.num_darts], np.int64))).any()
    np.testing.assert_array_equal(np.asarray(s.dart_valid([0, 1])), np.asarray(s.dart_valid(np.arange(2))))
    for bad in (np.array([3.5]), 3.0, np.ones(2, bool), "3"):
        with pytest.raises(errors.InvalidIndexError, match="dart_valid: ids"):
            s.dart_valid(bad)


def test_adjacent_and_one_ring_check_their_ids_and_read_big_endian():
    """adjacent and one_ring took ids straight into jit: 0.9 read as 0, and big-endian ids, after
    a call with native ones of the same shape, were read as native bytes (wrong answers)."""
    from jaxcds.algorithms import adjacent, one_ring
    from jaxcds.generators import icosphere
    from jaxcds.structures import registry

    s = registry.build("halfedge", icosphere(1))
    u = np.array([0, 1], np.int32)
    v = np.asarray(s.target(s.edge_of_vertex(u)))
    assert np.asarray(adjacent(s, u, v)).all()
    assert np.asarray(adjacent(s, u.astype(">i4"), v.astype(">i4"))).all()
    np.testing.assert_array_equal(np.asarray(one_ring(s, u.astype(">i4"), 8)[0]),
                                  np.asarray(one_ring(s, u, 8)[0]))
    with pytest.raises(errors.InvalidIndexError, match="adjacent: u"):
        adjacent(s, [0.9], [1])
    with pytest.raises(errors.InvalidIndexError, match="one_ring: vertices"):
        one_ring(s, np.array([1.9]), 6)


def test_half_precision_positions_are_summed_in_float32():
    from jaxcds.algorithms import vertex_normals
    from jaxcds.generators import icosphere
    from jaxcds.structures import registry

    mesh = icosphere(2)
    s = registry.build("halfedge", mesh)
    p = np.asarray(mesh.vertices * 1000, np.float32)
    got = np.asarray(vertex_normals(s, p.astype(np.float16)))  # all NaN before (cross products)
    np.testing.assert_allclose(got, np.asarray(vertex_normals(s, p.astype(np.float16).astype(np.float32))),
                               atol=1e-6)


@pytest.mark.parametrize("kind", [np.array([1, 2]), [0, 1], np.ma.array([1, 2], mask=[0, 1]), 7])
def test_check_ids_with_the_arguments_swapped_is_an_argument_error(kind):
    """``check_ids(ids, "dart")``: an array as the kind raised numpy's untyped 'truth value of an
    array is ambiguous' ValueError from the membership test."""
    from jaxcds.generators import icosphere
    from jaxcds.structures import registry

    s = registry.build("halfedge", icosphere(0))
    with pytest.raises(errors.ArgumentError, match=r"unknown id kind .*: 'dart', 'vertex' or 'face' "
                                                   r"\(check_ids\(kind, ids\): the kind comes first\)"):
        s.check_ids(kind, "dart")
