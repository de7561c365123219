"""Optimally fault tolerant Jacobians a 7R arm can realise (Xie 2019 sec. 3.3.5, eqs 3.20-3.24).

A revolute column is j_i = [v_i; w_i] with |w_i| = 1 and v_i perpendicular to w_i
(eq 3.20); eq 3.22 writes it with three angles (alpha_i, beta_i, gamma_i) and |v_i|.
The isotropic 6 x 7 Jacobian with the optimal null vector n_i = w_i / |w| (eq 3.15)
is the top of an orthogonal U whose columns are u_i = [sqrt(3/7) j_i; n_i] (eq 3.21),
so sigma = sqrt(7/3) and |v_i| = sqrt(4/3 - 7 n_i^2 / 3) (eq 3.23). The rows of U
must then be orthonormal: 28 equations in the 21 angles.

Counting (not in the chapter, but it explains its remark that the constraints cannot
be met for every set of probabilities): orthogonal U with a given last row form a
15-dimensional set, less 3 for the rotation of the whole arm, against 14 revolute
conditions (|w_i| = 1, v_i . w_i = 0): two too many. So the realisable weights form
a thin set, and `realisable_design` searches for weights near the requested ones,
as the chapter did with Levenberg-Marquardt to obtain eq 3.24.

Readings taken: the weights printed with eq 3.24 lost one entry in extraction; the
null vector of the printed Jacobian gives w = [0.15 0.11 0.11 0.12 0.19 0.19 0.12]
(sum 0.99, matching footnote 5, "do not add up to 1 due to rounding"), so the
missing entry is the third, 0.11. Rows of eq 3.24 are linear velocity first.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ft_core.measures import failure_weights, null_space_basis

N_JOINTS = 7
SIGMA = float(np.sqrt(7.0 / 3.0))  # singular value of the isotropic 6 x 7 Jacobian (eq 3.21)

# Xie 2019 eq 3.24 (rounded to 0.01 in the text) and its weights (footnote 5 reading).
J_324 = np.array([
    [-0.38, -1.02, 0.52, -0.39, -0.10, 0.48, 0.69],
    [0.04, -0.30, 0.39, 0.79, -0.70, 0.59, -0.79],
    [-0.91, -0.16, -0.84, 0.57, 0.52, 0.41, 0.01],
    [0.68, -0.28, -0.79, 0.44, -0.65, -0.03, 0.74],
    [-0.66, 0.51, 0.56, 0.66, -0.39, -0.55, 0.65],
    [-0.31, 0.81, -0.23, -0.61, -0.66, 0.83, 0.17],
])
W_324 = np.array([0.15, 0.11, 0.11, 0.12, 0.19, 0.19, 0.12])

_UPPER = np.triu_indices(N_JOINTS)
_MAX_NORM = float(np.sqrt(4.0 / 7.0))  # |n_i| above this makes |v_i|^2 < 0 (eq 3.23)


@dataclass(frozen=True)
class RealisableDesign:
    """Result of `realisable_design`.

    Attributes:
        jacobian: 6 x 7 Jacobian (linear rows first), tool point at the origin.
        weights: the failure weights it is optimal for (sum 1, eq 3.4).
        residual: max |U U^T - I| (0 for an exactly realisable optimum).
        angles: (3, 7) alpha, beta, gamma of eq 3.22 (rad).
        target: the requested weights.
    """

    jacobian: np.ndarray
    weights: np.ndarray
    residual: float
    angles: np.ndarray
    target: np.ndarray

    @property
    def realisable(self) -> bool:
        """True when the constraints hold to 1e-9."""
        return self.residual < 1e-9


def linear_speed_norms(null_vector: np.ndarray) -> np.ndarray:
    """|v_i| = sqrt(4/3 - 7 n_i^2 / 3) for a unit null vector n (eq 3.23)."""
    n = np.asarray(null_vector, dtype=float)
    return np.sqrt(np.maximum(4.0 / 3.0 - 7.0 * n**2 / 3.0, 0.0))


def columns_from_angles(angles: np.ndarray, null_vector: np.ndarray) -> np.ndarray:
    """6 x 7 revolute Jacobian of eq 3.22 from angles (3, 7) and the null vector (eq 3.23)."""
    alpha, beta, gamma = np.asarray(angles, dtype=float).reshape(3, -1)
    ca, sa, cb, sb, cg, sg = (np.cos(alpha), np.sin(alpha), np.cos(beta), np.sin(beta),
                              np.cos(gamma), np.sin(gamma))
    omega = np.array([ca * cb, sa * cb, sb])
    v = linear_speed_norms(null_vector) * np.array(
        [ca * sb * cg + sa * sg, sa * sb * cg - ca * sg, -cb * cg])
    return np.vstack([v, omega])


def angles_from_columns(J: np.ndarray) -> np.ndarray:
    """Angles (3, 7) of eq 3.22 that best describe the columns of a 6 x 7 Jacobian."""
    v, omega = J[:3], J[3:] / np.linalg.norm(J[3:], axis=0)
    alpha = np.arctan2(omega[1], omega[0])
    beta = np.arcsin(np.clip(omega[2], -1.0, 1.0))
    ca, sa, cb, sb = np.cos(alpha), np.sin(alpha), np.cos(beta), np.sin(beta)
    # v = |v| (cos gamma e1 - sin gamma e2) with e1, e2 the unit vectors of eq 3.22.
    e1 = np.array([ca * sb, sa * sb, -cb])
    e2 = np.array([-sa, ca, np.zeros_like(ca)])
    gamma = np.arctan2(-np.sum(v * e2, axis=0), np.sum(v * e1, axis=0))
    return np.vstack([alpha, beta, gamma])


def orthogonality_residuals(angles: np.ndarray, null_vector: np.ndarray) -> np.ndarray:
    """Upper triangle (28,) of U U^T - I, U = [sqrt(3/7) J; n^T] (eqs 3.16, 3.21)."""
    J = columns_from_angles(angles, null_vector)
    U = np.vstack([J / SIGMA, null_vector])
    return (U @ U.T - np.eye(N_JOINTS))[_UPPER]


def _unit(raw: np.ndarray) -> np.ndarray:
    return raw / np.linalg.norm(raw)


def _solve(x0: np.ndarray, target: np.ndarray, anchor: np.ndarray | None, penalty: float,
           max_nfev: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Two least-squares stages with the weights free.

    x = angles (21,) + raw null vector (7,), the latter kept within a factor 3 of
    the target's null vector so no weight vanishes. Stage 1 adds `penalty` times
    the distance to the anchor (the start Jacobian's entries if given, else the
    target null vector); stage 2 polishes on the 28 constraints alone, moving to
    the nearest exactly realisable point.
    """
    t = _unit(target)

    def residuals(x: np.ndarray) -> np.ndarray:
        n = _unit(x[21:])
        pull = (n - t) if anchor is None else (columns_from_angles(x[:21], n) - anchor).ravel()
        return np.concatenate([orthogonality_residuals(x[:21], n), penalty * pull])

    lower = np.concatenate([np.full(21, -np.inf), t / 3.0])
    upper = np.concatenate([np.full(21, np.inf), np.minimum(3.0 * t, 1.0)])
    x0 = np.clip(x0, lower + 1e-12, upper - 1e-12)
    fit = least_squares(residuals, x0, bounds=(lower, upper), method="trf", max_nfev=max_nfev)
    fit = least_squares(lambda x: residuals(x)[:28], fit.x, bounds=(lower, upper),
                        method="trf", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=max_nfev)
    n = _unit(fit.x[21:])
    residual = float(np.abs(orthogonality_residuals(fit.x[:21], n)).max())
    return fit.x[:21], n, residual


