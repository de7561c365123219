"""Per-cycle post-failure analysis from A = J J^T and its rank-one downdates (compiled).

The control loop needs, for every joint i, the smallest singular value s_i of iJ
(J with column i removed), its gradient, and the velocity iqd' = (iJ)# xd the
robot would have if i locked. Removing column j_i is a rank-one downdate:
iJ iJ^T = A - j_i j_i^T. So instead of n SVDs of m x (n - 1) matrices, one
symmetric eigen-decomposition A = V diag(L) V^T (ascending L) and, per joint:

- s_i^2 = L_0 - tau_i (in exact arithmetic; see below for how s_i is computed),
  the smallest root of the secular equation of the downdate
  (Golub 1973; the same equation LAPACK's dlaed4 solves): with c = V^T j_i and
  d_k = L_k - L_0, tau_i > 0 is the root of the concave function
      G(tau) = c_0^2 + sum_{k>0} c_k^2 tau / (d_k + tau) - tau,
  found by Newton's method from tau = |c|^2 (Weyl's bound, where G <= 0), which
  converges monotonically from the right. Equal eigenvalues need no deflation
  (their terms are constant in tau). Its eigenvector is u_i = V y / |y| with
  y_k = c_k / (d_k + tau_i);
- the damped inverse of iJ is iJ^T (iJ iJ^T + lambda_i^2 I)^-1 (the same matrix as
  `pseudoinverse.pseudo_inverse_from_svd`); (A + lambda_i^2 I - j_i j_i^T)^-1
  follows from Sherman-Morrison in the eigenbasis of A. Its denominator is
  positive because the downdated matrix is positive definite (lambda_i > 0) or
  iJ has full row rank (lambda_i = 0 only when s_i >= epsilon).

Values are not taken as square roots of eigenvalues: squaring J costs about
sqrt(machine epsilon) * sigma_max(J) of absolute precision near zero (an
eigenvalue of 1e-17 m^2 becomes 3e-9 m), and which rounding a machine's BLAS
kernel makes would then decide whether a singular arm reports 0 or 3e-9. So:

- s_i is exactly 0 where the structure says so: iJ has n - 1 < m columns and
  cannot span the task (Lewis & Maciejewski 1997, eq 5, read for that case as
  "no tolerance left");
- elsewhere s_i = |iJ^T u_i|, the norm of iJ^T applied to the vector from the
  downdate, which is the Rayleigh-quotient refinement of the value (its error is
  second order in that of u_i);
- where that norm is below `SVD_BELOW` * sigma_max(J) (a nearly singular reduced
  arm, where a vector from J J^T may be poor), s_i and u_i come from an SVD of iJ.

The same holds for sigma_m(J) itself (`analyse`'s sigma_min). Measured against a
batched LAPACK SVD of the same matrices over every locked set of the Panda and the
iiwa (position and pose tasks, seeded configurations, OpenBLAS kernels default,
Prescott and Haswell) and 20 000 random and rank-deficient matrices: absolute error
at most 6e-16 * sigma_max(J), where the square root of the downdated eigenvalue was
off by up to 4e-8 * sigma_max(J).

The functions are compiled with numba (nopython, cached on disk) and take plain
arrays, so the engine's compiled cycle calls them without Python in between;
from Python they are called like any function. `measures` and `velocity_jump` (SVD
based) are the reference; the tests check this module against them. All inputs are
for the robot as it is (healthy columns only), float64, with m <= n.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ft_core.pseudoinverse import squared_damping

#: Below this post-failure singular value (m) its gradient is taken as 0.
GRADIENT_FLOOR = 1e-12

#: Below this fraction of sigma_max(J), a singular value is taken from an SVD (module docstring).
SVD_BELOW = 1e-3

_EPS = float(np.finfo(np.float64).eps)

#: Newton iterations of the secular equation never exceed this (5-10 are typical).
MAX_NEWTON_STEPS = 60


@njit(cache=True, error_model="numpy")
def downdate_root(c: np.ndarray, d: np.ndarray) -> tuple[float, int]:
    """(tau, Newton steps taken): tau >= 0 with G(tau) = 0 (module docstring).

    tau = 0 when c_0 = 0 and no root is positive (the smallest eigenvalue stays, and
    so does its eigenvector).
    """
    tau = 0.0
    for k in range(c.size):
        tau += c[k] * c[k]
    steps = 0
    for steps in range(MAX_NEWTON_STEPS):  # noqa: B007 (the count is returned)
        g, slope = c[0] * c[0] - tau, -1.0
        for k in range(1, c.size):
            denominator = d[k] + tau
            if denominator > 0.0:
                # Ratios first: denominator^2 underflows to 0 at exact singularities.
                g += c[k] * c[k] * (tau / denominator)
                if d[k] > 0.0:
                    slope += c[k] * c[k] / denominator * (d[k] / denominator)
            else:
                g += c[k] * c[k]
        if g >= 0.0 or slope >= 0.0:
            break  # at the root, up to rounding
        step = g / slope
        if step <= 4e-16 * tau:
            break
        tau = max(tau - step, 0.0)
    return tau, steps


@njit(cache=True, error_model="numpy")
def analyse(J: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                    np.ndarray, float]:
    """Decompose A = J J^T and every downdate A - j_i j_i^T of an m x n J (m <= n).

    Returns (L, V, columns, sigmas, vectors, sigma_min): eigenvalues (m,) ascending
    and eigenvectors (m, m) of A; J's columns in that eigenbasis, J^T V (n, m), which
    `damped_inverse` and `downdated_velocities` reuse; s_i = sigma_m(iJ) (n,); u_i, the
    left singular vector of s_i, as row i of vectors (n, m); sigma_m(J). Singular
    values carry the precision of an SVD (module docstring).
    """
    m, n = J.shape
    L, V = np.linalg.eigh(gram(J))
    d = L - L[0]
    columns = in_eigenbasis(J, V)
    small = SVD_BELOW * np.sqrt(max(L[m - 1], 0.0))
    sigmas, vectors = np.empty(n), np.zeros((n, m))
    y = np.empty(m)
    for i in range(n):
        c = columns[i]
        tau, _ = downdate_root(c, d)
        if tau <= _EPS * L[m - 1]:  # L_0 - tau = L_0 to working precision: A's smallest
            # eigenpair survives (c_0 = 0 with no root below L_0, or c_0 so small that
            # c_0 / tau would dominate y anyway)
            y[:] = 0.0
            y[0] = 1.0
        else:
            norm = 0.0
            for k in range(m):
                y[k] = c[k] / (d[k] + tau)
                norm += y[k] * y[k]
            y /= np.sqrt(norm)
        for a in range(m):
            for k in range(m):
                vectors[i, a] += V[a, k] * y[k]
        if n - 1 < m:
            sigmas[i] = 0.0  # iJ cannot span the task: 0 by structure
            continue
        sigmas[i] = _norm_without(columns, y, i)
        if sigmas[i] < small:
            U, values, _ = np.linalg.svd(_without(J, i))
            sigmas[i], vectors[i] = values[m - 1], U[:, m - 1]
    sigma_min = np.sqrt(np.sum(columns[:, 0] ** 2))  # |J^T v_0|, refined as above
    if sigma_min < small:
        sigma_min = np.linalg.svd(J)[1][m - 1]
    return L, V, columns, sigmas, vectors, sigma_min


@njit(cache=True, error_model="numpy")
def _norm_without(columns: np.ndarray, y: np.ndarray, skip: int) -> float:
    """|J^T V y| over the columns other than `skip`."""
    total = 0.0
    for b in range(columns.shape[0]):
        if b != skip:
            value = 0.0
            for k in range(y.size):
                value += columns[b, k] * y[k]
            total += value * value
    return np.sqrt(total)


@njit(cache=True, error_model="numpy")
def _without(J: np.ndarray, skip: int) -> np.ndarray:
    """J with column `skip` removed (m, n - 1)."""
    m, n = J.shape
    reduced = np.empty((m, n - 1))
    for b in range(n - 1):
        reduced[:, b] = J[:, b if b < skip else b + 1]
    return reduced


@njit(cache=True, error_model="numpy")
def gram(J: np.ndarray) -> np.ndarray:
    """A = J J^T (m, m), in loops: cheaper than a BLAS call at this size."""
    m, n = J.shape
    A = np.empty((m, m))
    for a in range(m):
        for b in range(a, m):
            total = 0.0
            for k in range(n):
                total += J[a, k] * J[b, k]
            A[a, b] = total
            A[b, a] = total
    return A


@njit(cache=True, error_model="numpy")
def in_eigenbasis(J: np.ndarray, V: np.ndarray) -> np.ndarray:
    """J^T V (n, m): row i is column j_i in the eigenbasis of A."""
    m, n = J.shape
    columns = np.zeros((n, m))
    for i in range(n):
        for k in range(m):
            for a in range(m):
                columns[i, k] += J[a, i] * V[a, k]
    return columns


@njit(cache=True, error_model="numpy")
def weighted_sigma_gradient(J: np.ndarray, dJ: np.ndarray, sigmas: np.ndarray,
                            vectors: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """g_k = sum_i w_i ds_i/dq_k, with ds_i/dq_k = u_i^T dJ[k] v_i (Maciejewski et al. eq 8).

    v_i = iJ^T u_i / s_i. dJ is (n, m, n), dJ[k] = dJ/dq_k. Only the weighted sum is
    needed (the kfm ascent), so it is formed as g_k = sum_ab dJ[k, a, b] M[a, b] with
    M = sum_i w_i u_i v_i^T: O(n^2 m) instead of the O(n^3 m) of every ds_i/dq_k.
    Joints with s_i below `GRADIENT_FLOOR` add nothing (a subgradient there).
    """
    m, n = J.shape
    M = np.zeros((m, n))
    for i in range(n):
        if weights[i] == 0.0 or sigmas[i] <= GRADIENT_FLOOR:
            continue
        u = vectors[i]
        scale = weights[i] / sigmas[i]
        for b in range(n):
            if b == i:
                continue
            vb = 0.0
            for a in range(m):
                vb += u[a] * J[a, b]
            vb *= scale  # w_i v_i[b]
            for a in range(m):
                M[a, b] += u[a] * vb
    g = np.zeros(n)
    for k in range(n):
        total = 0.0
        for a in range(m):
            for b in range(n):
                total += dJ[k, a, b] * M[a, b]
        g[k] = total
    return g


@njit(cache=True, error_model="numpy")
def damped_inverse(columns: np.ndarray, L: np.ndarray, V: np.ndarray, sigma_min: float,
                   threshold: float, max_damping: float) -> np.ndarray:
    """Damped pseudo-inverse of J itself (n, m): J^T (J J^T + lambda^2 I)^-1 (`analyse`'s parts)."""
    n, m = columns.shape
    lam2 = squared_damping(sigma_min, threshold, max_damping)
    inverse = np.zeros((n, m))
    for i in range(n):
        for k in range(m):
            factor = columns[i, k] / (L[k] + lam2)
            for a in range(m):
                inverse[i, a] += factor * V[a, k]
    return inverse


@njit(cache=True, error_model="numpy")
def downdated_velocities(columns: np.ndarray, xd: np.ndarray, L: np.ndarray, V: np.ndarray,
                       sigmas: np.ndarray, threshold: float, max_damping: float) -> np.ndarray:
    """Row i: iqd' = (iJ)# xd with the damped inverse of iJ, 0 at joint i (n, n).

    columns, L, V and sigmas are `analyse`'s.
    """
    n, m = columns.shape
    xv = np.zeros(m)
    for k in range(m):
        for a in range(m):
            xv[k] += xd[a] * V[a, k]
    reduced = np.zeros((n, n))
    w = np.empty(m)
    for i in range(n):
        lam2 = squared_damping(sigmas[i], threshold, max_damping)
        jy, jc = 0.0, 0.0  # j_i^T (A + lambda_i^2)^-1 xd and j_i^T (A + lambda_i^2)^-1 j_i
        for k in range(m):
            inverse = 1.0 / (L[k] + lam2)
            jy += columns[i, k] * inverse * xv[k]
            jc += columns[i, k] * inverse * columns[i, k]
        factor = jy / (1.0 - jc)
        for k in range(m):  # (iJ iJ^T + lambda_i^2)^-1 xd in the eigenbasis
            w[k] = (xv[k] + columns[i, k] * factor) / (L[k] + lam2)
        for b in range(n):  # J^T V w, 0 at joint i
            if b != i:
                for k in range(m):
                    reduced[i, b] += columns[b, k] * w[k]
    return reduced
