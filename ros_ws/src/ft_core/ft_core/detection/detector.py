"""The lock detector: streams of commands and measurements in, declared locks out.

`LockDetector` keeps the command history (`plant_model`), the window of measurements
(`window`) and the identification (`identification`), and applies the rules (`rules`)
at each decision (docs/detection.md).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from ft_core.detection import blind_falls, rules
from ft_core.detection.config import DetectorConfig
from ft_core.detection.drives import (
    ANSWER_SPANS,
    DEPARTURE_KEEP,
    DEPARTURE_SHARE,
    HELD_LIMIT_MARGIN,
    HELD_TIME,
    STILL_SPAN,
    UNANSWERED_TIME,
    Accelerations,
    Drives,
)
from ft_core.detection.evidence import (
    Confirmation,
    Decision,
    Disturbance,
    JointEvidence,
    Update,
    Veto,
    declare_locks,
    declare_swings,
)
from ft_core.detection.follow import MEMORY, FollowMeter
from ft_core.detection.identification import PlantEstimate, PlantIdentification
from ft_core.detection.plant_model import CommandHistory
from ft_core.detection.spans import SLOW_SPAN, Spans
from ft_core.detection.window import Offsets, Samples, _ingest, _window_fit

#: Shortest time (s) between two decisions (`LockDetector.measure`). Every measurement
#: goes into the window; the fits and rules run at every measurement up to 250 Hz, at
#: every second one at 500 Hz and every third at 1 kHz, where the window (80 ms by
#: default) moves by 1 ms per measurement. Well short of 250 Hz's 4 ms, so that streams
#: up to that rate, with up to 1.5 ms of jitter, are judged at every measurement, and no
#: exact multiple of a common period, so that rounding in the stamps' differences
#: (3 ms coming out as 2.9999 ms) cannot skip one more.
DECISION_PERIOD = 0.0025
#: s over which a suspect from elsewhere, commanded too slowly for the window's test, is
#: judged (`LockDetector.confirm`): the task-space channel's window, over which it
#: suspected the joint.
SUSPECT_SPAN = 0.5


@dataclass
class LockDetector:
    """Streams of commands and measurements in, declared locks out."""

    lower: np.ndarray
    upper: np.ndarray
    config: DetectorConfig = field(default_factory=DetectorConfig)

    def __post_init__(self) -> None:
        self.lower, self.upper = np.asarray(self.lower, float), np.asarray(self.upper, float)
        self.n = self.lower.size
        self.reset()

    def reset(self) -> None:
        """Forget every lock and all history (after a repair or a new configuration)."""
        self._latencies, response_times = self.config.grids()
        self._longest_latency = float(self._latencies.max())
        self._plant = PlantIdentification(self._latencies, response_times)
        models = self._plant.all_models.size
        self.history = CommandHistory(self.n, response_times)
        self._samples = Samples(self.n, models)
        self._offsets = Offsets(self.n, models)
        self._spans = Spans(self._samples, self._offsets, self.history, self._plant,
                            self.lower, self.upper)
        self._resumed_at = -math.inf  # when commands last resumed after a gap (or began)
        self._seen_following = 0.0
        self._last_update = -math.inf
        self.not_observing: str | None = "no command yet"
        self.plant_fault: str | None = None
        #: why the last joints ready to be declared locked were not (the tool in contact)
        self.contact: str | None = None
        self.joints = [JointEvidence() for _ in range(self.n)]
        self.follow = FollowMeter(self.n)
        self._declared_at = -math.inf  # when a joint was last declared locked or swinging
        self._accelerations = Accelerations()  # of the window slopes
        #: rad/s^2, the joints' accelerations at the last update (the window slopes'
        #: change over `drives.ACCELERATION_SPAN`); None: not yet known
        self.acceleration: np.ndarray | None = None
        #: joints beyond their predictions whose drives did not answer at the last update
        self.unanswered = np.zeros(self.n, dtype=bool)
        #: s, since when each joint's velocity has lain beyond its predictions
        #: (`rules.departure`); NaN: not now
        self.departed_since = np.full(self.n, math.nan)
        #: joints whose drives gave no torque at the last update (silent or unanswered)
        self.torqueless = np.zeros(self.n, dtype=bool)
        #: those of them contact cannot explain, since such a drive pushes against nothing:
        #: all, but while the tool is pushed (`Drives.carried`) only those falling off their
        #: predictions (an obstacle can carry a healthy joint's weight, its drive idle)
        self.beyond_contact = np.zeros(self.n, dtype=bool)

    def configure(self, config: DetectorConfig) -> None:
        """New parameters; a change of the model grid restarts identification (locks kept)."""
        old = self.config
        self.config = config
        if [g.tolist() for g in config.grids()] != [g.tolist() for g in old.grids()]:
            locked = [(j, e.position, e.locked_at) for j, e in enumerate(self.joints)
                      if e.locked_at is not None]
            self.reset()
            for j, position, time in locked:
                self.lock(j, position, time)

    # ----------------------------------------------------------------- state
    @property
    def latest_time(self) -> float:
        """Time (s) of the newest measurement; -inf before any."""
        samples = self._samples
        return float(samples.times[samples.end - 1]) if len(samples) else -math.inf

    @property
    def locked(self) -> dict[int, float]:
        """{joint index: position at lock} of every locked joint."""
        return {i: e.position for i, e in enumerate(self.joints) if e.locked_at is not None}

    @property
    def swinging(self) -> dict[int, float]:
        """{joint index: time declared} of the joints declared free-swinging (not locked)."""
        return {i: e.swinging_at for i, e in enumerate(self.joints)
                if e.swinging_at is not None and e.locked_at is None}

    def lock(self, joint: int, position: float, time: float) -> None:
        """Mark a joint locked (a failure declared on purpose, or restored from storage)."""
        evidence = self.joints[joint]
        if evidence.locked_at is None:
            evidence.locked_at, evidence.position = time, position
            self._declared_at = max(self._declared_at, time)

    def fill_unknown_positions(self, position: np.ndarray) -> bool:
        """Give locked joints of unknown position (nan) this measured one; True if any."""
        filled = False
        for j, evidence in enumerate(self.joints):
            if evidence.locked_at is not None and not math.isfinite(evidence.position):
                evidence.position, filled = float(position[j]), True
        return filled

    def estimate(self) -> PlantEstimate:
        """The identified plant model (the prior's ranges until identified)."""
        return self._plant.estimate(self.config.min_excitation)

    # ---------------------------------------------------------------- inputs
    def command(self, time: float, velocity: np.ndarray) -> None:
        """The velocity sent to the plant from `time` on (rad/s)."""
        last = self.history.last_time  # -inf before any command
        if time < last:
            return  # out of order: ignored
        if time - last > self.config.window:
            self._resumed_at = time  # the first command, or the first after a gap
            self._seen_following = 0.0
        # Floats and contiguous arrays: the types `compile_ahead` compiled for.
        self.history.append(float(time), np.ascontiguousarray(velocity, dtype=float),
                            time - max(2 * self.config.window, self._spans.horizon(self.config))
                            - self._longest_latency)

    def measure(self, time: float, position: np.ndarray, blind: str | None = None,
                falling: Callable[[], np.ndarray | None] | None = None,
                veto: Veto | None = None, drives: Drives | None = None) -> Update:
        """A measured configuration; the joints it newly declares locked or free-swinging.

        `blind` (a reason) forbids decisions and identification at this update; while
        the detector's own reasons hold (`rules.not_observing`, or the plant not yet
        seen following), only a silent drive's fall is judged (`blind_falls`).
        `falling` returns (n,) the sign of the acceleration gravity gives each joint at
        `position` were its torque lost, 0 where it is too weak to move it
        (`ft_core.swing.falling_directions`), or None where the arm's gravity is unknown;
        it is called only when a joint moves on its own by the other tests (gravity's
        test can only clear a joint), so a healthy cycle pays nothing for it. `veto`
        (`evidence.Veto`) is asked before joints are declared locked (contact), never
        about a joint whose drive gives no torque (`beyond_contact`).
        `drives` (`drives.DriveWatch`, from the efforts): a joint whose drive is silent
        (no torque while gravity turns it) outside its plausible predictions, the way
        gravity turns it, moves on its own at once, with no allowance for a servo's
        transient and no wait; one whose drive works against its motion does not
        (`Drives.let_go`); one off every plausible prediction whose drive gives nothing
        for it (`Drives.unanswered`), another joint moving as commanded, moves on its
        own once it has been off them `UNANSWERED_TIME` (`departed_since`); one whose
        drive pushes, still within `STILL_SPAN` over the window while a plausible model
        commands it and another joint moves, is a lock candidate; one stalled whose
        drive's torque the dynamics explain is not (`Drives.braking`).
        """
        if time <= self.latest_time:
            return Update()  # out of order or repeated: ignored
        self._into_window(float(time), np.ascontiguousarray(position, dtype=float))
        if blind is None and time - self._last_update < DECISION_PERIOD:
            return Update()  # in the window; judged at the next decision
        dt = time - self._last_update if math.isfinite(self._last_update) else 0.0
        self._last_update = time
        reason = blind or rules.not_observing(
            time, self.history.last_time, self._resumed_at, self._spans.settling_time(self.config),
            self._samples.window()[0], self.config.window, self.config.min_samples)
        self.not_observing = reason
        if reason is not None:
            self.plant_fault = None  # no evidence either way
            kept = self._clear_evidence()
            return Update() if blind else self._falls_while_blind(time, kept, falling, drives)
        return self._update(time, dt, falling, veto, drives)

    def _falls_while_blind(self, now: float, kept: list[float | None],
                           falling: Callable[[], np.ndarray | None] | None,
                           drives: Drives | None) -> Update:
        """`blind_falls.declare_falls`, where a drive is silent and the arm's gravity known."""
        if drives is None or falling is None or not drives.silent.any():
            return Update()
        gravity = falling()
        if gravity is None:
            return Update()
        history = self.history
        swinging, released = blind_falls.declare_falls(
            now, self.joints, kept, self._samples, history.values[history.start:history.end],
            drives.silent, np.asarray(gravity, dtype=float), self._plant, self.config,
            self._declared_at)
        self.torqueless, self.beyond_contact = drives.silent.copy(), drives.silent.copy()
        if swinging:
            self._declared_at = now
        return Update((), tuple(swinging), tuple(released))

    def _into_window(self, time: float, position: np.ndarray) -> None:
        """The measurement into the window, its offsets kept (`_ingest`, compiled)."""
        samples, offsets, history = self._samples, self._offsets, self.history
        samples.make_room_for(time)
        offsets.make_room_for_one()
        samples.start, offsets.start = _ingest(
            time, position, self._latencies,
            (history.times, history.values, history.integrals, history.lagged, history.rate,
             history.response_times), (history.start, history.end),
            samples.times, samples.positions, samples.predicted, samples.predicted_sum,
            samples.timed_sum, (samples.start, samples.end), samples.base,
            time - self.config.window, offsets.times, offsets.values, offsets.means,
            (offsets.start, offsets.end),
            time - max(self._spans.horizon(self.config), SUSPECT_SPAN))
        samples.end += 1
        offsets.end += 1

    def confirm(self, joint: int, position: float, time: float,
                veto: Veto | None = None) -> Confirmation:
        """Decide on a suspected lock of `joint` (at `position` rad, `time` s) from elsewhere.

        Refused when `veto` explains the joint's stall (contact), unless its drive gave
        no torque at the last update (`beyond_contact`).

        Locked when the joint is a candidate of the detector's own stall test at the
        last update, without the witness of another joint seen following (a suspect
        comes exactly where no such witness exists: a joint the task-space channel
        suspects is often the only one commanded); the noise tests, the joint-limit rule
        and the plant-fault rule all apply. Or, for a joint commanded too slowly for the
        window's test, when it lost its motion over the last `SUSPECT_SPAN` s
        (`rules.slow_stall`).
        """
        evidence = self.joints[joint]
        if evidence.locked_at is not None:
            return Confirmation(Decision.KNOWN, replace(evidence))
        if (veto is not None and not self.beyond_contact[joint]
                and veto([joint], time) is not None):
            return Confirmation(Decision.REFUSED, replace(evidence))
        if not evidence.candidate:
            slow = None if (self.not_observing is not None or self.plant_fault is not None
                            ) else self._spans.slow_stalls(
                self.config, self._resumed_at,
                np.array([e.standard_error for e in self.joints]), SUSPECT_SPAN)
            if slow is None or not slow.stalled[joint]:
                return Confirmation(Decision.REFUSED, replace(evidence))
            evidence = replace(evidence, candidate=True, measured=float(slow.measured[joint]),
                               commanded=float(slow.commanded[joint]),
                               deficit=float(slow.deficit[joint]))
        self.lock(joint, position, time)
        return Confirmation(Decision.LOCKED,
                            replace(evidence, locked_at=time, position=position))

    # -------------------------------------------------------------- decisions
    def _clear_evidence(self) -> list[float | None]:
        """Forget the evidence under way; returns when each joint's swing evidence began."""
        kept = [e.swing_since for e in self.joints]
        for evidence in self.joints:
            evidence.evidence_since = evidence.swing_since = None
        self.unanswered = np.zeros(self.n, dtype=bool)
        self.departed_since = np.full(self.n, math.nan)
        return kept

    def _update(self, now: float, dt: float,
                falling: Callable[[], np.ndarray | None] | None,
                veto: Veto | None, drives: Drives | None) -> Update:
        cfg, plant = self.config, self._plant
        samples = self._samples
        times, positions, _predicted = window = samples.window()
        fit = (*window, samples.predicted_sum, samples.timed_sum, samples.base)
        best = plant.best  # always plausible
        # Identification (every model) at most every IDENTIFY_PERIOD; decisions need only
        # the plausible models, far fewer once identified.
        identify = plant.due(now)
        if identify:
            measured, slopes, error = _window_fit(*fit, plant.all_models, best)  # (models, n)
            plausible = slopes[plant.plausible]
        else:
            measured, plausible, error = _window_fit(*fit, plant.plausible_models, best)
        joints = self.joints
        unlocked = np.array([e.locked_at is None for e in joints])
        undeclared = np.array([e.swinging_at is None for e in joints])
        stalling = np.array([e.evidence_since is not None for e in joints])
        latest = positions[-1]
        evidence_of = (measured, plausible, error, latest, self.lower, self.upper, unlocked,
                       undeclared, stalling)
        limits = (cfg.min_command, cfg.confidence, cfg.ratio, cfg.following_ratio,
                  cfg.limit_margin)
        flags = rules.classify(*evidence_of, np.zeros(self.n), False, *limits)
        directions = falling() if falling is not None and flags[-1].any() else None
        if directions is not None:  # gravity's test only clears joints: now it matters
            flags = rules.classify(*evidence_of, np.asarray(directions, dtype=float), True,
                                   *limits)
        weakest, observable, following, stalled, pushing, candidates, on_its_own = flags
        on_its_own = on_its_own & (True if drives is None else drives.let_go(measured))
        # What the efforts say (`drives`): a drive without torque against gravity.
        silent = np.zeros(self.n, dtype=bool) if drives is None else drives.silent
        quiet = silent if drives is None or drives.quiet is None else silent | drives.quiet
        falls = np.zeros(self.n, dtype=bool)  # moving as its drive's silence makes it
        if quiet.any():
            gravity = directions if directions is not None else falling() if falling else None
            if gravity is not None:
                falls = rules.silent_and_on_its_own(
                    silent, quiet, measured, plausible, error, unlocked, undeclared,
                    np.asarray(gravity, dtype=float), (latest, self.lower, self.upper),
                    cfg.min_command, cfg.confidence, cfg.limit_margin)
                on_its_own = on_its_own | falls
        # A stalled joint counts while another is seen moving as commanded; a held one alone.
        witnessed = bool(rules.vouching(measured, plausible, error, unlocked, cfg.min_command,
                                        cfg.confidence, cfg.following_ratio).any())
        # A joint off its predictions whose drive does not answer (`Drives.unanswered`),
        # another seen moving as commanded (a stopped plant moves none).
        inside = (latest - self.lower > HELD_LIMIT_MARGIN) & (self.upper - latest
                                                              > HELD_LIMIT_MARGIN)
        away = np.zeros(self.n) if drives is None or not witnessed else rules.departure(
            measured, plausible, error, unlocked & undeclared & inside,
            DEPARTURE_SHARE * cfg.min_command, cfg.confidence, self.unanswered, DEPARTURE_KEEP)
        self.unanswered = unanswered = (drives.unanswered(away, plant.slowest_response)
                                        if drives is not None and away.any()
                                        else np.zeros(self.n, dtype=bool))
        self.departed_since = departed = np.where(away > 0, np.fmin(self.departed_since, now),
                                                  math.nan)
        on_its_own = on_its_own | unanswered
        self.torqueless = unanswered | falls | silent
        self.beyond_contact = beyond = (unanswered | falls if drives is not None
                                        and drives.carried else self.torqueless)
        deficit = np.zeros(self.n)
        if (candidates & undeclared).any():  # (a swung joint's test: stopping)
            deficit, lost = self._spans.lost_position(cfg, now, weakest, error, times,
                                                      cfg.window)
            candidates = candidates & (lost | ~undeclared)
        self.acceleration = acceleration = self._accelerations.update(now, measured)
        if drives is not None and drives.weighed and candidates.any():
            # A brake holds its joint against its drive's push; a healthy servo that falls
            # behind its command for a moment (undershooting a falling command, the lurch
            # as an obstacle goes) is held by torques the dynamics explain (`drives`).
            braked = (np.zeros(self.n, dtype=bool) if acceleration is None
                      else drives.braking(measured, acceleration, weakest))
            candidates = candidates & (braked | ~undeclared)
        # Commanded too slowly for the window: judged over the slow span, behind where
        # it stood before the span's second half (a servo that ran ahead and pauses until
        # its reference catches up is not), and held there by a torque the dynamics do
        # not explain (`Drives.braking`; without efforts, not judged).
        slow = unlocked & undeclared & ~observable & ~on_its_own & ~candidates
        stalls = (self._spans.slow_stalls(cfg, self._resumed_at, error)
                  if slow.any() and drives is not None else None)
        if (stalls is not None and drives is not None and acceleration is not None
                and (slow & stalls.stalled).any()):
            behind, lost = self._spans.lost_position(cfg, now, stalls.commanded, error,
                                                     times, SLOW_SPAN / 2)
            slow = slow & stalls.stalled & lost & drives.braking(measured, acceleration,
                                                                 stalls.commanded)
            deficit = np.where(slow, behind, deficit)
            candidates = candidates | slow
        held = np.zeros(self.n, dtype=bool) if drives is None else rules.held_still(
            drives.pushing & unlocked & inside, positions, plausible,
            cfg.min_command, STILL_SPAN)  # a push the joint does not follow
        if drives is not None and acceleration is not None and (candidates | held).any():
            # Stalled or held by the other links' accelerations, not by a brake.
            moved = drives.moved_by_others(measured, acceleration, weakest, cfg.min_command)
            candidates, held = candidates & ~moved, held & ~moved
        since = np.array([math.nan if e.held_since is None else e.held_since for e in joints])
        held_long = held & (now - np.fmin(since, now) >= HELD_TIME)
        candidates = candidates | held_long
        # Python lists from here on (per-joint numpy scalars cost more than the fits).
        measured_of, weakest_of, error_of = measured.tolist(), weakest.tolist(), error.tolist()
        candidate_of, following_of = candidates.tolist(), following.tolist()
        own_of = on_its_own.tolist()
        for evidence, observes, follows, v, c, s, at_limit, candidate, behind, is_held in zip(
                joints, observable.tolist(), following_of, measured_of, weakest_of, error_of,
                (stalled & pushing).tolist(), candidate_of, deficit.tolist(), held.tolist(),
                strict=True):
            evidence.observable, evidence.following = observes, follows
            evidence.measured, evidence.commanded, evidence.standard_error = v, c, s
            evidence.at_limit, evidence.candidate, evidence.deficit = at_limit, candidate, behind
            evidence.held_since = (now if evidence.held_since is None else
                                   evidence.held_since) if is_held else None
        if stalls is not None:  # a slow stall's velocities are its span's
            for k in np.flatnonzero(slow & stalls.stalled & candidates).tolist():
                joints[k].measured = float(stalls.measured[k])
                joints[k].commanded = float(stalls.commanded[k])
        n_stalled, n_following, n_own = sum(candidate_of), sum(following_of), sum(own_of)
        if n_stalled == 0 and n_own == 0 and identify:
            plant.identify(now, measured, slopes, error, unlocked & ~pushing,
                           window=cfg.window, min_command=cfg.min_command,
                           memory=cfg.memory, min_excitation=cfg.min_excitation)
        # A joint held against its drive's push is no sign of a stopped plant (it pushes
        # nothing), nor is one moving on its own whose drive gives no torque (its own).
        unheld = [c and not h for c, h in zip(candidate_of, held.tolist(), strict=True)]
        odd = rules.plant_fault(unheld, following_of, own_of, self.torqueless.tolist())
        if odd is not None:
            self.plant_fault = "plant not following commands: " + ", ".join(
                f"joint {j} measured {measured_of[j]:.3f} rad/s, expected {weakest_of[j]:.3f}"
                for j, is_odd in enumerate(odd) if is_odd)
            self._seen_following = 0.0
            self._clear_evidence()
            for evidence in joints:
                evidence.candidate = False
            return Update()
        self.plant_fault = None
        if self._seen_following < cfg.follow_time:
            # The plant follows while joints follow and the stalled ones show no plant
            # fault (a joint failed since the start or a gap stalls throughout). It is
            # live at once where a drive gives nothing for its joint's departure while
            # another joint follows (`unanswered` asks for that witness), or, nothing
            # else stalling, where a drive pushes a joint that stays.
            if unanswered.any() or (held_long.any() and not any(unheld)):
                self._seen_following = cfg.follow_time
            elif n_following:
                self._seen_following += dt
        if self._seen_following < cfg.follow_time:
            self.not_observing = "plant not yet seen following commands"
            return self._falls_while_blind(now, self._clear_evidence(), falling, drives)
        settle = plant.settling_time(best)
        # Disturbed too once the tool came off an obstacle: its servos turn round.
        disturbance = Disturbance(joints, now, math.inf if drives is not None and drives.left
                                  else self._declared_at + settle)
        # An unanswered departure's time counts from when it began, as far back as the
        # drive's torques show it giving nothing (`drives.ANSWER_SPANS` response times).
        silent_for = ANSWER_SPANS * plant.slowest_response
        swinging, released, pushed = declare_swings(
            joints, own_of, now, disturbance, cfg.persistence, settle,
            lambda j, since: 0.0 if falls[j] or silent[j] else min(
                rules.swing_wait(measured_of[j], error_of[j], plausible, settle,
                                 cfg.confidence, cfg.min_command),
                max(0.0, UNANSWERED_TIME - min(since - departed[j], silent_for))
                if unanswered[j] else math.inf), veto, beyond.tolist())
        supported = (held_long | (candidates & witnessed)).tolist()
        newly, contact = declare_locks(joints, supported, latest, now, disturbance,
                                       cfg.persistence, settle, veto, beyond.tolist())
        contact = contact or pushed
        if contact is not None or not (any(supported) or any(own_of)):
            self.contact = contact
        if newly or swinging:
            self._declared_at = now
        judged = observable & ~pushing & ~on_its_own & (not disturbance.settling)
        resisted = (drives.resisted(measured, acceleration, weakest)
                    if drives is not None and acceleration is not None else None)
        degraded = [j for j in self.follow.update(now, dt, measured, weakest, judged, resisted)
                    if joints[j].degraded_at is None and joints[j].locked_at is None]
        asked = [j for j in degraded if not beyond[j]]
        if asked and veto is not None:  # slowed by a force on the tool: not degraded
            slowed = veto(asked, now - MEMORY)
            if slowed is not None:  # the stall in contact says nothing of the drive
                self.follow.forget(asked)
                self.contact, degraded = slowed, [j for j in degraded if beyond[j]]
        for j in degraded:
            joints[j].degraded_at = now
        return Update(tuple(newly), tuple(swinging), tuple(released), tuple(degraded))


@functools.cache
def compile_ahead() -> None:
    """Run the detector's compiled functions once, so numba compiles (or loads) them now.

    Once per process, on the types the detector passes them. `make build` calls it, so
    that they are compiled and cached on disk, not inside the first monitor's joint-state
    callback (seconds on 2 cores, its commands held meanwhile). Every
    `ft_core.monitor.Monitor` calls it on construction, so that they are loaded from that
    cache before its first callback rather than one by one as the detector first needs
    each, holding the callbacks that need them.
    """
    detector = LockDetector(np.full(2, -1.0), np.full(2, 1.0))
    for k in range(300):  # 1.2 s: past the settling time, so that decisions run
        t = 0.004 * k
        detector.command(t, np.full(2, 0.1))
        detector.measure(t + 0.004, np.full(2, 0.0004 * k))
