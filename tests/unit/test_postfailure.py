"""The eigen-decomposition fast path (ft_core.postfailure) against the SVD reference."""

from __future__ import annotations

import numpy as np
import pytest
from ft_core import measures, postfailure, robots
from ft_core.pseudoinverse import Damping, damped_pinv
from ft_core.velocity_jump import post_failure_velocities
from hypothesis import given, settings
from hypothesis import strategies as st

DAMPING = Damping()
DAMPING_ARGS = (DAMPING.threshold, DAMPING.max_damping)


def analysed_like_an_svd(J: np.ndarray, relative: float) -> tuple:
    """`postfailure.analyse(J)`, its s_i and sigma_min checked against SVDs.

    Within `relative` times J's largest singular value: the precision of an SVD, not of
    a square root of an eigenvalue (the module docstring).
    """
    analysed = postfailure.analyse(J)
    sigmas, sigma_min = analysed[3], analysed[5]
    values = np.linalg.svd(J, compute_uv=False)
    np.testing.assert_allclose(sigmas, measures.post_failure_sigmas(J), rtol=0,
                               atol=relative * values[0])
    assert sigma_min == pytest.approx(values[-1], abs=relative * values[0])
    return analysed


@settings(max_examples=60, deadline=None)
@given(name=st.sampled_from(["panda", "puma560", "planar3r", "iiwa14"]), seed=st.integers(0, 2**31))
def test_fast_path_equals_the_reference(name: str, seed: int) -> None:
    robot = robots.load(name)
    rng = np.random.default_rng(seed)
    q = robot.random_configuration(rng)
    J, dJ = robot.jacobian_and_derivatives(q)
    J, dJ = robot.scale_task(J), robot.scale_task(dJ)
    xd = rng.normal(size=robot.m)
    L, V, columns, sigmas, vectors, sigma_min = analysed_like_an_svd(J, 1e-12)
    np.testing.assert_allclose(postfailure.damped_inverse(columns, L, V, sigma_min,
                                                          *DAMPING_ARGS),
                               damped_pinv(J, DAMPING), atol=1e-8)
    scale = 1 + np.abs(post_failure_velocities(J, xd, DAMPING)).max()
    np.testing.assert_allclose(
        postfailure.downdated_velocities(columns, xd, L, V, sigmas, *DAMPING_ARGS),
        post_failure_velocities(J, xd, DAMPING), atol=1e-9 * scale)
    reference, grads = measures.post_failure_sigma_gradients(J, dJ)
    clear = reference > 1e-5  # gradients of singular values near 0 are ill-conditioned
    for i in np.flatnonzero(clear):  # one joint's weight at a time: row i of every ds_i/dq
        np.testing.assert_allclose(postfailure.weighted_sigma_gradient(
            J, dJ, sigmas, vectors, np.eye(J.shape[1])[i]), grads[i], atol=1e-6)
    weights = rng.uniform(size=J.shape[1]) * clear
    np.testing.assert_allclose(postfailure.weighted_sigma_gradient(J, dJ, sigmas, vectors,
                                                                   weights),
                               weights @ grads, atol=1e-6)


def test_exactly_singular_post_failure_jacobians_stay_finite() -> None:
    J = np.array([[1.0, 0, 0, 0], [0, 1, 0, 1], [0, 0, 1, 1]])  # joint 0 carries a task row
    L, V, columns, sigmas, vectors, _ = postfailure.analyse(J)
    assert sigmas[0] == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_allclose(sigmas[1:], measures.post_failure_sigmas(J)[1:], atol=1e-12)
    reduced = postfailure.downdated_velocities(columns, np.array([1.0, 0.5, 0.2]), L, V, sigmas,
                                             *DAMPING_ARGS)
    assert np.all(np.isfinite(reduced))
    gradient = postfailure.weighted_sigma_gradient(J, np.ones((4, 3, 4)), sigmas, vectors,
                                                   np.ones(4))
    assert np.all(np.isfinite(gradient))
    assert np.any(gradient != 0)  # the other joints' terms are there


