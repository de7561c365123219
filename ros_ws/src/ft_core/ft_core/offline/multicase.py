"""Design for several cases of failure probabilities: planar 3R (Xie 2019 sec. 3.4, eq 3.30).

The objective of eq 3.30 for an n-joint arm of total length 1,

    F = (1/n) sum_f  f_sigma_m(c_0) + sum_i  i_sigma_m(c_i),

adds the equal-probability case (configuration c_0) and, for each joint i, the case
where joint i is failing (configuration c_i), each at its own best configuration.
Following sec. 3.4.2 the link lengths are discretised (step 0.02, sum 1) and, for
every design, each component is maximised over the self-motion manifold of each
workspace point; F is the largest sum over workspace points (the constraint that
all f(c_i) are equal: one task point for all cases).

Readings taken:

- A planar arm's singular values do not depend on where the task point lies on a
  circle about the base, so the workspace is sampled by the distance r of the
  task point (a uniform grid on (0, 1]) rather than by 5000 points of the disk.
- The self-motion manifold of r is traced by the absolute angle phi of the last
  link (a uniform grid), with both elbow branches of the first two links.
- Links of length 0 are left out (every l_i >= step): such arms have fewer joints.
- "If failures in joints one and three are equally likely the optimal link
  lengths are l1 = l2 = 0.3": read as the design of the optimal family (largest F)
  on which the joint-1 and joint-3 components are equal (`balanced_design`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ft_core.offline import batch

COMPONENTS = ("equal", "joint 1", "joint 2", "joint 3")
_TIE = 1e-4  # component values this close to the maximum count as optimal


def link_grid(step: float = 0.02) -> np.ndarray:
    """All (l1, l2, l3) with l_i >= step on a grid of `step` and l1 + l2 + l3 = 1, (k, 3)."""
    count = round(1.0 / step)
    if count < 3 or not math.isclose(count * step, 1.0, abs_tol=1e-9):
        raise ValueError(f"step must divide 1 into at least 3 parts, got {step}")
    rows = [(i, j, count - i - j) for i in range(1, count) for j in range(1, count - i)]
    return np.array(rows, dtype=float) / count


def _sigma_min_2x2(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Smallest singular value of [[a, b], [c, d]] (element-wise arrays).

    |det| / sigma_max, with sigma_max^2 the larger root of s^4 - trace s^2 + det^2: no
    cancellation, so a small value keeps its relative precision (the smaller root taken
    directly would lose it, as a square root of an eigenvalue near 0 does).
    """
    trace = a * a + b * b + c * c + d * d
    det = a * d - b * c
    largest = np.sqrt(trace / 2 + np.sqrt(np.maximum(trace**2 / 4 - det**2, 0.0)))
    return np.divide(np.abs(det), largest, out=np.zeros_like(largest), where=largest > 0)


def manifold_configurations(lengths: Sequence[float], radius: float | np.ndarray,
                            samples: int = 360) -> tuple[np.ndarray, np.ndarray]:
    """Configurations (k, 3) (rad) of the planar 3R reaching (r, 0), and their radius index.

    Traces every self-motion manifold of each radius by the last link's absolute
    angle phi (`samples` values) and both elbow branches; points where the first two
    links cannot reach the wrist are dropped.
    """
    l1, l2, l3 = (float(v) for v in lengths)
    r = np.atleast_1d(np.asarray(radius, dtype=float))
    phi = np.linspace(-np.pi, np.pi, samples, endpoint=False)
    R, P = np.meshgrid(r, phi, indexing="ij")
    index = np.broadcast_to(np.arange(r.size)[:, None], R.shape)
    wx, wy = R - l3 * np.cos(P), -l3 * np.sin(P)
    cos2 = (wx**2 + wy**2 - l1**2 - l2**2) / (2 * l1 * l2)
    ok = np.abs(cos2) <= 1.0
    wx, wy, P, index, cos2 = wx[ok], wy[ok], P[ok], index[ok], cos2[ok]
    configurations, owners = [], []
    for sign in (1.0, -1.0):
        t2 = sign * np.arccos(cos2)
        t1 = np.arctan2(wy, wx) - np.arctan2(l2 * np.sin(t2), l1 + l2 * np.cos(t2))
        t3 = P - t1 - t2
        configurations.append(np.angle(np.exp(1j * np.stack([t1, t2, t3], axis=1))))
        owners.append(index)
    return np.concatenate(configurations), np.concatenate(owners)


