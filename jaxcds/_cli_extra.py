"""CLI sub-commands of the codec and Polylla modules: ``encode``, ``decode``, ``polylla``.

Called by :func:`jaxcds.cli._extend_parser` with the argparse sub-parsers object. The commands
follow ``jaxcds.cli``'s conventions: ``--json`` prints exactly one JSON object (snake_case keys)
on stdout, errors of :mod:`jaxcds.errors` are printed by ``cli.main`` on stderr with exit status
2 and no traceback, and every output file is written atomically (temporary name in the same
folder, then ``os.replace``), so a failed run never leaves a partial file behind.

* ``jaxcds encode MESH -o FILE.cds`` -- the 4n-3 bit connectivity (CDS paper, Sec. 3.1; the
  streamable mixed word of Sec. 3.3 by default) and float32 geometry in the ``.cds`` container
  (``docs/cds-format.md``); meshes with holes are closed with one dummy vertex per hole.
* ``jaxcds decode FILE.cds -o MESH.off|.obj|.ply|.stl [--structure cds6n|cds5n|cds4n|none]`` --
  decode (Sec. 3.2, Fig. 10-13) and write the mesh in its original vertex order.
* ``jaxcds polylla INPUT [-o OUT.off] [--structure halfedge|pemb|lr|lr-bits] [--mode reference|canonical]`` -- Polylla polygonal mesh
  (Salinas-Fernández et al. 2022; IMR 2023 slides) of a Triangle ``.node``/``.ele`` (``.neigh``
  optional), a 2-D OFF triangulation or a point list.
"""

from __future__ import annotations

import os
import time

from jaxcds import errors

__all__ = ["add_commands", "cmd_encode", "cmd_decode", "cmd_polylla"]

_MESH_SUFFIXES = (".off", ".obj", ".ply", ".stl")


def _cli():
    from jaxcds import cli

    return cli


def _emit(args, report: dict) -> None:
    """``--json``: one JSON object; else one ``key: value`` line per entry (as ``jaxcds build``)."""
    if args.json:
        _cli()._print_json(report)
        return
    for k, v in report.items():
        if isinstance(v, dict):
            v = ", ".join(f"{a}={b:.4g}" if isinstance(b, float) else f"{a}={b}" for a, b in v.items())
        print(f"{k:>24}: {v}")


def _check_output(path: str, suffixes: tuple, what: str, source: str) -> None:
    """Refuse a bad output path *before* any work: wrong suffix, missing folder, a folder, or
    the input file ``source`` itself (``polylla IN.off -o IN.off`` replaced the triangulation
    with its polygon mesh and exited 0: the input was lost)."""
    ext = os.path.splitext(path)[1].lower()
    if os.path.isdir(path):  # checked first: a folder has no suffix, and "unknown suffix ''" hid why
        raise errors.OutputError(f"output {path!r} is a folder; give a file path in it "
                                 f"(e.g. {os.path.join(path, 'out' + suffixes[0])!r})")
    if ext not in suffixes:
        raise errors.OutputError(f"output {path!r}: unknown suffix {ext!r} for {what} "
                                 f"(use {', '.join(suffixes)})")
    from jaxcds.codec.fileformat import check_writable

    check_writable(path)
    try:
        same = os.path.samefile(path, source)
    except OSError:  # either one missing (or unreadable): the reader names the input's problem
        same = False
    if same:
        raise errors.OutputError(f"output {path!r} is the input file {source!r}: writing it would "
                                 "replace the input; give another output path")


def _writing(path: str):
    """Context turning an ``OSError`` of the (atomic) write into a typed error naming the file."""
    import contextlib

    @contextlib.contextmanager
    def ctx():
        try:
            yield
        except errors.JaxcdsError:  # typed already (an OutputError is an OSError too)
            raise
        except OSError as exc:
            raise errors.OutputError(f"cannot write {path!r}: {exc.strerror or exc}") from exc

    return ctx()


