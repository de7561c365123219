"""`ft-bounds`: boxes, intersection, verdicts, exit codes and the parameters file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from ft_core import robots, selfmotion
from ft_core.offline import bounds, cli


def run(tmp_path: Path, *args: str) -> tuple[int, Path]:
    output = tmp_path / "bounds.yaml"
    return bounds.main([*args, "--output", str(output)]), output


def test_writes_soft_limits_the_controller_accepts(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture) -> None:
    status, output = run(tmp_path, "--robot", "panda", "--task", "position",
                         "--points", "0.5,0.1,0.4; 0.45,-0.15,0.35")
    assert status == 0
    printed = capsys.readouterr().out
    assert "intersection" in printed and "every point is reachable" in printed
    params = yaml.safe_load(output.read_text())["/**"]["ros__parameters"]
    assert params["robot_model"] == "panda" and params["task_space"] == "position"
    assert params["critical_points"] == [0.5, 0.1, 0.4, 0.45, -0.15, 0.35]
    lower = np.array(params["soft_limits"]["lower"])
    upper = np.array(params["soft_limits"]["upper"])
    robot = robots.load("panda", task_space="position")
    assert np.all(lower <= upper)
    assert np.all(lower >= robot.lower) and np.all(upper <= robot.upper)
    targets = [np.array(p) for p in ([0.5, 0.1, 0.4], [0.45, -0.15, 0.35])]
    expected = selfmotion.intersect([  # seeded from the home configuration, as the CLI
        selfmotion.bounding_box(robot, t, selfmotion.find_seed(robot, t, robot.home()))
        for t in targets])
    np.testing.assert_allclose(lower, expected[0], atol=1e-9)
    np.testing.assert_allclose(upper, expected[1], atol=1e-9)


def test_unbounded_joints_are_written_as_large_finite_limits(tmp_path: Path) -> None:
    status, output = run(tmp_path, "--robot", "planar3r", "--task", "planar",
                         "--points", "0.6,0.8")  # one link from the base: full circles
    assert status == 0
    params = yaml.safe_load(output.read_text())["/**"]["ros__parameters"]
    assert params["soft_limits"]["lower"] == [-bounds.UNBOUNDED] * 3
    assert params["soft_limits"]["upper"] == [bounds.UNBOUNDED] * 3


@pytest.mark.parametrize(("args", "status", "message"), [
    (["--robot", "panda", "--points", "1.5,0,0.3"], 3, "out of reach"),
    (["--robot", "planar3r", "--task", "planar", "--points", "2.9,0;-2.9,0.2"], 4,
     "do not intersect"),
    (["--robot", "no_such_robot", "--points", "1,2,3"], 1, "unknown robot model"),
    (["--robot", "panda", "--points", "0.5,0.1"], 1, "multiple of 3"),
    (["--robot", "panda", "--points", "0.5,0.1,0.4", "--seed", "0,0"], 1, "7 joint values"),
])
def test_failures_exit_non_zero_with_a_clear_message_and_write_nothing(
        tmp_path: Path, capsys: pytest.CaptureFixture, args: list[str], status: int,
        message: str) -> None:
    code, output = run(tmp_path, *args)
    assert code == status
    assert message in capsys.readouterr().err
    assert not output.exists()


def test_pose_points_use_position_and_quaternion() -> None:
    robot = robots.load("panda")
    q = np.array([0.1, -0.3, 0.2, -2.0, 0.3, 1.5, 0.4])
    pose = robot.forward(q)
    w = np.sqrt(1 + np.trace(pose[:3, :3])) / 2
    quaternion = [(pose[2, 1] - pose[1, 2]) / (4 * w), (pose[0, 2] - pose[2, 0]) / (4 * w),
                  (pose[1, 0] - pose[0, 1]) / (4 * w), w]
    (target,) = selfmotion.targets_from_flat(robot, [*pose[:3, 3], *quaternion])
    np.testing.assert_allclose(target, pose, atol=1e-12)
    with pytest.raises(ValueError, match="multiple of 7"):
        selfmotion.targets_from_flat(robot, [0.0] * 6)


def test_an_arm_without_a_home_is_seeded_from_a_bent_configuration(tmp_path) -> None:
    """Issue 15 (in part): ft-bounds on a user's URDF seeded from the all-zero pose."""
    from models import chain_urdf

    urdf = tmp_path / "arm7.urdf"
    urdf.write_text(chain_urdf("zyzyzyz", name="arm7"))
    robot = robots.load(str(urdf), task_space="position")
    points = selfmotion.points_around(robot, selfmotion.bent_configuration(robot))
    text = ";".join(",".join(f"{v:.5f}" for v in p) for p in points)
    output = tmp_path / "soft.yaml"
    assert bounds.main(["--robot", str(urdf), "--task", "position", f"--points={text}",
                        "--output", str(output)]) == 0
    params = yaml.safe_load(output.read_text())["/**"]["ros__parameters"]
    assert len(params["soft_limits"]["lower"]) == robot.n


