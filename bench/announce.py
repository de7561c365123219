"""From a decision on the locked set to its announcement on `ft/locked_joints`.

    python bench/announce.py --out bench_out

The monitor node (`ft_monitor.monitor_node`, on the EventsExecutor the executables spin,
its state directory on this machine's disk under `--out`) is handed `--changes` changes
of its locked set: a joint declared on `ft/declare_failure`, then `monitor/reset`, in
turn, each a random 20-40 ms after the previous one was announced. A subscriber in the
same process takes each announcement; its delay is the wall clock at arrival minus the
message's stamp, which is the time of the decision (the node's clock, `Change.time`):
the write of the state file (`ft_core.locked_set.save`, timed on its own), the wait for
the announcement after it, and the delivery. Conditions: joint states at 250 Hz (as from
an arm's driver) or none; the disk as it is, or each fsync and fdatasync 50 ms slower
(a slow disk, emulated); the slot format, or the previous one (a new file written,
fsynced and renamed over the old, the directory fsynced) for comparison. Writes
bench_out/announce.md and .json; docs/benchmarks.md has the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from contextlib import ExitStack
from pathlib import Path
from unittest import mock

import numpy as np
import rclpy
from ft_core import locked_set
from ft_monitor.monitor_node import MonitorNode
from ft_msgs_py import convert, names, qos
from rclpy.context import Context
from rclpy.experimental.events_executor import EventsExecutor
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

sys.path.insert(0, str(Path(__file__).resolve().parent))
from engine_cycle import machine

#: The Panda's joints and a configuration away from its limits (rad).
JOINTS = [f"panda_joint{k}" for k in range(1, 8)]
Q0 = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]
#: Joint-state rate of the conditions with joint states (Hz).
STATE_RATE = 250.0
#: Extra time (s) of every fsync and fdatasync in the slow-disk conditions.
SLOW = 0.05
#: Longest wait (s) for one announcement.
TIMEOUT = 5.0


def previous_save(path: Path, robot: str, locked: dict[str, float]) -> None:
    """The previous versions' write: a new file fsynced, renamed, the directory fsynced."""
    text = json.dumps({"robot": robot, "locked": {
        name: (position if np.isfinite(position) else None)
        for name, position in sorted(locked.items())}}, indent=1)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    with os.fdopen(handle, "w") as file:
        file.write(text)
        file.flush()
        os.fsync(file.fileno())
    os.replace(temporary, path)
    directory = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(directory)
    finally:
        os.close(directory)


class Harness:
    """The monitor node, a joint-state source and the announcements' subscriber."""

    def __init__(self, context: Context, state: Path):
        self.monitor = MonitorNode(context=context, parameter_overrides=[
            Parameter("robot_model", value="panda"),
            Parameter("state_directory", value=str(state))])
        self.node = rclpy.create_node("announce_bench", context=context)
        self.executor = EventsExecutor(context=context)
        for node in (self.monitor, self.node):
            self.executor.add_node(node)
        self._states = self.node.create_publisher(JointState, names.JOINT_STATES,
                                                  qos.SENSOR_INPUT)
        self._declare = self.node.create_publisher(JointState, names.DECLARE_FAILURE,
                                                   qos.RELIABLE)
        self._reset = self.node.create_client(Trigger, "monitor/reset")
        #: (arrival, wall clock s; stamp s; joint names) of each announcement
        self.announced: list[tuple[float, float, list[str]]] = []
        self.node.create_subscription(JointState, names.LOCKED_JOINTS, self._on_locked,
                                      qos.LATCHED)
        self.stream = False
        self.node.create_timer(1.0 / STATE_RATE, self._send_state)

    def _on_locked(self, msg: JointState) -> None:
        self.announced.append((time.time(), convert.stamp_seconds(msg.header.stamp),
                               list(msg.name)))

    def _send_state(self) -> None:
        if self.stream:
            self._states.publish(convert.joint_state(
                JOINTS, self.node.get_clock().now().to_msg(), position=Q0))

    def spin_until(self, condition, timeout: float) -> bool:
        """Spin until `condition()` or `timeout` s; whether it holds."""
        deadline = time.monotonic() + timeout
        while not condition() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.001)
        return condition()

    def change(self, joint: str | None) -> float:
        """Declare `joint` (None: reset); the delay (s) of its announcement."""
        count = len(self.announced)
        if joint is None:
            self._reset.call_async(Trigger.Request())
        else:
            self._declare.publish(JointState(name=[joint]))
        expected = [] if joint is None else [joint]
        if not self.spin_until(lambda: any(
                names_ == expected for _, _, names_ in self.announced[count:]), TIMEOUT):
            raise TimeoutError(f"{expected} not announced within {TIMEOUT:g} s")
        arrival, stamp, _ = next(a for a in self.announced[count:] if a[2] == expected)
        return arrival - stamp


