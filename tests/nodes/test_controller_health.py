"""controller_node in-process: it adapts to `ft/joint_health`, and gives up a task it cannot do."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, KeyValue
from ft_controller.controller_node import ControllerNode
from ft_core import robots
from ft_core.adaptation import INFEASIBLE
from ft_core.command_limits import DriverCheck
from ft_core.health import Health, JointHealth
from ft_msgs_py import health, qos
from ft_msgs_py.spin import harness_node, spin_until
from geometry_msgs.msg import TwistStamped
from rclpy.parameter import Parameter
from rosutil import FakePlant, ros_context
from std_msgs.msg import String
from test_controller import controller_status  # the controller tests read it so

PANDA = robots.load("panda")
Q0 = np.array([0.4, 0.3, -0.5, -1.9, 0.6, 1.4, -0.2])
TWIST = np.array([0.05, 0.0, -0.02, 0.0, 0.0, 0.1])


class Recorder:
    """A logger that keeps what it is told (the watch's, in place of the node's)."""

    def __init__(self):
        self.lines: list[tuple[str, str]] = []

    def __getattr__(self, level: str):
        return lambda message, **_: self.lines.append((level, message))


@contextmanager
def controller(**parameters) -> Iterator[tuple[ControllerNode, FakePlant]]:
    """A controller (sim time, 100 Hz, smoothed commands) and a fake Panda plant at Q0."""
    values = {"robot_model": "panda", "use_sim_time": True, "control_rate": 100.0,
              "resolution": "least_norm", **parameters}
    with ros_context() as (context, executor):
        node = ControllerNode(context=context, parameter_overrides=[
            Parameter(name, value=value) for name, value in values.items()])
        executor.add_node(node)
        yield node, FakePlant(context, executor, node.command_joints, Q0)


def health_publisher(plant: FakePlant, name: str = "monitor"):
    """A `ft/joint_health` publisher on a node of that name, as the monitor's."""
    node = harness_node(name, plant.node.context)
    plant.executor.add_node(node)
    return node.create_publisher(DiagnosticArray, "ft/joint_health", qos.LATCHED)


def every_joint(**states: JointHealth) -> dict[str, JointHealth]:
    """The monitor's message content: every joint, healthy unless named."""
    return {joint: states.get(joint, JointHealth()) for joint in PANDA.joint_names}


def twist_sender(plant: FakePlant, twist: np.ndarray = TWIST):
    publisher = plant.node.create_publisher(TwistStamped, "ft/target_twist", qos.RELIABLE)

    def send(p: FakePlant) -> None:
        msg = TwistStamped()
        msg.header.stamp = p.stamp()
        msg.twist.linear.x, msg.twist.linear.y, msg.twist.linear.z = twist[:3]
        msg.twist.angular.x, msg.twist.angular.y, msg.twist.angular.z = twist[3:]
        publisher.publish(msg)

    return send


def test_a_degraded_joint_is_slowed_and_a_free_swinging_one_pinned() -> None:
    with controller(velocity_scale=0.5) as (node, plant):
        plant.frozen = True
        send = twist_sender(plant, 20 * TWIST)  # far too fast: scaled into the limits
        plant.run(20, send)
        lowered = 0.4 * 0.5 * PANDA.velocity_limits[1]
        assert abs(plant.velocity()[1]) > 2 * lowered
        publisher = health_publisher(plant)
        publisher.publish(health.message(every_joint(
            panda_joint1=JointHealth(follows=1.3),  # a healthy joint ahead of its prediction
            panda_joint2=JointHealth(Health.DEGRADED, follows=0.4),
            panda_joint6=JointHealth(Health.FREE_SWINGING)), plant.stamp()))
        plant.run(60, send)  # the stop of joint 2 to its new limit, on the ramp
        qd = plant.velocity()
        assert abs(qd[1]) <= lowered + 1e-9
        assert qd[5] == 0.0 and np.any(qd)
        assert node.core.pinned == (5,) and node.locked_joints == []
        assert "panda_joint2 degraded, speed x0.40" in node.core.adaptation.note
        publisher.publish(health.message(every_joint(), plant.stamp()))  # the monitor's reset
        plant.run(60, send)
        assert abs(plant.velocity()[1]) > 2 * lowered
        assert plant.velocity()[5] != 0.0 and node.core.adaptation.note == "none"


