"""The one exception hierarchy of jaxcds.

Every error that jaxcds raises on bad input derives from :class:`JaxcdsError`, and its message
names the problem *and where* it is (which face, edge, vertex, byte or bit offset), so a user can
fix the input without reading a traceback. The CLI prints ``str(err)`` and exits non-zero.

Hierarchy::

    JaxcdsError
    ├── MeshError                     input meshes (loading and validation)
    │   ├── UnreadableMeshError       file missing, unknown format, parse failure
    │   ├── EmptyMeshError            no vertices or no faces
    │   ├── InvalidIndexError         face index negative or >= number of vertices
    │   ├── UnreferencedVertexError   a vertex in no face (load_mesh drops them)
    │   ├── NonFiniteCoordinateError  NaN / inf in positions
    │   ├── DegenerateFaceError       a face repeats a vertex
    │   ├── DuplicateFaceError        two faces on the same vertex set
    │   ├── NonManifoldEdgeError      an edge shared by more than two faces
    │   ├── NonManifoldVertexError    a vertex whose faces form more than one fan
    │   ├── InconsistentOrientationError  two faces traverse a shared edge the same way
    │   └── UnsupportedTopologyError  valid mesh, but not one this structure accepts
    │                                 (genus > 0 for Schnyder woods, boundaries, components...)
    ├── StructureError                a structure failed its own invariant check
    ├── CodecError                    compressed streams and files (.cds)
    │   ├── FormatError               bad magic, version, checksum, truncation
    │   └── EncodingError             a word that is not a valid encoding
    ├── PolyllaError                  Polylla inputs
    ├── OutputError                   an output file cannot be written (nothing is left behind)
    └── ArgumentError                 a call's arguments: an unknown operator, id kind or
                                      method, an array of the wrong length

Two warnings (``UserWarning``s, not errors: the work goes on) say where jaxcds acted on its
own: ``ResourceLimitWarning`` (JAX's caches cleared near the memory-mapping limit) and
``PolyllaWarning`` (a point set's exact duplicates left in no triangle).
"""

from __future__ import annotations

__all__ = [
    "JaxcdsError",
    "MeshError",
    "UnreadableMeshError",
    "EmptyMeshError",
    "InvalidIndexError",
    "UnreferencedVertexError",
    "NonFiniteCoordinateError",
    "DegenerateFaceError",
    "DuplicateFaceError",
    "NonManifoldEdgeError",
    "NonManifoldVertexError",
    "InconsistentOrientationError",
    "UnsupportedTopologyError",
    "StructureError",
    "CodecError",
    "FormatError",
    "EncodingError",
    "PolyllaError",
    "ArgumentError",
    "OutputError",
    "ResourceLimitWarning",
    "PolyllaWarning",
]


class JaxcdsError(Exception):
    """Root of every error jaxcds raises on bad input."""


class MeshError(JaxcdsError, ValueError):
    """An input mesh is unreadable or defective."""


class UnreadableMeshError(MeshError):
    """The file does not exist, has an unknown format, or cannot be parsed."""


class EmptyMeshError(MeshError):
    """The mesh has no vertices or no faces."""


class InvalidIndexError(MeshError):
    """A face refers to a vertex index that is negative or out of range."""


class UnreferencedVertexError(MeshError):
    """A vertex that no face uses (:func:`jaxcds.mesh.load_mesh` drops them; a hand-made
    ``TriMesh`` may still have them)."""


class NonFiniteCoordinateError(MeshError):
    """A vertex coordinate is NaN or infinite."""


class DegenerateFaceError(MeshError):
    """A face uses the same vertex twice."""


class DuplicateFaceError(MeshError):
    """Two faces have the same set of vertices."""


class NonManifoldEdgeError(MeshError):
    """An edge is shared by more than two faces."""


class NonManifoldVertexError(MeshError):
    """The faces around a vertex form more than one fan (a 'bow tie')."""


class InconsistentOrientationError(MeshError):
    """Two faces traverse a shared edge in the same direction (non-orientable or flipped)."""


class UnsupportedTopologyError(MeshError):
    """A valid mesh that this particular structure does not accept (e.g. genus > 0)."""


class StructureError(JaxcdsError):
    """A built structure violates one of its invariants (a bug or corrupted arrays)."""


class CodecError(JaxcdsError, ValueError):
    """A compressed stream or ``.cds`` file is invalid."""


class FormatError(CodecError):
    """Bad magic, version, checksum, size or truncation in a ``.cds`` file."""


class EncodingError(CodecError):
    """A connectivity word that is not a valid encoding (unbalanced, wrong counts...)."""


class PolyllaError(JaxcdsError, ValueError):
    """A Polylla input that cannot be meshed."""


class ArgumentError(JaxcdsError, ValueError):
    """A call's arguments are not ones the function takes: an unknown operator, id kind or
    method name, or a per-vertex / per-face array whose length is not the count it must be."""


class OutputError(JaxcdsError, OSError):
    """An output file cannot be written: its folder is missing, a folder is in its place, no
    permission, a full disk. Writes go to a temporary file renamed at the end, so nothing half
    written is left behind."""


class ResourceLimitWarning(UserWarning):
    """A process resource ran near its limit and jaxcds acted (``jaxcds._mappings.relieve``:
    JAX's caches cleared before the kernel's memory-mapping limit crashed XLA)."""


class PolyllaWarning(UserWarning):
    """Polylla's input was taken with a change the user should know of: a point set's exact
    duplicates are left in no triangle (as Triangle leaves them), the first copy is used."""
