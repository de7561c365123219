"""Probability of task failure along a joint trajectory (Xie 2019, ch. 4, sec. 4.2).

A point-to-point task visits task points 1..K in order. While the arm heads for
point k, the points k..K remain; a joint i that locks at q_i fails the task when a
remaining point's self-motion manifold has no configuration with that q_i, i.e.
q_i is outside the intersection of the remaining points' bounding boxes for joint i
(sec. 4.2.2: the regions are bounded by those intersections and re-divided after
each point is reached). Inside, the lock is survived unless a second joint locks
during the post-failure trajectory (scenarios C and D of Table 4.1: with one degree
of redundancy the reduced arm has none left).

Readings taken (the extracted eqs 4.3-4.8 lost their minus signs; docs/planning.md): a
joint with exponential failure rate lambda fails in [t0, t1] with probability
exp(-lambda t0) - exp(-lambda t1) (eqs 4.3-4.4), and eqs 4.7-4.8 are that probability
for the first joint over a segment times the same for the second over the
post-failure time Delta t2. With more than two joints, "the second joint" is any other
joint (a sum over them). Like the chapter, the probabilities of the
pieces are summed without survival factors for the other joints (first order in
lambda t: `monte_carlo` samples the exact competing failures, and the two agree to
O((sum lambda t)^2)). Times follow eq 4.2: every leg of a trajectory takes
max_i |Delta q_i| / v.

Units: rad, s, failure rates in 1/s, speeds in rad/s.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

#: Failure rates (1/s): one for all joints, or one per joint.
Rates = Sequence[float] | np.ndarray
#: Tolerance (rad) of the box edges: a lock exactly on an edge is survived (002 fn. 3).
EDGE = 1e-9
#: Segments the trajectory is divided into for the second-failure terms (sec. 4.2.3).
SEGMENTS = 400
#: 1/s; the largest failure rate taken: a joint failing once a second on average is no
#: joint, and far larger rates underflow every interval's probability to 0.
MAX_RATE = 1.0


@dataclass(frozen=True)
class TaskPoint:
    """One task point's traced self-motion manifold component and its bounding box.

    Attributes:
        paths: ordered samples (k, n) of the traced paths (rad), as
            `selfmotion.Manifold.paths`.
        lower: per-joint lower bound of the box (rad).
        upper: per-joint upper bound of the box (rad).
    """

    paths: tuple[np.ndarray, ...]
    lower: np.ndarray
    upper: np.ndarray

    @classmethod
    def from_paths(cls, paths: Sequence[np.ndarray]) -> TaskPoint:
        """The task point whose box is the samples' per-joint range."""
        arrays = tuple(np.atleast_2d(np.asarray(p, dtype=float)) for p in paths)
        samples = np.vstack(arrays)
        return cls(arrays, samples.min(axis=0), samples.max(axis=0))

    @classmethod
    def from_manifold(cls, manifold) -> TaskPoint:
        """From a `selfmotion.Manifold` (its paths and physical-limit-clipped box)."""
        lower, upper = manifold.box
        return cls(tuple(manifold.paths), lower, upper)

    @property
    def samples(self) -> np.ndarray:
        """All traced configurations, (k, n)."""
        return np.vstack(self.paths)

    def crossings(self, joint: int, value: float) -> np.ndarray:
        """Configurations on the manifold with q[joint] = value, (c, n), interpolated.

        With `joint` locked at `value` the reduced arm reaches the point at any of
        them (Lewis & Maciejewski 1997 sec. III); none when `value` is outside the manifold's range.
        """
        found = []
        for path in self.paths:
            offset = path[:, joint] - value
            if path.shape[0] == 1:
                if abs(offset[0]) <= EDGE:
                    found.append(path[0])
                continue
            for k in np.flatnonzero(offset[:-1] * offset[1:] <= 0):
                span = offset[k] - offset[k + 1]
                t = 0.0 if span == 0 else offset[k] / span
                found.append(path[k] + t * (path[k + 1] - path[k]))
        n = self.lower.size
        return np.array(found).reshape(-1, n)


