"""Free-swinging joint failures: the swing angle of each joint and its measure (seed 002).

A joint that loses its torque swings under gravity until the centre of mass of
everything outboard of it hangs lowest. The swing angle of joint i (seed 002 sec. 2.3,
eqs 11-13) is the angle between the projections of s (the first moment of inertia of
the outboard composite body about the joint's origin) and of the downward direction
onto the plane normal to the joint's axis z:

    theta_i = atan2(z . (g x s), (s x z) . (z x g)),    g pointing up,

the rotation about z (rad, right-handed) the joint makes as it falls: -pi/2 for a
horizontal arm whose axis points out of the vertical plane it moves in, 0 hanging,
+-pi upright. The measure is h(q) = theta^T W theta (eq 14), W diagonal. Reading taken:
the paper indexes joints from 1 with D-H frame i-1 on joint i; here joint i's own axis
and origin from the URDF (the same physical quantities). A joint whose outboard
moment or gravity is parallel to its axis has no defined swing: its angle and its
term of the gradient are 0. Revolute joints only (a chain with a prismatic joint is
refused).

The gradient of h is analytic: joint k rotating moves, about its axis z_k, every vector
outboard of it, so dz_i/dq_k = z_k x z_i and ds_i/dq_k = z_k x s_i for k < i, and
ds_i/dq_k = z_k x s_k for k >= i (only the bodies outboard of k move, about p_k).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ft_core.robots import Robot

#: Gravity (m/s^2) in the URDF root frame when none is given: -z, as URDF assumes.
STANDARD_GRAVITY = (0.0, 0.0, -9.81)
#: Norm below which a projection (of s or g on the plane normal to an axis) is zero.
_DEGENERATE = 1e-12


def _angle_terms(z: np.ndarray, s: np.ndarray, up: np.ndarray) -> tuple[float, float]:
    """(A, B) with theta = atan2(A, B) (eqs 11-13)."""
    return float(z @ np.cross(up, s)), float(np.cross(s, z) @ np.cross(z, up))


def _defined(z: np.ndarray, s: np.ndarray, up: np.ndarray) -> bool:
    return (np.linalg.norm(np.cross(s, z)) > _DEGENERATE
            and np.linalg.norm(np.cross(z, up)) > _DEGENERATE)


def _moments(robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    axes, moments = robot.outboard_moments(q)
    prismatic = [robot.joint_names[i] for i in np.flatnonzero(np.linalg.norm(axes, axis=1) == 0)]
    if prismatic:
        raise ValueError(f"the swing measure takes revolute joints only: {prismatic}")
    return axes, moments


def swing_angles(robot: Robot, q: np.ndarray,
                 gravity: Sequence[float] = STANDARD_GRAVITY) -> np.ndarray:
    """Swing angle of each joint were it to fail at q (rad, (n,); eq 13)."""
    up = -np.asarray(gravity, dtype=float)
    axes, moments = _moments(robot, q)
    return np.array([np.arctan2(*_angle_terms(z, s, up)) if _defined(z, s, up) else 0.0
                     for z, s in zip(axes, moments, strict=True)])


def swing_measure(robot: Robot, q: np.ndarray, weights: Sequence[float] | None = None,
                  gravity: Sequence[float] = STANDARD_GRAVITY) -> float:
    """h(q) = theta^T W theta (rad^2; eq 14), W = diag(weights), default the identity."""
    theta = swing_angles(robot, q, gravity)
    w = np.ones(robot.n) if weights is None else np.asarray(weights, dtype=float)
    return float(theta @ (w * theta))


def swing_gradient(robot: Robot, q: np.ndarray, weights: Sequence[float] | None = None,
                   gravity: Sequence[float] = STANDARD_GRAVITY) -> np.ndarray:
    """dh/dq (rad^2 per rad, (n,)), analytic (see the module notes)."""
    up = -np.asarray(gravity, dtype=float)
    w = np.ones(robot.n) if weights is None else np.asarray(weights, dtype=float)
    axes, moments = _moments(robot, q)
    gradient = np.zeros(robot.n)
    for i, (z, s) in enumerate(zip(axes, moments, strict=True)):
        if not _defined(z, s, up) or w[i] == 0:
            continue
        a, b = _angle_terms(z, s, up)
        theta = np.arctan2(a, b)
        for k in range(robot.n):
            zk = axes[k]
            dz = np.cross(zk, z) if k < i else np.zeros(3)
            ds = np.cross(zk, s if k < i else moments[k])
            da = dz @ np.cross(up, s) + z @ np.cross(up, ds)
            db = ((np.cross(ds, z) + np.cross(s, dz)) @ np.cross(z, up)
                  + np.cross(s, z) @ np.cross(dz, up))
            gradient[k] += 2 * w[i] * theta * (b * da - a * db) / (a * a + b * b)
    return gradient
