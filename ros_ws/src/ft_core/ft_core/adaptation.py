"""The controller adapted to what is left of the arm: joint health into limits, weights, pins.

The monitor says per joint what it still gives (`ft_core.health.JointHealth`, on
`ft/joint_health`); `derive` turns that into what the engine uses (docs/controller.md,
"Adapting to the joints left"):

- a **degraded** joint's velocity limit times the share of its command it follows
  (`follows`), at least `MIN_FOLLOWS` of it (nan, not measured yet: unchanged);
- its failure probability raised in the weighting of Xie 2019 eq. 3.3 (w_i = p_i / sum p):
  p_i becomes max(p_i, p_max) / f, p_max the largest probability of any joint and f its
  `follows` within [`MIN_FOLLOWS`, `DEGRADED_FOLLOWS`] (`DEGRADED_FOLLOWS` when not
  measured). Our reading: a joint that has begun to fail is at least as likely to fail
  next as the likeliest joint without evidence, and the more so the less of its command
  it gives; the monitor calls a joint degraded below half its command, so a joint
  degraded by other evidence (a stop inside its range) counts as one at that threshold,
  twice the likeliest. The kfm ascent (on F_w, Xie eq. 3.3) then keeps the arm able to
  lose that joint, and the minimum-jump term moves the command towards the velocity
  without it: the null space shifts away from the degraded joint;
- a usable range narrower than the URDF's becomes a **hard limit** (kept after a lock,
  unlike the soft limits);
- a joint locked or free-swinging by health, or braked, is **pinned**: held at 0 and left
  out of the Jacobian as a locked joint is, whether or not `ft/locked_joints` names it yet.

`Adaptation` holds the latest health. A degraded joint's share is taken as the lowest
the monitor has reported since it declared the joint, rounded down to `FOLLOWS_STEP`: the
measured share wanders with the motion, and is not measured at all (nan) while the joint
is hardly commanded, so this way the limits change (and the engine is rebuilt) a few
times per joint at most, and the joint stays slowed until the monitor's reset, as its
state stays declared. `Adaptation.judge` says, each cycle, whether the joints left can do
the task: not with no joint left, nor with joints lost and the
reduced Jacobian's smallest singular value below `MIN_SIGMA` at the current configuration
and at every one of `MOVES` configurations around it (the joints left moved by
`NEIGHBOURHOOD` each way, the lost ones where they are): a direction of the task the
joints left have lost, not a singularity they can move out of (the planar 3R stretched
out with its last joint locked is one: bending the elbow leaves it). Then the controller
commands zeros (on its ramp) and says why, until the set of usable joints changes (the
monitor's reset). Fewer usable joints than task coordinates is infeasible only once they
can produce less than `MIN_PRODUCIBLE` of the task velocity asked for `GIVE_UP_AFTER`:
otherwise the engine's least squares takes the tool to the nearest pose the joints left
reach (a PUMA 560 with a locked joint on a pose task: within 0 mm and 8 degrees of its
goals).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ft_core.engine import CycleResult, EngineConfig
from ft_core.health import Health, JointHealth
from ft_core.robots import Robot

#: Smallest share of its velocity limit a degraded joint keeps: a joint that follows
#: less (friction seen while nearly stopped) still gets commands the monitor can observe
#: (0.1 of the Panda's 2.2-2.6 rad/s at velocity_scale 0.5 is above the monitor's
#: smallest observable command, 0.05 rad/s), instead of being locked undeclared.
MIN_FOLLOWS = 0.1
#: The share a degraded joint is weighted as following at most (see the module docstring).
DEGRADED_FOLLOWS = 0.5
#: Steps in which `Adaptation` takes a degraded joint's share (rounded down).
FOLLOWS_STEP = 0.05
#: m (scaled Jacobian, `Robot.scale_task`): with joints pinned, a reduced Jacobian whose
#: smallest singular value is below this has lost a task direction here: 1 mm/s of the
#: tool per rad/s of the joints, a tenth of the damping's threshold (0.01 m), so a reduced
#: arm passing near a singularity it can leave is not stopped.
MIN_SIGMA = 1e-3
#: rad each joint left is moved, each way, around the current configuration to tell a lost
#: direction from a singularity the joints left can move out of.
NEIGHBOURHOOD = 0.2
#: How many configurations around the current one are tried (fixed sign patterns).
MOVES = 8
#: Least share of the commanded task velocity (scaled) the joints left must be able to
#: produce, when fewer than the task coordinates, for the task to go on.
MIN_PRODUCIBLE = 0.5
#: s the share may stay below `MIN_PRODUCIBLE` before the task is given up.
GIVE_UP_AFTER = 1.0
#: The controller's problem kind (diagnostics, log) while the task is infeasible.
INFEASIBLE = "task infeasible"


@dataclass(frozen=True)
class Derived:
    """What the engine uses of the joints' health (chain order; see `derive`).

    Attributes:
        velocity_factors: per joint, the share of its velocity limit; () when all 1.
        probabilities: the failure probabilities to weight with; () for the configured.
        hard_lower, hard_upper: rad, usable ranges as hard limits; () when none narrower.
        pinned: chain indices of joints locked, free-swinging or braked by health.
    """

    velocity_factors: tuple[float, ...] = ()
    probabilities: tuple[float, ...] = ()
    hard_lower: tuple[float, ...] = ()
    hard_upper: tuple[float, ...] = ()
    pinned: tuple[int, ...] = ()

    def apply(self, config: EngineConfig) -> EngineConfig:
        """`config` with these limits and weights (the configured ones where none)."""
        return replace(config, velocity_factors=self.velocity_factors,
                       failure_probabilities=self.probabilities or config.failure_probabilities,
                       hard_lower=self.hard_lower, hard_upper=self.hard_upper)


def problem(health: JointHealth) -> str | None:
    """Why a joint's health is not the monitor's (a number no measurement gives), or None.

    `follows` and `torque_margin` are finite or nan (a share measured beyond 1 or below 0
    is a measurement: a healthy joint follows about 1 or more, one pushed back by gravity
    less than 0); the usable range is not nan (`ft_msgs_py.health.read` refuses one upside
    down).
    """
    for name in ("follows", "torque_margin"):
        value = getattr(health, name)
        if math.isinf(value):
            return f"{name} is {value!r}: a measured share is finite (or nan: none)"
    if math.isnan(health.usable_lower) or math.isnan(health.usable_upper):
        return "the usable range has a nan side"
    return None


def _follows(health: JointHealth, default: float) -> float:
    """The joint's `follows` within [MIN_FOLLOWS, 1]; `default` when not measured."""
    return default if math.isnan(health.follows) else min(max(health.follows, MIN_FOLLOWS), 1.0)


