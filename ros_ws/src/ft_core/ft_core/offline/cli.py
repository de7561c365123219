"""What the `ft-*` command-line tools share: model arguments, bounded numbers, file errors.

Every tool that works on an arm takes the model the way the nodes do: `--robot`
(a built-in name or a URDF path), `--base-link`, `--tip-link` and `--task`.

Every number a tool takes has a documented bound, checked where it comes in:
`bounded` for one number (argparse refuses it with exit status 2 and says the range),
`numbers` for a list (finite, at most `MAX_NUMBERS`). An option that takes a list refuses
an empty value as a usage error (`nonempty`, exit status 2): leaving the option out is how
a default is asked for. A file that cannot be written is one line and exit status 1
(`clear_file_errors`; `check_file` and `check_folder` find it before the work), never a
traceback.
"""

from __future__ import annotations

import argparse
import functools
import math
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ft_core import limits, robots

#: Most numbers one list argument may hold.
MAX_NUMBERS = 4096
#: Most worker processes a tool starts.
MAX_WORKERS = 256
#: Random seeds: numpy's range.
MAX_SEED = 2**32 - 1
#: Tracing steps (rad) along a self-motion manifold (`selfmotion.STEP` by default):
#: finer costs memory and time without bound, coarser jumps between components.
STEP_RANGE = (1e-4, 0.5)


