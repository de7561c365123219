"""Stationary angles of a free-swinging joint, and the workspace they leave (any arm).

Maciejewski et al. sec. 3.3: with the healthy joints held, a joint without torque
rests at its hanging angle (`ft_core.swing`, eq 13) or on a position limit gravity
presses it against (`stationary_angles`). `sample_workspace` samples the healthy joints
uniformly within their limits and records the tool positions at every stationary angle
of each failed joint; `volume_shares` compares the volumes reached, counted in cubes.
The readings taken where the paper is silent are in `ft_core.offline.swing_workspace`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ft_core import swing
from ft_core.robots import Robot

#: Largest number of samples or grid vertices a call evaluates (each costs one Pinocchio
#: pass for the swing angle and one per stationary configuration).
MAX_EVALUATIONS = 2_000_000


def _wrap(angle: np.ndarray | float) -> np.ndarray:
    """Angle(s) in [-pi, pi) (rad)."""
    return (np.asarray(angle) + math.pi) % (2 * math.pi) - math.pi


def _range(robot: Robot, joint: int) -> tuple[float, float]:
    """The joint's sampling range (rad): its limits, [-pi, pi] for a continuous joint."""
    lo, hi = float(robot.lower[joint]), float(robot.upper[joint])
    return (lo, hi) if math.isfinite(lo) and math.isfinite(hi) else (-math.pi, math.pi)


def _stationary(robot: Robot, joint: int, rest: float, turned: bool = True
                ) -> tuple[list[float], list[bool]]:
    """Stationary angles (rad) of `joint` whose hanging angle is `rest`, and which are stops.

    Each turn of the hanging angle inside the limits, then each limit that gravity
    presses the joint against: gravity turns it towards the hanging angle the short way
    round, never past the upright one. A joint gravity does not turn (`turned` False)
    stays at `rest`, its own angle.
    """
    lo, hi = float(robot.lower[joint]), float(robot.upper[joint])
    if not turned or not (math.isfinite(lo) and math.isfinite(hi)):
        return [rest], [False]
    first = math.ceil((lo - rest) / (2 * math.pi))
    last = math.floor((hi - rest) / (2 * math.pi))
    angles = [rest + 2 * math.pi * k for k in range(first, last + 1)]
    stops = [limit for limit, pressed in ((lo, _wrap(rest - lo) < 0), (hi, _wrap(rest - hi) > 0))
             if pressed]
    return angles + stops, [False] * len(angles) + [True] * len(stops)


def stationary_angles(robot: Robot, q: np.ndarray, joint: int,
                      gravity: Sequence[float] = swing.STANDARD_GRAVITY) -> np.ndarray:
    """Angles (rad, (k,)) at which the free `joint` is stationary, the others held at q.

    The hanging angle inside the limits (each turn of it, for a joint whose range
    exceeds one), then each limit that gravity presses the joint against. A neutral
    joint (`swing.swing_state`) gives its own angle in q.
    """
    q = np.asarray(q, dtype=float)
    theta, turned = swing.swing_state(robot, q, gravity)
    return np.array(_stationary(robot, joint, float(q[joint] + theta[joint]),
                                bool(turned[joint]))[0])


@dataclass(frozen=True)
class SampledWorkspace:
    """Tool positions sampled after a free-swinging failure of one joint (or healthy).

    Attributes:
        joint: the failed joint (0-based), None for the healthy arm.
        positions: (k, 3) tool positions (m, base frame) of stationary configurations.
        on_stop: (k,) whether the failed joint rests on a position limit there.
        neutral: share of the samples at which gravity has no torque about the joint.
    """

    joint: int | None
    positions: np.ndarray
    on_stop: np.ndarray
    neutral: float

    def voxels(self, size: float) -> set[tuple[int, ...]]:
        """The cubes of edge `size` (m), on a grid through the base, that hold a position."""
        return set(map(tuple, np.floor(self.positions / size).astype(int).tolist()))


def _samples(robot: Robot, count: int, seed: int) -> np.ndarray:
    if not 1 <= count <= MAX_EVALUATIONS:
        raise ValueError(f"samples must be in [1, {MAX_EVALUATIONS}], got {count}")
    bounds = np.array([_range(robot, j) for j in range(robot.n)])
    rng = np.random.default_rng(seed)
    return bounds[:, 0] + rng.random((count, robot.n)) * (bounds[:, 1] - bounds[:, 0])


def sample_workspace(robot: Robot, joints: Sequence[int], samples: int, seed: int = 0,
                     gravity: Sequence[float] = swing.STANDARD_GRAVITY
                     ) -> tuple[SampledWorkspace, dict[int, SampledWorkspace]]:
    """The healthy workspace and the post-failure one of each of `joints` (0-based).

    `samples` configurations drawn uniformly within the limits (continuous joints over
    one turn), the same for every joint: the healthy arm's tool positions, and, for each
    failed joint, the tool at every stationary angle of that joint with the others at
    the sample (`stationary_angles`). Needs a model with inertias.
    """
    if not robot.has_inertias:
        raise ValueError(f"{robot.name} has no inertias in its URDF: gravity's torques are "
                         "unknown")
    draws = _samples(robot, samples, seed)
    healthy = np.array([robot.target_position(robot.forward(q)) for q in draws])
    positions: dict[int, list[np.ndarray]] = {j: [] for j in joints}
    stops: dict[int, list[bool]] = {j: [] for j in joints}
    neutral = dict.fromkeys(joints, 0)
    for q in draws:
        theta, turned = swing.swing_state(robot, q, gravity)
        for j in joints:
            neutral[j] += int(not turned[j])
            angles, on_stop = _stationary(robot, j, float(q[j] + theta[j]), bool(turned[j]))
            stops[j] += on_stop
            for angle in angles:
                settled = q.copy()
                settled[j] = angle
                positions[j].append(robot.target_position(robot.forward(settled)))
    return SampledWorkspace(None, healthy, np.zeros(len(healthy), bool), 0.0), {
        j: SampledWorkspace(j, np.array(positions[j]).reshape(-1, 3), np.array(stops[j], bool),
                            neutral[j] / samples) for j in joints}


def volume_shares(healthy: SampledWorkspace, failed: dict[int, SampledWorkspace], size: float,
                  seed: int = 0) -> tuple[float, dict[int, float]]:
    """Share of the workspace's volume the healthy sample, and each failed joint, reaches.

    Counted in cubes of edge `size` (m). Every sampled position is one the healthy arm
    reaches, so the workspace is the union of all the samples' cubes. Each failed joint
    is given as many positions as the healthy sample has (drawn with `seed` where it has
    more: a joint resting on a stop or on several turns gives a sample more than one),
    so no share gains from a denser sample; the healthy sample's own share (below 1 while
    the samples are sparse against the cubes) is the yardstick of the others.
    """
    workspace = healthy.voxels(size).union(*(w.voxels(size) for w in failed.values()))
    rng = np.random.default_rng(seed)
    count = len(healthy.positions)
    shares = {}
    for j, w in failed.items():
        pick = (rng.choice(len(w.positions), count, replace=False)
                if len(w.positions) > count else slice(None))
        shares[j] = len(SampledWorkspace(j, w.positions[pick], w.on_stop[pick], w.neutral)
                        .voxels(size)) / len(workspace)
    return len(healthy.voxels(size)) / len(workspace), shares
