"""Task velocities from the user's targets: pose goals and twist streams.

- A pose goal is tracked with a proportional law, xd = gain * e (e from
  `Robot.task_error`: position error, and for pose tasks the rotation error as a
  rotation vector), its linear part capped at `max_linear` (m/s) and its angular
  part at `max_angular` (rad/s), directions kept. Inside the goal tolerances the
  task velocity is exactly 0, so the arm stops at the goal instead of creeping.
  For position and planar tasks the goal's orientation is ignored.
- A twist (m/s, rad/s, base frame) is a feed-forward velocity; the rows the task
  space does not have are dropped. Once older than the timeout it decays linearly
  to 0 over one more timeout, so a lost stream stops the arm smoothly.

`TwistTarget` and `PoseTarget` are the target the controller's cycle follows (`Target`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ft_core.robots import Robot, TaskSpace


@dataclass(frozen=True)
class PoseTracking:
    """Gains and limits of pose-goal tracking.

    Attributes:
        gain: proportional gain (1/s), > 0.
        max_linear: cap on the linear task speed (m/s), > 0.
        max_angular: cap on the angular task speed (rad/s), > 0.
        position_tolerance: goal reached below this position error (m).
        angle_tolerance: goal reached below this rotation error (rad).
    """

    gain: float = 2.0
    max_linear: float = 0.25
    max_angular: float = 0.5
    position_tolerance: float = 1e-4
    angle_tolerance: float = 1e-3

    def __post_init__(self) -> None:
        for name in ("gain", "max_linear", "max_angular", "position_tolerance",
                     "angle_tolerance"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and positive, got {value}")


def goal_from_transform(robot: Robot, transform: np.ndarray) -> np.ndarray:
    """The task goal of a 4x4 pose (base frame): the pose, the position, or x-y."""
    if robot.task_space == TaskSpace.POSE:
        return np.asarray(transform, dtype=float)
    return np.asarray(transform, dtype=float)[: robot.m, 3].copy()


def norm(vector: np.ndarray) -> float:
    """The Euclidean norm of a vector: `np.linalg.norm`'s arithmetic (the root of x . x).

    Without its argument handling, several times a cycle.
    """
    return math.sqrt(vector.dot(vector))


def _cap(vector: np.ndarray, limit: float) -> np.ndarray:
    size = norm(vector)
    return vector if size <= limit else vector * (limit / size)


def pose_velocity(robot: Robot, error: np.ndarray,
                  tracking: PoseTracking) -> tuple[np.ndarray, bool]:
    """(task velocity, whether the goal is reached) for a task error (`Robot.task_error`).

    The caller computes the error once per cycle (the controller's task channel
    watches its norm too).
    """
    linear, angular = error[: min(3, robot.m)], error[3:]
    reached = (norm(linear) < tracking.position_tolerance
               and norm(angular) < tracking.angle_tolerance)
    if reached:
        return np.zeros(robot.m), True
    return np.concatenate([_cap(tracking.gain * linear, tracking.max_linear),
                           _cap(tracking.gain * angular, tracking.max_angular)]), False


def twist_velocity(robot: Robot, twist: np.ndarray) -> np.ndarray:
    """The task rows of a base-frame twist [vx, vy, vz, wx, wy, wz]."""
    twist = np.asarray(twist, dtype=float)
    return twist.copy() if robot.task_space == TaskSpace.POSE else twist[: robot.m].copy()


def staleness_scale(age: float, timeout: float) -> float:
    """1 up to `timeout` seconds, then linearly down to 0 at twice the timeout."""
    if age <= timeout:
        return 1.0
    return max(0.0, 2.0 - age / timeout)


@dataclass(frozen=True)
class TwistTarget:
    """A task velocity (m/s and rad/s, `twist_velocity`), decaying from its stamp."""

    value: np.ndarray
    stamp: float  #: s, the twist's stamp
    kind: ClassVar[str] = "twist"  #: as diagnostics name it


@dataclass(frozen=True)
class PoseTarget:
    """A pose goal (`goal_from_transform`), tracked until another target comes."""

    value: np.ndarray
    stamp: float  #: s, when the goal arrived
    kind: ClassVar[str] = "pose"  #: as diagnostics name it


#: The latest target the cycle follows.
Target = TwistTarget | PoseTarget


#: s: a joint state this much older than the node's clock is stamped by another clock.
OTHER_CLOCK = 86400.0


def stale_state(age: float) -> str:
    """Why a joint state `age` s old stops the arm (another clock's, or just old)."""
    if age > OTHER_CLOCK:
        return (f"joint states are stamped {age:.0f} s before this node's clock: another "
                "clock's (use_sim_time set on one node and not on the other?)")
    return f"no joint state for {age:.3f} s"
