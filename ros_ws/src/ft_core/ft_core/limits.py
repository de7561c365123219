"""Joint limits at velocity level: bounds, soft-limit avoidance, saturation in the null space.

- `velocity_bounds`: the joint velocities from which each joint, braking within its
  deceleration limit after a lead time, stops inside [lower, upper], within the velocity
  limits. A joint already outside (or on) a limit may stay or move back, never further
  out, so 0 is always allowed.
- `avoidance`: a null-space preference pushing joints away from the edges of a box
  (the bounding-box soft limits of Lewis & Maciejewski 1997 sec. III, smooth functions): exactly 0
  more than `buffer` away from an edge, growing quadratically (C1) inside it.
- `edge_yield`: how much of another null-space preference (kfm ascent, minimum jump) to
  keep near the edges, so that none holds a joint on an edge against the avoidance.
- `saturate_in_null_space`: Saturation in the Null Space (Flacco, De Luca and
  Khatib, ICRA 2012, Algorithm 1): joints that would break their bounds are held
  at the bound, the task is re-solved with the remaining joints, and only when
  they cannot achieve it is the task velocity scaled down, keeping its direction.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ft_core.pseudoinverse import damped_from_svd

#: Slack (rad/s) in bound checks against round-off.
TOLERANCE = 1e-10
#: Measured positions beyond these are physically absurd and refused where they come in:
#: further outside the joint's limits (rad), or larger in magnitude (rad: 160 000 turns
#: of a continuous joint; beyond, differences of positions lose the precision detection
#: needs, and squares overflow).
ABSURD_POSITION = 1.0
ABSURD_MAGNITUDE = 1e6
#: A speed beyond this is physically absurd and refused, not clipped (rad/s, m/s): a task
#: velocity component, a joint velocity command (10 000 rpm; no arm's joint does).
ABSURD_SPEED = 1e3
#: m; a task point further than this from the base is no arm's (and 1e308 overflows).
ABSURD_DISTANCE = 1e3


@njit(cache=True, error_model="numpy")
def absurd_joint(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> int:
    """The first joint whose finite position q is absurd (see `ABSURD_POSITION`), else -1."""
    for j in range(q.size):
        if (q[j] < lower[j] - ABSURD_POSITION or q[j] > upper[j] + ABSURD_POSITION
                or abs(q[j]) > ABSURD_MAGNITUDE):
            return j
    return -1


def absurd_command(qd: np.ndarray, names: Sequence[str]) -> str | None:
    """Why a joint velocity command (finite, rad/s) is physically absurd, or None.

    A command beyond `ABSURD_SPEED` is a fault of its sender, not a speed to scale into
    the velocity limit, so it is refused like a non-finite one; a command merely above a
    joint's velocity limit is scaled into it.
    """
    speeds = [abs(v) for v in qd.tolist()]  # every cycle: Python floats, no numpy call
    if max(speeds, default=0.0) <= ABSURD_SPEED:
        return None
    j = next(j for j, speed in enumerate(speeds) if speed > ABSURD_SPEED)
    return f"{names[j]} commanded {qd[j]:.4g} rad/s (beyond {ABSURD_SPEED:g})"


def absurd_position(q: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                    names: Sequence[str]) -> str | None:
    """Why the measured configuration q (finite, rad) is physically absurd, or None."""
    j = absurd_joint(q, lower, upper)
    if j < 0:
        return None
    return (f"{names[j]} at {q[j]:.4g} rad is more than {ABSURD_POSITION:g} rad outside its "
            f"limits [{lower[j]:.4g}, {upper[j]:.4g}] or beyond {ABSURD_MAGNITUDE:g} rad")


@njit(cache=True, error_model="numpy")
def _stoppable(distance: float, lead: float, deceleration: float) -> float:
    """The speed (rad/s) from which a joint stops within `distance` (rad, > 0).

    Moving on at that speed for `lead` s, then braking at `deceleration` (rad/s^2):
    v lead + v^2 / (2 deceleration) = distance, so v = 2 distance / (lead + sqrt(lead^2 +
    2 distance / deceleration)); distance / lead with no deceleration limit (inf); inf
    for an infinite distance.
    """
    if distance == np.inf:
        return np.inf
    return 2.0 * distance / (lead + np.sqrt(lead * lead + 2.0 * distance / deceleration))


@njit(cache=True, error_model="numpy")
def velocity_bounds(q: np.ndarray, ahead: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                    velocity_limits: np.ndarray, lead: np.ndarray,
                    deceleration: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-joint (lo, hi) velocity bounds (rad/s) from which a joint stops inside its limits.

    Towards each limit, the speed of `_stoppable` over the distance left (rad) from the
    furthest of q and q + `ahead` (the motion already commanded that the measurement does
    not show yet, `reference.CommandedConfiguration`), within the velocity limits: the
    position-limit side of the velocity bounds of Flacco, De Luca and Khatib (ICRA 2012,
    sec. III), with a latency. `lead` (s, > 0): the cycle plus the time the commands take
    to start braking; `deceleration` (rad/s^2, inf for none: one cycle to the limit at
    lead = the cycle). lo <= 0 <= hi: a joint on or beyond a limit may stay or move back,
    never further out. q must be finite (infinite position limits give the velocity limit).
    """
    n = q.size
    lo, hi = np.zeros(n), np.zeros(n)
    for j in range(n):
        room_up = upper[j] - max(q[j], q[j] + ahead[j])
        room_down = min(q[j], q[j] + ahead[j]) - lower[j]
        if room_up > 0:
            hi[j] = min(velocity_limits[j], _stoppable(room_up, lead[j], deceleration[j]))
        if room_down > 0:
            lo[j] = -min(velocity_limits[j], _stoppable(room_down, lead[j], deceleration[j]))
    return lo, hi


