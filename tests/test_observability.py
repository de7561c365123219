"""Issue 16, part 1: observability motion (ft_core.observability, the controller's option)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from ft_core import engine, robots
from ft_core.observability import OBSERVED_SPEED, Excursions, ObservabilityConfig
from ft_sim.scenario import TASK_POINTS, Scenario, ScenarioConfig
from rclpy.parameter import Parameter
from rosutil import fresh_domain

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
        qd = cycle.step(q, rng.normal(scale=0.05, size=robot.m)).qd
        for joint in range(robot.n):
            out = cycle.excursion(q, qd, joint, 0.15)
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
    out = cycle.excursion(q, np.zeros(7), 6, -0.15)  # towards the limit: cut to the edge
    assert out is not None and q[6] + 0.004 * out[6] >= lower[6] - 1e-12
    assert cycle.excursion(q, np.zeros(7), 6, 0.15)[6] == pytest.approx(0.15)
    # Six healthy joints for a pose task: no null space, nothing to excite.
    pose = engine.ResolutionEngine(robots.load("panda", task_space="pose"))
    assert pose.excursion(q, np.zeros(7), 6, 0.15, locked=[0]) is None
    assert pose.excursion(q, np.zeros(7), 0, 0.15, locked=[0]) is None  # a locked joint


@pytest.mark.parametrize("enabled", [True, False])
def test_a_lock_on_a_joint_the_task_never_moves_is_found_by_the_excursions(
        enabled: bool) -> None:
    """The Panda holds a position goal; joint 7 (on the tool axis) locks unseen.

    In lock-step on a realistic plant (20 ms latency, 30 ms response time, holding the
    last command): with excursions of 0.5 s after 2 s idle the monitor declares the lock
    within the idle time plus a round of excursions of the 7 idle joints; without, never.
    While the arm holds the goal the tool stays within 0.5 mm (the excursions are in the
    null space; the lagging plant follows them a little late while the null space turns:
    a second-order deviation).
    """
    config = ScenarioConfig(points=(TASK_POINTS["panda"][0],), soft_limits=False, rate=125.0,
                            noise=0.0, command_latency=0.02, response_time=0.03,
                            hold_last_command=True)
    scenario = Scenario(config, domain_id=fresh_domain())
    try:
        scenario.controller.set_parameters([
            Parameter("observability.enabled", value=enabled),
            Parameter("observability.idle_time", value=2.0),
            Parameter("observability.duration", value=0.5)])
        scenario.start()
        assert scenario.reach(0, 1e-4, 10.0)
        excited = set()
        deviation = 0.0
        for _ in range(150):  # holding the goal for 6 s, noting which joints move
            deviation = max(deviation, scenario.hold(0, 0.04))
            excited |= {j for j in range(7) if abs(scenario.command[j]) > 0.05}
        print(f"tool deviation while holding: max {deviation * 1e3:.3f} mm")
        assert deviation < 5e-4
        assert (6 in excited) == enabled  # an excursion of joint 7 happened
        scenario.inject("panda_joint7")
        latency = scenario.until_detected(2.0 + 7 * 0.5 + 1.0)  # every joint idle: a round
        if enabled:
            assert scenario.record.detected == ["panda_joint7"]
            print(f"lock of an idle joint detected after {latency:.2f} s")
            assert 0 < latency <= 6.5
        else:
            assert latency is None and scenario.record.detected == []
    finally:
        scenario.close()


def test_the_controller_refuses_bad_observability_parameters() -> None:
    import rclpy
    from ft_controller.controller_node import ControllerNode
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context, domain_id=fresh_domain())
    try:
        node = ControllerNode(context=context, parameter_overrides=[
            Parameter("robot_model", value="panda"), Parameter("task_space", value="position")])
        result = node.set_parameters([Parameter("observability.speed", value=math.nan)])
        assert not result[0].successful
        assert node.set_parameters([Parameter("observability.enabled", value=True)])[0].successful
        assert node._observability_note() == "waiting"
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
