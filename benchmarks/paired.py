"""Ratios of two programs timed in turn, round by round, with a confidence interval.

Why: the ratio targets of the issues (normals within 1.5x of the face list, Target within 2x of
the half-edge) are read off races on a shared 2-core VM whose speed drifts by up to 3x within
minutes (RESULTS.md: "absolute times moved by up to 3x between runs"). A ratio of two medians
mixes rounds timed under different loads; the ratio *within* a round pairs two runs a few
milliseconds apart, so the drift cancels. The median of those paired ratios comes with a
distribution-free interval (the binomial order statistics of the median: no normality assumed),
and a target is called met or missed only when the whole interval is on one side of it.

    from benchmarks.paired import paired_summary
    s = paired_summary(times["cds6n"], times["face_list"], target=1.5)
    s.median, s.low, s.high, s.verdict   # 1.46, 1.43, 1.49, 'met'
"""

from __future__ import annotations

import dataclasses
import math
from typing import Optional, Sequence

__all__ = ["PairedSummary", "median_interval", "paired_ratios", "paired_summary"]


@dataclasses.dataclass(frozen=True)
class PairedSummary:
    """Median of the per-round ratios ``a / b`` and its interval (``level`` coverage at least).

    ``verdict`` against ``target`` (a ratio, lower is better): ``"met"`` when ``high <= target``,
    ``"missed"`` when ``low > target``, ``"undecided"`` when the interval holds the target, and
    ``None`` without a target. ``low`` / ``high`` are ``None`` when there are too few rounds for
    the level (fewer than 6 for 95%)."""

    median: float
    low: Optional[float]
    high: Optional[float]
    rounds: int
    level: float
    target: Optional[float] = None

    @property
    def verdict(self) -> Optional[str]:
        if self.target is None:
            return None
        if self.low is None:
            return "undecided"
        if self.high <= self.target:
            return "met"
        return "missed" if self.low > self.target else "undecided"

    def __str__(self) -> str:
        ci = ("" if self.low is None else
              f", {self.level:.0%} interval {self.low:.2f}-{self.high:.2f}")
        v = "" if self.verdict is None else f": {self.verdict} at {self.target:g}x"
        return f"paired {self.median:.2f}x{ci} ({self.rounds} rounds){v}"


def paired_ratios(a: Sequence[float], b: Sequence[float]) -> list:
    """``a[i] / b[i]`` for every round ``i`` (the two lists as a race returns them, one time per
    round each)."""
    if len(a) != len(b):
        raise ValueError(f"paired ratios need one time per round for both: {len(a)} against {len(b)}")
    if not len(a):
        raise ValueError("paired ratios need at least one round")
    if any(y <= 0 for y in b):
        raise ValueError("paired ratios need positive times in the denominator")
    return [x / y for x, y in zip(a, b)]


def _binom_cdf(k: int, n: int) -> float:
    """P(X <= k) for X ~ Binomial(n, 1/2)."""
    return sum(math.comb(n, i) for i in range(k + 1)) / 2 ** n


def median_interval(x: Sequence[float], level: float = 0.95):
    """``(median, low, high)``: the sample median and the order statistics ``x_(k)``,
    ``x_(n+1-k)`` (1-based, sorted) with ``k`` the largest rank whose two-sided binomial tail
    keeps the coverage at least ``level`` (the sign-test interval of the median; e.g. 60 rounds
    at 95%: ranks 22 and 39). ``low`` / ``high`` are ``None`` when even the extremes do not
    reach the level (``n < 6`` at 95%)."""
    if not 0 < level < 1:
        raise ValueError(f"level must lie strictly between 0 and 1, got {level}")
    s = sorted(x)
    n = len(s)
    if n == 0:
        raise ValueError("no values")
    mid = n // 2
    median = s[mid] if n % 2 else (s[mid - 1] + s[mid]) / 2
    k = 0  # coverage of [x_(j), x_(n+1-j)] is 1 - 2 P(X <= j - 1)
    for j in range(1, mid + 1):
        if 1 - 2 * _binom_cdf(j - 1, n) >= level:
            k = j
        else:
            break
    if k == 0:
        return median, None, None
    return median, s[k - 1], s[n - k]


def paired_summary(a: Sequence[float], b: Sequence[float], target: Optional[float] = None,
                   level: float = 0.95) -> PairedSummary:
    """:class:`PairedSummary` of the per-round ratios ``a / b``."""
    med, lo, hi = median_interval(paired_ratios(a, b), level)
    return PairedSummary(med, lo, hi, len(a), level, target)