@njit(cache=True, error_model="numpy")
def _zone(lower: float, upper: float, buffer: float) -> float:
    """Width (rad) of the zone inside each edge of [lower, upper]: buffer, half the box at most."""
    width = upper - lower
    return min(buffer, width / 2) if np.isfinite(width) else buffer


@njit(cache=True, error_model="numpy")
def avoidance(q: np.ndarray, lower: np.ndarray, upper: np.ndarray, buffer: float) -> np.ndarray:
    """Smooth push (dimensionless, <= 1 at an edge) away from the edges of [lower, upper].

    ((lower + b - q) / b)^2 inside the lower zone, -((q - upper + b) / b)^2 inside
    the upper zone, 0 elsewhere, with b = min(buffer, half the box width). It keeps
    growing outside the box, so a joint that starts outside is pushed back in.
    Infinite limits have no zone.
    """
    push = np.zeros(q.size)
    for j in range(q.size):
        if lower[j] + buffer < q[j] < upper[j] - buffer:
            continue
        b = _zone(lower[j], upper[j], buffer)
        if b <= 0:
            continue
        if np.isfinite(lower[j]) and q[j] < lower[j] + b:
            push[j] += ((lower[j] + b - q[j]) / b) ** 2
        if np.isfinite(upper[j]) and q[j] > upper[j] - b:
            push[j] -= ((q[j] - upper[j] + b) / b) ** 2
    return push


@njit(cache=True, error_model="numpy")
def edge_yield(motion: np.ndarray, q: np.ndarray, lower: np.ndarray, upper: np.ndarray,
               buffer: float) -> float:
    """How much of a null-space preference to keep near the edges of [lower, upper], in [0, 1].

    `motion` is the preference's joint motion (rad/s). Of the joints it moves towards an
    edge within `buffer` of it (b as in `avoidance`), the nearest sets the factor
    (d / b)^2, d its distance to that edge; 1 when it moves none. The preference times
    this, plus `avoidance`, never holds a joint on an edge: at the edge only the avoidance
    is left, pushing it back.
    """
    keep = 1.0
    for j in range(q.size):
        b = _zone(lower[j], upper[j], buffer)
        if b <= 0:
            continue
        d = np.inf
        if motion[j] < 0 and q[j] < lower[j] + b:
            d = q[j] - lower[j]
        elif motion[j] > 0 and q[j] > upper[j] - b:
            d = upper[j] - q[j]
        if d < np.inf:
            keep = min(keep, min(max(d / b, 0.0), 1.0) ** 2)
    return keep


