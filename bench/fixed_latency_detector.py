"""The detector before issue 13, kept as the reference `make bench` measures against.

It compares the measured slope with the raw command shifted by a fixed `latency`
(no plant model, no gap or plant-fault rule). `bench/detection.py` runs it beside
`ft_core.detection` on the same recorded data; `tests/unit/test_detection.py` shows it
declaring false locks where the new detector does not.

Over a sliding window of `window` seconds it fits a straight line to each joint's
measured positions (least squares) and compares the slope v with the mean command
c over the same window shifted back by `latency`: lock evidence when
v / c < `ratio` and |v - c| > `confidence` standard errors, held for `persistence` s.
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class DetectorConfig:
    """Detector parameters (see the module docstring).

    Attributes:
        window: sliding window (s), > 0.
        min_command: smallest observable command (rad/s or m/s), >= 0.
        latency: delay from a command to its effect on the measurements (s), >= 0.
        persistence: how long lock evidence must hold before a lock is declared (s).
        ratio: measured over commanded velocity below which a joint looks locked, in (0, 1).
        confidence: separation in standard errors (z), > 0.
        min_samples: fewest positions in the window for a decision, >= 3.
        limit_margin: distance to a physical limit counting as "at the limit" (rad).
    """

    window: float = 0.08
    min_command: float = 0.05
    latency: float = 0.0
    persistence: float = 0.02
    ratio: float = 0.3
    confidence: float = 5.0
    min_samples: int = 5
    limit_margin: float = 0.01

    def __post_init__(self) -> None:
        checks = {"window": self.window > 0, "min_command": self.min_command >= 0,
                  "latency": self.latency >= 0, "persistence": self.persistence >= 0,
                  "ratio": 0 < self.ratio < 1, "confidence": self.confidence > 0,
                  "min_samples": self.min_samples >= 3, "limit_margin": self.limit_margin >= 0}
        for name, ok in checks.items():
            value = getattr(self, name)
            if not (ok and math.isfinite(value)):
                raise ValueError(f"detection {name} = {value} is out of range")


@dataclass
class JointEvidence:
    """What the detector saw of one joint at its last update."""

    observable: bool = False
    measured: float = math.nan  #: slope of the measured positions (rad/s)
    commanded: float = math.nan  #: mean command over the window (rad/s)
    standard_error: float = math.nan  #: of the slope (rad/s)
    evidence_since: float | None = None  #: when the current lock evidence started (s)
    at_limit: bool = False  #: stalled at a physical limit
    locked_at: float | None = None  #: time the lock was declared (s)
    position: float = math.nan  #: position when locked (rad)


@dataclass
class LockDetector:
    """Streams of commands and measurements in, declared locks out."""

    lower: np.ndarray
    upper: np.ndarray
    config: DetectorConfig = field(default_factory=DetectorConfig)

    def __post_init__(self) -> None:
        self.lower = np.asarray(self.lower, dtype=float)
        self.upper = np.asarray(self.upper, dtype=float)
        self.n = self.lower.size
        self.reset()

    def reset(self) -> None:
        """Forget every lock and all history (after a repair)."""
        # Piecewise-constant commands: start times, values and the running integral of
        # the command up to each start (rad), so a window's mean is one difference.
        self._command_times: deque[float] = deque()
        self._command_values: deque[np.ndarray] = deque()
        self._command_integrals: deque[np.ndarray] = deque()
        self._times: deque[float] = deque()
        self._positions: deque[np.ndarray] = deque()
        self.joints = [JointEvidence() for _ in range(self.n)]

    @property
    def latest_time(self) -> float:
        """Time (s) of the newest measurement; -inf before any."""
        return self._times[-1] if self._times else -math.inf

    @property
    def locked(self) -> dict[int, float]:
        """{joint index: position at lock} of every locked joint."""
        return {i: e.position for i, e in enumerate(self.joints) if e.locked_at is not None}

    def lock(self, joint: int, position: float, time: float) -> None:
        """Mark a joint locked now (a failure declared on purpose)."""
        evidence = self.joints[joint]
        if evidence.locked_at is None:
            evidence.locked_at, evidence.position = time, position

    def command(self, time: float, velocity: np.ndarray) -> None:
        """The velocity commanded to the plant from `time` on (rad/s)."""
        times, values, integrals = (self._command_times, self._command_values,
                                    self._command_integrals)
        if times and time < times[-1]:
            return  # out of order: ignored
        integrals.append(integrals[-1] + (time - times[-1]) * values[-1] if times
                         else np.zeros(self.n))
        times.append(time)
        values.append(np.asarray(velocity, dtype=float).copy())
        horizon = time - 2 * self.config.window - self.config.latency
        while len(times) > 1 and times[1] <= horizon:
            times.popleft()
            values.popleft()
            integrals.popleft()

    def measure(self, time: float, position: np.ndarray) -> list[int]:
        """A measured configuration; returns the joints newly declared locked."""
        if self._times and time <= self._times[-1]:
            return []  # out of order or repeated: ignored
        self._times.append(time)
        self._positions.append(np.asarray(position, dtype=float).copy())
        while self._times and self._times[0] < time - self.config.window:
            self._times.popleft()
            self._positions.popleft()
        return self._update(time)

    def _integral(self, time: float) -> np.ndarray:
        """Integral of the command up to `time` (rad), from the newest start at or before it."""
        k = bisect.bisect_right(self._command_times, time) - 1
        start, value = self._command_times[k], self._command_values[k]
        return self._command_integrals[k] + (time - start) * value

    def _mean_command(self, start: float, end: float) -> np.ndarray | None:
        """Time average of the piecewise-constant command over [start, end]."""
        if not self._command_times or self._command_times[0] > start:
            return None
        return (self._integral(end) - self._integral(start)) / (end - start)

    def _update(self, now: float) -> list[int]:
        cfg = self.config
        times = np.array(self._times)
        if times.size < cfg.min_samples or np.max(np.diff(times), initial=0) > cfg.window / 2:
            return []
        if times[-1] - times[0] < cfg.window / 2:
            return []
        commanded = self._mean_command(times[0] - cfg.latency, times[-1] - cfg.latency)
        if commanded is None:
            return []
        positions = np.array(self._positions)
        centred = times - times.mean()
        spread = centred @ centred
        slope = centred @ (positions - positions.mean(axis=0)) / spread
        fitted = positions.mean(axis=0) + np.outer(centred, slope)
        residual = np.sum((positions - fitted) ** 2, axis=0) / (times.size - 2)
        error = np.sqrt(residual / spread)
        latest = positions[-1]
        newly = []
        for j, evidence in enumerate(self.joints):
            if evidence.locked_at is not None:
                continue
            c, v, s = commanded[j], slope[j], error[j]
            evidence.measured, evidence.commanded, evidence.standard_error = v, c, s
            evidence.observable = abs(c) >= cfg.min_command and abs(c) >= 2 * cfg.confidence * s
            stalled = (evidence.observable and v / c < cfg.ratio
                       and abs(v - c) > cfg.confidence * s)
            pushing_limit = ((c > 0 and latest[j] >= self.upper[j] - cfg.limit_margin)
                             or (c < 0 and latest[j] <= self.lower[j] + cfg.limit_margin))
            evidence.at_limit = stalled and pushing_limit
            if not stalled or pushing_limit:
                evidence.evidence_since = None
                continue
            if evidence.evidence_since is None:
                evidence.evidence_since = now
            if now - evidence.evidence_since >= cfg.persistence:
                evidence.locked_at, evidence.position = now, float(latest[j])
                newly.append(j)
        return newly
