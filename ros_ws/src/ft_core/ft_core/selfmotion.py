"""Self-motion manifolds of critical task points and their bounding boxes.

Lewis & Maciejewski 1997, secs. II-IV.

The configurations that put the tool at a task point x* form the self-motion
manifold of x*, of dimension r = n - m; the null space of J is its tangent space.
If a joint locks anywhere inside the manifold's bounding box (per joint, min and
max over the manifold), some configuration of the manifold still has that joint
at that value, so the reduced robot can still reach x* (Lewis & Maciejewski 1997 sec. II-III).

Tracing starts at a seed configuration and never leaves its connected component:
every path starts at the seed and moves by small null-space steps, each followed
by Newton drift correction J+ (x* - x) (`project`). Components found from other
starting points are never merged (Lewis & Maciejewski 1997, end of sec. IV).

- r = 1: the curve is followed both ways until it closes or meets a physical limit.
  Where it passes a singular configuration (smallest singular value of J below
  `BRANCH_SIGMA`, a local minimum along the curve), branches of the manifold may
  cross: from points around it in the 2-D near-null space of J, projected onto the
  manifold, every branch not traced yet is followed too (at most `MAX_BRANCHES`).
  They are connected to the seed's branch through the crossing, so they belong to
  its component. Without this, the planar 3R at (1, 0) traced from the seed
  `find_seed` gives (on the folded branch q3 = pi, where joint 2 turns freely)
  yields a box of normalised volume 1e-29, where the component spans every joint's
  full circle (Lewis & Maciejewski 1997 sec. II).
- r = 2: the spiral of Lewis & Maciejewski 1997 eqs 6-7, phi' = v / r, r = gamma phi, with
  theta' = sin(phi) v1 + cos(phi) v2 + J+ (x* - x). Reading taken for eqs 8-9
  (the extraction garbles eq 9): the new null-space basis is the rotation of the
  current one nearest the previous basis, computed exactly by the orthogonal
  Procrustes solution. The spiral stops after a full turn that widens no bound;
  the extremal walks below then polish each bound from the spiral's extreme sample.
- r > 2: the extremal iteration of eq 10, theta' = +-(I - J+ J) e_i + J+ (x* - x),
  per joint and direction, until the tangent space turns orthogonal to e_i. As the
  paper says, a local method: it may stop at a local extremum and underestimate.
  So for r >= 2, before the extremal walks, 2n walks in seeded random null-space
  directions (each direction carried along as the tangent space turns) explore the
  component first, and the extremal walks start from the extremes they found. On
  the Panda's position task this widened joint 5's range at a critical point from
  [-0.79, 2.9] to [-2.89, 2.9] rad. Every sample is still on the manifold and
  reached from the seed, so boxes can only grow towards the true ranges.

A physical limit met on the way is landed on exactly and then held (the joint
is pinned while the walk continues on the rest), so boxes are clipped to the
physical limits. Every path keeps its samples in order: consecutive samples are
neighbours on the manifold, which `recovery_configuration` interpolates.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ft_core import limits
from ft_core.pseudoinverse import Damping, damped_pinv
from ft_core.robots import Robot

#: Task error (m or rad) under which a configuration is on the manifold.
TOLERANCE = 1e-9
#: Default arc length (rad, in joint space) of one tracing step.
STEP = 0.02
#: Distance (rad) between successive turns of the spiral (r = 2); the extremal walks
#: that follow polish every bound, so the spiral only has to come near each extreme.
SPIRAL_SPACING = 0.3
#: The spiral explores with steps this many times `step` (Newton corrects the drift).
SPIRAL_STEP_FACTOR = 3
#: Steps of each random exploration walk (r >= 2).
EXPLORE_LENGTH = 300
#: Rounds of extremal walks (r >= 2).
EXTREMAL_ROUNDS = 2
#: Smallest singular value of J (m/rad) below which a curve's local minimum is a crossing.
BRANCH_SIGMA = 0.05
#: Most branches followed from crossings per trace (r = 1).
MAX_BRANCHES = 8
#: Directions tried around a crossing, and how far out (in tracing steps).
BRANCH_DIRECTIONS, BRANCH_OFFSET = 8, 5
#: Damping of the Newton steps (only near singular configurations).
NEWTON_DAMPING = Damping(threshold=1e-3, max_damping=1e-2)


class UnreachableError(ValueError):
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
        full = _full_turn(self.robot, lower, upper, 2 * self.step)
        return np.where(full, -np.inf, lower), np.where(full, np.inf, upper)


def check_target(robot: Robot, target: np.ndarray) -> np.ndarray:
    """Return the target as an array of the task's shape, or raise ValueError."""
    target = np.asarray(target, dtype=float)
    shape = (4, 4) if robot.task_space == "pose" else (robot.m,)
    if target.shape != shape:
        raise ValueError(f"a {robot.task_space} target must have shape {shape}, got "
                         f"{target.shape}")
    if not np.all(np.isfinite(target)):
        raise ValueError("the target has non-finite entries")
    position = target[:3, 3] if robot.task_space == "pose" else target
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


