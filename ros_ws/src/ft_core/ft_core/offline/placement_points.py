"""The fault tolerance of one task point for `ft-map` (Lewis & Maciejewski 1997 sec. III).

`evaluate_point` finds a seed configuration reaching the point by continuation from a
start configuration (`continuation_seed`), traces its self-motion component and records
the component's bounding-box volume and the local measure kfm (eq 5) on it
(`PointResult`); `evaluate_targets` does so for many points on worker processes or a
Dask cluster (`ft_core.offline.batch`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ft_core import measures, robots, selfmotion
from ft_core.offline import batch

#: Longest straight move (m) of the tool per continuation step when seeding.
CONTINUATION_STEP = 0.05
#: Most continuation steps (the move is cut into more, shorter steps only up to this).
MAX_CONTINUATION_STEPS = 200
#: Most manifold samples at which kfm is evaluated for `kfm_max`.
KFM_SAMPLES = 100

@dataclass
class PointResult:
    """Fault tolerance of one task point (NaN where unreachable).

    Attributes:
        reachable: a seed configuration was found.
        continued: the seed came from continuation (else from `find_seed`).
        volume: normalised volume of the traced component's box over the chosen joints.
        volume_rad: the same box's volume in rad^k (k chosen joints; m for prismatic).
        best_volume: largest normalised volume over the traced components (restarts).
        components: components traced (1 + distinct restarts; 0 if unreachable).
        kfm: kfm (Lewis & Maciejewski 1997 eq 5) at the seed, m/rad (scaled task rows).
        kfm_max: largest kfm over at most `KFM_SAMPLES` samples of the component.
        seed: the seed configuration (n,), rad.
        q_kfm: the sample where kfm_max was found (n,), rad.
        lower, upper: the component's box (n,), rad (+-inf for a joint without
            limits that turns fully).
    """

    reachable: bool
    continued: bool
    volume: float
    volume_rad: float
    best_volume: float
    components: int
    kfm: float
    kfm_max: float
    seed: np.ndarray
    q_kfm: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    @classmethod
    def unreachable(cls, n: int) -> PointResult:
        """The result of a point no configuration reaches."""
        nan = np.full(n, np.nan)
        return cls(False, False, 0.0, 0.0, 0.0, 0, math.nan, math.nan, nan, nan.copy(),
                   nan.copy(), nan.copy())


def kfm_of(robot: robots.Robot, q: np.ndarray) -> float:
    """kfm(q) = min_i sigma_m(iJ) of the task-scaled J (Lewis & Maciejewski 1997 eq 5), m/rad."""
    return measures.kfm(robot.scale_task(robot.jacobian(q)))


def continuation_seed(robot: robots.Robot, target: np.ndarray, q_start: np.ndarray,
                      ) -> np.ndarray | None:
    """A configuration reaching `target` that keeps the posture of q_start, or None.

    The tool point moves from `robot.forward(q_start)` to `target` in a straight
    line (a geodesic for a pose: exp6 of a fraction of log6 of the relative motion),
    in equal steps of at most `CONTINUATION_STEP` m (or rad for the rotation, at
    most `MAX_CONTINUATION_STEPS`), each corrected by `selfmotion.project` inside
    the physical limits. None when a step does not converge.
    """
    q = np.clip(np.asarray(q_start, dtype=float), robot.lower, robot.upper)
    start = robot.forward(q)
    if robot.task_space == "pose":
        motion = pin.log6(pin.SE3(start).inverse() * pin.SE3(target)).vector
        length = float(np.linalg.norm(motion))
    else:
        length = float(np.linalg.norm(target - start))
    steps = min(MAX_CONTINUATION_STEPS, max(1, math.ceil(length / CONTINUATION_STEP)))
    for k in range(1, steps + 1):
        fraction = k / steps
        if robot.task_space == "pose":
            waypoint = (pin.SE3(start) * pin.exp6(fraction * motion)).homogeneous
        else:
            waypoint = start + fraction * (target - start)
        q = selfmotion.project(robot, waypoint, q)
        if q is None:
            return None
    return q


def evaluate_point(robot: robots.Robot, target: np.ndarray, q_start: np.ndarray,
                   joints: Sequence[int] | None = None, step: float = selfmotion.STEP,
                   restarts: int = 0, index: int = 0) -> PointResult:
    """Fault tolerance of one task point: seed, traced component, box volume and kfm.

    Args:
        robot: the arm.
        target: the task point (as `robot.forward` returns it).
        q_start: start configuration (rad) for the continuation seed (module notes).
        joints: joints (0-based) of the volume; default all.
        step: tracing step (rad).
        restarts: further components to trace from seeded random configurations.
        index: the grid index, seeding the restarts' random generator (determinism).

    Returns:
        The point's `PointResult`.
    """
    seed = continuation_seed(robot, target, q_start)
    continued = seed is not None
    if seed is None:
        try:
            seed = selfmotion.find_seed(robot, target, q_start)
        except selfmotion.UnreachableError:
            return PointResult.unreachable(robot.n)
    manifold = selfmotion.trace(robot, target, seed, step=step)
    lower, upper = manifold.box
    volume = selfmotion.box_volume(robot, lower, upper, joints)
    finite_lower = np.where(np.isfinite(lower), lower, -math.pi)  # unlimited: one turn
    finite_upper = np.where(np.isfinite(upper), upper, math.pi)
    volume_rad = selfmotion.box_volume(robot, finite_lower, finite_upper, joints,
                                       normalized=False)
    samples = manifold.samples
    picked = samples[np.unique(np.linspace(0, len(samples) - 1, KFM_SAMPLES).astype(int))]
    values = np.array([kfm_of(robot, q) for q in picked])
    best = int(np.argmax(values))
    best_volume, components, traced = volume, 1, samples
    rng = np.random.default_rng(index)
    for _ in range(restarts):
        start = robot.random_configuration(rng)
        try:
            other = selfmotion.find_seed(robot, target, start, attempts=0)
        except selfmotion.UnreachableError:
            continue
        if selfmotion.near(robot, traced, other, 4 * step):
            continue  # on a component already traced
        component = selfmotion.trace(robot, target, other, step=step)
        best_volume = max(best_volume, selfmotion.box_volume(robot, *component.box, joints))
        traced = np.vstack([traced, component.samples])
        components += 1
    return PointResult(True, continued, volume, volume_rad, best_volume, components,
                       kfm_of(robot, seed), float(values[best]), seed, picked[best],
                       lower, upper)


_WORKER: dict = {}


def _run_chunk(job: tuple[tuple, dict, list[tuple[int, np.ndarray]]],
               ) -> list[tuple[int, PointResult]]:
    """Evaluate (index, target) pairs of `job` = (model, settings, pairs).

    The robot is built once per process and model (robots do not pickle).
    """
    model, settings, chunk = job
    if _WORKER.get("model") != model:
        _WORKER.update(model=model,
                       robot=robots.load(model[0], model[1], model[2], task_space=model[3]))
    robot = _WORKER["robot"]
    return [(index, evaluate_point(robot, target, settings["q_start"], settings["joints"],
                                   settings["step"], settings["restarts"], index))
            for index, target in chunk]


def evaluate_targets(model: tuple[str, str | None, str | None, str | None],
                     targets: Sequence[np.ndarray], q_start: np.ndarray,
                     joints: Sequence[int] | None = None, step: float = selfmotion.STEP,
                     restarts: int = 0, where: batch.Where = batch.HERE,
                     ) -> list[PointResult]:
    """`evaluate_point` for every target, where `where` says (`batch`).

    Args:
        model: (spec, base_link, tip_link, task_space) for `robots.load` in each worker.
        targets: the task points.
        q_start: start configuration (rad), as `evaluate_point`.
        joints: joints of the volume, as `evaluate_point`.
        step: tracing step (rad).
        restarts: further components per point, as `evaluate_point`.
        where: worker processes or a cluster; one worker evaluates here without a pool.

    Returns:
        The results in the order of `targets`.
    """
    settings = {"q_start": np.asarray(q_start, dtype=float),
                "joints": None if joints is None else list(joints), "step": step,
                "restarts": restarts}
    pairs = list(enumerate(targets))
    # Small chunks keep the load balanced (points near the boundary are quick, points
    # with large manifolds are slow) and the bar moving.
    size = max(1, min(16, len(pairs) // (8 * max(where.workers, 1))))
    jobs = [(model, settings, pairs[k:k + size]) for k in range(0, len(pairs), size)]
    results: list[PointResult | None] = [None] * len(pairs)
    for done in batch.results(_run_chunk, jobs, where, what="chunk"):
        for index, result in done:
            results[index] = result
    return results  # type: ignore[return-value]
