"""Smoke test of the benchmark harness (its ``--quick`` mode, as CI runs it) and of its timers."""

from __future__ import annotations

import json
import re
import sys
import time

import numpy as np
import pytest

from benchmarks import harness, peers, report


def test_timers_report_median_and_respect_the_budget():
    t = harness.time_call(lambda: time.sleep(0.02), repeats=5)
    assert len(t["times"]) == 5 and 0.02 <= t["median_s"] < 0.5 and t["min_s"] <= t["median_s"]
    t = harness.time_call(lambda: time.sleep(0.05), repeats=50, budget_s=0.1)
    assert 1 <= len(t["times"]) <= 2  # 50 runs of 50 ms would take 2.5 s

    import jax
    import jax.numpy as jnp

    f = jax.jit(lambda x: jnp.sort(x))
    x = jnp.arange(1000, dtype=jnp.float32)[::-1]
    t = harness.time_compiled(f, (x,), repeats=3)
    assert t["compile_s"] > 0 and len(t["times"]) == 3 and t["median_s"] > 0


def test_reference_normals_and_error_mapping():
    from jaxcds.generators import icosphere

    m = icosphere(2)
    ref = harness._reference_normals(m.vertices, m.faces)
    # on a sphere the area-weighted normal is close to the position itself
    assert np.max(np.abs(ref - m.vertices)) < 0.05
    order = np.random.default_rng(0).permutation(m.num_vertices)
    assert harness._max_err(ref[order], ref, order) == 0.0
    assert harness._max_err(ref[order], ref, None) > 0.5  # forgetting the permutation is caught


def test_quick_mode_smoke(tmp_path, capsys):
    """The quick run end to end: JSON on stdout, RESULTS.md and plots written, every normals
    result right, OpenMesh either timed or skipped with its reason."""
    t0 = time.perf_counter()
    rc = harness.main(["--quick", "--json", "--out", str(tmp_path),
                       "--structures", "halfedge,corner-table"])
    elapsed = time.perf_counter() - t0
    assert rc == 0
    res = json.loads(capsys.readouterr().out)
    assert elapsed < 120  # < 60 s on an idle 2-core machine
    assert set(res) >= {"machine", "command", "settings", "meshes", "timings", "memory", "skipped", "summary"}
    assert res["machine"]["jax"] and res["command"].startswith("jaxcds bench --quick")
    assert [m["name"] for m in res["meshes"]] == harness.QUICK_MESHES
    rows = res["timings"]
    impls = {r["impl"] for r in rows}
    assert {"halfedge", "corner-table", "plain-jax", "numba-loop", "trimesh"} <= impls
    for st in ("halfedge", "corner-table"):
        ops = {r["op"] for r in rows if r["impl"] == st}
        assert ops == {"vertex_degrees", "vertex_normals[scatter]", "vertex_normals[gather]",
                       "target", "face_left", "adjacent"}
    for r in rows:
        assert r["ns_per_item"] > 0 and r["median_s"] > 0 and r["per"] in ("vertex", "query")
        # trimesh and OpenMesh weight faces their own way (angle / unit face normals): their
        # max_err against the area-weighted reference is large by design
        if r["op"].startswith("vertex_normals") and r["impl"] not in ("trimesh", "openmesh"):
            assert r["max_err"] < 1e-4, r
        if r["op"] == "vertex_degrees" and r["kind"] == "structure":
            assert r["max_err"] == 0
    mem = {r["structure"]: r for r in res["memory"]}
    n = res["meshes"][0]["vertices"]
    # CDS paper Table 1 counts, on a closed triangulation: 19n and 13n references
    assert mem["halfedge"]["references"] == 19 * n - 36  # 3 * (6n - 12) + n
    assert mem["corner-table"]["references"] == 13 * n - 24  # 2 * (6n - 12) + n
    assert all(r["bytes"] > 0 for r in res["memory"])
    if "openmesh" not in impls:
        assert any(s["impl"] == "openmesh" and "openmesh" in s["reason"] for s in res["skipped"])
    else:  # installed: it answers unit normals, one per vertex
        om = [r for r in rows if r["impl"] == "openmesh"]
        assert om and all(r["max_err"] < 2.5 for r in om)
    for name in ("RESULTS.md", "normals.png", "queries.png", "memory.png"):
        assert (tmp_path / name).stat().st_size > 0
    md = (tmp_path / "RESULTS.md").read_text()
    assert "| halfedge |" in md and res["machine"]["jax"] in md
    assert "## Skipped" in md or "openmesh" in impls


