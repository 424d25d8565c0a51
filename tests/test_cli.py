"""The `jaxcds` command line: JSON keys, exit codes, no tracebacks."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from jaxcds.cli import main

from conftest import mesh_path

INFO_KEYS = {"vertices", "edges", "faces", "components", "boundary_loops", "euler_characteristic",
             "genus", "manifold", "orientable", "welded_vertices", "defects"}
BUILD_KEYS = {"structure", "vertices", "faces", "references", "references_per_vertex", "bytes"}


def run_json(capsys, argv):
    rc = main(argv)
    out = capsys.readouterr().out
    return rc, json.loads(out)


def test_info_json(capsys):
    rc, d = run_json(capsys, ["info", mesh_path("bunny.off"), "--json"])
    assert rc == 0 and INFO_KEYS <= set(d)
    assert d["vertices"] == 3485 and d["genus"] == 0 and d["manifold"] is True


def test_info_reports_defects_of_a_defective_mesh(capsys):
    rc, d = run_json(capsys, ["info", mesh_path("cow.off"), "--json"])
    assert rc == 0 and d["manifold"] is False and any("NonManifoldEdge" in x for x in d["defects"])


def test_no_weld_keeps_coincident_vertices_apart(capsys):
    """``--no-weld`` on info / build / encode: cow.off, refused once welded (its message says
    so), is a closed genus-0 manifold as written and builds and verifies as such."""
    rc, d = run_json(capsys, ["info", mesh_path("cow.off"), "--json", "--no-weld"])
    assert rc == 0 and d["manifold"] is True and d["genus"] == 0 and d["welded_vertices"] == 0, d
    rc, d = run_json(capsys, ["build", mesh_path("cow.off"), "-s", "cds5n", "--no-weld", "--verify",
                              "--json"])
    assert rc == 0 and d["mismatches"] == 0 and d["vertices"] == 2762, d
    assert main(["build", mesh_path("cow.off"), "-s", "cds5n"]) != 0
    assert "--no-weld" in capsys.readouterr().err


def test_encode_no_weld(capsys, tmp_path):
    out = tmp_path / "cow.cds"
    assert main(["encode", mesh_path("cow.off"), "-o", str(out), "--no-weld", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["vertices"] == 2762 and out.stat().st_size > 0


def test_build_verify_json(capsys):
    rc, d = run_json(capsys, ["build", mesh_path("grid.off"), "--structure", "corner-table",
                              "--verify", "--json"])
    assert rc == 0 and BUILD_KEYS <= set(d)
    assert d["mismatches"] == 0 and d["checked"] > 0 and d["closed_boundaries"] is True


def test_build_refuses_defective_mesh_with_exit_2(capsys):
    rc = main(["build", mesh_path("cow.off"), "--structure", "halfedge"])
    err = capsys.readouterr().err
    assert rc == 2 and "non-manifold" not in err.lower() or "shared by 4 faces" in err
    assert "Traceback" not in err


def test_unknown_structure(capsys):
    assert main(["build", mesh_path("cube.off"), "--structure", "nope"]) == 2
    assert "unknown structure" in capsys.readouterr().err


def test_build_lr_ring_sweeps(capsys):
    """``--ring-sweeps``: the LR ring search, its gain reported; refused for other structures."""
    rc, plain = run_json(capsys, ["build", mesh_path("bunny.off"), "-s", "lr", "--json"])
    rc2, searched = run_json(capsys, ["build", mesh_path("bunny.off"), "-s", "lr", "--json",
                                      "--ring-sweeps", "20"])
    assert rc == rc2 == 0 and plain["ring_search_gain"] == 0
    assert searched["ring_search_gain"] > 0
    assert searched["references"] == plain["references"] - searched["ring_search_gain"]
    assert searched["references_per_triangle"] < plain["references_per_triangle"]
    assert main(["build", mesh_path("cube.off"), "-s", "cds6n", "--ring-sweeps", "5"]) == 2
    assert "--ring-sweeps applies to lr and lr-bits" in capsys.readouterr().err


def test_demo_on_a_small_mesh(capsys, tmp_path, monkeypatch):
    """The demo's whole job (structures built, verified, degrees and normals compared) on the
    cube with one side open (a hole: the corner table is built on the closed copy, a CDS closes
    it itself, the half-edge takes it open; the demo stopped at the corner table with exit 2
    before). Three structures, one of each kind of hole handling: every structure's demo row
    costs a verify compilation (all nine took 96-132 s of CI); the bundled bunny with all nine
    is `make demo` itself and the slow test below."""
    from jaxcds.mesh import load_mesh
    from jaxcds.structures import registry

    kinds = ["halfedge", "corner-table", "cds5n"]
    monkeypatch.setattr(registry, "names", lambda: list(kinds))

    cube = load_mesh(mesh_path("cube.off"))
    f = cube.faces
    # face 0 and the face across its first edge: a quad hole
    nb = next(i for i in range(1, len(f)) if {f[0][0], f[0][1]} <= set(f[i].tolist()))
    keep = [x for i, x in enumerate(f.tolist()) if i not in (0, nb)]
    box = tmp_path / "box.off"
    with open(box, "w") as fh:
        fh.write(f"OFF\n{cube.num_vertices} {len(keep)} 0\n")
        fh.writelines(f"{x!r} {y!r} {z!r}\n" for x, y, z in cube.vertices.tolist())
        fh.writelines(f"3 {a} {b} {c}\n" for a, b, c in keep)
    assert main(["demo", str(box)]) == 0
    out = capsys.readouterr().out
    assert "closed=False" in out and "refused" not in out
    assert "all structures agree with the half-edge\n" in out
    assert all(name in out for name in kinds)
    # a mesh no structure takes is an error, not "all agree"
    bow = tmp_path / "bow.off"
    bow.write_text("OFF\n5 2 0\n0 0 0\n1 0 0\n0 1 0\n-1 0 0\n0 -1 0\n3 0 1 2\n3 0 3 4\n")
    assert main(["demo", str(bow)]) == 2
    assert "no structure accepts this mesh" in capsys.readouterr().err


def test_a_report_that_cannot_be_printed_is_one_line():
    """``> /dev/full``: the report's print failed with an OSError traceback."""
    r = subprocess.run(f"{sys.executable} -m jaxcds info {mesh_path('cube.off')} > /dev/full",
                       shell=True, capture_output=True, text=True, timeout=120)
    assert r.returncode == 74, r.stderr
    assert "cannot write the report to standard output" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.slow
