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


@settings(max_examples=60, deadline=None)
@given(name=st.sampled_from(["panda", "puma560", "planar3r", "iiwa14"]), seed=st.integers(0, 2**31))
def test_fast_path_equals_the_reference(name: str, seed: int) -> None:
    robot = robots.load(name)
    rng = np.random.default_rng(seed)
    q = robot.random_configuration(rng)
    J, dJ = robot.jacobian_and_derivatives(q)
    J, dJ = robot.scale_task(J), robot.scale_task(dJ)
    xd = rng.normal(size=robot.m)
    L, V, columns, sigmas, vectors = postfailure.analyse(J)
    # Squaring J costs precision near zero: about sqrt(eps) * sigma_max (module docstring).
    np.testing.assert_allclose(sigmas, measures.post_failure_sigmas(J), atol=1e-7)
    assert postfailure.smallest_singular_value(L) == pytest.approx(
        np.linalg.svd(J, compute_uv=False)[-1], abs=1e-7)
    np.testing.assert_allclose(postfailure.damped_inverse(columns, L, V, *DAMPING_ARGS),
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
    L, V, columns, sigmas, vectors = postfailure.analyse(J)
    assert sigmas[0] == pytest.approx(0.0, abs=1e-8)
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
        _, _, _, sigmas, vectors = postfailure.analyse(J)
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
        eigenvalues, _, columns, _, _ = postfailure.analyse(J)
        d = eigenvalues - eigenvalues[0]
        for column in columns:
            _, steps = postfailure.downdate_root(column, d)
            assert steps < postfailure.MAX_NEWTON_STEPS // 2
