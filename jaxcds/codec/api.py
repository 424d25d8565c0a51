"""High-level codec API: mesh <-> words <-> ``.cds`` files (CDS paper, Sec. 3).

* :func:`encode_mesh` -- Schnyder wood (maximal by default) + red/black words (Sec. 3.1).
* :func:`decode` -- words -> faces, the Thm 2 table, or a CDS structure (Sec. 3.2).
* :func:`write_cds` / :func:`read_cds` / :func:`cds_info` -- the ``.cds`` file
  (``docs/cds-format.md``), written atomically.
* :func:`encode_file` / :func:`decode_file` -- everything the ``jaxcds encode`` / ``jaxcds decode``
  commands do, returning a JSON-able report.
"""

from __future__ import annotations

import dataclasses
import os
import time
from typing import Any, Optional

import numpy as np

from jaxcds import errors
from jaxcds._args import flag_arg, shown
from jaxcds.codec import fileformat as ff
from jaxcds.codec.decode import Paper6n, decode_faces, decode_paper6n  # noqa: F401  (Paper6n: named in decode's docs)
from jaxcds.codec.encode import encode_faces
from jaxcds.codec.words import Words
from jaxcds.construct.schnyder import prepare_mesh
from jaxcds.mesh import (TriMesh, boundary_loops, close_boundaries, load_mesh, topology,
                         trusted_faces, validate)

__all__ = ["EncodedMesh", "encode_mesh", "decode", "write_cds", "read_cds", "cds_info",
           "encode_file", "decode_file", "write_mesh_atomic"]


def _flags(function: str, **flags) -> None:
    """:class:`ArgumentError` naming the first of ``flags`` that is not a bool (``'no'`` and
    ``None`` are truthy / falsy to Python: ``keep_order='no'`` stored the order)."""
    for flag, value in flags.items():
        flag_arg(value, f"{function}: {flag}")


@dataclasses.dataclass(frozen=True)
class EncodedMesh:
    """The connectivity words of a mesh and how its vertices were renumbered.

    Attributes:
      words: :class:`Words` (``words.bits`` is the packed ``uint8`` bit string, 4n-3 bits).
      order: ``(n,)`` int32, ``order[i]`` = vertex id in the encoded mesh of decoded vertex ``i``.
      mesh: the (closed) mesh that was encoded (dummy vertices/faces flagged if holes were closed).
      wood_seconds, words_seconds: time spent on the Schnyder wood and on the words.
    """

    words: Words
    order: np.ndarray
    mesh: TriMesh
    wood_seconds: float = 0.0
    words_seconds: float = 0.0

    @property
    def bits_per_vertex(self) -> float:
        return self.words.num_bits / self.words.num_vertices


def encode_mesh(mesh: Any, *, mixed: bool = True, maximal: bool = True, check: bool = True,
                close: bool = True, root_face: Optional[int] = None) -> EncodedMesh:
    """Encode the connectivity of a genus-0 mesh in 4n - 3 bits (Sec. 3.1, 3.3).

    Args:
      mesh: anything :func:`jaxcds.mesh.load_mesh` accepts.
      mixed: produce the streamable mixed word (Sec. 3.3) instead of red ++ black.
      maximal: use the maximal Schnyder wood (Lemma 3). Any wood encodes and decodes to a mesh;
        decoding into CDS6n / CDS5n / CDS4n needs the maximal wood's words (EncodingError
        otherwise: the Thm 7 face map and the 5n tables are decoded for it).
      check: validate the mesh first (typed :class:`MeshError` on defects). ``False``: trusted
        input, only its face ids are checked (O(F)); other defects are refused by the Schnyder
        wood or give words of unspecified meaning, never a crash.
      close: close boundaries with dummy vertices (``close_boundaries``) instead of refusing.

    Raises:
      UnsupportedTopologyError: genus > 0, several components, or (``close=False``) boundaries.
    """
    _flags("encode_mesh", mixed=mixed, maximal=maximal, check=check, close=close)
    mesh = load_mesh(mesh)
    if check and close:
        # holes closed, then genus 0 refused naming the file and the structures that take it:
        # the same checks (and messages) as the CDS builders
        mesh, _ = prepare_mesh(mesh, structure="the 4n-bit encoding (Schnyder woods)")
    elif check:
        validate(mesh, connected=True, structure="the 4n-bit encoding")
    else:  # the hole closing and the wood index arrays by vertex id: ids in range first
        trusted_faces(mesh.faces, mesh.num_vertices, f"encode_mesh: {mesh.source}")
    if not check and close and (mesh.dummy_vertices is None) and boundary_loops(mesh):
        mesh = close_boundaries(mesh)
    # the wood's out table and rotations, then the words in one DFS pass (encode_faces): the
    # colour labels of a full SchnyderWood are not needed to encode (same words)
    tm: dict = {}
    words, order = encode_faces(mesh.faces, mesh.num_vertices, mixed=mixed, maximal=maximal,
                                root_face=root_face, timings=tm)
    return EncodedMesh(words, order, mesh, tm["wood_s"], tm["words_s"])


