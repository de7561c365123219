"""ft_core.detection.drives: what the efforts say, a drive that gives no torque or pushes in vain.

Silence (an effort under a tenth of the gravity torque while the joint falls) lifts the
lock detector's allowance for servo transients, so a free swing is named within 200 ms
of the lost torque on the Panda joints gravity turns most (a healthy drive silent while
its command accelerates downhill, its joint following: tests/unit/test_physics_loop.py).
A push (an external torque of 0.3 of the effort limit) on a joint that stays still while
commanded names a lock the velocity test misses: two joints stalled at once (commands
that change sign faster than the plant's plausible lags: test_physics_loop.py too).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from ft_core import robots, swing
from ft_core.detection import DetectorConfig, drives, rules
from ft_core.detection.contact import ContactWatch
from ft_core.detection.drives import UNANSWERED_TIME, Drives, DriveWatch
from ft_core.faults import Fault, FaultKind
from ft_core.health import Health
from ft_core.monitor import Monitor, MonitorConfig
from ft_core.physics import PhysicsPlant
from ft_sim.closed_loop import DRIVERS, NOISE, ClosedLoop
from models import panda_from_rest

pytestmark = pytest.mark.unit

PANDA = robots.load("panda_inertial", tip_link="panda_link8")
Q = PANDA.home()
DT = 0.004  # s, the engine period


def _watch(effort_of, step: np.ndarray, cycles: int,
           carried: bool = False) -> list[np.ndarray]:
    """The silent flags of a DriveWatch over `cycles` updates, q moving by `step` each."""
    watch, q, flags = DriveWatch(PANDA), Q.copy(), []
    for k in range(cycles):
        flags.append(watch.update(k * DT, q, effort_of(q), carried).silent)
        q = q + step
    return flags


def _falling(joint: int) -> np.ndarray:
    """A step (rad per cycle) of `joint` the way gravity turns it, 1 mrad."""
    step = np.zeros(PANDA.n)
    step[joint] = 1e-3 * swing.falling_directions(PANDA, Q)[joint]
    return step


def test_a_drive_without_torque_whose_joint_falls_is_silent_after_its_time() -> None:
    gravity = lambda q: PANDA.gravity(q)  # noqa: E731

    def lost(q: np.ndarray) -> np.ndarray:
        effort = gravity(q)
        effort[1] = 0.0
        return effort

    flags = _watch(lost, _falling(1), 40)
    first = next(k for k, f in enumerate(flags) if f.any())
    assert np.flatnonzero(flags[first]).tolist() == [1]
    assert drives.SILENT_TIME - 1e-9 <= first * DT <= 0.2
    # The same drive giving its gravity torque, or the joint going uphill: never.
    assert not any(f.any() for f in _watch(gravity, _falling(1), 40))
    assert not any(f.any() for f in _watch(lost, -_falling(1), 40))
    # While a force on the tool (a wall lately) may carry the joint's weight, only once it
    # has fallen further than a wall would let it.
    carried = _watch(lost, _falling(1), 40, carried=True)
    fell = next(k for k, f in enumerate(carried) if f.any())  # mrad, 1 a cycle
    assert fell * 1e-3 == pytest.approx(drives.CARRIED_FALL, abs=1.1e-3)
    assert not any(f.any() for f in _watch(lost, _falling(1), 25, carried=True))


def test_a_joint_gravity_does_not_turn_is_never_silent() -> None:
    flags = _watch(lambda q: np.zeros(PANDA.n), np.full(PANDA.n, 1e-3), 40)
    assert not any(f[0] or f[6] for f in flags)  # vertical axis; the flange


@pytest.mark.parametrize("driver", list(DRIVERS))
@pytest.mark.parametrize("joint", [1, 3, 4])
def test_a_free_swing_is_named_within_200_ms_and_braked_by_the_driver(driver: str,
                                                                      joint: int) -> None:
    loop = ClosedLoop("position", DRIVERS[driver], seed=joint)
    loop.run(4.0)
    loop.run(4.5, stop=lambda: min(abs(loop.plant.qd[joint]), abs(loop.sent[joint])) > 0.1)
    assert loop.declared == [], "declared in healthy motion"
    start = loop.t
    loop.plant.inject(joint, Fault(FaultKind.FREE_SWING, PANDA.joint_names[joint]))
    loop.run(1.0, stop=lambda: bool(loop.declared))
    assert loop.declared, "the swing was not named"
    when, names = loop.declared[0]
    assert names == [PANDA.joint_names[joint]]
    assert when - start <= 0.2
    assert loop.monitor.board.states[joint] == Health.FREE_SWINGING
    assert loop.plant.held == {joint}  # the driver braked it on the monitor's word
    at = loop.plant.q[joint]
    loop.run(2.0)
    assert abs(loop.plant.q[joint] - at) < 1e-3
    assert [s for j, s in enumerate(loop.monitor.board.states) if j != joint] == \
        [Health.HEALTHY] * (PANDA.n - 1)
    loop.close()


def test_a_shoulder_left_a_quarter_of_its_torque_is_named_free_swinging_as_it_falls() -> None:
    """Panda joint 2 at authority 0.25 behind the fast driver sags, then falls to its stop.

    Its drive's shortfall against gravity reads, statically, as a force on the tool (the
    contact veto); the arm's own motion explains it (`contact.in_contact`'s residual), so
    the fall is named free-swinging and braked long before the stop's impact, and no
    other joint is declared.
    """
    loop = ClosedLoop("position", DRIVERS["fast"], seed=1)
    fastest = 0.0  # rad/s, the shoulder's fastest fall before it was named
    try:
        loop.run(4.0)
        loop.run(4.5, stop=lambda: min(abs(loop.plant.qd[1]), abs(loop.sent[1])) > 0.1)
        loop.plant.inject(1, Fault(FaultKind.AUTHORITY, "panda_joint2", severity=0.25))
        loop.goal_period = 3.0
        for _ in range(round(6.0 / loop.dt)):
            loop.run(loop.dt)
            if loop.declared:
                break
            fastest = max(fastest, abs(loop.plant.qd[1]))
        assert loop.declared, "the fall was not named"
        assert loop.declared[0][1] == ["panda_joint2"]
        assert loop.monitor.board.states[1] == Health.FREE_SWINGING
        assert fastest < 2.0  # named as it fell, long before its stop
        loop.run(3.0)
        assert [j for j, s in enumerate(loop.monitor.board.states) if s != Health.HEALTHY] \
            == [1]
        assert loop.plant.held == {1}
    finally:
        loop.close()


def test_a_pushed_joint_that_stays_still_while_commanded_is_held() -> None:
    positions = np.zeros((20, 3))
    positions[:, 1] = np.linspace(0.0, 0.02, 20)  # joint 1 moves 20 mrad
    plausible = np.array([[0.1, 0.1, 0.0], [-0.1, 0.1, 0.0]])  # joint 2 not commanded
    pushing = np.array([True, True, True])
    assert rules.held_still(pushing, positions, plausible, 0.05, 0.008).tolist() == \
        [True, False, False]
    assert not rules.held_still(~pushing, positions, plausible, 0.05, 0.008).any()


@pytest.mark.parametrize("driver", list(DRIVERS))
def test_two_locks_at_once_are_named_by_their_drives_push(driver: str) -> None:
    """Joints 2 and 5 locked together: no joint left moving as commanded to vouch for them.

    (One lock under commands that reverse within the plant's lags:
    tests/unit/test_physics_loop.py.)
    """
    joints = [1, 4]
    loop = ClosedLoop("position", DRIVERS[driver], seed=joints[0])
    try:
        loop.run(4.0)
        first = joints[0]
        loop.run(4.5, stop=lambda: min(abs(loop.plant.qd[first]), abs(loop.sent[first])) > 0.1)
        start = loop.t
        for j in joints:
            loop.plant.lock(j)
        loop.goal_period = 3.0
        loop.run(2.0, stop=lambda: len(loop.monitor.locked) == len(joints))
        named = {PANDA.joint_names[j] for j in joints}
        assert set(loop.monitor.locked) == named, loop.monitor.locked
        assert loop.declared[-1][0] - start <= 0.4
        assert any("held still while commanded" in h.evidence
                   for h in loop.monitor.health().values())
        loop.run(4.0)
        assert set(loop.monitor.locked) == named  # and no healthy joint after them
    finally:
        loop.close()


def test_a_drive_that_works_against_its_joints_motion_does_not_let_it_go() -> None:
    """Joint 0 dragged (its servo pulls back), 1 without torque falling, 2 a fall held short."""
    none = np.zeros(3, bool)
    gravity = np.array([10.0, 10.0, 10.0])  # N m, |g(q)|
    velocity = np.array([0.1, 0.1, -0.1])  # rad/s
    external = np.array([-0.5, 10.0, -0.5])  # N m, tau - g(q): -g for the free joint
    assert Drives(none, none, external, gravity).let_go(velocity).tolist() == \
        [False, True, False]
    assert Drives(none, none).let_go(velocity).all()  # no efforts: the motion alone


def test_a_silent_joint_resting_on_the_stop_gravity_turns_it_into_moves_on_its_own() -> None:
    lower, upper = np.full(4, -1.0), np.full(4, 1.0)
    latest = np.array([0.995, -0.995, 0.995, 0.5])  # rad: on the upper stop, the lower...
    falling = np.array([1.0, 1.0, 1.0, 1.0])  # gravity turns every joint towards +
    silent = np.array([True, True, False, True])
    still = np.zeros(4)  # rad/s, none moves
    plausible = np.zeros((1, 4))
    everyone = np.ones(4, bool)
    own = rules.silent_and_on_its_own(silent, silent, still, plausible, np.full(4, 1e-3),
                                      everyone, everyone, falling, (latest, lower, upper),
                                      0.05, 5.0, 0.01)
    # Only joint 0: joint 1's stop is not the one gravity turns it into, joint 2's drive
    # gives torque, joint 3 is nowhere near a stop.
    assert own.tolist() == [True, False, False, False]


#: (t s, |command in force - velocity| rad/s, departed since s or NaN, not observing why)
Step = tuple[float, float, float, str | None]


def _through_the_monitor(q: np.ndarray, driver: str, joint: int, fails_at: float,
                         command_at: Callable[[float], np.ndarray], seed: int,
                         paused: tuple[float, float] = (math.inf, math.inf),
                         ) -> tuple[list[str], float, Monitor, list[Step]]:
    """3 s of the physics plant from `q` behind `driver`, commanded through a monitor.

    `command_at(t)`: the controller's command at t (rad/s), none sent within `paused`
    (from, to; s); `joint` loses its torque at `fails_at` s; 1e-3 rad of noise (`seed`)
    on the positions, the drives' torques as efforts. Returns the monitor's events, when
    (s) the first came, the monitor, and per step (t, |command in force at the plant -
    velocity| of `joint`, rad/s, since when (s) the detector has seen `joint` depart where
    its drive leaves that unanswered, NaN elsewhere, and why the detector did not observe
    at the step's measurement, None where it did).
    """
    monitor = Monitor(PANDA, DetectorConfig(), MonitorConfig(), None)
    plant = PhysicsPlant(PANDA, q, DRIVERS[driver])
    rng = np.random.default_rng(seed)
    events: list[str] = []
    off: list[Step] = []
    first = np.inf
    t = 0.0
    for _ in range(round(3.0 / DT)):
        if abs(t - fails_at) < DT / 2:
            plant.inject(joint, Fault(FaultKind.FREE_SWING, PANDA.joint_names[joint]))
        change = monitor.observe(plant.q + rng.normal(0.0, NOISE, PANDA.n), t,
                                 effort=plant.torque)
        reason = monitor.detector.not_observing
        if change.events and not events:
            first = t
        events += change.events
        if not paused[0] <= t < paused[1]:
            plant.command(t, monitor.command(command_at(t), t))
        t += DT
        plant.step(t)
        detector = monitor.detector
        off.append((t, abs(plant.path.in_force(t)[joint] - plant.qd[joint]),
                    detector.departed_since[joint] if detector.unanswered[joint] else np.nan,
                    reason))
    monitor.close()
    return events, first, monitor, off


@pytest.mark.parametrize("driver", list(DRIVERS))  # stops on the pause; holds the command
@pytest.mark.parametrize("fails", [True, False])
def test_a_free_swing_while_the_command_stream_is_paused_is_named_within_200_ms(
        driver: str, fails: bool) -> None:
    """Panda joint 6 loses its torque 20 ms into a 0.5 s pause of the monitor's commands.

    The detector predicts nothing then (`rules.not_observing`), nor while it settles
    after the stream restarts; a drive silent while its joint falls faster than every
    command and than rest is named all the same (`rules.falls_past_every_command`),
    while the stream is still paused. With the same pause and no fault, nothing.
    """
    q = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 1.2, 0.8])
    joint, pause = 5, (1.5, 2.0)
    assert swing.falling_directions(PANDA, q)[joint] != 0  # gravity turns it

    def command_at(t: float) -> np.ndarray:
        w = 0.2 * math.sin(2 * math.pi * t / 0.8)
        return np.array([w, 0.0, -w, 0.1 * w, -w, w, 0.0])

    fails_at = pause[0] + 0.02 if fails else math.inf
    events, first, monitor, _ = _through_the_monitor(q, driver, joint, fails_at, command_at,
                                                     4, pause)
    if not fails:
        assert events == []
        return
    assert events, "the swing was not named"
    assert events[0].startswith("joint panda_joint6 free-swinging")
    assert first - fails_at <= 0.2
    assert first < pause[1]  # named while the commands were away
    assert [j for j, s in enumerate(monitor.board.states) if s != Health.HEALTHY] == [joint]


def test_a_free_swing_before_the_plant_is_seen_following_again_is_named_then() -> None:
    """Panda joint 6 loses its torque 180 ms after a 0.5 s pause of the commands ended.

    The detector has settled after the restart and waits to see the plant follow
    (`plant not yet seen following commands`, 0.2 s); the silent drive's fall is named in
    that wait (`blind_falls`), within 100 ms, not once the plant is seen following.
    """
    q = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 1.2, 0.8])
    joint, pause, fails_at = 5, (1.5, 2.0), 2.18

    def command_at(t: float) -> np.ndarray:
        w = 0.2 * math.sin(2 * math.pi * t / 0.8)
        return np.array([w, 0.0, -w, 0.1 * w, -w, w, 0.0])

    events, first, monitor, steps = _through_the_monitor(q, "fast", joint, fails_at,
                                                         command_at, 4, pause)
    waiting = [t - DT for t, *_, reason in steps
               if reason == "plant not yet seen following commands"]
    assert waiting and min(waiting) < fails_at, "no wait to see the plant follow"
    assert events, "the swing was not named"
    assert events[0].startswith("joint panda_joint6 free-swinging")
    assert first - fails_at <= 0.1
    assert any(abs(t - first) < DT / 2 for t in waiting)  # named in the wait
    assert [j for j, s in enumerate(monitor.board.states) if s != Health.HEALTHY] == [joint]


def _onto_the_stop(driver: str, fails_at: float) -> tuple[list[str], float, Monitor]:
    """Panda joint 2 driven at 0.1 rad/s onto its upper stop, losing its torque at `fails_at` s.

    Leaning out, so gravity turns it into that stop; joints 1, 5 and 7 move meanwhile.
    Returns the monitor's events, the s from the loss to the first, and the monitor.
    """
    q = PANDA.home()
    q[1] = PANDA.upper[1] - 0.2
    assert swing.falling_directions(PANDA, q)[1] > 0  # gravity turns it into that stop
    command = np.zeros(PANDA.n)
    command[[0, 1, 4, 6]] = [0.3, 0.1, 0.3, 0.3]
    events, first, monitor, _ = _through_the_monitor(
        q, driver, 1, fails_at, lambda t: command, 3)
    return events, first - fails_at, monitor


@pytest.mark.parametrize("driver", list(DRIVERS))
def test_a_shoulder_falling_as_the_monitor_begins_to_observe_is_named_free_swinging(
        driver: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Panda joint 2, leaning back near its lower stop, loses its torque 1.6 s in.

    The monitor has just begun to observe: its accelerations are not yet known, and the
    contact watch reads the fall, a drive giving nothing while gravity turns its joint, as
    a force at the tool (`ContactWatch.lately`). A wall that carries a joint's weight
    holds it up; one that has fallen `drives.CARRIED_FALL` is not held, and its drive is
    silent: named free-swinging within 200 ms.
    """
    q = np.array([-1.864, -1.666, 1.346, -2.165, -1.209, 0.824, 0.783])
    assert swing.falling_directions(PANDA, q)[1] < 0  # gravity turns it towards that stop
    fails_at = 1.6
    touched: list[float] = []
    looked = ContactWatch.lately

    def lately(watch: ContactWatch, *args: object, **kwargs: object) -> bool:
        seen = looked(watch, *args, **kwargs)
        if seen:
            touched.append(float(args[3]))  # type: ignore[arg-type]
        return seen

    monkeypatch.setattr(ContactWatch, "lately", lately)

    def command_at(t: float) -> np.ndarray:
        if t < fails_at - 0.06:
            w = 0.2 * math.sin(2 * math.pi * t / 0.8)
            return np.array([w, 0.0, -w, 0.01, -w, w, 0.0])
        if t < fails_at + 0.03:  # a new goal's first commands
            return np.array([0.11, -0.22, 0.43, 0.15, -0.02, 0.0, 0.0])
        return np.array([0.35, 0.48, 0.68, 0.3, 0.0, -0.17, 0.0])

    events, first, monitor, _ = _through_the_monitor(q, driver, 1, fails_at, command_at, 0)
    assert events, "the swing was not named"
    assert events[0].startswith("joint panda_joint2 free-swinging")
    assert first - fails_at <= 0.2
    assert [j for j, s in enumerate(monitor.board.states) if s != Health.HEALTHY] == [1]
    if driver == "slow":  # the case: the fall read as a contact before it was named
        assert any(fails_at < t < first for t in touched), touched


@pytest.mark.parametrize("driver", list(DRIVERS))
@pytest.mark.parametrize("fails_at", [1.85, 1.93])  # s: 17-19 and 9-11 mrad short of it
def test_a_free_swing_that_lands_on_its_stop_is_named_and_the_joints_it_drags_are_not(
        driver: str, fails_at: float) -> None:
    """Its fall reaches the stop before it counts as motion on its own, and shakes joint 4.

    Joint 2 rests on the stop without torque: free-swinging. Joint 4's servo, dragged by
    the fall, works against its motion: healthy (`Drives.let_go`).
    """
    events, first, monitor = _onto_the_stop(driver, fails_at)
    assert events, "the swing was not named"
    assert len(events) == 1, events
    assert events[0].startswith("joint panda_joint2 free-swinging")
    assert "its drive giving no torque" in events[0]
    assert first <= 0.2
    assert [j for j, s in enumerate(monitor.board.states) if s != Health.HEALTHY] == [1]


def _coasting(driver: str, fails_at: float,
              ) -> tuple[list[str], float, Monitor, tuple[float, float, float]]:
    """Panda joint 1 at 0.3 rad/s loses its torque at `fails_at` s; at 1.8 s its command turns.

    Joints 2, 5 and 7 move throughout (witnesses), all four commands vary by 0.15 rad/s
    at 2 Hz for the first 1.2 s (the plant's lag identified), joint 1's ramps from 0.3 to
    -0.3 rad/s at 2 rad/s^2 from 1.8 s on. Returns the monitor's events, the s from when
    joint 1's velocity, after the loss, first differed by 0.1 rad/s from the command in
    force at the plant to the first event, the monitor, and when (s) the detector saw
    joint 1 depart, first found its drive leaving that unanswered, and named it.
    """
    def command_at(t: float) -> np.ndarray:
        command = np.zeros(PANDA.n)
        command[[0, 1, 4, 6]] = [float(np.clip(0.3 - 2.0 * (t - 1.8), -0.3, 0.3)), 0.1,
                                 0.3, 0.3]
        if t < 1.2:  # varied: the monitor identifies the plant's lag meanwhile
            command[[0, 1, 4, 6]] += 0.15 * math.sin(4 * math.pi * t)
        return command

    events, first, monitor, off = _through_the_monitor(Q, driver, 0, fails_at, command_at, 5)
    shown = min((t for t, away, _, _ in off if t >= fails_at and away >= 0.1), default=np.inf)
    found, departed = next(((t - DT, since) for t, _, since, _ in off if since == since),
                           (np.inf, np.inf))  # judged at the step's start, DT before t
    return events, first - shown, monitor, (departed, found, first)


@pytest.mark.parametrize("driver", list(DRIVERS))
def test_a_joint_gravity_does_not_turn_coasting_without_torque_is_named_as_it_departs(
        driver: str) -> None:
    """Its drive does not answer the departure from the turning command (`unanswered`).

    About a vertical axis, joint 1 without torque coasts on at 0.3 rad/s as a healthy
    joint at constant speed would; once its command turns it departs, its drive giving
    nothing: free-swinging within 250 ms of the departure (the plausible lags' spread and
    the noise first, then `UNANSWERED_TIME`), braked, no other joint named. The same
    motion with the drive healthy: nothing.
    """
    events, after, monitor, _ = _coasting(driver, 1.5)
    assert events, "the swing was not named"
    assert events[0].startswith("joint panda_joint1 free-swinging")
    assert "its drive not answering" in events[0]
    assert 0.0 <= after <= 0.25
    assert [j for j, s in enumerate(monitor.board.states) if s != Health.HEALTHY] == [0]
    events, _, monitor, _ = _coasting(driver, np.inf)
    assert monitor.detector.not_observing is None
    assert events == []


def _uphill(driver: str, shoulder: float, fails: bool) -> tuple[list[str], float]:
    """Panda joint 4 commanded towards - at 0.25 rad/s, losing its torque at 1.5 s if `fails`.

    It is uphill there; joint 2 held at `shoulder` rad, joints 1, 5 and 7 moving
    (witnesses), the commands varied for the first 1.2 s. Returns the monitor's events
    and the s from the loss to the first.
    """
    fails_at = 1.5
    q = Q.copy()
    q[[1, 3]] = shoulder, -2.0 - 0.25 * fails_at  # about where it fails
    assert swing.falling_directions(PANDA, q)[3] > 0  # uphill is towards -
    q[3] = -2.0

    def command_at(t: float) -> np.ndarray:
        command = np.zeros(PANDA.n)
        command[[0, 3, 4, 6]] = [0.3, -0.25, 0.3, 0.3]
        if t < 1.2:
            command[[0, 3, 4, 6]] += 0.1 * math.sin(4 * math.pi * t)
        return command

    events, first, _, _ = _through_the_monitor(q, driver, 3, fails_at if fails else np.inf,
                                               command_at, 11)
    return events, first - fails_at


@pytest.mark.parametrize("driver", list(DRIVERS))
@pytest.mark.parametrize(("shoulder", "answer", "within"), [
    (1.0, "its drive not answering", 0.25),  # gravity on joint 4 under 3 % of its limit
    (1.2, "its drive giving no torque", 0.1)])  # over it
def test_a_joint_without_torque_slowing_uphill_is_named_free_swinging_not_locked(
        driver: str, shoulder: float, answer: str, within: float) -> None:
    """It slows as gravity alone slows it, its drive giving nothing: not a brake's stall.

    Where gravity turns the elbow weakly (under `GRAVITY_SHARE` of its effort limit), its
    departure is left unanswered: the drive gives no torque at all, less than the gravity
    torque it is short of (`Drives.unanswered` reads min(|tau - g|, |tau|)). Where gravity
    turns it harder, its drive is quiet and it lags its uphill command the way gravity
    turns it (`rules.silent_and_on_its_own`), before it has fallen. Either way it is
    named free-swinging, where it stalls as a locked joint would; the same motion with
    the drive healthy: nothing.
    """
    events, after = _uphill(driver, shoulder, True)
    assert events, "the swing was not named"
    assert events[0].startswith("joint panda_joint4 free-swinging"), events[0]
    assert answer in events[0]
    assert 0.0 < after <= within
    events, _ = _uphill(driver, shoulder, False)
    assert events == []


def test_an_unanswered_departure_counts_from_when_it_began() -> None:
    """A departure seen before its drive is found silent counts from when it began.

    Joint 1 loses its torque as its command turns: its departure shows before its drive
    is found silent, the torque from before the loss still within the two response times
    `Drives.unanswered` looks back over. Those times show the drive giving nothing all
    along, so the departure's `UNANSWERED_TIME` counts from when it began: the joint is
    named `persistence` after its drive is found silent, not `UNANSWERED_TIME` later.
    """
    events, _, _, (departed, found, named) = _coasting("slow", 1.93)
    assert events, "the swing was not named"
    assert events[0].startswith("joint panda_joint1 free-swinging")
    assert departed <= found - UNANSWERED_TIME  # it departed that long before
    persistence = DetectorConfig().persistence
    assert found + persistence - 1e-9 <= named <= found + persistence + 2 * DT


def _starting(driver: str, fails_at: float) -> tuple[list[str], float, Monitor]:
    """The arm starts from rest (`models.panda_from_rest`); joint 1 loses its torque at `fails_at`.

    `fails_at` in s. Returns the monitor's events, when (s) the first came, and the monitor.
    """
    events, first, monitor, _ = _through_the_monitor(Q, driver, 0, fails_at,
                                                     panda_from_rest, 7)
    return events, first, monitor


@pytest.mark.parametrize("driver", list(DRIVERS))
def test_a_joint_without_torque_from_the_start_is_named_before_the_plant_was_seen_following(
        driver: str) -> None:
    """Its drive gives nothing while the others follow: the plant is live all the same.

    Joint 1 without torque from the first command stands still while the others follow:
    the plant is never seen following with no joint stalled, which the detector waits
    for before any decision. A drive giving nothing for its joint's departure, another
    joint following, shows the plant live: free-swinging within 1 s of the start (the
    window, the settling after commands begin, then `UNANSWERED_TIME`). Healthy: nothing.
    """
    events, first, monitor = _starting(driver, 0.0)
    assert events, "the swing was not named"
    assert events[0].startswith("joint panda_joint1 free-swinging")
    assert "its drive not answering" in events[0]
    assert first <= 1.0
    assert [j for j, s in enumerate(monitor.board.states) if s != Health.HEALTHY] == [0]
    events, _, monitor = _starting(driver, np.inf)
    assert monitor.detector.not_observing is None
    assert events == []


def test_a_healthy_joint_pushed_into_its_stop_is_not_named() -> None:
    events, _, monitor = _onto_the_stop("slow", np.inf)
    assert monitor.detector.not_observing is None  # it judged the motion throughout
    assert events == []


#: Joints 2 and 5 reversing at 8 rad/s^2, where their coupling loads joint 1 (a deployed
#: run's configuration, joints 3 and 6 locked).
REVERSING_Q = np.array([-1.6, 0.55, 1.89, -1.9, -0.14, 0.85, 0.78])
REVERSING = np.array([0.0, -8.0, 0.0, 0.0, -8.0, 0.0, 0.0])


def _moved(brake: float, lag: float, free: bool = False) -> np.ndarray:
    """`Drives.moved_by_others` for joint 1 at 0.03 rad/s, `lag` rad/s behind its command.

    Its drive gives what the motion needs plus `brake` times the coupling torque (a
    brake's share); `free`: its drive gives no torque beyond gravity, and the others swing
    it (its own acceleration is the coupling's).
    """
    velocity, acceleration = np.zeros(PANDA.n), REVERSING.copy()
    velocity[0] = 0.03
    inertia, nonlinear = PANDA.dynamics(REVERSING_Q, velocity)
    gravity = PANDA.gravity(REVERSING_Q)
    coupling = inertia[0] @ REVERSING
    if free:
        acceleration[0] = -coupling / inertia[0, 0]
    effort = inertia @ acceleration + nonlinear
    if free:
        effort[0] = gravity[0]
    effort[0] += brake * coupling
    commanded = velocity.copy()
    commanded[0] += lag * np.sign(coupling)
    return Drives(np.zeros(PANDA.n, bool), np.zeros(PANDA.n, bool), effort - gravity,
                  np.abs(gravity), PANDA, REVERSING_Q, effort).moved_by_others(
                      velocity, acceleration, commanded, 0.05)


def test_a_joint_whose_drive_gives_what_its_motion_needs_is_moved_by_the_others() -> None:
    """Its lag is the way the coupling torque drives it, and the residual is none of it."""
    inertia, _ = PANDA.dynamics(REVERSING_Q, np.zeros(PANDA.n))
    assert abs(inertia[0] @ REVERSING) >= drives.COUPLING_SHARE * PANDA.effort_limits[0]
    assert _moved(0.0, 0.06).tolist() == [True] + [False] * 6
    assert _moved(0.4, 0.06)[0]  # a residual within the model's error


def test_a_brake_or_a_lag_the_coupling_does_not_explain_is_not_moved_by_the_others() -> None:
    """A brake leaves a residual of the coupling's size: not the coupling's doing.

    Nor is a lag against the coupling's push, a lag within the least one (commands that
    reverse), or the motion of a drive that gives no torque (the others swing a free
    joint, with no residual); without efforts nothing is known.
    """
    assert not _moved(1.0, 0.06)[0]
    assert not _moved(-1.0, 0.06)[0]
    assert not _moved(0.0, -0.06)[0]
    assert not _moved(0.0, 0.04)[0]
    assert not _moved(0.0, 0.06, free=True)[0]
    blind = Drives(np.zeros(PANDA.n, bool), np.zeros(PANDA.n, bool))
    assert not blind.moved_by_others(np.zeros(PANDA.n), REVERSING, np.ones(PANDA.n),
                                     0.05).any()


def _braking(residual: np.ndarray, along: np.ndarray) -> np.ndarray:
    """`Drives.braking` at `REVERSING_Q`, the others reversing, with `residual` (N m) left."""
    velocity = np.full(PANDA.n, 0.01)
    inertia, nonlinear = PANDA.dynamics(REVERSING_Q, velocity)
    effort = inertia @ REVERSING + nonlinear + residual
    gravity = PANDA.gravity(REVERSING_Q)
    return Drives(np.zeros(PANDA.n, bool), np.zeros(PANDA.n, bool), effort - gravity,
                  np.abs(gravity), PANDA, REVERSING_Q, effort).braking(
                      velocity, REVERSING, along)


def test_friction_resisting_a_joint_leaves_a_push_beyond_free_motion() -> None:
    """A residual of 30 % of the effort limit (and 5 N m) along the command: resisted.

    A wrist (12 N m) whose saturated drive spends 11 N m against viscous friction is
    resisted, one spending 3 N m (a brake's bar, more than a healthy wrist leaves) is
    not, nor a shoulder (87 N m) spending 20 N m, under its 26.1; a residual against
    the command is a push by something else, not a resistance.
    """
    velocity, along = np.full(PANDA.n, 0.1), np.full(PANDA.n, 0.3)
    inertia, nonlinear = PANDA.dynamics(REVERSING_Q, velocity)
    gravity = PANDA.gravity(REVERSING_Q)

    def resisted(residual: float) -> np.ndarray:
        effort = inertia @ REVERSING + nonlinear + residual
        return Drives(np.zeros(PANDA.n, bool), np.zeros(PANDA.n, bool), effort - gravity,
                      np.abs(gravity), PANDA, REVERSING_Q, effort).resisted(
                          velocity, REVERSING, along)

    assert resisted(11.0)[4:].all() and not resisted(11.0)[:4].any()
    assert not resisted(3.0).any()
    assert resisted(27.0).all()
    assert not resisted(-27.0).any()
    assert not Drives(np.zeros(PANDA.n, bool), np.zeros(PANDA.n, bool)).resisted(
        velocity, REVERSING, along).any()


def test_a_brake_holding_a_slowly_commanded_joint_leaves_its_drives_push() -> None:
    """A residual of 2 % of the effort limit (and 1 N m) along the command: braking.

    A shoulder (87 N m) whose drive pushes 3 N m beyond its motion's needs along a
    command of -0.03 rad/s is braked; one pushing 1.2 N m, what the dynamics' errors
    leave a healthy joint, is not, nor one whose residual points the other way; a wrist
    (12 N m) needs 1 N m, not 0.24. The coupling torque of the reversing links is in the
    dynamics: no residual of its own.
    """
    along = np.full(PANDA.n, -0.03)
    limits = np.asarray(PANDA.effort_limits, float)
    least = np.maximum(drives.BRAKE_SHARE * limits, drives.BRAKE_TORQUE)
    assert least[0] == pytest.approx(1.74) and least[5] == 1.0
    assert not _braking(np.zeros(PANDA.n), along).any()
    assert _braking(np.full(PANDA.n, -3.0), along).all()
    assert not _braking(np.full(PANDA.n, 3.0), along).any()
    assert not _braking(np.full(PANDA.n, -1.2), along)[:4].any()
    assert _braking(np.full(PANDA.n, -1.2), along)[4:].all()  # the wrists' 1 N m
    assert not _braking(np.full(PANDA.n, -0.5), along).any()
    blind = Drives(np.zeros(PANDA.n, bool), np.zeros(PANDA.n, bool))
    assert not blind.braking(np.zeros(PANDA.n), REVERSING, along).any()


def _unanswered(joint: int, external: float, departure: float,
                response: float = 0.05, q: np.ndarray = Q) -> np.ndarray:
    """`Drives.unanswered` at q (the home pose), `joint` departing, its drive giving `external`."""
    gravity = PANDA.gravity(q)
    effort = gravity.copy()
    effort[joint] += external
    away = np.zeros(PANDA.n)
    away[joint] = departure
    return Drives(np.zeros(PANDA.n, bool), np.zeros(PANDA.n, bool), effort - gravity,
                  np.abs(gravity), PANDA, q, effort).unanswered(away, response)


def test_a_drive_giving_nothing_for_its_joints_departure_leaves_it_unanswered() -> None:
    """A servo answers a departure dv with about M_jj dv / T; a free drive gives none.

    Panda joint 1 at home (a vertical axis: no gravity torque; M_11 = 0.53 kg m^2, as
    Pinocchio's CRBA gives it), 0.2 rad/s beyond its predictions behind a 50 ms servo:
    the answer is 2.1 N m. A drive giving nothing, or 0.1 N m, leaves it unanswered; one
    giving 1 N m, half the answer, does not. A departure of 0.008 rad/s (0.085 N m, under
    `ANSWER_TORQUE`) says nothing, nor a slower servo's (the answer scales as 1 / T), nor
    a shoulder gravity loads (`silent` judges it), nor a driver without efforts, nor a
    drive while a force on the tool may answer for it (`Drives.carried`).
    """
    inertia = PANDA.gravity_dynamics(Q)[1][0]
    assert inertia == pytest.approx(0.53, abs=0.01)
    assert inertia * 0.2 / 0.05 == pytest.approx(2.1, abs=0.05)
    assert np.flatnonzero(_unanswered(0, 0.0, 0.2)).tolist() == [0]
    assert _unanswered(0, -0.1, 0.2)[0]
    assert not _unanswered(0, 1.0, 0.2).any()
    assert not _unanswered(0, -1.0, 0.2).any()
    assert not _unanswered(0, 0.0, 0.008).any()
    assert not _unanswered(0, 0.0, 0.2, response=1.5).any()
    assert abs(PANDA.gravity(Q)[1]) >= drives.GRAVITY_SHARE * PANDA.effort_limits[1]
    assert not _unanswered(1, 0.0, 0.2).any()
    blind = Drives(np.zeros(PANDA.n, bool), np.zeros(PANDA.n, bool))
    assert not blind.unanswered(np.full(PANDA.n, 0.2), 0.05).any()
    away = np.zeros(PANDA.n)
    away[0] = 0.2
    assert DriveWatch(PANDA).update(0.0, Q, PANDA.gravity(Q)).unanswered(away, 0.05)[0]
    carried = DriveWatch(PANDA).update(0.0, Q, PANDA.gravity(Q), carried=True)
    assert not carried.unanswered(away, 0.05).any()  # a wall lately: it may answer instead


#: A loaded deployed run's Panda as its wrist (panda_joint5) lost its torque, leaning so
#: that gravity gives that joint 0.02 N m: it coasted on at 0.24 rad/s against a command
#: of about zero.
WRIST_COASTING = np.array([0.959, 1.657, -1.997, -2.112, 1.177, 0.784, 0.786])


def test_a_wrist_drive_giving_nothing_for_its_joints_coast_leaves_it_unanswered() -> None:
    """A wrist's servo answers a departure of 0.2 rad/s behind 75 ms with 0.15 N m.

    M_55 is 0.056 kg m^2 there (Pinocchio's CRBA): 0.056 x 0.2 / 0.075 = 0.15 N m, at
    least `ANSWER_TORQUE`. A drive giving nothing leaves the departure unanswered, one
    giving 0.05 N m (a third of the answer) does not, nor does a departure of 0.1 rad/s,
    whose answer (0.075 N m) is under the model's error.
    """
    gravity, inertia = PANDA.gravity_dynamics(WRIST_COASTING)
    assert abs(gravity[4]) < drives.GRAVITY_SHARE * PANDA.effort_limits[4]
    assert inertia[4] == pytest.approx(0.056, abs=0.002)
    assert np.flatnonzero(_unanswered(4, 0.0, 0.2, 0.075, WRIST_COASTING)).tolist() == [4]
    assert not _unanswered(4, 0.05, 0.2, 0.075, WRIST_COASTING).any()
    assert not _unanswered(4, 0.0, 0.1, 0.075, WRIST_COASTING).any()


def test_a_drive_that_pushed_within_its_last_response_times_answered_the_departure() -> None:
    """A healthy servo's torque crosses zero as its velocity overshoots a hard acceleration.

    Its reference term still pushes the joint on while its velocity term holds it back;
    just before, it pushed. Joint 1 at home, 0.2 rad/s beyond its predictions behind a
    50 ms servo (an answer of 2.1 N m): its drive gave 2 N m until 0.1 s, then nothing.
    Unanswered only once the push is `ANSWER_SPANS` response times (0.1 s) old, and at
    once for a drive that gave nothing throughout; a reset forgets the push.
    """
    gravity = PANDA.gravity(Q)
    pushed = gravity.copy()
    pushed[0] += 2.0
    away = np.zeros(PANDA.n)
    away[0] = 0.2
    times = 0.004 * np.arange(76)

    def first_unanswered(watch: DriveWatch, push_until: float) -> float:
        return min((float(t) for t in times if watch.update(
            t, Q, pushed if t <= push_until + 1e-9 else gravity).unanswered(away, 0.05)[0]),
                   default=math.inf)

    assert first_unanswered(DriveWatch(PANDA), 0.1) == pytest.approx(0.204)
    assert first_unanswered(DriveWatch(PANDA), -1.0) == 0.0
    watch = DriveWatch(PANDA)
    for t in times[:26]:
        watch.update(float(t), Q, pushed)
    watch.reset()
    assert watch.update(0.104, Q, gravity).unanswered(away, 0.05)[0]


def test_a_departure_is_how_far_a_velocity_lies_beyond_every_plausible_prediction() -> None:
    """Outside [low, high], ahead or behind, by more than the noise, for the free joints."""
    plausible = np.array([[0.2, -0.1, 0.0, 0.3, 0.3], [0.3, -0.2, 0.0, 0.3, 0.5]])
    measured = np.array([0.5, 0.1, 0.04, 0.5, 0.1])
    error = np.array([0.01, 0.01, 0.01, 0.1, 0.01])
    free = np.full(5, True)
    away = rules.departure(measured, plausible, error, free, 0.05, 5.0)
    # 0.2 ahead of 0.3; 0.2 against the command; 0.04 within the noise; 0.2 within 5
    # standard errors of 0.1; 0.2 behind 0.3.
    assert away == pytest.approx([0.2, 0.2, 0.0, 0.0, 0.2])
    assert rules.departure(measured, plausible, error, ~free, 0.05, 5.0).tolist() == [0] * 5
    # Departed at the last update, half the margin keeps it: 0.04 beyond 0.3 against a
    # margin of 0.05, the others as before.
    measured[4] = 0.26
    kept = np.array([False, False, False, False, True])
    assert rules.departure(measured, plausible, error, free, 0.05, 5.0,
                           kept, 0.5) == pytest.approx([0.2, 0.2, 0.0, 0.0, 0.04])
    assert rules.departure(measured, plausible, error, free, 0.05, 5.0)[4] == 0.0


def test_accelerations_are_the_velocities_change_over_their_span() -> None:
    accelerations = drives.Accelerations()
    span = drives.ACCELERATION_SPAN
    answers = [accelerations.update(k * DT, np.array([2.0 * k * DT, -1.0]))
               for k in range(20)]
    first = next(k for k, a in enumerate(answers) if a is not None)
    assert (first - 1) * DT < span <= first * DT + 1e-12  # none before the span is covered
    for a in answers[first:]:
        np.testing.assert_allclose(a, [2.0, 0.0], atol=1e-9)
