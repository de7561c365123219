"""Issue 30: the recovery after a lock (ft_core.recovery), without ROS.

A velocity-level controller stalls short of goals the locked arm can still reach; the
recovery plans an IK solution with the locked joints pinned and a joint path to it. The
stalled case below is one of `bench/recovery.py`'s kind: the controller from a random
configuration with a random joint locked, towards a random goal that stays reachable with
it pinned.
"""

from __future__ import annotations

import sys
from concurrent.futures import Future

import numpy as np
import pytest
from ft_core import limits, measures, recovery, robots, selfmotion
from ft_core.plant import PlantConfig
from ft_core.recovery import RecoveryConfig, StallWatch
from paths import REPO

sys.path.insert(0, str(REPO / "bench"))
from recovery import REACHED, closed_loop  # the benchmark's loop

PANDA = robots.load("panda", task_space="position")
#: A stall of the position task with panda_joint3 locked (see the module docstring).
START = np.array([-0.628, 1.376, -1.581, -1.201, -2.41, 3.122, 1.664])
LOCKED = 2
GOAL = np.array([-0.5849, -0.2168, 0.5689])
#: A stall with panda_joint3 locked and the controller told (`bench/recovery.py`'s seed 10).
STALL_START = np.array([2.642, -1.031, 1.903, -2.624, 0.074, 0.495, 1.095])
STALL_GOAL = np.array([0.3801, 0.524, 0.5394])


def test_a_stall_is_an_error_that_stops_improving() -> None:
    watch = StallWatch(RecoveryConfig(stall_time=1.0, progress=0.01, near=0.003))
    assert not watch.update(0.0, 0.5, False)
    assert not watch.update(0.9, 0.3, False)  # progress: the clock restarts at 0.9
    assert not watch.update(1.8, 0.295, False)  # less than `progress`: no restart
    assert watch.update(1.95, 0.295, False)  # 1.05 s without progress
    assert not watch.update(2.0, 0.1, True)  # reached: never a stall
    assert not watch.update(2.5, 0.1, False)
    assert watch.update(3.6, 0.1, False)


def test_near_the_goal_slow_convergence_and_noise_are_no_stall() -> None:
    watch = StallWatch(RecoveryConfig(stall_time=1.0, progress=0.001, near=0.003))
    # 8 mm halving every 0.9 s: each drop is less than `progress` but a quarter of the error.
    t, error = 0.0, 0.008
    while error >= 0.003:
        assert not watch.update(t, error, False)
        t, error = t + 0.9, error / 2
    watch.reset(t)
    for k in range(2000):  # 1 mm/s in 1 um steps: small drops that add up to progress
        assert not watch.update(t + 0.001 * k, 0.3 - 1e-6 * k, False)
    t += 2.0
    for k in range(300):  # at 2 mm of noise-level error for 3 s: never a stall
        assert not watch.update(t + 0.01 * k, 0.002 + 0.001 * (k % 2), False)


def test_creeping_while_pressed_against_a_limit_is_a_stall() -> None:
    """Seed 48 of the campaign: joint 3 at its limit, the error falling 1 cm/s from 0.35 m.

    Each 10 ms step is progress by the first rule (2 mm in a second add up), so only the
    pressed rule declares the stall, one `stall_time` after the pressing starts.
    """
    config = RecoveryConfig()
    free, held = StallWatch(config), StallWatch(config)
    stalled_at = None
    for k in range(1000):  # 10 s
        t, error = 0.01 * k, 0.35 - 0.0001 * k
        assert not free.update(t, error, False)
        if held.update(t, error, False, pressed=True) and stalled_at is None:
            stalled_at = t
    assert stalled_at is not None, "the creep was never declared a stall"
    assert stalled_at == pytest.approx(config.stall_time, abs=0.02)


