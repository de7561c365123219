"""monitor_node: detect locked joints and keep the task going around them.

The node is wiring (parameters, message conversion, the watchdog, publishing and
diagnostics); the logic below is `ft_core.monitor.Monitor`'s, usable without ROS.

Inputs: `ft/command_raw` (what a controller commands; or `ft/command_raw_array`,
a Float64MultiArray of velocities in `joints` order, as MoveIt Servo publishes
them) and `joint_states` (what happened). It republishes every command on
`ft/command` and `ft/command_array` (in `joints` order, for a
JointGroupVelocityController): unchanged while nothing
is locked; with locks, the locked joints get exactly 0 and, with
`remap_commands`, the rest is remapped through the reduced Jacobian so the tool
velocity J qd is kept (`ft_core.remap`). Every output is scaled, direction kept,
into `velocity_scale` times the URDF velocity limits and smoothed into the arm's
acceleration and jerk limits (`smooth_commands`, `limits.*`; `ft_core.smoothing`),
so detection compares the measured motion with a command the plant can follow. The
outputs are stamped with this node's clock when sent (what the smoother's limits are
kept against); the echo keeps the command's own stamp, which the controller matches.

Detection (`ft_core.detection`) compares the measured motion with what a model of
the plant (latency plus first-order lag, identified online from healthy motion)
predicts from the commands this node actually sent, stamped with this node's clock
when sent. It decides nothing while it lacks evidence: a gap in its own command
stream and the settling time after it, too few joint states, a plant not yet seen
following, or nobody subscribed to `ft/command` and `ft/command_array`; the reason
is in `/diagnostics`. Most joints stopping at once is a plant fault (ERROR), not
locks. A lock stays until `~/reset`. `ft/declare_failure` locks joints at once.
The full locked set is kept in a file under `state_directory` (`ft_core.locked_set`),
restored at start-up, and goes out on `ft/locked_joints` (transient local) only once
that file holds it.

Safety: a malformed command (NaN, wrong lengths, unknown, missing or duplicate
names, more than `convert.MAX_NAMES` names, a stamp ahead of the clock or older than
`command_timeout`) is replaced by explicit zeros; with no fresh command for `command_timeout` the
watchdog brings the commands to rest on a ramp (`SuiteNode.ramp`: a command every
`RAMP_PERIOD` s within the limits), then publishes zeros once per period until commands
return (a velocity controller holds its last command). On shutdown the same ramp runs
before the node leaves. Problems are logged once per episode.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from ft_core import locked_set, robots
from ft_core.command_limits import limits_config
from ft_core.detection import DetectorConfig
from ft_core.monitor import UNSEEN_AFTER, Change, Monitor, MonitorConfig
from ft_msgs_py import convert, diagnostics, names, parameters, qos, spin, wire
from ft_msgs_py.monitor_guard import ECHO_PERIOD
from ft_msgs_py.node import JointStateLike, StateListener, SuiteNode
from rclpy.clock import Clock, ClockType
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension, MultiArrayLayout
from std_srvs.srv import Trigger

DIAGNOSTICS_PERIOD = 0.5
#: s between checks for a written locked set while no joint state arrives (steady time).
ANNOUNCE_PERIOD = 0.02
#: s (steady) between two re-announcements of an unchanged locked set asked for on
#: `ft/declare_failure`: a flood of declarations costs one publication per period, and
#: the latched topic gives a late subscriber the set anyway.
REANNOUNCE_PERIOD = 0.1


_DETECTION, _MONITOR = DetectorConfig(), MonitorConfig()
#: Detector parameters whose negative value means "identified online" (None in the config).
_IDENTIFIED = ("detection.latency", "detection.response_time")
PARAMETERS: dict[str, tuple[object, str, dict]] = {
    **parameters.MODEL_PARAMETERS,
    **parameters.THREAD_PRIORITY,
    **parameters.COMMAND_LIMITS,
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
    "brake_free_swinging": (_MONITOR.brake_free_swinging, "declare a free-swinging joint "
                            "locked where it is (ask for its brake) instead of only "
                            "reporting it", {}),
    "remap_commands": (_MONITOR.remap_commands, "remap commands through the reduced "
                       "Jacobian once joints lock", {}),
    "command_timeout": (0.2, "s without a command before the watchdog publishes zeros",
                        parameters.float_range(0.001, 60.0)),
    "velocity_scale": (_MONITOR.velocity_scale, "fraction of the URDF velocity limits for "
                       "remapped commands", parameters.float_range(0.01, 1.0)),
    "state_directory": ("", "directory of the persisted locked set (empty: "
                        "$ROS_HOME/ft_arms, or ~/.ros/ft_arms)", {"read_only": True}),
}


#: The parameters the core's settings come from.
_CORE_PARAMETERS = [*(k for k in PARAMETERS if k.startswith("detection.")),
                    *parameters.COMMAND_LIMITS,
                    "remap_commands", "velocity_scale", "brake_free_swinging"]


class MonitorNode(SuiteNode):
    """The monitor; see the module docstring."""

    def __init__(self, **kwargs):
        super().__init__("monitor", **kwargs)
        parameters.declare(self, PARAMETERS)
        self.scheduling = self.apply_thread_priority()  #: reported in diagnostics
        self.core: Monitor | None = None  #: the logic, once the model is known
        self._order: list[int] = []
        #: `_order` as an index array, None where it is the chain's own (the command as is)
        self._reorder: np.ndarray | None = None
        self.command_joints: list[str] = []  #: joint names in command order
        # Built once per model, refilled for every command (`_publish_command`).
        self._command_writer = wire.CommandWriter([])
        self._array_msg = Float64MultiArray()
        self._last_command = -math.inf
        self._unseen: list[str] = []  #: joints last reported unseen (`Monitor.unseen`)
        self._command_pub, self._command_audience = self.create_counted_publisher(
            JointState, names.COMMAND, qos.RELIABLE)
        self._array_pub, self._array_audience = self.create_counted_publisher(
            Float64MultiArray, names.COMMAND_ARRAY, qos.RELIABLE)
        #: `ft/command` again, at most every ECHO_PERIOD s: the controller's guard hears it
        self._echo_pub, self._echo_audience = self.create_counted_publisher(
            JointState, names.COMMAND_ECHO, qos.RELIABLE)
        self._last_echo = -math.inf  # steady s
        self._locked_pub = self.create_publisher(JointState, names.LOCKED_JOINTS, qos.LATCHED)
        self._diagnostics_pub = self.create_publisher(DiagnosticArray, names.DIAGNOSTICS,
                                                      qos.RELIABLE)
        self._command_subscription = self.subscribe_joint_states(
            names.COMMAND_RAW, self._on_command, qos.SENSOR_INPUT, self._on_malformed_command)
        self.create_subscription(Float64MultiArray, names.COMMAND_RAW_ARRAY, self._on_array,
                                 qos.SENSOR_INPUT)
        self.subscribe_joint_states(names.JOINT_STATES, self._on_state, qos.SENSOR_INPUT)
        #: Also given each joint state (`share_joint_states`; ft-stack).
        self._state_listeners: list[StateListener] = []
        self._command_taker: Callable[[JointStateLike], None] | None = None
        self._taker_reader = wire.JointStateReader()  # the commands it is given, as read
        self.create_subscription(JointState, names.DECLARE_FAILURE, self._on_declare,
                                 qos.RELIABLE)
        self.create_subscription(JointState, names.SUSPECTED_FAILURE, self._on_suspect,
                                 qos.RELIABLE)
        self.create_service(Trigger, names.RESET, self._on_reset)
        self._command_timeout = self.param("command_timeout")
        parameters.on_change(self, self._configs, self._configure)
        parameters.request_model(self, self._set_model)
        # On steady time: with use_sim_time and no /clock the watchdog must still run.
        self._last_command_steady = time.monotonic()
        self._reannounced = -math.inf  # steady time of the last re-announcement (s)
        self._watchdog = self.create_timer(self.param("command_timeout"), self._check_watchdog,
                                           clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.create_timer(DIAGNOSTICS_PERIOD, self._publish_diagnostics)
        # Every joint state announces what was written meanwhile; this, when none comes
        # (the EventsExecutor has no guard conditions for the writer thread to wake it).
        self.create_timer(ANNOUNCE_PERIOD, self._announce_written,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))

    # ------------------------------------------------------------------ set-up
    def _configs(self, changes: dict | None = None) -> tuple[DetectorConfig, MonitorConfig]:
        """The core's settings from the parameters, with `changes` (name: value) applied."""
        value = {**{k: self.param(k) for k in _CORE_PARAMETERS}, **(changes or {})}
        for name in _IDENTIFIED:
            value[name] = None if value[name] < 0 else value[name]
        detection = DetectorConfig(
            window=value["detection.window"], min_command=value["detection.min_command"],
            latency=value["detection.latency"],
            response_time=value["detection.response_time"],
            persistence=value["detection.persistence"], ratio=value["detection.ratio"],
            confidence=value["detection.confidence"],
            follow_time=value["detection.follow_time"])
        return detection, MonitorConfig(
            remap_commands=value["remap_commands"], velocity_scale=value["velocity_scale"],
            brake_free_swinging=value["brake_free_swinging"],
            limits=limits_config(value["smooth_commands"], value["limits.preset"],
                                 value["limits.acceleration"] or (), value["limits.jerk"] or (),
                                 np.asarray(self._order) if self._order else None))

    def _configure(self) -> None:
        self._command_timeout = self.param("command_timeout")
        if self.core is not None:
            self.core.configure(*self._configs())

    def _set_model(self, spec: str, source: str) -> None:
        try:
            robot = robots.load(spec, *parameters.chain_arguments(self))
            order = parameters.joint_order(self, robot.joint_names)
        except (robots.RobotModelError, ValueError) as error:
            self.problems.report("model", f"cannot use the model from {source}: {error}")
            return
        self._order = order.tolist()
        self._reorder = None if self._order == list(range(robot.n)) else order
        joints = self.command_joints = [robot.joint_names[i] for i in self._order]
        self._command_writer = wire.CommandWriter(joints)
        self._array_msg = Float64MultiArray(layout=MultiArrayLayout(dim=[MultiArrayDimension(
            label="joints", size=len(joints), stride=len(joints))]))
        directory, name = self.param("state_directory"), self.get_fully_qualified_name()
        store = locked_set.path_for(directory, name, robot.name, self.context.get_domain_id())
        old = locked_set.unkeyed_path(directory, name, robot.name)
        if old.exists():
            self.get_logger().warning(
                f"{old} (a locked set of an older version, for no particular ROS domain) is "
                "not restored: declare on ft/declare_failure any joint still locked, then "
                "delete the file")
        try:
            core = Monitor(robot, *self._configs(), store, self.problems.report)
        except ValueError as error:  # command limits the model refuses
            self.problems.report("model", f"cannot use the model from {source}: {error}")
            return
        if self.core is not None:
            self.core.close()  # the old robot's last write, if any; its set is not ours now
        self.core = core
        self.get_logger().info(core.smoother.limits.describe() if core.smoother is not None
                               else "commands not smoothed (smooth_commands is false)")
        self.problems.report("model", None)
        self.get_logger().info(f"monitoring {robot.name}: joints {joints}")
        self._announce(self.core.restore(self.now()))
        self._publish_locked(self.now())

    @property
    def robot(self) -> robots.Robot | None:
        """The model in use (the core's), None until one is loaded."""
        return None if self.core is None else self.core.robot

    @property
    def locked(self) -> dict[str, float]:
        """{joint name: position at lock (rad)} of every locked joint, as announced.

        The set on disk (`Monitor.announced`): what `ft/locked_joints` and the
        diagnostics say. The command filter uses the newer set at once.
        """
        return {} if self.core is None else self.core.announced

    # ------------------------------------------------------- one-process wiring
    def take_commands_by_call(
            self) -> Callable[[np.ndarray, Sequence[str], wire.Stamp, float], None]:
        """Stop subscribing to `ft/command_raw`; returns what to call with each command.

        The call takes the velocities (rad/s) of the given joints, the command's stamp and
        the caller's clock time (s): a controller in the same process (ft-stack), whose
        commands need no conversion and no stamp checks (they are made now, on the same
        clock). Velocities for another chain than this model's go by name, as a message.
        """
        self.destroy_subscription(self._command_subscription)
        return self._take_command

    def _take_command(self, qd: np.ndarray, joints: Sequence[str], stamp: wire.Stamp,
                      now: float) -> None:
        if self.core is None:
            return
        if tuple(joints) != self.core.robot.joint_names:
            self._on_command(convert.joint_state(joints, Time(sec=stamp.sec, nanosec=stamp.nanosec),
                                                 velocity=qd))
            return
        self._forward("ft/command_raw", qd, stamp, now)

    def hand_commands_to(self, take: Callable[[JointStateLike], None]) -> None:
        """Give every command to `take` as a call too (a plant in the same process).

        `ft/command` is then published only while someone subscribes to it.
        """
        self._command_taker = take

    def share_joint_states(self, listener: StateListener) -> None:
        """Give `listener` every `joint_states` message this node takes, with its reading.

        Called after this node has observed the state, so a control cycle the listener
        runs (ft-stack) is filtered with the locks that state revealed. The reading is
        (positions in rad, the joints they are of, stamp in s) where the message passed
        this node's checks of the message itself (`parse_joint_state`),
        else None: a node of the same process need not parse it again.
        """
        self._state_listeners.append(listener)

    # ------------------------------------------------------------------ inputs
    def _on_state(self, msg: JointStateLike) -> None:
        core = self.core
        reading = None if core is None else self.parse_joint_state(msg, core.robot.joint_names)
        if reading is not None:
            self._observe(reading)
        for listener in self._state_listeners:  # after: a cycle they run sees this update
            listener(msg, None if reading is None else (reading[0], core.robot.joint_names,
                                                        reading[1]))

    def _observe(self, reading: tuple[np.ndarray, float]) -> None:
        """A joint state that passed `parse_joint_state`, to the detector if accepted."""
        q = self.accept_joint_state(*reading, self.core.absurd)
        if q is None:
            return
        listeners = (self._command_taker is not None or self._command_audience.count
                     or self._array_audience.count)
        stamp = self.state_stamp
        self._announce(self.core.observe(
            q, stamp, None if listeners else "nobody subscribes to ft/command(_array)"))

    def _on_suspect(self, msg: JointState) -> None:
        """A joint the controller's task channel suspects: locked if the measurements agree."""
        if self.core is None or self.core.q is None:
            self.get_logger().warning(f"suspected lock of {list(msg.name)[:3]} not decided: no "
                                      "model or joint state yet", throttle_duration_sec=5.0)
            return
        try:
            known = convert.names_to_indices(list(msg.name)[:convert.MAX_NAMES],
                                             self.core.robot.joint_names)
        except convert.MessageError as error:
            self.get_logger().warning(f"ft/suspected_failure ignored: {error}",
                                      throttle_duration_sec=5.0)
            return
        now = self.now()
        for name, j in known.items():
            answer, change = self.core.suspect(j, now)
            evidence = answer.evidence
            if answer.decision == "refused":
                reason = " at a joint limit" if evidence.at_limit else ""
                self.get_logger().warning(
                    f"suspected lock of {name} not confirmed{reason}: measured "
                    f"{evidence.measured:.4f} rad/s (+-{evidence.standard_error:.4f}), "
                    f"commanded {evidence.commanded:.4f}", throttle_duration_sec=5.0)
            self._announce(change)

    def _on_declare(self, msg: JointState) -> None:
        if self.core is None:
            return
        if (time.monotonic() - self._reannounced < REANNOUNCE_PERIOD
                and len(msg.name) <= len(self.core.detector.locked)
                and set(msg.name) <= self.core.locked.keys()):
            return  # a repeat, already answered this period: a flood costs nothing more
        try:
            known = convert.names_to_indices(list(msg.name), self.core.robot.joint_names)
        except convert.MessageError as error:
            self.get_logger().error(f"ft/declare_failure ignored: {error}",
                                    throttle_duration_sec=5.0)
            return
        if len(known) < len(msg.name):
            self.get_logger().warning(f"ft/declare_failure: {len(msg.name) - len(known)} unknown "
                                      "joint names ignored", throttle_duration_sec=5.0)
        now = self.now()
        before = self.core.locked
        change = self.core.declare(known.values(), now)
        self._announce(change)
        steady = time.monotonic()
        if (self.core.locked == before and not change.changed
                and steady - self._reannounced >= REANNOUNCE_PERIOD):
            self._reannounced = steady
            self._publish_locked(now)  # nothing new, announced again: the sender asked

    def _on_reset(self, _request: Trigger.Request, response: Trigger.Response):
        released = []
        if self.core is not None:
            released = self.core.reset(self.now())  # the empty set is published once written
            self._announce(self.core.settled())
        self.get_logger().info(f"reset: released {released or 'nothing'}")
        response.success, response.message = True, f"released {released or 'nothing'}"
        return response

    def _on_command(self, msg: JointStateLike) -> None:
        if self.core is None:
            return
        now = self.now()
        stamp = self.problems.message_time("ft/command_raw", msg.header.stamp, now)
        try:
            if stamp is None:
                raise convert.MessageError("stamp ahead of the clock")
            if now - stamp > self._command_timeout:
                raise convert.MessageError(f"stale: stamped {now - stamp:.3f} s ago")
            qd = convert.joint_vector(msg, self.core.robot.joint_names, "velocity")
        except convert.MessageError as error:
            self._refuse("ft/command_raw", error, msg.header.stamp, now)
            return
        self._forward("ft/command_raw", qd, msg.header.stamp, now)

    def _on_malformed_command(self, error: convert.MessageError) -> None:
        """Bytes on `ft/command_raw` that are not a JointState: refused, zeros sent instead."""
        if self.core is not None:
            nanoseconds = self.now_ns()
            self._refuse("ft/command_raw", error, wire.Stamp.of(nanoseconds), nanoseconds * 1e-9)

    def _on_array(self, msg: Float64MultiArray) -> None:
        """Velocities in `joints` order (MoveIt Servo's Float64MultiArray output, unstamped)."""
        if self.core is None:
            return
        stamp = self.get_clock().now().to_msg()
        try:
            qd = convert.array_vector(msg.data, self._order)
        except convert.MessageError as error:
            self._refuse("ft/command_raw_array", error, stamp, self.now())
            return
        self._forward("ft/command_raw_array", qd, stamp, self.now())

    def _refuse(self, topic: str, error: Exception | str, stamp: Time | wire.Stamp,
                now: float) -> None:
        """A malformed command: reported, and replaced by zeros (reached on a ramp)."""
        self.problems.report(topic, f"{error}: commanding zeros")
        self._publish_command(self.core.zeros(now), now, stamp)

    def _forward(self, source: str, qd: np.ndarray, stamp: Time | wire.Stamp,
                 now: float) -> None:
        """A well-formed command from `source` (chain order, rad/s), published.

        Filtered by the core; an absurd one (`Monitor.absurd_command`) is refused instead.
        """
        absurd = self.core.absurd_command(qd)
        if absurd is not None:
            self._refuse(source, absurd, stamp, now)
            return
        self.problems.report(source, None)
        self._last_command = now
        self._last_command_steady = time.monotonic()
        self.stop_ramp()
        self._publish_command(self.core.command(qd, now), now, stamp)

    # ----------------------------------------------------------------- outputs
    def _publish_command(self, qd_chain: np.ndarray, now: float,
                         answered: Time | wire.Stamp | None = None) -> None:
        """The command (chain order, rad/s) stamped `now` (s) out on `ft/command` as bytes.

        (`wire.CommandWriter`.) Also as a Float64MultiArray while someone subscribes to
        `ft/command_array`, and on `ft/command_echo` (the controller's guard of a dead
        monitor), stamped as the command it `answered`, at most once per `ECHO_PERIOD` of
        steady time while someone subscribes to it.
        """
        ordered = qd_chain if self._reorder is None else qd_chain[self._reorder]
        stamp = wire.Stamp.of(round(now * 1e9))
        serialized = self._command_writer.serialize(stamp.sec, stamp.nanosec, ordered)
        if self._command_taker is None or self._command_audience.count:
            self._command_pub.publish(serialized)
            if answered is not None and self._echo_audience.count:
                steady = time.monotonic()
                if steady - self._last_echo >= ECHO_PERIOD:
                    self._echo_pub.publish(self._command_writer.serialize(
                        answered.sec, answered.nanosec, ordered))
                    self._last_echo = steady
        if self._command_taker is not None:
            self._command_taker(self._taker_reader.read(serialized))
        if self._array_audience.count:  # a JointGroupVelocityController
            self._array_msg.data = ordered.tolist()
            self._array_pub.publish(self._array_msg)

    def destroy_node(self) -> None:
        """End the locked set's writer thread too (after the write under way, if any).

        Without it each node a process makes and destroys in turn (the campaign's runs)
        left an idle thread behind.
        """
        if self.core is not None:
            self.core.close()
        super().destroy_node()

    def stop(self) -> None:
        """Bring the commands to rest on a ramp, finish writing the locked set (on shutdown)."""
        if self.core is not None:
            bound = self.core.smoother.stop_time() if self.core.smoother is not None else 0.0
            self.ramp_now(self._ramp_step, bound + 0.1)
            self._announce(self.core.close())

    def _ramp_step(self, nanoseconds: int) -> bool:
        """The next command of a stop ramp, stamped `nanoseconds`; whether it is at rest."""
        now = nanoseconds * 1e-9
        self._publish_command(self.core.zeros(now), now)
        return not self.core.stopping

    def _announce_written(self) -> None:
        """Announce the changes of the locked set written since the last announcement."""
        if self.core is not None:
            self._announce(self.core.settled())

    def _announce(self, change: Change) -> None:
        """Log what happened and, if the locked set changed (on disk already), publish it.

        The diagnostics go out at once too (diagnostic_updater's force_update): a swing
        can end at the joint's stop, locked there, within one DIAGNOSTICS_PERIOD.
        """
        for event in change.events:
            self.get_logger().error(event)
        if change.changed:
            self._publish_locked(change.time)
        if change.changed or change.events:
            self._publish_diagnostics()

    def _publish_locked(self, time: float) -> None:
        """The locked set as written (`locked`): never one not yet on disk."""
        msg = convert.locked_message(self.locked,
                                     convert.stamp_from_nanoseconds(round(time * 1e9)))
        self._locked_pub.publish(msg)

    def _check_watchdog(self) -> None:
        if self.core is None:
            return
        age = time.monotonic() - self._last_command_steady
        if age > self._command_timeout and not self._ramp_step(self.now_ns()):
            self.ramp(self._ramp_step)

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
        core = self.core
        swinging = [] if core is None else core.swinging
        values["free_swinging_joints"] = swinging
        if core is not None:
            values.update(core.plant_values())
            values["unseen_joints"] = self._report_unseen(core.unseen(now))
            for name, j in zip(self.command_joints, self._order, strict=True):
                joint = core.joint_report(j)
                level = _LEVELS[joint.state]
                if joint.state == "stalled at a joint limit":
                    stalls.append(name)
                evidence = joint.evidence
                statuses.append(self.status(level, joint.state, {
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
        elif age > self._command_timeout:
            level, message = diagnostics.WARN, "no fresh command: publishing zeros"
        elif core is not None and core.detector.not_observing:
            level, message = diagnostics.OK, f"not observing: {core.detector.not_observing}"
        else:
            level, message = diagnostics.OK, "no locked joint"
        statuses.insert(0, self.status(level, message, values))
        self._diagnostics_pub.publish(diagnostics.array(statuses, self.get_clock().now().to_msg()))

    def _report_unseen(self, unseen: list[str]) -> list[str]:
        """Say (INFO) when joints become unseen, so a lock nobody reports has a reason.

        Once per joint that joins the unseen ones (not again as others leave them).
        """
        if set(unseen) - set(self._unseen):
            self.get_logger().info(
                f"a lock of {unseen} cannot be seen now: not commanded for "
                f"{UNSEEN_AFTER:.0f} s or more (a lock shows only while its joint is commanded; "
                "the controller's observability.enabled excites idle joints)")
        self._unseen = unseen
        return unseen


#: Diagnostic level of each joint state of `Monitor.joint_report`.
_LEVELS = {"ok": diagnostics.OK, "locked": diagnostics.ERROR,
           "free-swinging": diagnostics.ERROR, "stalled at a joint limit": diagnostics.WARN}


def main(args: list[str] | None = None) -> None:
    """Run the monitor until SIGINT, then command zero velocity and exit."""
    spin.run_node(MonitorNode, args)


if __name__ == "__main__":
    main()
