"""The command stream against the arm's limits: with and without smoothing, per mode.

For each plant (kinematic; physics: MuJoCo with 20 ms latency and 30 ms response time)
and each resolution mode, the demo's story (the Panda, position task, panda_joint2 locks)
runs with the smoother and without it. Reported per run, from the sim's driver test of
every command the plant got (`ft_core.command_limits.DriverCheck`, by the commands'
stamps, the locked joint left out): the largest commanded acceleration and jerk over the
limits (healthy motion and the lock together), the time to the first goal, the detection
latency, the tool's deviation (the tool-velocity error |J (qd_actual - qd_command)|
integrated, mm) while the lock was undetected and in the second after its detection, the
time from the detection until that error stays below 10 mm/s (the healthy joints on the
reduced solution), and whether every point was reached.
The raw runs do not refuse (they would stop at their first command). Then the
smoother's CPU per call, planning (a target step) and passing (a smooth target).

Usage: python bench/commands.py --out bench_out [--plants kinematic,physics]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from ft_core import robots
from ft_core.command_limits import command_limits
from ft_core.engine import RESOLUTIONS
from ft_core.smoothing import Smoother
from ft_sim import demo
from ft_sim.scenario import PHYSICS_ROBOT, ScenarioConfig, run


def one(plant: str, mode: str, smooth: bool, domain: int) -> dict:
    """The story on `plant` in `mode`, smoothed or not: the row of the table."""
    physics = plant == "physics"
    config = ScenarioConfig(robot=PHYSICS_ROBOT if physics else "panda", resolution=mode,
                            plant=plant, command_latency=0.02 if physics else 0.0,
                            response_time=0.03 if physics else 0.0, lock_time=5.0,
                            duration=40.0, smooth_commands=smooth, refuse_over_limits=smooth)
    record = run(config, domain_id=domain)
    summary = demo.summarise(config, record)
    a = record.arrays()
    first = next((end for end, _, ok in record.visits if ok), None)
    t, error = a["t"], a["tool_velocity_error"]
    injected, detected = record.injected_at or np.inf, record.detected_at or np.inf
    dt = 1.0 / config.rate
    undetected = (t > injected) & (t <= detected)
    after = (t > detected) & (t <= detected + 1.0)
    high = np.flatnonzero(after & (error >= 0.01))
    return {
        "plant": plant, "mode": mode, "smoothed": smooth,
        "peak_acceleration": summary["peak_acceleration"], "peak_jerk": summary["peak_jerk"],
        "first_goal_s": None if first is None else first - record.started_at,
        "latency_ms": summary["latency_ms"],
        "deviation_undetected_mm": 1e3 * dt * float(error[undetected].sum()),
        "deviation_after_mm": 1e3 * dt * float(error[after].sum()) if after.any() else None,
        "settled_ms": None if not after.any() else
        1e3 * ((t[high[-1]] + dt if high.size else detected) - detected),
        "reached": f"{len(summary['reached_after'])}/{summary['points']}",
        "reflex": record.reflex}


def smoother_cost(repeats: int = 20000) -> dict:
    """Median microseconds per `Smoother.step` on the Panda: planning, and passing."""
    panda = robots.load("panda")
    limits = command_limits(panda.name, panda.joint_names, panda.velocity_limits)
    result = {}
    for name, target in (("planning", lambda k: np.full(7, 1.0 if (k // 50) % 2 else -1.0)),
                         ("passing", lambda k: np.full(7, 0.2 * np.sin(0.002 * k)))):
        smoother, times = Smoother(limits), []
        for k in range(repeats):
            value = target(k)
            start = time.perf_counter()
            smoother.step(value, 0.001 * (k + 1))
            times.append(time.perf_counter() - start)
        result[name] = 1e6 * float(np.median(times))
    return result


def _fmt(value, digits: int = 3) -> str:
    return "n/a" if value is None else f"{value:.{digits}g}"


def main(argv: list[str] | None = None) -> None:
    """Run every story, write commands.md and commands.json into --out."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--plants", default="kinematic,physics")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    domain = 150
    for plant in args.plants.split(","):
        for mode in RESOLUTIONS:
            for smooth in (True, False):
                domain += 1
                rows.append(one(plant, mode, smooth, domain))
                print(rows[-1], flush=True)
    cost = smoother_cost()
    lines = ["# Commands against the arm's limits (the demo's story, Franka's limits)", "",
             "| plant | mode | smoothed | peak accel / limit | peak jerk / limit | first goal (s)"
             " | detection (ms) | tool deviation undetected (mm) | tool deviation in the second"
             " after (mm) | settled after detection (ms) | reached after | driver |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|---|"]
    for r in rows:
        lines.append(
            f"| {r['plant']} | {r['mode']} | {'yes' if r['smoothed'] else 'no'} | "
            f"{_fmt(r['peak_acceleration'])} | {_fmt(r['peak_jerk'])} | "
            f"{_fmt(r['first_goal_s'])} | {_fmt(r['latency_ms'])} | "
            f"{_fmt(r['deviation_undetected_mm'])} | {_fmt(r['deviation_after_mm'])} | "
            f"{_fmt(r['settled_ms'])} | "
            f"{r['reached']} | {r['reflex'] or 'took every command'} |")
    lines += ["", f"Smoother, median per call (7 joints): planning {cost['planning']:.1f} us, "
              f"passing {cost['passing']:.1f} us."]
    (args.out / "commands.md").write_text("\n".join(lines) + "\n")
    (args.out / "commands.json").write_text(json.dumps({"runs": rows, "smoother_us": cost},
                                                       indent=1))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
