"""Every topic of a run kept as a rosbag2 in MCAP, for Foxglove, PlotJuggler or `ros2 bag`.

A recorder subscribes to the suite's topics with the raw (serialised CDR) messages
and writes them unchanged with the `rosbags` library, which also writes the
`metadata.yaml` that `ros2 bag info` and `ros2 bag play` read. Messages are stamped
with the simulated time the run owns (the recording time of `ros2 bag record
--use-sim-time`). Message definitions come from rosbags' Jazzy type store, and
`metadata.yaml` names that distro (rosbags writes its own name there; the copy of the
metadata inside the MCAP file keeps it).
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import yaml
from diagnostic_msgs.msg import DiagnosticArray
from ft_msgs_py import names, qos
from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from visualization_msgs.msg import Marker

#: The ROS 2 distro of the message definitions (rosbags' type store) and of the metadata.
DISTRO = "jazzy"
STORE = Stores.ROS2_JAZZY
#: (topic, type, QoS of the subscription) of everything a run publishes.
TOPICS = (
    (names.JOINT_STATES, JointState, qos.SENSOR_INPUT),
    (names.TARGET_POSE, PoseStamped, qos.RELIABLE),
    (names.COMMAND_RAW, JointState, qos.SENSOR_INPUT),
    (names.COMMAND, JointState, qos.SENSOR_INPUT),
    (names.LOCKED_JOINTS, JointState, qos.LATCHED),
    (names.INJECT_FAILURE, JointState, qos.RELIABLE),
    (names.INJECT_FAULT, DiagnosticArray, qos.RELIABLE),
    (names.OBSTACLE, Marker, qos.RELIABLE),
    (names.JOINT_HEALTH, DiagnosticArray, qos.LATCHED),
    (names.METRICS, Float64MultiArray, qos.RELIABLE),
    (names.DIAGNOSTICS, DiagnosticArray, qos.RELIABLE),
)


def type_name(message_type: type) -> str:
    """'sensor_msgs/msg/JointState' for the rclpy class of that message."""
    return f"{message_type.__module__.split('.')[0]}/msg/{message_type.__name__}"


class Recorder:
    """Writes `TOPICS`, as `node` sees them, to a new rosbag2 (MCAP) folder at `path`.

    An existing folder at `path` (an interrupted earlier run) is replaced. `now`
    gives the time messages are logged at (ns). Call `close` to finish the file.
    """

    def __init__(self, node: Node, path: Path, now: Callable[[], int]):
        if path.exists():
            shutil.rmtree(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        self._now, self._path = now, path
        self._writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        store = get_typestore(STORE)
        for topic, message_type, profile in TOPICS:
            resolved = node.resolve_topic_name(topic)
            connection = self._writer.add_connection(resolved, type_name(message_type),
                                                     typestore=store)
            node.create_subscription(
                message_type, topic,
                lambda data, c=connection: self._writer.write(c, self._now(), data),
                profile, raw=True)

    def close(self) -> None:
        """Finish the file (its index and metadata), the metadata naming `DISTRO`."""
        self._writer.close()
        metadata = self._path / "metadata.yaml"
        content = yaml.safe_load(metadata.read_text())
        content["rosbag2_bagfile_information"]["ros_distro"] = DISTRO
        written = metadata.with_suffix(".yaml.tmp")
        written.write_text(yaml.safe_dump(content, sort_keys=False))
        written.replace(metadata)
