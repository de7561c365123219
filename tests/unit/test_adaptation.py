"""ft_core.adaptation: the controller adapted to the joints' health, and the task it gives up."""

from __future__ import annotations

import math
import re
from dataclasses import replace

import numpy as np
import pytest
from ft_core import adaptation, measures, robots
from ft_core.adaptation import INFEASIBLE, MIN_FOLLOWS, MIN_SIGMA, Adaptation, derive
from ft_core.command_limits import DriverCheck
from ft_core.controller import Controller, ControllerConfig
from ft_core.engine import EngineConfig, ResolutionEngine
from ft_core.health import Health, JointHealth
from models import PLANAR

PANDA = robots.load("panda", task_space="position")
Q = np.array([0.4, 0.3, -0.5, -1.9, 0.6, 1.4, -0.2])
XD = np.array([0.05, -0.02, 0.03])
DT = 0.004


def degraded(follows: float = math.nan, **fields) -> JointHealth:
    return JointHealth(Health.DEGRADED, follows=follows, **fields)


def core(robot=PANDA, smooth: bool = False) -> Controller:
    config = ControllerConfig() if smooth else ControllerConfig(limits=None)
    return Controller(robot, EngineConfig(dt=DT), config,
                      model_source=(robot.name if robot is PANDA else "planar3r",
                                    (None, None, robot.task_space)))


def test_a_degraded_joint_is_slowed_to_what_it_follows_and_weighted_as_likelier_to_fail() -> None:
    derived = derive(PANDA, {3: degraded(0.4)})
    assert derived.velocity_factors == (1, 1, 1, 0.4, 1, 1, 1)
    assert derived.probabilities == (1, 1, 1, 2.5, 1, 1, 1)  # p_max / follows
    weights = measures.failure_weights(derived.probabilities, PANDA.n)
    assert weights[3] == pytest.approx(2.5 / 8.5) and weights[0] == pytest.approx(1 / 8.5)
    assert derived.pinned == () and derived.hard_lower == ()
    engine = ResolutionEngine(PANDA, derived.apply(EngineConfig()))
    np.testing.assert_allclose(engine.speeds[3], 0.4 * 0.5 * PANDA.velocity_limits[3])
    np.testing.assert_allclose(engine.speeds[2], 0.5 * PANDA.velocity_limits[2])
    # A task far too fast: the degraded joint stays within its lowered limit.
    qd = engine.step(PANDA.kinematics(Q), 100 * XD).qd
    assert abs(qd[3]) <= engine.speeds[3] + 1e-12 and abs(qd[3]) > 0.9 * engine.speeds[3]
    # Configured probabilities: raised to the likeliest joint's, over what it follows.
    configured = derive(PANDA, {3: degraded(0.4)}, (1, 2, 1, 0.5, 1, 1, 1)).probabilities
    assert configured[3] == pytest.approx(2 / 0.4) and configured[1] == 2


def test_the_share_a_degraded_joint_follows_is_bounded() -> None:
    barely = derive(PANDA, {1: degraded(0.01)})
    assert barely.velocity_factors[1] == MIN_FOLLOWS
    assert barely.probabilities[1] == pytest.approx(1 / MIN_FOLLOWS)
    # Not measured yet (a stop found inside its range, say): its speed is left alone, and
    # it is weighted as a joint at the monitor's threshold of half its command.
    unmeasured = derive(PANDA, {1: degraded()})
    assert unmeasured.velocity_factors == () and unmeasured.probabilities[1] == 2.0
    assert derive(PANDA, {1: degraded(0.9)}).probabilities[1] == 2.0
    behind = derive(PANDA, {1: degraded(-0.3)})  # moving against its command
    assert behind.velocity_factors[1] == MIN_FOLLOWS
    assert behind.probabilities[1] == pytest.approx(1 / MIN_FOLLOWS)
    assert derive(PANDA, {1: JointHealth(follows=0.3)}) == adaptation.Derived()  # healthy


