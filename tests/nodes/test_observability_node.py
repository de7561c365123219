"""Issue 16, part 1, in the nodes: observability motion finds a lock the task hides."""

from __future__ import annotations

import math

import pytest
from ft_controller import loaded
from ft_sim.scenario import TASK_POINTS, Scenario, ScenarioConfig
from rclpy.parameter import Parameter
from rosutil import fresh_domain


@pytest.mark.slow
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
        assert loaded.observability_note(node.loaded) == "waiting"
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
