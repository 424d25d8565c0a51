"""Packed unions of pembs (:mod:`jaxcds.structures.pemb_packed`) given parts that no builder made.

The union's answers on meshes of every size are tested in ``tests/test_batch.py``; here, the
parts a caller can hand to :func:`jaxcds.batch.concatenate`: pembs assembled by hand from their
fields (``dataclasses.replace`` on a built one) and the odd pembs :meth:`PEMB.from_bits`
accepts.
"""

from __future__ import annotations

import numpy as np
import pytest

from jaxcds import errors
from jaxcds.structures.pemb import PEMB

# Sweep 51b: concatenate_pemb read each part's counts (num_edges, num_tree_parens...) as the sizes
# of its bits, and its _root_duals kernel (numba, no index checks) read the bits at offsets made
# of them: a part with more edges than bits read past the union's A (a segmentation fault), one
# with too many tree parentheses or a smaller P raised numpy's ValueError, a wrong leaf
# AttributeError. Probed in a child.
_HAND_MADE_PARTS_CHILD = r"""
import dataclasses
import numpy as np
import jaxcds.batch as B
from jaxcds.structures.pemb import PEMB

v = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
f = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5],
              [0, 3, 5]], np.int32)
p = PEMB.from_faces(f, 6)
q = PEMB.from_faces(np.array([[0, 1, 2]]), 3)
R = dataclasses.replace


def with_bits(s, lo, hi):  # s with its P's bits [lo, hi) reversed: same counts, unbalanced
    b = s.P.bits.to_numpy().copy()
    b[lo:hi] = b[lo:hi][::-1].copy()
    return R(s, P=type(s.P)._from_valid_bits(b, check=False))


cases = {
    "edges_big_first": [R(p, num_edges=10 ** 7), q],
    "edges_big_last": [p, R(q, num_edges=10 ** 6)],
    "tree_parens_big": [R(p, num_tree_parens=10 ** 6), q],
    "tree_parens_negative": [R(p, num_tree_parens=-4), q],
    "P_of_another": [R(p, P=q.P), q],
    "A_of_another": [R(p, A=q.A), q],
    "A_is_P": [R(p, A=p.P), q],
    "A_none": [q, R(p, A=None)],
    "holes_out_of_range": [R(p, holes=np.array([10 ** 6], np.int32)), q],
    "holes_2d": [R(p, holes=np.zeros((2, 2), np.int32)), q],
    "order_none": [R(p, order=None), q],
    "num_faces_wrong": [q, R(p, num_faces=2 ** 31)],
    "B_unbalanced": [q, with_bits(p, 0, p.num_tree_parens)],
    "Bstar_unbalanced": [with_bits(p, p.num_tree_parens, p.num_darts), q],
    "fine": [p, q, p],
}
for name, parts in cases.items():
    record(name, B.concatenate, parts)
"""


def test_concatenate_checks_hand_made_parts_in_a_child():
    from conftest import crash_probe

    out = crash_probe(_HAND_MADE_PARTS_CHILD)
    assert out.pop("fine") == ["built", ""], out
    assert all(kind == "StructureError" for kind, _ in out.values()), out
    want = {"edges_big_first": "part 0: A has 24 bits and P 24 parentheses for 10000000 edges",
            "edges_big_last": "part 1: A has 6 bits and P 6 parentheses for 1000000 edges",
            "tree_parens_big": "part 0: A has 10 ones (tree parentheses) but num_tree_parens = 1000000",
            "tree_parens_negative": "part 0: num_tree_parens = -4 is not a count",
            "P_of_another": "part 0: A has 24 bits and P 6 parentheses",
            "A_of_another": "part 0: A has 6 bits and P 24 parentheses",
            "A_is_P": "part 0: A must be a BitVector and P a BalancedParens, got BalancedParens",
            "A_none": "part 1: A must be a BitVector and P a BalancedParens, got NoneType",
            "holes_out_of_range": "part 0: holes must be a 1-D array of ids in [0, 8)",
            "holes_2d": "part 0: holes must be a 1-D array of ids in [0, 8), got dtype int32 shape (2, 2)",
            "order_none": "part 0: order must be a 1-D array of ids in [0, 6)",
            "num_faces_wrong": "part 1: num_faces = 2147483648, but B* has 8 faces and holes 0",
            "B_unbalanced": "part 1: B is unbalanced at offset 0: ')' closes nothing",
            "Bstar_unbalanced": "part 0: B* is unbalanced at offset 0: ')' closes nothing"}
    for name, msg in want.items():
        assert out[name][1].startswith("PEMB.concatenate: " + msg), (name, out[name])


def test_concatenate_of_pembs_with_tables_says_so():
    """A pemb with its tables is no packed batch: the refusal says what to pack instead."""
    import jaxcds.batch as B

    q = PEMB.from_faces(np.array([[0, 1, 2]]), 3)
    with pytest.raises(errors.UnsupportedTopologyError, match="a pemb with tables cannot be packed"):
        B.concatenate([q.with_tables(), q.with_tables()])
    u = B.concatenate([q, q]).structure
    with pytest.raises(errors.UnsupportedTopologyError, match="a packed batch cannot be packed again"):
        B.concatenate([u, u])


def test_concatenate_does_not_rescan_the_parts_bits(monkeypatch):
    """Sweep 51b: the union's A and ``B B*`` (the parts' own bits) were checked for values other
    than 0/1 again (``bits_array`` in ``BitVector.from_bits`` / ``BalancedParens.from_bits``)."""
    import jaxcds.batch as B
    from jaxcds.structures.succinct import bitvector as bv_mod
    from jaxcds.structures.succinct import bp as bp_mod

    q = PEMB.from_faces(np.array([[0, 1, 2]]), 3)
    calls = []
    for mod in (bv_mod, bp_mod):
        real = mod.bits_array
        monkeypatch.setattr(mod, "bits_array", lambda x, what, real=real: calls.append(what) or real(x, what))
    u = B.concatenate([q, q, q]).structure
    assert calls == [] and u.A.size == 18 and u.P.size == 18


def test_concatenate_names_a_hand_made_part_whose_order_is_short():
    """The order check of a hand-made part no test ran: ids in range, one too few."""
    import jaxcds.batch as B
    from jaxcds._dataclass import replace

    p = PEMB.from_faces(np.array([[0, 1, 2], [0, 2, 3]]), 4)
    short = replace(p, order=np.asarray(p.order)[:-1])
    with pytest.raises(errors.StructureError, match=r"PEMB.concatenate: part 1: order has 3 entries for 4 vertices"):
        B.concatenate([p, short])
