"""Online smoothing of joint velocity commands within acceleration and jerk limits.

Each call takes the newest target velocity and returns the next command, so that the
stream of commands passes `ft_core.command_limits.DriverCheck` by construction, whatever
the spacing of the commands' stamps:

- a target the previous command can reach within the limits in the time since it
  passes as it is, where the acceleration that takes is within a jerk step of the
  target's own (so the commands can go on following it: a target that stands still is
  not overshot) and can still be brought to 0 within the velocity limit (a controller's
  output that is smooth already is not delayed, and a delay catches up);
- otherwise the command follows the time-optimal, jerk-limited profile from the
  current velocity and acceleration to the target, sampled at the new stamp (Ruckig's
  velocity interface, Berscheid & Kroeger, RSS 2021, as MoveIt Servo's Ruckig smoothing
  plug-in uses it); the next call plans again from the sampled state, so the
  acceleration stays continuous and the jerk within its limit. The joints are
  phase-synchronised: where Ruckig can, their velocities move together along the
  straight line to the target, so a null-space motion stays in the null space (a
  joint-by-joint profile turned the tool off a held goal); otherwise time-synchronised.
  A caller may name joints to profile on their own: a joint braking for a position
  limit, which synchronised would brake only at the pace of the joint with the longest
  way to its target. The joints pass, or are smoothed, all together.

The velocity a joint would reach if its acceleration were brought to 0 at once at the
jerk limit, v + a|a|/(2J), stays within the velocity limit: the profiles land on
targets within it, and a target passes only under that condition. Samples of such a
profile keep the discrete acceleration within A and the divided
difference of the jerk within J (the acceleration is J-Lipschitz, and the difference
of its means over two intervals is at most J times the distance of their midpoints).

Joints named in `stopped` get exactly 0 at once, their state with them: a locked joint
(it is stopped anyway, and its command is moot) or a joint held at 0 by a caller.
A stop is a target of zeros: `stop_time` bounds how long it takes.
"""

from __future__ import annotations

import atexit
import math
import weakref
from collections.abc import Iterable

import numpy as np
from numba import njit
from ruckig import (
    ControlInterface,
    InputParameter,
    Result,
    Ruckig,
    RuckigError,
    Synchronization,
    Trajectory,
)

from ft_core.command_limits import CommandLimits

_RUCKIG_OK = (Result.Working, Result.Finished)
#: s assumed between the velocity held at a reset and the first command after it.
FIRST_INTERVAL = 1e-3
_NO_JOINTS = np.zeros(0, dtype=np.int64)


class Smoother:
    """The next command towards a target velocity within `CommandLimits` (module docstring).

    Args:
        limits: the arm's limits (velocity, acceleration, jerk; chain order).
    """

    def __init__(self, limits: CommandLimits):
        compile_ahead()  # numba's cache loaded here, not in the first control cycle
        self.limits = limits
        #: Ruckig's generator, input and trajectory, made at the first profile.
        self._ruckig: tuple[Ruckig, InputParameter, Trajectory] | None = None
        _LIVE.add(self)
        self.reset()

    def reset(self, velocity: np.ndarray | None = None) -> None:
        """Start again from `velocity` (rad/s; default zeros) held steady, time unknown."""
        n = self.limits.velocity.size
        self.velocity = np.zeros(n) if velocity is None else np.array(velocity, dtype=float)
        #: The profile's acceleration at the last command (rad/s^2), where the next starts.
        self.acceleration = np.zeros(n)
        #: The mean acceleration over the last interval (rad/s^2), as a driver computes it.
        self._mean = np.zeros(n)
        self._target = self.velocity.copy()  # rad/s, the last target
        self._interval = math.nan  # s, the last interval
        self.time: float | None = None  #: s, the stamp of the last command

    @property
    def at_rest(self) -> bool:
        """Whether the last command was zeros with no acceleration left."""
        return not (self.velocity.any() or self.acceleration.any() or self._mean.any())

    def stop_time(self) -> float:
        """An upper bound of the time (s) a stop from the current state takes."""
        limits = self.limits
        return float(np.max(np.abs(self.velocity) / limits.acceleration
                            + (np.abs(self.acceleration) + 2 * limits.acceleration) / limits.jerk))

    def step(self, target: np.ndarray, t: float, stopped: Iterable[int] = (),
             alone: Iterable[int] = ()) -> np.ndarray:
        """The command (rad/s, a new array) stamped `t` (s) towards `target` (rad/s).

        `alone`: joints whose profile is not synchronised with the others' (a joint braking
        for a position limit brakes at its own acceleration limit, not at the pace of a
        joint with further to go). The target is clipped into the velocity limits; a
        non-finite one counts as 0.
        A stamp not after the last command's repeats that command. The first command
        after `reset` is reached from the velocity held over `FIRST_INTERVAL`.
        """
        limits = self.limits
        if self.time is None:
            self.time = t - FIRST_INTERVAL
        dt = t - self.time
        # The interval before the first is a steady one as long as this one.
        previous = self._interval if math.isfinite(self._interval) else dt
        passed, target = _try_pass(
            np.asarray(target, dtype=float),
            np.array(stopped, dtype=np.int64) if stopped else _NO_JOINTS, dt, previous,
            self.velocity, self.acceleration, self._mean, self._target, limits.velocity,
            limits.acceleration, limits.jerk)
        if not dt > 0:
            return self.velocity.copy()
        if not passed:
            velocity, self.acceleration = self._profile(target, dt, alone)
            self._mean = (velocity - self.velocity) / dt
            self.velocity, self._target = velocity, target
        self._interval, self.time = dt, t
        return self.velocity.copy()

    def adopt(self, velocity: np.ndarray, t: float) -> bool:
        """Go on from a command (rad/s) another node sent the plant stamped `t` (s).

        As if this smoother had sent it: the velocity, and the mean acceleration from the
        last command to it (the profile's acceleration within the limits), so the next
        command continues the stream the driver saw. Whether it was taken: a stamp not
        after the last command's is not (the driver refuses it).
        """
        if self.time is not None and not t > self.time:
            return False
        velocity = np.array(velocity, dtype=float)
        dt = FIRST_INTERVAL if self.time is None else t - self.time
        self._mean = (velocity - self.velocity) / dt
        self.acceleration = np.clip(self._mean, -self.limits.acceleration,
                                    self.limits.acceleration)
        self.velocity, self._target = velocity, velocity.copy()
        self._interval, self.time = dt, t
        return True

    def _profile(self, target: np.ndarray, dt: float,
                 alone: Iterable[int]) -> tuple[np.ndarray, np.ndarray]:
        """Velocity and acceleration dt s along the time-optimal profile to `target`.

        Phase-synchronised, but for the joints `alone` (Ruckig's per-joint synchronisation).
        A start exactly on the boundary of what the limits allow (an acceleration at its
        limit whose stop lands exactly on the target) can have no profile in floating
        point: it is planned again from an acceleration smaller by a millionth. Should
        that fail too, the velocity is held.
        """
        if self._ruckig is None:
            self._ruckig = _ruckig(self.limits)
        generator, parameters, trajectory = self._ruckig
        limits = self.limits
        parameters.current_velocity = self.velocity.tolist()
        parameters.target_velocity = target.tolist()
        alone = set(alone)
        parameters.per_dof_synchronization = [
            Synchronization.No if j in alone else Synchronization.Phase
            for j in range(target.size)] if alone else None
        acceleration = np.clip(self.acceleration, -limits.acceleration, limits.acceleration)
        for shrink in (1.0, 1.0 - 1e-6):
            parameters.current_acceleration = (shrink * acceleration).tolist()
            try:
                if generator.calculate(parameters, trajectory) in _RUCKIG_OK:
                    _, velocity, reached = trajectory.at_time(dt)
                    return np.array(velocity), np.array(reached)
            except RuckigError:
                continue
        return self.velocity.copy(), np.zeros(target.size)


