"""`make bench`: the nodes at their real rate, on the wall clock.

A. One process (one executor): sim at 500 Hz, controller at 500 Hz (`blend`,
   Panda position task) and monitor, with a probe streaming a twist target. The
   controller's own loop accounting gives the achieved rate, the compute time per
   cycle and missed cycles; the probe measures the latency from receiving a
   `joint_states` message to receiving the next `ft/command`. With rclpy's
   EventsExecutor (`rclpy.experimental`, what the executables use) and with its
   SingleThreadedExecutor. Two references run in turn with them, timed by the same
   accounting: an rclpy timer at the same rate with an empty callback, alone in its
   process (what rclpy and the machine miss on their own), and a plain Python loop
   sleeping to each deadline, no ROS (what the machine misses on its own).
   `--repeats` runs of each (default 3); medians over the runs, percentiles over
   all their cycles.
B. Separate processes (`ft-sim`, `ft-controller`, `ft-monitor`): the same latency,
   and each process's resident set size after a warm-up and at the end of the run.
Detection quality is `bench/detection.py`.

Writes `<out>/nodes.md` and `<out>/nodes.json`. Parts A and B use the DDS domains
`FT_BENCH_DOMAIN` (default 61) and `FT_BENCH_DOMAIN_PROCESSES` (default 62).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import rclpy
from engine_cycle import machine, report
from ft_controller.controller_node import ControllerNode
from ft_monitor.monitor_node import MonitorNode
from ft_msgs_py import qos
from ft_msgs_py.loop import LoopAccounting
from ft_msgs_py.spin import settle_heap, spin_for
from ft_sim.sim_node import SimNode
from geometry_msgs.msg import TwistStamped
from rclpy.context import Context
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.experimental.events_executor import EventsExecutor
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

RATE = 500.0
MODEL = {"robot_model": "panda", "task_space": "position"}


class Probe:
    """Streams a circular twist target and times states against commands (wall clock)."""

    def __init__(self, context: Context, timing: bool = True):
        """With `timing` False it only streams the target until `time_latencies()`."""
        self.node = rclpy.create_node("probe", context=context)
        self._twist = self.node.create_publisher(TwistStamped, "ft/target_twist", qos.RELIABLE)
        self.node.create_timer(0.02, self._send)
        self._pending: float | None = None
        self.latencies: list[float] = []
        self._start = time.perf_counter()
        if timing:
            self.time_latencies()

    def time_latencies(self) -> None:
        """Subscribe to both streams and time them (in Python: half a core at 1 kHz)."""
        self.node.create_subscription(JointState, "joint_states", self._on_state,
                                      qos.SENSOR_INPUT)
        self.node.create_subscription(JointState, "ft/command", self._on_command,
                                      qos.SENSOR_INPUT)

    def _send(self) -> None:
        t = time.perf_counter() - self._start
        msg = TwistStamped()
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.twist.linear.y = 0.05 * np.cos(t)
        msg.twist.linear.z = -0.05 * np.sin(t)
        self._twist.publish(msg)

    def _on_state(self, _msg: JointState) -> None:
        if self._pending is None:
            self._pending = time.perf_counter()

    def _on_command(self, _msg: JointState) -> None:
        if self._pending is not None:
            self.latencies.append(time.perf_counter() - self._pending)
            self._pending = None


def percentiles(samples: list[float] | np.ndarray, scale: float = 1e3) -> dict[str, float]:
    """p50 and p99 (ms by default)."""
    values = np.asarray(samples) * scale
    return {"p50": float(np.percentile(values, 50)), "p99": float(np.percentile(values, 99)),
            "samples": int(values.size)} if values.size else {"samples": 0}


EXECUTORS = {"EventsExecutor": EventsExecutor, "SingleThreadedExecutor": SingleThreadedExecutor}
#: Part A's kinds of run: (executor, the whole stack?); no executor is the plain sleep loop.
KINDS = {
    "sim + controller + monitor, EventsExecutor": ("EventsExecutor", True),
    "sim + controller + monitor, SingleThreadedExecutor": ("SingleThreadedExecutor", True),
    "reference: an empty rclpy timer alone, EventsExecutor": ("EventsExecutor", False),
    "reference: a Python loop sleeping to each deadline, no ROS": (None, False),
}


class EmptyLoop:
    """A node whose timer at the control rate only does the loop's accounting."""

    def __init__(self, context: Context):
        self.node = rclpy.create_node("empty_loop", context=context)
        self.accounting = LoopAccounting(1.0 / RATE)
        self.node.create_timer(1.0 / RATE, self._cycle)

    def _cycle(self) -> None:
        self.accounting.start()
        self.accounting.end()


