"""Zhao & Li sec. V offline (bench/zhao_li_circle.py): the path error after a lock follows the jump.

Deterministic: a fixed start configuration, 1 ms Euler steps and ruckig's
acceleration/jerk-limited velocity, no wall time.
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest
from ft_core.velocity_jump import jump_index
from paths import REPO

sys.path.insert(0, str(REPO / "bench"))
import zhao_li_circle as study  # the study's own functions

pytestmark = pytest.mark.unit  # (tests/conftest.py marks the folder's tests as well)

MOMENTS = ("largest jump", "smallest jump")


@pytest.fixture(scope="module")
def runs() -> dict[tuple[str, str], dict[str, float]]:
    """Joint 3 locks at each mode's own largest- and smallest-jump moment."""
    return {(mode, moment): study.run(mode, lock_time)
            for mode in study.MODES
            for moment, lock_time in zip(MOMENTS, study.extreme_moments(mode), strict=True)}


def test_path_error_after_the_lock_is_larger_at_the_largest_jump(
        runs: dict[tuple[str, str], dict[str, float]]) -> None:
    for mode in study.MODES:
        big, small = runs[mode, "largest jump"], runs[mode, "smallest jump"]
        assert big["jump_rad_s"] > 100 * small["jump_rad_s"]
        assert big["max_path_error_mm"] > 10 * small["max_path_error_mm"]
        assert big["integrated_path_error_mm_s"] > 10 * small["integrated_path_error_mm_s"]
        assert big["max_tracking_error_mm"] > 10 * small["max_tracking_error_mm"]


def test_the_error_comes_from_the_acceleration_limit() -> None:
    # Velocities free to change at once: the largest jump leaves (almost) no error.
    t = study.extreme_moments("least_norm")[0]
    limited = study.run("least_norm", t)
    free = study.run("least_norm", t, acceleration=1e4, jerk=1e8)
    assert free["max_path_error_mm"] < 0.05 < 1.0 < limited["max_path_error_mm"]


def test_min_jump_jumps_less_than_least_norm_at_the_largest_jump_moment() -> None:
    t = study.extreme_moments("least_norm")[0]
    k = round(t / study.DT)
    least_norm, min_jump = study.healthy("least_norm"), study.healthy("min_jump")
    # On their own paths (same time, different configurations): the joint-3 jump (eq 1).
    assert min_jump["jump"][k] <= least_norm["jump"][k]
    # At the same configuration the all-joint index obeys eq 14 exactly.
    q = least_norm["q"][k]
    J, v = study.jacobian(q), study.command(q, least_norm["t"][k])
    qd_ln, qd_mj = study.resolve("least_norm", J, v), study.resolve("min_jump", J, v)
    assert study.lock_jump(J, qd_mj, v) <= study.lock_jump(J, qd_ln, v)
    delta = jump_index(J, qd_ln, v) - jump_index(J, qd_mj, v)
    assert delta == pytest.approx(3 * np.sum((qd_mj - qd_ln) ** 2), rel=1e-9)
    assert delta > 0


def test_the_numbers_are_sane(runs: dict[tuple[str, str], dict[str, float]]) -> None:
    # The circle of sec. V: radius 0.1 m, period 6 s; least norm's extreme jumps at the
    # paper's 3.1 s and 4.5 s (Q0 was chosen for this).
    assert study.RADIUS == pytest.approx(0.1) and study.PERIOD == pytest.approx(6.0)
    t_max, t_min = study.extreme_moments("least_norm")
    assert t_max == pytest.approx(3.1, abs=0.01) and t_min == pytest.approx(4.5, abs=0.01)
    for (mode, _), r in runs.items():
        assert all(math.isfinite(value) for value in r.values())
        assert 0.0 < r["lock_time_s"] <= study.PERIOD
        assert r["jump_rad_s"] >= 0.0 and r["jump_index_rad2_s2"] > 0.0
        assert r["max_path_error_mm"] > 0.0 and r["integrated_path_error_mm_s"] > 0.0
        assert r["max_tracking_error_mm"] >= r["max_path_error_mm"]
        assert r["path_error_before_lock_mm"] < 0.05  # on the circle until the lock
        assert r["max_path_error_mm"] < 50.0, mode  # millimetres, not a runaway
    for mode in study.MODES:  # the healthy paths stay away from singular reduced robots
        h = study.healthy(mode)
        assert np.all(np.isfinite(h["qd"])) and np.max(np.abs(h["qd"])) < 5.0
