"""controller_node: fault-tolerant redundancy resolution as a ROS 2 node.

Joint states plus an end-effector target (twist or pose) in, joint velocities out: one
`ft_core.controller.Controller.step` per cycle at `control_rate`, run by a
`ft_msgs_py.loop.CycleDriver` (an rclpy timer, the joint states in ft-stack, or the
process loop's ticks in its own process). The node wires: parameters
(`ft_controller.settings`), inputs (`ft_controller.inputs`, the locked set and the joints'
health through `ft_controller.monitor_watch`), outputs (`ft_controller.outputs`) and diagnostics
(`ft_controller.loaded`); the per-cycle logic, staleness included, is the core's. With no
usable state or target it commands zeros on a ramp within the arm's limits, as it does
on shutdown and, from its steady watchdog, when no cycle runs for `state_timeout`.
Topics, parameters and reactions: docs/controller.md.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from ft_core import robots, selfmotion
from ft_core.controller import Controller
from ft_core.engine import CycleResult, check_config
from ft_core.robots import Robot, RobotModelError
from ft_msgs_py import (
    diagnostics,
    markers,
    names,
    parameter_table,
    parameters,
    publishers,
    qos,
    spin,
)
from ft_msgs_py.loop import CycleDriver, LoopAccounting
from ft_msgs_py.node import JointStateLike, StateListener, StateReading, SuiteNode
from geometry_msgs.msg import PoseStamped, TwistStamped
from rclpy.clock import Clock, ClockType
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from ft_controller import inputs, settings
from ft_controller import loaded as report
from ft_controller.loaded import Loaded
from ft_controller.monitor_watch import MonitorWatch
from ft_controller.outputs import CommandTaker, Outputs
from ft_controller.settings import PARAMETERS

#: Diagnostics period (s).
DIAGNOSTICS_PERIOD = 0.5
#: Period (s, steady time) of the watchdog that publishes zeros when no cycle runs.
WATCHDOG_PERIOD = 0.05


class ControllerNode(SuiteNode):
    """The controller; see the module docstring."""

    def __init__(self, background: ProcessPoolExecutor | None = None, **kwargs):
        """`background`: the worker pool of its `Controller`s (None: each starts its own)."""
        super().__init__("controller", **kwargs)
        self._shared_background = background
        parameter_table.declare(self, PARAMETERS)
        self.scheduling = self.apply_thread_priority()  #: reported in diagnostics
        self.loaded: Loaded | None = None  #: the model and its core, once adopted
        self._q: np.ndarray | None = None  # the latest accepted joint state (rad)
        self._health: DiagnosticArray | None = None  # the latest ft/joint_health (latched)
        self.last_command: np.ndarray | None = None  #: rad/s, chain order (harnesses)
        self.accounting = LoopAccounting(1.0 / self.param("control_rate"),
                                         count_missed=not self.param("use_sim_time"))
        self.accounting.rate(self.now())
        self.outputs = Outputs(self)
        self._targets = inputs.Targets(self.problems)
        self._watch = MonitorWatch(self.param("monitor_timeout"), self.get_logger(), self.problems,
                                   self.now_ns)
        self._echo_subscription = self.subscribe_joint_states(
            names.COMMAND_ECHO, self._on_echo, qos.SENSOR_INPUT)
        #: Takes the echoes waiting, where the loop's ticks take them (else the executor
        #: hands them over as they come): before the guard asks how long the monitor is quiet.
        self._take_echoes: Callable[[], None] = lambda: None
        self._state_subscription = self.subscribe_joint_states(
            names.JOINT_STATES, self._on_state, qos.SENSOR_INPUT)
        self._target_subscriptions = (
            self.create_subscription(TwistStamped, names.TARGET_TWIST, self._on_twist,
                                     qos.RELIABLE),
            self.create_subscription(PoseStamped, names.TARGET_POSE, self._on_pose, qos.RELIABLE))
        self.create_subscription(JointState, names.LOCKED_JOINTS, self._on_locked, qos.LATCHED)
        self.create_subscription(DiagnosticArray, names.JOINT_HEALTH, self._on_health,
                                 qos.LATCHED)
        parameter_table.on_change(self, PARAMETERS, self._check, self._apply)
        parameters.request_model(self, self._set_model)  # says so (INFO) if it waits
        self.cycles = CycleDriver(self, self.update, 1.0 / self.param("control_rate"))
        self.create_timer(DIAGNOSTICS_PERIOD, self._publish_diagnostics)
        self.create_timer(markers.PERIOD, self._publish_markers)
        self.create_service(Trigger, names.OPTIMIZE_START, self._on_optimize_start)
        # On steady time: with use_sim_time and no /clock no cycle runs, and the plant
        # must still get explicit zeros.
        self._last_cycle, self._cycled = time.monotonic(), False
        self.create_timer(WATCHDOG_PERIOD, self._check_watchdog,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))

    # ------------------------------------------------------- model, parameters
    def _set_model(self, spec: str, source: str) -> None:
        try:
            robot = robots.load(spec, *parameters.chain_arguments(self))
            order = parameters.joint_order(self, robot.joint_names)
            values = parameter_table.values(self, PARAMETERS)
            core = Controller(robot, settings.engine_config(values, order),
                              settings.controller_config(values, order),
                              (spec, parameters.chain_arguments(self)),
                              report=self.problems.report, log=self.get_logger().info,
                              background=self._shared_background)
        except (RobotModelError, ValueError) as error:
            self.problems.report("model", f"cannot use the model from {source}: {error}")
            return
        if self.loaded is not None:
            self.loaded.core.close()
        core.start_worker()
        self.loaded = loaded = Loaded(robot, core, order)
        if self._health is not None:  # latched before the model came: its core adapts too
            self._on_health(self._health)
        if self.param("critical_points"):
            core.set_critical_points(self.param("critical_points"))
        self.problems.report("model", None)
        self.get_logger().info(
            f"model from {source}: {robot.name}, {robot.base_link} -> {robot.tip_link}, "
            f"{robot.task_space} task, joints {loaded.joints}")

    def _check(self, values: dict) -> None:
        """Raise ValueError where the core would refuse the parameters' `values`."""
        order = None if self.loaded is None else self.loaded.order
        settings.controller_config(values, order)
        if self.loaded is not None:
            check_config(self.robot, settings.engine_config(values, order))
            selfmotion.targets_from_flat(self.robot, values["critical_points"] or [])

    def _apply(self, changed: set[str]) -> None:
        self._watch.guard.timeout = self.param("monitor_timeout")
        if "control_rate" in changed:
            self.accounting.period = 1.0 / self.param("control_rate")
            self.cycles.set_period(self.accounting.period)
        if self.loaded is not None:
            values, order = parameter_table.values(self, PARAMETERS), self.loaded.order
            self.core.configure(settings.engine_config(values, order),
                                settings.controller_config(values, order))
            if "critical_points" in changed:
                self.core.set_critical_points(self.param("critical_points") or [])

    # ------------------------------------------- what it holds (harnesses, tests)
    @property
    def robot(self) -> Robot | None:
        """The model in use, None until one is adopted."""
        return None if self.loaded is None else self.loaded.robot

    @property
    def core(self) -> Controller | None:
        """The per-cycle logic, None until a model is adopted."""
        return None if self.loaded is None else self.loaded.core

    @property
    def command_joints(self) -> list[str]:
        """Joint names in command order (empty before a model)."""
        return [] if self.loaded is None else self.loaded.joints

    @property
    def locked_joints(self) -> list[str]:
        """The joints the monitor announced locked (empty before a model)."""
        return [] if self.loaded is None else self.loaded.names(self.loaded.core.locked)

    @property
    def last_metrics(self) -> dict[str, float]:
        """The last cycle's `ft/metrics` by label (`Loaded.last_metrics`; empty before any)."""
        return {} if self.loaded is None else self.loaded.last_metrics

    def destroy_node(self) -> None:
        """Stop the background work too."""
        if self.core is not None:
            self.core.close()
        super().destroy_node()

    def _on_optimize_start(self, _request: Trigger.Request, response: Trigger.Response,
                           ) -> Trigger.Response:
        """`~/optimize_start` (`Controller.optimize_start`): refused with the reason, or begun."""
        reason = "no robot model yet" if self.core is None else self.core.optimize_start(
            self._q, self.now())
        response.success = reason is None
        response.message = reason or self.core.start_phase.note
        return response

    def _publish_markers(self) -> None:
        if self.loaded is not None and self._q is not None:
            self.outputs.send_view(self.loaded, self._q, self.param("critical_points") or [],
                                   self.get_clock().now().to_msg())

    # ------------------------------------------------------- one-process wiring
    def hand_commands_to(self, take: CommandTaker) -> None:
        """Every command to `take` as a call (`Outputs.taker`), without the guard (ft-stack)."""
        self.outputs.taker = take
        self.destroy_subscription(self._echo_subscription)
        self.destroy_publisher(self.outputs.guard)

    def cycle_on_joint_states(self) -> None:
        """Cycles on the joint states handed over (ft-stack); with `use_sim_time`, the timer's."""
        if not self.param("use_sim_time"):
            self.cycles.drive_by_states()

    def cycle_on_loop_ticks(self) -> None:
        """Cycles on the loop's ticks, inputs taken first; with `use_sim_time`, the timer's."""
        if not self.param("use_sim_time"):
            self._take_echoes = self.take_on_demand(self._echo_subscription)
            self.cycles.drive_by_loop([
                self.take_on_demand(self._state_subscription), self._take_echoes,
                *(self.take_on_demand(subscription) for subscription in
                  self._target_subscriptions)])

    def use_shared_joint_states(self) -> StateListener:
        """Stop taking `joint_states`; returns what to call with each one and its reading."""
        self.destroy_subscription(self._state_subscription)
        return self._on_shared_state

    # ------------------------------------------------------------------ inputs
    def _on_state(self, msg: JointStateLike) -> None:
        if self.loaded is not None:
            self._q = self.read_joint_state(msg, self.loaded.robot.joint_names)

    def _on_shared_state(self, msg: JointStateLike, reading: StateReading | None) -> None:
        if reading is None or self.loaded is None or reading[1] != self.robot.joint_names:
            self._on_state(msg)
        else:
            self._q = self.accept_joint_state(reading[0], reading[2])
        self.cycles.state_arrived(self.now_ns())

    def _on_twist(self, msg: TwistStamped) -> None:
        self._targets.on_twist(msg, self.loaded, self.now())

    def _on_pose(self, msg: PoseStamped) -> None:
        self._targets.on_pose(msg, self.loaded, self.now())

    def _on_locked(self, msg: JointState) -> None:
        if self.loaded is not None:
            self._watch.on_locked(msg, *self._graph(names.LOCKED_JOINTS), self.loaded)

    def _on_health(self, msg: DiagnosticArray) -> None:
        self._health = msg
        if self.loaded is not None:
            self._watch.on_health(msg, *self._graph(names.JOINT_HEALTH), self.loaded)

    def _graph(self, topic: str) -> tuple[list[str], str | None]:
        """(full names of the topic's publishers, the monitor's full name or None: any)."""
        graph = self.get_publishers_info_by_topic(self.resolve_topic_name(topic))
        monitor = self.param("monitor_name")
        return ([publishers.full_name(p.node_namespace, p.node_name) for p in graph],
                publishers.expected(monitor, self.get_namespace()) if monitor else None)

    def _on_echo(self, msg: JointStateLike) -> None:
        self._watch.on_echo(msg, self.loaded)

    # ------------------------------------------------------------------- cycle
    def update(self, nanoseconds: int | None = None) -> None:
        """One control cycle at the node clock's `nanoseconds` (default now)."""
        self.stop_ramp()
        self._last_cycle, self._cycled = time.monotonic(), True
        nanoseconds = self.now_ns() if nanoseconds is None else nanoseconds
        self.cycles.ran(nanoseconds)
        self.accounting.start()
        try:
            self._control(nanoseconds)
            self._check_monitor()
        finally:
            self.accounting.end()

    def _control(self, nanoseconds: int | None = None) -> None:
        loaded = self.loaded
        if loaded is None:
            return
        nanoseconds = self.now_ns() if nanoseconds is None else nanoseconds
        now = nanoseconds * 1e-9
        step = loaded.core.step(self._q, now - self.state_stamp, now)
        for kind, problem in step.problems.items():
            self.problems.report(kind, problem)
        self._publish(step.qd, nanoseconds, step.result)
        if step.new_suspect:
            self.get_logger().warning(loaded.suspect_message(step.suspect),
                                      throttle_duration_sec=5.0)
        if step.announce:
            self.outputs.send_suspect(loaded.robot.joint_names[step.suspect], nanoseconds)

    def _publish(self, qd_chain: np.ndarray, nanoseconds: int | None = None,
                 result: CycleResult | None = None) -> None:
        """The command (chain order) stamped `nanoseconds` (default now); a result's metrics."""
        nanoseconds = self.now_ns() if nanoseconds is None else nanoseconds
        self.last_command = qd_chain
        sent = self.outputs.send(self.loaded, qd_chain, nanoseconds)
        if sent is not None:
            self._watch.guard.sent(sent[0], time.monotonic(), sent[1])
        if result is not None:
            self.loaded.last_result = result
            self.outputs.send_metrics(self.loaded, result)

    def _check_monitor(self) -> None:
        """The guard of a dead monitor (`MonitorWatch.check`), unless it is in-process.

        The echoes that came are taken first: the watchdog's timer asks too, and after a
        stall of this process it may run before the loop's next tick would take them.
        """
        if self.outputs.taker is None:
            self._take_echoes()
            stop = self._watch.check(self.loaded)
            if stop is not None:
                self.outputs.send_to_plant(*stop)

    def _check_watchdog(self) -> None:
        """Zeros while no cycle has run for `state_timeout` (steady s); the monitor's guard."""
        self._check_monitor()
        self.cycles.watch(self.now_ns())
        silent = time.monotonic() - self._last_cycle
        if silent <= max(self.param("state_timeout"), 2.0 / self.param("control_rate")):
            self.problems.report("control loop", None)
            return
        if not self._cycled:  # waiting, no fault: said once at INFO
            self.get_logger().info("waiting for the first control cycle (with use_sim_time: "
                                   "for /clock): commanding zeros", once=True)
        else:
            self.problems.report("control loop", f"no control cycle for {silent:.2f} s (is /clock "
                                 "published with use_sim_time?): commanding zeros")
        if self.loaded is not None and not self._ramp_step(self.now_ns()):
            self.ramp(self._ramp_step)

    def _ramp_step(self, nanoseconds: int) -> bool:
        """The next command of a stop ramp, stamped `nanoseconds`; whether it is at rest."""
        core = self.loaded.core
        self._publish(core.smooth(np.zeros(self.loaded.robot.n), nanoseconds * 1e-9), nanoseconds)
        return core.smoother is None or core.smoother.at_rest

    def stop(self) -> None:
        """Bring the commands to rest on a ramp within the limits (used on shutdown)."""
        if self.core is not None:
            smoother = self.core.smoother
            self.ramp_now(self._ramp_step, 0.1 + (smoother.stop_time() if smoother else 0.0))

    # ------------------------------------------------------------- diagnostics
    def _publish_diagnostics(self) -> None:
        now = self.now()
        values = {"mode": self.param("resolution"), "loop_rate_hz": self.accounting.rate(now),
                  "control_rate_hz": self.param("control_rate"), "scheduling": self.scheduling,
                  **report.loop_values(self.accounting),
                  "state_age_s": now - self.state_stamp if self._q is not None else "none",
                  **report.core_values(self.loaded, now)}
        self.outputs.diagnostics.publish(diagnostics.array(
            report.statuses(self.loaded, self.status, values, self.problems),
            self.get_clock().now().to_msg()))


def main(args: list[str] | None = None) -> None:
    """Run the controller until SIGINT, then command zero velocity and exit.

    Its cycles are ticked by the process's loop (`ControllerNode.cycle_on_loop_ticks`).
    """
    spin.run_node(_ticked_by_the_loop, args)


def _ticked_by_the_loop() -> ControllerNode:
    node = ControllerNode()
    node.cycle_on_loop_ticks()
    return node


if __name__ == "__main__":
    main()
