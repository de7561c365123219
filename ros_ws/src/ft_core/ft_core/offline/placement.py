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

One point's evaluation is `ft_core.offline.placement_points`, the grid and the outputs
`ft_core.offline.placement_map`; their public names are importable from here too.

Exit status: 0 success; 1 bad input (model, grid, seed, joints, offsets); 2 usage;
3 no grid point is reachable; 4 (`--suggest`) no placement keeps every point
reachable inside a non-empty intersection. The files are written for 0, 3 and 4.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin

from ft_core import limits, selfmotion
from ft_core.offline import batch, cli, fault_tolerant_workspace
from ft_core.offline.placement_map import (
    AXES,
    MAX_PANELS,
    MAX_TASKS,
    Grid,
    collect,
    parse_axis,
    plot,
    scores,
    task_target,
    write_csv,
)
from ft_core.offline.placement_points import (
    CONTINUATION_STEP,
    KFM_SAMPLES,
    MAX_CONTINUATION_STEPS,
    PointResult,
    continuation_seed,
    evaluate_point,
    evaluate_targets,
    kfm_of,
)

__all__ = ["AXES", "CONTINUATION_STEP", "KFM_SAMPLES", "MAX_CONTINUATION_STEPS", "MAX_PANELS",
           "MAX_TASKS", "Grid", "PointResult", "collect", "continuation_seed", "evaluate_point",
           "evaluate_targets", "kfm_of", "main", "parse_axis", "plot", "scores", "task_target",
           "write_csv"]


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