def decode(words: Words, *, structure: str = "faces", dummy=None):
    """Decode words (either form) in linear time (Sec. 3.2).

    ``dummy`` (CDS structures only): ``(n,)`` bool, the vertices that closed holes, in decoded
    order (``read_cds(path, original_order=False, drop_dummies=False)[0].dummy_vertices``), so
    the structure's degrees and normals are the open surface's.

    ``structure``:
      * ``"faces"``: ``(2n - 4, 3)`` int32 ccw triangles, vertices in ccw DFS order of ``T_red``;
      * ``"paper6n"``: the Thm 2 table (:class:`Paper6n`) only, no memory beyond it (the red and
        black stacks live in the blue columns);
      * ``"wood"``: ``(faces, Paper6n with targets)``;
      * ``"cds6n"`` / ``"cds5n"``: the CDS structures of ``jaxcds.structures.cds``, decoded in
        place into their packed references (Fig. 10-13);
      * ``"cds4n"``: CDS5n then relabelled by cwBFS (Thm 5; not memory-free, see
        :func:`jaxcds.codec.structures.decode_refs4n`).
    """
    if not isinstance(words, Words):  # bytes gave AttributeError: read_cds reads files
        raise errors.ArgumentError(f"decode: expected jaxcds.codec.Words, got {type(words).__name__} "
                                   "(a .cds file or its bytes: read_cds)")
    # not a str: an array's membership test raised numpy's untyped "truth value" ValueError
    if not isinstance(structure, str) or structure not in ("faces", "paper6n", "wood", "cds6n", "cds5n", "cds4n"):
        raise errors.ArgumentError(
            f"unknown structure {shown(structure)}: faces, paper6n, wood, cds6n, cds5n, cds4n")
    if dummy is not None and structure not in ("cds6n", "cds5n", "cds4n"):
        raise errors.ArgumentError(f"a dummy mask is for the CDS structures, not {structure!r} "
                                   "(its faces include the fans; drop them with the mask yourself)")
    if structure == "faces":
        return decode_faces(words)[0]
    if structure == "paper6n":
        return decode_paper6n(words, targets=False)
    if structure == "wood":
        return decode_faces(words)
    if structure in ("cds6n", "cds5n", "cds4n"):
        from jaxcds.codec.structures import build_cds

        return build_cds(structure, words, dummy=dummy)


# --------------------------------------------------------------------------- files
def _float32_geometry(vertices: np.ndarray, path, real=None) -> np.ndarray:
    """The float32 geometry of a ``.cds`` file, or :class:`NonFiniteCoordinateError` naming the
    first vertex whose finite coordinate float32 cannot hold (|x| > 3.4e38): it was written as
    inf, and read_cds refused the file it had just written; or :class:`MeshError` naming two
    vertices that float32 makes one (:func:`_refuse_float32_collapse`)."""
    with np.errstate(over="ignore"):
        p = np.asarray(vertices).astype(np.float32)
    bad = np.flatnonzero(~np.isfinite(p).all(axis=1))
    if bad.size:
        v = int(bad[0])
        raise errors.NonFiniteCoordinateError(
            f"cannot write {os.fspath(path)!r}: vertex {v} at {np.asarray(vertices)[v].tolist()} is "
            f"past float32's range (|x| <= {float(np.finfo(np.float32).max):.4g}), the .cds geometry "
            f"is float32 ({bad.size} such vertices); scale the mesh first")
    _refuse_float32_collapse(np.asarray(vertices), p, path, real)
    return p


