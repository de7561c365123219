"""ft_core.offline.parallel_manipulators: the fast steering mirror of Yi et al. 2006, Table I."""

from __future__ import annotations

import numpy as np
import pytest
from ft_core import measures
from ft_core.offline import parallel_manipulators

# Four-strut FSM at its home configuration (Yi et al. 2006, Section IV).
T = np.array([[0.707, 0, 0.5], [0, 0.707, 0.5], [-0.707, 0, 0.5], [0, -0.707, 0.5]])
J = np.array([[1.0, 0, 0], [0, -1, 0], [0, 0, 0.5]])
J_m = J[:2]  # only the rotations about x and y are critical


@pytest.mark.parametrize("strut", range(4))
def test_four_strut_mirror_position_failure_is_0_5775(strut: int) -> None:
    measure = parallel_manipulators.position_failure_measure(T, J_m, [strut])
    assert measure == pytest.approx(0.5775, abs=5e-4)


def test_four_strut_mirror_torque_failure_is_0_5() -> None:
    assert parallel_manipulators.torque_failure_measure(T, [3]) == pytest.approx(0.5, abs=5e-4)


def test_identity_mapping_reduces_to_the_serial_relative_manipulability() -> None:
    Js = np.random.default_rng(0).normal(size=(3, 6))
    serial = measures.relative_manipulability(Js)
    np.testing.assert_allclose(
        [parallel_manipulators.position_failure_measure(np.eye(6), Js, [i]) for i in range(6)],
        serial)


def test_two_failures_need_two_redundant_directions() -> None:
    assert parallel_manipulators.position_failure_measure(T, J_m, [0, 1]) == 0.0
    with pytest.raises(ValueError, match="actuator indices"):
        parallel_manipulators.position_failure_measure(T, J_m, [4])


def test_a_hard_failure_equivalent_to_a_torque_failure_gives_the_same_measure() -> None:
    """Yi et al. 2006 sec. IV: at home, losing strut 4 of the mirror is its torque failure.

    The hinge's constraint is dependent there: J_hat = J T_r^-1, and eq 16 gives
    t_4 = w(T_r) = 0.5 (eq 14, Table I).
    """
    J_hat = J @ np.linalg.inv(T[:3])
    h = parallel_manipulators.hard_failure_measure(J, J_hat)
    assert h == pytest.approx(parallel_manipulators.torque_failure_measure(T, [3]), rel=1e-9)
    assert h == pytest.approx(0.5, abs=5e-4)


def test_the_hard_failure_measure_looks_at_the_nominal_task_directions_only() -> None:
    """A gained DOF outside span(J) does not count (the paper's remark after eq 16)."""
    rng = np.random.default_rng(3)
    nominal = rng.normal(size=(3, 2))
    outside = np.cross(nominal[:, 0], nominal[:, 1])
    relaxed = np.column_stack([nominal @ np.diag([1.5, 2.0]), 4.0 * outside])
    assert parallel_manipulators.hard_failure_measure(nominal, relaxed) == pytest.approx(
        1 / 3.0)
    assert parallel_manipulators.hard_failure_measure(
        nominal, np.column_stack([nominal, outside])) == pytest.approx(1.0)
    # Against an independent reading: w of the coordinates in an orthonormal basis Q of
    # span(J), Q^T J_hat (wide), whose singular values are those of P_J J_hat.
    mixed = rng.normal(size=(3, 3))
    Q = np.linalg.qr(nominal)[0]
    expected = measures.manipulability(nominal) / measures.manipulability(Q.T @ mixed)
    assert parallel_manipulators.hard_failure_measure(nominal, mixed) == pytest.approx(expected)
    with pytest.raises(ValueError, match="lost a nominal task direction"):
        parallel_manipulators.hard_failure_measure(nominal, outside[:, None])
