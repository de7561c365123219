"""A periodic loop's own accounting: compute time per cycle and missed cycles (wall clock)."""

from __future__ import annotations

import time
from collections import deque

import numpy as np


class LoopAccounting:
    """Call `start()` at the top of every cycle and `end()` at its bottom.

    A cycle counts as missed when the gap between two cycle starts holds more than
    one period (plus half a period of slack): the timer could not keep up. Compute
    times are kept for the last `window` cycles.
    """

    def __init__(self, period: float, count_missed: bool = True, window: int = 5000):
        self.period, self.count_missed = period, count_missed
        self.cycles = self.missed = 0
        self._compute: deque[float] = deque(maxlen=window)
        self._last_start: float | None = None
        self._start = 0.0

    def start(self) -> None:
        """A cycle begins."""
        now = time.perf_counter()
        if self.count_missed and self._last_start is not None:
            gap = now - self._last_start
            if gap > 1.5 * self.period:
                self.missed += int(gap / self.period + 0.5) - 1
        self._last_start = self._start = now
        self.cycles += 1

    def end(self) -> None:
        """The cycle's work is done."""
        self._compute.append(time.perf_counter() - self._start)

    def compute_ms(self, percentile: float) -> float:
        """A percentile of the recent compute times (ms); 0 before any cycle."""
        return float(np.percentile(self._compute, percentile) * 1e3) if self._compute else 0.0

    def samples(self) -> np.ndarray:
        """The recent compute times (s)."""
        return np.array(self._compute)