def test_the_weight_shifts_the_null_space_motion_away_from_the_degraded_joint() -> None:
    """Minimum jump (Zhao & Li eq 5, w_i of Xie eq 3.3): towards the velocity without it."""
    config = EngineConfig(resolution="min_jump")
    kinematics = PANDA.kinematics(Q)
    before = ResolutionEngine(PANDA, config).step(kinematics, XD).qd
    for joint in range(6):  # joint 7 does not move the Panda's tool point
        engine = ResolutionEngine(PANDA, derive(PANDA, {joint: degraded(0.4)}).apply(config))
        after = engine.step(kinematics, XD).qd
        np.testing.assert_allclose(PANDA.jacobian(Q) @ after, XD, atol=1e-9)  # same task
        assert abs(after[joint]) < 0.9 * abs(before[joint]), joint


def test_a_narrower_usable_range_is_a_hard_limit_the_engine_keeps_after_a_lock() -> None:
    health = {1: JointHealth(usable_lower=0.2, usable_upper=0.45),
              4: degraded(usable_lower=-5.0, usable_upper=0.7)}  # beyond the URDF: clipped
    derived = derive(PANDA, health)
    assert derived.hard_lower[1] == 0.2 and derived.hard_upper[1] == 0.45
    assert derived.hard_lower[4] == PANDA.lower[4] and derived.hard_upper[4] == 0.7
    assert derived.hard_lower[0] == PANDA.lower[0] and derived.hard_upper[0] == PANDA.upper[0]
    engine = ResolutionEngine(PANDA, derived.apply(EngineConfig(dt=DT)))
    for locked in ((), (6,)):  # unlike the soft limits, kept after a lock
        lower, upper = engine.bounds(locked)
        assert lower[1] == 0.2 and upper[1] == 0.45 and upper[4] == 0.7
    # A twist pushing joint 2 up (and on): it stops at 0.45 and the task goes on with the rest.
    q, xd = Q.copy(), np.array([0.0, 0.0, -0.1])
    highest = q[1]
    for _ in range(1000):
        result = engine.step(PANDA.kinematics(q), xd)
        q = q + DT * result.qd
        highest = max(highest, q[1])
    assert highest <= 0.45 + 1e-9 and highest > 0.44
    assert result.at_hard_limit[1]


def test_joints_locked_or_free_swinging_by_health_are_pinned_before_the_locked_set_is() -> None:
    c = core()
    c.set_twist(XD, 0.0)
    c.set_locked([6])
    c.set_health({2: JointHealth(Health.LOCKED), 4: JointHealth(Health.FREE_SWINGING),
                  1: degraded(0.5, braked=True)})
    assert c.pinned == (1, 2, 4, 6) and c.locked == (6,)
    step = c.step(Q, 0.0, 0.0)
    assert not np.any(step.qd[[1, 2, 4, 6]]) and np.any(step.qd)
    np.testing.assert_allclose(PANDA.jacobian(Q) @ step.qd, XD, atol=1e-9)
    c.set_health({})  # the monitor's reset
    assert c.pinned == (6,) and np.all(c.step(Q, 0.0, 0.0).qd[[1, 2, 4]] != 0.0)


def test_health_that_is_not_the_monitors_is_named() -> None:
    assert adaptation.problem(degraded(0.4)) is None
    assert adaptation.problem(JointHealth(torque_margin=0.2)) is None
    assert adaptation.problem(JointHealth(follows=1.2)) is None  # ahead of a slow prediction
    assert adaptation.problem(degraded(-0.1)) is None  # pushed back
    assert "follows" in adaptation.problem(degraded(math.inf))
    assert "torque_margin" in adaptation.problem(JointHealth(torque_margin=-math.inf))
    assert "nan" in adaptation.problem(JointHealth(usable_lower=math.nan))


