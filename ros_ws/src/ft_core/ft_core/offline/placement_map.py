"""The grid of task positions `ft-map` scores, and its outputs: CSV rows and the figure.

`Grid` is the Cartesian product of the axes `parse_axis` reads; `collect` gathers the
`PointResult`s of its points into arrays, `scores` turns them into a placement score
(the normalised volume of the intersection of the critical points' boxes, Lewis &
Maciejewski 1997 sec. III, steps 3-4), `write_csv` and `plot` write them.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from ft_core import limits, robots, selfmotion
from ft_core.offline.placement_points import PointResult

#: Most grid points x critical points in one run.
MAX_TASKS = 200_000
#: Most heat-map panels (slices) of a 3-D grid.
MAX_PANELS = 12
#: Axis names of the task positions.
AXES = ("x", "y", "z")

def parse_axis(name: str, text: str) -> np.ndarray:
    """A grid axis from 'value' or 'start:stop:count' (inclusive, like numpy.linspace).

    Raises:
        ValueError: not a number, count not an integer in 1..`MAX_TASKS`, or a value
            beyond `limits.ABSURD_DISTANCE` (or non-finite).
    """
    parts = text.split(":")
    try:
        if len(parts) == 1:
            values = np.array([float(parts[0])])
        elif len(parts) == 3:
            count, start, stop = int(parts[2]), float(parts[0]), float(parts[1])
            if not (1 <= count <= MAX_TASKS and abs(start) <= limits.ABSURD_DISTANCE
                    and abs(stop) <= limits.ABSURD_DISTANCE):
                raise ValueError
            values = np.linspace(start, stop, count)
        else:
            raise ValueError
    except ValueError:
        raise ValueError(f"--{name} must be a value or start:stop:count (count an integer, "
                         f"1 to {MAX_TASKS}; within +-{limits.ABSURD_DISTANCE:g} m), "
                         f"got {text[:80]!r}") from None
    if not np.all(np.abs(values) <= limits.ABSURD_DISTANCE):  # also refuses nan
        raise ValueError(f"--{name} must be within +-{limits.ABSURD_DISTANCE:g} m, "
                         f"got {text[:80]!r}")
    return values


@dataclass(frozen=True)
class Grid:
    """A grid of task positions: the Cartesian product of its axes.

    Attributes:
        names: axis names ("x", "y" (, "z")), the task position's coordinates.
        axes: the values of each axis (m); fixed coordinates have one value.
    """

    names: tuple[str, ...]
    axes: tuple[np.ndarray, ...]

    @property
    def shape(self) -> tuple[int, ...]:
        """Number of values on each axis."""
        return tuple(len(a) for a in self.axes)

    @property
    def ranged(self) -> list[int]:
        """Indices of the axes with more than one value (the map's dimensions)."""
        return [k for k, a in enumerate(self.axes) if len(a) > 1]

    def points(self) -> np.ndarray:
        """Every grid point (N, d), the last axis varying fastest (C order)."""
        mesh = np.meshgrid(*self.axes, indexing="ij")
        return np.stack([m.ravel() for m in mesh], axis=1)


def task_target(robot: robots.Robot, position: np.ndarray,
                orientation: np.ndarray | None) -> np.ndarray:
    """The target `robot.forward` would return at `position` (with `orientation`, pose)."""
    if robot.task_space != "pose":
        return np.asarray(position, dtype=float).copy()
    pose = np.eye(4)
    pose[:3, :3] = orientation
    pose[:3, 3] = position
    return pose


_SCALARS = ("reachable", "continued", "volume", "volume_rad", "best_volume", "components",
            "kfm", "kfm_max")


def collect(results: Sequence[PointResult], placements: int, points: int) -> dict:
    """Arrays (placements, points[, n]) of every `PointResult` field."""
    names = [f.name for f in fields(PointResult)]
    return {name: np.array([getattr(r, name) for r in results]).reshape(
        (placements, points, *np.shape(getattr(results[0], name)))) for name in names}


def scores(robot: robots.Robot, data: dict, joints: Sequence[int] | None) -> np.ndarray:
    """Per placement: normalised volume of the intersection of its points' boxes.

    0 when a point is unreachable or the intersection is empty (Lewis & Maciejewski 1997 sec. III,
    steps 3-4). With a single point, its own volume.
    """
    placements = data["volume"].shape[0]
    score = np.zeros(placements)
    for k in range(placements):
        if not data["reachable"][k].all():
            continue
        box = selfmotion.intersect(zip(data["lower"][k], data["upper"][k], strict=True))
        if not selfmotion.empty_joints(box):
            score[k] = selfmotion.box_volume(robot, *box, joints)
    return score


def write_csv(path: Path, grid: Grid, data: dict, score: np.ndarray) -> None:
    """One row per grid point: coordinates, score, then each point's scalars."""
    points = data["volume"].shape[1]
    suffix = (lambda j: "") if points == 1 else (lambda j: f"_{j + 1}")
    header = [*grid.names, "score"] + [f"{name}{suffix(j)}" for j in range(points)
                                       for name in _SCALARS]
    with path.open("w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(header)
        for k, position in enumerate(grid.points()):
            row = [f"{v:.6g}" for v in position] + [f"{score[k]:.6g}"]
            for j in range(points):
                for name in _SCALARS:
                    value = data[name][k, j]
                    row.append(str(int(value)) if data[name].dtype.kind in "bi"
                               else f"{value:.6g}")
            writer.writerow(row)


def plot(path: Path, grid: Grid, score: np.ndarray, kfm: np.ndarray, title: str,
         label: str, marks: np.ndarray | None = None, best: np.ndarray | None = None,
         ) -> None:
    """A line plot (1-D grid), a heat map (2-D) or heat-map slices (3-D) of `score`.

    Args:
        path: the PNG to write.
        grid: the grid.
        score: per grid point (N,): the normalised volume or the placement score.
        kfm: per grid point (N,): the largest kfm on the component (m/rad), plotted
            beside the score in 1-D and 2-D.
        title: figure title.
        label: name of the score.
        marks: task positions (k, d) to mark (the suggested placement's points).
        best: per grid point (N,): the largest volume over traced components
            (`--restarts`), drawn dotted on a line plot.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ranged = grid.ranged
    shape = grid.shape
    score_grid = score.reshape(shape)
    kfm_grid = kfm.reshape(shape)
    fixed = ", ".join(f"{grid.names[k]} = {grid.axes[k][0]:g} m"
                      for k in range(len(shape)) if k not in ranged)
    if len(ranged) <= 1:
        axis = ranged[0] if ranged else 0
        values = grid.axes[axis]
        figure, left = plt.subplots(figsize=(7, 4))
        left.plot(values, score_grid.ravel(), "o-", color="tab:blue", markersize=3,
                  label="component through the seed")
        if best is not None:
            left.plot(values, best, ":", color="tab:blue",
                      label="largest over the traced components")
            left.legend(loc="upper left", fontsize=8)
        left.set_xlabel(f"{grid.names[axis]} (m)" + (f"   [{fixed}]" if fixed else ""))
        left.set_ylabel(label, color="tab:blue")
        right = left.twinx()
        right.plot(values, kfm_grid.ravel(), "s--", color="tab:orange", markersize=2)
        right.set_ylabel("largest kfm on the component (m/rad)", color="tab:orange")
        if marks is not None:
            for mark in marks:
                left.axvline(mark[axis], color="k", linestyle=":")
        left.grid(True, alpha=0.3)
    elif len(ranged) == 2:
        a, b = ranged
        figure, panels = plt.subplots(1, 2, figsize=(11, 4.5))
        for panel, values, name in ((panels[0], score_grid, label),
                                    (panels[1], kfm_grid,
                                     "largest kfm on the component (m/rad)")):
            image = np.squeeze(values).T  # rows: axis b, columns: axis a
            mesh = panel.pcolormesh(grid.axes[a], grid.axes[b],
                                    np.ma.masked_invalid(image), shading="nearest",
                                    cmap="viridis")
            panel.set_facecolor("0.85")  # unreachable (nan) points show grey
            figure.colorbar(mesh, ax=panel, label=name)
            panel.set_xlabel(f"{grid.names[a]} (m)")
            panel.set_ylabel(f"{grid.names[b]} (m)")
            panel.set_aspect("equal")
            if marks is not None:
                panel.plot(marks[:, a], marks[:, b], "r*", markersize=12)
        if fixed:
            panels[0].set_title(fixed, fontsize=9)
    else:
        a, b, c = ranged
        slices = np.unique(np.linspace(0, shape[c] - 1, min(shape[c], MAX_PANELS)).astype(int))
        columns = min(4, len(slices))
        rows = math.ceil(len(slices) / columns)
        figure, panels = plt.subplots(rows, columns, figsize=(3.4 * columns, 3.2 * rows),
                                      squeeze=False)
        top = float(np.nanmax(score)) if np.any(np.isfinite(score)) else 1.0
        for panel in panels.ravel()[len(slices):]:
            panel.axis("off")
        for panel, s in zip(panels.ravel(), slices, strict=False):
            image = np.take(score_grid, s, axis=c).T
            mesh = panel.pcolormesh(grid.axes[a], grid.axes[b], np.ma.masked_invalid(image),
                                    shading="nearest", cmap="viridis", vmin=0.0,
                                    vmax=top or 1.0)
            panel.set_facecolor("0.85")
            panel.set_title(f"{grid.names[c]} = {grid.axes[c][s]:.3g} m", fontsize=9)
            panel.set_aspect("equal")
            if marks is not None:
                panel.plot(marks[:, a], marks[:, b], "r*", markersize=8)
        figure.colorbar(mesh, ax=panels.ravel().tolist(), label=label)
    figure.suptitle(title, fontsize=10)
    figure.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(figure)
