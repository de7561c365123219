"""Whether the monitor still answers: the controller's guard for a dead monitor (issue 31).

The monitor forwards each `ft/command_raw` to `ft/command` with the same stamp. If it
dies (kill -9, a crash), a driver that holds its last command keeps the arm moving
(1.22 rad in 3 s were measured), and nothing else would stop it. The controller
remembers the stamps of the commands it sent; an `ft/command` carrying one of them is
the monitor's echo. Once an echo has been seen (a graph without a monitor never
triggers the guard), commands left unanswered for `timeout` s of steady time mean the
monitor is gone or stalled: the controller then publishes explicit zeros on the plant's
command topics itself, until an echo comes back. Times are steady seconds.
"""

from __future__ import annotations

from collections import deque

#: Stamps of sent commands remembered for matching echoes (a few cycles' worth).
REMEMBERED = 64

Stamp = tuple[int, int]  #: (sec, nanosec) of a message header


class MonitorGuard:
    """Sent commands against their echoes; `silent` says how long the monitor has been quiet."""

    def __init__(self, timeout: float):
        self.timeout = timeout
        self._sent: deque[Stamp] = deque(maxlen=REMEMBERED)
        self._seen = False  # an echo has come at least once
        self._waiting_since: float | None = None  # first command unanswered since

    def sent(self, stamp: Stamp, now: float) -> None:
        """A command went out on `ft/command_raw` with `stamp`."""
        self._sent.append(stamp)
        if self._waiting_since is None:
            self._waiting_since = now

    def received(self, stamp: Stamp) -> None:
        """A message arrived on `ft/command`: an echo if it carries a sent stamp."""
        if stamp in self._sent:
            self._seen, self._waiting_since = True, None

    def silent(self, now: float) -> float | None:
        """Seconds without an echo while commands wait, if beyond `timeout`; else None.

        None also before the first echo (no monitor known) and with `timeout` 0 (off).
        """
        if not (self._seen and self.timeout > 0) or self._waiting_since is None:
            return None
        waited = now - self._waiting_since
        return waited if waited > self.timeout else None
