"""`make bench`: one control cycle of the engine in each mode, beside pink, in one run.

Robot: the built-in Panda, pose task (m = 6). Every mode and pink see the same
seeded set of configurations inside the joint limits and the same small task
velocities. pink (pin-pink, DAQP) solves a frame task on `panda_hand_tcp` plus a
posture task, with its default configuration and velocity limits; its timed
cycle includes building `pink.Configuration` (forward kinematics and Jacobians),
as ours includes computing J (and dJ). Each figure is the median and 99th
percentile over repeated passes after a warm-up pass, the candidates' passes
interleaved.

Writes `<out>/engine_cycle.md` (a Markdown table) and `<out>/engine_cycle.json`
(every figure with the machine's description).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pink
import pinocchio as pin
from ft_core import robots
from ft_core.engine import RESOLUTIONS, EngineConfig, ResolutionEngine
from pink.tasks import FrameTask, PostureTask

TIP = "panda_hand_tcp"


def workload(count: int, seed: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Seeded configurations (0.2 rad inside the limits) and task velocities (|v| ~ 0.1)."""
    robot = robots.load("panda")
    rng = np.random.default_rng(seed)
    qs = [robot.random_configuration(rng, margin=0.2) for _ in range(count)]
    xds = [rng.normal(scale=0.05, size=6) for _ in range(count)]
    return qs, xds


def time_calls(calls: dict[str, Callable[[int], object]], count: int,
               repeats: int) -> dict[str, np.ndarray]:
    """Seconds per call of each candidate, over `repeats` passes after a warm-up pass.

    The passes are interleaved (every candidate once per pass, in turn), so a slow
    spell of a noisy machine falls on all of them alike.
    """
    samples: dict[str, list[float]] = {name: [] for name in calls}
    for repeat in range(repeats + 1):
        for name, call in calls.items():
            for i in range(count):
                start = time.perf_counter()
                call(i)
                if repeat:
                    samples[name].append(time.perf_counter() - start)
    return {name: np.array(values) for name, values in samples.items()}


def engine_call(mode: str, qs: list, xds: list) -> Callable[[int], object]:
    """One engine cycle per workload entry."""
    engine = ResolutionEngine(robots.load("panda"), EngineConfig(resolution=mode))
    return lambda i: engine.step(qs[i], xds[i])


def pink_call(qs: list, xds: list) -> Callable[[int], object]:
    """Pink with a frame task towards a pose 1 cm/0.01 rad ahead and a posture task."""
    model = pin.buildModelFromXML(robots.builtin_urdf("panda"))
    data = model.createData()
    frame = FrameTask(TIP, position_cost=1.0, orientation_cost=1.0)
    posture = PostureTask(cost=1e-3)
    targets = []
    for q, xd in zip(qs, xds, strict=True):
        configuration = pink.Configuration(model, data, q)
        pose = configuration.get_transform_frame_to_world(TIP)
        targets.append(pin.exp6(pin.Motion(xd[:3] * 0.2, xd[3:] * 0.2)) * pose)

    def call(i: int) -> object:
        configuration = pink.Configuration(model, data, qs[i])
        frame.set_target(targets[i])
        posture.set_target(qs[i])
        return pink.solve_ik(configuration, [frame, posture], 0.004, solver="daqp")

    return call


def machine() -> dict[str, str]:
    """What the figures were measured on."""
    cpu = platform.processor()
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        for line in cpuinfo.read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    return {"cpu": cpu, "cores": str(os.cpu_count()), "python": platform.python_version(),
            "numpy": np.__version__, "pinocchio": pin.__version__,
            "date": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")}


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and write the table and JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--configurations", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    qs, xds = workload(args.configurations, args.seed)
    calls = {f"ft engine {mode}": engine_call(mode, qs, xds) for mode in RESOLUTIONS}
    calls["pink (frame + posture, DAQP)"] = pink_call(qs, xds)
    results = {}
    for name, seconds in time_calls(calls, args.configurations, args.repeats).items():
        results[name] = {"median_us": float(np.median(seconds) * 1e6),
                         "p99_us": float(np.percentile(seconds, 99) * 1e6),
                         "samples": int(seconds.size)}
    pink_median = results["pink (frame + posture, DAQP)"]["median_us"]
    lines = ["| cycle (Panda, pose task) | median (us) | p99 (us) | median / pink |",
             "|---|---:|---:|---:|"]
    for name, figures in results.items():
        lines.append(f"| {name} | {figures['median_us']:.0f} | {figures['p99_us']:.0f} | "
                     f"{figures['median_us'] / pink_median:.2f} |")
    info = machine()
    lines.append("")
    lines.append(f"{args.configurations} configurations x {args.repeats} passes; "
                 f"{info['cpu']}, {info['cores']} cores, Python {info['python']}, "
                 f"{info['date']}.")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "engine_cycle.md").write_text("\n".join(lines) + "\n")
    (args.out / "engine_cycle.json").write_text(json.dumps(
        {"machine": info, "configurations": args.configurations, "repeats": args.repeats,
         "seed": args.seed, "results": results}, indent=2) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
