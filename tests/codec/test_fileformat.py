"""The .cds container: round trips on shared meshes, and every kind of bad input gives a typed
error naming where (docs/cds-format.md)."""

import os
import struct
import zlib

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from jaxcds import errors
from jaxcds.codec import cds_info, decode_file, encode_file, read_cds, write_cds
from jaxcds.codec import fileformat as ff
from jaxcds.codec.words import Words, pack
from jaxcds.generators import icosphere

from codec_helpers import canon_faces, fig9
from conftest import CLOSED_GENUS0, HIGHER_GENUS, HOLED_GENUS0, load_shared, mesh_params

CORPUS = os.path.join(os.path.dirname(__file__), "corpus")


@pytest.mark.parametrize("name", mesh_params(CLOSED_GENUS0 + HOLED_GENUS0))
def test_shared_mesh_round_trip(name, tmp_path):
    m = load_shared(name)
    path = tmp_path / "m.cds"
    rep = write_cds(path, m)
    assert rep["bits_per_vertex"] <= 4.0
    m2, info = read_cds(path)
    assert m2.num_vertices == m.num_vertices
    assert np.array_equal(m2.vertices, m.vertices.astype(np.float32).astype(np.float64))
    assert canon_faces(m2.faces) == canon_faces(m.faces)
    assert info["connectivity_bits"] == 4 * info["num_vertices_encoded"] - 3


@pytest.mark.parametrize("name", HIGHER_GENUS)
def test_higher_genus_is_refused_and_no_file_left(name, tmp_path):
    path = tmp_path / "g.cds"
    with pytest.raises(errors.UnsupportedTopologyError):
        write_cds(path, load_shared(name))
    assert os.listdir(tmp_path) == []


def test_decoded_order_without_permutation(tmp_path):
    m = icosphere(2)
    path = tmp_path / "i.cds"
    write_cds(path, m, keep_order=False)
    m2, info = read_cds(path)
    assert not info["has_order"] and info["file_bytes"] == ff.file_size(m.num_vertices, ff.FLAG_MIXED | ff.FLAG_GEOMETRY)
    # same triangles up to a renumbering: positions identify the vertices
    key = {tuple(p): i for i, p in enumerate(m.vertices.astype(np.float32).tolist())}
    remap = np.array([key[tuple(p)] for p in m2.vertices.astype(np.float32).tolist()])
    assert canon_faces(remap[m2.faces]) == canon_faces(m.faces)


def test_info_and_cli_helpers(tmp_path):
    src = tmp_path / "ico.off"
    m = icosphere(2)
    from jaxcds.codec import write_mesh_atomic
    write_mesh_atomic(src, m)
    rep = encode_file(src, tmp_path / "ico.cds")
    assert rep["file_bytes"] < rep["binary_off_bytes"]
    info = cds_info(tmp_path / "ico.cds")
    assert info["vertices"] == m.num_vertices and info["genus"] == 0 and info["closed"]
    assert info["connectivity_bits"] == 4 * m.num_vertices - 3
    assert info["bits_per_vertex"] == round((4 * m.num_vertices - 3) / m.num_vertices, 4)
    for ext in (".off", ".obj", ".ply"):
        out = tmp_path / ("back" + ext)
        r = decode_file(tmp_path / "ico.cds", out)
        assert r["vertices"] == m.num_vertices and out.exists()
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".tmp")) == []



@pytest.mark.parametrize("shift,scale", [(1e8, 1.0), (0.0, 1e-310)])
def test_vertices_that_float32_merges_are_refused_and_no_file_left(tmp_path, shift, scale):
    """Robustness sweep: a unit sphere at 1e8 (float32 steps of 8 there) or at 1e-310
    (subnormal: float32 makes every coordinate 0) was encoded without a word into a file whose
    vertices all coincide. Refused, naming the two vertices; nothing written."""
    import dataclasses

    m = icosphere(1)
    far = dataclasses.replace(m, vertices=m.vertices * scale + shift)
    with pytest.raises(errors.MeshError, match=r"vertices \d+ .* and \d+ .* are one point in float32"):
        write_cds(tmp_path / "far.cds", far)
    assert os.listdir(tmp_path) == []
    write_cds(tmp_path / "near.cds", dataclasses.replace(m, vertices=m.vertices + 1e4))  # still apart


