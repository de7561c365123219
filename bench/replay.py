"""A series recorded by `bench/faults_processes.py --record`, replayed through the monitor's core.

The live monitor's inputs as the probe heard them go into `ft_core.monitor.Monitor` at
default parameters, for the robot the deployed series run (`soak_processes.PLANTS`,
physics): each joint state (positions, efforts) into `Monitor.observe` at its stamp (the
sim's clock); each `ft/command` the monitor sent into the detector's command history at
its arrival mapped onto the sim's clock (arrival + the largest stamp - arrival over the
joint states: their least latency); `Monitor.reset` at each empty `ft/locked_joints` (the
probe resets the monitor between faults). The bag's arrival stamps are this machine's
monotonic clock (s below).

Prints what the replay declares and when, what the live monitor announced on
`ft/locked_joints`, each fault injected and obstacle placed or removed, and every *near
miss*: a lock candidate on a joint no fault was injected into since the last reset (how
long, its velocity against its weakest plausible prediction, its deficit), marked where
it began with an obstacle placed or removed within `WALL_MEMORY` s (the contact test's
to hold back). Replayed with the sources of the version that
ran live, the declarations come out as the live monitor's; with another, they say what a
change would have done to the same inputs. `--start` and `--end` replay a part (the
monitor then starts afresh at `--start`).
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from ft_core import robots
from ft_core.detection import DetectorConfig
from ft_core.monitor import Monitor, MonitorConfig
from ft_msgs_py import names
from ft_sim.bag import STORE
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore
from soak_processes import PLANTS

TOPICS = {names.JOINT_STATES, names.COMMAND, names.LOCKED_JOINTS, names.INJECT_FAULT,
          names.OBSTACLE}
#: s after an obstacle is removed that a near miss still counts as at the wall (the
#: contact watch's memory of a force on the tool, `ft_core.detection.contact`).
WALL_MEMORY = 1.0


@dataclass
class NearMiss:
    """A lock candidate on a joint no fault was injected into."""

    arrival: float  #: s, when it began (arrival clock)
    joint: str
    duration: float  #: s, how long it lasted (sim clock)
    measured: float  #: rad/s, its velocity when it began
    commanded: float  #: rad/s, its weakest plausible prediction then
    deficit: float  #: rad, its lost position then
    at_wall: bool  #: began with an obstacle placed, or removed within `WALL_MEMORY` s


@dataclass
class Replay:
    """What a replay saw: (arrival s, ...) each, in order."""

    declared: list[tuple[float, str]] = field(default_factory=list)  #: the replay's lines
    announced: list[tuple[float, list[str]]] = field(default_factory=list)  #: live locked sets
    injected: list[tuple[float, str, str]] = field(default_factory=list)  #: (joint, kind)
    walls: list[tuple[float, bool]] = field(default_factory=list)  #: placed (True) or removed
    near: list[NearMiss] = field(default_factory=list)


def _stamp(header: object) -> float:
    return header.stamp.sec + 1e-9 * header.stamp.nanosec


def _events(bag: Path, chain: list[str]) -> tuple[list[tuple[float, str, object]], float]:
    """The bag's monitor inputs and outputs, by arrival (s), and arrival -> sim clock (s)."""
    events: list[tuple[float, str, object]] = []
    offset = -math.inf
    with AnyReader([bag], default_typestore=get_typestore(STORE)) as reader:
        connections = [c for c in reader.connections if c.topic.lstrip("/") in TOPICS]
        for connection, ns, raw in reader.messages(connections=connections):
            topic, arrival = connection.topic.lstrip("/"), ns * 1e-9
            msg = reader.deserialize(raw, connection.msgtype)
            if topic in (names.JOINT_STATES, names.COMMAND):
                order = [list(msg.name).index(n) for n in chain]
                if topic == names.JOINT_STATES:
                    stamp = _stamp(msg.header)
                    offset = max(offset, stamp - arrival)
                    effort = np.asarray(msg.effort)[order] if len(msg.effort) else None
                    events.append((arrival, topic, (stamp, np.asarray(msg.position)[order],
                                                    effort)))
                else:
                    events.append((arrival, topic, np.asarray(msg.velocity)[order]))
            elif topic == names.LOCKED_JOINTS:
                events.append((arrival, topic, list(msg.name)))
            elif topic == names.OBSTACLE:
                events.append((arrival, topic, msg.action != msg.DELETE))
            else:
                events.append((arrival, topic, [(s.name, s.message) for s in msg.status]))
    events.sort(key=lambda e: e[0])
    return events, offset


