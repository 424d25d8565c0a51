"""One registry of every structure: name -> builder(TriMesh) -> structure.

Tests, the CLI (``jaxcds build --structure NAME``) and the benchmarks iterate over it, so a new
structure joins every check and every table by registering here.
"""

from __future__ import annotations

import dataclasses
from typing import Callable, Dict

from jaxcds import errors
from jaxcds.mesh import load_mesh

__all__ = ["register", "build", "names", "STRUCTURES", "StructureInfo"]


@dataclasses.dataclass(frozen=True)
class StructureInfo:
    """A registered structure.

    Attributes:
      name: registry name (``cds6n``...).
      builder: ``TriMesh -> structure``; raises a typed error on meshes it refuses.
      closes_boundaries: the builder closes holes with dummy vertices itself before building.
      description: one line for ``--help`` and the README table.
    """

    name: str
    builder: Callable
    closes_boundaries: bool = False
    description: str = ""


STRUCTURES: Dict[str, StructureInfo] = {}


def register(name: str, builder: Callable, *, closes_boundaries: bool = False,
             description: str = "") -> Callable:
    """Register ``builder`` under ``name`` (re-registration replaces, for reloads)."""
    STRUCTURES[name] = StructureInfo(name, builder, closes_boundaries, description)
    return builder


def names() -> list[str]:
    """The registered structure names, in registration order."""
    _load_all()
    return list(STRUCTURES)


def build(name: str, mesh) -> object:
    """Build structure ``name`` from a mesh (path, arrays or :class:`TriMesh`).

    Raises:
      ArgumentError: ``name`` is not a registered name (a bare ``JaxcdsError`` before, and a
        list's ``TypeError: unhashable type``), listing the registered ones.
      MeshError: what :func:`~jaxcds.mesh.load_mesh` raises on ``mesh``, and the defect or
        topology the builder refuses (a subclass naming it)."""
    _load_all()
    if not isinstance(name, str) or name not in STRUCTURES:
        raise errors.ArgumentError(
            f"unknown structure {name!r}; available: {', '.join(STRUCTURES)}")
    # every builder calls _mappings.relieve() first: a loop over many meshes piles up programs
    return STRUCTURES[name].builder(load_mesh(mesh))


def _load_all() -> None:
    import jaxcds.structures  # noqa: F401  (registers every module)
