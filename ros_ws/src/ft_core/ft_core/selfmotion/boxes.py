"""Bounding boxes of self-motion manifolds, their intersection, and soft limits.

Lewis & Maciejewski 1997 sec. III: the box of each critical point's manifold (per
joint, min and max over it), their intersection as soft limits, and the check that
every point is still reachable inside it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from ft_core.robots import Robot
from ft_core.selfmotion.critical_points import targets_from_flat
from ft_core.selfmotion.manifold import STEP, Manifold, UnreachableError, find_seed
from ft_core.selfmotion.tracing import trace


def bounding_box(robot: Robot, x_target: np.ndarray,
                 q_seed: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per-joint (lower, upper) of the manifold component of x_target through q_seed."""
    return trace(robot, x_target, q_seed).box


def box_volume(robot: Robot, lower: np.ndarray, upper: np.ndarray,
               joints: Sequence[int] | None = None, normalized: bool = True) -> float:
    """Volume of a box over `joints` (default all).

    Normalized (Lewis & Maciejewski 1997, end of sec. V): each side divided by its joint's range,
    so 1 is the whole joint space (a joint without limits has range 2 pi).
    Otherwise in rad^k (as Lewis & Maciejewski 1997 Table II).
    """
    joints = list(range(robot.n)) if joints is None else list(joints)
    sides = np.maximum(np.asarray(upper) - np.asarray(lower), 0.0)[joints]
    if not normalized:
        return float(np.prod(sides))
    ranges = (robot.upper - robot.lower)[joints]
    ranges = np.where(np.isfinite(ranges), ranges, 2 * math.pi)
    return float(np.prod(np.minimum(sides / ranges, 1.0)))


def intersect(boxes: Iterable[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Intersection of boxes; joints where lower > upper make it empty (`empty_joints`)."""
    boxes = list(boxes)
    if not boxes:
        raise ValueError("intersect needs at least one box")
    lower = np.max([np.asarray(b[0], dtype=float) for b in boxes], axis=0)
    upper = np.min([np.asarray(b[1], dtype=float) for b in boxes], axis=0)
    return lower, upper


def empty_joints(box: tuple[np.ndarray, np.ndarray]) -> list[int]:
    """Indices of joints whose range in the box is empty."""
    return np.flatnonzero(box[0] > box[1]).tolist()


def reachability(robot: Robot, targets: Sequence[np.ndarray], lower: np.ndarray,
                 upper: np.ndarray, q_start: np.ndarray | None = None,
                 ) -> list[np.ndarray | None]:
    """For each target a configuration inside [lower, upper] reaching it, or None.

    Lewis & Maciejewski 1997 sec. III, step five: check that every critical point is still
    reachable under the intersected soft limits.
    """
    found: list[np.ndarray | None] = []
    for target in targets:
        try:
            found.append(find_seed(robot, target, q_start, lower, upper))
        except UnreachableError:
            found.append(None)
    return found



@dataclass(frozen=True)
class CriticalBoxes:
    """The bounding boxes of critical points and their intersection.

    Lewis & Maciejewski 1997 sec. III.

    Attributes:
        manifolds: each point's traced component (steps 1-2).
        lower: the intersection's lower bounds (rad, step 3).
        upper: the intersection's upper bounds (rad).
        empty: joints on which the boxes do not intersect.
        unreachable: 1-based numbers of the points that cannot be reached inside the
            intersection (steps 4-5; not checked when `empty`).
    """

    manifolds: tuple[Manifold, ...]
    lower: np.ndarray
    upper: np.ndarray
    empty: tuple[int, ...]
    unreachable: tuple[int, ...]


def critical_boxes(robot: Robot, targets: Sequence[np.ndarray], q: np.ndarray,
                   step: float = STEP,
                   progress: Callable[[int, str], None] | None = None) -> CriticalBoxes:
    """Trace each critical point from the configuration nearest q, box, intersect, check.

    The pipeline of Lewis & Maciejewski 1997 sec. III shared by the controller and `ft-bounds`.
    `progress(point index, text)` is called before each point ("") and while tracing.
    Raises UnreachableError ("point k: ...") when a point is out of reach.
    """
    manifolds = []
    for index, target in enumerate(targets):
        if progress:
            progress(index, "")
        report = None if progress is None else (lambda text, i=index: progress(i, text))
        try:
            manifolds.append(trace(robot, target, find_seed(robot, target, q), step,
                                   progress=report))
        except UnreachableError as error:
            raise UnreachableError(f"point {index + 1}: {error}") from error
    lower, upper = intersect(m.box for m in manifolds)
    empty = tuple(empty_joints((lower, upper)))
    unreachable = () if empty else tuple(
        i + 1 for i, found in enumerate(reachability(robot, targets, lower, upper, q))
        if found is None)
    return CriticalBoxes(tuple(manifolds), lower, upper, empty, unreachable)


#: Most traced configurations kept per critical point as recovery seeds (`SoftLimits`).
MAX_SEEDS = 256


@dataclass(frozen=True)
class SoftLimits:
    """Soft limits from critical points, and what their tracing leaves for later.

    Attributes:
        box: (lower, upper) of the intersected boxes (rad).
        targets: the critical points (as `Robot.forward` returns them).
        traced: for each point, up to `MAX_SEEDS` configurations of its traced component,
            evenly spread over it (k, n; rad): seeds for inverse kinematics of that point
            after a lock (`recovery.solutions`).
    """

    box: tuple[np.ndarray, np.ndarray]
    targets: tuple[np.ndarray, ...]
    traced: tuple[np.ndarray, ...]


def soft_limits(robot: Robot, flat: list[float], q: np.ndarray) -> SoftLimits:
    """Critical points -> intersected self-motion boxes -> soft limits and traced seeds.

    Lewis & Maciejewski 1997 sec. III (`critical_boxes`). Raises UnreachableError when a
    point is out of reach, the boxes do not intersect or a point cannot be reached inside the
    intersection. Slow (0.1 to a few seconds): run it off the control loop:
    `soft_limits_for_model` in another process.
    """
    targets = targets_from_flat(robot, flat)
    boxes = critical_boxes(robot, targets, q)
    if boxes.empty:
        raise UnreachableError(
            f"the boxes do not intersect on {[robot.joint_names[j] for j in boxes.empty]}")
    if boxes.unreachable:
        raise UnreachableError(f"critical points {list(boxes.unreachable)} cannot be reached "
                               "inside the intersection")
    traced = tuple(m.samples[np.unique(np.linspace(0, len(m.samples) - 1, MAX_SEEDS).astype(int))]
                   for m in boxes.manifolds)
    return SoftLimits((boxes.lower, boxes.upper), tuple(targets), traced)


def soft_limits_for_model(spec: str, chain: Sequence, flat: list[float], q: np.ndarray,
                          ) -> SoftLimits:
    """`soft_limits` for a model given as `robots.load(spec, *chain)`: picklable arguments.

    For a worker process. A thread would not do: the tracing makes thousands of
    short calls that release the GIL, and a busy control loop in the same process
    takes it back each time, so a 1 s computation took 15-25 s beside it.
    """
    from ft_core import robots

    return soft_limits(robots.load(spec, *chain), flat, q)


