"""ft-stack's wiring in one process: the controller and the monitor connected by calls."""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable

import numpy as np
import rclpy
import yaml
from ft_controller.controller_node import ControllerNode
from ft_monitor.monitor_node import MonitorNode
from ft_msgs_py import convert, names, qos
from ft_msgs_py.spin import harness_node, spin_until
from ft_sim import stack
from ft_sim.sim_node import SimNode
from geometry_msgs.msg import TwistStamped
from paths import REPO
from rclpy.context import Context
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from rclpy.utilities import remove_ros_args
from rosutil import fresh_domain, ros_context
from sensor_msgs.msg import JointState

START = [0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]


def test_composed_nodes_exchange_commands_and_states_by_call() -> None:
    with tempfile.TemporaryDirectory() as state, ros_context() as (context, executor):
        sim = SimNode.stepped_by_hand(context, {"robot_model": "panda", "rate": 250.0,
                                                "initial_positions": START})
        common = {"robot_model": "panda", "task_space": "position", "use_sim_time": True}
        controller = ControllerNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in {**common, "state_timeout": 60.0}.items()])
        monitor = MonitorNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in {**common, "state_directory": state,
                                               "command_timeout": 60.0}.items()])
        stack.compose(controller, monitor)
        probe = harness_node("probe", context)
        for node in (sim, controller, monitor, probe):
            executor.add_node(node)
        # Neither node takes these topics from the middleware any more (the graph first
        # shows the entities made before and after those that are gone).
        assert spin_until(executor, lambda: controller.count_publishers(names.COMMAND_RAW) == 1
                          and controller.count_subscribers(names.COMMAND) == 1, 30.0)
        assert controller.count_subscribers(names.COMMAND_RAW) == 0
        assert controller.count_subscribers(names.COMMAND_ECHO) == 0  # no guard needed
        assert controller.count_subscribers(names.JOINT_STATES) == 1  # the monitor's
        outputs: list[JointState] = []
        probe.create_subscription(JointState, names.COMMAND, outputs.append, qos.SENSOR_INPUT)
        twist = probe.create_publisher(TwistStamped, names.TARGET_TWIST, qos.RELIABLE)
        msg = TwistStamped()
        msg.twist.linear.x = 0.05
        start = None
        for _ in range(100):
            msg.header.stamp = convert.stamp_from_nanoseconds(round(sim.t * 1e9))
            twist.publish(msg)
            sim.advance(executor)
            if start is None:
                start = controller.robot.forward(np.array(sim.q))
        # The monitor filtered the controller's commands (its detector has them), and the
        # arm moved along x: commands reached the plant through the monitor's ft/command.
        assert monitor.core.detector.history.last_time > 0.0
        assert outputs and any(np.any(np.asarray(m.velocity)) for m in outputs)
        moved = controller.robot.forward(np.array(sim.q)) - start
        assert moved[0] > 0.01 and abs(moved[1]) < 0.2 * moved[0], moved
        # ft/command_raw goes out again once someone else listens.
        raw: list[JointState] = []
        probe.create_subscription(JointState, names.COMMAND_RAW, raw.append, qos.SENSOR_INPUT)
        assert spin_until(executor, lambda: controller.outputs.command.get_subscription_count()
                          == 1, 10.0), "the probe's subscription was never matched"
        for _ in range(5):
            sim.advance(executor)
        assert raw, "no ft/command_raw although someone subscribes"


def test_a_command_by_call_for_another_chain_goes_by_name() -> None:
    with tempfile.TemporaryDirectory() as state, ros_context() as (context, _executor):
        monitor = MonitorNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in {"robot_model": "panda", "state_directory": state,
                                               "command_timeout": 60.0,
                                               # the filter's own output, as given
                                               "smooth_commands": False}.items()])
        take = monitor.take_commands_by_call()
        assert monitor.core is not None
        joints = monitor.core.robot.joint_names
        qd = np.linspace(0.1, 0.7, len(joints))
        sent = []
        for order in (slice(None), slice(None, None, -1)):  # the model's chain, then reversed
            now = monitor.now() + 0.01 * len(sent)
            take(qd[order], joints[order], convert.stamp_from_nanoseconds(round(now * 1e9)), now)
            history = monitor.core.detector.history
            sent.append((history.last_time, history.values[history.end - 1].copy()))
        assert sent[1][0] > sent[0][0], "the second command never reached the filter"
        np.testing.assert_allclose(sent[0][1], qd)
        np.testing.assert_allclose(sent[1][1], qd)  # by name: the same joints' velocities
        monitor.destroy_node()


def test_a_joint_state_read_by_the_monitor_is_not_parsed_again() -> None:
    """The controller takes the monitor's reading of its own chain; else the message."""
    with ros_context() as (context, _executor):
        controller = ControllerNode(context=context, parameter_overrides=[
            Parameter("robot_model", value="panda")])
        take = controller.use_shared_joint_states()
        joints = controller.robot.joint_names
        q = np.array(START)
        # An empty message with a reading of the chain: the reading is what counts.
        take(JointState(), (q, joints, 5.0))
        assert controller._q is not None, "the reading was refused"
        np.testing.assert_array_equal(controller._q, q)
        assert controller.state_stamp == 5.0 and "joint_states" not in controller.problems.active
        # A reading of another chain: the message is read, and this one lacks the joints.
        take(JointState(), (q[::-1], joints[::-1], 6.0))
        assert controller._q is None and controller.state_stamp == 5.0
        assert "lacks" in controller.problems.active["joint_states"]
        # A reading older than the last one is refused as going backwards.
        take(JointState(), (q, joints, 7.0))
        take(JointState(), (q, joints, 6.5))
        assert controller._q is None and "backwards" in controller.problems.active["joint_states"]
        controller.destroy_node()


