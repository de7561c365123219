"""A second detection channel, in task space, for locks the monitor has not seen.

Maciejewski et al. Theorem 1 (eqs 15-17): under a generalized-inverse law qd = G xd with an
undetected lock, the arm can converge to a configuration where the reduced Jacobian
is rank deficient and all the commanded motion is on the locked joint: xd lies in the
span of the locked joints' columns, so qd = sum alpha_i e_i. There the monitor's joint
channel has no witness (no other joint follows its command), and the task error stops
decreasing while joints are commanded.

This channel watches that symptom. Over a sliding `window` it compares the task
displacement the commands should have produced, sum J(q_k) qd_k dt_k with the measured
q_k, with the measured one, the sum of `Robot.displacement` between consecutive samples
(x(q_end) - x(q_start) for a position; for a pose task also the rotation's log, which
the angular rows integrate to over one cycle); the difference r is the unexplained
motion. When the task error has not shrunk by `progress` over the window while joints
were commanded (towards one goal: a new goal restarts the window, `restart`), and
|r| is at least `min_residual`, each joint i is tested as the culprit: had it not moved,
the expected motion would lack c_i = sum j_i(q_k) qd_ik dt_k, so the residual left is
|r - c_i|. The joint that leaves at most `explained`
of |r|, and less than half of what any other joint leaves, is the suspect; the
monitor decides (`MonitorNode`: it declares the suspect locked only if its own
measurements show that joint still while commanded). Units: the task rows of
`Robot.jacobian`, scaled (`Robot.scale_task`: m, and rad times the task's length scale).
Reading taken: the paper gives the theorem, not a detector; this is our test of its
condition (17) on measured data. The theorem is about converging to a fixed x_d, so the
channel watches a held goal: a goal that changes at every message (a streamed
trajectory) restarts the window each time and leaves detection to the joint channel.
Just after a change of goal the plant's lag (latency and response) puts the commanded
motion ahead of the measured one by up to (L + T) |xd|, an unexplained motion a joint
may well explain; comparing the errors to two goals would then call it no progress.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from ft_core.robots import Kinematics, Robot


@dataclass(frozen=True)
class TaskChannelConfig:
    """Parameters of the task-space channel (see the module docstring).

    Attributes:
        window: s of commands and measurements compared, > 0.
        progress: fraction by which the task error must shrink over the window to
            count as progress, in [0, 1).
        min_residual: smallest unexplained task displacement over the window worth
            explaining (m, scaled units), > 0.
        explained: largest fraction of the residual the suspect may leave, in (0, 1).
    """

    window: float = 0.5
    progress: float = 0.05
    min_residual: float = 0.01
    explained: float = 0.25

    def __post_init__(self) -> None:
        checks = {"window": self.window > 0, "progress": 0 <= self.progress < 1,
                  "min_residual": self.min_residual > 0, "explained": 0 < self.explained < 1}
        for name, ok in checks.items():
            if not (ok and math.isfinite(getattr(self, name))):
                raise ValueError(f"task channel {name} = {getattr(self, name)} is out of range")


class TaskChannel:
    """Streams of (measured q, commanded qd, task error) in, a suspected joint out.

    One Jacobian per update: each sample keeps its columns' expected motion
    J(q) qd dt up to the next sample, summed over the window as it slides.
    """

    def __init__(self, robot: Robot, config: TaskChannelConfig | None = None):
        self.robot = robot
        self.config = config or TaskChannelConfig()
        #: (time, task error, expected motion per joint from the previous sample (m, n),
        #: measured motion from the previous sample (m,))
        self._samples: deque[tuple[float, float, np.ndarray, np.ndarray]] = deque()
        self._columns = np.zeros((robot.m, robot.n))
        self._measured = np.zeros(robot.m)  #: the window's measured motion, summed
        #: (time, J(q) qd, task target) of the newest sample
        self._last: tuple[float, np.ndarray, np.ndarray] | None = None
        self.suspect: int | None = None  #: the joint whose loss explains the motion, if any
        self.residuals: np.ndarray = np.zeros(robot.n)  #: |r - c_i| / |r| at the last test

    def update(self, t: float, kinematics: Kinematics, qd: np.ndarray, error: float,
               locked: tuple[int, ...] = ()) -> int | None:
        """Add a cycle (s, rad, commanded rad/s, task error norm); return the suspect.

        `kinematics`: the cycle's snapshot at the configuration (`Robot.kinematics`). Joints in
        `locked` are already known and never suspected. Out-of-order times restart the
        window.
        """
        robot = self.robot
        if self._last is not None and t <= self._last[0]:
            self.restart()
        x = robot.forward(kinematics)
        motion, moved = np.zeros((robot.m, robot.n)), np.zeros(robot.m)
        if self._last is not None:
            motion = self._last[1] * (t - self._last[0])
            moved = robot.task_scale * robot.displacement(self._last[2], x)
            self._columns += motion
            self._measured += moved
        self._samples.append((t, float(error), motion, moved))
        commanded = robot.scale_task(robot.jacobian(kinematics)) * np.asarray(qd, dtype=float)
        self._last = (t, commanded, x)
        while self._samples[0][0] < t - self.config.window:
            self._samples.popleft()
            # The motion that led to the new first sample leaves the window.
            self._columns -= self._samples[0][2]
            self._measured -= self._samples[0][3]
        self.suspect = self._test(locked)
        return self.suspect

    def restart(self) -> None:
        """Forget the window: a new goal (progress towards the old one means nothing)."""
        self._samples.clear()
        self._columns[:] = 0.0
        self._measured[:] = 0.0
        self._last = None
        self.suspect = None

    def _test(self, locked: tuple[int, ...]) -> int | None:
        cfg = self.config
        first, last = self._samples[0], self._samples[-1]
        if len(self._samples) < 3 or last[0] - first[0] < 0.8 * cfg.window:
            return None
        if last[1] < (1 - cfg.progress) * first[1]:
            return None  # the task error is still going down
        residual = self._columns.sum(axis=1) - self._measured
        size = float(np.linalg.norm(residual))
        if size < cfg.min_residual:
            return None
        self.residuals = np.linalg.norm(residual[:, None] - self._columns, axis=0) / size
        candidates = [int(i) for i in np.argsort(self.residuals) if i not in locked]
        if not candidates or self.residuals[candidates[0]] > cfg.explained:
            return None
        best = candidates[0]
        if len(candidates) > 1 and self.residuals[candidates[1]] < 2 * self.residuals[best]:
            return None  # two joints explain it about as well: no suspect
        return best