def test_cli_bench_entry_and_bad_names(capsys):
    from jaxcds import cli

    rc = cli.main(["bench", "--quick", "--json", "--structures", "halfedge", "--peers",
                   "--ops", "vertex_degrees", "--repeats", "1"])
    assert rc == 0
    res = json.loads(capsys.readouterr().out)
    assert {(r["impl"], r["op"]) for r in res["timings"]} == {("halfedge", "vertex_degrees")}
    rc = cli.main(["bench", "--quick", "--structures", "no-such-structure", "--peers"])
    assert rc != 0
    assert "no-such-structure" in capsys.readouterr().err


@pytest.mark.parametrize("args,match", [
    (["--budget", "nan"], "finite number of seconds"),  # every op failed, exit 0
    (["--budget", "-1"], "finite number of seconds"),
    (["--max-call", "nan"], "finite number of seconds"),
    (["--ops", "nonsense"], "not \\(a prefix of\\) one of"),  # nothing timed, exit 0
])
def test_bench_options_are_checked(capsys, args, match):
    with pytest.raises(SystemExit) as exc:
        harness.main(["--quick", "--structures", "halfedge", "--peers"] + args)
    assert exc.value.code == 2
    assert re.search(match, capsys.readouterr().err)


def test_bench_out_naming_a_file_is_refused_before_timing(capsys, tmp_path):
    f = tmp_path / "afile"
    f.write_text("")
    assert harness.main(["--quick", "--structures", "halfedge", "--peers", "--out", str(f)]) == 2
    assert "is a file, not a folder" in capsys.readouterr().err


def test_peers_agree_with_reference():
    from jaxcds.generators import sphere_hull

    m = sphere_hull(300, seed=2)
    ref = harness._reference_normals(m.vertices, m.faces)
    for name in ("plain-jax", "numba-loop", "libigl"):
        try:
            ops = peers.PEERS[name](m.vertices, m.faces)
        except peers.PeerUnavailable:
            continue
        assert harness._max_err(ops["vertex_normals"][0](), ref) < 1e-5, name
    for name, (fn, _) in peers.plain_jax_variants(m.vertices, m.faces).items():
        assert harness._max_err(fn(), ref) < 1e-5, name
    deg = np.bincount(m.faces.ravel(), minlength=m.num_vertices)
    for name in ("plain-jax", "numba-loop", "trimesh"):
        got = np.asarray(peers.PEERS[name](m.vertices, m.faces)["vertex_degrees"][0]())
        np.testing.assert_array_equal(got, deg)


def test_report_markdown_from_minimal_results():
    res = {"machine": {"date": "d", "cpu": "c", "cores": 2, "memory_bytes": None, "platform": "p",
                       "python": "3", "jax": "0.x", "jax_backend": "cpu", "numpy": "2", "numba": "0"},
           "command": "jaxcds bench", "settings": {"dtype": "float32", "repeats": 1, "queries": 1,
                                                   "budget_s": 1},
           "meshes": [{"name": "m", "vertices": 1, "faces": 1}], "timings": [], "memory": [],
           "skipped": [{"impl": "openmesh", "reason": "not installed"}], "summary": {}}
    md = report.markdown(res)
    assert "## m: 1 vertices" in md and "openmesh: not installed" in md


@pytest.mark.slow
def test_fresh_process_probes(tmp_path, capsys):
    """Full-mode memory path: build and generator measured in fresh interpreters."""
    rc = harness.main(["--mesh", "random:300", "--structures", "halfedge", "--peers", "--ops",
                       "vertex_degrees", "--generators", "5000", "--rss", "subprocess", "--repeats", "1",
                       "--out", str(tmp_path), "--no-plots", "--json"])
    assert rc == 0
    res = json.loads(capsys.readouterr().out)
    (mem,) = res["memory"]
    assert mem["rss_measured"] == "fresh process" and mem["build_s"] > 0
    assert mem["peak_rss_build_bytes"] is None or mem["peak_rss_build_bytes"] >= 0
    (g,) = res["generators"]
    assert g["vertices"] == 5000 and g["faces_s"] > 0 and 0.05 < g["degree6_share"] < 0.2
    md = (tmp_path / "RESULTS.md").read_text()
    assert "fresh process" in md and "| 5,000 |" in md
    assert not (tmp_path / "normals.png").exists()


