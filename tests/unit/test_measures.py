"""ft_core.measures against the papers' numbers and against direct (loop) computations."""

from __future__ import annotations

import math

import numpy as np
import pytest
from ft_core import measures, robots
from hypothesis import given, settings
from hypothesis import strategies as st

# Maciejewski et al. eq 10: an optimally failure tolerant 3x4 Jacobian.
EQ10 = np.array([
    [-math.sqrt(3 / 4), math.sqrt(1 / 12), math.sqrt(1 / 12), math.sqrt(1 / 12)],
    [0.0, -math.sqrt(2 / 3), math.sqrt(1 / 6), math.sqrt(1 / 6)],
    [0.0, 0.0, -math.sqrt(1 / 2), math.sqrt(1 / 2)],
])


def sigma_min_removed(J: np.ndarray, removed: set[int]) -> float:
    """The m-th singular value of J with the `removed` columns deleted (0 if too few remain)."""
    keep = [j for j in range(J.shape[1]) if j not in removed]
    if len(keep) < J.shape[0]:
        return 0.0
    return np.linalg.svd(J[:, keep], compute_uv=False)[J.shape[0] - 1]


def w(A: np.ndarray) -> float:
    return math.sqrt(max(np.linalg.det(A @ A.T), 0.0))


def test_maciejewski_eq_10_attains_the_bound_of_eq_9() -> None:
    sigmas = measures.post_failure_sigmas(EQ10)
    np.testing.assert_allclose(sigmas, 0.5, atol=1e-12)
    assert measures.kfm(EQ10) == pytest.approx(math.sqrt((4 - 3) / 4), abs=1e-12)
    # The null vector is proportional to [1, 1, 1, 1]: every |n_i| = 1/2.
    np.testing.assert_allclose(measures.relative_manipulability(EQ10), 0.5, atol=1e-12)
    null = measures.null_space_basis(EQ10)[:, 0]
    np.testing.assert_allclose(np.abs(null), 0.5, atol=1e-12)


def test_k_is_zero_when_a_null_vector_entry_is_zero() -> None:
    J = np.array([[1.0, 0, 0, 0], [0, 1, 0, 1], [0, 0, 1, 1]])  # null vector [0, -1, -1, 1]
    assert measures.relative_manipulability(J)[0] == pytest.approx(0.0, abs=1e-12)
    assert measures.kfm(J) == pytest.approx(0.0, abs=1e-12)
    assert measures.post_failure_sigmas(J)[1:].min() > 0.1


@pytest.mark.parametrize("locked", [(), (2,), (0, 5)])
def test_post_failure_sigmas_equal_svds_of_the_reduced_jacobians(locked: tuple) -> None:
    J = np.random.default_rng(1).normal(size=(3, 7))
    sigmas = measures.post_failure_sigmas(J, locked)
    for i in range(7):
        if i in locked:
            assert math.isnan(sigmas[i])
        else:
            assert sigmas[i] == pytest.approx(sigma_min_removed(J, set(locked) | {i}), abs=1e-12)
    healthy = [s for s in sigmas if not math.isnan(s)]
    assert measures.kfm(J, locked) == pytest.approx(min(healthy))


def test_measures_are_zero_once_locks_leave_too_few_joints() -> None:
    J = np.random.default_rng(2).normal(size=(3, 5))
    # n - |F| - 1 = 5 - 2 - 1 = 2 < m = 3: the next failure leaves the task unreachable.
    np.testing.assert_allclose(measures.post_failure_sigmas(J, [0, 1])[2:], 0.0, atol=1e-12)
    assert measures.kfm(J, [0, 1]) == pytest.approx(0.0, abs=1e-12)
    assert measures.kfm(J, range(5)) == 0.0


def test_relative_manipulability_is_the_ratio_of_manipulabilities() -> None:
    J = np.random.default_rng(3).normal(size=(4, 7))
    rho = measures.relative_manipulability(J)
    direct = [w(np.delete(J, i, axis=1)) / w(J) for i in range(7)]
    np.testing.assert_allclose(rho, direct, rtol=1e-10)
    assert measures.manipulability(J) == pytest.approx(w(J))
    locked = measures.relative_manipulability(J, [3])
    reduced = np.delete(J, 3, axis=1)
    assert math.isnan(locked[3])
    np.testing.assert_allclose(np.delete(locked, 3),
                               [w(np.delete(reduced, i, axis=1)) / w(reduced) for i in range(6)],
                               rtol=1e-10)


def test_reduced_condition_numbers_and_worst_case_measures() -> None:
    J = np.random.default_rng(4).normal(size=(3, 6))
    direct = []
    for i in range(6):
        s = np.linalg.svd(np.delete(J, i, axis=1), compute_uv=False)
        direct.append(s)
    direct = np.array(direct)
    np.testing.assert_allclose(measures.reduced_condition_numbers(J), direct[:, 0] / direct[:, -1])
    assert measures.worst_case_inverse_condition(J) == pytest.approx(
        min(direct[:, -1] / direct[:, 0]))
    assert measures.worst_case_manipulability(J) == pytest.approx(min(np.prod(direct, axis=1)))
    singular = np.array([[1.0, 0, 0], [0, 1, 0]])  # locking joint 0 or 1 loses a direction
    assert np.isinf(measures.reduced_condition_numbers(singular)[:2]).all()


