"""How much of its command each joint follows: the share behind a degraded joint.

A joint whose drive is weakened (friction, lost torque authority) still moves, slower
than commanded; the lock test (`rules.is_stalled`, under `ratio` of the command) does
not see it, or sees it late and then takes it for a lock. `FollowMeter` measures, per
joint, the share of its commanded motion the joint made: the measured window slope v
along the weakest plausible prediction c, against |c|, both integrated over the updates
where the joint is judged (observable, not locked, not at a limit, not moving on its
own) and forgotten with time constant `MEMORY`:

    share = sum(v sign(c) dt e^(-age / MEMORY)) / sum(|c| dt e^(-age / MEMORY))

Displacements, not velocities: a servo that ran ahead of its reference and pauses for
it to catch up (docs/detection.md, "A lock loses position") loses nothing over the
memory, while a joint that follows half its command loses half of it steadily. The
weakest plausible prediction is what the slowest plausible healthy plant would have
done, so a healthy joint's share is about 1 or more. A joint is **degraded** once its
share, over at least `MIN_MOTION` of commanded motion, has stayed below
`DEGRADED_SHARE` for `PERSISTENCE`, or below `RESISTED_SHARE` where its drive's
efforts show something resisting its motion hard (`drives.Drives.resisted`): a friction
that saturates the drive slows the joint to about `DEGRADED_SHARE` of the weakest
prediction, where the share alone would wait on it.
"""

from __future__ import annotations

import math

import numpy as np

#: s, forgetting time of the shares.
MEMORY = 0.3
#: Share of its command below which a joint is degraded.
DEGRADED_SHARE = 0.5
#: Share below which a joint whose motion something resists hard is degraded
#: (`drives.Drives.resisted`): its drive's torque is spent, not its servo slow.
RESISTED_SHARE = 0.7
#: rad of commanded motion (forgotten as the shares) before a share says anything.
MIN_MOTION = 0.02
#: s a share must stay below `DEGRADED_SHARE`.
PERSISTENCE = 0.1


class FollowMeter:
    """Each joint's share of its commanded motion; see the module docstring."""

    def __init__(self, n: int):
        self.n = n
        self.reset()

    def reset(self) -> None:
        """Forget every share."""
        self.moved = np.zeros(self.n)  #: rad, measured motion along the command, forgotten
        self.commanded = np.zeros(self.n)  #: rad, commanded motion, forgotten
        self._below_since: list[float | None] = [None] * self.n

    def forget(self, joints: list[int]) -> None:
        """Forget the shares of `joints` (their motion said nothing of their drives)."""
        self.moved[joints] = self.commanded[joints] = 0.0
        for j in joints:
            self._below_since[j] = None

    @property
    def shares(self) -> np.ndarray:
        """(n,) share (0-1) of its command each joint followed (nan: too little commanded).

        A joint ahead of the weakest plausible prediction followed all of it: 1.
        """
        known = self.commanded >= MIN_MOTION
        share = np.divide(self.moved, self.commanded, out=np.zeros(self.n), where=known)
        return np.where(known, np.clip(share, 0.0, 1.0), math.nan)

    def update(self, now: float, dt: float, measured: np.ndarray, weakest: np.ndarray,
               judged: np.ndarray, resisted: np.ndarray | None = None) -> list[int]:
        """One decision's slopes (rad/s) over `dt` s; the joints degraded now, in order.

        Args:
            now: the decision's time (s).
            dt: s since the previous decision.
            measured: (n,) measured window slopes v.
            weakest: (n,) weakest plausible predictions c.
            judged: (n,) joints whose motion counts at this decision.
            resisted: (n,) joints whose motion something resists hard now, judged
                against `RESISTED_SHARE` (None: none).

        Returns:
            The joints whose share has stayed below `DEGRADED_SHARE` for `PERSISTENCE`
            (from then on at every call: the caller keeps what it declared).
        """
        decay = math.exp(-dt / MEMORY)
        self.moved *= decay
        self.commanded *= decay
        self.moved += np.where(judged, measured * np.sign(weakest) * dt, 0.0)
        self.commanded += np.where(judged, np.abs(weakest) * dt, 0.0)
        bar = (DEGRADED_SHARE if resisted is None
               else np.where(resisted, RESISTED_SHARE, DEGRADED_SHARE))
        low = (self.shares < bar).tolist()  # nan compares False
        degraded = []
        for j, is_low in enumerate(low):
            if not is_low:
                self._below_since[j] = None
                continue
            since = self._below_since[j]
            if since is None:
                self._below_since[j] = since = now
            if now - since >= PERSISTENCE:
                degraded.append(j)
        return degraded
