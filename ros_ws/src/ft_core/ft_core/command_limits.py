"""The joint velocity, acceleration and jerk limits a real arm's driver enforces.

A velocity-commanded arm refuses a command stream that jumps: Franka's controller stops
with a reflex ("joint_motion_generator_acceleration_discontinuity"), and KUKA FRI, UR's
`speedj` and Kinova's low-level loop check limits of the same kind. `CommandLimits`
holds an arm's limits, `command_limits` picks them (a built-in preset where the
manufacturer publishes them, a conservative default otherwise, either overridden by
parameters), and `DriverCheck` is the test a driver applies to each command.

How a stream of velocity commands v_k stamped t_k is read (the driver interpolates
between commands, as a ros2_control hardware interface with a rate limiter does):

    a_k = (v_k - v_(k-1)) / (t_k - t_(k-1))                  the acceleration, rad/s^2
    j_k = (a_k - a_(k-1)) / ((t_k - t_(k-2)) / 2)            the jerk, rad/s^3

j_k is the divided difference between the midpoints of the two intervals: the samples
of any velocity profile whose acceleration stays within A and whose jerk within J pass
both tests exactly, whatever the spacing of the stamps (`ft_core.smoothing` produces
such samples). Velocities are checked against the URDF's limits. Stamps are read to the
microsecond (`DriverCheck.time_tolerance`): a clock read as float seconds since 1970 is
rounded to a quarter of one, which at 1 kHz changes a_k by a few parts in 10^4.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from enum import Enum

import numpy as np


class Preset(Enum):
    """Where an arm's acceleration and jerk limits come from (`PRESETS`)."""

    FRANKA_PANDA = "franka_panda"
    XARM = "xarm"
    UR = "ur"
    DEFAULT = "default"


#: (acceleration rad/s^2, jerk rad/s^3) per joint from the base, and where they come from.
#: - Franka Panda (FER): "Robot and interface specifications" of the Franka Control
#:   Interface, the limits libfranka's rate limiter enforces (`kMaxJointAcceleration`,
#:   `kMaxJointJerk`).
#: - UFACTORY xArm: joint motion at most 1146 deg/s^2 and 28647 deg/s^3 (UFACTORY's
#:   guide to running the arm at its maximum speed), i.e. 20 rad/s^2 and 500 rad/s^3.
#: - Universal Robots: the controller limits torques, not joint accelerations; 10 rad/s^2
#:   is what UR's own MoveIt configuration (ur_moveit_config) uses, with the default jerk.
#: - Any other arm (KUKA iiwa and Kinova Gen3 included, whose data sheets give no joint
#:   acceleration or jerk limit): 5 rad/s^2 and 1000 rad/s^3, below every arm above.
PRESETS: dict[Preset, tuple[tuple[float, ...], tuple[float, ...]]] = {
    Preset.FRANKA_PANDA: ((15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0),
                          (7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0)),
    Preset.XARM: ((20.0,), (500.0,)),
    Preset.UR: ((10.0,), (1000.0,)),
    Preset.DEFAULT: ((5.0,), (1000.0,)),
}

_UR_JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
              "wrist_2_joint", "wrist_3_joint")


def detect_preset(robot_name: str, joint_names: tuple[str, ...] | list[str]) -> Preset:
    """The preset of an arm from its URDF name and chain joints (DEFAULT if none fits).

    Franka's Panda by its joints `panda_joint1..7` (a prefix allowed), a UR arm by its
    six joint names (a prefix allowed), an xArm by a URDF name starting with "xarm".
    """
    names = list(joint_names)
    if len(names) == 7 and all(re.fullmatch(rf"(.*_)?panda_joint{i + 1}", name)
                               for i, name in enumerate(names)):
        return Preset.FRANKA_PANDA
    if len(names) == 6 and all(name.endswith(ur) for name, ur in zip(names, _UR_JOINTS,
                                                                      strict=True)):
        return Preset.UR
    if robot_name.lower().startswith("xarm"):
        return Preset.XARM
    return Preset.DEFAULT


