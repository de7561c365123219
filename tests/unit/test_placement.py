"""`ft-map`: the fault-tolerance map over the workspace and placement suggestions.

Lewis & Maciejewski 1997 sec. II: for the planar 3R with unit links, a point at distance 1 from the
base has a self-motion manifold spanning every joint's full range (normalised box
volume 1) and a point on the workspace boundary has a single configuration (volume 0).
Lewis & Maciejewski 1997 sec. III / fig. 7: the PUMA 560 at height 0.5 m, reduced to a few points.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from ft_core import robots, selfmotion
from ft_core.offline import placement

FAST = ("--step", "0.05")  # coarser tracing: the planar 3R's boxes barely change


@pytest.fixture(scope="module")
def planar() -> robots.Robot:
    return robots.load("planar3r")


def run(tmp_path: Path, *args: str) -> tuple[int, Path]:
    prefix = tmp_path / "map"
    return placement.main([*args, "--output", str(prefix), "--workers", "1"]), prefix


def load(prefix: Path) -> dict:
    with np.load(f"{prefix}.npz") as data:
        return {key: data[key] for key in data.files}


def test_axes_parse_values_and_inclusive_ranges() -> None:
    np.testing.assert_allclose(placement.parse_axis("x", "0.5"), [0.5])
    np.testing.assert_allclose(placement.parse_axis("x", "-1:1:5"), [-1, -0.5, 0, 0.5, 1])
    for bad in ("1:2", "1:2:0", "a", "1:2:2.5", "nan", "0:inf:3"):
        with pytest.raises(ValueError, match="--x"):
            placement.parse_axis("x", bad)


def test_unit_planar_3r_full_manifold_at_distance_one_and_a_point_at_the_boundary(
        planar: robots.Robot) -> None:
    q0 = planar.home()
    ring = placement.evaluate_point(planar, np.array([0.6, -0.8]), q0, step=0.05)
    assert ring.reachable and ring.continued
    # Every joint turns fully (Lewis & Maciejewski 1997 sec. II).
    assert ring.volume == pytest.approx(1.0)
    assert np.all(np.isinf(ring.lower)) and np.all(np.isinf(ring.upper))
    assert ring.volume_rad == pytest.approx((2 * math.pi) ** 3)
    boundary = placement.evaluate_point(planar, np.array([3.0, 0.0]), q0, step=0.05)
    assert boundary.reachable and boundary.volume < 1e-6  # a single configuration
    np.testing.assert_allclose(boundary.lower, boundary.upper, atol=1e-3)
    near = placement.evaluate_point(planar, np.array([2.9, 0.0]), q0, step=0.05)
    assert 1e-4 < near.volume < 0.01
    outside = placement.evaluate_point(planar, np.array([3.2, 0.0]), q0, step=0.05)
    assert not outside.reachable and outside.volume == 0.0 and math.isnan(outside.kfm)


def test_seeds_keep_the_start_posture_and_kfm_is_that_of_the_seed(
        planar: robots.Robot) -> None:
    q0 = planar.home()  # elbow (q2, q3) bent positively
    target = np.array([-1.2, 1.5])
    seed = placement.continuation_seed(planar, target, q0)
    assert seed is not None
    np.testing.assert_allclose(planar.forward(seed), target, atol=1e-8)
    assert seed[1] > 0 and seed[2] > 0
    # From the mirrored start (elbow bent negatively), the mirrored point's seed is the
    # mirrored seed: the posture is kept, not picked by whichever Newton start converges.
    mirrored = placement.continuation_seed(planar, target * [1, -1], -q0)
    assert mirrored is not None
    np.testing.assert_allclose(mirrored, -seed, atol=1e-8)
    result = placement.evaluate_point(planar, target, q0, step=0.05)
    np.testing.assert_allclose(result.seed, seed, atol=1e-9)
    assert result.kfm == pytest.approx(placement.kfm_of(planar, seed))
    assert result.kfm <= result.kfm_max + 1e-12
    assert result.kfm_max == pytest.approx(placement.kfm_of(planar, result.q_kfm))
    assert np.all(result.lower <= seed + 1e-9) and np.all(seed <= result.upper + 1e-9)


def test_restarts_find_the_other_component_with_its_own_volume(
        planar: robots.Robot) -> None:
    # Near the base the two elbow postures are separate components of equal size;
    # with the joints' limits (none here) the largest volume can only grow.
    target = np.array([0.3, 0.0])
    single = placement.evaluate_point(planar, target, planar.home(), step=0.05)
    more = placement.evaluate_point(planar, target, planar.home(), step=0.05, restarts=4)
    assert single.components == 1 and more.components == 2
    assert more.volume == pytest.approx(single.volume)
    assert more.best_volume >= more.volume - 1e-12
    assert more.best_volume == pytest.approx(single.volume, rel=0.05)


def test_line_map_end_to_end(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    status, prefix = run(tmp_path, "--robot", "planar3r", "--x", "0:3.5:8", "--y", "0", *FAST)
    assert status == 0
    data = load(prefix)
    np.testing.assert_allclose(data["axis_x"], np.linspace(0, 3.5, 8))
    assert tuple(data["shape"]) == (8, 1) and data["volume"].shape == (8, 1)
    assert data["lower"].shape == (8, 1, 3)
    reachable = data["reachable"][:, 0]
    assert reachable.tolist() == [True] * 7 + [False]  # 3.5 m is beyond the 3 m reach
    volume = data["score"]
    assert volume[2] == pytest.approx(1.0)  # x = 1: full circles
    assert volume[6] < 1e-6  # x = 3: the boundary
    assert np.all(np.diff(volume[2:7]) < 0)  # shrinking towards the boundary
    assert np.argmax(volume) == 2
    meta = json.loads(str(data["meta"]))
    assert meta["robot"] == "planar3r" and meta["joints"] is None
    with open(f"{prefix}.csv", newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == 8 and float(rows[2]["volume"]) == pytest.approx(1.0)
    assert rows[7]["reachable"] == "0" and rows[7]["kfm"] == "nan"
    assert Path(f"{prefix}.png").stat().st_size > 1000
    printed = capsys.readouterr().out
    assert "reachable: 7 of 8" in printed and "[1.0, 0.0]" in printed


def test_plane_map_in_two_processes_matches_one(tmp_path: Path) -> None:
    args = ["--robot", "planar3r", "--x=-1:1:3", "--y", "0:1:2", *FAST, "--no-plot"]
    prefix = tmp_path / "pool"
    assert placement.main([*args, "--output", str(prefix), "--workers", "2"]) == 0
    status, single = run(tmp_path, *args)
    assert status == 0
    pooled, alone = load(prefix), load(single)
    for key in ("volume", "kfm", "lower", "upper", "seed", "score"):
        np.testing.assert_array_equal(pooled[key], alone[key])
    grid = pooled["score"].reshape(3, 2)  # x by y
    assert grid[0, 0] == pytest.approx(1.0) and grid[2, 0] == pytest.approx(1.0)  # (+-1, 0)
    assert grid[1, 1] == pytest.approx(1.0)  # (0, 1)
    assert grid[1, 0] < 1e-6  # (0, 0): folded into a triangle, only joint 1 turns
    assert not Path(f"{prefix}.png").exists()


def test_joints_select_the_volume(tmp_path: Path) -> None:
    status, prefix = run(tmp_path, "--robot", "planar3r", "--x", "2", "--y", "0", *FAST,
                         "--joints", "1", "--no-plot")
    assert status == 0
    data = load(prefix)
    lower, upper = data["lower"][0, 0], data["upper"][0, 0]
    assert data["volume"][0, 0] == pytest.approx((upper[0] - lower[0]) / (2 * math.pi))
    assert data["volume_rad"][0, 0] == pytest.approx(upper[0] - lower[0])


def test_suggest_places_a_rigid_pair_where_both_boxes_are_full(
        tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    # The pair (0, 0), (2, 0) translated along x: only at x = -1 are both points at
    # distance 1 from the base, where each box is the whole joint space.
    status, prefix = run(tmp_path, "--robot", "planar3r", "--x=-1.5:1.5:13", "--y", "0",
                         "--suggest", "0,0; 2,0", *FAST)
    assert status == 0
    data = load(prefix)
    assert data["volume"].shape == (13, 2) and data["offsets"].tolist() == [[0, 0], [2, 0]]
    best = int(np.argmax(data["score"]))
    assert data["axis_x"][best] == pytest.approx(-1.0)
    assert data["score"][best] == pytest.approx(1.0)
    assert np.all(np.delete(data["score"], best) < 0.5)
    assert data["score"][-1] == 0.0  # x = 1.5: the second point (3.5, 0) is out of reach
    printed = capsys.readouterr().out
    assert "suggested placement: reference at [-1.0, 0.0]" in printed
    assert '--points "-1.0000,0.0000;1.0000,0.0000"' in printed
    with open(f"{prefix}.csv", newline="") as stream:
        header = next(csv.reader(stream))
    assert "volume_1" in header and "volume_2" in header


def test_suggest_score_is_the_volume_of_the_intersection(planar: robots.Robot,
                                                         tmp_path: Path) -> None:
    status, prefix = run(tmp_path, "--robot", "planar3r", "--x", "1.6", "--y", "0.2",
                         "--suggest", "0,0; -0.13,0.46", *FAST, "--no-plot")
    assert status == 0
    data = load(prefix)
    box = selfmotion.intersect([(data["lower"][0, j], data["upper"][0, j]) for j in (0, 1)])
    expected = selfmotion.box_volume(planar, *box)
    assert 0 < expected < min(data["volume"][0]) - 0.01  # neither box holds the other
    assert data["score"][0] == pytest.approx(expected)


@pytest.mark.parametrize(("args", "status", "message"), [
    (["--robot", "planar3r", "--x", "1:2", "--y", "0"], 1, "start:stop:count"),
    (["--robot", "planar3r", "--x", "1"], 1, "give --y"),
    (["--robot", "planar3r", "--x", "1", "--y", "0", "--z", "0"], 1, "planar task has no --z"),
    (["--robot", "puma560", "--x", "1", "--y", "0"], 1, "give --z"),
    (["--robot", "no_such_robot", "--x", "1", "--y", "0"], 1, "unknown robot model"),
    (["--robot", "planar3r", "--x", "1", "--y", "0", "--joints", "4"], 1, "1..3"),
    (["--robot", "planar3r", "--x", "1", "--y", "0", "--seed", "0,0"], 1, "3 joint values"),
    (["--robot", "planar3r", "--x", "1", "--y", "0", "--suggest", "0,0;1"], 1, "offsets"),
    (["--robot", "planar3r", "--x", "0:1:1000", "--y", "0:1:1000"], 1, "at most"),
    (["--robot", "planar3r", "--x", "1", "--y", "0", "--orientation", "0,0,0,1"], 1,
     "pose task"),
])
def test_bad_input_exits_1_and_writes_nothing(tmp_path: Path, capsys: pytest.CaptureFixture,
                                              args: list[str], status: int,
                                              message: str) -> None:
    code, _ = run(tmp_path, *args)
    assert code == status
    assert message in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("option", [("--restarts", "many"), ("--step", "0")])
def test_usage_errors_exit_2(tmp_path: Path, option: tuple[str, str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        run(tmp_path, "--robot", "planar3r", "--x", "1", "--y", "0", *option)
    assert exit_info.value.code == 2


def test_nothing_reachable_exits_3_with_the_map_written(tmp_path: Path,
                                                        capsys: pytest.CaptureFixture) -> None:
    code, prefix = run(tmp_path, "--robot", "planar3r", "--x", "3.5:4:2", "--y", "0", *FAST)
    assert code == 3
    assert "no grid point is reachable" in capsys.readouterr().err
    assert not load(prefix)["reachable"].any()
    assert Path(f"{prefix}.csv").exists() and Path(f"{prefix}.png").exists()


def test_points_whose_boxes_do_not_intersect_exit_4(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture) -> None:
    # Both points near the boundary on opposite sides: joint 1 near 0 and near pi.
    code, prefix = run(tmp_path, "--robot", "planar3r", "--x=-2.95", "--y", "0",
                       "--suggest", "0,0; 5.9,0", *FAST, "--no-plot")
    assert code == 4
    assert "no placement" in capsys.readouterr().err
    data = load(prefix)
    assert data["reachable"].all() and data["score"][0] == 0.0


@pytest.mark.parametrize("shape", [(5, 1, 1), (4, 1, 3), (3, 2, 5)])
def test_figures_for_lines_planes_and_volumes(tmp_path: Path, shape: tuple) -> None:
    axes = tuple(np.linspace(0, 1, count) for count in shape)
    grid = placement.Grid(("x", "y", "z"), axes)
    rng = np.random.default_rng(0)
    score = rng.uniform(size=int(np.prod(shape)))
    score[0] = np.nan
    path = tmp_path / "figure.png"
    placement.plot(path, grid, score, rng.uniform(size=score.size), "test", "volume",
                   marks=np.array([[0.5, 0.0, 0.5]]))
    assert path.stat().st_size > 1000


def test_puma_560_fig_7_reduced(tmp_path: Path) -> None:
    # Lewis & Maciejewski 1997 fig. 7: distance from joint 1's axis at height 0.5 m; P1
    # (Table II) at 0.9 m, with theta1 in [-0.64, 0.27] and theta4 over its whole range.
    status, prefix = run(tmp_path, "--robot", "puma560", "--x", "0.1:0.9:2", "--y", "0",
                         "--z", "0.5", "--joints", "1,2,3,4,5", "--no-plot")
    assert status == 0
    data = load(prefix)
    near_axis, p1 = data["volume_rad"][:, 0]
    assert p1 > 3 * near_axis
    assert 50 < p1 < 150  # Table II: 91 rad^5
    puma = robots.load("puma560")
    lower, upper = data["lower"][1, 0], data["upper"][1, 0]
    assert lower[0] == pytest.approx(-0.64, abs=0.05) and upper[0] == pytest.approx(0.27,
                                                                                    abs=0.05)
    assert lower[3] == pytest.approx(puma.lower[3]) and upper[3] == pytest.approx(puma.upper[3])
    assert upper[5] - lower[5] == pytest.approx(puma.upper[5] - puma.lower[5])  # joint 6 free
    assert data["volume"][1, 0] == pytest.approx(selfmotion.box_volume(puma, lower, upper,
                                                                       range(5)))