def test_a_fast_or_converging_arm_pressed_against_a_limit_is_no_stall() -> None:
    watch = StallWatch(RecoveryConfig())
    for k in range(500):  # 0.2 m/s on a long move, a joint at its limit all along
        assert not watch.update(0.01 * k, 0.9 - 0.002 * k, False, pressed=True)
    watch.reset(5.0)
    t, error = 5.0, 0.04
    while error >= 0.003:  # the final approach, halving every 0.5 s
        assert not watch.update(t, error, False, pressed=True)
        t, error = t + 0.01, error * 0.5 ** (0.01 / 0.5)


def test_pressed_is_a_healthy_joint_at_a_bound_with_the_task_pushing_out() -> None:
    lower, upper = -np.ones(3), np.ones(3)
    q = np.array([0.0, 0.995, -0.999])
    assert recovery.pressed(q, np.array([0.0, 1.0, 0.0]), (lower, upper), ())
    assert recovery.pressed(q, np.array([0.0, 0.0, -1.0]), (lower, upper), ())
    # Pushed back into the bounds, or not at a bound, or locked: not pressed.
    assert not recovery.pressed(q, np.array([0.0, -1.0, 1.0]), (lower, upper), ())
    assert not recovery.pressed(q, np.array([5.0, 0.0, 0.0]), (lower, upper), ())
    assert not recovery.pressed(q, np.array([0.0, 1.0, 0.0]), (lower, upper), (1,))
    assert not recovery.pressed(q - [0, 0.02, 0], np.array([0.0, 1.0, 0.0]), (lower, upper), ())


def test_a_plan_reaches_the_goal_with_the_locked_joint_pinned_on_a_straight_line() -> None:
    lower, upper = PANDA.lower, PANDA.upper
    velocity = 0.5 * PANDA.velocity_limits
    config = RecoveryConfig()
    plan = recovery.plan(PANDA, GOAL, START, (LOCKED,), lower, upper, velocity, 0.004, config)
    assert plan is not None, "no plan for a goal reachable with the joint pinned"
    assert np.linalg.norm(PANDA.task_error(GOAL, plan.solution)) < 1e-4
    assert plan.solution[LOCKED] == START[LOCKED]
    assert np.all(plan.positions[:, LOCKED] == START[LOCKED])
    assert np.all(plan.positions >= lower - 1e-9) and np.all(plan.positions <= upper + 1e-9)
    # From rest at the start to rest at the solution, along the line between them.
    assert np.allclose(plan.positions[0], START) and np.allclose(plan.positions[-1],
                                                                 plan.solution)
    assert np.allclose(plan.velocities[[0, -1]], 0.0, atol=1e-9)
    share = (plan.positions - START) / np.where(plan.solution != START,
                                                plan.solution - START, 1.0)
    moving = plan.solution != START
    assert np.allclose(share[:, moving], share[:, moving][:, :1], atol=1e-6)
    # Within the velocity and acceleration limits (finite differences of the samples).
    assert np.all(np.abs(plan.velocities) <= velocity * (1 + 1e-6))
    dt = np.diff(plan.times)[:-1]
    acceleration = np.diff(plan.velocities[:-1], axis=0) / dt[:, None]
    assert np.abs(acceleration).max() <= config.acceleration * 1.05
    # Of the solutions found, the chosen keeps at least half the best kfm.
    found = recovery.solutions(PANDA, GOAL, START, (LOCKED,), lower, upper, config.attempts)
    best = max(measures.kfm(PANDA.scale_task(PANDA.jacobian(s)), (LOCKED,)) for s in found)
    assert plan.solutions == len(found) > 1 and plan.kfm >= 0.5 * best


