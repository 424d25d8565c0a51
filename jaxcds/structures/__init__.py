"""Connectivity structures. Importing this package registers every structure in
:mod:`jaxcds.structures.registry`."""

from jaxcds.structures.base import MeshStructure
from jaxcds.structures.corner_table import CornerTable
from jaxcds.structures.halfedge import HalfEdge
from jaxcds.structures import registry

registry.register("halfedge", HalfEdge.from_mesh,
                  description="array-based half-edge, reference (19n references)")
registry.register("corner-table", CornerTable.from_mesh,
                  description="Rossignac's corner table (13n references), closed meshes")

# Structures of later issues register themselves on import; a missing one is simply absent.
import importlib as _importlib

for _mod in ("cds", "lr", "pemb"):
    try:
        _importlib.import_module(f"jaxcds.structures.{_mod}")
    except ModuleNotFoundError as _exc:  # not written yet
        if _exc.name != f"jaxcds.structures.{_mod}":
            raise

__all__ = ["MeshStructure", "HalfEdge", "CornerTable", "registry"]
