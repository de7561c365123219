"""The whole loop: sim, controller and monitor on real topics, a joint locked mid-task."""

from __future__ import annotations

import ast
import json
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import psutil
import pytest
import yaml
from ft_core import robots, selfmotion, workers
from ft_sim import campaign, demo, scenario
from ft_sim.scenario import ScenarioConfig, run
from models import chain_urdf
from paths import PANDA_URDF, REPO
from rosutil import fresh_domain


@pytest.mark.slow
def test_the_demo_story_holds_and_its_recording_reads_back(tmp_path: Path) -> None:
    """Short demo: right joint detected, task continued, every point reached, all finite.

    Its rosbag2 (MCAP) reads back with rosbags and holds the lock as it happened.
    """
    assert demo.main(["--joint", "panda_joint4", "--lock-time", "3", "--record", "--out",
                      str(tmp_path)]) == 0
    text = (tmp_path / "report.md").read_text()
    assert "detected | panda_joint4" in text and "3 of 3" in text
    assert (tmp_path / "demo.png").stat().st_size > 10_000
    assert (tmp_path / "arm.png").stat().st_size > 10_000
    topics = recorded(tmp_path / "bag")
    metadata = yaml.safe_load((tmp_path / "bag" / "metadata.yaml").read_text())
    assert metadata["rosbag2_bagfile_information"]["ros_distro"] == "jazzy"
    assert set(topics) == {"/joint_states", "/ft/target_pose", "/ft/command_raw", "/ft/command",
                           "/ft/locked_joints", "/ft/joint_health", "/ft/inject_failure",
                           "/ft/inject_fault", "/ft/obstacle", "/ft/metrics", "/diagnostics"}
    assert len(topics["/joint_states"]) > 1000  # 250 Hz for several simulated seconds
    (injected_ns, injection), = topics["/ft/inject_failure"]
    assert list(injection.name) == ["panda_joint4"]
    locks = [(t, list(msg.name)) for t, msg in topics["/ft/locked_joints"] if list(msg.name)]
    assert locks and locks[0][1] == ["panda_joint4"]
    assert 0 < locks[0][0] - injected_ns < 2e9  # logged in simulated time, after the lock
    detected = float(text.split("detected | panda_joint4 at ")[1].split(" s")[0])
    assert abs(locks[0][0] / 1e9 - detected) < 0.1
    _, health = topics["/ft/joint_health"][-1]  # each joint's state, recorded as published
    assert {s.name: s.message for s in health.status if s.message != "healthy"} == {
        "panda_joint4": "locked"}


def recorded(bag: Path) -> dict[str, list[tuple[int, object]]]:
    """Every message of a rosbag2, by topic: (log time in ns, message)."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    topics: dict[str, list[tuple[int, object]]] = {}
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        assert [path.suffix for path in reader.paths] == [""]
        assert {c.msgtype for c in reader.connections} >= {"sensor_msgs/msg/JointState"}
        topics = {c.topic: [] for c in reader.connections}
        for connection, t, raw in reader.messages():
            topics[connection.topic].append((t, reader.deserialize(raw, connection.msgtype)))
    return topics


@pytest.mark.slow
def test_the_demo_on_a_real_world_urdf(tmp_path: Path) -> None:
    """Issue 15 (in part): `ft-demo --robot <urdf>`, here example-robot-data's Panda."""
    assert demo.main(["--robot", str(PANDA_URDF), "--joint", "panda_joint4", "--lock-time",
                      "3", "--duration", "14", "--out", str(tmp_path)]) == 0
    text = (tmp_path / "report.md").read_text()
    assert "detected | panda_joint4" in text and "3 of 3" in text


@pytest.mark.slow
def test_the_demo_with_a_pose_task_on_a_real_world_urdf(tmp_path: Path) -> None:
    """Issue 15: `--task pose`: pose points chosen around the home, soft limits from them."""
    assert demo.main(["--robot", str(PANDA_URDF), "--task", "pose", "--joint", "4",
                      "--out", str(tmp_path)]) == 0
    text = (tmp_path / "report.md").read_text()
    assert "detected | panda_joint4" in text and "3 of 3" in text
    assert "| soft limits | 3 critical points |" in text