@njit(cache=True, error_model="numpy")
def within(qd: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> bool:
    """Whether lo <= qd <= hi for every joint, up to `TOLERANCE`."""
    for j in range(qd.size):
        if not (lo[j] - TOLERANCE <= qd[j] <= hi[j] + TOLERANCE):
            return False
    return True


@njit(cache=True, error_model="numpy")
def largest_scale(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                  free: np.ndarray) -> tuple[float, int, bool]:
    """Largest s in [0, 1] with lo <= s a + b <= hi on the free joints.

    Returns (s, critical joint: the first to hit a bound as s grows, feasible).
    When no s works, feasible is False and the critical joint is the worst violator.
    """
    critical, s_max, s_min = 0, np.inf, 0.0
    for j in range(a.size):
        if not free[j]:
            up = np.inf
        elif a[j] > 0:
            up = (hi[j] - b[j]) / a[j]
            s_min = max(s_min, (lo[j] - b[j]) / a[j])
        elif a[j] < 0:
            up = (lo[j] - b[j]) / a[j]
            s_min = max(s_min, (hi[j] - b[j]) / a[j])
        else:  # never moves with s: fine, or stuck outside its bounds
            up = -np.inf if (b[j] > hi[j] + TOLERANCE or b[j] < lo[j] - TOLERANCE) else np.inf
        if up < s_max or j == 0:
            critical, s_max = j, up
    s_max = min(1.0, s_max)
    feasible = s_max >= 0 and s_min <= s_max + TOLERANCE
    return (max(s_max, 0.0) if feasible else 0.0), critical, feasible


@njit(cache=True, error_model="numpy")
def preference_scale(task: np.ndarray, null_motion: np.ndarray, lo: np.ndarray,
                     hi: np.ndarray) -> float:
    """Largest alpha in [0, 1] keeping task + alpha null_motion in [lo, hi]; 0 if none does.

    The task has priority over the null-space preference: SNS's first step.
    """
    alpha, _, feasible = largest_scale(null_motion, task, lo, hi, np.ones(task.size, np.bool_))
    return alpha if feasible else 0.0


@njit(cache=True, error_model="numpy")
def _solve(J: np.ndarray, xd: np.ndarray, z: np.ndarray, free: np.ndarray, q_sat: np.ndarray,
           threshold: float, max_damping: float, U: np.ndarray, S: np.ndarray,
           Vt: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Split qd = a + b: a = (J W)# xd (scaled with the task), b = the rest.

    Also returns sigma_min(J W), how well the free joints can still do the task.
    (U, S, Vt) is the SVD of J, used while every joint is free.
    """
    m, n = J.shape
    Jw, zw = J.copy(), z.copy()
    if not free.all():
        for j in range(n):
            if not free[j]:
                Jw[:, j] = 0.0
                zw[j] = 0.0
        U, S, Vt = np.linalg.svd(Jw, full_matrices=False)
    pinv = damped_from_svd(U, S, Vt, threshold, max_damping)
    a = pinv @ xd
    b = q_sat + zw - pinv @ (J @ q_sat + Jw @ zw)
    return a, b, S[-1] if m <= n else 0.0


@njit(cache=True, error_model="numpy")
def saturate_in_null_space(J: np.ndarray, xd: np.ndarray, z: np.ndarray, lo: np.ndarray,
                           hi: np.ndarray, threshold: float, max_damping: float,
                           pinv: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """(qd, task scale, saturated joints): J# xd + (I - J# J) z within [lo, hi] (SNS).

    Flacco et al.'s Algorithm 1 with the damped inverse (`pseudoinverse`; `pinv` is
    J's). The task has priority over the preference z: z is first shrunk by the
    largest factor in [0, 1] that keeps J# xd + (I - J# J) z inside the bounds (to 0
    when J# xd alone breaks them); then SNS saturates joints and, last, scales the
    task (scale in [0, 1], 1 = fully achieved). `lo <= 0 <= hi` must hold (as
    `velocity_bounds` guarantees). If the task at scale 0 cannot be met with the
    remaining preference, the preference is dropped. At most n saturation passes per
    preference; numbers that defeat them give zero velocity with task scale 0. Compiled.
    """
    m, n = J.shape
    a = pinv @ xd
    null_motion = z - pinv @ (J @ z)
    qd = a + null_motion
    if within(qd, lo, hi):
        return qd, 1.0, np.zeros(n, dtype=np.bool_)
    U, S, Vt = np.linalg.svd(J, full_matrices=False)
    # The task has priority: shrink the preference until it fits beside the task.
    shrunk = z * preference_scale(a, null_motion, lo, hi)
    # Flacco's "rank(J W) < m", numerically: the free joints have lost a task direction.
    rank_lost = min(threshold, S[-1] / 2 if m <= n else 0.0)
    for attempt in range(2):
        preference = shrunk if attempt == 0 else np.zeros(n)
        free, q_sat = np.ones(n, dtype=np.bool_), np.zeros(n)
        best_scale, best_free, best_q_sat = -1.0, free.copy(), q_sat.copy()
        for _ in range(n):  # each pass saturates one more joint: at most n passes
            a, b, sigma_free = _solve(J, xd, preference, free, q_sat, threshold, max_damping,
                                      U, S, Vt)
            if not free.all() and (sigma_free < rank_lost or free.sum() < m):
                break
            qd = a + b
            if np.all((qd <= hi + TOLERANCE) & (qd >= lo - TOLERANCE) | ~free):
                return qd, 1.0, ~free
            scale, critical, feasible = largest_scale(a, b, lo, hi, free)
            if feasible and scale > best_scale:
                best_scale, best_free, best_q_sat = scale, free.copy(), q_sat.copy()
            if not free[critical]:
                break  # no joint left to saturate (non-finite or degenerate numbers)
            free[critical] = False
            q_sat[critical] = min(max(qd[critical], lo[critical]), hi[critical])
        if best_scale >= 0.0:
            a, b, _ = _solve(J, xd, preference, best_free, best_q_sat, threshold, max_damping,
                             U, S, Vt)
            qd = np.minimum(np.maximum(best_scale * a + b, lo), hi)
            at_bound = ((qd >= hi - TOLERANCE) & (hi > 0)) | ((qd <= lo + TOLERANCE) & (lo < 0))
            return qd, best_scale, ~best_free | at_bound
    # In exact arithmetic the task at scale 0 without preference is feasible; with
    # overflowing inputs it may not be found: stop (explicit zeros), never raise.
    return np.zeros(n), 0.0, np.zeros(n, dtype=np.bool_)
