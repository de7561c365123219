"""controller_node in-process: tracking, limits, safety reactions, parameters, the executable."""

from __future__ import annotations

import math
import re
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace

import numpy as np
import pytest
import rclpy
from ft_controller.controller_node import PARAMETERS, ControllerNode
from ft_core import robots
from ft_monitor.monitor_node import PARAMETERS as MONITOR_PARAMETERS
from ft_msgs_py import convert, diagnostics, metrics, parameter_table, qos
from ft_msgs_py.spin import Ticked, harness_node, spin_for, spin_until
from geometry_msgs.msg import PoseStamped, TwistStamped
from paths import REPO
from rclpy.duration import Duration
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.experimental.events_executor import EventsExecutor
from rclpy.parameter import Parameter, parameter_dict_from_yaml_file
from rosutil import FakePlant, ros_context
from sensor_msgs.msg import JointState
from std_msgs.msg import Header, String
from std_srvs.srv import Trigger

PANDA = robots.load("panda")
Q0 = np.array([0.4, 0.3, -0.5, -1.9, 0.6, 1.4, -0.2])
TWIST = np.array([0.05, 0.0, -0.02, 0.0, 0.0, 0.1])


@contextmanager
def controller(executor_type: type[Executor] = SingleThreadedExecutor,
               **parameters) -> Iterator[tuple[ControllerNode, FakePlant]]:
    """A controller (sim time, 100 Hz) and a fake Panda plant at Q0, in one executor."""
    values = {"robot_model": "panda", "use_sim_time": True, "control_rate": 100.0,
              "resolution": "least_norm", **parameters}
    with ros_context(executor_type=executor_type) as (context, executor):
        node = ControllerNode(context=context, parameter_overrides=[
            Parameter(name, value=value) for name, value in values.items()])
        executor.add_node(node)
        joints = node.command_joints if node.robot else list(PANDA.joint_names)
        plant = FakePlant(context, executor, joints, Q0)
        yield node, plant


def twist_sender(plant: FakePlant, twist: np.ndarray = TWIST, frame: str = ""):
    publisher = plant.node.create_publisher(TwistStamped, "ft/target_twist", qos.RELIABLE)

    def send(p: FakePlant) -> None:
        msg = TwistStamped()
        msg.header.stamp, msg.header.frame_id = p.stamp(), frame
        msg.twist.linear.x, msg.twist.linear.y, msg.twist.linear.z = twist[:3]
        msg.twist.angular.x, msg.twist.angular.y, msg.twist.angular.z = twist[3:]
        publisher.publish(msg)

    return send


def monitor_publisher(plant: FakePlant, name: str = "monitor"):
    """A `ft/locked_joints` publisher on a node of that name, as the monitor's."""
    node = harness_node(name, plant.node.context)
    plant.executor.add_node(node)
    return node.create_publisher(JointState, "ft/locked_joints", qos.LATCHED)


def controller_status(plant: FakePlant):
    for array in reversed(plant.diagnostics):
        for status in array.status:
            if status.name == "/controller":
                return status
    return None


def all_finite(plant: FakePlant) -> bool:
    """Commands arrived, and every command and metric was finite."""
    return (bool(plant.commands) and all(np.all(np.isfinite(c.velocity)) for c in plant.commands)
            and all(np.all(np.isfinite(m.data)) for m in plant.metrics))


@pytest.mark.parametrize("executor_type", [SingleThreadedExecutor, EventsExecutor])
def test_twist_is_tracked_exactly_and_within_limits(executor_type: type[Executor]) -> None:
    """Also with the EventsExecutor the executables spin: its timers run on sim time."""
    with controller(executor_type, velocity_scale=0.5) as (node, plant):
        plant.frozen = True
        plant.run(30, twist_sender(plant))
        qd = plant.velocity()
        np.testing.assert_allclose(PANDA.jacobian(Q0) @ qd, TWIST, atol=1e-9)
        assert list(plant.commands[-1].name) == list(PANDA.joint_names)
        assert np.all(np.abs(qd) <= 0.5 * PANDA.velocity_limits + 1e-12)
        values = metrics.values(plant.metrics[-1])
        assert set(metrics.labels(node.command_joints)) == set(values)
        assert values["task_scale"] == 1.0 and values["soft_limit_margin"] == metrics.NO_SOFT_BOX
        assert all_finite(plant)


def test_too_fast_a_twist_is_scaled_inside_the_velocity_limits() -> None:
    with controller(velocity_scale=0.2) as (_, plant):
        plant.frozen = True
        plant.run(10, twist_sender(plant, 20 * TWIST))
        qd = plant.velocity()
        assert np.all(np.abs(qd) <= 0.2 * PANDA.velocity_limits + 1e-12)
        scale = metrics.values(plant.metrics[-1])["task_scale"]
        assert 0 < scale < 1
        np.testing.assert_allclose(PANDA.jacobian(Q0) @ qd, scale * 20 * TWIST, atol=1e-9)


