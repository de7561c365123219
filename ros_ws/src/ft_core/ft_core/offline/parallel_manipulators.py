"""Failure-tolerance measures of parallel manipulators (Yi, McInroy and Chen, Yi et al. 2006).

A parallel manipulator's actuator velocities are theta_a = T theta'_a (eq 2) with T
an N x n matrix of orthonormal columns, and its task velocity v_m = J_m theta'_a
(eq 1). With T = I these reduce to the serial relative manipulability of
`ft_core.measures.relative_manipulability`.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from ft_core.measures import as_matrix, manipulability, null_space_basis


def _rows(T: np.ndarray, indices: Iterable[int]) -> np.ndarray:
    rows = sorted(set(int(i) for i in indices))
    if not rows or rows[0] < 0 or rows[-1] >= T.shape[0]:
        raise ValueError(f"actuator indices {rows} must be non-empty and in 0..{T.shape[0] - 1}")
    return np.array(rows)


def position_failure_measure(T: np.ndarray, J_m: np.ndarray, failed: Iterable[int]) -> float:
    """Position-failure measure p = w((T N)_failed) / w(T_failed) (Yi et al. 2006 eq 9).

    The failed actuators are stuck in place.
    N is an orthonormal basis of the null space of the major-task Jacobian J_m.
    For one failure this is eq 10, p_i = w(T_i / |T_i| N). 0 when J_m has no null
    space (no redundancy left to absorb the failure).
    """
    T, J_m = as_matrix(T), as_matrix(J_m)
    if T.shape[1] != J_m.shape[1]:
        raise ValueError(f"T has {T.shape[1]} columns but J_m has {J_m.shape[1]}")
    rows = _rows(T, failed)
    N = null_space_basis(J_m)
    if N.shape[1] < rows.size:
        return 0.0
    return manipulability(T[rows] @ N) / manipulability(T[rows])


def torque_failure_measure(T: np.ndarray, failed: Iterable[int]) -> float:
    """Torque-failure measure t = w(T_r) (Yi et al. 2006 eq 14).

    T_r holds the rows of T of the remaining actuators.
    """
    T = as_matrix(T)
    rows = _rows(T, failed)
    remaining = np.setdiff1d(np.arange(T.shape[0]), rows)
    if remaining.size < T.shape[1]:
        return 0.0
    return manipulability(T[remaining])
