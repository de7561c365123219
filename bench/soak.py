"""`make bench`: false locks and free-swing declarations per hour of healthy motion, deployed.

The installed executables (`sim_node`, `controller_node`, `monitor_node` from the colcon
install space ros_ws/install, as `ros2 run` starts them) run as separate processes at
their default parameters (with `--layout stack`: `sim_node` and `stack`, the controller
and the monitor in one process, which cycles on each joint state) on each of the sim's
plants:
- kinematic: the Panda (`panda`, position task) behind a driver with a command watchdog
  (30 ms latency, 30 ms response time, 0.1 s command timeout, 1e-3 rad position noise);
- physics: the Panda with its inertias (`panda_inertial`, flange `panda_link8`, position
  task) in MuJoCo behind a slow driver that holds the last command (50 ms latency, a
  50 ms servo, 1e-3 rad position noise).
A probe in this process sends pose goals (`ft/target_pose`, three positions in turn)
every `--goal-period` s and every `--cycle` s stops sending them for `--pause` s, so
the arm keeps starting, moving and stopping. After a warm-up (goals until the monitor
says it observes: it has identified and seen the plant follow) each plant runs
`--minutes`: the first half on an otherwise idle machine, the second half with one busy
process per core beside the nodes (`ft_sim.cpu_load.busy_cores`, normal scheduler).

Counted per half (idle, loaded):
- false locks: every non-empty `ft/locked_joints` message, with its joints; each is
  followed by a call of the monitor's `~/reset` (as an operator would) and the run goes on;
- free-swing declarations: the monitor's log lines "joint ... free-swinging (t = ...)"
  (its stdout and stderr are kept in a file); the probe also sees them in the monitor's
  diagnostics (`free_swinging_joints`) and resets the monitor after each, or a joint
  declared once would never be declared again;
- observing: the share of the monitor's diagnostics (2 Hz) with `observing == yes` (a
  reset restarts the plant identification, so it drops after each);
- motion: the joint-space path travelled (rad, of positions averaged over blocks of 50
  joint states: the noise stays out) and the `ft/command` messages, with the largest gap
  between the stamps of two consecutive ones (ms: the controller's cycles, or the
  monitor's watchdog zeros) and between their arrivals at the probe; every gap of at
  least 100 ms between two stamps of `ft/command` or `joint_states` is listed (stalls, to
  set beside a lock's time);
- the machine: mean cores used by the nodes (and what they started), the probe, the busy
  processes and everything else (other users' work: an "idle" half is only idle if that
  is near 0).

Writes `<out>/soak.md`, `<out>/soak.json` and the processes' logs under
`<out>/soak_logs/<plant>/`. DDS domain `FT_BENCH_DOMAIN_SOAK` (default 63), discovery on
localhost only.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from engine_cycle import machine, report
from ft_msgs_py import convert, diagnostics, names, qos
from ft_sim.cpu_load import busy_cores
from geometry_msgs.msg import PoseStamped
from rclpy.context import Context
from rclpy.experimental.events_executor import EventsExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Header
from std_srvs.srv import Trigger

REPO = Path(__file__).resolve().parents[1]
INSTALL = REPO / "ros_ws" / "install"
PACKAGES = ("ft_core", "ft_msgs_py", "ft_controller", "ft_monitor", "ft_sim")
#: Per layout: name -> (package, executable) in the install space, started in this order.
LAYOUTS = {
    "separate": {"sim": ("ft_sim", "sim_node"), "monitor": ("ft_monitor", "monitor_node"),
                 "controller": ("ft_controller", "controller_node")},
    "stack": {"sim": ("ft_sim", "sim_node"), "stack": ("ft_sim", "stack")},
}
#: Pose goals visited in turn (m, Panda position task): reachable from the home pose.
GOALS = ((0.5, 0.1, 0.4), (0.45, -0.15, 0.35), (0.4, 0.05, 0.55))
#: Per plant: the parameters of all three nodes, and the sim's own.
PLANTS: dict[str, dict[str, dict[str, object]]] = {
    "kinematic": {
        "model": {"robot_model": "panda", "task_space": "position"},
        "sim": {"command_latency": 0.03, "response_time": 0.03, "command_timeout": 0.1,
                "position_noise": 0.001},
    },
    "physics": {
        "model": {"robot_model": "panda_inertial", "tip_link": "panda_link8",
                  "task_space": "position"},
        "sim": {"plant": "physics", "command_latency": 0.05, "response_time": 0.05,
                "hold_last_command": True, "position_noise": 0.001},
    },
}
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
#: A monitor log line (rcutils' default format): wall time (s) and message.
LOG_LINE = re.compile(r"^\[(\w+)\] \[(\d+(?:\.\d+)?)\] \[monitor\]: (.*)$")


def _argument(value: object) -> str:
    """A parameter value as `-p name:=value` takes it."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list | tuple):
        return "[" + ",".join(_argument(v) for v in value) + "]"
    return str(value)


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
        self.phase.goals += 1


