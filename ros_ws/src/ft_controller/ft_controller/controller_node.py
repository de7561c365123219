"""controller_node: fault-tolerant redundancy resolution as a ROS 2 node.

Joint states plus an end-effector target (twist or pose) in, joint velocities out:
one `ft_core.engine` cycle per timer tick at `control_rate`. Topics, parameters and
reactions are listed in docs/controller.md; the contract is shared/INTERFACE.md.

Safety: with no model, no joint state yet, a stale state (older than
`state_timeout`), missing joints, non-finite values, stamps in the future or going
backwards, or a state or target the engine refuses as physically absurd (a joint
far outside its limits, a task speed beyond 1000 m/s or rad/s), the node publishes
explicit zero commands (a velocity controller holds its last command) and an ERROR
diagnostic, and resumes by itself when good data returns. Each kind of problem is
logged once per episode. On shutdown it publishes zeros before leaving.
"""

from __future__ import annotations

import math
import multiprocessing
import os
import time
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from ft_core import robots, selfmotion, workers
from ft_core.engine import RESOLUTIONS, EngineConfig, ResolutionEngine, Status
from ft_core.observability import Excursions, ObservabilityConfig
from ft_core.robots import Robot, RobotModelError
from ft_core.targets import (
    PoseTracking,
    goal_from_transform,
    pose_velocity,
    staleness_scale,
    twist_velocity,
)
from ft_core.task_channel import TaskChannel
from ft_msgs_py import (
    convert,
    diagnostics,
    metrics,
    names,
    parameters,
    qos,
    spin,
    thread_priority,
)
from ft_msgs_py.loop import LoopAccounting
from ft_msgs_py.node import SuiteNode
from geometry_msgs.msg import PoseStamped, TwistStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, Header

#: Diagnostics period (s).
DIAGNOSTICS_PERIOD = 0.5
#: Pose goals further than this (m) from the base are refused as physically absurd.
ABSURD_DISTANCE = 1e3
#: Period (s, steady time) of the watchdog that publishes zeros when no cycle runs.
WATCHDOG_PERIOD = 0.05

#: name -> (default, description, extra descriptor fields)
PARAMETERS: dict[str, tuple[object, str, dict]] = {
    **parameters.MODEL_PARAMETERS,
    **parameters.THREAD_PRIORITY,
    "resolution": ("blend", "least_norm, max_kfm, min_jump or blend", {}),
    "kfm_gain": (50.0, "kfm gradient ascent, rad/s per (m/rad)",
                 parameters.float_range(0.0, 1e4)),
    "swing_gain": (0.0, "swing-measure descent for free-swinging failures, rad/s per rad "
                   "(0: off; needs the URDF's inertias)",
                   parameters.float_range(0.0, 100.0)),
    "jump_gain": (1.0, "minimum-jump term (1 = exact)",
                  parameters.float_range(0.0, 100.0)),
    "limit_gain": (1.0, "soft/hard limit avoidance, rad/s at a box edge",
                   parameters.float_range(0.0, 100.0)),
    "failure_probabilities": (Parameter.Type.DOUBLE_ARRAY, "one per joint in `joints` order "
                              "(empty: equal)", {}),
    "soft_limits.lower": (Parameter.Type.DOUBLE_ARRAY, "rad, `joints` order (empty: none)", {}),
    "soft_limits.upper": (Parameter.Type.DOUBLE_ARRAY, "rad, `joints` order (empty: none)", {}),
    "critical_points": (Parameter.Type.DOUBLE_ARRAY, "task points concatenated (pose: x y z "
                        "qx qy qz qw); their intersected self-motion boxes become soft limits",
                        {}),
    "release_soft_limits_on_failure": (True, "drop the soft limits once a joint is locked", {}),
    "control_rate": (250.0, "Hz", parameters.float_range(1.0, 2000.0)),
    "target_timeout": (0.5, "s; an older twist decays to 0 over one more timeout",
                       parameters.float_range(0.001, 60.0)),
    "state_timeout": (0.1, "s; older joint states stop the arm",
                      parameters.float_range(0.001, 60.0)),
    "position_gain": (2.0, "1/s, pose-goal tracking",
                      parameters.float_range(0.01, 100.0)),
    "max_linear_speed": (0.25, "m/s, pose-goal tracking",
                         parameters.float_range(0.001, 10.0)),
    "max_angular_speed": (0.5, "rad/s, pose-goal tracking",
                          parameters.float_range(0.001, 10.0)),
    "velocity_scale": (0.5, "fraction of the URDF velocity limits",
                       parameters.float_range(0.01, 1.0)),
    "monitor_name": ("monitor", "node name of the only accepted ft/locked_joints publisher, "
                     "in this namespace (empty: any single publisher)", {"read_only": True}),
    "idle_null_space_motion": (False, "with no target, allow null-space motion (kfm ascent, "
                               "limit avoidance); otherwise hold still", {}),
    "observability.enabled": (False, "null-space excursions of joints not commanded for "
                              "observability.idle_time, so that a lock on them shows up", {}),
    "observability.idle_time": (5.0, "s a joint may go uncommanded before an excursion",
                                parameters.float_range(0.01, 3600.0)),
    "observability.speed": (0.3, "rad/s, peak joint velocity of an excursion",
                            parameters.float_range(0.06, 10.0)),
    "observability.duration": (1.0, "s, one excursion (out and back)",
                               parameters.float_range(0.01, 60.0)),
}


