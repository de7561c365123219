"""`ft-campaign` (used by `make bench`): Lewis & Maciejewski 1997 sec. V's experiment at scale.

Does keeping the joints inside the critical points' bounding boxes while healthy keep
every critical point reachable after a lock (Lewis & Maciejewski 1997 sec. III-V)? Each
run is a `scenario` on the arm (the Panda by default, or `--robot` with its chain
options; `--task` position by default, pose, or planar): it wanders for a long time
between three critical points and `WAYPOINTS` far, non-critical waypoints, so that an
arm without soft limits can drift; a random joint locks at a random time in
`LOCK_WINDOW`; then the arm tours the critical points. Success: every critical point
reached again (within 5 mm, `TOUR_TIMEOUT` s each). The waypoints are drawn inside the
soft-limit box (so the arm with soft limits can reach them too) and far from the
critical points; a run with and one without soft limits share the seed, hence the
waypoints and the lock (a paired design). A lock declared before the failure is a false
lock. The sim's plant options (`--latency`, `--response-time`, `--hold-last-command`)
make it realistic.

Conditions: each resolution mode (`--modes`) with and without the soft limits.
The table gives each success rate with its 95 % Wilson interval, and per mode the
runs whose outcome the soft limits changed with the exact McNemar test on them.

Runs go to worker processes (`--workers`) or a Dask cluster (`--cluster`; `batch`), each
in a DDS domain of its own on its machine (`domains.lease`, from ROS_DOMAIN_ID + 1 on),
with a progress bar on a terminal. Each finished run is kept, here, in
`<out>/runs/<options>/` (a folder per arm, plant and task design) and not run again:
a campaign resumes where it stopped. `--record` also keeps each run's topics as a
rosbag2 (MCAP) in a folder of the run's name beside its result. Writes
`<out>/campaign.md` (tables and the throughput), `campaign.json` (every run) and
`campaign.png`.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import multiprocessing
import os
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from ft_core import robots, selfmotion
from ft_core.offline import batch, cli
from scipy import stats
from tqdm import tqdm

from ft_sim import domains
from ft_sim.demo import summarise
from ft_sim.scenario import PHYSICS_ROBOT, TASK_POINTS, ScenarioConfig, run

MODES = ("least_norm", "max_kfm", "min_jump", "blend")
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
#: Most seeds per condition.
MAX_RUNS = 100_000
GOAL_TOLERANCE = 5e-3  #: m
#: DDS domains a run may lease from `--first-domain` on (`domains.lease`).
DOMAIN_COUNT = 100
#: The key of a result that carries the run's recording ({file name: bytes}).
RECORDING = "_recording"
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


def one_run(task: Task) -> dict:
    """Run one scenario; its summary (JSON-ready), with its recording if `task.record`.

    The recording is a rosbag2 folder's files ({name: bytes}) under `RECORDING`: a run
    on a cluster's worker writes nothing on that machine's disk.
    """
    design = task.design
    robot = robots.load(design["robot"], design["base_link"] or None,
                        design["tip_link"] or None, task_space=design["task"])
    critical = tuple(tuple(p) for p in design["critical"])
    box = tuple(np.array(side) for side in design["box"])
    joint, lock_time = draw(task.seed, robot.joint_names)
    points, marks = tour(critical, waypoints(robot, box, critical, task.seed))
    config = ScenarioConfig(
        robot=design["robot"], base_link=design["base_link"], tip_link=design["tip_link"],
        task_space=design["task"], points=points, critical=marks, resolution=task.mode,
        soft_limits=task.soft, soft_box=tuple(tuple(side) for side in design["box"]),
        lock_joint=joint, lock_time=lock_time,
        duration=LOCK_WINDOW[1] + GOAL_TIMEOUT + len(critical) * design["tour_timeout"],
        rate=125.0, seed=task.seed, goal_tolerance=GOAL_TOLERANCE, goal_timeout=GOAL_TIMEOUT,
        tour_timeout=design["tour_timeout"], recovery=design["recovery"], **design["plant"])
    if multiprocessing.current_process().daemon:  # the controller's planner cannot start
        raise RuntimeError("a campaign run cannot run in a daemonic process (a Dask worker "
                           "started without DASK_DISTRIBUTED__WORKER__DAEMON=False)")
    # Discovery on this machine only, whatever the environment says: runs on other
    # machines of a cluster may use the same domain id.
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    with domains.lease(task.first_domain, DOMAIN_COUNT) as domain, \
            tempfile.TemporaryDirectory(prefix="ft_campaign_run_") as scratch:
        bag = Path(scratch) / "bag" if task.record else None
        record = run(config, domain_id=domain, bag=bag)
        recording = {path.name: path.read_bytes() for path in sorted(bag.iterdir())} \
            if bag is not None else None
    summary = summarise(config, record)
    j = robot.joint_names.index(joint)
    value = summary["locked_value"]
    q_lock = record.arrays()["q"][int(np.searchsorted(record.t, record.injected_at))] \
        if value is not None else None
    possible = None if q_lock is None else reachable(robot, critical, q_lock, j)
    summary.update(seed=task.seed, soft_limits=task.soft,
                   success=len(summary["reached_after"]) == summary["points"],
                   correct_detection=summary["detected"] == [joint],
                   outside_box=value is not None and not bool(box[0][j] <= value <= box[1][j]),
                   reachable=None if possible is None else len(possible),
                   reachable_points=possible,
                   reached_points=[marks.index(i) for i in summary["reached_after"]
                                   if i in marks],
                   last_joint=robot.joint_names[-1])
    if recording is not None:
        summary[RECORDING] = recording
    return summary


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
              recovery: bool = True, points: str = "task", task: str = "position") -> dict:
    """What every run of a campaign shares: arm, task, plant, recovery, critical points, box.

    `points`: the critical-point set (`POINT_SETS`). Raises selfmotion.UnreachableError
    when the critical points have no common box, robots.RobotModelError when the chain
    cannot follow the task or has no joint to spare for it (after a lock it could not go
    on, and there is no self-motion to bound).
    """
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
            "recovery": recovery, "tour_timeout": TOUR_TIMEOUT}


def tasks(runs: int, modes: tuple[str, ...], first_domain: int, design: dict,
          record: bool = False) -> list[Task]:
    """Every run: each seed under each mode, without and with soft limits."""
    return [Task(seed, mode, soft, design, first_domain, record) for seed in range(runs)
            for mode in modes for soft in (False, True)]


def kept(out: Path, task: Task) -> Path:
    """Where a finished run is kept: one folder per campaign design, one file per run."""
    options = hashlib.sha256(json.dumps(task.design, sort_keys=True).encode()).hexdigest()[:12]
    return out / "runs" / options / f"{task.name}.json"


def wilson(successes: int, runs: int) -> tuple[float, float]:
    """95 % Wilson score interval of a success rate."""
    interval = stats.binomtest(successes, runs).proportion_ci(0.95, method="wilson")
    return float(interval.low), float(interval.high)


def _rate(successes: int, runs: int) -> str:
    if not runs:
        return "-"
    low, high = wilson(successes, runs)
    return f"{successes}/{runs} ({100 * successes / runs:.0f} %, {100 * low:.0f}-{100 * high:.0f})"


def table(results: list[dict]) -> str:
    """Markdown tables: each condition, then the runs whose outcome soft limits changed.

    Per condition: success with its CI, IK reachability after the lock, success where
    every point stays reachable and where the last joint locked (the tool's own axis in a
    position task), runs in which the controller followed a recovery path, the lock
    against the box, waypoints, detection, the velocity jump, and the commands against
    the arm's limits (the sim's driver: runs it stopped, the largest commanded
    acceleration and jerk over the limits).
    """
    lines = ["| condition | runs | success (%, 95 % CI) | every point reachable (IK) | "
             "success where every point is reachable | success, last joint locked | "
             "runs with a recovery path | "
             "lock outside the box | waypoints reached | right joint detected "
             "| runs with a false lock "
             "| detection latency median / max (ms) | velocity jump median / max (rad/s) "
             "| driver reflexes | peak acceleration / jerk over the limits |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    modes = [m for m in MODES if any(r["resolution"] == m for r in results)]
    for mode in modes:
        for soft in (False, True):
            group = [r for r in results if r["resolution"] == mode and r["soft_limits"] == soft]
            if not group:
                continue
            latency = [r["latency_ms"] for r in group if r["latency_ms"] is not None]
            jump = [r["velocity_jump"] for r in group if r["velocity_jump"] is not None]
            visits = [v for r in group for v in r["waypoint_visits"]]
            possible = [r for r in group if r["reachable"] == r["points"]]
            last = [r for r in group if r["locked"] == r["last_joint"]]
            peaks = [(r.get("peak_acceleration") or 0.0, r.get("peak_jerk") or 0.0)
                     for r in group]
            lines.append(
                f"| {mode}, {'with' if soft else 'without'} soft limits | {len(group)} | "
                f"{_rate(sum(r['success'] for r in group), len(group))} | "
                f"{_rate(len(possible), len(group))} | "
                f"{_rate(sum(r['success'] for r in possible), len(possible))} | "
                f"{_rate(sum(r['success'] for r in last), len(last))} | "
                f"{sum(r.get('recovery_paths', 0) > 0 for r in group)}/{len(group)} | "
                f"{sum(r['outside_box'] for r in group)}/{len(group)} | "
                f"{100 * np.mean(visits) if visits else 0:.0f} % | "
                f"{sum(r['correct_detection'] for r in group)}/{len(group)} | "
                f"{sum(bool(r.get('false_locks')) for r in group)}/{len(group)} | "
                f"{_stat(latency, '.0f')} | {_stat(jump, '.2f')} | "
                f"{sum(bool(r.get('reflex')) for r in group)}/{len(group)} | "
                f"{max(p[0] for p in peaks):.3g} / {max(p[1] for p in peaks):.3g} |")
    lines += ["", "| mode | paired runs | failed only without soft limits | failed only with "
              "them | exact McNemar p |", "|---|---:|---:|---:|---:|"]
    for mode in modes:
        pairs = _pairs(results, mode)
        if not pairs:
            continue
        only_free = sum(soft["success"] and not free["success"] for free, soft in pairs)
        only_soft = sum(free["success"] and not soft["success"] for free, soft in pairs)
        p = stats.binomtest(only_free, only_free + only_soft).pvalue if only_free + only_soft \
            else 1.0
        lines.append(f"| {mode} | {len(pairs)} | {only_free} | {only_soft} | {p:.2g} |")
    return "\n".join(lines) + "\n"


def points_table(results: list[dict]) -> str:
    """Markdown: per locked joint and critical point, reached against reachable.

    A cell is "reached / reachable (IK)" over the runs in which that joint locked, without
    and with soft limits (every mode together): the runs in which the point stayed
    reachable with the joint pinned, and how many of them reached it after the lock.
    Runs without a lock (none injected) are left out.
    """
    done = [r for r in results if r.get("reachable_points") is not None]
    if not done:
        return ""
    count = max(r["points"] for r in done)
    header = " | ".join(f"point {k + 1} {side}" for k in range(count)
                        for side in ("without", "with"))
    lines = [f"| locked joint | {header} |", "|---|" + "---:|" * (2 * count)]
    for joint in sorted({r["locked"] for r in done}):
        cells = []
        for k in range(count):
            for soft in (False, True):
                group = [r for r in done if r["locked"] == joint and r["soft_limits"] == soft
                         and k in r["reachable_points"]]
                cells.append(f"{sum(k in r['reached_points'] for r in group)}/{len(group)}")
        lines.append(f"| {joint} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _pairs(results: list[dict], mode: str) -> list[tuple[dict, dict]]:
    """(without, with soft limits) runs of `mode` that share a seed."""
    by = {(r["seed"], r["soft_limits"]): r for r in results if r["resolution"] == mode}
    return [(by[seed, False], by[seed, True]) for seed, soft in sorted(by)
            if not soft and (seed, True) in by]


def _stat(values: list[float], fmt: str) -> str:
    if not values:
        return "n/a"
    return f"{np.median(values):{fmt}} / {np.max(values):{fmt}}"


def figure(results: list[dict], path: Path) -> None:
    """Success rates with their 95 % intervals, latency and jump distributions."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    conditions = [(m, s) for m in MODES for s in (False, True)
                  if any(r["resolution"] == m and r["soft_limits"] == s for r in results)]
    groups = [[r for r in results if r["resolution"] == m and r["soft_limits"] == s]
              for m, s in conditions]
    labels = [f"{m}\n{'soft' if s else 'no soft'}" for m, s in conditions]
    rates = np.array([np.mean([r["success"] for r in g]) for g in groups])
    intervals = np.array([wilson(sum(r["success"] for r in g), len(g)) for g in groups])
    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    axes[0].bar(labels, rates, color=["tab:gray" if not s else "tab:blue"
                                      for _, s in conditions])
    axes[0].errorbar(labels, rates, yerr=[rates - intervals[:, 0], intervals[:, 1] - rates],
                     fmt="none", color="k", capsize=3)
    axes[0].set_ylabel("success rate (95 % CI)")
    axes[1].boxplot([[r["latency_ms"] for r in g if r["latency_ms"] is not None] or [0]
                     for g in groups], tick_labels=labels)
    axes[1].set_ylabel("detection latency (ms)")
    axes[2].boxplot([[r["velocity_jump"] for r in g if r["velocity_jump"] is not None] or [0]
                     for g in groups], tick_labels=labels)
    axes[2].set_ylabel("joint velocity jump (rad/s)")
    for ax in axes:
        ax.tick_params(axis="x", labelsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def execute(todo: list[Task], out: Path, where: batch.Where) -> int:
    """Run `todo` (`batch.run`), keeping each result as it finishes; how many crashed.

    Each result is written here, by the client, with its recording (a folder of the
    run's name beside it), whether the run was local or on a cluster's worker.
    """
    crashed = 0
    for outcome in batch.run(one_run, todo, where, what="run"):
        task = todo[outcome.index]
        if outcome.error is not None:  # reported, not kept: a rerun retries it
            crashed += 1
            tqdm.write(f"run {task.name} crashed: {outcome.error!r}", file=sys.stderr)
            continue
        result, path = dict(outcome.result), kept(out, task)
        recording = result.pop(RECORDING, None)
        if recording is not None:
            folder = path.with_suffix("")
            if folder.exists():
                shutil.rmtree(folder)
            folder.mkdir(parents=True)
            for name, content in recording.items():
                (folder / name).write_bytes(content)
        path.write_text(json.dumps(result) + "\n")
    return crashed


def parser() -> argparse.ArgumentParser:
    """`ft-campaign`'s command line (every number bounded: `cli.bounded`)."""
    parser = argparse.ArgumentParser(prog="ft-campaign", description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=cli.bounded(int, 1, MAX_RUNS), default=20,
                        help=f"seeds per condition (1 to {MAX_RUNS})")
    parser.add_argument("--modes", nargs="+", choices=MODES, default=list(MODES),
                        help="resolution modes, each with and without soft limits")
    batch.add_arguments(parser)
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--record", action="store_true",
                        help="keep every run's topics as a rosbag2 (MCAP) beside its result")
    parser.add_argument("--robot", help="built-in name or URDF path (default panda, "
                        f"{PHYSICS_ROBOT} with --plant physics)")
    parser.add_argument("--plant", default="kinematic", choices=["kinematic", "physics"],
                        help="the sim's plant (physics: MuJoCo, docs/sim.md)")
    parser.add_argument("--base-link", default="", help="first link of the chain")
    parser.add_argument("--tip-link", default="", help="tool link of the chain")
    parser.add_argument("--task", default="position", choices=["position", "pose", "planar"],
                        help="task space (default %(default)s; planar for a planar arm)")
    parser.add_argument("--latency", type=cli.bounded(float, 0.0, 1.0), default=0.0,
                        help="plant latency (s, 0 to 1)")
    parser.add_argument("--response-time", type=cli.bounded(float, 0.0, 1.0), default=0.0,
                        help="plant velocity response time (s, 0 to 1)")
    parser.add_argument("--hold-last-command", action="store_true",
                        help="the plant holds the last command (ros2_control)")
    parser.add_argument("--no-recovery", action="store_true",
                        help="the controller without its recovery after a lock")
    parser.add_argument("--points", default="task", choices=POINT_SETS,
                        help="critical points: the arm's task points, or near the boundary "
                        "of its workspace (small boxes)")
    parser.add_argument("--first-domain", type=cli.bounded(int, 0, 232),
                        default=int(os.environ.get("ROS_DOMAIN_ID", "29")) + 1,
                        help="first DDS domain id of the runs (default ROS_DOMAIN_ID + 1)")
    return parser


