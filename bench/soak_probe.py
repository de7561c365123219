"""The soak's probe: sends the pose goals, records what the graph publishes, resets false locks.

`Probe` is one rclpy node in the soak's own process; what it sees in one phase of a
plant's run is a `Phase` (wall clock, s), with the joint-space path travelled (`Travel`).
"""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, field

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from ft_msgs_py import convert, diagnostics, names, qos
from geometry_msgs.msg import PoseStamped
from rclpy.context import Context
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Header
from std_srvs.srv import Trigger

#: Pose goals visited in turn (m, Panda position task): reachable from the home pose.
GOALS = ((0.5, 0.1, 0.4), (0.45, -0.15, 0.35), (0.4, 0.05, 0.55))
#: Joint states averaged per block before summing the path (500 Hz: 0.1 s blocks).
TRAVEL_BLOCK = 50
#: s after a reset's answer before another reset may be asked (stale diagnostics).
RESET_GUARD = 1.0
#: The probe's queue of each stream (messages): a second of joint states, so a probe
#: late by less than that loses nothing and the gaps measured are the publishers'.
STREAM = QoSProfile(depth=500, history=HistoryPolicy.KEEP_LAST,
                    reliability=ReliabilityPolicy.BEST_EFFORT,
                    durability=DurabilityPolicy.VOLATILE)
LOCKED = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                    reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: s; gaps between consecutive stamps of a stream from this long on are listed (stalls).
STALL = 0.1
#: Stalls listed per phase at most.
STALLS_KEPT = 500


class Travel:
    """Joint-space path (rad) of positions averaged over blocks of `TRAVEL_BLOCK` states."""

    def __init__(self) -> None:
        self._block: list[np.ndarray] = []
        self._previous: np.ndarray | None = None
        self.path = 0.0  #: rad, summed over the joints

    def add(self, q: np.ndarray) -> None:
        """One measured configuration (rad)."""
        self._block.append(q)
        if len(self._block) < TRAVEL_BLOCK:
            return
        mean = np.mean(self._block, axis=0)
        self._block.clear()
        if self._previous is not None and mean.shape == self._previous.shape:
            self.path += float(np.sum(np.abs(mean - self._previous)))
        self._previous = mean


@dataclass
class Phase:
    """What the probe saw in one phase of a plant's run (wall clock, s)."""

    name: str
    loaded: bool = False
    wall_start: float = field(default_factory=time.time)
    wall_end: float = 0.0
    locks: list[dict] = field(default_factory=list)  #: {"time", "joints"} per message
    swings_seen: list[dict] = field(default_factory=list)  #: from the diagnostics
    resets: list[dict] = field(default_factory=list)  #: {"time", "answer"}
    statuses: int = 0  #: the monitor's top-level diagnostics received
    observing: int = 0  #: of them with observing == yes
    not_observing: Counter = field(default_factory=Counter)  #: reason -> statuses
    messages: Counter = field(default_factory=Counter)  #: non-OK message -> statuses
    plant: dict[str, str] = field(default_factory=dict)  #: the monitor's last plant values
    commands: int = 0
    command_stamp_gap: float = 0.0  #: s, largest between consecutive stamps
    command_arrival_gap: float = 0.0  #: s, largest between consecutive arrivals
    states: int = 0
    state_stamp_gap: float = 0.0  #: s, largest between consecutive joint_states stamps
    #: {"time": wall s, "stream", "ms"} of every gap of at least STALL between two stamps.
    stalls: list[dict] = field(default_factory=list)
    cpu: dict[str, float] = field(default_factory=dict)  #: `cpu_use` over the phase
    goals: int = 0
    travel: Travel = field(default_factory=Travel)

    @property
    def seconds(self) -> float:
        """Wall-clock length of the phase (s; so far, while it runs)."""
        return (self.wall_end or time.time()) - self.wall_start


