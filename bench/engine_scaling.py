"""`make bench`: how one control cycle's cost grows with the number of joints.

Robot: a generated serial chain of n revolute joints (URDF built here), for n in
7, 12, 16, 24, 32, 48: joint axes alternating z, y, z, y, ..., 0.1 m apart along
the previous link's z, each limited to +-2.6 rad and 2 rad/s, then a 0.1 m tool
link; pose task (m = 6) at `tool`. At each n, `blend` and `least_norm`, pink and
mink are set up exactly as in `engine_cycle.py` (pink and mink with one reused
configuration, a frame task asking for the same task velocity, a posture task, the
URDF's position and velocity limits) and timed on the same seeded configurations
and task velocities, their passes interleaved.

Reports the median per cycle at each n, the ratio to pink, and the log-log slope
of median against n (a least-squares fit over every n, and over the
three largest sizes, 24 to 48 joints by default): a slope of 2 is a cost growing like
n^2.

Writes `<out>/engine_scaling.md` and `<out>/engine_scaling.json`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from engine_cycle import (
    MINK,
    PINK,
    engine_call,
    machine,
    mink_call,
    pink_call,
    report,
    summary,
    time_calls,
    workload,
)
from ft_core import robots

SIZES = (7, 12, 16, 24, 32, 48)
TOOL = "tool"
LINK = 0.1  # m between successive joints
LIMIT = 2.6  # rad
VELOCITY = 2.0  # rad/s


def chain_urdf(n: int) -> str:
    """URDF XML of a serial chain of n revolute joints with alternating z and y axes."""
    links = [f'  <link name="link{i}"/>' for i in range(n + 1)]
    links.append(f'  <link name="{TOOL}"/>')
    joints = []
    for i in range(n):
        axis = "0 0 1" if i % 2 == 0 else "0 1 0"
        height = 0.0 if i == 0 else LINK
        joints.append(
            f'  <joint name="joint{i + 1}" type="revolute">\n'
            f'    <parent link="link{i}"/>\n    <child link="link{i + 1}"/>\n'
            f'    <origin xyz="0 0 {height}" rpy="0 0 0"/>\n    <axis xyz="{axis}"/>\n'
            f'    <limit lower="{-LIMIT}" upper="{LIMIT}" velocity="{VELOCITY}" effort="10"/>\n'
            '  </joint>')
    joints.append(
        f'  <joint name="{TOOL}_joint" type="fixed">\n'
        f'    <parent link="link{n}"/>\n    <child link="{TOOL}"/>\n'
        f'    <origin xyz="0 0 {LINK}" rpy="0 0 0"/>\n  </joint>')
    return "\n".join([f'<?xml version="1.0"?>\n<robot name="chain{n}">', *links, *joints,
                      "</robot>"]) + "\n"


def slope(sizes: list[int], medians: list[float]) -> float:
    """Least-squares slope of log(median) against log(n)."""
    return float(np.polyfit(np.log(sizes), np.log(medians), 1)[0])


def measure(n: int, count: int, repeats: int, seed: int,
            with_mink: bool) -> dict[str, dict[str, float | int]]:
    """Median and p99 (us) of each candidate's cycle on the n-joint chain."""
    xml = chain_urdf(n)
    robot = robots.load(xml)
    qs, xds = workload(robot, count, seed)
    calls = {f"ft engine {mode}": engine_call(robot, mode, qs, xds)
             for mode in ("blend", "least_norm")}
    calls[PINK] = pink_call(xml, TOOL, qs, xds)
    if with_mink:
        calls[MINK] = mink_call(robot, xml, TOOL, qs, xds)
    return {name: summary(seconds)
            for name, seconds in time_calls(calls, count, repeats).items()}


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and write the table and JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--sizes", type=int, nargs="+", default=list(SIZES))
    parser.add_argument("--configurations", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    sizes = sorted(set(args.sizes))
    if len(sizes) < 2 or sizes[0] < 7:
        parser.error("give at least two sizes, each at least 7 joints")
    try:
        import mink  # noqa: F401
        with_mink = True
    except ImportError:
        with_mink = False
    results = {str(n): measure(n, args.configurations, args.repeats, args.seed, with_mink)
               for n in sizes}
    names = list(results[str(sizes[0])])
    medians = {name: [results[str(n)][name]["median_us"] for n in sizes] for name in names}
    tail = sizes[-3:] if len(sizes) > 2 else sizes
    slopes = {name: {"all": slope(sizes, values),
                     f"{tail[0]}-{tail[-1]}": slope(tail, values[-len(tail):])}
              for name, values in medians.items()}
    header = " | ".join(f"{name} (us)" for name in names)
    lines = [f"| joints | {header} | blend / pink |",
             "|---:|" + "---:|" * (len(names) + 1)]
    for k, n in enumerate(sizes):
        cells = " | ".join(f"{medians[name][k]:.0f}" for name in names)
        ratio = medians["ft engine blend"][k] / medians[PINK][k]
        lines.append(f"| {n} | {cells} | {ratio:.2f} |")
    lines.append("| log-log slope, all sizes | "
                 + " | ".join(f"{slopes[name]['all']:.2f}" for name in names) + " | |")
    lines.append(f"| log-log slope, {tail[0]}-{tail[-1]} joints | "
                 + " | ".join(f"{slopes[name][f'{tail[0]}-{tail[-1]}']:.2f}" for name in names)
                 + " | |")
    info = machine()
    lines.append("")
    lines.append(f"Medians; {args.configurations} configurations x {args.repeats} passes per "
                 f"size; {info['cpu']}, {info['cores']} cores, Python {info['python']}, "
                 f"{info['date']}.")
    report(args.out, "engine_scaling", lines, {
        "machine": info, "sizes": sizes, "configurations": args.configurations,
        "repeats": args.repeats, "seed": args.seed, "results": results, "slopes": slopes})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