def remaining_box(points: Sequence[TaskPoint], first: int) -> tuple[np.ndarray, np.ndarray]:
    """Intersection of the boxes of points first..K (sec. 4.2.2); empty where lower > upper."""
    lower = np.max([p.lower for p in points[first:]], axis=0)
    upper = np.min([p.upper for p in points[first:]], axis=0)
    return lower, upper


def fatal_joints(points: Sequence[TaskPoint], first: int, q: np.ndarray) -> np.ndarray:
    """Joints whose lock at q loses a remaining point: scenarios A and B (Table 4.1).

    Boolean (n,): q_i outside the intersection of the boxes of points first..K.
    The other joints are the double-failure scenarios C and D.
    """
    lower, upper = remaining_box(points, first)
    q = np.asarray(q, dtype=float)
    return (q < lower - EDGE) | (q > upper + EDGE)


def region(points: Sequence[TaskPoint], first: int, q: np.ndarray) -> tuple[int, ...]:
    """The region of q (sec. 4.2.2): per joint 0 below, 1 inside, 2 above the intersection.

    For two joints, 3 * code[1] + code[0] + 1 numbers the nine regions of fig. 4.1
    row by row (theta_1 across, theta_2 up: region 5 is the intersection).
    """
    lower, upper = remaining_box(points, first)
    q = np.asarray(q, dtype=float)
    return tuple(int(c) for c in np.where(q < lower - EDGE, 0, np.where(q > upper + EDGE, 2, 1)))


@dataclass(frozen=True)
class Trajectory:
    """A piecewise-linear joint trajectory through task points.

    Attributes:
        times: waypoint times (s), non-decreasing, from 0.
        configurations: waypoints (w, n), rad.
        arrivals: for each task point, the waypoint index where it is reached
            (non-decreasing); the task ends at the last one.
    """

    times: np.ndarray
    configurations: np.ndarray
    arrivals: tuple[int, ...]

    def __post_init__(self) -> None:
        times = np.asarray(self.times, dtype=float)
        q = np.atleast_2d(np.asarray(self.configurations, dtype=float))
        if times.shape != (q.shape[0],) or np.any(np.diff(times) < 0) or times[0] != 0.0:
            raise ValueError("times must be non-decreasing from 0, one per waypoint")
        arrivals = tuple(int(a) for a in self.arrivals)
        if not arrivals or list(arrivals) != sorted(arrivals) or arrivals[-1] >= q.shape[0] \
                or arrivals[0] < 0:
            raise ValueError("arrivals must be non-decreasing waypoint indices")
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "configurations", q)
        object.__setattr__(self, "arrivals", arrivals)

    @classmethod
    def at_speed(cls, configurations: np.ndarray, arrivals: Sequence[int],
                 speed: float) -> Trajectory:
        """Straight legs timed by eq 4.2: each takes max_i |Delta q_i| / speed."""
        q = np.atleast_2d(np.asarray(configurations, dtype=float))
        legs = np.abs(np.diff(q, axis=0)).max(axis=1, initial=0.0) / speed
        return cls(np.concatenate([[0.0], np.cumsum(legs)]), q, tuple(arrivals))

    @property
    def duration(self) -> float:
        """Time (s) when the last task point is reached."""
        return float(self.times[self.arrivals[-1]])

    def at(self, t: float | np.ndarray) -> np.ndarray:
        """Configuration(s) at time(s) t (rad), linear between waypoints."""
        t = np.asarray(t, dtype=float)
        return np.stack([np.interp(t, self.times, self.configurations[:, j])
                         for j in range(self.configurations.shape[1])], axis=-1)

    def remaining(self, t: float) -> int:
        """Index of the first task point not yet reached at time t."""
        return int(np.searchsorted(self.times[list(self.arrivals)], t, side="right"))


