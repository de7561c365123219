"""ft_core.plant: latency, response time, acceleration limits, watchdog or held command."""

from __future__ import annotations

import math

import numpy as np
import pytest
from ft_core.plant import Plant, PlantConfig

DT = 0.001


def plant(**options) -> Plant:
    return Plant(np.full(2, -3.0), np.full(2, 3.0), np.full(2, 2.0), np.zeros(2),
                 PlantConfig(**options))


def run(arm: Plant, seconds: float, command_until: float = math.inf) -> list[np.ndarray]:
    """Command [1, -0.5] rad/s every ms for `command_until` s; the velocities per step."""
    velocities, start = [], arm.t
    for k in range(round(seconds / DT)):
        if k * DT < command_until:
            arm.command(start + k * DT, np.array([1.0, -0.5]))
        arm.step(start + (k + 1) * DT)
        velocities.append(arm.qd.copy())
    return velocities


def test_latency_delays_the_motion() -> None:
    arm = plant(latency=0.03)
    v = run(arm, 0.1)
    assert np.all(v[28] == 0.0) and np.allclose(v[31], [1.0, -0.5])
    assert arm.q == pytest.approx([0.07, -0.035], abs=2e-3)


def test_response_time_is_a_first_order_lag() -> None:
    arm = plant(response_time=0.05)
    v = run(arm, 0.05)
    assert v[-1][0] == pytest.approx(1 - math.exp(-1), rel=1e-6)  # 63 % after one T
    # Exact displacement of a lag: u t - u T (1 - exp(-t/T)).
    assert arm.q[0] == pytest.approx(0.05 - 0.05 * (1 - math.exp(-1)), rel=1e-6)


def test_acceleration_limit_ramps_the_velocity() -> None:
    arm = plant(acceleration_limit=(10.0, 5.0))
    v = run(arm, 0.05)
    assert v[9] == pytest.approx([0.01 * 10, -0.01 * 5])
    assert v[-1] == pytest.approx([0.5, -0.25])


@pytest.mark.parametrize("hold", [False, True])
def test_a_watchdog_stops_the_arm_unless_it_holds_the_last_command(hold: bool) -> None:
    arm = plant(timeout=0.1, hold_last_command=hold)
    v = run(arm, 0.5, command_until=0.2)
    if hold:
        assert np.allclose(v[-1], [1.0, -0.5])
    else:
        assert np.all(v[310] == 0.0) and np.allclose(v[290], [1.0, -0.5])


def test_locks_limits_and_release() -> None:
    arm = plant()
    arm.lock(1)
    run(arm, 0.1)
    assert arm.q[1] == 0.0 and arm.q[0] == pytest.approx(0.1)
    assert arm.release() == [1]
    arm.q = np.array([2.999, 0.0])
    run(arm, 0.1)
    assert arm.q[0] == 3.0 and arm.qd[0] == 0.0  # stopped at the position limit


@pytest.mark.parametrize("options", [{"latency": -0.1}, {"response_time": math.nan},
                                     {"acceleration_limit": ()},
                                     {"acceleration_limit": (1.0, -2.0)}])
def test_invalid_plant_options_are_rejected(options: dict) -> None:
    with pytest.raises(ValueError):
        PlantConfig(**options)
    with pytest.raises(ValueError, match="3 values for 2 joints"):
        plant(acceleration_limit=(1.0, 1.0, 1.0))
