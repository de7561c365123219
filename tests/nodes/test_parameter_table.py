"""One parameter pattern: every node's table refuses absurd values with a reason.

The values below were accepted with an empty reason by the tables before they were
declarative (a black-box fuzz of 1 275 parameter sets); each is refused now, at set time
with the reason, and at start-up by an ERROR and the default.
"""

from __future__ import annotations

import math

import pytest
from ft_controller.controller_node import ControllerNode
from ft_monitor.monitor_node import MonitorNode
from ft_msgs_py import parameter_table
from ft_msgs_py.parameter_table import Setting
from ft_sim.sim_node import SimNode
from rclpy.parameter import Parameter
from rosutil import ros_context

TINY = 5e-324  # the smallest positive double


@pytest.mark.parametrize(("node_class", "name", "value", "reason"), [
    (SimNode, "failure.joint", "no_such_joint", "is not one of"),
    (SimNode, "failure.time", math.nan, "out of range"),
    (SimNode, "failure.time", math.inf, "out of range"),
    (ControllerNode, "soft_limits.lower", [-1e308] * 7, "out of range"),
    (ControllerNode, "soft_limits.upper", [-1e308] * 7, "out of range"),
    (ControllerNode, "monitor_timeout", 0.0, "out of range"),
    (ControllerNode, "monitor_timeout", TINY, "out of range"),
    (ControllerNode, "kfm_gain", TINY, "out of range"),
    (ControllerNode, "jump_gain", TINY, "out of range"),
    (ControllerNode, "limit_gain", TINY, "out of range"),
    (ControllerNode, "swing_gain", TINY, "out of range"),
    (MonitorNode, "detection.persistence", 0.0, "out of range"),
    (MonitorNode, "detection.persistence", TINY, "out of range"),
    (MonitorNode, "detection.follow_time", 0.0, "out of range"),
    (MonitorNode, "detection.follow_time", TINY, "out of range"),
    (MonitorNode, "detection.latency", [0.01, 0.02], "one value or none"),
])
def test_absurd_values_are_refused_with_a_reason(node_class, name, value, reason) -> None:
    with ros_context() as (context, _):
        node = node_class(context=context, parameter_overrides=[
            Parameter("robot_model", value="panda")])
        try:
            before = node.get_parameter(name).value
            (result,) = node.set_parameters([Parameter(name, value=value)])
            assert not result.successful, f"{name} = {value} was accepted"
            assert reason in result.reason, result.reason
            assert node.get_parameter(name).value == before
        finally:
            node.destroy_node()


def test_a_gain_of_zero_stays_off_and_the_monitor_identifies_or_takes_one_value() -> None:
    with ros_context() as (context, _):
        controller = ControllerNode(context=context, parameter_overrides=[
            Parameter("robot_model", value="panda")])
        monitor = MonitorNode(context=context, parameter_overrides=[
            Parameter("robot_model", value="panda")])
        try:
            (result,) = controller.set_parameters([Parameter("kfm_gain", value=0.0)])
            assert result.successful and controller.core.engine.config.kfm_gain == 0.0
            assert monitor.core.detector.config.latency is None  # identified online
            (result,) = monitor.set_parameters([Parameter("detection.latency", value=[0.02])])
            assert result.successful and monitor.core.detector.config.latency == 0.02
        finally:
            controller.destroy_node()
            monitor.destroy_node()


def test_a_refused_start_up_value_is_an_error_and_the_default() -> None:
    with ros_context() as (context, _):
        sim = SimNode(context=context, parameter_overrides=[
            Parameter("robot_model", value="panda"), Parameter("failure.joint", value="nope"),
            Parameter("failure.time", value=-1.0)])
        controller = ControllerNode(context=context, parameter_overrides=[
            Parameter("robot_model", value="panda"), Parameter("kfm_gain", value=TINY)])
        try:
            assert sim.get_parameter("failure.joint").value == ""  # no failure scheduled
            assert sim.get_parameter("failure.time").value == 0.0
            assert controller.get_parameter("kfm_gain").value == 50.0
        finally:
            sim.destroy_node()
            controller.destroy_node()


def test_a_setting_says_what_it_allows() -> None:
    gain = Setting(1.0, "gain", (1e-3, 100.0), off=0.0)
    assert gain.refusal("g", 0.0) is None and gain.refusal("g", 1e-3) is None
    assert gain.refusal("g", 1e-4) == "g = 0.0001 is out of range: 0.001 to 100 or 0 (off)"
    mode = Setting("a", "mode", choices=("a", "b"))
    assert mode.refusal("m", "c") == "m must be one of a, b, not 'c'"
    joints = Setting(Parameter.Type.STRING_ARRAY, "names")
    assert joints.refusal("j", ["x", "y"]) is None
    box = Setting(Parameter.Type.DOUBLE_ARRAY, "rad", (-1.0, 1.0))
    assert box.refusal("b", [0.5, 2.0]) == "b = 2 is out of range: each -1 to 1"
    assert box.refusal("b", [0.0] * (parameter_table.MAX_ARRAY + 1)).endswith("(at most 4096)")
    assert Setting(0.5, "s").refusal("s", math.nan) == "s must be finite"