def post_failure_time(points: Sequence[TaskPoint], first: int, q: np.ndarray, joint: int,
                      speed: float) -> float:
    """Time (s) the reduced arm needs to reach points first..K with `joint` locked at q.

    Each leg is a straight line timed by eq 4.2, through the configurations where the
    locked joint keeps its value (`TaskPoint.crossings`), chosen by dynamic
    programming for the shortest total time. inf when a point cannot be reached.
    """
    value = float(q[joint])
    here = np.atleast_2d(np.asarray(q, dtype=float))
    cost = np.zeros(1)
    for point in points[first:]:
        options = point.crossings(joint, value)
        if options.shape[0] == 0:
            return float("inf")
        legs = np.abs(here[:, None, :] - options[None, :, :]).max(axis=2) / speed
        cost = (cost[:, None] + legs).min(axis=0)
        here = options
    return float(cost.min())


def _interval_probability(rates: np.ndarray, t0: float | np.ndarray,
                          t1: float | np.ndarray) -> np.ndarray:
    """Probability that each joint fails in [t0, t1]: exp(-l t0) - exp(-l t1) (eqs 4.3-4.4)."""
    return np.exp(-rates * t0) - np.exp(-rates * t1)


def _pieces(points: Sequence[TaskPoint], trajectory: Trajectory, segments: int,
            ) -> list[tuple[float, float, int]]:
    """The trajectory's time pieces (t0, t1, first remaining point).

    Split where a joint crosses a region boundary (so the fatal set is constant on
    each piece) and at most duration / segments long.
    """
    times, q = trajectory.times, trajectory.configurations
    end = trajectory.duration
    longest = end / segments if end > 0 else 1.0
    pieces = []
    for w in range(trajectory.arrivals[-1]):
        t0, t1 = times[w], times[w + 1]
        if t1 <= t0:
            continue
        first = trajectory.remaining(t0)
        lower, upper = remaining_box(points, first)
        cuts = [t0, t1]
        delta = q[w + 1] - q[w]
        for bound in (lower, upper):
            moving = np.abs(delta) > 0
            s = np.full(delta.shape, -1.0)
            s[moving] = (bound[moving] - q[w][moving]) / delta[moving]
            cuts += [t0 + v * (t1 - t0) for v in s if 0.0 < v < 1.0]
        for a, b in itertools.pairwise(np.unique(cuts)):
            count = max(1, int(np.ceil((b - a) / longest - 1e-9)))
            edges = np.linspace(a, b, count + 1)
            pieces += [(float(c), float(d), first) for c, d in itertools.pairwise(edges)]
    return pieces


def _first_failure_probability(rates: np.ndarray, t0: float, t1: float) -> np.ndarray:
    """Probability that each joint is the first to fail and does so in [t0, t1].

    Competing exponential failures: lambda_i / Lambda (exp(-Lambda t0) - exp(-Lambda t1)),
    Lambda the sum of the rates.
    """
    total = float(rates.sum())
    if total == 0:
        return np.zeros_like(rates)
    return rates / total * (math.exp(-total * t0) - math.exp(-total * t1))