def test_genus_refusal_of_the_encoder_names_the_file(tmp_path):
    """The encoder's genus refusal named only the counts (the Schnyder wood's check); it names
    the mesh, its genus and the structures that take it, as `jaxcds build` does."""
    import trimesh

    from jaxcds.mesh import load_mesh

    t = trimesh.creation.torus(1.0, 0.3, major_sections=12, minor_sections=6)
    path = tmp_path / "torus.off"
    path.write_text(t.export(file_type="off"))
    with pytest.raises(errors.UnsupportedTopologyError, match=r"torus\.off: .* genus 1 .*'lr'"):
        write_cds(tmp_path / "t.cds", load_mesh(path))
    assert sorted(os.listdir(tmp_path)) == ["torus.off"]


def test_encoder_refusals_do_not_advise_building_or_packing(tmp_path):
    """Sweep 52a (gmsh's two spheres in one file, a torus): `jaxcds encode` answered "pack them
    into one: jaxcds.batch.pack(split_components(mesh), name)" (a placeholder, and a batch is no
    encoding) and "use the 'lr' or 'halfedge' structure for it", as if one could encode with
    them; it says what the encoding cannot take and what to do with the mesh instead."""
    import trimesh

    from jaxcds.mesh import load_mesh

    ico = icosphere(1)
    v, f = ico.vertices, ico.faces
    two = load_mesh(np.concatenate([v, v + 3.0]), np.concatenate([f, f + len(v)]))
    with pytest.raises(errors.UnsupportedTopologyError, match="2 components") as refused:
        write_cds(tmp_path / "two.cds", two)
    assert "pack" not in str(refused.value) and "split_components(mesh)" in str(refused.value)
    t = trimesh.creation.torus(1.0, 0.3, major_sections=12, minor_sections=6)
    with pytest.raises(errors.UnsupportedTopologyError, match="genus 1") as refused:
        write_cds(tmp_path / "t.cds", load_mesh(t))
    assert "use the 'lr'" not in str(refused.value) and "keep it as a mesh file" in str(refused.value)
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("ext", [".off", ".obj", ".ply"])
def test_decoded_mesh_files_keep_every_float32_digit(tmp_path, ext):
    """Robustness sweep: `jaxcds decode -o x.obj|x.off` wrote the coordinates with trimesh's
    fixed 8 / 10 decimals, so a mesh in small units (1e-9: every vertex 0) or 1.2345678e-5
    (two digits lost) came back wrong without a word. The written file now reads back to the
    float32 geometry of the .cds file exactly."""
    import dataclasses

    from jaxcds.codec import write_mesh_atomic
    from jaxcds.mesh import load_mesh

    m = icosphere(1)
    for scale in (1e-9, 1.2345678e-5, 3e30):
        small = dataclasses.replace(m, vertices=m.vertices * scale)
        write_cds(tmp_path / "s.cds", small)
        out = tmp_path / ("s" + ext)
        decode_file(tmp_path / "s.cds", out)
        back = load_mesh(out, weld=False)
        ref, _ = read_cds(tmp_path / "s.cds")
        assert np.array_equal(back.vertices.astype(np.float32), ref.vertices.astype(np.float32))
        assert np.array_equal(back.faces, ref.faces)
    if ext == ".ply":  # trimesh's PLY holds float32
        return
    v = np.array([[1e-300, 0, 0], [1 / 3, 1, 0], [0, 0, 1e300], [1, 1, 1]])  # float64 exact too
    f = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]], dtype=np.int32)
    write_mesh_atomic(tmp_path / ("d" + ext), load_mesh(v, f))
    assert np.array_equal(load_mesh(tmp_path / ("d" + ext), weld=False).vertices, v)

