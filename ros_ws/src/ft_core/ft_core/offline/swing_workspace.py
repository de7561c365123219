"""The workspace left after a free-swinging failure (Maciejewski et al. sec. 3.3, figs. 5-6).

A joint that loses its torque swings until gravity holds it. The post-failure workspace
is the set of tool positions the arm reaches while stationary with zero actuator torque
on the failed joint, the healthy joints at any values (Maciejewski et al. sec. 3.3). With
the healthy joints fixed, gravity's torque about a revolute joint is a sinusoid of its
angle (the outboard centre of mass turns about the axis), with one stable zero per turn:
the hanging angle q_i + theta_i, theta_i the swing angle of `ft_core.swing` (eq 13),
where the composite centre of mass of the outboard links hangs directly below the joint.

Readings taken where the paper is silent:

- Resting on a position limit that gravity presses the joint against is stationary too
  (the stop holds it, not the actuator): a limited joint whose hanging angle lies outside
  its range rests on that stop.
- A joint about which gravity has no torque at any angle (its axis along gravity, or the
  outboard centre of mass on the axis: the Panda's joint 1 on an upright base) is
  neutral. It stays where it failed, in effect a locked joint; the union over the angles
  it may fail at is the whole workspace, which is what the sampling reports for it.
- Statics only, as in the paper ("moving the healthy joints to their required positions
  along an arbitrary path" keeps the free joint at its rest): the dynamic swing, its
  overshoot and the coupling with moving joints are the physics plant's
  (`ft_core.physics`).

Two computations. `sample_workspace` samples the healthy joints uniformly within their
limits, puts the failed joint at each of its stationary angles and records the tool
positions: any arm, any joint. For a planar arm of three joints (the paper's example)
the stationary configurations reaching a point are isolated, and `solution_counts`
counts them over the plane (fig. 5's regions) while `zero_torque_solutions` finds them
at one point (fig. 6): both from a grid over the two healthy joints, whose image in the
plane is a mesh of triangles; a point is reached once for every triangle that covers it,
then each is refined by least squares.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from ft_core import swing
from ft_core.offline import cli
from ft_core.robots import Robot

#: Largest number of samples or grid vertices a call evaluates (each costs one Pinocchio
#: pass for the swing angle and one per stationary configuration).
MAX_EVALUATIONS = 2_000_000
#: m: a refined configuration counts as reaching the point within this distance.
REACH_TOLERANCE = 1e-9
#: rad: two configurations closer than this in every joint (modulo 2 pi) are one.
SAME_CONFIGURATION = 1e-6
#: Gravity (m/s^2, URDF root frame) of `ft-swing` for a planar arm, whose x-y plane is
#: taken as vertical; other arms get `swing.STANDARD_GRAVITY` (-z, as URDF assumes).
PLANAR_GRAVITY = (0.0, -9.81, 0.0)


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


def parser() -> argparse.ArgumentParser:
    """`ft-swing`'s command line (every number bounded: `cli.bounded`)."""
    parser = argparse.ArgumentParser(prog="ft-swing", description=__doc__.splitlines()[0])
    cli.add_model_arguments(parser, robot="planar3r_rods")
    parser.add_argument("--joints", type=cli.nonempty,
                        help="failed joints, 1-based, e.g. '2,4' (default: each in turn)")
    parser.add_argument("--gravity", type=cli.nonempty,
                        help="gravity 'gx,gy,gz' (m/s^2, URDF root frame); default -y for a "
                        "planar arm (its plane vertical), else -z")
    parser.add_argument("--samples", type=cli.bounded(int, 1, 200_000), default=20_000,
                        help="configurations sampled (1 to 200000), default %(default)s")
    parser.add_argument("--seed", type=cli.bounded(int, 0, cli.MAX_SEED), default=0,
                        help="random seed of the samples, default %(default)s")
    parser.add_argument("--voxel", type=cli.bounded(float, 0.01, 1.0), default=0.1,
                        help="edge of the cubes the volumes are counted in (m, 0.01 to 1), "
                        "default %(default)s")
    parser.add_argument("--point", type=cli.nonempty,
                        help="planar arm of 3 joints: list the stationary configurations "
                        "reaching 'x,y' (m)")
    parser.add_argument("--grid", type=cli.bounded(int, 10, 1000), default=200,
                        help="planar arm of 3 joints: grid over the healthy joints (10 to "
                        "1000 per joint), default %(default)s")
    parser.add_argument("--out", type=Path, default=Path("swing_out"), help="output folder")
    return parser


def _gravity(args: argparse.Namespace, robot: Robot) -> tuple[float, ...]:
    if args.gravity is None:
        return PLANAR_GRAVITY if robot.task_space == "planar" else swing.STANDARD_GRAVITY
    values = cli.numbers(args.gravity)
    if len(values) != 3 or not 0 < math.hypot(*values) <= 1e3:
        raise ValueError(f"--gravity needs 3 numbers of norm in (0, 1000] m/s^2: {args.gravity}")
    return tuple(values)


def _joints(args: argparse.Namespace, robot: Robot) -> list[int]:
    if args.joints is None:
        return list(range(robot.n))
    joints = [int(v) - 1 for v in cli.numbers(args.joints)]
    if any(not 0 <= j < robot.n for j in joints) or len(set(joints)) != len(joints):
        raise ValueError(f"--joints: distinct joint numbers from 1 to {robot.n}: {args.joints}")
    return joints


