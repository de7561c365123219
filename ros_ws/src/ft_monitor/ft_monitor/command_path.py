"""The monitor's command path: each command read, checked, filtered by the core and sent.

A command on `ft/command_raw` (a JointState: stamped, by name) or `ft/command_raw_array`
(velocities in `joints` order, unstamped, as MoveIt Servo publishes them) that is
malformed, stamped ahead of the clock or older than `timeout`, or physically absurd
(`Monitor.absurd_command`) is reported and replaced by zeros (reached on a ramp within
the limits); a good one goes through `Monitor.command` to `Outputs.send`.

Before a command goes to the plant, `Handover` says whether the controller's guard
commands it instead (`ft_monitor.handover`); a command held off is echoed alone, and
one held up in this process past `handover.ABSENT` between its take and its send is
not sent (`Handover.late`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
from builtin_interfaces.msg import Time
from ft_core.monitor import Monitor
from ft_msgs_py import convert, wire
from ft_msgs_py.episodes import Episodes
from ft_msgs_py.node import JointStateLike
from std_msgs.msg import Float64MultiArray

from ft_monitor.handover import Handover
from ft_monitor.outputs import Outputs, Wiring


class CommandPath:
    """Commands in, filtered commands out; when the last good one came.

    Attributes:
        timeout: s; an older command is stale (refused).
        last: node time (s) of the last command forwarded (-inf: none yet).
        last_steady: steady time (s) of the last command forwarded (the watchdog's).
        clock: the node clock (s), which stamps the commands.
    """

    def __init__(self, outputs: Outputs, problems: Episodes, timeout: float,
                 commanded: Callable[[], None], clock: Callable[[], float]):
        """A command path sending through `outputs`.

        `commanded()` is called with each command forwarded (the node ends a stop ramp).
        """
        self._outputs, self._problems, self._commanded = outputs, problems, commanded
        self.clock = clock
        self.timeout = timeout
        self.last, self.last_steady = -math.inf, time.monotonic()
        #: Whether the guard commands the plant; its `take_guard` is the node's.
        self.handover = Handover()

    def guarded(self, core: Monitor, qd: np.ndarray, stamp: float) -> None:
        """A command (chain order, rad/s) the controller's guard sent, stamped `stamp` (s)."""
        core.follow(qd, stamp)
        self.handover.guarded(time.monotonic())
        self._problems.report("guard", "the controller's guard commands the plant: nothing "
                              "sent on ft/command until it stops", warning=True)

    def command(self, core: Monitor, wiring: Wiring, msg: JointStateLike, now: float) -> None:
        """A JointState from `ft/command_raw` at node time `now` (s)."""
        stamp = self._problems.message_time("ft/command_raw", msg.header.stamp, now)
        try:
            if stamp is None:
                raise convert.MessageError("stamp ahead of the clock")
            if now - stamp > self.timeout:
                raise convert.MessageError(f"stale: stamped {now - stamp:.3f} s ago")
            qd = convert.joint_vector(msg, core.robot.joint_names, "velocity")
        except convert.MessageError as error:
            self.refuse(core, wiring, "ft/command_raw", error, msg.header.stamp, now)
            return
        self.forward(core, wiring, "ft/command_raw", qd, msg.header.stamp, now)

    def array(self, core: Monitor, wiring: Wiring, msg: Float64MultiArray, stamp: Time,
              now: float) -> None:
        """Velocities in `joints` order from `ft/command_raw_array`, stamped on arrival."""
        try:
            qd = convert.array_vector(msg.data, wiring.order)
        except convert.MessageError as error:
            self.refuse(core, wiring, "ft/command_raw_array", error, stamp, now)
            return
        self.forward(core, wiring, "ft/command_raw_array", qd, stamp, now)

    def refuse(self, core: Monitor, wiring: Wiring, topic: str, error: Exception | str,
               stamp: Time | wire.Stamp, now: float) -> None:
        """A malformed command: reported, and replaced by zeros (reached on a ramp)."""
        self._problems.report(topic, f"{error}: commanding zeros")
        if not self._held_off(core, wiring, stamp):
            self._send(wiring, core.zeros(now), now, stamp)

    def stop_step(self, core: Monitor, wiring: Wiring, now: float) -> bool:
        """The next command of a stop ramp at node time `now` (s); whether at rest."""
        if self.handover.stop_held_off(time.monotonic()):
            return False
        self._send(wiring, core.zeros(now), now)
        return not core.stopping

    def _held_off(self, core: Monitor, wiring: Wiring, stamp: Time | wire.Stamp) -> bool:
        """Whether the command stamped `stamp` must not go to the plant; then echoed alone."""
        if not self.handover.held_off(time.monotonic()):
            self._problems.report("guard", None)
            return False
        self._outputs.echo(wiring, core.sent, stamp)
        return True

    def _send(self, wiring: Wiring, qd_chain: np.ndarray, now: float,
              answered: Time | wire.Stamp | None = None) -> None:
        """`Outputs.send` of the command stamped `now` (s), unless it is late by then.

        Detection and the smoother go on from a command not sent as from one sent: the
        next one continues the same ramp within the limits, one step further.
        """
        if not self._outputs.send(wiring, qd_chain, now, answered, lambda: self.handover.late(
                self.clock() - now, time.monotonic())):
            self._problems.report("guard", f"a command held up {self.clock() - now:.3f} s "
                                  "in this process is not sent: the guard may command the "
                                  "plant meanwhile", warning=True)

    def forward(self, core: Monitor, wiring: Wiring, source: str, qd: np.ndarray,
                stamp: Time | wire.Stamp, now: float) -> None:
        """A well-formed command (chain order, rad/s), filtered and sent; an absurd one refused."""
        absurd = core.absurd_command(qd)
        if absurd is not None:
            self.refuse(core, wiring, source, absurd, stamp, now)
            return
        self._problems.report(source, None)
        self.last, self.last_steady = now, time.monotonic()
        self._commanded()
        if not self._held_off(core, wiring, stamp):
            self._send(wiring, core.command(qd, now), now, stamp)
