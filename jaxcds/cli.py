"""The ``jaxcds`` command line (also ``python -m jaxcds``).

Errors of the :mod:`jaxcds.errors` hierarchy exit with status 2 and print their message, never a
traceback. ``--json`` prints exactly one JSON object on stdout, with snake_case keys that scripts
may rely on.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from importlib import resources
from typing import Optional, Sequence

from jaxcds import errors

__all__ = ["main", "default_mesh_path"]

EXIT_BAD_INPUT = 2


def default_mesh_path() -> str:
    """The closed bunny (3485 vertices) shipped inside the package for ``jaxcds demo``."""
    return str(resources.files("jaxcds") / "data" / "bunny.off")


def _print_json(obj) -> None:
    json.dump(obj, sys.stdout, indent=2, sort_keys=False, default=_json_default)
    sys.stdout.write("\n")


def _json_default(x):
    import numpy as np

    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")


def require_jax() -> None:
    """Start JAX's backend before the work of a command that computes with JAX (``build``,
    ``demo``, ``decode`` into a structure, ``polylla``). An unusable ``JAX_PLATFORMS`` (``cuda``
    on a machine without a GPU plugin, a misspelt platform) raised an ``AssertionError`` or a
    ``RuntimeError`` traceback from inside the first array operation."""
    import jax

    try:
        jax.devices()
    except (RuntimeError, AssertionError) as exc:
        why = str(exc).split("(set JAX_PLATFORMS")[0].strip().rstrip(".") or "no backend started"
        raise errors.JaxcdsError(
            f"JAX cannot start (JAX_PLATFORMS={os.environ.get('JAX_PLATFORMS', '')!r}): {why}; "
            "unset JAX_PLATFORMS or name a platform this machine has (cpu, ...)") from None


# ------------------------------------------------------------------------------ info
def cmd_info(args) -> int:
    from jaxcds.mesh import load_mesh, topology

    if args.mesh.lower().endswith(".cds"):
        codec = _optional("jaxcds.codec", "the .cds codec")
        report = codec.cds_info(args.mesh)
    else:
        report = topology(load_mesh(args.mesh, weld=args.weld))
    if args.json:
        _print_json(report)
    else:
        for k, v in report.items():
            if k == "defects":
                print(f"{k:>30}: {len(v)}")
                for d in v:
                    print(f"{'':>32}- {d}")
            else:
                print(f"{k:>30}: {v}")
    return 0


# ------------------------------------------------------------------------------ build
def build_report(structure_name: str, mesh, verify: bool = False, ring_sweeps: int = 0,
                 return_structure: bool = False, weld: bool = True):
    """Build ``structure_name`` on ``mesh``; the dict ``jaxcds build --json`` prints.
    ``ring_sweeps``: the LR ring search (``lr`` / ``lr-bits`` only, see
    :func:`jaxcds.structures.lr.build_lr`). ``return_structure``: ``(dict, structure, mesh)``,
    the mesh being the one built on (holes closed for a structure that needs a closed mesh).
    ``weld``: :func:`~jaxcds.mesh.load_mesh`'s, for a path (``--no-weld``)."""
    from jaxcds.mesh import load_mesh
    from jaxcds.structures import registry

    mesh = load_mesh(mesh, weld=weld)
    registry.names()
    info = registry.STRUCTURES.get(structure_name)
    if info is None:
        raise errors.ArgumentError(
            f"unknown structure {structure_name!r}; available: {', '.join(registry.names())}")
    if ring_sweeps:
        if structure_name not in ("lr", "lr-bits"):
            raise errors.JaxcdsError(
                f"--ring-sweeps applies to lr and lr-bits, not {structure_name!r}")
        from jaxcds.construct.ring_search import check_sweeps
        from jaxcds.structures.lr import build_lr

        check_sweeps(ring_sweeps)

        def builder(m):
            return build_lr(m, bits=structure_name == "lr-bits", ring_sweeps=ring_sweeps)
    else:
        builder = info.builder
    closed = False
    if info.name not in ("halfedge", "pemb") and not info.closes_boundaries:
        from jaxcds.mesh import validate_and_close

        open_mesh = mesh
        closed_mesh = validate_and_close(mesh, connected=False, structure=structure_name)
        closed = closed_mesh is not mesh
        mesh = closed_mesh
    t0 = time.perf_counter()
    try:
        s = builder(mesh)
    except errors.UnsupportedTopologyError:
        if not (closed and structure_name.startswith("cds")):
            raise
        # the CDS builders close holes themselves and then name them ("Euler characteristic -2
        # after closing 3 boundary loop(s)"); on the mesh closed here the message gave the closed
        # surface's figures as the file's, against `jaxcds info` (sweep 50a: CGAL's
        # double-torus-3-holes.off, -2 against info's -5): their own refusal of the open mesh
        builder(open_mesh)
        raise
    build_s = time.perf_counter() - t0
    out = {
        "structure": structure_name,
        "vertices": int(s.num_vertices),
        "faces": int(s.num_faces),
        "references": int(s.references),
        "references_per_vertex": round(float(s.references_per_vertex), 4),
        # the papers' counts: navigation tables alone, and the CDS face map (Thm 7) apart
        "navigation_references_per_vertex": round(float(getattr(
            s, "navigation_references_per_vertex", s.references_per_vertex)), 4),
        "face_map_references_per_vertex": round(float(getattr(s, "face_map_references_per_vertex", 0.0)), 4),
        "bytes": int(s.nbytes),
        "bytes_per_vertex": round(s.nbytes / max(s.num_vertices, 1), 3),
        "closed_boundaries": closed,
        "dummy_vertices": int(mesh.dummy_vertices.sum()) if mesh.dummy_vertices is not None else 0,
        "build_seconds": round(build_s, 4),
        "vertex_permutation": s.vertex_order is not None,
    }
    if structure_name in ("lr", "lr-bits"):
        from jaxcds.structures.lr import stats

        st = stats(s)
        out.update(references_per_triangle=round(s.references / max(s.num_faces, 1), 4),
                   isolated_vertices=int(st["m_i"]), ring_search_gain=int(st["ring_search_gain"]))
    if verify:
        from jaxcds.verify import verify as run_verify

        rep = run_verify(s, mesh)
        out["checked"] = rep.checked
        out["mismatches"] = rep.mismatches
        out["mismatches_by_operator"] = {k: v for k, v in rep.by_operator.items() if v}
    return (out, s, mesh) if return_structure else out


