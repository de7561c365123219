"""The suite as users run it: installed executables as separate processes, and a probe.

`Graph` starts `sim_node`, `controller_node` and `monitor_node` from the colcon
install space (as `ros2 run` and `ros2 launch` do), each its own process on a DDS
domain of the test's own, and a probe node in the test process that drives pose
goals and records what the graph publishes. Processes can be killed (-9), paused
(SIGSTOP/SIGCONT, a stalled process) and restarted. `ft_sim.cpu_load.busy_cores` saturates
every core.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from ft_core.faults import Fault
from ft_core.health import JointHealth
from ft_msgs_py import convert, faults, health, qos
from ft_msgs_py.spin import spin_until
from geometry_msgs.msg import PoseStamped
from paths import INSTALL, PACKAGES
from rosutil import ros_context
from sensor_msgs.msg import JointState
from visualization_msgs.msg import Marker

EXECUTABLES = {"sim": ("ft_sim", "sim_node"), "controller": ("ft_controller", "controller_node"),
               "monitor": ("ft_monitor", "monitor_node"),
               "stack": ("ft_sim", "stack")}  # controller and monitor in one process
#: Pose goals visited in turn (Panda position task, m): reachable from the home pose.
GOALS = ((0.5, 0.1, 0.4), (0.45, -0.15, 0.35), (0.4, 0.05, 0.55))
MODEL = {"robot_model": "panda", "task_space": "position"}


def _argument(value: object) -> str:
    if value == "":
        return "''"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list | tuple):
        return "[" + ",".join(_argument(v) for v in value) + "]"
    return str(value)


def _children(pid: int) -> list[int]:
    """The processes `pid` started (Linux /proc), and theirs."""
    direct = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            direct += [int(child) for child in (task / "children").read_text().split()]
        except OSError:  # the thread ended meanwhile
            continue
    return direct + [grandchild for child in direct for grandchild in _children(child)]


def _running(pid: int) -> bool:
    """Whether `pid` runs (a zombie waiting for its parent's reaper has ended)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


class Graph:
    """Sim, controller and monitor processes plus an in-process probe; see the module."""

    def __init__(self, context, executor, domain: int, parameters: dict[str, dict],
                 log_dir: Path):
        self.executor, self.domain, self.parameters = executor, domain, parameters
        self.log_dir = log_dir
        self.processes: dict[str, subprocess.Popen] = {}
        self.node = rclpy.create_node("probe", context=context)
        executor.add_node(self.node)
        self.locked: list[JointState] = []
        self.states: list[JointState] = []
        self.commands: list[JointState] = []
        self.raw_commands: list[JointState] = []  # the controller's own output
        self.diagnostics: dict[str, list] = {}  # status name -> [(wall time, status)]
        #: Called with each locked set as it arrives, before anything else (None: nothing).
        self.on_locked: Callable[[JointState], None] | None = None
        self.node.create_subscription(JointState, "ft/locked_joints", self._on_locked,
                                      qos.LATCHED)
        self.node.create_subscription(JointState, "joint_states", self.states.append,
                                      qos.SENSOR_INPUT)
        self.node.create_subscription(JointState, "ft/command", self.commands.append,
                                      qos.SENSOR_INPUT)
        self.node.create_subscription(JointState, "ft/command_raw", self.raw_commands.append,
                                      qos.SENSOR_INPUT)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics,
                                      qos.SENSOR_INPUT)
        self._goal = self.node.create_publisher(PoseStamped, "ft/target_pose", qos.RELIABLE)
        self._inject = self.node.create_publisher(JointState, "ft/inject_failure", qos.RELIABLE)
        self._free = self.node.create_publisher(JointState, "ft/inject_free_swing", qos.RELIABLE)
        self._declare = self.node.create_publisher(JointState, "ft/declare_failure",
                                                   qos.RELIABLE)
        self._fault = self.node.create_publisher(DiagnosticArray, "ft/inject_fault",
                                                 qos.RELIABLE)
        self._obstacle = self.node.create_publisher(Marker, "ft/obstacle", qos.RELIABLE)
        #: Every `ft/joint_health` received.
        self.health: list[DiagnosticArray] = []
        self.node.create_subscription(DiagnosticArray, "ft/joint_health", self.health.append,
                                      qos.LATCHED)
        self._goal_index = 0
        #: Orientation (x, y, z, w) of every goal sent (a pose task needs a reachable one).
        self.orientation = (0.0, 0.0, 0.0, 1.0)

    def _on_locked(self, msg: JointState) -> None:
        if self.on_locked is not None:
            self.on_locked(msg)
        self.locked.append(msg)

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            self.diagnostics.setdefault(status.name, []).append((time.monotonic(), status))

    def start(self, name: str) -> None:
        """Start (or restart) one executable from the install space."""
        package, executable = EXECUTABLES[name]
        version = f"python{sys.version_info.major}.{sys.version_info.minor}"
        env = {**os.environ, "ROS_DOMAIN_ID": str(self.domain), "PYTHONPATH": os.pathsep.join(
            str(INSTALL / p / "lib" / version / "site-packages") for p in PACKAGES)}
        script = INSTALL / package / "lib" / package / executable
        assert script.is_file(), "run `make build`"
        values = {**MODEL, **self.parameters.get(name, {})}
        files = values.pop("params_file", None)
        arguments = [f"{k}:={_argument(v)}" for k, v in values.items()]
        log = open(self.log_dir / f"{name}.log", "a")
        self.processes[name] = subprocess.Popen(
            [sys.executable, str(script), "--ros-args",
             *(["--params-file", str(files)] if files else []),
             *[a for arg in arguments for a in ("-p", arg)]],
            env=env, stdout=log, stderr=subprocess.STDOUT)
        log.close()

    def kill(self, name: str) -> None:
        """Kill -9, as a crash would; the processes it started must end too (no orphans)."""
        process = self.processes.pop(name)
        children = _children(process.pid)
        process.kill()
        process.wait(timeout=10)
        self.wait(lambda: not any(_running(pid) for pid in children), 10.0,
                  f"the processes {name} started ({children}) to end after its kill -9")

    def pause(self, name: str, seconds: float) -> None:
        """Stop a process for `seconds` (SIGSTOP), spinning the probe meanwhile."""
        self.processes[name].send_signal(signal.SIGSTOP)
        try:
            self.spin(seconds)
        finally:
            self.processes[name].send_signal(signal.SIGCONT)

    def log(self, name: str) -> str:
        """What a process printed so far."""
        return (self.log_dir / f"{name}.log").read_text()

    def spin(self, seconds: float, goal_period: float | None = None) -> None:
        """Spin the probe for `seconds`, sending the next pose goal every `goal_period` s."""
        end = time.monotonic() + seconds
        goals = self._goals(goal_period)
        while time.monotonic() < end:
            goals()
            self.executor.spin_once(timeout_sec=0.01)

    def _goals(self, period: float | None):
        """A call that sends the next pose goal whenever `period` s have passed (None: never)."""
        due = [time.monotonic()]

        def send() -> None:
            if period is not None and time.monotonic() >= due[0]:
                self.send_goal()
                due[0] += period
        return send

    def alive(self) -> dict[str, bool]:
        """Which processes still run."""
        return {name: process.poll() is None for name, process in self.processes.items()}

    def wait(self, condition, timeout: float, what: str,
             goal_period: float | None = None) -> None:
        """Spin until `condition()`; fail with `what` if it does not happen in `timeout` s.

        With `goal_period`, the next pose goal goes out every that many s meanwhile.
        """
        goals = self._goals(goal_period)
        assert spin_until(self.executor, lambda: goals() or condition(), timeout), (
            f"timed out waiting for {what}\n{self.report()}")

    def report(self) -> str:
        """What the graph shows now: the locked set, the processes, the nodes' states.

        A timed-out wait prints it, so a failure on a CI machine says why.
        """
        monitor, controller = self.values("/monitor"), self.values("/controller")
        logs = "\n".join(f"--- {name}, its last lines\n"
                         + "\n".join(self.log(name).splitlines()[-12:])
                         for name in self.processes)
        return (f"locked set {self.locked_names()}, ever {sorted(self.ever_locked())}; "
                f"running {self.alive()}\nmonitor status {monitor[-1] if monitor else None}\n"
                f"controller status {controller[-1] if controller else None}\n"
                f"{logs}")

    def send_goal(self, index: int | None = None) -> None:
        """GOALS[index], or the next of GOALS."""
        if index is not None:
            self._goal_index = index
        msg = PoseStamped()
        msg.header.stamp = self.node.get_clock().now().to_msg()
        x, y, z = GOALS[self._goal_index % len(GOALS)]
        msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = x, y, z
        o = msg.pose.orientation
        o.x, o.y, o.z, o.w = self.orientation
        self._goal.publish(msg)
        self._goal_index += 1

    def inject(self, joint: str) -> None:
        """Lock a joint in the sim (the monitor is not told)."""
        self._inject.publish(JointState(name=[joint]))

    def declare(self, joint: str) -> None:
        """Tell the monitor a joint is locked (`ft/declare_failure`)."""
        self._declare.publish(JointState(name=[joint]))

    def inject_free_swing(self, joint: str) -> None:
        """Make a joint of the sim lose its torque (the monitor is not told)."""
        self._free.publish(JointState(name=[joint]))

    def inject_fault(self, fault: Fault) -> None:
        """Inject `fault` in the sim (`ft/inject_fault`; the monitor is not told)."""
        self._fault.publish(faults.message([fault]))

    def place_obstacle(self, pose: np.ndarray, size: tuple[float, float, float]) -> None:
        """A box of edges `size` (m) at `pose` (4x4, base frame) in the sim (`ft/obstacle`)."""
        self._obstacle.publish(faults.obstacle_message(pose, size))

    def remove_obstacle(self) -> None:
        """No obstacle in the sim."""
        self._obstacle.publish(Marker(action=Marker.DELETE))

    def joint_health(self) -> dict[str, JointHealth]:
        """The newest `ft/joint_health` read ({} before any)."""
        return health.read(self.health[-1], [s.name for s in self.health[-1].status])[0] \
            if self.health else {}

    def ever_unhealthy(self) -> set[str]:
        """Every joint any `ft/joint_health` named other than healthy."""
        return {s.name for msg in self.health for s in msg.status if s.message != "healthy"}

    def locked_names(self) -> list[str]:
        """The newest locked set seen (empty before any message)."""
        return sorted(self.locked[-1].name) if self.locked else []

    def ever_locked(self) -> set[str]:
        """Every joint any locked set named."""
        return {name for msg in self.locked for name in msg.name}

    def values(self, status_name: str) -> list[dict[str, str]]:
        """The key values of every status of that name received."""
        return [{kv.key: kv.value for kv in s.values} | {"message": s.message}
                for _, s in self.diagnostics.get(status_name, [])]

    def travelled(self, block: int = 50) -> float:
        """Joint-space path (rad) of the measured positions averaged over blocks of `block`.

        Averaging first keeps the position noise out: summed sample to sample, 1e-3 rad
        of noise alone adds some 0.001 rad per joint and sample.
        """
        q = np.array([convert.joint_vector(m, [f"panda_joint{i}" for i in range(1, 8)])
                      for m in self.states])
        blocks = len(q) // block
        if blocks < 2:
            return 0.0
        means = q[:blocks * block].reshape(blocks, block, -1).mean(axis=1)
        return float(np.sum(np.abs(np.diff(means, axis=0))))

    def close(self) -> None:
        """SIGINT every process (zeros on the way out), then make sure they are gone."""
        for process in self.processes.values():
            process.send_signal(signal.SIGCONT)
            process.send_signal(signal.SIGINT)
        for process in self.processes.values():
            try:
                process.wait(timeout=15)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()


@contextmanager
def graph(tmp_path: Path, parameters: dict[str, dict], before_start=None,
          processes: tuple[str, ...] = ("sim", "monitor", "controller")) -> Iterator[Graph]:
    """A running graph on a DDS domain of its own; every process stopped afterwards.

    `before_start(graph)` runs once the probe exists, before any process starts.
    """
    with ros_context() as (context, executor):
        g = Graph(context, executor, context.get_domain_id(), parameters, tmp_path)
        try:
            if before_start is not None:
                before_start(g)
            for name in processes:
                g.start(name)
            g.wait(lambda: len(g.states) > 10, 60.0, "joint states from the sim")
            yield g
        finally:
            g.close()