def test_writers_refuse_a_folder_or_a_missing_folder_before_any_work(tmp_path, monkeypatch):
    """write_cds / write_mesh_atomic onto a folder, into a folder that does not exist, or when
    the OS refuses the write: an OutputError naming the path, no temporary file left."""
    from jaxcds.codec import api, write_mesh_atomic

    m = icosphere(1)
    (tmp_path / "adir").mkdir()
    (tmp_path / "b.off").mkdir()
    with pytest.raises(errors.OutputError, match="adir' is a folder"):
        write_cds(tmp_path / "adir", m)
    with pytest.raises(errors.OutputError, match="does not exist"):
        write_cds(tmp_path / "nope" / "x.cds", m)
    with pytest.raises(errors.OutputError, match="b.off' is a folder"):
        write_mesh_atomic(tmp_path / "b.off", m)
    with pytest.raises(errors.OutputError, match="unknown suffix '.txt'"):
        write_mesh_atomic(tmp_path / "x.txt", m)
    calls = []
    monkeypatch.setattr(api, "encode_mesh", lambda *a, **k: calls.append(1))
    with pytest.raises(errors.OutputError):
        write_cds(tmp_path / "adir", m)
    assert calls == []  # refused before encoding
    monkeypatch.undo()

    def full(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(ff.os, "fsync", full)
    with pytest.raises(errors.OutputError, match="x.cds.*No space left"):
        write_cds(tmp_path / "x.cds", m)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["adir", "b.off"]  # nothing half written


def test_writers_refuse_a_device_or_fifo_in_place_of_the_output(tmp_path):
    """Eighth sweep: the atomic write renamed its temporary file over a FIFO or a device node
    (``-o /dev/null`` run as root replaced the system's /dev/null with a regular file, and
    /dev/full 'succeeded'). Such outputs are refused before any work, and left as they were."""
    import stat

    from jaxcds.codec import write_mesh_atomic
    from jaxcds.polylla_io import write_polygon_off

    m = icosphere(0)
    fifo = tmp_path / "pipe.cds"
    os.mkfifo(fifo)
    with pytest.raises(errors.OutputError, match="pipe.cds' is a FIFO, not a regular file"):
        write_cds(fifo, m)
    with pytest.raises(errors.OutputError, match="is a FIFO"):
        ff.atomic_write_bytes(fifo, b"x")
    os.mkfifo(tmp_path / "pipe.off")
    with pytest.raises(errors.OutputError, match="is a FIFO"):
        write_mesh_atomic(tmp_path / "pipe.off", m)
    with pytest.raises(errors.OutputError, match="is a FIFO"):
        write_polygon_off(str(tmp_path / "pipe.off"), np.zeros((3, 2)), np.array([0, 3]), np.array([0, 1, 2]))
    link = tmp_path / "null.off"
    link.symlink_to("/dev/null")  # a link to a device: the device is refused too
    with pytest.raises(errors.OutputError, match="null.off' is a character device"):
        write_mesh_atomic(link, m)
    assert stat.S_ISFIFO(os.stat(fifo).st_mode) and os.path.islink(link)
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["null.off", "pipe.cds", "pipe.off"]
    # a regular file in place is replaced as before
    (tmp_path / "old.cds").write_bytes(b"old")
    write_cds(tmp_path / "old.cds", m)
    assert read_cds(tmp_path / "old.cds")[0].num_vertices == 12


# ------------------------------------------------------------------------- corruption
def _small_file(tmp_path):
    path = tmp_path / "small.cds"
    write_cds(path, icosphere(0))  # 12 vertices
    return path, path.read_bytes()


def _read_bytes(tmp_path, data, name="bad.cds"):
    p = tmp_path / name
    p.write_bytes(data)
    return read_cds(p)


def _recrc_header(b: bytearray) -> bytearray:
    b[32:36] = struct.pack("<I", zlib.crc32(bytes(b[:32])) & 0xFFFFFFFF)
    return b


def test_every_single_bit_flip_is_detected(tmp_path):
    _, data = _small_file(tmp_path)
    read_cds(data)  # the intact bytes read fine
    for byte in range(len(data)):
        for bit in range(8):
            b = bytearray(data)
            b[byte] ^= 1 << bit
            with pytest.raises(errors.CodecError, match="byte"):
                read_cds(bytes(b))


@pytest.mark.parametrize("cut", [0, 5, 35, 36, 40, -5, -1])
def test_truncated(tmp_path, cut):
    _, data = _small_file(tmp_path)
    with pytest.raises(errors.FormatError, match="truncated") as exc:
        _read_bytes(tmp_path, data[:cut])
    assert "byte" in str(exc.value)


def test_wrong_magic_version_trailing(tmp_path):
    _, data = _small_file(tmp_path)
    with pytest.raises(errors.FormatError, match="magic.*byte 0"):
        _read_bytes(tmp_path, b"PLY\n" + data[4:])
    b = bytearray(data)
    b[8:10] = struct.pack("<H", 7)
    with pytest.raises(errors.FormatError, match="version 7 at byte 8"):
        _read_bytes(tmp_path, bytes(_recrc_header(b)))
    with pytest.raises(errors.FormatError, match="trailing"):
        _read_bytes(tmp_path, data + b"\0")


def test_giant_vertex_count_is_refused_before_allocating(tmp_path):
    _, data = _small_file(tmp_path)
    for n in (2**31 - 1, 2**40, 3):
        b = bytearray(data)
        b[12:20] = struct.pack("<Q", n)
        b[20:28] = struct.pack("<Q", max(4 * n - 3, 0))
        with pytest.raises(errors.FormatError, match="byte 12|truncated"):
            _read_bytes(tmp_path, bytes(_recrc_header(b)))


def test_vertex_count_and_bit_count_must_match(tmp_path):
    _, data = _small_file(tmp_path)
    b = bytearray(data)
    b[20:28] = struct.pack("<Q", 4 * 12 - 2)
    with pytest.raises(errors.FormatError, match="byte 20"):
        _read_bytes(tmp_path, bytes(_recrc_header(b)))
    b = bytearray(data)
    b[12:20] = struct.pack("<Q", 13)
    b[20:28] = struct.pack("<Q", 4 * 13 - 3)
    with pytest.raises(errors.FormatError, match="truncated|trailing"):
        _read_bytes(tmp_path, bytes(_recrc_header(b)))


def _file_with_words(words: Words, **kw) -> bytes:
    return ff.pack_cds(words, **kw)


def test_invalid_words_with_valid_checksums(tmp_path):
    w = fig9()
    bits = w.unpacked().copy()
    bits[5] ^= 1  # unbalanced red word
    bad = Words(10, pack(bits))
    with pytest.raises(errors.EncodingError, match=r"bit 6 of the red word .*file byte 36, bit 6"):
        _read_bytes(tmp_path, _file_with_words(bad))
    bits = w.unpacked().copy()
    bits[20 + 7] ^= 1  # a black count changed
    with pytest.raises(errors.EncodingError, match="black"):
        _read_bytes(tmp_path, _file_with_words(Words(10, pack(bits))))


def test_order_must_be_a_permutation(tmp_path):
    w = fig9()
    order = np.arange(10)
    order[3] = 4
    with pytest.raises(errors.FormatError, match="not a permutation"):
        _read_bytes(tmp_path, _file_with_words(w, order=order))
    order[3] = 99
    with pytest.raises(errors.FormatError, match="byte"):
        _read_bytes(tmp_path, _file_with_words(w, order=order))


def test_non_finite_geometry(tmp_path):
    pos = np.zeros((10, 3), np.float32)
    pos[6, 1] = np.nan
    with pytest.raises(errors.FormatError, match="vertex 6 at byte"):
        _read_bytes(tmp_path, _file_with_words(fig9(), positions=pos))


def test_missing_file(tmp_path):
    with pytest.raises(errors.FormatError, match="nope.cds: no such file"):
        read_cds(tmp_path / "nope.cds")
    (tmp_path / "dir.cds").mkdir()  # a directory, FIFO or device: refused before reading
    with pytest.raises(errors.FormatError, match="dir.cds: is a directory, not a regular file"):
        read_cds(tmp_path / "dir.cds")


# ------------------------------------------------------------------------- fuzzing
def _expect_codec_error_or_ok(tmp_path, data: bytes):
    p = tmp_path / "fuzz.cds"
    p.write_bytes(data)
    try:
        read_cds(p)
    except errors.CodecError:
        pass


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.binary(min_size=0, max_size=200))
def test_fuzz_random_bytes(tmp_path, blob):
    _expect_codec_error_or_ok(tmp_path, ff.MAGIC + blob)