def test_weighted_fault_tolerance_follows_eqs_3_3_and_3_4() -> None:
    J = np.random.default_rng(5).normal(size=(3, 6))
    sigmas = measures.post_failure_sigmas(J)
    assert measures.weighted_fault_tolerance(J, None) == pytest.approx(sigmas.mean())
    assert measures.weighted_fault_tolerance(J, [0, 0, 4, 0, 0, 0]) == pytest.approx(sigmas[2])
    p = np.array([1.0, 2, 3, 4, 5, 6])
    assert measures.weighted_fault_tolerance(J, p) == pytest.approx(p @ sigmas / p.sum())
    with_lock = measures.weighted_fault_tolerance(J, p, locked=[5])
    reduced = measures.post_failure_sigmas(J, [5])[:5]
    assert with_lock == pytest.approx(p[:5] @ reduced / p[:5].sum())


@pytest.mark.parametrize("p", [[1, 1], [1, -1, 1, 1, 1, 1], [0] * 6, [np.nan] + [1] * 5])
def test_bad_failure_probabilities_are_rejected(p: list) -> None:
    with pytest.raises(ValueError, match="probabilit"):
        measures.weighted_fault_tolerance(np.ones((3, 6)), p)


def test_bad_matrices_and_indices_are_rejected() -> None:
    with pytest.raises(ValueError, match="non-finite"):
        measures.kfm(np.array([[1.0, np.inf, 0.0]]))
    with pytest.raises(ValueError, match="2-D"):
        measures.kfm(np.ones(3))
    with pytest.raises(ValueError, match="locked joint index"):
        measures.kfm(np.ones((2, 3)), [3])


def test_panda_k_is_zero_in_a_post_failure_singular_pose_and_positive_generically() -> None:
    panda = robots.load("panda")
    ready = np.array([0, -math.pi / 4, 0, -3 * math.pi / 4, 0, math.pi / 2, math.pi / 4])
    J = panda.scale_task(panda.jacobian(ready))
    sigmas = measures.post_failure_sigmas(J)
    # Joints 1, 3, 5 and 7 in one plane: locking joint 2 (or 4, 6) leaves a singular arm.
    assert sigmas[1] == pytest.approx(0.0, abs=1e-9)
    assert measures.kfm(J) == pytest.approx(0.0, abs=1e-9)
    generic = np.array([0.4, 0.3, -0.5, -1.9, 0.6, 1.4, -0.2])
    assert measures.kfm(panda.scale_task(panda.jacobian(generic))) > 1e-3


@settings(max_examples=60, deadline=None)
@given(n=st.integers(3, 8), data=st.data())
def test_k_never_exceeds_the_isotropic_bound_of_eq_9(n: int, data: st.DataObject) -> None:
    m = data.draw(st.integers(1, n - 1))
    seed = data.draw(st.integers(0, 2**31))
    sigma = data.draw(st.floats(0.1, 10.0))
    # A random isotropic Jacobian: sigma times m orthonormal rows.
    Q = np.linalg.qr(np.random.default_rng(seed).normal(size=(n, n)))[0]
    J = sigma * Q[:m]
    assert measures.kfm(J) <= sigma * math.sqrt((n - m) / n) + 1e-9
    # s_i = sigma |n_i| for isotropic J (Xie 2019 eq 3.27).
    np.testing.assert_allclose(measures.post_failure_sigmas(J),
                               sigma * measures.relative_manipulability(J), atol=1e-9)


def numeric_gradient(f, q: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    return np.array([(f(q + eps * e) - f(q - eps * e)) / (2 * eps) for e in np.eye(q.size)])


GRADIENT_CASES = [("panda", [0.4, 0.3, -0.5, -1.9, 0.6, 1.4, -0.2], ()),
                  ("panda", [0.4, 0.3, -0.5, -1.9, 0.6, 1.4, -0.2], (6,)),
                  ("puma560", [0.2, -0.8, 1.6, 0.3, 0.6, 0.0], ()),
                  ("planar3r", [0.3, 1.2, 1.0], ())]


@pytest.mark.parametrize(("name", "q", "locked"), GRADIENT_CASES)
def test_kfm_gradient_matches_finite_differences(name: str, q: list, locked: tuple) -> None:
    robot = robots.load(name, task_space="position" if name == "panda" and locked else None)
    q = np.array(q)

    def scaled(q: np.ndarray) -> np.ndarray:
        return robot.scale_task(robot.jacobian(q))

    dJ = robot.scale_task(robot.jacobian_derivatives(q))
    sigmas = measures.post_failure_sigmas(scaled(q), locked)
    healthy = np.sort(sigmas[~np.isnan(sigmas)])
    assert healthy[1] - healthy[0] > 1e-3  # a unique minimiser: K is differentiable here
    exact = measures.kfm_gradient(scaled(q), dJ, locked)
    np.testing.assert_allclose(exact, numeric_gradient(
        lambda x: measures.kfm(scaled(x), locked), q), atol=1e-7)
    soft = measures.kfm_gradient(scaled(q), dJ, locked, temperature=0.02)
    np.testing.assert_allclose(soft, numeric_gradient(
        lambda x: measures.soft_kfm(scaled(x), locked, temperature=0.02), q), atol=1e-7)
    p = np.arange(1.0, robot.n + 1)
    weighted = measures.weighted_fault_tolerance_gradient(scaled(q), dJ, p, locked)
    np.testing.assert_allclose(weighted, numeric_gradient(
        lambda x: measures.weighted_fault_tolerance(scaled(x), p, locked), q), atol=1e-7)
    assert np.all(exact[list(locked)] == 0.0)


def test_soft_kfm_is_a_tight_lower_bound_of_k_at_a_tie() -> None:
    sigmas_tied = EQ10  # all four s_i equal: K is not differentiable
    k = measures.kfm(sigmas_tied)
    for tau in (0.001, 0.01, 0.1):
        soft = measures.soft_kfm(sigmas_tied, temperature=tau)
        assert k - tau * math.log(4) - 1e-12 <= soft <= k
    assert measures.soft_kfm(sigmas_tied, temperature=0.0) == k
