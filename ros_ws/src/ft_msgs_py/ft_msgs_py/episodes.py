"""Problems logged once per episode: when they start and when they end, not every cycle.

A problem that comes back within `RECUR_WINDOW` seconds of its end (a state that is
late now and then on a loaded machine) is not logged again: the next episode
logged after the window says how many brief ones went unlogged.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from typing import TYPE_CHECKING, Protocol

from builtin_interfaces.msg import Time

from ft_msgs_py import convert

if TYPE_CHECKING:
    from ft_msgs_py.messages import Stamp

#: Stamps up to this far (s) ahead of the node's clock are accepted: clock skew, and
#: with simulated time the node's /clock lagging the publisher's (tenths of a second
#: between processes on a loaded machine).
FUTURE_TOLERANCE = 0.05
FUTURE_TOLERANCE_SIM_TIME = 1.0
#: s within which a recurring problem is counted, not logged again.
RECUR_WINDOW = 10.0


class Logger(Protocol):
    """What `Episodes` needs of a logger: a node's (`Node.get_logger()`) has it."""

    def info(self, message: str) -> object:
        """Log `message` at INFO."""

    def warning(self, message: str) -> object:
        """Log `message` at WARN."""

    def error(self, message: str) -> object:
        """Log `message` at ERROR."""


class Episodes:
    """The node's current problems, by kind, each logged once when it starts and ends."""

    def __init__(self, logger: Logger, future_tolerance: float = FUTURE_TOLERANCE):
        self.logger, self.future_tolerance = logger, future_tolerance
        self.active: dict[str, str] = {}
        self._ended: dict[str, float] = {}  # kind -> steady time its last episode ended
        self._unlogged: Counter[str] = Counter()  # brief recurrences not logged
        self._quiet: set[str] = set()  # active kinds whose start was not logged

    def report(self, kind: str, text: str | None, warning: bool = False) -> None:
        """Set (text) or clear (None) the problem of this kind; logged as an error or warning."""
        now = time.monotonic()
        if text is None:
            if self.active.pop(kind, None) is not None:
                self._ended[kind] = now
                if kind not in self._quiet:
                    self.logger.info(f"{kind}: recovered")
                self._quiet.discard(kind)
            return
        if kind not in self.active:
            if now - self._ended.get(kind, -math.inf) < RECUR_WINDOW:
                self._unlogged[kind] += 1
                self._quiet.add(kind)
            else:
                count = self._unlogged.pop(kind, 0)
                line = f"{kind}: {text}" + (f" ({count} brief recurrences before, not logged)"
                                            if count else "")
                # One call site per severity: rclpy refuses a call site that changes severity.
                if warning:
                    self.logger.warning(line)
                else:
                    self.logger.error(line)
        self.active[kind] = text

    def summary(self) -> str:
        """'kind: text; ...' of the active problems, sorted."""
        return "; ".join(f"{k}: {v}" for k, v in sorted(self.active.items()))

    def message_time(self, kind: str, stamp: Time | Stamp, now: float) -> float | None:
        """Seconds of a message stamp (0: `now`); None, reported as a problem, if ahead."""
        seconds = convert.message_time(stamp, now, self.future_tolerance)
        if seconds is None:
            self.report(kind, f"stamp {convert.stamp_seconds(stamp):.3f} s is ahead of the "
                              f"clock ({now:.3f} s)")
        return seconds