def condition(harness: Harness, changes: int, rng: np.random.Generator, stream: bool,
              slow: bool, previous: bool) -> dict:
    """Run `changes` changes under one condition; delays and write times (ms)."""
    writes: list[float] = []
    save = previous_save if previous else locked_set.save

    def timed_save(*args) -> None:
        start = time.perf_counter()
        save(*args)
        writes.append(time.perf_counter() - start)

    def slowed(real):
        return lambda fd: (time.sleep(SLOW), real(fd))[1]

    with ExitStack() as patches:
        patches.enter_context(mock.patch.object(locked_set, "save", timed_save))
        if slow:
            patches.enter_context(mock.patch.object(os, "fsync", slowed(os.fsync)))
            patches.enter_context(mock.patch.object(os, "fdatasync", slowed(os.fdatasync)))
        harness.stream = stream
        harness.spin_until(lambda: False, 0.2)  # the first states in
        delays = []
        for k in range(changes):
            joint = JOINTS[(k // 2) % len(JOINTS)] if k % 2 == 0 else None
            delays.append(harness.change(joint))
            harness.spin_until(lambda: False, rng.uniform(0.02, 0.04))
        harness.stream = False
    delays_ms, writes_ms = np.array(delays) * 1e3, np.array(writes) * 1e3
    return {"joint_states": stream, "slow_fsync": slow, "format": "previous" if previous
            else "slots", "changes": changes,
            "delay_ms": {"p50": float(np.median(delays_ms)),
                         "p99": float(np.percentile(delays_ms, 99)),
                         "max": float(delays_ms.max())},
            "write_ms": {"p50": float(np.median(writes_ms)),
                         "p99": float(np.percentile(writes_ms, 99))}}


def main(argv: list[str] | None = None) -> int:
    """Run every condition; write the table and JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--changes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(args.seed)
    context = Context()
    rclpy.init(context=context)
    results = []
    with tempfile.TemporaryDirectory(dir=args.out, prefix="announce_state_") as state:
        harness = Harness(context, Path(state))
        try:
            if not harness.spin_until(lambda: harness.monitor.core is not None, 30.0):
                raise TimeoutError("the monitor did not load its model in 30 s")
            for stream, slow, previous in ((True, False, False), (False, False, False),
                                           (True, True, False), (True, False, True),
                                           (True, True, True)):
                results.append(condition(harness, args.changes, rng, stream, slow, previous))
                print(json.dumps(results[-1]), flush=True)
        finally:
            harness.monitor.destroy_node()
            harness.node.destroy_node()
            harness.executor.shutdown()
            rclpy.shutdown(context=context)
    lines = ["| state file | fsync, fdatasync | joint states | decision to announcement, "
             "p50 / p99 / max (ms) | write, p50 / p99 (ms) |", "|---|---|---|---:|---:|"]
    for r in results:
        delay, write = r["delay_ms"], r["write_ms"]
        lines.append(
            f"| {'slots, in place' if r['format'] == 'slots' else 'new file, renamed'} | "
            f"{f'+{SLOW * 1e3:.0f} ms' if r['slow_fsync'] else 'this disk'} | "
            f"{f'{STATE_RATE:.0f} Hz' if r['joint_states'] else 'none'} | "
            f"{delay['p50']:.1f} / {delay['p99']:.1f} / {delay['max']:.1f} | "
            f"{write['p50']:.1f} / {write['p99']:.1f} |")
    info = machine()
    lines += ["", f"{args.changes} changes per condition (a declared lock, then a reset, in "
              f"turn); {info['cpu']}, {info['cores']} cores, {info['date']}."]
    (args.out / "announce.md").write_text("\n".join(lines) + "\n")
    (args.out / "announce.json").write_text(json.dumps(
        {"machine": info, "results": results}, indent=2) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
