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
redundancy left) it equals (J_h)# x, and it is J_h# x + (I - J_h# J_h) qd_h, the
task with the healthy joints' command as the null-space preference. Given velocity
bounds for position limits (`limits.velocity_bounds`), a command the remap changes
keeps them: healthy joints that would break them are held at them and the task is
solved again with the others, scaled down last, the preference kept where it fits
(Saturation in the Null Space, Flacco, De Luca and Khatib 2012,
`limits.saturate_in_null_space`); one it does not change (the locked joints already at
0) is its sender's to keep in bounds. If the result breaks a velocity limit, the whole
command is scaled down, direction kept.
Singular values are compared on `Robot.scale_task(J)`, as everywhere.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from ft_core import limits
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
          velocity_limits: np.ndarray | None = None, damping: Damping | None = None,
          bounds: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """The command with the same tool velocity from the healthy joints; 0 for locked ones.

    Args:
        robot: the model.
        q: the measured configuration (rad).
        qd: the command (rad/s).
        locked: indices of locked joints (none: qd is returned unchanged, but scaled
            into the velocity limits; all: zeros).
        velocity_limits: |qd'| bounds (rad/s), default the URDF's.
        damping: damped least squares rule, default `Damping()`.
        bounds: (lo, hi) per joint (rad/s, lo <= 0 <= hi) the healthy joints stay within
            where the remap changes the command (`limits.velocity_bounds`); None: none.
    """
    qd = np.asarray(qd, dtype=float)
    mask = locked_mask(robot.n, locked)
    speeds = robot.velocity_limits if velocity_limits is None else velocity_limits
    result = qd.copy()
    if mask.all():
        return np.zeros(robot.n)
    if mask.any():
        damping = damping or Damping()
        J = robot.scale_task(robot.jacobian(q))
        healthy = ~mask
        J_h = np.ascontiguousarray(J[:, healthy])
        pinv = damped_pinv(J_h, damping)
        result = np.zeros(robot.n)
        result[healthy] = qd[healthy] + pinv @ (J[:, mask] @ qd[mask])
        if bounds is not None and qd[mask].any():
            lo, hi = bounds[0][healthy], bounds[1][healthy]
            if not limits.within(result[healthy], lo, hi):
                result[healthy] = limits.saturate_in_null_space(
                    J_h, J @ qd, qd[healthy], lo, hi, damping.threshold, damping.max_damping,
                    pinv)[0]
    return within_limits(result, speeds)


def compile_ahead() -> None:
    """Load (or compile) the bounded remap's compiled functions now, not in a callback.

    Numba compiles each for the array types it is first called with; these are the ones
    `remap` passes (`make build` leaves them in numba's cache).
    """
    J, x = np.eye(3, 4), np.ones(3)
    lo, hi = limits.velocity_bounds(np.zeros(4), np.zeros(4), np.full(4, -1.0),
                                    np.full(4, 1.0), np.ones(4), np.ones(4), np.ones(4))
    limits.saturate_in_null_space(J, x, np.ones(4), lo, 0.5 * hi, 0.01, 0.05,
                                  np.ascontiguousarray(J.T))
