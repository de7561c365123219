"""A velocity-commanded arm as real drivers execute commands (docs/detection.md).

The command path of a real arm, step by step (`Plant.step`):
1. transport and driver latency: a command takes effect `latency` s after it arrived;
2. the command in force is the newest one whose latency has passed; once older than
   `timeout` it is dropped to zero (a driver's command watchdog: Franka's FCI, KUKA's
   FRI and UR's RTDE stop the arm when commands pause), unless `hold_last_command`
   (ros2_control's velocity controllers keep the last command forever);
3. clipped to the velocity limits;
4. the velocity loop follows it as a first-order lag of time constant
   `response_time` (v' = (u - v) / T, integrated exactly for a command held over the
   step), then within `acceleration_limit` (rad/s^2, per joint);
5. positions integrate the velocity (exactly for the lag, trapezoidal under an
   acceleration limit) and stop at the position limits; locked joints do not move;
   free-swinging joints (`swing`) ignore the commands and follow the accelerations
   `free_swing_acceleration(q, qd)` gives (semi-implicit Euler, 1 ms substeps).

Degraded joints (`inject`, `ft_core.faults`) have kinematic analogues: friction and a
loss of torque authority scale the command down before step 4
(`FaultState.kinematic_velocity`), a range fault's stops join the position limits, and an
intermittent jam holds the joint still in its locked phases.

Times are seconds on the plant's clock; velocities rad/s (m/s for prismatic joints).
"""

from __future__ import annotations

import abc
import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ft_core.faults import Fault, FaultKind, FaultState


@dataclass(frozen=True)
class PlantConfig:
    """How the plant executes commands (see the module docstring).

    Attributes:
        latency: s from a command's arrival to its effect, >= 0.
        response_time: s, first-order time constant of the velocity loop (0: instant).
        acceleration_limit: rad/s^2, one value for all joints or one per joint (0: none).
        timeout: s; a command older than this is dropped to zero (not with hold).
        hold_last_command: execute the last command forever (ros2_control).
    """

    latency: float = 0.0
    response_time: float = 0.0
    acceleration_limit: tuple[float, ...] = (0.0,)
    timeout: float = 0.1
    hold_last_command: bool = False

    def __post_init__(self) -> None:
        values = {"latency": self.latency, "response_time": self.response_time,
                  "timeout": self.timeout}
        for name, value in values.items():
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"plant {name} = {value} must be finite and >= 0")
        if not self.acceleration_limit or not all(
                math.isfinite(a) and a >= 0 for a in self.acceleration_limit):
            raise ValueError(f"plant acceleration_limit = {list(self.acceleration_limit)} "
                             "must be one or more finite values >= 0")


class CommandPath:
    """Steps 1-3 of the module docstring, shared by every plant.

    Latency, watchdog or hold, velocity limits, and the per-joint acceleration limits
    the plants enforce.
    """

    def __init__(self, n: int, velocity_limits: np.ndarray, config: PlantConfig):
        self.n = n
        self.velocity_limits = np.asarray(velocity_limits, float)
        self.configure(config)
        self._commands: deque[tuple[float, np.ndarray]] = deque()

    def configure(self, config: PlantConfig) -> None:
        """Use new plant options from the next step on.

        Raises:
            ValueError: acceleration limits neither one value nor one per joint.
        """
        limits = np.asarray(config.acceleration_limit, float)
        if limits.size not in (1, self.n):
            raise ValueError(f"acceleration_limit has {limits.size} values for {self.n} joints")
        self.config = config
        self.acceleration = np.broadcast_to(limits, (self.n,)).copy()

    @property
    def command_time(self) -> float:
        """Arrival time (s) of the newest command; -inf before any."""
        return self._commands[-1][0] if self._commands else -math.inf

    def command(self, time: float, velocity: np.ndarray) -> None:
        """A command arrived at `time` (s)."""
        self._commands.append((time, np.asarray(velocity, float).copy()))

    def in_force(self, t: float) -> np.ndarray:
        """The command acting at `t` (s), clipped to the velocity limits.

        The newest command whose latency has passed, unless it timed out.
        """
        latency = self.config.latency
        while len(self._commands) > 1 and self._commands[1][0] + latency <= t:
            self._commands.popleft()
        if not self._commands or self._commands[0][0] + latency > t:
            return np.zeros(self.n)
        arrived, velocity = self._commands[0]
        if not self.config.hold_last_command and t - arrived - latency > self.config.timeout:
            return np.zeros(self.n)
        return np.clip(velocity, -self.velocity_limits, self.velocity_limits)