@pytest.mark.slow
def test_the_demo_on_an_arm_without_task_points(tmp_path: Path, capsys) -> None:
    """A synthetic 7-joint URDF: task points are chosen around a bent configuration."""
    urdf = tmp_path / "arm7.urdf"
    urdf.write_text(chain_urdf("zyzyzyz", name="arm7"))
    status = demo.main(["--robot", str(urdf), "--joint", "j2", "--lock-time", "4",
                        "--duration", "16", "--out", str(tmp_path)])
    assert status in (0, 1)  # 1: the story did not hold on this arm; the report says why
    assert "task points [[" in capsys.readouterr().out
    text = (tmp_path / "report.md").read_text()
    assert "detected | j2" in text
    assert (tmp_path / "demo.png").stat().st_size > 10_000


@pytest.mark.slow
@pytest.mark.parametrize(("robot", "task"), [
    ("panda", "position"), ("panda", "pose"), (str(PANDA_URDF), "position"),
    (str(PANDA_URDF), "pose"),
    ("iiwa14", "position"), ("iiwa14", "pose"), ("puma560", "position"),
    ("puma560", "pose"), ("planar3r", "planar")])
def test_the_demo_holds_on_every_arm_with_robot_and_task_alone(
        tmp_path: Path, robot: str, task: str) -> None:
    """Issue 30: `ft-demo --robot R --task T` holds on each arm fixture.

    Example-robot-data's Panda among them: the right joint detected and every task point
    reached after the lock.

    Where the locked arm cannot reach a point (a 6-joint arm's pose task), the demo
    replaces it by one it can reach, and the report says so. Soft limits come from the
    task points wherever redundancy leaves boxes to trace.
    """
    status = demo.main(["--robot", robot, "--task", task, "--out", str(tmp_path)])
    text = (tmp_path / "report.md").read_text()
    redundant = not (robot == "puma560" and task == "pose")
    assert ("| soft limits | 3 critical points |" in text) == redundant
    assert "Verdict: the task went on after the failure." in text, text
    assert status == 0
    reached = text.split("| task points reached after the lock | ")[1].split(" |")[0]
    count, points = reached.split(" of ")
    assert count == points and int(points) >= 2
    replaced = text.split("| task points out of the locked arm's reach, replaced | ")[1]
    if robot == "puma560" and task == "pose":  # 5 joints left for 6 task coordinates
        assert replaced.startswith("point ")


@pytest.mark.slow
def test_undetected_failure_spoils_tracking_and_detection_restores_it() -> None:
    config = ScenarioConfig(lock_joint="panda_joint2", lock_time=3.0, duration=12.0)
    record = run(config, domain_id=fresh_domain())
    summary = demo.summarise(config, record)
    assert summary["detected"] == ["panda_joint2"]
    # The plant follows the monitor's command, which smooths the controller's again from
    # its own state: the two differ by a few mm/s at most where the ramps meet the limits.
    assert summary["error_before"] < 0.01
    # Once detected, the healthy joints reach the reduced solution within their limits
    # (0.1 to 0.2 s on the Panda); from then on the tool follows again: on the goal it was
    # spoiled on, and on the goals after it within the few mm/s of the monitor's smoothing
    # where a new goal's ramps meet the limits, as before the failure.
    a = record.arrays()
    t, error, goal = a["t"], a["tool_velocity_error"], a["goal"]
    after = t > record.detected_at + 0.3
    visit = np.cumsum(np.diff(goal, prepend=goal[0]) != 0)  # index of the goal's visit
    same_goal = after & (visit == visit[np.searchsorted(t, record.detected_at)])
    assert same_goal.sum() > 0.5 * 250  # half a second on it at least (250 Hz)
    assert summary["error_during"] > 10 * error[same_goal].max()
    assert error[after].max() < 0.01
    assert summary["error_after"] < summary["error_during"]
    assert summary["non_finite"] == 0
    assert demo.verdict(summary) == []


@pytest.mark.slow
@pytest.mark.parametrize(("soft", "plant"), [(True, "kinematic"), (False, "physics")])
def test_a_campaign_run(soft: bool, plant: str) -> None:
    """One run per condition on the real-world Panda URDF and a realistic plant.

    Without soft limits on the MuJoCo plant (`ft-campaign --plant physics`, issue 29):
    servo lag, overshoot and gravity, the lock found on the right joint, no false one.
    """
    design = campaign.design_of(str(PANDA_URDF), "", "", {
        "plant": plant, "command_latency": 0.02, "response_time": 0.02,
        "hold_last_command": True})
    result = campaign.one_run(campaign.Task(3, "blend", soft, design, fresh_domain()))
    assert result["false_locks"] == []
    assert result["correct_detection"] and result["non_finite"] == 0
    assert len(result["waypoint_visits"]) >= 2  # it wandered before the lock
    if soft:  # the guarantee of the bounding boxes: locked inside, every point reachable
        assert not result["outside_box"] and result["reachable"] == 3
    row = campaign.table([result]).splitlines()[2]
    assert row.startswith(f"| blend, {'with' if soft else 'without'} soft limits | 1 |")


