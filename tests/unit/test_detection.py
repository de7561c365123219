"""ft_core.detection offline, on ft_core.plant (the sim's own plant): real plants, no tuning.

The plant grid of issue 13: latency {0, 10, 30, 50} ms x response time {0, 20, 50} ms,
default detector parameters. Each healthy run must declare nothing; each lock must
be found on the right joint within 300 ms; the fixed-latency detector of before
(latency 0, no plant model) is shown to fail on the same data.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest
from ft_core.detection import DECISION_PERIOD, DetectorConfig, LockDetector, Update
from ft_core.plant import PlantConfig
from paths import REPO

sys.path.insert(0, str(REPO / "bench"))
import fixed_latency_detector  # the detector before issue 13
from detection import DT, GRID, PANDA, START, record, replay  # the benchmark's recorder


def old_detector() -> fixed_latency_detector.LockDetector:
    """The detector before plant models, with its defaults (latency 0)."""
    return fixed_latency_detector.LockDetector(PANDA.lower, PANDA.upper)


def run(commands, seconds: float, plant: PlantConfig | None = None,
        lock: tuple[tuple[int, ...], float] | None = None, noise: float = 1e-3,
        detector=None, pauses: tuple[tuple[float, float], ...] = (),
        stop_at: float | None = None, seed: int = 0, dt: float = DT):
    """Record the plant under `commands(t)` and replay it: (detector, [(time, joints)])."""
    detector = detector or LockDetector(PANDA.lower, PANDA.upper)
    data = record(commands, seconds, plant, lock, noise, pauses, stop_at, seed, dt)
    return detector, replay(data, detector)


def sweeping(t: float) -> np.ndarray:
    """Speeds sweeping 0.05 .. 1 rad/s per joint, direction flipping every half second."""
    speed = 0.05 + 0.95 * (0.5 + 0.5 * np.sin(2 * np.pi * t / 7 + np.arange(7)))
    return speed * np.where(np.sin(2 * np.pi * t + np.arange(7)) >= 0, 1.0, -1.0)


def moving_targets(t: float) -> np.ndarray:
    """A smooth, closed-loop-like motion: each joint oscillates about START (0.3 rad)."""
    return 0.3 * 2 * np.pi * 0.3 * np.cos(2 * np.pi * 0.3 * t + np.arange(7))


@pytest.mark.parametrize(("latency", "response"), GRID)
def test_healthy_plants_of_the_grid_declare_nothing(latency: float, response: float) -> None:
    plant = PlantConfig(latency=latency, response_time=response)
    for commands in (sweeping, moving_targets):
        detector, events = run(commands, 10.0, plant)
        assert detector.not_observing is None, detector.not_observing
        assert events == [] and detector.swinging == {}


def test_the_fixed_latency_detector_fails_on_a_lagging_plant() -> None:
    """What issue 13 measured: a lagging plant locks healthy joints without a plant model."""
    plant = PlantConfig(latency=0.03, response_time=0.02)
    _, events = run(sweeping, 10.0, plant, detector=old_detector())
    assert events, "the old detector was expected to declare false locks here"


@pytest.mark.parametrize(("latency", "response"), GRID)
def test_a_lock_at_0_2_rad_s_is_found_on_the_right_joint(latency: float,
                                                          response: float) -> None:
    plant = PlantConfig(latency=latency, response_time=response)
    delays = []
    for joint in range(7):
        def commands(t: float) -> np.ndarray:
            return moving_targets(t) if t < 2.5 else np.full(7, 0.2)

        _, events = run(commands, 4.0, plant, lock=((joint,), 3.5), seed=joint)
        assert events, f"joint {joint} not detected"
        time, joints = events[0]
        assert joints == [joint]
        delays.append(time - 3.5)
    print(f"\nL {latency * 1e3:.0f} ms, T {response * 1e3:.0f} ms: detection (ms) "
          f"{[round(d * 1e3) for d in delays]}")
    assert max(delays) <= 0.3
    assert np.median(delays) <= 0.15


def test_identification_finds_the_plant() -> None:
    detector, events = run(moving_targets, 20.0, PlantConfig(latency=0.03, response_time=0.02))
    estimate = detector.estimate()
    assert events == [] and estimate.identified
    low, high = estimate.latency_range
    assert low <= 0.03 <= high and high - low <= 0.1
    low, high = estimate.response_time_range
    assert low <= 0.02 <= high
    # Latency and lag trade off for smooth motion; their sum is what is identified.
    assert estimate.latency + estimate.response_time == pytest.approx(0.05, abs=0.015)


@pytest.mark.parametrize("hold", [False, True])
@pytest.mark.parametrize("pause", [0.05, 0.1, 0.15, 0.3, 1.0])
def test_command_pauses_declare_nothing(pause: float, hold: bool) -> None:
    plant = PlantConfig(latency=0.03, response_time=0.02, timeout=0.1, hold_last_command=hold)
    pauses = tuple((start, start + pause) for start in (3.0, 5.0, 7.0))
    detector, events = run(sweeping, 9.0, plant, pauses=pauses)
    assert events == [] and detector.swinging == {}
    assert detector.not_observing is None  # observing again after the last pause


@pytest.mark.parametrize("timeout", [0.03, 0.1])
def test_a_hole_shorter_than_a_window_goes_on_observing(timeout: float) -> None:
    """Holes of 0.07 s in the commands (a monitor descheduled on a busy machine).

    No restart: the detector keeps observing through them. A driver whose watchdog
    (0.03 s) stops the arm inside the hole stalls every joint together: nothing declared.
    """
    plant = PlantConfig(latency=0.03, response_time=0.02, timeout=timeout)
    data = record(sweeping, 9.0, plant, pauses=tuple((t, t + 0.07) for t in (3.0, 5.0, 7.0)))
    detector = LockDetector(PANDA.lower, PANDA.upper)
    blind = []
    for kind, t, values in data.events:
        if kind == "command":
            detector.command(t, values)
            continue
        update = detector.measure(t, values)
        assert update.locked == () and update.swinging == (), (t, update)
        if t >= 2.5 and detector.not_observing is not None:
            blind.append(t)
    assert detector.not_observing is None
    assert len(blind) < 50, (len(blind), blind[:5])


def test_pauses_lock_joints_without_the_gap_rule() -> None:
    """The same pauses with the old detector: every moving joint is declared locked."""
    plant = PlantConfig(timeout=0.1)
    _, events = run(lambda t: np.full(7, 0.3), 4.0, plant, pauses=((2.0, 2.15),),
                    detector=old_detector())
    assert len({j for _, joints in events for j in joints}) >= 5


def test_a_plant_that_stops_is_a_plant_fault_not_seven_locks() -> None:
    detector, events = run(lambda t: np.full(7, 0.2), 3.0, stop_at=2.0)
    assert events == []
    assert detector.plant_fault is not None
    assert detector.plant_fault.startswith("plant not following commands")


def test_two_simultaneous_locks_are_both_declared() -> None:
    _, events = run(lambda t: np.full(7, 0.2), 3.0, lock=((1, 4), 2.0))
    assert events
    assert sorted(j for _, joints in events for j in joints) == [1, 4]


def test_an_acceleration_limited_plant_declares_nothing() -> None:
    plant = PlantConfig(latency=0.02, acceleration_limit=(5.0,))
    detector, events = run(moving_targets, 20.0, plant)
    assert events == [] and detector.swinging == {}


@pytest.mark.parametrize("holding", [False, True])
def test_a_joint_moving_on_its_own_is_free_swinging_not_locked(holding: bool) -> None:
    """Issue 16: joint 3 loses its torque at 4 s and swings.

    0.3 (1 - cos) rad, up to 0.94 rad/s, while the arm moves, or while it holds still
    (zero commands).
    """
    plant = PlantConfig(latency=0.02, response_time=0.03)

    def commands(t: float) -> np.ndarray:
        return moving_targets(t) if not holding or t < 2.5 else np.zeros(7)

    data = record(commands, 5.0, plant)
    for kind, t, values in data.events:
        if kind == "measure" and t >= 4.0:
            values[2] += 0.3 * (1 - np.cos(np.pi * (t - 4.0)))
    detector = LockDetector(PANDA.lower, PANDA.upper)
    declared, locks = _replay_all(data, detector)
    assert [j for _, j in declared] == [2]
    assert 4.0 < declared[0][0] < 4.5
    # Against its command it passes through a stall: a lock, taken back once it moves.
    assert {j for _, j in locks} <= {2}
    assert list(detector.swinging) == [2] and detector.locked == {}
    detector.lock(2, 0.0, 5.0)  # the brake: locked, and no longer reported as swinging
    assert detector.swinging == {} and list(detector.locked) == [2]


def test_a_swing_takes_a_declared_lock_back_and_the_update_says_so() -> None:
    """Joint 3, declared locked, moves on its own: the update names the lock it releases.

    The monitor writes the locked set on that (`Update.released`). Undeclared, the joint
    may pass through a stall against its command first (a lock, taken back once it
    moves): the update releases what was locked just before it, nothing else.
    """
    plant = PlantConfig(latency=0.02, response_time=0.03)
    data = record(moving_targets, 5.0, plant)
    for kind, t, values in data.events:
        if kind == "measure" and t >= 4.0:
            values[2] += 0.3 * (1 - np.cos(np.pi * (t - 4.0)))
    for declared in (True, False):
        detector = LockDetector(PANDA.lower, PANDA.upper)
        if declared:
            detector.lock(2, 0.0, 0.0)
        swings = []
        for kind, t, values in data.events:
            if kind == "command":
                detector.command(t, values)
                continue
            before = tuple(detector.locked)
            update = detector.measure(t, values)
            if update.swinging:
                swings.append((before, update))
        assert [u.swinging for _, u in swings] == [(2,)], swings
        before, update = swings[0]
        assert update.released == before
        assert before == (2,) or not declared  # declared: locked until the swing
        assert detector.locked == {} and list(detector.swinging) == [2]


def test_a_joint_falling_faster_than_any_transient_is_named_before_the_settling_time() -> None:
    """Joint 2 falls from rest at 3 s (10 rad/s^2) behind a slow servo while the arm holds.

    The plant's settling time (30 ms + 3 x 150 ms) is longer than a real fall onto a
    stop (issue 27: the Panda's joint 2, about 0.5 s): at twice any plausible command
    the motion is no servo transient, so `persistence` alone applies.
    """
    plant = PlantConfig(latency=0.03, response_time=0.15)
    data = record(lambda t: moving_targets(t) if t < 2.0 else np.zeros(7), 4.0, plant)
    for kind, t, values in data.events:
        if kind == "measure" and t >= 3.0:
            values[1] += 5.0 * (t - 3.0) ** 2
    detector = LockDetector(PANDA.lower, PANDA.upper)
    declared, _ = _replay_all(data, detector)
    estimate = detector.estimate()
    assert estimate.identified
    settling = estimate.latency + 3 * estimate.response_time
    assert settling > 0.3
    assert [j for _, j in declared] == [1]
    assert declared[0][0] - 3.0 < 0.2 < settling


@pytest.mark.parametrize(("gravity", "declared"), [(1.0, [2]), (-1.0, []), (0.0, [])])
def test_a_joint_moving_on_its_own_must_go_the_way_gravity_turns_it(
        gravity: float, declared: list[int]) -> None:
    """Issue 29: with the arm's gravity known, only motion downhill is a lost torque.

    Joint 3 moves on its own (positive) while the arm holds still; gravity would turn
    it positive, negative, or not at all (a vertical axis): free-swinging only in the
    first case, whatever the other evidence.
    """
    data = record(lambda t: moving_targets(t) if t < 2.5 else np.zeros(7), 5.0,
                  PlantConfig(latency=0.02, response_time=0.03))
    for kind, t, values in data.events:
        if kind == "measure" and t >= 4.0:
            values[2] += 0.3 * (1 - np.cos(np.pi * (t - 4.0)))
    falling = np.zeros(7)
    falling[2] = gravity
    detector = LockDetector(PANDA.lower, PANDA.upper)
    swings = []
    for kind, t, values in data.events:
        if kind == "command":
            detector.command(t, values)
        else:
            swings += detector.measure(t, values, falling=lambda: falling).swinging
    assert detector.estimate().identified, "the test never reached identification"
    assert swings == declared


def _replay_all(data, detector: LockDetector, command_scale: np.ndarray | None = None):
    """Feed a recording; (swings, locks) as [(time, joint)], commands scaled as given."""
    swings, locks = [], []
    for kind, t, values in data.events:
        if kind == "command":
            detector.command(t, values if command_scale is None else values * command_scale)
        else:
            update = detector.measure(t, values)
            swings += [(t, j) for j in update.swinging]
            locks += [(t, j) for j in update.locked]
    return swings, locks


@pytest.mark.parametrize("gain", [1.3, 1.6])
def test_a_joint_running_ahead_of_its_command_is_never_free_swinging(gain: float) -> None:
    """Issue 29: a servo's tracking error or overshoot is not a joint moving on its own.

    Joint 3 runs at `gain` times its command (the detector is told 1 / gain of what the
    plant executed) through 8 s of sweeping: faster than commanded, in the commanded
    direction. The rule before this issue declared it free-swinging.
    """
    plant = PlantConfig(latency=0.02, response_time=0.03)
    data = record(sweeping, 8.0, plant)
    scale = np.ones(7)
    scale[2] = 1 / gain
    detector = LockDetector(PANDA.lower, PANDA.upper)
    swings, locks = _replay_all(data, detector, scale)
    assert detector.estimate().identified, "the test never reached identification"
    assert swings == [] and locks == [] and detector.swinging == {}


def test_a_joint_declared_free_swinging_that_stops_while_commanded_is_locked() -> None:
    """Issue 29: whatever a joint was declared before, stopping while commanded is a lock.

    Joint 3 loses its torque at 4 s (as in the test above), is declared free-swinging,
    then jams at 4.6 s while the arm moves on: the detector locks it, and then a suspect
    for it is "known".
    """
    plant = PlantConfig(latency=0.02, response_time=0.03)
    data = record(lambda t: moving_targets(t) if t < 4.6 else np.full(7, 0.3), 5.5, plant,
                  lock=((2,), 4.6))
    for kind, t, values in data.events:
        if kind == "measure" and t >= 4.0:
            values[2] += 0.3 * (1 - np.cos(np.pi * (min(t, 4.6) - 4.0)))
    detector = LockDetector(PANDA.lower, PANDA.upper)
    swings, locks = _replay_all(data, detector)
    assert [j for _, j in swings] == [2] and swings[0][0] < 4.6
    assert locks and locks[-1][1] == 2 and locks[-1][0] > 4.6, locks
    assert list(detector.locked) == [2] and detector.swinging == {}
    assert detector.confirm(2, 0.0, 5.5).decision == "known"


#: Joint 1 slow (rad/s), the others fast enough to vouch for the plant.
SLOW_FIRST = np.array([0.07, 0.3, 0.3, 0.3, 0.3, 0.3, 0.3])


def _catching_up(t: float) -> float:
    """How far (rad) a position-integrating servo runs ahead of its command at `t` (s).

    From 3 s on: 15 mrad in 0.15 s (a reaction torque), then a pause at 0.07 rad/s
    commanded until caught up.
    """
    if t < 3.0:
        return 0.0
    if t < 3.15:
        return 0.015 * (1 - np.cos(np.pi * (t - 3.0) / 0.15)) / 2
    return max(0.015 - 0.07 * (t - 3.15), 0.0)


def test_a_servo_pausing_to_catch_up_after_running_ahead_is_not_a_lock() -> None:
    """Issue 29's last false lock: after running ahead, a servo pauses while commanded.

    The physics plant's joint 1 (the largest inertia, a vertical axis) is pushed ahead of
    its reference by the others' reaction torques, then stops for about 0.2 s while the
    reference catches up. Its velocity alone looks like a lock; its position never fell
    behind the command, so it is not one (the detector before the position-deficit rule
    declared it locked).
    """
    data = record(lambda t: SLOW_FIRST, 4.0, PlantConfig(latency=0.03, response_time=0.03))
    for kind, t, values in data.events:
        if kind == "measure":
            values[0] += _catching_up(t)
    detector = LockDetector(PANDA.lower, PANDA.upper)
    stalled = []
    for kind, t, values in data.events:
        if kind == "command":
            detector.command(t, values)
            continue
        assert detector.measure(t, values) == Update()
        evidence = detector.joints[0]
        if evidence.observable and evidence.measured < 0.3 * evidence.commanded:
            stalled.append((t, evidence.deficit))
    assert len(stalled) >= 10, "the pause never looked like a stall"
    assert all(deficit <= 0.0 for _, deficit in stalled), stalled
    assert detector.locked == {}


def test_a_lock_at_a_small_command_is_still_found() -> None:
    """The same arm and command as above, joint 1 locked at 3 s: found within 0.3 s."""
    _, events = run(lambda t: SLOW_FIRST, 4.0, PlantConfig(latency=0.03, response_time=0.03),
                    lock=((0,), 3.0))
    assert events, "the lock was never found"
    assert events[0][1] == [0] and 3.0 < events[0][0] < 3.3, events


def _then_joint_2_alone(t: float) -> np.ndarray:
    """Every joint moving for 1 s (the plant seen following), then joint 2 alone.

    At 0.02 rad/s: the equilibrium an undetected lock leaves (Maciejewski et al. Theorem
    1), below the window's observable speed at 1 mrad of noise.
    """
    if t < 1.0:
        return np.full(7, 0.3)
    alone = np.zeros(7)
    alone[1] = 0.02
    return alone


def _suspect_at_the_end(lock: tuple[tuple[int, ...], float] | None,
                        plant: PlantConfig | None = None):
    data = record(_then_joint_2_alone, 3.0, plant, lock)
    detector = LockDetector(PANDA.lower, PANDA.upper)
    assert replay(data, detector) == []  # the window's test alone declares nothing
    assert not detector.joints[1].observable and not detector.joints[1].candidate
    return detector, detector.confirm(1, -0.3, 3.0)


@pytest.mark.parametrize("plant", [None, PlantConfig(latency=0.05, response_time=0.05)])
def test_a_slowly_commanded_suspect_that_lost_its_motion_is_confirmed(plant) -> None:
    """Joint 2 locked at 2 s while commanded 0.02 rad/s: confirmed over the last 0.5 s."""
    detector, answer = _suspect_at_the_end(((1,), 2.0), plant)
    assert answer.decision == "locked"
    evidence = answer.evidence
    assert 0.015 < evidence.commanded < 0.025 and abs(evidence.measured) < 0.005
    assert 0.005 < evidence.deficit < 0.015  # about 10 mrad lost in 0.5 s
    assert detector.locked == {1: -0.3}


def test_a_slowly_commanded_healthy_suspect_is_refused() -> None:
    _, answer = _suspect_at_the_end(None, PlantConfig(latency=0.05, response_time=0.05))
    assert answer.decision == "refused"


def test_a_servo_catching_up_is_refused_as_a_suspect_too() -> None:
    """The catch-up pause above, suspected at every instant of it: never confirmed.

    Over the last 0.5 s the joint moved less than commanded (it ends its lead), but the
    half that holds the lead lost nothing: a lock loses in both halves.
    """
    data = record(lambda t: SLOW_FIRST, 4.0, PlantConfig(latency=0.03, response_time=0.03))
    for kind, t, values in data.events:
        if kind == "measure":
            values[0] += _catching_up(t)
    detector = LockDetector(PANDA.lower, PANDA.upper)
    decisions = set()
    for kind, t, values in data.events:
        if kind == "command":
            detector.command(t, values)
            continue
        detector.measure(t, values)
        if 3.0 <= t:
            decisions.add(detector.confirm(0, float(values[0]), t).decision)
    assert decisions == {"refused"}


def _excursion(t: float) -> np.ndarray:
    """Healthy motion for 2 s, then at 3 s the observability motion's excursion.

    Joint 7 follows one period of 0.3 sin(2 pi t) (out and back in 1 s), its witness,
    joint 5, 0.3 of that, the others still (`ft_core.observability`).
    """
    if t < 2.0:
        return moving_targets(t)
    command = np.zeros(7)
    if 3.0 <= t < 4.0:
        command[6] = 0.3 * np.sin(2 * np.pi * (t - 3.0))
        command[4] = 0.3 * command[6]
    return command


def test_a_witness_seen_moving_below_the_stall_bar_vouches_for_the_plant() -> None:
    """Joint 7 locked at 2.5 s, found in its excursion's first half under 1e-3 rad of noise.

    The witness peaks at 0.09 rad/s, under ten standard errors of its slope (not
    observable for a stall) yet clearly moving as commanded (`rules.vouching`); with the
    stall's bar for witnesses this lock is never found. In the second half the command
    brings joint 7 back to where it stands: no position lost, nothing to find there.
    """
    plant = PlantConfig(latency=0.02, response_time=0.03)
    seen = {"below the bar": False}

    def look(detector: LockDetector, t: float, events: list) -> None:
        # Joint 5 is the only joint moving: evidence under way means it vouched.
        if t < 3.5 and detector.joints[6].evidence_since is not None:
            seen["below the bar"] |= not detector.joints[4].observable

    events = _replay_looking(record(_excursion, 4.5, plant, ((6,), 2.5), 1e-3, (), None, 0,
                                    DT), look)
    assert seen["below the bar"], "the witness always cleared the stall bar"
    assert events, "the lock was never found"
    assert events[0][1] == [6] and 3.0 < events[0][0] < 3.5, events


def _replay_looking(data, look) -> list[tuple[float, list[int]]]:
    """Replay `data` into a new detector: [(time, joints newly locked)].

    `look(detector, t, events)` is called after every measurement (t in s).
    """
    detector = LockDetector(PANDA.lower, PANDA.upper)
    events: list[tuple[float, list[int]]] = []
    for kind, t, values in data.events:
        if kind == "command":
            detector.command(t, values)
            continue
        update = detector.measure(t, values)
        if update.locked:
            events.append((t, list(update.locked)))
        look(detector, t, events)
    return events


def _turning(t: float) -> np.ndarray:
    """Moving targets, then every joint but 6 at -0.3 rad/s, turning to +0.3 at 3 s."""
    if t < 2.5:
        return moving_targets(t)
    command = np.full(7, -0.3 if t < 3.0 else 0.3)
    command[5] = 0.2
    return command


def test_a_lock_as_the_others_turn_is_witnessed_by_the_lags_that_predict_the_turn() -> None:
    """Joint 6 locks at 3 s as every other joint turns: found within 0.16 s.

    For as long as the plausible lags disagree on where the turning joints are (their
    weakest prediction 0), the arm moving as the shorter lags predict vouches for the
    plant (`rules.vouching`); judged against the weakest prediction it did not, and the
    lock waited for the lags to agree (0.19 s on this plant).
    """
    seen = {"vouched at a loss": False}

    def look(detector: LockDetector, t: float, events: list) -> None:
        others = [e for j, e in enumerate(detector.joints) if j != 5]
        if detector.joints[5].evidence_since is not None and not events:
            seen["vouched at a loss"] |= all(e.commanded == 0.0 for e in others)

    plant = PlantConfig(latency=0.03, response_time=0.02)
    events = _replay_looking(record(_turning, 3.6, plant, ((5,), 3.0), 1e-3, (), None, 0, DT),
                             look)
    assert events, "the lock was never found"
    assert events[0][1] == [5] and 3.0 < events[0][0] < 3.16, events
    assert seen["vouched at a loss"], "the lags never disagreed on every other joint"


def _slowing(t: float) -> np.ndarray:
    """Moving targets, then 0.3 rad/s, joint 6 at 0.25 rad/s slowing to 0.06 at 3.02 s."""
    if t < 2.5:
        return moving_targets(t)
    command = np.full(7, 0.3)
    command[5] = 0.25 if t < 3.02 else 0.06
    return command


@pytest.mark.parametrize(("latency", "response"), [(0.0, 0.0), (0.05, 0.05)])
def test_a_lock_whose_command_slows_under_the_fresh_bar_is_still_found(
        latency: float, response: float) -> None:
    """Joint 6 locks at 3 s and is commanded 0.06 rad/s from 3.02 s: found within 0.2 s.

    0.06 rad/s is under twice `confidence` standard errors, the bar for a stall to begin,
    so the lock is found only because a stall under way stays observable down to one
    (`rules.is_observable`); without that hysteresis it never is.
    """
    seen = {"under the bar": False}

    def look(detector: LockDetector, t: float, events: list) -> None:
        joint = detector.joints[5]
        if len(events) == 1 and events[0][0] == t:  # the update that found it
            bar = 2 * DetectorConfig().confidence * joint.standard_error
            seen["under the bar"] = abs(joint.commanded) < bar

    plant = PlantConfig(latency=latency, response_time=response)
    events = _replay_looking(record(_slowing, 3.6, plant, ((5,), 3.0), 1e-3, (), None, 0, DT),
                             look)
    assert events, "the lock was never found"
    assert events[0][1] == [5] and 3.0 < events[0][0] < 3.2, events
    assert seen["under the bar"], "found while the command still cleared the fresh stall's bar"


def test_no_decision_at_start_up_until_the_plant_follows() -> None:
    detector = LockDetector(PANDA.lower, PANDA.upper)
    for k in range(100):  # commanded, never moving: not one lock, and why
        detector.command(k * DT, np.full(7, 0.3))
        assert detector.measure((k + 1) * DT, START) == Update()
    assert detector.not_observing is not None or detector.plant_fault is not None
    assert detector.locked == {}


def test_small_commands_are_unobservable() -> None:
    detector, events = run(lambda t: np.full(7, 0.02), 3.0, lock=((1,), 2.0))
    assert events == [] and not detector.joints[1].observable
    assert not detector.joints[1].candidate


def test_a_stall_at_a_joint_limit_is_not_a_lock() -> None:
    push = np.full(7, 0.1)
    push[3] = 0.3  # joint 4 runs into its upper limit (-0.0698) after ~7 s
    detector, events = run(lambda t: push, 9.0)
    assert events == []
    assert detector.joints[3].at_limit
    # Not a candidate either: a task-space suspect is refused there (the check "still
    # while commanded" alone confirmed it, a false lock in the campaign).
    assert not detector.joints[3].candidate
    answer = detector.confirm(3, -0.07, 9.0)
    assert answer.decision == "refused" and answer.evidence.at_limit
    assert detector.locked == {}


def _chattering_at_the_limit(t: float) -> np.ndarray:
    """Joint 4 driven into its upper limit, then commanded to and fro against it.

    The null space near a stretched elbow does this (seed 75 of the boundary campaign):
    +0.3 rad/s for 0.1 s, which the limit stops, then -0.12 for 0.15 s, which moves it.
    """
    if t < 1.0:
        return np.full(7, 0.3)
    if t < 3.0:
        command = np.full(7, 0.3)
        command[3] = 1.0
        return command
    command = np.zeros(7)
    command[3] = 0.3 if (t - 3.0) % 0.25 < 0.1 else -0.12
    return command


def test_a_joint_chattering_against_its_limit_is_not_a_slow_stall() -> None:
    """The boundary campaign's one false lock, replayed.

    Over the slow span the model's displacement was positive and the joint's not: the
    limit took the positive part. Now the limit anywhere in the span refuses it.
    """
    data = record(_chattering_at_the_limit, 4.55, PlantConfig(latency=0.02, response_time=0.03))
    detector = LockDetector(PANDA.lower, PANDA.upper)
    assert replay(data, detector) == []
    q = [values for kind, _, values in data.events if kind == "measure"][-1]
    assert q[3] > PANDA.upper[3] - 0.02  # it did reach the limit
    answer = detector.confirm(3, float(q[3]), 4.55)
    assert answer.decision == "refused", answer.evidence
    assert detector.locked == {}


def test_a_lock_without_a_witness_is_a_candidate_the_detector_does_not_declare() -> None:
    """Only the locked joint commanded: no following joint vouches for the plant.

    The detector declares nothing (Maciejewski et al.'s stuck arm); its candidate flag is what
    the monitor confirms a task-space suspect with.
    """
    alone = np.zeros(7)
    alone[1] = 0.2
    detector, events = run(lambda t: alone, 3.0, lock=((1,), 2.0))
    assert events == []
    assert detector.joints[1].candidate
    assert not any(e.candidate for k, e in enumerate(detector.joints) if k != 1)
    assert detector.confirm(0, 0.0, 3.0).decision == "refused"  # still, but not commanded
    answer = detector.confirm(1, -0.3, 3.0)  # the task channel's suspect: confirmed
    assert answer.decision == "locked" and answer.evidence.candidate
    assert detector.locked == {1: -0.3}
    assert detector.confirm(1, -0.3, 3.1).decision == "known"


def test_a_suspect_explained_by_contact_is_refused_unless_its_drive_gives_no_torque() -> None:
    """The veto (contact) refuses the suspect; not when the joint's drive is torqueless."""
    alone = np.zeros(7)
    alone[1] = 0.2
    asked: list[list[int]] = []

    def wall(joints: list[int], _since: float) -> str:
        asked.append(joints)
        return "the tool against a wall"

    detector, _ = run(lambda t: alone, 3.0, lock=((1,), 2.0))
    assert detector.joints[1].candidate
    assert detector.confirm(1, -0.3, 3.0, wall).decision == "refused"
    assert asked == [[1]] and detector.locked == {}
    detector.beyond_contact[1] = True  # its drive silent at the last update (`Drives`)
    assert detector.confirm(1, -0.3, 3.0, wall).decision == "locked"
    assert asked == [[1]] and detector.locked == {1: -0.3}


def test_a_torqueless_joint_joining_joints_stalled_in_contact_leaves_their_veto_standing(
        ) -> None:
    """Contact explains nothing of a drive without torque, and still explains the others.

    A tool pushed along a wall: panda_joint1 and panda_joint5 stalled by it for 30 ms
    (vetoed), then panda_joint2, its weight carried by the wall and its drive silent
    (`torqueless`), stalls too. The veto is asked about the first two only and keeps them
    undeclared; the silent one is declared once its own evidence has lasted.
    """
    from ft_core.detection.evidence import Disturbance, JointEvidence, declare_locks

    joints = [JointEvidence() for _ in range(7)]
    asked: list[list[int]] = []

    def wall(stalled: list[int], _since: float) -> str:
        asked.append(stalled)
        return "the tool against a wall"

    spared = [False, True] + [False] * 5
    declared = []
    for k in range(40):  # 4 ms updates; persistence 20 ms, no settling time
        now = 0.004 * k
        supported = [j in ((0, 4) if now < 0.03 else (0, 1, 4)) and joints[j].locked_at is None
                     for j in range(7)]
        newly, reason = declare_locks(joints, supported, np.zeros(7), now,
                                      Disturbance(joints, now, -1.0), 0.02, 0.0, wall,
                                      spared)
        assert reason == "the tool against a wall"
        declared += [(round(now, 3), j) for j in newly]
    assert declared == [(0.052, 1)]  # evidence from 0.032 s; nothing else, ever
    assert asked and all(stalled == [0, 4] for stalled in asked)


@pytest.mark.parametrize("carried", [True, False], ids=["carried", "not carried"])
def test_a_silent_drive_is_left_to_the_contact_test_while_the_tool_is_pushed(
        carried: bool) -> None:
    """A drive idle while an obstacle carries its joint's weight is asked about as any other.

    Panda joints 1, 2 and 5 held still at 0.2 rad/s commanded, their drives pushing, the
    drive of joint 2 silent (under a tenth of its gravity torque). While the tool is pushed
    (`Drives.carried`) the obstacle may carry that weight: the contact test is asked about
    all three and, explaining them, keeps them undeclared. With no push on the tool the
    silent drive gives no torque, which no contact explains: joint 2 alone is declared.
    """
    from ft_core.detection.drives import Drives

    still = (0, 1, 4)
    data = record(lambda t: np.full(7, 0.2), 1.5, lock=(still, 0.5))
    silent = np.zeros(7, bool)
    silent[1] = True
    pushing = np.zeros(7, bool)
    pushing[list(still)] = True
    drives = Drives(silent, pushing, carried=carried)
    asked: list[list[int]] = []

    def wall(stalled: list[int], _since: float) -> str:
        asked.append(stalled)
        return "the tool against a wall"

    detector, declared = LockDetector(PANDA.lower, PANDA.upper), []
    for kind, t, values in data.events:
        if kind == "command":
            detector.command(t, values)
        else:
            declared += detector.measure(t, values, veto=wall, drives=drives).locked
    assert asked, "the stalls never came to the contact test"
    if carried:
        assert declared == [] and [0, 1, 4] in asked
    else:
        assert declared == [1] and all(1 not in stalled for stalled in asked)


def test_joint_state_gaps_and_out_of_order_data_give_no_decision() -> None:
    detector = LockDetector(PANDA.lower, PANDA.upper)
    detector.command(0.0, np.full(7, 0.5))
    for t in (0.0, 0.004, 0.2, 0.204, 0.208):  # a 0.2 s gap: no positions in most windows
        detector.command(t, np.full(7, 0.5))
        assert detector.measure(t, START) == Update()
    assert detector.measure(0.1, START) == Update()  # out of order: ignored
    assert detector.latest_time == 0.208


@pytest.mark.parametrize(("dt", "every"), [(1 / 1000, 3), (1 / 500, 2), (1 / 250, 1)])
def test_a_fast_stream_is_judged_at_most_every_decision_period(dt: float, every: int,
                                                                 monkeypatch) -> None:
    """Every measurement goes into the window; decisions come at most every 2.5 ms."""
    decided = []
    update = LockDetector._update

    def counted(self, now, *args):
        decided.append(now)
        return update(self, now, *args)

    monkeypatch.setattr(LockDetector, "_update", counted)
    detector, events = run(moving_targets, 2.0, dt=dt)
    assert len(decided) > 100 and events == [] and detector.not_observing is None
    spacing = np.diff(decided)
    assert spacing.min() >= DECISION_PERIOD
    assert np.median(spacing) == pytest.approx(every * dt)


@pytest.mark.parametrize("joint", [1, 3, 5])
def test_a_lock_in_a_1_khz_stream_is_found_as_fast_as_at_250_hz(joint: int) -> None:
    plant = PlantConfig(latency=0.01, response_time=0.02)

    def commands(t: float) -> np.ndarray:
        return moving_targets(t) if t < 2.5 else np.full(7, 0.2)

    delays = {}
    for dt in (1 / 250, 1 / 1000):
        _, events = run(commands, 4.0, plant, lock=((joint,), 3.5), seed=joint, dt=dt)
        assert events, f"joint {joint} not detected at {1 / dt:.0f} Hz"
        time, joints = events[0]
        assert joints == [joint]
        delays[dt] = time - 3.5
    assert delays[1 / 1000] <= delays[1 / 250] + DECISION_PERIOD


def test_a_blind_caller_forbids_decisions() -> None:
    detector, _ = run(lambda t: np.full(7, 0.2), 2.0)
    assert detector.not_observing is None
    detector.command(2.0, np.full(7, 0.2))
    assert detector.measure(2.004, START, blind="nobody listens") == Update()
    assert detector.not_observing == "nobody listens"


def test_declared_locks_and_reset() -> None:
    detector = LockDetector(PANDA.lower, PANDA.upper)
    detector.lock(4, float("nan"), 1.0)
    assert detector.fill_unknown_positions(START)
    assert detector.locked == {4: START[4]}
    detector.reset()
    assert detector.locked == {}


@pytest.mark.parametrize("field", ["window", "ratio", "confidence", "min_samples", "memory"])
def test_invalid_configurations_are_rejected(field: str) -> None:
    with pytest.raises(ValueError, match=field):
        DetectorConfig(**{field: 0})


@pytest.mark.parametrize("start", [0.0, 1.7e9])  # simulated time, and ROS time since 1970
def test_window_sums_match_the_window(start: float) -> None:
    """Issue 28: the running sums the fits read equal sums over the window's entries.

    Through many windows, so that the entries move to the front of the arrays (and the
    sums are made afresh) several times, with every model's predictions; and the
    predictions stored are the command history's (computed here again in numpy).
    """

    def predictions(history, times: np.ndarray) -> np.ndarray:
        """(latencies x response times, n): U(t) - T y_T(t) from the entry in force at t."""
        rows = []
        for t in times:
            k = history.start + max(int(np.searchsorted(
                history.times[history.start:history.end], t, side="right")) - 1, 0)
            h, u = max(t - history.times[k], 0.0), history.values[k]
            for T, rate, lag in zip(history.response_times, history.rate, history.lagged[k],
                                    strict=True):
                rows.append(history.integrals[k] + h * u - T * (u + (lag - u) * np.exp(-h * rate)))
        return np.array(rows)

    rng = np.random.default_rng(3)
    detector = LockDetector(np.full(7, -3.0), np.full(7, 3.0))
    samples, history = detector._samples, detector.history
    compacted = 0
    for k in range(1000):
        time = start + 0.001 * k + 2e-4 * rng.random()
        detector.command(time - 5e-4, rng.normal(scale=0.3, size=7))
        before = samples.start
        detector.measure(time, rng.normal(size=7))
        compacted += samples.start < before
        times, _positions, predicted = samples.window()
        assert k < 100 or times.size >= 70
        np.testing.assert_allclose(samples.predicted_sum, predicted.sum(axis=0), atol=1e-10)
        timed = np.einsum("s,smj->mj", times - samples.base, predicted)
        np.testing.assert_allclose(samples.timed_sum, timed, atol=1e-10)
        np.testing.assert_allclose(predicted[-1], predictions(history, time - detector._latencies),
                                   rtol=1e-12, atol=1e-12)
    assert compacted >= 4  # summed afresh along the way


def test_odd_input_types_compile_nothing_in_the_control_loop() -> None:
    """An integer time or a strided vector must not make numba compile a new version.

    That takes seconds, inside the callback that took the joint state or the command.
    """
    from ft_core import detection

    def feed(detector: LockDetector, times, commands, positions) -> None:
        for t, u, q in zip(times, commands, positions, strict=True):
            detector.command(t, u)
            detector.measure(t + 0.5, q)

    detector = LockDetector(np.full(7, -3.0), np.full(7, 3.0))
    feed(detector, [0.0, 1.0], [np.full(7, 0.1)] * 2, [np.zeros(7)] * 2)
    compiled = {kernel: len(kernel.signatures)
                for kernel in (detection._ingest, detection._add_command)}
    assert all(compiled.values()), "the kernels never ran"
    strided = np.zeros((7, 3))
    feed(detector, [2, 3], [strided[:, 1] + 0.1, strided[:, 1]], [strided[:, 2]] * 2)
    assert {kernel: len(kernel.signatures) for kernel in compiled} == compiled
    assert detector.latest_time == 3.5


@pytest.mark.parametrize("brake", [3.0, 0.0], ids=["braked", "explained"])
def test_a_stall_its_drives_torque_explains_is_no_lock(brake: float) -> None:
    """Panda joint 2 stops at 1 s while commanded 0.2 rad/s, the others moving on.

    The efforts are those the measured motion needs (tau = M qdd + C qd + g at the
    detector's own velocities and accelerations of the update before: a healthy servo
    that fell behind, as one undershooting a falling command does), plus `brake` N m
    along the command on joint 2 once stopped: the push a brake takes. Only a drive
    pushing against something is held by a lock (`Drives.braking`: 1.74 N m for this
    shoulder); without that rule the explained stall is declared as the braked one is.
    """
    from ft_core import robots
    from ft_core.detection.drives import Drives

    inertial = robots.load("panda_inertial")
    data = record(lambda t: np.full(7, 0.2), 2.0, lock=((1,), 1.0))
    detector, declared = LockDetector(PANDA.lower, PANDA.upper), []
    velocity, acceleration = np.zeros(7), np.zeros(7)
    for kind, t, values in data.events:
        if kind == "command":
            detector.command(t, values)
            continue
        inertia, nonlinear = inertial.dynamics(values, velocity)
        effort = inertia @ acceleration + nonlinear
        effort[1] += brake if t > 1.0 else 0.0
        gravity = inertial.gravity(values)
        drives = Drives(np.zeros(7, bool), np.zeros(7, bool), effort - gravity,
                        np.abs(gravity), inertial, values, effort)
        declared += [(round(t, 3), j) for j in detector.measure(t, values, drives=drives).locked]
        velocity = np.array([e.measured for e in detector.joints])
        if detector.acceleration is not None:
            acceleration = detector.acceleration
    if brake:
        assert [j for _, j in declared] == [1]
        assert 1.0 < declared[0][0] < 1.2
    else:
        assert declared == []
