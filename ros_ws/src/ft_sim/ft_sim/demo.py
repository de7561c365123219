"""`make demo` / `ft-demo` / `ros2 run ft_sim demo`: a joint locks mid-task and the task goes on.

In one process (`ft_sim.scenario`): the sim (owning the clock), the controller (with
bounding-box soft limits from the task's critical points) and the monitor. The
Panda visits three task points in turn; mid-task a joint is locked through
`ft/inject_failure`; the monitor detects it and the controller carries on with
the remaining joints (`--plant physics`: on the MuJoCo plant, `ft_core.physics`). It
prints a report and writes it to the output folder with
two figures, the time plots (`demo.png`) and the arm in 3D before the lock, at the
lock and after recovery with its tool path and task points (`arm.png`); with
`--record`, every topic as a rosbag2 in MCAP (`bag/`). With `--live`, the run is
served to Foxglove as it happens (`ft_sim.live`), in real time, with the layout to
watch it written first (`foxglove_layout.json`); the demo waits up to `VIEWER_WAIT` s
for a viewer to connect. The report:

- detection latency: from the injection to `ft/locked_joints`;
- tool-velocity error |J (qd_actual - qd_commanded)| before the lock, while it is
  undetected, and after detection;
- the joint-velocity jump the lock caused (command after detection against the
  command just before the lock);
- kfm before and after (the latter for a further failure);
- whether each task point was reached again after the lock (a tour of them), and how
  often the controller went round a stall along a recovery path (`ft_core.recovery`).

Exit status 0 when the story holds: the right joint detected, every task point
reached after the lock, no non-finite value on any topic. `--fault KIND[:VALUE]` injects
another kind of fault instead (`ft_core.faults.parse_spec`, through `ft/inject_fault`):
then the story holds if no other joint is declared locked (the failed one need not be).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from ft_core import faults, robots
from ft_core.engine import RESOLUTIONS
from ft_core.offline import cli
from ft_core.robots import TaskSpace

from ft_sim import arm_view, live
from ft_sim.scenario import PHYSICS_ROBOT, Record, Scenario, ScenarioConfig

#: s of simulated time a demo may last (a run is stepped in memory: bounded).
MAX_DURATION = 3600.0
#: s of wall clock `--live` waits for Foxglove to connect before the run starts anyway.
VIEWER_WAIT = 60.0


def summarise(config: ScenarioConfig, record: Record) -> dict:
    """The report's numbers from a record."""
    a = record.arrays()
    t, error = a["t"], a["tool_velocity_error"]
    injected = record.injected_at
    i = int(np.searchsorted(t, injected)) if injected is not None else len(t)
    detected = record.detected_at
    d = int(np.searchsorted(t, detected)) if detected is not None else len(t)
    after = t > (detected if detected is not None else np.inf) + 2 / config.rate
    reached_after = sorted(p for p, ok in record.tour.items() if ok)
    jump, locked_value = None, None
    if injected is not None and config.lock_joint in record.joint_names and i < len(t):
        locked_value = float(a["q"][i, record.joint_names.index(config.lock_joint)])
    critical = set(range(len(config.points)) if config.critical is None else config.critical)
    if detected is not None and 0 < i and d + 1 < len(t):
        jump = float(np.linalg.norm(a["qd_command"][d + 1] - a["qd_command"][i - 1]))
    return {
        "robot": config.robot, "resolution": config.resolution, "locked": config.lock_joint,
        "fault": config.fault,
        "injected_at_s": injected, "locked_value": locked_value,
        "detected_at_s": detected, "detected": record.detected,
        "latency_ms": None if detected is None else 1000 * (detected - injected),
        "error_before": float(error[:i].max()) if i else 0.0,
        "error_during": float(error[i:d + 1].max()) if d > i else 0.0,
        "error_after": float(error[after].max()) if after.any() else None,
        "velocity_jump": jump,
        "kfm_before": float(a["kfm"][i - 1]) if i else None,
        "kfm_after": float(a["kfm"][-1]),
        "points": len(record.tour) or len(config.points), "reached_after": reached_after,
        "non_finite": record.non_finite, "false_locks": record.false_locks,
        "soft_limits": record.soft_limits,
        "waypoint_visits": [ok for _, p, ok in record.visits if p not in critical],
        "recovery_paths": len(recovery_paths(record)),
        "replaced": record.replaced,
        "reflex": record.reflex,
        "peak_acceleration": max(record.peaks[1]) if record.peaks else None,
        "peak_jerk": max(record.peaks[2]) if record.peaks else None,
    }