@settings(max_examples=300, deadline=None)
@given(n=st.integers(4, 40), data=st.data())
def test_fuzz_decoder_on_random_words(n, data):
    """Arbitrary bit strings of the right length: a decoded triangulation or an EncodingError,
    never a crash or a hang; mixed and separate forms both."""
    from jaxcds.codec import decode_faces

    nb = 4 * n - 3
    bits = np.array(data.draw(st.lists(st.integers(0, 1), min_size=nb, max_size=nb)), dtype=np.uint8)
    for mixed in (False, True):
        try:
            faces, _ = decode_faces(Words(n, pack(bits), mixed=mixed))
        except errors.EncodingError:
            continue
        from codec_helpers import is_closed_sphere
        assert is_closed_sphere(faces, n)


@settings(max_examples=200, deadline=None)
@given(n=st.integers(4, 30), seed=st.integers(0, 2**31 - 1), flips=st.integers(1, 3))
def test_fuzz_mutated_valid_words(n, seed, flips):
    """Valid words with a few bits flipped (checksums recomputed): sphere or EncodingError."""
    from jaxcds.codec import decode_faces
    from codec_helpers import is_closed_sphere, random_words

    rng = np.random.default_rng(seed)
    w = random_words(n, rng)
    bits = w.unpacked().copy()
    for i in rng.integers(0, bits.size, flips):
        bits[i] ^= 1
    try:
        faces, _ = decode_faces(Words(n, pack(bits)))
    except errors.EncodingError:
        return
    assert is_closed_sphere(faces, n)