def derive(robot: Robot, health: Mapping[int, JointHealth],
           probabilities: Sequence[float] = ()) -> Derived:
    """What the engine uses of `health` ({chain index: health}; joints not named: healthy).

    `probabilities`: the configured failure probabilities (chain order; empty: equal).
    See the module docstring for the rules.
    """
    n = robot.n
    factors = np.ones(n)
    p = np.array(probabilities if len(probabilities) else np.ones(n), dtype=float)
    lower, upper = robot.lower.copy(), robot.upper.copy()
    p_max, pinned, degraded = float(p.max()), [], False
    for j, h in health.items():
        if not h.usable:
            pinned.append(j)
            continue
        lower[j] = min(max(h.usable_lower, robot.lower[j]), robot.upper[j])
        upper[j] = max(min(h.usable_upper, robot.upper[j]), lower[j])
        if h.state == Health.DEGRADED:
            degraded = True
            factors[j] = _follows(h, 1.0)
            p[j] = max(p[j], p_max) / min(_follows(h, DEGRADED_FOLLOWS), DEGRADED_FOLLOWS)
    narrower = np.any(lower > robot.lower) or np.any(upper < robot.upper)
    return Derived(velocity_factors=tuple(factors.tolist()) if np.any(factors < 1) else (),
                   probabilities=tuple(p.tolist()) if degraded else (),
                   hard_lower=tuple(lower.tolist()) if narrower else (),
                   hard_upper=tuple(upper.tolist()) if narrower else (),
                   pinned=tuple(sorted(pinned)))