def test_max_kfm_raises_the_published_kfm() -> None:
    position_start = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
    runs = {}
    for mode in ("least_norm", "max_kfm"):
        with controller(resolution=mode, task_space="position") as (_, plant):
            plant.q = position_start.copy()
            plant.run(300, twist_sender(plant, np.array([0.0, 0.03, 0.0, 0, 0, 0])))
            runs[mode] = [metrics.values(m)["kfm"] for m in plant.metrics]
    assert runs["max_kfm"][-1] > runs["max_kfm"][0] + 0.05  # it grows
    assert runs["max_kfm"][-1] > 1.3 * runs["least_norm"][-1]


def test_pose_goal_is_reached_and_the_arm_stops() -> None:
    goal = PANDA.forward(Q0)
    goal[:3, 3] += [0.05, -0.04, 0.03]
    with controller() as (_, plant):
        publisher = plant.node.create_publisher(PoseStamped, "ft/target_pose", qos.RELIABLE)
        msg = PoseStamped()
        msg.pose = convert.pose_message(goal)
        publisher.publish(msg)
        plant.run(600)
        error = PANDA.task_error(goal, plant.q)
        assert np.linalg.norm(error[:3]) < 1e-3 and np.linalg.norm(error[3:]) < 1e-2
        assert np.all(plant.velocity() == 0.0)  # stopped exactly


def test_stale_twist_decays_to_zero() -> None:
    with controller(target_timeout=0.1) as (_, plant):
        plant.frozen = True
        twist_sender(plant)(plant)
        speeds = []
        for _ in range(40):
            plant.step()
            speeds.append(float(np.linalg.norm(plant.velocity())))
        assert speeds[5] > 0  # fresh
        assert speeds[14] < speeds[8]  # decaying after 0.1 s
        assert speeds[-1] == 0.0  # gone after 0.2 s


def test_stale_or_invalid_joint_states_stop_the_arm_until_good_data_returns() -> None:
    with controller(state_timeout=0.05) as (_, plant):
        plant.frozen = True
        send = twist_sender(plant)
        plant.run(20, send)
        assert np.linalg.norm(plant.velocity()) > 0
        plant.publish_states = False  # the driver goes quiet
        plant.run(20, send)
        assert np.all(plant.velocity() == 0.0)
        plant.publish_states = True
        plant.run(5, send)
        assert np.linalg.norm(plant.velocity()) > 0  # recovered by itself
        bad = {"NaN": {"position": [math.nan] * 7},
               "wrong length": {"position": [0.0] * 6},
               "duplicate names": {"name": [*PANDA.joint_names[:6], PANDA.joint_names[0]]},
               "missing joint": {"name": [*PANDA.joint_names[:6], "gripper"]}}
        for overrides in bad.values():
            plant.publish_states = False

            def send_bad(p: FakePlant, overrides=overrides) -> None:
                send(p)
                p.publish_state(**overrides)

            plant.run(5, send_bad)
            assert np.all(plant.velocity() == 0.0), overrides
            plant.publish_states = True
            plant.run(3, send)
            assert np.linalg.norm(plant.velocity()) > 0, overrides
        plant.step(timeout=1.0)
        spin_until(plant.executor, lambda: len(plant.diagnostics) > 0, 5.0)
        assert all_finite(plant)


def test_extra_joints_in_states_are_ignored_and_future_stamps_rejected() -> None:
    with controller() as (_, plant):
        plant.frozen = True
        send = twist_sender(plant)
        plant.publish_states = False

        def with_fingers(p: FakePlant) -> None:
            send(p)
            p.publish_state(name=["finger", *p.joints], position=[0.01, *p.q])

        plant.run(5, with_fingers)
        assert np.linalg.norm(plant.velocity()) > 0

        def ahead(seconds: float):
            def publish(p: FakePlant) -> None:
                send(p)
                p.publish_state(header=Header(stamp=convert.stamp_from_nanoseconds(
                    p.t_ns + round(seconds * 1e9))))
            return publish

        # With simulated time a /clock that lags by up to 1 s is tolerated (issue 14)...
        plant.run(5, ahead(0.5))
        assert np.linalg.norm(plant.velocity()) > 0
        plant.run(5, ahead(5.0))  # ... a stamp further ahead is refused
        assert np.all(plant.velocity() == 0.0)


