"""The ``.cds`` file: 4n-3 connectivity bits + float32 geometry (spec: ``docs/cds-format.md``).

Layout (little-endian; every section is followed by the CRC-32 of its bytes)::

    offset  size  field
    0       8     magic  b"\\x89CDS\\r\\n\\x1a\\n"
    8       2     version (1)
    10      2     flags: bit 0 MIXED (streamable word of Sec. 3.3, else red word ++ black word)
                         bit 1 GEOMETRY (float32 xyz per vertex)
                         bit 2 ORDER (uint32 original index per vertex)
                         bit 3 DUMMY (bit mask of dummy vertices added by close_boundaries)
                         other bits must be 0
    12      8     n, number of vertices (4 <= n < 2**31)
    20      8     connectivity bits, must be 4n - 3
    28      4     reserved, 0
    32      4     CRC-32 of bytes 0..31
    36      ...   connectivity: ceil((4n-3)/8) bytes, MSB first, zero padding bits; CRC-32
                  geometry: 12n bytes (if GEOMETRY); CRC-32
                  order: 4n bytes (if ORDER); CRC-32
                  dummy mask: ceil(n/8) bytes, MSB first (if DUMMY); CRC-32
                  end of file (no trailing bytes)

Vertex ``i`` of every per-vertex section is vertex ``i`` of the decoded mesh (ccw DFS order of
the red tree, Sec. 3.1); ``order[i]`` is its index in the mesh that was encoded.

Every size is checked against the file length before anything is allocated; every defect is a
:class:`~jaxcds.errors.FormatError` (container) or :class:`~jaxcds.errors.EncodingError` (words)
naming the byte (and bit) offset.
"""

from __future__ import annotations

import dataclasses
import os
import struct
import tempfile
import threading
import zlib
from typing import Optional

import numpy as np

from jaxcds import errors
from jaxcds.codec.words import MAX_VERTICES, Words, num_bits

__all__ = ["MAGIC", "VERSION", "HEADER_SIZE", "CdsContents", "pack_cds", "unpack_cds", "read_header",
           "atomic_write_bytes", "check_writable", "FLAG_MIXED", "FLAG_GEOMETRY", "FLAG_ORDER", "FLAG_DUMMY"]

MAGIC = b"\x89CDS\r\n\x1a\n"
VERSION = 1
FLAG_MIXED, FLAG_GEOMETRY, FLAG_ORDER, FLAG_DUMMY = 1, 2, 4, 8
_KNOWN = FLAG_MIXED | FLAG_GEOMETRY | FLAG_ORDER | FLAG_DUMMY
_HEAD = struct.Struct("<8sHHQQI")  # magic, version, flags, n, bits, reserved  (32 bytes)
HEADER_SIZE = _HEAD.size + 4


@dataclasses.dataclass(frozen=True)
class CdsContents:
    """What a ``.cds`` file holds (arrays in decoded vertex order)."""

    words: Words
    positions: Optional[np.ndarray]  # (n, 3) float32
    order: Optional[np.ndarray]      # (n,) int64 original index of decoded vertex i
    dummy: Optional[np.ndarray]      # (n,) bool
    flags: int
    version: int = VERSION
    dummy_offset: int = -1           # byte offset of the dummy mask section (-1: none)


def _crc(b) -> int:
    return zlib.crc32(b) & 0xFFFFFFFF


