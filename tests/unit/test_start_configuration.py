"""Issue 34 item 2: the start configuration of best dexterity after a failure (Zhao & Li)."""

from __future__ import annotations

import time

import numpy as np
import pytest
from ft_core import robots, selfmotion, start_configuration
from ft_core.controller import Controller, ControllerConfig
from ft_core.engine import EngineConfig
from models import planar_arm

#: Zhao & Li sec. IV: the planar 3R of three 0.5 m links, the tool at X = [0.35, 0] m.
ROBOT = planar_arm([0.5, 0.5, 0.5])
TARGET = np.array([0.35, 0.0])


@pytest.mark.parametrize("joints", [None, [1, 2]], ids=["every joint", "joints 2 and 3"])
def test_the_descent_reaches_the_least_cost_of_the_whole_self_motion_curve(joints) -> None:
    """From a start far from it, the descent ends at the manifold's best configuration.

    Checked against the traced self-motion curve (closed, one component), sampled every
    0.01 rad: its least cost, for all three joints failing (sec. IV-1) and for joints 2
    and 3 only (sec. IV-2). The tool never leaves X, and the path moves at most about
    one step per sample (a joint path to follow).
    """
    q0 = selfmotion.find_seed(ROBOT, TARGET, np.array([0.3, 1.0, 1.0]))
    plan = start_configuration.optimal_start(ROBOT, q0, joints)
    curve = selfmotion.trace(ROBOT, TARGET, q0, step=0.01)
    assert curve.closed
    samples = np.vstack(curve.paths)
    least = min(start_configuration.dexterity_cost(ROBOT, q, joints) for q in samples)
    assert plan.start_cost > 3 * least  # the start is a poor one
    assert plan.cost == pytest.approx(least, rel=1e-3)
    assert plan.cost <= least * (1 + 1e-6)  # no sample of the curve is better
    assert max(np.linalg.norm(ROBOT.forward(q) - TARGET) for q in plan.path) < 1e-8
    assert np.abs(np.diff(plan.path, axis=0)).max() < 0.06


def test_the_cost_is_the_square_sum_of_the_reduced_condition_numbers() -> None:
    """Zhao & Li eq 15 per joint; a reduced Jacobian singular at the start is inf."""
    q = np.array([0.2, 0.9, 1.1])
    J = ROBOT.jacobian(q)
    expected = 0.0
    for i in range(3):
        s = np.linalg.svd(np.delete(J, i, axis=1), compute_uv=False)
        expected += (s[0] / s[-1]) ** 2
    assert start_configuration.dexterity_cost(ROBOT, q) == pytest.approx(expected)
    stretched = np.zeros(3)  # every reduced Jacobian is singular on the straight arm
    assert start_configuration.dexterity_cost(ROBOT, stretched) == np.inf
    with pytest.raises(ValueError, match="must be positive"):
        start_configuration.optimal_start(ROBOT, q, step=0.0)


def _controller() -> Controller:
    robot = robots.load("planar3r")
    return Controller(robot, EngineConfig(dt=0.004), ControllerConfig(),
                      ("planar3r", (None, None, None, None)))


def test_the_idle_controller_moves_to_the_start_configuration_with_the_tool_still() -> None:
    """The controller's pre-task phase on the planar 3R: planned, followed, done.

    The plant integrates the commands; the tool stays within 1 mm of where it was, and
    the arm ends at the planned configuration, whose cost is the descent's.
    """
    controller = _controller()
    robot = controller.robot
    try:
        q = selfmotion.find_seed(robot, np.array([0.35, 0.0]), np.array([0.3, 1.0, 1.0]))
        tool, planned = robot.forward(q), start_configuration.optimal_start(robot, q)
        assert planned.cost < planned.start_cost / 2
        assert controller.optimize_start(q, 0.0) is None
        assert controller.optimize_start(q, 0.0) == "already under way: planning the start " \
            "configuration"
        deadline = time.monotonic() + 60.0  # the plan, in the worker, in wall time
        while controller.start_phase.planning and time.monotonic() < deadline:
            time.sleep(0.01)
        now, drift = 0.0, 0.0
        for _ in range(round(60.0 / 0.004)):  # bounded: 60 s of simulated time
            if not controller.start_phase.active:
                break
            qd = controller.step(q, 0.0, now).qd
            q, now = q + 0.004 * qd, now + 0.004
            drift = max(drift, float(np.linalg.norm(robot.forward(q) - tool)))
        assert controller.start_phase.note == "at the start configuration", \
            controller.start_phase.note
        assert np.abs(q - planned.q).max() < 0.01  # recovery.ARRIVED
        assert start_configuration.dexterity_cost(robot, q) == pytest.approx(planned.cost,
                                                                             rel=0.01)
        assert drift < 1e-3
        assert np.abs(controller.step(q, 0.0, now).qd).max() < 1e-9  # idle again: still
    finally:
        controller.close()


def test_a_target_or_a_lock_refuses_or_ends_the_start_phase() -> None:
    controller = _controller()
    try:
        q = np.array([0.3, 1.0, 1.0])
        assert controller.optimize_start(None, 0.0) == "no joint state yet"
        controller.set_locked([1], 0.0)
        assert "locked" in controller.optimize_start(q, 0.0)
        controller.set_locked([], 0.0)
        assert controller.optimize_start(q, 0.0) is None
        controller.set_pose_goal(np.array([0.5, 0.5]), 0.1)
        assert not controller.start_phase.active
        assert controller.start_phase.note == "stopped: a pose goal arrived"
        assert "target is in force" in controller.optimize_start(q, 0.2)
    finally:
        controller.close()
