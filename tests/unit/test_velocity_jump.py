"""Minimum joint-velocity jump (Zhao & Li) and its planar 3R simulation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from ft_core import measures, velocity_jump
from ft_core.engine import EngineConfig, ResolutionEngine
from models import planar_arm

RNG = np.random.default_rng(11)


def random_problem(m: int = 3, n: int = 5) -> tuple[np.ndarray, np.ndarray]:
    return RNG.normal(size=(m, n)), RNG.normal(size=m)


def test_post_failure_velocities_lock_their_joint_and_track_the_task() -> None:
    J, xd = random_problem()
    reduced = velocity_jump.post_failure_velocities(J, xd)
    np.testing.assert_allclose(np.diag(reduced), 0.0, atol=1e-12)
    np.testing.assert_allclose(reduced @ J.T, np.tile(xd, (5, 1)), atol=1e-10)
    for i in range(5):  # least norm among the velocities of the reduced robot (eq 2)
        kept = np.delete(np.arange(5), i)
        np.testing.assert_allclose(reduced[i, kept], np.linalg.pinv(J[:, kept]) @ xd, atol=1e-10)


@pytest.mark.parametrize(("m", "n"), [(2, 3), (3, 4), (3, 7), (6, 7)])
def test_min_jump_tracks_and_beats_least_norm_by_eq_14(m: int, n: int) -> None:
    J, xd = random_problem(m, n)
    optimal = velocity_jump.min_jump_velocity(J, xd)
    least_norm = np.linalg.pinv(J) @ xd
    np.testing.assert_allclose(J @ optimal, xd, atol=1e-10)
    homogeneous = optimal - least_norm
    np.testing.assert_allclose(J @ homogeneous, 0.0, atol=1e-10)
    delta = velocity_jump.jump_index(J, least_norm, xd) - velocity_jump.jump_index(J, optimal, xd)
    assert delta == pytest.approx(n * homogeneous @ homogeneous, rel=1e-9, abs=1e-12)
    assert delta > 0


@pytest.mark.parametrize("k", range(4))
def test_only_joint_k_may_fail_so_it_stays_still(k: int) -> None:
    J, xd = random_problem(3, 4)
    p = np.zeros(4)
    p[k] = 1.0
    qd = velocity_jump.min_jump_velocity(J, xd, p)
    assert qd[k] == pytest.approx(0.0, abs=1e-10)  # Zhao & Li eq 8
    np.testing.assert_allclose(J @ qd, xd, atol=1e-10)
    assert velocity_jump.jump_index(J, qd, xd, p) == pytest.approx(0.0, abs=1e-18)


def test_min_jump_is_the_weighted_optimum() -> None:
    J, xd = random_problem(3, 6)
    p = np.array([0.1, 0.3, 0.05, 0.2, 0.25, 0.1])
    optimal = velocity_jump.min_jump_velocity(J, xd, p)
    best = velocity_jump.jump_index(J, optimal, xd, p)
    null = measures.null_space_basis(J)
    for _ in range(100):  # any other velocity that tracks xd jumps more
        other = optimal + null @ RNG.normal(scale=0.3, size=null.shape[1])
        assert velocity_jump.jump_index(J, other, xd, p) >= best


def test_per_joint_jumps_follow_eq_1() -> None:
    J, xd = random_problem(2, 3)
    qd = np.linalg.pinv(J) @ xd
    jumps = velocity_jump.joint_velocity_jumps(J, qd, xd)
    np.testing.assert_allclose(np.diag(jumps), np.abs(qd))  # a locked joint jumps to 0
    assert np.sum(jumps**2) == pytest.approx(velocity_jump.jump_index(J, qd, xd))


def test_bad_task_velocities_are_rejected() -> None:
    J, _ = random_problem()
    with pytest.raises(ValueError, match="xd"):
        velocity_jump.min_jump_velocity(J, np.ones(2))
    with pytest.raises(ValueError, match="non-finite"):
        velocity_jump.jump_index(J, np.zeros(5), np.array([0.0, np.nan, 0.0]))


def simulate_004(resolution_mode: str, probabilities: tuple = ()) -> dict[str, float]:
    """Zhao & Li sec. IV-A: 1 s circle at 1 ms from X = [0.35, 0]; mean indexes over the run."""
    arm = planar_arm([0.5, 0.5, 0.5], velocity=50.0)
    q = START_004.copy()
    config = EngineConfig(resolution=resolution_mode, dt=0.001, kfm_gain=5.0, limit_gain=0.0,
                          failure_probabilities=probabilities)
    engine = ResolutionEngine(arm, config)
    jumps, conditions = [], []
    for step in range(1000):
        t = step * 0.001
        xd = 0.2 * math.pi * np.array([math.sin(2 * math.pi * t), math.cos(2 * math.pi * t)])
        result = engine.step(arm.kinematics(q), xd)
        J = arm.jacobian(q)
        np.testing.assert_allclose(J @ result.qd, xd, atol=1e-9)
        jumps.append(velocity_jump.jump_index(J, result.qd, xd, probabilities or None))
        conditions.append(np.sum(measures.reduced_condition_numbers(J) ** 2))
        q = q + result.qd * 0.001
    # The circle closes: after one period the tool is back at the start.
    np.testing.assert_allclose(arm.forward(q), [0.35, 0.0], atol=1e-3)
    return {"jump": float(np.mean(jumps)), "rcn": float(np.mean(conditions))}


#: Start configuration: the paper gives only the tool position X = [0.35, 0] m;
#: this is the inverse-kinematics solution found from [1.2, -1.9, -1.6] rad.
START_004 = np.array([1.5639385294, -1.6118093141, -1.8336118477])


def test_start_configuration_reaches_the_papers_start_point() -> None:
    arm = planar_arm([0.5, 0.5, 0.5])
    np.testing.assert_allclose(arm.forward(START_004), [0.35, 0.0], atol=1e-6)


def test_zhao_li_planar_3r_all_joints_may_fail() -> None:
    """All three joints may fail (Zhao & Li Fig. 2), max_kfm standing in for the paper's MDA.

    Holds, as in the paper: minimum jump has the lowest mean jump index and max_kfm
    the highest, least norm in the middle and close to minimum jump; on the reduced
    condition number (square sum over joints) the order is reversed: max_kfm the
    lowest (most dexterous), minimum jump the highest.
    """
    runs = {mode: simulate_004(mode) for mode in ("min_jump", "least_norm", "max_kfm")}
    print({mode: {k: round(v, 4) for k, v in r.items()} for mode, r in runs.items()})
    assert runs["min_jump"]["jump"] < runs["least_norm"]["jump"] < runs["max_kfm"]["jump"]
    assert runs["least_norm"]["jump"] < 1.05 * runs["min_jump"]["jump"]
    assert runs["max_kfm"]["rcn"] < runs["least_norm"]["rcn"] < runs["min_jump"]["rcn"]


def test_zhao_li_planar_3r_only_joints_2_and_3_may_fail() -> None:
    """Only joints 2 and 3 may fail (Zhao & Li Fig. 4).

    Holds, as in the paper: minimum jump's advantage in the jump index is larger
    than with all joints (here its mean is under 70 % of least norm's) while the
    reduced condition numbers of the three algorithms stay within 5 % of each other.
    """
    p = (0.0, 1.0, 1.0)
    runs = {mode: simulate_004(mode, p) for mode in ("min_jump", "least_norm", "max_kfm")}
    print({mode: {k: round(v, 4) for k, v in r.items()} for mode, r in runs.items()})
    assert runs["min_jump"]["jump"] < min(runs["least_norm"]["jump"], runs["max_kfm"]["jump"])
    assert runs["min_jump"]["jump"] < 0.7 * runs["least_norm"]["jump"]
    rcn = [r["rcn"] for r in runs.values()]
    assert max(rcn) < 1.05 * min(rcn)