def _refuse_float32_collapse(v: np.ndarray, p: np.ndarray, path, real=None) -> None:
    """:class:`MeshError` naming two vertices that are apart in ``v`` (float64) but one point in
    ``p`` (their float32 geometry): far from the origin (1e8: float32 steps of 8) or at subnormal
    scales (1e-310: every coordinate 0), the file held a mesh of coincident vertices and
    zero-area faces, written without a word. ``real``: mask of the vertices to check (a hole's
    dummy vertex is dropped on reading)."""
    exact = (p == v).all(axis=1)  # (p promoted to float64: exact)
    if real is not None:
        exact |= ~np.asarray(real, bool)
    if exact.all():
        return  # float32 held every coordinate: its equal points are equal in float64 too
    idx = np.arange(p.shape[0]) if real is None else np.flatnonzero(real)
    q = p if real is None else p[idx]  # (no gather of every row when all are real)
    idx = _same_hash(q + np.float32(0), idx)  # + 0: -0.0 and 0.0 are one point, as == says
    q = p[idx]
    o = np.lexsort((q[:, 2], q[:, 1], q[:, 0]))  # the few candidates only: stable, by vertex
    same = np.flatnonzero((q[o[1:]] == q[o[:-1]]).all(axis=1))
    if same.size == 0:
        return
    a, b = idx[o[same]], idx[o[same + 1]]
    apart = np.flatnonzero((v[a] != v[b]).any(axis=1))
    if apart.size == 0:  # the same point in float64 too (an unwelded input): not ours to refuse
        return
    i, j = sorted((int(a[apart[0]]), int(b[apart[0]])))
    raise errors.MeshError(
        f"cannot write {os.fspath(path)!r}: vertices {i} {v[i].tolist()} and {j} {v[j].tolist()} "
        f"are one point in float32, the .cds geometry ({apart.size} such pairs): the decoded mesh "
        "would have coincident vertices and zero-area faces; move the mesh near the origin or "
        "scale it first")


