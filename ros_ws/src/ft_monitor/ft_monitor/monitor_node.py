"""monitor_node: detect locked joints and keep the task going around them.

Inputs: `ft/command_raw` (what a controller commands; or `ft/command_raw_array`,
a Float64MultiArray of velocities in `joints` order, as MoveIt Servo publishes
them) and `joint_states` (what happened). It republishes every command on
`ft/command` and `ft/command_array` (in `joints` order, for a
JointGroupVelocityController): unchanged while nothing
is locked; with locks, the locked joints get exactly 0 and, with
`remap_commands`, the rest is remapped through the reduced Jacobian so the tool
velocity J qd is kept (`ft_core.remap`). Every output is scaled, direction kept,
into `velocity_scale` times the URDF velocity limits, so detection compares the
measured motion with a command the plant can follow.

Detection (`ft_core.detection`) compares the measured motion with what a model of
the plant (latency plus first-order lag, identified online from healthy motion)
predicts from the commands this node actually sent, stamped with this node's clock
when sent. It decides nothing while it lacks evidence: a gap in its own command
stream and the settling time after it, too few joint states, a plant not yet seen
following, or nobody subscribed to `ft/command` and `ft/command_array`; the reason
is in `/diagnostics`. Most joints stopping at once is a plant fault (ERROR), not
locks. A lock stays until `~/reset`. `ft/declare_failure` locks joints at once.
The full locked set goes out on `ft/locked_joints` (transient local) and is kept
in a file under `state_directory` (`ft_core.locked_set`), restored at start-up.

Safety: a malformed command (NaN, wrong lengths, unknown, missing or duplicate
names, more than `convert.MAX_NAMES` names, a stamp ahead of the clock or older than
`command_timeout`) is replaced by explicit zeros; with no fresh command for `command_timeout` the
watchdog publishes zeros once per period until commands return (a velocity
controller holds its last command). Problems are logged once per episode.
"""

from __future__ import annotations

import math
import time

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from ft_core import locked_set, remap, robots
from ft_core.detection import DetectorConfig, LockDetector
from ft_msgs_py import convert, diagnostics, names, parameters, qos, spin
from ft_msgs_py.node import SuiteNode
from rclpy.clock import Clock, ClockType
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension, MultiArrayLayout
from std_srvs.srv import Trigger

DIAGNOSTICS_PERIOD = 0.5


_DETECTION = DetectorConfig()
#: Detector parameters whose negative value means "identified online" (None in the config).
_IDENTIFIED = ("detection.latency", "detection.response_time")
PARAMETERS: dict[str, tuple[object, str, dict]] = {
    **parameters.MODEL_PARAMETERS,
    **parameters.THREAD_PRIORITY,
    "detection.window": (_DETECTION.window, "s, sliding window of the comparison",
                         parameters.float_range(0.005, 10.0)),
    "detection.min_command": (_DETECTION.min_command, "rad/s; smaller predicted motion is "
                              "unobservable (no decision)", parameters.float_range(0.0, 10.0)),
    "detection.latency": (-1.0, "s from a command to its effect on the measurements; "
                          "negative: identified online", parameters.float_range(-1.0, 1.0)),
    "detection.response_time": (-1.0, "s, first-order time constant of the plant's "
                                "velocity loop; negative: identified online",
                                parameters.float_range(-1.0, 1.0)),
    "detection.persistence": (_DETECTION.persistence, "s the lock evidence must hold",
                              parameters.float_range(0.0, 10.0)),
    "detection.ratio": (_DETECTION.ratio, "measured over predicted velocity below which a "
                        "joint looks locked", parameters.float_range(0.01, 0.99)),
    "detection.confidence": (_DETECTION.confidence, "separation in standard errors",
                             parameters.float_range(0.5, 50.0)),
    "detection.follow_time": (_DETECTION.follow_time, "s the plant must be seen following "
                              "commands before any decision", parameters.float_range(0.0, 10.0)),
    "brake_free_swinging": (False, "declare a free-swinging joint locked where it is (ask "
                            "for its brake) instead of only reporting it", {}),
    "remap_commands": (True, "remap commands through the reduced Jacobian once joints lock",
                       {}),
    "command_timeout": (0.2, "s without a command before the watchdog publishes zeros",
                        parameters.float_range(0.001, 60.0)),
    "velocity_scale": (1.0, "fraction of the URDF velocity limits for remapped commands",
                       parameters.float_range(0.01, 1.0)),
    "state_directory": ("", "directory of the persisted locked set (empty: "
                        "$ROS_HOME/ft_arms, or ~/.ros/ft_arms)", {"read_only": True}),
}


