"""`make bench`: the fault grid's faults injected into the installed executables, deployed.

The separate-process counterpart of `bench/faults.py`: `sim_node` (the MuJoCo Panda with
its inertias behind the slow driver: 50 ms latency, a 50 ms servo, the last command held,
1e-3 rad noise, efforts reported), `monitor_node` and `controller_node` from the colcon
install space at their default parameters, as `bench/soak.py` starts them, in real time
on this machine. A probe in this process sends pose goals every 1.5 s; for each fault it
waits until the monitor observes and the faulty joint is commanded and moves at 0.1 rad/s
or more, publishes the fault on `ft/inject_fault`, watches `ft/joint_health` for `WATCH` s
while the goals go on, then resets the sim and the monitor (`~/reset`) for the next one.
A second lock, on joint (j + 3) mod 6, follows the first `SECOND` s later, once its joint
moves as the first did (waiting at most `SECOND_WAIT` s more), and is watched at least
`SECOND_WATCH` s. Kinds, in turn on each of the six joints the position task commands:
lock, free swing, intermittent jam (0.5 s), viscous 50 N m s/rad, dry 5 N m, authority
0.25, a range cut 0.05 rad ahead, a second lock, lock and free swing again: 60 faults.
Then 20 contacts: with the arm at rest at a goal, a wall (`ft_sim.closed_loop.WALL`) is
placed across the tool's way to the next one (`ft_sim.closed_loop.wall_across`), the goal
sent, the wall removed `PUSH` s later, and the goal waited for; every joint declared is
a healthy one. `--loaded` runs them all with one busy process per core beside the nodes
(`ft_sim.cpu_load.busy_cores`). `--record` keeps every topic this probe hears as a rosbag2
(`ft_sim.bag`, stamped with its arrival on this machine's monotonic clock, ns) in
`<out>/faults_processes_bag/`: the monitor's inputs, to replay a declaration offline.

Per fault: the state the monitor first declared the faulty joint in, and when (s from the
injection's publication to the `ft/joint_health` message's arrival here: the delay a
subscriber sees), and every other joint declared (a healthy joint declared; the second
lock's joint excepted). A fault shows only once the joint moves other than commanded: a
lock of a joint the controller is not moving, or a free swing of one that coasts as
commanded, is there to see only later. So each delay is also given from when the fault
showed: the joint's reported velocity first differing by `MOVING` from the command in
force at the sim (this probe's last command sent `LATENCY` s before) after the injection,
that command taken as 0 within `LIMIT_MARGIN` of the limit it points into (a healthy joint
stops there too: a lock at a limit shows once the command turns away from it). And each
joint's least share of its command while watched, and for the faulty joint when it first
slowed below half of it (`RESPONSE_TIME`): the degraded target counts from then.
Writes `<out>/faults_processes.md` and `.json` (`_loaded` with `--loaded`), the processes'
logs under `<out>/faults_processes_logs/`. DDS domain `FT_BENCH_DOMAIN_FAULTS` (default 64).
"""

from __future__ import annotations

import argparse
import math
import os
import time
from collections import deque
from contextlib import nullcontext
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from engine_cycle import machine, report
from ft_core import robots
from ft_core.detection import DetectorConfig
from ft_core.detection.follow import PERSISTENCE, FollowMeter
from ft_core.faults import Fault, FaultKind
from ft_core.health import Health
from ft_msgs_py import faults as fault_messages
from ft_msgs_py import health as health_messages
from ft_msgs_py import names, qos
from ft_sim.bag import Recorder
from ft_sim.closed_loop import WALL, wall_across
from ft_sim.cpu_load import busy_cores
from rclpy.context import Context
from rclpy.experimental.events_executor import EventsExecutor
from sensor_msgs.msg import JointState
from soak_probe import GOALS, STREAM, Probe
from soak_processes import PLANTS, deployed
from std_srvs.srv import Trigger
from visualization_msgs.msg import Marker

