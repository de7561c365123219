"""The engine's configuration: the resolution modes, the gains and limits, their checks.

`EngineConfig` refuses values no robot could use; `check_config` what this robot cannot
(probabilities and soft limits per joint, the swing measure without inertias), without
building an engine: the controller node validates a parameter change with it.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ft_core import measures
from ft_core.pseudoinverse import Damping
from ft_core.robots import Robot


class Resolution(enum.StrEnum):
    """The null-space preference of a cycle (`EngineConfig.resolution`; docs/engine.md).

    LEAST_NORM: limit avoidance only; MAX_KFM: ascent on the fault-tolerance measure
    (Maciejewski et al. eq 8); MIN_JUMP: the minimum velocity jump at the next failure
    (Zhao & Li eq 5); BLEND: both.
    """

    LEAST_NORM = "least_norm"
    MAX_KFM = "max_kfm"
    MIN_JUMP = "min_jump"
    BLEND = "blend"


#: The resolution names, as plain strings (parameter validation, messages).
RESOLUTIONS = tuple(r.value for r in Resolution)
#: The share of the commands' acceleration limit the velocity bounds brake at (`braking`).
BRAKING_SHARE = 0.5


@dataclass(frozen=True)
class EngineConfig:
    """Parameters of the engine; invalid values raise ValueError with the reason.

    Attributes:
        resolution: a `Resolution` value: "least_norm", "max_kfm", "min_jump" or "blend".
        kfm_gain: gain of the kfm gradient ascent, rad/s per (m/rad) of grad K, >= 0.
        swing_gain: gain of the swing-measure descent, rad/s per rad of grad h, >= 0.
        jump_gain: gain of the minimum-jump term (1 = exact minimum), >= 0.
        limit_gain: gain of the soft/hard-limit avoidance (rad/s at an edge), >= 0.
        failure_probabilities: one per joint (>= 0); empty = equally likely.
        soft_lower, soft_upper: soft-limit box (rad); empty = none.
        hard_lower, hard_upper: hard limits narrower than the URDF's (rad; a joint's usable
            range, `ft_core.adaptation`), intersected with them and kept after a failure;
            -inf / inf for a side not narrowed; empty = the URDF's.
        velocity_factors: one per joint in (0, 1], multiplying its velocity limit on top
            of `velocity_scale` (a degraded joint's, `ft_core.adaptation`); empty = all 1.
        acceleration, jerk: the commands' limits, one per joint (rad/s^2, rad/s^3; the
            controller's smoother's, `ft_core.command_limits`): a joint's velocity is
            bounded so that braking within them it stops before its position limit
            (`braking`); empty = the commands have none: one cycle to the limit.
        release_soft_limits_on_failure: drop the soft box once a joint is locked.
        dt: control period (s) over which position limits are enforced.
        velocity_scale: fraction of the URDF velocity limits that may be used, in (0, 1].
        damping: damped pseudo-inverse rule (singular values in m).
        kfm_temperature: soft-min temperature (m) of the kfm gradient; 0 = plain eq 8.
        limit_buffer: width (rad) of the zone near a box edge where avoidance acts.
    """

    resolution: str = "blend"
    kfm_gain: float = 50.0
    swing_gain: float = 0.0
    jump_gain: float = 1.0
    limit_gain: float = 1.0
    failure_probabilities: Sequence[float] = ()
    soft_lower: Sequence[float] = ()
    soft_upper: Sequence[float] = ()
    hard_lower: Sequence[float] = ()
    hard_upper: Sequence[float] = ()
    velocity_factors: Sequence[float] = ()
    acceleration: Sequence[float] = ()
    jerk: Sequence[float] = ()
    release_soft_limits_on_failure: bool = True
    dt: float = 0.004
    velocity_scale: float = 0.5
    damping: Damping = field(default_factory=Damping)
    kfm_temperature: float = 0.005
    limit_buffer: float = 0.15

    def __post_init__(self) -> None:
        if self.resolution not in RESOLUTIONS:
            raise ValueError(f"resolution {self.resolution!r} is not one of {RESOLUTIONS}")
        for name in ("kfm_gain", "swing_gain", "jump_gain", "limit_gain", "kfm_temperature",
                     "limit_buffer"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {value}")
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be positive, got {self.dt}")
        if not (math.isfinite(self.velocity_scale) and 0 < self.velocity_scale <= 1):
            raise ValueError(f"velocity_scale must be in (0, 1], got {self.velocity_scale}")
        if len(self.soft_lower) != len(self.soft_upper):
            raise ValueError("soft_lower and soft_upper must have the same length")
        if len(self.hard_lower) != len(self.hard_upper):
            raise ValueError("hard_lower and hard_upper must have the same length")


def check_config(robot: Robot, config: EngineConfig) -> tuple[np.ndarray | None,
                                                              tuple[np.ndarray, np.ndarray]]:
    """What of `config` depends on the robot, checked: (failure probabilities, soft box).

    Raises ValueError where the engine would refuse it (a probability per joint; soft
    limits of n finite values each, lower below upper; hard limits of n values each, not
    nan, lower below upper; n velocity factors in (0, 1]; n finite positive accelerations and
    jerks, or none of either; swing_gain > 0 on a model without
    inertias, whose swing measure is undefined), without building an engine: the node
    validates parameter changes with it. No probabilities: None; no soft limits: two
    empty arrays.
    """
    n = robot.n
    if config.swing_gain > 0 and not robot.has_inertias:
        raise ValueError(f"swing_gain > 0 needs a model with inertias: {robot.name}'s URDF "
                         "gives its links no mass (use swing_gain 0 or a URDF with <inertial>)")
    probabilities = None
    if len(config.failure_probabilities):
        probabilities = np.asarray(config.failure_probabilities, dtype=float)
        measures.failure_weights(probabilities, n)  # validates
    soft = (np.zeros(0), np.zeros(0))
    if len(config.soft_lower):
        lower = np.asarray(config.soft_lower, dtype=float)
        upper = np.asarray(config.soft_upper, dtype=float)
        if (lower.shape != (n,) or upper.shape != (n,)
                or not np.all(np.isfinite(lower) & np.isfinite(upper))):
            raise ValueError(f"soft limits need {n} finite values each")
        if np.any(lower > upper):
            raise ValueError("a soft lower limit is above its upper limit")
        soft = (lower, upper)
    hard_limits(robot, config)
    velocity_limits(robot, config)
    braking(robot, config)
    return probabilities, soft


def hard_limits(robot: Robot, config: EngineConfig) -> tuple[np.ndarray, np.ndarray]:
    """The hard limits in force (rad): the URDF's, narrowed to `hard_lower`/`hard_upper`.

    A narrowed side outside the URDF's range is clipped into it. ValueError: not n values
    each, a nan, or a lower side above its upper side.
    """
    n = robot.n
    if not len(config.hard_lower):
        return robot.lower.copy(), robot.upper.copy()
    lower = np.asarray(config.hard_lower, dtype=float)
    upper = np.asarray(config.hard_upper, dtype=float)
    if lower.shape != (n,) or upper.shape != (n,) or np.any(np.isnan(lower) | np.isnan(upper)):
        raise ValueError(f"hard limits need {n} values each, none nan")
    if np.any(lower > upper):
        raise ValueError("a hard lower limit is above its upper limit")
    return (np.clip(lower, robot.lower, robot.upper), np.clip(upper, robot.lower, robot.upper))


def velocity_limits(robot: Robot, config: EngineConfig) -> np.ndarray:
    """The joint speeds the engine allows (rad/s): URDF's x velocity_scale x velocity_factors.

    ValueError: not n factors, or one outside (0, 1].
    """
    speeds = robot.velocity_limits * config.velocity_scale
    if not len(config.velocity_factors):
        return speeds
    factors = np.asarray(config.velocity_factors, dtype=float)
    if factors.shape != (robot.n,) or not np.all((factors > 0) & (factors <= 1)):
        raise ValueError(f"velocity_factors need {robot.n} values in (0, 1]")
    return speeds * factors


def braking(robot: Robot, config: EngineConfig) -> tuple[np.ndarray, np.ndarray]:
    """(lead s, deceleration rad/s^2) per joint, for `limits.velocity_bounds`.

    The lead is the cycle dt plus 2 a / j: the jerk-limited time to turn an acceleration
    of a towards a limit into a braking of a. The deceleration is `BRAKING_SHARE` a: the commands
    brake at up to a (`smoothing`, the joint profiled on its own), and the other half
    covers the error of the plant lag the controller identified (`reference`), by which
    the configuration the commands take the arm to is known. Without command limits: dt
    and inf.
    ValueError: not n finite positive values each, or only one of the two given.
    """
    n = robot.n
    if not len(config.acceleration) and not len(config.jerk):
        return np.full(n, config.dt), np.full(n, np.inf)
    acceleration = np.asarray(config.acceleration, dtype=float)
    jerk = np.asarray(config.jerk, dtype=float)
    for name, value in (("acceleration", acceleration), ("jerk", jerk)):
        if value.shape != (n,) or not np.all(np.isfinite(value) & (value > 0)):
            raise ValueError(f"{name} limits need {n} finite values > 0, got "
                             f"{value.tolist()}")
    return braking_from(config.dt, acceleration, jerk)


def braking_from(lead: float, acceleration: np.ndarray, jerk: np.ndarray,
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(`lead` + 2 a / j s, `BRAKING_SHARE` a rad/s^2) per joint: see `braking`."""
    return lead + 2.0 * acceleration / jerk, BRAKING_SHARE * acceleration