@dataclass(frozen=True)
class CommandLimits:
    """Per-joint limits of commanded joint motion, chain order.

    Attributes:
        velocity: rad/s (or m/s), > 0, inf for none (the URDF's).
        acceleration: rad/s^2, > 0.
        jerk: rad/s^3, > 0.
        preset: where acceleration and jerk come from (None: given by parameters).
    """

    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray
    preset: Preset | None = None

    def __post_init__(self) -> None:
        n = self.velocity.size
        for name in ("acceleration", "jerk"):
            value = getattr(self, name)
            if value.shape != (n,) or not (np.all(np.isfinite(value)) and np.all(value > 0)):
                raise ValueError(f"{name} limits must be {n} finite values > 0, got "
                                 f"{np.asarray(value).tolist()}")
        if not np.all(self.velocity > 0):
            raise ValueError(f"velocity limits must be > 0, got {self.velocity.tolist()}")

    def describe(self) -> str:
        """One line for a log: the acceleration and jerk limits and their source."""
        source = "parameters" if self.preset is None else f"preset {self.preset.value}"
        return (f"command limits from {source}: acceleration {self.acceleration.tolist()} "
                f"rad/s^2, jerk {self.jerk.tolist()} rad/s^3")


def _per_joint(values, n: int, what: str) -> np.ndarray:
    values = np.asarray(values, dtype=float).ravel()
    if values.size == 1:
        return np.full(n, values[0])
    if values.size != n:
        raise ValueError(f"{what} has {values.size} values for {n} joints (give one or {n})")
    return values.copy()


def command_limits(robot_name: str, joint_names: tuple[str, ...] | list[str],
                   velocity: np.ndarray, preset: str = "auto",
                   acceleration=(), jerk=()) -> CommandLimits:
    """The limits of an arm's commands.

    Args:
        robot_name: the URDF robot name.
        joint_names: the chain's joints (chain order).
        velocity: the URDF's velocity limits (rad/s, chain order).
        preset: "auto" (`detect_preset`) or a `Preset` value.
        acceleration: rad/s^2, one value or one per joint (chain order); empty: the preset's.
        jerk: rad/s^3, likewise.

    Raises:
        ValueError: an unknown preset, a preset for another number of joints, or values
            that are not finite and positive.
    """
    n = len(joint_names)
    if preset == "auto":
        chosen = detect_preset(robot_name, joint_names)
    else:
        try:
            chosen = Preset(preset)
        except ValueError:
            raise ValueError(f"unknown limits preset {preset!r}: auto, "
                             f"{', '.join(p.value for p in Preset)}") from None
    preset_acceleration, preset_jerk = PRESETS[chosen]
    given = len(acceleration) > 0 and len(jerk) > 0
    return CommandLimits(
        np.asarray(velocity, dtype=float).copy(),
        _per_joint(acceleration if len(acceleration) else preset_acceleration, n,
                   f"acceleration limits (preset {chosen.value})"),
        _per_joint(jerk if len(jerk) else preset_jerk, n, f"jerk limits (preset {chosen.value})"),
        None if given else chosen)


class Violation(Enum):
    """What a refused command broke."""

    VELOCITY = "velocity"
    ACCELERATION = "acceleration"
    JERK = "jerk"
    STAMP = "stamp"


@dataclass(frozen=True)
class Refusal:
    """Why a driver refused a command: the limit, the joint and by how much."""

    violation: Violation
    joint: int  #: chain index (-1 for a stamp)
    value: float  #: the commanded velocity, acceleration or jerk (or the stamp step, s)
    limit: float

    def __str__(self) -> str:
        if self.violation is Violation.STAMP:
            return f"command stamp not after the previous one (step {self.value:.6f} s)"
        return (f"joint {self.joint}: commanded {self.violation.value} {self.value:.4g} over its "
                f"limit {self.limit:.4g} ({abs(self.value) / self.limit:.2f} times)")


