"""Issue 32: the live view, the controller's and the sim's `~/markers`, on the closed loop."""

from __future__ import annotations

import json
import struct
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from ft_core import robots
from ft_msgs_py import markers, qos
from ft_sim import demo, live
from ft_sim.live import LiveServer
from ft_sim.scenario import TASK_POINTS, Scenario, ScenarioConfig
from paths import REPO
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from rosutil import fresh_domain
from sensor_msgs.msg import JointState
from visualization_msgs.msg import Marker, MarkerArray


def _by_ns(message: MarkerArray) -> dict[str, Marker]:
    return {marker.ns: marker for marker in message.markers}


def _xyz(marker: Marker) -> np.ndarray:
    return np.array([[p.x, p.y, p.z] for p in marker.points])


def _rgba(color) -> tuple[float, ...]:
    return tuple(round(v, 3) for v in (color.r, color.g, color.b, color.a))


def test_the_markers_show_the_goal_the_path_and_the_lock_before_and_after_detection() -> None:
    """The Panda goes to its first task point; joint 2 locks, and the monitor finds it.

    The sim's markers: the arm in the base link (a line from the base through the joint
    origins to the tool, a sphere per joint), the tool's path growing as it moves, the
    locked joint red from the injection on. The controller's: the goal where it was sent,
    the three critical points, and a red halo on joint 2 only once the monitor announced
    it (none before).
    """
    config = ScenarioConfig(lock_joint="", soft_limits=False, rate=125.0)
    scenario = Scenario(config, domain_id=fresh_domain())
    seen: dict[str, list[MarkerArray]] = {"controller": [], "sim": []}
    try:
        for node in seen:
            scenario.driver.create_subscription(
                MarkerArray, f"/{node}/markers", seen[node].append, qos.RELIABLE)
        scenario.controller.set_parameters([Parameter(
            "critical_points", value=[v for p in TASK_POINTS["panda"] for v in p])])
        scenario.start()
        scenario.send_goal(0)
        for _ in range(round(1.0 * config.rate)):
            scenario.step()
        assert seen["sim"] and seen["controller"], "no markers in 1 s of simulated time"
        robot = scenario.robot
        sim, controller = _by_ns(seen["sim"][-1]), _by_ns(seen["controller"][-1])
        assert {m.header.frame_id for m in (*sim.values(), *controller.values())} == {
            robot.base_link}
        links, joints = sim["arm/links"], sim["arm/joints"]
        assert links.type == Marker.LINE_STRIP and len(links.points) == robot.n + 2
        np.testing.assert_allclose(_xyz(links)[1:], robot.skeleton(scenario.sim.q), atol=0.02)
        assert {_rgba(c) for c in joints.colors} == {markers.HEALTHY}
        path = sim["tool_path"]
        assert path.type == Marker.LINE_STRIP and len(path.points) >= 5
        assert np.linalg.norm(_xyz(path)[-1] - _xyz(path)[0]) > 0.01  # it moved
        np.testing.assert_allclose(_xyz(controller["goal"])[0], TASK_POINTS["panda"][0])
        np.testing.assert_allclose(_xyz(controller["critical_points"]),
                                   np.array(TASK_POINTS["panda"]))
        assert controller["locked_joints"].action == Marker.DELETE

        scenario.inject("panda_joint2")
        for _ in range(2):  # a marker period of the sim: the lock drawn red
            scenario.step()
        seen["sim"].clear()
        for _ in range(round(markers.PERIOD * config.rate)):
            scenario.step()
        joints = _by_ns(seen["sim"][-1])["arm/joints"]
        assert [_rgba(c) for c in joints.colors] == [
            markers.LOCKED if j == 1 else markers.HEALTHY for j in range(robot.n)]
        assert scenario.until_detected(2.0) is not None, "the lock was not detected"
        seen["controller"].clear()
        for _ in range(round(2 * markers.PERIOD * config.rate)):
            scenario.step()
        halo = _by_ns(seen["controller"][-1])["locked_joints"]
        assert halo.action == Marker.ADD and _rgba(halo.color) == markers.ANNOUNCED
        np.testing.assert_allclose(_xyz(halo), robot.skeleton(scenario.sim.q)[[1]], atol=0.01)
    finally:
        scenario.close()


