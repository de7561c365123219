"""Online identification of the plant model from a bank of candidates (docs/detection.md).

Each candidate (a latency L and a response time T on a grid) is scored by the squared
error between the measured and its predicted slopes of every moving joint, with
exponential forgetting: least squares over recent informative windows, shared by all
joints. The plausible set is what the detector decides with.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: s between two candidate latencies: the identified latency's resolution.
LATENCY_STEP = 0.01
#: Candidate latencies (s) and response times (s) of the identified plant model.
LATENCY_GRID = np.round(np.arange(0.0, 0.1501, LATENCY_STEP), 3)
RESPONSE_TIME_GRID = np.array([0.0, 0.01, 0.02, 0.035, 0.05, 0.075, 0.1, 0.15])
#: Shortest time (s) between two identification updates (each scores every model).
IDENTIFY_PERIOD = 0.01
#: Widening of the plausible set: latency below and above (s), response-time grid steps.
LATENCY_MARGIN = (0.01, 0.02)
RESPONSE_STEPS = 1


@dataclass(frozen=True)
class PlantEstimate:
    """The identified plant model: best values and the plausible ranges (s)."""

    latency: float
    response_time: float
    latency_range: tuple[float, float]
    response_time_range: tuple[float, float]
    identified: bool  #: False: still the prior (every model on the grid)
    excitation: float  #: s of informative data behind the estimate (with forgetting)


class PlantIdentification:
    """The candidate models, their scores and the plausible set.

    Model i has latency `model_latency[i]` and response time `model_response[i]` (s),
    every latency with every response time, latency-major. Until `min_excitation` s of
    informative data have been seen (the prior) every model is plausible; afterwards
    the plausible set is every model whose score is at most twice the best's, widened
    by `LATENCY_MARGIN` of latency and `RESPONSE_STEPS` grid steps of response time.
    """

    def __init__(self, latencies: np.ndarray, response_times: np.ndarray):
        self.response_times = response_times
        models = np.array([(lat, rt) for lat in latencies for rt in response_times])
        self.model_latency, self.model_response = models[:, 0], models[:, 1]
        self.all_models = np.arange(len(models))
        self.scores = np.zeros(len(models))
        self.weight = 0.0  # forgetting count of identification updates
        self.excitation = 0.0  # s of informative data, with forgetting
        self.last_identification = -math.inf
        self.last_try = -math.inf
        self.set_plausible(np.ones(len(models), dtype=bool))

    @property
    def best(self) -> int:
        """Index of the best-scoring model (always plausible)."""
        return int(np.argmin(self.scores))

    def due(self, now: float) -> bool:
        """Whether an update at `now` (s) scores every model: at most every `IDENTIFY_PERIOD`."""
        due = now - self.last_try >= IDENTIFY_PERIOD
        if due:
            self.last_try = now
        return due

    def settling_time(self, model: int) -> float:
        """A model's settling time (s): its latency and three response times."""
        return float(self.model_latency[model] + 3 * self.model_response[model])

    def set_plausible(self, plausible: np.ndarray) -> None:
        """The plausible models (mask and indices), their longest settling and response times."""
        self.plausible = plausible
        self.plausible_models = np.flatnonzero(plausible)
        self.slowest_response = float(self.model_response[plausible].max())
        self.slowest = float(self.model_latency[plausible].max()) + 3 * self.slowest_response

    def identify(self, now: float, measured: np.ndarray, slopes: np.ndarray,
                 error: np.ndarray, usable: np.ndarray, *, window: float,
                 min_command: float, memory: float, min_excitation: float) -> None:
        """Add one window's least-squares errors to the scores; update the plausible set.

        Args:
            now: time of the window's end (s).
            measured: measured slopes (n,) (rad/s).
            slopes: every model's predicted slopes (models, n) (rad/s).
            error: the measured slopes' standard errors (n,) (rad/s).
            usable: joints whose slopes may be compared (n,) (unlocked, not at a limit).
            window: the detector's window (s), the longest step of excitation counted.
            min_command: smallest predicted velocity of a moving joint (rad/s).
            memory: forgetting time (s).
            min_excitation: s of informative data before the prior is replaced.

        Informative only where a usable joint moves and the models disagree about it by
        at least 0.02 rad/s and three standard errors; otherwise nothing changes.
        """
        moving = usable & (np.max(np.abs(slopes), axis=0) >= min_command)
        disagreement = np.ptp(slopes, axis=0)
        if not np.any(moving & (disagreement >= np.maximum(0.02, 3 * error))):
            return
        elapsed = now - self.last_identification
        self.last_identification = now
        forget = math.exp(-min(elapsed, 1e3) / memory)
        step = min(elapsed, window)
        squared = (measured[moving] - slopes[:, moving]) ** 2
        self.scores = forget * self.scores + squared.sum(axis=1)
        self.weight = forget * self.weight + 1.0
        self.excitation = forget * self.excitation + step
        if self.excitation < min_excitation:
            return
        best = self.scores.min()
        floor = self.weight * 1e-6 * moving.sum()  # (1 mrad/s)^2 per joint and update
        chosen = self.scores <= 2 * best + floor
        lat, rt = self.model_latency[chosen], self.model_response[chosen]
        grid = self.response_times
        low = grid[max(int(np.searchsorted(grid, rt.min())) - RESPONSE_STEPS, 0)]
        high = grid[min(int(np.searchsorted(grid, rt.max())) + RESPONSE_STEPS, grid.size - 1)]
        self.set_plausible((self.model_latency >= lat.min() - LATENCY_MARGIN[0] - 1e-9)
                           & (self.model_latency <= lat.max() + LATENCY_MARGIN[1] + 1e-9)
                           & (self.model_response >= low) & (self.model_response <= high))

    def estimate(self, min_excitation: float) -> PlantEstimate:
        """The identified model (the prior's ranges until `min_excitation` s of data)."""
        best = self.best if self.weight > 0 else 0
        lat = self.model_latency[self.plausible]
        rt = self.model_response[self.plausible]
        identified = self.excitation >= min_excitation and self.weight > 0
        return PlantEstimate(
            latency=float(self.model_latency[best]) if identified else math.nan,
            response_time=float(self.model_response[best]) if identified else math.nan,
            latency_range=(float(lat.min()), float(lat.max())),
            response_time_range=(float(rt.min()), float(rt.max())),
            identified=identified, excitation=self.excitation)