JOINTS = [f"panda_joint{k}" for k in range(1, 8)]
#: (kind, value) in turn; "second" is a lock, then another `SECOND` s later.
KINDS = [("lock", math.nan), ("free_swing", math.nan), ("intermittent", 0.5),
         ("viscous", 50.0), ("dry", 5.0), ("authority", 0.25), ("range", 0.05),
         ("second", math.nan), ("lock", math.nan), ("free_swing", math.nan)]
#: s after the first lock of a "second" run that the second joint may lock.
SECOND = 2.0
#: s the second lock then waits at most for its joint to move at `MOVING`.
SECOND_WAIT = 4.0
#: s each fault is watched.
WATCH = 8.0
#: s a second lock is watched at least.
SECOND_WATCH = 3.0
#: rad/s the faulty joint must be commanded and move at when it fails; also how far its
#: velocity must differ from the command in force for its fault to show.
MOVING = 0.1
#: s, the sim's command latency (`soak_processes.PLANTS`): a command is in force this long
#: after it was sent.
LATENCY = float(PLANTS["physics"]["sim"]["command_latency"])
#: s, the sim's servo response time: a healthy joint's velocity follows the command in
#: force as the physics plant's critically damped servo makes it (`ft_core.physics`).
RESPONSE_TIME = float(PLANTS["physics"]["sim"]["response_time"])
#: A joint's share of its command is `ft_core.detection.follow`'s, measured against that
#: healthy joint's velocity (the plant's own servo) instead of the monitor's predictions.
#: A degraded joint has slowed (the target's "below half of its command") from when its
#: share falls below `DEGRADED_SHARE` to stay there `PERSISTENCE` s (a healthy
#: panda_joint1, its drive at its torque limit as the command turns, dips below half for
#: about 20 ms): `FollowMeter` names it then, `PERSISTENCE` s later (within a joint state).
#: rad, the detector's `limit_margin`: this close to a limit, a joint commanded into it
#: stops there, healthy or not.
LIMIT_MARGIN = DetectorConfig().limit_margin
PANDA = robots.load("panda")
#: The deployed model and tool point (`soak_processes.PLANTS`), for where the tool is.
TOOL = robots.load(PLANTS["physics"]["model"]["robot_model"],
                   tip_link=PLANTS["physics"]["model"]["tip_link"])
#: Contacts after the faults, and s the tool is driven into the wall in each.
CONTACTS = 20
PUSH = 6.0  # past the start of the controller's recovery, which holds six joints at the wall
#: s the arm rests at a goal before the wall; s the goal is waited for once it is gone.
REST = 2.0
REACH = 10.0
#: m from the goal for it to count as reached.
REACHED = 0.01
#: s the probe waits for the joint to move before it injects anyway.
MOVE_TIMEOUT = 20.0
#: The states that name a fault of each kind right (the rest: any but healthy).
RIGHT = {"lock": {Health.LOCKED}, "second": {Health.LOCKED}, "intermittent": {Health.LOCKED},
         "free_swing": {Health.FREE_SWINGING, Health.LOCKED}}


@dataclass
class Outcome:
    """One fault's outcome as a subscriber of `ft/joint_health` saw it."""

    kind: str
    joint: int
    moving: bool = False  #: the joint moved at `MOVING` when it failed
    second_moving: bool = False  #: the second lock's joint moved at `MOVING` when it locked
    named: str = "healthy"  #: the faulty joint's first declared state
    delay: float = math.nan  #: s from the injection to that message
    second_delay: float = math.nan  #: s from the second lock to its joint's declaration
    shown_delay: float = math.nan  #: s from when the fault showed to that message
    second_shown_delay: float = math.nan  #: the same for the second lock
    others: list[str] = field(default_factory=list)  #: healthy joints declared
    least_share: float = math.nan  #: the faulty joint's least share while watched
    others_least_share: float = math.nan  #: the other joints' least share (healthy: ~1)
    #: s from the faulty joint's share first falling below half to its declaration
    #: (0 when declared before; nan when it never slowed)
    slowed_delay: float = math.nan
    held: float = math.nan  #: m, a contact's tool from its goal as the wall was removed
    reached: bool = False  #: a contact's goal reached once the wall was gone