def test_corpus_regressions(tmp_path):
    """Inputs kept from fuzzing (tests/codec/corpus/*.cds): each must raise a CodecError."""
    files = sorted(f for f in os.listdir(CORPUS) if f.endswith(".cds")) if os.path.isdir(CORPUS) else []
    for f in files:
        with pytest.raises(errors.CodecError):
            read_cds(os.path.join(CORPUS, f))


def _with_dummy_mask(data: bytes, mask: np.ndarray) -> bytes:
    """``data`` (a .cds without a dummy mask) with ``mask`` appended as its dummy section and
    every checksum made right: only the mask's meaning is wrong."""
    out = bytearray(data)
    n = struct.unpack_from("<Q", out, 12)[0]
    bits = np.packbits(mask[:n]).tobytes()
    out += bits + struct.pack("<I", zlib.crc32(bits))
    struct.pack_into("<H", out, 10, struct.unpack_from("<H", out, 10)[0] | ff.FLAG_DUMMY)
    struct.pack_into("<I", out, 32, zlib.crc32(bytes(out[:32])))
    return bytes(out)


@pytest.mark.parametrize("flagged", ["all", "two neighbours"])
def test_a_dummy_mask_close_boundaries_cannot_write_is_refused(flagged, tmp_path):
    """Dummy vertices are the apexes of hole-closing fans: never two on one face, and some face
    has none. A mask (checksums right) that breaks this used to decode to an empty or wrongly
    holed mesh with exit 0; now a FormatError names the mask's bytes, and no output is written."""
    m = icosphere(1)
    path = tmp_path / "ok.cds"
    write_cds(path, m)
    n = m.num_vertices
    decoded = read_cds(path, original_order=False)[0].faces  # the mask's bits: decoded ids
    mask = np.ones(n, bool) if flagged == "all" else np.isin(np.arange(n), decoded[0][:2])
    data = _with_dummy_mask(path.read_bytes(), mask)
    with pytest.raises(errors.FormatError, match=r"dummy mask \(bytes from \d+\)"):
        read_cds(data)
    bad = tmp_path / "bad.cds"
    bad.write_bytes(data)
    with pytest.raises(errors.FormatError):
        decode_file(bad, tmp_path / "out.off")
    assert not (tmp_path / "out.off").exists()


def test_a_dummy_mask_of_a_real_hole_still_reads(tmp_path):
    m = icosphere(1)
    keep = np.ones(m.num_faces, bool)
    keep[0] = False  # one triangular hole
    from jaxcds.mesh import load_mesh
    opened = load_mesh((m.vertices, m.faces[keep]))
    path = tmp_path / "h.cds"
    write_cds(path, opened)
    m2, info = read_cds(path)
    assert info["dummy_vertices"] == 1 and m2.num_faces == opened.num_faces


def test_dummy_mask_padding_bits_must_be_zero(tmp_path):
    """As in the connectivity section: the bits past vertex n - 1 in the mask's last byte."""
    m = icosphere(1)  # 42 vertices: the mask's last byte has 6 padding bits
    path = tmp_path / "ok.cds"
    write_cds(path, m)
    out = bytearray(_with_dummy_mask(path.read_bytes(), np.zeros(42, bool)))
    n_bytes = 6  # ceil(42 / 8), then its CRC-32
    start = len(out) - 4 - n_bytes
    out[start + n_bytes - 1] |= 1  # the last padding bit (MSB first)
    struct.pack_into("<I", out, len(out) - 4, zlib.crc32(bytes(out[start:start + n_bytes])))
    with pytest.raises(errors.FormatError, match=rf"non-zero padding bits in byte {start + n_bytes - 1} \(dummy mask"):
        read_cds(bytes(out))


