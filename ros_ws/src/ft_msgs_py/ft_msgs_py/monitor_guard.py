"""Whether the monitor still answers: the controller's guard for a dead monitor.

The monitor forwards each `ft/command_raw` to `ft/command` with the same stamp. If it
dies (kill -9, a crash), a driver that holds its last command keeps the arm moving at
that velocity, and nothing else would stop it. The monitor also publishes what it sent
on `ft/command` to `ft/command_echo`, at most once per `ECHO_PERIOD`: taking every
`ft/command` at 1 kHz would take much of the controller's process's CPU
(docs/benchmarks.md), and the guard needs to hear from the monitor a few times per
timeout, not every cycle. The controller remembers the stamps of the commands
it sent; an echo carrying one of them is the monitor's answer. Once an echo has been
seen (a graph without a monitor never triggers the guard), commands left unanswered for
`timeout` s of steady time mean the monitor is gone or stalled: the controller then
publishes explicit zeros on the plant's command topics itself, until an echo comes back,
each also on `ft/command_guard` for a monitor that comes back to go on from
(`ft_monitor.handover`).
Times are steady seconds. The controller asks (`silent`) every cycle; a longer gap
between two questions than `timeout` is the controller's own stall (stopped, starved of
the CPU), not the monitor's: echoes that arrived meanwhile may still wait in its queue
behind the question, so the wait starts again; and the caller takes the echoes waiting
before each question: a pause of the controller alone never fires the guard on a live
monitor.

The echoes also say which joints the monitor holds locked, in a way no other node can
forge by merely publishing: it zeros them on the command path (`zeroed`). The controller
uses that to tell the monitor's locked set from a stranger's while both publish
(`ft_msgs_py.publishers`).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence

#: Stamps of sent commands remembered for matching echoes (a few cycles' worth).
REMEMBERED = 64
#: Shortest time (s, steady) between two echoes the monitor publishes: a command
#: unanswered waits up to this much longer for its answer than when every command was
#: echoed, a tenth of the default `monitor_timeout` (0.05 s).
ECHO_PERIOD = 0.005

Stamp = tuple[int, int]  #: (sec, nanosec) of a message header


class MonitorGuard:
    """Sent commands against their echoes; `silent` says how long the monitor has been quiet."""

    def __init__(self, timeout: float):
        self.timeout = timeout
        self._sent: OrderedDict[Stamp, Sequence[float]] = OrderedDict()
        self._seen = False  # an echo has come at least once
        self._waiting_since: float | None = None  # first command unanswered since
        self._asked: float | None = None  # when `silent` was last called
        #: Joints (command order) the latest echo zeroed where the command moved them: the
        #: monitor's locked set, as its command path shows it.
        self.zeroed: frozenset[int] = frozenset()
        #: The velocities (rad/s, command order) of the latest echo: what the plant holds.
        self.last_echo: Sequence[float] | None = None

    def sent(self, stamp: Stamp, now: float, velocity: Sequence[float]) -> None:
        """A command (`velocity`, rad/s, not changed after) went out with `stamp`."""
        self._sent[stamp] = velocity
        while len(self._sent) > REMEMBERED:
            self._sent.popitem(last=False)
        if self._waiting_since is None:
            self._waiting_since = now

    def received(self, stamp: Stamp, velocity: Sequence[float]) -> bool:
        """A message arrived on `ft/command_echo`; whether it is an echo (a sent stamp).

        An echo that moves some joint updates `zeroed` (one of all zeros, a refused
        command, says nothing of locks).
        """
        command = self._sent.get(stamp)
        if command is None:
            return False
        self._seen, self._waiting_since = True, None
        self.last_echo = velocity
        if len(velocity) == len(command) and any(velocity):
            self.zeroed = frozenset(j for j, (c, e) in enumerate(zip(command, velocity,
                                                                      strict=True))
                                    if c != 0 and e == 0)
        return True

    def silent(self, now: float) -> float | None:
        """Seconds without an echo while commands wait, if beyond `timeout`; else None.

        None also before the first echo (no monitor known) and with `timeout` 0 (off).
        After a gap of more than `timeout` since the last call (the caller stalled) the
        wait starts again at `now`.
        """
        stalled = self._asked is not None and now - self._asked > self.timeout
        self._asked = now
        if stalled and self._waiting_since is not None:
            self._waiting_since = now
        if not (self._seen and self.timeout > 0) or self._waiting_since is None:
            return None
        waited = now - self._waiting_since
        return waited if waited > self.timeout else None
