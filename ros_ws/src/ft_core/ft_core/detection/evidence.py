"""Each joint's evidence, when evidence becomes a declaration, and what the detector answers.

Lock evidence (a candidate of the stall rules, vouched for by a joint that follows) is
declared once it has held for `persistence`; free-swing evidence (motion on its own)
for `persistence` plus `rules.swing_wait`. Evidence that begins while the arm is
**disturbed** must also outlast the plant's settling time (the best model's latency and
three response times): a joint losing its torque or stopping at a lock pushes the
others through the links' coupling, and the remap's new commands are a step of their
own, so the joints around a failure stall or move on their own for a moment (docs/
detection.md, "After a declaration"). The arm is disturbed within the settling time
after a declaration, once the tool has come off an obstacle it was held at (its servos,
wound up against it, turn round: `ContactWatch.left`), and for a joint whose evidence
begins after another joint's evidence, still under way, began. Evidence that begins at
the same update as another's (two joints failing at once) is not delayed.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass


@dataclass
class JointEvidence:
    """What the detector saw of one joint at its last update."""

    observable: bool = False
    following: bool = False
    measured: float = 0.0  #: slope of the measured positions (rad/s)
    commanded: float = 0.0  #: weakest plausible predicted velocity (rad/s)
    standard_error: float = 0.0  #: of the slope (rad/s)
    #: position lost against the best plant model during the window (rad, along the
    #: command; computed only when a never-swinging joint stalls, else 0)
    deficit: float = 0.0
    evidence_since: float | None = None  #: when the current lock evidence started (s)
    at_limit: bool = False  #: stalled at a physical limit
    #: a lock candidate at the last update: stalled beyond the noise, not at a limit, not
    #: moving on its own, no plant fault (whether or not a following joint vouches for the
    #: plant, which the detector's own decision also needs)
    candidate: bool = False
    #: held still against its drive's push (`rules.held_still`) since (s), or None; a
    #: lock candidate once that lasts `detector.HELD_TIME`
    held_since: float | None = None
    swing_since: float | None = None  #: when the current free-swing evidence started (s)
    swinging_at: float | None = None  #: time free-swinging was declared (s)
    locked_at: float | None = None  #: time the lock was declared (s)
    position: float = 0.0  #: position when locked (rad)
    degraded_at: float | None = None  #: time it was declared degraded (s)
    #: the current lock / free-swing evidence began while the arm was disturbed
    #: (`Disturbance`): it must outlast the plant's settling time
    evidence_late: bool = False
    swing_late: bool = False


@dataclass(frozen=True)
class Update:
    """What one measurement decided: joints newly declared locked, free-swinging, degraded.

    `released`: those of `swinging` that were declared locked (a swing takes the lock back).
    """

    locked: tuple[int, ...] = ()
    swinging: tuple[int, ...] = ()
    released: tuple[int, ...] = ()
    degraded: tuple[int, ...] = ()


class Decision(enum.StrEnum):
    """The detector's answer to a suspected lock (`Confirmation.decision`)."""

    LOCKED = "locked"  #: declared now
    KNOWN = "known"  #: already locked
    REFUSED = "refused"  #: not a lock candidate at the last update


@dataclass(frozen=True)
class Confirmation:
    """The detector's answer to a suspect from elsewhere (the controller's task channel).

    Attributes:
        decision: `Decision.LOCKED` (declared now), `KNOWN` (already locked) or
            `REFUSED` (not a lock candidate at the last update: following, within the
            noise, moving on its own, or at a limit). A joint declared free-swinging is
            decided like any other: locked if it has stopped while commanded.
        evidence: the joint's evidence at the decision (a copy).
    """

    decision: Decision
    evidence: JointEvidence


class Disturbance:
    """Whether evidence beginning at `now` (s) begins while the arm is disturbed.

    Args:
        joints: every joint's evidence before this update's.
        now: the update's time (s).
        settled_at: s, when the settling time after the latest declaration ends (inf
            once the tool has come off an obstacle, `ContactWatch.left`).
    """

    def __init__(self, joints: list[JointEvidence], now: float, settled_at: float):
        self._starts = [min(math.inf if e.evidence_since is None else e.evidence_since,
                            math.inf if e.swing_since is None else e.swing_since)
                        for e in joints]
        self._ordered = sorted(self._starts)
        self.now = now
        #: within the settling time after a declaration, or the tool off an obstacle
        self.settling = now < settled_at

    def late(self, joint: int) -> bool:
        """Whether evidence of `joint` that begins now begins while the arm is disturbed."""
        ordered = self._ordered
        first = self._starts[joint] == ordered[0] and len(ordered) > 1
        others = ordered[1] if first else ordered[0]  # the earliest start of another joint
        return self.settling or others < self.now