def test_without_points_it_chooses_them_around_the_seed_and_says_which(
        tmp_path: Path, capsys) -> None:
    """Issue 15: `ft-bounds --robot <urdf>` alone, on the real-world Panda URDF."""
    from paths import PANDA_URDF

    output = tmp_path / "soft.yaml"
    assert bounds.main(["--robot", str(PANDA_URDF), "--output", str(output)]) == 0
    out = capsys.readouterr().out
    assert "no --points: chose 3 around the seed: --points " in out
    chosen = out.split("--points ")[1].split("\n")[0].strip('"')
    params = yaml.safe_load(output.read_text())["/**"]["ros__parameters"]
    np.testing.assert_allclose(params["critical_points"], cli.parse_points(chosen),
                               atol=1e-4)
    robot = robots.load(str(PANDA_URDF), task_space="position")
    start = selfmotion.bent_configuration(robot)
    np.testing.assert_allclose(np.reshape(params["critical_points"], (3, 3)),
                               selfmotion.points_around(robot, start), atol=1e-4)
    lower, upper = np.array(params["soft_limits"]["lower"]), np.array(
        params["soft_limits"]["upper"])
    assert np.all(lower <= start + 1e-9) and np.all(start <= upper + 1e-9)


def test_chosen_pose_points_round_trip_and_a_thin_intersection_says_what_to_try(
        tmp_path: Path, capsys) -> None:
    """Pose points are written as position and quaternion and read back as the same poses.

    The default points of a pose task (0.15 rad apart around the Panda's home) share a
    box; 0.3 rad apart, the 1-D self-motion curves give boxes whose intersection
    misses two of the points: exit 4 with advice.
    """
    robot = robots.load("panda", task_space="pose")
    code, output = run(tmp_path, "--robot", "panda", "--task", "pose")
    assert code == 0
    params = yaml.safe_load(output.read_text())["/**"]["ros__parameters"]
    chosen = selfmotion.points_around(robot, robot.home())
    for target, expected in zip(selfmotion.targets_from_flat(robot, params["critical_points"]),
                                chosen, strict=True):
        np.testing.assert_allclose(target, expected, atol=1e-9)
    apart = selfmotion.flat_from_targets(robot, selfmotion.points_around(robot, robot.home(),
                                                                         step=0.3))
    text = ";".join(",".join(f"{v:.9f}" for v in apart[i:i + 7]) for i in range(0, 21, 7))
    output.unlink()
    code, output = run(tmp_path, "--robot", "panda", "--task", "pose", f"--points={text}")
    assert code == 4 and not output.exists()
    assert "cannot be reached inside the intersection: try fewer or closer points" in (
        capsys.readouterr().err)


FIXTURES = sorted(p.name for p in (Path(robots.__file__).parent / "urdf").glob("*.urdf"))


@pytest.mark.parametrize("task", ["position", "pose"])
@pytest.mark.parametrize("fixture", FIXTURES)
def test_every_urdf_fixture_with_robot_and_task_alone(fixture: str, task: str, tmp_path: Path,
                                                      capsys) -> None:
    """Issue 32: `ft-bounds --robot <urdf> --task T` on every URDF of the repository.

    Soft limits where the task is redundant; where it is not (as many joints as task
    coordinates or fewer: the PUMA 560's pose task, the planar 3R's position task) exit
    status 4 with the reason, and a 3-joint arm cannot follow a pose task at all (1).
    """
    urdf = Path(robots.__file__).parent / "urdf" / fixture
    robot = robots.load(str(urdf), task_space=task)
    code, output = run(tmp_path, "--robot", str(urdf), "--task", task)
    err = capsys.readouterr().err
    if robot.n < robot.m:
        assert code == 1 and "cannot follow it" in err, err
    elif robot.n <= robot.m:
        assert code == 4 and "no redundancy" in err, err
        assert not output.exists()
    else:
        assert code == 0, err
        params = yaml.safe_load(output.read_text())["/**"]["ros__parameters"]
        assert len(params["soft_limits"]["lower"]) == robot.n
