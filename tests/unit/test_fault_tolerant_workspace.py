"""Lewis & Maciejewski 1997 figs 1, 3 and 7: the failure-tolerant workspace and the PUMA's P1.

Fig. 1 / sec. II: without joint limits, the planar 3R with unit links is failure tolerant
only on the circle of radius one link. Fig. 3 / sec. II: software limits before a failure
leave a failure-tolerant region of positive area, "an approximately 60% reduction" of the
restricted workspace (`ft_core.offline.fault_tolerant_workspace`, with our reading of the
limits). Fig. 7 / Table II: P1's box, 0.9 m from joint 1's axis at a height of 0.5 m, has
joint 2 up to 0.75 rad, which no configuration reaching a point 0.5 m above Table I's
frame 0 has; 0.5 m above the floor the PUMA stands on (its shoulder 0.672 m up) the box
and the curve's jump to its maximum near 0.9 m are the paper's (docs/placement.md).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from ft_core import robots, selfmotion
from ft_core.offline import fault_tolerant_workspace as ftw
from ft_core.offline import placement
from scipy import ndimage

FULL = (ftw.FULL_TURN,) * 3
COUNT = 121  # grid points per axis in the tests: a cell of 0.05 link lengths


@pytest.fixture(scope="module")
def fig3() -> ftw.Workspaces:
    return ftw.compute(ftw.FIG3_LIMITS, COUNT)


def _points(count: int) -> np.ndarray:
    axis = np.linspace(-3, 3, count)
    x, y = np.meshgrid(axis, axis)
    return np.stack([x, y], axis=-1)


def test_the_closed_form_reaches_what_the_planar3r_model_reaches() -> None:
    planar = robots.load("planar3r")
    rng = np.random.default_rng(0)
    for ranges in (FULL, ftw.FIG3_LIMITS):
        lows, highs = np.array(ranges).T
        q = rng.uniform(lows, highs, size=(200, 3))
        tips = np.array([planar.forward(c) for c in q])
        for joint in range(3):
            found = [ftw.reachable(tip, joint, c[joint], ranges) for tip, c in zip(tips, q,
                                                                                strict=True)]
            assert all(found), (ranges, joint)
    assert not ftw.reachable(np.array([3.01, 0.0]), 0, 0.0, FULL)
    # Joint 2 at 0 stretches links 1 and 2 into one of length 2: the tool at 1 to 3.
    assert ftw.reachable(np.array([[0.99, 0], [1.01, 0], [2.99, 0]]), 1, 0.0, FULL).tolist() == [
        False, True, True]


def test_the_restricted_workspace_is_where_sampled_configurations_put_the_tool(
        fig3: ftw.Workspaces) -> None:
    # (a) against forward kinematics: configurations drawn inside the limits, binned
    # into the grid's cells, hit (a) and nothing more than one cell outside it.
    rng = np.random.default_rng(1)
    lows, highs = np.array(ftw.FIG3_LIMITS).T
    q = rng.uniform(lows, highs, size=(400_000, 3))
    angles = np.cumsum(q, axis=1)
    x, y = np.cos(angles).sum(axis=1), np.sin(angles).sum(axis=1)
    half = (fig3.axis[1] - fig3.axis[0]) / 2
    edges = np.append(fig3.axis - half, fig3.axis[-1] + half)
    hit = np.histogram2d(y, x, bins=(edges, edges))[0] > 0  # [y, x] like the masks
    assert fig3.restricted.any() and hit.any()
    assert not (hit & ~ndimage.binary_dilation(fig3.restricted)).any()
    assert not (fig3.restricted & ~ndimage.binary_dilation(hit)).any()


def test_without_limits_only_the_unit_circle_is_failure_tolerant() -> None:
    # Lewis & Maciejewski 1997 fig. 1 and sec. II.
    unrestricted = ftw.compute(FULL, COUNT)
    radius = np.hypot(*np.moveaxis(_points(COUNT), -1, 0))
    assert unrestricted.area(unrestricted.restricted) == pytest.approx(9 * math.pi, rel=0.01)
    # Joint 1 locked anywhere: within 2 of every point of the unit circle, the unit disc.
    disc = unrestricted.failures[0]
    assert disc.any() and not (disc ^ (radius <= 1 + 1e-9)).any()
    # Joints 2 and 3: the intersection of the annuli |rho - 1| <= r <= rho + 1 over
    # rho in [0, 2] is the unit circle; on the grid, the points that lie on it.
    tolerant = unrestricted.tolerant
    assert tolerant.any() and np.all(np.abs(radius[tolerant] - 1) < 1e-9)
    assert unrestricted.area(tolerant) < 0.01 * math.pi
    # Off the grid: every point of the circle, and none 1 % inside or outside it.
    turn = np.linspace(-math.pi, math.pi, 97)
    for scale, expected in ((1.0, True), (0.99, False), (1.01, False)):
        points = scale * np.stack([np.cos(turn), np.sin(turn)], axis=-1)
        every = ftw.restricted_workspace(points, FULL)
        for joint in range(3):
            every &= ftw.failure_region(points, joint, FULL)
        assert np.all(every == expected), scale


def test_the_limits_of_fig_3_leave_a_failure_tolerant_region_about_60_percent_smaller(
        fig3: ftw.Workspaces) -> None:
    points = _points(COUNT)
    radius = np.hypot(*np.moveaxis(points, -1, 0))
    # Joints 2 and 3 locked within +-90 deg: the links they join are 2 cos(c / 2) in
    # [sqrt 2, 2] apart, so the annulus 1 <= r <= 1 + sqrt 2 (points on an edge aside).
    outer = 1 + math.sqrt(2)
    clear = (np.abs(radius - 1) > 1e-6) & (np.abs(radius - outer) > 1e-6)
    annulus = (radius >= 1) & (radius <= outer)
    for joint in (1, 2):
        assert fig3.failures[joint].any()
        assert not ((fig3.failures[joint] ^ annulus) & clear).any()
    # Joint 1 locked within +-15 deg: within 2 of every point of that arc of the unit
    # circle (links 2 and 3 reach any distance up to 2).
    arc = np.linspace(*ftw.FIG3_LIMITS[0], 2001)
    farthest = np.max(np.hypot(points[..., :1] - np.cos(arc), points[..., 1:] - np.sin(arc)),
                      axis=-1)
    assert fig3.failures[0].any()
    assert not ((fig3.failures[0] ^ (farthest <= 2)) & (np.abs(farthest - 2) > 1e-4)).any()
    np.testing.assert_array_equal(fig3.tolerant, fig3.restricted & fig3.failures.all(axis=0))
    # The limits make a region of positive area failure tolerant (fig. 1's circle has
    # none): 3.1 of the restricted 7.5 (link lengths^2), a 58 % reduction; the paper's
    # "approximately 60%" within 5 points.
    assert fig3.area(fig3.tolerant) > 3.0
    assert fig3.reduction == pytest.approx(ftw.PAPER_REDUCTION, abs=0.05)


def test_ft_map_runs_the_subcommand_and_refuses_bad_limits(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    figure = tmp_path / "out" / "ftw.png"
    assert placement.main([ftw.COMMAND, "--count", "41", "-o", str(figure)]) == 0
    assert figure.stat().st_size > 10_000
    assert "reduction of (a)" in capsys.readouterr().out
    for bad in ("0:10,0:10", "10:0,0:10,0:10", "0:10,0:10,a:b", "-400:0,0:10,0:10"):
        assert placement.main([ftw.COMMAND, f"--limits={bad}", "-o",
                               str(tmp_path / "bad.png")]) == 1
        assert "--limits" in capsys.readouterr().err
    assert not (tmp_path / "bad.png").exists()


def test_the_documented_figure_stays_small() -> None:
    figure = Path(__file__).resolve().parents[2] / "docs" / "fault_tolerant_workspace.png"
    assert 10_000 < figure.stat().st_size < 200_000


# --- Lewis & Maciejewski 1997 fig. 7 and Table II (PUMA 560) -------------------------------

#: Table II, P1: (min, max) of joints 1-5 (rad) and the volume (rad^5).
TABLE_II_P1 = ((-0.64, 0.27), (-0.98, 0.75), (0.06, 3.53), (-1.89, 2.94), (-1.72, 1.72))
TABLE_II_P1_VOLUME = 91
#: Table I: the tool is d4 + d6 from joint 3's origin at most (m).
FOREARM_AND_TOOL = 0.433 + 0.392
#: The PUMA 560's shoulder above the floor it stands on (m; Corke's Robotics Toolbox).
SHOULDER_HEIGHT = 0.672
P1_DISTANCE, P1_HEIGHT = 0.9, 0.5
FLOOR_HEIGHT = P1_HEIGHT - SHOULDER_HEIGHT  # P1 in Table I's frame, 0.5 m above the floor


@pytest.fixture(scope="module")
def puma() -> robots.Robot:
    return robots.load("puma560")


def _distance_from_elbow(height: float, theta2: float) -> float:
    """Least distance (m) from joint 3's origin, at theta2 and any theta1, to P1 at `height`."""
    elbow = robots.load("puma560", tip_link="puma_link3").forward(np.array([0.0, theta2, 0.0]))
    return math.hypot(P1_DISTANCE - math.hypot(elbow[0], elbow[1]), height - elbow[2])