class BasePlant(abc.ABC):
    """What every plant shares: the command path, the clock, the failed joints.

    Attributes:
        t: plant time (s).
        locked: joint index -> position (rad) where it locked.
        swinging: joints that lost their torque (`swing`).
    """

    def __init__(self, lower: np.ndarray, upper: np.ndarray, velocity_limits: np.ndarray,
                 config: PlantConfig | None = None, time: float = 0.0):
        self.lower, self.upper = np.asarray(lower, float), np.asarray(upper, float)
        self.velocity_limits = np.asarray(velocity_limits, float)
        self.n = self.lower.size
        self.path = CommandPath(self.n, self.velocity_limits, config or PlantConfig())
        self.t = time
        self.locked: dict[int, float] = {}
        self.swinging: set[int] = set()
        #: joints braked on the monitor's word (`follow_declared`)
        self.held: set[int] = set()
        self._held_swinging: set[int] = set()  # of them, those that had lost their torque
        self.faults = FaultState(self.n)

    def configure(self, config: PlantConfig) -> None:
        """Use new plant options from the next step on."""
        self.path.configure(config)

    @property
    def command_time(self) -> float:
        """Arrival time (s) of the newest command; -inf before any."""
        return self.path.command_time

    def command(self, time: float, velocity: np.ndarray) -> None:
        """A command arrived at `time` (s)."""
        self.path.command(time, velocity)

    @abc.abstractmethod
    def position(self, joint: int) -> float:
        """Joint index `joint`'s position (rad)."""

    @abc.abstractmethod
    def lock(self, joint: int) -> None:
        """Lock a joint where it is."""

    @abc.abstractmethod
    def unlock(self, joint: int) -> None:
        """Release the lock of one joint (its other faults stay)."""

    @abc.abstractmethod
    def swing(self, joint: int) -> None:
        """The joint's drive loses its torque."""

    def follow_declared(self, declared: set[int]) -> tuple[list[int], list[int]]:
        """The driver's brakes on the monitor's word: its locked set `declared` (indices).

        Every joint declared locked is braked where it is, as a driver that acts on
        `ft/locked_joints` must: the controller counts it held, and a joint that lost its
        torque (or most of it) would fall on, one stuck by friction jump when it slips.
        One no longer declared (the monitor's `~/reset`) is released, and swings again if
        it had lost its torque. Joints locked otherwise (injected) are left as they are.
        Returns (braked, released).
        """
        braked = sorted(j for j in declared if j not in self.locked)
        self._held_swinging.update(j for j in braked if j in self.swinging)
        for j in braked:
            self.lock(j)
        self.held.update(braked)
        released = sorted(self.held - declared)
        for j in released:
            self.unlock(j)
            if j in self._held_swinging:
                self.swing(j)
        self.held.difference_update(released)
        self._held_swinging.difference_update(released)
        return braked, released

    def check_fault(self, joint: int, fault: Fault) -> None:
        """Raise `ft_core.faults.FaultError` if `fault` cannot act on joint index `joint`."""
        if fault.kind is FaultKind.RANGE:
            fault.stops(self.lower[joint], self.upper[joint], self.position(joint))

    def inject(self, joint: int, fault: Fault) -> None:
        """`fault` on joint index `joint` from now on, until `release`.

        Raises:
            ft_core.faults.FaultError: it cannot be injected there (`check_fault`).
        """
        self.check_fault(joint, fault)
        if fault.kind is FaultKind.LOCK:
            self.lock(joint)
        elif fault.kind is FaultKind.FREE_SWING:
            self.swing(joint)
        else:
            stops = fault.stops(self.lower[joint], self.upper[joint], self.position(joint)) \
                if fault.kind is FaultKind.RANGE else (-math.inf, math.inf)
            self.faults.add(joint, fault, self.t, stops)
            self._degrade(joint)

    def _degrade(self, joint: int) -> None:  # noqa: B027 (a hook: most plants need none)
        """Make the faults in `self.faults` on joint index `joint` act (plants that must)."""

    def failures(self) -> dict[int, list[str]]:
        """{joint index: the kinds (`FaultKind`) in force on it}, locks and free swings too."""
        return {j: [*([FaultKind.LOCK] if j in self.locked else []),
                    *([FaultKind.FREE_SWING] if j in self.swinging else []),
                    *self.faults.faults.get(j, {})]
                for j in sorted({*self.locked, *self.swinging, *self.faults.faults})}

    def release(self) -> list[int]:
        """Release every lock, free swing and fault; returns the joints that were failed."""
        released = sorted(set(self.locked) | self.swinging | set(self.faults.faults))
        self.locked.clear()
        self.swinging.clear()
        self.held.clear()
        self._held_swinging.clear()
        self.faults.clear()
        return released


