"""Recovery when local control is stuck after a lock: stall test, pinned IK, joint path.

A velocity-level controller follows the task direction from where the arm is. After a
lock it can stop short of a goal the locked arm can still reach: a joint pressed
against its hard limit, or the arm at the edge of the soft-limit box where the reduced
arm cannot make the task direction without leaving it (docs/campaign.md). Recovery:

1. **Stall** (`StallWatch`): the pose goal's error has not dropped below its best value
   by `progress` (or by a quarter of it, if that is less: a converging arm near its goal)
   for `stall_time` s, while it is at least `near` (closer, the error is the final
   approach or the measurement noise, and the arm is left to it). Every cause of a stall
   (a hard limit, a soft-limit edge, a singular reduced arm) shows this way. While a
   healthy joint is **pressed** against a bound in force (`pressed`: within `AT_BOUND` of
   it, the error's steepest descent pointing out of the bounds), the drop needed is
   larger: `PRESSED_PROGRESS` (or a quarter of the error, if less). Pressed against a
   limit, local control creeps: the other joints make what they can of the task
   direction, and the error falls by a few mm/s, each step counted as progress by the
   first rule, for the whole visit (docs/campaign.md).
2. **Plan** (`plan`, run in a worker process, never in the control cycle): inverse
   kinematics of the goal with the locked joints pinned (`selfmotion.project`: Newton
   with an active set on the joint bounds), multi-start (`solutions`): the current
   configuration, then the goal's traced self-motion configurations when it is a
   critical point (those whose locked joints are nearest first), then seeded random
   configurations inside the bounds (`attempts` in all, each at most
   `selfmotion.project`'s iterations: bounded). The bounds are the ones the engine
   enforces (hard limits, and the soft-limit box while it still applies). Among the
   solutions whose remaining arm keeps at least half the best kfm (Lewis & Maciejewski
   1997, eq 5, on the healthy joints' columns: the arm's tolerance of a next failure),
   the nearest to the current configuration. Reading taken: the issue asks for "kfm of
   the remaining arm, then distance"; a strict order would drive the arm across joint
   space for a marginal kfm gain, so kfm screens and distance chooses.
3. **Path**: the straight line in joint space from the current configuration to the
   solution. Both ends lie in the bounds, a box, so the whole line does; the locked
   joints do not move on it. It is time-parameterised by Ruckig (Berscheid & Kroeger,
   RSS 2021): time-optimal, jerk-limited, from rest to rest, with phase
   synchronisation keeping every joint on the line, within the engine's velocity limits
   and `acceleration` and `jerk`. Ruckig rather than TOPP-RA: the path is one segment
   between two states at rest, which Ruckig solves in closed form in microseconds
   without a path discretisation or a solver, jerk-limited as well. The worker samples
   it at the control period and returns plain arrays.
4. **Follow** (`follow`): velocity of the path plus `gain` times its position error, on
   the healthy joints, inside the engine's velocity bounds; then the task-space
   controller takes over again.

A stall with no joint known to be locked is handled the same way, with nothing pinned:
a lock nobody has seen (its joint hardly commanded, so the monitor could not tell) is the
common cause, and the path commands every joint, the locked one too, so the monitor sees
it stall and declares it; the new locked set drops the path, and the next stall plans
with that joint pinned. On a healthy arm the path simply goes round what stopped local
control (a hard limit, the soft-limit box's edge).

Times are seconds, angles rad, task errors in the task's scaled units (`Robot.scale_task`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from concurrent.futures import Future
from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Synchronization, Trajectory

from ft_core import measures, robots, selfmotion, workers
from ft_core.robots import Robot, TaskSpace

#: Share of the best error whose drop counts as progress, when less than `progress`.
RELATIVE_PROGRESS = 0.25
#: Task units (m) per `stall_time` the error must drop by while a joint is pressed
#: against a bound (`pressed`), when less than `RELATIVE_PROGRESS` of it: a quarter of the
#: tool speed a velocity-limited arm makes on a long move (about 0.2 m/s).
PRESSED_PROGRESS = 0.05
#: rad; a joint this close to a bound in force is at it (10 x the sensor noise).
AT_BOUND = 0.01
#: A plan's path has at most this many samples (bounded memory: a longer path is
#: sampled more coarsely than the control period).
MAX_SAMPLES = 20000


@dataclass(frozen=True)
class RecoveryConfig:
    """When local control counts as stuck, and how the recovery path moves.

    Attributes:
        stall_time: s without progress before a stall is declared, > 0.
        progress: a drop of the goal's error by this much (or by a quarter of it) counts
            as progress, > 0.
        near: errors below this are never a stall, >= 0.
        attempts: IK starts of one plan, >= 1.
        timeout: s a plan may take before its result is ignored, > 0.
        acceleration: rad/s^2, largest joint acceleration on the path, > 0.
        jerk: rad/s^3, largest joint jerk on the path, > 0.
        gain: 1/s, correction of the path's position error while following it, >= 0.
        plans_per_goal: plans tried for one goal before giving up on it, >= 1.
    """

    stall_time: float = 1.0
    progress: float = 0.002
    near: float = 0.003
    attempts: int = 30
    timeout: float = 10.0
    acceleration: float = 1.0
    jerk: float = 10.0
    gain: float = 5.0
    plans_per_goal: int = 2

    def __post_init__(self) -> None:
        positive = ("stall_time", "progress", "timeout", "acceleration", "jerk")
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"recovery {name} must be finite and > 0, got {value}")
        for name in ("gain", "near"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"recovery {name} must be finite and >= 0, got {value}")
        for name in ("attempts", "plans_per_goal"):
            if getattr(self, name) < 1:
                raise ValueError(f"recovery {name} must be >= 1, got {getattr(self, name)}")


class StallWatch:
    """The pose goal's error over time: stalled when it stops improving."""

    def __init__(self, config: RecoveryConfig):
        self.config = config
        self.reset(math.nan)

    def reset(self, now: float) -> None:
        """Forget the error seen so far (a new goal, a new locked set, a path done)."""
        # The error when progress was last made, and when: the reference a drop is
        # measured from (not the latest error: many small drops add up to progress).
        self._best, self._since = math.inf, now

    def update(self, now: float, error: float, reached: bool, pressed: bool = False) -> bool:
        """Whether the error (>= 0) has not improved for `stall_time` s (see the module).

        `pressed`: a healthy joint holds at a bound against the task direction (`pressed`).
        """
        config = self.config
        if reached or not math.isfinite(error) or error < config.near:
            self.reset(now)
            return False
        needed = max(config.progress, PRESSED_PROGRESS) if pressed else config.progress
        if math.isnan(self._since) or error < self._best - min(needed,
                                                               RELATIVE_PROGRESS * self._best):
            self._best, self._since = error, now
            return False
        return now - self._since >= self.config.stall_time


