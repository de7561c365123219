"""The sliding window of measurements, its least-squares fits and the window offsets.

Every measurement enters the window with every candidate model's predicted position
(`_ingest`); the fits read running sums over the window, so that an update costs
models x joints, not that x the window's samples (docs/detection.md).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ft_core.detection.buffers import _Buffers
from ft_core.detection.plant_model import _predicted_positions


@njit(cache=True, error_model="numpy")
def _slope_error(values: np.ndarray, centred: np.ndarray, slope: np.ndarray,
                 spread: float) -> np.ndarray:
    """Standard error of least-squares slopes from the fit's residuals (per column)."""
    count, n = values.shape
    error = np.empty(n)
    for j in range(n):
        mean = values[:, j].mean()
        total = 0.0
        for s in range(count):
            residual = values[s, j] - mean - centred[s] * slope[j]
            total += residual * residual
        error[j] = np.sqrt(total / (count - 2) / spread)
    return error


@njit(cache=True, error_model="numpy")
def _window_fit(times: np.ndarray, positions: np.ndarray, predicted: np.ndarray,
                predicted_sum: np.ndarray, timed_sum: np.ndarray, base: float,
                models: np.ndarray, best: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least-squares slopes over the window (compiled: one call per joint state).

    Returns the measured slopes (n,), the slopes of the models at indices `models`
    (len(models), n) and the slopes' standard error (n,): the smaller of the residual
    estimates of the measured positions and of the measured minus the best model's.
    A model's slope comes from the window's running sums (`Samples`): the sum over
    samples of (t - mean t) p = sum (t - base) p - (mean t - base) sum p, so it costs
    the models times the joints, not that times the samples.
    """
    count, n = positions.shape
    mean = times.mean()
    centred = times - mean
    spread = centred @ centred
    measured = np.zeros(n)
    best_slope = np.zeros(n)
    for s in range(count):
        c = centred[s] / spread
        for j in range(n):
            measured[j] += c * positions[s, j]
            best_slope[j] += c * predicted[s, best, j]
    shift = mean - base
    slopes = np.empty((models.size, n))
    for i in range(models.size):
        m = models[i]
        for j in range(n):
            slopes[i, j] = (timed_sum[m, j] - shift * predicted_sum[m, j]) / spread
    error = np.minimum(_slope_error(positions, centred, measured, spread),
                       _slope_error(positions - predicted[:, best, :], centred,
                                    measured - best_slope, spread))
    return measured, slopes, error


@njit(cache=True, error_model="numpy")
def _window_offsets(positions: np.ndarray, predicted_sum: np.ndarray,
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Mean over the window of measured minus predicted positions, (models, n) (rad).

    From the window's running sum of predicted positions (`Samples`); also returns the
    window's mean measured positions (n,).
    """
    count, n = positions.shape
    means = np.zeros(n)
    for s in range(count):
        for j in range(n):
            means[j] += positions[s, j]
    means /= count
    out = np.empty(predicted_sum.shape)
    for i in range(predicted_sum.shape[0]):
        for j in range(n):
            out[i, j] = means[j] - predicted_sum[i, j] / count
    return out, means


@njit(cache=True, error_model="numpy")
def _accumulate(predicted_sum: np.ndarray, timed_sum: np.ndarray, times: np.ndarray,
                predicted: np.ndarray, first: int, last: int, base: float,
                sign: float) -> None:
    """Add (sign 1) or take away (-1) entries [first, last) to the running sums.

    `predicted_sum` += p and `timed_sum` += (t - base) p, per model and joint.
    """
    models, n = predicted_sum.shape
    for s in range(first, last):
        weight = times[s] - base
        for i in range(models):
            for j in range(n):
                p = sign * predicted[s, i, j]
                predicted_sum[i, j] += p
                timed_sum[i, j] += weight * p


@njit(cache=True, error_model="numpy")
def _largest_step(times: np.ndarray) -> float:
    """The longest interval between consecutive times (s)."""
    largest = 0.0
    for i in range(1, times.size):
        largest = max(largest, times[i] - times[i - 1])
    return largest


@njit(cache=True, error_model="numpy")
def _ingest(time: float, position: np.ndarray, latencies: np.ndarray,
            history: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                           np.ndarray],
            history_span: tuple[int, int],
            times: np.ndarray, positions: np.ndarray, predicted: np.ndarray,
            predicted_sum: np.ndarray, timed_sum: np.ndarray, span: tuple[int, int],
            base: float, window_start: float,
            offset_times: np.ndarray, offset_values: np.ndarray, offset_means: np.ndarray,
            offset_span: tuple[int, int], keep_from: float) -> tuple[int, int]:
    """One measurement into the window and the window's offsets, compiled (`measure`).

    Stores the measurement at index `span[1]` of the samples with every model's
    prediction (`_predicted_positions`; `history` is the command history's times,
    values, integrals, lags, rates and response times), adds it to the running sums
    (`_accumulate`), drops the samples before `window_start` from the window and the
    sums, stores the window's offsets (`_window_offsets`) at index `offset_span[1]` and
    drops the offsets before `keep_from`. The caller made room at both ends. Returns
    the new starts of the samples and of the offsets.
    """
    starts, values, integrals, lagged, rate, response_times = history
    start, end = span
    prediction = _predicted_positions(starts, values, integrals, lagged, history_span[0],
                                      history_span[1], rate, response_times, time - latencies)
    times[end] = time
    positions[end] = position
    for i in range(latencies.size):
        for t in range(response_times.size):
            predicted[end, i * response_times.size + t] = prediction[i, t]
    _accumulate(predicted_sum, timed_sum, times, predicted, end, end + 1, base, 1.0)
    end += 1
    first = start + int(np.searchsorted(times[start:end], window_start, side="left"))
    _accumulate(predicted_sum, timed_sum, times, predicted, start, first, base, -1.0)
    offsets, means = _window_offsets(positions[first:end], predicted_sum)
    k = offset_span[1]
    offset_times[k] = time
    offset_values[k] = offsets
    offset_means[k] = means
    kept = offset_span[0] + int(np.searchsorted(offset_times[offset_span[0]:k + 1], keep_from,
                                                side="left"))
    return first, kept


