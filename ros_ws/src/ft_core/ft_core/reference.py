"""Where the commands are taking the arm: the configuration the kfm ascent is taken at.

The kfm gradient ascent (Maciejewski et al. eq 8, `engine`) closes a loop through the
plant. Taken at the measured configuration q, each cycle's gradient lags the commands by
the driver's latency and its servo's response; behind a slow driver (50 ms latency, 50 ms
servo) that loop limit-cycles in the null space at the default gain, the joints'
commands reversing every 0.2 s (docs/controller.md, "Behind a slow driver"). Taken at

    q_c = q + U(t) - P(t_q)

the loop no longer runs through the lag: a Smith predictor's reading. U is the integral of
the commands sent up to now t, P the identified plant model's prediction of the position
at the measurement's time t_q (latency L and first-order response T, as the detector's,
`detection.plant_model`), both counted from the first command. The model is identified
from the controller's own commands and measurements as the monitor identifies it
(`detection.identification`): every candidate (L, T) on the detector's grid scored by its
slopes' squared error over the last `WINDOW`, in windows where the arm moves as some
candidate says. Until identified, and on a plant identified to show each command at once
(L = T = 0), q_c = q. A joint that does not follow its commands (locked before it is
declared, held by an obstacle) leaves q_c at most its commands over L + T from the arm.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from ft_core.detection.config import DetectorConfig
from ft_core.detection.identification import (
    LATENCY_GRID,
    RESPONSE_TIME_GRID,
    PlantIdentification,
)
from ft_core.detection.plant_model import CommandHistory

#: The identification's settings are the monitor's defaults: the span of the slopes
#: compared (`window`, s), the smallest predicted velocity of a moving joint
#: (`min_command`, rad/s), the forgetting time (`memory`, s) and the informative data
#: before the identified model replaces the prior (`min_excitation`, s).
DETECTION = DetectorConfig()
WINDOW, MIN_COMMAND = DETECTION.window, DETECTION.min_command
MEMORY, MIN_EXCITATION = DETECTION.memory, DETECTION.min_excitation
#: rad/s and fraction of the predicted speed: how far outside every candidate's slope a
#: joint may move and its window still be informative (not moving on its own).
UNEXPLAINED = (0.02, 0.5)
#: A joint every candidate moves one way (at `MIN_COMMAND` at least) that moves less than
#: this fraction of the slowest is stalled (locked before it is declared, held by an
#: obstacle): it is left out of the identification for `STALL_HOLD` s.
STALL_RATIO, STALL_HOLD = 0.3, 1.0
#: s of commands kept: the window, the longest latency and a late measurement's age.
KEEP = 0.5
#: s without a command after which the history starts again (the plant at rest).
GAP = 0.1


class CommandedConfiguration:
    """q_c (rad), the configuration the commands sent are taking the arm to (module)."""

    def __init__(self, n: int):
        self.n = n
        self.history = CommandHistory(n, RESPONSE_TIME_GRID)
        self.plant = PlantIdentification(LATENCY_GRID, RESPONSE_TIME_GRID)
        self._positions: deque[tuple[float, np.ndarray]] = deque()  # (s, rad), newest last
        self._stalled_until = np.full(n, -np.inf)  # s, per joint

    @property
    def note(self) -> str:
        """Where the ascent is taken, for the diagnostics."""
        estimate = self.plant.estimate(MIN_EXCITATION)
        if not estimate.identified:
            return "measured configuration (plant lag not yet identified)"
        return (f"commanded configuration: plant latency {estimate.latency:.2f} s, response "
                f"time {estimate.response_time:.2f} s")

    def sent(self, now: float, qd: np.ndarray) -> None:
        """The command (rad/s, finite) sent at `now` (s), in force until the next one."""
        if now - self.history.last_time > GAP or now < self.history.last_time:
            self.history = CommandHistory(self.n, RESPONSE_TIME_GRID)
            self._positions.clear()
        self.history.append(float(now), np.ascontiguousarray(qd, dtype=float), now - KEEP)

    def update(self, q: np.ndarray, measured_at: float, now: float,
               pinned: tuple[int, ...] = ()) -> np.ndarray | None:
        """q_c at `now` (s) for the arm measured at q (rad, finite) at `measured_at` (s).

        None where q_c = q (not identified, or no lag). The measurement (once per
        distinct time) enters the identification; `pinned` joints (not commanded) are
        left out of it.
        """
        q = np.asarray(q, dtype=float)
        positions = self._positions
        if not positions or measured_at > positions[-1][0]:
            positions.append((measured_at, q.copy()))
            while len(positions) > 2 and positions[1][0] <= measured_at - WINDOW:
                positions.popleft()
            if self.plant.due(measured_at):
                self._identify(measured_at, q, pinned)
        estimate = self.plant.estimate(MIN_EXCITATION)
        if (not estimate.identified or len(self.history) == 0
                or estimate.latency + estimate.response_time == 0):
            return None
        grid = RESPONSE_TIME_GRID
        ahead = self.history.predicted(np.array([now, measured_at - estimate.latency]))
        return q + ahead[0, 0] - ahead[1, int(np.flatnonzero(grid == estimate.response_time)[0])]

    def _identify(self, now: float, q: np.ndarray, pinned: tuple[int, ...]) -> None:
        """Score every candidate on the slopes since the measurement a `WINDOW` ago.

        Joints pinned or lately stalled are left out; a joint moving where no candidate
        takes it (on its own) leaves the window out.
        """
        then, before = self._positions[0]
        span = now - then
        if span < WINDOW / 2 or len(self.history) == 0:
            return
        measured = (q - before) / span
        latencies = LATENCY_GRID
        shown = self.history.predicted(np.concatenate([now - latencies, then - latencies]))
        slopes = ((shown[:latencies.size] - shown[latencies.size:]) / span).reshape(-1, self.n)
        low, high = slopes.min(axis=0), slopes.max(axis=0)
        slowest = np.where(low * high > 0, np.minimum(np.abs(low), np.abs(high)), 0.0)
        stalled = (slowest >= MIN_COMMAND) & (np.sign(low) * measured < STALL_RATIO * slowest)
        self._stalled_until[stalled] = now + STALL_HOLD
        usable = self._stalled_until < now
        usable[list(pinned)] = False
        outside = np.abs(measured - np.clip(measured, low, high))
        reach = np.maximum(np.abs(low), np.abs(high))
        if np.any(usable & (outside > UNEXPLAINED[0] + UNEXPLAINED[1] * reach)):
            return  # a joint moving on its own: not the plant model's motion
        self.plant.identify(now, measured, slopes, np.zeros(self.n), usable, window=WINDOW,
                            min_command=MIN_COMMAND, memory=MEMORY,
                            min_excitation=MIN_EXCITATION)
