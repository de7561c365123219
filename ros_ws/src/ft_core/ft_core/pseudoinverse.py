"""Damped pseudo-inverse with damping that acts only near singularities.

Damping rule (Maciejewski and Klein's numerical filtering, also Nakamura): with
sigma_min the smallest of the min(m, k) singular values of an m x k matrix,

    lambda^2 = lambda_max^2 (1 - (sigma_min / epsilon)^2)   if sigma_min < epsilon
    lambda^2 = 0                                           otherwise

and A# = V diag(sigma / (sigma^2 + lambda^2)) U^T. Far from singularities
(sigma_min >= epsilon) it is the exact Moore-Penrose inverse, so tracking is
exact; the damping grows smoothly (continuous in sigma_min) to lambda_max at a
singularity, where the result stays finite. Works on stacks of matrices.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy")
def squared_damping(sigma_min: float | np.ndarray, threshold: float,
                    max_damping: float) -> float | np.ndarray:
    """lambda^2 (m^2) for a smallest singular value, or elementwise for an array of them."""
    ratio = np.minimum(sigma_min / threshold, 1.0)
    return max_damping**2 * (1.0 - ratio**2)


@dataclass(frozen=True)
class Damping:
    """Parameters of the damping rule, in the units of the singular values (m after scaling).

    Attributes:
        threshold: epsilon, the smallest singular value below which damping starts (> 0).
        max_damping: lambda_max, the damping at a singularity (> 0).
    """

    threshold: float = 0.01
    max_damping: float = 0.05

    def __post_init__(self) -> None:
        if not (self.threshold > 0 and self.max_damping > 0
                and np.isfinite(self.threshold) and np.isfinite(self.max_damping)):
            raise ValueError(f"damping threshold and max_damping must be positive: {self}")

    def squared(self, sigma_min: np.ndarray) -> np.ndarray:
        """lambda^2 for each matrix of a stack, given its smallest singular value."""
        return np.asarray(squared_damping(sigma_min, self.threshold, self.max_damping))


def pseudo_inverse_from_svd(U: np.ndarray, S: np.ndarray, Vt: np.ndarray,
                            damping: Damping | None) -> np.ndarray:
    """Pseudo-inverse (..., k, m) from a thin SVD of (..., m, k) matrices.

    With `damping` the damped inverse: sigma_min is the last of the min(m, k)
    singular values, the m-th for a wide matrix (task directions), the k-th for a
    tall one (least squares). Without, the Moore-Penrose inverse (singular values
    below 1e-15 times the largest count as 0, as in numpy.linalg.pinv).
    """
    if damping is None:
        cutoff = 1e-15 * S[..., :1]
        factors = np.divide(1.0, S, out=np.zeros_like(S), where=S > cutoff)
    else:
        lam2 = damping.squared(S[..., -1])[..., None]
        factors = np.divide(S, S**2 + lam2, out=np.zeros_like(S), where=S > 0)
    return np.swapaxes(Vt, -1, -2) @ (factors[..., None] * np.swapaxes(U, -1, -2))


@njit(cache=True, error_model="numpy")
def damped_from_svd(U: np.ndarray, S: np.ndarray, Vt: np.ndarray, threshold: float,
                    max_damping: float) -> np.ndarray:
    """`pseudo_inverse_from_svd` with damping for one matrix (k, m), compiled."""
    lam2 = squared_damping(S[-1], threshold, max_damping)
    k, m = Vt.shape[1], U.shape[0]
    inverse = np.zeros((k, m))
    for r in range(S.size):
        if S[r] > 0:
            factor = S[r] / (S[r] * S[r] + lam2)
            for i in range(k):
                for a in range(m):
                    inverse[i, a] += Vt[r, i] * factor * U[a, r]
    return inverse


def damped_pinv(A: np.ndarray, damping: Damping) -> np.ndarray:
    """Damped pseudo-inverse of an m x k matrix or a stack of them."""
    U, S, Vt = np.linalg.svd(np.asarray(A, dtype=float), full_matrices=False)
    return pseudo_inverse_from_svd(U, S, Vt, damping)