def recovery_paths(record: Record) -> list[tuple[float, float]]:
    """(start, end) in simulated s of each recovery path the controller followed."""
    notes = [*record.recovery, (record.t[-1] if record.t else 0.0, "end of the run")]
    return [(t, notes[k + 1][0]) for k, (t, note) in enumerate(notes[:-1])
            if note.startswith("following")]


def verdict(summary: dict) -> list[str]:
    """What went wrong (empty: the story holds)."""
    problems = []
    locks = faults.parse_spec(summary["fault"])[0] is faults.FaultKind.LOCK
    if locks and summary["detected"] != [summary["locked"]]:
        problems.append(f"detected {summary['detected']} instead of {summary['locked']}")
    if not locks and not set(summary["detected"]) <= {summary["locked"]}:
        problems.append(f"healthy joints declared locked after the {summary['fault']} of "
                        f"{summary['locked']}: {summary['detected']}")
    if len(summary["reached_after"]) < summary["points"]:
        problems.append(f"only {len(summary['reached_after'])} of {summary['points']} task "
                        "points reached after the lock")
    if summary["non_finite"]:
        problems.append(f"{summary['non_finite']} messages with non-finite values")
    if summary["false_locks"]:
        problems.append(f"healthy joints declared locked before the failure: "
                        f"{summary['false_locks']}")
    if summary["reflex"]:
        problems.append(f"the driver refused a command and stopped the arm: {summary['reflex']}")
    return problems


def _fmt(value, unit: str = "", digits: int = 4) -> str:
    return "n/a" if value is None else f"{value:.{digits}g}{unit}"


def report(summary: dict, problems: list[str]) -> str:
    """The report as Markdown."""
    s = summary
    replaced = ", ".join(
        f"point {p} by one {1000 * metres:.0f} mm"
        + (f" and {np.degrees(radians):.0f} deg" if radians else "") + " away"
        for p, (metres, radians) in sorted(s["replaced"].items())) or "none"
    lines = [
        f"# ft-arms demo: {s['robot']}, {s['resolution']}, {s['locked']} "
        + ("locks" if s["fault"] == "lock" else f"fails ({s['fault']})"), "",
        "| | |", "|---|---|",
        f"| {'lock' if s['fault'] == 'lock' else 'fault'} injected | "
        f"{_fmt(s['injected_at_s'], ' s')} |",
        f"| detected | {', '.join(s['detected']) or 'nothing'} at "
        f"{_fmt(s['detected_at_s'], ' s')} |",
        f"| detection latency | {_fmt(s['latency_ms'], ' ms', 3)} |",
        f"| tool-velocity error before the lock | {_fmt(s['error_before'], ' m/s', 2)} |",
        f"| tool-velocity error while undetected | {_fmt(s['error_during'], ' m/s', 2)} |",
        f"| tool-velocity error after detection | {_fmt(s['error_after'], ' m/s', 2)} |",
        f"| joint-velocity jump at the lock | {_fmt(s['velocity_jump'], ' rad/s', 3)} |",
        f"| kfm before / after | {_fmt(s['kfm_before'], ' m', 3)} / "
        f"{_fmt(s['kfm_after'], ' m', 3)} |",
        f"| largest commanded acceleration / jerk, over the arm's limits | "
        f"{_fmt(s['peak_acceleration'], '', 3)} / {_fmt(s['peak_jerk'], '', 3)} |",
        f"| driver | {s['reflex'] or 'took every command'} |",
        f"| soft limits | {s['soft_limits']} |",
        f"| recovery paths (local control stalled) | {s['recovery_paths']} |",
        f"| task points reached after the lock | "
        f"{len(s['reached_after'])} of {s['points']} |",
        f"| task points out of the locked arm's reach, replaced | {replaced} |", "",
        "Verdict: " + ("the task went on after the failure." if not problems
                       else "FAILED: " + "; ".join(problems)),
    ]
    return "\n".join(lines) + "\n"