def test_race_queries_times_every_route(capsys):
    from benchmarks import race_queries

    res = race_queries.race([("a", lambda x: x + 1, (np.arange(10, dtype=np.int32),)),
                             ("b", lambda x: x * 2, (np.arange(10, dtype=np.int32),))], 10, rounds=3)
    assert set(res) == {"a", "b"} and all(0 < lo <= med for lo, med in res.values())
    assert race_queries.main(["--vertices", "300", "--queries", "1000", "--rounds", "1",
                              "--structures", "halfedge", "cds5n-o1", "--ops", "target", "adjacent"]) == 0
    out = capsys.readouterr().out
    assert "halfedge target" in out and "cds5n-o1 target" in out and "cds5n-o1 adjacent" in out
    assert "cds5n-o1 target / halfedge target: paired" in out  # one round: no interval
    with pytest.raises(SystemExit):  # argparse's error: an operator no structure has
        race_queries.main(["--vertices", "300", "--queries", "10", "--ops", "no_such_op"])
    assert "no dart operator 'no_such_op'" in capsys.readouterr().err


def test_race_queries_races_both_routes(capsys):
    """``--per-query`` adds each table operator's per-query route and pairs the two;
    ``--table-ratio`` moves the threshold while tracing and leaves the class as it was."""
    from benchmarks import race_queries
    from jaxcds.structures.cds import CDS5nO1, CDS6n

    before = (CDS5nO1.table_batch_ratio, CDS6n.table_batch_ratio, "table_batch_ratio" in vars(CDS6n))
    assert race_queries.main(["--vertices", "300", "--queries", "100", "--rounds", "1", "--per-query",
                              "--table-ratio", "0", "--structures", "halfedge", "cds6n", "cds5n-o1"]) == 0
    out = capsys.readouterr().out
    assert "cds6n target/per-query" in out and "cds5n-o1 target/per-query" in out
    assert "cds5n-o1 target / cds5n-o1 target/per-query: paired" in out
    assert "halfedge target/per-query" not in out  # the half-edge has no table route
    assert (CDS5nO1.table_batch_ratio, CDS6n.table_batch_ratio, "table_batch_ratio" in vars(CDS6n)) == before


def test_race_o1_first_read_routes_agree(capsys):
    """benchmarks/race_o1_first_read.py: the old row route and the column route answer alike
    (it exits otherwise) and every route is timed."""
    from benchmarks import race_o1_first_read

    assert race_o1_first_read.main(["--vertices", "300", "--queries", "5000", "--rounds", "1"]) == 0
    out = capsys.readouterr().out
    assert "rows" in out and "columns" in out and "halfedge" in out


@pytest.mark.slow  # an experiment's race (row orders not adopted): 22-29 s of CI on stop 54's AMD host
def test_race_row_orders_every_order_gives_the_face_list_normals(capsys):
    """Every row order of benchmarks/race_row_orders.py sums the same normals as the face list,
    for packed LR and packed CDS, and for one LR and one CDS mesh."""
    from benchmarks import race_row_orders

    for mesh in ("packed:3", "random:400"):
        assert race_row_orders.main(["--mesh", mesh, "--structures", "lr,cds4n", "--rounds", "1",
                                     "--orders", "cur,g4,p8x8,l2x4"]) == 0
        out = capsys.readouterr().out
        errs = [float(line.rsplit(" ", 1)[1]) for line in out.splitlines() if "largest difference" in line]
        assert len(errs) == 8 and max(errs) < 1e-4, out
        assert "lr/p8x8" in out and "cds4n/l2x4" in out


def test_race_target_rounds_every_loop_form_gives_the_targets(capsys):
    """benchmarks/race_target_rounds.py checks each loop form against ``all_edge_targets``."""
    from benchmarks import race_target_rounds

    assert race_target_rounds.main(["--meshes", "random:300,random:1000", "--rounds", "1",
                                    "--structure", "cds4n"]) == 0
    out = capsys.readouterr().out
    assert out.count("static_two=") == 2 and "target_rounds=" in out, out


def test_race_face_derivation_checks_each_route_against_the_face_list(capsys):
    """benchmarks/race_face_derivation.py checks the structure's own normals and the face list on
    its given rows before timing them; a structure that closes a mesh's holes is skipped by name."""
    from benchmarks import race_face_derivation

    assert race_face_derivation.main(["--meshes", "random:300,packed:2,grid.off", "--structures", "cds5n,lr",
                                      "--rounds", "1"]) == 0
    out = capsys.readouterr().out
    assert out.count("largest difference") == 10 and out.count("x the face list") == 13, out
    assert "packed:2 lr/given_rows" in out and "grid.off cds5n: skipped" in out, out