def test_table_ii_p1_is_not_0_5_m_above_table_i_frame(puma: robots.Robot) -> None:
    # The volume of Table II is rad^5 over joints 1-5 (joint 6 only turns the tool).
    assert np.prod([high - low for low, high in TABLE_II_P1]) == pytest.approx(
        TABLE_II_P1_VOLUME, abs=0.5)
    # The tool is never farther than d4 + d6 from joint 3's origin ...
    elbow = robots.load("puma560", tip_link="puma_link3")
    rng = np.random.default_rng(2)
    spans = [np.linalg.norm(puma.forward(q) - elbow.forward(q[:3]))
             for q in (puma.random_configuration(rng) for _ in range(500))]
    assert FOREARM_AND_TOOL - 0.02 < max(spans) <= FOREARM_AND_TOOL + 1e-9
    # ... so with joint 2 at Table II's 0.75 rad (upper arm 43 deg below horizontal) P1
    # is out of reach 0.5 m above frame 0: 0.97 m from the elbow. Table II's box cannot
    # be of that point; joint 2 reaches 0.75 at 0.9 m only up to a height of 0.32 m.
    theta2_max = TABLE_II_P1[1][1]
    assert _distance_from_elbow(P1_HEIGHT, theta2_max) == pytest.approx(0.967, abs=0.005)
    elbow_at = elbow.forward(np.array([0.0, theta2_max, 0.0]))
    highest = elbow_at[2] + math.sqrt(FOREARM_AND_TOOL ** 2 - (
        P1_DISTANCE - math.hypot(elbow_at[0], elbow_at[1])) ** 2)
    assert highest == pytest.approx(0.320, abs=0.002)
    assert _distance_from_elbow(FLOOR_HEIGHT, theta2_max) < FOREARM_AND_TOOL


