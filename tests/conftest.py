"""Shared fixtures: the real meshes of ``../shared/meshes`` and their expected topology."""

from __future__ import annotations

import os
import pathlib

# Tests check answers, not speed: XLA's LLVM back end runs at -O0 here, which cuts the suite's
# compilation (most of its time) by about a third (lr-bits verify on grid.off: 30.6 -> 20.8 s;
# 2026-12-01). Set before JAX creates its CPU client (it reads XLA_FLAGS once); the subprocess
# tests (sharding, notebooks) inherit it. Benchmarks never import this file. A level the caller
# gave in XLA_FLAGS is kept.
if "xla_backend_optimization_level" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " --xla_backend_optimization_level=0").strip()
# XLA:CPU's older elemental emitters instead of its fusion emitters, for the same reason: 18%
# less time to compile four structures' verify programs (lr-bits, pemb, cds5n, lr on grid.off,
# 3 runs in turn on stop 56's AMD host: 57.8 -> 47.5 s), 26% fewer memory mappings held per
# program (5,850 -> 4,330; the workers no longer reach jaxcds._mappings' cache clear), and the
# quick set's tests took 979 s of worker time against 1,852 s (16.5 -> 8.5 min on 2 workers).
# Both code generators compute the same operations (the suite passes under either).
if "xla_cpu_use_fusion_emitters" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (os.environ["XLA_FLAGS"] + " --xla_cpu_use_fusion_emitters=false").strip()

import jax  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
SHARED = pathlib.Path(os.environ.get("JAXCDS_SHARED", ROOT.parent / "shared"))
MESHES = SHARED / "meshes"

# One persistent XLA compilation cache for the whole run, shared by the xdist workers: the same
# (structure, mesh) pair is compiled by several test files (protocol, paper, codec), and most of
# the suite's time is XLA compilation. Gitignored; a fresh clone starts empty.
jax.config.update("jax_compilation_cache_dir",
                  os.environ.get("JAXCDS_JAX_CACHE", str(ROOT / ".jax_cache")))
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.3)
jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)

# From ../shared/meshes/README.md (counts after welding): V, F, boundary edges, chi, bodies.
# "nm" marks the meshes that must be refused (non-manifold).
MESH_TABLE = {
    "cube.off": (8, 12, 0, 2, 1),
    "decimated-knight.off": (502, 1000, 0, 2, 1),
    "bunny.off": (3485, 6966, 0, 2, 1),
    "spot.obj": (2930, 5856, 0, 2, 1),
    "cheburashka.obj": (6669, 13334, 0, 2, 1),
    "elephant.obj": (6034, 12064, 0, 2, 1),
    "fandisk.off": (7229, 14454, 0, 2, 1),
    "bumpy-cube.obj": (19970, 39936, 0, 2, 1),
    "armadillo.obj": (43243, 86482, 0, 2, 1),
    "rocker-arm.obj": (10044, 20088, 0, 0, 1),
    "3holes.off": (3596, 7200, 0, -4, 1),
    "stanford-bunny.obj": (34834, 69451, 223, -3, 1),
    "face.obj": (25905, 51712, 96, 1, 1),
    "camelhead.off": (11381, 22704, 56, 1, 1),
    "grid.off": (145, 256, 32, 1, 1),
    "2triangles.off": (4, 2, 4, 1, 1),
    "beetle.off": (19885, 38656, 1136, -11, 1),
    "teapot.obj": (3241, 6320, 160, 1, 3),
    "cow.off": (2761, 5520, 0, 2, 1),
    "suzanne.obj": (505, 968, 42, 1, 1),
}
# beetle.off and teapot.obj have manifold edges but "bow-tie" vertices (README counts only edges)
DEFECTIVE = {"cow.off", "suzanne.obj", "teapot.obj", "beetle.off"}
VALID = [m for m in MESH_TABLE if m not in DEFECTIVE]
CLOSED_GENUS0 = ["cube.off", "decimated-knight.off", "bunny.off", "spot.obj", "cheburashka.obj",
                 "elephant.obj", "fandisk.off", "bumpy-cube.obj", "armadillo.obj"]
HOLED_GENUS0 = ["stanford-bunny.obj", "face.obj", "camelhead.off", "grid.off", "2triangles.off"]
HIGHER_GENUS = ["rocker-arm.obj", "3holes.off"]
# the Schnyder-wood structures (issue 3): genus-0 meshes only, holes closed by the builders
CDS_FAMILY = ("cds6n", "cds5n", "cds4n", "cds5n-o1")
# structures that keep borders as they are; the others close holes (their builder, or close_boundaries)
BORDER_AWARE = {"halfedge", "pemb"}
LARGE = {"armadillo.obj", "stanford-bunny.obj", "face.obj", "bumpy-cube.obj", "beetle.obj",
         "beetle.off"}


