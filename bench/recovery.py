"""`make bench`: the recovery after a lock (issue 30), with and without, on the same runs.

The controller core (`ft_core.controller`, default parameters) drives the Panda position
task on the sim's kinematic plant behind the campaign's driver (20 ms latency, 30 ms
response time, the last command held), without ROS. Each trial draws, from its seed, a
configuration inside the joint limits, a joint that is locked there (any of the 7), and a
goal that stays reachable with it pinned (the tool point of another random configuration
with the same value of that joint); the controller knows the lock from the start and
tracks the goal for `--seconds` of simulated time, once without and once with recovery.
A plan is waited for in wall time with the simulated clock held (a planner much faster
than the arm; on a real arm the controller keeps tracking meanwhile).

Reports: goals reached (5 mm) with and without recovery, the runs that stalled without
it and how many of those it saved, the time to reach with recovery, and the wall time of
`Controller.step` per cycle in both (median, p99, max: the plan runs in the worker
process, so the cycle should not notice it). Writes `<out>/recovery.md` and `.json`.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from engine_cycle import machine, report
from ft_core import robots
from ft_core.controller import Controller, ControllerConfig
from ft_core.engine import EngineConfig
from ft_core.plant import Plant, PlantConfig
from ft_core.recovery import RecoveryConfig

PANDA = robots.load("panda", task_space="position")
#: The campaign's driver (docs/campaign.md).
DRIVER = PlantConfig(latency=0.02, response_time=0.03, hold_last_command=True)
#: m; the goal counts as reached this close (the campaign's tolerance).
REACHED = 0.005
#: s of wall time a plan may take before the trial stops waiting for it.
PLAN_WAIT = 60.0


def closed_loop(q0: np.ndarray, locked: int, goal: np.ndarray, enabled: bool,
                seconds: float, driver: PlantConfig = DRIVER, known: bool = True) -> dict:
    """One run of the controller towards `goal` with joint `locked` held at q0's value.

    `known`: the controller is told of the lock from the start (otherwise never).

    Returns the goal's error at the end (m), when it was reached (s or None), the
    recovery's notes in order, the locked joint's travel (rad) and every step's wall
    time (s).
    """
    engine = EngineConfig()
    config = ControllerConfig(recovery=RecoveryConfig() if enabled else None)
    controller = Controller(PANDA, engine, config, ("panda", (None, None, "position", None)))
    started = controller.start_worker()  # as the controller node does at model load,
    if started is not None:  # before its first cycle
        started.result(timeout=PLAN_WAIT)
    plant = Plant(PANDA.lower, PANDA.upper, PANDA.velocity_limits, q0, driver)
    plant.lock(locked)
    if known:
        controller.set_locked([locked], 0.0)
    controller.set_pose_goal(goal, 0.0)
    notes: list[str] = []
    steps: list[float] = []
    t, reached = 0.0, None
    try:
        while t < seconds and reached is None:
            deadline = time.monotonic() + PLAN_WAIT
            while (controller.recovery is not None and controller.recovery.planning
                   and time.monotonic() < deadline):
                time.sleep(0.005)
            start = time.perf_counter()
            step = controller.step(plant.q, 0.0, t)
            steps.append(time.perf_counter() - start)
            if not notes or notes[-1] != controller.recovery_note:
                notes.append(controller.recovery_note)
            plant.command(t, step.qd)
            t += engine.dt
            plant.step(t)
            if np.linalg.norm(PANDA.task_error(goal, plant.q)) < REACHED:
                reached = t
    finally:
        controller.close()
    return {"error": float(np.linalg.norm(PANDA.task_error(goal, plant.q))),
            "reached": reached, "notes": notes,
            "locked_travel": float(abs(plant.q[locked] - q0[locked])), "steps": steps}


def draw(seed: int) -> tuple[np.ndarray, int, np.ndarray]:
    """(start configuration, locked joint, goal reachable with it pinned) of a trial."""
    rng = np.random.default_rng(seed)
    q0 = rng.uniform(PANDA.lower, PANDA.upper)
    locked = int(rng.integers(0, PANDA.n))
    other = rng.uniform(PANDA.lower, PANDA.upper)
    other[locked] = q0[locked]
    return q0, locked, PANDA.transform(other)[:3, 3]


def main(argv: list[str] | None = None) -> int:
    """Run the trials with and without recovery; write the table and JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--trials", type=int, default=40)
    parser.add_argument("--seconds", type=float, default=15.0,
                        help="simulated time per run (s)")
    args = parser.parse_args(argv)
    runs = []
    for seed in range(args.trials):
        q0, locked, goal = draw(seed)
        without = closed_loop(q0, locked, goal, False, args.seconds)
        with_ = closed_loop(q0, locked, goal, True, args.seconds)
        runs.append({"seed": seed, "locked": locked, "without": without, "with": with_})
        print(f"seed {seed}: joint {locked + 1} locked; without {without['error']:.4f} m, "
              f"with {with_['error']:.4f} m ({with_['notes'][-1]})", flush=True)
    stalled = [r for r in runs if r["without"]["reached"] is None]
    saved = [r for r in stalled if r["with"]["reached"] is not None]
    lost = [r for r in runs if r["without"]["reached"] is not None
            and r["with"]["reached"] is None]
    times = [r["with"]["reached"] for r in runs if r["with"]["reached"] is not None]

    def steps(key: str) -> str:
        values = np.concatenate([r[key]["steps"] for r in runs]) * 1e3
        return (f"{np.median(values):.3f} / {np.percentile(values, 99):.3f} / "
                f"{values.max():.2f}")

    reached = {key: sum(r[key]["reached"] is not None for r in runs) for key in ("without",
                                                                                 "with")}
    lines = ["| recovery | goals reached (5 mm) | stalled runs saved | reached only without |"
             " time to reach, median / max (s) | `Controller.step` wall time, median / p99 /"
             " max (ms) |", "|---|---:|---:|---:|---:|---:|",
             f"| off | {reached['without']}/{len(runs)} | - | - | - | {steps('without')} |",
             f"| on | {reached['with']}/{len(runs)} | {len(saved)}/{len(stalled)} | "
             f"{len(lost)} | {np.median(times):.1f} / {max(times):.1f} | {steps('with')} |"]
    info = machine()
    lines += ["", f"{args.trials} trials, {args.seconds:.0f} s each: the Panda position task, "
              "a random joint locked at a random configuration, a goal reachable with it "
              f"pinned; plant 20 ms latency, 30 ms response time; {info['cpu']}, "
              f"{info['date']}."]
    for run in runs:
        for key in ("without", "with"):
            run[key]["steps"] = float(np.max(run[key]["steps"]))  # keep the JSON small
    report(args.out, "recovery", lines, {"machine": info, "runs": runs})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
