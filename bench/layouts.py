"""`make bench`: what one arm costs in CPU, with the nodes as separate processes or as one.

For each control rate (250 and 1000 Hz by default), each `thread_priority` of the
controller and the monitor (0, the normal scheduler, and SCHED_FIFO 50) and each
layout, the installed console scripts run on the wall clock beside a probe streaming
a twist target; at 1000 Hz (`--busy-rates`) every case runs once more with one busy
process per core beside them (`ft_sim.cpu_load.busy_cores`):

- separate: `ft-sim`, `ft-controller` and `ft-monitor`, one process each (the
  `ros2 run` / launch-file layout);
- one process: `ft-sim` and `ft-stack` (controller and monitor on one executor,
  connected by calls: `ft_sim.stack.compose`);
- the floor, at each rate (idle, normal scheduler): `ft-sim` and a bare rclpy node
  (`rclpy_floor.py`) that takes `joint_states` and publishes a command for each (as
  `ft-stack` cycles on each joint state), nothing else: what any Python node exchanging
  those two messages pays, below which `ft-stack` cannot go.

These use the Panda's position task; at each of `--pose-rates` (250 and 1000 Hz) both
layouts run once more with the pose task (idle, normal scheduler). The table also
gives the controller's own CPU per cycle where it is a process of its own.

After a warm-up, each process's CPU time (user + system, from /proc) is read
before and after the timed run, and the controller's achieved rate comes from its
own `/diagnostics` (`loop_rate_hz`); the probe only streams the target meanwhile,
so the machine runs nothing else. Then the probe times a `joint_states` message to
the next `ft/command` for as long again (subscribing to both streams in Python costs
the probe about half a core at 1 kHz: that is why it is a phase of its own). "Per
arm" is the controller and the monitor (a real arm has a driver, not our sim); "arms
on this machine" is the number of cores divided by that share of a core: an upper
bound that ignores the driver and everything else the machine runs. SCHED_FIFO
needs root or an rtprio limit; where it is refused, the nodes say so and the row
shows the normal scheduler's figures under the label "refused".

Last, the command smoother's cost: the controller's own CPU per cycle in separate
processes at 1 kHz (pose task, idle), with `smooth_commands` off and on, alternated
(`--smoothing-pairs` pairs).

Writes `<out>/layouts.md` and `<out>/layouts.json`. DDS domain `FT_BENCH_DOMAIN_LAYOUTS`
(default 63).
"""

from __future__ import annotations

import argparse
import os
import time
from contextlib import nullcontext
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from engine_cycle import machine, report
from ft_msgs_py import qos
from ft_msgs_py.spin import spin_for, spin_until
from ft_sim.cpu_load import busy_cores
from nodes import installed, percentiles