def mesh_path(name: str) -> str:
    p = MESHES / name
    if not p.exists():
        pytest.skip(f"shared mesh {name} not found under {MESHES}")
    return str(p)


def slow_params(values, slow):
    """Parametrise over ``values``, those in ``slow`` marked slow (the quick set skips them)."""
    return [pytest.param(v, marks=pytest.mark.slow) if v in slow else v for v in values]


def mesh_params(names):
    """Parametrise over shared meshes, the large ones marked slow."""
    return slow_params(names, LARGE)


_cache: dict = {}


def as_accepted(mesh, structure: str):
    """``mesh`` as ``structure`` takes it: as it is for the border-aware structures and those
    whose builder closes holes itself, else closed by ``close_boundaries`` (the corner table)."""
    from jaxcds.mesh import close_boundaries
    from jaxcds.structures import registry

    if structure in BORDER_AWARE or registry.STRUCTURES[structure].closes_boundaries:
        return mesh
    return close_boundaries(mesh)


def load_shared(name: str):
    """The shared mesh ``name`` as a TriMesh (cached per test process)."""
    from jaxcds.mesh import load_mesh

    if name not in _cache:
        _cache[name] = load_mesh(mesh_path(name))
    return _cache[name]


@pytest.fixture
def x64():
    """Run a test with float64 enabled (gradients vs finite differences)."""
    prev = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", True)
    yield
    jax.config.update("jax_enable_x64", prev)


def octahedron():
    v = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    f = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4],
                  [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]], np.int32)
    return v, f


_PROBE_PRELUDE = """
import json
from jaxcds import errors
out = {}

def record(key, build, *args):
    # out[key]: ["built", ""] if build(*args) returns, else the typed error's class and message
    try:
        build(*args)
        out[key] = ["built", ""]
    except errors.JaxcdsError as exc:
        out[key] = [type(exc).__name__, str(exc)]
"""


def crash_probe(code: str, timeout: float = 300) -> dict:
    """Run ``code`` in a child interpreter (a numba kernel reading out of bounds kills the
    process, not the test run) and return the ``out`` dict it fills with ``record(key, build,
    *args)`` (defined for it, with ``json`` and ``errors``); a non-zero exit (a negative one is
    a signal: a crash) fails the test with the child's stderr."""
    import json
    import subprocess
    import sys

    env = dict(os.environ, PYTHONPATH=str(ROOT))
    child = _PROBE_PRELUDE + code + "\nprint(json.dumps(out))\n"
    r = subprocess.run([sys.executable, "-c", child], env=env, capture_output=True, text=True,
                       timeout=timeout)
    assert r.returncode == 0, f"child exited {r.returncode}: {r.stderr[-3000:]}"
    return json.loads(r.stdout.strip().splitlines()[-1])


def crash_probe_lines(code: str, timeout: float = 300) -> list:
    """:func:`crash_probe` for a child that prints its findings: runs ``code`` as it is (no
    prelude) and returns its stdout lines; a non-zero exit fails the test with its stderr."""
    import subprocess
    import sys

    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                       timeout=timeout)
    assert r.returncode == 0, f"child exited {r.returncode}: {r.stderr[-3000:]}"
    return r.stdout.splitlines()


# ---------------------------------------------------------------- CPU cost per test
# `JAXCDS_CPU_TIMES=/tmp/cpu.txt make test` appends "<cpu seconds> <test id>" per test: CPU time
# (XLA compiles on several threads) is the budget that matters on a shared 2-core CI machine,
# where wall-clock durations mostly measure the neighbours.
_CPU_LOG = os.environ.get("JAXCDS_CPU_TIMES")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):  # setup (fixtures) + call + teardown
    import time

    t0 = time.process_time()
    yield
    if _CPU_LOG:
        with open(_CPU_LOG, "a") as fh:
            fh.write(f"{time.process_time() - t0:.2f} {item.nodeid}\n")


@pytest.fixture(autouse=True)
def _drop_compiled_programs_after_slow_tests(request):
    """Each mesh of the slow set compiles its own programs (shapes differ), and JAX keeps every
    compiled executable: the slow pemb protocol run grew by ~1 GB per mesh (9.3 GB after 8 tests)
    and would not fit a 24 GiB box. Slow tests drop them when done; the quick set keeps its cache
    (its tests share shapes, and recompiling would cost CI minutes)."""
    yield
    if request.node.get_closest_marker("slow") is not None:
        jax.clear_caches()