def task_failure_probability(points: Sequence[TaskPoint], trajectory: Trajectory,
                             rates: Rates, speed: float,
                             second_failures: bool = True, segments: int = SEGMENTS,
                             exact: bool = False) -> float:
    """Probability that a lock makes the task fail along the trajectory (sec. 4.2.3).

    Sums, over the trajectory's pieces and joints, eqs 4.3-4.4 for joints whose lock
    loses a remaining point (scenarios A, B) and, with `second_failures`, eqs 4.7-4.8
    for the others: the joint fails in the piece and another joint fails during the
    post-failure trajectory (`post_failure_time`, from the piece's midpoint as fig.
    4.4 takes it constant over a small segment). The chapter's planner (sec. 4.3)
    ignores second failures. Second failures assume one degree of redundancy.

    Args:
        points: the task points in visiting order.
        trajectory: the joint trajectory; the task ends at its last arrival.
        rates: exponential failure rate of each joint (1/s), >= 0.
        speed: joint speed v of the post-failure trajectories (rad/s), > 0.
        second_failures: add scenarios C and D.
        segments: the trajectory is cut into at least this many pieces for C and D.
        exact: integrate the pieces exactly instead of the chapter's first-order sum.

    The chapter's sum is first order: at high rates it can exceed 1, and is clamped
    there (a probability). With `exact`, the same pieces are integrated exactly for
    exponential failures instead (the model `monte_carlo` samples): a joint fails first
    in a piece with `_first_failure_probability`, and after it, one of the others fails
    within the post-failure time with 1 - exp(-(Lambda - lambda_i) T), memoryless. Only
    the pieces' discretisation (fatal joints and post-failure times taken at each
    piece's midpoint) remains, so it never exceeds 1 and needs no clamp.
    """
    lam = check_rates(rates, trajectory.configurations.shape[1])
    if not speed > 0:
        raise ValueError(f"speed must be positive, got {speed}")
    total = 0.0
    for t0, t1, first in _pieces(points, trajectory, segments):
        q = trajectory.at(0.5 * (t0 + t1))
        fatal = fatal_joints(points, first, q)
        here = (_first_failure_probability(lam, t0, t1) if exact
                else _interval_probability(lam, t0, t1))
        total += float(here[fatal].sum())
        if not second_failures:
            continue
        for i in np.flatnonzero(~fatal & (lam > 0)):
            after = post_failure_time(points, first, q, int(i), speed)
            others = np.delete(lam, i)
            total += float(here[i] * (-math.expm1(-others.sum() * after) if exact else
                                      _interval_probability(others, t1, t1 + after).sum()))
    return min(total, 1.0)


def monte_carlo(points: Sequence[TaskPoint], trajectory: Trajectory, rates: Rates,
                speed: float, samples: int, rng: np.random.Generator,
                second_failures: bool = True) -> tuple[int, int]:
    """Simulate exponential joint failures along the trajectory: (task failures, samples).

    Each sample draws every joint's failure time; the first one before the task ends
    locks its joint where the trajectory has it. The task fails if that loses a
    remaining point, or (with `second_failures`) if another joint's failure time falls
    within the post-failure trajectory. Exact for this model, unlike the chapter's
    first-order sum: the check of `task_failure_probability`.
    """
    lam = check_rates(rates, trajectory.configurations.shape[1])
    with np.errstate(divide="ignore"):
        scale = np.where(lam > 0, 1.0 / lam, np.inf)
    times = rng.exponential(1.0, size=(samples, lam.size)) * scale
    first_joint = np.argmin(times, axis=1)
    first_time = times[np.arange(samples), first_joint]
    failures = 0
    for s in np.flatnonzero(first_time < trajectory.duration):
        t, i = float(first_time[s]), int(first_joint[s])
        q = trajectory.at(t)
        remaining = trajectory.remaining(t)
        if fatal_joints(points, remaining, q)[i]:
            failures += 1
        elif second_failures:
            after = post_failure_time(points, remaining, q, i, speed)
            failures += int(np.delete(times[s], i).min() < t + after)
    return failures, samples


def check_rates(rates: Rates, n: int) -> np.ndarray:
    """Failure rates (1/s) as an (n,) array: one value for all joints, or n (ValueError).

    Each in [0, `MAX_RATE`]: at 1e308/s every interval's probability underflowed to 0,
    and the task's failure probability came out 0 where it is 1.
    """
    lam = np.asarray(rates, dtype=float).reshape(-1)
    if lam.size == 1:
        lam = np.full(n, lam[0])
    if lam.shape != (n,) or not np.all((lam >= 0) & (lam <= MAX_RATE)):
        raise ValueError(f"rates must be one or {n} values in [0, {MAX_RATE:g}] (1/s)")
    return lam
