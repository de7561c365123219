"""Who commands the plant: this monitor, or the controller's guard while it was away.

The plant's command topics have a second publisher at times: the controller's guard,
which ramps the arm to rest while the monitor does not answer
(`ft_msgs_py.monitor_guard`) and sends each of its commands on `ft/command_guard` too.
Two streams interleaved on `ft/command` make the driver see velocity jumps, which a real
one refuses, so the monitor commands the plant only when the guard does not:

- before each command it takes what waits on `ft/command_guard`; each guard command is
  the plant's last command from then on (`Monitor.follow`: detection expects it, the
  smoother continues from it), and the monitor sends nothing on the plant's topics
  until `HANDOVER` s after the guard's last one;
- a monitor that was away (its process stopped or starved: a gap between two commands
  taken of more than `ABSENT` s and `ABSENT_INTERVALS` times their usual interval) may
  find the guard's commands still on their way to it, behind the commands it takes
  first: it sends nothing for `LISTEN` s, time for them to arrive;
- a monitor away within one command (its stamp, read as the command was taken, more
  than `ABSENT` s old by the moment before its publish: the guard may have fired
  meanwhile) does not send that command, stamped before the guard's, and listens
  likewise (`late`).

Both only where a guard is there to fire (a publisher of `ft/command_guard` matched),
and not with simulated time (`use_sim_time`): a sim stepped by hand waits for each
command before its clock goes on, and a command held off would stop it.

Each command held off is echoed alone on `ft/command_echo` with the plant's last
command: the guard, answered, stops, and the monitor's next command continues from the
guard's last within the limits. A guard command stamped before the monitor's own last
is too late to take over from (`Smoother.adopt`); the monitor still holds off.

Two cases are left: a monitor stopped inside the publish call itself, after the last
look at the clock (its command goes out late, stamped before the guard's); and the
guard firing on a monitor that was not away (its echoes lost or late on the
controller's side): then both publish until the monitor takes the guard's first
command, a command or two.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable

from ft_msgs_py.audience import Audience

#: s (steady) after the guard's last command before the monitor commands the plant
#: again: several of the guard's periods (a command every control cycle, 4 ms at the
#: controller's default 250 Hz) and delivery jitter.
HANDOVER = 0.03
#: s (steady) between two commands taken beyond which the monitor counts itself away,
#: if also beyond `ABSENT_INTERVALS` times the median of the last `INTERVALS` gaps (a
#: slow controller's commands are not an absence): under the guard's default timeout
#: (0.05 s), which fires only after that long without an echo.
ABSENT = 0.02
ABSENT_INTERVALS = 3.0
INTERVALS = 5
#: s (steady) the monitor sends nothing after it was away.
LISTEN = 0.01


class Handover:
    """Whether the monitor may command the plant now (see the module docstring).

    Attributes:
        take_guard: takes what waits on `ft/command_guard` now, handing each command to
            the node, which calls `guarded`.
        wall_time: whether the node runs on wall time, where it may count itself away.
        guards: the publishers of `ft/command_guard` matched.
    """

    def __init__(self) -> None:
        self.take_guard: Callable[[], None] = lambda: None
        self.wall_time = True
        self.guards = Audience()
        self._guard_heard = -math.inf  # steady s: the guard's last command taken
        self._taken = -math.inf  # steady s: the last command taken
        self._gaps: deque[float] = deque(maxlen=INTERVALS)  # s between commands taken
        self._listen_until = -math.inf  # steady s

    @property
    def _guard_may_fire(self) -> bool:
        """Whether a guard's publisher is matched and the node runs on wall time."""
        return self.wall_time and bool(self.guards.count)

    def guarded(self, steady: float) -> None:
        """A command of the guard was taken at `steady` (s)."""
        self._guard_heard = steady

    def guarded_lately(self, steady: float) -> bool:
        """Whether a guard command was taken within `HANDOVER` s of `steady` (s)."""
        return steady - self._guard_heard < HANDOVER

    def held_off(self, steady: float) -> bool:
        """Whether a command taken at `steady` (s) must not go to the plant."""
        gap = steady - self._taken
        usual = sorted(self._gaps)[len(self._gaps) // 2] if self._gaps else 0.0
        if math.isfinite(gap):
            if self._guard_may_fire and gap > max(ABSENT, ABSENT_INTERVALS * usual):
                self._listen_until = steady + LISTEN
            self._gaps.append(gap)
        self._taken = steady
        return self.stop_held_off(steady)

    def late(self, age: float, steady: float) -> bool:
        """Whether a command must not go out at `steady` (s): its stamp `age` s old.

        Older than `ABSENT`, where a guard may fire: the monitor was away within the
        command; it listens from `steady` on, as after a gap.
        """
        if not (self._guard_may_fire and age > ABSENT):
            return False
        self._listen_until = steady + LISTEN
        return True

    def stop_held_off(self, steady: float) -> bool:
        """Whether a step of a stop ramp at `steady` (s) must not go to the plant."""
        self.take_guard()
        return steady < self._listen_until or self.guarded_lately(steady)
