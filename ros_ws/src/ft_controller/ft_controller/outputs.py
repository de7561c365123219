"""The controller's publications: its command, the guard's stop, metrics and suspects.

The command goes out as bytes (`wire.CommandWriter`) on `ft/command_raw`, or as a call to
a monitor of the same process (`Outputs.taker`, ft-stack) and then on the topic only
while someone else subscribes; the metrics only while someone subscribes (a recorder, a
plot). The guard's stop goes on the plant's own topics, `ft/command` and
`ft/command_array`, while the monitor does not answer, and on `ft/command_guard` for the
monitor: a monitor that answers again sends nothing while the guard commands, then goes on
from the guard's last command (`ft_monitor.command_path`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from ft_core.engine import CycleResult
from ft_msgs_py import convert, markers, metrics, names, qos, wire
from ft_msgs_py.node import SuiteNode
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, Header
from visualization_msgs.msg import MarkerArray

from ft_controller.loaded import Loaded, metric_values, view

#: What takes each command by a call (`ControllerNode.hand_commands_to`): (velocities in
#: rad/s, the joints they are for, the stamp, the node clock's time in s).
CommandTaker = Callable[[np.ndarray, Sequence[str], wire.Stamp, float], None]


class Outputs:
    """The controller node's publishers, and how each output goes out."""

    def __init__(self, node: SuiteNode):
        self.command, self._command_audience = node.create_counted_publisher(
            JointState, names.COMMAND_RAW, qos.RELIABLE)
        self._plant = node.create_publisher(JointState, names.COMMAND, qos.RELIABLE)
        self._plant_array = node.create_publisher(Float64MultiArray, names.COMMAND_ARRAY,
                                                  qos.RELIABLE)
        #: The guard's commands for the monitor (none in ft-stack: no guard there).
        self.guard = node.create_publisher(JointState, names.COMMAND_GUARD, qos.RELIABLE)
        self._metrics, self._metrics_audience = node.create_counted_publisher(
            Float64MultiArray, names.METRICS, qos.RELIABLE)
        self._suspect = node.create_publisher(JointState, names.SUSPECTED_FAILURE, qos.RELIABLE)
        self.diagnostics = node.create_publisher(DiagnosticArray, names.DIAGNOSTICS,
                                                 qos.RELIABLE)
        self.markers = node.create_publisher(MarkerArray, names.MARKERS, qos.RELIABLE)
        #: Takes each command as a call (ft-stack), or None.
        self.taker: CommandTaker | None = None

    def send(self, loaded: Loaded, qd_chain: np.ndarray, nanoseconds: int,
             ) -> tuple[wire.Stamp, np.ndarray] | None:
        """The command (chain order, rad/s) stamped `nanoseconds` (node clock).

        Returns its stamp and velocities (command order) where it went out on the topic
        for the monitor to answer, None where a taker got it.
        """
        stamp = wire.Stamp.of(nanoseconds)
        taker = self.taker
        if taker is None or self._command_audience.count:
            velocity = qd_chain[loaded.order]
            self.command.publish(loaded.writer.serialize(*stamp, velocity))
        if taker is None:
            return stamp, velocity
        taker(qd_chain, loaded.robot.joint_names, stamp, nanoseconds * 1e-9)
        return None

    def send_metrics(self, loaded: Loaded, result: CycleResult) -> None:
        """A cycle's `ft/metrics`, only while someone subscribes."""
        if self._metrics_audience.count:
            metrics.fill(loaded.metrics_msg, metric_values(result, loaded.order))
            self._metrics.publish(loaded.metrics_msg)

    def send_to_plant(self, loaded: Loaded, velocity: list[float], nanoseconds: int) -> None:
        """The guard's command (command order) on the plant's topics, past the monitor.

        And the same on `ft/command_guard`, for the monitor to hand over from.
        """
        msg = convert.joint_state(loaded.joints, convert.stamp_from_nanoseconds(nanoseconds),
                                  velocity=velocity)
        self._plant.publish(msg)
        self._plant_array.publish(Float64MultiArray(data=velocity))
        self.guard.publish(msg)

    def send_suspect(self, joint: str, nanoseconds: int) -> None:
        """The joint the task channel suspects, on `ft/suspected_failure`."""
        self._suspect.publish(JointState(header=Header(
            stamp=convert.stamp_from_nanoseconds(nanoseconds)), name=[joint]))

    def send_view(self, loaded: Loaded, q: np.ndarray, critical_points: list[float],
                  stamp) -> None:
        """The live view at `q` (`loaded.view`), only while someone subscribes."""
        if self.markers.get_subscription_count():
            self.markers.publish(markers.array(
                loaded.robot.base_link, stamp,
                lambda header: view(loaded, q, critical_points, header)))