def sleep_loop(seconds: float) -> dict:
    """The machine alone: sleep to each deadline of the schedule, then account the cycle.

    Like rcl's timer, a deadline already passed by a whole period is skipped.
    """
    period = 1.0 / RATE
    accounting = LoopAccounting(period, window=int(RATE * seconds * 1.2) + 1)
    start = time.perf_counter()
    due = start + period
    while due - start <= seconds:
        now = time.perf_counter()
        if due > now:
            time.sleep(due - now)
        else:
            due += (now - due) // period * period
        accounting.start()
        accounting.end()
        due += period
    elapsed = time.perf_counter() - start
    return {"seconds": elapsed, "achieved_rate_hz": accounting.cycles / elapsed,
            "missed_cycles": accounting.missed, "compute_s": accounting.samples().tolist(),
            "state_to_command_s": []}


def one_process(seconds: float, executor_name: str | None, stack: bool) -> dict:
    """One run of part A, timed by the loop's own accounting.

    The whole stack, the empty timer alone, or (no executor) the sleep loop.
    """
    if executor_name is None:
        return sleep_loop(seconds)
    context = Context()
    rclpy.init(context=context, domain_id=int(os.environ.get("FT_BENCH_DOMAIN", "61")))
    executor = EXECUTORS[executor_name](context=context)
    probe = None
    if stack:
        params = [Parameter(k, value=v) for k, v in MODEL.items()]
        sim = SimNode(context=context,
                      parameter_overrides=[*params, Parameter("rate", value=RATE)])
        loop = ControllerNode(context=context, parameter_overrides=[
            *params, Parameter("control_rate", value=RATE),
            Parameter("resolution", value="blend")])
        monitor = MonitorNode(context=context, parameter_overrides=params)
        probe = Probe(context)
        nodes = [sim, loop, monitor, probe.node]
    else:
        loop = EmptyLoop(context)
        nodes = [loop.node]
    for node in nodes:
        executor.add_node(node)
    settle_heap()  # as `run_node` does for the executables
    spin_for(executor, 2.0)  # warm-up
    # Fresh accounting for the timed run, holding every cycle's compute time.
    accounting = loop.accounting = LoopAccounting(1.0 / RATE,
                                                  window=int(RATE * seconds * 1.2) + 1)
    if probe is not None:
        probe.latencies.clear()
    elapsed = spin_for(executor, seconds)
    result = {
        "seconds": elapsed,
        "achieved_rate_hz": accounting.cycles / elapsed,
        "missed_cycles": accounting.missed,
        "compute_s": accounting.samples().tolist(),
        "state_to_command_s": list(probe.latencies) if probe is not None else [],
    }
    executor.shutdown()
    rclpy.shutdown(context=context)
    return result


def summary(runs: list[dict]) -> dict:
    """Repeated runs of one kind.

    Medians of the rate and of the missed cycles (with their range); percentiles over
    the cycles of all runs.
    """
    missed = [run["missed_cycles"] for run in runs]
    return {
        "runs": len(runs),
        "seconds": float(np.median([run["seconds"] for run in runs])),
        "achieved_rate_hz": float(np.median([run["achieved_rate_hz"] for run in runs])),
        "missed_cycles": float(np.median(missed)),
        "missed_cycles_per_run": missed,
        "cycle_compute_ms": percentiles([t for run in runs for t in run["compute_s"]]),
        "state_to_command_ms": percentiles([t for run in runs
                                            for t in run["state_to_command_s"]]),
    }


def part_a(seconds: float, repeats: int) -> dict:
    """Part A: every kind in turn, repeated (interleaved, so all see the same machine)."""
    runs: dict[str, list[dict]] = {kind: [] for kind in KINDS}
    for _ in range(repeats):
        for kind, (executor_name, stack) in KINDS.items():
            runs[kind].append(one_process(seconds, executor_name, stack))
    return {kind: summary(kind_runs) for kind, kind_runs in runs.items()}