class Samples(_Buffers):
    """The window's measurements: times, positions and every model's predicted positions.

    Contiguous arrays: the per-update fits read views, no copies. Also the running sums
    over the window of each model's predicted positions p and of (t - `base`) p, which
    the fits use (`_window_fit`, `_window_offsets`): kept as entries come and go, and
    summed afresh whenever the entries move to the front of the arrays (every few
    windows), so rounding never accumulates. `base` is the first entry's time then.
    """

    NAMES = ("times", "positions", "predicted")

    def __init__(self, n: int, models: int, capacity: int = 128):
        self.times = np.zeros(capacity)
        self.positions = np.zeros((capacity, n))
        self.predicted = np.zeros((capacity, models, n))
        self.start = self.end = 0
        self.base = 0.0
        self.predicted_sum = np.zeros((models, n))
        self.timed_sum = np.zeros((models, n))

    def make_room_for(self, time: float) -> None:
        """Room for one more entry, at `time`.

        The sums are made afresh when the entries move, and start at `time` (`base`)
        when the window is empty.
        """
        if self.end == self.times.size:
            self._make_room()
            self._sum_afresh()
        if not len(self):
            self.base = time
            self.predicted_sum[:] = self.timed_sum[:] = 0.0

    def _sum_afresh(self) -> None:
        self.base = float(self.times[self.start]) if len(self) else 0.0
        self.predicted_sum[:] = self.timed_sum[:] = 0.0
        _accumulate(self.predicted_sum, self.timed_sum, self.times, self.predicted,
                    self.start, self.end, self.base, 1.0)

    def window(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(times, positions, predicted) of the window, as views."""
        return (self.times[self.start:self.end], self.positions[self.start:self.end],
                self.predicted[self.start:self.end])


class Offsets(_Buffers):
    """Per update: every model's window-mean offset, and the window-mean position.

    The offset is measured minus predicted position. Kept for `horizon` s, so that a
    stalled joint's position can be compared with where it stood against the same model
    before the stall (the position-deficit rule), and a slowly commanded suspect's motion
    over that span (`LockDetector.confirm`).
    """

    NAMES = ("times", "values", "means")

    def __init__(self, n: int, models: int, capacity: int = 256):
        self.times = np.zeros(capacity)
        self.values = np.zeros((capacity, models, n))
        self.means = np.zeros((capacity, n))
        self.start = self.end = 0

    def between(self, start: float, end: float) -> tuple[np.ndarray, np.ndarray]:
        """The kept windows ending in [start, end]: their end times (k,), offsets (k, models, n)."""
        times = self.times[self.start:self.end]
        first = self.start + int(np.searchsorted(times, start, side="left"))
        last = self.start + int(np.searchsorted(times, end, side="right"))
        return self.times[first:last], self.values[first:last]