def test_a_degraded_joints_share_is_its_lowest_reported_in_steps_until_the_reset() -> None:
    """The measured share wanders and lapses (nan) with the motion: the engine does not."""
    a = Adaptation(PANDA)
    assert a.set_health({3: degraded(0.43)})
    assert a.derived.velocity_factors[3] == pytest.approx(0.4)
    for share in (0.47, 0.41, math.nan, 0.6):  # wandering, not measured: nothing changes
        assert not a.set_health({3: degraded(share)}), share
    assert a.set_health({3: degraded(0.33)})  # lower: slowed further
    assert a.derived.velocity_factors[3] == pytest.approx(0.3)
    assert a.derived.probabilities[3] == pytest.approx(1 / 0.3)
    assert a.set_health({3: degraded(0.02)})  # the floor
    assert a.derived.velocity_factors[3] == MIN_FOLLOWS
    assert a.set_health({3: JointHealth(follows=0.9)})  # the reset: healthy
    assert a.derived == adaptation.Derived() and a.note == "none"
    assert a.set_health({3: degraded(0.8)})  # declared again: a fresh share
    assert a.derived.velocity_factors[3] == pytest.approx(0.8)
    assert a.derived.probabilities[3] == 2.0


def _run_to_rest(c: Controller, robot, q: np.ndarray, t: float, cycles: int,
                 check: DriverCheck, twist: np.ndarray | None = None) -> tuple[list, float]:
    """`cycles` steps at `q`, the `twist` target sent again at each (None: as it is)."""
    steps = []
    for _ in range(cycles):
        if twist is not None:
            c.set_twist(twist, t)
        t += DT
        step = c.step(q, 0.0, t)
        assert check.check(step.qd, t, c.pinned) is None, step.qd
        steps.append(step)
    return steps, t


def test_a_planar3r_with_two_joints_locked_gives_up_its_task_to_rest_and_says_so() -> None:
    """One joint left, asked to move the tool across its only direction: given up after 1 s.

    Asked along it, the joint left goes on (the engine's least squares).
    """
    c = core(PLANAR, smooth=True)
    check = DriverCheck(c.smoother.limits)
    q = np.array([0.3, 0.8, -0.6])
    column = PLANAR.jacobian(q)[:, 1]
    across = 0.2 * np.array([-column[1], column[0]]) / np.linalg.norm(column)
    c.set_twist(across, 0.0)
    steps, t = _run_to_rest(c, PLANAR, q, 0.0, 50, check)
    assert np.any(steps[-1].qd) and INFEASIBLE not in steps[-1].problems
    c.set_locked([0, 2], t)
    locked_at = t
    along = 0.2 * column / np.linalg.norm(column)  # it goes on
    steps, t = _run_to_rest(c, PLANAR, q, t, 400, check, along)
    assert all(INFEASIBLE not in s.problems for s in steps) and np.any(steps[-1].qd)
    steps, t = _run_to_rest(c, PLANAR, q, t, 400, check, across)
    given_up = [s for s in steps if s.problems.get(INFEASIBLE)]
    assert given_up, "never given up"
    reason = given_up[0].problems[INFEASIBLE]
    assert "1 joints left (joint2) for the 2 coordinates of the planar task" in reason
    assert "can produce 0% of the task velocity asked" in reason
    first = next(k for k, step in enumerate(steps) if step.problems.get(INFEASIBLE))
    assert 0.9 < first * DT < 1.2, first * DT  # after GIVE_UP_AFTER
    assert all(s.problems[INFEASIBLE] == reason for s in steps[first:])
    assert not np.any(steps[-1].qd) and locked_at < t  # at rest, reached on the ramp
    assert c.smoother.at_rest
    c.set_locked([2], t)  # the monitor's reset of one joint: two left, the task resumes
    c.set_twist(across, t)
    steps, t = _run_to_rest(c, PLANAR, q, t, 50, check)
    assert steps[0].problems[INFEASIBLE] is None
    assert INFEASIBLE not in steps[1].problems and np.any(steps[-1].qd)


