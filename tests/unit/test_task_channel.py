"""Issue 16, part 2: undetected locks (Maciejewski et al. Theorem 1) and the task-space channel."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from ft_core import robots, selfmotion
from ft_core.task_channel import TaskChannel, TaskChannelConfig
from models import DT, PLANAR, pseudoinverse_control


def test_theorem_1_an_undetected_lock_of_joint_2_still_converges() -> None:
    """Maciejewski et al. fig. 3: from x_i = (2, -1.4) to x_d = (1.5, 1.5) with joint 2 locked."""
    q0 = selfmotion.find_seed(PLANAR, np.array([2.0, -1.4]), np.array([-0.48, -0.97, 1.51]))
    q, _, _, suspected = pseudoinverse_control(q0, np.array([1.5, 1.5]), locked=1)
    assert np.linalg.norm(PLANAR.forward(q) - [1.5, 1.5]) < 1e-3
    assert suspected is None  # converging: nothing to suspect


def test_theorem_1_an_undetected_lock_of_joint_1_converges_wrongly_and_is_caught() -> None:
    """Maciejewski et al. fig. 4: from x_i = (-0.9, 1.8) with joint 1 locked.

    The arm stops far from x_d = (1.5, 1.5), which the crippled arm could reach, where
    the reduced Jacobian [j2 j3] is rank deficient and all the commanded motion is on
    joint 1 (eqs 16-17); the task-space channel names joint 1. The paper does not give
    the initial configuration: this one (elbow up, q1 = 1.87 rad) shows the behaviour.
    Issue 34 item 6: the equilibrium is a saddle. The arm stays at it, 1.87 m off, for
    more than 40 s, then leaves it and is within 5 cm of x_d by 100 s.
    """
    q0 = selfmotion.find_seed(PLANAR, np.array([-0.9, 1.8]), np.array([1.873, -0.708, 2.05]))
    x_d = np.array([1.5, 1.5])
    q, qd, channel, suspected = pseudoinverse_control(q0, x_d, locked=0)
    assert np.linalg.norm(PLANAR.forward(q) - x_d) > 1.0  # stuck far away
    J = PLANAR.jacobian(q)
    assert np.linalg.svd(J[:, 1:], compute_uv=False)[-1] < 1e-2  # eq 17: rank deficient
    assert np.linalg.svd(J, compute_uv=False)[-1] > 0.1  # at a non-singular configuration
    assert abs(qd[0]) > 0.99 * np.linalg.norm(qd)  # eq 16: only the failed joint commanded
    x_c = x_d - PLANAR.forward(q)
    cosine = abs(x_c @ J[:, 0]) / (np.linalg.norm(x_c) * np.linalg.norm(J[:, 0]))
    assert cosine > 0.99  # x_c lies along j1
    # x_d is in the post-failure workspace: reachable with joint 1 where it locked.
    lower, upper = PLANAR.lower.copy(), PLANAR.upper.copy()
    lower[0] = upper[0] = q0[0]
    assert selfmotion.find_seed(PLANAR, x_d, q, lower, upper) is not None
    assert suspected is not None and suspected[1] == 0
    assert channel.suspect == 0 and channel.residuals[0] < 0.25 < channel.residuals[1:].min()
    lingering = pseudoinverse_control(q, x_d, locked=0)[0]  # at 40 s: still there
    assert np.linalg.norm(PLANAR.forward(lingering) - x_d) > 1.8
    assert np.linalg.svd(PLANAR.jacobian(lingering)[:, 1:], compute_uv=False)[-1] < 1e-2
    late = pseudoinverse_control(lingering, x_d, locked=0, seconds=60.0)[0]  # at 100 s
    assert np.linalg.norm(PLANAR.forward(late) - x_d) < 0.05


def test_a_healthy_stall_or_a_slow_approach_is_not_suspected() -> None:
    """A goal out of reach: the error stops shrinking, but nothing is unexplained.

    The joints do what they are told, so no joint is suspected.
    """
    channel = TaskChannel(PLANAR)
    q = np.array([0.3, 0.4, 0.5])
    for k in range(400):
        error = np.array([5.0, 0.0]) - PLANAR.forward(q)  # 5 m: beyond the 3 m reach
        qd = np.linalg.pinv(PLANAR.jacobian(q)) @ error
        qd *= min(1.0, 0.5 / np.linalg.norm(qd))
        assert channel.update(k * DT, PLANAR.kinematics(q), qd,
                              float(np.linalg.norm(error))) is None
        q = q + DT * qd


def test_configuration_and_task_checks() -> None:
    with pytest.raises(ValueError, match="explained"):
        TaskChannelConfig(explained=1.0)






def test_a_pose_task_explains_rotation_and_names_a_lone_locked_joint() -> None:
    """Pose tasks too (`Robot.displacement`).

    A healthy arm turning and moving leaves no unexplained motion; one that stands still
    while only joint 2 is commanded (the equilibrium of Theorem 1) has joint 2 named.
    """
    panda = robots.load("panda", task_space="pose")
    channel, q = TaskChannel(panda), panda.home()
    qd = np.array([0.3, -0.2, 0.25, 0.2, -0.3, 0.3, 0.4])
    for k in range(200):  # an error that does not shrink: the test runs at every update
        assert channel.update(k * DT, panda.kinematics(q), qd, 0.1) is None
        q = q + DT * qd
    path = [panda.home() + k * DT * qd for k in range(201)]  # 0.8 s, 0.9 rad of turn
    integrated = sum(panda.jacobian(p) @ qd * DT for p in path[:-1])
    summed = sum(panda.displacement(panda.forward(a), panda.forward(b))
                 for a, b in itertools.pairwise(path))
    # Per cycle, the angular rows integrate to the rotation's log (to second order).
    assert np.linalg.norm(summed - integrated) < 0.01 * np.linalg.norm(integrated)
    channel, qd = TaskChannel(panda), np.zeros(7)
    qd[1] = 0.05
    suspects = [channel.update(k * DT, panda.kinematics(panda.home()), qd, 0.1) for k in range(200)]
    assert suspects[-1] == 1
