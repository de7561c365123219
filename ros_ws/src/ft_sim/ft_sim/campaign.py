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
make it realistic. `--fault KIND[:VALUE]` makes the drawn joint fail another way
(`ft_core.faults.parse_spec`; docs/sim.md#faults): `correct_detection` then says whether it
was declared locked, and the points counted reachable are those reachable with it pinned
(fewer than it may still reach while it moves).

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
from pathlib import Path

import numpy as np
from ft_core import faults, robots, selfmotion
from ft_core.engine import RESOLUTIONS
from ft_core.offline import batch, cli
from tqdm import tqdm

from ft_sim import domains
from ft_sim.campaign_design import (
    BOUNDARY,
    FAR,
    GOAL_TIMEOUT,
    GOAL_TOLERANCE,
    LOCK_WINDOW,
    POINT_SETS,
    TOUR_TIMEOUT,
    WAYPOINTS,
    Task,
    boundary_points,
    critical_points,
    design_of,
    draw,
    reachable,
    tasks,
    tour,
    waypoints,
)
from ft_sim.campaign_report import figure, points_table, table, wilson
from ft_sim.demo import summarise
from ft_sim.scenario import PHYSICS_ROBOT, TASK_POINTS, ScenarioConfig, run

__all__ = ["BOUNDARY", "DOMAIN_COUNT", "FAR", "GOAL_TIMEOUT", "GOAL_TOLERANCE", "LOCK_WINDOW",
           "MAX_RUNS", "MODES", "PHYSICS_ROBOT", "POINT_SETS", "RECORDING", "TASK_POINTS",
           "TOUR_TIMEOUT", "WAYPOINTS", "Task", "boundary_points", "critical_points",
           "design_of", "draw", "execute", "figure", "kept", "main", "one_run", "parser",
           "points_table", "reachable", "table", "tasks", "tour", "waypoints", "wilson"]

#: The resolution modes a campaign compares (`--modes`): the engine's.
MODES = RESOLUTIONS
#: Most seeds per condition.
MAX_RUNS = 100_000
#: DDS domains a run may lease from `--first-domain` on (`domains.lease`).
DOMAIN_COUNT = 100
#: The key of a result that carries the run's recording ({file name: bytes}).
RECORDING = "_recording"


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
        lock_joint=joint, lock_time=lock_time, fault=design.get("fault", "lock"),
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


def kept(out: Path, task: Task) -> Path:
    """Where a finished run is kept: one folder per campaign design, one file per run."""
    options = hashlib.sha256(json.dumps(task.design, sort_keys=True).encode()).hexdigest()[:12]
    return out / "runs" / options / f"{task.name}.json"


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
    parser.add_argument("--fault", default="lock", metavar="KIND[:VALUE]",
                        help="what fails in each run (as ft-demo's --fault; default "
                        "%(default)s)")
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
                           not args.no_recovery, args.points, args.task, args.fault)
    except robots.RobotModelError as error:
        arguments.error(f"--robot: {error}")
    except faults.FaultError as error:
        arguments.error(f"--fault: {error}")
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
