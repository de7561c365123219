"""Critical points: their flat-list form (a parameter) and points chosen near a configuration."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ft_core.robots import Robot, TaskSpace
from ft_core.rotations import quaternion_from_rotation, rotation_from_quaternion
from ft_core.selfmotion.manifold import check_target


def point_size(robot: Robot) -> int:
    """Numbers per critical point in a flat list: m, or 7 (x, y, z, qx, qy, qz, qw) for pose."""
    return 7 if robot.task_space == TaskSpace.POSE else robot.m


def targets_from_flat(robot: Robot, flat: Sequence[float]) -> list[np.ndarray]:
    """Critical points from a flat list (the controller's `critical_points` parameter)."""
    values = np.asarray(flat, dtype=float)
    size = point_size(robot)
    if values.ndim != 1 or values.size % size:
        raise ValueError(f"critical points for a {robot.task_space} task need a multiple of "
                         f"{size} numbers, got {values.size}")
    if not np.all(np.isfinite(values)):
        raise ValueError("critical points must be finite")
    targets = []
    for chunk in values.reshape(-1, size):
        if robot.task_space != TaskSpace.POSE:
            targets.append(check_target(robot, chunk.copy()))
            continue
        quaternion = chunk[3:]
        with np.errstate(over="ignore"):  # 1e308: an infinite norm, refused
            norm = np.linalg.norm(quaternion)
        if not 0 < norm < np.inf:
            raise ValueError("a pose critical point's quaternion must be non-zero (and its "
                             "norm finite)")
        pose = np.eye(4)
        pose[:3, :3] = rotation_from_quaternion(quaternion)
        pose[:3, 3] = chunk[:3]
        targets.append(check_target(robot, pose))
    return targets


def flat_from_targets(robot: Robot, targets: Sequence[np.ndarray]) -> list[float]:
    """The flat list `targets_from_flat` reads: x, y(, z) or x, y, z, qx, qy, qz, qw each."""
    flat: list[float] = []
    for target in targets:
        target = np.asarray(target, dtype=float)
        if robot.task_space != TaskSpace.POSE:
            flat += [float(v) for v in target]
            continue
        flat += [float(v) for v in (*target[:3, 3], *quaternion_from_rotation(target[:3, :3]))]
    return flat


def bent_configuration(robot: Robot) -> np.ndarray:
    """A working configuration for an arm without a known home (rad).

    The middle of each joint's limits (0 for continuous joints), every joint then
    bent 0.4 rad, alternately up and down, and kept 0.1 rad inside its limits: away
    from the straight, singular zero pose most URDFs define. A built-in's home wins.
    """
    from ft_core.robots import HOME

    if robot.name in HOME and len(HOME[robot.name]) == robot.n:
        return robot.home()
    middle = np.where(np.isfinite(robot.lower) & np.isfinite(robot.upper),
                      0.5 * (robot.lower + robot.upper), 0.0)
    bend = 0.4 * np.where(np.arange(robot.n) % 2 == 0, 1.0, -1.0)
    return np.clip(middle + bend, robot.lower + 0.1, robot.upper - 0.1)


def points_around(robot: Robot, q: np.ndarray, count: int = 3, step: float | None = None,
                  ) -> list[np.ndarray]:
    """`count` task points the tool reaches near q.

    The tool at q, then with one more joint at a time moved by +-step rad (first
    joints first), kept inside the limits. Each point is reachable by construction
    (its configuration is given): critical points for a demo or a campaign on an arm
    nobody chose points for. The default step is 0.3 rad, or 0.15 for a pose task:
    its self-motion manifolds are thinner (a curve on a 7-joint arm), and the boxes
    of points 0.3 rad apart on the Panda do not all contain each point.
    """
    if step is None:
        step = 0.15 if robot.task_space == TaskSpace.POSE else 0.3
    points, moved = [robot.forward(q)], q.copy()
    for k in range(1, count):
        joint = (k - 1) % robot.n
        moved = moved.copy()
        moved[joint] += step if k % 2 else -step
        moved = np.clip(moved, robot.lower, robot.upper)
        points.append(robot.forward(moved))
    return points