# ------------------------------------------------------------------------------ encode
def cmd_encode(args) -> int:
    """``jaxcds encode MESH -o FILE.cds``: load, encode (Schnyder wood + words), write atomically.

    JSON keys: ``vertices`` / ``faces`` (the input mesh), ``encoded_vertices`` / ``encoded_faces``
    (after closing holes: ``n`` and ``2n - 4``), ``dummy_vertices`` (one per closed hole),
    ``connectivity_bits`` (``4n - 3``), ``bits_per_vertex`` (per encoded vertex), ``file_bytes``,
    ``binary_off_bytes`` and ``ratio_vs_binary_off`` (Table 2's comparison), ``encode_seconds``
    (Schnyder wood + words), ``schnyder_seconds``, ``words_seconds``, ``total_seconds`` (load,
    encode, pack and write), ``mixed``, ``input``, ``output``."""
    from jaxcds.codec.api import write_cds
    from jaxcds.mesh import load_mesh

    _check_output(args.output, (".cds",), "a .cds file", args.mesh)
    t0 = time.perf_counter()
    mesh = load_mesh(args.mesh, weld=args.weld)
    with _writing(args.output):
        rep = write_cds(args.output, mesh, mixed=not args.separate_words)
    n, f = mesh.num_vertices, mesh.num_faces
    binary_off = 12 * n + 12 * f  # float32 xyz + 3 int32 per face (Table 2 note 6)
    out = {
        "input": os.fspath(args.mesh),
        "output": os.fspath(args.output),
        "vertices": n,
        "faces": f,
        "encoded_vertices": rep["vertices"],
        "encoded_faces": rep["faces"],
        "dummy_vertices": rep["dummy_vertices"],
        "connectivity_bits": rep["connectivity_bits"],
        "bits_per_vertex": rep["bits_per_vertex"],
        "file_bytes": rep["file_bytes"],
        "input_bytes": os.path.getsize(args.mesh),
        "binary_off_bytes": binary_off,
        "ratio_vs_binary_off": round(rep["file_bytes"] / binary_off, 4),
        "mixed": rep["mixed"],
        "encode_seconds": round(rep["schnyder_seconds"] + rep["words_seconds"], 4),
        "schnyder_seconds": rep["schnyder_seconds"],
        "words_seconds": rep["words_seconds"],
        "total_seconds": round(time.perf_counter() - t0, 4),
    }
    _emit(args, out)
    return 0


# ------------------------------------------------------------------------------ decode
def cmd_decode(args) -> int:
    """``jaxcds decode FILE.cds -o MESH``: decode the words, optionally into a CDS structure
    (``--structure``, default ``cds6n``; ``none`` skips it), write the mesh atomically.

    JSON keys: ``vertices`` / ``faces`` (of the written mesh: dummy vertices dropped, original
    order), ``encoded_vertices``, ``connectivity_bits``, ``bits_per_vertex``, ``decode_seconds``
    (words -> faces), ``structure``, ``structure_seconds`` (words -> structure, Fig. 10-13),
    ``references``, ``references_per_vertex`` and ``structure_bytes`` of the decoded structure
    (``null`` with ``--structure none``), ``file_bytes``, ``output_bytes``, ``seconds`` (total);
    with ``--verify`` also ``checked`` and ``mismatches`` (operator check vs the half-edge)."""
    from jaxcds.codec.api import decode_file

    _check_output(args.output, _MESH_SUFFIXES, "a mesh", args.input)
    structure = None if args.structure == "none" else args.structure
    if args.verify and structure is None:
        raise errors.JaxcdsError("--verify needs a decoded structure (--structure cds6n|cds5n|cds4n)")
    if structure is not None:
        _cli().require_jax()
    t0 = time.perf_counter()
    with _writing(args.output):
        rep = decode_file(args.input, args.output, structure=structure, verify=args.verify)
    n = rep["num_vertices_encoded"]
    out = {
        "input": rep["input"],
        "output": rep["output"],
        "vertices": rep["vertices"],
        "faces": rep["faces"],
        "encoded_vertices": n,
        "dummy_vertices": rep["dummy_vertices"],
        "connectivity_bits": rep["connectivity_bits"],
        "bits_per_vertex": rep["bits_per_vertex"],
        "mixed": rep["mixed"],
        "decode_seconds": rep["decode_seconds"],
        "structure": structure,
        "structure_seconds": rep.get("structure_seconds"),
        "references": rep.get("references"),
        "references_per_vertex": (round(rep["references"] / n, 4) if structure else None),
        "structure_bytes": rep.get("structure_bytes"),
        "file_bytes": rep["file_bytes"],
        "output_bytes": rep["output_bytes"],
        "seconds": round(time.perf_counter() - t0, 4),
    }
    if args.verify:
        out["checked"] = rep["checked"]
        out["mismatches"] = rep["mismatches"]
    _emit(args, out)
    return 1 if args.verify and out["mismatches"] else 0


