"""Tracing the connected component of a self-motion manifold through a seed.

Lewis & Maciejewski 1997, secs. II and IV. The manifold of a task point x* has
dimension r = n - m; the null space of J is its tangent space.

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
from collections.abc import Callable

import numpy as np

from ft_core.robots import Robot
from ft_core.selfmotion.manifold import (
    STEP,
    Manifold,
    UnreachableError,
    Walker,
    check_target,
    find_seed,
    full_turn,
    near,
    null_basis,
    project,
    unlimited_joints,
    wrapped_distance,
)

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


def _curve(walker: Walker, seed: np.ndarray, step: float,
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
            if count > 3 and wrapped_distance(robot, moved, seed) < 0.75 * step:
                return [np.array(path)], True
            q, previous = moved, tangent
        paths.append(np.array(path))
    return paths, False


def _crossings(robot: Robot, path: np.ndarray) -> list[np.ndarray]:
    """Samples of a path where branches of the manifold may cross (see the module notes)."""
    sigma = np.array([np.linalg.svd(robot.scale_task(robot.jacobian(q)), compute_uv=False)[-1]
                      for q in path])
    padded = np.concatenate([[np.inf], sigma, [np.inf]])
    minima = (sigma < BRANCH_SIGMA) & (sigma <= padded[:-2]) & (sigma <= padded[2:])
    return [path[k] for k in np.flatnonzero(minima)]


def _branches(walker: Walker, paths: list[np.ndarray], step: float,
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


def _extremal(walker: Walker, start: np.ndarray, joint: int, sign: float, step: float,
              max_steps: int) -> np.ndarray:
    """Along the null-space projection of +-e_joint to its extremum (Lewis & Maciejewski eq 10)."""
    robot = walker.robot
    q, path = start, [start]
    pinned = np.zeros(robot.n, dtype=bool)
    turn = 2 * math.pi if unlimited_joints(robot)[joint] else math.inf
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


def _explore(walker: Walker, seed: np.ndarray, step: float, walks: int, length: int,
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


def _spiral(walker: Walker, seed: np.ndarray, step: float, spacing: float,
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
            if np.any(widened & ~full_turn(robot, lower, upper)):
                last_growth = phi
            lower, upper = np.minimum(lower, q), np.maximum(upper, q)
        phi += step / (gamma * phi)
        if phi - last_growth > 2 * math.pi:
            break  # a whole turn without widening any bound
    return np.array(path)


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
    walker = Walker(robot, target)
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


