"""A campaign's design and draws: critical points, waypoints, the lock and the runs to do.

Everything a run of `ft-campaign` is built from, as pure functions of the arm, the
critical-point set and the run's seed (Lewis & Maciejewski 1997 sec. V): the critical
points (`critical_points`), the far waypoints drawn inside their soft-limit box
(`waypoints`), the visiting order (`tour`), the joint that locks and when (`draw`), and
which critical points inverse kinematics still reaches after the lock (`reachable`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from ft_core import faults, robots, selfmotion

from ft_sim.scenario_config import TASK_POINTS, ScenarioConfig

#: Far, non-critical waypoints per run (visited in turn after the critical points).
WAYPOINTS = 8
#: A waypoint is at least this fraction of the arm's typical reach from every critical point.
FAR = 0.3
#: The lock comes this long (simulated s) after the task starts, drawn uniformly.
LOCK_WINDOW = (12.0, 24.0)
#: Critical-point sets (`--points`): the arm's task points, or points near the boundary of
#: its workspace, where the self-motion boxes are small (`boundary_points`).
POINT_SETS = ("task", "boundary")
#: The boundary set's middle point is this fraction of the reach along its ray.
BOUNDARY = 0.9
GOAL_TOLERANCE = 5e-3  #: m
GOAL_TIMEOUT = 5.0  #: s per visit
TOUR_TIMEOUT = ScenarioConfig.tour_timeout  #: s per visit of the tour after the lock


@dataclass(frozen=True)
class Task:
    """One run to do: the seed (the draws), the condition, the design, how to run it.

    `design` holds everything the runs of one campaign share (arm, plant options,
    critical points, soft-limit box); it names the folder the run is kept in. The run
    leases a DDS domain from `first_domain` on, on the machine it runs on
    (`domains.lease`); with `record`, its topics come back with its result
    (`RECORDING`), to be written where the campaign runs.
    """

    seed: int
    mode: str
    soft: bool
    design: dict = field(hash=False)
    first_domain: int = 30
    record: bool = False

    @property
    def name(self) -> str:
        """The run's file name stem."""
        return f"{self.seed}-{self.mode}-{'soft' if self.soft else 'free'}"


def critical_points(robot: robots.Robot, kind: str = "task") -> tuple[tuple[float, ...], ...]:
    """Three critical points of set `kind` (`POINT_SETS`), each flat (`selfmotion.point_size`).

    "task": the built-in's task points for a position task, or around a bent
    configuration; "boundary": `boundary_points`. m, and a pose's quaternion x, y, z, w.
    """
    if kind == "boundary":
        chosen = boundary_points(robot)
    elif robot.name in TASK_POINTS and robot.task_space == "position":
        return TASK_POINTS[robot.name]
    else:
        chosen = selfmotion.points_around(robot, selfmotion.bent_configuration(robot))
    size = selfmotion.point_size(robot)
    flat = selfmotion.flat_from_targets(robot, chosen)
    return tuple(tuple(flat[i:i + size]) for i in range(0, len(flat), size))


def boundary_points(robot: robots.Robot, steps: int = 20) -> list[np.ndarray]:
    """Three critical points near the boundary of the workspace (m).

    On the ray from the shoulder (the second joint's origin) through the tool point of
    `selfmotion.bent_configuration`, the farthest point inverse kinematics reaches is found
    by bisection (`steps` halvings, so bounded); the middle point is `BOUNDARY` of the way
    there, and the other two are `selfmotion.points_around` its configuration (a pose
    task keeps the bent configuration's orientation along the ray). Near the
    boundary the self-motion manifolds shrink, and so do their bounding boxes: the case
    Lewis & Maciejewski 1997 (sec. III) say the soft limits matter in. On the Panda the
    common box spans 0.3 to 0.5 of the range of joints 1, 2 and 4 (the task set: 0.6 to
    0.9).

    Raises selfmotion.UnreachableError when the bent configuration's own tool point is
    out of reach (a chain without room to move).
    """
    q0 = selfmotion.bent_configuration(robot)
    shoulder, tool = robot.skeleton(q0)[1], robot.transform(q0)
    ray = tool[:3, 3] - shoulder

    def along(length: float) -> np.ndarray:  # the task target `length` rays from the shoulder
        pose = tool.copy()
        pose[:3, 3] = shoulder + length * ray
        return robot.task_coordinates(pose)

    # In lengths of the ray: 1 is the bent tool point itself; `Robot.reach` (the sum of
    # the links) is beyond any point the arm reaches.
    near, far = 1.0, max(1.0, 2 * robot.reach / max(float(np.linalg.norm(ray)), 1e-9))
    selfmotion.find_seed(robot, along(1.0), q0)
    for _ in range(steps):
        middle = 0.5 * (near + far)
        try:
            selfmotion.find_seed(robot, along(middle), q0, attempts=10)
        except selfmotion.UnreachableError:
            far = middle
        else:
            near = middle
    q = selfmotion.find_seed(robot, along(BOUNDARY * near), q0)
    return selfmotion.points_around(robot, q)


