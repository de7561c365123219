"""Each joint's health: degraded joints, states that never flap, the ft/joint_health message.

A joint that follows a fraction of its command is degraded (`ft_core.detection.follow`);
a declared state only gets worse until reset (`ft_core.health.HealthBoard`); the monitor
keeps a joint in its locked set once declared; `ft_msgs_py.health` writes and reads the
latched topic.
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from ft_core import robots
from ft_core.detection import DetectorConfig, LockDetector
from ft_core.detection.follow import (
    DEGRADED_SHARE,
    MIN_MOTION,
    PERSISTENCE,
    RESISTED_SHARE,
    FollowMeter,
)
from ft_core.health import Health, HealthBoard, JointCondition, JointHealth
from ft_core.monitor import Monitor, MonitorConfig
from ft_core.plant import PlantConfig
from ft_msgs_py import health
from ft_msgs_py.messages import MessageError
from paths import REPO

sys.path.insert(0, str(REPO / "bench"))
from detection import GRID, PANDA, record  # the benchmark's recorder


def moving_targets(t: float) -> np.ndarray:
    """Each joint oscillating about the start, as a controller tracking goals moves them."""
    return 0.3 * 2 * np.pi * 0.3 * np.cos(2 * np.pi * 0.3 * t + np.arange(7))


def slowed(data, joint: int, share: float, start: float = 4.0):
    """The recording with `joint` making only `share` of its motion from `start` on."""
    origin = None
    for kind, t, values in data.events:
        if kind == "measure" and t >= start:
            origin = values[joint] if origin is None else origin
            values[joint] = origin + share * (values[joint] - origin)
    return data


def replay(data, detector: LockDetector) -> list[tuple[float, str, int]]:
    """(time, 'locked' / 'degraded' / 'swinging', joint) for every declaration."""
    out = []
    for kind, t, values in data.events:
        if kind == "command":
            detector.command(t, values)
            continue
        update = detector.measure(t, values)
        out += [(t, "locked", j) for j in update.locked]
        out += [(t, "degraded", j) for j in update.degraded]
        out += [(t, "swinging", j) for j in update.swinging]
    return out


def test_the_share_of_a_joint_that_follows_is_about_one_and_says_nothing_when_idle() -> None:
    meter = FollowMeter(3)
    assert np.isnan(meter.shares).all()  # nothing commanded yet
    for k in range(200):  # joint 0 follows, joint 1 makes 40 %, joint 2 is never commanded
        degraded = meter.update(0.005 * k, 0.005, np.array([0.2, 0.08, 0.0]),
                                np.array([0.2, 0.2, 0.0]), np.array([True, True, False]))
    shares = meter.shares
    assert shares[0] == pytest.approx(1.0) and shares[1] == pytest.approx(0.4)
    assert math.isnan(shares[2])
    assert degraded == [1]
    meter.reset()
    assert np.isnan(meter.shares).all()


def test_a_share_below_half_must_last_before_a_joint_is_degraded() -> None:
    meter = FollowMeter(1)
    dt, found = 0.0025, None
    for k in range(400):
        judged = np.array([True])
        slow = k * dt >= 0.5  # from 0.5 s on, it makes 20 % of its command
        if meter.update(k * dt, dt, np.array([0.04 if slow else 0.2]), np.array([0.2]),
                        judged) and found is None:
            found = k * dt
    assert found is not None, "never degraded"
    assert meter.commanded[0] >= MIN_MOTION
    # The share falls below DEGRADED_SHARE within about a memory, then PERSISTENCE holds.
    assert 0.5 + PERSISTENCE < found < 1.5, found
    assert meter.shares[0] < DEGRADED_SHARE


def test_a_resisted_joint_is_degraded_below_a_higher_share() -> None:
    """Making 60 % of its command: degraded only while something resists it hard."""
    for resisted in (False, True):
        meter, found = FollowMeter(1), None
        for k in range(400):
            if meter.update(k * 0.0025, 0.0025, np.array([0.12]), np.array([0.2]),
                            np.array([True]), np.array([resisted])) and found is None:
                found = k * 0.0025
        assert meter.shares[0] == pytest.approx(0.6)
        assert DEGRADED_SHARE < meter.shares[0] < RESISTED_SHARE
        assert (found is not None) == resisted, found


@pytest.mark.parametrize(("latency", "response"), GRID[::3])
def test_healthy_plants_declare_no_joint_degraded(latency: float, response: float) -> None:
    data = record(moving_targets, 8.0, PlantConfig(latency=latency, response_time=response))
    detector = LockDetector(PANDA.lower, PANDA.upper)
    assert replay(data, detector) == []
    shares = detector.follow.shares
    assert np.nanmin(shares) > 0.9 and np.nanmax(shares) == 1.0, shares


@pytest.mark.parametrize("share", [0.3, 0.4])
def test_a_joint_making_a_fraction_of_its_command_is_named_degraded_within_a_second(
        share: float) -> None:
    """Joint 4 makes `share` of its commanded motion from 4 s on (a drive with friction)."""
    data = slowed(record(moving_targets, 8.0, PlantConfig(latency=0.03, response_time=0.03)),
                  3, share)
    declared = replay(data, LockDetector(PANDA.lower, PANDA.upper))
    assert declared, "nothing declared"
    when, kind, joint = declared[0]
    assert (kind, joint) == ("degraded", 3), declared
    assert when - 4.0 <= 1.5, when


def test_a_state_only_gets_worse_until_reset() -> None:
    board = HealthBoard(2)
    assert board.declare(0, Health.DEGRADED, 1.0, "slow")
    assert board.declare(0, Health.LOCKED, 2.0, "stuck")
    assert not board.declare(0, Health.DEGRADED, 3.0, "slow again")  # never better
    assert not board.declare(0, Health.LOCKED, 4.0, "stuck again")
    assert board.states == [Health.LOCKED, Health.HEALTHY]
    assert (board.since[0], board.evidence[0]) == (2.0, "stuck")
    assert board.declare(1, Health.FREE_SWINGING, 5.0, "falls", braked=True)
    assert board.of(Health.FREE_SWINGING) == [1] and board.braked == [False, True]
    h = board.health(1, 0.2, math.nan, -1.0, 1.0)
    assert (h.state, h.braked, h.usable, h.follows) == (Health.FREE_SWINGING, True, False, 0.2)
    board.reset()
    assert board.states == [Health.HEALTHY] * 2 and board.braked == [False] * 2
    assert Health.worst(Health.DEGRADED, Health.LOCKED) == Health.LOCKED


def test_a_locked_joint_that_moves_on_its_own_stays_locked_and_is_free_swinging() -> None:
    """Joint 3, declared locked, then swings: reported free-swinging, kept in the set.

    Without the brake the detector takes its lock back; the monitor locks it again where
    it is (the set only grows until reset), and its health is free-swinging for good.
    """
    plant = PlantConfig(latency=0.02, response_time=0.03)
    data = record(moving_targets, 5.0, plant)
    for kind, t, values in data.events:
        if kind == "measure" and t >= 4.0:
            values[2] += 0.3 * (1 - np.cos(np.pi * (t - 4.0)))
    robot = robots.load("panda")
    monitor = Monitor(robot, DetectorConfig(), MonitorConfig(brake_free_swinging=False), None)
    monitor.declare([2], 0.0)
    sets = []
    for kind, t, values in data.events:
        if kind == "command":
            monitor.detector.command(t, values)  # as recorded: the joint still commanded
            continue
        change = monitor.observe(values, t)
        if change.changed:
            sets.append(sorted(monitor.locked))
    assert monitor.detector.swinging == {}  # locked again
    assert list(monitor.locked) == ["panda_joint3"]
    assert all(s == ["panda_joint3"] for s in sets), sets
    assert monitor.swinging == ["panda_joint3"]
    states = monitor.health()
    assert states["panda_joint3"].state == Health.FREE_SWINGING
    assert states["panda_joint3"].braked
    assert monitor.joint_report(2).state == JointCondition.FREE_SWINGING
    assert {s.state for name, s in states.items() if name != "panda_joint3"} == {Health.HEALTHY}
    monitor.reset(6.0)
    assert monitor.health()["panda_joint3"].state == Health.HEALTHY
    assert monitor.swinging == [] and monitor.locked == {}


def test_the_monitor_brakes_free_swinging_joints_by_default() -> None:
    assert MonitorConfig().brake_free_swinging


def test_the_joint_health_message_round_trips_and_refuses_garbage() -> None:
    joints = {"a": JointHealth(Health.DEGRADED, 0.4, math.nan, -1.0, 2.0, 3.5, False, "slow"),
              "b": JointHealth(Health.FREE_SWINGING, braked=True)}
    msg = health.message(joints, Time(sec=3), "panda")
    assert [s.name for s in msg.status] == ["a", "b"]
    assert [s.message for s in msg.status] == ["degraded", "free-swinging"]
    assert msg.status[0].hardware_id == "panda" and msg.header.stamp.sec == 3
    read, unknown = health.read(msg, ["a", "b", "c"])
    assert unknown == []
    b = read["b"]
    assert (b.state, b.braked, b.usable_lower, b.usable_upper) == (
        Health.FREE_SWINGING, True, -math.inf, math.inf)
    assert math.isnan(b.follows) and math.isnan(b.since)
    a = read["a"]
    assert (a.state, a.follows, a.usable_lower, a.usable_upper, a.since, a.evidence) == (
        Health.DEGRADED, 0.4, -1.0, 2.0, 3.5, "slow")
    assert math.isnan(a.torque_margin)
    read, unknown = health.read(msg, ["a"])
    assert list(read) == ["a"] and unknown == ["b"]
    for field, value, error in (("message", "sick", "unknown state"),
                                ("name", "a", "twice")):
        bad = health.message(joints, Time(), "panda")
        setattr(bad.status[1], field, value)
        with pytest.raises(MessageError, match=error):
            health.read(bad, ["a", "b"])
    bad = health.message(joints, Time(), "panda")
    bad.status[0].values[0].value = "lots"
    with pytest.raises(MessageError, match="not a number"):
        health.read(bad, ["a", "b"])
    bad = health.message({"a": JointHealth(usable_lower=1.0, usable_upper=0.0)}, Time())
    with pytest.raises(MessageError, match="usable range"):
        health.read(bad, ["a"])
    bad.status = bad.status * 2000
    with pytest.raises(MessageError, match="statuses"):
        health.read(bad, ["a"])


def test_the_torque_margin_is_what_the_largest_recent_effort_leaves_of_the_limit() -> None:
    board = HealthBoard(2)
    assert math.isnan(board.torque_margin(0, 87.0))  # no efforts reported
    board.effort(0.0, np.array([43.5, -10.0]))
    board.effort(0.001, np.array([5.0, -2.0]))  # the peak counts for a while
    assert board.torque_margin(0, 87.0) == pytest.approx(0.5, abs=0.01)
    assert board.torque_margin(1, 87.0) == pytest.approx(1 - 10 / 87, abs=0.01)
    assert math.isnan(board.torque_margin(0, math.inf))  # the URDF gives no limit
    board.effort(10.0, np.array([5.0, 100.0]))  # forgotten after several seconds; saturated
    assert board.torque_margin(0, 87.0) == pytest.approx(1 - 5 / 87, abs=0.01)
    assert board.torque_margin(1, 87.0) == 0.0


def test_the_urdf_effort_limits_are_read() -> None:
    panda = robots.load("panda")
    assert panda.effort_limits.tolist() == [87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0]
    planar = robots.load("planar3r")
    assert planar.effort_limits.shape == (3,)
