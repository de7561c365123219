"""One control cycle of fault-tolerant redundancy resolution.

`ResolutionEngine.step(kinematics, xd, locked)` turns the kinematics at the joint
positions (`Robot.kinematics`, one snapshot a cycle), a desired task velocity and the
set of locked joints into joint velocities (docs/engine.md):

    qd = J# xd + (I - J# J) z            (Lewis & Maciejewski 1997 eq 4, Maciejewski et al. eq 3)

on the reduced robot (the Jacobian columns of locked joints removed; their
velocity is exactly 0). J# is the damped pseudo-inverse of `pseudoinverse`;
singular values are compared on `Robot.scale_task(J)` (angular rows times the
characteristic length). The null-space preference z sums, by `resolution`:

- `max_kfm` and `blend`: kfm_gain * grad K (Maciejewski et al. eq 8, soft-min remedy for
  ties, see `measures.kfm_gradient`), or the gradient of the failure-probability
  weighted measure F_w (Xie 2019 eq 3.3) when probabilities are given; taken at the
  cycle's configuration, or at `step`'s `commanded` (the controller's: where its
  commands are taking the arm, `reference`);
- `min_jump` and `blend`: jump_gain * sum_i w_i iqd' (Zhao & Li eq 5; gain 1 is
  the exact minimum-jump solution);
- always, when a box applies: limit_gain * `limits.avoidance` away from the edges
  of the effective box (soft limits intersected with the URDF limits), with every other
  term scaled by `limits.edge_yield` first: near an edge a preference that moves a joint
  towards it yields, so no preference holds a joint on an edge; both taken where the
  commands are taking the arm (`step`'s `commanded`), like the ascent;
- in every mode, when swing_gain > 0: -swing_gain * grad h, descent on the swing
  measure of free-swinging failures (`swing`, Maciejewski et al. eq 14 used in eq 3 as the
  paper proposes; zero for a URDF without inertias). About 0.6 ms a cycle on 7
  joints (numpy over every joint pair, not compiled): off by default.

The kfm and jump terms refer to the next failure and are used only while
n - |locked| - 1 >= m. Hard limits (URDF positions, narrowed where a joint's usable
range is: `hard_lower`/`hard_upper`; velocity_scale times URDF velocities, times a
degraded joint's `velocity_factors`) and, while no joint is locked or when configured
to keep them, the soft limits are enforced on qd itself by saturation in the null space
(`limits.saturate_in_null_space`), within velocity bounds from which every joint can
still stop inside them, braking within the commands' acceleration and jerk limits
(`acceleration`, `jerk`) from where the commands already sent take it
(`limits.velocity_bounds`); without those limits, q integrated over dt never leaves them;
the task is scaled down, direction kept, only as a last resort. With fewer
healthy joints than task coordinates the cycle returns the damped least-squares
velocity scaled into the bounds and reports the task infeasible.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from ft_core import limits, measures, postfailure, robots, swing
from ft_core.engine_config import RESOLUTIONS as RESOLUTIONS  # the engine's public names
from ft_core.engine_config import (
    EngineConfig,
    Resolution,
    braking,
    check_config,
    hard_limits,
    velocity_limits,
)
from ft_core.observability import MIN_SHARE
from ft_core.pseudoinverse import damped_pinv
from ft_core.robots import Kinematics, Robot


class Status(enum.StrEnum):
    """What a cycle achieved, from best to worst (published as its string value)."""

    OK = "ok"
    NEAR_SINGULARITY = "near_singularity"
    LIMITED = "limited"  # the task was scaled down to keep the joints within their bounds
    INFEASIBLE = "infeasible"  # fewer healthy joints than task coordinates


class Gains(NamedTuple):
    """The scalar settings of the compiled cycle (`EngineConfig`'s, by name).

    The cycle receives them as one float array in this order (numba checks an
    array's type in a fraction of the time it takes for a tuple of seven).
    """

    kfm: float
    jump: float
    limit: float
    kfm_temperature: float
    limit_buffer: float
    damping_threshold: float
    max_damping: float


#: Distance (rad or m) within which a joint counts as at a limit.
AT_LIMIT = 1e-3


@dataclass(slots=True)
class CycleResult:
    """What one cycle computed: the command and the numbers the controller publishes.

    Attributes:
        qd: joint velocities (n,), rad/s; exactly 0 for locked joints.
        status: what the cycle achieved (`Status`).
        kfm: K of the reduced robot for the next failure (m/s per rad/s, scaled J).
        sigma_min: smallest singular value of the reduced, scaled Jacobian.
        post_failure_sigmas: s_i per joint (n,), nan for locked joints.
        jump_index: weighted jump index of qd (rad^2/s^2), 0 when not defined.
        task_scale: fraction of xd achieved, 1 = fully.
        soft_limit_margin: smallest distance (rad) of q to an active soft limit
            (negative outside; inf with no soft box).
        saturated: joints whose velocity was held at a bound (n,).
        at_soft_limit, at_hard_limit: joints within 1e-3 of an active soft or URDF limit.
    """

    qd: np.ndarray
    status: Status
    kfm: float
    sigma_min: float
    post_failure_sigmas: np.ndarray
    jump_index: float
    task_scale: float
    soft_limit_margin: float
    saturated: np.ndarray
    at_soft_limit: np.ndarray
    at_hard_limit: np.ndarray


@dataclass(frozen=True)
class _LockedSet:
    """What depends only on which joints are locked, computed once per locked set."""

    locked: bool  #: whether any joint is locked
    healthy: np.ndarray  #: indices of the healthy joints
    soft: bool  #: whether the soft box applies
    #: rows of the healthy joints: effective lower and upper limits (rad), velocity
    #: limits (rad/s), failure weights, braking lead (s) and deceleration (rad/s^2)
    #: (`BOX_ROWS`)
    box: np.ndarray
    use_kfm: bool  #: whether the kfm gradient is part of the preference
    use_jump: bool  #: whether the minimum-jump term is part of the preference
    zeros: np.ndarray  #: zeros for the healthy joints: the swing bias when it is off


#: The rows of `_LockedSet.box`.
BOX_ROWS = ("lower", "upper", "velocity", "weights", "lead", "deceleration")


@njit(cache=True, error_model="numpy")
def _jump_index(reduced: np.ndarray, qd: np.ndarray, scale: float,
                weights: np.ndarray) -> float:
    """The weighted jump index n sum_i w_i |scale iqd' - qd|^2 (rad^2/s^2, Zhao & Li eq 9)."""
    n = qd.size
    total = 0.0
    for i in range(n):
        squared = 0.0
        for j in range(n):
            jump = scale * reduced[i, j] - qd[j]
            squared += jump * jump
        total += weights[i] * squared
    return n * total


@njit(cache=True, error_model="numpy")
def _cycle(J6: np.ndarray, ascent_J6: np.ndarray, ascent_apart: bool, xd: np.ndarray,
           q: np.ndarray, ahead: np.ndarray, healthy: np.ndarray, task_scale: np.ndarray,
           box: np.ndarray,
           gains: np.ndarray, use_kfm: bool, use_jump: bool, probabilities: bool,
           bias: np.ndarray, limit_box: np.ndarray, soft: bool) -> tuple:
    """`ResolutionEngine.step` for m <= healthy joints, compiled in one call.

    J6 is the tool point's 6-row Jacobian in the base's axes (`Robot.base_jacobian`),
    `ascent_J6` the one where the kfm gradient is taken (used only when `ascent_apart`),
    `ahead` (rad) the motion commanded that q does not show yet (`limits.velocity_bounds`),
    `box` the locked set's `BOX_ROWS`, `gains` `Gains` as an array, `bias` (healthy
    joints) is added to z, `limit_box` holds the robot's lower and upper limits and the
    soft box (rows, n). z = avoidance + `limits.edge_yield` x (bias, jump, kfm terms).
    qd = J# x + alpha (I - J# J) z with the largest alpha in [0, 1]
    that keeps it within the velocity bounds (`limits.preference_scale`), else
    `limits.saturate_in_null_space`. Returns, over all n joints (locked: qd 0, sigma
    nan): (qd, saturated, sigmas, at_soft, at_hard, kfm, sigma_min, jump index,
    task scale, soft-limit margin).
    """
    kfm_gain, jump_gain, limit_gain, temperature, buffer, threshold, max_damping = gains
    lower, upper, velocity, weights, lead, deceleration = box
    m, nh, n = task_scale.size, healthy.size, q.size
    if use_kfm:
        J, dJ = robots.task_jacobians(J6, m)
        ascent_J = J
        if ascent_apart:
            ascent_J, dJ = robots.task_jacobians(ascent_J6, m)
    else:
        J, dJ = J6[:m], np.zeros((0, 0, 0))
        ascent_J = J
    Js = np.empty((m, nh))
    for a in range(m):
        for j in range(nh):
            Js[a, j] = task_scale[a] * J[a, healthy[j]]
    x = task_scale * xd
    qh = q[healthy]
    L, V, columns, sigmas, vectors, sigma_min = postfailure.analyse(Js)
    z = bias.copy()
    reduced = np.zeros((0, 0))
    if nh > m:
        reduced = postfailure.downdated_velocities(columns, x, L, V, sigmas, threshold,
                                                   max_damping)
        if use_jump:
            z += jump_gain * (weights @ reduced)
        if use_kfm:
            dJs = np.empty((nh, m, nh))
            for k in range(nh):
                for a in range(m):
                    for j in range(nh):
                        dJs[k, a, j] = task_scale[a] * dJ[healthy[k], a, healthy[j]]
            Ja, sigmas_a, vectors_a = Js, sigmas, vectors
            if ascent_apart:
                Ja = np.empty((m, nh))
                for a in range(m):
                    for j in range(nh):
                        Ja[a, j] = task_scale[a] * ascent_J[a, healthy[j]]
                sigmas_a, vectors_a = postfailure.analyse(Ja)[3:5]
            ascent = weights if probabilities else measures.kfm_weights(sigmas_a, temperature)
            z += kfm_gain * postfailure.weighted_sigma_gradient(Ja, dJs, sigmas_a, vectors_a,
                                                                ascent)
    pinv = postfailure.damped_inverse(columns, L, V, sigma_min, threshold, max_damping)
    qc = qh + ahead[healthy]  # where the commands sent take the healthy joints
    z = (limit_gain * limits.avoidance(qc, lower, upper, buffer)
         + limits.edge_yield(z - pinv @ (Js @ z), qc, lower, upper, buffer) * z)
    lo, hi = limits.velocity_bounds(qh, ahead[healthy], lower, upper, velocity, lead,
                                    deceleration)
    task = pinv @ x
    null_motion = z - pinv @ (Js @ z)
    qd_h = task + null_motion
    scale, saturated_h = 1.0, np.zeros(nh, dtype=np.bool_)
    if not limits.within(qd_h, lo, hi):
        # SNS's first step, the common case: shrink the preference beside the task.
        qd_h = task + limits.preference_scale(task, null_motion, lo, hi) * null_motion
        if not limits.within(qd_h, lo, hi):
            qd_h, scale, saturated_h = limits.saturate_in_null_space(
                Js, x, z, lo, hi, threshold, max_damping, pinv)
    jump = _jump_index(reduced, qd_h, scale, weights) if reduced.size else 0.0
    qd, saturated, sigmas_n = np.zeros(n), np.zeros(n, dtype=np.bool_), np.full(n, np.nan)
    for j in range(nh):
        qd[healthy[j]], saturated[healthy[j]] = qd_h[j], saturated_h[j]
        sigmas_n[healthy[j]] = sigmas[j]
    margin, at_soft, at_hard = _limit_report(q, limit_box, soft)
    return (qd, saturated, sigmas_n, at_soft, at_hard, sigmas.min(), sigma_min, jump, scale,
            margin)


@njit(cache=True, error_model="numpy")
def _input_problem(q: np.ndarray, xd: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> int:
    """0 when q and xd are usable; else 1 non-finite, 2 q absurd, 3 xd absurd.

    Checked in that order, in one compiled pass.
    """
    for values in (q, xd):
        for value in values:
            if not np.isfinite(value):
                return 1
    if limits.absurd_joint(q, lower, upper) >= 0:
        return 2
    for value in xd:
        if abs(value) > limits.ABSURD_SPEED:
            return 3
    return 0


_INPUT_PROBLEMS = {
    1: "q and xd must be finite",
    2: f"q is more than {limits.ABSURD_POSITION:g} rad outside the joint limits or beyond "
       f"{limits.ABSURD_MAGNITUDE:g} rad",
    3: f"xd exceeds {limits.ABSURD_SPEED:g} (m/s, rad/s): no arm can do that",
}


@njit(cache=True, error_model="numpy")
def _limit_report(q: np.ndarray, limit_box: np.ndarray,
                  soft: bool) -> tuple[float, np.ndarray, np.ndarray]:
    """(soft-limit margin, at_soft_limit, at_hard_limit) of `CycleResult`.

    `limit_box` rows: lower and upper joint limits, soft lower and upper (rad).
    """
    margin = np.inf
    at_soft = np.zeros(q.size, dtype=np.bool_)
    if soft:
        distance = np.minimum(q - limit_box[2], limit_box[3] - q)
        margin = distance.min()
        at_soft = distance < AT_LIMIT
    return margin, at_soft, np.minimum(q - limit_box[0], limit_box[1] - q) < AT_LIMIT


class ResolutionEngine:
    """Fault-tolerant redundancy resolution for one robot and one configuration.

    The cycle's arithmetic is compiled by numba on first use after installation
    (about 10 s on 2 cores) and cached on disk; the constructor runs a cycle of each
    path (every joint healthy, and too few left for the task: `_infeasible`) so that
    happens, or the cache is loaded, before the first control cycle (a pose task's
    first cycle after a second lock took 12 ms, 87 ms on a busy machine, loading it). Every
    compiled function of ft_core uses numba's numpy error model: a division by zero
    at an exact singularity gives inf or nan as numpy would (the damping and the
    clamps keep them out of the results), never an exception in the control loop.
    """

    def __init__(self, robot: Robot, config: EngineConfig | None = None):
        self.robot = robot
        self.config = config or EngineConfig()
        cfg = self.config
        self._probabilities, self._soft = check_config(robot, cfg)
        self._gains = np.array(Gains(
            kfm=cfg.kfm_gain, jump=cfg.jump_gain, limit=cfg.limit_gain,
            kfm_temperature=cfg.kfm_temperature, limit_buffer=cfg.limit_buffer,
            damping_threshold=cfg.damping.threshold, max_damping=cfg.damping.max_damping))
        self._hard = hard_limits(robot, cfg)
        #: The joint speeds the cycle allows (rad/s, `engine_config.velocity_limits`).
        self.speeds = velocity_limits(robot, cfg)
        self._lead, self._deceleration = braking(robot, cfg)
        self._limit_box = np.array([*self._hard,
                                    *(self._soft if self._soft[0].size else self._hard)])
        self._locked_sets: dict[tuple[int, ...], _LockedSet] = {}
        home = robot.kinematics(robot.home())
        self.step(home, np.zeros(robot.m))
        self.step(home, np.zeros(robot.m), range(min(robot.n, robot.n - robot.m + 1)))

    @property
    def ascends(self) -> bool:
        """Whether the cycle may take a kfm gradient (`resolution` and `kfm_gain`)."""
        return (self.config.resolution in (Resolution.MAX_KFM, Resolution.BLEND)
                and self.config.kfm_gain > 0)

    def soft_limits_active(self, any_locked: bool) -> bool:
        """Whether the soft box applies (configured, and not released by a failure)."""
        return self._soft[0].size > 0 and not (
            any_locked and self.config.release_soft_limits_on_failure)

    def bounds(self, locked: Iterable[int] = ()) -> tuple[np.ndarray, np.ndarray]:
        """The joint bounds (rad) enforced with `locked` joints.

        The hard limits (the URDF's, narrowed by `hard_lower`/`hard_upper`), within the
        soft box while it applies.
        """
        lower, upper = self._hard
        if self.soft_limits_active(bool(tuple(locked))):
            return np.maximum(lower, self._soft[0]), np.minimum(upper, self._soft[1])
        return lower.copy(), upper.copy()

    def velocity_bounds(self, q: np.ndarray, bounds: tuple[np.ndarray, np.ndarray],
                        ahead: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The cycle's joint-velocity bounds (lo, hi) (rad/s) at q (rad) within `bounds`.

        `bounds`: (lower, upper) position limits (rad, `bounds`); `ahead`: the motion
        commanded that q does not show yet (rad, `limits.velocity_bounds`), none if None.
        """
        return limits.velocity_bounds(q, np.zeros(q.size) if ahead is None else ahead,
                                      *bounds, self.speeds, self._lead, self._deceleration)

    def _locked_set(self, locked: Iterable[int]) -> _LockedSet:
        """The cached view of the robot with `locked` joints (validated on first use)."""
        key = tuple(sorted(set(locked)))
        view = self._locked_sets.get(key)
        if view is None:
            cfg, robot = self.config, self.robot
            healthy = ~measures.locked_mask(robot.n, key)
            soft = self.soft_limits_active(bool(key))
            lower, upper = self.bounds(key)
            p = None if self._probabilities is None else self._probabilities[healthy]
            if p is not None and not np.any(p > 0):
                p = None  # none of the healthy joints is expected to fail: equal weights
            nh = int(healthy.sum())
            next_failure = nh - 1 >= robot.m
            view = self._locked_sets[key] = _LockedSet(
                locked=bool(key), healthy=np.flatnonzero(healthy), soft=soft,
                box=np.array([lower[healthy], upper[healthy],
                              self.speeds[healthy],
                              measures.failure_weights(p, nh) if nh else np.zeros(0),
                              self._lead[healthy], self._deceleration[healthy]]),
                use_kfm=next_failure and self.ascends,
                use_jump=(next_failure
                          and cfg.resolution in (Resolution.MIN_JUMP, Resolution.BLEND)),
                zeros=np.zeros(nh))
        return view

    def _swing_descent(self, q: np.ndarray, view: _LockedSet) -> np.ndarray:
        """-swing_gain * grad h on the healthy joints (zeros when the gain is 0)."""
        healthy = view.healthy
        if self.config.swing_gain == 0:
            return view.zeros
        weights = np.zeros(self.robot.n)
        weights[healthy] = 1.0  # a locked joint is braked: it does not swing
        return -self.config.swing_gain * swing.swing_gradient(self.robot, q, weights)[healthy]

    def excursion(self, kinematics: Kinematics, qd: np.ndarray, joint: int, speed: float,
                  locked: Iterable[int] = ()) -> np.ndarray | None:
        """The command qd plus a null-space motion moving `joint` at `speed` (rad/s), or None.

        `kinematics`: the cycle's snapshot at the configuration q (`Robot.kinematics`).

        The motion is N e_j speed / N_jj with N = V V^T the projector on the null space of
        the healthy joints' Jacobian (V from its SVD), so J of the motion is 0 to numerical
        precision and `joint` moves at exactly `speed`. It is scaled down by the largest
        factor in [0, 1] that keeps qd + motion inside the velocity bounds of the active
        soft and hard limits (`limits.preference_scale`). None when N_jj is below
        `observability.MIN_SHARE`: the joint cannot move without moving the tool.
        (`ft_core.observability`.)
        """
        view = self._locked_set(locked)
        index = view.healthy
        if joint not in index:
            return None
        q = kinematics.q
        J = self.robot.scale_task(self.robot.jacobian(kinematics))[:, index]
        _, sigmas, Vt = np.linalg.svd(J)
        rank = int(np.sum(sigmas > 1e-12 * max(sigmas.max(initial=0.0), 1.0)))
        null = Vt[rank:].T
        k = int(np.flatnonzero(index == joint)[0])
        column = null @ null[k]
        if column[k] < MIN_SHARE:
            return None
        motion = speed * column / column[k]
        qd = np.array(qd, dtype=float)
        lower, upper, velocity, _, lead, deceleration = view.box
        lo, hi = limits.velocity_bounds(np.asarray(q, dtype=float)[index], view.zeros, lower,
                                        upper, velocity, lead, deceleration)
        qd[index] += limits.preference_scale(qd[index], motion, lo, hi) * motion
        return qd

    def step(self, kinematics: Kinematics, xd: np.ndarray, locked: Iterable[int] = (),
             commanded: Kinematics | None = None) -> CycleResult:
        """One cycle: joint velocities (rad/s) for task velocity xd at q with `locked` joints.

        `kinematics`: the cycle's snapshot at the configuration q (`Robot.kinematics`).
        `commanded`: a snapshot of the configuration the commands sent are taking the arm
        to (`reference.CommandedConfiguration`): the kfm gradient and the limit avoidance
        are taken there instead, and each joint keeps the room to stop before its limits
        from the furthest of the two (`velocity_bounds`); the task and every other term
        stay at q.

        Raises ValueError (before any arithmetic) for wrong lengths, non-finite q or
        xd, physically absurd ones (q more than `limits.ABSURD_POSITION` outside the joint
        limits or beyond `limits.ABSURD_MAGNITUDE`, a component of xd beyond
        `limits.ABSURD_SPEED`), or locked indices that
        are not joints.
        """
        cfg, robot = self.config, self.robot
        n, m = robot.n, robot.m
        q, xd = kinematics.q, np.asarray(xd, dtype=float)
        if q.shape != (n,):
            raise ValueError(f"q must have {n} entries, got shape {q.shape}")
        if xd.shape != (m,):
            raise ValueError(f"xd must have {m} entries, got shape {xd.shape}")
        problem = _input_problem(q, xd, robot.lower, robot.upper)
        if problem:
            raise ValueError(_INPUT_PROBLEMS[problem])
        view = self._locked_set(locked)
        index, nh = view.healthy, view.healthy.size
        if nh < m:
            return self._infeasible(q, xd, view)
        ahead = np.zeros(n) if commanded is None else commanded.q - q
        (qd, saturated, sigmas, at_soft, at_hard, kfm, sigma_min, jump, scale,
         margin) = _cycle(kinematics.base_jacobian,
                          (kinematics if commanded is None else commanded).base_jacobian,
                          commanded is not None, xd, q, ahead, index, robot.task_scale,
                          view.box,
                          self._gains, view.use_kfm, view.use_jump,
                          self._probabilities is not None, self._swing_descent(q, view),
                          self._limit_box, view.soft)
        if scale < 1.0:
            status = Status.LIMITED
        elif sigma_min < cfg.damping.threshold:
            status = Status.NEAR_SINGULARITY
        else:
            status = Status.OK
        return CycleResult(qd, status, kfm, sigma_min, sigmas, jump, scale, margin, saturated,
                           at_soft, at_hard)

    def _infeasible(self, q: np.ndarray, xd: np.ndarray, view: _LockedSet) -> CycleResult:
        """Fewer healthy joints than task coordinates: least squares, scaled into the bounds."""
        cfg, robot = self.config, self.robot
        index, nh, n = view.healthy, view.healthy.size, robot.n
        lower, upper, velocity, _, lead, deceleration = view.box
        Js, x = robot.scale_task(robot.jacobian(q))[:, index], robot.task_scale * xd
        lo, hi = limits.velocity_bounds(q[index], view.zeros, lower, upper, velocity, lead,
                                        deceleration)
        qd_h = damped_pinv(Js, cfg.damping) @ x if nh else np.zeros(0)
        scale, _, _ = limits.largest_scale(qd_h, np.zeros(nh), lo, hi, np.ones(nh, bool))
        qd, sigmas = np.zeros(n), np.full(n, np.nan)
        qd[index], sigmas[index] = scale * qd_h, 0.0
        margin, at_soft, at_hard = _limit_report(q, self._limit_box, view.soft)
        return CycleResult(qd, Status.INFEASIBLE, 0.0, 0.0, sigmas, 0.0, float(scale), margin,
                           np.zeros(n, dtype=bool), at_soft, at_hard)
