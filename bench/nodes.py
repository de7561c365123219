"""`make bench`: the nodes at their real rate, on the wall clock.

A. One process (one executor): sim at 500 Hz, controller at 500 Hz (`blend`,
   Panda position task) and monitor, with a probe streaming a twist target. The
   controller's own loop accounting gives the achieved rate, the compute time per
   cycle and missed cycles; the probe measures the latency from receiving a
   `joint_states` message to receiving the next `ft/command`. Run twice: with
   rclpy's EventsExecutor (`rclpy.experimental`, what the executables use) and with
   its SingleThreadedExecutor.
B. Separate processes (`ft-sim`, `ft-controller`, `ft-monitor`): the same latency,
   and each process's resident set size after a warm-up and at the end of the run.
C. The monitor's detector alone: detection latency of locks while the joint is
   commanded at 0.1, 0.2 and 0.5 rad/s (250 Hz, 1e-3 rad noise, random joints and
   lock times).

Writes `<out>/nodes.md` and `<out>/nodes.json`. Parts A and B use the DDS domains
`FT_BENCH_DOMAIN` (default 61) and `FT_BENCH_DOMAIN_PROCESSES` (default 62).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import rclpy
from engine_cycle import machine
from ft_controller.controller_node import ControllerNode
from ft_core import robots
from ft_core.detection import LockDetector
from ft_monitor.monitor_node import MonitorNode
from ft_msgs_py import qos
from ft_msgs_py.loop import LoopAccounting
from ft_msgs_py.spin import settle_heap
from ft_sim.sim_node import SimNode
from geometry_msgs.msg import TwistStamped
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.experimental.events_executor import EventsExecutor
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

RATE = 500.0
MODEL = {"robot_model": "panda", "task_space": "position"}


class Probe:
    """Streams a circular twist target and times states against commands (wall clock)."""

    def __init__(self, context: Context):
        self.node = rclpy.create_node("probe", context=context)
        self._twist = self.node.create_publisher(TwistStamped, "ft/target_twist", qos.RELIABLE)
        self.node.create_subscription(JointState, "joint_states", self._on_state,
                                      qos.SENSOR_INPUT)
        self.node.create_subscription(JointState, "ft/command", self._on_command,
                                      qos.SENSOR_INPUT)
        self.node.create_timer(0.02, self._send)
        self._pending: float | None = None
        self.latencies: list[float] = []
        self._start = time.perf_counter()

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


def one_process(seconds: float, executor_name: str) -> dict:
    """Part A with the named executor."""
    context = Context()
    rclpy.init(context=context, domain_id=int(os.environ.get("FT_BENCH_DOMAIN", "61")))
    executor = EXECUTORS[executor_name](context=context)
    params = [Parameter(k, value=v) for k, v in MODEL.items()]
    sim = SimNode(context=context, parameter_overrides=[*params, Parameter("rate", value=RATE)])
    controller = ControllerNode(context=context, parameter_overrides=[
        *params, Parameter("control_rate", value=RATE), Parameter("resolution", value="blend")])
    monitor = MonitorNode(context=context, parameter_overrides=params)
    probe = Probe(context)
    for node in (sim, controller, monitor, probe.node):
        executor.add_node(node)
    settle_heap()  # as `run_node` does for the executables
    warm_up = time.monotonic() + 2.0
    while time.monotonic() < warm_up:
        executor.spin_once(timeout_sec=0.01)
    # Fresh accounting for the timed run, holding every cycle's compute time.
    accounting = controller.accounting = LoopAccounting(1.0 / RATE,
                                                        window=int(RATE * seconds * 1.2) + 1)
    probe.latencies.clear()
    start = time.monotonic()
    while time.monotonic() - start < seconds:
        executor.spin_once(timeout_sec=0.01)
    elapsed = time.monotonic() - start
    result = {
        "seconds": elapsed,
        "achieved_rate_hz": accounting.cycles / elapsed,
        "missed_cycles": accounting.missed,
        "cycle_compute_ms": percentiles(accounting.samples()),
        "state_to_command_ms": percentiles(probe.latencies),
    }
    executor.shutdown()
    rclpy.shutdown(context=context)
    return result


def rss_kib(pid: int) -> int:
    """Resident set size of a process (KiB)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


