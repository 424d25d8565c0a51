"""``jaxcds encode`` / ``jaxcds decode`` (issue 4): JSON keys, round trips through the CLI, and
bad input that writes nothing (typed error naming the byte, exit 2, no output, no temp file)."""

from __future__ import annotations

import json
import os
import re
import struct
import subprocess
import sys
import zlib

import numpy as np
import pytest

from jaxcds.cli import main
from jaxcds.codec import fileformat as ff
from jaxcds.codec.words import Words
from jaxcds.mesh import load_mesh

from conftest import mesh_path

ENCODE_KEYS = {"vertices", "faces", "encoded_vertices", "encoded_faces", "dummy_vertices",
               "connectivity_bits", "bits_per_vertex", "file_bytes", "binary_off_bytes",
               "encode_seconds", "total_seconds"}
DECODE_KEYS = {"vertices", "faces", "encoded_vertices", "connectivity_bits", "bits_per_vertex",
               "decode_seconds", "structure", "references_per_vertex", "structure_seconds",
               "output_bytes"}


def run_json(capsys, argv):
    rc = main(argv)
    out = capsys.readouterr()
    assert rc == 0, out.err
    return json.loads(out.out)


def canon(faces):
    """Faces as a set of rotation-canonical triangles (orientation kept)."""
    f = np.asarray(faces)
    k = np.argmin(f, axis=1)
    rows = np.stack([np.roll(r, -int(i)) for r, i in zip(f, k)])
    return set(map(tuple, rows.tolist()))


@pytest.fixture(scope="module")
def cube_cds(tmp_path_factory):
    """``cube.off`` encoded once (8 vertices: a 180-byte file, cheap to corrupt byte by byte)."""
    d = tmp_path_factory.mktemp("cube")
    path = d / "cube.cds"
    assert main(["encode", mesh_path("cube.off"), "-o", str(path)]) == 0
    return path.read_bytes()


def test_encode_decode_grid_with_hole_json(capsys, tmp_path):
    """grid.off has one boundary loop: closed with one dummy vertex, dropped again on decode."""
    src = mesh_path("grid.off")
    cds = tmp_path / "g.cds"
    e = run_json(capsys, ["encode", src, "-o", str(cds), "--json"])
    assert ENCODE_KEYS <= set(e)
    assert (e["vertices"], e["faces"], e["dummy_vertices"]) == (145, 256, 1)
    n = e["encoded_vertices"]
    assert n == 146 and e["encoded_faces"] == 2 * n - 4
    assert e["connectivity_bits"] == 4 * n - 3 and e["bits_per_vertex"] == round((4 * n - 3) / n, 4)
    assert e["bits_per_vertex"] <= 4 and e["file_bytes"] == os.path.getsize(cds)
    assert e["file_bytes"] == ff.file_size(n, ff.FLAG_MIXED | ff.FLAG_GEOMETRY | ff.FLAG_ORDER
                                           | ff.FLAG_DUMMY)
    assert oct(os.stat(cds).st_mode & 0o777) != oct(0o600)  # not mkstemp's private mode

    out = tmp_path / "g.off"
    d = run_json(capsys, ["decode", str(cds), "-o", str(out), "--structure", "cds5n", "--json"])
    assert DECODE_KEYS <= set(d)
    assert (d["vertices"], d["faces"], d["encoded_vertices"]) == (145, 256, 146)
    assert d["structure"] == "cds5n" and d["connectivity_bits"] == e["connectivity_bits"]
    assert d["references_per_vertex"] == round(d["references"] / 146, 4) > 0
    src_mesh, dec = load_mesh(src), load_mesh(str(out))
    assert canon(dec.faces) == canon(src_mesh.faces)  # original order and orientation restored
    np.testing.assert_array_equal(dec.vertices, src_mesh.vertices.astype(np.float32))
    assert sorted(os.listdir(tmp_path)) == ["g.cds", "g.off"]  # no temporary file left


