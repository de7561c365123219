"""`ft-bounds`: bounding-box soft limits for critical task points, as a parameters file.

    ft-bounds --robot panda --task position --points "0.5,0.1,0.4;0.45,-0.15,0.35"
    ft-bounds --robot my_arm.urdf --tip-link tool0

Without `--points`, three points the tool reaches around the seed configuration are
chosen (`selfmotion.points_around`) and printed. For each critical point it traces the
self-motion manifold (from a configuration that reaches the point, found from `--seed`,
else the built-in's home or, for other arms, `selfmotion.bent_configuration`), prints
the point's bounding box and normalised volume, then the intersection of the boxes and
whether every point is still reachable inside it (Lewis & Maciejewski 1997 sec. III, steps 3-5). On
success it writes a ROS 2 parameters file that the controller accepts
(`soft_limits.lower`, `soft_limits.upper`, `critical_points`, with the model
selection), for every node (`/**`).

Exit status: 0 success; 1 bad input (robot model, points, seed) or an output file
that cannot be written (checked before the tracing); 2 usage (an empty list value
too); 3 a point is out of reach; 4 the boxes do not intersect or a point cannot be
reached inside the intersection. Nothing is written unless the status is 0.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import yaml

from ft_core import selfmotion
from ft_core.offline import cli

#: Stand-in for "no soft limit" on a joint without position limits (YAML has no inf
#: that every ROS 2 parameter parser accepts).
UNBOUNDED = 1.0e9


class _Progress:
    """Per point a line, and while tracing a one-line status on a terminal."""

    def __init__(self, total: int, targets: Sequence[np.ndarray], stream=sys.stderr):
        self.total, self.targets, self.stream = total, targets, stream
        self.tty = stream.isatty()

    def __call__(self, index: int, text: str) -> None:
        if not text:
            target = self.targets[index]
            label = np.round(target[:3, 3] if target.ndim == 2 else target, 4).tolist()
            self.done()
            self.stream.write(f"[{index + 1}/{self.total}] point {label}\n")
        elif self.tty:
            self.stream.write(f"\r    tracing: {text:<24}")
        self.stream.flush()

    def done(self) -> None:
        if self.tty:
            self.stream.write("\r" + " " * 40 + "\r")


def _fmt(values: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:7.3f}" for v in values) + "]"


def _finite(values: np.ndarray) -> list[float]:
    return [float(np.clip(v, -UNBOUNDED, UNBOUNDED)) for v in values]


def parameters(args: argparse.Namespace, lower: np.ndarray, upper: np.ndarray,
               flat_points: Sequence[float]) -> dict:
    """The ROS 2 parameters-file content for the controller."""
    params = {"robot_model": args.robot, "task_space": args.task,
              "soft_limits": {"lower": _finite(lower), "upper": _finite(upper)},
              "critical_points": [float(v) for v in flat_points]}
    if args.base_link:
        params["base_link"] = args.base_link
    if args.tip_link:
        params["tip_link"] = args.tip_link
    return {"/**": {"ros__parameters": params}}


def parser() -> argparse.ArgumentParser:
    """`ft-bounds`'s command line (every number bounded: `cli.bounded`)."""
    parser = argparse.ArgumentParser(prog="ft-bounds", description=__doc__.splitlines()[0])
    cli.add_model_arguments(parser, task="position")
    parser.add_argument("--points", type=cli.nonempty,
                        help="'x,y,z;x,y,z' (planar: 'x,y;...'; pose: x,y,z,qx,qy,qz,qw); "
                        "default: three points around the seed")
    parser.add_argument("--seed", type=cli.nonempty,
                        help="seed configuration 'q1,...,qn' (rad) for the tracing "
                        "(default: the built-in's home, else a bent configuration)")
    parser.add_argument("--step", **cli.tracing_step())
    parser.add_argument("--output", "-o", type=Path, default=Path("ft_bounds.yaml"),
                        help="parameters file to write, default %(default)s")
    return parser


@cli.clear_file_errors("ft-bounds")
def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    args = parser().parse_args(argv)
    cli.check_file(args.output)  # an unwritable output fails now, not after the tracing
    try:
        robot = cli.load_robot(args)
        seed = None if args.seed is None else cli.configuration(args.seed, robot, "--seed")
        # Without --seed: the built-in's home, else a bent configuration (the all-zero pose
        # of most URDFs is straight and singular, and its components rarely share a box).
        around = selfmotion.bent_configuration(robot) if seed is None else seed
        if args.points is None:
            flat = selfmotion.flat_from_targets(robot, selfmotion.points_around(robot, around))
        else:
            flat = cli.parse_points(args.points)
        targets = selfmotion.targets_from_flat(robot, flat)
    except ValueError as error:
        print(f"ft-bounds: {error}", file=sys.stderr)
        return 1
    print(f"{robot.name}: {robot.n} joints {list(robot.joint_names)}, {robot.task_space} task")
    if robot.n <= robot.m:
        print(f"ft-bounds: {robot.name} has {robot.n} joints for a {robot.task_space} task of "
              f"{robot.m} coordinates: no redundancy, so a task point has no self-motion and "
              "its box is one configuration (Lewis & Maciejewski 1997 need n > m); try a "
              "task of fewer coordinates (--task position or planar)", file=sys.stderr)
        return 4
    if args.points is None:
        size = selfmotion.point_size(robot)
        chosen = ";".join(",".join(f"{v:.4f}" for v in flat[i:i + size])
                          for i in range(0, len(flat), size))
        print(f"no --points: chose {len(targets)} around the seed: --points \"{chosen}\"")
    progress = _Progress(len(targets), targets)
    try:
        boxes = selfmotion.critical_boxes(robot, targets, around, args.step, progress)
    except selfmotion.UnreachableError as error:
        progress.done()
        print(f"ft-bounds: {error}", file=sys.stderr)
        return 3
    progress.done()
    for index, manifold in enumerate(boxes.manifolds):
        lower, upper = manifold.box
        print(f"  point {index + 1}: lower {_fmt(lower)}\n"
              f"           upper {_fmt(upper)}\n"
              f"           volume {selfmotion.box_volume(robot, lower, upper):.4g} "
              f"({manifold.method}, {len(manifold.samples)} samples)")
    lower, upper = boxes.lower, boxes.upper
    print(f"intersection: lower {_fmt(lower)}\n              upper {_fmt(upper)}")
    if boxes.empty:
        names = [robot.joint_names[j] for j in boxes.empty]
        print(f"ft-bounds: the boxes do not intersect on {names}: no soft limits keep every "
              "point reachable after a failure. Try --seed with a configuration that reaches "
              "the points from one posture (each point's self-motion component is traced "
              "from the one nearest the seed), or fewer or closer points", file=sys.stderr)
        return 4
    print(f"  volume {selfmotion.box_volume(robot, lower, upper):.4g}")
    if boxes.unreachable:
        print(f"ft-bounds: points {list(boxes.unreachable)} cannot be reached inside the "
              "intersection: try fewer or closer points (a pose task's self-motion is a "
              "curve, so its boxes are thin), or --seed with a configuration that reaches "
              "them all from one posture", file=sys.stderr)
        return 4
    print("every point is reachable inside the intersection")
    header = "# Soft limits from ft-bounds (Lewis & Maciejewski 1997 sec. III).\n"
    args.output.write_text(header + yaml.safe_dump(parameters(args, lower, upper, flat),
                                                   sort_keys=False))
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