def waypoints(robot: robots.Robot, box: tuple[np.ndarray, np.ndarray],
              critical: tuple[tuple[float, ...], ...], seed: int,
              count: int = WAYPOINTS) -> list[tuple[float, ...]]:
    """`count` far waypoints for run `seed`, reachable inside the soft-limit box.

    Configurations drawn uniformly inside the box (and the joint limits); their tool
    points (flat as `critical_points`), kept when their position is at least `FAR` x the
    median distance of the drawn positions from the base away from every critical point
    (the farthest ones if too few are that far).
    """
    rng = np.random.default_rng([seed, 1])
    lower = np.maximum(box[0], robot.lower)
    upper = np.minimum(box[1], robot.upper)
    lower, upper = np.where(np.isfinite(lower), lower, -np.pi), np.where(
        np.isfinite(upper), upper, np.pi)
    tools = [robot.forward(q) for q in rng.uniform(lower, upper, (20 * count, robot.n))]
    drawn = np.array(selfmotion.flat_from_targets(robot, tools)).reshape(len(tools), -1)
    positions = drawn[:, :min(robot.m, 3)]
    centres = np.array(critical)[:, :positions.shape[1]]
    distance = np.min(np.linalg.norm(positions[:, None, :] - centres[None], axis=2), axis=1)
    far = np.flatnonzero(distance >= FAR * np.median(np.linalg.norm(positions, axis=1)))
    if far.size < count:
        far = np.argsort(-distance)[:count]
    return [tuple(float(v) for v in drawn[i]) for i in far[:count]]


def tour(critical: tuple[tuple[float, ...], ...], far: list[tuple[float, ...]],
         ) -> tuple[tuple[tuple[float, ...], ...], tuple[int, ...]]:
    """The points in visiting order and the indices of the critical ones among them.

    Each critical point is followed by two waypoints, the remaining waypoints come last:
    the arm travels far between critical points, as in a pick-and-place cell.
    """
    order: list[tuple[float, ...]] = []
    marks: list[int] = []
    rest = list(far)
    for point in critical:
        marks.append(len(order))
        order += [point, *rest[:2]]
        rest = rest[2:]
    return tuple(order + rest), tuple(marks)


def draw(seed: int, joints: tuple[str, ...]) -> tuple[str, float]:
    """The joint that locks and when (s after the task starts), for run `seed`."""
    rng = np.random.default_rng(seed)
    return joints[int(rng.integers(len(joints)))], float(rng.uniform(*LOCK_WINDOW))



def reachable(robot: robots.Robot, critical: tuple[tuple[float, ...], ...], q: np.ndarray,
              joint: int) -> list[int]:
    """The critical points (indices, flat) the arm can reach at all with `joint` locked at q's.

    Inverse kinematics with that joint pinned, from q and 30 seeded random starts
    (`selfmotion.find_seed`): what the bounding boxes guarantee (Lewis & Maciejewski 1997 sec. III),
    whatever a local controller then manages.
    """
    lower, upper = robot.lower.copy(), robot.upper.copy()
    lower[joint] = upper[joint] = q[joint]
    targets = selfmotion.targets_from_flat(robot, [v for p in critical for v in p])
    return [k for k, found in enumerate(selfmotion.reachability(robot, targets, lower, upper, q))
            if found is not None]


def design_of(robot_spec: str, base_link: str, tip_link: str, plant: dict,
              recovery: bool = True, points: str = "task", task: str = "position",
              fault: str = "lock") -> dict:
    """What every run of a campaign shares: arm, task, plant, recovery, critical points, box.

    `points`: the critical-point set (`POINT_SETS`); `fault`: what fails in each run,
    `KIND[:VALUE]` (`ft_core.faults.parse_spec`), under the key "fault" unless a lock (so
    a lock campaign's design, and the runs kept under it, are as they were). Raises
    ft_core.faults.FaultError for a fault spec it refuses, selfmotion.UnreachableError
    when the critical points have no common box, robots.RobotModelError when the chain
    cannot follow the task or has no joint to spare for it (after a lock it could not go
    on, and there is no self-motion to bound).
    """
    faults.parse_spec(fault)
    robot = robots.load(robot_spec, base_link or None, tip_link or None, task_space=task)
    if robot.n <= robot.m:
        raise robots.RobotModelError(f"{robot.name} has {robot.n} joint(s): no redundancy for "
                                     f"a campaign, which needs more than the {task} task's "
                                     f"{robot.m}")
    critical = critical_points(robot, points)
    box = selfmotion.soft_limits(robot, [v for p in critical for v in p],
                                 selfmotion.bent_configuration(robot)).box
    return {"robot": robot_spec, "base_link": base_link, "tip_link": tip_link, "task": task,
            "plant": plant, "points": points, "critical": [list(p) for p in critical],
            "box": [[float(v) for v in side] for side in box],
            "waypoints": WAYPOINTS, "lock_window": list(LOCK_WINDOW),
            "recovery": recovery, "tour_timeout": TOUR_TIMEOUT,
            **({"fault": fault} if fault != "lock" else {})}


def tasks(runs: int, modes: tuple[str, ...], first_domain: int, design: dict,
          record: bool = False) -> list[Task]:
    """Every run: each seed under each mode, without and with soft limits."""
    return [Task(seed, mode, soft, design, first_domain, record) for seed in range(runs)
            for mode in modes for soft in (False, True)]