def pressed(q: np.ndarray, descent: np.ndarray, bounds: tuple[np.ndarray, np.ndarray],
            locked: Sequence[int]) -> bool:
    """Whether a healthy joint holds at a bound in force against the task direction.

    `descent`: J^T e, the steepest descent of the task error e's squared norm in joint
    space (rad/s per unit gain); its sign for joint j is the way j alone would reduce the
    error. Pressed: some joint not in `locked` is within `AT_BOUND` of its lower bound
    with descent < 0, or of its upper bound with descent > 0. Reading taken: the issue's
    "a joint holds at a hard or soft limit against the task direction" judged joint by
    joint on the Jacobian-transpose direction, which needs no solve and has the same sign
    as the least-squares solution's component whenever the columns are orthogonal.
    Asked every cycle towards a pose goal: a loop over Python floats (the same
    comparisons), a fraction of what numpy's calls cost on a 7-joint arm.
    """
    lower, upper = bounds
    for j, (x, d, low, high) in enumerate(zip(q.tolist(), descent.tolist(), lower.tolist(),
                                              upper.tolist(), strict=True)):
        if ((d < 0 and x - low < AT_BOUND) or (d > 0 and high - x < AT_BOUND)) and (
                j not in locked):
            return True
    return False


@dataclass(frozen=True)
class Plan:
    """A way to the goal with the locked joints pinned: a solution and a sampled path.

    Attributes:
        solution: the configuration reaching the goal (rad).
        kfm: the remaining arm's kfm there (m/rad, scaled task units).
        times: s from the path's start, (k,), spaced by the control period.
        positions, velocities: (k, n), rad and rad/s; the last sample is the solution
            at rest.
        solutions: how many distinct IK solutions were found.
    """

    solution: np.ndarray
    kfm: float
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    solutions: int

    @property
    def duration(self) -> float:
        """Time (s) from the path's start to the solution."""
        return float(self.times[-1])