def test_errors_show_in_diagnostics() -> None:
    # state_timeout is also the steady-time watchdog's: 0.2 s, so that a stall of the
    # test's own process (another test worker beside it) is not what the status shows.
    with controller(state_timeout=0.2) as (_, plant):
        plant.publish_states = False
        plant.run(60)  # 0.6 s of simulated time: diagnostics at 2 Hz
        status = controller_status(plant)
        assert status.level == diagnostics.WARN and "waiting" in status.message
        plant.publish_states = True
        plant.run(60)
        assert controller_status(plant).level == diagnostics.OK
        plant.publish_states = False  # the driver goes quiet
        plant.run(100)  # the last diagnostics at least 0.5 s after the last state
        status = controller_status(plant)
        assert status.level == diagnostics.ERROR and "joint_states" in status.message
        joints = [s for s in plant.diagnostics[-1].status if "joint" in s.name]
        assert joints == []  # no per-joint status without a fresh state to judge


@pytest.mark.parametrize("executor_type", [SingleThreadedExecutor, EventsExecutor])
def test_locked_joints_get_exactly_zero_and_the_task_is_still_tracked(
        executor_type: type[Executor]) -> None:
    with controller(executor_type, task_space="position") as (_, plant):
        plant.frozen = True
        publisher = monitor_publisher(plant)
        publisher.publish(convert.locked_message({"panda_joint4": Q0[3]}, plant.stamp()))
        twist = np.array([0.03, -0.02, 0.01, 0, 0, 0])
        plant.run(20, twist_sender(plant, twist))
        qd = plant.velocity()
        assert qd[3] == 0.0
        position = robots.load("panda", task_space="position")
        np.testing.assert_allclose(position.jacobian(Q0) @ qd, twist[:3], atol=1e-9)
        assert metrics.values(plant.metrics[-1])["s_panda_joint4"] == metrics.LOCKED
        publisher.publish(convert.locked_message({}, plant.stamp()))  # repaired
        plant.run(5, twist_sender(plant, twist))
        assert plant.velocity()[3] != 0.0


def test_the_locked_set_is_taken_from_the_monitor_only() -> None:
    """Issue 14: a forged empty set made the controller command a locked joint."""
    twist = np.array([0.03, -0.02, 0.01, 0, 0, 0])
    with controller(task_space="position") as (node, plant):
        plant.frozen = True
        monitor = monitor_publisher(plant)
        # The monitor's command path, as echoed: each command, its locked joints zeroed.
        zeroed = {3}
        forwarded = plant.node.create_publisher(JointState, "ft/command_echo", qos.RELIABLE)
        plant.node.create_subscription(JointState, "ft/command_raw", lambda msg: (
            forwarded.publish(JointState(header=msg.header, name=list(msg.name), velocity=[
                0.0 if j in zeroed else v for j, v in enumerate(msg.velocity)]))),
            qos.SENSOR_INPUT)
        monitor.publish(convert.locked_message({"panda_joint4": Q0[3]}, plant.stamp()))
        plant.run(10, twist_sender(plant, twist))
        assert plant.velocity()[3] == 0.0
        forger = monitor_publisher(plant, "forger")
        forger.publish(convert.locked_message({}, plant.stamp()))
        plant.run(10, twist_sender(plant, twist))
        assert plant.velocity()[3] == 0.0  # still locked: the forged set is refused
        assert "2 publishers" in node.problems.active["ft/locked_joints"]
        assert "/forger" in node.problems.active["ft/locked_joints"]
        # Issue 31 item 11: beside the stranger, a new lock is taken once the monitor's
        # command path shows it; a forged one, which the monitor does not zero, is not.
        forger.publish(convert.locked_message({"panda_joint4": Q0[3], "panda_joint6": Q0[5]},
                                              plant.stamp()))
        plant.run(10, twist_sender(plant, twist))
        assert node.locked_joints == ["panda_joint4"]
        zeroed.add(1)  # the monitor locks panda_joint2
        monitor.publish(convert.locked_message({"panda_joint4": Q0[3], "panda_joint2": Q0[1]},
                                               plant.stamp()))
        plant.run(10, twist_sender(plant, twist))
        assert node.locked_joints == ["panda_joint2", "panda_joint4"]
        assert plant.velocity()[1] == 0.0 and plant.velocity()[3] == 0.0
        monitor.publish(convert.locked_message({}, plant.stamp()))  # a release waits
        plant.run(10, twist_sender(plant, twist))
        assert node.locked_joints == ["panda_joint2", "panda_joint4"]
    # Another name, or the monitor's name in another namespace.
    for namespace, name in ((None, "impostor"), ("/evil", "monitor")):
        impostor = f"{namespace or ''}/{name}"
        with controller(task_space="position") as (node, plant):
            plant.frozen = True
            stranger = rclpy.create_node(name, namespace=namespace, context=plant.node.context)
            plant.executor.add_node(stranger)
            stranger.create_publisher(JointState, "/ft/locked_joints", qos.LATCHED).publish(
                convert.locked_message({"panda_joint2": Q0[1]}, plant.stamp()))
            plant.run(10, twist_sender(plant, twist))
            assert plant.velocity()[1] != 0.0  # a lone publisher that is not the monitor
            problem = node.problems.active["ft/locked_joints"]
            assert "not by the monitor '/monitor'" in problem and impostor in problem


