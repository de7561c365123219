"""`make bench`: every way a joint fails, on the physics plant, through the controller and monitor.

The fault grid of docs/benchmarks.md ("Faults beyond a clean lock"): kinds x joints x
severities on `ft_sim.closed_loop` (the controller and monitor cores at their default
parameters, the MuJoCo Panda with its inertias, a position task, a goal every 1.5 s),
behind two drivers (fast: 10 ms latency, 20 ms servo; slow: 50 ms, 50 ms, the last command
held). Each run moves through healthy goals for 4 s, waits until the faulty joint is
commanded and moves (at least 0.1 rad/s, as a lock shows only then), injects the fault
(`ft_core.faults`) and runs on: the goal under way, then four goals, 3 s each (15 s in
all). A second lock follows the first on joint (j + 3) mod 6 after 0, 2 or 5 s.
Contact: the tool driven into a wall across its way to a fresh goal for 3 s, 10 times
per driver (the least-share column then holds how far, m, the wall held the tool from
its goal).

Per run: the state the monitor first declared the faulty joint in and when (s after the
fault; for a free swing also after its velocity first departed from the command in force
at the plant, which for a joint gravity does not turn comes only once the command
changes), its smallest share of the command after the fault (`follows`), every other
joint declared (a healthy joint declared: as bad as a missed failure), the goals after
the fault the tool came within 1 cm of, and how many of them the arm could still reach
with its failed joints held where they ended (`ft_core.recovery.reachable`). Healthy
motion: `--healthy-minutes` per driver, every declaration counted. The loop runs in
simulated time: its figures do not depend on the machine's load (the nodes under load:
tests/processes).

Writes `<out>/faults.md`, `<out>/faults.json` and `<out>/faults.png`.
"""

from __future__ import annotations

import argparse
import math
import multiprocessing
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from engine_cycle import machine, report
from ft_core import recovery
from ft_core.faults import Fault, FaultKind
from ft_core.health import Health
from ft_sim.closed_loop import DRIVERS, GOAL_PERIOD, WALL, ClosedLoop, wall_across

#: s of healthy goals before a fault (the monitor identifies the plant meanwhile).
HEALTHY = 4.0
#: s between goals after the fault: long enough for a healthy arm to come within `REACHED`.
AFTER_PERIOD = 3.0
#: Goals after the fault whose reach is counted.
GOALS_AFTER = 4
#: s after the fault: the goal under way (its period becomes `AFTER_PERIOD`), then the
#: goals counted.
AFTER = (GOALS_AFTER + 1) * AFTER_PERIOD
#: rad/s the faulty joint must move and be commanded at when the fault comes.
MOVING = 0.1
#: m within which a goal counts as reached.
REACHED = 0.01
#: Inverse-kinematics starts for whether a goal not reached was still reachable.
REACH_ATTEMPTS = 20
#: s the tool is held by a wall in a contact run.
CONTACT = 3.0
#: Contact runs per driver.
CONTACTS = 10
#: The grid's conditions: (kind, severity or period or cut, label).
CONDITIONS = ([("lock", math.nan, "lock"), ("free_swing", math.nan, "free swing")]
              + [("viscous", s, f"viscous {s:g}") for s in (5.0, 20.0, 50.0)]
              + [("dry", s, f"dry {s:g}") for s in (1.0, 3.0, 5.0)]
              + [("authority", s, f"authority {s:g}") for s in (0.75, 0.5, 0.25)]
              + [("range", 0.05, "range cut"), ("intermittent", 0.5, "intermittent")]
              + [("second", d, f"second lock +{d:g} s") for d in (0.0, 2.0, 5.0)])
#: The states that name a fault of each kind right.
NAMED_RIGHT = {"lock": {Health.LOCKED}, "second": {Health.LOCKED},
               "intermittent": {Health.LOCKED}, "range": {Health.LOCKED, Health.DEGRADED},
               "free_swing": {Health.FREE_SWINGING, Health.LOCKED}}
DEGRADING = {Health.DEGRADED, Health.LOCKED, Health.FREE_SWINGING}
#: The share of its command below which a joint has slowed (the degraded target's "half").
SLOWED = 0.5