def composed(context: Context, state: str, common: dict,
             ) -> tuple[ControllerNode, MonitorNode, Callable[[bytes], None]]:
    """A controller and a monitor with `common` parameters, composed as in ft-stack.

    Also the monitor's `joint_states` callback, to hand it bytes without an executor.
    """
    controller = ControllerNode(context=context, parameter_overrides=[
        Parameter(k, value=v) for k, v in common.items()])
    monitor = MonitorNode(context=context, parameter_overrides=[
        Parameter(k, value=v) for k, v in {**common, "state_directory": state}.items()])
    stack.compose(controller, monitor)
    take = next(s.callback for s in monitor.subscriptions
                if s.topic_name == "/" + names.JOINT_STATES)
    return controller, monitor, take

def test_each_joint_state_runs_a_cycle_after_the_monitor_observed_it() -> None:
    """ft-stack cycles on joint states: at once, after the monitor, one a control period.

    The control timer is off meanwhile. When the states stop, the steady watchdog starts
    it again and it cycles: zeros once they are stale.
    """
    with tempfile.TemporaryDirectory() as state, ros_context() as (context, executor):
        controller, monitor, take = composed(context, state, {
            "robot_model": "panda", "task_space": "position", "control_rate": 10.0})
        calls: list[str] = []
        observe, step = monitor.core.observe, controller.core.step
        monitor.core.observe = lambda *a: calls.append("observe") or observe(*a)
        controller.core.step = lambda *a: calls.append("step") or step(*a)
        joints = controller.robot.joint_names

        def state() -> bytes:
            stamp = convert.stamp_from_nanoseconds(controller.now_ns())
            return serialize_message(convert.joint_state(joints, stamp, position=START))

        cycles = controller.accounting.cycles
        assert not controller.cycles.timer.is_canceled()  # no state yet: the timer cycles
        take(state())  # no executor spins: the call itself runs the cycle
        assert calls == ["observe", "step"], calls
        assert controller.accounting.cycles == cycles + 1
        assert controller.cycles.timer.is_canceled(), "the timer ticks while the states drive"
        # Back to back within a quarter of the control period (0.1 s): no more cycles,
        # the next one a control period after the first.
        for _ in range(4):
            take(state())
        assert controller.accounting.cycles == cycles + 1, controller.accounting.cycles
        assert calls.count("observe") == 5, "the monitor missed states"
        time.sleep(0.1)
        take(state())
        assert controller.accounting.cycles == cycles + 2, controller.accounting.cycles
        # The states stop: the control timer cycles, and commands zeros once they are stale.
        executor.add_node(controller)
        executor.add_node(monitor)
        before = controller.accounting.cycles
        assert spin_until(executor, lambda: controller.accounting.cycles >= before + 3, 10.0), \
            "no cycle from the control timer after the states stopped"
        assert "joint_states" in controller.problems.active
        assert not np.any(controller.last_command), controller.last_command
        controller.destroy_node()
        monitor.destroy_node()


def test_with_simulated_time_the_clock_still_drives_the_cycles() -> None:
    """A state may come before the /clock of its instant: the timer ticks as before."""
    with tempfile.TemporaryDirectory() as state, ros_context() as (context, _executor):
        controller, monitor, take = composed(context, state, {"robot_model": "panda",
                                                              "use_sim_time": True})
        observed = monitor.core.detector.latest_time
        stamp = convert.stamp_from_nanoseconds(1_000_000)
        take(serialize_message(convert.joint_state(controller.robot.joint_names, stamp,
                                                   position=START)))
        assert monitor.core.detector.latest_time > observed, "the monitor never took the state"
        assert controller.accounting.cycles == 0
        period = round(1e9 / controller.param("control_rate"))
        assert controller.cycles.timer.timer_period_ns == period
        controller.destroy_node()
        monitor.destroy_node()


def test_the_stack_starts_on_the_task_of_the_shipped_parameters(tmp_path) -> None:
    """`ros2 run ft_sim stack` takes controller.yaml's task space, as the launch files do.

    A parameters file or `-p` on the command line overrides it; the stack's own options
    stay its own.
    """
    shipped = REPO / "ros_ws" / "src" / "ft_controller" / "config" / "controller.yaml"
    task_space = yaml.safe_load(shipped.read_text())["/**"]["ros__parameters"]["task_space"]
    assert task_space == "position"
    own = tmp_path / "arm.yaml"
    own.write_text("/**:\n  ros__parameters:\n    task_space: planar\n")
    for given, expected in (([], task_space), (["--ros-args", "-p", "task_space:=pose"], "pose"),
                            (["--ros-args", "--params-file", str(own)], "planar")):
        argv = stack.shipped_defaults(["ft-stack", "--sim", *given])
        assert remove_ros_args(args=argv) == ["ft-stack", "--sim"]
        context = Context()
        rclpy.init(args=argv, context=context, domain_id=fresh_domain())
        try:
            node = SimNode(context=context)
            assert node.get_parameter("task_space").value == expected, given
            node.destroy_node()
        finally:
            rclpy.shutdown(context=context)
