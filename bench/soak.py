"""`make bench`: false locks and free-swing declarations per hour of healthy motion, deployed.

The installed executables (`sim_node`, `controller_node`, `monitor_node` from the colcon
install space ros_ws/install, as `ros2 run` starts them) run as separate processes at
their default parameters (with `--layout stack`: `sim_node` and `stack`, the controller
and the monitor in one process, which cycles on each joint state) on each of the sim's
plants:
- kinematic: the Panda (`panda`, position task) behind a driver with a command watchdog
  (30 ms latency, 30 ms response time, 0.1 s command timeout, 1e-3 rad position noise);
- physics: the Panda with its inertias (`panda_inertial`, flange `panda_link8`, position
  task) in MuJoCo behind a slow driver that holds the last command (50 ms latency, a
  50 ms servo, 1e-3 rad position noise).
A probe in this process sends pose goals (`ft/target_pose`, three positions in turn)
every `--goal-period` s and every `--cycle` s stops sending them for `--pause` s, so
the arm keeps starting, moving and stopping. After a warm-up (goals until the monitor
says it observes: it has identified and seen the plant follow) each plant runs
`--minutes`: the first half on an otherwise idle machine, the second half with one busy
process per core beside the nodes (`ft_sim.cpu_load.busy_cores`, normal scheduler).

Counted per half (idle, loaded):
- false locks: every non-empty `ft/locked_joints` message, with its joints; each is
  followed by a call of the monitor's `~/reset` (as an operator would) and the run goes on;
- free-swing and degraded declarations: the monitor's log lines "joint ... free-swinging
  (t = ...)" and "joint ... degraded (t = ...)"
  (its stdout and stderr are kept in a file); the probe also sees them in the monitor's
  diagnostics (`free_swinging_joints`) and resets the monitor after each, or a joint
  declared once would never be declared again (a degraded joint is logged once until
  the next reset);
- observing: the share of the monitor's diagnostics (2 Hz) with `observing == yes` (a
  reset restarts the plant identification, so it drops after each);
- motion: the joint-space path travelled (rad, of positions averaged over blocks of 50
  joint states: the noise stays out) and the `ft/command` messages, with the largest gap
  between the stamps of two consecutive ones (ms: the controller's cycles, or the
  monitor's watchdog zeros) and between their arrivals at the probe; every gap of at
  least 100 ms between two stamps of `ft/command` or `joint_states` is listed (stalls, to
  set beside a lock's time);
- the machine: mean cores used by the nodes (and what they started), the probe, the busy
  processes and everything else (other users' work: an "idle" half is only idle if that
  is near 0).

Writes `<out>/soak.md`, `<out>/soak.json` and the processes' logs under
`<out>/soak_logs/<plant>/`. DDS domain `FT_BENCH_DOMAIN_SOAK` (default 63), discovery on
localhost only.
"""

from __future__ import annotations

import argparse
import os
import re
import time
from pathlib import Path

import rclpy
from engine_cycle import machine, report
from ft_sim.cpu_load import busy_cores
from rclpy.context import Context
from rclpy.experimental.events_executor import EventsExecutor
from soak_probe import GOALS, LOCKED, STREAM, Phase, Probe, Travel
from soak_processes import LAYOUTS, PLANTS, cpu_counters, cpu_use, deployed

__all__ = ["GOALS", "LAYOUTS", "LOCKED", "LOG_LINE", "PLANTS", "STREAM", "Phase", "Probe",
           "Travel", "cpu_counters", "cpu_use", "deployed", "main", "monitor_log",
           "run_plant", "spin_phase", "summary", "table"]

#: A monitor log line (rcutils' default format): wall time (s) and message.
LOG_LINE = re.compile(r"^\[(\w+)\] \[(\d+(?:\.\d+)?)\] \[monitor\]: (.*)$")


def spin_phase(probe: Probe, executor: EventsExecutor, seconds: float,
               until: str | None = None) -> bool:
    """Spin `seconds` (wall clock) with the goal schedule; stop early once `until` holds.

    `until` "observing": the monitor's newest diagnostics say it observes. Returns
    whether it stopped early.
    """
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        probe.tick()
        executor.spin_once(timeout_sec=0.005)
        if until == "observing" and probe.observing == "yes":
            return True
    return False


