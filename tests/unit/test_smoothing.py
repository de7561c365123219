"""ft_core.smoothing and ft_core.command_limits: commands a real arm's driver accepts."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from ft_core import robots
from ft_core.command_limits import (
    CommandLimits,
    DriverCheck,
    LimitsConfig,
    Preset,
    Violation,
    command_limits,
    detect_preset,
    limits_config,
)
from ft_core.controller import Controller, ControllerConfig
from ft_core.detection import DetectorConfig
from ft_core.engine import EngineConfig
from ft_core.monitor import Monitor, MonitorConfig
from ft_core.smoothing import Smoother
from hypothesis import given, settings
from hypothesis import strategies as st

PANDA = robots.load("panda", task_space="position")
LIMITS = command_limits(PANDA.name, PANDA.joint_names, PANDA.velocity_limits)
#: Franka's published limits (Robot and interface specifications).
FRANKA_ACCELERATION = [15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]
FRANKA_JERK = [7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0]
Q = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])


def test_the_panda_gets_frankas_published_limits_by_name_in_either_urdf() -> None:
    assert LIMITS.preset is Preset.FRANKA_PANDA
    assert LIMITS.acceleration.tolist() == FRANKA_ACCELERATION
    assert LIMITS.jerk.tolist() == FRANKA_JERK
    np.testing.assert_array_equal(LIMITS.velocity, PANDA.velocity_limits)  # the URDF's
    erd = robots.load(str(Path(robots.__file__).parent / "urdf"
                          / "panda_from_example_robot_data.urdf"))
    assert detect_preset(erd.name, erd.joint_names) is Preset.FRANKA_PANDA


def test_other_arms_get_their_preset_or_the_conservative_default() -> None:
    ur = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
          "wrist_2_joint", "wrist_3_joint")
    assert detect_preset("ur5e", tuple(f"left_{j}" for j in ur)) is Preset.UR
    assert detect_preset("xarm7", tuple(f"joint{i}" for i in range(1, 8))) is Preset.XARM
    iiwa = robots.load("iiwa14")
    assert detect_preset(iiwa.name, iiwa.joint_names) is Preset.DEFAULT
    limits = command_limits(iiwa.name, iiwa.joint_names, iiwa.velocity_limits)
    assert limits.acceleration.tolist() == [5.0] * 7 and limits.jerk.tolist() == [1000.0] * 7
    xarm = command_limits("xarm7", tuple(f"joint{i}" for i in range(1, 8)), np.full(7, 3.14))
    # UFACTORY: 1146 deg/s^2 and 28647 deg/s^3.
    assert xarm.acceleration[0] == pytest.approx(np.radians(1146), rel=1e-3)
    assert xarm.jerk[0] == pytest.approx(np.radians(28647), rel=1e-3)


def test_parameters_override_the_preset_in_command_order_and_bad_values_are_refused() -> None:
    order = np.array([6, 5, 4, 3, 2, 1, 0])  # joints given tip to base
    config = limits_config(True, "auto", [1, 2, 3, 4, 5, 6, 7], [100.0], order)
    assert config == LimitsConfig("auto", (7.0, 6.0, 5.0, 4.0, 3.0, 2.0, 1.0), (100.0,))
    limits = config.build(PANDA.name, PANDA.joint_names, PANDA.velocity_limits)
    assert limits.preset is None and limits.jerk.tolist() == [100.0] * 7
    assert limits_config(False, "auto", (), ()) is None
    for bad in ((0.0,), (np.nan,), (1.0, 2.0)):
        with pytest.raises(ValueError):
            limits_config(True, "auto", bad, (), order)
    with pytest.raises(ValueError, match="unknown limits preset"):
        limits_config(True, "kuka_magic", (), ())
    with pytest.raises(ValueError, match="3 values for 7 joints"):
        command_limits(PANDA.name, PANDA.joint_names, PANDA.velocity_limits, "auto", (1, 2, 3))


def test_the_driver_refuses_a_step_a_jerk_and_a_speed_and_says_which_joint() -> None:
    driver = DriverCheck(LIMITS)
    assert driver.check(np.zeros(7), 0.0) is None
    assert driver.check(np.zeros(7), 0.001) is None
    step = np.zeros(7)
    step[1] = 0.05  # 50 rad/s^2 on joint 2, 6.7 times Franka's 7.5
    refusal = driver.check(step, 0.002)
    assert refusal is not None and refusal.violation is Violation.ACCELERATION
    assert refusal.joint == 1 and refusal.value == pytest.approx(50.0)
    assert "6.67 times" in str(refusal)
    driver = DriverCheck(LIMITS)
    for k, v in enumerate((0.0, 0.0, 0.007)):  # 7 rad/s^2 at once: a jerk of 7000 rad/s^3
        refusal = driver.check(np.array([0, v, 0, 0, 0, 0, 0.0]), 0.001 * k)
    assert refusal is not None and refusal.violation is Violation.JERK and refusal.joint == 1
    fast = PANDA.velocity_limits * 1.01
    refusal = DriverCheck(LIMITS).check(fast, 0.0)
    assert refusal is not None and refusal.violation is Violation.VELOCITY
    driver = DriverCheck(LIMITS)
    driver.check(np.zeros(7), 1.0)
    assert driver.check(np.zeros(7), 1.0) is None  # a repeat
    refusal = driver.check(np.full(7, 1e-3), 1.0)  # another command at the same instant
    assert refusal is not None and refusal.violation is Violation.STAMP
    refusal = driver.check(np.zeros(7), 0.5)  # an earlier stamp
    assert refusal is not None and refusal.violation is Violation.STAMP
    # An exempt joint (locked in the plant) is not tested.
    driver = DriverCheck(LIMITS)
    driver.check(step, 0.0)
    assert driver.check(np.zeros(7), 0.001, exempt=(1,)) is None


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([0.0002, 0.001, 0.004]))
def test_every_command_passes_the_driver_whatever_the_targets_and_the_stamps(
        seed: int, period: float) -> None:
    """Random target jumps, noise, speeds past the limits, uneven stamps, a lock."""
    rng = np.random.default_rng(seed)
    smoother, driver = Smoother(LIMITS), DriverCheck(LIMITS)
    t, target, stopped = 0.0, np.zeros(7), ()
    for k in range(600):
        t += period * rng.choice([0.3, 1.0, 1.0, 2.5, 40.0])
        if rng.random() < 0.05:
            target = rng.uniform(-1.3, 1.3, 7) * PANDA.velocity_limits
        if k == 300:
            stopped = (int(rng.integers(7)),)
        command = smoother.step(target + rng.normal(0, 0.01, 7), t, stopped)
        assert all(command[j] == 0.0 for j in stopped)
        refusal = driver.check(command, t, exempt=stopped)
        assert refusal is None, f"command {k}: {refusal}"
    assert driver.peaks.max() <= 1.0 + 1e-6


def test_a_smooth_target_passes_unchanged_and_a_step_is_reached_in_minimum_time() -> None:
    smoother = Smoother(LIMITS)
    t = np.arange(1, 2001) * 0.001
    slow = 0.2 * np.sin(2 * np.pi * 0.5 * t)[:, None] * np.ones(7)  # 1.3 rad/s^2 at most
    for k, tk in enumerate(t):
        np.testing.assert_array_equal(smoother.step(slow[k], tk), slow[k])
    # A step of 1 rad/s on joint 2: time-optimal = v/A + A/J = 0.1333 + 0.002 s.
    smoother.reset()
    target = np.array([0, 1.0, 0, 0, 0, 0, 0])
    times = np.arange(1, 301) * 0.001
    reached = next(tk for tk in times if smoother.step(target, tk)[1] == 1.0)
    assert reached == pytest.approx(1.0 / 7.5 + 7.5 / 3750, abs=0.0021)


def test_a_joint_profiled_alone_brakes_at_its_own_limit_not_at_the_others_pace() -> None:
    """A stop of joint 1 from 0.2 rad/s beside a change of 2 rad/s of joint 2.

    Phase-synchronised, it lasts as long as joint 2's change; alone, it takes its own
    time-optimal 0.2/15 + 15/7500 s, within the limits either way.
    """
    start, target = np.array([0.2, -1.0, 0, 0, 0, 0, 0]), np.array([0, 1.0, 0, 0, 0, 0, 0])
    times = np.arange(1, 301) * 0.001
    stopped = {}
    for alone in ((), (0,)):
        smoother, driver = Smoother(LIMITS), DriverCheck(LIMITS)
        smoother.reset(start)
        driver.check(start, 0.0)
        commands = [smoother.step(target, t, alone=alone) for t in times]
        assert all(driver.check(c, t) is None for c, t in zip(commands, times, strict=True))
        stopped[alone] = next(t for t, c in zip(times, commands, strict=True)
                              if abs(c[0]) < 1e-9)
        assert commands[-1][1] == 1.0  # joint 2 reaches its target either way
    assert stopped[(0,)] == pytest.approx(0.2 / 15.0 + 15.0 / 7500.0, abs=0.0021)
    assert stopped[()] > 0.2  # with joint 2's 2 rad/s at 7.5 rad/s^2


def test_a_stop_from_full_speed_comes_to_rest_within_its_bound() -> None:
    smoother = Smoother(LIMITS)
    smoother.reset(PANDA.velocity_limits * np.array([1, -1, 1, -1, 1, -1, 1]))
    bound = smoother.stop_time()
    assert bound == pytest.approx(2.175 / 7.5 + 2 * 7.5 / 3750, rel=1e-9)  # joint 2 slowest
    t, driver = 0.0, DriverCheck(LIMITS)
    driver.check(smoother.velocity, t)
    while not smoother.at_rest:
        t += 0.001
        assert driver.check(smoother.step(np.zeros(7), t), t) is None
        assert t <= bound + 0.003  # the profile's end, then up to two commands of zeros
    assert t > 2.175 / 7.5  # not faster than joint 2 may brake


def test_the_controller_core_commands_within_the_limits_and_a_lock_zeroes_at_once() -> None:
    controller = Controller(PANDA, EngineConfig(dt=0.004), ControllerConfig(),
                            ("panda", (None, None, "position")))
    driver = DriverCheck(LIMITS)
    controller.set_pose_goal(PANDA.forward(Q) + np.array([0.2, 0.0, -0.1]), 0.0)
    commands = []
    for k in range(1, 200):
        if k == 100:
            controller.set_locked([3])
        step = controller.step(Q, 0.0, 0.004 * k)
        commands.append(step.qd)
        assert driver.check(step.qd, 0.004 * k, exempt=(3,) if k >= 100 else ()) is None
    commands = np.array(commands)
    assert np.abs(commands[98, 3]) > 0.01 and np.all(commands[99:, 3] == 0.0)
    # Raw, the first command jumps from rest far beyond Franka's limits.
    raw = Controller(PANDA, EngineConfig(dt=0.004), ControllerConfig(limits=None),
                     ("panda", (None, None, "position")))
    raw.set_pose_goal(PANDA.forward(Q) + np.array([0.2, 0.0, -0.1]), 0.0)
    first = raw.step(Q, 0.0, 0.004).qd
    assert np.max(np.abs(first) / 0.004 / LIMITS.acceleration) > 10
    controller.close()
    raw.close()


def test_the_monitor_smooths_its_remap_at_a_lock_and_ramps_its_zeros() -> None:
    monitor = Monitor(PANDA, DetectorConfig(), MonitorConfig(), None)
    monitor.q = Q
    driver = DriverCheck(LIMITS)
    qd = np.array([0.3, -0.2, 0.2, 0.3, -0.1, 0.2, 0.1])
    t = 0.0
    for _ in range(200):  # healthy: the command reached on a ramp, then passed
        t += 0.004
        sent = monitor.command(qd, t)
        assert driver.check(sent, t) is None
    np.testing.assert_array_equal(sent, qd)
    monitor.declare([1], t)
    t += 0.004
    sent = monitor.command(qd, t)
    assert sent[1] == 0.0 and driver.check(sent, t, exempt=(1,)) is None
    for _ in range(100):  # the locked joint is stopped: a driver does not judge it
        t += 0.004
        sent = monitor.command(qd, t)
        assert driver.check(sent, t, exempt=(1,)) is None and sent[1] == 0.0
    assert np.any(sent != qd)  # remapped
    while monitor.stopping:
        t += 0.004
        sent = monitor.zeros(t)
        assert driver.check(sent, t, exempt=(1,)) is None
    assert not np.any(sent) and t > 0.8 + 0.1  # a ramp, not a step


@pytest.mark.parametrize("guard_steps", [10, 200], ids=["mid-ramp", "at-rest"])
def test_the_monitor_takes_over_from_another_nodes_stop_within_the_limits(
        guard_steps: int) -> None:
    """The controller's guard stops the plant while the monitor is away, then hands back.

    The monitor, away for 60 ms, follows the guard's stop ramp (`Monitor.follow`) and,
    30 ms after its last command, commands again: one stream the driver accepts, the
    detector's commands with it. Going on from its own last command instead is refused.
    """
    def run(follow: bool) -> tuple[Monitor, DriverCheck, list]:
        monitor = Monitor(PANDA, DetectorConfig(), MonitorConfig(), None)
        monitor.q = Q
        driver, refusals = DriverCheck(LIMITS), []
        qd = np.array([0.8, -0.6, 0.6, 0.8, -0.5, 0.6, 0.5])
        t = 0.0
        for _ in range(200):
            t += 0.004
            refusals.append(driver.check(monitor.command(qd, t), t))
        guard = Smoother(LIMITS)
        guard.reset(monitor.sent)  # the guard's ramp from the monitor's last echo
        t += 0.06
        for _ in range(guard_steps):
            sent = guard.step(np.zeros(7), t)
            refusals.append(driver.check(sent, t))
            if follow:
                monitor.follow(sent, t)
                np.testing.assert_array_equal(monitor.sent, sent)
            t += 0.004
        t += 0.03
        for _ in range(100):
            refusals.append(driver.check(monitor.command(qd, t), t))
            t += 0.004
        return monitor, driver, [r for r in refusals if r is not None]

    monitor, driver, refusals = run(follow=True)
    assert refusals == [] and driver.peaks.max() <= 1.0 + 1e-6
    assert monitor.detector.history.last_time == pytest.approx(monitor.smoother.time)
    # A guard's command stamped before the monitor's last is not taken over from.
    sent = monitor.sent.copy()
    monitor.follow(np.zeros(7), monitor.smoother.time - 0.001)
    np.testing.assert_array_equal(monitor.sent, sent)
    assert run(follow=False)[2], "going on from its own last command passed the driver"


def test_command_limits_refuse_what_no_arm_has() -> None:
    with pytest.raises(ValueError, match="acceleration limits"):
        CommandLimits(np.ones(2), np.array([1.0, -1.0]), np.ones(2))
    with pytest.raises(ValueError, match="velocity limits"):
        CommandLimits(np.array([1.0, 0.0]), np.ones(2), np.ones(2))
