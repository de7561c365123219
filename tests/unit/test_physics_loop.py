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
`tests/processes/test_deployment.py`; `bench/detection.py` measures the latency (the loop:
`ft_sim.closed_loop`)
distribution over a grid of plants.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from ft_core import robots
from ft_core.detection import DetectorConfig
from ft_core.monitor import Monitor, MonitorConfig
from ft_core.physics import PhysicsPlant
from ft_sim.closed_loop import DRIVERS, GOAL_PERIOD, NOISE, ClosedLoop
from models import panda_from_rest

#: s of healthy goals before the lock (the monitor identifies the plant meanwhile).
HEALTHY = 4.0
#: rad/s; the joint locks at the first moment after HEALTHY that it moves this fast and
#: is commanded as fast (a lock shows only while its joint is commanded: a joint that
#: overshoots briefly as the others ramp up, then is hardly commanded, is not the case
#: this test is about; docs/monitor.md "Locks the monitor cannot see").
LOCK_SPEED = 0.1


CASES = [(task, joint, driver) for task, joints in (("position", range(6)), ("pose", range(7)))
         for joint in joints for driver in DRIVERS]


@pytest.mark.parametrize(("task", "joint", "driver"), CASES)
def test_a_lock_on_a_physics_plant_is_named_within_a_second(task: str, joint: int,
                                                            driver: str) -> None:
    loop = ClosedLoop(task, DRIVERS[driver])
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


def _slowing(loop: ClosedLoop, joint: int) -> bool:
    """Run until `joint`'s command decays through (0.03, 0.12) rad/s; whether it did.

    The arm slows into its goal: the joint is commanded ever less, and a lock from here
    on is commanded too slowly for the window's test (docs/detection.md, "Slowly
    commanded joints").
    """
    last = abs(loop.sent[joint])
    for _ in range(round(2 * GOAL_PERIOD / loop.dt)):
        loop.run(loop.dt)
        now = abs(loop.sent[joint])
        if 0.03 < now < 0.12 and now < last - 1e-4 and abs(loop.plant.qd[joint]) > 0.03:
            return True
        last = now
    return False


@pytest.mark.parametrize("joint", [0, 2, 3])
def test_a_lock_as_the_arm_slows_into_its_goal_is_named_within_0_8_s(joint: int) -> None:
    """A lock leaves the joint commanded slowly, to and fro; the slow span sees it held.

    Behind the slow driver, with 1 mrad of noise, the commands are a few hundredths of a
    rad/s. The window alone named these after 0.86 to 1.54 s, once the next goal moved
    them.
    """
    loop = ClosedLoop("position", DRIVERS["slow"], seed=1)
    loop.run(HEALTHY)
    assert _slowing(loop, joint), f"joint {joint} never slows into a goal"
    assert loop.declared == [], "declared in healthy motion"
    locked_at = loop.t
    loop.plant.lock(joint)
    loop.run(2.0, stop=lambda: bool(loop.declared))
    name = loop.robot.joint_names[joint]
    assert loop.declared, f"{name} not found within 2 s"
    when, names = loop.declared[0]
    assert names == [name], f"{names} declared instead of {name}"
    assert when - locked_at <= 0.8


def _open_loop(q: np.ndarray, command_at: Callable[[float], np.ndarray], until: float,
               seed: int = 3, lock: tuple[int, float] | None = None,
               silent: set[int] | None = None, efforts: bool = True) -> tuple[list, list]:
    """The monitor between fixed commands and the physics plant behind the slow driver.

    From `q` (rad), the plant is sent `command_at(t)` (rad/s) through the monitor every
    4 ms until `until` (s); `lock` (joint, s): that joint's brake engages then. Returns
    the declarations [(t, line)] and the plant's velocities [(t, qd)]; `silent` collects
    the joints whose drives the monitor found silent (`detection.drives`). Without
    `efforts` the monitor is not given the drives' torques.
    """
    robot = robots.load("panda_inertial", tip_link="panda_link8")
    monitor = Monitor(robot, DetectorConfig(), MonitorConfig(), None)
    plant = PhysicsPlant(robot, q.copy(), DRIVERS["slow"])
    rng = np.random.default_rng(seed)
    events, velocities, t, dt = [], [], 0.0, 0.004
    while t < until:
        if lock is not None and abs(t - lock[1]) < dt / 2:
            plant.lock(lock[0])
        change = monitor.observe(plant.q + rng.normal(0.0, NOISE, robot.n), t,
                                 effort=plant.torque if efforts else None)
        events += [(t, line) for line in change.events]
        if silent is not None:
            silent.update(np.flatnonzero(monitor._drives.silent).tolist())
        plant.command(t, monitor.command(command_at(t), t))
        t += dt
        plant.step(t)
        velocities.append((t, plant.qd.copy()))
    monitor.close()
    return events, velocities


