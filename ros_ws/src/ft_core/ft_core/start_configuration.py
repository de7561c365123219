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

The controller runs it as a pre-task phase (`StartPhase`, the controller node's
`~/optimize_start` service): planned in its worker process (`plan_for_model`: the descent,
then the polyline time-parameterised along its length by Ruckig, at rest at both ends,
within the joint velocity limits and the recovery's acceleration and jerk), then followed
as the recovery follows its path (`recovery.follow`: the path's velocity plus a position
correction). The tool holds still: every sample is on the manifold, and between samples
0.05 rad apart the chord leaves it by a fraction of a mm.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import Future
from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Trajectory

from ft_core import measures, recovery, robots, selfmotion, workers
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


def timed_path(path: np.ndarray, velocity: np.ndarray, acceleration: float, jerk: float,
               period: float) -> recovery.Plan:
    """The polyline `path` (k, n; rad) at rest at both ends, sampled every `period` s.

    Its length is measured in the max norm, so a speed along it within the smallest of
    `velocity` (rad/s) keeps every joint within its own; `acceleration` and `jerk` bound
    that speed's profile (Ruckig, one degree of freedom). As a `recovery.Plan` (kfm nan:
    not an IK solution's) for `recovery.follow`.
    """
    steps = np.abs(np.diff(path, axis=0)).max(axis=1) if len(path) > 1 else np.zeros(0)
    arc = np.concatenate([[0.0], np.cumsum(steps)])
    generator, parameters, trajectory = Ruckig(1), InputParameter(1), Trajectory(1)
    parameters.current_position, parameters.target_position = [0.0], [float(arc[-1])]
    parameters.max_velocity = [max(float(np.min(velocity)), 1e-6)]
    parameters.max_acceleration, parameters.max_jerk = [acceleration], [jerk]
    if generator.calculate(parameters, trajectory) not in (Result.Working, Result.Finished):
        raise ValueError("no time parameterisation of the start path")
    times = recovery.sample_times(trajectory.duration, period)
    along = np.array([trajectory.at_time(float(t))[:2] for t in times]).reshape(-1, 2)
    s, speed = along[:, 0], along[:, 1]
    positions = np.column_stack([np.interp(s, arc, path[:, j]) for j in range(path.shape[1])])
    segment = np.clip(np.searchsorted(arc, s, side="right") - 1, 0, max(len(steps) - 1, 0))
    slopes = (np.diff(path, axis=0) / np.maximum(steps, 1e-12)[:, None] if len(steps)
              else np.zeros((1, path.shape[1])))
    velocities = slopes[segment] * speed[:, None]
    positions[-1], velocities[-1] = path[-1], 0.0
    return recovery.Plan(path[-1].copy(), math.nan, times, positions, velocities, 1)


def plan_for_model(spec: str, chain: Sequence, q0: np.ndarray, velocity: np.ndarray,
                   period: float, acceleration: float, jerk: float,
                   ) -> tuple[StartPlan, recovery.Plan]:
    """`optimal_start` from q0 for `robots.load(spec, *chain)`, and its timed path.

    For the controller's worker process (plain arguments: the robot is built there).
    """
    robot = robots.load(spec, *chain)
    found = optimal_start(robot, q0)
    return found, timed_path(found.path, velocity, acceleration, jerk, period)


#: Starts a start-configuration plan in the background: q -> its future.
Submit = Callable[[np.ndarray], "Future[tuple[StartPlan, recovery.Plan]]"]


class StartPhase:
    """The controller's pre-task phase: plan the start configuration, then move there.

    `note` says what it does (diagnostics). A target (twist or pose goal), a lock, or a
    failed plan ends it; the arm then stands still or follows the target.
    """

    def __init__(self, submit: Submit, gain: float, timeout: float):
        self._submit, self._gain, self._timeout = submit, gain, timeout
        self._job: workers.Job | None = None
        self._path: tuple[recovery.Plan, float] | None = None
        self.note = "idle"

    @property
    def active(self) -> bool:
        """Whether a plan is computed or a path followed."""
        return self._job is not None or self._path is not None

    @property
    def planning(self) -> bool:
        """Whether a plan is being computed (its result not back yet)."""
        return self._job is not None and self._job.running

    def request(self, q: np.ndarray, now: float) -> None:
        """Plan from q (rad) in the background.

        Raises:
            RuntimeError: no worker process can start (inside a daemon), or one plan
                runs already.
        """
        if self.active:
            raise RuntimeError(f"already under way: {self.note}")
        try:
            self._job = workers.Job(self._submit(q.copy()), now, self._timeout)
        except (AssertionError, OSError) as problem:
            raise RuntimeError(f"cannot plan ({problem})") from problem
        self.note = "planning the start configuration"

    def cancel(self, why: str) -> None:
        """End the phase (a plan still running is ignored when it ends)."""
        if self.active:
            self._job, self._path = None, None
            self.note = f"stopped: {why}"

    def step(self, now: float, q: np.ndarray,
             velocity_bounds: tuple[np.ndarray, np.ndarray]) -> np.ndarray | None:
        """The command (rad/s) while the path is followed; None otherwise."""
        if self._job is not None:
            self._take(self._job, now)
        if self._path is None:
            return None
        plan, start = self._path
        end = recovery.path_end(plan, now - start, q)
        if end is None:
            return recovery.follow(plan, now - start, q, (), self._gain, *velocity_bounds)
        self._path = None
        self.note = ("at the start configuration" if end == "arrived" else
                     "start path not completed in time: stopped")
        return None

    def _take(self, job: workers.Job, now: float) -> None:
        state, result = job.poll(now)
        if state == workers.JobState.PENDING:
            return
        self._job = None
        if state == workers.JobState.LATE:
            self.note = f"planning took over {self._timeout:.1f} s: given up"
            return
        if state == workers.JobState.FAILED:
            self.note = f"no start configuration: {result}"
            return
        found, plan = result
        if not found.cost < found.start_cost:
            self.note = f"already at the best start configuration (cost {found.cost:.3g})"
            return
        self._path = (plan, now)
        self.note = (f"moving to the start configuration: {plan.duration:.2f} s, reduced "
                     f"condition cost {found.start_cost:.3g} -> {found.cost:.3g}")