def monitor_log(path: Path, phases: list[Phase], context: int = 4) -> dict[str, dict]:
    """Free-swing, lock and degraded lines of the monitor's log, counted per phase (log time).

    Returns {phase name: {"swings", "locks", "degraded", "suspicions_refused" (the controller's
    task-space channel suspected a lock, the monitor's evidence refused it: logged at most
    every 5 s), "events": [lines around each swing and lock]}}.
    """
    lines = path.read_text(errors="replace").splitlines() if path.is_file() else []
    result: dict[str, dict] = {p.name: {"swings": 0, "locks": 0, "degraded": 0,
                                        "suspicions_refused": 0, "events": []}
                               for p in phases}
    for i, line in enumerate(lines):
        match = LOG_LINE.match(line)
        if match is None:
            continue
        stamp, message = float(match.group(2)), match.group(3)
        phase = next((p for p in phases if p.wall_start <= stamp < p.wall_end), None)
        if phase is None:
            continue
        entry = result[phase.name]
        if "not confirmed" in message:  # the controller's suspicion, refused (throttled 5 s)
            entry["suspicions_refused"] += 1
        swing = "free-swinging (t =" in message
        lock = " locked at " in message or "locked (suspected" in message
        degraded = " degraded (t =" in message
        if swing or lock or degraded:
            entry["swings" if swing else "locks" if lock else "degraded"] += 1
            entry["events"].append(lines[max(0, i - context):i + context + 1])
    return result


def run_plant(plant: str, minutes: float, domain: int, out: Path, goal_period: float,
              cycle: float, pause: float, warm_up: float, layout: str) -> dict:
    """One plant: start-up, warm-up until observing, idle half, loaded half."""
    log_dir = out / "soak_logs" / plant
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    executor = EventsExecutor(context=context)
    probe = Probe(context, goal_period, cycle, pause)
    executor.add_node(probe.node)
    half = minutes * 60.0 / 2
    phases: list[Phase] = []
    alive: dict[str, dict[str, int | None]] = {}
    try:
        with deployed(plant, domain, log_dir, layout) as processes:
            start = time.monotonic()
            while probe.phase.states < 10 and time.monotonic() - start < 60.0:
                executor.spin_once(timeout_sec=0.01)
            if probe.phase.states < 10:
                raise RuntimeError(f"{plant}: no joint states in 60 s; see {log_dir}")
            warm = probe.phase = Phase("warm-up")
            observed = spin_phase(probe, executor, warm_up, until="observing")
            warm.wall_end = time.time()
            print(f"{time.strftime('%H:%M:%S')} {plant}: warm-up {warm.seconds:.1f} s, "
                  f"observing: {observed}", flush=True)
            pids = [p.pid for p in processes.values()]
            for name, loaded in (("idle", False), ("loaded", True)):
                counters = cpu_counters(pids)
                phase = probe.phase = Phase(name, loaded)
                if loaded:
                    with busy_cores():
                        spin_phase(probe, executor, half)
                else:
                    spin_phase(probe, executor, half)
                phase.wall_end = time.time()
                phase.cpu = cpu_use(counters, cpu_counters(pids), phase.seconds)
                phases.append(phase)
                alive[name] = {n: p.poll() for n, p in processes.items()}
                print(f"{time.strftime('%H:%M:%S')} {plant} {name}: {phase.seconds:.0f} s, "
                      f"locks {len(phase.locks)}, swings {len(phase.swings_seen)}, observing "
                      f"{phase.observing}/{phase.statuses}, travelled {phase.travel.path:.1f} "
                      f"rad, other processes {phase.cpu['others']:.2f} cores, exit codes "
                      f"{alive[name]}", flush=True)
    finally:
        executor.shutdown()
        rclpy.shutdown(context=context)
    logged = monitor_log(log_dir / ("stack.log" if layout == "stack" else "monitor.log"),
                         phases)
    return {"warm_up": {"seconds": warm.seconds, "observing": observed,
                        "not_observing": dict(warm.not_observing.most_common(5))},
            "phases": {p.name: summary(p, logged[p.name], alive[p.name]) for p in phases}}