def test_race_normals_peers_pairs_every_structure_with_every_peer(capsys):
    """benchmarks/race_normals_peers.py checks each structure's normals against the face list,
    skips a structure that closes holes and a peer that is not installed by name, and pairs every
    structure with the face list and every peer that ran; an unknown peer is refused."""
    from benchmarks import race_normals_peers as R

    assert R.main(["--meshes", "random:300,grid.off", "--structures", "cds5n,lr",
                   "--peers", "trimesh,openmesh", "--rounds", "6"]) == 0  # 6: the fewest with an interval
    out = capsys.readouterr().out
    ran = 1 + ("openmesh: skipped" not in out)  # OpenMesh builds from source: often absent
    assert "grid.off cds5n: skipped" in out, out
    assert out.count(" / ") == 3 * (1 + ran), out  # random:300 cds5n, lr; grid.off lr
    assert "random:300 lr / trimesh: paired" in out and "grid.off lr / face_list: paired" in out, out
    pairs = [line for line in out.splitlines() if " / " in line]
    assert all("interval" in line for line in pairs), out
    assert all(line.endswith("at 1.5x") == (" / face_list:" in line) for line in pairs), out  # own targets
    assert R.main(["--meshes", "random:300", "--peers", "trimesh,igl"]) == 2  # argparse's status
    assert "unknown peer(s) ['igl']" in capsys.readouterr().err


def test_race_in_loop_checks_both_routes_against_the_face_list(capsys):
    """benchmarks/race_in_loop.py traces the CDS5n-O(1) normals with the Target plans inside and
    outside the one-trip loop (``base.IN_LOOP_MAX_VERTICES`` forced each way) and checks both
    against the face list before timing: the outside route of meshes from 16K vertices up is
    also checked on small ones here."""
    from benchmarks import race_in_loop
    from jaxcds.structures import base

    limit = base.IN_LOOP_MAX_VERTICES
    assert race_in_loop.main(["--meshes", "random:300,decimated-knight.off", "--rounds", "1"]) == 0
    assert base.IN_LOOP_MAX_VERTICES == limit  # restored
    rows = [json.loads(x) for x in capsys.readouterr().out.splitlines() if x.startswith("{")]
    assert [r["mesh"] for r in rows] == ["random:300", "decimated-knight.off"], rows
    assert all(set(r["x_face_list"]) == {"cds5n-o1/in_loop", "cds5n-o1/outside"} for r in rows), rows


def test_race_dummy_mask_checks_both_answers(capsys):
    """benchmarks/race_dummy_mask.py checks the open surface's answers with the mask and the
    closed surface's without it before timing."""
    from benchmarks import race_dummy_mask

    assert race_dummy_mask.main(["--vertices", "300", "--rounds", "1", "--structures", "cds5n"]) == 0
    out = capsys.readouterr().out
    assert "cds5n normals, mask" in out and "cds5n degrees, no mask" in out, out


def test_race_lf_words_checks_both_routes_against_the_face_list(capsys):
    """benchmarks/race_lf_words.py compiles the word and the parts route and checks both."""
    from benchmarks import race_lf_words
    from jaxcds.structures import cds

    before = cds._WORD_MIN_VERTICES, cds._WORD_VERTICES
    assert race_lf_words.main(["--meshes", "random:300,packed:3", "--structures", "cds6n,cds5n-o1",
                               "--rounds", "1"]) == 0
    out = capsys.readouterr().out
    assert out.count("words=") == 4 and out.count("parts=") == 4, out
    assert (cds._WORD_MIN_VERTICES, cds._WORD_VERTICES) == before  # the switches are restored


def test_race_lr_block_checks_both_routes_against_the_face_list(capsys):
    """benchmarks/race_lr_block.py compiles the loop and the identity-scatter route of the packed
    LR ring block, checks both against the face list, and restores the library's route."""
    from benchmarks import race_lr_block
    from jaxcds.structures import base, lr_packed

    assert race_lr_block.main(["--meshes", "packed:3", "--structures", "lr,lr-bits", "--rounds", "1"]) == 0
    out = capsys.readouterr().out
    assert out.count("/loop:") == 2 and out.count("/scatter:") == 2, out
    assert lr_packed.materialize_loop is base.materialize_loop


def test_probe_page_faults_reports_every_route(capsys):
    """benchmarks/probe_page_faults.py: temporaries, time and faults per call for each route."""
    from benchmarks import probe_page_faults

    assert probe_page_faults.main(["--mesh", "packed:3", "--structures", "lr,cds6n", "--rounds", "2"]) == 0
    out = capsys.readouterr().out
    assert all(f"{k}: temporaries" in out for k in ("face_list", "lr", "cds6n")), out
    assert out.count("faults per call [") == 3, out