def test_a_restarted_monitor_is_believed_while_its_dead_predecessor_is_in_the_graph() -> None:
    """A killed monitor's publisher lingers until its lease ends: both bear its name."""
    twist = np.array([0.03, -0.02, 0.01, 0, 0, 0])
    with controller(task_space="position") as (node, plant):
        plant.frozen = True
        monitor_publisher(plant)  # the dead one: in the graph, silent
        monitor = monitor_publisher(plant)
        monitor.publish(convert.locked_message({"panda_joint4": Q0[3]}, plant.stamp()))
        plant.run(10, twist_sender(plant, twist))
        assert node.locked_joints == ["panda_joint4"] and plant.velocity()[3] == 0.0
        monitor.publish(convert.locked_message({}, plant.stamp()))  # a reset: released
        plant.run(10, twist_sender(plant, twist))
        assert node.locked_joints == [] and plant.velocity()[3] != 0.0
        assert node.problems.active.get("ft/locked_joints") is None


def test_twist_in_another_frame_is_rejected() -> None:
    with controller() as (_, plant):
        plant.run(10, twist_sender(plant, frame="camera_link"))
        assert np.all(plant.velocity() == 0.0)


def test_bad_frames_huge_twists_and_absurd_states_give_zeros_and_recover() -> None:
    """Issue 14: mixed frames crashed the node; a twist of 1e306 hung it."""
    with controller() as (node, plant):
        plant.run(3, twist_sender(plant, frame="camera_link"))  # a warning episode
        plant.run(3, twist_sender(plant))
        plant.run(3, twist_sender(plant, np.full(6, math.nan)))  # an error from the same site
        assert "non-finite" in node.problems.active["ft/target_twist"]
        plant.run(3, twist_sender(plant, np.full(6, 1e306)))
        assert "engine" in node.problems.active
        assert "no arm can do that" in node.problems.active["engine"]
        plant.run(10)  # zeros, reached on a ramp within the arm's limits
        assert np.all(plant.velocity() == 0.0)
        far = Q0.copy()
        far[3] = 1e300
        plant.q = far
        plant.run(3)
        assert "outside the joint limits" in node.problems.active["engine"]
        assert np.all(plant.velocity() == 0.0)
        plant.q = Q0.copy()
        plant.run(5, twist_sender(plant))
        assert "engine" not in node.problems.active
        assert np.any(plant.velocity() != 0.0)  # recovered


def test_without_a_target_the_arm_holds_still() -> None:
    with controller(resolution="blend") as (_, plant):
        plant.run(10)
        assert np.all(plant.velocity() == 0.0)
    with controller(resolution="blend", idle_null_space_motion=True,
                    task_space="position") as (_, plant):
        plant.q = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
        plant.run(10)
        assert np.linalg.norm(plant.velocity()) > 0  # kfm ascent in the null space
        J = robots.load("panda", task_space="position").jacobian(plant.q)
        np.testing.assert_allclose(J @ plant.velocity(), 0.0, atol=1e-9)


def test_critical_points_become_soft_limits() -> None:
    points = [0.5, 0.1, 0.4, 0.45, -0.15, 0.35]
    with controller(task_space="position", critical_points=points) as (node, plant):
        plant.q = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
        plant.step()
        assert node.core.soft_limits_note.startswith("computing soft limits")  # in the background
        computed, commanded, deadline = False, 0, time.monotonic() + 60.0
        while not computed and time.monotonic() < deadline:
            # The loop keeps commanding while the boxes are traced in the background (a
            # second of CPU in another process). Counted, not timed: on a busy machine one
            # cycle can wait for a core, but a loop that traced in its callback would
            # command once, before or after.
            commanded += plant.step(timeout=2.0)
            computed = (metrics.values(plant.metrics[-1])["soft_limit_margin"]
                        < metrics.NO_SOFT_BOX)
        assert computed, "the soft limits never arrived"
        assert commanded >= 10, f"{commanded} commands while tracing: the loop was blocked"
        plant.run(70)
        assert "2 critical points" in dict(
            (kv.key, kv.value) for kv in controller_status(plant).values)["soft_limits"]
    with controller(task_space="position", critical_points=[1.5, 0.0, 0.3]) as (node, plant):
        plant.step()
        deadline = time.monotonic() + 60.0
        while node.core.soft_limits_pending and time.monotonic() < deadline:
            plant.step()
        plant.run(70)
        status = controller_status(plant)
        assert status.level == diagnostics.ERROR and "critical points" in status.message
        assert metrics.values(plant.metrics[-1])["soft_limit_margin"] == metrics.NO_SOFT_BOX
        assert np.all(np.isfinite(plant.velocity()))


