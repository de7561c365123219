"""Issue 34 item 1: the workspace after a free-swinging failure (Maciejewski et al. sec. 3.3).

The paper's planar 3R (unit links, a 1 kg rod each, joint 2 free, figs. 5-6), then the
Panda with its real inertias.
"""

from __future__ import annotations

import numpy as np
import pytest
from ft_core import robots, swing
from ft_core.offline import swing_workspace as sw

DOWN_Y = sw.PLANAR_GRAVITY
RODS = robots.load("planar3r_rods")
JOINT2 = 1


@pytest.fixture(scope="module")
def mesh() -> sw.PlanarMesh:
    return sw.planar_mesh(RODS, JOINT2, 120, DOWN_Y)


def _hangs_below(robot: robots.Robot, q: np.ndarray, joint: int) -> bool:
    """Whether the outboard links' centre of mass is straight below the joint (fig. 6)."""
    _, moments = robot.outboard_moments(q)
    return abs(moments[joint, 0]) < 1e-9 and moments[joint, 1] < 0


def test_four_stationary_configurations_reach_a_point_of_the_dark_region(mesh) -> None:
    """Fig. 6's statement, at a point of our four-solution region (see the next test)."""
    point = (0.25, -1.01)
    solutions = sw.zero_torque_solutions(RODS, JOINT2, point, mesh, DOWN_Y)
    assert len(solutions) == 4
    for q in solutions:
        assert np.linalg.norm(RODS.forward(q) - point) < 1e-9
        assert _hangs_below(RODS, q, JOINT2)
    # Distinct configurations, not one found twice.
    gaps = [np.abs(np.sin((a - b) / 2)).max() for i, a in enumerate(solutions)
            for b in solutions[i + 1:]]
    assert min(gaps) > 0.01


def test_the_papers_point_has_four_only_with_a_tool_load(mesh) -> None:
    """The paper's point (0.41, -1.01) has four only with 0.2 kg more at the tool.

    It is just outside the four-solution region of the arm as the paper describes it; a
    tool load of 0.2 kg (outboard moment ratio above 0.404) puts it in.
    """
    point = (0.41, -1.01)
    assert len(sw.zero_torque_solutions(RODS, JOINT2, point, mesh, DOWN_Y)) == 2
    # Link 3 with 0.2 kg more at its tip: 1.2 kg with its centre of mass at 0.5833 m.
    head, link3 = robots.builtin_urdf("planar3r_rods").split('<link name="link3">')
    loaded = robots.load(head + '<link name="link3">' + link3.replace(
        '<origin xyz="0.5 0 0" rpy="0 0 0"/>\n      <mass value="1"/>',
        '<origin xyz="0.58333 0 0" rpy="0 0 0"/>\n      <mass value="1.2"/>', 1),
        task_space="planar")
    _, moments = loaded.outboard_moments(np.zeros(3))
    assert moments[2, 0] == pytest.approx(0.7, abs=1e-4)  # link 3 and the load
    solutions = sw.zero_torque_solutions(loaded, JOINT2, point,
                                         sw.planar_mesh(loaded, JOINT2, 120, DOWN_Y), DOWN_Y)
    assert len(solutions) == 4
    assert all(_hangs_below(loaded, q, JOINT2) for q in solutions)


def test_the_regions_of_fig_5(mesh) -> None:
    """Two configurations per point almost everywhere, four in a lens below the base.

    Mirror-symmetric about the vertical through the base.
    """
    counts, centres = sw.solution_counts(mesh, 3.1, 125)
    values, pixels = np.unique(counts, return_counts=True)
    shown = dict(zip(values.tolist(), pixels.tolist(), strict=True))
    assert shown.get(2, 0) > 3000 and shown.get(4, 0) > 10
    assert max(shown) == 4
    odd = sum(v for k, v in shown.items() if k % 2)
    assert odd <= 0.005 * counts.size  # only pixel centres on a fold
    assert np.mean(counts == counts[:, ::-1]) > 0.99
    rows, columns = np.nonzero(counts == 4)
    assert np.all(np.abs(centres[rows] + 1.0) < 0.2)  # the lens about 1 m below the base
    assert np.all(np.abs(centres[columns]) < 0.41)  # not as far out as the paper's point