def _solve_fixed(x0: np.ndarray, n: np.ndarray, max_nfev: int) -> tuple[np.ndarray, float]:
    fit = least_squares(orthogonality_residuals, x0, args=(n,), method="lm", xtol=1e-15,
                        ftol=1e-15, gtol=1e-15, max_nfev=max_nfev)
    return fit.x, float(np.abs(fit.fun).max())


def realisable_design(probabilities: Iterable[float] | None = None, *, free_weights: bool = True,
                      start: np.ndarray | None = None, restarts: int = 8, seed: int = 0,
                      penalty: float = 1e-2, max_nfev: int = 3000) -> RealisableDesign:
    """An optimally fault tolerant Jacobian that a 7R arm realises (eqs 3.20-3.24).

    Args:
        probabilities: 7 failure probabilities (None: equal).
        free_weights: False solves the 28 equations of eq 3.21 with the weights
            fixed (usually impossible: see the module docstring); True lets the
            weights move and returns the realisable design whose null vector is
            nearest the requested one among the restarts (the chapter's approach).
        start: a 6 x 7 Jacobian to start from (e.g. `J_324`), used as the first
            start before the random ones; with free weights its first stage pulls
            towards this Jacobian's entries rather than the target weights, so a
            rounded published design is polished into the nearest realisable one.
        restarts: random starts (bounded; the best is kept).
        seed: random generator seed (deterministic result).
        penalty: weight of the pull (|n - n_target|, or |J - start| for the start)
            against the constraints in the first stage.
        max_nfev: evaluation budget of each least-squares run.

    Returns:
        The best RealisableDesign (smallest residual with fixed weights; with free
        weights, the nearest weights among designs with residual < 1e-9, else the
        smallest residual).

    Raises:
        ValueError: wrong number of probabilities, or a weight whose |n_i| exceeds
            sqrt(4/7) (eq 3.23 has no real |v_i|).
    """
    p = np.ones(N_JOINTS) if probabilities is None else np.asarray(list(probabilities), float)
    target = failure_weights(p, N_JOINTS)
    n_target = _unit(target)
    if np.any(n_target > _MAX_NORM):
        raise ValueError(f"|n_i| = {n_target.max():.3f} > sqrt(4/7): no revolute column has"
                         " that null-vector entry (eq 3.23)")
    if restarts < 0 or max_nfev < 1:
        raise ValueError("restarts must be >= 0 and max_nfev >= 1")
    rng = np.random.default_rng(seed)
    starts = [] if start is None else [angles_from_columns(np.asarray(start, float)).ravel()]
    starts += [rng.uniform(-np.pi, np.pi, 21) for _ in range(restarts)]
    if not starts:
        raise ValueError("need a start Jacobian or at least one restart")
    best: RealisableDesign | None = None
    for x0 in starts:
        if free_weights:
            anchored = start is not None and x0 is starts[0]
            raw0 = _null_vector(np.asarray(start, float)) if anchored else n_target
            anchor = np.asarray(start, float) if anchored else None
            angles, n, residual = _solve(np.concatenate([x0, raw0]), target, anchor, penalty,
                                         max_nfev)
        else:
            angles, residual = _solve_fixed(x0, n_target, max_nfev)
            n = n_target
        design = RealisableDesign(columns_from_angles(angles, n), n / n.sum(), residual,
                                  angles.reshape(3, N_JOINTS), target)
        if best is None or _better(design, best, free_weights):
            best = design
    assert best is not None
    return best


def _null_vector(J: np.ndarray) -> np.ndarray:
    """|n| of the unit null vector of a 6 x 7 J (`measures.null_space_basis`)."""
    return np.abs(null_space_basis(np.asarray(J, float))[:, -1])


def _better(new: RealisableDesign, old: RealisableDesign, free_weights: bool) -> bool:
    if not free_weights or not (new.realisable or old.realisable):
        return new.residual < old.residual
    if new.realisable != old.realisable:
        return new.realisable
    return bool(np.linalg.norm(_unit(new.weights) - _unit(new.target))
                < np.linalg.norm(_unit(old.weights) - _unit(old.target)))


def weights_of(J: np.ndarray) -> np.ndarray:
    """Failure weights for which J is optimal: |n| / sum |n| of its null vector (eq 3.15)."""
    n = _null_vector(J)
    return n / n.sum()
