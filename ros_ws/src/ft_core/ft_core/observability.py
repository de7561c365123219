"""Observability motion: null-space excursions that let a lock on an idle joint show up.

Nothing can be detected for a joint that is not commanded (docs/detection.md): in a
Panda position task the tool point lies on joint 7's axis, so joint 7 is never
commanded and its lock goes unseen until the task changes, and then the controller
commands a joint that cannot move. With this option the controller gives each joint
not commanded for `idle_time` a short excursion: the joint's velocity follows one period
of speed x sin(2 pi t / duration) (out and back, no net displacement), made up by the
other joints through the null space of the healthy Jacobian, so the tool velocity is
unchanged (`ResolutionEngine.excursion` projects it and keeps it inside every soft and
hard limit). One idle joint at a time, the longest idle first, with a witness joint
(see `Excursions`). When every joint is idle (the arm holding still) a lock is seen
within `idle_time` plus one round of n excursions. A joint that cannot move
without moving the tool (its share of the null space below `MIN_SHARE`, e.g. on a
non-redundant task) is not excited and is retried after another `idle_time`.

"Commanded" means at least `OBSERVED_SPEED`, the monitor's default smallest observable
velocity, so every joint the timers count as observed is one the monitor could judge.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from ft_core.detection import DetectorConfig

#: A joint commanded at least this fast (rad/s) is observed (the monitor's default).
OBSERVED_SPEED = DetectorConfig.min_command
#: Share (I - J+ J)_jj of the null space below which joint j is not excited.
MIN_SHARE = 0.05


@dataclass(frozen=True)
class ObservabilityConfig:
    """When and how joints are excited.

    Attributes:
        idle_time: s a joint may go without being commanded before an excursion, > 0.
        speed: peak joint velocity of an excursion (rad/s), > `OBSERVED_SPEED`.
        duration: s of one excursion (one sine period), > 0.
    """

    idle_time: float = 5.0
    speed: float = 0.3
    duration: float = 1.0

    def __post_init__(self) -> None:
        for name, low in (("idle_time", 0.0), ("duration", 0.0), ("speed", OBSERVED_SPEED)):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > low):
                raise ValueError(f"observability {name} must be finite and > {low}, "
                                 f"got {value}")


class Excursions:
    """Per-joint idle timers and the excursion under way (times in s, any clock).

    Each excursion moves two joints: the idle one and a witness, the healthy joint
    observed longest ago after it. The monitor declares a lock only while another
    joint is seen moving as commanded (a stopped plant is not n locks), and the null
    space alone may move just the idle joint (joint 7 of a Panda position task).
    """

    def __init__(self, n: int, config: ObservabilityConfig):
        self.config = config
        self._last: np.ndarray | None = None  # time each joint was last observed
        self._clock = -math.inf  # the t of the last update
        self._n = n
        self._active: tuple[int, int | None, float] | None = None  # (joint, witness, start)

    @property
    def active(self) -> int | None:
        """The idle joint being excited, if any."""
        return None if self._active is None else self._active[0]

    def update(self, t: float, qd: np.ndarray, locked: Iterable[int]) -> list[tuple[int, float]]:
        """Note the command about to be sent at t; return the (joint, velocity) to add.

        Empty, or the idle joint first and then its witness. Joints in `locked` are
        never excited. A backwards jump of t (a restarted simulation clock) restarts
        every timer.
        """
        if self._last is None or t < self._clock:
            self._last, self._active = np.full(self._n, t), None
        self._clock = t
        self._last[np.abs(qd) >= OBSERVED_SPEED] = t
        cfg = self.config
        if self._active is None and t - self._last.min() < cfg.idle_time:
            return []  # no joint, locked or not, idle long enough: the common cycle, no sort
        locked = set(locked)
        if self._active is not None:
            joint, witness, start = self._active
            if t - start < cfg.duration and joint not in locked:
                speed = cfg.speed * math.sin(2 * math.pi * (t - start) / cfg.duration)
                return [(joint, speed)] + ([] if witness is None or witness in locked
                                           else [(witness, speed)])
            self._last[[joint] if witness is None else [joint, witness]] = t
            self._active = None
        order = [int(j) for j in np.argsort(self._last, kind="stable") if j not in locked]
        if not order or t - self._last[order[0]] < cfg.idle_time:
            return []
        witness = order[1] if len(order) > 1 else None
        self._active = (order[0], witness, t)
        return [(order[0], 0.0)] + ([] if witness is None else [(witness, 0.0)])

    def cannot_move(self, joint: int, t: float) -> None:
        """`joint` cannot be excited now (no null-space share): retry after `idle_time`."""
        if self._last is not None:
            self._last[joint] = t
        if self.active == joint:
            self._active = None