def _plan_in_a_worker() -> tuple[int, int]:
    """In a pool's process: the shared planner runs a job; (this pid, the planner's pid)."""
    return os.getpid(), scenario.planner().submit(os.getpid).result(timeout=60)


def _running(pid: int) -> bool:
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def test_the_scenarios_of_a_process_share_one_worker_process() -> None:
    """Issue 33: one planner process per process, replaced once gone, ended at exit.

    A campaign worker that ran scenarios must still exit: without the finalizer, its
    exit waited for the planner, which waited for work (the campaign hung at its end).
    """
    first = scenario.planner()
    assert scenario.planner() is first
    first.shutdown()
    second = scenario.planner()
    assert second is not first
    assert second.submit(os.getpid).result(timeout=60) != os.getpid()
    scenario.stop_planner()
    pool = ProcessPoolExecutor(max_workers=1, mp_context=workers.SPAWN)
    worker, planner = pool.submit(_plan_in_a_worker).result(timeout=120)
    assert _running(worker) and _running(planner) and planner != worker
    pool.shutdown(wait=False)
    deadline = time.monotonic() + 30.0
    try:
        while (_running(worker) or _running(planner)) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not _running(worker) and not _running(planner)
    finally:
        for pid in (worker, planner):
            if _running(pid):
                psutil.Process(pid).kill()


def test_the_per_point_table_counts_reached_among_reachable() -> None:
    def result(joint: str, soft: bool, reachable: list[int], reached: list[int]) -> dict:
        return {"locked": joint, "soft_limits": soft, "points": 3,
                "reachable_points": reachable, "reached_points": reached}

    rows = campaign.points_table([
        result("j1", False, [0, 1, 2], [0, 2]), result("j1", False, [0, 2], [0, 1]),
        result("j1", True, [0, 1, 2], [0, 1, 2]), result("j2", False, [1], [1]),
        {"locked": "j2", "soft_limits": True, "points": 3, "reachable_points": None},
    ]).splitlines()
    assert rows[0].startswith("| locked joint | point 1 without | point 1 with |")
    # j1 without: point 1 reachable twice, reached twice; point 2 reachable once, missed
    # (reached once where IK found it out of reach: not counted); point 3 1 of 2.
    assert rows[2] == "| j1 | 2/2 | 1/1 | 0/1 | 1/1 | 1/2 | 1/1 |"
    assert rows[3] == "| j2 | 0/0 | 0/0 | 1/1 | 0/0 | 0/0 | 0/0 |"


def test_the_boundary_set_has_smaller_boxes_than_the_task_set() -> None:
    """`--points boundary`: near the workspace boundary the boxes shrink.

    The case Lewis & Maciejewski 1997 (sec. III) mean the soft limits for (issue 30).
    """
    robot = robots.load("panda", task_space="position")
    widths = {}
    for kind in campaign.POINT_SETS:
        design = campaign.design_of("panda", "", "", {}, points=kind)
        lower, upper = (np.array(side) for side in design["box"])
        widths[kind] = (upper - lower) / (robot.upper - robot.lower)
        assert design["points"] == kind and len(design["critical"]) == 3
    boundary = np.linalg.norm(np.array(campaign.critical_points(robot, "boundary")) -
                              robot.skeleton(robot.home())[1], axis=1)
    assert boundary.min() > 0.75, boundary  # the Panda reaches about 0.86 m from its shoulder
    assert widths["boundary"].min() < 0.35 and widths["task"].min() > 0.5, widths


FIXTURES = sorted((Path(robots.__file__).parent / "urdf").glob("*.urdf"))


