"""controller_node: fault-tolerant redundancy resolution as a ROS 2 node.

Joint states plus an end-effector target (twist or pose) in, joint velocities out:
one `ft_core.controller.Controller.step` per tick at `control_rate` (an rclpy timer's,
or in its own process the process loop's: `cycle_on_loop_ticks`). The node
is wiring: parameters, message conversion, the watchdog, publishing and diagnostics;
the per-cycle logic is the core's. Topics, parameters and reactions are listed in
docs/controller.md.

Safety: with no model, no joint state yet, a stale state (older than
`state_timeout`), missing joints, non-finite values, stamps in the future or going
backwards, or a state or target the engine refuses as physically absurd (a joint
far outside its limits, a task speed beyond 1000 m/s or rad/s), the node publishes
zeros (a velocity controller holds its last command), reached on a ramp within the
arm's acceleration and jerk limits as every command (`ft_core.smoothing`), and an ERROR
diagnostic, and resumes by itself when good data returns. Each kind of problem is
logged once per episode. On shutdown it brings the commands to rest on that ramp
before leaving; with no control cycle for `state_timeout` the watchdog does
(`SuiteNode.ramp`), and so does the guard of a dead monitor on the plant's topics, from
the monitor's last command.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from ft_core import limits, robots, selfmotion
from ft_core.controller import Controller
from ft_core.engine import RESOLUTIONS, Status, check_config
from ft_core.robots import Robot, RobotModelError
from ft_core.targets import goal_from_transform, twist_velocity
from ft_msgs_py import (
    convert,
    diagnostics,
    markers,
    metrics,
    names,
    parameters,
    publishers,
    qos,
    spin,
    wire,
)
from ft_msgs_py.loop import LoopAccounting, StateSchedule
from ft_msgs_py.monitor_guard import MonitorGuard
from ft_msgs_py.node import JointStateLike, StateListener, StateReading, SuiteNode
from geometry_msgs.msg import PoseStamped, TwistStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.parameter import Parameter
from rclpy.timer import Timer
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, Header
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from ft_controller import settings
from ft_controller.settings import PARAMETERS

#: Diagnostics period (s).
DIAGNOSTICS_PERIOD = 0.5
#: Period (s, steady time) of the watchdog that publishes zeros when no cycle runs.
WATCHDOG_PERIOD = 0.05
#: Period (s) of the control timer while joint states drive the cycles
#: (`cycle_on_joint_states`), or the control period if longer. It runs only while they
#: have stopped: the steady watchdog starts it again (within `WATCHDOG_PERIOD`).
STATE_WAIT = 0.01
#: What takes each command by a call (`hand_commands_to`): (velocities in rad/s, the
#: joints they are for, the stamp, the node clock's time in s).
CommandTaker = Callable[[np.ndarray, Sequence[str], wire.Stamp, float], None]

class ControllerNode(SuiteNode):
    """The controller; see the module docstring."""

    def __init__(self, background: ProcessPoolExecutor | None = None, **kwargs):
        """`background`: the worker pool of its `Controller`s (None: each starts its own)."""
        super().__init__("controller", **kwargs)
        self._shared_background = background
        parameters.declare(self, PARAMETERS)
        self.scheduling = self.apply_thread_priority()  #: reported in diagnostics
        self.robot: Robot | None = None
        self.core: Controller | None = None  #: the per-cycle logic, once a model is loaded
        self._order: np.ndarray | None = None  # command index -> chain index
        self.command_joints: list[str] = []  #: joint names in command order
        self._labels: list[str] = []
        # Built once per model, refilled each cycle (`_publish`).
        self._command_writer = wire.CommandWriter([])
        self._metrics_msg = Float64MultiArray()
        self._last_result = None  # the last cycle's engine result (its metrics)
        self._q: np.ndarray | None = None
        #: The last command published (rad/s, chain order), for in-process harnesses.
        self.last_command: np.ndarray | None = None
        self.accounting = LoopAccounting(1.0 / self.param("control_rate"),
                                         count_missed=not self.param("use_sim_time"))
        self._rate_window = (0, self.now())
        self._rate = 0.0

        self._command_pub, self._command_audience = self.create_counted_publisher(
            JointState, names.COMMAND_RAW, qos.RELIABLE)
        # The plant's own topics, for the guard's zeros when the monitor is gone.
        self._guard = MonitorGuard(self.param("monitor_timeout"))
        #: The guard's stop while the monitor does not answer (`Controller.stopper`; None:
        #: it answers): the next command (chain order) for a time (s).
        self._guard_stop: Callable[[float], np.ndarray] | None = None
        #: A locked set heard while a stranger publishes too: its new locks wait for the
        #: monitor's echoes to show them (`_take_corroborated`).
        self._contested: set[str] = set()
        self._plant_pub = self.create_publisher(JointState, names.COMMAND, qos.RELIABLE)
        self._plant_array_pub = self.create_publisher(Float64MultiArray, names.COMMAND_ARRAY,
                                                      qos.RELIABLE)
        self._echo_subscription = self.subscribe_joint_states(
            names.COMMAND_ECHO, self._on_echo, qos.SENSOR_INPUT)
        self._metrics_pub, self._metrics_audience = self.create_counted_publisher(
            Float64MultiArray, names.METRICS, qos.RELIABLE)
        self._suspect_pub = self.create_publisher(JointState, names.SUSPECTED_FAILURE,
                                                  qos.RELIABLE)
        self._diagnostics_pub = self.create_publisher(DiagnosticArray, names.DIAGNOSTICS,
                                                      qos.RELIABLE)
        self._markers_pub = self.create_publisher(MarkerArray, names.MARKERS, qos.RELIABLE)
        self._state_subscription = self.subscribe_joint_states(
            names.JOINT_STATES, self._on_state, qos.SENSOR_INPUT)
        #: Takes each command as a call (`hand_commands_to`; ft-stack), or None.
        self._command_taker: CommandTaker | None = None
        self._target_subscriptions = (
            self.create_subscription(TwistStamped, names.TARGET_TWIST, self._on_twist,
                                     qos.RELIABLE),
            self.create_subscription(PoseStamped, names.TARGET_POSE, self._on_pose, qos.RELIABLE))
        self.create_subscription(JointState, names.LOCKED_JOINTS, self._on_locked, qos.LATCHED)
        self.add_on_set_parameters_callback(self._validate)
        self.add_post_set_parameters_callback(self._apply)
        self._load_model()
        self._timer = self._control_timer(states_drive=False)
        #: Steady time (s) of the next tick where the process's loop ticks the cycles
        #: (`cycle_on_loop_ticks`; their period is the accounting's), else inf.
        self._next_tick = math.inf
        #: Where the loop ticks the cycles: what takes the cycle's inputs at each tick.
        self._take_inputs: list[Callable[[], None]] = []
        self.create_timer(DIAGNOSTICS_PERIOD, self._publish_diagnostics)
        self.create_timer(markers.PERIOD, self._publish_markers)
        self.create_service(Trigger, names.OPTIMIZE_START, self._on_optimize_start)
        # The watchdog runs on steady time: with use_sim_time and no /clock the control
        # timer never fires, and the plant must still get explicit zeros.
        self._last_cycle = time.monotonic()
        self._cycled = False  # no control cycle yet: with use_sim_time, no /clock yet
        self.create_timer(WATCHDOG_PERIOD, self._check_watchdog,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))

    # ------------------------------------------------------------------- model
    def _load_model(self) -> None:
        parameters.request_model(self, self._set_model)  # says so (INFO) if it waits

    def _set_model(self, spec: str, source: str) -> None:
        try:
            robot = robots.load(spec, *parameters.chain_arguments(self))
            order = parameters.joint_order(self, robot.joint_names)
            values = self._values({})
            core = Controller(robot, settings.engine_config(values, order),
                              settings.controller_config(values, order),
                              (spec, parameters.chain_arguments(self)),
                              report=self.problems.report, log=self.get_logger().info,
                              background=self._shared_background)
        except (RobotModelError, ValueError) as error:
            self.problems.report("model", f"cannot use the model from {source}: {error}")
            return
        if self.core is not None:
            self.core.close()
        core.start_worker()
        self.robot, self._order, self.core = robot, order, core
        self.command_joints = [robot.joint_names[i] for i in order]
        self._labels = metrics.labels(self.command_joints)
        self._command_writer = wire.CommandWriter(self.command_joints)
        self._metrics_msg = metrics.template(self._labels)
        self._last_result = None
        if self.param("critical_points"):
            core.set_critical_points(self.param("critical_points"))
        self.problems.report("model", None)
        self.get_logger().info(
            f"model from {source}: {robot.name}, {robot.base_link} -> {robot.tip_link}, "
            f"{robot.task_space} task, joints {self.command_joints}")

    def _values(self, changes: dict) -> dict:
        """Every parameter's value, pending `changes` (name -> value) in place of the current."""
        return {name: changes.get(name, self.param(name)) for name in PARAMETERS}

    # -------------------------------------------------------------- parameters
    def _validate(self, params: list[Parameter]) -> SetParametersResult:
        changes = {p.name: p.value for p in params}
        try:
            parameters.check_sizes(changes)
            if "resolution" in changes and changes["resolution"] not in RESOLUTIONS:
                raise ValueError(f"resolution must be one of {RESOLUTIONS}")
            values = self._values(changes)
            settings.controller_config(values, self._order)
            if self.robot is not None:
                check_config(self.robot, settings.engine_config(values, self._order))
                if "critical_points" in changes:
                    selfmotion.targets_from_flat(self.robot, changes["critical_points"] or [])
        except (ValueError, TypeError) as error:
            return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    def _apply(self, parameters: list[Parameter]) -> None:
        changed = {p.name for p in parameters}
        self._guard.timeout = self.param("monitor_timeout")
        if "control_rate" in changed:
            self.accounting.period = 1.0 / self.param("control_rate")
            if math.isfinite(self._next_tick):  # the loop ticks the cycles
                self._next_tick = time.monotonic() + self.accounting.period
            else:
                self._timer.cancel()
                self.destroy_timer(self._timer)
                self._timer = self._control_timer(states_drive=self._schedule is not None)
        if self.core is None:
            return
        values = self._values({})
        self.core.configure(settings.engine_config(values, self._order),
                            settings.controller_config(values, self._order))
        if "critical_points" in changed:
            self.core.set_critical_points(self.param("critical_points") or [])

    @property
    def last_metrics(self) -> dict[str, float]:
        """The last cycle's `ft/metrics`, by label, published or not (empty before any)."""
        if self._last_result is None:
            return {}
        return dict(zip(self._labels, self._metric_values(self._last_result), strict=True))

    @property
    def suspected_lock(self) -> str | None:
        """The joint the task-space channel suspects now, if any."""
        if self.core is None or self.core.suspect is None:
            return None
        return self.robot.joint_names[self.core.suspect]

    @property
    def soft_limits_note(self) -> str:
        """The soft limits in force: "none", "<k> critical points", "computing ...".

        "none (critical points failed)" when they could not be computed (the reason
        is in the diagnostics).
        """
        return "none" if self.core is None else self.core.soft_limits_note

    @property
    def locked_joints(self) -> list[str]:
        """The joints the monitor announced locked (the core holds them as indices)."""
        if self.core is None:
            return []
        return [self.robot.joint_names[j] for j in self.core.locked]

    @property
    def soft_limits_pending(self) -> bool:
        """Whether soft limits from the critical points are still to be computed or taken."""
        return self.core is not None and self.core.soft_limits_pending

    def destroy_node(self) -> None:
        """Stop the background work too."""
        if self.core is not None:
            self.core.close()
        super().destroy_node()

    def _on_optimize_start(self, _request: Trigger.Request, response: Trigger.Response,
                           ) -> Trigger.Response:
        """`~/optimize_start`: the idle arm to its start configuration of best dexterity.

        Refused (success false, the reason) without a model or a joint state, with a
        target in force, a locked joint, or a phase under way (`Controller.optimize_start`).
        """
        reason = "no robot model yet" if self.core is None else self.core.optimize_start(
            self._q, self.now())
        response.success = reason is None
        response.message = reason or self.core.start_phase.note
        return response

    def _publish_markers(self) -> None:
        """The live view (`ft_msgs_py.markers`): goal, critical points, announced locks.

        Only while someone subscribes; off the control cycle (a timer of its own).
        """
        core, robot = self.core, self.robot
        if core is None or self._q is None or not self._markers_pub.get_subscription_count():
            return
        target = core.target
        goal = [robot.target_position(target.value)] if target and target.kind == "pose" else []
        critical = [robot.target_position(point) for point in
                    selfmotion.targets_from_flat(robot, self.param("critical_points") or [])]
        locked = robot.skeleton(self._q)[list(core.locked)]
        self._markers_pub.publish(markers.array(robot.base_link, self.get_clock().now().to_msg(),
                                                lambda header: [
            markers.spheres(header, "goal", goal, markers.GOAL),
            markers.spheres(header, "critical_points", critical, markers.CRITICAL),
            markers.spheres(header, "locked_joints", locked, markers.ANNOUNCED,
                            markers.HALO_DIAMETER)]))

    # ------------------------------------------------------- one-process wiring
    def hand_commands_to(self, take: CommandTaker) -> None:
        """Give every command to `take` as a call (the monitor's, in the same process).

        `take(qd, joints, stamp, now)`: the velocities (rad/s) of `joints` (the chain's
        names), the command's stamp and the node clock's time then (s).

        `ft/command_raw` is then published only while someone else subscribes to it. The
        guard of a dead monitor is off: the monitor dies only with this process.
        """
        self._command_taker = take
        self.destroy_subscription(self._echo_subscription)

    def cycle_on_joint_states(self) -> None:
        """Run the control cycle on each joint state taken, as ros2_control reads, then updates.

        For ft-stack, whose monitor hands this node each state after observing it: the
        command follows the freshest state at once instead of at the next tick, and the
        executor wakes once per cycle instead of twice (the timer's thread and the main
        thread; `make bench` measures the saving). At most `control_rate` cycles a second
        whatever the rate of the states (`loop.StateSchedule`: a faster stream is thinned,
        one at the control rate passes whole through 3/4 of a period of jitter). The
        control timer then runs every `STATE_WAIT` s (or control period if longer) and
        cycles only where no cycle ran for a control period: when states stop, commands
        go on as they would from the timer (zeros once the last state is older than
        `state_timeout`). While the states drive the cycles it is off: its ticks woke the
        executor between states, 6 % of ft-stack's CPU at 1 kHz (measured back to back,
        docs/benchmarks.md). The steady
        watchdog starts it again once no cycle ran for a control period, so it takes over
        within `WATCHDOG_PERIOD` + `STATE_WAIT` s of the last state.

        Not with `use_sim_time`: there the simulated clock's ticks drive the cycles as
        before, since a state can be taken before the /clock message of its instant (the
        cycle would run at the instant before; `ft_sim.scenario` steps on that clock).
        """
        if self.param("use_sim_time"):
            return
        self._timer.cancel()
        self.destroy_timer(self._timer)
        self._timer = self._control_timer(states_drive=True)

    def cycle_on_loop_ticks(self) -> None:
        """Run the control cycle on ticks of the process's loop (`spin.Ticked`), not a timer.

        For the controller as a process of its own (`main`): the same period on steady
        time, ticks missed by more than a period skipped as an rclpy timer skips them; the
        executor's timer thread, which woke the loop once per cycle besides the joint
        states, no longer runs (about 0.02 ms of CPU per cycle less at 1 kHz on a bare
        node, docs/benchmarks.md). Each tick first takes the inputs the cycle reads (joint
        states, the monitor's echoes, the targets; `SuiteNode.take_on_demand`), as they
        wait in their queues: the cycle sees the same latest messages, and they no longer
        wake the loop as they arrive (about 0.04 ms of CPU per cycle less at 1 kHz). Not
        with `use_sim_time`: there the simulated clock's timer drives the cycles, and the
        messages their callbacks.
        """
        if self.param("use_sim_time"):
            return
        self._timer.cancel()
        self.destroy_timer(self._timer)
        self._timer_runs = False
        self._next_tick = time.monotonic() + self.accounting.period
        self._take_inputs = [self.take_on_demand(subscription) for subscription in (
            self._state_subscription, self._echo_subscription, *self._target_subscriptions)]

    def next_tick(self) -> float:
        """Steady time (s) of the next loop tick (`cycle_on_loop_ticks`); inf: not so driven."""
        return self._next_tick

    def tick(self, now: float) -> None:
        """The control cycle of the loop tick due at or before `now` (steady s)."""
        period = self.accounting.period
        self._next_tick += period * (math.floor((now - self._next_tick) / period) + 1)
        for take in self._take_inputs:
            take()
        self._cycle()

    def _control_timer(self, states_drive: bool) -> Timer:
        """The control timer for the current `control_rate`, with the joint states' schedule.

        `_schedule` says when a joint state runs a cycle where states drive the cycles
        (`cycle_on_joint_states`; ft-stack); None where the timer drives them.
        """
        period = 1.0 / self.param("control_rate")
        self._schedule: StateSchedule | None = (StateSchedule(period * 1e9) if states_drive
                                                else None)
        #: whether the timer runs; where states drive the cycles, it stops at the first
        #: state-driven cycle and the watchdog starts it once the states stop (kept here,
        #: since every timer is made here, so no cycle asks rclpy's `is_canceled`)
        self._timer_runs = True
        if states_drive:
            return self.create_timer(max(period, STATE_WAIT), self._cycle_if_states_stopped)
        return self.create_timer(period, self._cycle)

    def _cycle_if_states_stopped(self) -> None:
        nanoseconds = self.now_ns()
        if self._schedule is not None and self._schedule.quiet(nanoseconds):
            self._cycle(nanoseconds)

    def use_shared_joint_states(self) -> StateListener:
        """Stop taking `joint_states` here; returns what to call with each one instead.

        The call takes the message and, where a node of the same process parsed it
        already, its reading (positions in rad, their joints, stamp in s), used when the
        joints are this model's chain; else this node reads the message itself.
        """
        self.destroy_subscription(self._state_subscription)
        return self._on_shared_state

    # ------------------------------------------------------------------ inputs
    def _on_state(self, msg: JointStateLike) -> None:
        if self.robot is not None:
            self._q = self.read_joint_state(msg, self.robot.joint_names)

    def _on_shared_state(self, msg: JointStateLike, reading: StateReading | None) -> None:
        if reading is None or self.robot is None or reading[1] != self.robot.joint_names:
            self._on_state(msg)
        else:
            self._q = self.accept_joint_state(reading[0], reading[2])
        if self._schedule is not None:
            nanoseconds = self.now_ns()
            if self._schedule.ready(nanoseconds):
                self._cycle(nanoseconds)
                if self._timer_runs:  # the states drive the cycles again
                    self._timer.cancel()
                    self._timer_runs = False

    def _frame_ok(self, frame: str, kind: str) -> bool:
        if frame in ("", self.robot.base_link):
            self.problems.report(kind, None)
            return True
        self.problems.report(kind, f"frame '{frame}' is not the base frame "
                                    f"'{self.robot.base_link}': ignored", warning=True)
        return False

    def _on_twist(self, msg: TwistStamped) -> None:
        if self.robot is None or not self._frame_ok(msg.header.frame_id, "ft/target_twist"):
            return
        stamp = self.problems.message_time("ft/target_twist", msg.header.stamp, self.now())
        try:
            twist = convert.twist_vector(msg.twist)
        except convert.MessageError as error:
            self.problems.report("ft/target_twist", str(error))
            return
        if stamp is not None:
            self.core.set_twist(twist_velocity(self.robot, twist), stamp)

    def _on_pose(self, msg: PoseStamped) -> None:
        if self.robot is None or not self._frame_ok(msg.header.frame_id, "ft/target_pose"):
            return
        try:
            transform = convert.pose_matrix(msg.pose)
            if np.max(np.abs(transform[:3, 3])) > limits.ABSURD_DISTANCE:
                raise convert.MessageError(f"goal further than {limits.ABSURD_DISTANCE:g} m: "
                                           "no arm reaches it")
            goal = goal_from_transform(self.robot, transform)
        except convert.MessageError as error:
            self.problems.report("ft/target_pose", str(error))
            return
        self.problems.report("ft/target_pose", None)
        self.core.set_pose_goal(goal, self.now())

    def _on_locked(self, msg: JointState) -> None:
        if self.robot is None:
            return
        graph = self.get_publishers_info_by_topic(self.resolve_topic_name(names.LOCKED_JOINTS))
        monitor = self.param("monitor_name")
        verdict = publishers.judge(
            [publishers.full_name(p.node_namespace, p.node_name) for p in graph],
            publishers.expected(monitor, self.get_namespace()) if monitor else None)
        self.problems.report("ft/locked_joints", verdict.problem)
        if verdict.take == "none":
            return
        try:
            locked, unknown = convert.locked_joints(msg, self.robot.joint_names)
        except convert.MessageError as error:
            self.get_logger().error(f"ft/locked_joints: {error}: ignored",
                                    throttle_duration_sec=5.0)
            return
        if unknown:
            self.get_logger().warning(f"ft/locked_joints: unknown joints {unknown} ignored",
                                      throttle_duration_sec=5.0)
        if verdict.take == "additions":  # taken as the monitor's echoes confirm it
            self._contested = set(locked)
            self._take_corroborated()
            return
        self._contested = set()
        if set(locked) != set(self.locked_joints):
            self.get_logger().warning(f"locked joints now {sorted(locked) or 'none'}")
        self.core.set_locked([self.robot.joint_names.index(name) for name in locked],
                             self.now())

    # ------------------------------------------------------------------- cycle
    def _on_echo(self, msg: JointStateLike) -> None:
        """What the monitor told the plant (`ft/command_echo`): its answer to a command, or not."""
        if self._guard.received((msg.header.stamp.sec, msg.header.stamp.nanosec),
                                msg.velocity):
            self._take_corroborated()

    def _take_corroborated(self) -> None:
        """Of a contested locked set, take the new locks the monitor's echoes show.

        The monitor zeros its locked joints on the command path (`ft_msgs_py.publishers`).
        """
        if not self._contested or self.robot is None:
            return
        current = set(self.locked_joints)
        shown = {self.command_joints[j] for j in self._guard.zeroed
                 if j < len(self.command_joints)}
        confirmed = (self._contested - current) & shown
        if confirmed:
            self.get_logger().warning(f"locked joints now {sorted(current | confirmed)} "
                                      "(the monitor's commands show them)")
            self.core.set_locked([self.robot.joint_names.index(name)
                                  for name in current | confirmed], self.now())
        self._contested -= confirmed

    def _check_monitor(self) -> None:
        """Zeros on the plant's topics (and an ERROR) while the monitor does not answer.

        Not where the monitor takes the commands by a call (`hand_commands_to`).
        """
        if self._command_taker is not None:
            return
        silent = self._guard.silent(time.monotonic())
        if silent is None:
            self.problems.report("monitor", None)
            self._guard_stop = None
            return
        self.problems.report("monitor", f"no answer from the monitor for {silent:.2f} s: "
                             "commanding zeros on ft/command and ft/command_array")
        if self.core is None:
            return
        nanoseconds = self.now_ns()
        if self._guard_stop is None:
            echo = self._guard.last_echo
            held = np.zeros(self.robot.n)
            if echo is not None and len(echo) == self.robot.n:
                held[self._order] = echo
            self._guard_stop = self.core.stopper(held)
        velocity = self._guard_stop(nanoseconds * 1e-9)[self._order].tolist()
        self._plant_pub.publish(convert.joint_state(
            self.command_joints, convert.stamp_from_nanoseconds(nanoseconds), velocity=velocity))
        self._plant_array_pub.publish(Float64MultiArray(data=velocity))

    def _check_watchdog(self) -> None:
        """Zeros (and an ERROR) while no control cycle has run for `state_timeout` (steady).

        Also the guard of a dead monitor (`_check_monitor`), and where joint states drive
        the cycles, the control timer started again once they stopped.
        """
        self._check_monitor()
        if (self._schedule is not None and not self._timer_runs
                and self._schedule.quiet(self.now_ns())):
            self._timer.reset()
            self._timer_runs = True
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
        if self.core is not None and not self._ramp_step(self.now_ns()):
            self.ramp(self._ramp_step)

    def _ramp_step(self, nanoseconds: int) -> bool:
        """The next command of a stop ramp, stamped `nanoseconds`; whether it is at rest."""
        self._publish(self.core.smooth(np.zeros(self.robot.n), nanoseconds * 1e-9), nanoseconds)
        return self.core.smoother is None or self.core.smoother.at_rest

    def _cycle(self, nanoseconds: int | None = None) -> None:
        """One control cycle at the node clock's `nanoseconds` (default now)."""
        self.stop_ramp()
        self._last_cycle, self._cycled = time.monotonic(), True
        nanoseconds = self.now_ns() if nanoseconds is None else nanoseconds
        if self._schedule is not None:
            self._schedule.ran(nanoseconds)
        self.accounting.start()
        try:
            self._control(nanoseconds)
            self._check_monitor()
        finally:
            self.accounting.end()

    def _control(self, nanoseconds: int | None = None) -> None:
        core = self.core
        if core is None:
            return
        nanoseconds = self.now_ns() if nanoseconds is None else nanoseconds
        now = nanoseconds * 1e-9
        step = core.step(self._q, now - self.state_stamp, now)
        for kind, problem in step.problems.items():
            self.problems.report(kind, problem)
        self._publish(step.qd, nanoseconds, step.result)
        if step.new_suspect:
            self.get_logger().warning(
                f"task error not decreasing while joints are commanded: "
                f"{self.robot.joint_names[step.suspect]}'s loss explains the motion (residual "
                f"{core.channel.residuals[step.suspect]:.2f} of the unexplained motion); "
                "suspected, for the monitor to decide", throttle_duration_sec=5.0)
        if step.announce:
            self._suspect_pub.publish(JointState(header=Header(
                stamp=convert.stamp_from_nanoseconds(nanoseconds)),
                                                 name=[self.robot.joint_names[step.suspect]]))

    def _publish(self, qd_chain: np.ndarray, nanoseconds: int | None = None,
                 result=None) -> None:
        """The command stamped `nanoseconds` (default now), with a cycle's result the metrics too.

        The command as bytes (`wire.CommandWriter`), the metrics in a preallocated
        message and only while someone subscribes to them (a recorder, a plot). With a
        taker in this process (ft-stack) the command goes to it as a call, and out on
        `ft/command_raw` only while someone else subscribes.
        """
        nanoseconds = self.now_ns() if nanoseconds is None else nanoseconds
        stamp = wire.Stamp.of(nanoseconds)
        self.last_command = qd_chain
        taker = self._command_taker
        if taker is None or self._command_audience.count:
            velocity = qd_chain[self._order]
            self._command_pub.publish(self._command_writer.serialize(*stamp, velocity))
        if taker is None:
            self._guard.sent(stamp, time.monotonic(), velocity)
        else:
            taker(qd_chain, self.robot.joint_names, stamp, nanoseconds * 1e-9)
        if result is None:
            return
        self._last_result = result
        if self._metrics_audience.count:
            metrics.fill(self._metrics_msg, self._metric_values(result))
            self._metrics_pub.publish(self._metrics_msg)

    def _metric_values(self, result) -> list[float]:
        """A cycle's `ft/metrics` values, in label order (`ft_msgs_py.metrics`)."""
        sigmas = result.post_failure_sigmas[self._order]
        return [result.kfm, result.sigma_min, result.jump_index, result.task_scale,
                result.soft_limit_margin if math.isfinite(result.soft_limit_margin)
                else metrics.NO_SOFT_BOX,
                *np.where(np.isfinite(sigmas), sigmas, metrics.LOCKED).tolist()]

    # ------------------------------------------------------------- diagnostics
    def _publish_diagnostics(self) -> None:
        now = self.now()
        cycles, since = self._rate_window
        if now > since:
            self._rate = (self.accounting.cycles - cycles) / (now - since)
        self._rate_window = (self.accounting.cycles, now)
        statuses = [self._controller_status(now)]
        last = None if self.core is None else self.core.last
        locked_names = set(self.locked_joints)
        if last is not None:
            for joint, i in zip(self.command_joints, self._order, strict=True):
                locked = joint in locked_names
                level = (diagnostics.ERROR if locked else
                         diagnostics.WARN if last.at_hard_limit[i] else diagnostics.OK)
                statuses.append(self.status(
                    level,
                    "locked" if locked else "ok", {
                        "locked": locked, "at_soft_limit": bool(last.at_soft_limit[i]),
                        "at_hard_limit": bool(last.at_hard_limit[i]),
                        "post_failure_sigma": float(last.post_failure_sigmas[i])
                        if not locked else "n/a"}, joint=joint))
        self._diagnostics_pub.publish(diagnostics.array(statuses,
                                                        self.get_clock().now().to_msg()))

    def _controller_status(self, now: float):
        core = self.core
        last = None if core is None else core.last
        target = None if core is None else core.target
        values = {"mode": self.param("resolution"), "loop_rate_hz": self._rate,
                  "control_rate_hz": self.param("control_rate"), "scheduling": self.scheduling,
                  "cycle_compute_median_ms": self.accounting.compute_ms(50),
                  "cycle_compute_p99_ms": self.accounting.compute_ms(99),
                  "missed_cycles": self.accounting.missed if self.accounting.count_missed
                  else "n/a (simulated time)",
                  "state_age_s": now - self.state_stamp if self._q is not None else "none",
                  "target": target.kind if target else "none",
                  "target_age_s": now - target.stamp if target else "none",
                  "locked_joints": sorted(self.locked_joints), "soft_limits": self.soft_limits_note,
                  "observability": self._observability_note(),
                  "recovery": "off" if self.core is None else self.core.recovery_note,
                  "start_configuration": "idle" if self.core is None
                  else self.core.start_phase.note,
                  "suspected_lock": self.suspected_lock or "none"}
        if last is not None:
            values.update(kfm=last.kfm, task_scale=last.task_scale, status=last.status)
        if self.problems.active:
            level, message = diagnostics.ERROR, self.problems.summary()
        elif core is None:
            level, message = diagnostics.WARN, "waiting for the robot model"
        elif last is None:
            level, message = diagnostics.WARN, "waiting for joint states"
        elif last.status == Status.INFEASIBLE:
            level, message = diagnostics.WARN, "task infeasible with the remaining joints"
        else:
            level, message = diagnostics.OK, last.status
        return self.status(level, message, values)

    def _observability_note(self) -> str:
        if self.core is None or self.core.excursions is None:
            return "off"
        joint = self.core.excursions.active
        return "waiting" if joint is None else f"exciting {self.robot.joint_names[joint]}"

    def stop(self) -> None:
        """Bring the commands to rest on a ramp within the limits (used on shutdown)."""
        if self.core is not None:
            smoother = self.core.smoother
            self.ramp_now(self._ramp_step, 0.1 + (smoother.stop_time() if smoother else 0.0))


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