def test_the_goals_traced_configurations_seed_the_pinned_inverse_kinematics() -> None:
    """The traced component's configurations nearest in the locked joint are tried first.

    Lewis & Maciejewski 1997 sec. III: a lock inside the box leaves a configuration of the
    traced component with the locked joint at its value. From random configurations with
    a joint locked inside the box, two starts (the configuration itself, then one more)
    find a solution every time with the trace; with a random second start, not every time.
    """
    goal = GOAL
    manifold = selfmotion.trace(PANDA, goal, selfmotion.find_seed(PANDA, goal, START))
    lower, upper = manifold.box
    rng = np.random.default_rng(7)
    with_trace = without = 0
    for trial in range(20):
        joint = int(rng.integers(7))
        q = rng.uniform(np.maximum(PANDA.lower, -3), np.minimum(PANDA.upper, 3))
        q[joint] = rng.uniform(lower[joint], upper[joint])
        args = (PANDA, goal, q, [joint], PANDA.lower, PANDA.upper, 2, trial)
        found = recovery.solutions(*args, traced=manifold.samples)
        with_trace += bool(found)
        without += bool(recovery.solutions(*args))
        for solution in found:
            assert np.linalg.norm(PANDA.forward(solution) - goal) < 1e-6
            assert solution[joint] == pytest.approx(q[joint], abs=1e-12)
    assert with_trace == 20
    assert without < 20


def test_a_goal_out_of_reach_gives_no_plan() -> None:
    plan = recovery.plan(PANDA, np.array([3.0, 0.0, 0.5]), START, (LOCKED,), PANDA.lower,
                         PANDA.upper, PANDA.velocity_limits, 0.004, RecoveryConfig(attempts=5))
    assert plan is None


def test_after_a_lock_the_controller_goes_round_a_stall() -> None:
    """On an instant plant; the plan is waited for with the simulated clock held."""
    without = closed_loop(STALL_START, LOCKED, STALL_GOAL, False, 12.0, PlantConfig())
    assert without["error"] > 0.1, "this case no longer stalls without recovery"
    assert without["notes"] == ["off"]
    run = closed_loop(STALL_START, LOCKED, STALL_GOAL, True, 12.0, PlantConfig())
    notes = run["notes"]
    assert any(n.startswith("stalled") for n in notes), notes
    assert any(n.startswith("following") for n in notes), notes
    assert run["error"] < REACHED, (run["error"], notes)
    assert run["locked_travel"] == 0.0


def test_a_stall_with_no_lock_known_plans_with_nothing_pinned() -> None:
    """A lock nobody has seen: the path commands every joint, the locked one too.

    Here no monitor tells the controller, so the path cannot be followed and the two
    plans of the goal are used up; in the closed loop with the monitor (the campaign) the
    locked joint, commanded, stalls and is declared, and the next plan pins it.
    """
    run = closed_loop(START, LOCKED, GOAL, True, 12.0, PlantConfig(), known=False)
    stalls = [n for n in run["notes"] if n.startswith("stalled")]
    assert stalls and all(n.endswith("joints [] pinned") for n in stalls), run["notes"]
    assert any(n.startswith("following") for n in run["notes"]), run["notes"]
    assert run["locked_travel"] == 0.0


def test_the_follower_stays_inside_the_velocity_bounds_and_keeps_locked_joints_still() -> None:
    plan = recovery.plan(PANDA, GOAL, START, (LOCKED,), PANDA.lower, PANDA.upper,
                         0.5 * PANDA.velocity_limits, 0.004, RecoveryConfig())
    assert plan is not None
    lo, hi = limits.velocity_bounds(START, np.zeros(PANDA.n), PANDA.lower, PANDA.upper,
                                    0.1 * PANDA.velocity_limits, np.full(PANDA.n, 0.004),
                                    np.full(PANDA.n, np.inf))
    far = START + 0.3  # far off the path: the correction alone would exceed the bounds
    qd = recovery.follow(plan, plan.duration / 2, far, (LOCKED,), 5.0, lo, hi)
    assert np.all(qd >= lo) and np.all(qd <= hi) and qd[LOCKED] == 0.0
    assert np.any(qd != 0.0)


def _stall(rec: recovery.Recovery, until: float, t: float = 0.0) -> float:
    """Feed `rec` a goal error that never improves, every 10 ms up to `until` s."""
    bounds = (PANDA.lower, PANDA.upper)
    speeds = (-PANDA.velocity_limits, PANDA.velocity_limits)
    while t < until:
        assert rec.step(t, START, GOAL, 0.3, np.zeros(PANDA.n), False, (LOCKED,), bounds,
                        speeds) is None
        t += 0.01
    return t


