"""Position lost over spans of the kept window offsets: slow stalls and lost position.

Per update the detector keeps every model's window-mean offset, measured minus
predicted position (`window.Offsets`), for twice the plausible set's slowest settling
time. Over a span longer than the window, the best model's offsets say how much
position a joint lost against its commands: the deficit behind a stall
(`rules.lost_position`), and the motion of a joint commanded too slowly for the window's
velocity test (`rules.slow_stall`, over `SLOW_SPAN`). Both allow for the best model's
latency being known only to a step of the grid (`LATENCY_STEP`): a change of command dv
moves an offset by up to that step times dv (docs/detection.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ft_core.detection import rules
from ft_core.detection.config import DetectorConfig
from ft_core.detection.identification import LATENCY_STEP, PlantIdentification
from ft_core.detection.plant_model import CommandHistory
from ft_core.detection.window import Offsets, Samples

#: s over which the detector judges, on its own, the joints commanded too slowly for the
#: window's test (`rules.slow_stall`): two halves longer than the window, so their means
#: do not overlap, and short enough that a lock as the arm slows into its goal is named
#: before the next goal (docs/detection.md, "Slowly commanded joints").
SLOW_SPAN = 0.2


@dataclass(frozen=True)
class SlowStalls:
    """What the detector saw of every joint over a span of two halves (arrays (n,)).

    Attributes:
        stalled: the joints that lost their motion there (`rules.slow_stall`).
        measured: the velocity over the span's second half (rad/s).
        commanded: the model's over that half (rad/s).
        deficit: the position lost over the span, along each half's prediction (rad).
    """

    stalled: np.ndarray
    measured: np.ndarray
    commanded: np.ndarray
    deficit: np.ndarray


@dataclass(frozen=True)
class Spans:
    """The detector's window, offsets, commands and identification, judged over spans.

    The same objects the detector updates (one set per `LockDetector.reset`); `lower`
    and `upper` the joints' position limits (rad).
    """

    samples: Samples
    offsets: Offsets
    history: CommandHistory
    plant: PlantIdentification
    lower: np.ndarray
    upper: np.ndarray

    def settling_time(self, config: DetectorConfig) -> float:
        """The window and the plausible set's slowest settling time (s)."""
        return config.window + self.plant.slowest

    def horizon(self, config: DetectorConfig) -> float:
        """How long (s) window offsets are kept: the window and twice the slowest settling."""
        return config.window + 2 * self.plant.slowest

    def slow_stalls(self, config: DetectorConfig, resumed_at: float, error: np.ndarray,
                    span: float = SLOW_SPAN) -> SlowStalls | None:
        """Every joint's motion over the last `span` s, and which of them lost it.

        Over each half of the span (window means `span` / 2 apart) the best model
        predicts a displacement d = (change of the window-mean position) - (change of
        its offset); `rules.slow_stall` judges them, allowing for a model latency off by
        a step of the grid (`LATENCY_STEP` times the change of command over the half,
        each taken at its mark lagged by the model's latency). None: no judgement, with
        commands (re)started at `resumed_at` (s) within the span and its settling time,
        or fewer offsets kept than the span. `error`: the slopes' standard errors
        (rad/s, (n,)).
        """
        offsets, samples, plant = self.offsets, self.samples, self.plant
        now = float(samples.times[samples.end - 1])
        if (resumed_at + self.settling_time(config) > now - span
                or offsets.times[offsets.start] > now - span + config.window):
            return None
        times = offsets.times[offsets.start:offsets.end]
        marks = offsets.start + np.searchsorted(
            times, [now - span, now - span / 2, now], side="left")
        marks[-1] = offsets.end - 1
        best = plant.best
        moved = np.diff(offsets.means[marks], axis=0)
        predicted = moved - np.diff(offsets.values[marks, best], axis=0)
        lag = plant.model_latency[best] + config.window / 2
        shift = LATENCY_STEP * np.abs(np.diff(self.history.at(offsets.times[marks] - lag),
                                              axis=0))
        sigma = rules.mean_difference_error(error, samples.window()[0])
        stalled = rules.slow_stall(
            moved, predicted, offsets.means[marks[0]:marks[-1] + 1],
            samples.positions[samples.end - 1], self.lower, self.upper, sigma, shift,
            config.min_command * config.window, config.ratio, config.confidence,
            config.limit_margin)
        half = float(offsets.times[marks[-1]] - offsets.times[marks[1]])
        along = np.sign(predicted)
        return SlowStalls(stalled, moved[-1] / half, predicted[-1] / half,
                          (np.abs(predicted) - along * moved).sum(axis=0))

    def lost_position(self, config: DetectorConfig, now: float, along: np.ndarray,
                      error: np.ndarray, times: np.ndarray,
                      since: float) -> tuple[np.ndarray, np.ndarray]:
        """`rules.lost_position` against the windows that ended `since` s ago or earlier.

        The best model alone: the plausible models' offsets differ by their lags times
        the change of command, no loss of position. Its latency is known to within a
        step of the grid: a change of command dv since an earlier window (at its middle,
        lagged) moves its offset by up to that step times dv. `now` (s): the update's
        time; `along` (n,): the prediction the deficit is counted along (rad/s); `error`
        the slopes' standard errors (rad/s), `times` the window's (s).
        """
        offsets, best = self.offsets, self.plant.best
        ends, past = offsets.between(now - self.horizon(config), now - since)
        lag = self.plant.model_latency[best] + config.window / 2
        commands = self.history.at(np.append(ends, now) - lag)
        return rules.lost_position(
            offsets.values[offsets.end - 1, best], past[:, best], along,
            rules.mean_difference_error(error, times), config.confidence,
            LATENCY_STEP * np.abs(commands[:-1] - commands[-1]))
