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
the share of |tau_ext|^2 outside them. Both explanations are weighed with as many
unknowns: a force has three components, k locks k brake torques, and k locks explain
more as k grows, every torque once all the joints that carry one are stalled (a tool
held at a wall, its controller's recovery pushing six Panda joints against it). So for
more than three stalled joints R_l counts only the three of them with the largest
external torques. It is contact when the force explains the
torques (1 - R_f >= `CONTACT_SHARE`), better than the stalled joints do (R_l > R_f),
they are more than a drive's model error (|tau_ext| >= `MIN_TORQUE` N m), and the
command drives the tool into the force: an obstacle pushes back only on a tool sent into
it, so where no contact was found lately (`ContactWatch`) the commanded tool velocity
J qd_c must lie within `PUSH_ANGLE` of f. Where three or more joints stall and the force
leaves less than a drive's model error unexplained (|tau_ext - J^T f| < `MIN_TORQUE`),
the stalled joints are no better an explanation, however their shares compare (at some
postures a force at the tool loads three Panda joints alone): the command's direction
decides. A joint on its position stop is left out as a braked one is: the stop takes
any torque (a wall that pushes a wrist onto its stop). This tells
a contact from the reaction of links stopped by locks: a stopping link's inertial torques
are also J^T of a force (the link's deceleration times its mass), and a locked pair of
joints can put its drives' pushes in the range of J^T, but neither has anything to do
with where the command sends the tool. A lock while the tool pushes leaves its own
joint's torque unexplained by a tool force, and is named when that is most of it.
Without efforts or inertias nothing is vetoed.

While the arm moves, tau - g(q) holds the torques of its own motion too: a joint
falling under a drive short of its gravity torque (lost authority) leaves tau - g = M qdd
+ C qd, the shape of a force at the tool (the shoulder's shortfall, chiefly), and so
does the rest of the arm slowing while one joint stops at a lock. Where the detector's
window accelerations are known, the external torques are the inverse dynamics' residual
tau - M(q) qdd - C qd - g(q) (the external-torque reading of De Luca & Mattone's
actuator-fault residuals): a weak drive's fall and a slowing arm leave none, a push on
the tool leaves J^T f, and for an arm at rest against an obstacle it is tau - g(q).
The watch's look with no joint stalled (`ContactWatch.lately`) reads it too: a link
falling without torque loads the drives statically as a force at the tool would, and
would end the silence of its drive (`ft_core.detection.drives`) for as long.

The efforts also tell a joint that moved again after its lock with its drive's torque (a
jam that let go, its servo catching up: `driven`) from one whose drive lost its torque
(a free swing).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ft_core.detection.config import DetectorConfig
from ft_core.detection.evidence import JointEvidence
from ft_core.robots import Robot

#: Least share of the external torques a tool force must explain for contact.
CONTACT_SHARE = 0.8
#: N m, the smallest external torque (norm over the joints) that says anything.
MIN_TORQUE = 5.0
#: rad, the largest angle between the commanded tool velocity and the force the tool
#: exerts, for contact: a tool pushed into an obstacle is commanded into it (on the physics
#: plant's walls, within 52 degrees; the stops of two locked joints' links read as a force
#: 90 degrees and more from the command).
PUSH_ANGLE = math.radians(75.0)
#: s between two looks at whether the tool is in contact (`ContactWatch`).
CONTACT_PERIOD = 0.02
#: s after a contact during which the joints' motion still says nothing of their drives
#: (the arm leaving the obstacle, its servos catching up).
AFTER_CONTACT = 1.0
#: s, the longest gap between two looks that found contact within one contact.
CONTACT_GAP = 0.1
#: s a contact must have lasted for the tool's leaving it to disturb the arm
#: (`ContactWatch.left`): on the physics plant a wall held the tool 0.5-5.9 s, while a
#: brake's push under reversing commands read as a contact for 40 ms at a time.
HELD_CONTACT = 0.3
#: Least external torque, as a share of the effort limits (norm over the joints), for
#: `ContactWatch` to see contact with no joint stalled: above what the servos' transients
#: give in free motion (at most 0.13 of the Panda's limits on the physics plant, against
#: 0.2 and more pushing into a wall).
WATCH_SHARE = 0.15
#: Share of the gravity torque a drive must give to be driving its joint (`driven`).
DRIVEN_SHARE = 0.3


def explained_by_contact(external: np.ndarray, jacobian: np.ndarray, stalled: list[int],
                         commanded: np.ndarray | None = None) -> tuple[bool, float, float]:
    """Whether a force on the tool explains the external torques better than locks do.

    Or as well, three or more joints stalled, the force leaving under `MIN_TORQUE` N m.

    Args:
        external: (n,) tau_ext, the efforts less the gravity torques (N m).
        jacobian: (3, n) the tool point's linear Jacobian (m/rad).
        stalled: the joints about to be declared locked or degraded.
        commanded: (n,) the joint velocities commanded (rad/s): the force must lie within
            `PUSH_ANGLE` of the tool velocity they command. None: not asked.

    Returns:
        (contact, share the force explains 1 - R_f, share the stalled joints explain 1 - R_l,
        the latter from at most as many of them as the force has components).
    """
    total = float(external @ external)
    if not math.isfinite(total) or total < MIN_TORQUE ** 2:
        return False, math.nan, math.nan
    force = np.linalg.lstsq(jacobian.T, external, rcond=None)[0]
    residual = external - jacobian.T @ force
    by_force = 1.0 - float(residual @ residual) / total
    shares = np.sort(external[stalled] ** 2)[::-1]
    by_locks = float(shares[:len(force)].sum()) / total
    contact = by_force >= CONTACT_SHARE and (
        by_force > by_locks or (len(stalled) >= len(force)
                                and float(residual @ residual) < MIN_TORQUE ** 2))
    if contact and commanded is not None:
        sent = jacobian @ commanded
        contact = float(sent @ force) >= math.cos(PUSH_ANGLE) * float(
            np.linalg.norm(sent) * np.linalg.norm(force)) > 0.0
    return contact, by_force, by_locks


def in_contact(robot: Robot, q: np.ndarray, effort: np.ndarray, stalled: list[int],
               least: float = MIN_TORQUE, braked: Sequence[int] = (),
               commanded: np.ndarray | None = None,
               motion: tuple[np.ndarray, np.ndarray] | None = None) -> str | None:
    """Why the `stalled` joints are held by a force on the tool, not failed; None if not.

    At the configuration `q` (rad) with the drives' `effort` (N m), an external torque of
    at least `least` N m; the arm's URDF must have inertias (gravity torques). The
    `braked` joints (locked already) are left out: their brakes take any torque.
    `commanded`: the joint velocities commanded (rad/s), as `explained_by_contact` takes
    them. The external torques are tau - g(q), or, given the arm's `motion` (velocities
    rad/s, accelerations rad/s^2), the inverse dynamics' residual tau - M(q) qdd - C qd
    - g(q): what no motion of the arm's own explains.
    """
    if motion is None:
        external = effort - robot.gravity(q)
    else:
        inertia, nonlinear = robot.dynamics(q, motion[0])
        external = effort - inertia @ motion[1] - nonlinear
    jacobian = robot.base_jacobian(q)[:3]
    external[list(braked)], jacobian[:, list(braked)] = 0.0, 0.0
    if not float(external @ external) >= least ** 2:
        return None
    contact, by_force, by_locks = explained_by_contact(external, jacobian, stalled, commanded)
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
    """Whether the tool is in contact (`explains`), or was within `AFTER_CONTACT` s (`lately`).

    A contact begins where the command drives the tool into the force (`PUSH_ANGLE`).
    Within `AFTER_CONTACT` s of a look of `lately` that found one (the tool pushed with
    `WATCH_SHARE` of the effort limits), the command's direction is not asked: a
    controller whose task stalls at a wall changes its command and backs off while its
    servos push on from the position they were sent to, and once the tool is free the
    arm's rush to its goal loads the drives as a force at the tool would. A look at
    stalled joints (`explains`) begins no such while: a lock's push and the stopping
    links' reactions can read as a small force at the tool for a moment, and the
    direction must go on telling them from a contact.
    """

    def __init__(self, robot: Robot,
                 stop_margin: float = DetectorConfig.limit_margin) -> None:
        limits = robot.effort_limits
        #: rad, how near a position limit a joint stands on its stop (left out as braked)
        self.stop_margin = stop_margin
        #: N m: `WATCH_SHARE` of the effort limits (no watch without finite limits)
        self.least = (WATCH_SHARE * float(np.linalg.norm(limits)) if np.isfinite(limits).all()
                      else math.inf)
        self._looked = -math.inf  # s, when `lately` last looked
        self._touched = -math.inf  # s, when `lately` last found the tool in contact
        self._found = False  # whether its latest look found the tool in contact
        self._began = -math.inf  # s, when the latest contact began (`CONTACT_GAP`)

    def explains(self, robot: Robot, q: np.ndarray, effort: np.ndarray, stalled: list[int],
                 now: float, joints: Sequence[JointEvidence], least: float = MIN_TORQUE,
                 acceleration: np.ndarray | None = None) -> str | None:
        """`in_contact` at `now` (s), the command's direction asked only as a contact begins.

        It is asked unless `lately` found the tool in contact within `AFTER_CONTACT` s, and
        not for joints moving on their own. `joints`: every joint's evidence at the last
        update, for the velocities commanded (`JointEvidence.commanded`), the joints locked
        (braked, as are those within `stop_margin` of a position limit) and those moving on
        their own (`swing_since`). A joint that moves on its
        own while the drives' torques are a force at the tool is pushed, by an obstacle or
        by the arm's own links as they stop or start (their inertial reaction is J^T of a
        force too), whatever the command: not a free swing. Given the joints'
        `acceleration` (rad/s^2, velocities from `JointEvidence.measured`) every look
        reads the residual of the arm's motion (`in_contact`'s `motion`): a lock that
        stops one joint while the others speed up or slow loads the drives with the arm's
        own inertia, which statically reads as a force at the tool.
        """
        on_stop = ((q - robot.lower <= self.stop_margin) | (robot.upper - q <= self.stop_margin))
        braked = [j for j, e in enumerate(joints) if e.locked_at is not None or on_stop[j]]
        motion = None if acceleration is None else (
            np.array([e.measured for e in joints]), acceleration)
        swinging = bool(stalled) and all(joints[j].swing_since is not None for j in stalled)
        commanded = None if swinging or now - self._touched < AFTER_CONTACT else np.array(
            [e.commanded for e in joints])
        return in_contact(robot, q, effort, stalled, least, braked, commanded, motion=motion)

    def lately(self, robot: Robot, q: np.ndarray, effort: np.ndarray, now: float,
               joints: Sequence[JointEvidence],
               acceleration: np.ndarray | None = None) -> bool:
        """Whether the tool is or was lately in contact at `now` (s).

        Looked at every `CONTACT_PERIOD` s, with no joint stalled and `least` N m (`joints`
        and `acceleration` as `explains` takes them). The joints' shares of their
        commands then say nothing of their drives (`ft_core.detection.follow`), nor does
        a drive that gives no torque (`ft_core.detection.drives`): the obstacle's force
        can carry its joint's weight.
        """
        if now - self._looked >= CONTACT_PERIOD and math.isfinite(self.least):
            self._looked = now
            self._found = self.explains(robot, q, effort, [], now, joints, self.least,
                                        acceleration) is not None
            if self._found:
                if now - self._touched > CONTACT_GAP:
                    self._began = now
                self._touched = now
        return now - self._touched < AFTER_CONTACT

    def left(self, now: float) -> bool:
        """Whether the tool came off an obstacle lately, at `now` (s), as of `lately`'s looks.

        The last look found no contact, and one within `AFTER_CONTACT` s ended a contact
        that lasted `HELD_CONTACT` s or more (looks that found it no more than
        `CONTACT_GAP` s apart): the servos wound up against the obstacle are turning round,
        and a joint lags its command meanwhile as a locked one does
        (`evidence.Disturbance`). A brake's push read as a contact for a moment is none.
        """
        return bool(not self._found and now - self._touched < AFTER_CONTACT
                    and self._touched - self._began >= HELD_CONTACT)