class Adaptation:
    """The latest joint health, what the engine derives from it, and the task's feasibility.

    Args:
        robot: the chain.
    """

    def __init__(self, robot: Robot):
        self.robot = robot
        #: {chain index: health} of the joints the monitor does not call healthy.
        self.health: dict[int, JointHealth] = {}
        self.derived = Derived()
        self._probabilities: tuple[float, ...] = ()  # the configured ones (chain order)
        self._shares: dict[int, float] = {}  # a degraded joint's lowest share reported
        #: Why the task is infeasible with the joints left (None: it is not, or not judged).
        self.infeasible: str | None = None
        self._judged: tuple[int, ...] | None = None  # the pinned set it was judged for
        self._said = False  # whether the controller has reported `infeasible`
        self._short_since = math.nan  # s, since when too little of the task is producible
        #: Each joint moved by +-NEIGHBOURHOOD, in fixed patterns (`_lost`).
        self._moves = NEIGHBOURHOOD * np.random.default_rng(0).choice([-1.0, 1.0],
                                                                      (MOVES, robot.n))

    def set_health(self, health: Mapping[int, JointHealth]) -> bool:
        """The monitor's latest health ({chain index: health}); whether the engine changes.

        A degraded joint's `follows` is taken as the lowest share reported since it was
        declared, rounded down to `FOLLOWS_STEP` (see the module docstring).
        """
        shares: dict[int, float] = {}
        for j, h in health.items():
            if h.state == Health.DEGRADED:
                lowest = self._shares.get(j, math.inf)
                if not math.isnan(h.follows):
                    step = math.floor(round(h.follows / FOLLOWS_STEP, 6)) * FOLLOWS_STEP
                    lowest = min(lowest, max(step, MIN_FOLLOWS))
                if math.isfinite(lowest):
                    shares[j] = lowest
        self._shares = shares
        self.health = {j: replace(h, follows=shares.get(j, h.follows))
                       for j, h in sorted(health.items()) if h.state != Health.HEALTHY
                       or h.usable_lower > self.robot.lower[j]
                       or h.usable_upper < self.robot.upper[j]}
        derived = derive(self.robot, self.health, self._probabilities)
        changed = derived != self.derived
        self.derived = derived
        return changed

    def adapt(self, config: EngineConfig) -> EngineConfig:
        """The engine's configuration `config` adapted to the latest health (`Derived.apply`)."""
        probabilities = tuple(config.failure_probabilities)
        if probabilities != self._probabilities:
            self._probabilities = probabilities
            self.derived = derive(self.robot, self.health, probabilities)
        return self.derived.apply(config)

    def pinned(self, locked: Sequence[int]) -> tuple[int, ...]:
        """The joints the engine must not use: `locked` and those pinned by health."""
        return tuple(sorted({*locked, *self.derived.pinned}))

    def judge(self, result: CycleResult, pinned: tuple[int, ...], q: np.ndarray,
              xd: np.ndarray, now: float) -> dict[str, str | None]:
        """The cycle's `INFEASIBLE` problem: {INFEASIBLE: why} while the task is infeasible.

        `result`: the engine's cycle at the configuration `q` (rad) with the `pinned`
        joints held, for the task velocity `xd`, at `now` (s). Once infeasible for a
        pinned set (rules: the module docstring), it stays so until the set changes (the
        arm is commanded to rest: its configuration no longer says anything new).
        {INFEASIBLE: None} once when it ends, {} otherwise.
        """
        if pinned != self._judged:
            self._judged, self.infeasible, self._short_since = pinned, None, math.nan
        if self.infeasible is None:
            self.infeasible = self._why(result, pinned, q, xd, now)
        if self.infeasible is not None:
            self._said = True
            return {INFEASIBLE: self.infeasible}
        if self._said:
            self._said = False
            return {INFEASIBLE: None}
        return {}

    def _why(self, result: CycleResult, pinned: tuple[int, ...], q: np.ndarray,
             xd: np.ndarray, now: float) -> str | None:
        robot = self.robot
        left = [name for j, name in enumerate(robot.joint_names) if j not in pinned]
        joints = f"{len(left)} joints left ({', '.join(left) or 'none'})"
        until = "commanding zeros until the usable joints change (the monitor's reset)"
        if not left:
            return f"no joint left for the {robot.task_space} task; {until}"
        share = self._producible(q, pinned, xd) if len(left) < robot.m else math.nan
        if not share < MIN_PRODUCIBLE:  # also nan: not judged (enough joints, or idle)
            self._short_since = math.nan
        elif math.isnan(self._short_since):
            self._short_since = now
        elif now - self._short_since >= GIVE_UP_AFTER:
            return (f"{joints} for the {robot.m} coordinates of the {robot.task_space} task "
                    f"can produce {share:.0%} of the task velocity asked (for "
                    f"{GIVE_UP_AFTER:g} s); {until}")
        if pinned and result.sigma_min < MIN_SIGMA and self._lost(q, pinned):
            return (f"{joints} have lost a direction of the {robot.task_space} task "
                    f"(smallest singular value {result.sigma_min:.2g} m, below {MIN_SIGMA:g}, "
                    f"here and within {NEIGHBOURHOOD:g} rad of the joints left); {until}")
        return None

    def _producible(self, q: np.ndarray, pinned: tuple[int, ...], xd: np.ndarray) -> float:
        """Share of the task velocity `xd` the joints not `pinned` produce at best (scaled).

        nan for a task velocity too small to say (the arm at its goal).
        """
        robot = self.robot
        wanted = robot.scale_task(np.asarray(xd, dtype=float)[:, None])[:, 0]
        size = float(np.linalg.norm(wanted))
        if size < 1e-4:
            return math.nan
        left = np.setdiff1d(np.arange(robot.n), pinned)
        J = robot.scale_task(robot.jacobian(q))[:, left]
        produced = J @ np.linalg.lstsq(J, wanted, rcond=None)[0]
        return float(np.linalg.norm(produced)) / size

    def _lost(self, q: np.ndarray, pinned: tuple[int, ...]) -> bool:
        """Whether the joints not `pinned` lack a task direction at every move around q."""
        robot = self.robot
        left = np.setdiff1d(np.arange(robot.n), pinned)
        for move in self._moves:
            moved = np.array(q, dtype=float)
            moved[left] += move[left]
            J = robot.scale_task(robot.jacobian(moved))[:, left]
            if np.linalg.svd(J, compute_uv=False)[-1] >= MIN_SIGMA:
                return False
        return True

    @property
    def note(self) -> str:
        """What the controller adapted, for diagnostics ("none" when nothing)."""
        robot, derived = self.robot, self.derived
        parts = []
        for j, h in self.health.items():
            part = f"{robot.joint_names[j]} {h.state}"
            if j in derived.pinned:
                part += " (pinned)"
            if derived.velocity_factors and derived.velocity_factors[j] < 1:
                part += f", speed x{derived.velocity_factors[j]:.2f}"
            if derived.hard_lower and (derived.hard_lower[j] > robot.lower[j]
                                       or derived.hard_upper[j] < robot.upper[j]):
                part += f", range [{derived.hard_lower[j]:.3f}, {derived.hard_upper[j]:.3f}]"
            parts.append(part)
        return "; ".join(parts) or "none"