def components(lengths: Sequence[float], q: np.ndarray) -> np.ndarray:
    """The four components of eq 3.30 at configurations q (k, 3): (k, 4).

    Column 0: (1/3) sum_f f_sigma_m; columns 1-3: i_sigma_m for a failure of joint i,
    with f_sigma_m the smallest singular value of the 2 x 2 Jacobian without column f.
    """
    l1, l2, l3 = (float(v) for v in lengths)
    q = np.atleast_2d(q)
    a1, a2, a3 = q[:, 0], q[:, 0] + q[:, 1], q[:, 0] + q[:, 1] + q[:, 2]
    # Joint positions and the tool point; column i = perp(tool - p_i).
    p2 = np.stack([l1 * np.cos(a1), l1 * np.sin(a1)], axis=1)
    p3 = p2 + np.stack([l2 * np.cos(a2), l2 * np.sin(a2)], axis=1)
    tool = p3 + np.stack([l3 * np.cos(a3), l3 * np.sin(a3)], axis=1)
    cols = [tool, tool - p2, tool - p3]
    jx = [-c[:, 1] for c in cols]
    jy = [c[:, 0] for c in cols]
    failed = [_sigma_min_2x2(jx[b], jx[c], jy[b], jy[c]) for b, c in ((1, 2), (0, 2), (0, 1))]
    return np.stack([sum(failed) / 3.0, *failed], axis=1)


@dataclass(frozen=True)
class DesignScore:
    """Eq 3.30 for one set of link lengths.

    Attributes:
        lengths: (l1, l2, l3).
        objective: F with one task point for all cases (max over r of the sum).
        unconstrained: F with each case at its own task point.
        radius: the task-point distance where F is reached.
        maxima: the four component maxima at that radius.
        configurations: (4, 3) configuration (rad) maximising each component there,
            task point on the +x axis; where a component's maximum is attained on a
            set (within 1e-4), the configuration nearest the equal case's is given.
    """

    lengths: tuple[float, float, float]
    objective: float
    unconstrained: float
    radius: float
    maxima: np.ndarray
    configurations: np.ndarray


def score(lengths: Sequence[float], radii: int = 100, samples: int = 360) -> DesignScore:
    """Evaluate eq 3.30 for one planar 3R (total length 1) on a radius x phi grid."""
    lengths = tuple(float(v) for v in lengths)
    if len(lengths) != 3 or min(lengths) <= 0:
        raise ValueError(f"need three positive link lengths, got {lengths}")
    total = sum(lengths)
    r = np.linspace(0.0, total, radii + 1)[1:]
    q, owner = manifold_configurations(lengths, r, samples)
    values = components(lengths, q)
    best = np.full((r.size, 4), -np.inf)
    for c in range(4):
        np.maximum.at(best[:, c], owner, values[:, c])
    reached = np.all(np.isfinite(best), axis=1)
    sums = np.where(reached, best.sum(axis=1), -np.inf)
    k = int(np.argmax(sums))
    at_k = owner == k
    q_k, v_k = q[at_k], values[at_k]
    first = q_k[np.argmax(v_k[:, 0])]
    configurations = [first]
    for c in range(1, 4):  # among near-ties, the configuration nearest the equal case's
        near = v_k[:, c] >= v_k[:, c].max() - _TIE
        gap = np.abs(np.angle(np.exp(1j * (q_k[near] - first)))).sum(axis=1)
        configurations.append(q_k[near][np.argmin(gap)])
    return DesignScore(lengths, float(sums[k]), float(best[reached].max(axis=0).sum()),
                       float(r[k]), best[k], np.array(configurations))


def _score_chunk(args: tuple[np.ndarray, int, int]) -> list[DesignScore]:
    chunk, radii, samples = args
    return [score(row, radii, samples) for row in chunk]


def score_grid(grid: np.ndarray, radii: int = 100, samples: int = 360,
               where: batch.Where = batch.HERE) -> list[DesignScore]:
    """Score every row of `grid` (k, 3), in chunks, where `where` says (`batch`).

    Args:
        grid: link lengths, e.g. `link_grid()`.
        radii: task-point distances per design (see `score`).
        samples: points per self-motion manifold (see `score`).
        where: worker processes or a cluster (default: this process).
    """
    chunks = np.array_split(np.asarray(grid, float), max(1, min(len(grid), 8 * where.workers)))
    jobs = [(c, radii, samples) for c in chunks if len(c)]
    return [s for part in batch.results(_score_chunk, jobs, where, what="chunk") for s in part]


def optimal_family(scores: Sequence[DesignScore], tolerance: float = 1e-3) -> list[DesignScore]:
    """Designs whose F is within `tolerance` (relative) of the best (Figure 3.4)."""
    best = max(s.objective for s in scores)
    return [s for s in scores if s.objective >= best * (1 - tolerance)]


def balanced_design(family: Sequence[DesignScore]) -> DesignScore:
    """The design of the family whose joint-1 and joint-3 components are closest (sec. 3.4.2)."""
    return min(family, key=lambda s: abs(s.maxima[1] - s.maxima[3]))
