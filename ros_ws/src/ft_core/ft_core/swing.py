"""Free-swinging joint failures: the swing angle of each joint and its measure (Maciejewski et al.).

A joint that loses its torque swings under gravity until the centre of mass of
everything outboard of it hangs lowest. The swing angle of joint i (Maciejewski et al. sec. 2.3,
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
#: Viscous damping (1/s) of a free-swinging joint in `pendulum_acceleration`.
FREE_SWING_DAMPING = 2.0
#: rad/s^2: gravity that accelerates a torqueless joint less than this cannot be what
#: moves it (`falling_directions`).
MIN_FALL_ACCELERATION = 0.5
#: Norm below which a projection (of s or g on the plane normal to an axis) is zero.
_DEGENERATE = 1e-12


def _moments(robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    axes, moments = robot.outboard_moments(q)
    prismatic = [robot.joint_names[i] for i in np.flatnonzero(np.linalg.norm(axes, axis=1) == 0)]
    if prismatic:
        raise ValueError(f"the swing measure takes revolute joints only: {prismatic}")
    return axes, moments


class _Terms:
    """Eqs 11-13 for every joint: theta = atan2(a, b), with the cross products reused."""

    def __init__(self, axes: np.ndarray, moments: np.ndarray, gravity: Sequence[float]):
        self.up = -np.asarray(gravity, dtype=float)
        self.z_up = np.cross(axes, self.up)
        self.up_s = np.cross(self.up, moments)
        self.s_z = np.cross(moments, axes)
        self.a = np.einsum("ic,ic->i", axes, self.up_s)
        self.b = np.einsum("ic,ic->i", self.s_z, self.z_up)
        self.defined = ((np.linalg.norm(self.s_z, axis=1) > _DEGENERATE)
                        & (np.linalg.norm(self.z_up, axis=1) > _DEGENERATE))
        self.theta = np.where(self.defined, np.arctan2(self.a, self.b), 0.0)


def swing_angles(robot: Robot, q: np.ndarray,
                 gravity: Sequence[float] = STANDARD_GRAVITY) -> np.ndarray:
    """Swing angle of each joint were it to fail at q (rad, (n,); eq 13)."""
    return swing_state(robot, q, gravity)[0]


def swing_state(robot: Robot, q: np.ndarray, gravity: Sequence[float] = STANDARD_GRAVITY
                ) -> tuple[np.ndarray, np.ndarray]:
    """(swing angles (rad, (n,); eq 13), whether gravity turns each joint at all (bool, (n,))).

    Not turned: the joint's axis is along gravity or its outboard centre of mass is on
    the axis, so gravity has no torque about it at any angle (neutral); its angle is 0.
    """
    terms = _Terms(*_moments(robot, q), gravity)
    return terms.theta, terms.defined


def swing_measure(robot: Robot, q: np.ndarray, weights: Sequence[float] | None = None,
                  gravity: Sequence[float] = STANDARD_GRAVITY) -> float:
    """h(q) = theta^T W theta (rad^2; eq 14), W = diag(weights), default the identity."""
    theta = swing_angles(robot, q, gravity)
    w = np.ones(robot.n) if weights is None else np.asarray(weights, dtype=float)
    return float(theta @ (w * theta))


def swing_gradient(robot: Robot, q: np.ndarray, weights: Sequence[float] | np.ndarray | None = None,
                   gravity: Sequence[float] = STANDARD_GRAVITY) -> np.ndarray:
    """dh/dq (rad^2 per rad, (n,)), analytic (see the module notes)."""
    w = np.ones(robot.n) if weights is None else np.asarray(weights, dtype=float)
    axes, moments = _moments(robot, q)
    t = _Terms(axes, moments, gravity)
    # All pairs at once: [i, k] holds the derivative of joint i's terms by q_k.
    below = (np.arange(robot.n)[None, :] < np.arange(robot.n)[:, None])[..., None]
    dz = np.where(below, np.cross(axes[None, :], axes[:, None]), 0.0)
    ds = np.cross(axes[None, :], np.where(below, moments[:, None], moments[None, :]))
    da = np.einsum("ikc,ic->ik", dz, t.up_s) + np.einsum("ikc,ic->ik", ds, t.z_up)
    db = (np.einsum("ikc,ic->ik", np.cross(ds, axes[:, None]) + np.cross(moments[:, None], dz),
                    t.z_up) + np.einsum("ikc,ic->ik", np.cross(dz, t.up), t.s_z))
    factor = np.where(t.defined, 2 * w * t.theta, 0.0) / np.where(
        t.defined, t.a ** 2 + t.b ** 2, 1.0)
    return factor @ (t.b[:, None] * da - t.a[:, None] * db)


def pendulum_acceleration(robot: Robot, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """Joint accelerations (rad/s^2, (n,)) of each joint were it free-swinging at q, qd.

    The simulated stand-in for a joint that lost its torque: a pendulum about its axis,
    the other joints held by their drives, -g_i(q) / M_ii - `FREE_SWING_DAMPING` qd_i
    with g the generalised gravity and M the joint-space inertia (Pinocchio, from the
    URDF's inertias; a joint without outboard inertia gets 0). It neglects the
    coupling with the moving joints and friction other than the viscous term.
    """
    gravity, inertia = robot.gravity_dynamics(q)
    with np.errstate(divide="ignore", invalid="ignore"):
        falling = np.where(inertia > 0, -gravity / inertia, 0.0)
    return falling - FREE_SWING_DAMPING * np.asarray(qd, dtype=float)


def falling_directions(robot: Robot, q: np.ndarray) -> np.ndarray | None:
    """The way gravity would turn each joint at q were its torque lost: +1, -1, or 0.

    0 where `pendulum_acceleration` at rest is below `MIN_FALL_ACCELERATION` (a
    vertical axis, a joint near its hanging or upright balance, little outboard
    mass); None for a model without inertias, whose gravity is unknown. The lock
    detector's evidence that a joint moving on its own follows gravity (Maciejewski
    et al. sec. 2.3: a joint that lost its torque falls).
    """
    if not robot.has_inertias:
        return None
    acceleration = pendulum_acceleration(robot, q, np.zeros(robot.n))
    return np.where(np.abs(acceleration) >= MIN_FALL_ACCELERATION, np.sign(acceleration), 0.0)
