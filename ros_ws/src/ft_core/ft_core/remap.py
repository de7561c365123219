"""Reduced-Jacobian remapping of a joint velocity command around locked joints.

A controller that knows nothing about failures (MoveIt Servo, teleoperation)
keeps commanding the locked joints. The command means a tool velocity
x = J qd = J_h qd_h + J_l qd_l (healthy and locked columns); the locked joints get
exactly 0 and the healthy ones make up for them: qd'_h = qd_h + (J_h)# J_l qd_l (damped
least squares, see `pseudoinverse`; the closest achievable tool velocity when the
reduced robot cannot produce x). That is the smallest change of the healthy joints'
command that keeps x, so their own motion (a controller's null-space motion: kfm
ascent, limit avoidance, a recovery path) passes unchanged, and a command that already
holds the locked joints at 0 passes as it is. Where J_h has full column rank (no
redundancy left) it equals (J_h)# x. If the result breaks a velocity limit, the whole
command is scaled down, direction kept.
Singular values are compared on `Robot.scale_task(J)`, as everywhere.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from ft_core.measures import locked_mask
from ft_core.pseudoinverse import Damping, damped_pinv
from ft_core.robots import Robot


def within_limits(qd: np.ndarray, velocity_limits: np.ndarray) -> np.ndarray:
    """Qd scaled down as a whole (direction kept) so that |qd_i| <= velocity_limits_i.

    The limits are positive (inf for none). Python floats (every command passes here):
    numpy's calls cost more on a 7-joint arm. A nan in qd gives a nan in the result either
    way (the callers then command zeros).
    """
    excess = max((abs(v) / limit for v, limit in zip(qd.tolist(), velocity_limits.tolist(),
                                                     strict=True)), default=0.0)
    return qd / excess if excess > 1 else qd


def remap(robot: Robot, q: np.ndarray, qd: np.ndarray, locked: Iterable[int],
          velocity_limits: np.ndarray | None = None,
          damping: Damping | None = None) -> np.ndarray:
    """The command with the same tool velocity from the healthy joints; 0 for locked ones.

    Args:
        robot: the model.
        q: the measured configuration (rad).
        qd: the command (rad/s).
        locked: indices of locked joints (none: qd is returned unchanged, but scaled
            into the velocity limits; all: zeros).
        velocity_limits: |qd'| bounds (rad/s), default the URDF's.
        damping: damped least squares rule, default `Damping()`.
    """
    qd = np.asarray(qd, dtype=float)
    mask = locked_mask(robot.n, locked)
    limits = robot.velocity_limits if velocity_limits is None else velocity_limits
    result = qd.copy()
    if mask.all():
        return np.zeros(robot.n)
    if mask.any():
        J = robot.scale_task(robot.jacobian(q))
        healthy = ~mask
        result = np.zeros(robot.n)
        result[healthy] = qd[healthy] + damped_pinv(J[:, healthy], damping or Damping()) @ (
            J[:, mask] @ qd[mask])
    return within_limits(result, limits)
