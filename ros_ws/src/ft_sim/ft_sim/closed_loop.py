"""The controller and monitor cores in closed loop with a plant, without ROS.

What the nodes do at their default parameters, one engine period a cycle: the
controller core (`ft_core.controller`) tracks pose goals, a new one every `GOAL_PERIOD`;
the monitor core (`ft_core.monitor`) filters its commands and watches the measured
positions (with noise, and the plant's efforts where it has them); the plant (by default
the MuJoCo `ft_core.physics.PhysicsPlant` of the Panda with its inertias) executes the
commands behind its latency. Deterministic for a seed, and several times faster than
real time: the tests of `tests/unit/test_physics_loop.py` and the fault grid of
`bench/faults.py` run on it; the nodes as separate processes are tested in
`tests/processes`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from ft_core import robots, targets
from ft_core.controller import Controller, ControllerConfig
from ft_core.detection import DetectorConfig
from ft_core.engine import EngineConfig
from ft_core.monitor import Monitor, MonitorConfig
from ft_core.physics import PhysicsPlant
from ft_core.plant import PlantConfig

#: Goal positions visited in turn (m), as `tests/deployment.py` sends them.
GOALS = ((0.5, 0.1, 0.4), (0.45, -0.15, 0.35), (0.4, 0.05, 0.55))
#: s between goals.
GOAL_PERIOD = 1.5
#: rad, the measured positions' noise (the sim's default in the deployment tests).
NOISE = 1e-3
#: m, the edges of the wall `wall_across` places (wide, thin).
WALL = (0.6, 0.6, 0.02)
#: s between the monitor's publications of every joint's health (its diagnostics period).
HEALTH_PERIOD = 0.5
#: Two drivers: a fast one and the slowest of the detection targets (50 ms latency, a 50 ms
#: servo, the last command held).
DRIVERS = {"fast": PlantConfig(latency=0.01, response_time=0.02),
           "slow": PlantConfig(latency=0.05, response_time=0.05, hold_last_command=True)}


def wall_across(start: np.ndarray, goal: np.ndarray, share: float = 0.4,
                beyond: float = 0.0) -> np.ndarray:
    """The pose (4x4, base frame) of a wall of edges `WALL` across the way start -> goal (m).

    Its centre `share` of the way along and `beyond` m further, its thin edge along the
    way: a tool going straight to `goal` meets it.
    """
    way = np.asarray(goal, float) - np.asarray(start, float)
    normal = way / np.linalg.norm(way)
    side = np.cross(normal, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    pose = np.eye(4)
    pose[:3, :3] = np.column_stack([side, np.cross(normal, side), normal])
    pose[:3, 3] = np.asarray(start, float) + share * way + beyond * normal
    return pose


class ClosedLoop:
    """Controller -> monitor filter -> plant -> monitor, one engine period a cycle.

    Attributes:
        robot, controller, monitor, plant: the parts.
        t: s, the loop's time.
        goal_period: s between goals (`GOAL_PERIOD`; may change between runs).
        goal_sent_at: s, when the current goal was sent (-inf before the first).
        declared: (time, locked set) at every change of the monitor's locked set; the
            controller and the plant's driver (`BasePlant.follow_declared`: it brakes every
            joint declared) are given the set at once, the controller every
            joint's health with each change and every `HEALTH_PERIOD`, as the nodes
            publish them.
        sent: rad/s, the last command the plant got.
    """

    def __init__(self, task: str, driver: PlantConfig, seed: int = 29,
                 monitor: MonitorConfig | None = None):
        self.robot = robots.load("panda_inertial", tip_link="panda_link8", task_space=task)
        engine = EngineConfig()
        self.dt = engine.dt
        self.controller = Controller(self.robot, engine, ControllerConfig(),
                                     ("panda_inertial", (None, "panda_link8", task)))
        self.monitor = Monitor(self.robot, DetectorConfig(), monitor or MonitorConfig(), None)
        self.plant = PhysicsPlant(self.robot, self.robot.home(), driver)
        self.orientation = self.robot.transform(self.robot.home())[:3, :3]
        self.rng = np.random.default_rng(seed)
        self.t = 0.0
        self.goals = 0
        self.goal_period = GOAL_PERIOD
        self.goal_sent_at = -np.inf
        self.declared: list[tuple[float, list[str]]] = []
        self.sent = np.zeros(self.robot.n)
        self._health_at = -np.inf  # when the controller was last given the joints' health

    @property
    def goal(self) -> np.ndarray:
        """The current goal position (m)."""
        return np.array(GOALS[(self.goals - 1) % len(GOALS)])

    def send_goal(self) -> None:
        """The next goal of `GOALS`, at the home orientation."""
        pose = np.eye(4)
        pose[:3, :3] = self.orientation
        pose[:3, 3] = GOALS[self.goals % len(GOALS)]
        self.controller.set_pose_goal(targets.goal_from_transform(self.robot, pose), self.t)
        self.goals += 1
        self.goal_sent_at = self.t

    def tool_error(self) -> float:
        """The distance (m) between the tool and the current goal."""
        return float(np.linalg.norm(self.robot.transform(self.plant.q)[:3, 3] - self.goal))

    def close(self) -> None:
        """End the controller's worker process and the monitor's writer thread."""
        self.controller.close()
        self.monitor.close()

    def run(self, seconds: float, stop: Callable[[], bool] = lambda: False) -> None:
        """Cycle for `seconds`, a goal every `goal_period`, until `stop()`."""
        for _ in range(round(seconds / self.dt)):
            if self.t >= self.goal_sent_at + self.goal_period - 1e-9:
                self.send_goal()
            q = self.plant.q + self.rng.normal(0.0, NOISE, self.robot.n)
            change = self.monitor.observe(q, self.t, effort=getattr(self.plant, "torque", None))
            if change.changed:
                names = list(self.monitor.locked)
                self.declared.append((self.t, names))
                locked = [self.robot.joint_names.index(n) for n in names]
                self.controller.set_locked(locked)
                self.plant.follow_declared(set(locked))  # the driver's brakes
            if change.events or self.t - self._health_at >= HEALTH_PERIOD:
                self.controller.set_health(dict(enumerate(self.monitor.health().values())),
                                           self.t)
                self._health_at = self.t
            step = self.controller.step(q, 0.0, self.t)
            if step.announce and step.suspect is not None:
                self.monitor.suspect(step.suspect, self.t)
            self.sent = self.monitor.command(step.qd, self.t)
            self.plant.command(self.t, self.sent)
            self.t += self.dt
            self.plant.step(self.t)
            if stop():
                return