def test_a_goal_without_an_ik_solution_is_reported_and_not_planned_again() -> None:
    submitted = []

    def submit(*args) -> Future:
        submitted.append(args)
        done: Future = Future()
        done.set_result(None)  # no solution with the joint pinned
        return done

    rec = recovery.Recovery(RecoveryConfig(stall_time=0.5), submit)
    _stall(rec, 3.0)
    assert len(submitted) == 1 and rec.note.startswith("goal not reachable"), rec.note


def test_a_stall_against_a_limit_says_so_in_the_note() -> None:
    rec = recovery.Recovery(RecoveryConfig(), lambda *args: Future())  # a plan never back
    q = START.copy()
    q[0] = PANDA.upper[0]  # joint 1 at its upper limit, the task pushing it further
    descent = np.zeros(PANDA.n)
    descent[0] = 1.0
    bounds, speeds = (PANDA.lower, PANDA.upper), (-PANDA.velocity_limits, PANDA.velocity_limits)
    for k in range(150):  # 1 cm/s from 0.3 m: progress by the 2 mm rule, not when pressed
        rec.step(0.01 * k, q, GOAL, 0.3 - 1e-4 * k, descent, False, (LOCKED,), bounds, speeds)
    assert rec.planning and "(a joint pressed against a limit)" in rec.note, rec.note


def test_a_plan_that_does_not_come_back_in_time_is_given_up_and_tried_again() -> None:
    submitted = []

    def submit(*args) -> Future:
        submitted.append(args)
        return Future()  # never finishes

    config = RecoveryConfig(stall_time=0.5, timeout=1.0, plans_per_goal=2)
    rec = recovery.Recovery(config, submit)
    t = _stall(rec, 1.2)  # stalled at 0.5 s: planning since
    assert len(submitted) == 1 and rec.planning
    t = _stall(rec, 2.5, t)  # given up at 1.5 s, stalled again at 2 s
    assert len(submitted) == 2, "no second plan after the first was given up"
    _stall(rec, 8.0, t)
    assert len(submitted) == 2 and rec.note.startswith("planning took over")
    rec.reset(8.0)  # a new goal: plans may start again
    _stall(rec, 9.0, 8.0)
    assert len(submitted) == 3


@pytest.mark.parametrize("field", ["stall_time", "progress", "timeout", "acceleration", "jerk",
                                   "near"])
def test_invalid_recovery_settings_are_refused(field: str) -> None:
    with pytest.raises(ValueError, match=field):
        RecoveryConfig(**{field: -1.0 if field == "near" else 0.0})


def test_a_pose_out_of_a_locked_six_joint_arms_reach_is_replaced_by_the_nearest_reachable() -> None:
    """The demo's tour after a lock (`ft_sim.scenario.Scenario.keep_reachable`).

    A 6-joint arm's pose task has no redundancy: with joint 2 locked, a pose reached with
    joint 2 elsewhere is out of reach, one reached with it where it locked is not. The
    replacement is reachable and nearer than where the arm stands (here no configuration
    keeps the position: the PUMA's wrist centre moves on a surface with joint 2 locked).
    """
    puma = robots.load("puma560", task_space="pose")
    q = puma.home()
    moved = q.copy()
    moved[1] += 0.3
    moved[0] += 0.2
    same = q.copy()
    same[0] += 0.2
    assert recovery.reachable(puma, puma.forward(same), q, [1], [], 30)
    goal = puma.forward(moved)
    assert not recovery.reachable(puma, goal, q, [1], [moved], 30)
    assert recovery.reachable(puma, goal, moved, [1], [moved], 0)  # seeded: at once
    replacement = recovery.nearest_reachable(puma, goal, q, [1], 30, 2000, 10.0)
    metres, radians = recovery.mismatch(puma, goal, replacement)
    staying = recovery.mismatch(puma, goal, puma.forward(q))
    assert 0 < metres + radians / 10 < staying[0] + staying[1] / 10
    assert metres < 0.1
    assert recovery.reachable(puma, replacement, q, [1], [], 30)