def test_input_names_the_file_and_odd_inputs_are_typed(tmp_path):
    """Eighth sweep: read_cds / cds_info errors named the byte but not the file; cds_info on the
    file's bytes (which read_cds takes) raised ValueError ('embedded null byte': it reopened the
    bytes as a path); a str holding a NUL, an int or None raised ValueError / TypeError."""
    from jaxcds.codec import cds_info

    path, data = _small_file(tmp_path)
    (tmp_path / "cut.cds").write_bytes(data[:50])
    for f in (read_cds, cds_info):
        with pytest.raises(errors.FormatError, match=r"cut.cds: truncated .cds file: 50 bytes"):
            f(tmp_path / "cut.cds")
    b = bytearray(data)
    b[40] ^= 1
    (tmp_path / "flip.cds").write_bytes(bytes(b))
    with pytest.raises(errors.FormatError, match=r"flip.cds: checksum mismatch in the connectivity"):
        read_cds(tmp_path / "flip.cds")
    rep = cds_info(data)  # the bytes, as read_cds takes them
    assert rep["vertices"] == 12 and rep["format_version"] == ff.VERSION
    assert rep["file_bytes"] == len(data) == cds_info(path)["file_bytes"]
    with pytest.raises(errors.FormatError, match="truncated"):
        cds_info(data[:40])
    with pytest.raises(errors.FormatError, match=r"not a file name \(it holds a NUL"):
        read_cds(data.decode("latin-1"))
    for bad in (3, None):
        with pytest.raises(errors.ArgumentError, match="a .cds input is a path or the file's bytes"):
            read_cds(bad)


def test_geometry_past_float32_is_refused_not_written_as_inf(tmp_path):
    """Eighth sweep: a vertex at 1e39 (finite in float64) was cast to float32 inf and written;
    read_cds then refused the file it had written ('non-finite coordinate'). Refused before the
    write, no file left; geometry=False still writes."""
    m = icosphere(0)
    v = m.vertices.copy()
    v[5] = [1e39, 0.0, 0.0]
    from jaxcds.mesh import TriMesh

    big = TriMesh(vertices=v, faces=m.faces)
    with pytest.raises(errors.NonFiniteCoordinateError, match=r"vertex 5 .*past float32's range"):
        write_cds(tmp_path / "big.cds", big)
    assert list(tmp_path.iterdir()) == []
    write_cds(tmp_path / "nogeo.cds", big, geometry=False)
    assert read_cds(tmp_path / "nogeo.cds")[0].num_vertices == 12


def test_an_output_in_place_keeps_its_mode_and_links(tmp_path):
    """Stop 44's sweep left: ``-o`` onto an existing file replaced it with default permissions
    (0666 & ~umask), and onto a symbolic link replaced the link by a plain file, the file it
    named keeping its old contents. The file in place keeps its permission bits; the link keeps
    pointing at its file, which gets the new contents."""
    import stat

    old = tmp_path / "old.bin"
    old.write_bytes(b"old")
    os.chmod(old, 0o640)
    ff.atomic_write_bytes(old, b"new")
    assert old.read_bytes() == b"new" and stat.S_IMODE(os.stat(old).st_mode) == 0o640
    os.chmod(old, 0o751)
    ff.atomic_write_bytes(old, b"newer")
    assert stat.S_IMODE(os.stat(old).st_mode) == 0o751

    (tmp_path / "sub").mkdir()
    real = tmp_path / "sub" / "real.off"
    real.write_bytes(b"old")
    os.chmod(real, 0o600)
    link = tmp_path / "link.off"
    link.symlink_to(real)
    ff.atomic_write_bytes(link, b"through")
    assert os.path.islink(link) and os.readlink(link) == str(real)
    assert real.read_bytes() == b"through" and stat.S_IMODE(os.stat(real).st_mode) == 0o600
    # a dangling link: the file it names is created, with the usual mode
    dangling = tmp_path / "dangling.off"
    dangling.symlink_to(tmp_path / "sub" / "made.off")
    ff.atomic_write_bytes(dangling, b"made")
    assert os.path.islink(dangling) and (tmp_path / "sub" / "made.off").read_bytes() == b"made"
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(os.stat(tmp_path / "sub" / "made.off").st_mode) == 0o666 & ~umask
    # no temporary file left in either folder
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dangling.off", "link.off", "old.bin", "sub"]
    assert sorted(p.name for p in (tmp_path / "sub").iterdir()) == ["made.off", "real.off"]


