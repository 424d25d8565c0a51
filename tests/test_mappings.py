"""jaxcds._mappings: JAX's caches cleared before the kernel's memory-mapping limit crashes XLA."""

from __future__ import annotations

import warnings

import jax
import jax.numpy as jnp
import pytest

from jaxcds import _mappings, errors
from jaxcds.structures import registry
from jaxcds.structures.cds import CDS4n, CDS6n
from jaxcds.structures.corner_table import CornerTable
from jaxcds.structures.halfedge import HalfEdge
from jaxcds.structures.lr import LR, LRBits
from jaxcds.structures.pemb import PEMB


def _compiled_once():
    f = jax.jit(lambda x: x + 1)
    f(jnp.ones(3)).block_until_ready()
    assert f._cache_size() == 1
    return f


@pytest.fixture(autouse=True)
def _every_call_checks(monkeypatch):
    monkeypatch.setattr(_mappings, "INTERVAL_S", 0.0)


def test_near_the_limit_caches_are_cleared_with_a_warning(monkeypatch):
    f = _compiled_once()
    monkeypatch.setattr(_mappings, "_max_map_count", lambda: 1000)
    monkeypatch.setattr(_mappings, "_map_count", lambda: 900)
    with pytest.warns(errors.ResourceLimitWarning, match=r"900 memory mappings, 90% .*max_map_count = 1000"):
        assert _mappings.relieve()
    assert f._cache_size() == 0  # the executable is gone (its mappings with it)


def test_below_the_limit_or_off_linux_nothing_is_cleared(monkeypatch):
    f = _compiled_once()
    monkeypatch.setattr(_mappings, "_max_map_count", lambda: 1000)
    monkeypatch.setattr(_mappings, "_map_count", lambda: 799)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert not _mappings.relieve()
        monkeypatch.setattr(_mappings, "_max_map_count", lambda: None)  # no /proc
        assert not _mappings.relieve()
    assert f._cache_size() == 1


def test_checks_are_throttled(monkeypatch):
    monkeypatch.setattr(_mappings, "INTERVAL_S", 3600.0)
    monkeypatch.setattr(_mappings, "_max_map_count", lambda: 1000)
    monkeypatch.setattr(_mappings, "_map_count", lambda: 900)
    monkeypatch.setattr(_mappings, "_last", [float("-inf")])
    with pytest.warns(errors.ResourceLimitWarning):
        assert _mappings.relieve()
    assert not _mappings.relieve()  # within the interval: not read again


def test_the_real_counts_are_read_on_linux():
    limit, count = _mappings._max_map_count(), _mappings._map_count()
    if limit is None:
        pytest.skip("no /proc/sys/vm/max_map_count here")
    assert 0 < count < limit


BUILDERS = {
    "registry.build": lambda m: registry.build("cds5n-o1", m),
    "HalfEdge.from_mesh": lambda m: HalfEdge.from_mesh(m),
    "CornerTable.from_mesh": lambda m: CornerTable.from_mesh(m),
    "CDS6n.from_mesh": lambda m: CDS6n.from_mesh(m),
    "CDS4n.from_mesh": lambda m: CDS4n.from_mesh(m),
    "LR.from_mesh": lambda m: LR.from_mesh(m),
    "LRBits.from_mesh": lambda m: LRBits.from_mesh(m),
    "PEMB.from_mesh": lambda m: PEMB.from_mesh(m),
    # the README's Polylla recipe builds with from_faces (and so does polylla.run), and a folder
    # of .cds files is decoded straight into CDS structures: neither relieved before (sweep 49)
    "HalfEdge.from_faces": lambda m: HalfEdge.from_faces(m.faces, len(m.vertices)),
    "CornerTable.from_faces": lambda m: CornerTable.from_faces(m.faces, len(m.vertices)),
    "PEMB.from_faces": lambda m: PEMB.from_faces(m.faces, len(m.vertices)),
    "codec.decode": lambda m: _decode_cds5n(m),
}


def _decode_cds5n(m):
    from jaxcds.codec import decode, encode_mesh

    words = encode_mesh(m).words
    _mappings_calls.clear()  # only the decoding into a structure counts
    return decode(words, structure="cds5n")


#: relieve's calls in the test below (the decoding builder clears what encoding added)
_mappings_calls: list = []


@pytest.mark.parametrize("builder", list(BUILDERS))
def test_every_builder_relieves_before_building(monkeypatch, builder):
    """The registry's and each class's own builder (a loop may call either)."""
    calls = _mappings_calls
    calls.clear()
    monkeypatch.setattr(_mappings, "relieve", lambda: calls.append(1) or False)
    import trimesh

    BUILDERS[builder](trimesh.creation.icosahedron())
    assert calls, f"{builder} built without relieving"  # LR also through CornerTable.from_faces
