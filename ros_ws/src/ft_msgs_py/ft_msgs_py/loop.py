"""A control loop's timing: its own accounting, and the schedule of one run by messages.

`LoopAccounting`: compute time per cycle and missed cycles (wall clock) of a periodic
loop; `StateSchedule`: when a cycle run on each joint state is due.
"""

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


class StateSchedule:
    """When a cycle run on an incoming message (a joint state) is due: at most one a period.

    Slots `period` ns apart. A message at t runs a cycle when t is no earlier than
    3/4 of a period before the next slot (`SLACK`): a stream at the control rate passes
    whole through that much jitter; a faster one is thinned to the control rate (a
    stream at twice the rate gets every other message); the long-run rate never exceeds
    one cycle a period. The slots keep their phase while messages come within
    `SLACK` of them, and take the phase of a message later than that (a stream that
    paused). `quiet` says when no cycle ran for a whole period, for a timer to take
    over. The clock is the node's (wall time); one that jumps back more than two
    periods starts the schedule again.
    """

    SLACK = 0.75

    def __init__(self, period_ns: float) -> None:
        self.period = period_ns
        self._due: float | None = None  # the next slot (ns)
        self._last: float | None = None  # the last cycle (ns)

    def ready(self, now: int) -> bool:
        """Whether a message taken at `now` (ns) runs a cycle."""
        due = self._due
        return (due is None or now >= due - self.SLACK * self.period
                or now < due - 2 * self.period)

    def quiet(self, now: int) -> bool:
        """Whether no cycle ran in the period before `now` (ns), or the clock went back."""
        return self._last is None or not 0 <= now - self._last < self.period

    def ran(self, now: int) -> None:
        """A cycle ran at `now` (ns), on a message or not."""
        due, period = self._due, self.period
        if due is None or now > due + self.SLACK * period or now < due - 2 * period:
            due = now  # the first cycle, a stream that paused, a clock that went back
        self._due = due + period
        self._last = now
