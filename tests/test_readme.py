"""The README's Python examples run as printed: every ```python block of README.md, in a fresh
interpreter from the repository root (the examples read ``jaxcds/data/bunny.off`` from the
checkout), so an API change that leaves the README behind fails here."""

from __future__ import annotations

import pathlib
import re
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


def python_blocks(text: str) -> list:
    """The bodies of the fenced ```python blocks of a Markdown text, in order."""
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


def test_python_blocks_are_found():
    """The extraction itself: two blocks, other languages and unclosed fences left out."""
    md = "```python\na = 1\n```\n```sh\nls\n```\n```python\nb = 2\nc = 3\n```\n```python\nd"
    assert python_blocks(md) == ["a = 1\n", "b = 2\nc = 3\n"]


BLOCKS = python_blocks((ROOT / "README.md").read_text(encoding="utf-8"))


def test_the_readme_has_its_examples():
    """The "Ten lines" tour and the "Scaling out" example (a README rewrite that drops them should
    say so here)."""
    assert len(BLOCKS) >= 2, "README.md lost its ```python examples"
    assert any("vertex_normals" in b and "jax.grad" in b for b in BLOCKS)
    assert any("shard_structure" in b for b in BLOCKS)


@pytest.mark.parametrize("k", range(len(BLOCKS)))
def test_readme_python_block_runs(k):
    """Block ``k`` runs without an error; the last statement's value is checked by the block's own
    names (normals finite, the sharded normals and Target equal to the unsharded ones)."""
    checks = {
        "normals": "assert jax.numpy.isfinite(normals).all()\n",
        "grad": "assert jax.numpy.isfinite(grad).all()\n",
        "tgt": "assert (jax.numpy.asarray(tgt) == s.target(dart_ids)).all()\n",
    }
    code = BLOCKS[k]
    tail = "".join(c for name, c in checks.items() if re.search(rf"^{name}\b", code, flags=re.M))
    r = subprocess.run([sys.executable, "-c", code + "import jax\n" + tail], cwd=ROOT,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, f"README block {k} failed:\n{code}\n--- stderr:\n{r.stderr[-3000:]}"


# ---------------------------------------------------------------------------- docs/ARCHITECTURE.md
ARCH = (ROOT / "docs" / "ARCHITECTURE.md").read_text(encoding="utf-8")


def test_architecture_test_paths_exist():
    """Every ``tests/...py`` file docs/ARCHITECTURE.md names exists (its layout named a
    ``tests/structures/test_halfedge.py`` that never did: the HalfEdge's tests are
    ``test_reference.py`` and ``test_protocol.py``)."""
    paths = set(re.findall(r"\btests/[\w/]+\.py\b", ARCH))
    assert paths, "docs/ARCHITECTURE.md names no test file"
    missing = sorted(p for p in paths if not (ROOT / p).is_file())
    assert not missing, f"docs/ARCHITECTURE.md names test files that do not exist: {missing}"


def test_architecture_register_keywords_exist():
    """The keywords docs/ARCHITECTURE.md gives ``registry.register`` are its own (it said
    ``requires=...``, which register refuses with a TypeError; they are ``closes_boundaries`` and
    ``description``)."""
    import inspect

    from jaxcds.structures import registry

    m = re.search(r"registry\.register\(([^)]*)\)", ARCH)
    assert m, "docs/ARCHITECTURE.md no longer shows registry.register's signature"
    documented = set(re.findall(r"(\w+)=", m.group(1)))
    params = set(inspect.signature(registry.register).parameters)
    assert documented and documented <= params, (
        f"docs/ARCHITECTURE.md gives register keywords {sorted(documented - params)} that it lacks")


def test_architecture_static_field_examples_are_static_fields():
    """The static fields docs/ARCHITECTURE.md names as examples are static fields of some
    registered structure (it named a ``max_degree`` that no structure has)."""
    import dataclasses

    import jaxcds.structures  # noqa: F401  (registers every structure class)
    from jaxcds.structures.base import MeshStructure

    m = re.search(r"shapes are `static_field\(\)`s \(([^)]*)\)", ARCH)
    assert m, "docs/ARCHITECTURE.md no longer names example static fields"
    named = set(re.findall(r"`(\w+)`", m.group(1)))

    def subclasses(c):
        for k in c.__subclasses__():
            yield k
            yield from subclasses(k)

    static = {f.name for c in subclasses(MeshStructure) if dataclasses.is_dataclass(c)
              for f in dataclasses.fields(c) if f.metadata.get("static")}
    assert named and named <= static, f"not a static field of any structure: {sorted(named - static)}"


def test_readme_names_every_dtype_a_structure_stores():
    """The README's opening says what structures are made of; every dtype a registered
    structure stores is named there (it said "pytrees of `int32` arrays", while lr-bits keeps its
    16-bit offsets as int16 and pemb its bit vectors as uint32 words)."""
    import jax

    import jaxcds
    from jaxcds.structures import registry

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    m = re.search(r"Structures are immutable pytrees of (.*?);", text, flags=re.S)
    assert m, "README.md no longer says what structures are made of"
    named = set(re.findall(r"`(u?int\d+)`", m.group(1)))
    mesh = jaxcds.load_mesh(ROOT / "jaxcds" / "data" / "bunny.off")
    stored = {str(leaf.dtype) for name in registry.names()
              for leaf in jax.tree_util.tree_leaves(registry.build(name, mesh))}
    assert stored <= named, f"README.md does not name the dtypes {sorted(stored - named)}"


def _cli_synopsis() -> dict:
    """``{command: set of options}`` of the README's "Command line" block (bench left out: its
    ``...`` stands for the harness's many options)."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    m = re.search(r"^## Command line\n+```\n(.*?)^```", text, flags=re.S | re.M)
    assert m, "README.md lost its \"Command line\" block"
    out = {}
    for line in m.group(1).splitlines():
        words = line.split("#")[0].split()
        if len(words) >= 2 and words[0] == "jaxcds" and words[1] != "bench":
            out[words[1]] = set(re.findall(r"(?<![\w-])(--?[a-z][\w-]*)", " ".join(words[2:])))
    return out


def test_readme_cli_synopsis_matches_the_parser():
    """Every option the README's "Command line" block shows exists on its command, and every
    option of a command is shown (``--no-weld`` of info / encode / demo was missing from it)."""
    import argparse

    from jaxcds import cli

    sub = next(a for a in cli._parser()._actions if isinstance(a, argparse._SubParsersAction))
    synopsis = _cli_synopsis()
    assert {"demo", "info", "build", "encode", "decode", "polylla"} <= set(synopsis)
    for command, shown in synopsis.items():
        parser = sub.choices[command]
        options = {s for a in parser._actions if not isinstance(a, argparse._HelpAction)
                   for s in a.option_strings}
        longest = {max(a.option_strings, key=len) for a in parser._actions
                   if a.option_strings and not isinstance(a, argparse._HelpAction)}
        assert shown <= options, f"README shows {sorted(shown - options)} that `jaxcds {command}` lacks"
        unshown = {o for o in longest if o not in shown
                   and not any(s in shown for a in parser._actions if o in a.option_strings
                               for s in a.option_strings)}
        assert not unshown, f"README's synopsis of `jaxcds {command}` leaves out {sorted(unshown)}"


def test_readme_float64_advice_names_x64():
    """The README's "Float32 range" bullet offers float64 positions as a way past float32's
    range: that holds only with ``jax_enable_x64`` on (without it JAX reads float64 positions as
    float32 and the normals overflow to NaN as before), so the advice must say so (it did not)."""
    code = (
        "import jax, numpy as np, jaxcds\n"
        "from jaxcds.algorithms import vertex_normals\n"
        "m = jaxcds.load_mesh('jaxcds/data/bunny.off')\n"
        "s = jaxcds.build('halfedge', m)\n"
        "p = np.asarray(m.vertices, np.float64) * 1e22\n"
        "print(bool(np.isnan(np.asarray(vertex_normals(s, p))).any()))\n"
        "jax.config.update('jax_enable_x64', True)\n"
        "print(bool(np.isnan(np.asarray(vertex_normals(s, p))).any()))\n")
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.split() == ["True", "False"], r.stdout  # NaN without x64, finite with it
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    m = re.search(r"pass float64 positions([^.]*)", text)
    assert m, "README.md no longer offers float64 positions"
    assert "jax_enable_x64" in m.group(1), (
        "README.md offers float64 positions without saying they need jax_enable_x64")