def _descendants(pid: int) -> list[int]:
    """`pid` and every process it started, and theirs (Linux /proc)."""
    found = [pid]
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            children = (task / "children").read_text().split()
        except OSError:  # the thread ended meanwhile
            continue
        found += [d for child in children for d in _descendants(int(child))]
    return found


def cpu_counters(pids: list[int]) -> dict[str, float]:
    """CPU seconds so far: the whole machine busy, `pids` and theirs, this process, reaped children.

    The machine's busy time is /proc/stat's user, nice, system, irq, softirq and steal.
    """
    tick = os.sysconf("SC_CLK_TCK")
    fields = Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]
    user, nice, system, _idle, _iowait, irq, softirq, steal = (int(v) for v in fields[:8])
    nodes = 0
    for pid in {d for p in pids for d in _descendants(p)}:
        try:
            stat = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        nodes += int(stat[11]) + int(stat[12])  # utime, stime
    own = os.times()
    return {"machine": (user + nice + system + irq + softirq + steal) / tick,
            "nodes": nodes / tick, "probe": own.user + own.system,
            "reaped": own.children_user + own.children_system}


def cpu_use(start: dict[str, float], end: dict[str, float], seconds: float,
            ) -> dict[str, float]:
    """Mean cores busy between two `cpu_counters`: all, the nodes, the probe, the rest.

    "reaped" is the busy processes of the loaded half (reaped when it ends); "others" is
    what the rest of the machine used meanwhile (other users' work).
    """
    use = {k: (end[k] - start[k]) / seconds for k in start}
    use["others"] = max(0.0, use["machine"] - use["nodes"] - use["probe"] - use["reaped"])
    return use


@contextmanager
def deployed(plant: str, domain: int, log_dir: Path, layout: str,
             ) -> Iterator[dict[str, subprocess.Popen]]:
    """The installed executables of `layout` for `plant` on `domain`; SIGINT (then kill) after.

    Their stdout and stderr go to `<log_dir>/<name>.log`; the monitor keeps its locked set
    in a fresh temporary directory.
    """
    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    env = {**os.environ, "ROS_DOMAIN_ID": str(domain),
           "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
           "PYTHONPATH": os.pathsep.join(str(INSTALL / p / "lib" / version / "site-packages")
                                         for p in PACKAGES)}
    log_dir.mkdir(parents=True, exist_ok=True)
    processes: dict[str, subprocess.Popen] = {}
    with tempfile.TemporaryDirectory(prefix="ft_soak_state_") as state:
        values = {"sim": PLANTS[plant]["sim"], "controller": {},
                  "monitor": {"state_directory": state}, "stack": {"state_directory": state}}
        try:
            for name, (package, executable) in LAYOUTS[layout].items():
                script = INSTALL / package / "lib" / package / executable
                if not script.is_file():
                    raise SystemExit(f"{script} is missing: run `make build`")
                parameters = {**PLANTS[plant]["model"], **values[name]}
                arguments = [a for k, v in parameters.items()
                             for a in ("-p", f"{k}:={_argument(v)}")]
                with open(log_dir / f"{name}.log", "w") as log:
                    processes[name] = subprocess.Popen(
                        [sys.executable, str(script), "--ros-args", *arguments],
                        env=env, stdout=log, stderr=subprocess.STDOUT)
            yield processes
        finally:
            for process in processes.values():
                process.send_signal(signal.SIGINT)
            for process in processes.values():
                try:
                    process.wait(timeout=15)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait()


def spin_phase(probe: Probe, executor: EventsExecutor, seconds: float,
               until: str | None = None) -> bool:
    """Spin `seconds` (wall clock) with the goal schedule; stop early once `until` holds.

    `until` "observing": the monitor's newest diagnostics say it observes. Returns
    whether it stopped early.
    """
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        probe.tick()
        executor.spin_once(timeout_sec=0.005)
        if until == "observing" and probe.observing == "yes":
            return True
    return False


