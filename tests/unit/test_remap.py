"""ft_core.remap: the tool velocity survives a lock."""

from __future__ import annotations

import numpy as np
import pytest
from ft_core import remap, robots

PANDA = robots.load("panda")
Q = np.array([0.4, 0.3, -0.5, -1.9, 0.6, 1.4, -0.2])
QD = np.array([0.1, -0.2, 0.1, 0.3, -0.1, 0.2, 0.1])


def test_without_locks_the_command_passes_unchanged() -> None:
    np.testing.assert_array_equal(remap.remap(PANDA, Q, QD, []), QD)


def test_locked_joints_get_zero_and_the_tool_velocity_is_kept() -> None:
    J = PANDA.jacobian(Q)
    for joint in (0, 2, 5):
        out = remap.remap(PANDA, Q, QD, [joint])
        assert out[joint] == 0.0
        np.testing.assert_allclose(J @ out, J @ QD, atol=1e-9)


def test_the_healthy_joints_own_motion_passes_unchanged() -> None:
    """Issue 30: a command that holds the locked joint at 0 passes unchanged.

    A controller that knows of the lock sends null-space motion or a recovery path; the
    monitor must not project it onto the task.
    """
    arm = robots.load("panda", task_space="position")  # 6 healthy joints, 3 task rows
    J = arm.scale_task(arm.jacobian(Q))
    null = np.linalg.svd(np.delete(J, 2, axis=1))[2][-1]  # healthy null-space motion
    knowing = np.insert(0.3 * null, 2, 0.0)
    np.testing.assert_allclose(remap.remap(arm, Q, knowing, [2]), knowing, atol=1e-12)
    # Anything on the locked joint is made up for on top of the healthy joints' motion.
    out = remap.remap(arm, Q, knowing + QD[2] * np.eye(7)[2], [2])
    assert out[2] == 0.0
    np.testing.assert_allclose(J @ out, J @ (knowing + QD[2] * np.eye(7)[2]), atol=1e-9)


def test_a_task_the_reduced_robot_cannot_do_gets_least_squares() -> None:
    out = remap.remap(PANDA, Q, QD, [1, 4])  # 5 joints for a 6-D pose task
    assert out[1] == out[4] == 0.0
    J = PANDA.scale_task(PANDA.jacobian(Q))
    healthy = [0, 2, 3, 5, 6]
    best = np.linalg.lstsq(J[:, healthy], J @ QD, rcond=None)[0]
    np.testing.assert_allclose(out[healthy], best, atol=1e-6)


def test_velocity_limits_scale_the_whole_command() -> None:
    out = remap.remap(PANDA, Q, 30 * QD, [2], velocity_limits=np.full(7, 1.0))
    assert np.max(np.abs(out)) == np.float64(1.0)
    direction = remap.remap(PANDA, Q, 30 * QD, [2], velocity_limits=np.full(7, 1e9))
    np.testing.assert_allclose(out / np.linalg.norm(out), direction / np.linalg.norm(direction))


def test_every_joint_locked_gives_zeros() -> None:
    np.testing.assert_array_equal(remap.remap(PANDA, Q, QD, range(7)), np.zeros(7))


def test_bounds_hold_a_healthy_joint_and_the_others_keep_the_task() -> None:
    """Velocity bounds (position limits) saturate a joint; the task is solved without it.

    Bounds the remap does not reach change nothing. One that a healthy joint's remapped
    command breaks holds it at the bound, and the other healthy joints (five for a
    position task: redundant) still give the tool velocity the command meant.
    """
    arm = robots.load("panda", task_space="position")
    J = arm.scale_task(arm.jacobian(Q))
    free = remap.remap(arm, Q, QD, [2])
    wide = (np.full(7, -10.0), np.full(7, 10.0))
    np.testing.assert_array_equal(remap.remap(arm, Q, QD, [2], bounds=wide), free)
    j = int(np.argmax(np.abs(np.delete(free, 2))))
    j += j >= 2  # back to chain order
    lo, hi = wide[0].copy(), wide[1].copy()
    if free[j] > 0:
        hi[j] = 0.3 * free[j]
    else:
        lo[j] = 0.3 * free[j]
    out = remap.remap(arm, Q, QD, [2], bounds=(lo, hi))
    assert out[2] == 0.0
    assert out[j] == pytest.approx(0.3 * free[j])
    assert np.all((lo - 1e-9 <= out) & (out <= hi + 1e-9))
    np.testing.assert_allclose(J @ out, J @ QD, atol=1e-6)


def test_bounds_leave_a_command_that_holds_the_locked_joints_to_its_sender() -> None:
    """A command the remap does not change passes as it is, whatever the bounds say."""
    knowing = QD.copy()
    knowing[2] = 0.0
    tight = (np.full(7, -1e-3), np.full(7, 1e-3))
    np.testing.assert_array_equal(remap.remap(PANDA, Q, knowing, [2], bounds=tight), knowing)