def _figure(path: Path, robot: Robot, whole: float, table: list[dict], planar: dict | None
            ) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = 2 if planar else 1
    fig, axes = plt.subplots(1, panels, figsize=(5.2 * panels, 4.4), squeeze=False)
    bars = axes[0, -1]
    labels = [str(row["joint"]) for row in table]
    bars.bar(labels, [row["volume_share"] for row in table], color="tab:blue",
             label="share of the workspace reached")
    bars.bar(labels, [row["volume_share"] * row["on_stop"] for row in table], color="tab:red",
             label="... times the share of samples on a stop")
    bars.axhline(whole, color="k", ls="--", lw=1, label="healthy, as many samples")
    bars.set_xlabel("free-swinging joint")
    bars.set_ylim(0, 1.05)
    bars.set_title(f"{robot.name}: workspace after a free-swinging failure", fontsize=9)
    bars.legend(fontsize=7, loc="lower right")
    if planar:
        ax = axes[0, 0]
        counts, centres = planar["counts"], planar["centres"]
        extent = (centres[0], centres[-1], centres[0], centres[-1])
        ax.imshow(np.where(counts > 0, counts, np.nan), origin="lower", extent=extent,
                  cmap="Greys", vmin=0, vmax=1.5 * max(4, int(counts.max())),
                  interpolation="nearest")
        for q in planar["solutions"]:
            chain = robot.skeleton(q)
            ax.plot(chain[:, 0], chain[:, 1], "-o", ms=2, lw=1)
        if planar["point"] is not None:
            ax.plot(*planar["point"], "r+", ms=10)
        ax.set_aspect("equal")
        ax.set_title(f"joint {planar['joint'] + 1} free: stationary configurations per point "
                     f"(grey levels 2, 4)", fontsize=9)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m), gravity down")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


@cli.clear_file_errors("ft-swing")
def main(argv: list[str] | None = None) -> int:
    """Run `ft-swing`; return the exit status (0 success, 1 bad input)."""
    args = parser().parse_args(argv)
    try:
        robot = cli.load_robot(args)
        gravity = _gravity(args, robot)
        joints = _joints(args, robot)
        point = None if args.point is None else cli.numbers(args.point)
        if point is not None and len(point) != 2:
            raise ValueError(f"--point needs 'x,y': {args.point}")
        if point is not None:
            _planar(robot)
        healthy, failed = sample_workspace(robot, joints, args.samples, args.seed, gravity)
    except ValueError as error:  # RobotModelError is a ValueError
        print(f"ft-swing: {error}", file=sys.stderr)
        return 1
    cli.check_folder(args.out)
    whole, shares = volume_shares(healthy, failed, args.voxel, args.seed)
    table = [{"joint": j + 1, "name": robot.joint_names[j], "volume_share": shares[j],
              "on_stop": float(w.on_stop.mean()), "neutral": w.neutral}
             for j, w in failed.items()]
    lines = [f"# {robot.name}: the workspace after a free-swinging failure", "",
             f"{args.samples} configurations (seed {args.seed}), gravity {list(gravity)} m/s^2, "
             f"volumes counted in {args.voxel:g} m cubes (`volume_shares`).", "",
             "| joint | name | share of the workspace reached | samples on a stop | neutral |",
             "|---:|---|---:|---:|---:|", f"| - | healthy (same count) | {whole:.3f} | - | - |"]
    lines += [f"| {r['joint']} | {r['name']} | {r['volume_share']:.3f} | {r['on_stop']:.2f} | "
              f"{r['neutral']:.2f} |" for r in table]
    planar: dict | None = None
    solutions = np.zeros((0, 3))
    if robot.task_space == "planar" and robot.n == 3:
        # The counts need one failed joint: the first asked for, else the paper's joint 2.
        joint = 1 if args.joints is None else joints[0]
        mesh = planar_mesh(robot, joint, args.grid, gravity)
        reach = float(np.nanmax(np.abs(mesh.tools)))
        counts, centres = solution_counts(mesh, 1.05 * reach, 300)
        if point is not None:
            solutions = zero_torque_solutions(robot, joint, point, mesh, gravity)
        planar = {"joint": joint, "counts": counts, "centres": centres, "point": point,
                  "solutions": solutions}
        shown = dict(zip(*np.unique(counts, return_counts=True), strict=True))
        lines += ["", f"Joint {joint + 1} free: pixels by number of stationary configurations "
                  f"reaching them: {', '.join(f'{k}: {v}' for k, v in shown.items())}."]
        if point is not None:
            lines += ["", f"{len(solutions)} stationary configuration(s) reach {point} (rad):"]
            lines += [f"- {np.round(q, 4).tolist()}" for q in solutions]
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "swing.md").write_text("\n".join(lines) + "\n")
    (args.out / "swing.json").write_text(json.dumps(
        {"robot": robot.name, "gravity": list(gravity), "samples": args.samples,
         "seed": args.seed, "voxel": args.voxel, "healthy_share": whole, "joints": table,
         "solutions": solutions.tolist()}, indent=1))
    _figure(args.out / "swing.png", robot, whole, table, planar)
    print("\n".join(lines))
    print(f"wrote {args.out}/swing.md, swing.json, swing.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