class DriverCheck:
    """The test a real driver applies to each velocity command (see the module docstring).

    Args:
        limits: the arm's limits.
        tolerance: relative slack of every test (rounding).
        time_tolerance: s by which each stamp may be off.
    """

    def __init__(self, limits: CommandLimits, tolerance: float = 1e-6,
                 time_tolerance: float = 1e-6):
        self.limits = limits
        self.tolerance = tolerance
        self.time_tolerance = time_tolerance
        self._last: tuple[float, np.ndarray, np.ndarray | None, float] | None = None
        #: Largest |value| / limit seen per joint (not exempt): velocity, acceleration,
        #: jerk (3, n); the stamps' slack can take them a few parts in 10^3 past 1.
        self.peaks = np.zeros((3, limits.velocity.size))

    def reset(self) -> None:
        """Forget the stream (after the arm stopped): the next command starts afresh."""
        self._last = None

    def check(self, velocity: np.ndarray, t: float, exempt: tuple[int, ...] = ()
              ) -> Refusal | None:
        """Test the command `velocity` (rad/s, chain order) stamped `t` (s); None: accepted.

        `exempt` joints are not tested (a joint the plant holds locked: its command is
        moot). The first command, and the first after `reset`, is tested against its
        velocity only. The same velocity again with the same stamp is a repeat, accepted;
        another velocity at the same stamp, or an earlier stamp, is refused.
        """
        limits = self.limits
        velocity = np.asarray(velocity, dtype=float)
        mask = np.ones(velocity.size, bool)
        mask[list(exempt)] = False
        refusals = [self._worst(Violation.VELOCITY, velocity, limits.velocity, limits.velocity,
                                mask, 0)]
        if self._last is None:
            self._last = (t, velocity.copy(), None, math.nan)
            return refusals[0]
        t0, v0, a0, dt0 = self._last
        dt = t - t0
        if dt == 0 and np.array_equal(velocity, v0):
            return refusals[0]  # the same command again (a simulated clock stood still)
        if not dt > 0:
            return Refusal(Violation.STAMP, -1, dt, 0.0)
        tau = self.time_tolerance
        acceleration = (velocity - v0) / dt
        refusals.append(self._worst(Violation.ACCELERATION, acceleration, limits.acceleration,
                                    limits.acceleration * (1 + 2 * tau / dt), mask, 1))
        if a0 is not None:
            # What the stamps' error can make of the two accelerations, in jerk.
            slack = 2 * tau * (np.abs(acceleration) / dt + np.abs(a0) / dt0) / ((dt + dt0) / 2)
            refusals.append(self._worst(Violation.JERK, (acceleration - a0) / ((dt + dt0) / 2),
                                        limits.jerk, limits.jerk + slack, mask, 2))
        self._last = (t, velocity.copy(), acceleration, dt)
        return next((refusal for refusal in refusals if refusal is not None), None)

    def _worst(self, violation: Violation, value: np.ndarray, limit: np.ndarray,
               allowed: np.ndarray, mask: np.ndarray, row: int) -> Refusal | None:
        """One test: |value| / limit into the peaks; the worst joint's refusal, if any.

        A joint is refused over what is `allowed` (the limit with the stamps' slack).
        """
        value = np.where(mask, value, 0.0)
        np.maximum(self.peaks[row], np.abs(value) / limit, out=self.peaks[row])
        excess = np.abs(value) / allowed
        worst = int(np.argmax(excess))
        if excess[worst] <= 1.0 + self.tolerance:
            return None
        return Refusal(violation, worst, float(value[worst]), float(limit[worst]))


@dataclass(frozen=True)
class LimitsConfig:
    """How a node picks its arm's limits (`command_limits`), chain order.

    Attributes:
        preset: "auto" or a `Preset` value.
        acceleration: rad/s^2, one value or one per joint; empty: the preset's.
        jerk: rad/s^3, likewise.
    """

    preset: str = "auto"
    acceleration: tuple[float, ...] = ()
    jerk: tuple[float, ...] = ()

    def build(self, robot_name: str, joint_names: tuple[str, ...] | list[str],
              velocity: np.ndarray) -> CommandLimits:
        """The limits for a chain (ValueError as `command_limits`)."""
        return command_limits(robot_name, joint_names, velocity, self.preset,
                              self.acceleration, self.jerk)


def limits_config(smooth: bool, preset: str, acceleration, jerk,
                  order: np.ndarray | None = None) -> LimitsConfig | None:
    """A node's `LimitsConfig` from its parameters; None where `smooth` is off.

    `acceleration` and `jerk`: one value, or one per joint in command order, where the
    k-th joint is the chain's `order[k]` (None: chain order); empty: the preset's.
    Raises ValueError for values that are not finite and positive, or an unknown preset.
    """
    if preset != "auto" and preset not in {p.value for p in Preset}:
        raise ValueError(f"unknown limits preset {preset!r}: auto, "
                         f"{', '.join(p.value for p in Preset)}")
    chained = []
    for name, values in (("limits.acceleration", acceleration), ("limits.jerk", jerk)):
        values = np.asarray(values, dtype=float).ravel()
        if not (np.all(np.isfinite(values)) and np.all(values > 0)):
            raise ValueError(f"{name} must be finite and > 0, got {values.tolist()}")
        if values.size > 1 and order is not None:
            if values.size != order.size:
                raise ValueError(f"{name} has {values.size} values for {order.size} joints "
                                 f"(give one or {order.size})")
            chain = np.empty(order.size)
            chain[order] = values
            values = chain
        chained.append(tuple(values.tolist()))
    return LimitsConfig(preset, *chained) if smooth else None