def test_codec_file_functions_name_arguments_of_the_wrong_kind(tmp_path):
    """write_cds(None, mesh) raised os.fspath's TypeError; encode_file(arrays or a TriMesh, out)
    encoded and wrote the file, then raised TypeError from os.path.getsize; write_mesh_atomic of
    a tuple an AttributeError; decode_file(verify=True) without a structure ignored verify; and
    the bool flags of write_cds / read_cds took 'no' or None as truthy / falsy (keep_order='no'
    stored the order). Each is now an ArgumentError naming the argument, nothing written."""
    from jaxcds.codec.api import write_mesh_atomic

    mesh = icosphere(1)
    v, f = mesh.vertices, mesh.faces
    with pytest.raises(errors.ArgumentError, match="output path is a str or os.PathLike, not NoneType"):
        write_cds(None, mesh)
    with pytest.raises(errors.ArgumentError, match="output path is a str or os.PathLike, not int"):
        write_mesh_atomic(3, mesh)
    out = tmp_path / "a.cds"
    with pytest.raises(errors.ArgumentError, match="encode_file: mesh_path must be a mesh file's path, got tuple"):
        encode_file((v, f), out)
    assert not out.exists()
    with pytest.raises(errors.ArgumentError, match=r"write_mesh_atomic: mesh must be a jaxcds\.mesh\.TriMesh "
                       r"\(jaxcds\.load_mesh makes one\), got tuple"):
        write_mesh_atomic(tmp_path / "m.off", (v, f))
    with pytest.raises(errors.ArgumentError, match="write_cds: keep_order must be True or False, got 'no'"):
        write_cds(out, mesh, keep_order="no")
    assert not out.exists()
    write_cds(out, mesh)
    with pytest.raises(errors.ArgumentError, match="read_cds: drop_dummies must be True or False, got None"):
        read_cds(out, drop_dummies=None)
    with pytest.raises(errors.ArgumentError, match="decode_file: verify checks the structure"):
        decode_file(out, tmp_path / "m.off", verify=True)
    assert not (tmp_path / "m.off").exists()


def test_a_read_only_output_is_refused_and_kept(tmp_path, monkeypatch):
    """Stop 49 left: the atomic write (a rename, which needs only the folder's write access)
    replaced a file its owner had made read-only, where ``open(path, 'w')`` refuses. Every writer
    (``.cds``, decoded meshes, Polylla's OFF) now refuses it before any work, and keeps it; as
    root ``os.access`` allows everything, so the mode's write bits decide. A folder that cannot
    be written is refused up front too (it was found by the temporary file, after the work)."""
    from jaxcds.codec import write_mesh_atomic
    from jaxcds.polylla_io import write_polygon_off

    m = icosphere(0)
    old = tmp_path / "kept.off"
    old.write_bytes(b"old")
    os.chmod(old, 0o444)
    for write in (lambda: write_cds(old, m), lambda: write_mesh_atomic(old, m),
                  lambda: write_polygon_off(str(old), np.zeros((3, 2)), np.array([0, 3]), np.array([0, 1, 2]))):
        with pytest.raises(errors.OutputError, match=r"kept.off' is read-only \(mode 0444\): not replaced"):
            write()
    link = tmp_path / "link.off"  # through a link, the file it names decides
    link.symlink_to(old)
    with pytest.raises(errors.OutputError, match="is read-only"):
        ff.atomic_write_bytes(link, b"new")
    assert old.read_bytes() == b"old" and sorted(p.name for p in tmp_path.iterdir()) == ["kept.off", "link.off"]
    os.chmod(old, 0o644)
    ff.atomic_write_bytes(old, b"new")
    assert old.read_bytes() == b"new"

    real_access = os.access
    monkeypatch.setattr(ff.os, "access", lambda p, m: False if os.path.isdir(p) else real_access(p, m))
    with pytest.raises(errors.OutputError, match="is not writable"):
        write_cds(tmp_path / "new.cds", m)


