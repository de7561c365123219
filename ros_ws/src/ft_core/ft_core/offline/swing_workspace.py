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

The sampling is `ft_core.offline.swing_stationary`, the planar meshes
`ft_core.offline.swing_planar`; this module is `ft-swing`'s command line and
re-exports both modules' public names.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from ft_core import swing
from ft_core.offline import cli
from ft_core.offline.swing_planar import (
    REACH_TOLERANCE,
    SAME_CONFIGURATION,
    PlanarMesh,
    _planar,
    planar_mesh,
    solution_counts,
    zero_torque_solutions,
)
from ft_core.offline.swing_stationary import (
    MAX_EVALUATIONS,
    SampledWorkspace,
    sample_workspace,
    stationary_angles,
    volume_shares,
)
from ft_core.robots import Robot

__all__ = ["MAX_EVALUATIONS", "PLANAR_GRAVITY", "REACH_TOLERANCE", "SAME_CONFIGURATION",
           "PlanarMesh", "SampledWorkspace", "main", "parser", "planar_mesh", "sample_workspace",
           "solution_counts", "stationary_angles", "volume_shares", "zero_torque_solutions"]

#: Gravity (m/s^2, URDF root frame) of `ft-swing` for a planar arm, whose x-y plane is
#: taken as vertical; other arms get `swing.STANDARD_GRAVITY` (-z, as URDF assumes).
PLANAR_GRAVITY = (0.0, -9.81, 0.0)


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
