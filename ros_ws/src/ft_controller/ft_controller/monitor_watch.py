"""The controller's watch on the monitor: which locked set and health to believe, a dead monitor.

`MonitorWatch` joins the guard of a dead monitor (`ft_msgs_py.monitor_guard`: commands
against the monitor's echoes), the trust in the locked set (`ft_msgs_py.publishers`: who
publishes `ft/locked_joints`, and which of a contested set's locks the monitor's echoes
show) and the joints' health (`ft/joint_health`, which the core adapts to:
`ft_core.adaptation`). The node hands it the messages and publishes what it returns.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from ft_core import adaptation
from ft_msgs_py import convert, health, publishers
from ft_msgs_py.episodes import Episodes
from ft_msgs_py.messages import MessageError
from ft_msgs_py.monitor_guard import MonitorGuard
from rclpy.impl.rcutils_logger import RcutilsLogger
from sensor_msgs.msg import JointState

from ft_controller.loaded import Loaded


class MonitorWatch:
    """The locked set the controller believes, and its stop while the monitor is silent."""

    def __init__(self, timeout: float, logger: RcutilsLogger, problems: Episodes,
                 clock: Callable[[], int]):
        """`timeout`: s (steady) without the monitor's answer before the guard stops the arm.

        `logger` and `problems`: the node's, for what it decides and what it refuses;
        `clock`: the node clock in ns, read only when a set is adopted or a stop is due.
        """
        self.guard = MonitorGuard(timeout)
        self._logger, self._problems, self._clock = logger, problems, clock
        self._trust = publishers.LockedSetTrust()
        #: The guard's stop while the monitor does not answer (`Controller.stopper`; None:
        #: it answers): the next command (chain order) for a time (s).
        self._stop: Callable[[float], np.ndarray] | None = None

    def on_locked(self, msg: JointState, graph: list[str], monitor: str | None,
                  loaded: Loaded) -> None:
        """An `ft/locked_joints` message, published by the nodes `graph` (full names).

        `monitor`: the full name of the only node to believe (None: any single one). The
        set decided is the core's from now on.
        """
        verdict = publishers.judge(graph, monitor)
        self._problems.report("ft/locked_joints", verdict.problem)
        if verdict.take == publishers.Take.NONE:
            return
        try:
            locked, unknown = convert.locked_joints(msg, loaded.robot.joint_names)
        except convert.MessageError as error:
            self._logger.error(f"ft/locked_joints: {error}: ignored", throttle_duration_sec=5.0)
            return
        if unknown:
            self._logger.warning(f"ft/locked_joints: unknown joints {unknown} ignored",
                                 throttle_duration_sec=5.0)
        self._adopt(self.locked_set(verdict, locked, loaded), loaded)

    def on_health(self, msg: DiagnosticArray, graph: list[str], monitor: str | None,
                  loaded: Loaded) -> None:
        """An `ft/joint_health` message, published by the nodes `graph` (full names).

        Taken whole from the monitor alone (`monitor`: its full name; None: any single
        publisher), else ignored; refused whole for an unknown or duplicate joint, an
        unknown state or a number out of its range (`adaptation.problem`). Each refusal is
        a WARN, at most every 5 s; an adaptation that changes is logged.
        """
        if publishers.judge(graph, monitor).take != publishers.Take.ALL:
            self._logger.warning(f"ft/joint_health: published by {sorted(graph)[:10]}, not "
                                 f"by the monitor alone: ignored", throttle_duration_sec=5.0)
            return
        try:
            joints, unknown = health.read(msg, loaded.robot.joint_names)
            if unknown:
                raise MessageError(f"unknown joints {unknown[:10]}")
            for name, joint in joints.items():
                problem = adaptation.problem(joint)
                if problem is not None:
                    raise MessageError(f"{name}: {problem}")
        except MessageError as error:
            self._logger.warning(f"ft/joint_health: {error}: ignored", throttle_duration_sec=5.0)
            return
        core, before = loaded.core, loaded.core.adaptation.note
        core.set_health(dict(zip(loaded.indices(joints), joints.values(), strict=True)),
                        self._clock() * 1e-9)
        if core.adaptation.note != before:
            self._logger.info(f"adapted to the joints' health: {core.adaptation.note}")

    def on_echo(self, msg, loaded: Loaded | None) -> None:
        """An `ft/command_echo` message: the monitor's answer to a command, or not."""
        self._adopt(self.echo((msg.header.stamp.sec, msg.header.stamp.nanosec), msg.velocity,
                              loaded), loaded)

    def _adopt(self, change: tuple[set[str], str] | None, loaded: Loaded | None) -> None:
        if change is not None and loaded is not None:
            if change[1]:
                self._logger.warning(change[1])
            loaded.core.set_locked(loaded.indices(change[0]), self._clock() * 1e-9)

    def locked_set(self, verdict: publishers.Verdict, locked: Iterable[str],
                   loaded: Loaded) -> tuple[set[str], str] | None:
        """The set to adopt on an `ft/locked_joints` message, with the log line; or None.

        `verdict`: `publishers.judge`'s on the message; `locked`: its joints.
        """
        current = set(loaded.names(loaded.core.locked))
        adopt = self._trust.heard(verdict.take, locked, current, self._shown(loaded))
        if adopt is None:
            return None
        if verdict.take == publishers.Take.ADDITIONS:
            return adopt, f"locked joints now {sorted(adopt)} (the monitor's commands show them)"
        return adopt, (f"locked joints now {sorted(adopt) or 'none'}" if adopt != current
                       else "")

    def echo(self, stamp: tuple[int, int], velocity, loaded: Loaded | None,
             ) -> tuple[set[str], str] | None:
        """An `ft/command_echo` message: the set to adopt, with the log line, if it shows one.

        An echo answering a command may show locks of a contested locked set zeroed.
        """
        if not self.guard.received(stamp, velocity) or loaded is None:
            return None
        adopt = self._trust.corroborated(set(loaded.names(loaded.core.locked)),
                                         self._shown(loaded))
        if adopt is None:
            return None
        return adopt, f"locked joints now {sorted(adopt)} (the monitor's commands show them)"

    def _shown(self, loaded: Loaded) -> set[str]:
        """The joints the monitor's latest echo zeroed (`MonitorGuard.zeroed`)."""
        return {loaded.joints[j] for j in self.guard.zeroed if j < len(loaded.joints)}

    def check(self, loaded: Loaded | None) -> tuple[Loaded, list[float], int] | None:
        """The guard's command while the monitor does not answer (an ERROR said), else None.

        Asked every cycle and every watchdog period: what to publish on the plant's
        topics for the model `loaded`, and its stamp (ns, node clock).
        """
        silent = self.guard.silent(time.monotonic())
        if silent is None:
            self._stop = None
            self._problems.report("monitor", None)
            return None
        self._problems.report("monitor", f"no answer from the monitor for {silent:.2f} s: "
                              "commanding zeros on ft/command and ft/command_array")
        if loaded is None:
            return None
        nanoseconds = self._clock()
        return loaded, self.stop(loaded, nanoseconds * 1e-9), nanoseconds

    def stop(self, loaded: Loaded, now: float) -> list[float]:
        """The guard's command (command order, rad/s) at node time `now` (s).

        A ramp from what the monitor last sent (its last echo) to rest, within the
        arm's limits (`Controller.stopper`).
        """
        if self._stop is None:
            echo = self.guard.last_echo
            held = np.zeros(loaded.robot.n)
            if echo is not None and len(echo) == loaded.robot.n:
                held[loaded.order] = echo
            self._stop = loaded.core.stopper(held)
        return self._stop(now)[loaded.order].tolist()