@pytest.mark.parametrize(("name", "value", "reason"), [
    ("kfm_gain", -1.0, "out of range"),
    ("resolution", "fastest", "resolution"),
    ("soft_limits.lower", [0.0, 1.0], "soft_limits"),
    ("failure_probabilities", [1.0, -1.0, 1.0, 1.0, 1.0, 1.0, 1.0], "probabilit"),
    ("critical_points", [0.5, 0.1], "multiple of 3"),
    ("robot_model", "puma560", "read-only"),
    ("swing_gain", 1.0, "needs a model with inertias"),  # issue 31 item 5: once it hung
    # Issue 31 item 6: refused before reading, with a short reason (17 MB before).
    ("failure_probabilities", [0.5] * 1_000_000, "at most 4096"),
    ("soft_limits.lower", [0.0] * 5000, "at most 4096"),
])
def test_invalid_parameters_are_rejected_and_the_old_value_kept(name: str, value, reason: str,
                                                                ) -> None:
    with controller(task_space="position") as (node, _):
        before = node.param(name)
        (result,) = node.set_parameters([Parameter(name, value=value)])
        assert not result.successful and reason in result.reason
        assert len(result.reason) < 300, len(result.reason)
        assert node.param(name) == before


def test_a_swing_gain_the_model_cannot_honour_refuses_the_model_not_the_node() -> None:
    """Issue 31 item 5: swing_gain > 0 on a URDF without inertias killed the controller."""
    with controller(swing_gain=1.0) as (node, _):
        assert node.core is None
        assert "needs a model with inertias" in node.problems.active["model"]
    with controller(swing_gain=1.0, robot_model="panda_inertial") as (node, _):
        assert node.core is not None and "model" not in node.problems.active


def test_default_parameters_are_the_cores_defaults_written_once() -> None:
    """Every default that configures a core comes from its dataclass (issue 28).

    A node started with only a model builds exactly the default configurations of
    `ft_core` (the engine's, the cycle's, the plant's): no default is written twice.
    """
    from ft_core.controller import ControllerConfig
    from ft_core.engine import EngineConfig
    from ft_core.plant import PlantConfig
    from ft_sim.sim_node import SimNode

    with ros_context() as (context, _):
        node = ControllerNode(context=context, parameter_overrides=[
            Parameter("robot_model", value="panda")])
        sim = SimNode(context=context, parameter_overrides=[
            Parameter("robot_model", value="panda")])
        try:
            assert node.robot is not None
            config, limits = node.core.engine.config, node.core.smoother.limits
            # The core adds its smoother's limits, which the engine brakes within.
            assert config.acceleration == tuple(limits.acceleration)
            assert config.jerk == tuple(limits.jerk)
            assert replace(config, acceleration=(), jerk=()) == EngineConfig()
            assert node.core.config == ControllerConfig()
            assert sim.plant.path.config == PlantConfig()
        finally:
            node.destroy_node()
            sim.destroy_node()


def test_parameters_change_at_run_time() -> None:
    with controller() as (node, plant):
        plant.frozen = True
        results = node.set_parameters([Parameter("velocity_scale", value=0.1),
                                       Parameter("resolution", value="blend")])
        assert all(result.successful for result in results)
        assert node.core.engine.config.velocity_scale == 0.1
        assert node.core.engine.config.resolution == "blend"
        plant.run(5, twist_sender(plant, 20 * TWIST))
        assert np.all(np.abs(plant.velocity()) <= 0.1 * PANDA.velocity_limits + 1e-12)


def test_malformed_urdf_does_not_crash_and_is_reported() -> None:
    with controller(robot_model="", robot_description="<robot name='x'><link") as (node, plant):
        assert node.robot is None
        for _ in range(60):
            plant.step(timeout=0.02)  # no command is coming: the model is missing
        assert not plant.commands
        status = controller_status(plant)
        assert status.level == diagnostics.ERROR and "does not parse" in status.message