@pytest.mark.parametrize("task", ["position", "pose", "planar"])
@pytest.mark.parametrize("urdf", FIXTURES, ids=lambda path: path.stem)
def test_a_campaign_designs_itself_on_every_urdf_fixture(urdf: Path, task: str,
                                                          capsys) -> None:
    """Issue 32: `ft-campaign --robot <urdf> --task T` on every URDF of the repository.

    Where the task leaves joints to spare: three critical points of the task's size with
    their common box, far waypoints inside it, and the critical points reachable by
    inverse kinematics with any joint pinned at the bent configuration. Where it leaves
    none (the PUMA 560's pose task, the planar 3R's position task), or the arm cannot
    follow it (the planar 3R's pose task): exit status 2 and the reason, before any run.
    (Whole campaigns: the pose task on the iiwa 14 and the planar task on the planar 3R
    below.)
    """
    try:
        robot = robots.load(str(urdf), task_space=task)
    except robots.RobotModelError:
        robot = None
    if robot is None or robot.n <= robot.m:
        with pytest.raises(SystemExit) as exit_status:
            campaign.main(["--robot", str(urdf), "--task", task, "--runs", "1"])
        assert exit_status.value.code == 2
        assert "no redundancy" in capsys.readouterr().err or robot is None
        return
    design = campaign.design_of(str(urdf), "", "", {}, task=task)
    size = 7 if task == "pose" else robot.m
    critical = tuple(tuple(p) for p in design["critical"])
    assert design["task"] == task and [len(p) for p in critical] == [size] * 3
    lower, upper = (np.array(side) for side in design["box"])
    assert np.all(lower <= upper) and np.all(upper - lower > 0)
    far = campaign.waypoints(robot, (lower, upper), critical, seed=0)
    assert len(far) == campaign.WAYPOINTS and {len(p) for p in far} == {size}
    q = selfmotion.bent_configuration(robot)
    assert campaign.reachable(robot, critical, q, 0) != []


@pytest.mark.slow
@pytest.mark.busy_machine  # two worker processes: both cores
def test_a_campaign_on_the_planar_arm(tmp_path: Path, capsys) -> None:
    """Issue 32: `ft-campaign --robot <planar3r.urdf> --task planar`, nothing else.

    One run with and one without soft limits: the lock found on the right joint, every
    critical point reached again, no false lock and no non-finite value.
    """
    urdf = Path(robots.__file__).parent / "urdf" / "planar3r.urdf"
    status = campaign.main(["--robot", str(urdf), "--task", "planar", "--runs", "1",
                            "--modes", "blend", "--workers", "2", "--out", str(tmp_path)])
    assert "2 runs (0 kept from before)" in capsys.readouterr().out
    results = json.loads((tmp_path / "campaign.json").read_text())
    assert status == 0 and len(results) == 2
    for result in results:
        assert result["correct_detection"] and result["false_locks"] == [], result
        assert result["success"], result


def test_launch_files_compile() -> None:
    launch_files = sorted((REPO / "ros_ws" / "src").glob("*/launch/*.launch.py"))
    assert len(launch_files) == 2
    for path in launch_files:
        tree = ast.parse(path.read_text(), str(path))
        assert any(isinstance(node, ast.FunctionDef) and node.name ==
                   "generate_launch_description" for node in tree.body)
        compile(tree, str(path), "exec")


@pytest.mark.slow
@pytest.mark.busy_machine  # two worker processes: both cores
def test_a_short_campaign_on_another_arm_resumes_from_kept_runs(tmp_path: Path, capsys) -> None:
    """Issues 15 and 32: ft-campaign on another arm, resumable.

    The iiwa 14's URDF with a pose task and a realistic plant: the right joint detected,
    every critical point reached again.
    """
    urdf = Path(robots.__file__).parent / "urdf" / "iiwa14.urdf"
    arguments = ["--runs", "1", "--modes", "blend", "--workers", "2", "--robot", str(urdf),
                 "--task", "pose", "--latency", "0.02", "--response-time", "0.02",
                 "--hold-last-command", "--record", "--out", str(tmp_path)]
    assert campaign.main(arguments) == 0
    assert "2 runs (0 kept from before)" in capsys.readouterr().out
    kept = sorted((tmp_path / "runs").glob("*/*.json"))
    assert [path.name for path in kept] == ["0-blend-free.json", "0-blend-soft.json"]
    for path in kept:  # each run's recording, with the lock injected in it
        injected = recorded(path.with_suffix(""))["/ft/inject_failure"]
        assert len(injected) == 1 and json.loads(path.read_text())["locked"] in (
            injected[0][1].name)
    for result in json.loads((tmp_path / "campaign.json").read_text()):
        assert result["correct_detection"] and result["false_locks"] == [], result
        assert result["success"], result
    text = (tmp_path / "campaign.md").read_text()
    assert "runs with a false lock" in text and "| blend | 1 |" in text
    assert campaign.main(arguments) == 0  # nothing left to run
    assert "2 runs (2 kept from before)" in capsys.readouterr().out