class Probe:
    """Sends the pose goals, records what the graph publishes and resets false locks."""

    def __init__(self, context: Context, goal_period: float, cycle: float, pause: float):
        """Goals every `goal_period` s, none in the last `pause` s of every `cycle` s."""
        self.node = rclpy.create_node("soak_probe", context=context)
        self.goal_period, self.cycle, self.pause = goal_period, cycle, pause
        self.phase = Phase("start-up")
        self._goal = self.node.create_publisher(PoseStamped, names.TARGET_POSE, qos.RELIABLE)
        self._reset = self.node.create_client(Trigger, "monitor/reset")
        self.node.create_subscription(JointState, names.LOCKED_JOINTS, self._on_locked, LOCKED)
        self.node.create_subscription(JointState, names.JOINT_STATES, self._on_state, STREAM)
        self.node.create_subscription(JointState, names.COMMAND, self._on_command, STREAM)
        self.node.create_subscription(DiagnosticArray, names.DIAGNOSTICS, self._on_diagnostics,
                                      STREAM)
        self.locked: list[str] = []  #: the newest locked set
        self.swinging = "[]"  #: the newest `free_swinging_joints` of the monitor
        self.observing = ""  #: the newest `observing` of the monitor
        self._pending = None  # the reset call under way
        self._reset_done = -np.inf  # monotonic time of the last reset's answer
        self._last_stamp: float | None = None
        self._last_state_stamp: float | None = None
        self._last_arrival: float | None = None
        self._goal_index = 0
        self._schedule_start = time.monotonic()
        self._next_goal = self._schedule_start

    # ---------------------------------------------------------------- inputs
    def _on_locked(self, msg: JointState) -> None:
        self.locked = sorted(msg.name)
        if self.locked:
            self.phase.locks.append({"time": time.time(), "joints": self.locked})
            print(f"{time.strftime('%H:%M:%S')} {self.phase.name}: locked {self.locked}",
                  flush=True)

    def _on_state(self, msg: JointState) -> None:
        phase, stamp = self.phase, convert.stamp_seconds(msg.header.stamp)
        phase.states += 1
        phase.travel.add(np.asarray(msg.position, dtype=float))
        if self._last_state_stamp is not None:
            gap = stamp - self._last_state_stamp
            phase.state_stamp_gap = max(phase.state_stamp_gap, gap)
            self._stall(names.JOINT_STATES, gap)
        self._last_state_stamp = stamp

    def _stall(self, stream: str, gap: float) -> None:
        if gap >= STALL and len(self.phase.stalls) < STALLS_KEPT:
            self.phase.stalls.append({"time": round(time.time(), 3), "stream": stream,
                                      "ms": round(gap * 1e3, 1)})

    def _on_command(self, msg: JointState) -> None:
        arrival, stamp = time.monotonic(), convert.stamp_seconds(msg.header.stamp)
        phase = self.phase
        phase.commands += 1
        if self._last_stamp is not None:
            phase.command_stamp_gap = max(phase.command_stamp_gap, stamp - self._last_stamp)
            self._stall(names.COMMAND, stamp - self._last_stamp)
        if self._last_arrival is not None:
            phase.command_arrival_gap = max(phase.command_arrival_gap,
                                            arrival - self._last_arrival)
        self._last_stamp, self._last_arrival = stamp, arrival

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name != "/monitor":
                continue
            values = {kv.key: kv.value for kv in status.values}
            phase = self.phase
            phase.statuses += 1
            self.observing = values.get("observing", "")
            if self.observing == "yes":
                phase.observing += 1
            else:
                phase.not_observing[self.observing[:100]] += 1
            if status.level != diagnostics.OK:
                phase.messages[status.message[:100]] += 1
            phase.plant = {k: values[k] for k in ("plant_model", "latency_s", "response_time_s")
                           if k in values}
            swinging = values.get("free_swinging_joints", "[]")
            if swinging != "[]" and swinging != self.swinging:
                phase.swings_seen.append({"time": time.time(), "joints": swinging})
                print(f"{time.strftime('%H:%M:%S')} {phase.name}: free-swinging {swinging}",
                      flush=True)
            self.swinging = swinging

    # --------------------------------------------------------------- actions
    def tick(self, send_goals: bool = True) -> None:
        """Send the next goal when due (outside the pauses), and reset the monitor if needed."""
        now = time.monotonic()
        in_pause = (now - self._schedule_start) % self.cycle >= self.cycle - self.pause
        if send_goals and not in_pause and now >= self._next_goal:
            self._send_goal()
            self._next_goal = now + self.goal_period
        if self._pending is not None and self._pending.done():
            answer = self._pending.result()
            self.phase.resets.append({"time": time.time(),
                                      "answer": answer.message if answer else "no answer"})
            self._pending, self._reset_done = None, now
            self.swinging = "[]"
        if (self._pending is None and (self.locked or self.swinging != "[]")
                and now - self._reset_done > RESET_GUARD and self._reset.service_is_ready()):
            self._pending = self._reset.call_async(Trigger.Request())

    def _send_goal(self) -> None:
        goal = np.eye(4)
        goal[:3, 3] = GOALS[self._goal_index % len(GOALS)]
        self._goal.publish(PoseStamped(header=Header(stamp=self.node.get_clock().now().to_msg()),
                                       pose=convert.pose_message(goal)))
        self._goal_index += 1