class FaultProbe(Probe):
    """The soak's probe, with the fault injection, the health and both resets."""

    def __init__(self, context: Context):
        super().__init__(context, goal_period=1.5, cycle=math.inf, pause=0.0)
        node = self.node
        self._inject = node.create_publisher(DiagnosticArray, names.INJECT_FAULT, qos.RELIABLE)
        self._sim_reset = node.create_client(Trigger, "sim/reset")
        self._obstacle = node.create_publisher(Marker, names.OBSTACLE, qos.RELIABLE)
        node.create_subscription(DiagnosticArray, names.JOINT_HEALTH, self._on_health,
                                 qos.LATCHED)
        node.create_subscription(JointState, names.JOINT_STATES, self._on_q, STREAM)
        node.create_subscription(JointState, names.COMMAND, self._on_sent, STREAM)
        self.states: dict[str, tuple[Health, float]] = {}  #: joint -> (state, arrival)
        self.q = np.zeros(7)
        self.qd = np.zeros(7)
        self.sent = np.zeros(7)
        self._sent_since: deque[tuple[float, np.ndarray]] = deque(maxlen=1000)
        #: joint -> when its fault showed (monotonic s; inf: not yet), for the faulty joints
        self.shown: dict[int, float] = {}
        #: joint -> when its share first fell below half (inf: not yet), the same joints
        self.slowed: dict[int, float] = {}
        self._init_share(time.monotonic())

    def _init_share(self, now: float) -> None:
        """The healthy servo at rest and no share yet, at `now` (monotonic s)."""
        #: each joint's least share since `inject` (inf: too little commanded)
        self.least = np.full(7, math.inf)
        self._share_at = now
        self._ref, self._healthy_q, self._healthy_qd = np.zeros(7), np.zeros(7), np.zeros(7)
        self._meter = FollowMeter(7)

    def _on_health(self, msg: DiagnosticArray) -> None:
        arrival = time.monotonic()
        health, _ = health_messages.read(msg, JOINTS)
        for name, h in health.items():
            if h.state != Health.HEALTHY and name not in self.states:
                self.states[name] = (h.state, arrival)

    def _on_q(self, msg: JointState) -> None:
        index = {name: k for k, name in enumerate(msg.name)}
        if all(name in index for name in JOINTS) and len(msg.velocity) == len(msg.name):
            self.q = np.array([msg.position[index[name]] for name in JOINTS])
            self.qd = np.array([msg.velocity[index[name]] for name in JOINTS])
            now = time.monotonic()
            in_force = next((sent for at, sent in reversed(self._sent_since)
                             if at <= now - LATENCY), None)
            if in_force is None:
                return
            stopped = (((in_force > 0) & (self.q >= PANDA.upper - LIMIT_MARGIN))
                       | ((in_force < 0) & (self.q <= PANDA.lower + LIMIT_MARGIN)))
            followable = np.where(stopped, 0.0, in_force)
            self._share(followable, now)
            for joint, shown in self.shown.items():
                if math.isinf(shown) and abs(followable[joint] - self.qd[joint]) >= MOVING:
                    self.shown[joint] = now

    def _share(self, followable: np.ndarray, now: float) -> None:
        """Update each joint's share of its command: see `RESPONSE_TIME`."""
        dt = min(now - self._share_at, 0.1)
        self._share_at = now
        w = 1.0 / RESPONSE_TIME
        for _ in range(max(round(dt / 1e-3), 1)):  # the healthy servo (ft_core.physics)
            h = dt / max(round(dt / 1e-3), 1)
            self._ref += followable * h
            self._healthy_qd += h * (w * w * (self._ref - self._healthy_q)
                                     + 2 * w * (followable - self._healthy_qd))
            self._healthy_q += self._healthy_qd * h
            self._ref = np.clip(self._ref, self._healthy_q - 0.1, self._healthy_q + 0.1)
        slowed = self._meter.update(now, dt, self.qd, self._healthy_qd, np.ones(7, bool))
        self.least = np.fmin(self.least, self._meter.shares)
        for joint in slowed:
            if math.isinf(self.slowed.get(joint, -math.inf)):
                self.slowed[joint] = now - PERSISTENCE

    def _on_sent(self, msg: JointState) -> None:
        index = {name: k for k, name in enumerate(msg.name)}
        if all(name in index for name in JOINTS) and len(msg.velocity) == len(msg.name):
            self.sent = np.array([msg.velocity[index[name]] for name in JOINTS])
            self._sent_since.append((time.monotonic(), self.sent))

    def moving(self, joint: int) -> bool:
        """Whether `joint` is commanded and moves at `MOVING` or more."""
        return bool(min(abs(self.sent[joint]), abs(self.qd[joint])) >= MOVING)

    def tick(self, send_goals: bool = True) -> None:
        """Send the next goal when due (no resets: the run does them)."""
        now = time.monotonic()
        if send_goals and now >= self._next_goal:
            self._send_goal()
            self._next_goal = now + self.goal_period

    def tool(self) -> np.ndarray:
        """Where the tool point is by the latest joint state (m, base frame)."""
        return TOOL.transform(self.q)[:3, 3]

    def next_goal(self) -> np.ndarray:
        """The goal the next `send_goal` sends (m)."""
        return np.array(GOALS[self._goal_index % len(GOALS)])

    def send_goal(self) -> None:
        """Send the next goal now."""
        self._send_goal()

    def wall(self, pose: np.ndarray | None) -> None:
        """A wall of edges `WALL` at `pose` (4x4, base frame) in the sim; None: removed."""
        self._obstacle.publish(Marker(action=Marker.DELETE) if pose is None
                               else fault_messages.obstacle_message(pose, WALL))

    def inject(self, fault: Fault, joint: int) -> float:
        """Publish `fault` of `joint`; the monotonic time of publication."""
        self._inject.publish(fault_messages.message([fault]))
        self.shown[joint] = self.slowed[joint] = math.inf
        if len(self.shown) == 1:
            self.least = np.full(7, math.inf)
        return time.monotonic()

    def reset(self, executor: EventsExecutor) -> None:
        """Reset the sim and the monitor, waiting for both answers (5 s at most each)."""
        for client in (self._sim_reset, self._reset):
            future = client.call_async(Trigger.Request())
            spin(self, executor, 5.0, future.done)
        self.states, self.shown, self.slowed = {}, {}, {}