@dataclass
class _Target:
    """The latest target: a twist (task velocity) or a pose goal."""

    kind: str  # "twist" or "pose"
    value: np.ndarray  # task velocity, or goal
    stamp: float  # s


class ControllerNode(SuiteNode):
    """The controller; see the module docstring."""

    def __init__(self, **kwargs):
        super().__init__("controller", **kwargs)
        parameters.declare(self, PARAMETERS)
        self.scheduling = self.apply_thread_priority()  #: reported in diagnostics
        self.robot: Robot | None = None
        self.engine: ResolutionEngine | None = None
        self.tracking = PoseTracking()
        self._order: np.ndarray | None = None  # command index -> chain index
        self.command_joints: list[str] = []  #: joint names in command order
        self._labels: list[str] = []
        # Built once per model, refilled each cycle (`_publish`).
        self._command_msg = JointState()
        self._metrics_msg = Float64MultiArray()
        self._q: np.ndarray | None = None
        self._target: _Target | None = None
        self._locked: dict[str, float] = {}
        self._soft_note = "none"
        self._critical_box: tuple[np.ndarray, np.ndarray] | None = None
        self._boxes_dirty = False
        self._background: ProcessPoolExecutor | None = None  # started with the first boxes
        self._model_source: tuple[str, tuple] | None = None
        self._boxes_job: tuple[int, Future] | None = None
        self._boxes_generation = 0
        self._last = None
        self._excursions: Excursions | None = None
        self._channel: TaskChannel | None = None
        self._suspect: str | None = None
        self._suspect_sent = -math.inf
        self.accounting = LoopAccounting(1.0 / self.param("control_rate"),
                                         count_missed=not self.param("use_sim_time"))
        self._read_cycle_parameters()
        self._rate_window = (0, self.now())
        self._rate = 0.0

        self._command_pub = self.create_publisher(JointState, names.COMMAND_RAW, qos.RELIABLE)
        self._metrics_pub = self.create_publisher(Float64MultiArray, names.METRICS, qos.RELIABLE)
        self._suspect_pub = self.create_publisher(JointState, names.SUSPECTED_FAILURE,
                                                  qos.RELIABLE)
        self._diagnostics_pub = self.create_publisher(DiagnosticArray, names.DIAGNOSTICS,
                                                      qos.RELIABLE)
        self.create_subscription(JointState, names.JOINT_STATES, self._on_state,
                                 qos.SENSOR_INPUT)
        self.create_subscription(TwistStamped, names.TARGET_TWIST, self._on_twist, qos.RELIABLE)
        self.create_subscription(PoseStamped, names.TARGET_POSE, self._on_pose, qos.RELIABLE)
        self.create_subscription(JointState, names.LOCKED_JOINTS, self._on_locked, qos.LATCHED)
        self.add_on_set_parameters_callback(self._validate)
        self.add_post_set_parameters_callback(self._apply)
        self._load_model()
        self._timer = self.create_timer(1.0 / self.param("control_rate"), self._cycle)
        self.create_timer(DIAGNOSTICS_PERIOD, self._publish_diagnostics)
        # The watchdog runs on steady time: with use_sim_time and no /clock the control
        # timer never fires, and the plant must still get explicit zeros.
        self._last_cycle = time.monotonic()
        self.create_timer(WATCHDOG_PERIOD, self._check_watchdog,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))

    # ------------------------------------------------------------------- model
    def _load_model(self) -> None:
        if not (self.param("robot_description") or self.param("robot_model")):
            self.problems.report("model", "waiting for the robot_description topic")
        parameters.request_model(self, self._set_model)

    def _set_model(self, spec: str, source: str) -> None:
        try:
            robot = robots.load(spec, *parameters.chain_arguments(self))
            order = parameters.joint_order(self, robot.joint_names)
            engine = ResolutionEngine(robot, self._engine_config(robot, order, {}))
        except (RobotModelError, ValueError) as error:
            self.problems.report("model", f"cannot use the model from {source}: {error}")
            return
        self.robot, self._order, self.engine = robot, order, engine
        self._excursions = self._observability(robot, {})
        self._channel = TaskChannel(robot) if robot.task_space != "pose" else None
        self._model_source = (spec, parameters.chain_arguments(self))
        self.command_joints = [robot.joint_names[i] for i in order]
        self._labels = metrics.labels(self.command_joints)
        self._command_msg = convert.joint_state(self.command_joints, Time())
        self._metrics_msg = metrics.template(self._labels)
        self._boxes_dirty = len(self.param("critical_points")) > 0
        self.problems.report("model", None)
        self.get_logger().info(
            f"model from {source}: {robot.name}, {robot.base_link} -> {robot.tip_link}, "
            f"{robot.task_space} task, joints {self.command_joints}")

    def _chain(self, values: list[float], order: np.ndarray, what: str) -> np.ndarray:
        """Per-joint values given in command order, put in chain order."""
        values = np.asarray(values, dtype=float)
        if values.shape != (order.size,) or not np.all(np.isfinite(values)):
            raise ValueError(f"{what} needs {order.size} finite values, got {list(values)}")
        chain = np.empty(order.size)
        chain[order] = values
        return chain

    def _engine_config(self, robot: Robot, order: np.ndarray, changes: dict,
                       soft: tuple | None = None) -> EngineConfig:
        """The engine configuration from the parameters (with pending `changes`)."""
        value = {name: changes.get(name, self.param(name)) for name in PARAMETERS}
        probabilities = list(value["failure_probabilities"] or [])
        if probabilities:
            probabilities = list(self._chain(probabilities, order, "failure_probabilities"))
        sides = [self._chain(value[name], order, name) if value[name] else None
                 for name in ("soft_limits.lower", "soft_limits.upper")]
        # One side alone (set one at a time through SetParameters): no soft limits yet.
        box = None if any(side is None for side in sides) else tuple(sides)
        if soft is not None:
            box = soft if box is None else (np.maximum(box[0], soft[0]),
                                            np.minimum(box[1], soft[1]))
        return EngineConfig(
            resolution=value["resolution"], kfm_gain=value["kfm_gain"],
            swing_gain=value["swing_gain"],
            jump_gain=value["jump_gain"], limit_gain=value["limit_gain"],
            failure_probabilities=probabilities,
            soft_lower=() if box is None else box[0], soft_upper=() if box is None else box[1],
            release_soft_limits_on_failure=value["release_soft_limits_on_failure"],
            dt=1.0 / value["control_rate"], velocity_scale=value["velocity_scale"])

    # -------------------------------------------------------------- parameters
    def _validate(self, parameters: list[Parameter]) -> SetParametersResult:
        changes = {p.name: p.value for p in parameters}
        try:
            if "resolution" in changes and changes["resolution"] not in RESOLUTIONS:
                raise ValueError(f"resolution must be one of {RESOLUTIONS}")
            PoseTracking(changes.get("position_gain", self.param("position_gain")),
                         changes.get("max_linear_speed", self.param("max_linear_speed")),
                         changes.get("max_angular_speed", self.param("max_angular_speed")))
            if self.robot is not None:
                robot = self.robot
                config = self._engine_config(robot, self._order, changes)
                ResolutionEngine(robot, config)  # validates lengths against the robot
                if "critical_points" in changes:
                    selfmotion.targets_from_flat(robot, changes["critical_points"] or [])
                self._observability(robot, changes)
        except (ValueError, TypeError) as error:
            return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    def _read_cycle_parameters(self) -> None:
        """The parameters the control cycle reads, read once per change, not per cycle."""
        self._state_timeout = self.param("state_timeout")
        self._target_timeout = self.param("target_timeout")
        self._idle_null_space_motion = self.param("idle_null_space_motion")

    def _apply(self, parameters: list[Parameter]) -> None:
        changed = {p.name for p in parameters}
        self._read_cycle_parameters()
        self.tracking = PoseTracking(self.param("position_gain"), self.param("max_linear_speed"),
                                     self.param("max_angular_speed"))
        if "control_rate" in changed:
            self.accounting.period = 1.0 / self.param("control_rate")
            self._timer.cancel()
            self.destroy_timer(self._timer)
            self._timer = self.create_timer(1.0 / self.param("control_rate"), self._cycle)
        if self.robot is None:
            return
        if "critical_points" in changed:
            self._boxes_dirty = True
        if any(name.startswith("observability.") for name in changed):
            self._excursions = self._observability(self.robot, {})
        self._rebuild_engine(self._critical_box)

    def _observability(self, robot: Robot, changes: dict) -> Excursions | None:
        """The excursions the `observability.*` parameters (with `changes`) ask for."""
        value = {name: changes.get(f"observability.{name}", self.param(f"observability.{name}"))
                 for name in ("enabled", "idle_time", "speed", "duration")}
        config = ObservabilityConfig(value["idle_time"], value["speed"], value["duration"])
        return Excursions(robot.n, config) if value["enabled"] else None

    @property
    def suspected_lock(self) -> str | None:
        """The joint the task-space channel suspects now, if any."""
        return self._suspect

    @property
    def soft_limits_note(self) -> str:
        """The soft limits in force: "none", "<k> critical points", "computing ...".

        "none (critical points failed)" when they could not be computed (the reason
        is in the diagnostics).
        """
        return self._soft_note

    @property
    def soft_limits_pending(self) -> bool:
        """Whether soft limits from the critical points are still to be computed or taken."""
        return self._boxes_dirty or self._boxes_job is not None

    def _rebuild_engine(self, critical_box: tuple | None) -> None:
        """New engine from the parameters; `critical_box` from the critical points, if any."""
        self._critical_box = critical_box
        self.engine = ResolutionEngine(self.robot, self._engine_config(
            self.robot, self._order, {}, critical_box))

    def _start_boxes(self, q: np.ndarray) -> None:
        """Compute the critical points' soft limits in a worker process (never in the cycle).

        The control loop goes on with the limits it has; `_take_boxes` switches to
        the new ones, in the cycle, once they are ready. A change of the points while
        a computation runs makes its result stale: it is dropped and computed again.
        """
        self._boxes_dirty = False
        flat = list(self.param("critical_points") or [])
        if not flat:
            self._soft_note = "none"
            self.problems.report("critical points", None)
            self._rebuild_engine(None)
            return
        self._boxes_generation += 1
        self._soft_note = (f"computing soft limits from {len(flat)} values of critical points "
                           "(the previous limits meanwhile)")
        try:
            if self._background is None:
                self._background = ProcessPoolExecutor(
                    max_workers=1, mp_context=multiprocessing.get_context("spawn"),
                    initializer=workers.exit_with_parent, initargs=(os.getpid(),))
            with thread_priority.lowered():  # the worker starts here: never at the loop's
                self._boxes_job = (self._boxes_generation, self._background.submit(
                    selfmotion.soft_limits_for_model, *self._model_source, flat, q.copy()))
        except (AssertionError, RuntimeError, OSError) as error:  # e.g. inside a daemon
            self._soft_note = "none (critical points failed)"
            self.problems.report("critical points", f"cannot start the process that traces "
                                 f"the boxes ({error}); running without their soft limits")

    def _take_boxes(self) -> None:
        """Switch to soft limits computed in the background, if any are ready."""
        generation, job = self._boxes_job
        if not job.done():
            return
        self._boxes_job = None
        if generation != self._boxes_generation:
            return  # the points changed meanwhile: a newer computation follows
        try:
            box, count = job.result()
        except (selfmotion.UnreachableError, RobotModelError, ValueError, BrokenProcessPool,
                ) as error:
            self._soft_note = "none (critical points failed)"
            self.problems.report("critical points", f"{error}; running without their soft limits")
            self._rebuild_engine(None)
            return
        self._soft_note = f"{count} critical points"
        self.problems.report("critical points", None)
        self.get_logger().info(f"soft limits from {count} critical points: "
                               f"lower {np.round(box[0], 3).tolist()}, "
                               f"upper {np.round(box[1], 3).tolist()}")
        self._rebuild_engine(box)

    def destroy_node(self) -> None:
        """Stop the background work too."""
        if self._background is not None:
            self._background.shutdown(wait=False, cancel_futures=True)
        super().destroy_node()

    # ------------------------------------------------------------------ inputs
    def _on_state(self, msg: JointState) -> None:
        if self.robot is not None:
            self._q = self.read_joint_state(msg, self.robot.joint_names)

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
            self._target = _Target("twist", twist_velocity(self.robot, twist), stamp)

    def _on_pose(self, msg: PoseStamped) -> None:
        if self.robot is None or not self._frame_ok(msg.header.frame_id, "ft/target_pose"):
            return
        try:
            transform = convert.pose_matrix(msg.pose)
            if np.max(np.abs(transform[:3, 3])) > ABSURD_DISTANCE:
                raise convert.MessageError(f"goal further than {ABSURD_DISTANCE:g} m: no arm "
                                           "reaches it")
            goal = goal_from_transform(self.robot, transform)
        except convert.MessageError as error:
            self.problems.report("ft/target_pose", str(error))
            return
        self.problems.report("ft/target_pose", None)
        self._target = _Target("pose", goal, self.now())

    def _locked_publisher_problem(self) -> str | None:
        """Why `ft/locked_joints` cannot be trusted now, or None (one publisher: the monitor)."""
        publishers = self.get_publishers_info_by_topic(
            self.resolve_topic_name(names.LOCKED_JOINTS))
        expected = self.param("monitor_name")
        named = sorted(f"{p.node_namespace.rstrip('/')}/{p.node_name}" for p in publishers)
        if len(publishers) > 1:
            return (f"{len(publishers)} publishers {named[:10]}: only the monitor may publish "
                    "the locked set (see docs/security.md on SROS2); ignored")
        if expected and publishers and publishers[0].node_name != expected:
            return f"published by {named[0]}, not by the monitor '{expected}'; ignored"
        return None

    def _on_locked(self, msg: JointState) -> None:
        if self.robot is None:
            return
        problem = self._locked_publisher_problem()
        self.problems.report("ft/locked_joints", problem)
        if problem is not None:
            return
        try:
            locked, unknown = convert.locked_joints(msg, self.robot.joint_names)
        except convert.MessageError as error:
            self.get_logger().error(f"ft/locked_joints: {error}: ignored")
            return
        if unknown:
            self.get_logger().warning(f"ft/locked_joints: unknown joints {unknown} ignored")
        if set(locked) != set(self._locked):
            self.get_logger().warning(f"locked joints now {sorted(locked) or 'none'}")
        self._locked = locked

    # ------------------------------------------------------------------- cycle
    def _check_watchdog(self) -> None:
        """Zeros (and an ERROR) while no control cycle has run for `state_timeout` (steady)."""
        silent = time.monotonic() - self._last_cycle
        if silent <= max(self.param("state_timeout"), 2.0 / self.param("control_rate")):
            self.problems.report("control loop", None)
            return
        self.problems.report("control loop", f"no control cycle for {silent:.2f} s (is /clock "
                             "published with use_sim_time?): commanding zeros")
        if self.robot is not None:
            self._publish(np.zeros(self.robot.n))

    def _cycle(self) -> None:
        self._last_cycle = time.monotonic()
        self.accounting.start()
        try:
            self._control()
        finally:
            self.accounting.end()

    def _control(self) -> None:
        robot = self.robot
        if robot is None:
            return
        clock = self.get_clock().now()
        now, stamp = clock.nanoseconds * 1e-9, clock.to_msg()
        q = self._q
        if q is not None and now - self.state_stamp > self._state_timeout:
            self.problems.report("joint_states",
                                 f"no joint state for {now - self.state_stamp:.3f} s")
            q = None
        if q is None:
            self._last = None
            self._publish(np.zeros(robot.n), stamp)
            return
        if self._boxes_job is not None:
            self._take_boxes()
        if self._boxes_dirty:
            self._start_boxes(q)
        xd, idle, error = self._task_velocity(q, now)
        locked = [robot.joint_names.index(name) for name in self._locked]
        try:
            result = self.engine.step(q, xd, locked)
        except ValueError as error:  # physically absurd state or target
            self.problems.report("engine", f"{error}: commanding zeros")
            self._last = None
            self._publish(np.zeros(robot.n), stamp)
            return
        self.problems.report("engine", None)
        qd = result.qd
        if idle and not self._idle_null_space_motion:
            qd = np.zeros(robot.n)
            result.jump_index = 0.0
        qd = self._excite(q, qd, locked, now)
        if not np.all(np.isfinite(qd)):
            qd = np.zeros(robot.n)
        self._last = result
        self._publish(qd, stamp, result)
        if error is not None:
            self._watch_task(q, qd, locked, now, error)

    def _watch_task(self, q: np.ndarray, qd: np.ndarray, locked: list[int], now: float,
                    error: float) -> None:
        """Feed the task-space channel (`ft_core.task_channel`) the pose goal's error (m).

        A new suspect is published on `ft/suspected_failure` for the monitor to decide.
        """
        if self._channel is None:
            return
        joint = self._channel.update(now, q, qd, error, tuple(locked))
        name = None if joint is None else self.robot.joint_names[joint]
        if name is not None and name != self._suspect:
            self.get_logger().warning(
                f"task error not decreasing while joints are commanded: {name}'s loss explains "
                f"the motion (residual {self._channel.residuals[joint]:.2f} of the unexplained "
                "motion); suspected, for the monitor to decide", throttle_duration_sec=5.0)
        if name is not None and (name != self._suspect
                                 or now - self._suspect_sent >= self._channel.config.window):
            # Again every window while it lasts: the monitor may not have had the evidence.
            self._suspect_pub.publish(JointState(header=Header(
                stamp=self.get_clock().now().to_msg()), name=[name]))
            self._suspect_sent = now
        self._suspect = name

    def _excite(self, q: np.ndarray, qd: np.ndarray, locked: list[int], now: float) -> np.ndarray:
        """The command with the observability excursion under way, if any (null space only)."""
        if self._excursions is None:
            return qd
        for k, (joint, speed) in enumerate(self._excursions.update(now, qd, locked)):
            moved = self.engine.excursion(q, qd, joint, speed, locked)
            if moved is not None:
                qd = moved
            elif k == 0:  # the idle joint itself cannot move: no excursion now
                self._excursions.cannot_move(joint, now)
                return qd
        return qd

    def _task_velocity(self, q: np.ndarray, now: float) -> tuple[np.ndarray, bool, float | None]:
        """(task velocity, idle, the pose goal's error norm or None) from the latest target."""
        target, robot = self._target, self.robot
        if target is None:
            return np.zeros(robot.m), True, None
        if target.kind == "pose":
            error = robot.task_error(target.value, q)
            xd, reached = pose_velocity(robot, error, self.tracking)
            return xd, reached, float(np.linalg.norm(error))
        scale = staleness_scale(now - target.stamp, self._target_timeout)
        return scale * target.value, scale == 0.0, None

    def _publish(self, qd_chain: np.ndarray, stamp: Time | None = None, result=None) -> None:
        """The command (and with a cycle's result, the metrics), in preallocated messages."""
        msg = self._command_msg
        msg.header.stamp = self.get_clock().now().to_msg() if stamp is None else stamp
        msg.velocity = qd_chain[self._order].tolist()
        self._command_pub.publish(msg)
        if result is None:
            return
        sigmas = result.post_failure_sigmas[self._order]
        metrics.fill(self._metrics_msg, [
            result.kfm, result.sigma_min, result.jump_index, result.task_scale,
            result.soft_limit_margin if math.isfinite(result.soft_limit_margin)
            else metrics.NO_SOFT_BOX, *np.where(np.isfinite(sigmas), sigmas, metrics.LOCKED)])
        self._metrics_pub.publish(self._metrics_msg)

    # ------------------------------------------------------------- diagnostics
    def _publish_diagnostics(self) -> None:
        now = self.now()
        cycles, since = self._rate_window
        if now > since:
            self._rate = (self.accounting.cycles - cycles) / (now - since)
        self._rate_window = (self.accounting.cycles, now)
        statuses = [self._controller_status(now)]
        if self.robot is not None and self._last is not None:
            for joint, i in zip(self.command_joints, self._order, strict=True):
                locked = joint in self._locked
                level = (diagnostics.ERROR if locked else
                         diagnostics.WARN if self._last.at_hard_limit[i] else diagnostics.OK)
                statuses.append(self.status(
                    level,
                    "locked" if locked else "ok", {
                        "locked": locked, "at_soft_limit": bool(self._last.at_soft_limit[i]),
                        "at_hard_limit": bool(self._last.at_hard_limit[i]),
                        "post_failure_sigma": float(self._last.post_failure_sigmas[i])
                        if not locked else "n/a"}, joint=joint))
        self._diagnostics_pub.publish(diagnostics.array(statuses,
                                                        self.get_clock().now().to_msg()))

    def _controller_status(self, now: float):
        values = {"mode": self.param("resolution"), "loop_rate_hz": self._rate,
                  "control_rate_hz": self.param("control_rate"), "scheduling": self.scheduling,
                  "cycle_compute_median_ms": self.accounting.compute_ms(50),
                  "cycle_compute_p99_ms": self.accounting.compute_ms(99),
                  "missed_cycles": self.accounting.missed if self.accounting.count_missed
                  else "n/a (simulated time)",
                  "state_age_s": now - self.state_stamp if self._q is not None else "none",
                  "target": self._target.kind if self._target else "none",
                  "target_age_s": now - self._target.stamp if self._target else "none",
                  "locked_joints": sorted(self._locked), "soft_limits": self._soft_note,
                  "observability": self._observability_note(),
                  "suspected_lock": self._suspect or "none"}
        if self._last is not None:
            values.update(kfm=self._last.kfm, task_scale=self._last.task_scale,
                          status=self._last.status)
        if self.problems.active:
            level, message = diagnostics.ERROR, self.problems.summary()
        elif self._last is None:
            level, message = diagnostics.WARN, "waiting for joint states"
        elif self._last.status == Status.INFEASIBLE:
            level, message = diagnostics.WARN, "task infeasible with the remaining joints"
        else:
            level, message = diagnostics.OK, self._last.status
        return self.status(level, message, values)

    def _observability_note(self) -> str:
        if self._excursions is None:
            return "off"
        joint = self._excursions.active
        return "waiting" if joint is None else f"exciting {self.robot.joint_names[joint]}"

    def stop(self) -> None:
        """Publish explicit zero velocities (used on shutdown)."""
        if self.robot is not None:
            self._publish(np.zeros(self.robot.n))


def main(args: list[str] | None = None) -> None:
    """Run the controller until SIGINT, then command zero velocity and exit."""
    spin.run_node(ControllerNode, args)


if __name__ == "__main__":
    main()