FLOOR = "floor: a bare rclpy node (bench/rclpy_floor.py)"
LAYOUTS = {
    "separate processes": {"sim": ["ft-sim"], "controller": ["ft-controller"],
                           "monitor": ["ft-monitor"]},
    "one process (ft-stack)": {"sim": ["ft-sim"], "controller + monitor": ["ft-stack"]},
    FLOOR: {"sim": ["ft-sim"], "bare node": ["python", str(Path(__file__).with_name(
        "rclpy_floor.py"))]},
}
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    """User plus system CPU time of a process so far (s)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def run(layout: str, rate: float, priority: int, seconds: float, warm_up: float,
        busy: bool = False, task: str = "position", smooth: bool = True) -> dict:
    """One layout at one rate and priority: CPU per process, the controller's rate, latencies.

    With `busy`, the timed runs share the machine with one busy process per core.
    `task`: the Panda's task space (the probe's twist has six components). `smooth`:
    the controller's and the monitor's `smooth_commands`.
    """
    common = ["--ros-args", "-p", "robot_model:=panda", "-p", f"task_space:={task}",
              "-p", f"rate:={rate}", "-p", f"control_rate:={rate}", "-p", "resolution:=blend",
              "-p", f"smooth_commands:={str(smooth).lower()}"]
    commands = {name: [*script, *common] for name, script in LAYOUTS[layout].items()}
    for name, argv in commands.items():
        if name != "sim":
            argv += ["-p", f"thread_priority:={priority}"]
    rates: list[float] = []
    scheduling: set[str] = set()

    def on_diagnostics(msg: DiagnosticArray) -> None:
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            if "scheduling" in values:
                scheduling.add(values["scheduling"])
            if status.name == "/controller" and "loop_rate_hz" in values:
                rates.append(float(values["loop_rate_hz"]))

    domain = os.environ.get("FT_BENCH_DOMAIN_LAYOUTS", "63")
    with installed(commands, domain, timing=False) as (processes, executor, probe):
        probe.node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics,
                                       qos.SENSOR_INPUT)
        spin_for(executor, warm_up)
        with busy_cores() if busy else nullcontext():
            start = {name: cpu_seconds(p.pid) for name, p in processes.items()}
            rates.clear()
            began = time.monotonic()
            spin_for(executor, seconds)
            # The controller reports its rate with its diagnostics (DIAGNOSTICS_PERIOD): on
            # a busy machine a short window may hold none, so it is stretched to the first.
            # (The floor's node reports none.)
            spin_until(executor, lambda: bool(rates) or layout == FLOOR, 10.0)
            elapsed = time.monotonic() - began
            used = {name: cpu_seconds(p.pid) - start[name] for name, p in processes.items()}
            achieved = list(rates)
            probe.time_latencies()
            spin_for(executor, seconds)
            latencies = list(probe.latencies)
    share = {name: value / elapsed for name, value in used.items()}
    arm = sum(v for name, v in share.items() if name != "sim")
    return {"rate_hz": rate, "thread_priority": priority, "busy": busy, "task": task,
            "scheduling": sorted(scheduling),
            "seconds": elapsed, "cpu_share": share,
            "arm_cpu_share": arm, "arm_cpu_ms_per_cycle": 1e3 * arm / rate,
            "controller_rate_hz": float(np.median(achieved)) if achieved else float("nan"),
            "arms_per_machine": int((os.cpu_count() or 1) // arm) if arm > 0 else 0,
            "state_to_command_ms": percentiles(latencies)}


def above_floor(results: list[dict], cases: list[tuple]) -> list[str]:
    """Per rate, ft-stack's CPU per cycle against the floor's (idle, normal scheduler)."""
    idle = {(case[0], case[3]): r for r, case in zip(results, cases, strict=True)
            if not case[2] and not case[1] and case[4] == "position"}
    lines = []
    for (rate, layout), floor in idle.items():
        stack = idle.get((rate, "one process (ft-stack)"))
        if layout == FLOOR and stack is not None:
            mine, bare = stack["arm_cpu_ms_per_cycle"], floor["arm_cpu_ms_per_cycle"]
            lines.append(f"- {rate:.0f} Hz: ft-stack {mine:.3f} ms of CPU per cycle, the floor "
                         f"{bare:.3f} ms ({mine / bare:.2f} x): {mine - bare:.3f} ms is the "
                         "controller's and the monitor's own work and wiring.")
    return lines


def main(argv: list[str] | None = None) -> int:
    """Run every layout at every rate; write the table and JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--rates", type=float, nargs="+", default=[250.0, 1000.0])
    parser.add_argument("--priorities", type=int, nargs="+", default=[0, 50],
                        help="thread_priority of controller and monitor (0: normal)")
    parser.add_argument("--busy-rates", type=float, nargs="*", default=[1000.0],
                        help="rates also run with one busy process per core")
    parser.add_argument("--seconds", type=float, default=20.0,
                        help="timed run of each, and the latency run after it")
    parser.add_argument("--warm-up", type=float, default=10.0, help="discovery and warm-up")
    parser.add_argument("--pose-rates", type=float, nargs="*", default=[250.0, 1000.0],
                        help="rates also run with the pose task (idle, normal scheduler)")
    parser.add_argument("--smoothing-pairs", type=int, default=3,
                        help="alternated runs without and with the command smoother")
    args = parser.parse_args(argv)
    cases = [(rate, priority, busy, layout, "position")
             for busy, rates in ((False, args.rates), (True, args.busy_rates))
             for rate in rates for priority in args.priorities for layout in LAYOUTS
             if layout != FLOOR]
    cases += [(rate, 0, False, FLOOR, "position") for rate in args.rates]
    cases += [(rate, 0, False, layout, "pose") for rate in args.pose_rates for layout in LAYOUTS
              if layout != FLOOR]
    results = [run(layout, rate, priority, args.seconds, args.warm_up, busy, task)
               for rate, priority, busy, layout, task in cases]
    info = machine()
    lines = ["| task | rate | machine | scheduling | layout | controller rate (Hz) | CPU per arm "
             "(controller + monitor) | CPU per cycle (ms) | controller's CPU per cycle (ms) | "
             "sim's CPU | arms on this machine (bound) | joint_states to ft/command p50 / p99 "
             "(ms) |",
             "|---|---:|---|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r, (_, _, busy, layout, task) in zip(results, cases, strict=True):
        latency = r["state_to_command_ms"]
        shown = (f"{latency['p50']:.2f} / {latency['p99']:.2f}" if latency["samples"]
                 else "-")
        scheduling = "normal" if not r["thread_priority"] else (
            f"SCHED_FIFO {r['thread_priority']}" if all(
                s.startswith("SCHED_FIFO") for s in r["scheduling"]) else "refused")
        machine_load = "a busy process per core" if busy else "idle"
        controller = r["cpu_share"].get("controller")
        alone = "-" if controller is None else f"{1e3 * controller / r['rate_hz']:.3f}"
        achieved = "-" if layout == FLOOR else f"{r['controller_rate_hz']:.1f}"
        lines.append(f"| {task} | {r['rate_hz']:.0f} Hz | {machine_load} | {scheduling} | "
                     f"{layout} | {achieved} | "
                     f"{100 * r['arm_cpu_share']:.0f} % | {r['arm_cpu_ms_per_cycle']:.3f} | "
                     f"{alone} | "
                     f"{100 * r['cpu_share']['sim']:.0f} % | "
                     f"{'-' if busy else r['arms_per_machine']} | "
                     f"{shown} |")
    lines += ["", *above_floor(results, cases)]
    smoothing = smoothing_cost(args.smoothing_pairs, args.seconds, args.warm_up)
    lines += ["", *smoothing["lines"]]
    lines += ["", f"{args.seconds:.0f} s per run after {args.warm_up:.0f} s of warm-up, then "
              f"{args.seconds:.0f} s of latency timing; {info['cpu']}, {info['cores']} cores, "
              f"Python {info['python']}, {info['date']}."]
    report(args.out, "layouts", lines, {"machine": info, "runs": results,
                                        "smoothing": smoothing["runs"]})
    return 0


def smoothing_cost(pairs: int, seconds: float, warm_up: float) -> dict:
    """The controller's CPU per cycle (ms) without and with smoothing, alternated pairs."""
    runs: dict[str, list[float]] = {"off": [], "on": []}
    for _ in range(pairs):
        for smooth in (False, True):
            r = run("separate processes", 1000.0, 0, seconds, warm_up, task="pose",
                    smooth=smooth)
            runs["on" if smooth else "off"].append(1e3 * r["cpu_share"]["controller"] / 1000.0)
    if not pairs:
        return {"lines": [], "runs": runs}
    off, on = float(np.median(runs["off"])), float(np.median(runs["on"]))
    return {"runs": runs, "lines": [
        f"The command smoother: the controller's CPU per cycle at 1 kHz (pose task, separate "
        f"processes, idle), {pairs} alternated pairs: without {off:.3f} ms, with {on:.3f} ms "
        f"(medians; {100 * (on - off) / off:+.0f} %); runs without "
        f"{[round(v, 3) for v in runs['off']]}, with {[round(v, 3) for v in runs['on']]}."]}


if __name__ == "__main__":
    raise SystemExit(main())
