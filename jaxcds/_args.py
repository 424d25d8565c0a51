"""Argument checks shared by the builders and generators (host side, before any work)."""
from __future__ import annotations

import numpy as np


def is_integer(x) -> bool:
    """True for a Python or numpy integer; False for booleans (``True`` is an ``int`` to Python,
    and a seed count of ``True`` is a mistake, not 1) and for everything else."""
    return isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_))
