"""``jaxcds polylla`` (issue 7): JSON keys, the reference's 17 polygons of points50.1 from each
input kind (Triangle files, 2-D OFF, point list), the same file on pemb, errors that write
nothing. One triangulation shape throughout (jit compiles once per shape)."""

from __future__ import annotations

import json
import os
import pathlib

import numpy as np
import pytest

from jaxcds import errors
from jaxcds import polylla_io as io
from jaxcds.algorithms import polylla as P
from jaxcds.cli import main

SHARED = pathlib.Path(os.environ.get("JAXCDS_SHARED",
                                     pathlib.Path(__file__).resolve().parents[1].parent / "shared"))
POLYLLA = SHARED / "polylla"
KEYS = {"polygons", "barrier_edge_tips", "repaired_polygons", "vertices", "triangles", "regions",
        "frontier_edges", "structure", "input", "output", "timings", "seconds"}
PHASES = {"build", "label", "traversal", "repair", "polygons"}


def _need(name: str) -> str:
    p = POLYLLA / name
    if not p.exists():
        pytest.skip(f"{p} not found")
    return str(p)


def run_json(capsys, argv):
    rc = main(argv)
    out = capsys.readouterr()
    assert rc == 0, out.err
    return json.loads(out.out)


@pytest.fixture(scope="module")
def reference():
    """The reference Polylla's 17 polygons of points50.1 as canonical cycles."""
    _, ref = io.read_polygon_off(_need("points50.1.off"))
    assert len(ref) == 17
    return P.polygons_as_cycles(ref)


@pytest.fixture(scope="module")
def halfedge_run(tmp_path_factory, reference):
    """``jaxcds polylla points50.1.node -o out.off --json`` once: (report, output bytes)."""
    out = tmp_path_factory.mktemp("he") / "out.off"
    rc = main(["polylla", _need("points50.1.node"), "-o", str(out), "--json"])
    assert rc == 0
    return out, out.read_bytes()


def test_triangle_input_json_and_off(capsys, tmp_path, reference):
    out = tmp_path / "p.off"
    d = run_json(capsys, ["polylla", _need("points50.1.node"), "-o", str(out), "--json"])
    assert KEYS <= set(d) and PHASES <= set(d["timings"])
    assert (d["polygons"], d["vertices"], d["triangles"]) == (17, 50, 83)
    assert (d["barrier_edge_tips"], d["repaired_polygons"], d["structure"]) == (0, 0, "halfedge")
    assert d["regions"] == 17 and d["output"] == str(out)
    pts, polys = io.read_polygon_off(str(out))
    assert pts.shape == (50, 2) and P.polygons_as_cycles(polys) == reference
    assert os.listdir(tmp_path) == ["p.off"]  # no temporary file left
    assert os.stat(out).st_mode & 0o777 != 0o600  # not mkstemp's private mode


def test_other_inputs_give_the_same_file(capsys, tmp_path, halfedge_run):
    """The same triangulation as a 2-D OFF file, the .ele stem, and the bare points (scipy's
    Delaunay of points50's 50 points is Triangle's points50.1): byte-identical OFF outputs where
    the triangles are listed in the same order; from the bare points (scipy lists them its own
    way) the same polygons, in the order the reference would write for scipy's list, and
    byte-identical files in canonical mode, whose output does not depend on the numbering."""
    ref_out, ref_bytes = halfedge_run
    tri = io.read_triangle(_need("points50.1.node"))
    off = tmp_path / "tri.off"
    off.write_text(f"OFF\n{tri.num_vertices} {tri.num_faces} 0\n"
                   + "".join(f"{x!r} {y!r} 0\n" for x, y in tri.points.tolist())
                   + "".join(f"3 {a} {b} {c}\n" for a, b, c in tri.faces.tolist()))
    xy = tmp_path / "pts.xy"
    np.savetxt(xy, tri.points, fmt="%.17g")
    out = tmp_path / "o.off"
    for src in (str(off), str(xy), _need("points50.1.ele")):
        d = run_json(capsys, ["polylla", src, "-o", str(out), "--json"])
        assert (d["polygons"], d["vertices"], d["triangles"]) == (17, 50, 83), src
        if src != str(xy):
            assert out.read_bytes() == ref_bytes, src
        else:
            assert P.polygons_as_cycles(io.read_polygon_off(str(out))[1]) == \
                P.polygons_as_cycles(io.read_polygon_off(str(ref_out))[1])
    canonical = []
    for src in (str(off), str(xy)):
        run_json(capsys, ["polylla", src, "-o", str(out), "--json", "--mode", "canonical"])
        canonical.append(out.read_bytes())
    assert canonical[0] == canonical[1] != ref_bytes  # canonical: another order, same polygons
    # without -o: a report, no file; text mode prints one "key: value" line per key
    assert main(["polylla", str(xy)]) == 0
    text = capsys.readouterr().out
    assert "polygons: 17" in text and "barrier_edge_tips: 0" in text
    assert sorted(os.listdir(tmp_path)) == ["o.off", "pts.xy", "tri.off"]