class MonitorNode(SuiteNode):
    """The monitor; see the module docstring."""

    def __init__(self, **kwargs):
        super().__init__("monitor", **kwargs)
        parameters.declare(self, PARAMETERS)
        self.scheduling = self.apply_thread_priority()  #: reported in diagnostics
        self.robot: robots.Robot | None = None
        self.detector: LockDetector | None = None
        self._store = None  # path of the persisted locked set, once the model is known
        self._order: list[int] = []
        self.command_joints: list[str] = []  #: joint names in command order
        # Built once per model, refilled for every command (`_publish_command`).
        self._command_msg = JointState()
        self._array_msg = Float64MultiArray()
        self._velocity_limits = np.zeros(0)
        self._q: np.ndarray | None = None
        self._last_command = -math.inf
        self._command_pub = self.create_publisher(JointState, names.COMMAND, qos.RELIABLE)
        self._array_pub = self.create_publisher(Float64MultiArray, names.COMMAND_ARRAY,
                                                qos.RELIABLE)
        self._locked_pub = self.create_publisher(JointState, names.LOCKED_JOINTS, qos.LATCHED)
        self._diagnostics_pub = self.create_publisher(DiagnosticArray, names.DIAGNOSTICS,
                                                      qos.RELIABLE)
        self.create_subscription(JointState, names.COMMAND_RAW, self._on_command,
                                 qos.SENSOR_INPUT)
        self.create_subscription(Float64MultiArray, names.COMMAND_RAW_ARRAY, self._on_array,
                                 qos.SENSOR_INPUT)
        self.create_subscription(JointState, names.JOINT_STATES, self._on_state,
                                 qos.SENSOR_INPUT)
        self.create_subscription(JointState, names.DECLARE_FAILURE, self._on_declare,
                                 qos.RELIABLE)
        self.create_subscription(JointState, names.SUSPECTED_FAILURE, self._on_suspect,
                                 qos.RELIABLE)
        self.create_service(Trigger, names.RESET, self._on_reset)
        self._read_command_parameters()
        parameters.on_change(self, self._detector_config, self._configure_detector)
        parameters.request_model(self, self._set_model)
        # On steady time: with use_sim_time and no /clock the watchdog must still run.
        self._last_command_steady = time.monotonic()
        self._watchdog = self.create_timer(self.param("command_timeout"), self._check_watchdog,
                                           clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.create_timer(DIAGNOSTICS_PERIOD, self._publish_diagnostics)

    # ------------------------------------------------------------------ set-up
    def _detector_config(self, changes: dict | None = None) -> DetectorConfig:
        value = {**{k: self.param(k) for k in PARAMETERS if k.startswith("detection.")},
                 **(changes or {})}
        for name in _IDENTIFIED:
            value[name] = None if value[name] < 0 else value[name]
        return DetectorConfig(
            window=value["detection.window"], min_command=value["detection.min_command"],
            latency=value["detection.latency"],
            response_time=value["detection.response_time"],
            persistence=value["detection.persistence"], ratio=value["detection.ratio"],
            confidence=value["detection.confidence"],
            follow_time=value["detection.follow_time"])

    def _configure_detector(self) -> None:
        self._read_command_parameters()
        if self.detector is not None:
            self.detector.configure(self._detector_config())

    def _read_command_parameters(self) -> None:
        """The parameters every command reads, read once per change, not per command."""
        self._command_timeout = self.param("command_timeout")
        self._remap = self.param("remap_commands")
        if self.robot is not None:
            self._velocity_limits = self.robot.velocity_limits * self.param("velocity_scale")

    def _set_model(self, spec: str, source: str) -> None:
        try:
            robot = robots.load(spec, *parameters.chain_arguments(self))
            order = parameters.joint_order(self, robot.joint_names)
        except (robots.RobotModelError, ValueError) as error:
            self.problems.report("model", f"cannot use the model from {source}: {error}")
            return
        self.robot = robot
        self._order = order.tolist()
        joints = self.command_joints = [robot.joint_names[i] for i in self._order]
        self._command_msg = convert.joint_state(joints, Time())
        self._array_msg = Float64MultiArray(layout=MultiArrayLayout(dim=[MultiArrayDimension(
            label="joints", size=len(joints), stride=len(joints))]))
        self._read_command_parameters()
        self.detector = LockDetector(robot.lower, robot.upper, self._detector_config())
        self.problems.report("model", None)
        self.get_logger().info(f"monitoring {robot.name}: joints {joints}")
        self._store = locked_set.path_for(self.param("state_directory"),
                                          self.get_fully_qualified_name(), robot.name)
        self._restore_locked()
        self._publish_locked(self.now())

    def _restore_locked(self) -> None:
        try:
            stored = locked_set.load(self._store, self.robot.name, list(self.robot.joint_names))
        except locked_set.LockedSetError as error:
            self.problems.report("state_directory", f"{error}: starting with no locked joint",
                                 warning=True)
            return
        now = self.now()
        for name, position in stored.items():
            self.detector.lock(self.robot.joint_names.index(name), position, now)
        if stored:
            self.get_logger().error(f"restored locked joints {sorted(stored)} from "
                                    f"{self._store} (call ~/reset after a repair)")

    @property
    def locked(self) -> dict[str, float]:
        """{joint name: position at lock (rad)} of every locked joint (the detector's)."""
        if self.detector is None:
            return {}
        return {self.robot.joint_names[j]: p for j, p in self.detector.locked.items()}

    # ------------------------------------------------------------------ inputs
    def _on_state(self, msg: JointState) -> None:
        if self.robot is None:
            return
        q = self.read_joint_state(msg, self.robot.joint_names)
        if q is None:
            return
        self._q, stamp = q, self.state_stamp
        if self.detector.fill_unknown_positions(q):
            self._locked_changed(stamp)
        listeners = (self._command_pub.get_subscription_count()
                     + self._array_pub.get_subscription_count())
        update = self.detector.measure(
            stamp, q, None if listeners else "nobody subscribes to ft/command(_array)")
        self.problems.report("plant", self.detector.plant_fault)
        if update.swinging:
            self._free_swinging(update.swinging, q, stamp)
        if update.locked:
            for j in update.locked:
                name = self.robot.joint_names[j]
                evidence = self.detector.joints[j]
                self.get_logger().error(
                    f"joint {name} locked at {evidence.position:.4f} rad (t = {stamp:.3f} s): "
                    f"measured {evidence.measured:.4f} rad/s against at least "
                    f"{evidence.commanded:.4f} expected")
            self._locked_changed(stamp)

    def _free_swinging(self, joints: tuple[int, ...], q: np.ndarray, stamp: float) -> None:
        """Report joints newly found moving on their own; with the option, brake them."""
        brake = self.param("brake_free_swinging")
        for j in joints:
            evidence = self.detector.joints[j]
            self.get_logger().error(
                f"joint {self.robot.joint_names[j]} free-swinging (t = {stamp:.3f} s): measured "
                f"{evidence.measured:.4f} rad/s, commanded {evidence.commanded:.4f}"
                + ("; declaring it locked where it is (brake)" if brake else ""))
            if brake:
                self.detector.lock(j, float(q[j]), stamp)
        self._locked_changed(stamp)  # a lock taken back, or the brake applied

    def _on_suspect(self, msg: JointState) -> None:
        """A joint the controller's task channel suspects: locked if the measurements agree."""
        if self.robot is None or self._q is None:
            return
        try:
            known = convert.names_to_indices(list(msg.name)[:convert.MAX_NAMES],
                                             self.robot.joint_names)
        except convert.MessageError as error:
            self.get_logger().warning(f"ft/suspected_failure ignored: {error}",
                                      throttle_duration_sec=5.0)
            return
        now = self.now()
        for j in known.values():
            answer = self.detector.confirm(j, float(self._q[j]), now)
            name = self.robot.joint_names[j]
            evidence = answer.evidence
            if answer.decision == "refused":
                reason = " at a joint limit" if evidence.at_limit else ""
                self.get_logger().warning(
                    f"suspected lock of {name} not confirmed{reason}: measured "
                    f"{evidence.measured:.4f} rad/s (+-{evidence.standard_error:.4f}), "
                    f"commanded {evidence.commanded:.4f}", throttle_duration_sec=5.0)
            if answer.decision != "locked":
                continue
            self.get_logger().error(
                f"joint {name} locked (suspected by the task-space channel, confirmed: measured "
                f"{evidence.measured:.4f} rad/s against {evidence.commanded:.4f} commanded)")
            self._locked_changed(now)

    def _on_declare(self, msg: JointState) -> None:
        if self.robot is None:
            return
        now = self.now()
        try:
            known = convert.names_to_indices(list(msg.name), self.robot.joint_names)
        except convert.MessageError as error:
            self.get_logger().error(f"ft/declare_failure ignored: {error}",
                                    throttle_duration_sec=5.0)
            return
        if len(known) < len(msg.name):
            self.get_logger().warning(f"ft/declare_failure: {len(msg.name) - len(known)} unknown "
                                      "joint names ignored", throttle_duration_sec=5.0)
        for j in known.values():
            name = self.robot.joint_names[j]
            if j not in self.detector.locked:
                position = float(self._q[j]) if self._q is not None else math.nan
                self.detector.lock(j, position, now)
                self.get_logger().error(f"joint {name} declared locked")
        self._locked_changed(now)

    def _on_reset(self, _request: Trigger.Request, response: Trigger.Response):
        released = sorted(self.locked)
        if self.detector is not None:
            self.detector.reset()
            self._locked_changed(self.now())
        self.get_logger().info(f"reset: released {released or 'nothing'}")
        response.success, response.message = True, f"released {released or 'nothing'}"
        return response

    def _on_command(self, msg: JointState) -> None:
        if self.robot is None:
            return
        now = self.now()
        stamp = self.problems.message_time("ft/command_raw", msg.header.stamp, now)
        try:
            if stamp is None:
                raise convert.MessageError("stamp ahead of the clock")
            if now - stamp > self._command_timeout:
                raise convert.MessageError(f"stale: stamped {now - stamp:.3f} s ago")
            qd = convert.joint_vector(msg, self.robot.joint_names, "velocity")
        except convert.MessageError as error:
            self._refuse("ft/command_raw", error, msg.header.stamp)
            return
        self._forward("ft/command_raw", qd, msg.header.stamp, now)

    def _on_array(self, msg: Float64MultiArray) -> None:
        """Velocities in `joints` order (MoveIt Servo's Float64MultiArray output, unstamped)."""
        if self.robot is None:
            return
        stamp = self.get_clock().now().to_msg()
        try:
            qd = convert.array_vector(msg.data, self._order)
        except convert.MessageError as error:
            self._refuse("ft/command_raw_array", error, stamp)
            return
        self._forward("ft/command_raw_array", qd, stamp, self.now())

    def _refuse(self, topic: str, error: convert.MessageError, stamp) -> None:
        """A malformed command: reported, and replaced by explicit zeros."""
        self.problems.report(topic, f"{error}: commanding zeros")
        self._publish_command(np.zeros(self.robot.n), stamp)

    def _forward(self, topic: str, qd: np.ndarray, stamp, now: float) -> None:
        """A good command (chain order): locked joints zeroed or remapped, then published."""
        self.problems.report(topic, None)
        self._last_command = now
        self._last_command_steady = time.monotonic()
        locked = sorted(self.detector.locked)
        limits = self._velocity_limits
        if locked and self._remap and self._q is not None:
            qd = remap.remap(self.robot, self._q, qd, locked, limits)
        else:
            qd = qd.copy()
            qd[locked] = 0.0
            qd = remap.within_limits(qd, limits)
        if not np.all(np.isfinite(qd)):
            qd = np.zeros(self.robot.n)
        self._publish_command(qd, stamp, now)

    # ----------------------------------------------------------------- outputs
    def _publish_command(self, qd_chain: np.ndarray, stamp, now: float | None = None) -> None:
        """Publish a command and tell the detector it is in force from `now` (this clock)."""
        ordered = qd_chain[self._order].tolist()
        self._command_msg.header.stamp = stamp
        self._command_msg.velocity = ordered
        self._command_pub.publish(self._command_msg)
        self._array_msg.data = ordered
        self._array_pub.publish(self._array_msg)
        self.detector.command(self.now() if now is None else now, qd_chain)

    def stop(self) -> None:
        """Publish explicit zero velocities (used on shutdown)."""
        if self.robot is not None:
            self._publish_command(np.zeros(self.robot.n), self.get_clock().now().to_msg())

    def _locked_changed(self, time: float) -> None:
        """Publish the locked set and keep it on disk."""
        self._publish_locked(time)
        try:
            locked_set.save(self._store, self.robot.name, self.locked)
            self.problems.report("state_directory", None)
        except OSError as error:
            self.problems.report("state_directory", f"cannot keep the locked set: {error}")

    def _publish_locked(self, time: float) -> None:
        msg = convert.locked_message(self.locked,
                                     convert.stamp_from_nanoseconds(round(time * 1e9)))
        self._locked_pub.publish(msg)

    def _check_watchdog(self) -> None:
        if self.robot is None:
            return
        age = time.monotonic() - self._last_command_steady
        if age > self.param("command_timeout"):
            self._publish_command(np.zeros(self.robot.n), self.get_clock().now().to_msg())

    def _plant_values(self) -> dict[str, object]:
        """The detector's view of the plant, for /diagnostics."""
        estimate = self.detector.estimate()
        values: dict[str, object] = {
            "observing": self.detector.not_observing or "yes",
            "plant_model": "identified" if estimate.identified else "prior (not yet identified)",
            "latency_range_s": list(estimate.latency_range),
            "response_time_range_s": list(estimate.response_time_range),
            "identification_data_s": estimate.excitation}
        if estimate.identified:
            values["latency_s"] = estimate.latency
            values["response_time_s"] = estimate.response_time
        return values

    def _publish_diagnostics(self) -> None:
        now = self.now()
        age = now - self._last_command
        locked = self.locked
        values = {"locked_joints": sorted(locked), "remap_commands":
                  self.param("remap_commands"),
                  "command_age_s": age if math.isfinite(age) else "none",
                  "scheduling": self.scheduling}
        stalls = []
        statuses = []
        swinging = [] if self.detector is None else sorted(
            self.robot.joint_names[j] for j in self.detector.swinging)
        values["free_swinging_joints"] = swinging
        if self.robot is not None:
            values.update(self._plant_values())
            for name in self.command_joints:
                evidence = self.detector.joints[self.robot.joint_names.index(name)]
                level, message = diagnostics.OK, "ok"
                if name in locked:
                    level, message = diagnostics.ERROR, "locked"
                elif name in swinging:
                    level, message = diagnostics.ERROR, "free-swinging"
                elif evidence.at_limit:
                    level, message = diagnostics.WARN, "stalled at a joint limit"
                    stalls.append(name)
                statuses.append(self.status(level, message, {
                    "observable": evidence.observable, "following": evidence.following,
                    "measured_velocity": evidence.measured,
                    "expected_velocity": evidence.commanded,
                    "standard_error": evidence.standard_error}, joint=name))
        if self.problems.active:
            level, message = diagnostics.ERROR, self.problems.summary()
        elif locked or swinging:
            level, message = diagnostics.ERROR, "; ".join(
                [f"locked: {sorted(locked)}"] * bool(locked)
                + [f"free-swinging: {swinging}"] * bool(swinging))
        elif stalls:
            level, message = diagnostics.WARN, f"stalled at a limit: {stalls}"
        elif age > self.param("command_timeout"):
            level, message = diagnostics.WARN, "no fresh command: publishing zeros"
        elif self.detector is not None and self.detector.not_observing:
            level, message = diagnostics.OK, f"not observing: {self.detector.not_observing}"
        else:
            level, message = diagnostics.OK, "no locked joint"
        statuses.insert(0, self.status(level, message, values))
        self._diagnostics_pub.publish(diagnostics.array(statuses, self.get_clock().now().to_msg()))


def main(args: list[str] | None = None) -> None:
    """Run the monitor until SIGINT, then command zero velocity and exit."""
    spin.run_node(MonitorNode, args)


if __name__ == "__main__":
    main()