def add_model_arguments(parser: argparse.ArgumentParser, robot: str | None = None,
                        task: str | None = None,
                        tasks: Sequence[str] = tuple(sorted(map(str, robots.TaskSpace))),
                        ) -> None:
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
        robots.RobotModelError: the model cannot be loaded, or has fewer joints than
            task coordinates (`trackable`).
    """
    return trackable(robots.load(args.robot, args.base_link or None, args.tip_link or None,
                                 task_space=args.task))


def trackable(robot: robots.Robot) -> robots.Robot:
    """`robot`, if it has at least as many joints as task coordinates, else RobotModelError.

    Fewer cannot follow the task at all (a URDF with a single joint and the default pose
    task, say); the tools' array shapes assume n >= m.
    """
    if robot.n < robot.m:
        raise robots.RobotModelError(
            f"{robot.name} has {robot.n} joint(s) for a {robot.task_space} task of {robot.m} "
            "coordinates: it cannot follow it (another --task, or a longer chain)")
    return robot


def numbers(text: str) -> list[float]:
    """Comma- or space-separated finite numbers, e.g. '0.1, 0.2 0.3'.

    Raises ValueError for anything else, a non-finite value or more than `MAX_NUMBERS`.
    """
    words = text.replace(",", " ").split()
    if len(words) > MAX_NUMBERS:
        raise ValueError(f"{len(words)} numbers in one argument (at most {MAX_NUMBERS})")
    values = [float(v) for v in words]
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"non-finite number in {text[:80]!r}")
    return values


def nonempty(text: str) -> str:
    """An argparse type: `text` unchanged if it holds a value, else a usage error.

    Values are the words left once ',', ';' and blanks are taken out: '', ' ' and ';'
    hold none. The tool parses the words itself (`numbers`, `parse_points`); an optional
    list option left out takes its default, given empty it is refused.
    """
    if not text.replace(",", " ").replace(";", " ").split():
        raise argparse.ArgumentTypeError(f"no number in {text[:80]!r}")
    return text


def bounded(kind: type[int] | type[float], low: float, high: float,
            ) -> Callable[[str], int | float]:
    """An argparse type: a `kind` number in [low, high], else a usage error naming the range."""
    def parse(text: str) -> int | float:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not {'an integer' if kind is int else 'a number'}"
                                             f": {text[:80]!r}") from None
        if not low <= value <= high:  # also refuses nan
            shown = f"[{low}, {high}]" if kind is int else f"[{low:g}, {high:g}]"
            raise argparse.ArgumentTypeError(f"{text[:80]} is outside {shown}")
        return value

    parse.__name__ = kind.__name__  # argparse names the type in its messages
    parse.bounds = (low, high)  # type: ignore[attr-defined]  # for the tests: documented
    return parse


def tracing_step() -> dict:
    """`add_argument` keywords of `--step`, a tracing step in `STEP_RANGE` (rad)."""
    from ft_core.selfmotion import STEP

    return {"type": bounded(float, *STEP_RANGE), "default": STEP,
            "help": f"tracing step (rad, {STEP_RANGE[0]:g} to {STEP_RANGE[1]:g}), "
                    "default %(default)s"}


def workers(default: int) -> dict:
    """`add_argument` keywords of a worker-process count: 1 to `MAX_WORKERS`."""
    return {"type": bounded(int, 1, MAX_WORKERS), "default": default}


#: Largest input file a tool reads (bytes; `ft_core.files`).
MAX_FILE_BYTES = 1_000_000


def check_folder(path: Path) -> None:
    """Raise OSError now if `path` cannot be made a folder, before the tool's work.

    A file in the way (at `path` or above it) or a folder that cannot be written;
    nothing is created, so a run refused later leaves nothing behind.
    """
    for existing in (path, *path.parents):
        if not existing.exists():
            continue
        if not existing.is_dir():
            raise NotADirectoryError(f"{existing} is a file, not a folder")
        if not os.access(existing, os.W_OK):
            raise PermissionError(f"{existing} cannot be written")
        return


def check_file(path: Path) -> None:
    """Raise OSError now if `path` cannot be written as a file, before the tool's work.

    Its folder must exist, the path must not name a folder, and the file must open for
    writing: the probe opens it for appending (an existing file keeps its content, a new
    one is removed again), without waiting for a reader if it is a FIFO.
    """
    if path.is_dir():
        raise IsADirectoryError(f"{path} is a folder, not a file")
    if not path.parent.exists():
        raise FileNotFoundError(f"{path.parent}: no such folder")
    if not path.parent.is_dir():
        raise NotADirectoryError(f"{path.parent} is a file, not a folder")
    existed = path.exists()
    os.close(os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NONBLOCK, 0o666))
    if not existed:
        path.unlink()


def clear_file_errors(prog: str) -> Callable[[Callable[..., int]], Callable[..., int]]:
    """Decorate a tool's `main`: a file it cannot read or write is one line, exit status 1.

    (A read-only folder, an output path naming a folder or a file in the way.) And
    Ctrl-C is one line too, exit status 130 (its workers end quietly: `workers.SPAWN`).
    """
    def wrap(main: Callable[..., int]) -> Callable[..., int]:
        @functools.wraps(main)
        def run(*args, **kwargs) -> int:
            try:
                return main(*args, **kwargs)
            except OSError as error:
                print(f"{prog}: {error}", file=sys.stderr)
                return 1
            except KeyboardInterrupt:
                print(f"\n{prog}: interrupted", file=sys.stderr)
                return 130

        return run

    return wrap


def configuration(text: str, robot: robots.Robot, option: str) -> np.ndarray:
    """A joint configuration 'q1,...,qn' (rad) for `robot`, or ValueError naming `option`.

    n finite values, none physically absurd (`limits.absurd_position`: more than 1 rad
    outside the joint's limits).
    """
    q = np.array(numbers(text))
    if q.shape != (robot.n,):
        raise ValueError(f"{option} needs {robot.n} joint values, got {q.size}")
    absurd = limits.absurd_position(q, robot.lower, robot.upper, robot.joint_names)
    if absurd is not None:
        raise ValueError(f"{option}: {absurd}")
    return q


def parse_points(text: str) -> list[float]:
    """'x1,y1,z1;x2,y2,z2' -> the flat list [x1, y1, z1, x2, y2, z2]."""
    return [v for chunk in text.split(";") for v in numbers(chunk)]