def _frames(websocket, until, timeout: float = 10.0) -> list:
    """Frames from the server until `until(frames)` holds; fails after `timeout` s."""
    frames: list = []
    deadline = time.monotonic() + timeout
    while not until(frames):
        left = deadline - time.monotonic()
        assert left > 0, f"the server sent {len(frames)} frames, not what was awaited"
        try:
            frames.append(websocket.recv(timeout=min(left, 0.2)))
        except TimeoutError:
            continue
    return frames


def test_ft_demo_live_serves_the_run_to_foxglove(tmp_path: Path) -> None:
    """Issue 32: `ft-demo --live` is Foxglove's WebSocket protocol, decoded as a viewer does.

    A client connects while the demo waits for a viewer: every topic of the run is
    advertised with its ROS 2 message definition; subscribed, the sim's markers and the
    joint states arrive as CDR that rclpy decodes; the run goes on in real time (no
    faster than the wall clock), and the layout is written for the robot's base link.
    """
    from websockets.sync.client import connect

    done: dict = {}

    def run() -> None:
        done["status"] = demo.main(["--live", "0", "--lock-time", "1.0", "--duration", "3.0",
                                    "--no-soft-limits", "--out", str(tmp_path)])

    port = {}
    real = LiveServer.__init__

    def note_port(self, node, requested):
        real(self, node, requested)
        port["value"] = self.port

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(LiveServer, "__init__", note_port)
        thread = threading.Thread(target=run, daemon=True)
        started = time.monotonic()
        thread.start()
        deadline = time.monotonic() + 30.0
        while "value" not in port:
            assert time.monotonic() < deadline and thread.is_alive(), "no live server"
            time.sleep(0.05)
    with connect(f"ws://127.0.0.1:{port['value']}", subprotocols=["foxglove.sdk.v1"]) as ws:
        frames = _frames(ws, lambda f: any('"advertise"' in x for x in f if isinstance(x, str)))
        channels = {c["topic"]: c for frame in frames if isinstance(frame, str)
                    for c in json.loads(frame).get("channels", [])}
        assert {"/sim/markers", "/controller/markers", "/joint_states", "/ft/locked_joints",
                "/ft/metrics", "/diagnostics"} <= set(channels), sorted(channels)
        markers_channel = channels["/sim/markers"]
        assert markers_channel["encoding"] == "cdr"
        assert markers_channel["schemaName"] == "visualization_msgs/msg/MarkerArray"
        assert "int32 type" in markers_channel["schema"]  # the definition, field names kept
        topics = {1: ("/sim/markers", MarkerArray), 2: ("/joint_states", JointState)}
        ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": sid, "channelId": channels[topic]["id"]}
            for sid, (topic, _) in topics.items()]}))
        decoded: dict[int, list] = {1: [], 2: []}

        def both(frames: list) -> bool:
            for frame in frames[len(both.seen):]:
                if isinstance(frame, bytes) and frame[0] == 1:  # opcode: message data
                    sid = struct.unpack_from("<I", frame, 1)[0]
                    decoded[sid].append(deserialize_message(frame[13:], topics[sid][1]))
            both.seen = list(frames)
            return all(decoded.values())

        both.seen = []
        _frames(ws, both, timeout=30.0)
    thread.join(60.0)
    assert not thread.is_alive() and done["status"] == 0
    assert time.monotonic() - started > 3.0  # paced: 3 s of simulated time took longer
    arm = _by_ns(decoded[1][-1])["arm/links"]
    assert arm.header.frame_id == "panda_link0" and len(arm.points) == 9
    assert len(decoded[2][-1].name) == 7
    layout = json.loads((tmp_path / "foxglove_layout.json").read_text())
    assert layout["content"]["items"][0]["content"]["config"]["fixedFrame"] == "panda_link0"


def test_the_layout_in_the_docs_is_the_one_the_demo_writes() -> None:
    robot = robots.load("panda", task_space="position")
    expected = live.layout(robot.base_link, list(robot.joint_names))
    assert (REPO / "docs" / "foxglove_layout.json").read_text() == expected, (
        "docs/foxglove_layout.json is stale: write live.layout('panda_link0', ...) there")