@pytest.mark.slow  # pemb compiles every phase for its own shape (~12-18 s CPU)
@pytest.mark.parametrize("flags", [[], ["--no-tables"]])
def test_pemb_writes_the_same_file(capsys, tmp_path, halfedge_run, flags):
    _, ref_bytes = halfedge_run
    out = tmp_path / "pemb.off"
    d = run_json(capsys, ["polylla", _need("points50.1.node"), "-o", str(out), "-s", "pemb",
                          "--json", *flags])
    assert d["structure"] == "pemb" and d["polygons"] == 17
    assert d["tables"] is (not flags)
    assert out.read_bytes() == ref_bytes


def test_structure_choices_are_polyllas_border_structures():
    """``-s`` offers every structure Polylla runs on (it offered halfedge and pemb only, while
    lr / lr-bits give the same polygons); the parser reads Polylla's own list
    (``polylla_io.BORDER_STRUCTURES``, no JAX import at parser time)."""
    from jaxcds.cli import _parser

    assert P.BORDER_STRUCTURES == ("halfedge", "pemb", "lr", "lr-bits")
    for name in P.BORDER_STRUCTURES:
        assert _parser().parse_args(["polylla", "x.node", "-s", name]).structure == name
    with pytest.raises(SystemExit):
        _parser().parse_args(["polylla", "x.node", "-s", "cds6n"])


@pytest.mark.slow  # lr / lr-bits compile every phase for their own shapes (~20 s CPU each)
@pytest.mark.parametrize("structure", ["lr", "lr-bits"])
def test_laced_rings_write_the_same_file(capsys, tmp_path, halfedge_run, structure):
    _, ref_bytes = halfedge_run
    out = tmp_path / f"{structure}.off"
    d = run_json(capsys, ["polylla", _need("points50.1.node"), "-o", str(out), "-s", structure,
                          "--json"])
    assert d["structure"] == structure and d["polygons"] == 17
    assert out.read_bytes() == ref_bytes


def test_no_tables_flag_reaches_the_run(capsys, tmp_path, halfedge_run):
    """``--no-tables`` on the half-edge (whose arrays are its tables): same file, reported."""
    _, ref_bytes = halfedge_run
    out = tmp_path / "he.off"
    d = run_json(capsys, ["polylla", _need("points50.1.node"), "-o", str(out), "--no-tables",
                          "--json"])
    assert d["tables"] is False and d["polygons"] == 17
    assert out.read_bytes() == ref_bytes


def _refused(capsys, argv, out, match):
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2 and match in err and "Traceback" not in err, err
    assert not os.path.exists(out)


def test_a_lone_node_file_is_triangulated_as_a_point_set(capsys, tmp_path):
    """Sweep 53b: a .node alone was refused ("p.ele does not exist"), but it is Triangle's own
    input format for a point set (``triangle p.node`` writes its Delaunay triangulation), so
    it is triangulated as an .xy list is now (attributes and markers ignored), and the report
    says so; by either spelling of the input. An .ele named but missing is still refused."""
    pts = np.random.default_rng(3).random((12, 2))
    lines = [f"{i + 1} {x!r} {y!r} 7.5 {i % 2}" for i, (x, y) in enumerate(pts.tolist())]
    (tmp_path / "p.node").write_text("# points\n12 2 1 1\n" + "\n".join(lines) + "\n")
    (tmp_path / "p.xy").write_text("".join(f"{x!r} {y!r}\n" for x, y in pts.tolist()))
    out = tmp_path / "o.off"
    for given in ("p.node", "p"):
        rep = run_json(capsys, ["polylla", str(tmp_path / given), "-o", str(out), "--json"])
        assert rep["triangles"] == io.read_input(str(tmp_path / "p.xy")).num_faces
        assert "p.node has no .ele beside it: its 12 points were Delaunay-triangulated" in rep["notes"][0]
    tri = io.read_input(str(tmp_path / "p.node"))
    np.testing.assert_array_equal(tri.points, pts)
    np.testing.assert_array_equal(tri.faces, io.read_input(str(tmp_path / "p.xy")).faces)
    refused = str(tmp_path / "x.off")
    _refused(capsys, ["polylla", str(tmp_path / "p.ele"), "-o", refused], refused,
             "p.node: its triangles file p.ele does not exist")
    with pytest.raises(errors.PolyllaError, match=r"give the .node alone or the points as \.xy"):
        io.read_triangle(str(tmp_path / "p.node"), ele=str(tmp_path / "p.ele"))


