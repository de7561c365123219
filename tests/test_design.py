"""ft_core.design: optimal null vectors and isotropic Jacobians of seed 001 ch. 3."""

from __future__ import annotations

import math

import numpy as np
import pytest
from ft_core import design, measures

PROBABILITIES = [[1, 1, 1, 1], [1, 2, 3, 4], [0.05, 0.5, 0.2, 0.15, 0.1], [0, 1, 1],
                 [0.15, 0.11, 0.12, 0.19, 0.19, 0.12, 0.12], [3, 1, 1, 1, 1, 1, 1]]


@pytest.mark.parametrize("p", PROBABILITIES)
def test_optimal_jacobian_is_isotropic_with_the_optimal_null_vector(p: list) -> None:
    n = len(p)
    J = design.optimal_jacobian(p, n - 1)
    np.testing.assert_allclose(J @ J.T, np.eye(n - 1), atol=1e-12)  # isotropic, sigma = 1
    w = np.asarray(p, float) / np.sum(p)
    expected = w / np.linalg.norm(w)  # eq 3.15
    np.testing.assert_allclose(design.optimal_null_vector(p), expected, atol=1e-12)
    np.testing.assert_allclose(J @ expected, 0.0, atol=1e-12)
    # eq 3.12: post-failure singular values are sigma |n_i|.
    np.testing.assert_allclose(measures.post_failure_sigmas(J), expected, atol=1e-12)


@pytest.mark.parametrize("p", PROBABILITIES[1:4])
def test_optimal_jacobian_beats_random_isotropic_ones_on_the_weighted_measure(p: list) -> None:
    n = len(p)
    best = measures.weighted_fault_tolerance(design.optimal_jacobian(p, n - 1), p)
    rng = np.random.default_rng(0)
    for _ in range(200):
        J = np.linalg.qr(rng.normal(size=(n, n)))[0][: n - 1]
        assert measures.weighted_fault_tolerance(J, p) <= best + 1e-12


def test_equal_weights_give_the_canonical_optimal_jacobians() -> None:
    np.testing.assert_allclose(design.optimal_jacobian([1, 1, 1, 1], 3), [
        [-math.sqrt(3 / 4), math.sqrt(1 / 12), math.sqrt(1 / 12), math.sqrt(1 / 12)],
        [0, -math.sqrt(2 / 3), math.sqrt(1 / 6), math.sqrt(1 / 6)],
        [0, 0, -math.sqrt(1 / 2), math.sqrt(1 / 2)],
    ], atol=1e-12)  # seed 002 eq 10
    canonical = np.zeros((6, 7))  # seed 001 eq 2.6
    for i in range(1, 7):
        canonical[i - 1, i - 1] = -math.sqrt((7 - i) / (8 - i))
        canonical[i - 1, i:] = math.sqrt(1 / ((7 - i) * (8 - i)))
    np.testing.assert_allclose(design.optimal_jacobian([1] * 7, 6), canonical, atol=1e-12)
    assert measures.kfm(canonical) == pytest.approx(math.sqrt(1 / 7))  # eq 2.5


def test_null_space_norms_of_eq_3_29() -> None:
    equal = design.optimal_null_space_norms([1] * 7, 3)
    np.testing.assert_allclose(equal, math.sqrt(4 / 7))
    skewed = design.optimal_null_space_norms([10, 1, 1, 1, 1, 1, 1], 3)
    assert skewed[0] == 1.0  # capped
    np.testing.assert_allclose(skewed[1:], math.sqrt(3 / 6))
    for p in ([1, 2, 3, 4, 5], [5, 5, 1, 1, 1]):
        norms = design.optimal_null_space_norms(p, 2)
        assert np.sum(norms**2) == pytest.approx(3.0)  # eq 3.28
        assert norms.max() <= 1.0


def test_invalid_design_requests_are_rejected() -> None:
    with pytest.raises(ValueError, match="m = n - 1"):
        design.optimal_jacobian([1] * 7, 3)
    with pytest.raises(ValueError, match="1 <= m < n"):
        design.optimal_jacobian([1, 1, 1], 3)
    with pytest.raises(ValueError, match="probabilit"):
        design.optimal_jacobian([1, -1, 1], 2)
