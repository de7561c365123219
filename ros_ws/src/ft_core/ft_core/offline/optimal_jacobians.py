"""Optimally fault tolerant null spaces and Jacobians (Xie 2019, ch. 3).

Given failure probabilities p (weights w = p / sum p, Xie 2019 eq 3.4), the
isotropic Jacobian that maximises the weighted fault tolerance F_w has a null
vector with |n_i| = w_i / |w| (eq 3.15); its post-failure singular values are then
s_i = sigma |n_i| (eq 3.12). `optimal_jacobian` builds it with the triangular
construction of eq 3.18, which for equal weights is the canonical optimal
Jacobian (Xie 2019 eq 2.6, Maciejewski et al. eq 10). `redundant_optimal_jacobian` extends it
to several degrees of redundancy (eqs 3.26-3.29).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from ft_core.measures import failure_weights


def optimal_null_vector(probabilities: Iterable[float]) -> np.ndarray:
    """Unit null vector with |n_i| = w_i / |w| (Xie 2019 eq 3.15), entries >= 0."""
    p = np.asarray(list(probabilities), dtype=float)
    w = failure_weights(p, p.size)
    return w / np.linalg.norm(w)


def optimal_null_space_norms(probabilities: Iterable[float], m: int) -> np.ndarray:
    """Row norms |n_i| of an optimal orthonormal null-space basis (Xie 2019 eq 3.29).

    |n_i| = w_i sqrt((n - m) / sum w^2), capped at 1; as the text after eq 3.29
    says, a capped row keeps norm 1 and the others share the remaining n - m - k
    by the same rule, repeated until no row exceeds 1. The squares sum to n - m
    (eq 3.28).
    """
    p = np.asarray(list(probabilities), dtype=float)
    n = p.size
    _check_task_dimension(m, n)
    w = failure_weights(p, n)
    norms = np.zeros(n)
    capped = np.zeros(n, dtype=bool)
    while True:
        free = ~capped
        budget = (n - m) - capped.sum()
        norms[capped] = 1.0
        norms[free] = w[free] * np.sqrt(budget / np.sum(w[free] ** 2))
        over = free & (norms > 1.0)
        if not over.any():
            return norms
        capped |= over


def optimal_jacobian(probabilities: Iterable[float], m: int) -> np.ndarray:
    """Isotropic m x n Jacobian (singular value 1) with null vector w / |w| (m = n - 1).

    Xie 2019 eq 3.18: sort the weights ascending, fill the upper-triangular form
    j_pp = -sqrt(S_{p+1} / S_p), j_pq = w_p w_q / sqrt(S_p S_{p+1}) (q > p) with
    S_p = sum_{i >= p} w_i^2, then permute the columns back.
    """
    p = np.asarray(list(probabilities), dtype=float)
    n = p.size
    _check_task_dimension(m, n)
    if m != n - 1:
        raise ValueError(f"optimal_jacobian builds one degree of redundancy (m = n - 1 = {n - 1}),"
                         f" got m = {m}")
    w = failure_weights(p, n)
    order = np.argsort(w, kind="stable")
    ws = w[order]
    tail = np.cumsum((ws**2)[::-1])[::-1]  # tail[p] = S_p
    J = np.zeros((m, n))
    for row in range(m):
        J[row, row] = -np.sqrt(tail[row + 1] / tail[row])
        J[row, row + 1:] = ws[row] * ws[row + 1:] / np.sqrt(tail[row] * tail[row + 1])
    unsorted = np.empty_like(J)
    unsorted[:, order] = J
    return unsorted


def projection_with_diagonal(diagonal: Iterable[float], rank: int) -> np.ndarray:
    """Orthogonal Q (n x n) whose first `rank` columns have row norms sqrt(diagonal).

    Q diag(1, .., 1, 0, .., 0) Q^T is the orthogonal projection of that rank with the
    given diagonal (Schur-Horn: exists iff 0 <= d_i <= 1 and sum d = rank). Built
    with at most n - 1 plane rotations, each moving diagonal mass between two
    entries (the T-transforms of Marshall and Olkin, Lemma 2.B.1, done as Givens
    rotations), so the loop is bounded by n.

    Raises:
        ValueError: the diagonal is outside [0, 1] or does not sum to `rank`.
    """
    d = np.asarray(list(diagonal), dtype=float)
    n = d.size
    if not 0 <= rank <= n or np.any(d < -1e-12) or np.any(d > 1 + 1e-12) \
            or abs(d.sum() - rank) > 1e-9 * max(1, n):
        raise ValueError(f"no rank-{rank} projection has diagonal {d}: need entries in [0, 1]"
                         f" summing to {rank}")
    order = np.argsort(-d, kind="stable")
    target = d[order]
    A = np.diag((np.arange(n) < rank).astype(float))
    Q = np.eye(n)
    for _ in range(n):  # each pass fixes one more diagonal entry
        current = np.diag(A)
        above = np.flatnonzero(current > target + 1e-14)
        below = np.flatnonzero(current < target - 1e-14)
        if above.size == 0 or below.size == 0:
            break
        j = int(above[-1])
        k = int(below[below > j][0]) if np.any(below > j) else int(below[0])
        value = current[j] - min(current[j] - target[j], target[k] - current[k])
        G = _rotation_setting_diagonal(A, j, k, value)
        A = G @ A @ G.T
        Q = G @ Q
    unsorted = np.empty_like(Q)
    unsorted[order] = Q
    return unsorted


def _rotation_setting_diagonal(A: np.ndarray, j: int, k: int, value: float) -> np.ndarray:
    """Givens rotation G in the (j, k) plane with (G A G^T)_jj = value.

    value must lie between A_jj and A_kk: f(phi) = a cos^2 + 2 b sin cos + c sin^2
    runs from A_jj (phi = 0) to A_kk (phi = pi / 2).
    """
    a, b, c = A[j, j], A[j, k], A[k, k]
    half, mean = (a - c) / 2.0, (a + c) / 2.0
    radius = float(np.hypot(half, b))
    phase = float(np.arctan2(b, half))
    ratio = 1.0 if radius == 0 else float(np.clip((value - mean) / radius, -1.0, 1.0))
    phi = (phase + np.arccos(ratio)) / 2.0
    if abs(mean + half * np.cos(2 * phi) + b * np.sin(2 * phi) - value) > 1e-9:
        phi = (phase - np.arccos(ratio)) / 2.0
    G = np.eye(A.shape[0])
    G[j, j] = G[k, k] = np.cos(phi)
    G[j, k], G[k, j] = np.sin(phi), -np.sin(phi)
    return G


def redundant_optimal_jacobian(probabilities: Iterable[float], m: int,
                               sigma: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Isotropic m x n Jacobian maximising F_w with n - m >= 1 degrees of redundancy.

    Xie 2019 eqs 3.25-3.29: J = sigma U_1 with U = [U_1; U_2] orthogonal, and the
    post-failure singular values are sigma |n_i| (eq 3.27) with |n_i| the row norms
    of the null-space basis U_2^T, so the optimum has the norms of eq 3.29
    (`optimal_null_space_norms`). A null-space basis with those row norms is built
    by `projection_with_diagonal`; for n - m = 1 it is the null vector of eq 3.15.

    Args:
        probabilities: n failure probabilities (eq 3.4).
        m: task dimension, 1 <= m < n.
        sigma: the singular value (m/s per rad/s, or 1 for the unit design).

    Returns:
        (J, N): J (m, n) with J J^T = sigma^2 I, and N (n, n - m) an orthonormal
        basis of its null space with row norms `optimal_null_space_norms`.
    """
    norms = optimal_null_space_norms(probabilities, m)
    n = norms.size
    Q = projection_with_diagonal(norms**2, n - m)
    return sigma * Q[:, n - m:].T, Q[:, :n - m]


def _check_task_dimension(m: int, n: int) -> None:
    if not 1 <= m < n:
        raise ValueError(f"task dimension m must satisfy 1 <= m < n = {n}, got {m}")