def test_race_vertex_order_relabels_the_face_list(capsys):
    """benchmarks/race_vertex_order.py: the face list in the structure's order gives the same
    normals (checked inside), for a single mesh and a packed batch."""
    from benchmarks import race_vertex_order

    for mesh in ("random:300", "packed:3"):
        assert race_vertex_order.main(["--mesh", mesh, "--structure", "cds4n", "--rounds", "1"]) == 0
    out = capsys.readouterr().out
    assert out.count("face_list_structure_order=") == 2 and out.count("cds4n=") == 2, out


def test_race_chunked_queries_runs_and_checks_the_answers(capsys, monkeypatch):
    from benchmarks import race_chunked_queries
    from jaxcds.structures import base

    monkeypatch.setattr(base, "QUERY_CHUNK", 64)
    assert race_chunked_queries.main(["--vertices", "200", "--queries", "1000", "--rounds", "1",
                                      "--structures", "cds5n-o1,lr", "--ops", "target,next"]) == 0
    out = capsys.readouterr().out
    assert out.count("one-pass") == 4 and "lr target chunked" in out, out
    assert race_chunked_queries.main(["--packed", "2", "--queries", "1000", "--rounds", "1",
                                      "--structures", "cds6n", "--ops", "target"]) == 0
    assert "packed:2" in capsys.readouterr().out


@pytest.mark.parametrize("argv,message", [(["--queries", "-5"], "-5 must be at least 1"),
                                          (["--repeats", "0"], "0 must be at least 1"),
                                          (["--quick", "--mesh", "icosphere:abc"], "must be numbers")])
def test_bad_bench_arguments_are_named(argv, message, capsys):
    """0 used to turn silently into the default, a negative count and a bad mesh size into
    tracebacks."""
    try:
        rc = harness.main(argv)
    except SystemExit as exc:  # argparse
        rc = exc.code
    assert rc == 2 and message in capsys.readouterr().err


@pytest.mark.slow  # 25-40 s (a 25K-vertex CDS compiled twice); the padding's answers are in the quick set
def test_no_uneven_split_loop_selects_a_gathered_value_in_cds_normals(capsys):
    """benchmarks/scan_split_loops.py on a CDS whose 3n target entries (75,003) are odd and long
    enough for XLA:CPU to split the pointer-jumping rounds over its threads: no loop split in
    unequal parts both gathers and selects (the padding of ``cds.pointer_jump``); and
    benchmarks/race_split_padding.py traces the padding on and off with equal normals."""
    from benchmarks import race_split_padding, scan_split_loops

    assert scan_split_loops.main(["--mesh", "random:25001", "--structures", "cds6n"]) == 0
    out = capsys.readouterr().out
    assert "cds6n:" in out and not re.search(r"GS\s*$", out, re.M), out
    assert race_split_padding.main(["--meshes", "random:25001", "--structures", "cds6n",
                                    "--rounds", "1"]) == 0
    row = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    from jaxcds.structures import base

    assert row["sizes"]["cds6n"]["targets_pad"] == base.split_padding(75_003)


def test_paired_ratios_interval_and_verdict():
    """benchmarks/paired.py: the sign-test interval of the median (ranks from the binomial tail),
    the verdict only when the whole interval is on one side of the target, and refusals."""
    from benchmarks import paired

    # 60 rounds at 95%: ranks 22 and 39 (1-based), as the docstring says
    x = list(range(1, 61))
    med, lo, hi = paired.median_interval(x)
    assert (med, lo, hi) == (30.5, 22, 39)
    assert paired.median_interval([3.0, 1.0, 2.0, 5.0, 4.0]) == (3.0, None, None)  # 5 < 6 rounds
    assert paired.median_interval([1, 2, 3, 4, 5, 6]) == (3.5, 1, 6)
    # the drift cancels: b doubles from round to round, a stays 1.4x b
    b = [2.0 ** i for i in range(12)]
    s = paired.paired_summary([1.4 * y for y in b], b, target=1.5)
    assert abs(s.median - 1.4) < 1e-12 and s.verdict == "met" and "met at 1.5x" in str(s)
    assert paired.paired_summary([1.6 * y for y in b], b, target=1.5).verdict == "missed"
    mixed = [1.3, 1.7] * 6
    assert paired.paired_summary([m * y for m, y in zip(mixed, b)], b, target=1.5).verdict == "undecided"
    assert paired.paired_summary([1.0] * 3, [1.0] * 3, target=1.5).verdict == "undecided"
    assert paired.paired_summary([1.0] * 8, [1.0] * 8).verdict is None
    for a, bb in (([1.0], [1.0, 2.0]), ([], []), ([1.0], [0.0])):
        with pytest.raises(ValueError):
            paired.paired_ratios(a, bb)
    with pytest.raises(ValueError, match="level"):
        paired.median_interval([1.0], level=1.0)


