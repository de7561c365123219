"""ft_core.detection.rules one by one, on small synthetic inputs.

Each rule fires when it should and not when it should not. Velocities rad/s, positions
rad, times s; the defaults of `DetectorConfig` unless a test says otherwise.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from ft_core.detection import DetectorConfig, rules

pytestmark = pytest.mark.unit  # (tests/conftest.py marks the folder's tests as well)

CFG = DetectorConfig()
MIN, Z = CFG.min_command, CFG.confidence  # 0.05 rad/s, 5 standard errors


@pytest.mark.parametrize(("low", "high", "weakest"), [
    (0.1, 0.3, 0.1), (-0.3, -0.1, -0.1), (-0.1, 0.2, 0.0), (0.0, 0.2, 0.0), (0.0, 0.0, 0.0)])
def test_the_weakest_prediction_is_the_smallest_when_all_agree_in_sign(
        low: float, high: float, weakest: float) -> None:
    assert rules.weakest_prediction(low, high) == weakest


@pytest.mark.parametrize(("c", "s", "unlocked", "observable"), [
    (0.2, 0.001, True, True), (-0.2, 0.001, True, True),
    (0.04, 0.0, True, False),  # below min_command
    (0.2, 0.03, True, False),  # |c| < 2 z s: the noise could hide it
    (0.2, 0.001, False, False)])  # a locked joint is not examined
def test_observable(c: float, s: float, unlocked: bool, observable: bool) -> None:
    assert rules.is_observable(c, s, unlocked, MIN, Z, False) is observable


@pytest.mark.parametrize(("c", "s", "observable"), [
    (0.2, 0.03, True),  # z s <= |c| < 2 z s: still observable once stalling
    (-0.2, 0.03, True),
    (0.2, 0.05, False),  # |c| < z s
    (0.04, 0.0, False)])  # below min_command, stalling or not
def test_a_joint_whose_stall_is_under_way_stays_observable_down_to_one_separation(
        c: float, s: float, observable: bool) -> None:
    assert rules.is_observable(c, s, True, MIN, Z, True) is observable
    assert not rules.is_observable(c, s, False, MIN, Z, True)  # never a locked joint


@pytest.mark.parametrize(("v", "c", "s", "observable", "stalled"), [
    (0.01, 0.2, 0.001, True, True), (-0.01, -0.2, 0.001, True, True),
    (0.0, 0.2, 0.001, True, True), (-0.05, 0.2, 0.001, True, True),  # backwards: stalled
    (0.1, 0.2, 0.001, True, False),  # half the prediction: above ratio 0.3
    (0.01, 0.2, 0.05, True, False),  # |v - c| within z s
    (0.01, 0.2, 0.001, False, False)])
def test_stalled(v: float, c: float, s: float, observable: bool, stalled: bool) -> None:
    assert rules.is_stalled(v, c, s, observable, CFG.ratio, Z) is stalled


@pytest.mark.parametrize(("v", "c", "observable", "following"), [
    (0.15, 0.2, True, True), (-0.15, -0.2, True, True), (0.3, 0.2, True, True),
    (0.1, 0.2, True, False), (0.15, 0.2, False, False)])
def test_following(v: float, c: float, observable: bool, following: bool) -> None:
    assert rules.is_following(v, c, observable, CFG.following_ratio) is following


@pytest.mark.parametrize(("c", "position", "pushing"), [
    (0.2, 0.995, True), (0.2, 0.98, False), (0.2, -0.995, False),
    (-0.2, -0.995, True), (-0.2, 0.995, False), (0.0, 0.995, False)])
def test_pushing_into_a_limit(c: float, position: float, pushing: bool) -> None:
    assert rules.is_pushing(c, position, -1.0, 1.0, CFG.limit_margin) is pushing


def _own(v: float, low: float = 0.0, high: float = 0.0, unlocked: bool = True,
         undeclared: bool = True, falling: float = 0.0, gravity_known: bool = False,
         s: float = 0.001, fastest: float | None = None) -> bool:
    fastest = max(abs(low), abs(high)) if fastest is None else fastest
    return rules.moves_on_its_own(v, s, low, high, fastest, unlocked, undeclared, falling,
                                  gravity_known, MIN, Z)


def test_moving_with_no_command_or_against_it_is_moving_on_its_own() -> None:
    assert _own(0.3) and _own(-0.3)
    assert _own(-0.3, low=0.2, high=0.2)  # against its command
    assert _own(0.3, low=0.2, high=0.2, unlocked=False)  # a locked joint should not move


def test_moving_faster_than_commanded_or_within_the_noise_is_not_on_its_own() -> None:
    assert not _own(0.3, low=0.2, high=0.2)  # a servo's overshoot, the commanded way
    assert not _own(0.04)  # below min_command
    assert not _own(0.06, s=0.02)  # within z s of the healthy range
    assert not _own(0.3, low=0.0, high=0.3)  # a plausible model predicts it
    assert not _own(0.3, undeclared=False)  # already declared free-swinging
    assert not _own(0.3, low=0.1, high=0.1, fastest=0.5)  # pushed by faster joints


def test_falling_the_commanded_way_beyond_any_transient_is_moving_on_its_own() -> None:
    """Twice the fastest plausible prediction of any joint, and the noise, further."""
    assert _own(0.8, low=0.2, high=0.2, fastest=0.3)  # 0.8 > 2 x 0.3 + 0.05
    assert not _own(0.6, low=0.2, high=0.2, fastest=0.3)
    assert not _own(0.8, low=0.2, high=0.2, fastest=0.3, falling=-1.0, gravity_known=True)


def test_with_gravity_known_moving_on_its_own_must_go_downhill() -> None:
    assert _own(0.3, falling=1.0, gravity_known=True)
    assert not _own(0.3, falling=-1.0, gravity_known=True)  # uphill
    assert not _own(0.3, falling=0.0, gravity_known=True)  # gravity cannot turn it
    assert _own(0.3, falling=0.0, gravity_known=False)  # unknown gravity: not asked


def _candidate(v: float = 0.0, stalled: bool = True, pushing: bool = False,
               on_its_own: bool = False, undeclared: bool = True) -> bool:
    return rules.is_candidate(v, 0.001, stalled, pushing, on_its_own, undeclared, MIN, Z)


def test_a_lock_candidate_is_stalled_not_at_a_limit_and_not_on_its_own() -> None:
    assert _candidate()
    assert not _candidate(stalled=False)
    assert not _candidate(pushing=True)
    assert not _candidate(on_its_own=True)


def test_a_joint_once_free_swinging_is_a_candidate_again_only_once_it_stops() -> None:
    assert not _candidate(v=-0.1, undeclared=False)
    assert _candidate(v=0.01, undeclared=False)


def test_classify_applies_the_rules_joint_by_joint() -> None:
    """Joint 0 stalls, joint 1 follows, joint 2 is not commanded and moves on its own."""
    measured = np.array([0.0, 0.2, 0.3])
    plausible = np.array([[0.2, 0.2, 0.0], [0.25, 0.22, 0.0]])  # two models
    error = np.full(3, 0.001)
    weakest, observable, following, stalled, pushing, candidate, own = rules.classify(
        measured, plausible, error, np.zeros(3), np.full(3, -1.0), np.full(3, 1.0),
        np.ones(3, dtype=bool), np.ones(3, dtype=bool), np.zeros(3, dtype=bool), np.zeros(3),
        False, MIN, Z, CFG.ratio, CFG.following_ratio, CFG.limit_margin)
    np.testing.assert_array_equal(weakest, [0.2, 0.2, 0.0])
    assert observable.tolist() == [True, True, False]
    assert following.tolist() == [False, True, False]
    assert stalled.tolist() == [True, False, False]
    assert pushing.tolist() == [False, False, False]
    assert candidate.tolist() == [True, False, False]
    assert own.tolist() == [False, False, True]


def test_a_witness_moves_as_some_plausible_model_commands_it() -> None:
    """Right after a turn the lags disagree in sign (weakest 0): the arm still vouches.

    Joint 0 moves as the shorter lag predicts, joint 1 against every model, joint 2 as
    a model predicts but within the noise, joint 3 is locked, joint 4 is commanded under
    `min_command` by every model.
    """
    plausible = np.array([[0.3, 0.3, 0.3, 0.3, 0.04],    # a short lag: the new command
                          [-0.2, 0.2, -0.2, -0.2, 0.03]])  # a long one: the old command
    measured = np.array([0.28, -0.3, 0.28, 0.28, 0.04])
    error = np.array([0.01, 0.01, 0.1, 0.01, 0.001])
    unlocked = np.array([True, True, True, False, True])
    weakest = np.array([rules.weakest_prediction(lo, hi) for lo, hi
                        in zip(plausible.min(axis=0), plausible.max(axis=0), strict=True)])
    assert weakest[:4].tolist() == [0.0, 0.2, 0.0, 0.0]
    vouching = rules.vouching(measured, plausible, error, unlocked, MIN, Z,
                              CFG.following_ratio)
    assert vouching.tolist() == [True, False, False, False, False]


def test_the_error_of_a_difference_of_window_means() -> None:
    """sqrt(2 / samples) of one position's scatter, the slope's error times sqrt(spread)."""
    times = np.array([0.0, 1.0, 2.0])  # spread: sum of squared deviations = 2
    expected = 0.5 * math.sqrt(2.0) * math.sqrt(2.0 / 3)
    assert rules.mean_difference_error(0.5, times) == pytest.approx(expected)
    np.testing.assert_allclose(rules.mean_difference_error(np.array([0.5, 1.0]), times),
                               [expected, 2 * expected])


def test_a_lock_loses_position_a_servo_catching_up_does_not() -> None:
    """Offsets are measured minus predicted positions; the command is positive."""
    weakest, sigma = np.array([0.2]), np.array([0.001])
    deficit, lost = rules.lost_position(np.array([-0.01]), np.array([[-0.002], [0.0]]),
                                        weakest, sigma, Z, np.zeros((2, 1)))
    assert deficit == pytest.approx([0.008]) and lost.tolist() == [True]
    # Ahead of its command earlier, then back to where it stood once: nothing lost.
    deficit, lost = rules.lost_position(np.array([-0.001]), np.array([[0.005], [-0.001]]),
                                        weakest, sigma, Z, np.zeros((2, 1)))
    assert deficit == pytest.approx([0.0]) and lost.tolist() == [False]
    # The same along a negative command.
    deficit, lost = rules.lost_position(np.array([0.01]), np.array([[0.0]]), -weakest,
                                        sigma, Z, np.zeros((1, 1)))
    assert deficit == pytest.approx([0.01]) and lost.tolist() == [True]


def test_an_offset_the_models_latency_error_moves_is_no_lost_position() -> None:
    """A model 10 ms late: the joint runs 13 mrad ahead of it at 1.3 rad/s, 1 at 0.1.

    After the deceleration (1.2 rad/s) the offset fell by 12 mrad, all of it what a
    10 ms latency error times the change of command moves it (the `shift` of the window
    at 1.3 rad/s), none against the window already at 0.1 rad/s; a lock there loses
    more.
    """
    weakest, sigma = np.array([0.1]), np.array([0.0005])
    past = np.array([[0.013], [0.001]])  # (windows, joints): at 1.3, then at 0.1 rad/s
    shift = np.array([[0.012], [0.0]])  # rad: 0.01 s x the change of command since each
    deficit, lost = rules.lost_position(np.array([0.001]), past, weakest, sigma, Z, shift)
    assert deficit == pytest.approx([0.0]) and lost.tolist() == [False]
    # Without the shift the fall reads as lost.
    deficit, lost = rules.lost_position(np.array([0.001]), past[:1], weakest, sigma, Z,
                                        np.zeros((1, 1)))
    assert deficit == pytest.approx([0.012]) and lost.tolist() == [True]
    # A lock after the deceleration loses beyond it: 5 mrad more.
    deficit, lost = rules.lost_position(np.array([-0.004]), past, weakest, sigma, Z, shift)
    assert deficit == pytest.approx([0.005]) and lost.tolist() == [True]


def test_with_no_earlier_window_the_deficit_is_infinite() -> None:
    deficit, lost = rules.lost_position(np.zeros(2), np.zeros((0, 2)), np.full(2, 0.2),
                                        np.full(2, 0.001), Z, np.zeros((0, 2)))
    assert np.isinf(deficit).all() and lost.all()


def test_a_fast_swing_need_not_wait_for_the_settling_time() -> None:
    plausible = np.array([[0.1, -0.05]])
    # Faster than twice the largest prediction plus the noise: no wait.
    assert rules.swing_wait(0.3, 0.001, plausible, 0.2, Z, MIN) == 0.0
    assert rules.swing_wait(-0.3, 0.001, plausible, 0.2, Z, MIN) == 0.0
    # Slower: a servo's transient could explain it, so it must outlast the settling time.
    assert rules.swing_wait(0.2, 0.001, plausible, 0.2, Z, MIN) == 0.2
    assert rules.swing_wait(0.3, 0.02, plausible, 0.2, Z, MIN) == 0.2


def _slow(moved, predicted, reached=(0.0, 0.0), latest: float = 0.0,
          shift=(0.0, 0.0), least: float = 0.01) -> bool:
    """`rules.slow_stall` for one joint in [-1, 1] rad, sigma 1 mrad."""
    column = lambda values: np.array(values, dtype=float)[:, None]  # noqa: E731
    stalled = rules.slow_stall(column(moved), column(predicted), column(reached),
                               np.array([latest]), np.array([-1.0]), np.array([1.0]),
                               np.array([0.001]), column(shift), least, CFG.ratio, Z,
                               CFG.limit_margin)
    assert stalled.shape == (1,)
    return bool(stalled[0])


def test_a_slow_stall_loses_motion_in_both_halves_of_the_span() -> None:
    assert _slow([0.0, 0.0], [0.02, 0.02])
    assert _slow([0.0, 0.0], [-0.02, -0.02])
    assert not _slow([0.02, 0.0], [0.02, 0.02])  # a servo holding its lead in one half
    assert not _slow([0.0, 0.0], [0.004, 0.004])  # within the noise
    assert not _slow([0.01, 0.01], [0.02, 0.02])  # moved half of it
    assert not _slow([-0.01, -0.01], [0.02, 0.02])  # pushed back against it: not held


def test_a_slow_stall_may_be_commanded_to_and_fro() -> None:
    assert _slow([0.0, 0.0], [0.02, -0.01])  # still, commanded one way then the other
    assert not _slow([0.02, -0.01], [0.02, -0.01])  # followed both ways
    assert not _slow([0.0, -0.01], [0.02, -0.01])  # followed the second half


def test_a_slow_stall_needs_a_least_commanded_motion() -> None:
    assert _slow([0.0, 0.0], [0.006, 0.006])
    assert not _slow([0.0, 0.0], [0.006, 0.006], least=0.015)  # 12 mrad in all, under 15


def test_a_slow_stall_allows_for_the_models_latency_error() -> None:
    assert _slow([0.0, 0.0], [0.008, 0.008])
    assert not _slow([0.0, 0.0], [0.008, 0.008], shift=(0.004, 0.0))


def test_a_slow_stall_near_a_limit_the_command_points_into_is_not_one() -> None:
    assert not _slow([0.0, 0.0], [0.02, 0.02], latest=0.985)
    assert not _slow([0.0, 0.0], [0.02, 0.02], reached=(0.0, 0.985))  # touched it earlier
    assert not _slow([0.0, 0.0], [-0.02, -0.02], latest=-0.985)
    assert _slow([0.0, 0.0], [-0.02, -0.02], latest=0.985)  # the other limit
    assert not _slow([0.0, 0.0], [-0.02, 0.02], latest=0.985)  # one half points into it


def _reason(now: float = 1.0, last_command: float = 0.99, resumed_at: float = 0.0,
            times: np.ndarray | None = None) -> str | None:
    times = np.arange(0.92, 1.0001, 0.004) if times is None else times
    return rules.not_observing(now, last_command, resumed_at, 0.3, times, CFG.window,
                               CFG.min_samples)


def test_no_decision_without_evidence() -> None:
    assert _reason() is None
    assert _reason(last_command=-math.inf) == "no command yet"
    assert _reason(last_command=0.9) == "command stream paused for 0.100 s"
    # A hole shorter than a window (the monitor descheduled on a busy machine): the driver
    # holds the last command, and the detector goes on.
    assert _reason(last_command=0.95) is None
    assert _reason(resumed_at=0.8) == "settling after the command stream (re)started"
    assert _reason(times=np.array([0.97, 0.98, 0.99, 1.0])) == (
        "too few joint states in the window")
    times = np.concatenate([np.arange(0.92, 0.94, 0.004), np.arange(0.99, 1.0001, 0.002)])
    assert _reason(times=times) == "joint states arrive with gaps"


def test_a_plant_fault_is_more_odd_joints_than_following_ones() -> None:
    assert rules.plant_fault([True, True, False], [False, False, True], [False] * 3) == [
        True, True, False]
    assert rules.plant_fault([False] * 3, [False, False, True], [True, True, False]) == [
        True, True, False]
    # Two locks on an arm whose other joints follow: locks, no plant fault.
    assert rules.plant_fault([True, True, False, False, False], [False, False, True, True, True],
                             [False] * 5) is None
    assert rules.plant_fault([True, False], [False, False], [False, False]) is None


def test_a_joint_moving_on_its_own_without_torque_is_no_plant_fault() -> None:
    """A drive that gives no torque explains its own joint's motion, not the plant's.

    Two joints moving on their own, none following, is a stopped plant; where one of them
    is a drive without torque (a shoulder falling onto its stop, its neighbour pushed by
    the fall, on the physics plant) only one joint is left to say so.
    """
    own, following, stalled = [True, False, False, True], [False] * 4, [False] * 4
    assert rules.plant_fault(stalled, following, own) == own
    assert rules.plant_fault(stalled, following, own, [True, False, False, False]) is None
    assert rules.plant_fault(stalled, following, own, [False, True, True, False]) == own


def test_a_silent_joint_falling_past_every_command_and_rest_falls() -> None:
    """Four joints gravity turns the + way; commands kept 0.3 and -0.2 rad/s on each."""
    commands = np.array([[0.3, 0.3, 0.3, -0.2], [-0.2, -0.2, -0.2, 0.3]])
    measured = np.array([0.3 + MIN + 0.01, 0.3 + MIN - 0.01, 0.6, 0.6])
    silent = np.array([True, True, False, True])
    everyone, falling = np.ones(4, bool), np.ones(4)
    fastest = rules.fastest_fall(commands, falling)
    assert fastest.tolist() == [0.3, 0.3, 0.3, 0.3]
    own = rules.falls_past_every_command(silent, measured, np.full(4, 1e-3), fastest, falling,
                                         everyone, MIN, Z)
    # Joint 1 is within min_command of the fastest command; joint 2's drive gives torque.
    assert own.tolist() == [True, False, False, True]
    # Falling the other way than gravity turns it, past the commands: no fall.
    assert not rules.falls_past_every_command(silent, -measured, np.full(4, 1e-3), fastest,
                                              falling, everyone, MIN, Z).any()
    # With no command kept, or only uphill ones, rest is the bound; the noise widens it.
    rest = rules.fastest_fall(-np.abs(commands), falling)
    assert rest.tolist() == [0.0] * 4
    assert rules.fastest_fall(np.zeros((0, 4)), falling).tolist() == [0.0] * 4
    slow = np.full(4, 0.2)
    assert rules.falls_past_every_command(silent, slow, np.full(4, 1e-3), rest, falling,
                                          everyone, MIN, Z).tolist() == [True, True, False, True]
    assert not rules.falls_past_every_command(silent, slow, np.full(4, 0.05), rest,
                                              falling, everyone, MIN, Z).any()
    # Neither a joint gravity does not turn, nor one declared already.
    assert not rules.falls_past_every_command(silent, measured, np.full(4, 1e-3), fastest,
                                              np.zeros(4), everyone, MIN, Z).any()
    assert not rules.falls_past_every_command(silent, measured, np.full(4, 1e-3), fastest,
                                              falling, np.zeros(4, bool), MIN, Z).any()
