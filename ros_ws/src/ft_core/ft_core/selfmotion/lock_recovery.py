"""Recovery configurations: where the reduced robot still reaches a traced point.

Lewis & Maciejewski 1997 sec. III: a joint locked inside the manifold's range leaves a
configuration of the manifold with that joint at its value.
"""

from __future__ import annotations

import numpy as np

from ft_core.selfmotion.manifold import Manifold, project


def recovery_configuration(manifold: Manifold, joint: int, value: float) -> np.ndarray:
    """A configuration on the manifold with q[joint] = value (joint locked at `value`).

    Interpolates between the consecutive traced samples that straddle `value` and
    corrects onto the manifold with the joint held at `value`: from it the reduced
    robot reaches the target exactly. Raises ValueError when `value` is outside
    the manifold's range for that joint.
    """
    robot = manifold.robot
    candidates = []
    for path in manifold.paths:
        values = path[:, joint] - value
        for k in np.flatnonzero(values[:-1] * values[1:] <= 0):
            a, b = path[k], path[k + 1]
            span = b[joint] - a[joint]
            t = 0.0 if span == 0 else (value - a[joint]) / span
            candidates.append(a + t * (b - a))
    exact = np.flatnonzero(np.abs(manifold.samples[:, joint] - value) < 1e-12)
    candidates += [manifold.samples[k] for k in exact]
    for candidate in candidates:
        candidate = candidate.copy()
        candidate[joint] = value
        q = project(robot, manifold.target, candidate, fixed=[joint])
        if q is not None:
            return q
    lower, upper = manifold.box
    raise ValueError(f"joint {joint} at {value:.4f} is outside the manifold's range "
                     f"[{lower[joint]:.4f}, {upper[joint]:.4f}] or no sample pair "
                     "straddling it could be corrected")


def recover(manifold: Manifold, q: np.ndarray, joint: int) -> np.ndarray | None:
    """Drive the robot with `joint` locked at q[joint] back to the manifold's target.

    Inside the manifold's range for that joint, the other joints move in a straight
    line (inside the limits, which are a box) to `recovery_configuration`, where
    the target is reached exactly: the guarantee of Lewis & Maciejewski 1997 sec. III. Otherwise
    nothing guarantees success: the reduced Jacobian's closed loop (Newton on the
    healthy joints, inside the limits) runs from q and may stop short. Returns the
    final configuration, or None when the target was not reached.
    """
    q = np.asarray(q, dtype=float)
    try:
        return recovery_configuration(manifold, joint, float(q[joint]))
    except ValueError:
        return project(manifold.robot, manifold.target, q, fixed=[joint], iterations=300)