def _ruckig(limits: CommandLimits) -> tuple[Ruckig, InputParameter, Trajectory]:
    """Ruckig's objects for `limits`: velocity interface, phase-synchronised."""
    n = limits.velocity.size
    parameters = InputParameter(n)
    parameters.control_interface = ControlInterface.Velocity
    parameters.synchronization = Synchronization.Phase
    parameters.max_acceleration = limits.acceleration.tolist()
    parameters.max_jerk = limits.jerk.tolist()
    parameters.current_position = [0.0] * n
    parameters.target_acceleration = [0.0] * n
    return Ruckig(n), parameters, Trajectory(n)


#: Every smoother alive, whose Ruckig objects `_release` drops before the interpreter
#: ends: nanobind reports objects of its modules still alive then as leaks, on stderr.
_LIVE: weakref.WeakSet[Smoother] = weakref.WeakSet()


@atexit.register
def _release() -> None:
    for smoother in list(_LIVE):
        smoother._ruckig = None


@njit(cache=True, error_model="numpy")
def _try_pass(target: np.ndarray, stopped: np.ndarray, dt: float, previous: float,
              velocity: np.ndarray, acceleration: np.ndarray, mean: np.ndarray,
              last: np.ndarray, v_max: np.ndarray, a_max: np.ndarray, j_max: np.ndarray,
              ) -> tuple[bool, np.ndarray]:
    """(whether `target` passed as it is, the target as taken).

    The target (rad/s) is made finite (a non-finite value counts as 0) and clipped into
    `v_max`; the `stopped` joints (indices) get 0, their velocity, acceleration and
    mean (the state, rad/s and rad/s^2, changed in place) with them. It passes where,
    on every joint, its mean acceleration over dt is within `a_max`, differs from the
    last one (`mean`, over `previous` s) by at most `j_max` times the midpoints'
    distance and from the target's own (from `last`, the last target) by at most `j_max`
    dt, and where the velocity it would reach with that acceleration brought to 0 at
    `j_max` stays within `v_max` (the module docstring); then the state becomes it
    (velocity and `last` the target, acceleration and `mean` that mean). Nothing passes
    without time (dt <= 0).
    """
    n = target.size
    clean = np.empty(n)
    for j in range(n):
        value = target[j] if np.isfinite(target[j]) else 0.0
        clean[j] = min(max(value, -v_max[j]), v_max[j])
    for j in stopped:
        clean[j] = velocity[j] = acceleration[j] = mean[j] = 0.0
    if not dt > 0:
        return False, clean
    reached = np.empty(n)
    for j in range(n):
        a = (clean[j] - velocity[j]) / dt
        if (abs(a) > a_max[j] or abs(a - mean[j]) > j_max[j] * (dt + previous) / 2
                or abs(a - (clean[j] - last[j]) / dt) > j_max[j] * dt
                or abs(clean[j] + a * abs(a) / (2 * j_max[j])) > v_max[j]):
            return False, clean
        reached[j] = a
    velocity[:] = clean
    last[:] = clean
    acceleration[:] = reached
    mean[:] = reached
    return True, clean


def compile_ahead() -> None:
    """Load the compiled pass test now (numba's cache), not in a control cycle."""
    zeros = np.zeros(1)
    _try_pass(zeros, _NO_JOINTS, 1e-3, 1e-3, zeros.copy(), zeros.copy(), zeros.copy(),
              zeros.copy(), np.ones(1), np.ones(1), np.ones(1))