def test_decode_formats_and_structures(capsys, tmp_path, cube_cds):
    cds = tmp_path / "c.cds"
    cds.write_bytes(cube_cds)
    cube = load_mesh(mesh_path("cube.off"))
    for suffix, structure in ((".obj", "none"), (".ply", "cds6n"), (".stl", "cds4n")):
        out = tmp_path / f"c{suffix}"
        d = run_json(capsys, ["decode", str(cds), "-o", str(out), "-s", structure, "--json"])
        assert d["structure"] == (None if structure == "none" else structure)
        assert (d["references_per_vertex"] is None) == (structure == "none")
        m = load_mesh(str(out))
        assert (m.num_vertices, m.num_faces) == (8, 12)
        if suffix != ".stl":  # STL stores triangles only: vertex ids are not kept
            assert canon(m.faces) == canon(cube.faces)
    # text output: one "key: value" line per key
    assert main(["decode", str(cds), "-o", str(tmp_path / "t.off"), "-s", "none"]) == 0
    assert re.search(r"bits_per_vertex: 3\.625", capsys.readouterr().out)  # (4*8-3)/8


def test_decode_verify_against_halfedge(capsys, tmp_path, cube_cds):
    cds = tmp_path / "c.cds"
    cds.write_bytes(cube_cds)
    d = run_json(capsys, ["decode", str(cds), "-o", str(tmp_path / "c.off"), "--verify", "--json"])
    assert d["structure"] == "cds6n" and d["checked"] > 0 and d["mismatches"] == 0


def _refused(capsys, argv, out, match=r"byte \d+"):
    """Exit 2, a message on stderr matching ``match``, no traceback, no output file, no temp."""
    before = set(os.listdir(os.path.dirname(out)))
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2, err
    assert re.search(match, err), err
    assert "Traceback" not in err
    assert not os.path.exists(out)
    assert set(os.listdir(os.path.dirname(out))) == before
    return err


