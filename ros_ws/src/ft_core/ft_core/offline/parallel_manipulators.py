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


def hard_failure_measure(J: np.ndarray, J_hat: np.ndarray) -> float:
    """Hard-failure measure h = w(J) / w(P_J J_hat) (Yi et al. 2006 eq 16).

    A strut lost altogether (fatigue, a blown-off strut): `J_hat` is the Jacobian derived
    again after the loss, from the remaining actuator rates to the same task velocities
    as the nominal `J` (task rows by actuator columns, J of full column rank). The loss
    may free degrees of freedom, so J_hat can have more columns than J has rank;
    P_J = J (J^T J)^-1 J^T projects onto the nominal task directions, and the measure
    compares manipulability there only (the paper: it does not see the gained DOFs).

    Reading of w for P_J J_hat, whose rank is at most J's n: the product of its n
    largest singular values (the paper's w(P_J J_hat) where P_J J_hat has full rank n,
    and eq 13's w(J_hat) when nothing is gained, P_J J_hat = J_hat). In [0, 1] when the
    failure only relaxes constraints; 0 as the manipulator loses kinematic stability
    (J_hat unbounded).

    Raises:
        ValueError: J not of full column rank, shapes that differ in task rows, or a
            J_hat that lost a nominal direction (P_J J_hat of rank below n).
    """
    J, J_hat = as_matrix(J), as_matrix(J_hat)
    if J.shape[0] != J_hat.shape[0]:
        raise ValueError(f"J has {J.shape[0]} task rows but J_hat has {J_hat.shape[0]}")
    U, s, _ = np.linalg.svd(J, full_matrices=False)
    n = J.shape[1]
    if n > J.shape[0] or s[-1] <= 1e-12 * max(s[0], 1e-300):
        raise ValueError(f"J ({J.shape[0]} x {n}) must have full column rank")
    projected = U @ (U.T @ J_hat)  # P_J J_hat, with P_J = U U^T = J (J^T J)^-1 J^T
    kept = np.linalg.svd(projected, compute_uv=False)[:n]
    if kept.size < n or kept[-1] <= 1e-12 * s[0]:
        raise ValueError("J_hat lost a nominal task direction: not a hard failure's "
                         "relaxation (use the position-failure measure)")
    return float(np.prod(s) / np.prod(kept))
