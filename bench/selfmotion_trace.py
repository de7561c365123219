"""`make bench`: seconds to trace self-motion manifolds and compute their boxes.

- Panda, pose task: the 1-D manifold through a working configuration (followed both
  ways until it closes or meets a limit).
- Panda, position task: the 4-D manifold of one critical point (extremal walks).
- PUMA 560 with joint 6 held, position task: the 2-D surface of Table II's P1 (spiral).

Each figure is the median over repeats after a warm-up run, written to
`<out>/selfmotion_trace.md` and `.json`.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from engine_cycle import machine, report
from ft_core import robots, selfmotion


def cases() -> dict[str, Callable[[], selfmotion.Manifold]]:
    """The traced manifolds, each as a function."""
    pose = robots.load("panda")
    q = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
    position = robots.load("panda", task_space="position")
    puma = robots.load(robots.builtin_urdf("puma560").replace(
        'name="puma_joint6" type="revolute"', 'name="puma_joint6" type="fixed"'),
        task_space="position")
    p1 = np.array([0.0, 0.9, 0.5])
    puma_seed = selfmotion.find_seed(puma, p1, np.array([np.pi / 2, -1.0, 2.0, 0.0, 0.5]))
    return {
        "Panda pose task, 1-D curve": lambda: selfmotion.trace(pose, pose.forward(q), q),
        "Panda position task, 4-D box of one point":
            lambda: selfmotion.trace(position, np.array([0.5, 0.1, 0.4])),
        "PUMA 560 joints 1-5, 2-D surface of P1 (spiral)":
            lambda: selfmotion.trace(puma, p1, puma_seed),
    }


def main(argv: list[str] | None = None) -> int:
    """Time each case and write the table and JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    results = {}
    for name, case in cases().items():
        manifold = case()
        seconds = []
        for _ in range(args.repeats):
            start = time.perf_counter()
            case()
            seconds.append(time.perf_counter() - start)
        results[name] = {"median_s": float(np.median(seconds)), "samples": len(manifold.samples),
                         "method": manifold.method, "repeats": args.repeats}
    lines = ["| self-motion tracing | method | samples | median (s) |", "|---|---|---:|---:|"]
    for name, figures in results.items():
        lines.append(f"| {name} | {figures['method']} | {figures['samples']} | "
                     f"{figures['median_s']:.2f} |")
    info = machine()
    lines += ["", f"{args.repeats} repeats; {info['cpu']}, Python {info['python']}, "
              f"{info['date']}."]
    report(args.out, "selfmotion_trace", lines, {"machine": info, "results": results})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
