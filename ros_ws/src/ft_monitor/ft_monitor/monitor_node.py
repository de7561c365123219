"""monitor_node: detect locked joints and keep the task going around them.

Inputs: `ft/command_raw` (what a controller commands; or `ft/command_raw_array`, as
MoveIt Servo publishes it) and `joint_states` (what happened). Every command goes out on
`ft/command` and `ft/command_array` (`ft_monitor.outputs`), filtered by the core
(`ft_core.monitor.Monitor`: locked joints at exactly 0, the rest remapped through the
reduced Jacobian with `remap_commands`, scaled into `velocity_scale` of the URDF limits
and smoothed into the arm's acceleration and jerk limits). Detection
(`ft_core.detection`) compares the measured motion with what a model of the plant
predicts from the commands this node sent, stamped with its own clock. The locked set
is written under `state_directory` (`ft_core.locked_set`) before it goes out on
`ft/locked_joints`; `~/reset` releases it, `ft/declare_failure` adds to it. A malformed
command is replaced by zeros; with no fresh command for `command_timeout` the watchdog
brings the commands to rest on a ramp within the limits, as on shutdown. The node wires;
topics, parameters, rules and reactions: docs/monitor.md and docs/detection.md.
"""

from __future__ import annotations

import functools
import math
import threading
import time
import weakref
from collections.abc import Callable, Sequence

import numpy as np
from builtin_interfaces.msg import Time
from ft_core import locked_set, robots
from ft_core.announcements import Change
from ft_core.detection import Decision
from ft_core.monitor import Monitor
from ft_msgs_py import (
    convert,
    diagnostics,
    names,
    parameter_table,
    parameters,
    publishers,
    qos,
    spin,
    wire,
)
from ft_msgs_py.node import JointStateLike, StateListener, SuiteNode
from rclpy.clock import Clock, ClockType
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from ft_monitor import report, settings
from ft_monitor.command_path import CommandPath
from ft_monitor.outputs import Outputs, Wiring
from ft_monitor.settings import PARAMETERS

DIAGNOSTICS_PERIOD = 0.5
#: s (steady) between two re-announcements of an unchanged locked set asked for on
#: `ft/declare_failure`: a flood of declarations costs one publication per period, and
#: the latched topic gives a late subscriber the set anyway.
REANNOUNCE_PERIOD = 0.1


