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
from dataclasses import dataclass


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
