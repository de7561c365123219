"""A bare rclpy node doing only what ft-stack must do with the plant: the floor of `layouts.py`.

    python bench/rclpy_floor.py

It takes `joint_states` and, on each, publishes a `JointState` of zero velocities for its
joints on `ft/command` (as `ft-stack` runs its control cycle on each joint state), on the
suite's own executor loop (`ft_msgs_py.spin.run_node`: rclpy's EventsExecutor), with the
suite's QoS, both messages as bytes read and written as the suite's nodes do
(`ft_msgs_py.wire`).
No control, no filtering, no detection: its CPU per cycle is what one message in and one
message out cost a Python node at the sim's rate, below which no Python controller and
monitor can go (docs/benchmarks.md, issue 28). `-p` overrides (the layouts' common
arguments) are ignored.
"""

from __future__ import annotations

import numpy as np
from ft_msgs_py import names, qos, spin, wire
from rclpy.node import Node
from sensor_msgs.msg import JointState


class FloorNode(Node):
    """Joint states in, a zero velocity command out for each."""

    def __init__(self) -> None:
        super().__init__("rclpy_floor")
        self._joints: tuple[str, ...] = ()
        self._writer = wire.CommandWriter([])
        self._reader = wire.JointStateReader()
        self._clock_handle = self.get_clock().handle
        self._publisher = self.create_publisher(JointState, names.COMMAND, qos.RELIABLE)
        self.create_subscription(JointState, names.JOINT_STATES, self._on_state,
                                 qos.SENSOR_INPUT, raw=True)

    def _on_state(self, raw: bytes) -> None:
        joints = self._reader.read(raw).name
        if joints != self._joints:
            self._joints, self._writer = joints, wire.CommandWriter(joints)
        stamp = wire.Stamp.of(self._clock_handle.get_now().nanoseconds)
        self._publisher.publish(self._writer.serialize(*stamp, np.zeros(len(self._joints))))


if __name__ == "__main__":
    spin.run_node(FloorNode)