class MonitorNode(SuiteNode):
    """The monitor; see the module docstring."""

    def __init__(self, **kwargs):
        super().__init__("monitor", **kwargs)
        parameter_table.declare(self, PARAMETERS)
        self.scheduling = self.apply_thread_priority()  #: reported in diagnostics
        self.core: Monitor | None = None  #: the logic, once the model is known
        self.wiring: Wiring | None = None  #: the model's command order, built with the core
        self._unseen = report.Unseen(self.get_logger().info)
        #: Held while the core hands changes over and they are announced: the executor's
        #: callbacks and the locked set's writer thread (`_announce_written`) take turns.
        self._announcing = threading.RLock()
        self._closed = False  #: destroyed: the writer thread announces nothing more
        self.outputs = Outputs(self)
        self._command_subscription = self.subscribe_joint_states(
            names.COMMAND_RAW, self._on_command, qos.SENSOR_INPUT, self._on_malformed_command)
        self.create_subscription(Float64MultiArray, names.COMMAND_RAW_ARRAY, self._on_array,
                                 qos.SENSOR_INPUT)
        self.subscribe_joint_states(names.JOINT_STATES, self._on_state, qos.SENSOR_INPUT)
        #: Also given each joint state (`share_joint_states`; ft-stack).
        self._state_listeners: list[StateListener] = []
        # Declarations and suspicions as bytes, as the commands: a flood of them costs a
        # third of what rclpy's message objects do, and leaves the executor's queue short.
        for topic, callback in ((names.DECLARE_FAILURE, self._on_declare),
                                (names.SUSPECTED_FAILURE, self._on_suspect)):
            self.subscribe_joint_states(topic, callback, qos.RELIABLE,
                                        functools.partial(self._on_malformed, topic))
        self.create_service(Trigger, names.RESET, self._on_reset)
        self.commands = CommandPath(self.outputs, self.problems, self.param("command_timeout"),
                                    self.stop_ramp, self.now)
        handover = self.commands.handover
        handover.take_guard = self.take_on_demand(self.subscribe_joint_states(
            names.COMMAND_GUARD, self._on_guard, qos.RELIABLE, publishers=handover.guards))
        handover.wall_time = not self.param("use_sim_time")
        parameter_table.on_change(self, PARAMETERS, self._check, self._configure)
        parameters.request_model(self, self._set_model)
        # On steady time: with use_sim_time and no /clock the watchdog must still run.
        self._reannounced = -math.inf  # steady time of the last re-announcement (s)
        self._watchdog = self.create_timer(self.param("command_timeout"), self._check_watchdog,
                                           clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.create_timer(DIAGNOSTICS_PERIOD, self._publish_diagnostics)

    # ------------------------------------------------------------------ set-up
    def _order(self) -> np.ndarray | None:
        return None if self.wiring is None else np.asarray(self.wiring.order)

    def _check(self, values: dict) -> None:
        settings.configs(values, self._order())

    def _configure(self, _changed: set[str]) -> None:
        self.commands.timeout = self.param("command_timeout")
        if self.core is not None:
            self.core.configure(*settings.configs(parameter_table.values(self, PARAMETERS),
                                                  self._order()))

    def _set_model(self, spec: str, source: str) -> None:
        try:
            robot = robots.load(spec, *parameters.chain_arguments(self))
            order = parameters.joint_order(self, robot.joint_names)
        except (robots.RobotModelError, ValueError) as error:
            self.problems.report("model", f"cannot use the model from {source}: {error}")
            return
        directory, name = self.param("state_directory"), self.get_fully_qualified_name()
        store = locked_set.path_for(directory, name, robot.name, self.context.get_domain_id())
        old = locked_set.unkeyed_warning(directory, name, robot.name)
        if old is not None:
            self.get_logger().warning(old)
        try:
            core = Monitor(robot, *settings.configs(parameter_table.values(self, PARAMETERS),
                                                    order), store, self.problems.report,
                           _weakly(self._announce_written))
        except ValueError as error:  # command limits the model refuses
            self.problems.report("model", f"cannot use the model from {source}: {error}")
            return
        with self._announcing:
            if self.core is not None:
                self.core.close()  # the old robot's last write, if any; its set is not ours
            self.core, self.wiring = core, Wiring(robot, order)
            self.get_logger().info(core.smoother.limits.describe() if core.smoother is not None
                                   else "commands not smoothed (smooth_commands is false)")
            self.problems.report("model", None)
            self.get_logger().info(f"monitoring {robot.name}: joints {self.wiring.joints}")
            self._announce(self.core.restore(self.now()))
            self.outputs.send_locked(self.locked, self.now())

    @property
    def robot(self) -> robots.Robot | None:
        """The model in use (the core's), None until one is loaded."""
        return None if self.core is None else self.core.robot

    @property
    def command_joints(self) -> list[str]:
        """Joint names in command order (empty before a model)."""
        return [] if self.wiring is None else self.wiring.joints

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
        """Stop subscribing to `ft/command_raw`; returns what a controller in-process calls.

        With (velocities in rad/s, their joints, the stamp, the caller's time in s).
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
        self.commands.forward(self.core, self.wiring, "ft/command_raw", qd, stamp, now)

    def hand_commands_to(self, take: Callable[[JointStateLike], None]) -> None:
        """Give every command to `take` as a call too (`Outputs.taker`; a plant in-process)."""
        self.outputs.taker = take

    def share_joint_states(self, listener: StateListener) -> None:
        """Give `listener` every `joint_states` message, with its reading, once observed.

        So a cycle the listener runs (ft-stack) is filtered with the locks that state
        revealed. The reading is None where the message failed `parse_joint_state`.
        """
        self._state_listeners.append(listener)

    # ------------------------------------------------------------------ inputs
    def _on_state(self, msg: JointStateLike) -> None:
        core = self.core
        reading = None if core is None else self.parse_joint_state(msg, core.robot.joint_names)
        if reading is not None:
            q = self.accept_joint_state(*reading, core.absurd)
            if q is not None:
                efforts = self._efforts(msg)
                with self._announcing:
                    self._announce(core.observe(q, self.state_stamp, None if self.outputs.heard
                                                else "nobody subscribes to ft/command(_array)",
                                                efforts))
        for listener in self._state_listeners:  # after: a cycle they run sees this update
            listener(msg, None if reading is None else (reading[0], core.robot.joint_names,
                                                        reading[1]))

    def _efforts(self, msg: JointStateLike) -> np.ndarray | None:
        """The joints' efforts (N m, chain order) where the joint state has them, else None.

        Efforts are optional (many drivers leave them empty); unusable ones are said, at
        most every 5 s, and not used.
        """
        if not len(msg.effort):
            return None
        try:
            return convert.joint_vector(msg, self.core.robot.joint_names, "effort")
        except convert.MessageError as error:
            self.get_logger().warning(f"joint_states efforts ignored: {error}",
                                      throttle_duration_sec=5.0)
            return None

    def _on_suspect(self, msg: JointStateLike) -> None:
        """A joint the controller's task channel suspects: locked if the measurements agree."""
        if self.core is None or self.core.q is None:
            self.get_logger().warning(f"suspected lock of {list(msg.name)[:3]} not decided: no "
                                      "model or joint state yet", throttle_duration_sec=5.0)
            return
        known = self._names(msg, "ft/suspected_failure", limit=convert.MAX_NAMES)
        now = self.now()
        for name, j in (known or {}).items():
            with self._announcing:
                answer, change = self.core.suspect(j, now)
                self._announce(change)
            evidence = answer.evidence
            if answer.decision == Decision.REFUSED:
                reason = " at a joint limit" if evidence.at_limit else ""
                self.get_logger().warning(
                    f"suspected lock of {name} not confirmed{reason}: measured "
                    f"{evidence.measured:.4f} rad/s (+-{evidence.standard_error:.4f}), "
                    f"commanded {evidence.commanded:.4f}", throttle_duration_sec=5.0)

    def _names(self, msg: JointStateLike, topic: str, limit: int | None = None,
               log: Callable[..., object] | None = None) -> dict[str, int] | None:
        """The message's joint names that are the model's (name -> chain index), or None.

        None where the message is refused, said with `log` (default: a warning).
        """
        try:
            return convert.names_to_indices(list(msg.name)[:limit], self.core.robot.joint_names)
        except convert.MessageError as error:
            (log or self.get_logger().warning)(f"{topic} ignored: {error}",
                                               throttle_duration_sec=5.0)
            return None

    def _on_malformed(self, topic: str, error: convert.MessageError) -> None:
        self.get_logger().error(f"{topic} ignored: {error}", throttle_duration_sec=5.0)

    def _on_declare(self, msg: JointStateLike) -> None:
        if self.core is None:
            return
        if (time.monotonic() - self._reannounced < REANNOUNCE_PERIOD
                and len(msg.name) <= len(self.core.detector.locked)
                and set(msg.name) <= self.core.locked.keys()):
            return  # a repeat, already answered this period: a flood costs nothing more
        known = self._names(msg, "ft/declare_failure", log=self.get_logger().error)
        if known is None:
            return
        if len(known) < len(msg.name):
            self.get_logger().warning(f"ft/declare_failure: {len(msg.name) - len(known)} unknown "
                                      "joint names ignored", throttle_duration_sec=5.0)
        with self._announcing:
            now, before = self.now(), self.core.locked
            change = self.core.declare(known.values(), now)
            self._announce(change)
            steady = time.monotonic()
            if (self.core.locked == before and not change.changed
                    and steady - self._reannounced >= REANNOUNCE_PERIOD):
                self._reannounced = steady
                self.outputs.send_locked(self.locked, now)  # nothing new: the sender asked

    def _on_reset(self, _request: Trigger.Request, response: Trigger.Response):
        released = []
        if self.core is not None:
            with self._announcing:
                released = self.core.reset(self.now())  # the empty set: published once written
                self._announce(self.core.settled())
        self.get_logger().info(f"reset: released {released or 'nothing'}")
        response.success, response.message = True, f"released {released or 'nothing'}"
        return response

    def _on_command(self, msg: JointStateLike) -> None:
        if self.core is not None:
            self.commands.command(self.core, self.wiring, msg, self.now())

    def _on_malformed_command(self, error: convert.MessageError) -> None:
        """Bytes on `ft/command_raw` that are not a JointState: refused, zeros sent instead."""
        if self.core is not None:
            nanoseconds = self.now_ns()
            self.commands.refuse(self.core, self.wiring, "ft/command_raw", error,
                                 wire.Stamp.of(nanoseconds), nanoseconds * 1e-9)

    def _on_guard(self, msg: JointStateLike) -> None:
        """A command of the controller's guard (`ft_monitor.handover`), if obeyed.

        Obeyed from the one publisher of `ft/command_guard` that publishes on `ft/command`
        too (asked of the graph as the guard starts, not at each of its commands): any
        other can already command the plant, or can not, and is reported and ignored.
        """
        core = self.core
        if core is None:
            return
        now = self.now()
        stamp = self.problems.message_time(names.COMMAND_GUARD, msg.header.stamp, now)
        try:
            if stamp is None:
                return
            qd = convert.joint_vector(msg, core.robot.joint_names, "velocity")
            if not self.commands.handover.guarded_lately(time.monotonic()):
                guards = self._publisher_names(names.COMMAND_GUARD)
                if len(guards) != 1 or guards[0] not in self._publisher_names(names.COMMAND):
                    raise convert.MessageError(f"published by {guards[:5]}, not by one node "
                                               "that publishes ft/command too")
        except convert.MessageError as error:
            self.problems.report(names.COMMAND_GUARD, f"{error}: ignored")
            return
        self.problems.report(names.COMMAND_GUARD, None)
        self.commands.guarded(core, qd, stamp)

    def _publisher_names(self, topic: str) -> list[str]:
        """Full names of the nodes publishing `topic`."""
        return [publishers.full_name(p.node_namespace, p.node_name)
                for p in self.get_publishers_info_by_topic(self.resolve_topic_name(topic))]

    def _on_array(self, msg: Float64MultiArray) -> None:
        if self.core is not None:
            self.commands.array(self.core, self.wiring, msg, self.get_clock().now().to_msg(),
                                self.now())

    # ----------------------------------------------------------------- outputs
    def destroy_node(self) -> None:
        """End the locked set's writer thread too (after the write under way, if any)."""
        with self._announcing:
            if self.core is not None:
                self.core.close()
            self._closed = True
        super().destroy_node()

    def stop(self) -> None:
        """Bring the commands to rest on a ramp, finish writing the locked set (on shutdown)."""
        if self.core is not None:
            bound = self.core.smoother.stop_time() if self.core.smoother is not None else 0.0
            self.ramp_now(self._ramp_step, bound + 0.1)
            with self._announcing:
                self._announce(self.core.close())

    def _ramp_step(self, nanoseconds: int) -> bool:
        """The next command of a stop ramp, stamped `nanoseconds`; whether it is at rest."""
        return self.commands.stop_step(self.core, self.wiring, nanoseconds * 1e-9)

    def _announce_written(self) -> None:
        """Announce the changes of the locked set written since the last announcement.

        Called in the writer's thread as each write ends: the announcement goes out then,
        not at the next joint state (there may be none: a stopped driver) or timer tick.
        """
        with self._announcing:
            if self.core is not None and not self._closed:
                self._announce(self.core.settled())

    def _announce(self, change: Change) -> None:
        """Log what happened and, if the locked set changed (on disk already), publish it.

        The diagnostics go out at once too (diagnostic_updater's force_update): a swing
        can end at the joint's stop, locked there, within one DIAGNOSTICS_PERIOD.
        """
        for event in change.events:
            self.get_logger().error(event)
        if change.changed:
            self.outputs.send_locked(self.locked, change.time)
        if change.changed or change.events:
            self._publish_diagnostics()

    def _check_watchdog(self) -> None:
        if self.core is None:
            return
        age = time.monotonic() - self.commands.last_steady
        if age > self.commands.timeout and not self._ramp_step(self.now_ns()):
            self.ramp(self._ramp_step)

    def _publish_diagnostics(self) -> None:
        with self._announcing:  # also from the writer's thread (`_announce`)
            self._publish_diagnostics_now()

    def _publish_diagnostics_now(self) -> None:
        now = self.now()
        age = now - self.commands.last
        values = {"locked_joints": sorted(self.locked),
                  "remap_commands": self.param("remap_commands"),
                  "command_age_s": age if math.isfinite(age) else "none",
                  "scheduling": self.scheduling}
        if self.core is not None:
            values["unseen_joints"] = self._unseen.update(self.core.unseen(now))
        statuses = report.statuses(
            self.core, self.command_joints, [] if self.wiring is None else self.wiring.order,
            values, self.problems.summary() if self.problems.active else None,
            age > self.commands.timeout, self.status)
        stamp = self.get_clock().now().to_msg()
        self.outputs.diagnostics.publish(diagnostics.array(statuses, stamp))
        if self.core is not None and self.wiring is not None:
            joints = self.core.health()
            self.outputs.send_health({name: joints[name] for name in self.wiring.joints},
                                     stamp, self.core.robot.name)


def _weakly(method: Callable[[], None]) -> Callable[[], None]:
    """`method`, called while its object lives: a thread holding this keeps nothing alive.

    The writer's thread outlives a node that is never destroyed (a test's), and a node
    kept alive keeps its context's participant, and its latched messages, on the graph.
    """
    reference = weakref.WeakMethod(method)

    def call() -> None:
        bound = reference()
        if bound is not None:
            bound()

    return call


def main(args: list[str] | None = None) -> None:
    """Run the monitor until SIGINT, then command zero velocity and exit."""
    spin.run_node(MonitorNode, args)


if __name__ == "__main__":
    main()