def test_model_from_the_robot_description_topic() -> None:
    with controller(robot_model="") as (node, plant):
        publisher = plant.node.create_publisher(String, "robot_description", qos.LATCHED)
        publisher.publish(String(data=robots.builtin_urdf("panda")))
        assert spin_until(plant.executor, lambda: node.robot is not None, 10.0)
        plant.run(5, twist_sender(plant))
        assert len(plant.commands) >= 5
        # Issue 14: a second description (another robot, or the same one with 50x
        # velocity limits) is refused while running; the model and its limits stay.
        robot, limits = node.robot, node.robot.velocity_limits.copy()
        fast = re.sub(r'velocity="([0-9.]+)"', lambda m: f'velocity="{50 * float(m[1])}"',
                      robots.builtin_urdf("panda"))
        assert fast != robots.builtin_urdf("panda")
        for other in (robots.builtin_urdf("iiwa14"), fast, "not a robot " * 100):
            publisher.publish(String(data=other))
            plant.run(3, twist_sender(plant))
            assert node.robot is robot
            np.testing.assert_array_equal(node.robot.velocity_limits, limits)
        assert np.all(np.abs(plant.velocity()) <= limits)
        # ... until someone asks for a reload, which adopts the newest usable description.
        client = plant.node.create_client(Trigger, "controller/reload_model")
        assert client.wait_for_service(timeout_sec=5.0)

        def reload() -> Trigger.Response:
            future = client.call_async(Trigger.Request())
            assert spin_until(plant.executor, future.done, 5.0)
            return future.result()

        refused = reload()  # the newest is not a robot: the model is kept
        assert not refused.success and "cannot be used" in refused.message
        assert node.robot is robot
        publisher.publish(String(data=robots.builtin_urdf("iiwa14")))
        answers: list[Trigger.Response] = []
        assert spin_until(plant.executor, lambda: answers.append(reload()) or
                          answers[-1].success, 5.0)  # once the node has the new description
        assert answers[-1].message == "now using iiwa14"
        assert node.robot.name == "iiwa14"





def test_out_of_range_start_up_values_fall_back_to_the_defaults() -> None:
    with controller(kfm_gain=-5.0, control_rate=1e6) as (node, plant):
        assert node.get_parameter("kfm_gain").value == 50.0
        assert node.get_parameter("control_rate").value == 250.0
        plant.frozen = True
        plant.run(3, twist_sender(plant))
        assert len(plant.commands) >= 3


def test_empty_arrays_from_a_parameters_file_and_a_dump_round_trip(tmp_path) -> None:
    """`critical_points: []` (as `ros2 param dump` writes it) starts the node (issue 14)."""
    import yaml
    from rcl_interfaces.msg import ParameterType
    from rclpy.context import Context

    arrays = ("critical_points", "soft_limits.lower", "soft_limits.upper",
              "failure_probabilities", "joints")
    first = tmp_path / "first.yaml"
    first.write_text(yaml.safe_dump({"controller": {"ros__parameters": {
        "robot_model": "panda", **{name: [] for name in arrays}}}}))
    dumped = tmp_path / "dumped.yaml"
    for path in (first, dumped):
        context = Context()
        rclpy.init(context=context, args=["--ros-args", "--params-file", str(path)])
        try:
            node = ControllerNode(context=context)
            assert node.robot is not None
            assert all(node.param(name) == [] for name in arrays)
            kinds = {name: node.describe_parameter(name).type for name in arrays}
            assert kinds == {**dict.fromkeys(arrays[:4], ParameterType.PARAMETER_DOUBLE_ARRAY),
                             "joints": ParameterType.PARAMETER_STRING_ARRAY}
            dump = {name: node.param(name) for name in node._parameters if name != "use_sim_time"}
            dumped.write_text(yaml.safe_dump({"controller": {"ros__parameters": dump}}))
            node.destroy_node()
        finally:
            rclpy.shutdown(context=context)


def test_with_sim_time_and_no_clock_the_watchdog_still_commands_zeros() -> None:
    """Issue 14: with use_sim_time and no /clock nothing at all was published."""
    with controller() as (node, plant):
        plant.publish_state()  # a state, but never a /clock: the control timer cannot fire
        assert spin_until(plant.executor, lambda: len(plant.commands) >= 3, 5.0)
        assert all(np.all(np.array(c.velocity) == 0.0) for c in plant.commands)
        # Never a cycle yet: waiting for /clock (INFO once, issue 32), not a fault.
        assert not node._cycled and "control loop" not in node.problems.active
        plant.run(5)  # /clock: cycles run; then the clock stops, which is a fault
        assert node._cycled
        assert spin_until(plant.executor,
                          lambda: "control loop" in node.problems.active, 5.0)
        assert "no control cycle" in node.problems.active["control loop"]


def test_soft_limits_can_be_set_one_side_at_a_time() -> None:
    """Issue 14: through SetParameters (one parameter at a time) a valid pair was refused."""
    lower, upper = list(Q0 - 0.5), list(Q0 + 0.5)
    with controller(task_space="position") as (node, plant):
        (first,) = node.set_parameters([Parameter("soft_limits.lower", value=lower)])
        assert first.successful
        assert node.core.engine.config.soft_lower == ()  # one side alone: none yet
        (second,) = node.set_parameters([Parameter("soft_limits.upper", value=upper)])
        assert second.successful
        np.testing.assert_allclose(node.core.engine.config.soft_upper, upper)
        plant.run(3)
        assert metrics.values(plant.metrics[-1])["soft_limit_margin"] < metrics.NO_SOFT_BOX


