"""The monitor's publications: every command it forwards, its echo, and the locked set.

Each command goes out as bytes on `ft/command` (`wire.CommandWriter`), as a
Float64MultiArray on `ft/command_array` while someone subscribes (a
JointGroupVelocityController), and to a plant of the same process as a call
(`Outputs.taker`; `ft/command` then only while someone subscribes). The echo on
`ft/command_echo` (the controller's guard of a dead monitor) carries the stamp of the
command it answers, at most once per `ECHO_PERIOD` of steady time while someone
subscribes; while the controller's guard commands the plant, the echo alone goes out
(`ft_monitor.handover`). The locked set goes on `ft/locked_joints` and every joint's
health on `ft/joint_health` (both transient local).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from ft_core.health import JointHealth
from ft_core.robots import Robot
from ft_msgs_py import convert, health, names, qos, wire
from ft_msgs_py.monitor_guard import ECHO_PERIOD
from ft_msgs_py.node import JointStateLike, SuiteNode
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension, MultiArrayLayout


class Wiring:
    """A model's command order and the messages built once for it.

    Attributes:
        order: chain index of each joint of the command order.
        reorder: `order` as an index array, None where it is the chain's own.
        joints: joint names in command order.
        writer: the command's bytes, refilled for every command.
        array: `ft/command_array`'s message, refilled for every command.
    """

    def __init__(self, robot: Robot, order: np.ndarray):
        self.order: list[int] = order.tolist()
        self.reorder = None if self.order == list(range(robot.n)) else order
        self.joints = [robot.joint_names[i] for i in self.order]
        self.writer = wire.CommandWriter(self.joints)
        self.array = Float64MultiArray(layout=MultiArrayLayout(dim=[MultiArrayDimension(
            label="joints", size=len(self.joints), stride=len(self.joints))]))


class Outputs:
    """The monitor node's publishers, and how each output goes out."""

    def __init__(self, node: SuiteNode):
        self.command, self.command_audience = node.create_counted_publisher(
            JointState, names.COMMAND, qos.RELIABLE)
        self.array, self.array_audience = node.create_counted_publisher(
            Float64MultiArray, names.COMMAND_ARRAY, qos.RELIABLE)
        self._echo, self._echo_audience = node.create_counted_publisher(
            JointState, names.COMMAND_ECHO, qos.RELIABLE)
        self._last_echo = -math.inf  # steady s
        self._locked = node.create_publisher(JointState, names.LOCKED_JOINTS, qos.LATCHED)
        self._health = node.create_publisher(DiagnosticArray, names.JOINT_HEALTH, qos.LATCHED)
        self.diagnostics = node.create_publisher(DiagnosticArray, names.DIAGNOSTICS,
                                                 qos.RELIABLE)
        #: Also given every command as a call (a plant in the same process), or None.
        self.taker: Callable[[JointStateLike], None] | None = None
        self._taker_reader = wire.JointStateReader()  # the commands it is given, as read

    @property
    def heard(self) -> bool:
        """Whether anyone takes the commands (a subscriber, or a taker in-process)."""
        return bool(self.taker is not None or self.command_audience.count
                    or self.array_audience.count)

    def send(self, wiring: Wiring, qd_chain: np.ndarray, now: float,
             answered: Time | wire.Stamp | None = None,
             late: Callable[[], bool] = lambda: False) -> bool:
        """The command (chain order, rad/s) stamped `now` (s), echoed as `answered`.

        Nothing goes out if `late()`, asked once the message is ready (the last moment
        before the publishers); returns whether the command went out.
        """
        ordered = qd_chain if wiring.reorder is None else qd_chain[wiring.reorder]
        stamp = wire.Stamp.of(round(now * 1e9))
        serialized = wiring.writer.serialize(stamp.sec, stamp.nanosec, ordered)
        if self.array_audience.count:
            wiring.array.data = ordered.tolist()
        if late():
            return False
        if self.taker is None or self.command_audience.count:
            self.command.publish(serialized)
            if answered is not None:
                self._echo_ordered(wiring, ordered, answered)
        if self.taker is not None:
            self.taker(self._taker_reader.read(serialized))
        if self.array_audience.count:
            self.array.publish(wiring.array)
        return True

    def echo(self, wiring: Wiring, qd_chain: np.ndarray, answered: Time | wire.Stamp) -> None:
        """The echo alone: the command stamped `answered` came, the plant holds `qd_chain`."""
        self._echo_ordered(
            wiring, qd_chain if wiring.reorder is None else qd_chain[wiring.reorder], answered)

    def _echo_ordered(self, wiring: Wiring, ordered: np.ndarray,
                      answered: Time | wire.Stamp) -> None:
        """`ft/command_echo` (command order), at most once per `ECHO_PERIOD`, if heard."""
        if self._echo_audience.count:
            steady = time.monotonic()
            if steady - self._last_echo >= ECHO_PERIOD:
                self._echo.publish(wiring.writer.serialize(
                    answered.sec, answered.nanosec, ordered))
                self._last_echo = steady

    def send_locked(self, locked: dict[str, float], time: float) -> None:
        """The locked set ({joint: position at lock, rad}) stamped `time` (s)."""
        self._locked.publish(convert.locked_message(
            locked, convert.stamp_from_nanoseconds(round(time * 1e9))))

    def send_health(self, joints: dict[str, JointHealth], stamp: Time, robot: str) -> None:
        """Every joint's health ({joint: health}, in the order to publish) on `ft/joint_health`."""
        self._health.publish(health.message(joints, stamp, robot))
