"""`ft-demo --live`: the run served to Foxglove as it happens, and the layout to watch it.

A WebSocket server of the `foxglove-sdk` library (Foxglove's own, on PyPI) forwards
every topic of the run unchanged: a raw subscription per topic hands the serialised
(CDR) message to a channel that carries its `ros2msg` definition (from rosbags' Jazzy
type store, as in the recordings), so Foxglove decodes and draws them as it does on a
ROS 2 graph: the sim's and the controller's `~/markers` in a 3D panel, the metrics in
plots. The server listens on localhost only (over a network: an SSH tunnel to the port).
`layout` builds the Foxglove layout (`docs/foxglove_layout.json` is its output for the
Panda) with the SDK's layout classes.
"""

from __future__ import annotations

import json
import threading

import foxglove
from foxglove import layouts
from ft_msgs_py import names, qos
from rclpy.node import Node
from rosbags.typesys import get_typestore
from visualization_msgs.msg import MarkerArray

from ft_sim.bag import STORE, TOPICS, type_name

#: The markers of the two nodes that draw them (`ft_msgs_py.markers`), beside `bag.TOPICS`.
MARKER_TOPICS = tuple((f"{node}/{names.MARKERS.removeprefix('~/')}", MarkerArray, qos.RELIABLE)
                      for node in ("sim", "controller"))
#: The port Foxglove suggests for a WebSocket connection.
DEFAULT_PORT = 8765


class _Viewers(foxglove.ServerListener):
    """Notes that a client subscribed to something."""

    def __init__(self):
        self.subscribed = threading.Event()

    def on_subscribe(self, client, channel) -> None:
        self.subscribed.set()


class LiveServer:
    """Serves every topic `node` sees (`bag.TOPICS` and `MARKER_TOPICS`) on `port`.

    Port 0 takes a free one (`port` then says which); a port taken raises OSError. Call
    `close` to stop.
    """

    def __init__(self, node: Node, port: int = DEFAULT_PORT):
        self._context = foxglove.Context()
        self._viewers = _Viewers()
        try:
            self._server = foxglove.start_server(name="ft-arms", host="127.0.0.1", port=port,
                                                 server_listener=self._viewers,
                                                 context=self._context)
        except RuntimeError as error:  # the SDK's FoxgloveError: the port is taken
            raise OSError(f"cannot serve the live view on port {port}: {error}") from error
        store = get_typestore(STORE)
        for topic, message_type, profile in (*TOPICS, *MARKER_TOPICS):
            name = type_name(message_type)
            definition, _ = store.generate_msgdef(name, ros_version=2)
            channel = foxglove.Channel(
                node.resolve_topic_name(topic), message_encoding="cdr",
                schema=foxglove.Schema(name=name, encoding="ros2msg",
                                       data=definition.encode()),
                context=self._context)
            node.create_subscription(message_type, topic,
                                     lambda data, c=channel: c.log(data), profile, raw=True)

    @property
    def port(self) -> int:
        """The TCP port the server listens on."""
        return self._server.port

    @property
    def url(self) -> str:
        """What to give Foxglove's "Open connection" > "Foxglove WebSocket"."""
        return f"ws://localhost:{self.port}"

    def wait_for_viewer(self, timeout: float) -> bool:
        """Wait (at most `timeout` s) until a client subscribes to a topic; whether one did."""
        return self._viewers.subscribed.wait(timeout)

    def close(self) -> None:
        """Stop the server (its clients are disconnected)."""
        self._server.stop()


def layout(base_link: str, joints: list[str]) -> str:
    """A Foxglove layout (JSON) for a run of an arm with these base link and joints.

    Left, the 3D panel fixed on the base link with both nodes' markers; right, the
    commanded joint velocities and kfm over time, the locked set and the diagnostics.
    """
    velocities = [layouts.PlotSeries(value=f"/{names.COMMAND}.velocity[{j}]", label=joint,
                                     enabled=True) for j, joint in enumerate(joints)]
    scene = layouts.ThreeDeePanel(title="arm, goal, critical points, locks", config=(
        layouts.ThreeDeeConfig(
            fixed_frame=base_link, follow_tf=base_link,
            topics={f"/{topic}": layouts.BaseRendererRosMarkerTopicSettings(visible=True)
                    for topic, _, _ in MARKER_TOPICS},
            camera_state=layouts.ThreeDeeCameraState(distance=2.2, phi=60.0,
                                                     theta_offset=45.0,
                                                     target=(0.3, 0.0, 0.4)))))
    side = layouts.SplitContainer(direction="column", items=[
        layouts.SplitItem(content=layouts.PlotPanel(title="commanded joint velocity (rad/s)",
                                                    config=layouts.PlotConfig(
                                                        paths=velocities))),
        layouts.SplitItem(content=layouts.PlotPanel(title="kfm (m)", config=layouts.PlotConfig(
            paths=[layouts.PlotSeries(value=f"/{names.METRICS}.data[0]", label="kfm",
                                      enabled=True)]))),
        layouts.SplitItem(content=layouts.RawMessagesPanel(
            title="locked joints", config=layouts.RawMessagesConfig(
                topic_path=f"/{names.LOCKED_JOINTS}.name"))),
        layouts.SplitItem(content=layouts.DiagnosticsSummaryPanel(
            config=layouts.DiagnosticsSummaryConfig(topic_to_render=names.DIAGNOSTICS))),
    ])
    content = layouts.SplitContainer(direction="row", items=[
        layouts.SplitItem(proportion=3, content=scene),
        layouts.SplitItem(proportion=2, content=side)])
    return json.dumps(json.loads(layouts.Layout(content=content).to_json()), indent=2,
                      sort_keys=True) + "\n"
