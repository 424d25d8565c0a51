"""Keep a long-running process under the kernel's limit on memory mappings.

Every XLA:CPU executable keeps its JIT-compiled code in mappings of its own, and JAX's caches
keep every executable alive. A CDS compiles its programs again for each mesh (its roots are
static metadata: the exterior is patched after one lean pass, see ``_CDS._target_start``), so
a loop that builds and uses a CDS per mesh adds about 70 mappings per mesh (``vertex_normals``
on cds6n, measured 2026-12-03; a half-edge about 36 per new vertex count). Past
``/proc/sys/vm/max_map_count`` (65,530 by default: about 850 meshes) LLVM cannot map more code
and jaxlib 0.10.2 dies of a segmentation fault instead of raising. :func:`relieve` is called
before each build (``jaxcds.build`` and every structure's own builder: ``build_cds``,
``build_lr``, ``HalfEdge`` / ``CornerTable`` / ``PEMB.from_faces``, which their ``from_mesh``
goes through, and the codec's ``build_cds``): near the limit it clears
JAX's caches (the executables are compiled again when next used) and warns once per clearing. Linux only (elsewhere a no-op).
"""

from __future__ import annotations

import time
import warnings

from jaxcds import errors

FRACTION = 0.8  # of max_map_count: one mesh's programs take well under the remaining 20%
INTERVAL_S = 0.25  # checks at most this often: reading /proc/self/maps took 0.5 ms at 1,000
# mappings, against 0.7 ms for a whole 642-vertex half-edge build; programs pile up only by
# compiling, which takes longer than this per mesh
_last = [float("-inf")]


def _max_map_count() -> int | None:
    try:
        with open("/proc/sys/vm/max_map_count", "rb") as fh:
            return int(fh.read())
    except (OSError, ValueError):
        return None


def _map_count() -> int | None:
    try:
        with open("/proc/self/maps", "rb") as fh:
            return sum(1 for _ in fh)  # about 10 ms at 60,000 mappings; a build costs more
    except OSError:
        return None


def relieve() -> bool:
    """Clear JAX's caches if this process holds more than :data:`FRACTION` of the kernel's
    memory-mapping limit; True if it did. Checks at most every :data:`INTERVAL_S` seconds."""
    now = time.monotonic()
    if now - _last[0] < INTERVAL_S:
        return False
    _last[0] = now
    limit = _max_map_count()
    count = _map_count() if limit else None
    if count is None or count < FRACTION * limit:
        return False
    import jax

    jax.clear_caches()
    warnings.warn(
        f"this process holds {count} memory mappings, {count / limit:.0%} of the kernel's limit "
        f"(vm.max_map_count = {limit}), most of them compiled XLA programs (a CDS compiles per "
        "mesh): jaxcds cleared JAX's caches, so programs compile again when next used. For many "
        "meshes, pack them (jaxcds.batch.pack: one compilation) or raise vm.max_map_count",
        errors.ResourceLimitWarning, stacklevel=3)
    return True
