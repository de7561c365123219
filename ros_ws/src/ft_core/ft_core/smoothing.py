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
  The joints pass, or are smoothed, all together.

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


class Smoother:
    """The next command towards a target velocity within `CommandLimits` (module docstring).

    Args:
        limits: the arm's limits (velocity, acceleration, jerk; chain order).
    """

    def __init__(self, limits: CommandLimits):
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

    def step(self, target: np.ndarray, t: float, stopped: Iterable[int] = ()) -> np.ndarray:
        """The command (rad/s, a new array) stamped `t` (s) towards `target` (rad/s).

        The target is clipped into the velocity limits; a non-finite one counts as 0.
        A stamp not after the last command's repeats that command. The first command
        after `reset` is reached from the velocity held over `FIRST_INTERVAL`.
        """
        limits = self.limits
        target = np.clip(np.nan_to_num(np.asarray(target, dtype=float), nan=0.0, posinf=0.0,
                                       neginf=0.0), -limits.velocity, limits.velocity)
        stopped = list(stopped)
        if stopped:
            self.velocity[stopped] = self.acceleration[stopped] = self._mean[stopped] = 0.0
            target[stopped] = 0.0
        if self.time is None:
            self.time = t - FIRST_INTERVAL
        dt = t - self.time
        if not dt > 0:
            return self.velocity.copy()
        mean = (target - self.velocity) / dt
        # The interval before the first is a steady one as long as this one.
        previous = self._interval if math.isfinite(self._interval) else dt
        own = (target - self._target) / dt  # the target's acceleration
        passes = ((np.abs(mean - own) <= limits.jerk * dt)
                  & (np.abs(mean) <= limits.acceleration)
                  & (np.abs(mean - self._mean) <= limits.jerk * (dt + previous) / 2)
                  & (np.abs(target + mean * np.abs(mean) / (2 * limits.jerk))
                     <= limits.velocity))
        velocity, acceleration = target, mean
        if not passes.all():
            velocity, acceleration = self._profile(target, dt)
        self._mean = (velocity - self.velocity) / dt
        self.velocity, self.acceleration, self._target = velocity, acceleration, target
        self._interval, self.time = dt, t
        return velocity.copy()

    def _profile(self, target: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Velocity and acceleration dt s along the time-optimal profile to `target`.

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
