"""What the `ft-*` command-line tools share: the model arguments and number lists.

Every tool that works on an arm takes the model the way the nodes do: `--robot`
(a built-in name or a URDF path), `--base-link`, `--tip-link` and `--task`.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from ft_core import robots


def add_model_arguments(parser: argparse.ArgumentParser, robot: str | None = None,
                        task: str | None = None,
                        tasks: Sequence[str] = tuple(sorted(robots.TASK_DIMENSIONS))) -> None:
    """Add `--robot`, `--base-link`, `--tip-link` and `--task` to `parser`.

    Args:
        parser: the tool's parser.
        robot: default model; None makes `--robot` required.
        task: default task space; None uses the built-in's own (position for URDFs).
        tasks: the task spaces the tool accepts.
    """
    names = ", ".join(sorted(robots.BUILTINS))
    if robot is None:
        parser.add_argument("--robot", required=True, help=f"built-in name ({names}) or URDF")
    else:
        parser.add_argument("--robot", default=robot,
                            help=f"built-in name ({names}) or URDF (default %(default)s)")
    parser.add_argument("--base-link", default="", help="first link of the chain")
    parser.add_argument("--tip-link", default="", help="tool link of the chain")
    parser.add_argument("--task", default=task, choices=list(tasks),
                        help="task space (default: the built-in's own, else pose)")


def load_robot(args: argparse.Namespace) -> robots.Robot:
    """The model the arguments of `add_model_arguments` select.

    Raises:
        robots.RobotModelError: the model cannot be loaded.
    """
    return robots.load(args.robot, args.base_link or None, args.tip_link or None,
                       task_space=args.task)


def numbers(text: str) -> list[float]:
    """Comma- or space-separated numbers, e.g. '0.1, 0.2 0.3' (ValueError if not)."""
    return [float(v) for v in text.replace(",", " ").split()]


def parse_points(text: str) -> list[float]:
    """'x1,y1,z1;x2,y2,z2' -> the flat list [x1, y1, z1, x2, y2, z2]."""
    return [v for chunk in text.split(";") for v in numbers(chunk)]