@dataclass
class Run:
    """One fault's outcome."""

    kind: str
    severity: float
    label: str
    driver: str
    joint: int
    named: str = "healthy"  #: the faulty joint's first declared state
    delay: float = math.nan  #: s from the fault (the second's, for a second lock) to it
    second_delay: float = math.nan  #: s from the second lock to its declaration
    #: s from the first command of at least `MOVING` to the second locked joint to its
    #: declaration (a lock shows only while its joint is commanded)
    second_commanded_delay: float = math.nan
    least_share: float = math.nan  #: the faulty joint's smallest share after the fault
    #: s from its share first falling below one half to its first declaration (a fault
    #: that leaves a joint following shows only once it slows)
    slowed_delay: float = math.nan
    #: s from the faulty joint's velocity first differing by `MOVING` from the command in
    #: force at the plant to its first declaration (a joint gravity does not turn coasts
    #: on as commanded when it loses its torque, and shows only once the command changes)
    shown_delay: float = math.nan
    others: list[str] = field(default_factory=list)  #: healthy joints declared
    goals: int = 0
    reached: int = 0
    #: goals the arm could still reach, its failed joints held where they ended
    reachable: int = 0


def _fault(kind: str, severity: float, loop: ClosedLoop, joint: int) -> Fault:
    name = loop.robot.joint_names[joint]
    if kind in ("lock", "free_swing", "second"):
        return Fault(FaultKind.FREE_SWING if kind == "free_swing" else FaultKind.LOCK, name)
    if kind == "intermittent":
        return Fault(FaultKind.INTERMITTENT, name, period=severity)
    if kind == "range":  # a stop `severity` rad ahead of the joint in its motion
        q, ahead = loop.plant.q[joint], math.copysign(severity, loop.plant.qd[joint])
        return Fault(FaultKind.RANGE, name, **({"upper": q + ahead} if ahead > 0
                                                else {"lower": q + ahead}))
    return Fault(FaultKind(kind), name, severity=severity)


def run_one(kind: str, severity: float, label: str, driver: str, joint: int) -> Run:
    """Inject one fault of the grid on `joint` behind `driver`; its outcome."""
    loop = ClosedLoop("position", DRIVERS[driver], seed=joint)
    try:
        return _run(loop, kind, severity, label, driver, joint)
    finally:
        loop.close()


def _run(loop: ClosedLoop, kind: str, severity: float, label: str, driver: str,
         joint: int) -> Run:
    loop.run(HEALTHY)
    loop.run(3 * GOAL_PERIOD, stop=lambda: min(abs(loop.plant.qd[joint]),
                                               abs(loop.sent[joint])) > MOVING)
    result = Run(kind, severity, label, driver, joint)
    second = (joint + 3) % 6
    loop.plant.inject(joint, _fault(kind, severity, loop, joint))
    loop.goal_period = AFTER_PERIOD  # from the next goal on
    start, board, names = loop.t, loop.monitor.board, loop.robot.joint_names
    shares, second_at, goals = [], math.inf if kind != "second" else start + severity, {}
    commanded_at = math.inf  # when the second locked joint was first commanded
    slowed_at = math.inf  # when the faulty joint's share first fell below SLOWED
    shown_at = math.inf  # when the faulty joint's velocity first departed from its command
    where: dict[int, np.ndarray] = {}  # each goal's position (m)
    for _ in range(round(AFTER / loop.dt)):
        if loop.t >= second_at and second not in loop.plant.locked:
            loop.plant.lock(second)
            second_at = loop.t
        loop.run(loop.dt)
        if abs(loop.plant.path.in_force(loop.plant.t)[joint] - loop.plant.qd[joint]) >= MOVING:
            shown_at = min(shown_at, loop.t)
        if loop.t >= second_at and abs(loop.sent[second]) >= MOVING:
            commanded_at = min(commanded_at, loop.t)
        if result.named == "healthy" and board.states[joint] != Health.HEALTHY:
            result.named, result.delay = str(board.states[joint]), loop.t - start
        if (kind == "second" and math.isnan(result.second_delay)
                and board.states[second] != Health.HEALTHY and loop.t >= second_at):
            result.second_delay = loop.t - second_at
            result.second_commanded_delay = loop.t - min(commanded_at, loop.t)
        share = loop.monitor.detector.follow.shares[joint]
        if not math.isnan(share):
            shares.append(float(share))
            slowed_at = min(slowed_at, loop.t) if share < SLOWED else slowed_at
        if loop.goal_sent_at >= start and len(goals) <= GOALS_AFTER:  # sent after the fault
            goals[loop.goals] = min(goals.get(loop.goals, math.inf), loop.tool_error())
            where[loop.goals] = loop.goal
    faulty = {joint, second} if kind == "second" else {joint}
    result.others = [names[j] for j, s in enumerate(board.states)
                     if s != Health.HEALTHY and j not in faulty]
    result.least_share = min(shares, default=math.nan)
    if math.isfinite(slowed_at):
        result.slowed_delay = max(start + result.delay - slowed_at, 0.0)
    if math.isfinite(shown_at):
        result.shown_delay = max(start + result.delay - shown_at, 0.0)
    counted = sorted(goals)[:GOALS_AFTER]
    result.goals, result.reached = len(counted), sum(goals[g] < REACHED for g in counted)
    q, failed = loop.plant.q, sorted({*loop.plant.locked, *loop.plant.swinging})
    result.reachable = result.reached + sum(
        recovery.reachable(loop.robot, where[g], q, failed, [q], REACH_ATTEMPTS)
        for g in counted if goals[g] >= REACHED)
    return result