def test_parameter_values_make_the_core_configurations_without_a_node() -> None:
    """`ft_controller.settings`: parameter values to the core's configurations.

    The table's defaults are the cores' defaults; per-joint values given in command order
    land in chain order; values the core refuses raise.
    """
    from ft_controller import settings
    from ft_core.controller import ControllerConfig
    from ft_core.engine import EngineConfig

    values = parameter_table.defaults(PARAMETERS)
    chain = np.arange(7)
    assert settings.engine_config(values, chain) == EngineConfig()
    assert settings.controller_config(values) == ControllerConfig()
    order = chain[::-1]  # the command lists the joints last to first
    lower = [-1.0, -2.0, -3.0, -4.0, -5.0, -6.0, -7.0]
    config = settings.engine_config({**values, "soft_limits.lower": lower,
                                     "soft_limits.upper": [1.0] * 7}, order)
    np.testing.assert_array_equal(config.soft_lower, lower[::-1])
    np.testing.assert_array_equal(config.soft_upper, [1.0] * 7)
    assert settings.engine_config({**values, "soft_limits.lower": lower}, order).soft_lower == ()
    with pytest.raises(ValueError, match="failure_probabilities needs 7 finite values, got 3"):
        settings.engine_config({**values, "failure_probabilities": [0.1, 0.2, 0.3]}, chain)
    with pytest.raises(ValueError, match="with a non-finite one"):
        settings.engine_config({**values, "soft_limits.lower": [math.nan] * 7,
                                "soft_limits.upper": [1.0] * 7}, chain)
    with pytest.raises(ValueError):
        settings.controller_config({**values, "observability.speed": 0.0})
    assert settings.controller_config({**values, "recovery.enabled": False}).recovery is None


def test_the_shipped_parameters_file_names_only_declared_parameters() -> None:
    """config/controller.yaml (the launch file's default): every key is the controller's."""
    shipped = REPO / "ros_ws" / "src" / "ft_controller" / "config" / "controller.yaml"
    values = parameter_dict_from_yaml_file(str(shipped), use_wildcard=True)
    assert "thread_priority" in values and "critical_points" in values
    assert set(values) <= set(PARAMETERS)
    # The launch file gives the monitor the same file: what it shares, it declares too.
    assert {"thread_priority", "robot_model", "task_space"} <= set(MONITOR_PARAMETERS)


def test_optimize_start_moves_the_idle_arm_with_the_tool_held_still() -> None:
    """Issue 34 item 2: `~/optimize_start` (Zhao & Li sec. III-D step i) on the Panda.

    Called on the idle arm, the service says it plans; the path is followed; the tool
    moves less than 2 mm; the reduced-condition cost drops. A target in force refuses
    it, with the reason.
    """
    from ft_core import start_configuration

    robot = robots.load("panda", task_space="position")
    with controller(resolution="blend", task_space="position") as (node, plant):
        plant.run(5)
        client = plant.node.create_client(Trigger, "controller/optimize_start")
        assert spin_until(plant.executor, client.service_is_ready, 10.0)
        future = client.call_async(Trigger.Request())
        assert spin_until(plant.executor, future.done, 10.0)
        answer = future.result()
        assert answer.success and answer.message == "planning the start configuration"
        # The plan runs in the controller's worker process, in wall time.
        assert spin_until(plant.executor, lambda: not node.core.start_phase.planning, 60.0)
        tool, cost = robot.forward(plant.q), start_configuration.dexterity_cost(robot, plant.q)
        for _ in range(60):  # at most 60 s of simulated time
            plant.run(100)
            if not node.core.start_phase.active:
                break
        assert node.core.start_phase.note == "at the start configuration", \
            node.core.start_phase.note
        assert np.linalg.norm(robot.forward(plant.q) - tool) < 2e-3
        assert start_configuration.dexterity_cost(robot, plant.q) < 0.9 * cost
        twist_sender(plant)(plant)
        plant.run(2)
        future = client.call_async(Trigger.Request())
        assert spin_until(plant.executor, future.done, 10.0)
        assert not future.result().success and "target is in force" in future.result().message