def _line(robot: robots.Robot, height: float, distances: tuple[float, ...],
          ) -> list[placement.PointResult]:
    home = np.array(robots.HOME["puma560"])[:robot.n]
    return [placement.evaluate_point(robot, np.array([d, 0.0, height]), home, range(5))
            for d in distances]


def test_fig_7_at_0_5_m_above_the_floor_and_not_above_the_shoulder(puma: robots.Robot) -> None:
    distances = (0.8, 0.85, 0.9, 1.0, 1.1)
    floor = _line(puma, FLOOR_HEIGHT, distances)
    assert all(r.reachable for r in floor)
    volume = [r.volume_rad for r in floor]
    # The curve jumps where joint 2's upper bound jumps to its limit (the component
    # grows across the folded elbow), peaks there and falls: fig. 7's discontinuity
    # and its optimum near 0.9 m (0.85 m on this grid).
    assert floor[0].upper[1] < 0 and floor[1].upper[1] == pytest.approx(puma.upper[1])
    assert volume[1] > 2 * volume[0]
    assert volume[1] == max(volume) and volume[2] > volume[3] > volume[4]
    # P1's box is Table II's in joints 1, 2, 4 and 5; its volume 74 rad^5 against 91.
    p1 = floor[2]
    for joint in (0, 1, 3, 4):
        np.testing.assert_allclose([p1.lower[joint], p1.upper[joint]], TABLE_II_P1[joint],
                                   atol=0.05, err_msg=f"joint {joint + 1}")
    assert p1.upper[2] == pytest.approx(TABLE_II_P1[2][1], abs=0.1)
    assert 60 < p1.volume_rad < TABLE_II_P1_VOLUME
    # Joint 3's lower bound is 0.77 on the traced component; Table II's 0.06 is
    # reachable at P1 inside the limits (joint 2 at its limit), outside what we trace.
    assert p1.lower[2] > 0.5
    low = selfmotion.project(puma, np.array([P1_DISTANCE, 0.0, FLOOR_HEIGHT]),
                             np.array([0.11, 0.79, TABLE_II_P1[2][0], -0.7, 1.32, 4.52]),
                             fixed=[2])
    assert low is not None and low[2] == pytest.approx(TABLE_II_P1[2][0])
    assert np.all(low >= puma.lower) and np.all(low <= puma.upper)
    # 0.5 m above the shoulder, with joint 6 in the model (extremal walks) or fixed (the
    # paper's five joints, the spiral of eqs 6-9): no jump after 0.75 m, the volume falls.
    five_joints = robots.load(robots.builtin_urdf("puma560").replace(
        '<joint name="puma_joint6" type="revolute">', '<joint name="puma_joint6" type="fixed">'),
        task_space="position")
    assert five_joints.n == 5
    for robot in (puma, five_joints):
        shoulder = _line(robot, P1_HEIGHT, (0.75, 0.9, 1.0))
        assert all(r.reachable for r in shoulder)
        assert shoulder[0].volume_rad > shoulder[1].volume_rad > shoulder[2].volume_rad
        assert shoulder[1].upper[1] < TABLE_II_P1[1][1] - 0.3