def _sections(n: int, flags: int) -> list[tuple[str, int]]:
    out = [("connectivity", (num_bits(n) + 7) // 8)]
    if flags & FLAG_GEOMETRY:
        out.append(("geometry", 12 * n))
    if flags & FLAG_ORDER:
        out.append(("order", 4 * n))
    if flags & FLAG_DUMMY:
        out.append(("dummy mask", (n + 7) // 8))
    return out


def file_size(n: int, flags: int) -> int:
    """Exact size in bytes of a ``.cds`` file for ``n`` vertices and these flags."""
    return HEADER_SIZE + sum(size + 4 for _, size in _sections(n, flags))


def pack_cds(words: Words, positions=None, order=None, dummy=None) -> bytes:
    """Serialise into the bytes of a ``.cds`` file."""
    n = words.num_vertices
    flags = (FLAG_MIXED if words.mixed else 0)
    flags |= FLAG_GEOMETRY if positions is not None else 0
    flags |= FLAG_ORDER if order is not None else 0
    flags |= FLAG_DUMMY if dummy is not None else 0
    head = _HEAD.pack(MAGIC, VERSION, flags, n, num_bits(n), 0)
    parts = [head, struct.pack("<I", _crc(head))]
    nb = (num_bits(n) + 7) // 8
    conn = np.zeros(nb, dtype=np.uint8)
    conn[:] = np.asarray(words.bits, dtype=np.uint8)[:nb]
    pad = 8 * nb - num_bits(n)
    if pad:
        conn[-1] &= np.uint8((0xFF << pad) & 0xFF)
    blobs = [conn.tobytes()]
    if positions is not None:
        p = np.ascontiguousarray(np.asarray(positions).reshape(n, 3), dtype="<f4")
        blobs.append(p.tobytes())
    if order is not None:
        blobs.append(np.ascontiguousarray(order, dtype="<u4").tobytes())
    if dummy is not None:
        blobs.append(np.packbits(np.asarray(dummy, dtype=bool)).tobytes())
    for b in blobs:
        parts.append(b)
        parts.append(struct.pack("<I", _crc(b)))
    return b"".join(parts)


def read_header(data: bytes, total_size: Optional[int] = None) -> dict:
    """Check and parse the 36-byte header (needs only the first 36 bytes and the file size)."""
    size = len(data) if total_size is None else int(total_size)
    if size < HEADER_SIZE or len(data) < HEADER_SIZE:
        raise errors.FormatError(f"truncated .cds file: {size} bytes, the header alone needs {HEADER_SIZE} "
                                 f"(missing from byte {size})")
    magic, version, flags, n, bits, reserved = _HEAD.unpack_from(data, 0)
    if magic != MAGIC:
        raise errors.FormatError(f"not a .cds file: bad magic {magic!r} at byte 0 (expected {MAGIC!r})")
    if version != VERSION:
        raise errors.FormatError(f"unsupported .cds version {version} at byte 8 (this reader knows {VERSION})")
    (hcrc,) = struct.unpack_from("<I", data, _HEAD.size)
    if _crc(data[: _HEAD.size]) != hcrc:
        raise errors.FormatError(f"header checksum mismatch: CRC-32 of bytes 0..{_HEAD.size - 1} does not "
                                 f"match the value stored at byte {_HEAD.size} (a bit flipped in the header)")
    if flags & ~_KNOWN:
        raise errors.FormatError(f"unknown flag bits {flags & ~_KNOWN:#x} at byte 10")
    if reserved != 0:
        raise errors.FormatError(f"reserved field at byte 28 is {reserved}, must be 0")
    if not 4 <= n <= MAX_VERTICES:
        raise errors.FormatError(f"vertex count {n} at byte 12 out of range [4, {MAX_VERTICES}]")
    if bits != num_bits(n):
        raise errors.FormatError(f"connectivity bit count {bits} at byte 20 does not match the vertex count: "
                                 f"4n - 3 = {num_bits(n)} for n = {n}")
    expect = file_size(n, flags)
    if size < expect:
        raise errors.FormatError(f"truncated .cds file: {size} bytes, header (n = {n}, flags = {flags:#x}) "
                                 f"implies {expect}; data missing from byte {size}")
    if size > expect:
        raise errors.FormatError(f".cds file has {size - expect} trailing bytes after byte {expect} "
                                 f"(header: n = {n}, flags = {flags:#x})")
    return {"version": version, "flags": flags, "num_vertices": n, "connectivity_bits": bits,
            "mixed": bool(flags & FLAG_MIXED), "geometry": bool(flags & FLAG_GEOMETRY),
            "order": bool(flags & FLAG_ORDER), "dummy": bool(flags & FLAG_DUMMY), "file_size": size}


def unpack_cds(data: bytes) -> CdsContents:
    """Parse and check the bytes of a ``.cds`` file (container level; the words themselves are
    checked by the decoder)."""
    head = read_header(data)
    n, flags = head["num_vertices"], head["flags"]
    off = HEADER_SIZE
    blobs = {}
    for name, size in _sections(n, flags):
        blob = memoryview(data)[off: off + size]
        (crc,) = struct.unpack_from("<I", data, off + size)
        if _crc(blob) != crc:
            raise errors.FormatError(f"checksum mismatch in the {name} section (bytes {off}..{off + size - 1}, "
                                     f"CRC-32 stored at byte {off + size}): the file is corrupted")
        blobs[name] = (off, blob)
        off += size + 4
    coff, conn = blobs["connectivity"]
    conn = np.frombuffer(conn, dtype=np.uint8)
    pad = 8 * conn.size - num_bits(n)
    if pad and int(conn[-1]) & ((1 << pad) - 1):
        raise errors.FormatError(f"non-zero padding bits in byte {coff + conn.size - 1} "
                                 f"(connectivity bits {num_bits(n)}..{8 * conn.size - 1})")
    words = Words(n, conn, mixed=bool(flags & FLAG_MIXED))
    positions = order = dummy = None
    if flags & FLAG_GEOMETRY:
        goff, g = blobs["geometry"]
        positions = np.frombuffer(g, dtype="<f4").reshape(n, 3)
        bad = np.flatnonzero(~np.isfinite(positions).all(axis=1))
        if bad.size:
            raise errors.FormatError(f"non-finite coordinate for vertex {int(bad[0])} at byte {goff + 12 * int(bad[0])}")
    if flags & FLAG_ORDER:
        ooff, o = blobs["order"]
        order = np.frombuffer(o, dtype="<u4").astype(np.int64)
        big = np.flatnonzero(order >= n)
        if big.size:
            raise errors.FormatError(f"vertex order entry {int(order[big[0]])} >= n = {n} at byte {ooff + 4 * int(big[0])}")
        seen = np.zeros(n, dtype=bool)
        seen[order] = True
        if not seen.all():
            missing = int(np.flatnonzero(~seen)[0])
            raise errors.FormatError(f"vertex order section (byte {ooff}) is not a permutation: "
                                     f"original vertex {missing} missing")
    doff = -1
    if flags & FLAG_DUMMY:
        doff, m = blobs["dummy mask"]
        mb = np.frombuffer(m, dtype=np.uint8)
        pad = 8 * mb.size - n
        if pad and int(mb[-1]) & ((1 << pad) - 1):
            raise errors.FormatError(f"non-zero padding bits in byte {doff + mb.size - 1} "
                                     f"(dummy mask bits {n}..{8 * mb.size - 1})")
        dummy = np.unpackbits(mb, count=n).astype(bool)
    return CdsContents(words, positions, order, dummy, flags, head["version"], doff)


def check_dummy_mask(dummy: np.ndarray, faces: np.ndarray, offset: Optional[int]) -> None:
    """Raise unless ``dummy`` (decoded order) can be a mask that
    :func:`jaxcds.mesh.close_boundaries` wrote for ``faces`` (decoded order): every dummy vertex
    is the apex of its own closing fan, so no face holds two of them, and some face holds none.
    ``offset``: the mask section's first byte in a file (bit ``i`` of the mask is in byte
    ``offset + i // 8``; a :class:`FormatError` names them), or ``None`` for a mask passed as an
    argument (an :class:`~jaxcds.errors.ArgumentError`)."""
    where = "dummy mask" if offset is None else f"dummy mask (bytes from {offset})"
    fail = errors.ArgumentError if offset is None else errors.FormatError
    bad = "does not fit this mesh" if offset is None else "is corrupted"
    per_face = dummy[faces].sum(axis=1)
    two = np.flatnonzero(per_face > 1)
    if two.size:
        f = faces[int(two[0])]
        a, b = (int(x) for x in f[dummy[f]][:2])
        at = "" if offset is None else f" (bytes {offset + a // 8} and {offset + b // 8})"
        raise fail(f"{where} flags vertices {a} and {b}{at} of one face {f.tolist()}: hole-closing "
                   f"dummy vertices never share a face; the mask {bad}")
    if faces.shape[0] and not (per_face == 0).any():
        raise fail(f"{where} leaves no face without a dummy vertex: the mask {bad}")


def check_writable(path: str | os.PathLike) -> str:
    """``path`` as a string if a file can be written there (its folder exists, no folder in its
    place, no device, FIFO, socket or read-only file there), else :class:`~jaxcds.errors.OutputError` naming it.
    Called before any work.

    Writes are a temporary file renamed over ``path``: on a device (``/dev/null``,
    ``/dev/full``) or a FIFO that rename would replace the node itself with a regular file (as
    root, ``-o /dev/null`` replaced the system's /dev/null), so such outputs are refused, as the
    readers refuse them as inputs."""
    import stat

    if not isinstance(path, (str, os.PathLike)):  # os.fspath's TypeError before
        raise errors.ArgumentError(f"an output path is a str or os.PathLike, not {type(path).__name__}")
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise errors.OutputError(f"output {path!r}: folder {folder!r} does not exist")
    if os.path.isdir(path):
        raise errors.OutputError(f"output {path!r} is a folder")
    if not os.access(folder, os.W_OK | os.X_OK):  # else found by the temporary file, after the work
        raise errors.OutputError(f"output {path!r}: folder {folder!r} is not writable")
    try:
        mode = os.stat(path).st_mode
    except OSError:  # nothing there (or a dangling link): the rename creates the file
        return path
    if not stat.S_ISREG(mode):
        kind = ("a character device" if stat.S_ISCHR(mode) else "a block device" if stat.S_ISBLK(mode)
                else "a FIFO" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode)
                else "not a regular file")
        raise errors.OutputError(f"output {path!r} is {kind}, not a regular file: the atomic write "
                                 "(a temporary file renamed over it) would replace it; give a file path")
    # the rename needs write access to the folder only, so a file its owner made read-only was
    # replaced without a word, where ``open(path, 'w')`` (or a shell's ``>``) refuses it; as
    # root, ``os.access`` allows everything, so the mode's write bits are read as well
    if not (mode & 0o222) or not os.access(path, os.W_OK):
        raise errors.OutputError(f"output {path!r} is read-only (mode {stat.S_IMODE(mode):04o}): not "
                                 "replaced; make it writable or give another path")
    return path


def rows_text(row: str, a: np.ndarray, chunk: int = 1 << 18) -> str:
    """``row % a[i]`` for every row of ``a``, joined (the text mesh writers: decoded OBJ / OFF,
    Polylla's OFF). One ``%`` over a repeated format per chunk of rows: C-level formatting
    (``np.savetxt``'s per-row Python loop took 7.7 s for 500K vertices and 1M faces, trimesh's
    export 2.9 s, this 1.0 s), chunked so the Python tuple stays small. Same bytes as
    ``np.savetxt(fmt=...)``."""
    return "".join((row * len(part)) % tuple(part.ravel().tolist())
                   for part in (a[i:i + chunk] for i in range(0, a.shape[0], chunk)))


def _output_mode(path: str) -> int:
    """Permission bits for a file written over ``path``: those of the file already there (an
    executable or group-writable output keeps them), else the usual ``0666 & ~umask``
    (``mkstemp`` creates its file ``0600``)."""
    import stat

    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        return 0o666 & ~_current_umask()


_UMASK_LOCK = threading.Lock()


def _current_umask() -> int:
    """The process's umask, read without changing it where Linux says it (``/proc/self/status``,
    Linux 4.7+). ``os.umask`` can only be read by setting it, and the umask is one per process:
    two threads writing new files at once (``umask(0)`` then the restore, interleaved) left the
    process with umask 0 for good, every later file world-writable, and a file another thread
    created inside the window was too (sweep 55a). Elsewhere the swap is made under a lock, to
    the restrictive ``077`` rather than to ``0``."""
    try:
        with open("/proc/self/status", "rb") as fh:
            for line in fh:
                if line.startswith(b"Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    with _UMASK_LOCK:
        umask = os.umask(0o077)
        os.umask(umask)
    return umask


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to a temporary file next to ``path``, fsync, then rename over ``path``:
    readers never see a partial file, and a failed write leaves nothing behind. A file already
    at ``path`` keeps its permission bits; a symbolic link at ``path`` keeps pointing at the
    file it names, which is the one replaced.

    Raises:
      OutputError: the folder is missing, a folder is in the way, or the OS refuses the write
        (permission, full disk), naming ``path``."""
    path = check_writable(path)
    # through a symbolic link, the file it names is replaced (as ``>`` in a shell writes through
    # it): renamed over the link itself, the link became a plain file and its target kept the old
    # contents
    target = os.path.realpath(path) if os.path.islink(path) else path
    d = os.path.dirname(os.path.abspath(target))
    try:
        fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=os.path.basename(target), dir=d)
    except OSError as exc:
        raise errors.OutputError(f"cannot write {path!r}: {exc.strerror or exc}") from None
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, _output_mode(target))
        os.replace(tmp, target)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError):
            raise errors.OutputError(f"cannot write {path!r}: {exc.strerror or exc}") from None
        raise