def cmd_build(args) -> int:
    require_jax()
    out = build_report(args.structure, args.mesh, verify=args.verify,
                       ring_sweeps=args.ring_sweeps, weld=args.weld)
    if args.json:
        _print_json(out)
    else:
        for k, v in out.items():
            print(f"{k:>34}: {v}")
    return 1 if args.verify and out["mismatches"] else 0


# ------------------------------------------------------------------------------ demo
def _degrees_and_normals(s, mesh):
    """Vertex degrees and normals of structure ``s`` of ``mesh``, rows in the mesh's order."""
    import numpy as np

    from jaxcds.algorithms import vertex_degrees, vertex_normals

    order = s.vertex_order
    v = np.asarray(mesh.vertices)
    if s.num_vertices > v.shape[0]:  # holes closed by the builder: dummies at their loops' centroid
        from jaxcds.mesh import close_boundaries

        v = np.asarray(close_boundaries(mesh).vertices)
    pos = v if order is None else v[np.asarray(order)]
    deg = np.asarray(vertex_degrees(s))
    nrm = np.asarray(vertex_normals(s, pos.astype(np.float32)))
    if order is not None:
        inv = np.empty_like(np.asarray(order))
        inv[np.asarray(order)] = np.arange(inv.size)
        deg, nrm = deg[inv], nrm[inv]
    return deg, nrm


def cmd_demo(args) -> int:
    """Load the bundled bunny, report its topology, build every registered structure, verify
    each against the half-edge and compute degrees and normals on each."""
    import numpy as np

    from jaxcds.mesh import load_mesh, topology
    from jaxcds.structures import registry

    require_jax()
    path = default_mesh_path() if args.mesh is None else args.mesh
    mesh = load_mesh(path, weld=args.weld)
    topo = topology(mesh)
    print(f"mesh: {os.path.basename(path)}  V={topo['vertices']} E={topo['edges']} F={topo['faces']} "
          f"genus={topo['genus']} closed={topo['closed']} manifold={topo['manifold']}")
    print(f"{'structure':<14}{'refs/vertex':>12}{'bytes/vertex':>14}{'build s':>9}"
          f"{'checked':>10}{'mismatch':>9}{'degree ok':>10}{'normal err':>12}")
    references = {}  # the half-edge's degrees and normals, per mesh built on (open / closed)
    failures = refused = 0
    for name in registry.names():
        try:
            rep, s, built_on = build_report(name, mesh, verify=True, return_structure=True)
        except errors.JaxcdsError as exc:
            print(f"{name:<14} refused: {exc}")
            refused += 1
            continue
        # a structure built on the closed copy answers for it (its dummies are vertices), unless
        # it knows its dummies (the CDS family: the open mesh's answers)
        if built_on is not mesh and s.dummy_vertex_mask() is not None:
            built_on = mesh
        deg, nrm = _degrees_and_normals(s, built_on)
        if id(built_on) not in references:
            he = registry.build("halfedge", built_on)
            references[id(built_on)] = _degrees_and_normals(he, built_on)
        ref_deg, ref_nrm = references[id(built_on)]
        n = mesh.num_vertices
        deg_ok = bool(np.array_equal(deg[:n], ref_deg[:n]))
        err = float(np.abs(nrm[:n] - ref_nrm[:n]).max())
        failures += rep["mismatches"] > 0 or not deg_ok or err > 1e-4
        print(f"{name:<14}{rep['references_per_vertex']:>12.2f}{rep['bytes_per_vertex']:>14.1f}"
              f"{rep['build_seconds']:>9.3f}{rep['checked']:>10}{rep['mismatches']:>9}"
              f"{str(deg_ok):>10}{err:>12.2e}")
    if refused == len(registry.names()):
        raise errors.MeshError(f"{path}: no structure accepts this mesh (see the reasons above)")
    tail = f" ({refused} refused the mesh)" if refused else ""
    print(f"all structures agree with the half-edge{tail}" if not failures
          else f"{failures} structure(s) disagree with the half-edge{tail}")
    return 1 if failures else 0


