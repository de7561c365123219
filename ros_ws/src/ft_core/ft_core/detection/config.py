"""The detector's parameters, checked on construction (docs/detection.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ft_core.detection.identification import LATENCY_GRID, RESPONSE_TIME_GRID


@dataclass(frozen=True)
class DetectorConfig:
    """Detector parameters (docs/detection.md).

    Attributes:
        window: sliding window (s), > 0.
        min_command: smallest observable predicted velocity (rad/s or m/s), >= 0.
        latency: plant latency (s) if known (fixes the model); None: identified.
        response_time: plant response time (s) if known; None: identified.
        persistence: how long lock evidence must hold before a lock is declared (s).
        ratio: measured over predicted velocity below which a joint looks stalled, in (0, 1).
        following_ratio: measured over predicted velocity from which a joint follows.
        confidence: separation in standard errors (z), > 0.
        min_samples: fewest positions in the window for a decision, >= 3.
        limit_margin: distance to a physical limit counting as "at the limit" (rad).
        follow_time: s the plant must be seen following before decisions.
        memory: s, forgetting time of the identification.
        min_excitation: s of informative data before the identified set replaces the prior.
    """

    window: float = 0.08
    min_command: float = 0.05
    latency: float | None = None
    response_time: float | None = None
    persistence: float = 0.03
    ratio: float = 0.3
    following_ratio: float = 0.7
    confidence: float = 5.0
    min_samples: int = 5
    limit_margin: float = 0.01
    follow_time: float = 0.2
    memory: float = 10.0
    min_excitation: float = 0.5

    def __post_init__(self) -> None:
        checks = {"window": self.window > 0, "min_command": self.min_command >= 0,
                  "persistence": self.persistence >= 0, "ratio": 0 < self.ratio < 1,
                  "following_ratio": self.ratio <= self.following_ratio <= 1,
                  "confidence": self.confidence > 0, "min_samples": self.min_samples >= 3,
                  "limit_margin": self.limit_margin >= 0, "follow_time": self.follow_time >= 0,
                  "memory": self.memory > 0, "min_excitation": self.min_excitation >= 0}
        for name in ("latency", "response_time"):
            value = getattr(self, name)
            checks[name] = value is None or 0 <= value <= 1.0
        for name, ok in checks.items():
            value = getattr(self, name)
            if not ok or (value is not None and not math.isfinite(value)):
                raise ValueError(f"detection {name} = {value} is out of range")

    def grids(self) -> tuple[np.ndarray, np.ndarray]:
        """(latencies, response times) of the candidate models (s)."""
        return (LATENCY_GRID if self.latency is None else np.array([self.latency]),
                RESPONSE_TIME_GRID if self.response_time is None
                else np.array([self.response_time]))
