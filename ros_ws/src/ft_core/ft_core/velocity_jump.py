"""Minimum joint-velocity jump (Zhao and Li, Zhao & Li), generalised to failure probabilities.

If joint i locks now, the task velocity xd is carried on by the reduced robot with
the least-norm velocity iqd' = (iJ)+ xd, re-embedded with 0 at joint i (Zhao & Li
eqs 2, 6). The jump a lock causes is iqd' - qd (eq 1). Weighting the failures by
w_i = p_i / sum p (Xie 2019 eq 3.4) and minimising

    jump index = sum_i c_i |iqd' - qd|^2,   c_i = n w_i,   subject to J qd = xd

gives qd = J+ xd + (I - J+ J) sum_i w_i iqd' (Zhao & Li eq 5 when w_i = 1/n).
With equal probabilities c_i = 1 and the index is the paper's eqs 9-10, so
least norm exceeds the optimum by exactly n |qd_H|^2 (eq 14). With all weight on
joint k the optimum is kqd' itself: joint k stays still (eq 8).

Every function works on the Jacobian of the robot as it is (pass the healthy
columns when joints are already locked). Without `damping` the pseudo-inverses
are exact Moore-Penrose inverses. This is the closed form as the paper writes it, for
scripts and notebooks and as the reference the engine's compiled minimum-jump term
(`ft_core.engine`, `ft_core.postfailure`) is tested against; the control cycle does not
call it.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from ft_core.measures import as_matrix, failure_weights, post_failure_svd
from ft_core.pseudoinverse import Damping, pseudo_inverse_from_svd


def _pinv(A: np.ndarray, damping: Damping | None) -> np.ndarray:
    return pseudo_inverse_from_svd(*np.linalg.svd(A, full_matrices=False), damping)


def _task_velocity(xd: np.ndarray, m: int) -> np.ndarray:
    xd = np.asarray(xd, dtype=float)
    if xd.shape != (m,):
        raise ValueError(f"xd must have shape ({m},), got {xd.shape}")
    if not np.all(np.isfinite(xd)):
        raise ValueError("xd has non-finite entries")
    return xd


def post_failure_velocities(J: np.ndarray, xd: np.ndarray,
                            damping: Damping | None = None) -> np.ndarray:
    """Row i: the velocity iqd' = (iJ)+ xd the robot would have if joint i locked (n, n).

    Entry (i, i) is 0 (Zhao & Li eqs 2 and 6).
    """
    J = as_matrix(J)
    xd = _task_velocity(xd, J.shape[0])
    U, S, Vt = post_failure_svd(J)
    return pseudo_inverse_from_svd(U, S, Vt, damping) @ xd


def min_jump_velocity(J: np.ndarray, xd: np.ndarray,
                      probabilities: Iterable[float] | None = None,
                      damping: Damping | None = None) -> np.ndarray:
    """Joint velocity with the least weighted jump index that tracks xd (Zhao & Li eq 5)."""
    J = as_matrix(J)
    xd = _task_velocity(xd, J.shape[0])
    n = J.shape[1]
    pinv = _pinv(J, damping)
    mean = failure_weights(probabilities, n) @ post_failure_velocities(J, xd, damping)
    return pinv @ xd + mean - pinv @ (J @ mean)


def jump_index(J: np.ndarray, qd: np.ndarray, xd: np.ndarray,
               probabilities: Iterable[float] | None = None,
               damping: Damping | None = None) -> float:
    """sum_i c_i |iqd' - qd|^2 with c_i = n w_i (Zhao & Li eqs 9-10 for equal probabilities)."""
    J = as_matrix(J)
    qd = np.asarray(qd, dtype=float)
    n = J.shape[1]
    if qd.shape != (n,):
        raise ValueError(f"qd must have shape ({n},), got {qd.shape}")
    jumps = post_failure_velocities(J, xd, damping) - qd
    return float(n * failure_weights(probabilities, n) @ np.sum(jumps**2, axis=1))


def joint_velocity_jumps(J: np.ndarray, qd: np.ndarray, xd: np.ndarray,
                         damping: Damping | None = None) -> np.ndarray:
    """Per-joint jumps |iqd'_j - qd_j| (n, n): row i for a lock of joint i (Zhao & Li eq 1)."""
    return np.abs(post_failure_velocities(J, xd, damping) - np.asarray(qd, dtype=float))
