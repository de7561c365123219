"""The controller's targets read against the model: twists and pose goals in the base frame.

`twist` and `pose_goal` raise `convert.MessageError` with the reason a message is
refused; `Targets` hands the accepted ones to the core and reports the rest.
"""

from __future__ import annotations

import numpy as np
from ft_core import limits
from ft_core.robots import Robot
from ft_core.targets import goal_from_transform, twist_velocity
from ft_msgs_py import convert, names
from ft_msgs_py.episodes import Episodes
from geometry_msgs.msg import PoseStamped, TwistStamped

from ft_controller.loaded import Loaded

TWIST, POSE = names.TARGET_TWIST, names.TARGET_POSE


def frame_problem(robot: Robot, frame: str) -> str | None:
    """Why a target in `frame` is ignored (None: the base frame, or none given)."""
    if frame in ("", robot.base_link):
        return None
    return f"frame '{frame}' is not the base frame '{robot.base_link}': ignored"


def twist(robot: Robot, msg: TwistStamped) -> np.ndarray:
    """The task velocity (`ft_core.targets.twist_velocity`) of a twist message."""
    return twist_velocity(robot, convert.twist_vector(msg.twist))


def pose_goal(robot: Robot, msg: PoseStamped) -> np.ndarray:
    """The goal (`ft_core.targets.goal_from_transform`) of a pose message.

    Refused further than `limits.ABSURD_DISTANCE` m from the base: no arm reaches it.
    """
    transform = convert.pose_matrix(msg.pose)
    if np.max(np.abs(transform[:3, 3])) > limits.ABSURD_DISTANCE:
        raise convert.MessageError(f"goal further than {limits.ABSURD_DISTANCE:g} m: "
                                   "no arm reaches it")
    return goal_from_transform(robot, transform)


class Targets:
    """The controller's targets, checked and handed to the core; refusals reported.

    A target outside the base frame is ignored (a WARN); a malformed one, or a twist
    stamped ahead of the clock, is refused (an ERROR) and the core keeps what it had.
    """

    def __init__(self, problems: Episodes):
        """`problems`: the node's, where refusals are reported by topic."""
        self._problems = problems

    def _read(self, topic: str, msg: TwistStamped | PoseStamped, loaded: Loaded | None,
              ) -> np.ndarray | None:
        if loaded is None:
            return None
        problem = frame_problem(loaded.robot, msg.header.frame_id)
        self._problems.report(topic, problem, warning=problem is not None)
        if problem is not None:
            return None
        try:
            return (twist if topic == TWIST else pose_goal)(loaded.robot, msg)
        except convert.MessageError as error:
            self._problems.report(topic, str(error))
            return None

    def on_twist(self, msg: TwistStamped, loaded: Loaded | None, now: float) -> None:
        """A twist at node time `now` (s): the core's target from its stamp on."""
        velocity = self._read(TWIST, msg, loaded)
        stamp = None if velocity is None else self._problems.message_time(
            TWIST, msg.header.stamp, now)
        if stamp is not None:
            loaded.core.set_twist(velocity, stamp)

    def on_pose(self, msg: PoseStamped, loaded: Loaded | None, now: float) -> None:
        """A pose goal at node time `now` (s): the core's target from now on."""
        goal = self._read(POSE, msg, loaded)
        if goal is not None:
            self._problems.report(POSE, None)
            loaded.core.set_pose_goal(goal, now)