def test_repeated_eigenvalues_and_zero_columns_need_no_special_case() -> None:
    """J J^T = I (every eigenvalue equal), with a joint that moves nothing, and a mix."""
    plain = np.hstack([np.eye(3), np.zeros((3, 1))])
    mixed = np.hstack([np.eye(3), np.array([[0.0], [0.6], [0.8]]), np.zeros((3, 1))])
    for J in (plain, mixed):
        _, _, _, sigmas, vectors, _ = postfailure.analyse(J)
        np.testing.assert_allclose(sigmas, measures.post_failure_sigmas(J), atol=1e-12)
        for i in range(J.shape[1]):  # u_i is a unit left singular vector of iJ for s_i
            u = vectors[i]
            assert np.linalg.norm(u) == pytest.approx(1.0)
            assert np.linalg.norm(np.delete(J, i, axis=1).T @ u) == pytest.approx(
                sigmas[i], abs=1e-12)


def test_the_secular_equation_converges_within_its_step_budget() -> None:
    """Newton from Weyl's bound: a handful of steps on random arms, never the cap."""
    rng = np.random.default_rng(3)
    for _ in range(200):
        J = rng.normal(size=(6, 7)) * rng.uniform(0.01, 1.0, size=(6, 1))
        eigenvalues, _, columns, _, _, _ = postfailure.analyse(J)
        d = eigenvalues - eigenvalues[0]
        for column in columns:
            _, steps = postfailure.downdate_root(column, d)
            assert steps < postfailure.MAX_NEWTON_STEPS // 2


RANK_CASES = {
    # Columns 0, 1, 2 span only a plane and column 3 is 0: every reduced matrix is
    # singular and J J^T has an exactly zero eigenvalue with c_0 = 0 for joint 1 (the
    # downdate's root at 0, where the vector must be A's own).
    "singular arm": np.array([[0.06, -0.26, 0.22, 0.0], [-0.01, -0.25, -0.19, 0.0],
                              [0.0, 0.0, 0.0, 0.0]]) + np.array([[0.0], [0.0], [1.0]]) @
    np.array([[0.0, 0.05, 0.03, 0.0]]),
    "zero column": np.array([[1.0, 0.0, 0.3, 0.0], [0.0, 1.0, 0.2, 0.0], [0.0, 0.0, 1.0, 0.0]]),
    "dependent column": np.array([[1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0],
                                  [0.0, 0.0, 1.0e-9, 0.0]]),
}


@pytest.mark.parametrize("case", sorted(RANK_CASES))
def test_small_values_keep_the_precision_of_an_svd(case: str) -> None:
    """Where a reduced arm is (nearly) singular the value is that of an SVD, not ~1e-8."""
    J = RANK_CASES[case]
    _, _, _, sigmas, vectors, _ = analysed_like_an_svd(J, 1e-14)
    largest = np.linalg.svd(J, compute_uv=False)[0]
    for i in range(J.shape[1]):  # u_i belongs to s_i
        assert np.linalg.norm(np.delete(J, i, axis=1).T @ vectors[i]) == pytest.approx(
            sigmas[i], abs=1e-14 * largest)


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**31), shape=st.sampled_from([(2, 3), (3, 4), (3, 7), (6, 7), (6, 8)]),
       rank_drop=st.integers(0, 2), zero_column=st.booleans())
def test_values_match_an_svd_on_rank_deficient_matrices(seed: int, shape: tuple[int, int],
                                                        rank_drop: int,
                                                        zero_column: bool) -> None:
    m, n = shape
    rng = np.random.default_rng(seed)
    rank = max(m - rank_drop, 1)
    J = rng.normal(size=(m, rank)) @ rng.normal(size=(rank, n))
    if zero_column:
        J[:, rng.integers(n)] = 0.0
    analysed_like_an_svd(J, 1e-12)


def test_square_jacobians_report_exact_zeros() -> None:
    """With m = n, removing any column leaves n - 1 < m: every s_i is 0.0 by structure."""
    J = np.random.default_rng(0).normal(size=(3, 3))
    assert postfailure.analyse(J)[3].tolist() == [0.0, 0.0, 0.0]
    assert measures.post_failure_sigmas(J).tolist() == [0.0, 0.0, 0.0]