def _garbage() -> list[DiagnosticArray]:
    """Messages the controller must refuse whole, each with one fault."""
    def with_value(joint: str, key: str, value: str) -> DiagnosticArray:
        msg = health.message(every_joint(), None)
        status = next(s for s in msg.status if s.name == joint)
        status.values = [kv for kv in status.values if kv.key != key] + [KeyValue(key=key,
                                                                               value=value)]
        return msg

    unknown = health.message({**every_joint(), "gripper": JointHealth(Health.LOCKED)}, None)
    duplicate = health.message(every_joint(), None)
    duplicate.status.append(duplicate.status[0])
    state = health.message(every_joint(), None)
    state.status[2].message = "haunted"
    return [unknown, duplicate, state, with_value("panda_joint3", "follows", "fast"),
            with_value("panda_joint3", "follows", "-inf"),
            with_value("panda_joint3", "torque_margin", "inf"),
            with_value("panda_joint3", "usable_lower", "nan")]


def test_garbage_on_joint_health_is_refused_with_a_warning_and_the_arm_goes_on() -> None:
    with controller() as (node, plant):
        plant.frozen = True
        send = twist_sender(plant)
        recorder = node._watch._logger = Recorder()
        publisher = health_publisher(plant)
        publisher.publish(health.message(every_joint(
            panda_joint4=JointHealth(Health.DEGRADED, follows=0.5)), plant.stamp()))
        plant.run(5, send)
        adapted = node.core.adaptation.derived
        assert adapted.velocity_factors[3] == 0.5
        for k, msg in enumerate(_garbage()):
            msg.header.stamp = plant.stamp()
            publisher.publish(msg)
            plant.run(3, send)
            assert recorder.lines[-1][0] == "warning" and "ignored" in recorder.lines[-1][1], k
            assert node.core.adaptation.derived == adapted, k  # the last good one stands
            assert np.any(plant.velocity()) and np.all(np.isfinite(plant.velocity())), k
        warnings = [line for level, line in recorder.lines if level == "warning"]
        assert "unknown joints ['gripper']" in warnings[0] and "twice" in warnings[1]
        assert "haunted" in warnings[2] and "not a number" in warnings[3]
        assert "follows is -inf" in warnings[4] and "torque_margin is inf" in warnings[5]
        # Another node than the monitor publishing: refused, whatever it says.
        stranger = health_publisher(plant, "stranger")
        stranger.publish(health.message(every_joint(), plant.stamp()))
        plant.run(3, send)
        assert "not by the monitor alone" in recorder.lines[-1][1]
        assert node.core.adaptation.derived == adapted


def test_with_too_few_joints_left_it_says_so_and_commands_zeros_within_the_limits() -> None:
    with controller() as (node, plant):
        send = twist_sender(plant, np.array([0.05, 0.0, -0.02, 0.0, 0.0, 0.0]))
        plant.run(30, send)
        assert np.linalg.norm(plant.velocity()) > 0
        publisher = health_publisher(plant)
        # A pose task (6 coordinates) with joints 1 to 4 locked and joint 6 free-swinging:
        # joints 5 and 7 left cannot produce half of the twist asked; given up after 1 s.
        failed = {f"panda_joint{k}": JointHealth(Health.LOCKED) for k in range(1, 5)}
        publisher.publish(health.message(every_joint(
            **failed, panda_joint6=JointHealth(Health.FREE_SWINGING)), plant.stamp()))
        first = len(plant.commands)
        plant.run(400, send)
        commands = plant.commands[first - 1:]
        assert not np.any(plant.velocity())  # at rest
        check = DriverCheck(node.core.smoother.limits)
        for command in commands:  # the ramp to rest, the failed joints at 0 at once
            stamp = command.header.stamp.sec + 1e-9 * command.header.stamp.nanosec
            assert check.check(np.array(command.velocity), stamp, (0, 1, 2, 3, 5)) is None
        reason = node.problems.active[INFEASIBLE]
        assert reason.startswith("2 joints left") and "6 coordinates of the pose task" in reason
        plant.run(60, send)  # diagnostics every 0.5 s
        status = controller_status(plant)
        assert status.level == b"\x02" and f"{INFEASIBLE}: 2 joints left" in status.message
        publisher.publish(health.message(every_joint(), plant.stamp()))  # the monitor's reset
        plant.run(30, send)
        assert np.linalg.norm(plant.velocity()) > 0 and INFEASIBLE not in node.problems.active
        assert math.isfinite(float(np.linalg.norm(plant.velocity())))


def test_health_latched_before_the_model_came_is_taken_with_the_model() -> None:
    with controller(robot_model="") as (node, plant):
        health_publisher(plant).publish(health.message(every_joint(
            panda_joint3=JointHealth(Health.LOCKED)), plant.stamp()))
        spin_until(plant.executor, lambda: node._health is not None, 5.0)
        assert node.robot is None
        description = plant.node.create_publisher(String, "robot_description", qos.LATCHED)
        description.publish(String(data=robots.builtin_urdf("panda")))
        assert spin_until(plant.executor, lambda: node.robot is not None, 10.0)
        assert node.core.pinned == (2,)
