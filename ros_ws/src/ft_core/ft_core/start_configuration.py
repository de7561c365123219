"""The start configuration of best post-failure dexterity on the tool's self-motion manifold.

Zhao & Li (the minimum-jump paper), sec. III-D, planning step (i): with the tool held at
its initial position (zero task velocity), move the joints along the self-motion manifold
(in the null space) to the configuration of minimum reduced condition number before the
task starts. The reduced condition number of joint i is k_i = sigma_1 / sigma_r of the
Jacobian with joint i locked (eq 15); for several joints that may fail, the paper takes the
square sum (sec. III-C), which `dexterity_cost` is. Our reading for a pose task, whose rows
mix m and rad: the rows are scaled first (`Robot.scale_task`), as for kfm.

`optimal_start` descends that cost along the manifold: the cost's gradient (central
differences) projected onto the null space, a step of at most `step` rad, each new
configuration put back on the manifold by Newton's method inside the joint limits
(`selfmotion.project`), halving the step until the cost decreases. Bounded: at most
`iterations` steps of at most `HALVINGS` halvings. The result is a local minimum on the
manifold's component through the start (the paper's step (iii) tries other initial
positions when it is not good enough), with the joint path that reaches it.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from ft_core import measures, selfmotion
from ft_core.robots import Robot

#: Most halvings of one step before the descent stops (no decrease found).
HALVINGS = 12
#: rad, the central-difference step of the gradient.
DIFFERENCE = 1e-6


@dataclass(frozen=True)
class StartPlan:
    """Where the descent ended, and how.

    Attributes:
        q: the configuration of least cost found (rad).
        cost: `dexterity_cost` there (inf: a reduced Jacobian singular at the start and
            nowhere better found).
        start_cost: the cost at the start.
        path: the configurations passed (k, n; rad), from the start to `q`, each on the
            manifold: a joint path along which the tool stays where it is.
    """

    q: np.ndarray
    cost: float
    start_cost: float
    path: np.ndarray


def dexterity_cost(robot: Robot, q: np.ndarray, joints: Iterable[int] | None = None) -> float:
    """Sum of the squared reduced condition numbers k_i (Zhao & Li eq 15) over `joints`.

    Default: every joint may fail. inf when a reduced Jacobian is singular.
    """
    k = measures.reduced_condition_numbers(robot.scale_task(robot.jacobian(q)))
    chosen = k[list(range(robot.n) if joints is None else joints)]
    return float(np.sum(chosen ** 2)) if np.all(np.isfinite(chosen)) else np.inf


def optimal_start(robot: Robot, q0: np.ndarray, joints: Iterable[int] | None = None,
                  step: float = 0.05, iterations: int = 400) -> StartPlan:
    """Descend `dexterity_cost` along the self-motion manifold through q0 (rad).

    The tool keeps the pose (or position) it has at q0. `step`: most joint motion (rad,
    max norm) of one step; `iterations`: most steps.

    Raises:
        ValueError: a non-positive step or iteration count, or a q0 of the wrong length.
    """
    if not step > 0 or iterations < 1:
        raise ValueError(f"step ({step}) and iterations ({iterations}) must be positive")
    q = np.asarray(q0, dtype=float)
    if q.shape != (robot.n,):
        raise ValueError(f"q0 needs {robot.n} values, got shape {q.shape}")
    chosen = list(range(robot.n) if joints is None else joints)
    target = robot.forward(q)
    cost = start_cost = dexterity_cost(robot, q, chosen)
    path = [q.copy()]
    for _ in range(iterations):
        gradient = _gradient(robot, q, chosen)
        if not np.all(np.isfinite(gradient)):
            break
        basis = measures.null_space_basis(robot.scale_task(robot.jacobian(q)))
        direction = -basis @ (basis.T @ gradient)
        largest = float(np.max(np.abs(direction))) if direction.size else 0.0
        if largest <= 1e-12:
            break
        direction *= step / largest
        for _ in range(HALVINGS):
            moved = selfmotion.project(robot, target, q + direction)
            if moved is not None and (moved_cost := dexterity_cost(robot, moved, chosen)) < cost:
                break
            direction /= 2
        else:
            break
        q, cost = moved, moved_cost
        path.append(q.copy())
    return StartPlan(q, cost, start_cost, np.array(path))


def _gradient(robot: Robot, q: np.ndarray, joints: list[int]) -> np.ndarray:
    """Central differences of `dexterity_cost` in each joint (per rad)."""
    gradient = np.empty(robot.n)
    for k in range(robot.n):
        offset = np.zeros(robot.n)
        offset[k] = DIFFERENCE
        gradient[k] = (dexterity_cost(robot, q + offset, joints)
                       - dexterity_cost(robot, q - offset, joints)) / (2 * DIFFERENCE)
    return gradient
