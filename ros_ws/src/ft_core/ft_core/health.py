"""What a joint still gives: its state (healthy, degraded, locked, free-swinging) and margins.

The monitor judges every joint from commanded against measured motion and publishes
one `JointHealth` per joint (`ft/joint_health`, docs/monitor.md); the controller adapts
to it (a degraded joint's speed and weight lowered, its usable range a hard limit).

States are ordered by what is left of the joint: healthy, then degraded (it moves, slower
than commanded or within a narrower range), then locked (it holds still, brake or jam;
Lewis & Maciejewski 1997, sec. I), then free-swinging (its drive has no torque; it moves
as gravity and the other links make it, Maciejewski et al. sec. 2.3). A declared state
changes only to a worse one until the monitor's `~/reset` (`Health.worst`).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # the detector's package, not loaded where only health is read
    from ft_core.detection.evidence import JointEvidence


class Health(enum.StrEnum):
    """A joint's state, from best to worst (the order of `rank`)."""

    HEALTHY = "healthy"
    DEGRADED = "degraded"
    LOCKED = "locked"
    FREE_SWINGING = "free-swinging"

    @property
    def rank(self) -> int:
        """0 for healthy up to 3 for free-swinging: larger is worse."""
        return list(Health).index(self)

    @staticmethod
    def worst(a: Health, b: Health) -> Health:
        """The worse of two states."""
        return a if a.rank >= b.rank else b


@dataclass(frozen=True)
class JointHealth:
    """One joint's state and what it still gives.

    Attributes:
        state: see `Health`.
        follows: fraction (0-1) of its commanded velocity the joint follows, measured over
            its recent commanded motion; nan when it has not been commanded enough to say.
        torque_margin: share (0-1) of its effort limit left at the largest effort seen
            lately; nan when the driver reports no efforts or the URDF gives no limit.
        usable_lower, usable_upper: rad, the range the joint can still reach (its URDF
            limits unless a stop was found inside them).
        since: s, when the state was declared (nan for healthy).
        braked: a free-swinging joint declared locked where it is (its brake asked for).
        evidence: one line saying what the state rests on.
    """

    state: Health = Health.HEALTHY
    follows: float = math.nan
    torque_margin: float = math.nan
    usable_lower: float = -math.inf
    usable_upper: float = math.inf
    since: float = math.nan
    braked: bool = False
    evidence: str = ""

    @property
    def usable(self) -> bool:
        """Whether a controller may command the joint (healthy or degraded)."""
        return self.state in (Health.HEALTHY, Health.DEGRADED) and not self.braked


#: s over which the largest effort seen counts for the torque margin (forgotten
#: exponentially with this time constant).
EFFORT_MEMORY = 1.0


class HealthBoard:
    """Each joint's declared state, kept from flapping: it changes only to a worse one.

    The monitor declares states as its detector decides them (`declare`); a joint stays
    in its state until `reset` (after a repair), whatever the detector sees later: a
    locked joint that moves again is free-swinging, never healthy again; a free-swinging
    joint that comes to rest stays free-swinging.
    """

    def __init__(self, n: int):
        self.n = n
        self.reset()

    def reset(self) -> None:
        """Every joint healthy again."""
        self.states = [Health.HEALTHY] * self.n
        self.since = [math.nan] * self.n
        self.evidence = [""] * self.n
        self.braked = [False] * self.n
        self._peak = np.full(self.n, math.nan)  # N m, the largest |effort| lately, forgotten
        self._effort_at = -math.inf  # s, the time of the last efforts

    def declare(self, joint: int, state: Health, now: float, evidence: str,
                braked: bool = False) -> bool:
        """`joint` is in `state` at `now` (s), as `evidence` says; whether that changed it.

        Only a worse state replaces the one declared; `braked` marks a free-swinging joint
        declared locked where it is, and stays.
        """
        changed = state.rank > self.states[joint].rank
        if changed:
            self.states[joint], self.since[joint], self.evidence[joint] = state, now, evidence
        if braked and not self.braked[joint]:
            self.braked[joint] = changed = True
        return changed

    def effort(self, now: float, effort: np.ndarray) -> None:
        """The efforts (N m, chain order) the driver reports at `now` (s)."""
        decay = math.exp(-max(now - self._effort_at, 0.0) / EFFORT_MEMORY)
        self._peak = np.fmax(np.abs(effort), np.nan_to_num(self._peak) * decay)
        self._effort_at = now

    def torque_margin(self, joint: int, limit: float) -> float:
        """Share (0-1) of `limit` (N m) above the largest effort of `joint` lately; nan unknown."""
        if not math.isfinite(limit) or math.isnan(self._peak[joint]):
            return math.nan
        return min(max(1.0 - float(self._peak[joint]) / limit, 0.0), 1.0)

    def of(self, state: Health) -> list[int]:
        """The joints in `state`, in chain order."""
        return [j for j, s in enumerate(self.states) if s == state]

    def report(self, joint: int, evidence: JointEvidence) -> JointReport:
        """`joint`'s state for diagnostics, from its declared state and `evidence`.

        A declared free swing, then a lock (braked or not), then a stall at a joint limit,
        then a declared degradation: the first that holds.
        """
        declared = self.states[joint]
        if declared == Health.FREE_SWINGING:
            state = JointCondition.FREE_SWINGING
        elif evidence.locked_at is not None:
            state = JointCondition.LOCKED
        elif evidence.at_limit:
            state = JointCondition.AT_LIMIT
        elif declared == Health.DEGRADED:
            state = JointCondition.DEGRADED
        else:
            state = JointCondition.OK
        return JointReport(state, replace(evidence))

    def health(self, joint: int, follows: float, torque_margin: float, lower: float,
               upper: float) -> JointHealth:
        """`joint`'s `JointHealth`, with the measured share, margin and range given."""
        return JointHealth(self.states[joint], follows, torque_margin, lower, upper,
                           self.since[joint], self.braked[joint], self.evidence[joint])


class JointCondition(enum.StrEnum):
    """A joint's state for diagnostics (`JointReport.state`)."""

    OK = "ok"
    LOCKED = "locked"
    FREE_SWINGING = "free-swinging"
    AT_LIMIT = "stalled at a joint limit"
    DEGRADED = "degraded"


@dataclass(frozen=True)
class JointReport:
    """One joint's state for diagnostics.

    Attributes:
        state: ok, degraded, locked, free-swinging or stalled at a joint limit
            (`JointCondition`).
        evidence: the detector's evidence at its last update (a copy).
    """

    state: JointCondition
    evidence: JointEvidence
