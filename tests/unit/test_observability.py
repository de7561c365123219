"""Issue 16, part 1: observability motion (ft_core.observability, the controller's option)."""

from __future__ import annotations

import numpy as np
import pytest
from ft_core import engine, robots
from ft_core.observability import OBSERVED_SPEED, Excursions, ObservabilityConfig

PANDA = robots.load("panda", task_space="position")


def test_excursions_take_idle_joints_in_turn_out_and_back_with_a_witness() -> None:
    config = ObservabilityConfig(idle_time=1.0, speed=0.2, duration=0.5)
    excursions = Excursions(3, config)
    moving = np.array([0.1, 0.0, 0.0])
    assert excursions.update(0.0, moving, []) == []  # the timers start
    assert excursions.update(0.99, moving, []) == []
    # The longest idle (lowest index first), witnessed by the next longest idle.
    assert excursions.update(1.0, moving, []) == [(1, 0.0), (2, 0.0)]
    (joint, speed), witness = excursions.update(1.125, moving, [])
    assert joint == 1 and speed == pytest.approx(0.2)  # a quarter period: the peak
    assert witness == (2, speed)
    (joint, speed), _ = excursions.update(1.375, moving, [])
    assert joint == 1 and speed == pytest.approx(-0.2)  # and back
    # Done: joint 2, commanded as the witness, counts as observed; joint 0 is moving.
    assert excursions.update(1.5, moving, []) == []
    assert excursions.update(2.49, moving, []) == []
    still = np.zeros(3)
    # A locked joint is never excited; an excursion under way on one stops.
    assert excursions.update(2.5, still, [1]) == [(2, 0.0), (0, 0.0)]  # 1 is due, but locked
    assert excursions.active == 2
    assert excursions.update(2.6, still, [2]) == [(1, 0.0), (0, 0.0)]  # 2 locks: the next
    # A joint that cannot move is retried after another idle time; a clock going back
    # (a restarted simulation) restarts the timers.
    excursions.cannot_move(1, 2.6)
    assert excursions.active is None
    assert excursions.update(3.59, moving, []) == []
    assert excursions.update(3.6, moving, []) == [(1, 0.0), (2, 0.0)]
    assert excursions.update(0.0, moving, []) == []
    with pytest.raises(ValueError, match="speed"):
        ObservabilityConfig(speed=OBSERVED_SPEED)


@pytest.mark.parametrize("task", ["position", "pose"])
def test_an_excursion_moves_its_joint_and_not_the_tool(task: str) -> None:
    robot = robots.load("panda", task_space=task)
    cycle = engine.ResolutionEngine(robot, engine.EngineConfig(dt=0.004, velocity_scale=0.5))
    rng = np.random.default_rng(3)
    moved_joints = 0
    for _ in range(20):
        q = robot.random_configuration(rng, margin=0.3)
        qd = cycle.step(robot.kinematics(q), rng.normal(scale=0.05, size=robot.m)).qd
        for joint in range(robot.n):
            out = cycle.excursion(robot.kinematics(q), qd, joint, 0.15)
            if out is None:  # no null-space share: nothing is changed
                continue
            moved_joints += 1
            J = robot.jacobian(q)
            assert np.linalg.norm(J @ (out - qd)) < 1e-12  # the tool velocity is unchanged
            assert out[joint] - qd[joint] == pytest.approx(0.15, abs=1e-9) or (
                0 <= (out[joint] - qd[joint]) / 0.15 < 1)  # scaled only by a bound
    assert moved_joints > 20 * robot.n // 2


def test_an_excursion_stays_inside_the_soft_limits_and_skips_what_cannot_move() -> None:
    q = PANDA.home()
    lower, upper = q - 0.2, q + 0.2
    lower[6] = q[6] - 1e-4  # joint 7 sits on its soft lower limit
    cycle = engine.ResolutionEngine(PANDA, engine.EngineConfig(
        dt=0.004, soft_lower=lower, soft_upper=upper))
    at = PANDA.kinematics(q)
    out = cycle.excursion(at, np.zeros(7), 6, -0.15)  # towards the limit: cut to the edge
    assert out is not None and q[6] + 0.004 * out[6] >= lower[6] - 1e-12
    assert cycle.excursion(at, np.zeros(7), 6, 0.15)[6] == pytest.approx(0.15)
    # Six healthy joints for a pose task: no null space, nothing to excite.
    pose = engine.ResolutionEngine(robots.load("panda", task_space="pose"))
    at = pose.robot.kinematics(q)
    assert pose.excursion(at, np.zeros(7), 6, 0.15, locked=[0]) is None
    assert pose.excursion(at, np.zeros(7), 0, 0.15, locked=[0]) is None  # a locked joint




