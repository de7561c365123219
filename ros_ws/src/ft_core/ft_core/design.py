"""Design tools: optimally fault tolerant null spaces and Jacobians (seed 001, ch. 3).

Given failure probabilities p (weights w = p / sum p, seed 001 eq 3.4), the
isotropic Jacobian that maximises the weighted fault tolerance F_w has a null
vector with |n_i| = w_i / |w| (eq 3.15); its post-failure singular values are then
s_i = sigma |n_i| (eq 3.12). `optimal_jacobian` builds it with the triangular
construction of eq 3.18, which for equal weights is the canonical optimal
Jacobian (seed 001 eq 2.6, seed 002 eq 10).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from ft_core.measures import failure_weights


def optimal_null_vector(probabilities: Iterable[float]) -> np.ndarray:
    """Unit null vector with |n_i| = w_i / |w| (seed 001 eq 3.15), entries >= 0."""
    p = np.asarray(list(probabilities), dtype=float)
    w = failure_weights(p, p.size)
    return w / np.linalg.norm(w)


def optimal_null_space_norms(probabilities: Iterable[float], m: int) -> np.ndarray:
    """Row norms |n_i| of an optimal orthonormal null-space basis (seed 001 eq 3.29).

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

    Seed 001 eq 3.18: sort the weights ascending, fill the upper-triangular form
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


def _check_task_dimension(m: int, n: int) -> None:
    if not 1 <= m < n:
        raise ValueError(f"task dimension m must satisfy 1 <= m < n = {n}, got {m}")
