"""jaxcds: compact connectivity structures for triangle meshes, in JAX.

Structures are immutable pytrees of int32 arrays; navigation operators are branch-free,
batched and jittable; per-vertex reductions (degrees, normals) run on every structure and
normals are differentiable with respect to positions.
"""


def _numba_cache_fallback() -> None:
    """The kernels are ``@numba.njit(cache=True)``: numba raised ``RuntimeError: cannot cache
    function ...: no locator available`` on importing them (so ``import jaxcds`` and every
    ``jaxcds`` command failed with a traceback) when neither the package's ``__pycache__`` nor
    the user's cache folder (``~/.cache/numba``) can be written: an install owned by root run by
    a user without a writable home (a container's ``--user`` with ``HOME=/``). The kernels are
    then cached in a private temporary folder, removed at exit (compiled again by each process).
    A ``NUMBA_CACHE_DIR`` the user set is left to numba."""
    import numba
    from numba.core import caching

    if numba.config.CACHE_DIR:
        return
    try:
        caching.FunctionCache(_numba_cache_fallback)  # the locators numba tries for this package
    except Exception as exc:  # noqa: BLE001 - a numba whose internals moved: leave it be
        if not isinstance(exc, RuntimeError):
            return
        import atexit
        import shutil
        import tempfile

        numba.config.CACHE_DIR = tempfile.mkdtemp(prefix="jaxcds-numba-")
        atexit.register(shutil.rmtree, numba.config.CACHE_DIR, True)


_numba_cache_fallback()

from jaxcds import errors  # noqa: E402
from jaxcds.mesh import TriMesh, close_boundaries, load_mesh, topology, validate  # noqa: E402
from jaxcds.structures import CornerTable, HalfEdge, MeshStructure  # noqa: E402
from jaxcds.structures.registry import build  # noqa: E402
from jaxcds.algorithms import adjacent, one_ring, vertex_degrees, vertex_normals  # noqa: E402

__version__ = "0.1.0"

__all__ = ["errors", "TriMesh", "load_mesh", "validate", "topology", "close_boundaries",
           "MeshStructure", "HalfEdge", "CornerTable", "build", "adjacent", "one_ring",
           "vertex_degrees", "vertex_normals", "__version__"]