def spin(probe: FaultProbe, executor: EventsExecutor, seconds: float,
         until=lambda: False, goals: bool = True) -> bool:
    """Spin `seconds` (wall clock), the goals going on if `goals`; stop early once `until()`."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        probe.tick(goals)
        executor.spin_once(timeout_sec=0.005)
        if until():
            return True
    return False


def _fault(kind: str, value: float, joint: int, probe: FaultProbe) -> Fault:
    name = JOINTS[joint]
    if kind in ("lock", "second"):
        return Fault(FaultKind.LOCK, name)
    if kind == "free_swing":
        return Fault(FaultKind.FREE_SWING, name)
    if kind == "intermittent":
        return Fault(FaultKind.INTERMITTENT, name, period=value)
    if kind == "range":  # a stop `value` rad ahead of the joint in its motion
        ahead = probe.q[joint] + math.copysign(value, probe.qd[joint])
        return Fault(FaultKind.RANGE, name, **({"upper": ahead} if probe.qd[joint] > 0
                                              else {"lower": ahead}))
    return Fault(FaultKind(kind), name, severity=value)


def run_fault(probe: FaultProbe, executor: EventsExecutor, kind: str, value: float,
              joint: int) -> Outcome:
    """One fault, from waiting for its joint to move to the resets after it."""
    outcome = Outcome(kind, joint)
    spin(probe, executor, 30.0, lambda: probe.observing == "yes")
    outcome.moving = spin(probe, executor, MOVE_TIMEOUT, lambda: probe.moving(joint))
    injected = probe.inject(_fault(kind, value, joint, probe), joint)
    second, second_at = (joint + 3) % 6, math.inf
    end = injected + WATCH
    while time.monotonic() < end:
        since = time.monotonic() - injected
        if kind == "second" and math.isinf(second_at) and since >= SECOND and (
                probe.moving(second) or since >= SECOND + SECOND_WAIT):
            outcome.second_moving = probe.moving(second)
            second_at = probe.inject(Fault(FaultKind.LOCK, JOINTS[second]), second)
            end = max(end, second_at + SECOND_WATCH)
        spin(probe, executor, 0.02)
    name = JOINTS[joint]
    if name in probe.states:
        state, arrival = probe.states[name]
        outcome.named, outcome.delay = str(state), arrival - injected
        outcome.shown_delay = max(arrival - probe.shown[joint], 0.0)
    if kind == "second" and JOINTS[second] in probe.states:
        arrival = probe.states[JOINTS[second]][1]
        outcome.second_delay = arrival - second_at
        outcome.second_shown_delay = max(arrival - probe.shown.get(second, math.inf), 0.0)
    least = np.where(np.isinf(probe.least), math.nan, probe.least)
    outcome.least_share = float(least[joint])
    others = [j for j in range(6) if j != joint and not (kind == "second" and j == second)]
    outcome.others_least_share = float(np.nanmin(least[others])) if np.isfinite(
        least[others]).any() else math.nan
    slowed = probe.slowed.get(joint, math.inf)
    if math.isfinite(slowed):
        outcome.slowed_delay = (max(probe.states[name][1] - slowed, 0.0)
                                if name in probe.states else math.inf)
    faulty = {name} | ({JOINTS[second]} if kind == "second" else set())
    outcome.others = sorted(set(probe.states) - faulty)
    probe.reset(executor)
    spin(probe, executor, 2.0)
    print(f"{time.strftime('%H:%M:%S')} {kind} {name}: {outcome.named} after "
          f"{1e3 * outcome.delay:.0f} ms, moving {outcome.moving}, least share "
          f"{outcome.least_share:.2f} (others {outcome.others_least_share:.2f}), named "
          f"{1e3 * outcome.slowed_delay:.0f} ms after it slowed, others {outcome.others}",
          flush=True)
    return outcome


def run_contact(probe: FaultProbe, executor: EventsExecutor) -> Outcome:
    """One contact: the tool driven into a wall for `PUSH` s, then freed (the module)."""
    outcome = Outcome("contact", -1)
    spin(probe, executor, 30.0, lambda: probe.observing == "yes")
    spin(probe, executor, REST, goals=False)
    goal = probe.next_goal()
    probe.wall(wall_across(probe.tool(), goal))
    spin(probe, executor, 0.5, goals=False)
    probe.send_goal()
    spin(probe, executor, PUSH, goals=False)
    outcome.held = float(np.linalg.norm(probe.tool() - goal))
    probe.wall(None)
    outcome.reached = spin(probe, executor, REACH, lambda: bool(
        np.linalg.norm(probe.tool() - goal) < REACHED), goals=False)
    spin(probe, executor, 1.0)
    outcome.others = sorted(probe.states)
    probe.reset(executor)
    spin(probe, executor, 2.0)
    print(f"{time.strftime('%H:%M:%S')} contact: held {outcome.held:.3f} m from its goal, "
          f"reached after {outcome.reached}, declared {outcome.others}", flush=True)
    return outcome


def _percentile(values: list[float], q: float) -> float:
    return float(np.percentile(values, q)) if values else math.nan


def table(outcomes: list[Outcome]) -> list[str]:
    """The markdown table, by kind."""
    lines = ["| fault | runs | named right | named as | delay p50 / p99 (ms) | "
             "from when it showed, p50 / p99 (ms) | least share (median; others' least) | "
             "slowed below half: named within 1 s | healthy joints declared |",
             "|---|---|---|---|---|---|---|---|---|"]
    for kind in dict.fromkeys(k for k, _ in KINDS):
        rows = [o for o in outcomes if o.kind == kind]
        right = [o for o in rows if o.named in {str(s) for s in RIGHT.get(kind, {
            Health.DEGRADED, Health.LOCKED, Health.FREE_SWINGING})}]
        delays = [1e3 * (o.second_delay if kind == "second" else o.delay) for o in right]
        shown = [1e3 * (o.second_shown_delay if kind == "second" else o.shown_delay)
                 for o in right]
        shown = [d for d in shown if math.isfinite(d)]
        slowed = [o for o in rows if not math.isnan(o.slowed_delay)]
        least = [o.least_share for o in rows if not math.isnan(o.least_share)]
        others = [o.others_least_share for o in rows if not math.isnan(o.others_least_share)]
        named: dict[str, int] = {}
        for o in rows:
            named[o.named] = named.get(o.named, 0) + 1
        lines.append(f"| {kind} | {len(rows)} | {len(right)} | "
                     + ", ".join(f"{k} {v}" for k, v in sorted(named.items()))
                     + f" | {_percentile(delays, 50):.0f} / {_percentile(delays, 99):.0f} | "
                     f"{_percentile(shown, 50):.0f} / {_percentile(shown, 99):.0f} | "
                     f"{_percentile(least, 50):.2f}; {min(others, default=math.nan):.2f} | "
                     f"{sum(o.slowed_delay <= 1.0 for o in slowed)} of {len(slowed)} | "
                     f"{sum(bool(o.others) for o in rows)} |")
    contacts = [o for o in outcomes if o.kind == "contact"]
    if contacts:
        lines.append(f"| contact {PUSH:.0f} s | {len(contacts)} | - | held "
                     f"{_percentile([o.held for o in contacts], 50):.2f} m from its goal "
                     f"(median), reached after the wall {sum(o.reached for o in contacts)} | "
                     f"- | - | - | - | {sum(bool(o.others) for o in contacts)} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    """Run the series and write its table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--loaded", action="store_true",
                        help="one busy process per core beside the nodes")
    parser.add_argument("--faults", type=int, default=len(KINDS) * 6)
    parser.add_argument("--kinds", default=",".join(dict.fromkeys(k for k, _ in KINDS)),
                        help="the kinds to inject, comma-separated (default: all)")
    parser.add_argument("--contacts", type=int, default=CONTACTS)
    parser.add_argument("--record", action="store_true",
                        help="keep every topic heard in <out>/faults_processes_bag")
    args = parser.parse_args(argv)
    domain = int(os.environ.get("FT_BENCH_DOMAIN_FAULTS", "64"))
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    executor = EventsExecutor(context=context)
    probe = FaultProbe(context)
    executor.add_node(probe.node)
    recorder = (Recorder(probe.node, args.out / "faults_processes_bag", time.monotonic_ns)
                if args.record else None)
    kinds = set(args.kinds.split(","))
    cases = [(kind, value, joint) for kind, value in KINDS if kind in kinds
             for joint in range(6)][:args.faults]
    outcomes: list[Outcome] = []
    try:
        with deployed("physics", domain, args.out / "faults_processes_logs", "separate"):
            spin(probe, executor, 90.0, lambda: probe.observing == "yes")
            with busy_cores() if args.loaded else nullcontext():
                outcomes = [run_fault(probe, executor, *case) for case in cases]
                outcomes += [run_contact(probe, executor) for _ in range(args.contacts)]
    finally:
        if recorder is not None:
            recorder.close()
        executor.shutdown()
        rclpy.shutdown(context=context)
    report(args.out, "faults_processes_loaded" if args.loaded else "faults_processes",
           table(outcomes),
           {"machine": machine(), "loaded": args.loaded,
            "outcomes": [asdict(o) for o in outcomes]})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