def contact_run(driver: str, seed: int) -> Run:
    """The tool held by a wall across its way for `CONTACT` s, then freed; the outcome.

    Every joint declared counts as a healthy joint declared; the goal is reached once the
    wall is gone.
    """
    loop = ClosedLoop("position", DRIVERS[driver], seed=seed)
    try:
        loop.run(HEALTHY + 0.3 * seed)
        while loop.tool_error() < 0.12:  # a goal far enough away
            loop.run(loop.dt)
        loop.goal_period = math.inf  # the goal under way: held by the wall, then reached
        tool = loop.robot.transform(loop.plant.q)[:3, 3]
        loop.plant.place_obstacle(wall_across(tool, loop.goal, beyond=0.01), np.array(WALL))
        loop.run(CONTACT)
        held = loop.tool_error()
        loop.plant.remove_obstacle()
        error = math.inf
        for _ in range(round(AFTER_PERIOD / loop.dt)):
            loop.run(loop.dt)
            error = min(error, loop.tool_error())
        result = Run("contact", CONTACT, f"contact {CONTACT:g} s", driver, -1)
        result.others = [loop.robot.joint_names[j]
                         for j, state in enumerate(loop.monitor.board.states)
                         if state != Health.HEALTHY]
        result.least_share = held  # m: how far the wall held the tool from its goal
        result.goals, result.reached = 1, int(error < REACHED)
        result.reachable = 1
        return result
    finally:
        loop.close()


def healthy_minutes(driver: str, minutes: float) -> dict[str, float]:
    """Declarations in `minutes` of healthy goals behind `driver`."""
    loop = ClosedLoop("position", DRIVERS[driver], seed=99)
    declared: list[str] = []
    try:
        for _ in range(round(minutes * 60 / 10)):
            loop.run(10.0)
            declared += [loop.robot.joint_names[j]
                         for j, s in enumerate(loop.monitor.board.states) if s != Health.HEALTHY]
            if declared:  # an operator's ~/reset, and on
                loop.monitor.reset(loop.t)
                loop.controller.set_locked([])
    finally:
        loop.close()
    return {"driver": driver, "minutes": minutes, "declared": len(declared),
            "joints": sorted(set(declared))}


def _percentile(values: list[float], q: float) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return float(np.percentile(finite, q)) if finite else math.nan