def _decelerating(joint: int, fast: float, lock_at: float | None = None) -> tuple[list, float]:
    """The monitor's declarations while `joint` runs at `fast` rad/s, then at 0.1.

    Behind the slow driver (50 ms latency, a 50 ms critically damped servo): joints 1
    and 2 move at 0.3 and 0.6 rad/s throughout; `joint` moves at 0.3 rad/s from rest,
    at `fast` from 0.8 s, and at 0.1 from 1.5 s (the monitor's smoother decelerates it at
    the Panda's acceleration limit), towards the middle of its range. `lock_at` (s):
    its brake engages then. Returns [(t, line)] and when the brake engaged.
    """
    panda = robots.load("panda_inertial", tip_link="panda_link8")
    q = panda.home()
    along = 1.0 if q[joint] < 0.5 * (panda.lower[joint] + panda.upper[joint]) else -1.0

    def command_at(t: float) -> np.ndarray:
        command = np.zeros(panda.n)
        command[[0, 1]] = [0.3, 0.6]
        command[joint] = along * (0.3 if t < 0.8 else fast if t < 1.5 else 0.1)
        return command

    events, _ = _open_loop(q, command_at, 3.0,
                           lock=None if lock_at is None else (joint, lock_at))
    return events, math.nan if lock_at is None else lock_at


def _from_the_start(lock_at: float | None) -> list:
    """Declarations as the arm starts from rest, efforts unreported, joint 1 locked at `lock_at` s.

    The command is `models.panda_from_rest`.
    """
    panda = robots.load("panda_inertial", tip_link="panda_link8")
    events, _ = _open_loop(panda.home(), panda_from_rest, 2.0, efforts=False,
                           lock=None if lock_at is None else (0, lock_at))
    return events


def test_a_lock_from_the_first_command_is_named_while_the_others_follow() -> None:
    """The plant counts as seen following while joints follow and no plant fault shows.

    Before any decision the detector waits for the plant to follow its commands for
    `detection.follow_time`. Joint 1 braked from the first command stalls throughout,
    so with the others following it is a lock candidate, not a stopped plant: named
    locked within 1 s of the start (the window, the settling after commands begin, the
    following time), and nothing else. Healthy: nothing.
    """
    events = _from_the_start(0.0)
    assert events, "the lock was not named"
    assert [line.split()[1] for _, line in events] == ["panda_joint1"]
    assert "locked" in events[0][1]
    assert events[0][0] <= 1.0
    assert _from_the_start(None) == []


@pytest.mark.parametrize(("joint", "fast"), [(3, 1.5), (5, 1.5), (5, 2.0)])
def test_a_healthy_joint_decelerating_hard_is_not_declared(joint: int, fast: float) -> None:
    """After the drop to 0.1 rad/s the servo runs short of it for 0.2-0.3 s, even backwards.

    Its position first ran ahead of the detector's model (latency 10 ms longer than the
    plant's) by that error times the speed; back at 0.1 rad/s it reads as lost unless the
    model's latency error times the change of command is allowed for.
    """
    events, _ = _decelerating(joint, fast)
    assert events == []


def test_a_lock_after_a_hard_deceleration_is_named() -> None:
    events, locked_at = _decelerating(5, 1.5, lock_at=1.8)
    assert events, "the lock was not named"
    when, line = events[0]
    assert line.startswith("joint panda_joint6 locked")
    assert 0.0 < when - locked_at <= 0.25  # a lock named within 250 ms


