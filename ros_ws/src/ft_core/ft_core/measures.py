"""Local fault-tolerance measures of a Jacobian for locked-joint failures.

Every function takes a plain m x n matrix J (no robot needed) and the indices of
joints already locked (`locked`). Locking joint i removes column i of J; here it
is zeroed, which leaves the nonzero singular values unchanged (Maciejewski et al., eq 5).
All post-failure Jacobians are decomposed in one batched SVD.

For a pose task, pass `Robot.scale_task(J)` so that angular rows are in m/s.

Reading taken where the papers are silent: when a further failure would leave
fewer healthy joints than task coordinates (n - |locked| - 1 < m), the reduced
Jacobian cannot span the task and its m-th singular value is 0, so the
post-failure singular value of that joint is reported as exactly 0.0 (no tolerance), not
as undefined. Entries for joints that are already locked are nan.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from numba import njit


def as_matrix(J: np.ndarray) -> np.ndarray:
    """Return J as a finite 2-D float array, or raise ValueError saying what is wrong."""
    J = np.asarray(J, dtype=float)
    if J.ndim != 2 or J.shape[0] == 0 or J.shape[1] == 0:
        raise ValueError(f"J must be a non-empty 2-D matrix, got shape {J.shape}")
    if not np.all(np.isfinite(J)):
        raise ValueError("J has non-finite entries")
    return J


def locked_mask(n: int, locked: Iterable[int] = ()) -> np.ndarray:
    """Boolean mask (n,) of locked joints; raise ValueError for an index outside 0..n-1."""
    mask = np.zeros(n, dtype=bool)
    for index in locked:
        if isinstance(index, bool) or int(index) != index or not 0 <= index < n:
            raise ValueError(f"locked joint index {index!r} is not in 0..{n - 1}")
        mask[int(index)] = True
    return mask


def post_failure_jacobians(J: np.ndarray, locked: Iterable[int] = ()) -> np.ndarray:
    """Stack (n, m, n): entry i is J with the columns of `locked` and of joint i zeroed."""
    J = as_matrix(J)
    n = J.shape[1]
    keep = ~locked_mask(n, locked)
    batch = np.repeat((J * keep)[None], n, axis=0)
    batch[np.arange(n), :, np.arange(n)] = 0.0
    return batch


def post_failure_svd(J: np.ndarray, locked: Iterable[int] = ()) -> tuple[np.ndarray, ...]:
    """Thin SVD (U, S, Vt) of all post-failure Jacobians in one batched call.

    Shapes (n, m, k), (n, k), (n, k, n) with k = min(m, n); entry i belongs to a
    failure of joint i (with `locked` also removed).
    """
    J = as_matrix(J)
    return np.linalg.svd(post_failure_jacobians(J, locked), full_matrices=False)


def post_failure_singular_values(J: np.ndarray, locked: Iterable[int] = ()) -> np.ndarray:
    """Singular values of every post-failure Jacobian, shape (n, m), descending.

    Row i belongs to a failure of joint i; rows of locked joints are nan. Values past
    the number of remaining columns (n - |locked| - 1) are exactly 0; the others carry
    LAPACK's absolute precision, about machine epsilon times the largest.
    """
    J = as_matrix(J)
    m, n = J.shape
    mask = locked_mask(n, locked)
    values = np.linalg.svd(post_failure_jacobians(J, np.flatnonzero(mask)), compute_uv=False)
    if values.shape[1] < m:
        values = np.pad(values, ((0, 0), (0, m - values.shape[1])))
    # n - |locked| - 1 nonzero columns span at most that many values: the rest are 0 by
    # structure, not whatever rounding LAPACK leaves there.
    values[:, max(n - int(mask.sum()) - 1, 0):] = 0.0
    values[mask] = np.nan
    return values


def post_failure_sigmas(J: np.ndarray, locked: Iterable[int] = ()) -> np.ndarray:
    """s_i = sigma_m(J without columns locked + {i}) for every joint i (Maciejewski et al. eq 6).

    Returns an (n,) array; nan for joints in `locked`.
    """
    return post_failure_singular_values(J, locked)[:, -1]


def kfm(J: np.ndarray, locked: Iterable[int] = ()) -> float:
    """Worst-case fault tolerance K = min_i s_i over healthy joints.

    Lewis & Maciejewski 1997 eq 5, Maciejewski et al. eq 6.

    0 when no healthy joint is left.
    """
    sigmas = post_failure_sigmas(J, locked)
    healthy = sigmas[~np.isnan(sigmas)]
    return float(healthy.min()) if healthy.size else 0.0


def failure_weights(probabilities: Iterable[float] | None, n: int,
                    locked: Iterable[int] = ()) -> np.ndarray:
    """Weights w_i = p_i / sum(p) over healthy joints (Xie 2019 eq 3.4); 0 for locked joints.

    `probabilities=None` (or empty) means equally likely failures. Raises ValueError
    for a wrong length, negative or non-finite entries, or no positive weight left.
    """
    mask = locked_mask(n, locked)
    p = np.ones(n) if probabilities is None else np.asarray(list(probabilities), dtype=float)
    if p.size == 0:
        p = np.ones(n)
    if p.shape != (n,):
        raise ValueError(f"need {n} failure probabilities, got {p.size}")
    if not np.all(np.isfinite(p)) or np.any(p < 0):
        raise ValueError(f"failure probabilities must be finite and >= 0, got {p}")
    p = np.where(mask, 0.0, p)
    if not np.any(p > 0):
        raise ValueError("failure probabilities of the healthy joints are all zero")
    p = p / p.max()  # relative values up to 1e308 sum without overflow
    return p / p.sum()


def weighted_fault_tolerance(J: np.ndarray, probabilities: Iterable[float] | None,
                             locked: Iterable[int] = ()) -> float:
    """F_w = sum_i w_i s_i with w from the failure probabilities (Xie 2019 eqs 3.3-3.4)."""
    J = as_matrix(J)
    w = failure_weights(probabilities, J.shape[1], locked)
    sigmas = np.nan_to_num(post_failure_sigmas(J, locked))
    return float(w @ sigmas)


def manipulability(A: np.ndarray) -> float:
    """Manipulability w(A) = max(sqrt(det(A A^T)), sqrt(det(A^T A))).

    The product of the min(rows, cols) singular values (Yi et al. 2006, after eq 8;
    Xie 2019 eq 2.10).
    """
    return float(np.prod(np.linalg.svd(as_matrix(A), compute_uv=False)))


def null_space_basis(A: np.ndarray) -> np.ndarray:
    """Orthonormal basis (k, k - m) of the null space of a full-row-rank m x k matrix A.

    The last k - m right singular vectors; continuous in A wherever A has full row
    rank. Empty (k, 0) when k <= m.
    """
    m, k = A.shape
    if k <= m:
        return np.zeros((k, 0))
    return np.linalg.svd(A)[2][m:].T


def relative_manipulability(J: np.ndarray, locked: Iterable[int] = ()) -> np.ndarray:
    """rho_i = w(iJ) / w(J) with w(A) = sqrt(det(A A^T)) (Yi et al. 2006 eqs 8-10, T = I).

    Computed as the norm of row i of an orthonormal null-space basis of the healthy
    columns (Yi et al. 2006 eq 10; Xie 2019 eq 3.26), which equals the ratio wherever J
    has full row rank and is its continuous extension elsewhere. nan for locked joints.
    """
    J = as_matrix(J)
    mask = locked_mask(J.shape[1], locked)
    rho = np.full(J.shape[1], np.nan)
    rho[~mask] = np.linalg.norm(null_space_basis(J[:, ~mask]), axis=1)
    return rho


def reduced_condition_numbers(J: np.ndarray, locked: Iterable[int] = ()) -> np.ndarray:
    """k_i = sigma_1(iJ) / sigma_m(iJ) for every joint (Zhao & Li eq 15); inf when singular."""
    values = post_failure_singular_values(J, locked)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = values[:, 0] / values[:, -1]
    ratio[(values[:, -1] == 0) & ~np.isnan(values[:, 0])] = np.inf
    return ratio


def worst_case_inverse_condition(J: np.ndarray, locked: Iterable[int] = ()) -> float:
    """min_f sigma_m(fJ) / sigma_1(fJ): reciprocal of kappa* of Xie 2019 eq 2.11 (0 to 1)."""
    values = post_failure_singular_values(J, locked)
    healthy = values[~np.isnan(values[:, 0])]
    if not healthy.size:
        return 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = np.where(healthy[:, 0] > 0, healthy[:, -1] / healthy[:, 0], 0.0)
    return float(inverse.min())


def worst_case_manipulability(J: np.ndarray, locked: Iterable[int] = ()) -> float:
    """w* = min_f w(fJ), the product of the m post-failure singular values (Xie 2019 eq 2.12)."""
    values = post_failure_singular_values(J, locked)
    healthy = values[~np.isnan(values[:, 0])]
    return float(np.prod(healthy, axis=1).min()) if healthy.size else 0.0


def sigma_gradients(U: np.ndarray, Vt: np.ndarray, dJ: np.ndarray,
                    locked: np.ndarray) -> np.ndarray:
    """G[i, k] = ds_i/dq_k = u_i^T (d iJ/dq_k) v_i from a `post_failure_svd`.

    Maciejewski et al. eq 8.

    `locked` is the boolean mask of joints already removed; dJ is (n, m, n).
    """
    n, m = U.shape[0], U.shape[1]
    u = U[:, :, m - 1]
    # Zero the removed columns so d(iJ)/dq_k = dJ[k] restricted to the kept columns.
    v = Vt[:, m - 1, :] * ~locked
    v[np.arange(n), np.arange(n)] = 0.0
    return np.einsum("ia,kab,ib->ik", u, dJ, v)


def post_failure_sigma_gradients(J: np.ndarray, dJ: np.ndarray,
                                 locked: Iterable[int] = ()) -> tuple[np.ndarray, np.ndarray]:
    """Post-failure singular values s_i and their gradients ds_i/dq_k (Maciejewski et al. eqs 7-8).

    Args:
        J: m x n Jacobian (m <= n).
        dJ: (n, m, n) derivatives, dJ[k] = dJ/dq_k (from `Robot.jacobian_derivatives`,
            scaled like J).
        locked: joints already locked.

    Returns:
        (s, G): s (n,) as `post_failure_sigmas`; G (n, n) with G[i, k] = ds_i/dq_k =
        u_i^T (d iJ/dq_k) v_i, u_i and v_i the singular vectors of s_i. Rows of
        locked joints are nan. Where s_i is 0 the value is a subgradient.
    """
    J = as_matrix(J)
    m, n = J.shape
    dJ = np.asarray(dJ, dtype=float)
    if dJ.shape != (n, m, n):
        raise ValueError(f"dJ must have shape ({n}, {m}, {n}), got {dJ.shape}")
    if m > n:
        raise ValueError(f"gradients need m <= n, got a {m} x {n} Jacobian")
    mask = locked_mask(n, locked)
    U, S, Vt = post_failure_svd(J, np.flatnonzero(mask))
    grads = sigma_gradients(U, Vt, dJ, mask)
    sigmas = S[:, m - 1].copy()
    sigmas[mask] = np.nan
    grads[mask] = np.nan
    return sigmas, grads


def soft_kfm(J: np.ndarray, locked: Iterable[int] = (), temperature: float = 0.01) -> float:
    """Smooth lower bound of K: -tau log sum_i exp(-s_i / tau) over healthy joints.

    Equals K when temperature is 0; K - tau log(n) <= soft_kfm <= K otherwise.
    """
    sigmas = post_failure_sigmas(J, locked)
    healthy = sigmas[~np.isnan(sigmas)]
    if not healthy.size:
        return 0.0
    low = healthy.min()
    if temperature <= 0:
        return float(low)
    return float(low - temperature * np.log(np.sum(np.exp(-(healthy - low) / temperature))))


@njit(cache=True, error_model="numpy")
def kfm_weights(sigmas: np.ndarray, temperature: float = 0.0) -> np.ndarray:
    """Weights (n,) such that grad K = weights @ G; 0 for nan (locked) entries.

    K = min_i s_i is not differentiable where two joints tie for the minimum
    (Maciejewski et al. footnote 2). Remedy taken here: with `temperature` tau > 0 the
    weights are softmax(-s_i / tau), the exact gradient of `soft_kfm`, which blends
    the joints within a few tau of the minimum so the ascent direction changes
    continuously when the minimising joint changes. With tau = 0 all weight goes to
    the (first) minimising joint: Maciejewski et al. eq 8. Compiled (numba): the engine's
    cycle calls it.
    """
    weights = np.zeros(sigmas.size)
    first, smallest = -1, np.inf
    for i in range(sigmas.size):
        if sigmas[i] < smallest or (first < 0 and not np.isnan(sigmas[i])):
            first, smallest = i, sigmas[i]
    if first < 0:
        return weights
    if temperature <= 0:
        weights[first] = 1.0
        return weights
    for i in range(sigmas.size):
        if not np.isnan(sigmas[i]):
            weights[i] = np.exp(-(sigmas[i] - smallest) / temperature)
    return weights / weights.sum()


def kfm_gradient(J: np.ndarray, dJ: np.ndarray, locked: Iterable[int] = (),
                 temperature: float = 0.0) -> np.ndarray:
    """Gradient of K over q (n,), 0 for locked joints (Maciejewski et al. eq 8; `kfm_weights`)."""
    sigmas, grads = post_failure_sigma_gradients(J, dJ, locked)
    return (kfm_weights(sigmas, temperature) @ np.nan_to_num(grads)) * ~np.isnan(sigmas)


def weighted_fault_tolerance_gradient(J: np.ndarray, dJ: np.ndarray,
                                      probabilities: Iterable[float] | None,
                                      locked: Iterable[int] = ()) -> np.ndarray:
    """Gradient of F_w = sum_i w_i s_i over q (n,), 0 for locked joints.

    Xie 2019 eq 3.3, Maciejewski et al. eq 8.
    """
    sigmas, grads = post_failure_sigma_gradients(J, dJ, locked)
    weights = failure_weights(probabilities, sigmas.size, locked)
    return (weights @ np.nan_to_num(grads)) * ~np.isnan(sigmas)
