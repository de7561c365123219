"""`ft-campaign` (used by `make bench`): the fault experiment of seed 000 sec. V at scale.

Each run is a `scenario`: the Panda (position task) cycles between three critical
points and a non-critical waypoint far to the side; a random joint locks at a
random time (seeded, the same draws for every condition); then it tours the
critical points. Success: every critical point reached again (within the goal
tolerance and timeout). Conditions:

- with and without the critical points' bounding-box soft limits (`blend`);
- each resolution mode with soft limits, for the distributions of detection
  latency and of the joint-velocity jump at the lock.

Runs go to a process pool (one DDS domain per concurrent run). Writes
`<out>/campaign.md` (table), `campaign.json` (every run) and `campaign.png`.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from multiprocessing import Pool
from pathlib import Path

import numpy as np

from ft_sim.demo import summarise
from ft_sim.scenario import TASK_POINTS, ScenarioConfig, run

#: The Panda's critical points, then a non-critical waypoint far from them (m).
POINTS = (*TASK_POINTS["panda"], (0.15, 0.5, 0.25))
MODES = ("least_norm", "max_kfm", "min_jump", "blend")


def draw(seed: int) -> tuple[str, float]:
    """The joint that locks and when (s), for run `seed`."""
    rng = np.random.default_rng(seed)
    return f"panda_joint{rng.integers(1, 8)}", float(rng.uniform(2.0, 8.0))


def one_run(task: tuple[int, str, bool, int]) -> dict:
    """Run one scenario; return its summary (JSON-ready)."""
    seed, mode, soft, domain = task
    joint, lock_time = draw(seed)
    config = ScenarioConfig(points=POINTS, critical=(0, 1, 2), resolution=mode,
                            soft_limits=soft, lock_joint=joint, lock_time=lock_time,
                            duration=30.0, rate=125.0, seed=seed, goal_tolerance=5e-3,
                            goal_timeout=5.0)
    record = run(config, domain_id=domain)
    summary = summarise(config, record)
    summary.update(seed=seed, soft_limits=soft,
                   success=len(summary["reached_after"]) == summary["points"],
                   correct_detection=summary["detected"] == [joint])
    return summary


def tasks(runs: int, first_domain: int) -> list[tuple[int, str, bool, int]]:
    """Every (seed, mode, soft limits, DDS domain) to run."""
    conditions = [("blend", False)] + [(mode, True) for mode in MODES]
    todo = [(seed, mode, soft) for seed in range(runs) for mode, soft in conditions]
    return [(seed, mode, soft, first_domain + i % 60) for i, (seed, mode, soft) in
            enumerate(todo)]


def table(results: list[dict]) -> str:
    """Markdown table: success, detection and jump per condition."""
    lines = ["| condition | runs | success | right joint detected | detection latency "
             "median / max (ms) | velocity jump median / max (rad/s) |",
             "|---|---:|---:|---:|---:|---:|"]
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
    parser.add_argument("--first-domain", type=int, default=30,
                        help="first DDS domain id of the runs (each concurrent run gets one)")
    args = parser.parse_args(argv)
    todo = tasks(args.runs, args.first_domain)
    print(f"{len(todo)} runs on {args.workers} workers ...", flush=True)
    with Pool(args.workers) as pool:
        results = pool.map(one_run, todo, chunksize=1)
    text = table(results)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "campaign.md").write_text(text)
    (args.out / "campaign.json").write_text(json.dumps(results, indent=1) + "\n")
    figure(results, args.out / "campaign.png")
    print(text)
    return 0 if not any(r["non_finite"] for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
