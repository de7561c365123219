"""Where the commands are taking the arm: the configuration the kfm ascent is taken at.

The kfm gradient ascent (Maciejewski et al. eq 8, `engine`) closes a loop through the
plant: taken at the measured configuration q, each cycle's gradient lags the commands by
the driver's latency, its servo's response and the command smoothing. Behind a slow
driver (50 ms latency, 50 ms servo) that loop limit-cycles in the null space at the
default gain: the joints' commands reverse every 0.2 s (docs/controller.md, "Behind a
slow driver"). Taken at

    q_c = q + sum of qd_sent dt over the last `HORIZON` s

(a Smith predictor's reading: the measurement plus what the commands not yet seen in it
add), the loop no longer runs through that lag. A longer horizon than the plant's lag
leads the measurement a little; a joint that does not follow its commands (locked before
it is declared, held by an obstacle) leaves q_c at most |qd| HORIZON from the arm. The
task, its Jacobian and every other term of the cycle stay at q.
"""

from __future__ import annotations

from collections import deque

import numpy as np

#: s of commands added to the measurement: the slow driver's latency and servo response.
HORIZON = 0.1


class CommandedConfiguration:
    """q_c (rad), the configuration the commands published are taking the arm to (module)."""

    def __init__(self) -> None:
        self._spans: deque[tuple[float, np.ndarray]] = deque()  # (s, rad/s), newest last
        self._sent: np.ndarray | None = None  # rad/s, the command in force
        self._at = -np.inf  # s, the last update

    def update(self, q: np.ndarray, now: float) -> np.ndarray:
        """q_c at `now` (s), the arm measured at q (rad, finite).

        The command in force since the last update counts for the time between them; after
        a gap of `HORIZON` or more, or a step back in time, q_c starts again at q.
        """
        q = np.asarray(q, dtype=float)
        dt = now - self._at
        if not 0.0 <= dt < HORIZON:
            self._spans.clear()
        elif self._sent is not None and self._sent.shape == q.shape:
            self._spans.append((dt, self._sent))
        self._at = now
        ahead, total = np.zeros(q.size), 0.0
        for k in range(len(self._spans) - 1, -1, -1):
            span, qd = self._spans[k]
            if total >= HORIZON or qd.shape != q.shape:
                for _ in range(k + 1):  # older than the horizon: no longer needed
                    self._spans.popleft()
                break
            ahead += qd * min(span, HORIZON - total)
            total += span
        return q + ahead

    def sent(self, qd: np.ndarray) -> None:
        """The command published (rad/s), in force until the next update."""
        self._sent = np.array(qd, dtype=float)