def _same_hash(q: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """The entries of ``idx`` (increasing) whose float32 point ``q`` shares its 64-bit hash with
    another's: every group of equal points, and rare collisions (compared exactly by the
    caller). One argsort of n hashes instead of a 3-key lexsort of n points (5M vertices:
    0.4 s instead of 3.9 s in write_cds)."""
    b = q.view(np.uint32).astype(np.uint64)
    h = (b[:, 0] * np.uint64(0x9E3779B97F4A7C15) ^ b[:, 1] * np.uint64(0xC2B2AE3D27D4EB4F)
         ^ b[:, 2] * np.uint64(0x165667B19E3779F9))
    o = np.argsort(h)
    dup = np.flatnonzero(h[o[1:]] == h[o[:-1]])
    return idx[np.sort(o[np.union1d(dup, dup + 1)])]


def write_cds(path: str | os.PathLike, mesh: Any, *, mixed: bool = True, geometry: bool = True,
              keep_order: bool = True, maximal: bool = True) -> dict:
    """Encode ``mesh`` and write it as a ``.cds`` file (temporary name, then rename).

    Geometry is stored as float32 in decoded order; with ``keep_order`` the original vertex
    ids are stored too (4 bytes per vertex) so :func:`read_cds` restores the input numbering.
    Meshes with holes are closed with dummy vertices, flagged in the file and removed on read.
    Returns a report (sizes, bits per vertex, timings).

    Raises:
      OutputError: ``path`` cannot be written (checked before encoding).
      ArgumentError: ``path`` is not a path (``os.fspath``'s TypeError before), or a flag is
        not a bool (``keep_order='no'`` stored the order)."""
    ff.check_writable(path)
    _flags("write_cds", mixed=mixed, geometry=geometry, keep_order=keep_order, maximal=maximal)
    t0 = time.perf_counter()
    enc = encode_mesh(mesh, mixed=mixed, maximal=maximal)
    m = enc.mesh
    pos = None
    if geometry:
        real = None if m.dummy_vertices is None else ~np.asarray(m.dummy_vertices, bool)
        pos = _float32_geometry(m.vertices, path, real)[enc.order]
    dummy = None
    if m.dummy_vertices is not None and m.dummy_vertices.any():
        dummy = m.dummy_vertices[enc.order]
    data = ff.pack_cds(enc.words, positions=pos, order=enc.order if keep_order else None, dummy=dummy)
    ff.atomic_write_bytes(path, data)
    n = enc.words.num_vertices
    return {
        "path": os.fspath(path),
        "vertices": n,
        "faces": 2 * n - 4,
        "dummy_vertices": int(dummy.sum()) if dummy is not None else 0,
        "connectivity_bits": enc.words.num_bits,
        "bits_per_vertex": round(enc.bits_per_vertex, 4),
        "file_bytes": len(data),
        "mixed": bool(mixed),
        "maximal_wood": bool(maximal),
        "schnyder_seconds": round(enc.wood_seconds, 4),
        "words_seconds": round(enc.words_seconds, 4),
        "total_seconds": round(time.perf_counter() - t0, 4),
    }


def _read_bytes(path) -> bytes:
    """The file's bytes; a directory, FIFO or device is refused by name before a byte is read (a
    FIFO would block, a link to ``/dev/urandom`` fill memory)."""
    from jaxcds.mesh import read_regular_file

    if not isinstance(path, (str, os.PathLike)):
        raise errors.ArgumentError(f"a .cds input is a path or the file's bytes, not "
                                   f"{type(path).__name__}")
    return read_regular_file(path, error=errors.FormatError)


def _named(exc: errors.CodecError, path) -> errors.CodecError:
    """``exc`` with the input's name in front (the messages name the byte, not the file)."""
    if path == "<bytes>":
        return exc
    return type(exc)(f"{os.fspath(path)}: {exc}")


def _with_file_offset(exc: errors.EncodingError) -> errors.EncodingError:
    bit = getattr(exc, "bit", None)
    if bit is None:
        return errors.EncodingError(f"{exc} (connectivity section: bytes from {ff.HEADER_SIZE})")
    return errors.EncodingError(f"{exc}; file byte {ff.HEADER_SIZE + bit // 8}, bit {bit % 8} (MSB first)")


def read_cds(path: str | os.PathLike, *, original_order: bool = True, drop_dummies: bool = True,
             return_words: bool = False):
    """Read a ``.cds`` file (a path, or the file's bytes): ``(TriMesh, info)`` (or
    ``(TriMesh, info, words)``).

    The mesh is in the original vertex order when the file stores it (and ``original_order``),
    else in decoded order; dummy vertices and their faces are dropped (``drop_dummies``).
    Raises :class:`FormatError` / :class:`EncodingError` naming the byte / bit offset, and
    :class:`ArgumentError` for a flag that is not a bool or an input that is not a path or bytes."""
    _flags("read_cds", original_order=original_order, drop_dummies=drop_dummies,
           return_words=return_words)
    t0 = time.perf_counter()
    if isinstance(path, (bytes, bytearray, memoryview)):
        data, path = bytes(path), "<bytes>"
    else:
        data = _read_bytes(path)
    try:
        c = ff.unpack_cds(data)
    except errors.CodecError as exc:  # the file's name, then the byte
        raise _named(exc, path) from None
    t1 = time.perf_counter()
    try:
        faces, table = decode_faces(c.words)
    except errors.EncodingError as exc:
        raise _named(_with_file_offset(exc), path) from None
    t2 = time.perf_counter()
    n = c.words.num_vertices
    pos = (np.asarray(c.positions, dtype=np.float64) if c.positions is not None
           else np.zeros((n, 3), dtype=np.float64))
    dummy = c.dummy
    if dummy is not None:
        try:
            ff.check_dummy_mask(dummy, faces, c.dummy_offset)
        except errors.CodecError as exc:
            raise _named(exc, path) from None
    if original_order and c.order is not None:
        inv_pos = np.empty_like(pos)
        inv_pos[c.order] = pos
        pos = inv_pos
        faces = c.order[faces].astype(np.int32)
        if dummy is not None:
            d2 = np.empty_like(dummy)
            d2[c.order] = dummy
            dummy = d2
    dummy_faces = None
    if dummy is not None:
        dummy_faces = dummy[faces].any(axis=1)
    if drop_dummies and dummy is not None and dummy.any():
        keep = ~dummy
        remap = np.cumsum(keep) - 1
        faces = remap[faces[~dummy_faces]].astype(np.int32)
        pos = pos[keep]
        dummy = dummy_faces = None
    mesh = TriMesh(vertices=pos, faces=np.ascontiguousarray(faces, dtype=np.int32),
                   dummy_vertices=dummy, dummy_faces=dummy_faces, source=os.fspath(path))
    info = {
        "num_vertices_encoded": n,
        "connectivity_bits": c.words.num_bits,
        "bits_per_vertex": round(c.words.num_bits / n, 4),
        "mixed": bool(c.words.mixed),
        "has_geometry": c.positions is not None,
        "has_order": c.order is not None,
        "dummy_vertices": int(c.dummy.sum()) if c.dummy is not None else 0,
        "file_bytes": len(data),
        "read_seconds": round(t1 - t0, 4),
        "decode_seconds": round(t2 - t1, 4),
    }
    return (mesh, info, c.words) if return_words else (mesh, info)


def cds_info(path: str | os.PathLike) -> dict:
    """Report of a ``.cds`` file: the mesh keys of :func:`jaxcds.mesh.topology` (of the
    decoded mesh) plus ``connectivity_bits``, ``bits_per_vertex``, ``file_bytes``,
    ``format_version``, ``mixed``, ``has_geometry``, ``has_order``, ``dummy_vertices``."""
    mesh, info = read_cds(path)  # a path or the file's bytes (read once)
    rep = topology(mesh)
    rep.update({
        "connectivity_bits": info["connectivity_bits"],
        "bits_per_vertex": info["bits_per_vertex"],
        "file_bytes": info["file_bytes"],
        "format_version": ff.VERSION,  # read_cds refuses every other version
        "mixed": info["mixed"],
        "has_geometry": info["has_geometry"],
        "has_order": info["has_order"],
        "dummy_vertices_encoded": info["dummy_vertices"],
    })
    return rep


# --------------------------------------------------------------------------- CLI helpers
_MESH_TYPES = {".off": "off", ".obj": "obj", ".ply": "ply", ".stl": "stl"}


def write_mesh_atomic(path: str | os.PathLike, mesh: TriMesh) -> None:
    """Write ``mesh`` as .off / .obj / .ply / .stl (by suffix) to a temporary file in the same
    folder, then rename it over ``path``. OFF and OBJ keep every digit (float64 too); PLY and
    STL are binary float32, exact for a decoded ``.cds`` geometry (float32), rounded for a
    float64 mesh.

    Raises:
      OutputError: an unknown suffix, or ``path`` cannot be written.
      ArgumentError: ``mesh`` is not a :class:`TriMesh` (an ``AttributeError`` before), or
        ``path`` is not a path."""
    import trimesh

    if not isinstance(mesh, TriMesh):
        raise errors.ArgumentError(f"write_mesh_atomic: mesh must be a jaxcds.mesh.TriMesh "
                                   f"(jaxcds.load_mesh makes one), got {type(mesh).__name__}")
    if not isinstance(path, (str, os.PathLike)):  # os.fspath's TypeError before
        raise errors.ArgumentError(f"an output path is a str or os.PathLike, not {type(path).__name__}")
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    if ext not in _MESH_TYPES:
        raise errors.OutputError(f"cannot write {path!r}: unknown suffix {ext!r} "
                                 f"(use {', '.join(_MESH_TYPES)})")
    ff.check_writable(path)
    if ext in (".off", ".obj"):
        # trimesh writes text coordinates with a fixed 10 (OFF) or 8 (OBJ) decimals: 1e-9
        # became 0 and 1.2345678e-5 lost two digits. Written here in full precision instead.
        data = _mesh_text(mesh, ext).encode()
    else:  # binary PLY and STL: trimesh writes float32, the .cds geometry's own precision
        tm = trimesh.Trimesh(vertices=mesh.vertices, faces=mesh.faces, process=False, validate=False)
        data = tm.export(file_type=_MESH_TYPES[ext])
        if isinstance(data, str):
            data = data.encode()
    ff.atomic_write_bytes(path, data)


def _mesh_text(mesh: TriMesh, ext: str) -> str:
    """OFF or OBJ text of ``mesh`` whose coordinates read back exactly: 9 significant digits
    where every coordinate is a float32 (a decoded ``.cds`` geometry), else 17."""
    v = np.asarray(mesh.vertices, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3)
    with np.errstate(over="ignore", invalid="ignore"):
        single = bool(np.all(v.astype(np.float32).astype(np.float64) == v))
    g = "%.9g" if single else "%.17g"
    if ext == ".off":
        head, vrow, frow, f1 = f"OFF\n{v.shape[0]} {f.shape[0]} 0\n", f"{g} {g} {g}\n", "3 %d %d %d\n", f
    else:
        head, vrow, frow, f1 = "", f"v {g} {g} {g}\n", "f %d %d %d\n", f + 1
    return head + ff.rows_text(vrow, v) + ff.rows_text(frow, f1)


def encode_file(mesh_path: str | os.PathLike, out_path: str | os.PathLike, *, mixed: bool = True,
                keep_order: bool = True) -> dict:
    """``jaxcds encode MESH -o FILE.cds``: load, encode, write atomically; JSON-able report
    (adds ``input_bytes``, ``binary_off_bytes`` and ``ratio_vs_binary_off``).

    Raises:
      ArgumentError: ``mesh_path`` is not a path (arrays or a TriMesh were encoded and written,
        then ``os.path.getsize`` raised TypeError; :func:`write_cds` takes those), or
        ``keep_order`` is not a bool."""
    if not isinstance(mesh_path, (str, os.PathLike)):
        raise errors.ArgumentError(f"encode_file: mesh_path must be a mesh file's path, got "
                                   f"{type(mesh_path).__name__} (write_cds(out_path, mesh) takes "
                                   "arrays and TriMesh objects)")
    mesh = load_mesh(mesh_path)
    rep = write_cds(out_path, mesh, mixed=mixed, keep_order=keep_order)
    rep["input"] = os.fspath(mesh_path)
    rep["input_bytes"] = os.path.getsize(mesh_path)
    n, f = mesh.num_vertices, mesh.num_faces
    rep["binary_off_bytes"] = 12 * n + 12 * f  # float32 xyz + 3 int32 per face (Table 2 note 6)
    rep["ratio_vs_binary_off"] = round(rep["file_bytes"] / rep["binary_off_bytes"], 4)
    return rep


def decode_file(cds_path: str | os.PathLike, out_path: str | os.PathLike, *,
                structure: Optional[str] = None, verify: bool = False) -> dict:
    """``jaxcds decode FILE.cds -o MESH.off|.obj|.ply [--structure cds6n|cds5n]``: read and decode,
    optionally build a CDS structure from the decoded words (and ``verify`` it against the
    half-edge), write the mesh atomically. Returns a JSON-able report.

    Raises:
      ArgumentError: ``verify`` without a ``structure`` (nothing to verify: it was ignored), or
        ``verify`` not a bool; what :func:`read_cds` and :func:`write_mesh_atomic` raise."""
    _flags("decode_file", verify=verify)
    # checked before the file is read: an array raised numpy's "truth value" ValueError, a
    # misspelt name was refused only after the decoding
    if structure is not None and (not isinstance(structure, str)
                                  or structure not in ("", "cds6n", "cds5n", "cds4n")):
        raise errors.ArgumentError(f"decode_file: unknown structure {shown(structure)}: 'cds6n', 'cds5n', "
                                   "'cds4n' or None")
    if verify and not structure:
        raise errors.ArgumentError("decode_file: verify checks the structure built from the words; "
                                   "give structure='cds6n', 'cds5n' or 'cds4n'")
    mesh, info, words = read_cds(cds_path, return_words=True)
    rep = {"input": os.fspath(cds_path), "output": os.fspath(out_path),
           "vertices": mesh.num_vertices, "faces": mesh.num_faces, **info}
    if structure:
        from jaxcds.codec.structures import build_cds

        t0 = time.perf_counter()
        s = build_cds(structure, words, boundaries_closed=info["dummy_vertices"] > 0)
        rep["structure"] = structure
        rep["structure_seconds"] = round(time.perf_counter() - t0, 4)
        rep["references"] = int(s.references)
        rep["structure_bytes"] = int(s.nbytes)
        if verify:
            from jaxcds.verify import verify as run_verify

            dm = TriMesh(vertices=np.zeros((words.num_vertices, 3)), faces=decode_faces(words)[0])
            r = run_verify(s, dm)
            rep["checked"] = int(r.checked)
            rep["mismatches"] = int(r.mismatches)
    write_mesh_atomic(out_path, mesh)
    rep["output_bytes"] = os.path.getsize(out_path)
    return rep