class _Walker:
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


def _continuous(robot: Robot) -> np.ndarray:
    """Joints without position limits (angles taken modulo 2 pi)."""
    return ~np.isfinite(robot.lower) | ~np.isfinite(robot.upper)


def _full_turn(robot: Robot, lower: np.ndarray, upper: np.ndarray,
               slack: float = 0.0) -> np.ndarray:
    """Joints without limits whose unwrapped span covers a full turn (less `slack`)."""
    return _continuous(robot) & (upper - lower >= 2 * math.pi - slack)


def _wrapped_distance(robot: Robot, a: np.ndarray, b: np.ndarray) -> float:
    """Joint-space distance, modulo 2 pi for joints without position limits."""
    difference = a - b
    continuous = _continuous(robot)
    difference[continuous] = (difference[continuous] + np.pi) % (2 * np.pi) - np.pi
    return float(np.linalg.norm(difference))


def _curve(walker: _Walker, seed: np.ndarray, step: float,
           max_steps: int) -> tuple[list[np.ndarray], bool]:
    """Follow a 1-D manifold both ways from the seed (until it closes or meets a limit)."""
    robot = walker.robot
    paths = []
    pinned = np.zeros(robot.n, dtype=bool)
    initial = null_basis(robot, seed)[:, 0]
    for sign in (1.0, -1.0):
        q, previous, path = seed, sign * initial, [seed]
        for count in range(max_steps):
            tangent = null_basis(robot, q)[:, 0]
            tangent = tangent if tangent @ previous >= 0 else -tangent
            moved, hit = walker.advance(q, step * tangent, pinned)
            if moved is None:
                break
            path.append(moved)
            if hit is not None:
                break
            if count > 3 and _wrapped_distance(robot, moved, seed) < 0.75 * step:
                return [np.array(path)], True
            q, previous = moved, tangent
        paths.append(np.array(path))
    return paths, False


def near(robot: Robot, samples: np.ndarray, q: np.ndarray, distance: float) -> bool:
    """Whether q is within `distance` of a sample (modulo 2 pi for joints without limits)."""
    difference = samples - q
    continuous = _continuous(robot)
    difference[:, continuous] = (difference[:, continuous] + np.pi) % (2 * np.pi) - np.pi
    return bool(np.min(np.linalg.norm(difference, axis=1)) < distance)


def _crossings(robot: Robot, path: np.ndarray) -> list[np.ndarray]:
    """Samples of a path where branches of the manifold may cross (see the module notes)."""
    sigma = np.array([np.linalg.svd(robot.scale_task(robot.jacobian(q)), compute_uv=False)[-1]
                      for q in path])
    padded = np.concatenate([[np.inf], sigma, [np.inf]])
    minima = (sigma < BRANCH_SIGMA) & (sigma <= padded[:-2]) & (sigma <= padded[2:])
    return [path[k] for k in np.flatnonzero(minima)]


