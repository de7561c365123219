"""`ft-map`: where to put the task, a map of fault tolerance over the workspace.

    ft-map --robot puma560 --x 0.05:1.0:96 --y 0 --z 0.5 --joints 1,2,3,4,5 -o puma_line
    ft-map --robot planar3r --x=-3:3:41 --y=-3:3:41 -o planar
    ft-map --robot puma560 --x 0.3:0.9:13 --y=-0.3:0.3:13 --z 0.5 --suggest "0,0,0;0.1,0,0"

(A range that starts with a minus sign needs the `=` form: `--y=-0.3:0.3:13`.)

`ft-map fault-tolerant-workspace` (first argument) runs
`ft_core.offline.fault_tolerant_workspace` instead: the failure-tolerant workspace of the
planar 3R under software joint limits (Lewis & Maciejewski 1997 fig. 3), with its own options.

Lewis & Maciejewski 1997 sec. III, steps 1-2 (and fig. 7): the size of a task point's self-motion
manifold says how fault tolerant the point is, so a critical task is best placed
where that size is large. For every point of a grid of task positions (a line, a
plane or a volume: each of `--x`, `--y` (and `--z`) is a value or a range
`start:stop:count`), this tool

1. finds a seed configuration reaching the point from the start configuration
   (`--seed`, default the built-in's home, else `selfmotion.bent_configuration`) by
   *continuation*: the tool point is moved from where the start configuration puts it
   to the grid point in a straight line, in steps of at most `CONTINUATION_STEP`, and
   Newton corrects each step inside the physical limits, so the seed keeps the start's
   posture (elbow up or down, wrist flipped or not) wherever the line allows. Where
   it does not (the line leaves the workspace or meets a limit), `selfmotion.find_seed`
   from the start configuration (then seeded random starts) takes over;
2. traces the connected component of the self-motion manifold through that seed
   (`selfmotion.trace`) and takes its bounding box;
3. records the box's normalised volume over `--joints` (each side divided by its
   joint's range, so 1 is the whole joint space) and its volume in rad^k (Lewis & Maciejewski 1997
   Table II), the local measure kfm (Lewis & Maciejewski 1997 eq 5, with `Robot.scale_task`) at the
   seed, and the largest kfm over at most `KFM_SAMPLES` samples of the component;
4. with `--restarts K`, traces up to K further components from seeded random
   configurations and records the largest volume of all of them (`best_volume`):
   Lewis & Maciejewski 1997 traces one component per point, and which one depends on the seed.

Grid points are shared, in chunks, among `--workers` processes (default: every core) or
the workers of a Dask cluster (`--cluster`; `ft_core.offline.batch`); each builds its own
robot from the model arguments.

`--suggest "dx,dy(,dz);..."` takes critical points as offsets from a reference point
(a rigid set, translated but not rotated): the grid then holds placements of the
reference, every critical point is evaluated at each placement, and a placement's
score is the normalised volume of the intersection of the points' boxes (Lewis & Maciejewski 1997
sec. III, steps 3-4; 0 when it is empty or a point is out of reach). The `--top`
best placements are checked as step 5 asks (every point reachable inside the
intersection, `selfmotion.reachability`) and the best that passes is suggested, with
the `ft-bounds` command for its soft limits. Without `--suggest` there is a single
point at offset 0 and the score is its volume; the best grid point is printed.

Writes PREFIX.npz (every array, by grid point), PREFIX.csv (a row per grid point)
and PREFIX.png (a line plot for a 1-D grid, a heat map for 2-D, slices for 3-D).

Exit status: 0 success; 1 bad input (model, grid, seed, joints, offsets); 2 usage;
3 no grid point is reachable; 4 (`--suggest`) no placement keeps every point
reachable inside a non-empty intersection. The files are written for 0, 3 and 4.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
import pinocchio as pin

from ft_core import limits, measures, robots, selfmotion
from ft_core.offline import batch, cli, fault_tolerant_workspace

#: Longest straight move (m) of the tool per continuation step when seeding.
CONTINUATION_STEP = 0.05
#: Most continuation steps (the move is cut into more, shorter steps only up to this).
MAX_CONTINUATION_STEPS = 200
#: Most manifold samples at which kfm is evaluated for `kfm_max`.
KFM_SAMPLES = 100
#: Most grid points x critical points in one run.
MAX_TASKS = 200_000
#: Most heat-map panels (slices) of a 3-D grid.
MAX_PANELS = 12
#: Axis names of the task positions.
AXES = ("x", "y", "z")


@dataclass
class PointResult:
    """Fault tolerance of one task point (NaN where unreachable).

    Attributes:
        reachable: a seed configuration was found.
        continued: the seed came from continuation (else from `find_seed`).
        volume: normalised volume of the traced component's box over the chosen joints.
        volume_rad: the same box's volume in rad^k (k chosen joints; m for prismatic).
        best_volume: largest normalised volume over the traced components (restarts).
        components: components traced (1 + distinct restarts; 0 if unreachable).
        kfm: kfm (Lewis & Maciejewski 1997 eq 5) at the seed, m/rad (scaled task rows).
        kfm_max: largest kfm over at most `KFM_SAMPLES` samples of the component.
        seed: the seed configuration (n,), rad.
        q_kfm: the sample where kfm_max was found (n,), rad.
        lower, upper: the component's box (n,), rad (+-inf for a joint without
            limits that turns fully).
    """

    reachable: bool
    continued: bool
    volume: float
    volume_rad: float
    best_volume: float
    components: int
    kfm: float
    kfm_max: float
    seed: np.ndarray
    q_kfm: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    @classmethod
    def unreachable(cls, n: int) -> PointResult:
        """The result of a point no configuration reaches."""
        nan = np.full(n, np.nan)
        return cls(False, False, 0.0, 0.0, 0.0, 0, math.nan, math.nan, nan, nan.copy(),
                   nan.copy(), nan.copy())


def kfm_of(robot: robots.Robot, q: np.ndarray) -> float:
    """kfm(q) = min_i sigma_m(iJ) of the task-scaled J (Lewis & Maciejewski 1997 eq 5), m/rad."""
    return measures.kfm(robot.scale_task(robot.jacobian(q)))


def continuation_seed(robot: robots.Robot, target: np.ndarray, q_start: np.ndarray,
                      ) -> np.ndarray | None:
    """A configuration reaching `target` that keeps the posture of q_start, or None.

    The tool point moves from `robot.forward(q_start)` to `target` in a straight
    line (a geodesic for a pose: exp6 of a fraction of log6 of the relative motion),
    in equal steps of at most `CONTINUATION_STEP` m (or rad for the rotation, at
    most `MAX_CONTINUATION_STEPS`), each corrected by `selfmotion.project` inside
    the physical limits. None when a step does not converge.
    """
    q = np.clip(np.asarray(q_start, dtype=float), robot.lower, robot.upper)
    start = robot.forward(q)
    if robot.task_space == "pose":
        motion = pin.log6(pin.SE3(start).inverse() * pin.SE3(target)).vector
        length = float(np.linalg.norm(motion))
    else:
        length = float(np.linalg.norm(target - start))
    steps = min(MAX_CONTINUATION_STEPS, max(1, math.ceil(length / CONTINUATION_STEP)))
    for k in range(1, steps + 1):
        fraction = k / steps
        if robot.task_space == "pose":
            waypoint = (pin.SE3(start) * pin.exp6(fraction * motion)).homogeneous
        else:
            waypoint = start + fraction * (target - start)
        q = selfmotion.project(robot, waypoint, q)
        if q is None:
            return None
    return q


def evaluate_point(robot: robots.Robot, target: np.ndarray, q_start: np.ndarray,
                   joints: Sequence[int] | None = None, step: float = selfmotion.STEP,
                   restarts: int = 0, index: int = 0) -> PointResult:
    """Fault tolerance of one task point: seed, traced component, box volume and kfm.

    Args:
        robot: the arm.
        target: the task point (as `robot.forward` returns it).
        q_start: start configuration (rad) for the continuation seed (module notes).
        joints: joints (0-based) of the volume; default all.
        step: tracing step (rad).
        restarts: further components to trace from seeded random configurations.
        index: the grid index, seeding the restarts' random generator (determinism).

    Returns:
        The point's `PointResult`.
    """
    seed = continuation_seed(robot, target, q_start)
    continued = seed is not None
    if seed is None:
        try:
            seed = selfmotion.find_seed(robot, target, q_start)
        except selfmotion.UnreachableError:
            return PointResult.unreachable(robot.n)
    manifold = selfmotion.trace(robot, target, seed, step=step)
    lower, upper = manifold.box
    volume = selfmotion.box_volume(robot, lower, upper, joints)
    finite_lower = np.where(np.isfinite(lower), lower, -math.pi)  # unlimited: one turn
    finite_upper = np.where(np.isfinite(upper), upper, math.pi)
    volume_rad = selfmotion.box_volume(robot, finite_lower, finite_upper, joints,
                                       normalized=False)
    samples = manifold.samples
    picked = samples[np.unique(np.linspace(0, len(samples) - 1, KFM_SAMPLES).astype(int))]
    values = np.array([kfm_of(robot, q) for q in picked])
    best = int(np.argmax(values))
    best_volume, components, traced = volume, 1, samples
    rng = np.random.default_rng(index)
    for _ in range(restarts):
        start = robot.random_configuration(rng)
        try:
            other = selfmotion.find_seed(robot, target, start, attempts=0)
        except selfmotion.UnreachableError:
            continue
        if selfmotion.near(robot, traced, other, 4 * step):
            continue  # on a component already traced
        component = selfmotion.trace(robot, target, other, step=step)
        best_volume = max(best_volume, selfmotion.box_volume(robot, *component.box, joints))
        traced = np.vstack([traced, component.samples])
        components += 1
    return PointResult(True, continued, volume, volume_rad, best_volume, components,
                       kfm_of(robot, seed), float(values[best]), seed, picked[best],
                       lower, upper)


# --- worker processes ----------------------------------------------------------------

_WORKER: dict = {}


def _run_chunk(job: tuple[tuple, dict, list[tuple[int, np.ndarray]]],
               ) -> list[tuple[int, PointResult]]:
    """Evaluate (index, target) pairs of `job` = (model, settings, pairs).

    The robot is built once per process and model (robots do not pickle).
    """
    model, settings, chunk = job
    if _WORKER.get("model") != model:
        _WORKER.update(model=model,
                       robot=robots.load(model[0], model[1], model[2], task_space=model[3]))
    robot = _WORKER["robot"]
    return [(index, evaluate_point(robot, target, settings["q_start"], settings["joints"],
                                   settings["step"], settings["restarts"], index))
            for index, target in chunk]


def evaluate_targets(model: tuple[str, str | None, str | None, str | None],
                     targets: Sequence[np.ndarray], q_start: np.ndarray,
                     joints: Sequence[int] | None = None, step: float = selfmotion.STEP,
                     restarts: int = 0, where: batch.Where = batch.HERE,
                     ) -> list[PointResult]:
    """`evaluate_point` for every target, where `where` says (`batch`).

    Args:
        model: (spec, base_link, tip_link, task_space) for `robots.load` in each worker.
        targets: the task points.
        q_start: start configuration (rad), as `evaluate_point`.
        joints: joints of the volume, as `evaluate_point`.
        step: tracing step (rad).
        restarts: further components per point, as `evaluate_point`.
        where: worker processes or a cluster; one worker evaluates here without a pool.

    Returns:
        The results in the order of `targets`.
    """
    settings = {"q_start": np.asarray(q_start, dtype=float),
                "joints": None if joints is None else list(joints), "step": step,
                "restarts": restarts}
    pairs = list(enumerate(targets))
    # Small chunks keep the load balanced (points near the boundary are quick, points
    # with large manifolds are slow) and the bar moving.
    size = max(1, min(16, len(pairs) // (8 * max(where.workers, 1))))
    jobs = [(model, settings, pairs[k:k + size]) for k in range(0, len(pairs), size)]
    results: list[PointResult | None] = [None] * len(pairs)
    for done in batch.results(_run_chunk, jobs, where, what="chunk"):
        for index, result in done:
            results[index] = result
    return results  # type: ignore[return-value]


# --- grid ----------------------------------------------------------------------------

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


# --- output --------------------------------------------------------------------------

_SCALARS = ("reachable", "continued", "volume", "volume_rad", "best_volume", "components",
            "kfm", "kfm_max")
_VECTORS = ("seed", "q_kfm", "lower", "upper")


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


# --- command line --------------------------------------------------------------------

def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ft-map", description=__doc__.splitlines()[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="grid: each task coordinate (--x, --y, and --z unless the task is planar) is\n"
               "  a value or start:stop:count (count values from start to stop inclusive), in\n"
               "  the base link's frame (m). One range makes a line (line plot), two a plane\n"
               "  (heat map), three a volume (heat-map slices). A range starting with a minus\n"
               "  sign needs the = form: --y=-0.3:0.3:13.\n"
               "  Lewis & Maciejewski 1997 fig. 7 (PUMA 560, distance from joint 1's axis at\n"
               "  height 0.5 m):\n"
               "    ft-map --robot puma560 --x 0.05:1.15:45 --y 0 --z 0.5 --joints 1,2,3,4,5\n"
               "outputs: PREFIX.npz, PREFIX.csv, PREFIX.png (see the module docstring).\n"
               f"subcommand: ft-map {fault_tolerant_workspace.COMMAND} (-h for its options):\n"
               "  the failure-tolerant workspace of the planar 3R under joint limits\n"
               "  (Lewis & Maciejewski 1997 fig. 3).\n"
               "exit status: 0 ok, 1 bad input, 2 usage, 3 nothing reachable, 4 no placement.")
    cli.add_model_arguments(parser, task=None, tasks=("planar", "position", "pose"))
    for name in AXES:
        parser.add_argument(f"--{name}", metavar="V|START:STOP:COUNT",
                            help=f"{name} of the task points (m): a value or a range"
                            + (" (not for a planar task)" if name == "z" else ""))
    parser.add_argument("--orientation", metavar="QX,QY,QZ,QW", type=cli.nonempty,
                        help="pose task: the tool orientation at every point (default: "
                        "the start configuration's)")
    parser.add_argument("--seed", metavar="Q1,...,QN", type=cli.nonempty,
                        help="start configuration (rad) the seeds are continued from "
                        "(default: the built-in's home, else a bent configuration)")
    parser.add_argument("--joints", metavar="I,J,...", type=cli.nonempty,
                        help="joints (1-based) spanning the volume, e.g. 1,2,3,4,5 for "
                        "the PUMA's rad^5 of Lewis & Maciejewski 1997 Table II (default: all)")
    parser.add_argument("--restarts", type=cli.bounded(int, 0, 100), default=0,
                        help="further components traced from random configurations per "
                        "point, for best_volume (default %(default)s)")
    parser.add_argument("--suggest", metavar="DX,DY,DZ;...", type=cli.nonempty,
                        help="critical points as offsets (m) from a reference point: the grid "
                        "is then of placements of the reference, scored by the volume of "
                        "the intersection of the points' boxes")
    parser.add_argument("--top", type=cli.bounded(int, 1, 1000), default=5,
                        help="placements checked for reachability inside the intersection "
                        "and printed (default %(default)s)")
    parser.add_argument("--step", **cli.tracing_step())
    batch.add_arguments(parser)
    parser.add_argument("--output", "-o", type=Path, default=Path("ft_map"),
                        help="output prefix (PREFIX.npz, .csv, .png), default %(default)s")
    parser.add_argument("--no-plot", action="store_true", help="do not draw the figure")
    return parser


def _setup(args: argparse.Namespace) -> tuple:
    """Validate the arguments; return robot, grid, offsets, start, joints, orientation."""
    robot = cli.load_robot(args)
    names = AXES[:2] if robot.task_space == "planar" else AXES
    if robot.task_space == "planar" and args.z is not None:
        raise ValueError("a planar task has no --z")
    missing = [f"--{name}" for name in names if getattr(args, name) is None]
    if missing:
        raise ValueError(f"give {' and '.join(missing)} (a value or start:stop:count)")
    grid = Grid(tuple(names), tuple(parse_axis(n, getattr(args, n)) for n in names))
    start = selfmotion.bent_configuration(robot) if args.seed is None else cli.configuration(
        args.seed, robot, "--seed")
    joints = None
    if args.joints is not None:
        values = cli.numbers(args.joints)
        if not values or any(v != int(v) or not 1 <= v <= robot.n for v in values):
            raise ValueError(f"--joints must be joint numbers in 1..{robot.n}")
        joints = sorted({int(v) - 1 for v in values})
    d = len(names)
    offsets = np.zeros((1, d))
    if args.suggest is not None:
        flat = cli.parse_points(args.suggest)
        if not flat or len(flat) % d or not np.all(np.abs(flat) <= limits.ABSURD_DISTANCE):
            raise ValueError(f"--suggest needs offsets of {d} numbers each ('dx,dy"
                             f"{',dz' if d == 3 else ''};...'), within "
                             f"+-{limits.ABSURD_DISTANCE:g} m, "
                             f"got {len(flat)} numbers")
        offsets = np.array(flat).reshape(-1, d)
    orientation = None
    if robot.task_space == "pose":
        if args.orientation is None:
            orientation = robot.transform(start)[:3, :3]
        else:
            quaternion = np.array(cli.numbers(args.orientation))
            with np.errstate(over="ignore"):  # 1e308: an infinite norm, refused
                norm = np.linalg.norm(quaternion)
            if quaternion.shape != (4,) or not 0 < norm < np.inf:
                raise ValueError("--orientation needs qx,qy,qz,qw (not all zero, norm finite)")
            quaternion /= np.linalg.norm(quaternion)
            orientation = pin.Quaternion(*quaternion[[3, 0, 1, 2]]).toRotationMatrix()
    elif args.orientation is not None:
        raise ValueError("--orientation is for a pose task")
    tasks = len(grid.points()) * len(offsets)
    if tasks > MAX_TASKS:
        raise ValueError(f"{tasks} task points (grid x critical points): at most {MAX_TASKS}")
    return robot, grid, offsets, start, joints, orientation


@cli.clear_file_errors("ft-map")
def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    arguments = sys.argv[1:] if argv is None else list(argv)
    if arguments[:1] == [fault_tolerant_workspace.COMMAND]:
        return fault_tolerant_workspace.main(arguments[1:])
    args = _parser().parse_args(arguments)
    try:
        robot, grid, offsets, start, joints, orientation = _setup(args)
    except ValueError as error:  # RobotModelError is a ValueError
        print(f"ft-map: {error}", file=sys.stderr)
        return 1
    cli.check_folder(args.output.parent)  # a file in the way fails now, not after the work
    placements = grid.points()
    positions = (placements[:, None, :] + offsets[None]).reshape(-1, placements.shape[1])
    targets = [task_target(robot, p, orientation) for p in positions]
    where = batch.Where.from_arguments(args)
    volume_joints = "all joints" if joints is None else "joints " + ",".join(
        str(j + 1) for j in joints)
    print(f"{robot.name}: {robot.n} joints, {robot.task_space} task; grid {grid.shape} "
          f"x {len(offsets)} point(s) = {len(targets)} task points {where.describe()}; "
          f"volume over {volume_joints}")
    results = evaluate_targets((args.robot, args.base_link or None, args.tip_link or None,
                                robot.task_space), targets, start, joints, args.step,
                               args.restarts, where)
    data = collect(results, len(placements), len(offsets))
    score = scores(robot, data, joints)
    # Per placement, the worst point's largest kfm on its component (Lewis & Maciejewski 1997 eq 5).
    kfm = np.min(np.where(data["reachable"], data["kfm_max"], np.inf), axis=1)
    kfm = np.where(np.isfinite(kfm), kfm, np.nan)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    prefix = str(args.output)
    meta = {"robot": args.robot, "task": robot.task_space, "joint_names": robot.joint_names,
            "joints": joints, "start": start.tolist(), "step": args.step,
            "restarts": args.restarts, "argv": sys.argv[1:] if argv is None else list(argv)}
    np.savez_compressed(prefix + ".npz", names=np.array(grid.names), shape=np.array(grid.shape),
                        points=placements, offsets=offsets, score=score,
                        **{f"axis_{n}": a for n, a in zip(grid.names, grid.axes, strict=True)},
                        **data, meta=json.dumps(meta))
    write_csv(Path(prefix + ".csv"), grid, data, score)
    reachable = data["reachable"].all(axis=1)
    print(f"reachable: {int(reachable.sum())} of {len(placements)} grid points; "
          f"wrote {prefix}.npz, {prefix}.csv", end="")
    order = np.argsort(-score, kind="stable")[:args.top]
    suggested = None
    if len(offsets) == 1:
        if reachable.any():
            suggested = int(order[0])
    else:
        for k in order:
            if score[k] <= 0:
                break
            box = selfmotion.intersect(zip(data["lower"][k], data["upper"][k], strict=True))
            found = selfmotion.reachability(robot, [targets[i] for i in range(
                k * len(offsets), (k + 1) * len(offsets))], *box, start)
            if all(q is not None for q in found):
                suggested = int(k)
                break
    marks = None if suggested is None else placements[suggested] + offsets
    label = ("normalised box volume" if len(offsets) == 1 else
             f"volume of the intersection of {len(offsets)} boxes")
    if not args.no_plot:
        best = data["best_volume"][:, 0] if len(offsets) == 1 and args.restarts else None
        shown = np.where(reachable, score, np.nan)  # unreachable placements show grey
        plot(Path(prefix + ".png"), grid, shown, kfm,
             f"{robot.name}: self-motion box volume ({volume_joints})", label, marks, best)
        print(f", {prefix}.png", end="")
    print()
    print("best grid points (score, position, largest kfm on the component):")
    for k in order:
        print(f"  {score[k]:.4g}  {np.round(placements[k], 4).tolist()}  kfm {kfm[k]:.4g}")
    if not reachable.any():
        print("ft-map: no grid point is reachable", file=sys.stderr)
        return 3
    if suggested is None:
        print("ft-map: no placement keeps every critical point reachable inside a non-empty "
              "intersection of their boxes: try a finer or larger grid, closer points or "
              "another --seed", file=sys.stderr)
        return 4
    if len(offsets) > 1:
        chosen = targets[suggested * len(offsets):(suggested + 1) * len(offsets)]
        flat = selfmotion.flat_from_targets(robot, chosen)
        size = selfmotion.point_size(robot)
        points = ";".join(",".join(f"{v:.4f}" for v in flat[i:i + size])
                          for i in range(0, len(flat), size))
        seed = ",".join(f"{v:.4f}" for v in data["seed"][suggested, 0])
        print(f"suggested placement: reference at {np.round(placements[suggested], 4).tolist()}"
              f", intersection volume {score[suggested]:.4g}; every point reachable inside it")
        print(f"  soft limits: ft-bounds --robot {args.robot} --task {robot.task_space} "
              f"--points \"{points}\" --seed={seed}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
