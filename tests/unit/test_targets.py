"""ft_core.targets: pose-goal tracking law and twist staleness."""

from __future__ import annotations

import numpy as np
import pytest
from ft_core import robots
from ft_core.targets import (
    PoseTracking,
    goal_from_transform,
    pose_velocity,
    staleness_scale,
    twist_velocity,
)

PANDA = robots.load("panda")
Q = np.array([0.4, 0.3, -0.5, -1.9, 0.6, 1.4, -0.2])


def test_far_goals_are_approached_at_capped_speeds_in_the_error_direction() -> None:
    goal = PANDA.forward(Q)
    goal[:3, 3] += [0.3, 0.0, -0.4]
    tracking = PoseTracking(gain=2.0, max_linear=0.1, max_angular=0.2)
    xd, reached = pose_velocity(PANDA, PANDA.task_error(goal, Q), tracking)
    assert not reached
    assert np.linalg.norm(xd[:3]) == pytest.approx(0.1)
    np.testing.assert_allclose(xd[:3] / 0.1, np.array([0.3, 0.0, -0.4]) / 0.5, atol=1e-12)


def test_near_goals_use_the_gain_and_reached_goals_give_zero() -> None:
    goal = PANDA.forward(Q)
    goal[:3, 3] += [0.01, 0.0, 0.0]
    xd, _ = pose_velocity(PANDA, PANDA.task_error(goal, Q), PoseTracking(gain=2.0))
    np.testing.assert_allclose(xd[:3], [0.02, 0, 0], atol=1e-12)
    xd, reached = pose_velocity(PANDA, PANDA.task_error(PANDA.forward(Q), Q), PoseTracking())
    assert reached and np.all(xd == 0.0)


def test_position_tasks_ignore_orientation() -> None:
    position = robots.load("panda", task_space="position")
    transform = PANDA.forward(Q)
    goal = goal_from_transform(position, transform)
    np.testing.assert_allclose(goal, transform[:3, 3])
    assert twist_velocity(position, np.arange(6.0)).tolist() == [0.0, 1.0, 2.0]
    planar = robots.load("planar3r")
    assert goal_from_transform(planar, transform).shape == (2,)


def test_staleness_scale() -> None:
    assert staleness_scale(0.3, 0.5) == 1.0
    assert staleness_scale(0.75, 0.5) == pytest.approx(0.5)
    assert staleness_scale(1.5, 0.5) == 0.0


@pytest.mark.parametrize("field", ["gain", "max_linear", "max_angular"])
def test_invalid_tracking_parameters(field: str) -> None:
    with pytest.raises(ValueError, match=field):
        PoseTracking(**{field: 0.0})