# ------------------------------------------------------------------------------ polylla
def cmd_polylla(args) -> int:
    """``jaxcds polylla INPUT [-o OUT.off] [--structure halfedge|pemb|lr|lr-bits] [--mode reference|canonical]``.

    JSON keys (from :func:`jaxcds.algorithms.polylla.run`): ``polygons``, ``barrier_edge_tips``,
    ``repaired_polygons``, ``regions``, ``frontier_edges``, ``vertices``, ``triangles``,
    ``structure``, ``mode``, ``input``, ``output``, ``timings`` (seconds per phase: ``build``, ``label``,
    ``traversal``, ``repair``, ``polygons``, ``order``, ``repair_count``, and ``cpu_*`` process
    CPU seconds; the first run in a process includes jit compilation), ``seconds`` (total); for
    some inputs ``duplicate_points`` and ``notes`` (a point set's exact repeats left in no
    triangle, a lone ``.node`` triangulated as a point set)."""
    from jaxcds.algorithms import polylla

    if args.output is not None:
        _check_output(args.output, (".off",), "the polygon mesh", args.input)
    _cli().require_jax()
    t0 = time.perf_counter()
    with _writing(args.output or ""):
        rep = polylla.run(args.input, args.output, structure=args.structure,
                          tables=not args.no_tables, mode=args.mode)
    rep["seconds"] = round(time.perf_counter() - t0, 4)
    _emit(args, rep)
    return 0


# ------------------------------------------------------------------------------ parser
def add_commands(sub) -> None:
    """Add ``encode``, ``decode`` and ``polylla`` to the ``jaxcds`` sub-parsers."""
    from jaxcds.polylla_io import BORDER_STRUCTURES  # the light input module, not the mesher

    e = sub.add_parser("encode", help="compress a genus-0 mesh into a .cds file (4n-3 bits "
                                      "of connectivity + float32 geometry)")
    e.add_argument("mesh", help="input mesh (.off, .obj, .ply, .stl), genus 0, holes allowed")
    e.add_argument("-o", "--output", required=True, help="the .cds file to write")
    e.add_argument("--separate-words", action="store_true",
                   help="store the red word then the black word instead of the streamable "
                        "mixed word (Sec. 3.3)")
    e.add_argument("--json", action="store_true")
    e.add_argument("--no-weld", dest="weld", action="store_false",
                   help="keep vertices that share a position apart (by default they are welded: "
                        "texture seams)")
    e.set_defaults(func=cmd_encode)

    d = sub.add_parser("decode", help="decompress a .cds file into a mesh (and a CDS structure)")
    d.add_argument("input", help="the .cds file")
    d.add_argument("-o", "--output", required=True, help="mesh to write: .off, .obj, .ply or .stl")
    d.add_argument("--structure", "-s", default="cds6n", choices=["cds6n", "cds5n", "cds4n", "none"],
                   help="structure to decode into (memory-free for cds6n/cds5n, Fig. 10-13); "
                        "default cds6n")
    d.add_argument("--verify", action="store_true",
                   help="check every operator of the decoded structure against the half-edge")
    d.add_argument("--json", action="store_true")
    d.set_defaults(func=cmd_decode)

    p = sub.add_parser("polylla", help="Polylla polygonal mesh of a 2-D triangulation or point set")
    p.add_argument("input", help="Triangle .node/.ele (.neigh optional) or their stem, a 2-D OFF "
                                 "triangulation, or a point list (.xy/.txt/.csv/.npy, Delaunay)")
    p.add_argument("-o", "--output", help="polygon mesh to write (.off)")
    p.add_argument("--structure", "-s", default="halfedge", choices=list(BORDER_STRUCTURES),
                   help="structure to run on: the array half-edge (default), pemb (succinct "
                        "planar embedding), lr or lr-bits (Laced Ring; a border needs no closing); "
                        "the polygons are identical")
    p.add_argument("--no-tables", action="store_true",
                   help="navigate the structure as it is, without per-run navigation tables "
                        "(pemb: a parenthesis search per operator; slower, smaller peak memory)")
    p.add_argument("--mode", default="reference", choices=["reference", "canonical"],
                   help="reference (default): the reference implementation's polygons, its "
                        "sequential walk and repair on the input's numbering; canonical: "
                        "order-free phases, every barrier-edge tip repaired")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_polylla)
