"""ft_core.offline.dh: DH parameters from a Jacobian, the 7! designs of eq 2.7 (Xie 2019 sec. 2.3).

Tolerances against the chapter: its numbers are computed from the unrounded J*, the
code gets the rounded eq 2.7 (entries +-0.005), so printed alphas and a's are met
to 0.015 rad / 0.01 and the d range (5.35) to 0.03. Reading of J's columns: unit
axis z = w / |w|, v as printed (see `dh.joint_axes`).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from ft_core.offline import design, dh
from hypothesis import given
from hypothesis import strategies as st


@pytest.fixture(scope="module")
def family() -> dh.PermutationFamily:
    return dh.organise_permutations(dh.J_STAR)


def test_counts_of_sec_2_3(family: dh.PermutationFamily) -> None:
    assert len(family.permutations) == math.factorial(7)
    assert len(family.pairs) == 21 and len(set(np.round(family.pair_alpha, 9))) == 21
    assert len(family.triples) == 210
    assert len(set(zip(np.round(family.triple_d, 9), np.round(family.triple_theta, 9),
                       strict=True))) == 210
    assert family.tree_choices() == [21, 10, 4, 3, 2, 1]  # Figure 2.3
    # Every design has a reverse version, distinct from it: 7!/2 pairs (Figure 2.9).
    assert np.all(family.reverse[family.reverse] == np.arange(5040))
    assert np.all(family.reverse != np.arange(5040))
    # Each design is exactly one path of the tree: its 6 pairs determine it.
    assert len({tuple(row) for row in family.pair_index.tolist()}) == 5040


def test_values_printed_in_sec_2_3(family: dh.PermutationFamily) -> None:
    alpha, a = family.pair_alpha, family.pair_a
    assert a.min() == pytest.approx(0.00, abs=0.01)  # "a vary from 0.00 to 1.57"
    assert a.max() == pytest.approx(1.57, abs=0.01)
    assert alpha[alpha < 0].max() == pytest.approx(-0.50, abs=0.015)  # gap -0.50 .. 0.86
    assert alpha[alpha > 0].min() == pytest.approx(0.86, abs=0.015)
    assert np.sum(np.abs(np.abs(alpha) - np.pi / 2) < 0.2) >= 5  # "many near +-pi/2"
    assert family.triple_d.max() == pytest.approx(5.35, abs=0.03)  # "d from -5.35 to 5.35"
    assert family.triple_d.min() == pytest.approx(-5.35, abs=0.03)
    # {d, theta} symmetric about the origin: the reversed triple negates both.
    lookup = {t: i for i, t in enumerate(family.triples)}
    for index, (i, j, k) in enumerate(family.triples):
        mirror = lookup[(k, j, i)]
        assert family.triple_d[mirror] == pytest.approx(-family.triple_d[index], abs=1e-12)
        assert family.triple_theta[mirror] == pytest.approx(-family.triple_theta[index],
                                                            abs=1e-12)
    # The three good {alpha, a} pairs of sec. 2.4.4 and the joints that give them.
    good = family.match_pairs(dh.GOOD_PAIRS, tolerance=0.015)
    assert [family.pairs[g] for g in good] == [(2, 5), (0, 1), (4, 6)]
    with pytest.raises(ValueError, match="no"):
        family.match_pairs([(0.0, 0.5)], tolerance=0.015)


def test_good_pair_groups_match_inclusion_exclusion(family: dh.PermutationFamily) -> None:
    # The good pairs use six distinct joints, so a design contains s given ones
    # adjacent in 2^s (7-s)! ways; inclusion-exclusion gives the group sizes of Fig. 2.8.
    with_s = [math.comb(3, s) * 2**s * math.factorial(7 - s) for s in range(4)]
    exactly = [sum((-1) ** (s - k) * math.comb(s, k) * with_s[s] for s in range(k, 4))
               for k in range(4)]
    assert exactly == [1968, 2016, 864, 192]
    assert family.group_sizes(family.match_pairs(dh.GOOD_PAIRS)) == exactly


def test_tables_agree_with_direct_computation_of_designs(family: dh.PermutationFamily) -> None:
    # Every 9th design (560 of 5040) recomputed from its own axes, with its reverse;
    # `ft-design dh --verify` checks all 5040.
    assert dh.verify_family(dh.J_STAR, family, range(0, 5040, 9)) == 560
    broken = dh.PermutationFamily(**{**family.__dict__, "pair_a": family.pair_a + 1e-6})
    with pytest.raises(AssertionError, match="a"):
        dh.verify_family(dh.J_STAR, broken, [0])


def test_dh_chain_reproduces_the_jacobian() -> None:
    table = dh.dh_from_jacobian(dh.J_STAR)
    assert table.d[0] == table.theta[0] == 0.0 and table.alpha[-1] == 0.0
    assert table.a[-1] == pytest.approx(1.0, abs=0.01)  # a_7 = 1 of [35]
    J = dh.dh_jacobian(table)
    # Same joint axes up to a rigid motion: equal Gram matrices (rounding of eq 2.7).
    np.testing.assert_allclose(J.T @ J, dh.J_STAR.T @ dh.J_STAR, atol=0.012)
    # The tool point is a_7 from the last axis: |v_7| = a_7, and d_7 along that axis.
    assert np.linalg.norm(J[:3, -1]) == pytest.approx(table.a[-1], abs=1e-12)
    points = dh.forward_points(table)
    assert np.linalg.norm(points[-1] - points[-2]) == pytest.approx(
        math.hypot(table.a[-1], table.d[-1]), abs=1e-12)


def _revolute_jacobian(directions: np.ndarray, points: np.ndarray) -> np.ndarray:
    z = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    return np.vstack([np.cross(z, -points).T, z.T])  # v = z x p, p from axis to the tool


@given(st.integers(0, 2**32 - 1))
def test_exact_revolute_jacobians_round_trip(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 8))
    J = _revolute_jacobian(rng.normal(size=(n, 3)), rng.normal(size=(n, 3)))
    table = dh.dh_from_jacobian(J)
    rebuilt = dh.dh_jacobian(table)
    np.testing.assert_allclose(rebuilt.T @ rebuilt, J.T @ J, atol=1e-9)
    assert np.all(table.a >= 0)
    assert np.all(np.abs(table.alpha) <= np.pi) and np.all(np.abs(table.theta) <= np.pi)


def test_parallel_and_intersecting_axes() -> None:
    z = np.array([0.0, 0.0, 1.0])
    parallel = dh.common_normal(dh.Axis(np.zeros(3), z), dh.Axis(np.array([2.0, 0, 0]), z))
    assert parallel.alpha == 0.0 and parallel.a == pytest.approx(2.0)
    crossing = dh.common_normal(dh.Axis(np.zeros(3), z),
                                dh.Axis(np.zeros(3), np.array([0.0, 1.0, 0.0])))
    assert crossing.a == 0.0 and crossing.alpha == pytest.approx(np.pi / 2)  # x = z1 x z2
    swapped = dh.common_normal(dh.Axis(np.zeros(3), np.array([0.0, 1.0, 0.0])),
                               dh.Axis(np.zeros(3), z))
    assert swapped.alpha == pytest.approx(np.pi / 2)  # symmetric in the pair


def test_non_revolute_columns_are_rejected() -> None:
    with pytest.raises(ValueError, match="6 rows"):
        dh.joint_axes(np.ones((3, 4)))
    with pytest.raises(ValueError, match="revolute"):
        dh.joint_axes(design.optimal_jacobian([1] * 7, 6))  # eq 3.18 is not realisable


def test_planar_link_lengths_of_sec_3_3_4() -> None:
    # Equal probabilities: l = [sqrt 2, sqrt 2, sqrt(2/3)]; joint f failing: 1l = [1, sqrt 2,
    # 1], 2l = [1, 1, 1], 3l = [sqrt 2, 1, 0] (sigma = 1).
    r2 = math.sqrt(2)
    cases = {(1, 1, 1): [r2, r2, math.sqrt(2 / 3)], (1, 0, 0): [1, r2, 1],
             (0, 1, 0): [1, 1, 1], (0, 0, 1): [r2, 1, 0]}
    for p, lengths in cases.items():
        np.testing.assert_allclose(dh.planar_links_from_jacobian(design.optimal_jacobian(p, 2)),
                                   lengths, atol=1e-12)