def test_errors_write_nothing(capsys, tmp_path):
    out = str(tmp_path / "o.off")
    _refused(capsys, ["polylla", str(tmp_path / "missing.off"), "-o", out], out, "no such file")
    quad = tmp_path / "q.off"
    quad.write_text("OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n")
    _refused(capsys, ["polylla", str(quad), "-o", out], out, "face 0 has 4 vertices")
    tri = tmp_path / "t.off"
    tri.write_text("OFF\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n5 5 0\n3 0 1 2\n3 0 2 3\n")
    _refused(capsys, ["polylla", str(tri), "-o", str(tmp_path / "o.obj")],
             str(tmp_path / "o.obj"), "unknown suffix '.obj'")
    # pemb is chosen (and refuses the unused vertex 4 by name) before anything is compiled
    _refused(capsys, ["polylla", str(tri), "-o", out, "-s", "pemb"], out, "vertex 4 is in no face")
    with pytest.raises(SystemExit) as exc:  # argparse: not a structure Polylla runs on
        main(["polylla", str(tri), "-s", "cds6n"])
    assert exc.value.code == 2 and "invalid choice" in capsys.readouterr().err
    keep = tmp_path / "keep.off"
    keep.write_text("old")
    assert main(["polylla", str(quad), "-o", str(keep)]) == 2
    assert keep.read_text() == "old"
    capsys.readouterr()


_BAD_INPUTS = {
    "negnode.node": ("-1 2 0 0\n", "negnode.ele", "1 3 0\n1 1 2 3\n", "vertex count -1, expected at least 3"),
    "negele.node": ("3 2 0 0\n0 0 0\n1 1 0\n2 0 1\n", "negele.ele", "-1 3 0\n",
                    "triangle count -1, expected at least 1"),
    "baddim.node": ("3 two 0 0\n0 0 0\n1 1 0\n2 0 1\n", "baddim.ele", "1 3 0\n0 0 1 2\n",
                    "dimension 'two' is not an integer"),
    "badper.node": ("3 2 0 0\n0 0 0\n1 1 0\n2 0 1\n", "badper.ele", "1 x 0\n0 0 1 2\n",
                    "nodes per triangle 'x' is not an integer"),
    "negoff.off": ("OFF\n3 -1 0\n0 0 0\n1 0 0\n0 1 0\n", None, None, "3 vertices and -1 faces"),
    "garbage.npy": ("garbage, not an npy file\n", None, None, "not a numeric .npy array"),
}


@pytest.mark.parametrize("name", list(_BAD_INPUTS))
def test_bad_headers_are_named_not_tracebacks(name, capsys, tmp_path):
    """Negative or non-numeric header fields used to escape as IndexError / ValueError."""
    text, ele, ele_text, message = _BAD_INPUTS[name]
    (tmp_path / name).write_text(text)
    if ele:
        (tmp_path / ele).write_text(ele_text)
    out = str(tmp_path / "o.off")
    _refused(capsys, ["polylla", str(tmp_path / name), "-o", out], out, message)


def test_the_input_file_as_output_is_refused_and_left(capsys, tmp_path):
    """Sweep 15b: ``polylla IN.off -o IN.off`` replaced the triangulation with its polygon mesh
    and exited 0 (the input lost; a second run then refused 'face 0 has 4 vertices'); ``decode
    F -o F`` of a .cds file named .off likewise. Also through a hard link and a relative path."""
    tri = tmp_path / "t.off"
    text = "OFF\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n"
    tri.write_text(text)
    os.link(tri, tmp_path / "hard.off")
    cds = tmp_path / "c.off"
    cds.write_bytes(b"\x89CDS\r\n\x1a\n")  # refused before it is read
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        for argv in (["polylla", str(tri), "-o", str(tri)], ["polylla", str(tri), "-o", "hard.off"],
                     ["polylla", "t.off", "-o", str(tri), "--json"], ["decode", "c.off", "-o", str(cds)]):
            assert main(argv) == 2, argv
            err = capsys.readouterr().err
            assert "is the input file" in err and "Traceback" not in err, err
    finally:
        os.chdir(cwd)
    assert tri.read_text() == text and cds.read_bytes() == b"\x89CDS\r\n\x1a\n"
    assert sorted(os.listdir(tmp_path)) == ["c.off", "hard.off", "t.off"]