#: Says why joints about to be declared failed (their indices, and when the earliest
#: one's evidence began, s) are not (the tool in contact), or None.
Veto = Callable[[list[int], float], str | None]


def declare_swings(joints: list[JointEvidence], own: list[bool], now: float,
                   disturbance: Disturbance, persistence: float, settle: float,
                   wait: Callable[[int, float], float], veto: Veto | None = None,
                   spared: Sequence[bool] = ()) -> tuple[list[int], list[int], str | None]:
    """Joints newly declared free-swinging at `now` (s), those of them that were locked.

    `own[j]`: joint j moves on its own at this update; `wait(j, since)`: how long (s)
    beyond `persistence` it must go on doing so, having done so since `since` (s);
    `settle`: the plant's settling time (s). A joint declared locked that moves was never
    locked: it swings, and its lock is taken back. When `veto` gives a reason for the
    joints ready to be declared, none of them is, their evidence starts anew, and the
    reason is returned last; it is not asked about the `spared` ones (`_vetoed`).
    """
    ready = []
    for j, evidence in enumerate(joints):
        if not own[j]:
            evidence.swing_since = None
            continue
        if evidence.swinging_at is not None:
            continue
        if evidence.swing_since is None:
            evidence.swing_since, evidence.swing_late = now, disturbance.late(j)
        needed = persistence + wait(j, evidence.swing_since)
        if evidence.swing_late:
            needed = max(needed, persistence + settle)
        if now - evidence.swing_since >= needed:
            ready.append(j)
    reason, ready = _vetoed(joints, ready, veto, "swing_since", now, spared)
    released = [j for j in ready if joints[j].locked_at is not None]
    for j in ready:
        joints[j].swinging_at, joints[j].locked_at = now, None
    return ready, released, reason


def declare_locks(joints: list[JointEvidence], supported: list[bool], latest: Sequence[float],
                  now: float, disturbance: Disturbance, persistence: float,
                  settle: float, veto: Veto | None = None, spared: Sequence[bool] = (),
                  ) -> tuple[list[int], str | None]:
    """Joints newly declared locked at `now` (s), where they are (`latest`, rad).

    `supported[j]`: joint j is a lock candidate and another joint is seen moving as
    commanded (`rules.vouching`). `veto` is asked at every update with a supported
    joint; when it gives a reason, none of them is declared, their evidence starts anew,
    and the reason is returned (with the `spared` joints declared, about which it is not
    asked: `_vetoed`). So a stall must last
    `persistence` after the last moment a veto explained it: a joint stalled by a wall
    that was just removed, still catching up on what it was commanded meanwhile, is
    judged only from the removal on.
    """
    ready = []
    for j, evidence in enumerate(joints):
        if not supported[j]:
            evidence.evidence_since = None
            continue
        if evidence.evidence_since is None:
            evidence.evidence_since, evidence.evidence_late = now, disturbance.late(j)
        if now - evidence.evidence_since >= persistence + settle * evidence.evidence_late:
            ready.append(j)
    under_way = [j for j, s in enumerate(supported) if s]
    reason, left = _vetoed(joints, under_way, veto, "evidence_since", now, spared)
    ready = [j for j in ready if j in left]
    for j in ready:
        evidence = joints[j]
        evidence.locked_at, evidence.position = now, float(latest[j])
        # Seen swinging before: should it move on its own again, it swings again.
        evidence.swinging_at = None
    return ready, reason


def _vetoed(joints: list[JointEvidence], ready: list[int], veto: Veto | None, since: str,
            now: float, spared: Sequence[bool] = ()) -> tuple[str | None, list[int]]:
    """`veto`'s reason for the `ready` joints, and those of them it leaves to be declared.

    It is asked about the joints not `spared` (`spared[j]`: a drive that gives no torque,
    which pushes against nothing, so that contact explains nothing of its joint); given
    a reason, their evidence (field `since`) starts anew and only the spared are left.
    """
    asked = [j for j in ready if not (j < len(spared) and spared[j])]
    if not asked or veto is None:
        return None, ready
    reason = veto(asked, min(getattr(joints[j], since) or now for j in asked))
    if reason is None:
        return None, ready
    for j in asked:
        setattr(joints[j], since, now)
    return reason, [j for j in ready if j not in asked]
