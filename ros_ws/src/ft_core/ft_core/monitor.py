"""The monitor's logic without ROS: filter the commands, decide on locks, keep the set.

The counterpart of `ft_core.controller` for the monitor node (and for `ft-stack`,
which hands the controller's command to `Monitor.command` as a call): the node
converts messages, runs the watchdog and publishes; everything between is here.

- **Commands** (`command`, `zeros`): the locked joints get exactly 0 and, with
  `remap_commands`, the rest is remapped through the reduced Jacobian so the tool
  velocity J qd is kept (`ft_core.remap`; where that changes the command, each healthy
  joint within the speeds from which it still stops inside its position limits,
  `_position_bounds`); every command is scaled, direction kept,
  into `velocity_scale` times the URDF velocity limits, then smoothed into the arm's
  acceleration and jerk limits (`ft_core.smoothing`; locked joints get 0 at once, and
  zeros are reached on a ramp: `stopping` says one is under way), and is recorded by
  the detector as in force from the time given: the plant model the detector
  identifies is the one between the smoothed command and the measured motion.
- **Detection** (`observe`, `suspect`): the measured configurations go to the
  `ft_core.detection.LockDetector`, with the way gravity would turn each joint
  (`ft_core.swing.falling_directions`; a joint moving on its own must go that way to
  be free-swinging); a joint it declares free-swinging is, with
  `brake_free_swinging` (the default), declared locked where it is (its brake
  applied). A suspect from elsewhere (the controller's task-space channel) is decided
  by the detector's own confirm rule.
- **Each joint's health** (`health`, `board`): healthy, degraded (it follows less than
  half its command, `ft_core.detection.follow`), locked or free-swinging
  (`ft_core.health`), changing only to a worse state until `reset`; the locked set
  likewise only grows until `reset` (a locked joint that moves on its own is
  free-swinging and locked again where it is).
- **Declared failures and reset** (`declare`, `reset`).
- **Persist, then announce, without waiting for the disk** (docs/monitor.md). A change
  of the locked set takes effect at once in the command filter, and is written to its
  file (`ft_core.locked_set`) by a writer thread (`ft_core.announcements`). The `Change`
  a call returns holds only what is on disk by then (`settled` hands over the rest once
  written); the set to publish is `announced`, the set last written. `reset` is
  answered at once and its empty set published once written; a crash in between
  restores the released joints as locked, the safe side.

Each `Change` says whether the announced set changed (`Change.changed`) and carries
the lines to log (`Change.events`, errors, about the arm); problems with the state
file go to `report` as with the controller's core.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ft_core import limits, locked_set, remap, swing
from ft_core.announcements import Announcements, Change
from ft_core.command_limits import LimitsConfig
from ft_core.detection import (
    Confirmation,
    Decision,
    DetectorConfig,
    JointEvidence,
    LockDetector,
    compile_ahead,
)
from ft_core.detection.contact import ContactWatch, driven
from ft_core.detection.drives import DriveWatch
from ft_core.engine_config import braking_from
from ft_core.health import Health, HealthBoard, JointHealth, JointReport
from ft_core.input_checks import all_finite
from ft_core.robots import Robot
from ft_core.smoothing import Smoother

#: Reports a problem of a named input (None: solved), `warning` for a WARN, not an ERROR.
Report = Callable[..., None]
#: s `close` waits for the locked set's last write.
CLOSE_TIMEOUT = 2.0
#: s without being observable after which a joint counts as unseen (`Monitor.unseen`).
UNSEEN_AFTER = 5.0


@dataclass(frozen=True)
class MonitorConfig:
    """What the monitor does with commands and declarations besides detecting.

    Attributes:
        remap_commands: remap commands through the reduced Jacobian once joints lock
            (otherwise only zero the locked joints).
        velocity_scale: fraction of the URDF velocity limits every command is scaled into.
        brake_free_swinging: declare a free-swinging joint locked where it is (its brake
            asked for, Maciejewski et al. sec. 2.3: the swing angle is the damage).
        limits: the acceleration and jerk limits every command is smoothed into;
            None: raw commands (which a real driver refuses).
    """

    remap_commands: bool = True
    velocity_scale: float = 1.0
    brake_free_swinging: bool = True
    limits: LimitsConfig | None = field(default_factory=LimitsConfig)

    def __post_init__(self) -> None:
        if not 0 < self.velocity_scale <= 1:
            raise ValueError(f"velocity_scale must be in (0, 1], got {self.velocity_scale}")


class Monitor:
    """The monitor's logic; see the module docstring.

    Args:
        robot: the chain.
        detection: the detector's settings.
        config: the command filter's settings.
        store: the file of the persisted locked set (None: kept in memory only).
        report: called with ("state_directory", problem or None, warning=...) and
            ("plant", fault or None).
        written: called in the writer's thread as each write of the locked set ends: from
            then on `settled` hands the change over. The core is not thread-safe: a
            caller that calls `settled` from there serialises it with the calls that
            hand changes over (`restore`, `observe`, `suspect`, `declare`, `reset`,
            `settled`, `flush`, `close`).
    """

    def __init__(self, robot: Robot, detection: DetectorConfig, config: MonitorConfig,
                 store: Path | None, report: Report = lambda *_args, **_kwargs: None,
                 written: Callable[[], object] | None = None):
        self.robot = robot
        compile_ahead()  # the detector's compiled functions, loaded now, not in a callback
        remap.compile_ahead()  # and the bounded remap's
        self.detector = LockDetector(robot.lower, robot.upper, detection)
        self.board = HealthBoard(robot.n)  #: each joint's declared state (`ft_core.health`)
        self.effort: np.ndarray | None = None  #: the latest efforts reported (N m)
        self._touch = ContactWatch(robot, detection.limit_margin)
        self._drives = DriveWatch(robot)
        self.store = store
        self._report = report
        self.q: np.ndarray | None = None  #: the latest measured configuration (rad)
        self._announcements = Announcements(
            locked_set.Writer(store, robot.name, written) if store is not None else None,
            report)
        #: steady or ROS time (s) each joint was last observable (commanded fast enough for
        #: the detector to judge it); None before the first joint state
        self._observed_at: np.ndarray | None = None
        self._observed_latest = -math.inf  #: the largest of `_observed_at` (s)
        self.smoother: Smoother | None = None
        self.config = MonitorConfig(limits=None)
        self.configure(detection, config)

    def configure(self, detection: DetectorConfig, config: MonitorConfig) -> None:
        """New settings; a change of the detector's model grid restarts identification.

        Raises ValueError for limits the arm's model refuses (`command_limits`).
        """
        if config.limits != self.config.limits:
            old, robot = self.smoother, self.robot
            self.smoother = None if config.limits is None else Smoother(
                config.limits.build(robot.name, robot.joint_names, robot.velocity_limits))
            if old is not None and self.smoother is not None:
                self.smoother.reset(old.velocity)
        self.config = config
        self._limits = self.robot.velocity_limits * config.velocity_scale
        self.detector.configure(detection)

    # ----------------------------------------------------------------- state
    @property
    def locked(self) -> dict[str, float]:
        """{joint name: position at lock (rad)} of every locked joint."""
        names = self.robot.joint_names
        return {names[j]: p for j, p in self.detector.locked.items()}

    @property
    def announced(self) -> dict[str, float]:
        """The locked set as the changes handed over so far leave it: on disk, to publish."""
        return self._announcements.announced

    @property
    def writing(self) -> bool:
        """Whether a change waits for a write of the locked set still under way."""
        return self._announcements.writing

    @property
    def swinging(self) -> list[str]:
        """Names of the joints declared free-swinging (braked or not), sorted."""
        return sorted(self.robot.joint_names[j] for j in self.board.of(Health.FREE_SWINGING))

    def health(self) -> dict[str, JointHealth]:
        """Every joint's state and what it still gives, in chain order (`ft/joint_health`)."""
        robot, shares, board = self.robot, self.detector.follow.shares, self.board
        return {name: board.health(j, float(shares[j]),
                                   board.torque_margin(j, float(robot.effort_limits[j])),
                                   float(robot.lower[j]), float(robot.upper[j]))
                for j, name in enumerate(robot.joint_names)}

    def restore(self, now: float) -> Change:
        """Take the locked set kept in the store (at start-up), and have it written back.

        The write back puts the file in the slot format (`Announcements.on_disk`).
        """
        if self.store is None:
            return Change()
        try:
            stored = locked_set.load(self.store, self.robot.name, list(self.robot.joint_names))
        except locked_set.LockedSetError as error:
            self._report("state_directory", f"{error}: starting with no locked joint",
                         warning=True)
            return Change()
        for name, position in stored.items():
            j = self.robot.joint_names.index(name)
            self.detector.lock(j, position, now)
            self.board.declare(j, Health.LOCKED, now, f"restored from {self.store}")
        self._announcements.on_disk(self.locked)
        if not stored:
            return Change()
        return Change(True, [f"restored locked joints {sorted(stored)} from {self.store} "
                             "(call ~/reset after a repair)"], now)

    # -------------------------------------------------------------- commands
    @property
    def stopping(self) -> bool:
        """Whether the commands have not come to rest yet (a stop ramp goes on)."""
        return self.smoother is not None and not self.smoother.at_rest

    def command(self, qd: np.ndarray, now: float) -> np.ndarray:
        """The command to send, stamped `now` (s), for `qd` (rad/s, chain order)."""
        locked = sorted(self.detector.locked)
        if locked and self.config.remap_commands and self.q is not None:
            qd = remap.remap(self.robot, self.q, qd, locked, self._limits,
                             bounds=self._position_bounds(self.q))
        else:
            qd = np.array(qd, dtype=float)
            if locked:
                qd[locked] = 0.0
            qd = remap.within_limits(qd, self._limits)
        if not all_finite(qd):
            qd = np.zeros(self.robot.n)
        if self.smoother is not None:
            qd = self.smoother.step(qd, now, locked)
        self.detector.command(now, qd)
        return qd

    def _position_bounds(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Velocity bounds (rad/s) from which each joint stops inside its position limits.

        `limits.velocity_bounds` at the configuration `q` measured, with the lead of the
        slowest plant model still plausible (its latency and response time, the
        detector's `estimate`) and, with command limits, the braking of
        `engine_config.braking_from`; without them, no deceleration limit.
        """
        estimate = self.detector.estimate()
        lead = estimate.latency_range[1] + estimate.response_time_range[1]
        n = self.robot.n
        if self.smoother is None:
            leads, deceleration = np.full(n, lead), np.full(n, np.inf)
        else:
            leads, deceleration = braking_from(lead, self.smoother.limits.acceleration,
                                               self.smoother.limits.jerk)
        return limits.velocity_bounds(q, np.zeros(n), self.robot.lower, self.robot.upper,
                                      self._limits, leads, deceleration)

    def zeros(self, now: float) -> np.ndarray:
        """Zeros, or the next command towards them within the limits, stamped `now` (s).

        For a refused command and the watchdog; while `stopping`, call again.
        """
        qd = np.zeros(self.robot.n)
        if self.smoother is not None:
            qd = self.smoother.step(qd, now, sorted(self.detector.locked))
        self.detector.command(now, qd)
        return qd

    @property
    def sent(self) -> np.ndarray:
        """The last command the plant was sent (rad/s, chain order; zeros before any)."""
        return self.detector.history.at(np.array([math.inf]))[0]

    def follow(self, qd: np.ndarray, now: float) -> None:
        """A command (rad/s, chain order) another node sent the plant, stamped `now` (s).

        The controller's guard of a silent monitor: detection expects the plant to
        follow it, and the next command continues from it (`Smoother.adopt`). One
        stamped before the last command sent is ignored.
        """
        if self.smoother is None or self.smoother.adopt(qd, now):
            self.detector.command(now, qd)

    # ------------------------------------------------------------- detection
    def absurd(self, q: np.ndarray) -> str | None:
        """Why a measured configuration (finite, rad) is physically absurd, else None.

        Such a joint state is refused before `observe` (`limits.absurd_position`): its
        differences would carry inf and nan into detection and diagnostics.
        """
        robot = self.robot
        return limits.absurd_position(q, robot.lower, robot.upper, robot.joint_names)

    def absurd_command(self, qd: np.ndarray) -> str | None:
        """Why a command (finite, rad/s, chain order) is refused as absurd, else None.

        See `limits.absurd_command`.
        """
        return limits.absurd_command(qd, self.robot.joint_names)

    def observe(self, q: np.ndarray, now: float, blind: str | None = None,
                effort: np.ndarray | None = None) -> Change:
        """A measured configuration (rad) at `now` (s); `blind`: a reason to decide nothing.

        `effort`: the joints' efforts (N m) where the driver reports them.
        """
        self.q, self.effort = q, effort
        touching = False  # the tool is or was lately in contact (`ContactWatch.lately`)
        if effort is not None:
            self.board.effort(now, effort)
            touching = self.robot.has_inertias and self._touch.lately(
                self.robot, q, effort, now, self.detector.joints, self.detector.acceleration)
            if touching:
                self.detector.follow.forget(list(range(self.robot.n)))  # says nothing
        change = Change(self.detector.fill_unknown_positions(q))
        drives = None if effort is None else self._drives.update(
            now, q, effort, touching, touching and self._touch.left(now))
        update = self.detector.measure(now, q, blind,
                                       lambda: swing.falling_directions(self.robot, q),
                                       self._contact if self.robot.has_inertias
                                       and effort is not None else None, drives)
        self._report("plant", self.detector.plant_fault)
        names, joints = self.robot.joint_names, self.detector.joints
        brake, board = self.config.brake_free_swinging, self.board
        for j in update.swinging:
            evidence = joints[j]
            # Declared locked once, it stays in the locked set (no flapping): a swing that
            # takes the detector's lock back is braked again where the joint is now.
            stays = j in update.released
            if stays and self.effort is not None and self.robot.has_inertias and driven(
                    self.robot, q, self.effort, j):  # `detection.contact.driven`
                line = (f"joint {names[j]} moved again after its lock (t = {now:.3f} s) with "
                        "its drive's torque: a jam that let go; it stays locked")
                change.events.append(line)
                board.declare(j, Health.LOCKED, now, line)
                self.detector.lock(j, float(q[j]), now)
                continue
            line = (f"joint {names[j]} free-swinging (t = {now:.3f} s): measured "
                    f"{evidence.measured:.4f} rad/s, commanded {evidence.commanded:.4f}"
                    + (", its drive not answering" if self.detector.unanswered[j] else
                       ", its drive giving no torque" if self.detector.torqueless[j] else ""))
            change.events.append(line + ("; declaring it locked where it is (brake)" if brake
                                         else "; it stays locked" if stays else ""))
            board.declare(j, Health.FREE_SWINGING, now, line, braked=brake or stays)
            if brake or stays:
                self.detector.lock(j, float(q[j]), now)
        for j in update.locked:
            evidence = joints[j]
            line = (f"joint {names[j]} locked at {evidence.position:.4f} rad (t = {now:.3f} s): "
                    + ("held still while commanded, its drive pushing"
                       if evidence.held_since is not None else
                       f"measured {evidence.measured:.4f} rad/s against at least "
                       f"{evidence.commanded:.4f} expected, {1e3 * evidence.deficit:.1f} mrad "
                       "behind"))
            change.events.append(line)
            board.declare(j, Health.LOCKED, now, line)
        shares = self.detector.follow.shares
        for j in update.degraded:
            line = (f"joint {names[j]} degraded (t = {now:.3f} s): it followed "
                    f"{shares[j]:.2f} of its commanded motion lately")
            change.events.append(line)
            board.declare(j, Health.DEGRADED, now, line)
        # A new lock or a brake changes the set (a lock taken back by a swing and braked
        # again: the same joints, at the position where it was braked).
        change.changed |= bool(update.locked) or any(
            brake or j in update.released for j in update.swinging)
        if self._observed_at is None or now < self._observed_latest:
            self._observed_at = np.full(self.robot.n, now)  # the first state, or time reset
            self._observed_latest = now
        if self.detector.not_observing is None:  # else the evidence is the last update's
            observable = [e.observable for e in joints]
            if any(observable):
                self._observed_at[observable] = self._observed_latest = now
        self._hold(change, now)
        return self.settled()

    @property
    def contact(self) -> str | None:
        """Why joints ready to be declared locked were not, lately (the tool in contact)."""
        return self.detector.contact

    def _contact(self, joints: list[int], _since: float) -> str | None:
        """Why stalled `joints` are in contact, not failed, or None (`detection.contact`)."""
        if self.effort is None or self.q is None:
            return None
        return self._touch.explains(self.robot, self.q, self.effort, joints,
                                    self.detector.latest_time, self.detector.joints,
                                    acceleration=self.detector.acceleration)

    def unseen(self, now: float, after: float = UNSEEN_AFTER) -> list[str]:
        """Unlocked joints not observable for `after` s or more at `now` (s): their names.

        A lock shows only while its joint is commanded at least `min_command` (the
        detector's rule); a lock of one of these, injected or real, cannot be seen until
        it is commanded again (the controller's observability motion does that).
        """
        if self._observed_at is None:
            return []
        locked = self.detector.locked
        return [name for j, name in enumerate(self.robot.joint_names)
                if j not in locked and now - self._observed_at[j] >= after]

    def suspect(self, joint: int, now: float) -> tuple[Confirmation, Change]:
        """Decide on a lock of `joint` suspected elsewhere, on its own evidence (not in contact)."""
        if self.q is None:
            return Confirmation(Decision.REFUSED, JointEvidence()), Change()
        answer = self.detector.confirm(joint, float(self.q[joint]), now, self._contact)
        if answer.decision != Decision.LOCKED:
            return answer, Change()
        evidence = answer.evidence
        line = (f"joint {self.robot.joint_names[joint]} locked (suspected by the task-space "
                f"channel, confirmed: measured {evidence.measured:.4f} rad/s against "
                f"{evidence.commanded:.4f} commanded)")
        self.board.declare(joint, Health.LOCKED, now, line)
        self._hold(Change(True, [line]), now)
        return answer, self.settled()

    def declare(self, joints: Iterable[int], now: float) -> Change:
        """Lock `joints` (chain indices) at once, where they are now (nan before any state)."""
        change = Change()
        for j in joints:
            if j not in self.detector.locked:
                position = float(self.q[j]) if self.q is not None else math.nan
                self.detector.lock(j, position, now)
                line = f"joint {self.robot.joint_names[j]} declared locked"
                change.events.append(line)
                self.board.declare(j, Health.LOCKED, now, line + " (ft/declare_failure)")
                change.changed = True
        self._hold(change, now)
        return self.settled()

    def reset(self, now: float) -> list[str]:
        """Release every lock (after a repair, at `now` s) and forget the history; the names.

        Changes not yet handed over are dropped: the empty set supersedes them.
        """
        released = sorted(self.locked)
        self.detector.reset()
        self._drives.reset()
        self.board.reset()
        self._announcements.drop()
        self._hold(Change(True), now)
        return released

    def joint_report(self, joint: int) -> JointReport:
        """The state of `joint` (chain index) for diagnostics (`HealthBoard.report`)."""
        return self.board.report(joint, self.detector.joints[joint])

    def plant_values(self) -> dict[str, object]:
        """The detector's view of the plant, for diagnostics."""
        estimate = self.detector.estimate()
        values: dict[str, object] = {
            "observing": self.detector.not_observing or "yes",
            "contact": self.contact or "no",
            "plant_model": "identified" if estimate.identified else "prior (not yet identified)",
            "latency_range_s": list(estimate.latency_range),
            "response_time_range_s": list(estimate.response_time_range),
            "identification_data_s": estimate.excitation}
        if estimate.identified:
            values["latency_s"] = estimate.latency
            values["response_time_s"] = estimate.response_time
        return values

    # ----------------------------------------------------------- persistence
    def settled(self) -> Change:
        """The changes written since the last call, in order (nothing to announce: empty)."""
        return self._announcements.settled()

    def flush(self, timeout: float) -> Change:
        """Wait up to `timeout` s for the writes under way; then `settled`."""
        return self._announcements.flush(timeout)

    def close(self) -> Change:
        """Finish the last write (at most CLOSE_TIMEOUT s) and end the writer thread."""
        return self._announcements.close(CLOSE_TIMEOUT)

    def _hold(self, change: Change, now: float) -> None:
        """Queue `change`, decided at `now` s, for `settled` (`Announcements.hold`)."""
        self._announcements.hold(change, now, self.locked)