def separate_processes(seconds: float, memory_seconds: float) -> dict:
    """Part B."""
    domain = os.environ.get("FT_BENCH_DOMAIN_PROCESSES", "62")
    env = {**os.environ, "ROS_DOMAIN_ID": domain, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    bin_dir = Path(sys.executable).parent
    model = ["-p", "robot_model:=panda", "-p", "task_space:=position"]
    commands = {
        "sim": [str(bin_dir / "ft-sim"), "--ros-args", *model, "-p", f"rate:={RATE}"],
        "controller": [str(bin_dir / "ft-controller"), "--ros-args", *model,
                       "-p", f"control_rate:={RATE}", "-p", "resolution:=blend"],
        "monitor": [str(bin_dir / "ft-monitor"), "--ros-args", *model],
    }
    processes = {name: subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL,
                                        stderr=subprocess.DEVNULL)
                 for name, cmd in commands.items()}
    context = Context()
    rclpy.init(context=context, domain_id=int(domain))
    executor = SingleThreadedExecutor(context=context)
    probe = Probe(context)
    executor.add_node(probe.node)
    try:
        start = time.monotonic()
        while time.monotonic() - start < 10.0:  # discovery and warm-up
            executor.spin_once(timeout_sec=0.01)
        rss_start = {name: rss_kib(p.pid) for name, p in processes.items()}
        probe.latencies.clear()
        while time.monotonic() - start < 10.0 + seconds:
            executor.spin_once(timeout_sec=0.01)
        latencies = list(probe.latencies)
        while time.monotonic() - start < 10.0 + memory_seconds:
            executor.spin_once(timeout_sec=0.05)
        rss_end = {name: rss_kib(p.pid) for name, p in processes.items()}
    finally:
        for p in processes.values():
            p.terminate()
        for p in processes.values():
            p.wait(timeout=20)
        executor.shutdown()
        rclpy.shutdown(context=context)
    return {"state_to_command_ms": percentiles(latencies),
            "rss_kib_after_warm_up": rss_start, "rss_kib_at_end": rss_end,
            "memory_seconds": memory_seconds}


def detection(trials: int = 30, seed: int = 0) -> dict:
    """Part C."""
    panda = robots.load("panda")
    start = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
    rng = np.random.default_rng(seed)
    dt = 1 / 250
    results = {}
    for speed in (0.1, 0.2, 0.5):
        latencies = []
        for _ in range(trials):
            joint, lock = int(rng.integers(7)), float(rng.uniform(0.5, 1.0))
            detector, q = LockDetector(panda.lower, panda.upper), start.copy()
            signs = rng.choice([-1.0, 1.0], size=7)
            for k in range(int(2.0 / dt)):
                t = k * dt
                qd = speed * signs
                detector.command(t, qd)
                move = qd.copy()
                if t >= lock:
                    move[joint] = 0.0
                q = q + move * dt
                if detector.measure(t + dt, q + rng.normal(scale=1e-3, size=7)):
                    latencies.append(t + dt - lock)
                    break
        results[f"{speed} rad/s"] = {**percentiles(latencies), "detected": len(latencies),
                                     "trials": trials}
    return results


def main(argv: list[str] | None = None) -> int:
    """Run A, B and C and write the table and JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--seconds", type=float, default=60.0, help="part A and B's timing run")
    parser.add_argument("--memory-seconds", type=float, default=600.0,
                        help="part B's run before the final memory reading")
    args = parser.parse_args(argv)
    a = {name: one_process(args.seconds, name) for name in EXECUTORS}
    b = separate_processes(min(args.seconds, 30.0), max(args.memory_seconds, args.seconds))
    c = detection()
    info = machine()
    runs = list(a.values())

    def row(label: str, figure: Callable[[dict], str]) -> str:
        return f"| {label} | " + " | ".join(figure(run) for run in runs) + " |"

    lines = [
        f"| nodes at {RATE:.0f} Hz, one process, {runs[0]['seconds']:.0f} s | "
        + " | ".join(a) + " |", "|---|" + "---:|" * len(a),
        row("achieved controller rate (Hz)", lambda r: f"{r['achieved_rate_hz']:.1f}"),
        row("missed cycles (the loop's own accounting)", lambda r: f"{r['missed_cycles']}"),
        row("cycle compute p50 / p99 (ms)", lambda r: f"{r['cycle_compute_ms']['p50']:.3f} / "
            f"{r['cycle_compute_ms']['p99']:.3f}"),
        row("joint_states to ft/command p50 / p99 (ms)",
            lambda r: f"{r['state_to_command_ms']['p50']:.2f} / "
            f"{r['state_to_command_ms']['p99']:.2f}"),
        "",
        "| separate processes, detection | value |", "|---|---:|",
        f"| joint_states to ft/command, separate processes, p50 / p99 | "
        f"{b['state_to_command_ms'].get('p50', float('nan')):.2f} / "
        f"{b['state_to_command_ms'].get('p99', float('nan')):.2f} ms |",
    ]
    for name in b["rss_kib_at_end"]:
        lines.append(f"| resident memory of {name}: after warm-up -> after "
                     f"{b['memory_seconds']:.0f} s | {b['rss_kib_after_warm_up'][name] / 1024:.1f}"
                     f" -> {b['rss_kib_at_end'][name] / 1024:.1f} MiB |")
    for speed, figures in c.items():
        lines.append(f"| detection latency at {speed}, p50 / p99 ({figures['detected']}/"
                     f"{figures['trials']} detected) | {figures.get('p50', float('nan')):.0f} / "
                     f"{figures.get('p99', float('nan')):.0f} ms |")
    lines += ["", f"{info['cpu']}, {info['cores']} cores, Python {info['python']}, "
              f"{info['date']}."]
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "nodes.md").write_text("\n".join(lines) + "\n")
    (args.out / "nodes.json").write_text(json.dumps(
        {"machine": info, "one_process": a, "separate_processes": b, "detection": c},
        indent=2) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