def summary(phase: Phase, logged: dict, exit_codes: dict[str, int | None]) -> dict:
    """The JSON figures of one phase (`logged`: its monitor log counts)."""
    hours = phase.seconds / 3600.0
    return {
        "loaded": phase.loaded, "busy_processes": (os.cpu_count() or 2) if phase.loaded else 0,
        "seconds": phase.seconds,
        "false_locks": len(phase.locks), "locks": phase.locks,
        "free_swing_declarations": logged["swings"], "swings_in_diagnostics": phase.swings_seen,
        "locks_in_log": logged["locks"], "degraded_declarations": logged["degraded"],
        "log_events": logged["events"],
        "suspicions_refused_in_log": logged["suspicions_refused"],
        "false_locks_per_hour": len(phase.locks) / hours,
        "free_swings_per_hour": logged["swings"] / hours,
        "resets": phase.resets,
        "monitor_statuses": phase.statuses,
        "observing_fraction": phase.observing / phase.statuses if phase.statuses else 0.0,
        "not_observing": dict(phase.not_observing.most_common(10)),
        "monitor_messages_not_ok": dict(phase.messages.most_common(10)),
        "plant_values": phase.plant,
        "goals": phase.goals, "joint_states": phase.states,
        "commands": phase.commands,
        "command_stamp_gap_max_ms": phase.command_stamp_gap * 1e3,
        "command_arrival_gap_max_ms": phase.command_arrival_gap * 1e3,
        "joint_states_stamp_gap_max_ms": phase.state_stamp_gap * 1e3,
        "stalls": phase.stalls,
        "travelled_rad": phase.travel.path,
        "cpu_cores": phase.cpu,
        "exit_codes_at_end": exit_codes,
    }


def table(results: dict[str, dict]) -> list[str]:
    """The Markdown table of every plant and phase."""
    lines = ["| plant | phase | minutes | false locks | free-swing declarations | "
             "degraded declarations | "
             "per hour (locks / swings) | observing % | ft/command messages | "
             "command gap max (ms, stamps / arrivals) | travelled (rad) | "
             "other users' CPU (cores) |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for plant, result in results.items():
        for name, p in result["phases"].items():
            lines.append(
                f"| {plant} | {name} | {p['seconds'] / 60:.1f} | {p['false_locks']} | "
                f"{p['free_swing_declarations']} | {p['degraded_declarations']} | "
                f"{p['false_locks_per_hour']:.1f} / "
                f"{p['free_swings_per_hour']:.1f} | {100 * p['observing_fraction']:.1f} | "
                f"{p['commands']} | {p['command_stamp_gap_max_ms']:.0f} / "
                f"{p['command_arrival_gap_max_ms']:.0f} | {p['travelled_rad']:.1f} | "
                f"{p['cpu_cores']['others']:.2f} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    """Soak both plants and write the table and JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--minutes", type=float, default=30.0,
                        help="per plant, after the warm-up: half idle, half loaded")
    parser.add_argument("--plants", nargs="+", choices=list(PLANTS), default=list(PLANTS))
    parser.add_argument("--goal-period", type=float, default=1.5, help="s between pose goals")
    parser.add_argument("--cycle", type=float, default=20.0,
                        help="s; the goals pause once per cycle")
    parser.add_argument("--pause", type=float, default=4.0, help="s without goals per cycle")
    parser.add_argument("--warm-up", type=float, default=90.0,
                        help="s of goals at most, until the monitor observes")
    parser.add_argument("--layout", choices=list(LAYOUTS), default="separate",
                        help="the nodes as separate processes, or ft-stack")
    args = parser.parse_args(argv)
    domain = int(os.environ.get("FT_BENCH_DOMAIN_SOAK", "63"))
    # The probe discovers the nodes the way they discover each other.
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    results = {plant: run_plant(plant, args.minutes, domain, args.out, args.goal_period,
                                args.cycle, args.pause, args.warm_up, args.layout)
               for plant in args.plants}
    info = machine()
    lines = [*table(results), "",
             f"Layout: {args.layout}. Pose goals every {args.goal_period:g} s, paused "
             f"{args.pause:g} s every "
             f"{args.cycle:g} s; loaded: {os.cpu_count()} busy processes (one per core). "
             + "; ".join(f"{plant} warm-up {r['warm_up']['seconds']:.0f} s"
                         for plant, r in results.items()) + ". Locks the controller "
             "suspected and the monitor refused (log lines, at most one per 5 s): "
             + "; ".join(f"{plant} " + " / ".join(
                 f"{p['suspicions_refused_in_log']} {name}" for name, p in r["phases"].items())
                 for plant, r in results.items()) + ".",
             f"{info['cpu']}, {info['cores']} cores, Python {info['python']}, {info['date']}."]
    report(args.out, "soak", lines, {
        "machine": info, "layout": args.layout, "minutes_per_plant": args.minutes,
        "goal_period_s": args.goal_period, "cycle_s": args.cycle, "pause_s": args.pause,
        "domain": domain,
        "plants": {plant: {"parameters": PLANTS[plant], **r} for plant, r in results.items()}})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
