"""A periodic loop's own accounting: compute time per cycle and missed cycles (wall clock)."""

from __future__ import annotations

import time

import numpy as np


class LoopAccounting:
    """Call `start()` at the top of every cycle and `end()` at its bottom.

    A cycle is missed when a whole period of the schedule passes with no cycle
    starting in it: a periodic ROS timer that is called more than a period late
    skips the periods it overran. The schedule's phase is estimated from the
    starts themselves (a timer never fires before its slot, so the earliest start
    relative to the schedule is its phase). A late cycle that still starts within
    its period is not missed. Compute times are kept for the last `window` cycles.
    """

    def __init__(self, period: float, count_missed: bool = True, window: int = 5000):
        self.period, self.count_missed = period, count_missed
        self.cycles = self.missed = 0
        self._compute = np.zeros(window)  # ring buffer of compute times (s)
        self._due: float | None = None  # estimated slot of the next cycle (s)
        self._start = 0.0

    def start(self) -> None:
        """A cycle begins."""
        now = time.perf_counter()
        slot = now
        if self._due is not None:
            skipped = int((now - self._due) / self.period + 1e-9) if now > self._due else 0
            if self.count_missed:
                self.missed += skipped
            slot = min(self._due + skipped * self.period, now)
        self._due = slot + self.period
        self._start = now
        self.cycles += 1

    def end(self) -> None:
        """The cycle's work is done."""
        self._compute[(self.cycles - 1) % self._compute.size] = time.perf_counter() - self._start

    def compute_ms(self, percentile: float) -> float:
        """A percentile of the recent compute times (ms); 0 before any cycle."""
        samples = self.samples()
        return float(np.percentile(samples, percentile) * 1e3) if samples.size else 0.0

    def samples(self) -> np.ndarray:
        """The recent compute times (s), at most `window` of them (not in time order)."""
        return self._compute[:min(self.cycles, self._compute.size)].copy()
