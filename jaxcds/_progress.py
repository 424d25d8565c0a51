"""A tiny text progress bar on stderr (no dependency), shared by the long builders (CDS
construction, the LR ring search)."""

from __future__ import annotations

import sys
import time
from typing import Optional, Sequence

#: meshes with at least this many vertices show a progress bar when stderr is a terminal
PROGRESS_MIN_VERTICES = 1_000_000


class Progress:
    """One line rewritten per stage: ``label [####....] k/n stage  seconds``."""

    def __init__(self, stages: Sequence[str], label: str, enabled: bool):
        self.stages, self.label, self.enabled = list(stages), label, enabled
        self.k, self.t0, self._err = 0, time.perf_counter(), sys.stderr
        self._draw("")

    def _draw(self, end):
        if not self.enabled:
            return
        n = len(self.stages)
        bar = "#" * (20 * self.k // n) + "." * (20 - 20 * self.k // n)
        what = self.stages[self.k] if self.k < n else "done"
        self._err.write(f"\r{self.label} [{bar}] {self.k}/{n} {what:<24} "
                        f"{time.perf_counter() - self.t0:7.1f} s{end}")
        self._err.flush()

    def step(self):
        self.k += 1
        self._draw("\n" if self.k == len(self.stages) else "")


def want_progress(progress: Optional[bool], n: int) -> bool:
    """``progress`` if given; otherwise on for ``n >= PROGRESS_MIN_VERTICES`` on a terminal."""
    if progress is not None:
        return bool(progress)
    isatty = getattr(sys.stderr, "isatty", None)
    return n >= PROGRESS_MIN_VERTICES and bool(isatty and isatty())