def _reversing(seed: int, lock_at: float | None = None) -> tuple[list, float]:
    """The monitor's declarations while joints 2 and 5 reverse hard and joint 1 crawls.

    Behind the slow driver, from a deployed run's configuration: joint 1 at 0.15 rad/s,
    joint 4 at 0.3, joints 2 and 5 at 1.5 and 2.0 rad/s until 1 s, then as fast the other
    way (the monitor's smoother reverses them at the Panda's acceleration limits). Their
    coupling loads joint 1, whose servo gives the torque late: it falls under a third of
    its command for about 0.2 s. `lock_at` (s): joint 1's brake engages then. Returns
    [(t, line)] and the least velocity of joint 1 after the reversal (rad/s).
    """

    def command_at(t: float) -> np.ndarray:
        fast = 1.0 if t < 1.0 else -1.0
        return np.array([0.15, 1.5 * fast, 0.0, 0.3, 2.0 * fast, 0.0, 0.0])

    events, velocities = _open_loop(np.array([-1.75, -0.6, 1.89, -2.3, -1.6, 0.85, 0.78]),
                                    command_at, 2.0, seed,
                                    None if lock_at is None else (0, lock_at))
    return events, min(qd[0] for t, qd in velocities if 1.0 < t < 1.5)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_healthy_joint_slowed_by_the_others_reversing_is_not_declared(seed: int) -> None:
    """The coupling stall of joint 1 (`drives.Drives.moved_by_others`): no lock."""
    events, slowest = _reversing(seed)
    assert slowest < 0.05  # the stall happened
    assert events == []


@pytest.mark.parametrize("lock_at", [1.05, 1.1, 1.2])
def test_a_lock_while_the_others_reverse_is_named(lock_at: float) -> None:
    """A brake on joint 1 during the reversal leaves a residual: named within 250 ms."""
    events, _ = _reversing(3, lock_at)
    assert events, "the lock was not named"
    assert len(events) == 1, events
    when, line = events[0]
    assert line.startswith("joint panda_joint1 locked")
    assert 0.0 < when - lock_at <= 0.25


def _alternating(joint: int, lock_at: float | None) -> list:
    """The declarations while `joint` is commanded 0.3 rad/s each way every 0.2 s.

    Joints 1 and 6 move steadily (witnesses); `lock_at` (s): `joint`'s brake engages then.
    """
    panda = robots.load("panda_inertial", tip_link="panda_link8")

    def command_at(t: float) -> np.ndarray:
        command = np.zeros(panda.n)
        command[[0, 5]] = [0.2, 0.3]
        command[joint] = 0.3 if int(t / 0.2) % 2 == 0 else -0.3
        return command

    return _open_loop(panda.home(), command_at, 2.5 if lock_at is None else lock_at + 1.0,
                      lock=None if lock_at is None else (joint, lock_at))[0]


@pytest.mark.parametrize("joint", [1, 3])
def test_a_healthy_joint_under_commands_reversing_within_the_lags_is_not_declared(
        joint: int) -> None:
    assert _alternating(joint, None) == []


@pytest.mark.parametrize(("joint", "lock_at"), [(1, 1.0), (3, 1.1), (3, 1.25)])
def test_a_lock_under_commands_reversing_within_the_lags_is_named_by_its_push(
        joint: int, lock_at: float) -> None:
    """The brake's push names it within 250 ms, held still while commanded.

    No plausible prediction agrees on a direction, so the velocity test cannot judge.
    """
    panda = robots.load("panda_inertial", tip_link="panda_link8")
    events = _alternating(joint, lock_at)
    assert events, "the lock was not named"
    when, line = events[0]
    assert line.startswith(f"joint {panda.joint_names[joint]} locked")
    assert "held still while commanded" in line
    assert 0.0 < when - lock_at <= 0.25
    assert len(events) == 1, events


def test_a_healthy_drive_silent_while_its_command_accelerates_downhill_is_not_named() -> None:
    """Joint 2 commanded downhill at gravity's own acceleration g/M (2.6 rad/s^2 at home).

    Its drive then gives about no torque, which `detection.drives` calls silent; the
    joint follows its command all the while, so it is not named.
    """
    panda = robots.load("panda_inertial", tip_link="panda_link8")
    q = panda.home()
    inertia, _ = panda.dynamics(q, np.zeros(panda.n))
    falls = np.sign(-panda.gravity(q)[1])  # gravity turns the shoulder this way
    rate = abs(panda.gravity(q)[1]) / inertia[1, 1]  # rad/s^2

    def command_at(t: float) -> np.ndarray:
        command = np.zeros(panda.n)
        command[0] = 0.2
        command[1] = falls * rate * min(max(t - 0.6, 0.0), 0.3, max(1.2 - t, 0.0))
        return command

    silent: set[int] = set()
    events, _ = _open_loop(q, command_at, 2.0, silent=silent)
    assert 1 in silent, "joint 2's drive was never silent: the case is gone"
    assert events == []
