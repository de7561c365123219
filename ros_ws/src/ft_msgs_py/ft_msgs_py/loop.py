"""A control loop's timing: its own accounting, and the schedule of one run by messages.

`LoopAccounting`: compute time per cycle and missed cycles (wall clock) of a periodic
loop; `StateSchedule`: when a cycle run on each joint state is due; `CycleDriver`: what
runs a node's control cycles (a timer, the joint states, or the process loop's ticks).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from enum import Enum
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from rclpy.timer import Timer

    from ft_msgs_py.node import SuiteNode


#: s, the shortest span `LoopAccounting.rate` measures over.
RATE_SPAN = 0.25


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
        self._rate_window: tuple[int, float] | None = None  # (cycles, time) at `rate`
        self._rate = 0.0
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

    def rate(self, now: float) -> float:
        """Cycles per second since the rate was last measured, at `now` (s).

        Measured over `RATE_SPAN` s at least: a call sooner returns the last figure and
        leaves the span running (a diagnostics timer that catches up after the process was
        held would otherwise count the few milliseconds between two of its calls, without
        a cycle, as a stopped loop). 0 at the first call; time going back starts anew.
        """
        if self._rate_window is None or now < self._rate_window[1]:
            self._rate_window = (self.cycles, now)
        elif now - self._rate_window[1] >= RATE_SPAN:
            cycles, since = self._rate_window
            self._rate = (self.cycles - cycles) / (now - since)
            self._rate_window = (self.cycles, now)
        return self._rate

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


class Drive(Enum):
    """What runs a node's control cycles (`CycleDriver`)."""

    TIMER = "timer"  #: an rclpy timer at the control period
    STATES = "joint states"  #: each joint state, thinned to the control rate
    LOOP = "loop ticks"  #: the process loop's ticks (`ft_msgs_py.spin.Ticked`)


class CycleDriver:
    """Runs a node's control cycle (`update`) in one of three ways (`Drive`).

    - `Drive.TIMER`: an rclpy timer at the control period (on the node's clock: with
      `use_sim_time`, simulated time drives the cycles).
    - `Drive.STATES` (`drive_by_states`; ft-stack, whose monitor hands each joint state
      on): `state_arrived` runs a cycle where the `StateSchedule` says so, as ros2_control
      reads, then updates. The timer then runs every max(period, `STATE_WAIT`) s and
      cycles only where no cycle ran for a period; the first state-driven cycle stops it
      and `watch` (the node's steady watchdog) starts it again once the states stop.
    - `Drive.LOOP` (`drive_by_loop`; a controller in its own process): the process loop
      calls `tick` at `next_tick` (steady s); each tick first takes the inputs the cycle
      reads from their queues, then runs the cycle. Ticks missed by more than a period
      are skipped, as an rclpy timer skips them.
    Neither of the last two with `use_sim_time`: a joint state may be taken before the
    /clock message of its instant.
    """

    #: s between checks of the timer while joint states drive the cycles.
    STATE_WAIT = 0.01

    def __init__(self, node: SuiteNode, update: Callable[[int | None], None], period: float):
        """`update(nanoseconds)` runs one cycle at the node clock's time (None: now)."""
        self._node, self._update, self.period = node, update, period
        self.drive = Drive.TIMER
        self._schedule: StateSchedule | None = None
        self._timer_runs = True
        self._next_tick = math.inf
        self._take_inputs: list[Callable[[], None]] = []
        self._timer = self._make_timer()

    @property
    def timer(self) -> Timer:
        """The control timer (cancelled while the loop or the joint states drive the cycles)."""
        return self._timer

    def _make_timer(self) -> Timer:
        self._timer_runs = True
        if self.drive == Drive.STATES:
            self._schedule = StateSchedule(self.period * 1e9)
            return self._node.create_timer(max(self.period, self.STATE_WAIT),
                                           self._cycle_if_states_stopped)
        self._schedule = None
        return self._node.create_timer(self.period, lambda: self._update(None))

    def _replace_timer(self) -> None:
        self._timer.cancel()
        self._node.destroy_timer(self._timer)
        self._timer = self._make_timer()

    def set_period(self, period: float) -> None:
        """A new control period (s), from the next cycle."""
        self.period = period
        if self.drive == Drive.LOOP:
            self._next_tick = time.monotonic() + period
        else:
            self._replace_timer()

    def drive_by_states(self) -> None:
        """Cycles on the joint states (`state_arrived`), the timer only while they stop."""
        self.drive = Drive.STATES
        self._replace_timer()

    def drive_by_loop(self, take_inputs: list[Callable[[], None]]) -> None:
        """Cycles on the process loop's ticks, each taking `take_inputs` first."""
        self.drive = Drive.LOOP
        self._timer.cancel()
        self._node.destroy_timer(self._timer)
        self._timer_runs = False
        self._next_tick = time.monotonic() + self.period
        self._take_inputs = take_inputs

    def next_tick(self) -> float:
        """Steady time (s) of the next loop tick; inf unless the loop drives the cycles."""
        return self._next_tick

    def tick(self, now: float) -> None:
        """The cycle of the loop tick due at or before `now` (steady s)."""
        period = self.period
        self._next_tick += period * (math.floor((now - self._next_tick) / period) + 1)
        for take in self._take_inputs:
            take()
        self._update(None)

    def state_arrived(self, nanoseconds: int) -> None:
        """A joint state was taken at `nanoseconds` (node clock): a cycle, if one is due."""
        if self._schedule is not None and self._schedule.ready(nanoseconds):
            self._update(nanoseconds)
            if self._timer_runs:  # the states drive the cycles again
                self._timer.cancel()
                self._timer_runs = False

    def ran(self, nanoseconds: int) -> None:
        """A cycle ran at `nanoseconds` (node clock), whatever started it."""
        if self._schedule is not None:
            self._schedule.ran(nanoseconds)

    def watch(self, nanoseconds: int) -> None:
        """The watchdog's check: the timer back on once the joint states have stopped."""
        if (self._schedule is not None and not self._timer_runs
                and self._schedule.quiet(nanoseconds)):
            self._timer.reset()
            self._timer_runs = True

    def _cycle_if_states_stopped(self) -> None:
        nanoseconds = self._node.now_ns()
        if self._schedule is not None and self._schedule.quiet(nanoseconds):
            self._update(nanoseconds)