def monitor_log(path: Path, phases: list[Phase], context: int = 4) -> dict[str, dict]:
    """Free-swing and lock lines of the monitor's log, counted per phase (by log time).

    Returns {phase name: {"swings", "locks", "suspicions_refused" (the controller's
    task-space channel suspected a lock, the monitor's evidence refused it: logged at most
    every 5 s), "events": [lines around each swing and lock]}}.
    """
    lines = path.read_text(errors="replace").splitlines() if path.is_file() else []
    result: dict[str, dict] = {p.name: {"swings": 0, "locks": 0, "suspicions_refused": 0,
                                        "events": []} for p in phases}
    for i, line in enumerate(lines):
        match = LOG_LINE.match(line)
        if match is None:
            continue
        stamp, message = float(match.group(2)), match.group(3)
        phase = next((p for p in phases if p.wall_start <= stamp < p.wall_end), None)
        if phase is None:
            continue
        entry = result[phase.name]
        if "not confirmed" in message:  # the controller's suspicion, refused (throttled 5 s)
            entry["suspicions_refused"] += 1
        swing = "free-swinging (t =" in message
        lock = " locked at " in message or "locked (suspected" in message
        if swing or lock:
            entry["swings" if swing else "locks"] += 1
            entry["events"].append(lines[max(0, i - context):i + context + 1])
    return result


def run_plant(plant: str, minutes: float, domain: int, out: Path, goal_period: float,
              cycle: float, pause: float, warm_up: float, layout: str) -> dict:
    """One plant: start-up, warm-up until observing, idle half, loaded half."""
    log_dir = out / "soak_logs" / plant
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    executor = EventsExecutor(context=context)
    probe = Probe(context, goal_period, cycle, pause)
    executor.add_node(probe.node)
    half = minutes * 60.0 / 2
    phases: list[Phase] = []
    alive: dict[str, dict[str, int | None]] = {}
    try:
        with deployed(plant, domain, log_dir, layout) as processes:
            start = time.monotonic()
            while probe.phase.states < 10 and time.monotonic() - start < 60.0:
                executor.spin_once(timeout_sec=0.01)
            if probe.phase.states < 10:
                raise RuntimeError(f"{plant}: no joint states in 60 s; see {log_dir}")
            warm = probe.phase = Phase("warm-up")
            observed = spin_phase(probe, executor, warm_up, until="observing")
            warm.wall_end = time.time()
            print(f"{time.strftime('%H:%M:%S')} {plant}: warm-up {warm.seconds:.1f} s, "
                  f"observing: {observed}", flush=True)
            pids = [p.pid for p in processes.values()]
            for name, loaded in (("idle", False), ("loaded", True)):
                counters = cpu_counters(pids)
                phase = probe.phase = Phase(name, loaded)
                if loaded:
                    with busy_cores():
                        spin_phase(probe, executor, half)
                else:
                    spin_phase(probe, executor, half)
                phase.wall_end = time.time()
                phase.cpu = cpu_use(counters, cpu_counters(pids), phase.seconds)
                phases.append(phase)
                alive[name] = {n: p.poll() for n, p in processes.items()}
                print(f"{time.strftime('%H:%M:%S')} {plant} {name}: {phase.seconds:.0f} s, "
                      f"locks {len(phase.locks)}, swings {len(phase.swings_seen)}, observing "
                      f"{phase.observing}/{phase.statuses}, travelled {phase.travel.path:.1f} "
                      f"rad, other processes {phase.cpu['others']:.2f} cores, exit codes "
                      f"{alive[name]}", flush=True)
    finally:
        executor.shutdown()
        rclpy.shutdown(context=context)
    logged = monitor_log(log_dir / ("stack.log" if layout == "stack" else "monitor.log"),
                         phases)
    return {"warm_up": {"seconds": warm.seconds, "observing": observed,
                        "not_observing": dict(warm.not_observing.most_common(5))},
            "phases": {p.name: summary(p, logged[p.name], alive[p.name]) for p in phases}}


