"""Contact is not a failure (`ft_core.detection.contact`), on the physics plant's closed loop.

The tool is driven into a wall across its way (`ft_core.physics.PhysicsPlant`'s
obstacle); the joints that move it stall. The efforts the plant reports, less gravity,
are a force on the tool (tau_ext = J^T f): nothing is declared. A lock while pushing is
named, at the latest once the tool leaves the wall.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from ft_core import robots
from ft_core.detection import drives
from ft_core.detection.contact import (
    AFTER_CONTACT,
    CONTACT_PERIOD,
    HELD_CONTACT,
    MIN_TORQUE,
    PUSH_ANGLE,
    ContactWatch,
    driven,
    explained_by_contact,
    in_contact,
)
from ft_core.detection.evidence import JointEvidence
from ft_core.faults import Fault, FaultKind
from ft_core.health import Health
from ft_sim import closed_loop
from ft_sim.closed_loop import DRIVERS, WALL, ClosedLoop, wall_across

PANDA = robots.load("panda_inertial", tip_link="panda_link8", task_space="position")
Q = PANDA.home()


def test_a_force_on_the_tool_explains_the_torques_a_lock_does_not() -> None:
    J = PANDA.base_jacobian(Q)[:3]
    pushed = J.T @ np.array([0.0, 0.0, -40.0])  # 40 N pressing down
    contact, by_force, by_locks = explained_by_contact(pushed, J, [1])
    assert contact and by_force == pytest.approx(1.0) and by_locks < by_force
    braked = np.zeros(7)
    braked[3] = 30.0  # a drive pushing its brake
    contact, by_force, by_locks = explained_by_contact(braked, J, [3])
    assert not contact and by_locks == pytest.approx(1.0) and by_force < by_locks
    # A lock while pressing: its own drive carries most of the external torque.
    contact, _, _ = explained_by_contact(pushed + 5 * braked, J, [3])
    assert not contact
    small = J.T @ np.array([0.0, 0.0, -0.5 * MIN_TORQUE / np.linalg.norm(J[2])])
    assert not explained_by_contact(small, J, [1])[0]  # within a drive's model error
    gravity = PANDA.gravity(Q)
    assert in_contact(PANDA, Q, gravity + pushed, [1]).startswith("['panda_joint2'] stalled")
    assert in_contact(PANDA, Q, gravity, [1]) is None  # free, at rest: nothing external


def test_a_tool_held_at_a_wall_by_six_stalled_joints_is_contact() -> None:
    """The deployed wall: the tool pressed with 200 N, six Panda joints held still.

    Six locks would explain every external torque (all but the flange's, which is nil),
    as the force does; weighed with as many unknowns as the force has, they explain 81 %.
    A brake's push among them that the force cannot explain is still no contact.
    """
    q = np.array([-0.11, 0.31, -0.1, -2.09, 1.56, 0.63, 0.81])
    J = PANDA.base_jacobian(q)[:3]
    pushed = J.T @ np.array([-23.0, -110.0, -162.0])
    held = [0, 1, 2, 3, 4, 5]
    assert pushed[held] @ pushed[held] / (pushed @ pushed) == pytest.approx(1.0)
    contact, by_force, by_locks = explained_by_contact(pushed, J, held)
    assert contact and by_force == pytest.approx(1.0) and by_locks == pytest.approx(0.81, abs=0.01)
    braked = np.zeros(7)
    braked[0] = 80.0  # panda_joint1's drive pushing its brake, near its limit
    contact, by_force, _ = explained_by_contact(pushed + braked, J, held)
    assert not contact and by_force < 0.8


def test_a_joint_falling_under_its_weak_drive_is_no_force_on_the_tool() -> None:
    """The shoulder falling with tau = M qdd + C qd + g exactly: its torque short of g(q).

    Read statically (tau - g) the shortfall is a force at the tool; the inverse dynamics'
    residual leaves nothing, and a real force on the tool is still one.
    """
    velocity, acceleration = np.zeros(7), np.zeros(7)
    velocity[1], acceleration[1] = 1.5, 8.0  # rad/s, rad/s^2: the shoulder falls forward
    inertia, nonlinear = PANDA.dynamics(Q, velocity)
    falling = inertia @ acceleration + nonlinear
    assert in_contact(PANDA, Q, falling, [1]) is not None  # the static reading: contact
    assert in_contact(PANDA, Q, falling, [1], motion=(velocity, acceleration)) is None
    pushed = PANDA.base_jacobian(Q)[:3].T @ np.array([0.0, 0.0, -40.0])
    assert in_contact(PANDA, Q, falling + pushed, [1],
                      motion=(velocity, acceleration)) is not None


def test_a_lock_while_the_rest_of_the_arm_accelerates_is_no_force_on_the_tool() -> None:
    """A wrist lock while the shoulder speeds up is no contact, read with the arm's motion.

    The wrist (joint 6) is held by its brake, its drive pushing 2.4 N m, while the
    shoulder speeds up at 3.2 rad/s^2 towards a new goal (a deployed lock on the physics
    plant).

    Read statically (tau - g), the arm's own acceleration and the push fit a force at
    the tool by 98 %, within `PUSH_ANGLE` of the command; the inverse dynamics' residual
    leaves the push alone, no contact.
    """
    q = np.array([-2.2, -1.69, 1.14, -2.12, 1.23, 0.78, 0.78])
    velocity = np.array([0.31, 0.21, -0.36, -0.26, -0.18, 0.0, 0.0])
    acceleration = np.array([3.2, 0.4, -2.8, -0.9, -0.6, 0.0, 0.0])
    commanded = np.array([0.0, 0.04, -0.06, -0.02, 0.0, -0.1, 0.0])
    inertia, nonlinear = PANDA.dynamics(q, velocity)
    push = np.zeros(7)
    push[5] = -2.4
    effort = inertia @ acceleration + nonlinear + push
    static = in_contact(PANDA, q, effort, [5], commanded=commanded)
    assert static is not None and "explains 98%" in static
    assert in_contact(PANDA, q, effort, [5], commanded=commanded,
                      motion=(velocity, acceleration)) is None
    # The monitor's look at the stalled wrist, given the detector's accelerations.
    joints = [JointEvidence(measured=v, commanded=c) for v, c in zip(velocity, commanded,
                                                                     strict=True)]
    watch = ContactWatch(PANDA)
    assert watch.explains(PANDA, q, effort, [5], 0.0, joints) is not None
    assert watch.explains(PANDA, q, effort, [5], 0.0, joints,
                          acceleration=acceleration) is None


def test_a_contact_begins_only_where_the_command_drives_the_tool_into_the_force() -> None:
    J = PANDA.base_jacobian(Q)[:3]
    down = np.array([0.0, 0.0, -1.0])
    pushed = J.T @ (40.0 * down)  # the tool presses down with 40 N
    into = np.linalg.pinv(J) @ (0.1 * down)  # joint velocities sending the tool down
    assert explained_by_contact(pushed, J, [1], into)[0]
    tilted = np.cos(PUSH_ANGLE + 0.1) * down + np.sin(PUSH_ANGLE + 0.1) * np.array([1, 0, 0])
    for away in (-into, np.linalg.pinv(J) @ (0.1 * tilted)):  # a stopping link's reaction
        contact, by_force, by_locks = explained_by_contact(pushed, J, [1], away)
        assert not contact and by_force == pytest.approx(1.0) and by_locks < by_force
    # Once the watch has seen the tool pushed (`ContactWatch.lately`), the command may
    # turn (a stalled task backs off): the contact lasts while the force does, and the
    # command's direction is asked again only after AFTER_CONTACT s without one. A look
    # at stalled joints alone begins no such while: a lock's push and the stopping links'
    # reactions can read as a small force at the tool for a moment.
    watch = ContactWatch(PANDA)
    effort = PANDA.gravity(Q) + 2.0 * pushed  # 80 N: over the watch's least torque
    assert np.linalg.norm(2.0 * pushed) >= watch.least

    def sent(qd: np.ndarray) -> list[JointEvidence]:
        return [JointEvidence(commanded=v) for v in qd]

    assert watch.explains(PANDA, Q, effort, [1], 0.0, sent(-into)) is None
    assert watch.explains(PANDA, Q, effort, [1], 0.1, sent(into)) is not None
    assert watch.explains(PANDA, Q, effort, [1], 0.2, sent(-into)) is None
    assert watch.lately(PANDA, Q, effort, 0.3, sent(into))
    assert watch.explains(PANDA, Q, effort, [1], 0.4, sent(-into)) is not None
    assert watch.explains(PANDA, Q, effort, [1], 0.3 + AFTER_CONTACT, sent(-into)) is None


def test_three_stalled_joints_that_carry_all_of_a_force_are_contact_if_driven_into_it() -> None:
    """A force whose torques fall on three joints: both explanations fit; the command decides.

    At this Panda posture a force of 148 N at the tool loads joints 1, 3 and 5 alone,
    nearly: their three locks explain the torques as fully as the force does (a wall
    across the physics plant's way, where their drives' model errors made the locks
    explain a little more). Where the force leaves less than a drive's model error
    (`MIN_TORQUE`), the stalled joints, as many as the force has components, are no
    better an explanation: contact if the command drives the tool into the force.
    """
    q = np.array([0.6908, -0.7082, -0.4383, -2.3572, -1.1797, 0.9167, 0.7892])
    J = PANDA.base_jacobian(q)[:3]
    external = J.T @ np.array([-50.7, 130.9, 40.9])
    external[1] = 0.0  # its 3 N m on joint 2 within that drive's model error
    commanded = np.array([0.349, 0.044, 0.357, -0.019, 0.151, -0.161, 0.0])
    contact, by_force, by_locks = explained_by_contact(external, J, [0, 2, 4], commanded)
    assert contact and by_force > 0.99 and by_locks > by_force  # the locks fit better
    assert not explained_by_contact(external, J, [0, 2, 4], -commanded)[0]


def test_a_joint_on_its_stop_is_left_out_like_a_braked_one() -> None:
    """A wall pushes Panda joint 6 onto its lower stop: the stop takes torque, not the drive.

    The efforts are the force's torques but for joint 6's, 50 N m of which its stop
    carries (a wall across the physics plant's way, joints 1, 2 and 6 stalled). With
    joint 6 in the fit, the force explains 84 %, its stall with joints 1's and 2's more;
    left out, as a brake's joint is, the force explains the rest: contact. Off its stop
    the same torques are no contact.
    """
    q = np.array([-0.669, 0.4794, 1.484, -1.6842, -1.678, -0.024, 0.771])
    assert q[5] < PANDA.lower[5]
    J = PANDA.base_jacobian(q)[:3]
    external = J.T @ np.array([309.7, 128.8, -85.6])
    external[5] -= 50.0
    commanded = np.array([0.452, 0.277, 0.003, 0.106, -0.43, 1.305, 0.0])
    joints = [JointEvidence(commanded=c) for c in commanded]
    assert not explained_by_contact(external, J, [0, 1, 5], commanded)[0]
    watch = ContactWatch(PANDA)
    effort = PANDA.gravity(q) + external
    assert watch.explains(PANDA, q, effort, [0, 1, 5], 0.0, joints) is not None
    free = q.copy()
    free[5] = 0.3
    effort = PANDA.gravity(free) + PANDA.base_jacobian(free)[:3].T @ np.array(
        [309.7, 128.8, -85.6])
    effort[5] -= 50.0
    assert watch.explains(PANDA, free, effort, [0, 1, 5], 0.0, joints) is None


def test_the_tool_has_left_an_obstacle_only_after_a_contact_that_held() -> None:
    """`ContactWatch.left`: a contact held `HELD_CONTACT` s, then a look that finds none.

    Pressed for 0.5 s, then free: the tool has left the obstacle for `AFTER_CONTACT` s
    after the last look that found it. Pressed for 40 ms (a brake's push read as a
    contact for a moment, under reversing commands on the physics plant): it has not.
    """
    J = PANDA.base_jacobian(Q)[:3]
    down = np.array([0.0, 0.0, -1.0])
    into = [JointEvidence(commanded=v) for v in np.linalg.pinv(J) @ (0.1 * down)]
    pressed = PANDA.gravity(Q) + J.T @ (80.0 * down)
    free = PANDA.gravity(Q)
    for held, expected in ((0.5, True), (0.04, False)):
        watch = ContactWatch(PANDA)
        looks = np.arange(0.0, held + 1e-9, CONTACT_PERIOD)
        for now in looks:
            assert watch.lately(PANDA, Q, pressed, now, into)
            assert not watch.left(now)
        end = looks[-1] + CONTACT_PERIOD
        watch.lately(PANDA, Q, free, end, into)
        assert watch.left(end) is expected, held
        assert not watch.left(looks[-1] + AFTER_CONTACT)
    assert 0.04 < HELD_CONTACT < 0.5


def _push(driver: str, seed: int) -> ClosedLoop:
    """A loop whose tool has just met a wall across its way to a fresh goal."""
    loop = ClosedLoop("position", DRIVERS[driver], seed=seed)
    loop.run(4.0 + 0.3 * seed)
    while loop.tool_error() < 0.12:  # a goal far enough away
        loop.run(loop.dt)
    tool = loop.robot.transform(loop.plant.q)[:3, 3]
    loop.plant.place_obstacle(wall_across(tool, loop.goal, beyond=0.01), np.array(WALL))
    return loop


def _declared(loop: ClosedLoop) -> dict[str, str]:
    return {loop.robot.joint_names[j]: str(s) for j, s in enumerate(loop.monitor.board.states)
            if s != Health.HEALTHY}


@pytest.mark.parametrize(("driver", "seed"), [("fast", 0), ("slow", 0), ("fast", 3),
                                              ("slow", 2)])
def test_a_tool_pushing_into_a_wall_declares_no_joint(driver: str, seed: int) -> None:
    loop = _push(driver, seed)
    loop.run(3.0)
    assert loop.tool_error() > 0.05, "the wall did not hold the tool"
    assert _declared(loop) == {} and loop.declared == []
    loop.plant.remove_obstacle()
    loop.run(3.0)  # and after it: the shares made in contact are forgotten
    assert _declared(loop) == {} and loop.declared == []


#: s more the loop may take to reach a goal once the wall is gone.
REACH = 6.0
#: Walls across the way between two goals where healthy joints were once declared, behind
#: the slow driver: (from, to (m), the wall's share of the way, s pushed, the loop's seed).
WALLS = {
    "three joints carry the force": ((0.323, -0.207, 0.465), (0.322, 0.197, 0.609), 0.42,
                                     3.2, 91),
    "a wrist on its stop": ((0.328, 0.021, 0.617), (0.594, 0.209, 0.548), 0.55, 5.9, 10),
    "the lurch as the wall goes": ((0.317, 0.028, 0.476), (0.497, 0.044, 0.338), 0.5, 2.1,
                                   99),
}


@pytest.mark.parametrize("wall", list(WALLS))
def test_a_wall_between_two_goals_declares_no_joint_while_pushed_or_after(
        wall: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The tool at rest at a goal, a wall across its way to the next, pushed, then freed.

    Three ways a contact read as locks: three stalled joints carrying the force's torques
    (`explained_by_contact`), a wrist held on its stop by the wall (`ContactWatch`), and
    the arm's lurch as the wall goes, a healthy joint moved back against its command for
    0.2 s with nothing external on it (`Drives.braking`, asked while the tool was pushed
    lately).
    """
    start, goal, share, push, seed = WALLS[wall]
    monkeypatch.setattr(closed_loop, "GOALS", (start, goal, start))
    loop = ClosedLoop("position", DRIVERS["slow"], seed=seed)
    try:
        loop.run(1.5)
        loop.goal_period = math.inf
        loop.run(2.0)
        tool = loop.robot.transform(loop.plant.q)[:3, 3]
        loop.plant.place_obstacle(wall_across(tool, np.array(goal), share), np.array(WALL))
        loop.run(0.5)
        loop.send_goal()
        loop.run(push)
        assert loop.tool_error() > 0.05, "the wall did not hold the tool"
        assert _declared(loop) == {} and loop.declared == []
        loop.plant.remove_obstacle()
        loop.run(3.0)
        assert _declared(loop) == {} and loop.declared == []
        # The goal is reached: how soon depends on when the controller's worker process
        # (niced, on a busy machine slow in the loop's time) answers its recovery.
        loop.run(REACH, stop=lambda: loop.tool_error() < 0.01)
        assert loop.tool_error() < 0.01, "the goal was not reached after the wall"
        assert _declared(loop) == {} and loop.declared == []
    finally:
        loop.close()


def test_a_tool_sent_back_off_a_wall_still_there_declares_no_joint(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Pushed into a wall 2.5 s behind the slow driver, then sent back with the wall in place.

    The servos wound up against the wall turn round as the tool leaves it, and a joint
    lags its command meanwhile as a locked one does, with little external torque left
    (panda_joint3 was named here, 0.76 s after the tool was sent back). The arm is
    disturbed once the tool has left an obstacle (`ContactWatch.left`): lock evidence
    must then outlast the plant's settling time.
    """
    start, goal = (0.4, 0.05, 0.55), (0.5, 0.1, 0.4)
    monkeypatch.setattr(closed_loop, "GOALS", (start, goal, start))
    loop = ClosedLoop("position", DRIVERS["slow"], seed=1)
    try:
        loop.run(1.5)
        loop.goal_period = math.inf
        loop.run(2.0)
        tool = loop.robot.transform(loop.plant.q)[:3, 3]
        loop.plant.place_obstacle(wall_across(tool, np.array(goal), 0.5), np.array(WALL))
        loop.run(0.5)
        loop.send_goal()
        loop.run(2.5)
        assert loop.tool_error() > 0.05, "the wall did not hold the tool"
        left: list[float] = []  # when the monitor saw the tool leave the wall
        seen = ContactWatch.left

        def watched(watch: ContactWatch, now: float) -> bool:
            if seen(watch, now):
                left.append(now)
                return True
            return False

        monkeypatch.setattr(ContactWatch, "left", watched)
        loop.send_goal()  # back where it came from, away from the wall
        loop.run(3.0)
        assert left, "the tool was never seen leaving the wall"
        assert _declared(loop) == {} and loop.declared == []
        loop.run(REACH, stop=lambda: loop.tool_error() < 0.01)  # as above
        assert loop.tool_error() < 0.01, "the goal was not reached after the wall"
        assert _declared(loop) == {} and loop.declared == []
    finally:
        loop.close()


def test_a_wall_that_carries_a_joints_weight_leaves_no_drive_torqueless() -> None:
    """Pushed into a wall behind the slow driver, Panda joints 2 and 4 let the wall hold them.

    Their efforts fall under a tenth of their gravity torques (`drives.SILENT_SHARE`),
    which alone would name their drives silent, and the contact test is not asked about a
    drive without torque. While the tool is in contact no drive counts as giving no
    torque before its joint has fallen 30 mrad, and no joint is declared.
    """
    loop = _push("slow", 2)
    idle: set[int] = set()
    torqueless: set[int] = set()

    def watch() -> bool:
        gravity = np.abs(loop.robot.gravity(loop.plant.q))
        quiet = (np.abs(loop.plant.torque) < drives.SILENT_SHARE * gravity) & (
            gravity >= drives.GRAVITY_SHARE * np.asarray(loop.robot.effort_limits))
        idle.update(np.flatnonzero(quiet).tolist())
        torqueless.update(np.flatnonzero(loop.monitor.detector.torqueless).tolist())
        return False

    loop.run(3.0, stop=watch)
    assert loop.tool_error() > 0.05, "the wall did not hold the tool"
    assert {1, 3} <= idle, idle
    assert torqueless == set() and _declared(loop) == {} and loop.declared == []


@pytest.mark.parametrize("joint", [1, 3])
def test_a_lock_while_pushing_is_named_at_the_latest_once_the_tool_leaves_the_wall(
        joint: int) -> None:
    loop = _push("slow", 0)
    loop.run(1.0)
    loop.plant.lock(joint)
    loop.run(2.0)
    loop.plant.remove_obstacle()
    loop.run(4.0)
    assert _declared(loop) == {loop.robot.joint_names[joint]: "locked"}


def test_a_drive_that_gives_torque_is_driving_its_joint() -> None:
    gravity = PANDA.gravity(Q)
    assert driven(PANDA, Q, gravity, 1)  # holding its link up
    assert not driven(PANDA, Q, 0.1 * gravity, 1)  # lost its torque
    assert not driven(PANDA, Q, np.zeros(7), 6)  # none, where gravity is small anyway


@pytest.mark.parametrize("driver", list(DRIVERS))
def test_an_intermittent_jam_is_locked_and_stays_locked_when_it_lets_go(driver: str) -> None:
    """Joint 3 jams for 1 s in every 2 s: locked, not free-swinging when its servo catches up."""
    loop = ClosedLoop("position", DRIVERS[driver], seed=2)
    loop.run(4.0)
    loop.plant.inject(2, Fault(FaultKind.INTERMITTENT, "panda_joint3", period=1.0))
    loop.run(8.0)
    assert _declared(loop) == {"panda_joint3": "locked"}
    assert loop.declared, "the jam was not named"
    assert all(names == ["panda_joint3"] for _, names in loop.declared)  # never released


def test_two_links_stopped_by_locks_at_once_are_no_contact() -> None:
    """Panda joints 2 and 5 locked together behind the slow driver: both named, no contact.

    Their drives' pushes fit a force at the tool (82 % of the external torques) 60 degrees
    from the commanded tool velocity, within `PUSH_ANGLE`: the veto holds the first
    declaration back until both joints are about to be declared: their own pushes then
    explain the torques better than a force does (both named within 0.4 s).
    """
    loop = ClosedLoop("position", DRIVERS["slow"], seed=1)
    loop.run(4.0)
    loop.run(1.5, stop=lambda: min(abs(loop.plant.qd[1]), abs(loop.sent[1])) > 0.1)
    loop.plant.lock(1)
    loop.plant.lock(4)
    start = loop.t
    loop.run(1.0)
    assert _declared(loop) == {"panda_joint2": "locked", "panda_joint5": "locked"}
    assert loop.declared[-1][0] - start <= 0.4
    assert loop.monitor.contact is None  # no contact left once both are named