def test_python_dash_m_and_demo():
    r = subprocess.run([sys.executable, "-m", "jaxcds", "demo"], capture_output=True, text=True,
                       timeout=900)
    assert r.returncode == 0, r.stderr
    assert "all structures agree with the half-edge" in r.stdout
    assert "halfedge" in r.stdout and "corner-table" in r.stdout


def test_missing_file_no_traceback():
    r = subprocess.run([sys.executable, "-m", "jaxcds", "info", "/nonexistent/x.off"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "no such file" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize("structure,nav", [("cds6n", 6), ("cds5n", 5), ("cds4n", 4), ("cds5n-o1", 5)])
def test_build_prints_the_papers_reference_counts(capsys, structure, nav):
    """CDS Thm 2/4/5/6: exactly 6, 5, 4, 5 references per vertex, +1 with the Thm 7 face map."""
    rc, d = run_json(capsys, ["build", mesh_path("cube.off"), "--structure", structure, "--json"])
    assert rc == 0
    assert d["navigation_references_per_vertex"] == nav
    assert d["face_map_references_per_vertex"] == 1
    assert d["references_per_vertex"] == nav + 1


def test_bench_console_script_finds_the_harness_from_the_repository_root(tmp_path):
    """``jaxcds bench`` as the console script runs it (``sys.path`` without the working
    directory: ``python -P``) from the repository root finds ``benchmarks/``; elsewhere it says
    where the harness lives."""
    import os
    import subprocess
    import sys

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    code = "from jaxcds.cli import main; raise SystemExit(main(['bench', '--help']))"
    env = {**os.environ, "PYTHONPATH": ""}
    ok = subprocess.run([sys.executable, "-P", "-c", code], cwd=root, capture_output=True, text=True,
                        env=env, timeout=300)
    assert ok.returncode == 0 and "usage" in ok.stdout.lower(), ok.stderr[-2000:]
    bad = subprocess.run([sys.executable, "-P", "-c", code], cwd=tmp_path, capture_output=True,
                         text=True, env=env, timeout=300)
    assert bad.returncode != 0 and "benchmarks/ of the source tree" in bad.stderr, bad.stderr[-2000:]


def test_an_install_numba_cannot_cache_in_still_runs(tmp_path):
    """Sweep 15b: with neither the package's ``__pycache__`` nor ``~/.cache/numba`` writable (a
    root-owned install run as a container's ``--user`` with ``HOME=/``), ``@numba.njit(cache=True)``
    raised 'no locator available' on import: every command was a traceback. numba's two
    locators are made to fail here as they do there; the kernels then cache in a temporary
    folder, removed at exit."""
    import os

    mods = ["jaxcds.mesh", "jaxcds.generators", "jaxcds.codec.api", "jaxcds.codec.structures",
            "jaxcds.construct.lr_pack", "jaxcds.construct.ring_search", "jaxcds.structures.cds",
            "jaxcds.structures.pemb_packed", "jaxcds.algorithms.polylla_reference",
            "jaxcds.algorithms.polylla_cycles"]
    code = ("import importlib, sys, numba\n"
            "from numba.core import caching\n"
            "for cls in (caching.InTreeCacheLocator, caching.UserWideCacheLocator):\n"
            "    cls.from_function = classmethod(lambda cls, py_func, py_file: None)\n"
            f"for m in {mods!r}:\n"
            "    importlib.import_module(m)\n"
            "print(numba.config.CACHE_DIR)\n"
            "from jaxcds.cli import main\n"
            f"raise SystemExit(main(['info', {str(tmp_path / 'missing.off')!r}]))\n")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                       timeout=300)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert "missing.off: no such file" in r.stderr
    cache = r.stdout.strip()
    assert os.path.basename(cache).startswith("jaxcds-numba-") and not os.path.exists(cache)


def test_an_unusable_jax_platforms_is_one_line(tmp_path):
    """Sweep 15b: ``JAX_PLATFORMS=bogus`` (or ``cuda`` without a GPU plugin: an AssertionError)
    made build / demo / decode into a structure / polylla a JAX traceback from the first array
    operation. Each command is called in one child (the failed backend is not cached)."""
    import os

    cube, out = mesh_path("cube.off"), str(tmp_path / "o.off")
    cds = str(tmp_path / "c.cds")
    assert main(["encode", cube, "-o", cds]) == 0  # the codec runs without JAX
    calls = [["build", cube], ["demo", cube], ["decode", cds, "-o", out],
             ["polylla", mesh_path("2triangles.off")]]
    code = ("import sys\nfrom jaxcds.cli import main\n"
            f"print([main(a) for a in {calls!r}])\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                       env={**os.environ, "JAX_PLATFORMS": "bogus"})
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr[-3000:]
    assert r.stdout.strip().splitlines()[-1] == "[2, 2, 2, 2]"
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 4 and all("JAX cannot start (JAX_PLATFORMS='bogus')" in x for x in lines)
    assert os.listdir(tmp_path) == ["c.cds"]


def test_a_loop_of_symbolic_links_is_named(capsys, tmp_path):
    """Sweep 15b: a mesh path that is a loop of symbolic links was reported 'no such file'
    (os.path.exists is false for it); the .cds reader already said what it is. A dangling
    link is still 'no such file'."""
    import os

    os.symlink(tmp_path / "b.off", tmp_path / "a.off")
    os.symlink(tmp_path / "a.off", tmp_path / "b.off")
    os.symlink(tmp_path / "nowhere.off", tmp_path / "dangling.off")
    for argv in (["info", str(tmp_path / "a.off")], ["build", str(tmp_path / "a.off"), "--json"]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "a.off: cannot read: Too many levels of symbolic links" in err, err
    assert main(["info", str(tmp_path / "dangling.off")]) == 2
    assert "dangling.off: no such file" in capsys.readouterr().err


def _holed_torus_off(path):
    """A 4 x 4 grid torus (genus 1) with one face removed: one boundary loop, Euler
    characteristic -1 as written (0 once the hole is closed)."""
    n = 4
    vid = lambda i, j: (i % n) * n + (j % n)
    faces = []
    for i in range(n):
        for j in range(n):
            faces += [(vid(i, j), vid(i + 1, j), vid(i + 1, j + 1)),
                      (vid(i, j), vid(i + 1, j + 1), vid(i, j + 1))]
    faces = faces[1:]
    from math import cos, sin

    lines = ["OFF", f"{n * n} {len(faces)} 0"]
    for i in range(n):
        for j in range(n):
            a, b = 2 * 3.14159265 * i / n, 2 * 3.14159265 * j / n
            lines.append(f"{(2 + 0.5 * cos(b)) * cos(a)} "
                         f"{(2 + 0.5 * cos(b)) * sin(a)} "
                         f"{0.5 * sin(b)}")
    lines += [f"3 {a} {b} {c}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")
    return str(path)


@pytest.mark.parametrize("kind", ["cds6n", "cds4n"])
def test_build_names_the_holes_a_cds_refusal_closed(capsys, tmp_path, kind):
    """The CLI closed the holes before a CDS builder saw the mesh, so its genus refusal gave the
    closed surface's Euler characteristic as the file's, against `jaxcds info` on the same file
    (sweep 50a, CGAL's double-torus-3-holes.off: -2 against -5). It now says the figure is
    after closing the file's loops, as the builder does from the API."""
    path = _holed_torus_off(tmp_path / "holed_torus.off")
    rc, d = run_json(capsys, ["info", path, "--json"])
    assert rc == 0 and (d["genus"], d["euler_characteristic"], d["boundary_loops"]) == (1, -1, 1)
    assert main(["build", path, "--structure", kind]) == 2
    err = capsys.readouterr().err
    assert "genus 1 (Euler characteristic 0 after closing 1 boundary loop(s))" in err, err
    assert err.count("\n") == 1, err


@pytest.mark.parametrize("kind,message", [
    ("pemb", "pemb needs a planar (genus 0) mesh, this one has genus 1"),
    ("cds6n", "cds6n (Schnyder woods) needs a genus-0 surface (a planar triangulation); this mesh has genus 1"),
])
def test_build_of_a_closed_torus_names_the_genus(capsys, kind, message):
    """A closed genus-1 mesh (nothing for the CLI to close): the builder's own refusal passes
    through, one line, exit 2 (the path no test ran)."""
    assert main(["build", mesh_path("rocker-arm.obj"), "--structure", kind]) == 2
    err = capsys.readouterr().err
    assert message in err and "rocker-arm.obj" in err and err.count("\n") == 1, err
