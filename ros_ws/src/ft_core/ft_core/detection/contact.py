"""Contact is not a failure: joints stalled by a force on the tool, told apart by their efforts.

A tool that meets a table or a wall stops every joint that moves it into the obstacle;
a command-against-motion test reads those stalls as locks. What tells them apart is
where the drives push: the obstacle's force f on the tool loads every joint as the
transposed Jacobian says, tau_ext = J^T f (the statics of a serial chain), while a brake
or a jam loads the drive of its own joint only, the others following as before.

The external torques are estimated as Franka's and KUKA iiwa's controllers do, from
the efforts the driver reports (`sensor_msgs/JointState.effort`) less the model's
gravity torques (the URDF's inertias): tau_ext = tau - g(q); a drive that follows its
command in free motion needs little more than g(q). When joints are about to be
declared locked (or degraded), `explained_by_contact` compares both explanations of
tau_ext: the best force at the tool, R_f = |tau_ext - J^T f|^2 / |tau_ext|^2 over f
(least squares, the tool point's linear rows of J), and the stalled joints alone, R_l =
the share of |tau_ext|^2 outside them. It is contact when the force explains the
torques (1 - R_f >= `CONTACT_SHARE`), better than the stalled joints do (R_l > R_f),
and they are more than a drive's model error (|tau_ext| >= `MIN_TORQUE` N m). A lock
while the tool pushes leaves its own joint's torque unexplained by a tool force, and is
named when that is most of it. Without efforts or inertias nothing is vetoed.

The efforts also tell a joint that moved again after its lock with its drive's torque (a
jam that let go, its servo catching up: `driven`) from one whose drive lost its torque
(a free swing).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ft_core.robots import Robot

#: Least share of the external torques a tool force must explain for contact.
CONTACT_SHARE = 0.8
#: N m, the smallest external torque (norm over the joints) that says anything.
MIN_TORQUE = 5.0
#: s between two looks at whether the tool is in contact (`ContactWatch`).
CONTACT_PERIOD = 0.02
#: s after a contact during which the joints' motion still says nothing of their drives
#: (the arm leaving the obstacle, its servos catching up).
AFTER_CONTACT = 1.0
#: Least external torque, as a share of the effort limits (norm over the joints), for
#: `ContactWatch` to see contact with no joint stalled: above what the servos' transients
#: give in free motion (at most 0.13 of the Panda's limits on the physics plant, against
#: 0.2 and more pushing into a wall).
WATCH_SHARE = 0.15
#: Share of the gravity torque a drive must give to be driving its joint (`driven`).
DRIVEN_SHARE = 0.3


def explained_by_contact(external: np.ndarray, jacobian: np.ndarray,
                         stalled: list[int]) -> tuple[bool, float, float]:
    """Whether a force on the tool explains the external torques better than locks do.

    Args:
        external: (n,) tau_ext, the efforts less the gravity torques (N m).
        jacobian: (3, n) the tool point's linear Jacobian (m/rad).
        stalled: the joints about to be declared locked or degraded.

    Returns:
        (contact, share the force explains 1 - R_f, share the stalled joints explain 1 - R_l).
    """
    total = float(external @ external)
    if not math.isfinite(total) or total < MIN_TORQUE ** 2:
        return False, math.nan, math.nan
    force = np.linalg.lstsq(jacobian.T, external, rcond=None)[0]
    residual = external - jacobian.T @ force
    by_force = 1.0 - float(residual @ residual) / total
    by_locks = float(external[stalled] @ external[stalled]) / total
    return by_force >= CONTACT_SHARE and by_force > by_locks, by_force, by_locks


def in_contact(robot: Robot, q: np.ndarray, effort: np.ndarray, stalled: list[int],
               least: float = MIN_TORQUE, braked: Sequence[int] = ()) -> str | None:
    """Why the `stalled` joints are held by a force on the tool, not failed; None if not.

    At the configuration `q` (rad) with the drives' `effort` (N m), an external torque of
    at least `least` N m; the arm's URDF must have inertias (gravity torques). The
    `braked` joints (locked already) are left out: their brakes take any torque.
    """
    external = effort - robot.gravity(q)
    jacobian = robot.base_jacobian(q)[:3]
    external[list(braked)], jacobian[:, list(braked)] = 0.0, 0.0
    if not float(external @ external) >= least ** 2:
        return None
    contact, by_force, by_locks = explained_by_contact(external, jacobian, stalled)
    if not contact:
        return None
    names = [robot.joint_names[j] for j in stalled]
    return (f"{names} stalled by a force on the tool, not locked: it explains "
            f"{by_force:.0%} of the external torques, the stalled joints {by_locks:.0%}")


def driven(robot: Robot, q: np.ndarray, effort: np.ndarray, joint: int) -> bool:
    """Whether `joint`'s drive gives torque at q (rad) by the `effort` reported (N m).

    A drive that lost its torque gives none against the gravity torque g(q); one that
    gives at least `DRIVEN_SHARE` of it and 1 N m moves its joint itself.
    """
    gravity = abs(float(robot.gravity(q)[joint]))
    return abs(float(effort[joint])) >= max(DRIVEN_SHARE * gravity, 1.0)


class ContactWatch:
    """Whether the tool is in contact, or was within `AFTER_CONTACT` s.

    Looked at every `CONTACT_PERIOD` s: the joints' shares of their commands then say
    nothing of their drives (`ft_core.detection.follow`).
    """

    def __init__(self, robot: Robot) -> None:
        limits = robot.effort_limits
        #: N m: `WATCH_SHARE` of the effort limits (no watch without finite limits)
        self.least = (WATCH_SHARE * float(np.linalg.norm(limits)) if np.isfinite(limits).all()
                      else math.inf)
        self._looked = -math.inf  # s, when contact was last looked at
        self._touched = -math.inf  # s, when the tool was last seen in contact

    def lately(self, robot: Robot, q: np.ndarray, effort: np.ndarray, now: float,
               braked: Sequence[int] = ()) -> bool:
        """Whether the tool is or was lately in contact at `now` (s), by `in_contact`."""
        if now - self._looked >= CONTACT_PERIOD and math.isfinite(self.least):
            self._looked = now
            if in_contact(robot, q, effort, [], self.least, braked) is not None:
                self._touched = now
        return now - self._touched < AFTER_CONTACT