def test_a_panda_position_task_with_four_joints_locked_gives_up_where_its_joints_cannot() -> None:
    """Joints 5, 6 and 7 left: joint 7's axis holds the tool point, so two directions are left."""
    c = core(smooth=True)
    check = DriverCheck(c.smoother.limits)
    c.set_pose_goal(PANDA.forward(Q) + np.array([0.05, 0.0, 0.0]), 0.0)
    steps, t = _run_to_rest(c, PANDA, Q, 0.0, 50, check)
    assert np.any(steps[-1].qd)
    c.set_health({j: JointHealth(Health.LOCKED) for j in range(4)}, t)
    steps, t = _run_to_rest(c, PANDA, Q, t, 300, check)
    reason = steps[0].problems[INFEASIBLE]
    assert "3 joints left (panda_joint5, panda_joint6, panda_joint7)" in reason
    assert f"below {MIN_SIGMA:g}" in reason and not np.any(steps[-1].qd)
    assert steps[0].result.sigma_min < MIN_SIGMA
    # Four locked leaving joints the task still has (1, 2, 4 and 6 here): not infeasible.
    c.set_health({j: JointHealth(Health.LOCKED) for j in (2, 4, 6)}, t)
    steps, t = _run_to_rest(c, PANDA, Q, t, 50, check)
    assert steps[0].problems[INFEASIBLE] is None and np.any(steps[-1].qd)


def test_a_singularity_the_joints_left_can_leave_is_not_a_lost_task() -> None:
    """The planar 3R stretched out, its last joint locked: bending the elbow leaves it."""
    a = Adaptation(PLANAR)
    stretched = np.array([0.3, 1e-4, 0.0])
    result = ResolutionEngine(PLANAR).step(PLANAR.kinematics(stretched), np.array([0.1, 0.0]),
                                           [2])
    assert result.sigma_min < MIN_SIGMA  # singular here ...
    assert a.judge(result, (2,), stretched, np.array([0.1, 0.0]), 0.0) == {}  # not around
    lost = replace(result, sigma_min=0.0)  # a lost direction: the rules, by pinned set
    panda, still = Adaptation(PANDA), np.zeros(3)
    assert panda.judge(lost, (), Q, still, 0.0) == {}  # a healthy arm is never given up
    assert panda.judge(lost, (0,), Q, still, 0.0) == {}  # six joints left, one singular point
    assert panda.judge(lost, (0, 1, 2, 3), Q, still, 0.0)[INFEASIBLE].startswith(
        "3 joints left")
    assert panda.judge(replace(lost, sigma_min=1.0), (0, 1, 2, 3), Q, still, 0.0)[
        INFEASIBLE]  # held
    assert panda.judge(lost, (0, 1, 2), Q, still, 0.0) == {INFEASIBLE: None}  # said once
    assert panda.judge(lost, (0, 1, 2), Q, still, 0.0) == {}


@pytest.mark.parametrize(("fields", "reason"), [
    ({"hard_lower": (0.0,) * 7}, "same length"),
    ({"hard_lower": (0.0,) * 6, "hard_upper": (1.0,) * 6}, "7 values each"),
    ({"hard_lower": (math.nan,) * 7, "hard_upper": (1.0,) * 7}, "none nan"),
    ({"hard_lower": (1.0,) * 7, "hard_upper": (0.0,) * 7}, "above its upper"),
    ({"velocity_factors": (1.0,) * 6}, "7 values in (0, 1]"),
    ({"velocity_factors": (0.0,) * 7}, "7 values in (0, 1]"),
    ({"velocity_factors": (1.5,) * 7}, "7 values in (0, 1]"),
])
def test_the_engine_refuses_limits_no_joint_could_have(fields: dict, reason: str) -> None:
    with pytest.raises(ValueError, match=re.escape(reason)):
        ResolutionEngine(PANDA, EngineConfig(**fields))