def figure(record: Record, summary: dict, path: Path) -> None:
    """Tool-velocity error, joint velocity commands and kfm against time (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    a = record.arrays()
    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    axes[0].semilogy(a["t"], np.maximum(a["tool_velocity_error"], 1e-12))
    axes[0].set_ylabel("tool velocity error (m/s)")
    for j, name in enumerate(record.joint_names):
        axes[1].plot(a["t"], a["qd_command"][:, j], label=name.split("_")[-1], lw=1)
    axes[1].set_ylabel("commanded joint velocity (rad/s)")
    axes[1].legend(ncol=4, fontsize=7, loc="upper left")
    axes[2].plot(a["t"], a["kfm"])
    axes[2].set_ylabel("kfm (m)")
    axes[2].set_xlabel("simulated time (s)")
    for ax in axes:
        for k, (start, end) in enumerate(recovery_paths(record)):
            ax.axvspan(start, end, color="tab:purple", alpha=0.15,
                       label="recovery path" if k == 0 else None)
        if summary["injected_at_s"] is not None:
            ax.axvline(summary["injected_at_s"], color="r", ls="--", lw=1)
        if summary["detected_at_s"] is not None:
            ax.axvline(summary["detected_at_s"], color="g", ls=":", lw=1)
    axes[0].set_title(f"{summary['locked']} locks (red), detected (green), recovery paths "
                      "shaded")
    if summary["recovery_paths"]:
        axes[0].legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def parser() -> argparse.ArgumentParser:
    """`ft-demo`'s command line (every number bounded: `cli.bounded`)."""
    defaults = ScenarioConfig()
    parser = argparse.ArgumentParser(prog="ft-demo", description=__doc__.splitlines()[0])
    parser.add_argument("--robot", help="built-in name "
                        f"({', '.join(sorted(robots.BUILTINS))}) or URDF path; without task "
                        "points of its own, three are chosen around a bent configuration "
                        f"(default {defaults.robot}, {PHYSICS_ROBOT} with --plant physics)")
    parser.add_argument("--plant", default=defaults.plant, choices=["kinematic", "physics"],
                        help="the sim's plant: kinematic, or physics (MuJoCo: servo lag, "
                        "overshoot, gravity; docs/sim.md) (default %(default)s)")
    parser.add_argument("--base-link", default="", help="first link of the chain")
    parser.add_argument("--tip-link", default="", help="tool link of the chain")
    parser.add_argument("--task", default=defaults.task_space,
                        choices=[space.value for space in TaskSpace],
                        help="task space (default %(default)s; planar for the planar3r)")
    parser.add_argument("--resolution", default=defaults.resolution,
                        choices=RESOLUTIONS)
    parser.add_argument("--joint", default="2", help="joint to lock: number (1 = base) or "
                        "name (default %(default)s)")
    parser.add_argument("--fault", default=defaults.fault, metavar="KIND[:VALUE]",
                        help="what fails: lock, free_swing, viscous[:N m s/rad], dry[:N m], "
                        "authority[:fraction], range[:rad either side], intermittent[:period "
                        "s] (docs/sim.md#faults; default %(default)s)")
    parser.add_argument("--lock-time", type=cli.bounded(float, 0.0, MAX_DURATION),
                        default=defaults.lock_time,
                        help="s of simulated time (default %(default)s)")
    parser.add_argument("--duration", type=cli.bounded(float, 1.0, MAX_DURATION),
                        default=defaults.duration, help="longest run, s of simulated time "
                        f"(1 to {MAX_DURATION:g}, default %(default)s)")
    parser.add_argument("--seed", type=cli.bounded(int, 0, cli.MAX_SEED), default=defaults.seed,
                        help="noise seed")
    parser.add_argument("--no-soft-limits", action="store_true",
                        help="run without the critical points' bounding-box soft limits")
    parser.add_argument("--out", type=Path, default=Path("demo_out"), help="output folder")
    parser.add_argument("--record", action="store_true", help="also write every topic as a "
                        "rosbag2 (MCAP) to <out>/bag, for Foxglove, PlotJuggler or ros2 bag")
    parser.add_argument("--live", nargs="?", const=live.DEFAULT_PORT, default=None,
                        type=cli.bounded(int, 0, 65535), metavar="PORT",
                        help="serve the run to Foxglove as it happens, in real time, on "
                        f"ws://localhost:PORT (default {live.DEFAULT_PORT}; 0: a free one); "
                        "the layout is written to <out>/foxglove_layout.json")
    return parser


