"""Observability motion (issue 16): time from a lock on an idle joint to its detection.

The Panda (position task) holds a task point on the sim's realistic plant (20 ms
latency, 30 ms response time, holding the last command), in lock-step simulated time;
the controller's excursions are on (idle time 5 s, 1 s each, 0.3 rad/s peak, the
defaults); after a random hold (so the lock comes at a random phase of the round of
excursions) `panda_joint7`, on the tool axis and never commanded by the task, locks.
Reports the latency from the lock to the monitor's declaration and the largest tool
deviation from the held point while the excursions run. Writes observability.md/json.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np
from ft_sim.scenario import TASK_POINTS, Scenario, ScenarioConfig
from rclpy.parameter import Parameter


def trial(seed: int, domain: int) -> tuple[float | None, float]:
    """(detection latency in s or None, largest tool deviation in m) of one trial."""
    config = ScenarioConfig(points=(TASK_POINTS["panda"][0],), soft_limits=False, rate=125.0,
                            noise=1e-3, seed=seed, command_latency=0.02, response_time=0.03,
                            hold_last_command=True)
    scenario = Scenario(config, domain_id=domain)
    try:
        scenario.controller.set_parameters([Parameter("observability.enabled", value=True)])
        scenario.start()
        if not scenario.reach(0, 2e-3, 10.0):
            raise RuntimeError("the arm did not reach the point")
        hold = float(np.random.default_rng(seed).uniform(5.0, 15.0))
        scenario.hold(0, 2.0)  # settling on the point
        deviation = scenario.hold(0, hold)
        scenario.inject("panda_joint7")
        return scenario.until_detected(30.0), deviation
    finally:
        scenario.close()


def main() -> None:
    """Run the trials and write the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--trials", type=int, default=20)
    args = parser.parse_args()
    domain = int(os.environ.get("ROS_DOMAIN_ID", "40")) + 1
    results = [trial(seed, domain) for seed in range(args.trials)]
    latencies = [lat for lat, _ in results if lat is not None]
    deviations = [dev for _, dev in results]
    summary = {"trials": args.trials, "detected": len(latencies),
               "latency_median_s": float(np.median(latencies)) if latencies else None,
               "latency_max_s": float(np.max(latencies)) if latencies else None,
               "deviation_median_mm": 1e3 * float(np.median(deviations)),
               "deviation_max_mm": 1e3 * float(np.max(deviations))}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "observability.json").write_text(json.dumps(
        {"summary": summary, "trials": results}, indent=1) + "\n")
    text = ("| trials | detected | latency median / max (s) | tool deviation median / max (mm) |\n"
            "|---:|---:|---:|---:|\n"
            f"| {args.trials} | {len(latencies)} | "
            f"{summary['latency_median_s'] or float('nan'):.2f} / "
            f"{summary['latency_max_s'] or float('nan'):.2f} | "
            f"{summary['deviation_median_mm']:.2f} / {summary['deviation_max_mm']:.2f} |\n")
    (args.out / "observability.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
