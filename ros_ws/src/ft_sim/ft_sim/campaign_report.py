"""A campaign's tables and figure: success rates with Wilson intervals, exact McNemar tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from ft_core.engine import RESOLUTIONS
from scipy import stats


def wilson(successes: int, runs: int) -> tuple[float, float]:
    """95 % Wilson score interval of a success rate."""
    interval = stats.binomtest(successes, runs).proportion_ci(0.95, method="wilson")
    return float(interval.low), float(interval.high)


def _rate(successes: int, runs: int) -> str:
    if not runs:
        return "-"
    low, high = wilson(successes, runs)
    return f"{successes}/{runs} ({100 * successes / runs:.0f} %, {100 * low:.0f}-{100 * high:.0f})"


def table(results: list[dict]) -> str:
    """Markdown tables: each condition, then the runs whose outcome soft limits changed.

    Per condition: success with its CI, IK reachability after the lock, success where
    every point stays reachable and where the last joint locked (the tool's own axis in a
    position task), runs in which the controller followed a recovery path, the lock
    against the box, waypoints, detection, the velocity jump, and the commands against
    the arm's limits (the sim's driver: runs it stopped, the largest commanded
    acceleration and jerk over the limits).
    """
    lines = ["| condition | runs | success (%, 95 % CI) | every point reachable (IK) | "
             "success where every point is reachable | success, last joint locked | "
             "runs with a recovery path | "
             "lock outside the box | waypoints reached | right joint detected "
             "| runs with a false lock "
             "| detection latency median / max (ms) | velocity jump median / max (rad/s) "
             "| driver reflexes | peak acceleration / jerk over the limits |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    modes = [m for m in RESOLUTIONS if any(r["resolution"] == m for r in results)]
    for mode in modes:
        for soft in (False, True):
            group = [r for r in results if r["resolution"] == mode and r["soft_limits"] == soft]
            if not group:
                continue
            latency = [r["latency_ms"] for r in group if r["latency_ms"] is not None]
            jump = [r["velocity_jump"] for r in group if r["velocity_jump"] is not None]
            visits = [v for r in group for v in r["waypoint_visits"]]
            possible = [r for r in group if r["reachable"] == r["points"]]
            last = [r for r in group if r["locked"] == r["last_joint"]]
            peaks = [(r.get("peak_acceleration") or 0.0, r.get("peak_jerk") or 0.0)
                     for r in group]
            lines.append(
                f"| {mode}, {'with' if soft else 'without'} soft limits | {len(group)} | "
                f"{_rate(sum(r['success'] for r in group), len(group))} | "
                f"{_rate(len(possible), len(group))} | "
                f"{_rate(sum(r['success'] for r in possible), len(possible))} | "
                f"{_rate(sum(r['success'] for r in last), len(last))} | "
                f"{sum(r.get('recovery_paths', 0) > 0 for r in group)}/{len(group)} | "
                f"{sum(r['outside_box'] for r in group)}/{len(group)} | "
                f"{100 * np.mean(visits) if visits else 0:.0f} % | "
                f"{sum(r['correct_detection'] for r in group)}/{len(group)} | "
                f"{sum(bool(r.get('false_locks')) for r in group)}/{len(group)} | "
                f"{_stat(latency, '.0f')} | {_stat(jump, '.2f')} | "
                f"{sum(bool(r.get('reflex')) for r in group)}/{len(group)} | "
                f"{max(p[0] for p in peaks):.3g} / {max(p[1] for p in peaks):.3g} |")
    lines += ["", "| mode | paired runs | failed only without soft limits | failed only with "
              "them | exact McNemar p |", "|---|---:|---:|---:|---:|"]
    for mode in modes:
        pairs = _pairs(results, mode)
        if not pairs:
            continue
        only_free = sum(soft["success"] and not free["success"] for free, soft in pairs)
        only_soft = sum(free["success"] and not soft["success"] for free, soft in pairs)
        p = stats.binomtest(only_free, only_free + only_soft).pvalue if only_free + only_soft \
            else 1.0
        lines.append(f"| {mode} | {len(pairs)} | {only_free} | {only_soft} | {p:.2g} |")
    return "\n".join(lines) + "\n"


def points_table(results: list[dict]) -> str:
    """Markdown: per locked joint and critical point, reached against reachable.

    A cell is "reached / reachable (IK)" over the runs in which that joint locked, without
    and with soft limits (every mode together): the runs in which the point stayed
    reachable with the joint pinned, and how many of them reached it after the lock.
    Runs without a lock (none injected) are left out.
    """
    done = [r for r in results if r.get("reachable_points") is not None]
    if not done:
        return ""
    count = max(r["points"] for r in done)
    header = " | ".join(f"point {k + 1} {side}" for k in range(count)
                        for side in ("without", "with"))
    lines = [f"| locked joint | {header} |", "|---|" + "---:|" * (2 * count)]
    for joint in sorted({r["locked"] for r in done}):
        cells = []
        for k in range(count):
            for soft in (False, True):
                group = [r for r in done if r["locked"] == joint and r["soft_limits"] == soft
                         and k in r["reachable_points"]]
                cells.append(f"{sum(k in r['reached_points'] for r in group)}/{len(group)}")
        lines.append(f"| {joint} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _pairs(results: list[dict], mode: str) -> list[tuple[dict, dict]]:
    """(without, with soft limits) runs of `mode` that share a seed."""
    by = {(r["seed"], r["soft_limits"]): r for r in results if r["resolution"] == mode}
    return [(by[seed, False], by[seed, True]) for seed, soft in sorted(by)
            if not soft and (seed, True) in by]


def _stat(values: list[float], fmt: str) -> str:
    if not values:
        return "n/a"
    return f"{np.median(values):{fmt}} / {np.max(values):{fmt}}"


def figure(results: list[dict], path: Path) -> None:
    """Success rates with their 95 % intervals, latency and jump distributions."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    conditions = [(m, s) for m in RESOLUTIONS for s in (False, True)
                  if any(r["resolution"] == m and r["soft_limits"] == s for r in results)]
    groups = [[r for r in results if r["resolution"] == m and r["soft_limits"] == s]
              for m, s in conditions]
    labels = [f"{m}\n{'soft' if s else 'no soft'}" for m, s in conditions]
    rates = np.array([np.mean([r["success"] for r in g]) for g in groups])
    intervals = np.array([wilson(sum(r["success"] for r in g), len(g)) for g in groups])
    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    axes[0].bar(labels, rates, color=["tab:gray" if not s else "tab:blue"
                                      for _, s in conditions])
    axes[0].errorbar(labels, rates, yerr=[rates - intervals[:, 0], intervals[:, 1] - rates],
                     fmt="none", color="k", capsize=3)
    axes[0].set_ylabel("success rate (95 % CI)")
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