def solutions(robot: Robot, goal: np.ndarray, q: np.ndarray, locked: Sequence[int],
              lower: np.ndarray, upper: np.ndarray, attempts: int,
              seed: int = 0, traced: np.ndarray | None = None) -> list[np.ndarray]:
    """IK solutions of `goal` with the `locked` joints at q's values, inside the bounds.

    Newton from q (clipped into the bounds), then from configurations of the goal's
    traced self-motion component (`traced`, (k, n), if the goal is a critical point:
    `selfmotion.SoftLimits`), those whose locked joints are nearest q's values first, for
    up to half the attempts, then from seeded random configurations inside the bounds;
    `attempts` starts in all, each bounded by `selfmotion.project`. The traced ones come
    first because of Lewis & Maciejewski 1997's guarantee (sec. III): a lock inside the
    box leaves a configuration of that component with the locked joint at its value.
    """
    rng = np.random.default_rng(seed)
    low = np.where(np.isfinite(lower), lower, -math.pi)
    high = np.where(np.isfinite(upper), upper, math.pi)
    pinned = list(locked)
    on_manifold = np.zeros((0, q.size)) if traced is None else np.asarray(traced, dtype=float)
    if pinned and len(on_manifold):
        on_manifold = on_manifold[np.argsort(
            np.abs(on_manifold[:, pinned] - q[pinned]).max(axis=1), kind="stable")]
    on_manifold = on_manifold[:max(0, attempts // 2)]
    found: list[np.ndarray] = []
    for k in range(attempts):
        if k == 0:
            start = np.clip(q, lower, upper)
        elif k <= len(on_manifold):
            start = np.clip(on_manifold[k - 1], lower, upper)
        else:
            start = rng.uniform(low, high)
        start[pinned] = q[pinned]
        solution = selfmotion.project(robot, goal, start, fixed=pinned, lower=lower,
                                      upper=upper)
        if solution is not None and not any(np.allclose(solution, s, atol=1e-3)
                                            for s in found):
            found.append(solution)
    return found


def reachable(robot: Robot, goal: np.ndarray, q: np.ndarray, locked: Sequence[int],
              seeds: Sequence[np.ndarray], attempts: int) -> bool:
    """Whether inverse kinematics reaches `goal` with the `locked` joints at q's values.

    Inside the hard limits: Newton (`selfmotion.project`) from each seed with the locked
    joints put at q's values (configurations known to have reached the goal before),
    then `solutions` (`attempts` starts).
    """
    pinned = list(locked)
    for seed in seeds:
        start = np.array(seed, dtype=float)
        start[pinned] = q[pinned]
        if selfmotion.project(robot, goal, start, fixed=pinned) is not None:
            return True
    return bool(solutions(robot, goal, q, pinned, robot.lower, robot.upper, attempts))


def mismatch(robot: Robot, goal: np.ndarray, other: np.ndarray) -> tuple[float, float]:
    """(m, rad) between two task targets (`Robot.forward`): positions, orientations (pose)."""
    if robot.task_space != TaskSpace.POSE:
        return float(np.linalg.norm(other - goal)), 0.0
    cosine = (np.trace(goal[:3, :3].T @ other[:3, :3]) - 1) / 2
    return (float(np.linalg.norm(other[:3, 3] - goal[:3, 3])),
            float(np.arccos(np.clip(cosine, -1.0, 1.0))))


def nearest_reachable(robot: Robot, goal: np.ndarray, q: np.ndarray, locked: Sequence[int],
                      attempts: int, samples: int, angle_per_metre: float,
                      seed: int = 0) -> np.ndarray:
    """The task target nearest `goal` that the arm reaches with `locked` at q's values.

    The target of a configuration with the locked joints at q's values, so reachable by
    construction, the nearest of some candidates by `mismatch` (orientation counted 1 m
    per `angle_per_metre` rad): for a pose task the pinned inverse kinematics of the
    goal's position alone (`solutions`, `attempts` starts: the same position at the
    nearest orientation the locked arm has there); otherwise, or if none is found,
    `samples` seeded random configurations inside the limits.
    """
    pinned = list(locked)
    candidates: list[np.ndarray] = []
    if robot.task_space == TaskSpace.POSE:
        position = robots.load(robot.urdf, robot.base_link, robot.tip_link,
                               task_space=TaskSpace.POSITION)
        candidates = solutions(position, goal[:3, 3], q, pinned, robot.lower, robot.upper,
                               attempts, seed)
    if not candidates:
        drawn = np.random.default_rng(seed).uniform(robot.lower, robot.upper,
                                                    (samples, robot.n))
        drawn[:, pinned] = q[pinned]
        candidates = list(drawn)

    def distance(configuration: np.ndarray) -> float:
        metres, radians = mismatch(robot, goal, robot.forward(configuration))
        return metres + radians / angle_per_metre

    return robot.forward(min(candidates, key=distance))


def choose(robot: Robot, found: Sequence[np.ndarray], q: np.ndarray,
           locked: Sequence[int]) -> tuple[np.ndarray, float]:
    """The nearest solution among those keeping at least half the best remaining kfm."""
    scores = [measures.kfm(robot.scale_task(robot.jacobian(s)), locked) for s in found]
    best = max(scores)
    eligible = [k for k, score in enumerate(scores) if score >= 0.5 * best]
    k = min(eligible, key=lambda i: float(np.linalg.norm(found[i] - q)))
    return found[k], scores[k]


def path(start: np.ndarray, end: np.ndarray, velocity: np.ndarray, acceleration: float,
         jerk: float, period: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The straight line from `start` to `end`, at rest at both ends, sampled.

    Every `period` s, or more coarsely for a path longer than `MAX_SAMPLES` periods.

    Returns (times, positions, velocities). Joints that do not move keep velocity 0.
    Raises ValueError when Ruckig finds no profile.
    """
    n = start.size
    generator, parameters, trajectory = Ruckig(n), InputParameter(n), Trajectory(n)
    parameters.current_position, parameters.target_position = start.tolist(), end.tolist()
    parameters.max_velocity = np.maximum(velocity, 1e-6).tolist()
    parameters.max_acceleration = [acceleration] * n
    parameters.max_jerk = [jerk] * n
    parameters.synchronization = Synchronization.Phase
    if generator.calculate(parameters, trajectory) not in (Result.Working, Result.Finished):
        raise ValueError("no time parameterisation of the recovery path")
    times = sample_times(trajectory.duration, period)
    samples = [trajectory.at_time(float(t)) for t in times]
    positions = np.array([s[0] for s in samples])
    velocities = np.array([s[1] for s in samples])
    positions[-1], velocities[-1] = end, 0.0
    return times, positions, velocities


def sample_times(duration: float, period: float) -> np.ndarray:
    """0 to `duration` (s) every `period` s, more coarsely past `MAX_SAMPLES`; ends on it."""
    step = max(period, duration / (MAX_SAMPLES - 1))
    times = np.minimum(np.arange(math.ceil(duration / step) + 1) * step, duration)
    times[-1] = duration
    return times


def plan(robot: Robot, goal: np.ndarray, q: np.ndarray, locked: Sequence[int],
         lower: np.ndarray, upper: np.ndarray, velocity: np.ndarray, period: float,
         config: RecoveryConfig, seed: int = 0, traced: np.ndarray | None = None,
         ) -> Plan | None:
    """A recovery plan from q to `goal` (see the module docstring); None: none found.

    `traced`: the goal's traced self-motion configurations, if it is a critical point
    (`solutions`).
    """
    q = np.asarray(q, dtype=float)
    goal = selfmotion.check_target(robot, goal)
    found = solutions(robot, goal, q, locked, lower, upper, config.attempts, seed, traced)
    if not found:
        return None
    solution, kfm = choose(robot, found, q, locked)
    solution[list(locked)] = q[list(locked)]
    times, positions, velocities = path(q, solution, velocity, config.acceleration,
                                        config.jerk, period)
    return Plan(solution, kfm, times, positions, velocities, len(found))


def plan_for_model(spec: str, chain: Sequence, goal: np.ndarray, q: np.ndarray,
                   locked: Sequence[int], lower: np.ndarray, upper: np.ndarray,
                   velocity: np.ndarray, period: float, config: RecoveryConfig,
                   seed: int = 0, traced: np.ndarray | None = None) -> Plan | None:
    """`plan` for a robot given as `robots.load` arguments (for a worker process)."""
    return plan(robots.load(spec, *chain), goal, q, locked, lower, upper, velocity, period,
                config, seed, traced)


def follow(recovery: Plan, elapsed: float, q: np.ndarray, locked: Sequence[int],
           gain: float, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The command (rad/s) `elapsed` s into the path at q: its velocity plus the correction.

    Inside [lo, hi] (the engine's velocity bounds at q); locked joints get 0.
    """
    k = int(np.searchsorted(recovery.times, elapsed, side="right")) - 1
    k = min(max(k, 0), recovery.times.size - 1)
    qd = recovery.velocities[k] + gain * (recovery.positions[k] - q)
    qd = np.clip(qd, lo, hi)
    qd[list(locked)] = 0.0
    return qd


#: rad; a path counts as done once the arm is this close to its end (largest joint error).
ARRIVED = 0.01
#: s the follower may take past the path's duration to arrive before it hands back anyway.
SETTLE = 2.0

def path_end(path: Plan, elapsed: float, q: np.ndarray) -> str | None:
    """How following `path` ends `elapsed` s in at q: None (go on), "arrived" or "late".

    Arrived: past its duration and within `ARRIVED` of its end; late: `SETTLE` s past
    its duration without arriving.
    """
    if elapsed >= path.duration and np.abs(path.solution - q).max() < ARRIVED:
        return "arrived"
    return "late" if elapsed >= path.duration + SETTLE else None


#: Starts a plan in the background: (goal, q, locked, lower, upper) -> its future.
Submit = Callable[[np.ndarray, np.ndarray, tuple[int, ...], np.ndarray, np.ndarray],
                  "Future[Plan | None]"]


class Recovery:
    """One controller's recovery: watching for a stall, planning, following a path.

    Used while a pose goal is set (the caller resets it on a new goal or locked set).
    `note` says what it does, for diagnostics.
    """

    def __init__(self, config: RecoveryConfig, submit: Submit):
        self.config = config
        self._submit = submit
        self._watch = StallWatch(config)
        self._job: workers.Job | None = None
        self._path: tuple[Plan, float] | None = None
        self._plans = 0
        self.note = "idle"

    @property
    def planning(self) -> bool:
        """Whether a plan is being computed (its result not back yet)."""
        return self._job is not None and self._job.running

    @property
    def following(self) -> bool:
        """Whether a recovery path is being followed."""
        return self._path is not None

    def reset(self, now: float) -> None:
        """Drop any plan or path (a new goal, a new locked set).

        A plan still running is ignored when it ends.
        """
        self._watch.reset(now)
        self._job, self._path, self._plans = None, None, 0
        self.note = "idle"

    def step(self, now: float, q: np.ndarray, goal: np.ndarray, error: float,
             descent: np.ndarray, reached: bool, locked: tuple[int, ...],
             bounds: tuple[np.ndarray, np.ndarray],
             velocity_bounds: tuple[np.ndarray, np.ndarray]) -> np.ndarray | None:
        """The command (rad/s) while a path is followed; None: the task controller's.

        `error`: the goal's error norm; `descent`: J^T e (`pressed`); `bounds`: the joint
        bounds in force (rad); `velocity_bounds`: the engine's (lo, hi) at q this
        cycle (rad/s, `ResolutionEngine.velocity_bounds`).
        """
        if self._job is not None:
            self._take(self._job, now, locked)
        if self._path is not None:
            plan, start = self._path
            end = path_end(plan, now - start, q)
            if end is None:
                return follow(plan, now - start, q, locked, self.config.gain, *velocity_bounds)
            self._path = None
            self._watch.reset(now)
            self.note = ("path done, tracking the goal again" if end == "arrived" else
                         "path not completed in time, tracking the goal again")
            return None
        against = pressed(q, descent, bounds, locked)
        if self._job is None and self._plans < self.config.plans_per_goal and (
                self._watch.update(now, error, reached, against)):
            try:
                self._job = workers.Job(self._submit(goal, q.copy(), locked, *bounds), now,
                                        self.config.timeout)
            except (AssertionError, RuntimeError, OSError) as problem:  # no worker process
                self._plans = self.config.plans_per_goal
                self.note = f"stalled, cannot plan ({problem})"
                return None
            self._plans += 1
            self.note = (f"stalled {error:.4f} from the goal"
                         f"{' (a joint pressed against a limit)' if against else ''}: "
                         f"planning a way round with joints {list(locked)} pinned")
        return None

    def _take(self, job: workers.Job, now: float, locked: tuple[int, ...]) -> None:
        """Start following a finished plan; give up on a failed or late one."""
        state, result = job.poll(now)
        if state == workers.JobState.PENDING:
            return
        self._job = None
        if state == workers.JobState.LATE:
            self._watch.reset(now)
            self.note = f"planning took over {self.config.timeout:.1f} s: given up"
            return
        if state == workers.JobState.FAILED or result is None:
            self._plans = self.config.plans_per_goal  # the goal is out of reach: stop trying
            self.note = "goal not reachable: " + (
                str(result) if state == workers.JobState.FAILED
                else f"no IK solution with joints {list(locked)} pinned")
            return
        self._path = (result, now)
        self.note = (f"following a {result.duration:.2f} s joint path to an IK solution "
                     f"(kfm {result.kfm:.3f}, {result.solutions} solutions found)")