def test_race_queries_pairs_are_edges_on_even_positions():
    """``random_pairs`` (the Adjacent queries): the even pairs are the two ends of a dart, found
    with the structure passed to one jitted program (a bound method closed over its tables,
    which XLA constant-folded for minutes at 2.5M vertices)."""
    from benchmarks import race_queries
    from jaxcds.generators import random_planar_triangulation
    from jaxcds.structures import registry

    s = registry.build("cds5n-o1", random_planar_triangulation(200, seed=3))
    u, v = race_queries.random_pairs(s, np.random.default_rng(0), 64)
    hit = np.asarray(s.adjacent(u, v))  # (checked against the half-edge in tests/structures)
    assert u.dtype == v.dtype == np.int32 and hit[::2].all() and not hit[1::2].all()


def test_bench_gpu_checks_every_op_against_the_cpu_backend(tmp_path, capsys):
    """bench_gpu.py (the leased-GPU run) on CPU, tiny: every op timed, normals and degrees
    judged, each op re-asked on the CPU backend, the JSON written as rows come; a structure
    past the deadline is listed as skipped, not dropped."""
    from benchmarks import bench_gpu

    assert bench_gpu.main(["--vertices", "300", "--queries", "2000", "--check-queries", "500",
                           "--repeats", "1", "--structures", "cds5n-o1,halfedge",
                           "--out", str(tmp_path)]) == 0
    doc = json.loads((tmp_path / "bench_gpu.json").read_text())
    ops = {(r.get("impl"), r["what"]) for r in doc["rows"]}
    for impl in ("cds5n-o1", "halfedge"):
        for op in ("normals", "grad", "degrees", "target", "face_left", "adjacent", "cpu-check"):
            assert (impl, op) in ops
    judged = [r for r in doc["rows"] if "ok" in r]
    assert judged and all(r["ok"] for r in judged)
    assert sum(r["what"] == "cpu-check" for r in doc["rows"]) == 10
    assert "CPU-backend checks: 10 run, 0 failed" in capsys.readouterr().out
    assert bench_gpu.main(["--vertices", "100", "--queries", "100", "--repeats", "1",
                           "--structures", "halfedge", "--deadline", "0", "--out", str(tmp_path)]) == 0
    doc = json.loads((tmp_path / "bench_gpu.json").read_text())
    assert [s["impl"] for s in doc["skipped"]] == ["halfedge"]