def _header_with(data: bytes, fmt: str, offset: int, value: int) -> bytes:
    """``data`` with one header field set to ``value`` and the header's checksum made right."""
    b = bytearray(data)
    struct.pack_into(fmt, b, offset, value)
    return bytes(_recrc_header(b))


@pytest.mark.parametrize("fmt,offset,value,msg", [
    ("<H", 10, 0x80, r"unknown flag bits 0x80 at byte 10"),
    ("<I", 28, 5, r"reserved field at byte 28 is 5, must be 0"),
])
def test_header_fields_a_reader_does_not_know_are_refused(tmp_path, fmt, offset, value, msg):
    _, data = _small_file(tmp_path)
    with pytest.raises(errors.FormatError, match=msg):
        read_cds(_header_with(data, fmt, offset, value))


def test_connectivity_padding_bits_must_be_zero(tmp_path):
    """12 vertices: 45 connectivity bits in 6 bytes, 3 padding bits in the last (checksum right)."""
    _, data = _small_file(tmp_path)
    b = bytearray(data)
    start, size = ff.HEADER_SIZE, 6
    b[start + size - 1] |= 1
    struct.pack_into("<I", b, start + size, zlib.crc32(bytes(b[start:start + size])))
    with pytest.raises(errors.FormatError, match=rf"non-zero padding bits in byte {start + size - 1} "
                                                 r"\(connectivity bits 45\.\.47\)"):
        read_cds(bytes(b))


def test_a_dummy_mask_on_every_face_is_refused(tmp_path):
    """The octahedron's two poles: no face holds both, but every face holds one, so nothing of
    the surface would be left. Both ways in: the file's mask (FormatError naming its bytes) and
    a mask given to decode (ArgumentError)."""
    from jaxcds.codec import decode
    from jaxcds.mesh import load_mesh

    v = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    f = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    path = tmp_path / "octa.cds"
    write_cds(path, load_mesh((v, f)))
    mesh, _, words = read_cds(path, original_order=False, return_words=True)
    neighbours = np.zeros((6, 6), bool)
    neighbours[mesh.faces, np.roll(mesh.faces, 1, axis=1)] = True
    pole = int(np.flatnonzero(~neighbours[0] & (np.arange(6) != 0))[0])  # vertex 0's antipode
    mask = np.isin(np.arange(6), [0, pole])
    with pytest.raises(errors.FormatError, match=r"dummy mask \(bytes from \d+\) leaves no face without a "
                                                 r"dummy vertex: the mask is corrupted"):
        read_cds(_with_dummy_mask(path.read_bytes(), mask))
    with pytest.raises(errors.ArgumentError, match=r"dummy mask leaves no face without a dummy vertex: "
                                                   r"the mask does not fit this mesh"):
        decode(words, structure="cds6n", dummy=mask)


@pytest.mark.parametrize("structure,got", [(np.array(["cds6n", "cds5n"]), "a ndarray"), ("cds7n", "'cds7n'")])
def test_decode_file_names_an_unknown_structure_before_reading(tmp_path, structure, got):
    """An array raised numpy's untyped 'truth value' ValueError; a misspelt name was refused only
    after the file was read and decoded. The file here does not exist: the argument comes first."""
    with pytest.raises(errors.ArgumentError, match=rf"decode_file: unknown structure {got}: 'cds6n', 'cds5n', "
                                                   r"'cds4n' or None"):
        decode_file(tmp_path / "missing.cds", tmp_path / "out.off", structure=structure)
    assert not (tmp_path / "out.off").exists()


def test_a_temporary_file_the_os_refuses_is_an_output_error(tmp_path, monkeypatch):
    """The atomic write's temporary file refused (a full inode table, a quota): named with the
    output path; nothing is left behind."""
    def refused(*a, **k):
        raise OSError(122, "Disk quota exceeded")

    monkeypatch.setattr(ff.tempfile, "mkstemp", refused)
    with pytest.raises(errors.OutputError, match=r"cannot write '.*x.cds': Disk quota exceeded"):
        ff.atomic_write_bytes(tmp_path / "x.cds", b"data")
    assert list(tmp_path.iterdir()) == []
