"""A traced self-motion manifold, Newton projection onto it and the walk's steps.

Lewis & Maciejewski 1997, secs. II-IV. The configurations that put the tool at a task
point x* form its self-motion manifold; `project` corrects a configuration onto it
(Newton, J+ (x* - x)), `null_basis` spans its tangent space, `Walker` takes the
null-space steps of the tracing (`ft_core.selfmotion.tracing`), landing exactly on
physical limits, and `find_seed` finds a first configuration on it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from ft_core import limits
from ft_core.errors import SuiteError
from ft_core.pseudoinverse import Damping, damped_pinv
from ft_core.robots import Robot, TaskSpace

#: Task error (m or rad) under which a configuration is on the manifold.
TOLERANCE = 1e-9
#: Default arc length (rad, in joint space) of one tracing step.
STEP = 0.02
#: Damping of the Newton steps (only near singular configurations).
NEWTON_DAMPING = Damping(threshold=1e-3, max_damping=1e-2)


class UnreachableError(SuiteError):
    """The task point cannot be reached (within the given joint bounds)."""


@dataclass(frozen=True)
class Manifold:
    """The traced connected component of a self-motion manifold.

    Attributes:
        robot: the robot it belongs to.
        target: the task point x* (as `Robot.forward` returns it).
        seed: the configuration the tracing started from (rad).
        paths: ordered samples (k, n) of each traced path; each starts at the seed or,
            for a branch followed from a crossing, next to an earlier path.
        method: "point", "curve", "spiral" or "extremal".
        step: the tracing step (rad).
        closed: a 1-D curve that came back to the seed.
    """

    robot: Robot
    target: np.ndarray
    seed: np.ndarray
    paths: tuple[np.ndarray, ...]
    method: str
    step: float = STEP
    closed: bool = False
    samples: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "samples", np.vstack(self.paths))

    @property
    def box(self) -> tuple[np.ndarray, np.ndarray]:
        """Per-joint (lower, upper) over the traced component, inside the physical limits.

        Angles are unwrapped along the paths; a joint without position limits whose
        span reaches a full turn (within two steps) is unbounded: (-inf, inf).
        """
        lower = np.maximum(self.samples.min(axis=0), self.robot.lower)
        upper = np.minimum(self.samples.max(axis=0), self.robot.upper)
        full = full_turn(self.robot, lower, upper, 2 * self.step)
        return np.where(full, -np.inf, lower), np.where(full, np.inf, upper)


def check_target(robot: Robot, target: np.ndarray) -> np.ndarray:
    """Return the target as an array of the task's shape, or raise ValueError."""
    target = np.asarray(target, dtype=float)
    shape = (4, 4) if robot.task_space == TaskSpace.POSE else (robot.m,)
    if target.shape != shape:
        raise ValueError(f"a {robot.task_space} target must have shape {shape}, got "
                         f"{target.shape}")
    if not np.all(np.isfinite(target)):
        raise ValueError("the target has non-finite entries")
    position = target[:3, 3] if robot.task_space == TaskSpace.POSE else target
    if not np.all(np.abs(position) <= limits.ABSURD_DISTANCE):
        raise ValueError(f"the target is further than {limits.ABSURD_DISTANCE:g} m: no arm's")
    return target


def project(robot: Robot, target: np.ndarray, q: np.ndarray, fixed: Iterable[int] = (),
            lower: np.ndarray | None = None, upper: np.ndarray | None = None,
            iterations: int = 100) -> np.ndarray | None:
    """Newton iteration onto the manifold of `target` from q, or None if it fails.

    Joints in `fixed` do not move. The others stay inside [lower, upper] (default:
    the physical limits): in each iteration, a joint that the step would push out
    is put on its bound and the step is solved again without it (an active set
    rebuilt every iteration, so a joint can leave its bound again).
    """
    lower = robot.lower if lower is None else lower
    upper = robot.upper if upper is None else upper
    movable = np.ones(robot.n, dtype=bool)
    movable[list(fixed)] = False
    q = np.array(q, dtype=float)
    for _ in range(iterations):
        error = robot.task_error(target, q)
        if np.linalg.norm(error) < TOLERANCE:
            return q
        J = robot.scale_task(robot.jacobian(q))
        e = robot.task_scale * error
        free = movable.copy()
        while True:
            moved = q + damped_pinv(J * free, NEWTON_DAMPING) @ e
            out = free & ((moved < lower) | (moved > upper))
            if not out.any():
                break
            free &= ~out
            q = np.where(out, np.clip(moved, lower, upper), q)
        q = moved
    return q if np.linalg.norm(robot.task_error(target, q)) < TOLERANCE else None


