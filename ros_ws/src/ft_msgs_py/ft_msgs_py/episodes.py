"""Problems logged once per episode: when they start and when they end, not every cycle."""

from __future__ import annotations

from builtin_interfaces.msg import Time
from rclpy.impl.rcutils_logger import RcutilsLogger

from ft_msgs_py import convert

#: Stamps up to this far (s) ahead of the node's clock are accepted (clock skew).
FUTURE_TOLERANCE = 0.05


class Episodes:
    """The node's current problems, by kind, each logged once when it starts and ends."""

    def __init__(self, logger: RcutilsLogger):
        self.logger = logger
        self.active: dict[str, str] = {}

    def report(self, kind: str, text: str | None, warning: bool = False) -> None:
        """Set (text) or clear (None) the problem of this kind; logged as an error or warning."""
        if text is None:
            if self.active.pop(kind, None) is not None:
                self.logger.info(f"{kind}: recovered")
            return
        if kind not in self.active:
            # One call site per severity: rclpy refuses a call site that changes severity.
            if warning:
                self.logger.warning(f"{kind}: {text}")
            else:
                self.logger.error(f"{kind}: {text}")
        self.active[kind] = text

    def summary(self) -> str:
        """'kind: text; ...' of the active problems, sorted."""
        return "; ".join(f"{k}: {v}" for k, v in sorted(self.active.items()))

    def message_time(self, kind: str, stamp: Time, now: float) -> float | None:
        """Seconds of a message stamp (0: `now`); None, reported as a problem, if ahead."""
        seconds = convert.message_time(stamp, now, FUTURE_TOLERANCE)
        if seconds is None:
            self.report(kind, f"stamp {convert.stamp_seconds(stamp):.3f} s is ahead of the "
                              f"clock ({now:.3f} s)")
        return seconds