def _branches(walker: _Walker, paths: list[np.ndarray], step: float,
              max_steps: int) -> list[np.ndarray]:
    """The curves through the crossings on `paths` not traced yet, followed in turn."""
    robot = walker.robot
    found, queue = list(paths), list(paths)
    while queue:
        for crossing in _crossings(robot, queue.pop(0)):
            near_null = np.linalg.svd(robot.scale_task(robot.jacobian(crossing)))[2][
                robot.m - 1:robot.m + 1]
            for angle in np.linspace(0, 2 * math.pi, BRANCH_DIRECTIONS, endpoint=False):
                offset = BRANCH_OFFSET * step * (math.cos(angle) * near_null[0]
                                                 + math.sin(angle) * near_null[1])
                start = project(robot, walker.target, crossing + offset)
                if start is None or near(robot, np.vstack(found), start, 2 * step):
                    continue
                branch, _ = _curve(walker, start, step, max_steps)
                found += branch
                queue += branch
                if len(found) - len(paths) >= MAX_BRANCHES:
                    return found
    return found


def _extremal(walker: _Walker, start: np.ndarray, joint: int, sign: float, step: float,
              max_steps: int) -> np.ndarray:
    """Along the null-space projection of +-e_joint to its extremum (Lewis & Maciejewski eq 10)."""
    robot = walker.robot
    q, path = start, [start]
    pinned = np.zeros(robot.n, dtype=bool)
    turn = 2 * math.pi if _continuous(robot)[joint] else math.inf
    for _ in range(max_steps):
        if abs(q[joint] - start[joint]) >= turn:
            break  # a joint without limits has gone all the way round
        basis = null_basis(robot, q, ~pinned)
        if not basis.shape[1]:
            break
        direction = sign * basis @ basis[joint]  # projection of sign * e_joint
        size = np.linalg.norm(direction)
        if size < 1e-6 or abs(direction[joint]) < 1e-6 * size:
            break  # the tangent space is orthogonal to e_joint: an extremum
        moved, hit = walker.advance(q, step * direction / size, pinned)
        if moved is None or sign * (moved[joint] - q[joint]) <= 1e-12:
            break
        path.append(moved)
        q = moved
        if hit is not None:
            if hit == joint:
                break  # the extremum is the physical limit
            pinned[hit] = True
    return np.array(path)


def _explore(walker: _Walker, seed: np.ndarray, step: float, walks: int, length: int,
             rng: np.random.Generator) -> list[np.ndarray]:
    """Walks from the seed in random null-space directions, kept as the tangent space turns."""
    robot = walker.robot
    paths = []
    pinned = np.zeros(robot.n, dtype=bool)
    for _ in range(walks):
        q, path = seed, [seed]
        basis = null_basis(robot, q)
        direction = basis @ rng.normal(size=basis.shape[1])
        for _ in range(length):
            basis = null_basis(robot, q)
            direction = basis @ (basis.T @ direction)
            size = np.linalg.norm(direction)
            if size < 1e-6:
                break
            direction /= size
            moved, hit = walker.advance(q, step * direction, pinned)
            if moved is None:
                break
            path.append(moved)
            q = moved
            if hit is not None:
                break
        paths.append(np.array(path))
    return paths


