"""The eigen-decomposition fast path (ft_core.postfailure) against the SVD reference."""

from __future__ import annotations

import numpy as np
import pytest
from ft_core import measures, postfailure, robots
from ft_core.pseudoinverse import Damping, damped_pinv
from ft_core.resolution import reduced_velocities
from hypothesis import given, settings
from hypothesis import strategies as st

DAMPING = Damping()


@settings(max_examples=60, deadline=None)
@given(name=st.sampled_from(["panda", "puma560", "planar3r", "iiwa14"]), seed=st.integers(0, 2**31))
def test_fast_path_equals_the_reference(name: str, seed: int) -> None:
    robot = robots.load(name)
    rng = np.random.default_rng(seed)
    q = robot.random_configuration(rng)
    J, dJ = robot.jacobian_and_derivatives(q)
    J, dJ = robot.scale_task(J), robot.scale_task(dJ)
    xd = rng.normal(size=robot.m)
    post = postfailure.analyse(J, with_vectors=True)
    # Squaring J costs precision near zero: about sqrt(eps) * sigma_max (module docstring).
    np.testing.assert_allclose(post.sigmas, measures.post_failure_sigmas(J), atol=1e-7)
    assert post.sigma_min == pytest.approx(np.linalg.svd(J, compute_uv=False)[-1], abs=1e-7)
    np.testing.assert_allclose(postfailure.damped_inverse(post, J, DAMPING),
                               damped_pinv(J, DAMPING), atol=1e-8)
    scale = 1 + np.abs(reduced_velocities(J, xd, DAMPING)).max()
    np.testing.assert_allclose(postfailure.reduced_velocities(post, J, xd, DAMPING),
                               reduced_velocities(J, xd, DAMPING), atol=1e-9 * scale)
    sigmas, grads = measures.post_failure_sigma_gradients(J, dJ)
    clear = sigmas > 1e-5  # gradients of singular values near 0 are ill-conditioned
    np.testing.assert_allclose(postfailure.sigma_gradients(post, J, dJ)[clear], grads[clear],
                               atol=1e-6)


def test_exactly_singular_post_failure_jacobians_stay_finite() -> None:
    J = np.array([[1.0, 0, 0, 0], [0, 1, 0, 1], [0, 0, 1, 1]])  # joint 0 carries a task row
    post = postfailure.analyse(J, with_vectors=True)
    assert post.sigmas[0] == pytest.approx(0.0, abs=1e-8)
    reduced = postfailure.reduced_velocities(post, J, np.array([1.0, 0.5, 0.2]), DAMPING)
    assert np.all(np.isfinite(reduced))
    gradients = postfailure.sigma_gradients(post, J, np.zeros((4, 3, 4)))
    assert np.all(np.isfinite(gradients))