def test_bench_10m_runs_every_step_in_a_child_per_structure(tmp_path, capsys):
    """bench_10m.py (every structure end to end, one child process each) on a tiny mesh: every
    step timed with its peak RSS and judged; a child that dies (here killed by --timeout) is
    reported with its status and step, and the others still run."""
    from benchmarks import bench_10m

    out = tmp_path / "b.json"
    assert bench_10m.main(["--vertices", "300", "--queries", "500", "--repeats", "1",
                           "--structures", "halfedge", "cds5n-o1", "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert [r["structure"] for r in doc["rows"]] == ["halfedge", "cds5n-o1"]
    for r in doc["rows"]:
        assert r["done"] and r["exit_status"] == 0 and r["vertices"] == 300
        assert set(r["steps"]) == set(bench_10m.STEPS)
        assert all(r["steps"][k]["ok"] for k in ("degrees", "normals", "grad", "target"))
        assert r["steps"]["target"]["ns_per_query"] > 0 and r["nbytes"] > 0
    table = capsys.readouterr().out
    assert "| halfedge |" in table and "| cds5n-o1 |" in table and "FAILED" not in table
    assert bench_10m.main(["--vertices", "100", "--structures", "halfedge", "--timeout", "0.5",
                           "--json", str(out)]) == 1
    (r,) = json.loads(out.read_text())["rows"]
    assert not r["done"] and r["exit_status"] == -9 and "--timeout" in r["failure"]
    assert "FAILED" in capsys.readouterr().out


@pytest.mark.slow  # the stop-48 experiment, not a library route: 22-29 s of CI on stop 54's AMD host
def test_race_pemb_host_rows_decodes_the_rows_of_face_vertices(capsys):
    """benchmarks/race_pemb_host_rows.py's host decoder (the stop-48 experiment) gives
    ``face_vertices()`` bit for bit on a pemb with a border loop and on a packed union, refuses
    bits that are not a walk, and the race checks its normals against the face list."""
    import jax.numpy as jnp

    from benchmarks import race_pemb_host_rows as H
    from jaxcds import batch
    from jaxcds.generators import random_planar_triangulation
    from jaxcds.mesh import load_mesh
    from jaxcds.structures import registry
    from conftest import SHARED

    grid = registry.build("pemb", load_mesh(str(SHARED / "meshes" / "grid.off")))
    assert int(grid.holes.shape[0]) == 1
    packed = batch.pack([random_planar_triangulation(n, seed=n) for n in (40, 7, 90)], "pemb").structure
    for s, offs in ((grid, jnp.zeros((1,), jnp.int32)), (packed, packed.mesh_dart_offsets)):
        np.testing.assert_array_equal(np.asarray(H.host_rows(s, offs)), np.asarray(s.face_vertices()))
    aw = np.asarray(grid.A.words)
    pw = np.zeros_like(np.asarray(grid.P.bits.words))  # every parenthesis ')': no walk
    args = (grid.num_darts, grid.P.size, grid.num_tree_parens, np.array([0, grid.num_darts], np.int32),
            np.asarray(grid.holes), grid.num_faces, grid._num_pemb_faces)
    assert H.decode_rows(aw, pw, *args)[1] is False
    assert H.main(["--vertices", "300", "--meshes", "3", "--rounds", "1"]) == 0
    assert capsys.readouterr().out.count("x the face list") == 6


_SCRIPTS_WITH_MAIN = sorted(
    p.stem for p in __import__("pathlib").Path(__file__).resolve().parents[1].joinpath("benchmarks").glob("*.py")
    if p.stem not in ("harness", "probe_eager_pemb") and "\ndef main(" in p.read_text())


@pytest.mark.parametrize("name", _SCRIPTS_WITH_MAIN)
def test_every_script_main_turns_jaxcds_errors_into_exit_2(name):
    """A typo'd structure or a missing mesh reaches a script as a JaxcdsError; unwrapped, it
    printed a traceback and exited 1 (``harness`` has its own handling)."""
    import importlib

    mod = importlib.import_module(f"benchmarks.{name}")
    assert getattr(mod.main, "__wrapped__", None) is not None, f"{name}.main is not @clean_exit"
    if "sys.exit(main())" in open(mod.__file__).read():  # the status reaches the shell
        assert getattr(mod, "sys", None) is sys, f"{name} calls sys.exit without importing sys"


@pytest.mark.parametrize("name,argv,message", [
    ("race_face_derivation", ["--meshes", "random:300", "--structures", "cds6x", "--rounds", "1"],
     "unknown structure 'cds6x'"),
    ("race_target_rounds", ["--meshes", "no-such-mesh.off", "--rounds", "1"], "no-such-mesh.off: no such file"),
    ("race_queries", ["--vertices", "0", "--queries", "10", "--rounds", "1"], "need n >= 4"),
    ("race_normals_peers", ["--meshes", "random:300", "--rounds", "0"], "--rounds: 0 must be at least 1"),
    ("race_pemb_match", ["--vertices", "300", "--meshes", "0", "--rounds", "0"], "--rounds: 0 must be at least 1"),
    ("bench_batch", ["--meshes", "2", "--repeat", "0"], "--repeat: 0 must be at least 1"),
    ("bench_codec", ["--meshes", "random:300", "--repeats", "0"], "--repeats: 0 must be at least 1"),
])
def test_script_bad_arguments_are_one_line_and_exit_2(name, argv, message, capsys):
    """Before: tracebacks (a JaxcdsError unwrapped, or ``statistics.median`` of no rounds)."""
    import importlib

    mod = importlib.import_module(f"benchmarks.{name}")
    try:
        rc = mod.main(argv)
    except SystemExit as exc:  # argparse
        rc = exc.code
    err = capsys.readouterr().err
    assert rc == 2 and message in err and "Traceback" not in err, err


@pytest.mark.parametrize("name,argv,message", [
    ("race_normals_peers", ["--meshes", "random:300", "--peers", "libigx", "--rounds", "1"],
     "--peers: unknown peer(s) ['libigx']"),
    ("bench_lr", ["--no-table1", "--no-fig10", "--construction-mesh", "subdiv:bunny.off", "--repeats", "1"],
     "expected subdiv:NAME:K, got 'subdiv:bunny.off'"),
])
def test_script_bad_names_exit_2_not_1(name, argv, message, capsys):
    """Before: SystemExit(message), status 1 (peers), or a ValueError traceback (bench_lr's split)."""
    import importlib

    rc = importlib.import_module(f"benchmarks.{name}").main(argv)
    err = capsys.readouterr().err
    assert rc == 2 and message in err and "Traceback" not in err, err


def test_bench_cds_navigation_times_the_face_list_and_each_op(tmp_path, capsys):
    """RESULTS' Table 3 command (navigation on): face_list_vertex_normals became a checking
    wrapper (no ``.lower``) and time_compiled raised AttributeError before any row."""
    from benchmarks import bench_cds

    out = tmp_path / "cds.json"
    assert bench_cds.main(["--meshes", "random:300", "--repeats", "1", "--queries", "100",
                           "--no-construction", "--structures", "cds6n",
                           "--ops", "vertex_normals", "target", "--json", str(out)]) == 0
    rows = json.loads(out.read_text())["navigation"]
    assert {(r["impl"], r["op"]) for r in rows} >= {("face-list (plain JAX)", "vertex_normals"),
                                                   ("cds6n", "vertex_normals"), ("cds6n", "target")}
    with pytest.raises(SystemExit) as exc:  # a typo'd op: argparse's choices, not a silent no-op
        bench_cds.main(["--meshes", "random:300", "--ops", "vertex_normal"])
    assert exc.value.code == 2 and "invalid choice: 'vertex_normal'" in capsys.readouterr().err


def test_race_chunked_queries_names_a_typod_operator(capsys):
    """Before: getattr inside jax.jit's trace, an AttributeError traceback."""
    from benchmarks import race_chunked_queries

    assert race_chunked_queries.main(["--vertices", "200", "--queries", "10", "--rounds", "1",
                                      "--structures", "cds6n", "--ops", "targt"]) == 2
    assert "--ops targt: cds6n has no dart operator 'targt'" in capsys.readouterr().err


def test_race_split_padding_and_dummy_mask_refuse_bad_names(capsys):
    """race_split_padding skipped a typo'd structure as one that refuses the mesh (status 0,
    the face list timed alone); race_dummy_mask's --vertices abc was a ValueError traceback."""
    from benchmarks import race_dummy_mask, race_split_padding

    assert race_split_padding.main(["--meshes", "random:300", "--structures", "cds6x", "--rounds", "1"]) == 2
    assert "--structures: unknown structure(s) ['cds6x']" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        race_dummy_mask.main(["--vertices", "abc", "--rounds", "1"])
    assert exc.value.code == 2 and "'abc' is not a comma-separated list" in capsys.readouterr().err


def test_bench_codec_and_bench_batch_refuse_bad_sizes(capsys):
    """Before: a ValueError traceback each (random:abc read by float(); --meshes 0 reached an
    empty concatenate)."""
    from benchmarks import bench_batch, bench_codec

    assert bench_codec.main(["--meshes", "random:abc", "--repeats", "1"]) == 2
    assert "--meshes random:abc: expected random:N[:SEED]" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        bench_batch.main(["--meshes", "0", "--repeat", "1"])
    assert exc.value.code == 2 and "--meshes: 0 must be at least 1" in capsys.readouterr().err


def test_bench_lr_normals_refuses_a_structure_it_would_build_as_lr(capsys):
    """Before: any name but lr-bits built an LR, timed it and printed it under that name."""
    from benchmarks import bench_lr_normals

    assert bench_lr_normals.main(["--meshes", "random:300", "--structures", "cds6n", "--repeat", "1"]) == 2
    assert "--structures cds6n: this script times lr and lr-bits only" in capsys.readouterr().err


@pytest.mark.parametrize("name,argv,message", [
    ("race_row_orders", ["--mesh", "packed:2", "--structures", "lr", "--orders", "cur,cux"],
     "cux: expected cur, gB, pDxS or lDxS"),
    ("profile_pemb_ops", ["--points", "300", "--ops", "twn"], "invalid choice: 'twn'"),
])
def test_typod_order_or_operator_is_argparses_error(name, argv, message, capsys):
    """Before: a traceback from inside the traced program (race_row_orders) and a KeyError
    traceback with status 0 (profile_pemb_ops)."""
    import importlib

    with pytest.raises(SystemExit) as exc:
        importlib.import_module(f"benchmarks.{name}").main(argv)
    assert exc.value.code == 2 and message in capsys.readouterr().err
