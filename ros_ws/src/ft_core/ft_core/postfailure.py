"""Per-cycle post-failure analysis from A = J J^T and its rank-one downdates.

The control loop needs, for every joint i, the smallest singular value s_i of iJ
(J with column i removed), its gradient, and the velocity iqd' = (iJ)# xd the
robot would have if i locked. Removing column j_i is a rank-one downdate:
iJ iJ^T = A - j_i j_i^T. So instead of n SVDs of m x (n - 1) matrices:

- s_i^2 is the smallest eigenvalue of A - j_i j_i^T (one batched `eigvalsh` of
  n symmetric m x m matrices), u_i its eigenvector;
- the damped inverse of iJ is iJ^T (iJ iJ^T + lambda_i^2 I)^-1 (the same matrix as
  `pseudoinverse.pseudo_inverse_from_svd`), and with A = V diag(L) V^T,
  (A + lambda_i^2 I - j_i j_i^T)^-1 follows from Sherman-Morrison in the
  eigenbasis of A, for every i at once. Its denominator is positive because the
  downdated matrix is positive definite (lambda_i > 0) or iJ has full row rank
  (lambda_i = 0 only when s_i >= epsilon).

`measures` (SVD based) is the reference; the tests check this module against it.
Squaring costs precision near zero: s_i carries an absolute error of about
sqrt(machine epsilon) * sigma_max(J), some 2e-8 m for a 7-DOF arm, where the SVD
gives 1e-16. Nothing in the control loop can tell the two apart (K, and the
damping of the inverses, change by far less than their own tolerances).
All inputs are for the robot as it is (healthy columns only) with m <= n.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ft_core.pseudoinverse import Damping

#: Below this post-failure singular value (m) its gradient is taken as 0.
GRADIENT_FLOOR = 1e-12


@dataclass(frozen=True)
class PostFailure:
    """Eigen-decompositions of J J^T and of its n downdates.

    Attributes:
        eigenvalues, eigenvectors: of A = J J^T (ascending; (m,), (m, m)).
        sigmas: s_i = sigma_m(iJ) (n,).
        vectors: u_i, the left singular vector of s_i (n, m); None unless requested.
    """

    eigenvalues: np.ndarray
    eigenvectors: np.ndarray
    sigmas: np.ndarray
    vectors: np.ndarray | None

    @property
    def sigma_min(self) -> float:
        """Smallest singular value of J itself."""
        return float(np.sqrt(max(self.eigenvalues[0], 0.0)))


def analyse(J: np.ndarray, with_vectors: bool = False) -> PostFailure:
    """Decompose J J^T and every J J^T - j_i j_i^T (m x n, m <= n)."""
    A = J @ J.T
    eigenvalues, eigenvectors = np.linalg.eigh(A)
    downdated = A[None] - J.T[:, :, None] * J.T[:, None, :]
    if with_vectors:
        mu, U = np.linalg.eigh(downdated)
        vectors = U[:, :, 0]
    else:
        mu, vectors = np.linalg.eigvalsh(downdated), None
    return PostFailure(eigenvalues, eigenvectors, np.sqrt(np.maximum(mu[:, 0], 0.0)), vectors)


def sigma_gradients(post: PostFailure, J: np.ndarray, dJ: np.ndarray) -> np.ndarray:
    """G[i, k] = ds_i/dq_k = u_i^T dJ[k] v_i with v_i = iJ^T u_i / s_i (seed 002 eq 8).

    Rows with s_i below `GRADIENT_FLOOR` are 0 (a subgradient there).
    """
    n = J.shape[1]
    u = post.vectors
    w = u @ J  # row i: J^T u_i
    w[np.arange(n), np.arange(n)] = 0.0  # iJ^T u_i
    live = post.sigmas > GRADIENT_FLOOR
    v = np.where(live[:, None], w / np.where(live, post.sigmas, 1.0)[:, None], 0.0)
    return np.einsum("ia,kab,ib->ik", u, dJ, v)


def damped_inverse(post: PostFailure, J: np.ndarray, damping: Damping) -> np.ndarray:
    """Damped pseudo-inverse of J itself (n, m): J^T (J J^T + lambda^2 I)^-1."""
    lam2 = damping.squared(post.sigma_min)
    V = post.eigenvectors
    return J.T @ (V / (post.eigenvalues + lam2)) @ V.T


def reduced_velocities(post: PostFailure, J: np.ndarray, xd: np.ndarray,
                       damping: Damping) -> np.ndarray:
    """Row i: iqd' = (iJ)# xd with the damped inverse of iJ, 0 at joint i (n, n)."""
    n = J.shape[1]
    V, L = post.eigenvectors, post.eigenvalues
    lam2 = damping.squared(post.sigmas)  # (n,)
    D = 1.0 / (L[None, :] + lam2[:, None])  # (n, m): (A + lambda_i^2)^-1 in the eigenbasis
    columns = J.T @ V  # (n, m): row i is j_i in the eigenbasis
    y = D * (xd @ V)  # row i: (A + lambda_i^2)^-1 xd
    c = D * columns  # row i: (A + lambda_i^2)^-1 j_i
    jy = np.einsum("ij,ij->i", columns, y)  # j_i^T (A + lambda_i^2)^-1 xd
    d = np.einsum("ij,ij->i", columns, c)  # j_i^T (A + lambda_i^2)^-1 j_i
    w = y + c * (jy / (1.0 - d))[:, None]  # (iJ iJ^T + lambda_i^2)^-1 xd, eigenbasis
    reduced = w @ columns.T  # row i: J^T w_i
    reduced[np.arange(n), np.arange(n)] = 0.0
    return reduced
