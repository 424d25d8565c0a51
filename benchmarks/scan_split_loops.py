"""List the loops of a structure's normals program that XLA:CPU splits over its threads in
unequal parts (the outer dimension is not a multiple of the thread count): those run as scalar
loops, and where they select a gathered value on an irregular pattern the select becomes a
mispredicted branch (see ``jaxcds.structures.base.split_padding`` and RESULTS.md, "CDS: the
pointer jumping padded for the thread split"). Columns: the fusion's shape, whether it gathers
(G) and selects (S). A diagnostic; it times nothing.

    .venv/bin/python benchmarks/scan_split_loops.py --mesh armadillo.obj --structures cds6n,lr
    .venv/bin/python benchmarks/scan_split_loops.py --mesh packed:300 --structures lr,cds5n-o1
"""

from __future__ import annotations

import argparse
import os
import re
import sys

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from script_errors import clean_exit  # noqa: E402

from race_lf_words import _in_order, _meshes, _structure  # noqa: E402

from jaxcds.algorithms import normals  # noqa: E402
from jaxcds.structures import base  # noqa: E402


def split_loops(hlo: str, parts: int):
    """``(all split fusions, [(shape, gathers, selects)] of those ``parts`` does not divide)``."""
    bodies = {blk.split(" ", 1)[0]: blk for blk in re.split(r"\n(?=%\S+ \()", hlo)}
    total, uneven = 0, []
    for line in hlo.splitlines():
        if "fusion(" not in line or "outer_dimension_partitions" not in line:
            continue
        total += 1
        dim = re.search(r"\[(\d+)", line)
        if dim and int(dim.group(1)) % parts:
            body = bodies.get(re.search(r"calls=(%[\w.\-]+)", line).group(1), "")
            uneven.append((re.search(r"= (\S+)", line).group(1), "gather(" in body, "select(" in body))
    return total, uneven


@clean_exit
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default="armadillo.obj")
    ap.add_argument("--structures", default="cds6n,cds4n,cds5n-o1,lr,halfedge")
    a = ap.parse_args(argv)
    m, parts = _meshes(a.mesh)
    pos = jnp.asarray(np.asarray(m.vertices, np.float32))
    threads = base.split_multiple()
    print(f"{a.mesh}: {m.num_vertices} vertices, {threads} threads")
    for name in a.structures.split(","):
        s = _structure(name, m, parts)
        if s.num_vertices != m.num_vertices:
            print(f"{name}: skipped (holes closed by dummy vertices)")
            continue
        p, = _in_order(s, pos)
        hlo = jax.jit(normals._vertex_normals).lower(s, p).compile().as_text()
        total, uneven = split_loops(hlo, threads)
        print(f"{name}: {total} split loops, {len(uneven)} uneven")
        for shape, gathers, selects in uneven:
            print(f"    {shape:28s} {'G' if gathers else ' '}{'S' if selects else ' '}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