def rss_kib(pid: int) -> int:
    """Resident set size of a process (KiB)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


@contextmanager
def installed(commands: dict[str, list[str]], domain: str, timing: bool = True,
              ) -> Iterator[tuple[dict[str, subprocess.Popen], Executor, Probe]]:
    """The installed console scripts (name -> arguments after the `ft-*` script) on `domain`.

    Yields the processes, an executor and a probe on it (`Probe`'s `timing`); every
    process is stopped after.
    """
    env = {**os.environ, "ROS_DOMAIN_ID": domain, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    bin_dir = Path(sys.executable).parent
    processes = {name: subprocess.Popen([str(bin_dir / argv[0]), *argv[1:]], env=env,
                                        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                 for name, argv in commands.items()}
    context = Context()
    rclpy.init(context=context, domain_id=int(domain))
    executor = SingleThreadedExecutor(context=context)
    probe = Probe(context, timing)
    executor.add_node(probe.node)
    try:
        yield processes, executor, probe
    finally:
        for p in processes.values():
            p.terminate()
        for p in processes.values():
            p.wait(timeout=20)
        executor.shutdown()
        rclpy.shutdown(context=context)


def separate_processes(seconds: float, memory_seconds: float, warm_up: float) -> dict:
    """Part B: the processes start, run `warm_up` s, then are timed and measured."""
    model = ["--ros-args", "-p", "robot_model:=panda", "-p", "task_space:=position"]
    commands = {
        "sim": ["ft-sim", *model, "-p", f"rate:={RATE}"],
        "controller": ["ft-controller", *model, "-p", f"control_rate:={RATE}",
                       "-p", "resolution:=blend"],
        "monitor": ["ft-monitor", *model],
    }
    domain = os.environ.get("FT_BENCH_DOMAIN_PROCESSES", "62")
    with installed(commands, domain) as (processes, executor, probe):
        spin_for(executor, warm_up)  # discovery and warm-up
        rss_start = {name: rss_kib(p.pid) for name, p in processes.items()}
        probe.latencies.clear()
        spin_for(executor, seconds)
        latencies = list(probe.latencies)
        spin_for(executor, memory_seconds - seconds)
        rss_end = {name: rss_kib(p.pid) for name, p in processes.items()}
    return {"state_to_command_ms": percentiles(latencies),
            "rss_kib_after_warm_up": rss_start, "rss_kib_at_end": rss_end,
            "memory_seconds": memory_seconds}


def main(argv: list[str] | None = None) -> int:
    """Run A and B and write the table and JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--seconds", type=float, default=60.0, help="part A and B's timing run")
    parser.add_argument("--memory-seconds", type=float, default=600.0,
                        help="part B's run before the final memory reading")
    parser.add_argument("--repeats", type=int, default=3, help="part A's runs of each kind")
    parser.add_argument("--warm-up", type=float, default=10.0,
                        help="part B's discovery and warm-up before timing (s)")
    args = parser.parse_args(argv)
    a = part_a(args.seconds, args.repeats)
    b = separate_processes(min(args.seconds, 30.0), max(args.memory_seconds, args.seconds),
                           args.warm_up)
    info = machine()
    def pair(figures: dict, digits: int) -> str:
        return (f"{figures['p50']:.{digits}f} / {figures['p99']:.{digits}f}"
                if figures["samples"] else "-")

    seconds = next(iter(a.values()))["seconds"]
    lines = [
        f"| one process at {RATE:.0f} Hz, {args.repeats} x {seconds:.0f} s | rate (Hz) | "
        "missed cycles per run: median (range) | cycle compute p50 / p99 (ms) | "
        "joint_states to ft/command p50 / p99 (ms) |", "|---|---:|---:|---:|---:|",
        *(f"| {kind} | {r['achieved_rate_hz']:.1f} | {r['missed_cycles']:.0f} "
          f"({min(r['missed_cycles_per_run'])}-{max(r['missed_cycles_per_run'])}) | "
          f"{pair(r['cycle_compute_ms'], 3)} | {pair(r['state_to_command_ms'], 2)} |"
          for kind, r in a.items()),
        "",
        "| separate processes | value |", "|---|---:|",
        f"| joint_states to ft/command, separate processes, p50 / p99 | "
        f"{b['state_to_command_ms'].get('p50', float('nan')):.2f} / "
        f"{b['state_to_command_ms'].get('p99', float('nan')):.2f} ms |",
    ]
    for name in b["rss_kib_at_end"]:
        lines.append(f"| resident memory of {name}: after warm-up -> after "
                     f"{b['memory_seconds']:.0f} s | {b['rss_kib_after_warm_up'][name] / 1024:.1f}"
                     f" -> {b['rss_kib_at_end'][name] / 1024:.1f} MiB |")
    lines += ["", f"{info['cpu']}, {info['cores']} cores, Python {info['python']}, "
              f"{info['date']}."]
    report(args.out, "nodes", lines, {"machine": info, "one_process": a, "separate_processes": b})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