def table(runs: list[Run], healthy: list[dict]) -> list[str]:
    """The markdown table of the grid, by condition."""
    lines = ["| fault | runs | named right | named as (first) | delay p50 / p99 (ms) | "
             "least share (median) | slowed below half: named | healthy joints declared | "
             "goals reached after (of those still reachable) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for _kind, _severity, label in [*CONDITIONS, ("contact", CONTACT, f"contact {CONTACT:g} s")]:
        rows = [r for r in runs if r.label == label]
        if not rows:
            continue
        right = [r for r in rows if _named_right(r)]
        delays = [1e3 * (r.second_delay if r.kind == "second" else r.delay) for r in right]
        since, what = (([1e3 * r.second_commanded_delay for r in right], "its first command")
                       if rows[0].kind == "second" else
                       ([1e3 * r.shown_delay for r in right], "when it showed")
                       if rows[0].kind == "free_swing" else ([], ""))
        named: dict[str, int] = {}
        for r in rows:
            named[r.named] = named.get(r.named, 0) + 1
        shares = [r.least_share for r in rows if math.isfinite(r.least_share)]
        if rows[0].kind == "contact":  # nothing to name: only false declarations count
            lines.append(f"| {label} | {len(rows)} | - | - | - | held {np.median(shares):.2f} m "
                         f"from its goal | - | {sum(bool(r.others) for r in rows)} | "
                         f"{sum(r.reached for r in rows)} of {len(rows)} (after the wall) |")
            continue
        slowed = [r for r in rows if r.least_share < SLOWED]
        late = [1e3 * r.slowed_delay for r in slowed if math.isfinite(r.slowed_delay)]
        lines.append(
            f"| {label} | {len(rows)} | {len(right)} | "
            + ", ".join(f"{k} {v}" for k, v in sorted(named.items())) + " | "
            f"{_percentile(delays, 50):.0f} / {_percentile(delays, 99):.0f}"
            + (f" ({_percentile(since, 50):.0f} / {_percentile(since, 99):.0f} from "
               f"{what})" if since else "") + " | "
            f"{np.median(shares) if shares else math.nan:.2f} | "
            f"{sum(r.named != 'healthy' for r in slowed)} of {len(slowed)}"
            + (f", at most {max(late):.0f} ms after it slowed" if late else "") + " | "
            f"{sum(bool(r.others) for r in rows)} | "
            f"{sum(r.reached for r in rows)} of {sum(r.goals for r in rows)} "
            f"({sum(r.reachable for r in rows)}) |")
    lines += ["", "| driver | healthy minutes | declarations |", "|---|---|---|"]
    lines += [f"| {h['driver']} | {h['minutes']:g} | {h['declared']} {h['joints'] or ''} |"
              for h in healthy]
    return lines


def _named_right(r: Run) -> bool:
    if r.kind == "second":
        return r.named == Health.LOCKED and math.isfinite(r.second_delay)
    return r.named in NAMED_RIGHT.get(r.kind, DEGRADING)


def figure(runs: list[Run], path: Path) -> None:
    """Delay from fault to declaration per condition, every run a dot (missed: at the top)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = [label for _, _, label in CONDITIONS if any(r.label == label for r in runs)]
    runs = [r for r in runs if r.kind != "contact"]  # nothing to name
    fig, ax = plt.subplots(figsize=(9, 4.5))
    for i, label in enumerate(labels):
        for r in (r for r in runs if r.label == label):
            delay = r.second_delay if r.kind == "second" else r.delay
            missed = not math.isfinite(delay)
            ax.plot(i + (0.15 if r.driver == "slow" else -0.15), AFTER if missed else delay,
                    "x" if missed else "o", color="tab:red" if r.others else
                    ("tab:blue" if r.driver == "fast" else "tab:orange"), ms=4)
    ax.set_xticks(range(len(labels)), labels, rotation=60, ha="right")
    ax.set_yscale("log")
    ax.set_ylabel("s from the fault to the joint's declaration")
    ax.set_title("Faults on the physics plant (blue fast, orange slow driver; red: another "
                 "joint declared; x: not named)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv: list[str] | None = None) -> None:
    """Run the grid and write its table, figures and plot."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--drivers", nargs="+", default=list(DRIVERS), choices=list(DRIVERS))
    parser.add_argument("--joints", nargs="+", type=int, default=list(range(6)))
    parser.add_argument("--healthy-minutes", type=float, default=5.0)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    cases = [(kind, severity, label, driver, joint) for kind, severity, label in CONDITIONS
             for driver in args.drivers for joint in args.joints]
    contacts = [(driver, seed) for driver in args.drivers for seed in range(CONTACTS)]
    with ProcessPoolExecutor(args.workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        runs = list(pool.map(run_one, *zip(*cases, strict=True)))
        runs += list(pool.map(contact_run, *zip(*contacts, strict=True)))
        healthy = list(pool.map(healthy_minutes, args.drivers,
                                [args.healthy_minutes] * len(args.drivers)))
    lines = table(runs, healthy)
    report(args.out, "faults", lines, {"machine": machine(),
                                       "runs": [asdict(r) for r in runs], "healthy": healthy})
    figure(runs, args.out / "faults.png")


if __name__ == "__main__":
    main()