def replay(bag: Path, start: float = -math.inf, end: float = math.inf) -> Replay:
    """Replay the bag at `bag` (a folder) between arrivals `start` and `end` (s)."""
    model = PLANTS["physics"]["model"]
    robot = robots.load(str(model["robot_model"]), tip_link=str(model["tip_link"]),
                        task_space=str(model["task_space"]))
    chain = list(robot.joint_names)
    events, offset = _events(bag, chain)
    core = Monitor(robot, DetectorConfig(), MonitorConfig(), None)
    seen = Replay()
    faulty: set[int] = set()
    wall_until = -math.inf  # arrival (s) until which a near miss counts as at the wall
    under_way: dict[int, tuple[NearMiss, float]] = {}  # joint -> (near miss, its first stamp)
    for arrival, topic, payload in events:
        if not start <= arrival <= end:
            continue
        if topic == names.COMMAND:
            core.detector.command(arrival + offset, payload)
        elif topic == names.JOINT_STATES:
            stamp, q, effort = payload
            change = core.observe(q, stamp, None, effort)
            seen.declared += [(arrival, line) for line in change.events]
            for j, evidence in enumerate(core.detector.joints):
                if evidence.candidate and evidence.locked_at is None and j not in faulty:
                    if j not in under_way:
                        under_way[j] = (NearMiss(arrival, chain[j], 0.0, evidence.measured,
                                                 evidence.commanded, evidence.deficit,
                                                 arrival <= wall_until), stamp)
                    under_way[j][0].duration = stamp - under_way[j][1]
                elif j in under_way:
                    seen.near.append(under_way.pop(j)[0])
        elif topic == names.LOCKED_JOINTS:
            seen.announced.append((arrival, payload))
            if not payload:  # the probe's reset
                core.reset(arrival + offset)
                faulty.clear()
        elif topic == names.OBSTACLE:
            seen.walls.append((arrival, payload))
            wall_until = math.inf if payload else arrival + WALL_MEMORY
        else:
            for name, kind in payload:
                if name in chain:
                    faulty.add(chain.index(name))
                    seen.injected.append((arrival, name, kind))
    core.close()
    return seen


def main(argv: list[str] | None = None) -> int:
    """Replay the bag named on the command line; print what it saw, in arrival order."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bag", type=Path, help="the bag folder (faults_processes_bag)")
    parser.add_argument("--start", type=float, default=-math.inf)
    parser.add_argument("--end", type=float, default=math.inf)
    args = parser.parse_args(argv)
    seen = replay(args.bag, args.start, args.end)
    lines = ([(a, f"injected {joint} {kind}") for a, joint, kind in seen.injected]
             + [(a, f"live locked set {names_}") for a, names_ in seen.announced]
             + [(a, f"replay: {line}") for a, line in seen.declared]
             + [(a, "obstacle placed" if placed else "obstacle removed")
                for a, placed in seen.walls]
             + [(m.arrival, f"near miss{' at the wall' if m.at_wall else ''} {m.joint} for "
                 f"{1e3 * m.duration:.0f} ms: measured {m.measured:.4f} rad/s against "
                 f"{m.commanded:.4f}, {1e3 * m.deficit:.1f} mrad behind") for m in seen.near])
    for arrival, line in sorted(lines, key=lambda x: x[0]):
        print(f"{arrival:.3f} {line}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