def test_every_corrupted_byte_writes_nothing(capsys, tmp_path, cube_cds):
    """Every byte of the file flipped (xor 0xff) and one bit of each, every truncation point,
    and a trailing byte: a typed error naming the byte offset, and no output."""
    bad, out = tmp_path / "bad.cds", str(tmp_path / "out.off")
    data = bytearray(cube_cds)
    for i in range(len(data)):
        for mask in (0xFF, 1 << (i % 8)):
            b = data.copy()
            b[i] ^= mask
            bad.write_bytes(bytes(b))
            _refused(capsys, ["decode", str(bad), "-o", out], out)
    for cut in sorted({0, 1, 8, 35, 36, 37, len(data) // 2, len(data) - 1}):
        bad.write_bytes(bytes(data[:cut]))
        err = _refused(capsys, ["decode", str(bad), "-o", out], out)
        assert "truncated" in err and f"byte {cut}" in err
    bad.write_bytes(bytes(data) + b"\0")
    _refused(capsys, ["decode", str(bad), "-o", out], out, "trailing")
    _refused(capsys, ["info", str(bad)], out, "trailing")


def _header(n, flags=ff.FLAG_MIXED, bits=None):
    head = struct.pack("<8sHHQQI", ff.MAGIC, ff.VERSION, flags, n, 4 * n - 3 if bits is None else bits, 0)
    return head + struct.pack("<I", zlib.crc32(head) & 0xFFFFFFFF)


def test_valid_checksums_but_invalid_content_writes_nothing(capsys, tmp_path):
    """Files whose checksums are right but whose contents are not a valid encoding."""
    bad, out = tmp_path / "bad.cds", str(tmp_path / "out.off")
    # giant vertex count: refused from the header and the file size, nothing allocated
    bad.write_bytes(_header(2**31 - 1))
    _refused(capsys, ["decode", str(bad), "-o", out], out, r"truncated.*byte 36")
    bad.write_bytes(_header(8, bits=30))
    _refused(capsys, ["decode", str(bad), "-o", out], out, r"byte 20")
    # words that are not encodings: all '(' (unbalanced red word), all ')' (closes first)
    for fill in (0x00, 0xFF):
        n = 8
        conn = np.full((4 * n - 3 + 7) // 8, fill, np.uint8)
        conn[-1] &= np.uint8((0xFF << (8 * conn.size - (4 * n - 3))) & 0xFF)
        bad.write_bytes(ff.pack_cds(Words(n, conn, mixed=True)))
        _refused(capsys, ["decode", str(bad), "-o", out], out, r"file byte \d+, bit \d")


def test_bad_meshes_and_outputs_write_nothing(capsys, tmp_path):
    out = str(tmp_path / "m.cds")
    _refused(capsys, ["encode", mesh_path("3holes.off"), "-o", out], out, "genus")
    _refused(capsys, ["encode", mesh_path("cow.off"), "-o", out], out, "edge")
    _refused(capsys, ["encode", str(tmp_path / "missing.off"), "-o", out], out, "no such file")
    txt = str(tmp_path / "m.txt")
    _refused(capsys, ["encode", mesh_path("cube.off"), "-o", txt], txt, "unknown suffix '.txt'")
    nodir = str(tmp_path / "nodir" / "m.cds")
    _refused(capsys, ["encode", mesh_path("cube.off"), "-o", nodir], str(tmp_path / "x"),
             "does not exist")
    folder = tmp_path / "a_folder"  # named as a folder (it was "unknown suffix ''"), for every writer
    folder.mkdir()
    for argv in (["encode", mesh_path("cube.off")], ["decode", str(tmp_path / "missing.cds")],
                 ["polylla", mesh_path("grid.off")]):
        _refused(capsys, argv + ["-o", str(folder)], str(tmp_path / "y"), "a_folder' is a folder; give a file path")
    _refused(capsys, ["decode", str(tmp_path / "missing.cds"), "-o", str(tmp_path / "m.off")],
             str(tmp_path / "m.off"), "missing.cds: no such file")
    # an existing output is left untouched when the input is bad
    keep = tmp_path / "keep.off"
    keep.write_text("old")
    bad = tmp_path / "bad.cds"
    bad.write_bytes(b"not a cds file at all, but long enough for a header")
    assert main(["decode", str(bad), "-o", str(keep)]) == 2
    assert "bad magic" in capsys.readouterr().err and keep.read_text() == "old"


def test_python_dash_m_exit_code_and_no_traceback(tmp_path, cube_cds):
    bad = tmp_path / "bad.cds"
    bad.write_bytes(cube_cds[:-3])
    r = subprocess.run([sys.executable, "-m", "jaxcds", "decode", str(bad), "-o",
                        str(tmp_path / "o.off")], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "truncated" in r.stderr and "Traceback" not in r.stderr
    assert os.listdir(tmp_path) == ["bad.cds"]


def test_decode_and_encode_onto_a_fifo_are_refused_and_leave_it(capsys, tmp_path, cube_cds):
    """Eighth sweep: ``decode -o`` a FIFO or device replaced the node with a regular file (the
    atomic rename; as root ``-o /dev/null`` replaced /dev/null) and exited 0."""
    import stat

    src = tmp_path / "cube.cds"
    src.write_bytes(cube_cds)
    for name, argv in (("p.off", ["decode", str(src), "-o"]),
                       ("p.cds", ["encode", mesh_path("cube.off"), "-o"])):
        fifo = tmp_path / name
        os.mkfifo(fifo)
        assert main(argv + [str(fifo)]) == 2
        assert "is a FIFO, not a regular file" in capsys.readouterr().err
        assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert sorted(os.listdir(tmp_path)) == ["cube.cds", "p.cds", "p.off"]


def test_decode_verify_without_a_structure_is_refused_before_reading(capsys, tmp_path, cube_cds):
    """``--verify`` checks the decoded structure against the half-edge: with ``--structure
    none`` there is none, refused by name before the file is read and nothing written."""
    cds = tmp_path / "c.cds"
    cds.write_bytes(cube_cds)
    out = str(tmp_path / "c.off")
    _refused(capsys, ["decode", str(cds), "-o", out, "--structure", "none", "--verify"], out,
             r"--verify needs a decoded structure \(--structure cds6n\|cds5n\|cds4n\)")
