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
