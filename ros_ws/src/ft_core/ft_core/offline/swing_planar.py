"""Stationary configurations of a planar 3-joint arm after a free-swinging failure.

Maciejewski et al. figs. 5-6: with one joint free, the configurations at which the arm
is stationary and reaches a point are isolated. `planar_mesh` maps a grid over the two
healthy joints, the failed one at its hanging angle, to a mesh of triangles in the
plane; a point is reached once for every triangle that covers it. `solution_counts`
counts them over the plane (fig. 5's regions), `zero_torque_solutions` finds and
refines them, by least squares, at one point (fig. 6).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ft_core import swing
from ft_core.offline.swing_stationary import MAX_EVALUATIONS, _range, _stationary, _wrap
from ft_core.robots import Robot

#: m: a refined configuration counts as reaching the point within this distance.
REACH_TOLERANCE = 1e-9
#: rad: two configurations closer than this in every joint (modulo 2 pi) are one.
SAME_CONFIGURATION = 1e-6


def _planar(robot: Robot) -> None:
    if robot.task_space != "planar" or robot.n != 3:
        raise ValueError("solution counts need a planar arm of three joints (its stationary "
                         f"configurations are then isolated); {robot.name} has {robot.n} "
                         f"joints and a {robot.task_space} task")


def _settle(robot: Robot, joint: int, q: np.ndarray, gravity: Sequence[float]
            ) -> np.ndarray | None:
    """Q with `joint` at its hanging angle inside its limits (the first turn), else None."""
    rest = float(q[joint] + swing.swing_angles(robot, q, gravity)[joint])
    angles, on_stop = _stationary(robot, joint, rest)
    hanging = [a for a, stop in zip(angles, on_stop, strict=True) if not stop]
    if not hanging:
        return None
    settled = np.array(q, dtype=float)
    settled[joint] = hanging[0]
    return settled


@dataclass(frozen=True)
class PlanarMesh:
    """The hanging configurations over a grid of the two healthy joints, and their tools.

    Attributes:
        configurations: (g, g, 3) joint angles (rad); NaN where the failed joint's hanging
            angle is outside its limits.
        tools: (g, g, 2) tool positions (m); NaN likewise.
    """

    configurations: np.ndarray
    tools: np.ndarray

    def triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """Two triangles per grid cell: vertex indices (t, 3, 2) and tool corners (t, 3, 2)."""
        g = self.tools.shape[0]
        rows, columns = np.meshgrid(np.arange(g - 1), np.arange(g - 1), indexing="ij")
        a, b = rows.ravel(), columns.ravel()
        corners = np.concatenate([
            np.stack([np.stack([a, b], -1), np.stack([a + 1, b], -1), np.stack([a, b + 1], -1)],
                     1),
            np.stack([np.stack([a + 1, b + 1], -1), np.stack([a, b + 1], -1),
                      np.stack([a + 1, b], -1)], 1)])
        tools = self.tools[corners[..., 0], corners[..., 1]]
        keep = np.isfinite(tools).all(axis=(1, 2))
        return corners[keep], tools[keep]


def planar_mesh(robot: Robot, joint: int, grid: int,
                gravity: Sequence[float] = swing.STANDARD_GRAVITY) -> PlanarMesh:
    """The stable zero-torque configurations of a planar 3-joint arm, on a `grid` x `grid` mesh.

    The two healthy joints over their ranges (a continuous joint over [-pi, pi], both
    ends included, so the mesh closes on itself), the failed `joint` (0-based) at its
    hanging angle. Resting on a stop is left out (the paper's arm has none).
    """
    _planar(robot)
    if not 2 <= grid or grid * grid > MAX_EVALUATIONS:
        raise ValueError(f"grid must be in [2, {math.isqrt(MAX_EVALUATIONS)}], got {grid}")
    healthy = [j for j in range(3) if j != joint]
    axes = [np.linspace(*_range(robot, j), grid) for j in healthy]
    configurations = np.full((grid, grid, 3), np.nan)
    tools = np.full((grid, grid, 2), np.nan)
    for a in range(grid):
        for b in range(grid):
            q = np.zeros(3)
            q[healthy] = axes[0][a], axes[1][b]
            settled = _settle(robot, joint, q, gravity)
            if settled is not None:
                configurations[a, b] = settled
                tools[a, b] = robot.forward(settled)
    return PlanarMesh(configurations, tools)


def _covers(triangles: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(k,) bool: whether triangle k (k, 3, 2) covers point k (k, 2), by barycentric signs."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]

    def side(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        return ((v[:, 0] - u[:, 0]) * (points[:, 1] - u[:, 1])
                - (v[:, 1] - u[:, 1]) * (points[:, 0] - u[:, 0]))

    s1, s2, s3 = side(a, b), side(b, c), side(c, a)
    return ((s1 >= 0) & (s2 >= 0) & (s3 >= 0)) | ((s1 <= 0) & (s2 <= 0) & (s3 <= 0))


def solution_counts(mesh: PlanarMesh, extent: float, pixels: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """How many stationary configurations reach each pixel's centre (fig. 5's regions).

    Args:
        mesh: `planar_mesh` of the arm and failed joint.
        extent: half-width of the square shown (m), centred on the base.
        pixels: pixels per side.

    Returns:
        counts (pixels, pixels), [row = y, column = x], and the pixel centres (pixels,) (m).
    """
    if not 1 <= pixels <= 4096:
        raise ValueError(f"pixels must be in [1, 4096], got {pixels}")
    centres = np.linspace(-extent, extent, pixels)
    step = centres[1] - centres[0] if pixels > 1 else 2 * extent
    counts = np.zeros((pixels, pixels), dtype=int)
    _, tools = mesh.triangles()
    low = np.clip(np.ceil((tools.min(axis=1) + extent) / step), 0, pixels).astype(int)
    high = np.clip(np.floor((tools.max(axis=1) + extent) / step), -1, pixels - 1).astype(int)
    span = int(max(1, (high - low + 1).max(initial=1)))
    for dx in range(span):
        for dy in range(span):
            ix, iy = low[:, 0] + dx, low[:, 1] + dy
            candidate = (ix <= high[:, 0]) & (iy <= high[:, 1])
            points = np.stack([centres[ix[candidate]], centres[iy[candidate]]], -1)
            inside = _covers(tools[candidate], points)
            np.add.at(counts, (iy[candidate][inside], ix[candidate][inside]), 1)
    return counts, centres


def zero_torque_solutions(robot: Robot, joint: int, point: Sequence[float], mesh: PlanarMesh,
                          gravity: Sequence[float] = swing.STANDARD_GRAVITY) -> np.ndarray:
    """The stationary configurations (k, 3; rad) of the planar arm whose tool is at `point`.

    Every mesh triangle covering the point gives a start (its barycentric blend of the
    healthy joints), refined by least squares on the tool's error with the failed joint
    kept at its hanging angle; those within `REACH_TOLERANCE`, once each (fig. 6).
    """
    _planar(robot)
    target = np.asarray(point, dtype=float)
    corners, tools = mesh.triangles()
    covering = _covers(tools, np.broadcast_to(target, (len(tools), 2)))
    healthy = [j for j in range(3) if j != joint]
    found: list[np.ndarray] = []
    for vertices in corners[covering]:
        start = mesh.configurations[vertices[:, 0], vertices[:, 1]][:, healthy].mean(axis=0)

        def error(h: np.ndarray) -> np.ndarray:
            q = np.zeros(3)
            q[healthy] = h
            settled = _settle(robot, joint, q, gravity)
            return (np.full(2, 1e3) if settled is None
                    else robot.forward(settled) - target)

        fit = least_squares(error, start, xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=200)
        q = np.zeros(3)
        q[healthy] = fit.x
        settled = _settle(robot, joint, q, gravity)
        if settled is None or np.linalg.norm(robot.forward(settled) - target) > REACH_TOLERANCE:
            continue
        if all(np.abs(_wrap(settled - other)).max() > SAME_CONFIGURATION for other in found):
            found.append(settled)
    return np.array(found).reshape(-1, 3)