def watch(scenario: Scenario, out: Path) -> None:
    """Write the Foxglove layout, say how to connect, and wait a while for a viewer."""
    out.mkdir(parents=True, exist_ok=True)
    layout = out / "foxglove_layout.json"
    layout.write_text(live.layout(scenario.robot.base_link, list(scenario.robot.joint_names)))
    print(f"live view: in Foxglove, Open connection > Foxglove WebSocket > "
          f"{scenario.live.url}, then import the layout {layout}; waiting up to "
          f"{VIEWER_WAIT:g} s for it ...", flush=True)
    if not scenario.live.wait_for_viewer(VIEWER_WAIT):
        print("no viewer connected: running anyway", flush=True)


@cli.clear_file_errors("ft-demo")
def main(argv: list[str] | None = None) -> int:
    """Run the demo; return 0 when the story holds."""
    defaults = ScenarioConfig()
    arguments = parser()
    args = arguments.parse_args(argv)
    args.robot = args.robot or (PHYSICS_ROBOT if args.plant == "physics" else defaults.robot)
    try:
        joints = cli.trackable(robots.load(args.robot, args.base_link or None,
                                           args.tip_link or None,
                                           task_space=args.task)).joint_names
    except robots.RobotModelError as error:
        arguments.error(f"--robot: {error}")
    joint = joints[int(args.joint) - 1] if args.joint.isdigit() and \
        1 <= int(args.joint) <= len(joints) else args.joint
    if joint not in joints:
        arguments.error(f"--joint must be 1..{len(joints)} or one of {list(joints)}")
    try:
        faults.parse_spec(args.fault)
    except faults.FaultError as error:
        arguments.error(f"--fault: {error}")
    if not 0 < args.lock_time < args.duration:
        arguments.error("--lock-time must lie inside the run")
    cli.check_folder(args.out)  # a file in the way fails now, not after the run
    scenario = Scenario(ScenarioConfig(
        robot=args.robot, base_link=args.base_link, tip_link=args.tip_link,
        task_space=args.task, resolution=args.resolution, plant=args.plant, lock_joint=joint,
        fault=args.fault, lock_time=args.lock_time, duration=args.duration, seed=args.seed,
        soft_limits=not args.no_soft_limits, reachable_tour=True),
        bag=args.out / "bag" if args.record else None, live_port=args.live)
    if scenario.live is not None:
        watch(scenario, args.out)
    what = "locks" if args.fault == "lock" else f"fails ({args.fault})"
    print(f"running the {scenario.robot.name} in simulated time; {joint} {what} at "
          f"{args.lock_time:g} s, then it visits every task point again; task points "
          f"{[[round(v, 3) for v in p] for p in scenario.config.points]} ...", flush=True)
    try:
        record = scenario.run()
    finally:
        scenario.close()
    config = scenario.config
    summary = summarise(config, record)
    problems = verdict(summary)
    text = report(summary, problems)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "report.md").write_text(text)
    figure(record, summary, args.out / "demo.png")
    arm_view.draw(scenario.robot, record, config.points, scenario.critical, config.lock_joint,
                  args.out / "arm.png")
    print(text)
    written = ["report.md", "demo.png", "arm.png"] + (["bag"] if args.record else [])
    print(f"wrote {', '.join(str(args.out / name) for name in written)}")
    return 0 if not problems else 1


if __name__ == "__main__":
    sys.exit(main())