class Plant(BasePlant):
    """Joint positions and velocities driven by velocity commands; see the module docstring."""

    def __init__(self, lower: np.ndarray, upper: np.ndarray, velocity_limits: np.ndarray,
                 q0: np.ndarray, config: PlantConfig | None = None, time: float = 0.0):
        super().__init__(lower, upper, velocity_limits, config, time)
        self.q = np.clip(np.asarray(q0, float), self.lower, self.upper)
        self.qd = np.zeros(self.n)
        #: (q, qd) -> accelerations (n,) of the free-swinging joints (rad/s^2).
        self.free_swing_acceleration: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None

    def position(self, joint: int) -> float:
        """Joint index `joint`'s position (rad)."""
        return float(self.q[joint])

    def lock(self, joint: int) -> None:
        """Lock a joint where it is (it stops at once; a free-swinging one is braked)."""
        self.locked.setdefault(joint, self.position(joint))
        self.swinging.discard(joint)
        self.qd[joint] = 0.0

    def unlock(self, joint: int) -> None:
        """Release the lock of one joint (its other faults stay)."""
        self.locked.pop(joint, None)

    def swing(self, joint: int) -> None:
        """The joint loses its torque: from now on it follows `free_swing_acceleration`."""
        if self.free_swing_acceleration is None:
            raise ValueError("free swinging needs free_swing_acceleration")
        if joint not in self.locked:
            self.swinging.add(joint)

    def step(self, time: float) -> None:
        """Advance to `time` (s) under the command in force at the step's start."""
        dt = max(time - self.t, 0.0)
        self.t = max(time, self.t)
        if dt == 0.0:
            return
        u = self.path.in_force(self.t)
        faults = self.faults
        if faults.faults:
            u = faults.kinematic_velocity(u, self.velocity_limits)
        tau = self.path.config.response_time
        if tau > 0:
            decay = math.exp(-dt / tau)
            v = u + (self.qd - u) * decay
            moved = u * dt + (self.qd - u) * tau * (1 - decay)
        else:
            v, moved = u, u * dt
        limited = self.path.acceleration > 0
        if np.any(limited):
            step = self.path.acceleration * dt
            v = np.where(limited, np.clip(v, self.qd - step, self.qd + step), v)
            moved = np.where(limited, 0.5 * (self.qd + v) * dt, moved)
        for j in set(self.locked) | faults.braked(self.t):
            v[j], moved[j] = 0.0, 0.0
        q = np.clip(self.q + moved, *self._limits())
        stopped = (q != self.q + moved)  # at a position limit
        v[stopped] = 0.0
        if self.swinging:
            q, v = self._swing(q, v, dt)
        self.q, self.qd = q, v

    def _swing(self, q: np.ndarray, v: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """The free-swinging joints over dt, from where they were (1 ms substeps)."""
        free = sorted(self.swinging)
        acceleration = self.free_swing_acceleration
        assert acceleration is not None  # swing() refuses a plant without it
        q, v = q.copy(), v.copy()
        q[free], v[free] = self.q[free], self.qd[free]
        steps = max(1, math.ceil(dt / 0.001))
        h = dt / steps
        for _ in range(steps):
            v[free] += h * acceleration(q, v)[free]
            q[free] += h * v[free]
            lower, upper = self._limits()
            at_limit = (q < lower) | (q > upper)
            q = np.clip(q, lower, upper)
            v[free] = np.where(at_limit[free], 0.0, v[free])
        return q, v

    def _limits(self) -> tuple[np.ndarray, np.ndarray]:
        """The position limits (rad) with the stops of range faults."""
        return np.maximum(self.lower, self.faults.lower), np.minimum(self.upper, self.faults.upper)
