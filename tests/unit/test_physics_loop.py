"""Issue 29: the controller and monitor cores in closed loop with the MuJoCo plant.

What the three nodes do at their default parameters, without ROS: `ft_core.controller`
tracks pose goals (a new one every 1.5 s, as the separate-process tests' probe sends
them), `ft_core.monitor` filters its commands and watches the measured positions, and
`ft_core.physics.PhysicsPlant` (servo lag and overshoot, 90 % gravity compensation,
a brake as the lock) executes them behind a latency. Healthy goals first, in which
nothing may be declared; then a joint locks while it moves, and the monitor must
name that joint, and no other, within 1 s (issue 29's p99 target). Every chain joint
of the pose task, every joint but the flange's of the position task (which the
position of `panda_link8` does not depend on, so no task commands it), on two drivers:
a fast one and the slowest of the issue's targets (50 ms latency, 50 ms servo, the
last command held). The separate-process test on the same plant is in
`tests/processes/test_deployment.py`; `bench/detection.py` measures the latency
distribution over a grid of plants.
"""

from __future__ import annotations

import numpy as np
import pytest
from ft_core import robots, targets
from ft_core.controller import Controller, ControllerConfig
from ft_core.detection import DetectorConfig
from ft_core.engine import EngineConfig
from ft_core.monitor import Monitor, MonitorConfig
from ft_core.physics import PhysicsPlant
from ft_core.plant import PlantConfig

#: Goal positions visited in turn (m), as `tests/deployment.py` sends them.
GOALS = ((0.5, 0.1, 0.4), (0.45, -0.15, 0.35), (0.4, 0.05, 0.55))
GOAL_PERIOD = 1.5
#: s of healthy goals before the lock (the monitor identifies the plant meanwhile).
HEALTHY = 4.0
#: rad/s; the joint locks at the first moment after HEALTHY that it moves this fast and
#: is commanded as fast (a lock shows only while its joint is commanded: a joint that
#: overshoots briefly as the others ramp up, then is hardly commanded, is not the case
#: this test is about; docs/monitor.md "Locks the monitor cannot see").
LOCK_SPEED = 0.1
DRIVERS = {"fast": PlantConfig(latency=0.01, response_time=0.02),
           "slow": PlantConfig(latency=0.05, response_time=0.05, hold_last_command=True)}
NOISE = 1e-3  # rad, the sim's default position noise in the deployment tests


class Loop:
    """Controller -> monitor filter -> physics plant -> monitor, one engine period a cycle."""

    def __init__(self, task: str, driver: PlantConfig):
        self.robot = robots.load("panda_inertial", tip_link="panda_link8", task_space=task)
        engine = EngineConfig()
        self.dt = engine.dt
        self.controller = Controller(self.robot, engine, ControllerConfig(),
                                     ("panda_inertial", (None, "panda_link8", task)))
        self.monitor = Monitor(self.robot, DetectorConfig(), MonitorConfig(), None,
                               lambda *_args, **_kwargs: None)
        self.plant = PhysicsPlant(self.robot, self.robot.home(), driver)
        self.orientation = self.robot.transform(self.robot.home())[:3, :3]
        self.rng = np.random.default_rng(29)
        self.t = 0.0
        self.goals = 0
        self.declared: list[tuple[float, list[str]]] = []  # (time, locked set) on changes
        self.sent = np.zeros(self.robot.n)  # the last command the plant got (rad/s)

    def send_goal(self) -> None:
        pose = np.eye(4)
        pose[:3, :3] = self.orientation
        pose[:3, 3] = GOALS[self.goals % len(GOALS)]
        self.controller.set_pose_goal(targets.goal_from_transform(self.robot, pose), self.t)
        self.goals += 1

    def run(self, seconds: float, stop=lambda: False) -> None:
        """Cycle for `seconds`, a goal every GOAL_PERIOD, until `stop()`."""
        for _ in range(round(seconds / self.dt)):
            if self.t >= self.goals * GOAL_PERIOD:
                self.send_goal()
            q = self.plant.q + self.rng.normal(0.0, NOISE, self.robot.n)
            change = self.monitor.observe(q, self.t)
            if change.changed:
                names = list(self.monitor.locked)
                self.declared.append((self.t, names))
                self.controller.set_locked([self.robot.joint_names.index(n) for n in names])
            step = self.controller.step(q, 0.0, self.t)
            if step.announce and step.suspect is not None:
                self.monitor.suspect(step.suspect, self.t)
            self.sent = self.monitor.command(step.qd, self.t)
            self.plant.command(self.t, self.sent)
            self.t += self.dt
            self.plant.step(self.t)
            if stop():
                return


CASES = [(task, joint, driver) for task, joints in (("position", range(6)), ("pose", range(7)))
         for joint in joints for driver in DRIVERS]


@pytest.mark.parametrize(("task", "joint", "driver"), CASES)
def test_a_lock_on_a_physics_plant_is_named_within_a_second(task: str, joint: int,
                                                            driver: str) -> None:
    loop = Loop(task, DRIVERS[driver])
    loop.run(HEALTHY)
    loop.run(3 * GOAL_PERIOD, stop=lambda: min(abs(loop.plant.qd[joint]),
                                               abs(loop.sent[joint])) > LOCK_SPEED)
    assert abs(loop.plant.qd[joint]) > LOCK_SPEED, f"joint {joint} never moves"
    assert loop.declared == [] and loop.monitor.swinging == [], "declared in healthy motion"
    assert loop.monitor.plant_values()["observing"] == "yes", "the monitor never observed"
    locked_at = loop.t
    loop.plant.lock(joint)
    loop.run(1.0, stop=lambda: bool(loop.declared))
    name = loop.robot.joint_names[joint]
    assert loop.declared, f"{name} not found within 1 s"
    when, names = loop.declared[0]
    assert names == [name], f"{names} declared instead of {name}"
    assert when - locked_at <= 1.0
    assert loop.monitor.swinging == []
