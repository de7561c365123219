"""Probability of task failure and the planner of Xie 2019 ch. 4 (`ft_core.offline`).

The chapter's examples are a planar 2R arm of which only the end effector's x is
controlled (sec. 4.4: one degree of redundancy). Its manifolds are written here in
closed form, for unit links: x = cos(q1) + cos(q1 + q2). The chapter prints no
numbers for these examples (only figures 4.15-4.18), so the tests check its closed
forms (eqs 4.3-4.4, 4.13-4.15), Table 4.1, the figures' trajectory shapes, an
exhaustive search and a Monte-Carlo simulation of exponential failures.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from ft_core import robots, selfmotion
from ft_core.offline import planning, reliability
from ft_core.offline.reliability import TaskPoint, Trajectory
from hypothesis import given, settings
from hypothesis import strategies as st


def two_link_x(x: float, samples: int = 801) -> TaskPoint:
    """Self-motion curve of the 2R arm at end-effector x (0 < x < 2), closed."""
    reach = math.acos(x - 1.0)  # |q1| <= reach: cos(q1) >= x - 1
    u = np.linspace(-math.pi / 2, math.pi / 2, samples)
    q1 = reach * np.sin(u)
    elbow = np.arccos(np.clip(x - np.cos(q1), -1.0, 1.0))
    upper = np.stack([q1, elbow - q1], axis=1)
    lower = np.stack([q1[::-1], -elbow[::-1] - q1[::-1]], axis=1)
    return TaskPoint.from_paths([np.vstack([upper, lower[1:]])])


def test_the_closed_form_curves_reach_their_point() -> None:
    point = two_link_x(1.3)
    q = point.samples
    np.testing.assert_allclose(np.cos(q[:, 0]) + np.cos(q[:, 0] + q[:, 1]), 1.3, atol=1e-12)
    assert point.lower[0] == pytest.approx(-math.acos(0.3))
    crossings = point.crossings(0, 0.2)
    assert crossings.shape == (2, 2)  # elbow up and down
    np.testing.assert_allclose(crossings[:, 0], 0.2)
    assert point.crossings(0, 1.5).shape == (0, 2)  # outside the curve's range of q1


def test_table_4_1_failure_scenarios_of_the_nine_regions() -> None:
    points = [two_link_x(1.0), two_link_x(1.5)]
    lower, upper = reliability.remaining_box(points, 0)
    assert np.all(lower < upper)  # the boxes intersect
    centres = [np.array([lower[0] - 0.1, upper[0] + 0.1]), np.array([lower[1] - 0.1,
                                                                       upper[1] + 0.1])]
    table = {}
    for c1 in (centres[0][0], 0.5 * (lower[0] + upper[0]), centres[0][1]):
        for c2 in (centres[1][0], 0.5 * (lower[1] + upper[1]), centres[1][1]):
            q = np.array([c1, c2])
            code = reliability.region(points, 0, q)
            fatal = reliability.fatal_joints(points, 0, q)
            # A / B: joint 1 / 2 fails here; C / D: it fails here and the other one later.
            scenarios = {"A" if fatal[0] else "C", "B" if fatal[1] else "D"}
            table[3 * code[1] + code[0] + 1] = scenarios
    assert len(table) == 9
    for regions, scenarios in (((1, 3, 7, 9), {"A", "B"}), ((2, 8), {"B", "C"}),
                               ((4, 6), {"A", "D"}), ((5,), {"C", "D"})):
        for r in regions:
            assert table[r] == scenarios, r


def p_joint(rate: float, t0: float, t1: float) -> float:
    """Eqs 4.3-4.4 with the intended signs."""
    return math.exp(-rate * t0) - math.exp(-rate * t1)


BOX = (np.array([1.0, 2.0]), np.array([1.5, 3.0]))


@pytest.mark.parametrize(("d1", "d2"), [(0.6, 0.6), (0.9, 0.4), (0.3, 0.8)])
def test_sub_case_3_equal_rotations_then_the_far_joint_eqs_4_13_to_4_15(d1: float,
                                                                          d2: float) -> None:
    rates, v, t0 = np.array([0.03, 0.05]), 0.5, 2.0
    start = np.array([BOX[0][0] - d1, BOX[0][1] - d2])  # region 1: scenarios A and B
    inside = np.array([1.4, 2.9])
    cost, T = planning.leg_cost(start, inside, t0, BOX, rates, v)
    assert T == pytest.approx(max(inside - start) / v)
    # Each joint exposed until it reaches the intersection at full speed: eq 4.13 when
    # d1 = d2 (then P1* = P2*, eq 4.14), else eq 4.15 (and its mirror image).
    expected = p_joint(rates[0], t0, t0 + d1 / v) + p_joint(rates[1], t0, t0 + d2 / v)
    assert cost == pytest.approx(expected, rel=1e-12)
    times, q = planning.leg_waypoints(start, inside, BOX, v)
    near = min(d1, d2) / v  # fig. 4.9: both joints rotate by the nearer distance first
    np.testing.assert_allclose(np.interp(near, times, q[:, 0]) - start[0], min(d1, d2))
    np.testing.assert_allclose(np.interp(near, times, q[:, 1]) - start[1], min(d1, d2))
    np.testing.assert_allclose(q[-1], inside)
    assert np.all(np.abs(np.diff(q, axis=0)) <= v * np.diff(times)[:, None] + 1e-12)
    # The evaluation of sec. 4.2.3 of that same leg (started at 0) gives the same.
    point = TaskPoint.from_paths([np.array(BOX)])  # a "manifold" whose box is BOX
    at_zero, _ = planning.leg_cost(start, inside, 0.0, BOX, rates, v)
    assert reliability.task_failure_probability(
        [point], Trajectory(times, q, (len(times) - 1,)), rates, v,
        second_failures=False) == pytest.approx(float(at_zero), rel=1e-9)


def test_the_first_order_sum_is_clamped_to_a_probability() -> None:
    """Issue 31 item 13: at high rates (here the largest taken) the sum exceeded 1."""
    points = chapter_points(2)
    start = np.array([-1.0, -1.0])
    rates, v = np.array([1.0, 1.0]), 0.5
    best = planning.plan(points, start, rates, v)
    # The sum gave 1.27 here.
    assert reliability.task_failure_probability(points, best.trajectory, rates, v) == 1.0


def test_the_exact_integral_stays_a_probability_and_matches_the_simulation() -> None:
    """Issue 34 item 6: beside the first-order sum, the exact integral of the same pieces.

    At the rates where the sum gave 1.27 it stays below 1 and agrees with the Monte-Carlo
    simulation within 4 standard errors; at low rates both agree to first order.
    """
    points = chapter_points(2)
    start = np.array([-1.0, -1.0])
    v = 0.5
    for rates in (np.array([1.0, 1.0]), np.array([0.3, 0.1])):
        trajectory = planning.plan(points, start, rates, v).trajectory
        exact = reliability.task_failure_probability(points, trajectory, rates, v, exact=True)
        failures, runs = reliability.monte_carlo(points, trajectory, rates, v, 40000,
                                                 np.random.default_rng(5))
        assert 0 < exact < 1
        standard_error = math.sqrt(exact * (1 - exact) / runs)
        assert abs(failures / runs - exact) < 4 * standard_error + 0.005, (failures, exact)
    low = np.array([0.002, 0.003])
    trajectory = planning.plan(points, start, low, v).trajectory
    first_order = reliability.task_failure_probability(points, trajectory, low, v)
    assert reliability.task_failure_probability(points, trajectory, low, v, exact=True) == \
        pytest.approx(first_order, rel=0.05)


def test_sub_case_2_only_the_outside_joint_is_exposed() -> None:
    rates, v = np.array([0.03, 0.05]), 0.5
    start = np.array([BOX[0][0] - 0.7, 2.5])  # region 4: scenario A only
    cost, _ = planning.leg_cost(start, np.array([1.2, 2.2]), 0.0, BOX, rates, v)
    assert cost == pytest.approx(p_joint(rates[0], 0.0, 0.7 / v), rel=1e-12)


def test_a_leg_too_short_to_reach_the_interval_is_exposed_throughout() -> None:
    rates, v = np.array([0.03, 0.05]), 1.0
    start, end = np.array([0.0, 2.5]), np.array([0.2, 2.5])  # joint 1 below, 1.0 away
    cost, T = planning.leg_cost(start, end, 0.0, BOX, rates, v)
    assert T == pytest.approx(0.2)
    assert cost == pytest.approx(p_joint(rates[0], 0.0, 0.2))


def chapter_points(case: int) -> list[TaskPoint]:
    # Case 1 (fig. 4.15): point 1's curve lies in the intersection (box 1 inside box 2).
    # Case 2 (figs 4.16-4.18): the intersection is point 2's box and point 1's curve
    # leaves it.
    return [two_link_x(1.6), two_link_x(1.0)] if case == 1 else \
        [two_link_x(0.3), two_link_x(1.9)]


def test_case_1_the_planned_trajectory_ends_its_exposure_in_the_intersection() -> None:
    points = chapter_points(1)
    lower, upper = reliability.remaining_box(points, 0)
    assert np.all(lower >= points[0].lower - 1e-12) and np.all(upper <= points[0].upper)
    rates, v = np.array([0.01, 0.02]), 0.5
    start = np.array([lower[0] - 0.8, lower[1] - 0.3])  # region 1 (fig. 4.15b)
    best = planning.plan(points, start, rates, v)
    expected = p_joint(rates[0], 0, 0.8 / v) + p_joint(rates[1], 0, 0.3 / v)
    assert best.probability == pytest.approx(expected, rel=1e-9)
    assert reliability.task_failure_probability(
        points, best.trajectory, rates, v, second_failures=False) == pytest.approx(expected)
    for k, q in enumerate(best.reached):  # each point reached inside the intersection
        assert not reliability.fatal_joints(points, k, q).any()


def all_pairs_minimum(points: list[TaskPoint], start: np.ndarray, rates: np.ndarray,
                      v: float) -> float:
    """Exhaustive search over the candidate configurations of the two points."""
    first, second = (planning._candidates(p) for p in points)
    best = math.inf
    for q1 in first:
        c1, t1 = planning.leg_cost(start, q1, 0.0, reliability.remaining_box(points, 0),
                                   rates, v)
        c2, _ = planning.leg_cost(q1[None], second, t1, reliability.remaining_box(points, 1),
                                  rates, v)
        best = min(best, float(c1 + c2.min()))
    return best


def test_case_2_search_matches_exhaustive_search_and_beats_straight_lines() -> None:
    points = chapter_points(2)
    rates, v = np.array([0.01, 0.02]), 0.5
    lower, upper = reliability.remaining_box(points, 0)
    assert not any(np.all((q >= lower) & (q <= upper)) for q in points[0].samples)  # case 2
    start = np.array([-1.2, 2.6])
    best = planning.plan(points, start, rates, v)
    assert best.probability > 0
    assert best.probability == pytest.approx(all_pairs_minimum(points, start, rates, v),
                                             rel=1e-12)
    evaluated = reliability.task_failure_probability(points, best.trajectory, rates, v,
                                                     second_failures=False)
    assert evaluated == pytest.approx(best.probability, rel=1e-9)
    baseline = reliability.task_failure_probability(
        points, planning.straight(points, start, v), rates, v, second_failures=False)
    assert best.probability < 0.9 * baseline
    trajectory = best.trajectory
    assert np.all(np.abs(np.diff(trajectory.configurations, axis=0))
                  <= v * np.diff(trajectory.times)[:, None] + 1e-9)  # the speed holds
    for k, q in enumerate(best.reached):
        x = math.cos(q[0]) + math.cos(q[0] + q[1])
        assert x == pytest.approx([0.3, 1.9][k], abs=1e-4)
        np.testing.assert_allclose(trajectory.configurations[trajectory.arrivals[k]], q)


@pytest.mark.parametrize("case", [1, 2])
def test_probability_agrees_with_a_monte_carlo_simulation(case: int) -> None:
    points = chapter_points(case)
    rates, v = np.array([0.02, 0.03]), 0.5
    start = np.array([-1.2, 2.6])
    for trajectory in (planning.plan(points, start, rates, v).trajectory,
                       planning.straight(points, start, v)):
        for second in (False, True):
            p = reliability.task_failure_probability(points, trajectory, rates, v, second)
            failures, runs = reliability.monte_carlo(points, trajectory, rates, v, 40000,
                                                     np.random.default_rng(case), second)
            assert failures > 0
            estimate = failures / runs
            standard_error = math.sqrt(max(p, 1e-6) * (1 - p) / runs)
            # The chapter sums pieces to first order in lambda t; the simulation is exact.
            second_order = (rates.sum() * (trajectory.duration + 10.0)) ** 2
            assert abs(estimate - p) < 4 * standard_error + second_order, (estimate, p)


def test_inside_the_intersection_only_second_failures_remain() -> None:
    points = chapter_points(1)
    lower, upper = reliability.remaining_box(points, 0)
    margin = np.minimum(points[0].samples - lower, upper - points[0].samples).min(axis=1)
    q1 = points[0].samples[np.argmax(margin)]  # the deepest inside the intersection
    assert margin.max() > 0.1
    q2 = points[1].crossings(0, q1[0])[0]
    start = q1 - 0.05 * np.sign(q1 - 0.5 * (lower + upper))
    trajectory = Trajectory.at_speed(np.array([start, q1, q2]), [1, 2], 0.5)
    rates = [0.01, 0.02]
    assert reliability.task_failure_probability(points, trajectory, rates, 0.5, False) == 0.0
    # Sec. 4.3.1: double failures are rare beside a single lock anywhere on the way.
    any_lock = sum(1 - math.exp(-r * trajectory.duration) for r in rates)
    assert 0 < reliability.task_failure_probability(points, trajectory, rates, 0.5) \
        < 0.1 * any_lock


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(0.0, 0.05), min_size=2, max_size=2),
       st.lists(st.floats(1.0, 3.0), min_size=2, max_size=2),
       st.floats(-2.0, 0.5), st.floats(0.0, 3.0))
def test_probability_is_a_probability_and_grows_with_the_rates(rates: list, scale: list,
                                                               q1: float, q2: float) -> None:
    points = chapter_points(2)
    start = np.array([q1, q2])
    trajectory = planning.straight(points, start, 0.5)
    p = reliability.task_failure_probability(points, trajectory, rates, 0.5)
    assert 0.0 <= p <= 1.0
    # Monotone while lambda t <= 1 (each exp(-l t0) - exp(-l t1) grows with l there).
    higher = np.asarray(rates) * np.asarray(scale)
    if higher.max() * (trajectory.duration + 20.0) <= 1.0:
        assert reliability.task_failure_probability(points, trajectory, higher, 0.5) >= p


def test_bad_rates_and_trajectories_are_refused() -> None:
    points = chapter_points(1)
    trajectory = planning.straight(points, np.zeros(2), 0.5)
    for rates in ([0.1, -0.1], [math.nan, 0.1], [0.1, 0.1, 0.1]):
        with pytest.raises(ValueError, match="rates"):
            reliability.task_failure_probability(points, trajectory, rates, 0.5)
    with pytest.raises(ValueError, match="times"):
        Trajectory(np.array([0.0, -1.0]), np.zeros((2, 2)), (1,))
    with pytest.raises(ValueError, match="arrivals"):
        Trajectory(np.array([0.0, 1.0]), np.zeros((2, 2)), (2,))


def test_on_a_traced_planar_3r_the_plan_is_no_worse_than_straight_lines() -> None:
    robot = robots.load("planar3r")
    start = np.array([0.2, 0.9, 0.9])
    points = []
    for x in ([1.9, 0.3], [0.3, 1.8]):  # near the workspace boundary: small boxes
        goal = selfmotion.targets_from_flat(robot, x)[0]
        points.append(TaskPoint.from_manifold(selfmotion.trace(
            robot, goal, selfmotion.find_seed(robot, goal, start))))
    rates, v = [0.01, 0.02, 0.01], 0.5
    best = planning.plan(points, start, rates, v)
    straight = planning.straight(points, start, v)
    assert best.probability <= reliability.task_failure_probability(
        points, straight, rates, v, second_failures=False) + 1e-12
    for k, q in enumerate(best.reached):
        np.testing.assert_allclose(robot.forward(q), [[1.9, 0.3], [0.3, 1.8]][k], atol=1e-3)


def test_ft_plan_writes_the_plan_its_check_and_a_figure(tmp_path) -> None:
    import json

    out = tmp_path / "plan"
    assert planning.main(["--points", "1.9,0.3;0.3,1.8", "--start", "0.2,0.9,0.9",
                          "--rates", "0.01,0.02,0.01", "--monte-carlo", "20000",
                          "--workers", "2", "--out", str(out)]) == 0
    summary = json.loads((out / "plan.json").read_text())
    assert (out / "plan.png").stat().st_size > 10000
    planned, straight = summary["planned"], summary["straight"]
    assert planned["single_failure"] <= straight["single_failure"]
    for entry in (planned, straight):
        assert len(entry["times"]) == len(entry["configurations"]) >= 3
        assert entry["monte_carlo"]["runs"] == 20000
        estimate = entry["monte_carlo"]["failures"] / 20000
        assert abs(estimate - entry["with_second_failures"]) < 0.01
        assert abs(estimate - entry["exact"]) < 0.01


@pytest.mark.parametrize(("arguments", "status"), [
    (["--points", "1.9,0.3", "--start", "0.2,0.9", "--rates", "0.01"], 1),
    (["--points", "1.9,0.3", "--start", "0.2,0.9,0.9", "--rates", "-1"], 1),
    (["--points", "5,5", "--start", "0.2,0.9,0.9", "--rates", "0.01"], 3),
])
def test_ft_plan_refuses_bad_input(tmp_path, arguments: list, status: int) -> None:
    assert planning.main([*arguments, "--out", str(tmp_path / "x")]) == status
    assert not (tmp_path / "x").exists()