def summary(phase: Phase, logged: dict, exit_codes: dict[str, int | None]) -> dict:
    """The JSON figures of one phase (`logged`: its monitor log counts)."""
    hours = phase.seconds / 3600.0
    return {
        "loaded": phase.loaded, "busy_processes": (os.cpu_count() or 2) if phase.loaded else 0,
        "seconds": phase.seconds,
        "false_locks": len(phase.locks), "locks": phase.locks,
        "free_swing_declarations": logged["swings"], "swings_in_diagnostics": phase.swings_seen,
        "locks_in_log": logged["locks"], "log_events": logged["events"],
        "suspicions_refused_in_log": logged["suspicions_refused"],
        "false_locks_per_hour": len(phase.locks) / hours,
        "free_swings_per_hour": logged["swings"] / hours,
        "resets": phase.resets,
        "monitor_statuses": phase.statuses,
        "observing_fraction": phase.observing / phase.statuses if phase.statuses else 0.0,
        "not_observing": dict(phase.not_observing.most_common(10)),
        "monitor_messages_not_ok": dict(phase.messages.most_common(10)),
        "plant_values": phase.plant,
        "goals": phase.goals, "joint_states": phase.states,
        "commands": phase.commands,
        "command_stamp_gap_max_ms": phase.command_stamp_gap * 1e3,
        "command_arrival_gap_max_ms": phase.command_arrival_gap * 1e3,
        "joint_states_stamp_gap_max_ms": phase.state_stamp_gap * 1e3,
        "stalls": phase.stalls,
        "travelled_rad": phase.travel.path,
        "cpu_cores": phase.cpu,
        "exit_codes_at_end": exit_codes,
    }


def table(results: dict[str, dict]) -> list[str]:
    """The Markdown table of every plant and phase."""
    lines = ["| plant | phase | minutes | false locks | free-swing declarations | "
             "per hour (locks / swings) | observing % | ft/command messages | "
             "command gap max (ms, stamps / arrivals) | travelled (rad) | "
             "other users' CPU (cores) |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for plant, result in results.items():
        for name, p in result["phases"].items():
            lines.append(
                f"| {plant} | {name} | {p['seconds'] / 60:.1f} | {p['false_locks']} | "
                f"{p['free_swing_declarations']} | {p['false_locks_per_hour']:.1f} / "
                f"{p['free_swings_per_hour']:.1f} | {100 * p['observing_fraction']:.1f} | "
                f"{p['commands']} | {p['command_stamp_gap_max_ms']:.0f} / "
                f"{p['command_arrival_gap_max_ms']:.0f} | {p['travelled_rad']:.1f} | "
                f"{p['cpu_cores']['others']:.2f} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    """Soak both plants and write the table and JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--minutes", type=float, default=30.0,
                        help="per plant, after the warm-up: half idle, half loaded")
    parser.add_argument("--plants", nargs="+", choices=list(PLANTS), default=list(PLANTS))
    parser.add_argument("--goal-period", type=float, default=1.5, help="s between pose goals")
    parser.add_argument("--cycle", type=float, default=20.0,
                        help="s; the goals pause once per cycle")
    parser.add_argument("--pause", type=float, default=4.0, help="s without goals per cycle")
    parser.add_argument("--warm-up", type=float, default=90.0,
                        help="s of goals at most, until the monitor observes")
    parser.add_argument("--layout", choices=list(LAYOUTS), default="separate",
                        help="the nodes as separate processes, or ft-stack")
    args = parser.parse_args(argv)
    domain = int(os.environ.get("FT_BENCH_DOMAIN_SOAK", "63"))
    # The probe discovers the nodes the way they discover each other.
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    results = {plant: run_plant(plant, args.minutes, domain, args.out, args.goal_period,
                                args.cycle, args.pause, args.warm_up, args.layout)
               for plant in args.plants}
    info = machine()
    lines = [*table(results), "",
             f"Layout: {args.layout}. Pose goals every {args.goal_period:g} s, paused "
             f"{args.pause:g} s every "
             f"{args.cycle:g} s; loaded: {os.cpu_count()} busy processes (one per core). "
             + "; ".join(f"{plant} warm-up {r['warm_up']['seconds']:.0f} s"
                         for plant, r in results.items()) + ". Locks the controller "
             "suspected and the monitor refused (log lines, at most one per 5 s): "
             + "; ".join(f"{plant} " + " / ".join(
                 f"{p['suspicions_refused_in_log']} {name}" for name, p in r["phases"].items())
                 for plant, r in results.items()) + ".",
             f"{info['cpu']}, {info['cores']} cores, Python {info['python']}, {info['date']}."]
    report(args.out, "soak", lines, {
        "machine": info, "layout": args.layout, "minutes_per_plant": args.minutes,
        "goal_period_s": args.goal_period, "cycle_s": args.cycle, "pause_s": args.pause,
        "domain": domain,
        "plants": {plant: {"parameters": PLANTS[plant], **r} for plant, r in results.items()}})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
