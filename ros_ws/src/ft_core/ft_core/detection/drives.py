"""A drive that gives no torque: a free swing told by the efforts as well as by the motion.

A joint whose drive lost its torque falls under gravity (Maciejewski et al. sec. 2.3:
the swing angle is the damage). By its motion alone the lock detector names it only
beyond what a healthy servo's transients could do (`rules.moves_on_its_own`: faster than
twice any joint's plausible command when it falls the way it was commanded, and for the
plant's settling time when slow). Those transients need torque; a drive without torque
gives none, while one that holds or moves a joint against gravity gives about the gravity
torque g(q) (the URDF's inertias).

`DriveWatch` names a joint *silent* when, for `SILENT_TIME` s, its reported effort stays
below `SILENT_SHARE` of its gravity torque, that torque is at least `GRAVITY_SHARE` of
the joint's effort limit, and the joint has fallen `FALL` rad, the way gravity turns it
(`ft_core.swing.falling_directions`), from the highest point since. Silence alone is no
fault: a healthy drive is silent while its command accelerates the joint downhill as
fast as gravity does (a Panda's shoulder: its 7.5 rad/s^2 limit is about g / inertia),
for 60 ms in 12 minutes of goals and for 200 ms in a remap after a brake, on the physics
plant. So a silent joint still has to move outside its plausible predictions, but with
no allowance for a servo's transient and no wait (`LockDetector.measure`), and the
contact veto does not hold it back (a drive pushing against an obstacle gives more
torque, not none). A joint gravity hardly turns (a vertical axis) is never silent: its
free swing is told by its motion alone. Without efforts, inertias or effort limits
nothing is silent.
"""

from __future__ import annotations

import math

import numpy as np

from ft_core import swing
from ft_core.robots import Robot

#: A drive giving less than this share of its joint's gravity torque gives none.
SILENT_SHARE = 0.1
#: Least gravity torque, as a share of the joint's effort limit, for a silent drive to say
#: anything (below it a healthy drive's torque is mostly its servo's).
GRAVITY_SHARE = 0.05
#: s a drive must stay silent, its joint falling, to be named.
SILENT_TIME = 0.05
#: rad the joint must have fallen meanwhile (five times the sim's position noise).
FALL = 0.005


class DriveWatch:
    """Which joints' drives give no torque while gravity turns them (see the module)."""

    def __init__(self, robot: Robot) -> None:
        self._robot = robot
        limits = np.asarray(robot.effort_limits, float)
        #: N m, the least gravity torque per joint (inf: never judged)
        self._least = np.where(np.isfinite(limits) & (limits > 0), GRAVITY_SHARE * limits,
                               math.inf)
        self._since = np.full(robot.n, math.nan)  # s, when each drive fell silent
        self._from = np.zeros(robot.n)  # rad, where its joint was then
        self.silent = np.zeros(robot.n, bool)  #: the joints named silent at the last update

    def reset(self) -> None:
        """Forget every silence."""
        self._since[:] = math.nan
        self.silent[:] = False

    def update(self, now: float, q: np.ndarray, effort: np.ndarray) -> np.ndarray:
        """The joints (n,) bool whose drives are silent at `now` (s), q (rad), `effort` (N m)."""
        robot = self._robot
        if not robot.has_inertias or not np.isfinite(self._least).any():
            return self.silent
        gravity = np.abs(robot.gravity_dynamics(q)[0])
        quiet = (gravity >= self._least) & (np.abs(effort) < SILENT_SHARE * gravity)
        started = quiet & np.isnan(self._since)
        self._since[started], self._from[started] = now, q[started]
        self._since[~quiet] = math.nan
        self.silent[:] = False
        if quiet.any():
            falling = swing.falling_directions(robot, q)
            if falling is not None:
                # The fall counts from the highest point since the drive fell silent (a
                # joint moving uphill then coasts to a stop first).
                fallen = (q - self._from) * falling
                self._from = np.where(quiet & (fallen < 0), q, self._from)
                self.silent[:] = (quiet & (now - self._since >= SILENT_TIME)
                                  & (fallen >= FALL))
        return self.silent