def null_basis(robot: Robot, q: np.ndarray, free: np.ndarray | None = None) -> np.ndarray:
    """Orthonormal basis (n, k) of the joint motions in the free joints that keep the task.

    With every joint free, k = n - m (the tangent space of the manifold).
    """
    J = robot.scale_task(robot.jacobian(q))
    if free is None or free.all():
        return np.linalg.svd(J)[2][robot.m:].T
    columns = np.flatnonzero(free)
    basis = np.zeros((robot.n, max(columns.size - robot.m, 0)))
    if basis.shape[1]:
        basis[columns] = np.linalg.svd(J[:, columns])[2][robot.m:].T
    return basis


class Walker:
    """Null-space steps from a configuration, landing exactly on physical limits."""

    def __init__(self, robot: Robot, target: np.ndarray):
        self.robot, self.target = robot, target

    def advance(self, q: np.ndarray, step: np.ndarray,
                pinned: np.ndarray) -> tuple[np.ndarray | None, int | None]:
        """Take `step` and correct drift; return (new q or None, joint whose limit was met)."""
        robot = self.robot
        moved = q + step
        hit = None
        crossing = (moved < robot.lower) | (moved > robot.upper)
        if crossing.any():
            bound = np.where(step < 0, robot.lower, robot.upper)
            with np.errstate(divide="ignore", invalid="ignore"):
                fraction = np.where(crossing, (bound - q) / step, np.inf)
            hit = int(np.argmin(fraction))
            moved = q + max(float(fraction[hit]), 0.0) * step
            moved[hit] = bound[hit]
        fixed = np.flatnonzero(pinned).tolist() + ([hit] if hit is not None else [])
        return project(robot, self.target, moved, fixed=fixed), hit


def unlimited_joints(robot: Robot) -> np.ndarray:
    """Joints without position limits (angles taken modulo 2 pi)."""
    return ~np.isfinite(robot.lower) | ~np.isfinite(robot.upper)


def full_turn(robot: Robot, lower: np.ndarray, upper: np.ndarray,
              slack: float = 0.0) -> np.ndarray:
    """Joints without limits whose unwrapped span covers a full turn (less `slack`)."""
    return unlimited_joints(robot) & (upper - lower >= 2 * math.pi - slack)


def wrapped_distance(robot: Robot, a: np.ndarray, b: np.ndarray) -> float:
    """Joint-space distance, modulo 2 pi for joints without position limits."""
    difference = a - b
    continuous = unlimited_joints(robot)
    difference[continuous] = (difference[continuous] + np.pi) % (2 * np.pi) - np.pi
    return float(np.linalg.norm(difference))


def near(robot: Robot, samples: np.ndarray, q: np.ndarray, distance: float) -> bool:
    """Whether q is within `distance` of a sample (modulo 2 pi for joints without limits)."""
    difference = samples - q
    continuous = unlimited_joints(robot)
    difference[:, continuous] = (difference[:, continuous] + np.pi) % (2 * np.pi) - np.pi
    return bool(np.min(np.linalg.norm(difference, axis=1)) < distance)



def find_seed(robot: Robot, target: np.ndarray, q_start: np.ndarray | None = None,
              lower: np.ndarray | None = None, upper: np.ndarray | None = None,
              attempts: int = 30, seed: int = 0) -> np.ndarray:
    """A configuration reaching `target` inside [lower, upper] (default: the physical limits).

    Newton from `q_start` (default: the middle of the limits), then from seeded random
    configurations inside the bounds. Joints without limits come back in [-pi, pi).
    Raises UnreachableError when none converges.
    """
    target = check_target(robot, target)
    lower = robot.lower if lower is None else np.asarray(lower, dtype=float)
    upper = robot.upper if upper is None else np.asarray(upper, dtype=float)
    if np.any(lower > upper):
        raise UnreachableError(f"the joint bounds are empty for joints "
                               f"{np.flatnonzero(lower > upper).tolist()}")
    finite_lower = np.where(np.isfinite(lower), lower, -math.pi)
    finite_upper = np.where(np.isfinite(upper), upper, math.pi)
    rng = np.random.default_rng(seed)
    starts = [] if q_start is None else [np.clip(np.asarray(q_start, float), lower, upper)]
    starts.append((finite_lower + finite_upper) / 2)
    starts += [rng.uniform(finite_lower, finite_upper) for _ in range(attempts)]
    continuous = unlimited_joints(robot)
    for start in starts:
        q = project(robot, target, start, lower=lower, upper=upper)
        if q is not None:
            q[continuous] = (q[continuous] + math.pi) % (2 * math.pi) - math.pi
            return q
    raise UnreachableError(
        f"task point {np.round(target, 4).tolist()} is out of reach within the joint bounds "
        f"({len(starts)} attempts)")


