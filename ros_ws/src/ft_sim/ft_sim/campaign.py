"""`ft-campaign` (used by `make bench`): the fault experiment of seed 000 sec. V at scale.

Each run is a `scenario`: the arm (the Panda by default, or `--robot` with its chain
options; position task) cycles between three critical points and a non-critical
waypoint far to the side; a random joint locks at a random time (seeded, the same
draws for every condition); then it tours the critical points. Success: every
critical point reached again (within the goal tolerance and timeout); a lock
declared before the failure is a false lock. The sim's plant options
(`--latency`, `--response-time`, `--hold-last-command`) make it realistic.
Conditions:

- with and without the critical points' bounding-box soft limits (`blend`);
- each resolution mode with soft limits, for the distributions of detection
  latency and of the joint-velocity jump at the lock.

Runs go to a process pool (`--workers`), one DDS domain per run counted from
ROS_DOMAIN_ID + 1. Each finished run is kept in `<out>/runs/<options>/` (a folder
per arm and plant options) and not run again: a campaign resumes where it stopped.
Writes `<out>/campaign.md` (table), `campaign.json` (every run) and `campaign.png`.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import multiprocessing
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from ft_core import robots, selfmotion

from ft_sim.demo import summarise
from ft_sim.scenario import TASK_POINTS, ScenarioConfig, run

#: The Panda's non-critical waypoint, far from its critical points (m).
PANDA_WAYPOINT = (0.15, 0.5, 0.25)
MODES = ("least_norm", "max_kfm", "min_jump", "blend")


def points(robot: robots.Robot) -> tuple[tuple[float, ...], ...]:
    """Three critical points, then a non-critical waypoint far from them (m).

    The built-in's task points, or for another arm three points around its bent
    configuration and, as the waypoint, the tool with the first joint turned 1.2 rad.
    """
    if robot.name == "panda":
        return (*TASK_POINTS["panda"], PANDA_WAYPOINT)
    start = selfmotion.bent_configuration(robot)
    far = start.copy()
    far[0] = np.clip(far[0] + 1.2, robot.lower[0], robot.upper[0])
    chosen = [*selfmotion.points_around(robot, start), robot.forward(far)]
    return tuple(tuple(float(v) for v in p[:3]) for p in chosen)


def draw(seed: int, joints: tuple[str, ...]) -> tuple[str, float]:
    """The joint that locks and when (s), for run `seed`."""
    rng = np.random.default_rng(seed)
    return joints[int(rng.integers(len(joints)))], float(rng.uniform(2.0, 8.0))


def one_run(task: tuple) -> dict:
    """Run one scenario; return its summary (JSON-ready)."""
    seed, mode, soft, domain, base = task
    robot = robots.load(base["robot"], base["base_link"] or None, base["tip_link"] or None,
                        task_space="position")
    joint, lock_time = draw(seed, robot.joint_names)
    config = ScenarioConfig(points=points(robot), critical=(0, 1, 2), resolution=mode,
                            soft_limits=soft, lock_joint=joint, lock_time=lock_time,
                            duration=30.0, rate=125.0, seed=seed, goal_tolerance=5e-3,
                            goal_timeout=5.0, **base)
    record = run(config, domain_id=domain)
    summary = summarise(config, record)
    summary.update(seed=seed, soft_limits=soft,
                   success=len(summary["reached_after"]) == summary["points"],
                   correct_detection=summary["detected"] == [joint])
    return summary


def tasks(runs: int, first_domain: int, base: dict) -> list[tuple]:
    """Every (seed, mode, soft limits, DDS domain, scenario options) to run."""
    conditions = [("blend", False)] + [(mode, True) for mode in MODES]
    todo = [(seed, mode, soft) for seed in range(runs) for mode, soft in conditions]
    return [(seed, mode, soft, (first_domain + i % 60) % 230, base) for i, (seed, mode, soft)
            in enumerate(todo)]


def _kept(out: Path, task: tuple) -> Path:
    """Where a finished run is kept: one folder per arm and plant, one file per run."""
    seed, mode, soft, _, base = task
    options = hashlib.sha256(json.dumps(base, sort_keys=True).encode()).hexdigest()[:12]
    return out / "runs" / options / f"{seed}-{mode}-{'soft' if soft else 'free'}.json"


def table(results: list[dict]) -> str:
    """Markdown table: success, detection and jump per condition."""
    lines = ["| condition | runs | success | right joint detected | runs with a false lock "
             "| detection latency median / max (ms) | velocity jump median / max (rad/s) |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    conditions = [("blend", False)] + [(mode, True) for mode in MODES]
    for mode, soft in conditions:
        group = [r for r in results if r["resolution"] == mode and r["soft_limits"] == soft]
        if not group:
            continue
        latency = [r["latency_ms"] for r in group if r["latency_ms"] is not None]
        jump = [r["velocity_jump"] for r in group if r["velocity_jump"] is not None]
        name = f"{mode}, {'with' if soft else 'without'} soft limits"
        lines.append(
            f"| {name} | {len(group)} | {sum(r['success'] for r in group)}/{len(group)} | "
            f"{sum(r['correct_detection'] for r in group)}/{len(group)} | "
            f"{sum(bool(r.get('false_locks')) for r in group)}/{len(group)} | "
            f"{_stat(latency, '.0f')} | {_stat(jump, '.2f')} |")
    return "\n".join(lines) + "\n"


def _stat(values: list[float], fmt: str) -> str:
    if not values:
        return "n/a"
    return f"{np.median(values):{fmt}} / {np.max(values):{fmt}}"


def figure(results: list[dict], path: Path) -> None:
    """Success rates and the latency and jump distributions per condition."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    conditions = [("blend", False)] + [(mode, True) for mode in MODES]
    labels = [f"{m}\n{'soft' if s else 'no soft'}" for m, s in conditions]
    groups = [[r for r in results if r["resolution"] == m and r["soft_limits"] == s]
              for m, s in conditions]
    axes[0].bar(labels, [np.mean([r["success"] for r in g]) if g else 0 for g in groups])
    axes[0].set_ylabel("success rate")
    axes[1].boxplot([[r["latency_ms"] for r in g if r["latency_ms"] is not None] or [0]
                     for g in groups], tick_labels=labels)
    axes[1].set_ylabel("detection latency (ms)")
    axes[2].boxplot([[r["velocity_jump"] for r in g if r["velocity_jump"] is not None] or [0]
                     for g in groups], tick_labels=labels)
    axes[2].set_ylabel("joint velocity jump (rad/s)")
    for ax in axes:
        ax.tick_params(axis="x", labelsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """Run the campaign and write its outputs; 0 unless a run produced non-finite values."""
    parser = argparse.ArgumentParser(prog="ft-campaign", description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20, help="seeds per condition")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--robot", default="panda", help="built-in name or URDF path")
    parser.add_argument("--base-link", default="", help="first link of the chain")
    parser.add_argument("--tip-link", default="", help="tool link of the chain")
    parser.add_argument("--latency", type=float, default=0.0, help="plant latency (s)")
    parser.add_argument("--response-time", type=float, default=0.0,
                        help="plant velocity response time (s)")
    parser.add_argument("--hold-last-command", action="store_true",
                        help="the plant holds the last command (ros2_control)")
    parser.add_argument("--first-domain", type=int,
                        default=int(os.environ.get("ROS_DOMAIN_ID", "29")) + 1,
                        help="first DDS domain id of the runs (default ROS_DOMAIN_ID + 1)")
    args = parser.parse_args(argv)
    try:
        robots.load(args.robot, args.base_link or None, args.tip_link or None)
    except robots.RobotModelError as error:
        parser.error(f"--robot: {error}")
    base = {"robot": args.robot, "base_link": args.base_link, "tip_link": args.tip_link,
            "command_latency": args.latency, "response_time": args.response_time,
            "hold_last_command": args.hold_last_command}
    every = tasks(args.runs, args.first_domain, base)
    todo = [task for task in every if not _kept(args.out, task).exists()]
    print(f"{len(every)} runs ({len(every) - len(todo)} kept from before) on {args.workers} "
          "workers ...", flush=True)
    if every:
        _kept(args.out, every[0]).parent.mkdir(parents=True, exist_ok=True)
    # Not multiprocessing.Pool: its workers are daemons, and a daemon cannot start the
    # process in which the controller traces the critical points' boxes. Spawned, not
    # forked: a fork of a process with DDS threads (a test session's) can deadlock.
    with ProcessPoolExecutor(args.workers, mp_context=multiprocessing.get_context("spawn")
                             ) as pool:
        for done, (task, result) in enumerate(zip(todo, pool.map(one_run, todo),
                                                  strict=True), 1):
            _kept(args.out, task).write_text(json.dumps(result) + "\n")
            print(f"  {done}/{len(todo)}: seed {task[0]}, {task[1]}, "
                  f"{'soft' if task[2] else 'free'}: "
                  f"{'success' if result['success'] else 'failed'}", flush=True)
    results = [json.loads(_kept(args.out, task).read_text()) for task in every]
    text = table(results)
    (args.out / "campaign.md").write_text(text)
    (args.out / "campaign.json").write_text(json.dumps(results, indent=1) + "\n")
    figure(results, args.out / "campaign.png")
    print(text)
    return 0 if not any(r["non_finite"] for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