@cli.clear_file_errors("ft-campaign")
def main(argv: list[str] | None = None) -> int:
    """Run the campaign and write its outputs; 0 unless a run crashed or went non-finite."""
    arguments = parser()
    args = arguments.parse_args(argv)
    args.robot = args.robot or (PHYSICS_ROBOT if args.plant == "physics" else "panda")
    plant = {"plant": args.plant, "command_latency": args.latency,
             "response_time": args.response_time, "hold_last_command": args.hold_last_command}
    try:
        design = design_of(args.robot, args.base_link, args.tip_link, plant,
                           not args.no_recovery, args.points, args.task)
    except robots.RobotModelError as error:
        arguments.error(f"--robot: {error}")
    except selfmotion.UnreachableError as error:
        print(f"ft-campaign: the critical points chosen for this arm have no common "
              f"soft-limit box ({error}); try another --tip-link", file=sys.stderr)
        return 1
    every = tasks(args.runs, tuple(args.modes), args.first_domain, design, args.record)
    todo = [task for task in every if not kept(args.out, task).exists()]
    where = batch.Where.from_arguments(args)
    print(f"{len(every)} runs ({len(every) - len(todo)} kept from before) "
          f"{where.describe()}; critical points {design['critical']} ...", flush=True)
    if every:
        kept(args.out, every[0]).parent.mkdir(parents=True, exist_ok=True)
    try:
        started = time.monotonic()
        crashed = execute(todo, args.out, where)
        elapsed = time.monotonic() - started
    except KeyboardInterrupt:
        done = sum(kept(args.out, task).exists() for task in every)
        print(f"\nft-campaign: interrupted; {done} of {len(every)} runs kept in {args.out} "
              "(the same command resumes)", file=sys.stderr)
        return 130
    results = [json.loads(kept(args.out, task).read_text()) for task in every
               if kept(args.out, task).exists()]
    text = table(results) + "\n" + points_table(results) if results else "no finished runs\n"
    if todo:
        text += (f"\n{len(todo) - crashed} runs in {elapsed:.0f} s {where.describe()}: "
                 f"{3600 * (len(todo) - crashed) / max(elapsed, 1e-9):.0f} runs per hour\n")
    (args.out / "campaign.md").write_text(text)
    (args.out / "campaign.json").write_text(json.dumps(results, indent=1) + "\n")
    if results:
        figure(results, args.out / "campaign.png")
    print(text)
    if crashed:
        print(f"{crashed} runs crashed (not kept: a rerun retries them)", file=sys.stderr)
    return 0 if not crashed and not any(r["non_finite"] for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
