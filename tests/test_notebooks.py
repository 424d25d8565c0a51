"""The notebooks of ``notebooks/`` (issue 5).

* quick: the committed ``.ipynb`` files are the ones ``notebooks/make_notebooks.py`` generates
  (same cells), were executed top to bottom without an error, and keep their pictures (PNG
  outputs), so a reader sees them without running anything. Reads JSON only, no kernel.
* slow: every notebook is executed from its generator cells with ``JAXCDS_NB_SMALL=1`` (small
  sizes) in a ``python3`` kernel of this interpreter (nbclient); any cell error fails the test.
  Each notebook costs 10-110 s of CPU at small sizes, mostly XLA compilation (the tour verifies
  nine structures operator by operator), hence ``slow`` (``make test-all``).
"""

from __future__ import annotations

import json
import os
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
NB_DIR = os.path.join(ROOT, "notebooks")
sys.path.insert(0, NB_DIR)

nbformat = pytest.importorskip("nbformat")
import make_notebooks as M  # noqa: E402  (notebooks/ is not a package)

NAMES = list(M.NOTEBOOKS)


def test_the_six_notebooks_of_issue_5_are_generated():
    assert [n[:2] for n in NAMES] == ["01", "02", "03", "04", "05", "06"]
    for name in NAMES:
        nb = M.make(name)
        nbformat.validate(nb)
        assert nb.cells[0].cell_type == "markdown" and nb.cells[0].source.startswith("# ")
        code = "\n".join(c.source for c in nb.cells if c.cell_type == "code")
        assert M.SMALL_ENV in code, f"{name} must honour {M.SMALL_ENV}"


@pytest.mark.parametrize("name", NAMES)
def test_committed_notebook_is_generated_and_executed(name):
    path = os.path.join(NB_DIR, name + ".ipynb")
    assert os.path.exists(path), f"{path} missing: run notebooks/make_notebooks.py --execute"
    with open(path) as fh:
        nb = nbformat.read(fh, as_version=4)
    assert M.source_cells(nb) == M.source_cells(M.make(name)), (
        f"{path} differs from the cells of notebooks/make_notebooks.py: regenerate it")
    code = [c for c in nb.cells if c.cell_type == "code"]
    counts = [c.execution_count for c in code]
    assert counts == list(range(1, len(code) + 1)), f"{name}: not executed top to bottom: {counts}"
    outputs = [o for c in code for o in c.outputs]
    errors = [o for o in outputs if o.output_type == "error"]
    assert not errors, f"{name}: saved with an error: {errors[0].get('ename')}: {errors[0].get('evalue')}"
    pngs = [o for o in outputs if "image/png" in o.get("data", {})]
    assert pngs, f"{name}: no picture saved with the outputs"
    text = json.dumps([o.get("text", "") for o in outputs])
    assert "small sizes" not in text, f"{name}: committed from a JAXCDS_NB_SMALL run"


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.parametrize("name", NAMES)
def test_notebook_runs_at_small_sizes(name, monkeypatch):
    pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    from nbclient.exceptions import CellExecutionError

    monkeypatch.setenv(M.SMALL_ENV, "1")  # inherited by the kernel process
    nb = M.make(name)
    try:
        M.execute(nb, timeout=600, cwd=NB_DIR)
    except CellExecutionError as exc:  # name the notebook and the failing cell
        pytest.fail(f"{name}: {exc}", pytrace=False)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert all(c.execution_count is not None for c in code)
    assert any("image/png" in o.get("data", {}) for c in code for o in c.outputs)