@pytest.mark.parametrize("executor_type", [SingleThreadedExecutor, EventsExecutor])
def test_the_process_loop_can_tick_the_cycles_instead_of_a_timer(
        executor_type: type[Executor]) -> None:
    """`ft-controller` as a process of its own: `spin.run_nodes` ticks its cycles.

    Same period on steady time, late ticks skipped as an rclpy timer skips them, the
    period following `control_rate`; the cycle's inputs wait for the tick, which takes
    them; with `use_sim_time` the timer stays, and the callbacks.
    """
    with controller(executor_type, use_sim_time=False, control_rate=250.0) as (node, plant):
        timer = node.cycles.timer
        assert math.isinf(node.cycles.next_tick())
        before = time.monotonic()
        node.cycle_on_loop_ticks()
        after = time.monotonic()
        assert isinstance(node.cycles, Ticked) and timer not in node.timers
        first, period = node.cycles.next_tick(), 1.0 / 250.0
        assert before + period <= first <= after + period  # one period from then
        node.last_command = None
        node.cycles.tick(first)
        assert node.last_command is not None and not np.any(node.last_command)  # no state
        assert node.cycles.next_tick() == pytest.approx(first + period)
        node.cycles.tick(first + 3.5 * period)  # late by 2.5 periods: those ticks are skipped
        assert node.cycles.next_tick() == pytest.approx(first + 4 * period)
        before = time.monotonic()
        node.set_parameters([Parameter("control_rate", value=100.0)])
        after = time.monotonic()
        assert before + 0.01 <= node.cycles.next_tick() <= after + 0.01
        due = node.cycles.next_tick()
        node.cycles.tick(due)
        assert node.cycles.next_tick() == pytest.approx(due + 0.01)
        # The inputs wait in their queues: the executor dispatches none of them ...
        held = {node.resolve_topic_name(topic) for topic in (
            "joint_states", "ft/command_echo", "ft/target_twist", "ft/target_pose")}
        assert held <= {s.topic_name for s in node._subscriptions}
        assert not held & {s.topic_name for s in node.subscriptions}
        plant.t_ns = node.now_ns()
        plant.publish_state()
        targets = plant.node.create_publisher(TwistStamped, "ft/target_twist", qos.RELIABLE)
        assert spin_until(plant.executor, lambda: targets.get_subscription_count() == 1)
        twist = TwistStamped()
        twist.header.stamp, twist.twist.linear.x = plant.stamp(), 0.05
        targets.publish(twist)
        assert targets.wait_for_all_acked(Duration(seconds=5.0))
        spin_for(plant.executor, 0.2)  # the executor's chance to dispatch them
        assert node.core.target is None and math.isinf(node.state_stamp)
        # ... the tick takes them, before its cycle.
        node.cycles.tick(node.cycles.next_tick())
        assert node.core.target is not None and node.core.target.kind == "twist"
        deadline = time.monotonic() + 5.0  # the state is best effort: it may be in flight
        while math.isinf(node.state_stamp) and time.monotonic() < deadline:
            node.cycles.tick(node.cycles.next_tick())
        assert node.state_stamp == pytest.approx(plant.t)
        np.testing.assert_allclose(node.core.target.value[:3], [0.05, 0.0, 0.0])
    with controller() as (node, _plant):  # use_sim_time: the simulated clock's timer
        timer = node.cycles.timer
        node.cycle_on_loop_ticks()
        assert math.isinf(node.cycles.next_tick()) and timer in node.timers
        assert len(list(node.subscriptions)) == len(node._subscriptions)


def test_the_guard_takes_the_echoes_waiting_before_it_judges_the_monitor() -> None:
    """The watchdog's check of the monitor sees the echoes that came while no tick ran.

    With the loop ticking the cycles, the monitor's echoes wait in their queue for the
    next tick. After a stall of the controller's process, the executor can run the
    watchdog's timer before that tick; its check must take them first, or it counts a
    monitor that answered as silent and the guard commands the plant beside it.
    """
    with controller(EventsExecutor, use_sim_time=False, control_rate=250.0) as (node, plant):
        node.cycle_on_loop_ticks()
        echo = plant.node.create_publisher(JointState, "ft/command_echo", qos.RELIABLE)
        assert spin_until(plant.executor, lambda: echo.get_subscription_count() == 1, 10.0)
        plant.t_ns = node.now_ns()
        plant.publish_state()

        def command_answered() -> None:
            """A tick (its command goes out), and the monitor's echo of that command."""
            sent = len(plant.commands)
            node.cycles.tick(node.cycles.next_tick())
            assert spin_until(plant.executor, lambda: len(plant.commands) > sent, 5.0)
            last = plant.commands[-1]
            echo.publish(JointState(header=last.header, name=last.name, velocity=last.velocity))

        command_answered()
        time.sleep(0.02)  # the echo on its way
        command_answered()  # the tick takes the first echo: a monitor known to answer
        assert node._watch.guard.last_echo is not None
        timeout = node.get_parameter("monitor_timeout").value
        start = time.monotonic()
        while time.monotonic() - start < 2 * timeout:  # no tick; the watchdog's checks
            time.sleep(timeout / 4)
            node._check_watchdog()
            assert "monitor" not in node.problems.active, "the guard fired on an answer"
