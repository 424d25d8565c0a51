"""Random balanced-parenthesis strings for the succinct-structure tests (shared by
``test_succinct_two_stage.py`` and ``test_pemb_tables.py``)."""

import numpy as np


def random_balanced(seed: int, pairs: int, p_open: float) -> np.ndarray:
    """``2 * pairs`` bits (1 = open) of a random balanced sequence: open with probability
    ``p_open`` while opens remain (always at depth 0), else close. ``p_open`` near 1 nests deep,
    so most matches lie far away."""
    rng = np.random.default_rng(seed)
    out = np.empty(2 * pairs, np.uint8)
    d = o = 0
    for k in range(2 * pairs):
        if o < pairs and (d == 0 or rng.random() < p_open):
            out[k], d, o = 1, d + 1, o + 1
        else:
            out[k], d = 0, d - 1
    return out