def test_sampled_positions_lie_in_the_counted_region(mesh) -> None:
    """The two computations agree: every sampled stationary tool position is counted."""
    counts, centres = sw.solution_counts(mesh, 3.1, 125)
    _, failed = sw.sample_workspace(RODS, [JOINT2], 400, seed=1, gravity=DOWN_Y)
    positions = failed[JOINT2].positions
    assert len(positions) == 400  # a continuous joint: one hanging angle per sample
    step = centres[1] - centres[0]
    ix = np.rint((positions[:, 0] - centres[0]) / step).astype(int)
    iy = np.rint((positions[:, 1] - centres[0]) / step).astype(int)
    near = np.zeros(len(positions), bool)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            near |= counts[np.clip(iy + dy, 0, 124), np.clip(ix + dx, 0, 124)] > 0
    assert near.all()


@pytest.fixture(scope="module")
def panda() -> robots.Robot:
    return robots.load("panda_inertial", task_space="position")


def test_the_pandas_stationary_configurations_hold_with_zero_torque(panda) -> None:
    """Pinocchio's gravity torque is zero and restoring at a hanging angle.

    Independent of the swing angle's formula; on a stop, gravity presses into the limit.
    """
    rng = np.random.default_rng(3)
    checked = {"hanging": 0, "stop": 0}
    for _ in range(30):
        q = panda.lower + rng.random(7) * (panda.upper - panda.lower)
        for joint in range(1, 7):
            for angle in sw.stationary_angles(panda, q, joint):
                settled = q.copy()
                settled[joint] = angle
                torque = panda.gravity_dynamics(settled)[0][joint]
                if angle in (panda.lower[joint], panda.upper[joint]):
                    checked["stop"] += 1
                    inward = 1 if angle == panda.lower[joint] else -1
                    assert -torque * inward <= 1e-9  # gravity pushes it onto the stop
                else:
                    checked["hanging"] += 1
                    assert abs(torque) < 1e-8
                    nudged = settled.copy()
                    nudged[joint] += 1e-4
                    assert panda.gravity_dynamics(nudged)[0][joint] > 0  # restoring
    assert checked["hanging"] > 20 and checked["stop"] > 20


def test_the_pandas_post_failure_workspace(panda) -> None:
    healthy, failed = sw.sample_workspace(panda, range(7), 600, seed=2)
    # Joint 1's axis is vertical: gravity never turns it, it stays where it failed.
    assert failed[0].neutral == 1.0
    np.testing.assert_allclose(failed[0].positions, healthy.positions)
    # Joint 2 cannot hang (that needs +-pi, beyond +-1.76 rad): it always rests on a stop.
    assert failed[1].on_stop.all()
    whole, shares = sw.volume_shares(healthy, failed, 0.15)
    assert 0 < whole <= 1
    assert shares[0] == pytest.approx(whole)
    assert all(0 < share <= 1 for share in shares.values())
    assert min(shares.values()) < whole  # some failure loses part of the workspace


def test_swing_state_marks_a_vertical_axis_neutral(panda) -> None:
    theta, turned = swing.swing_state(panda, np.zeros(7))
    assert not turned[0] and theta[0] == 0
    assert turned[1]


def test_ft_swing_end_to_end(tmp_path) -> None:
    out = tmp_path / "swing"
    assert sw.main(["--point", "0.25,-1.01", "--samples", "200", "--grid", "60",
                    "--out", str(out)]) == 0
    report = (out / "swing.md").read_text()
    assert "4 stationary configuration(s) reach [0.25, -1.01]" in report
    assert (out / "swing.png").stat().st_size > 10_000
    for bad in (["--robot", "panda_inertial", "--point", "0.3,0.2"], ["--joints", "4"],
                ["--gravity", "0,0,0"], ["--robot", "panda", "--samples", "10"]):
        assert sw.main([*bad, "--out", str(out)]) == 1, bad