# ------------------------------------------------------------------------------ bench
def cmd_bench(args, rest: Sequence[str]) -> int:
    import os
    import sys

    # the console script's sys.path starts at its own folder, not the working directory: find
    # benchmarks/ in the repository root the user runs from, as the error below advises
    if os.path.isfile(os.path.join("benchmarks", "harness.py")) and os.getcwd() not in sys.path:
        sys.path.insert(0, os.getcwd())
    try:
        from benchmarks import harness
    except ImportError:
        raise errors.JaxcdsError(
            "the benchmark harness lives in benchmarks/ of the source tree: run `jaxcds bench` from "
            "the repository root (or `python -m benchmarks`)") from None
    return int(harness.main(list(rest)) or 0)


def _optional(module: str, what: str):
    import importlib

    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name and module.startswith(exc.name.split(".")[0]) and exc.name.startswith("jaxcds"):
            raise errors.JaxcdsError(f"{what} is not available in this version of jaxcds") from None
        raise


# ------------------------------------------------------------------------------ main
def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="jaxcds", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)

    d = sub.add_parser("demo", help="run every structure on the bundled bunny and check it")
    d.add_argument("mesh", nargs="?", help="another mesh instead of the bundled bunny")
    d.add_argument("--no-weld", dest="weld", action="store_false",
                   help="keep vertices that share a position apart (by default they are welded: "
                        "texture seams)")
    d.set_defaults(func=cmd_demo)

    i = sub.add_parser("info", help="topology report of a mesh (or a .cds file)")
    i.add_argument("mesh")
    i.add_argument("--json", action="store_true")
    i.add_argument("--no-weld", dest="weld", action="store_false",
                   help="keep vertices that share a position apart (by default they are welded: "
                        "texture seams)")
    i.set_defaults(func=cmd_info)

    b = sub.add_parser("build", help="build a structure; memory figures; --verify checks it")
    b.add_argument("mesh")
    b.add_argument("--structure", "-s", default="halfedge")
    b.add_argument("--verify", action="store_true",
                   help="check every operator on every edge against the half-edge")
    b.add_argument("--json", action="store_true")
    b.add_argument("--no-weld", dest="weld", action="store_false",
                   help="keep vertices that share a position apart (by default they are welded: "
                        "texture seams)")
    b.add_argument("--ring-sweeps", type=int, default=0, metavar="N",
                   help="lr / lr-bits: anneal the ring for N sweeps towards fewer references "
                        "(beyond the paper; 0 = RING-EXPANDER's ring)")
    b.set_defaults(func=cmd_build)

    bench = sub.add_parser("bench", help="benchmarks (options: see `jaxcds bench --help`)",
                           add_help=False)
    bench.set_defaults(func=None)
    _extend_parser(sub)
    return p


def _extend_parser(sub) -> None:
    """Sub-commands of the optional modules (codec, polylla) when they are present."""
    from jaxcds import _cli_extra

    _cli_extra.add_commands(sub)


#: exit status when the report cannot be written to standard output
EXIT_OUTPUT = 74  # EX_IOERR of sysexits.h
_STDOUT_ERRNOS = (28, 5, 32)  # ENOSPC, EIO, EPIPE


def _silence_stdout() -> None:
    """Point standard output at /dev/null: the interpreter's last flush would fail again and
    print a second error (the recipe of Python's ``signal`` documentation for SIGPIPE)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # no real file descriptor (a test's captured stdout)
        pass


def main(argv: Optional[Sequence[str]] = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        if argv[:1] == ["bench"]:
            return cmd_bench(None, argv[1:])
        args = _parser().parse_args(argv)
        return int(args.func(args) or 0)
    except errors.JaxcdsError as exc:
        print(f"jaxcds: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except BrokenPipeError:  # `jaxcds info ... | head`: the reader left; nothing to report
        _silence_stdout()
        return EXIT_OUTPUT
    except OSError as exc:
        # output files are written atomically and name themselves (OutputError); an OSError
        # with no file name out of a full disk or a broken device is the report's own print
        if exc.errno not in _STDOUT_ERRNOS or exc.filename is not None:
            raise
        _silence_stdout()
        print(f"jaxcds: error: cannot write the report to standard output: {exc.strerror}",
              file=sys.stderr)
        return EXIT_OUTPUT
    except KeyboardInterrupt:  # pragma: no cover
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
