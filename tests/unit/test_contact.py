"""Contact is not a failure (`ft_core.detection.contact`), on the physics plant's closed loop.

The tool is driven into a wall across its way (`ft_core.physics.PhysicsPlant`'s
obstacle); the joints that move it stall. The efforts the plant reports, less gravity,
are a force on the tool (tau_ext = J^T f): nothing is declared. A lock while pushing is
named, at the latest once the tool leaves the wall.
"""

from __future__ import annotations

import numpy as np
import pytest
from ft_core import robots
from ft_core.detection.contact import MIN_TORQUE, driven, explained_by_contact, in_contact
from ft_core.faults import Fault, FaultKind
from ft_core.health import Health
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
