"""The plant model the detector predicts positions with, and the commands it integrates.

A velocity command u(t) takes effect after a latency L and is followed through a
first-order lag of time constant T: T v' = u(t - L) - v, from rest before the first
command. The predicted position is P(t) = U(t - L) - T y_T(t - L), with U the integral
of the command and y_T the command filtered by the lag (docs/detection.md).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ft_core.detection.buffers import _Buffers


@njit(cache=True, error_model="numpy")
def _add_command(times: np.ndarray, values: np.ndarray, integrals: np.ndarray,
                 lagged: np.ndarray, rate: np.ndarray, span: tuple[int, int], time: float,
                 velocity: np.ndarray, forget_before: float) -> int:
    """`CommandHistory.append`, compiled: entry `span[1]` from the one before it.

    Its integral and lag states follow entry k - 1's command over the interval
    (none before the first: zeros); then the entries no longer needed for times >=
    `forget_before` are dropped (the one in force then stays). Returns the new start.
    """
    start, k = span
    n = values.shape[1]
    if k > start:
        h = time - times[k - 1]
        for j in range(n):
            integrals[k, j] = integrals[k - 1, j] + h * values[k - 1, j]
        for t in range(rate.size):
            decay = np.exp(-h * rate[t])
            for j in range(n):
                u = values[k - 1, j]
                lagged[k, t, j] = u + (lagged[k - 1, t, j] - u) * decay
    else:
        integrals[k] = 0.0
        lagged[k] = 0.0
    times[k] = time
    values[k] = velocity
    keep = int(np.searchsorted(times[start:k + 1], forget_before, side="right")) - 1
    return start + max(keep, 0)


@njit(cache=True, error_model="numpy")
def _predicted_positions(starts: np.ndarray, values: np.ndarray, integrals: np.ndarray,
                         lagged: np.ndarray, start: int, end: int, rate: np.ndarray,
                         response_times: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Predicted displacement since the first command at `times`, (len(times), nT, n) (rad).

    Row i is U(t_i) - T y_T(t_i) for each response time T (`CommandHistory`'s entries
    [start, end)): the plant at rest before the first command. Each t_i is already
    shifted by its latency.
    """
    n, models = values.shape[1], response_times.size
    out = np.empty((times.size, models, n))
    for i in range(times.size):
        k = max(int(np.searchsorted(starts[start:end], times[i], side="right")) - 1, 0) + start
        h = max(times[i] - starts[k], 0.0)
        for t in range(models):
            decay = np.exp(-h * rate[t])
            for j in range(n):
                u = values[k, j]
                following = u + (lagged[k, t, j] - u) * decay
                out[i, t, j] = integrals[k, j] + h * u - response_times[t] * following
    return out


class CommandHistory(_Buffers):
    """Piecewise-constant commands, their running integral and their lagged versions.

    Entry k holds the command u_k in force from time s_k, the integral U(s_k) (rad)
    and, for each response time T, the lag's state y_T(s_k) (rad/s).
    """

    NAMES = ("times", "values", "integrals", "lagged")

    def __init__(self, n: int, response_times: np.ndarray, capacity: int = 256):
        self.n, self.response_times = n, np.asarray(response_times, float)
        self.rate = np.where(self.response_times > 0,
                             1.0 / np.maximum(self.response_times, 1e-12), 1e12)
        self.times = np.zeros(capacity)
        self.values = np.zeros((capacity, n))
        self.integrals = np.zeros((capacity, n))
        self.lagged = np.zeros((capacity, self.response_times.size, n))
        self.start = self.end = 0

    @property
    def last_time(self) -> float:
        """Start time (s) of the newest command; -inf before any."""
        return float(self.times[self.end - 1]) if len(self) else -math.inf

    def append(self, time: float, velocity: np.ndarray, forget_before: float) -> None:
        """The command in force from `time` on; earlier than the newest: ignored.

        Then drops the entries no longer needed for times >= `forget_before` (the one in
        force then stays).
        """
        if len(self) and time < self.last_time:
            return
        self.make_room_for_one()
        self.start = _add_command(self.times, self.values, self.integrals, self.lagged,
                                  self.rate, (self.start, self.end), time, velocity,
                                  forget_before)
        self.end += 1

    def at(self, times: np.ndarray) -> np.ndarray:
        """The commands in force at `times` (s), (len(times), n) (rad/s).

        Before the oldest entry kept: that entry's command (zeros before any command).
        """
        start, end = self.start, self.end
        if end == start:
            return np.zeros((len(times), self.n))
        index = np.searchsorted(self.times[start:end], times, side="right") - 1
        return self.values[start + np.maximum(index, 0)]

    def predicted(self, times: np.ndarray) -> np.ndarray:
        """Every response time's predicted displacement at `times` (s), (times, T, n) (rad).

        U(t) - T y_T(t) since the first command kept, the plant at rest before it; shift
        the times by a latency for that latency's model.
        """
        return _predicted_positions(self.times, self.values, self.integrals, self.lagged,
                                    self.start, self.end, self.rate, self.response_times,
                                    np.ascontiguousarray(times, dtype=float))