def _nearest_rotation(basis: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """The basis of span(basis) nearest `previous` (orthogonal Procrustes): eqs 8-9."""
    U, _, Vt = np.linalg.svd(basis.T @ previous)
    return basis @ (U @ Vt)


def _spiral(walker: _Walker, seed: np.ndarray, step: float, spacing: float,
            max_steps: int) -> np.ndarray:
    """A spiral of growing radius from the seed on a 2-D manifold (Lewis & Maciejewski eqs 6-7)."""
    robot = walker.robot
    gamma = spacing / (2 * math.pi)
    phi = 2 * math.pi  # start one turn out: radius `spacing`
    basis = null_basis(robot, seed)
    q, path = seed, [seed]
    lower, upper = seed.copy(), seed.copy()
    last_growth = phi
    pinned = np.zeros(robot.n, dtype=bool)
    for _ in range(max_steps):
        direction = math.sin(phi) * basis[:, 0] + math.cos(phi) * basis[:, 1]
        moved, _ = walker.advance(q, step * direction, pinned)
        if moved is not None:
            q = moved
            path.append(q)
            basis = _nearest_rotation(null_basis(robot, q), basis)
            widened = (q < lower - 0.1 * step) | (q > upper + 0.1 * step)
            if np.any(widened & ~_full_turn(robot, lower, upper)):
                last_growth = phi
            lower, upper = np.minimum(lower, q), np.maximum(upper, q)
        phi += step / (gamma * phi)
        if phi - last_growth > 2 * math.pi:
            break  # a whole turn without widening any bound
    return np.array(path)


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
    continuous = _continuous(robot)
    for start in starts:
        q = project(robot, target, start, lower=lower, upper=upper)
        if q is not None:
            q[continuous] = (q[continuous] + math.pi) % (2 * math.pi) - math.pi
            return q
    raise UnreachableError(
        f"task point {np.round(target, 4).tolist()} is out of reach within the joint bounds "
        f"({len(starts)} attempts)")


def trace(robot: Robot, target: np.ndarray, q_seed: np.ndarray | None = None,
          step: float = STEP, max_steps: int = 20000,
          progress: Callable[[str], None] | None = None) -> Manifold:
    """Trace the connected component of the self-motion manifold of `target` through q_seed.

    Without q_seed, `find_seed` looks for one (raising UnreachableError if none).
    A given seed is first corrected onto the manifold; it must already be close.
    """
    target = check_target(robot, target)
    if q_seed is None:
        seed = find_seed(robot, target)
    else:
        projected = project(robot, target, np.asarray(q_seed, dtype=float))
        if projected is None:
            raise UnreachableError("the seed configuration does not reach the target")
        seed = projected
    walker = _Walker(robot, target)
    r = robot.n - robot.m
    if r <= 0:
        return Manifold(robot, target, seed, (seed[None],), "point", step)
    if r == 1:
        curve, closed = _curve(walker, seed, step, max_steps)
        return Manifold(robot, target, seed, tuple(_branches(walker, curve, step, max_steps)),
                        "curve", step, closed)
    paths: list[np.ndarray] = []
    method = "extremal"
    if r == 2:
        method = "spiral"
        paths.append(_spiral(walker, seed, SPIRAL_STEP_FACTOR * step, SPIRAL_SPACING,
                             max_steps))
    paths += _explore(walker, seed, step, 2 * robot.n, EXPLORE_LENGTH, np.random.default_rng(0))
    # Each walk starts from the most extreme sample found so far (on an earlier path,
    # so the traced set stays connected); a second round lets walks that stopped at a
    # local extremum continue from better places found by the others.
    for _ in range(EXTREMAL_ROUNDS):
        for joint in range(robot.n):
            for sign in (1.0, -1.0):
                if progress:
                    progress(f"joint {joint + 1} {'max' if sign > 0 else 'min'}")
                samples = np.vstack(paths) if paths else seed[None]
                start = samples[np.argmax(sign * samples[:, joint])]
                paths.append(_extremal(walker, start, joint, sign, step, max_steps // 10))
    return Manifold(robot, target, seed, tuple(paths), method, step)


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


def recovery_configuration(manifold: Manifold, joint: int, value: float) -> np.ndarray:
    """A configuration on the manifold with q[joint] = value (joint locked at `value`).

    Interpolates between the consecutive traced samples that straddle `value` and
    corrects onto the manifold with the joint held at `value`: from it the reduced
    robot reaches the target exactly. Raises ValueError when `value` is outside
    the manifold's range for that joint.
    """
    robot = manifold.robot
    candidates = []
    for path in manifold.paths:
        values = path[:, joint] - value
        for k in np.flatnonzero(values[:-1] * values[1:] <= 0):
            a, b = path[k], path[k + 1]
            span = b[joint] - a[joint]
            t = 0.0 if span == 0 else (value - a[joint]) / span
            candidates.append(a + t * (b - a))
    exact = np.flatnonzero(np.abs(manifold.samples[:, joint] - value) < 1e-12)
    candidates += [manifold.samples[k] for k in exact]
    for candidate in candidates:
        candidate = candidate.copy()
        candidate[joint] = value
        q = project(robot, manifold.target, candidate, fixed=[joint])
        if q is not None:
            return q
    lower, upper = manifold.box
    raise ValueError(f"joint {joint} at {value:.4f} is outside the manifold's range "
                     f"[{lower[joint]:.4f}, {upper[joint]:.4f}] or no sample pair "
                     "straddling it could be corrected")


def recover(manifold: Manifold, q: np.ndarray, joint: int) -> np.ndarray | None:
    """Drive the robot with `joint` locked at q[joint] back to the manifold's target.

    Inside the manifold's range for that joint, the other joints move in a straight
    line (inside the limits, which are a box) to `recovery_configuration`, where
    the target is reached exactly: the guarantee of Lewis & Maciejewski 1997 sec. III. Otherwise
    nothing guarantees success: the reduced Jacobian's closed loop (Newton on the
    healthy joints, inside the limits) runs from q and may stop short. Returns the
    final configuration, or None when the target was not reached.
    """
    q = np.asarray(q, dtype=float)
    try:
        return recovery_configuration(manifold, joint, float(q[joint]))
    except ValueError:
        return project(manifold.robot, manifold.target, q, fixed=[joint], iterations=300)


def point_size(robot: Robot) -> int:
    """Numbers per critical point in a flat list: m, or 7 (x, y, z, qx, qy, qz, qw) for pose."""
    return 7 if robot.task_space == "pose" else robot.m


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
        if robot.task_space != "pose":
            targets.append(check_target(robot, chunk.copy()))
            continue
        quaternion = chunk[3:]
        with np.errstate(over="ignore"):  # 1e308: an infinite norm, refused
            norm = np.linalg.norm(quaternion)
        if not 0 < norm < np.inf:
            raise ValueError("a pose critical point's quaternion must be non-zero (and its "
                             "norm finite)")
        pose = np.eye(4)
        pose[:3, :3] = pin.Quaternion(*(quaternion[[3, 0, 1, 2]] / norm)).toRotationMatrix()
        pose[:3, 3] = chunk[:3]
        targets.append(check_target(robot, pose))
    return targets


def flat_from_targets(robot: Robot, targets: Sequence[np.ndarray]) -> list[float]:
    """The flat list `targets_from_flat` reads: x, y(, z) or x, y, z, qx, qy, qz, qw each."""
    flat: list[float] = []
    for target in targets:
        target = np.asarray(target, dtype=float)
        if robot.task_space != "pose":
            flat += [float(v) for v in target]
            continue
        quaternion = pin.Quaternion(target[:3, :3]).coeffs()  # x, y, z, w
        flat += [float(v) for v in (*target[:3, 3], *quaternion)]
    return flat


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
        step = 0.15 if robot.task_space == "pose" else 0.3
    points, moved = [robot.forward(q)], q.copy()
    for k in range(1, count):
        joint = (k - 1) % robot.n
        moved = moved.copy()
        moved[joint] += step if k % 2 else -step
        moved = np.clip(moved, robot.lower, robot.upper)
        points.append(robot.forward(moved))
    return points
