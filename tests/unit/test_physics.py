"""ft_core.physics: the Panda's dynamics in MuJoCo under joint servos, brakes and lost torque."""

from __future__ import annotations

import numpy as np
import pytest
from ft_core import physics, robots, swing
from ft_core.physics import PhysicsPlant
from ft_core.plant import PlantConfig

ARM = robots.load("panda_inertial")
DT = 0.002  # the sim's default period (500 Hz)


def drive(plant: PhysicsPlant, command: np.ndarray, seconds: float) -> np.ndarray:
    """Command `command` (rad/s) every period for `seconds`; the velocities (steps, n)."""
    velocities = []
    for _ in range(round(seconds / DT)):
        plant.command(plant.t, command)
        plant.step(plant.t + DT)
        velocities.append(plant.qd)
    return np.array(velocities)


def unit(joint: int, value: float) -> np.ndarray:
    u = np.zeros(ARM.n)
    u[joint] = value
    return u


@pytest.mark.parametrize("joint", [1, 3, 5])
def test_a_joint_follows_its_command_with_a_servo_lag(joint: int) -> None:
    plant = PhysicsPlant(ARM, ARM.home(), PlantConfig(response_time=0.03))
    drive(plant, np.zeros(ARM.n), 0.2)
    v = drive(plant, unit(joint, 0.4), 0.3)[:, joint]
    assert v[0] < 0.4 * 0.63, "a physical servo is not instantaneous"
    reached = int(np.argmax(v >= 0.4 * 0.63))
    assert 0 < reached * DT <= 0.04  # about 2 / w: a lag of tens of ms
    assert v.max() < 0.4 * 1.3  # overshoot, but bounded
    assert abs(v[-1] - 0.4) < 0.02  # settled on the command
    others = np.delete(np.abs(drive(plant, np.zeros(ARM.n), 0.3)), joint, axis=1)
    assert others[-1].max() < 0.02  # coupling transients die out


def test_latency_comes_before_any_motion() -> None:
    plant = PhysicsPlant(ARM, ARM.home(), PlantConfig(latency=0.03, response_time=0.02))
    drive(plant, np.zeros(ARM.n), 0.1)
    v = drive(plant, unit(3, 0.5), 0.1)[:, 3]
    assert np.abs(v[: round(0.028 / DT)]).max() < 0.01
    assert v[-1] > 0.3


def test_a_still_arm_sags_a_little_and_is_held_against_its_gravity_model_error() -> None:
    plant = PhysicsPlant(ARM, ARM.home(), PlantConfig(response_time=0.03))
    drive(plant, np.zeros(ARM.n), 2.0)
    drift = np.abs(plant.q - ARM.home())
    assert drift.max() > 1e-5, "a 90 % gravity compensation should let the arm sag"
    assert drift.max() < 0.01
    assert np.abs(plant.qd).max() < 1e-3


def test_a_braked_joint_holds_while_its_drive_pushes_and_tracks_again_after_release() -> None:
    plant = PhysicsPlant(ARM, ARM.home(), PlantConfig(response_time=0.03))
    drive(plant, unit(3, 0.3), 0.3)
    plant.lock(3)
    at = plant.locked[3]
    v = drive(plant, unit(3, 0.3), 0.5)[:, 3]
    assert abs(plant.q[3] - at) < 1e-3 and np.abs(v[50:]).max() < 1e-3
    assert abs(plant.torque[3]) > 10.0  # the drive pushes against the brake
    assert plant.release() == [3]
    v = drive(plant, unit(3, 0.3), 0.3)[:, 3]
    assert abs(v[-1] - 0.3) < 0.03


def test_a_torqueless_joint_falls_the_way_gravity_turns_it() -> None:
    q = ARM.home()
    plant = PhysicsPlant(ARM, q, PlantConfig(response_time=0.03))
    falling = swing.falling_directions(ARM, q)
    assert falling is not None and falling[1] != 0
    plant.swing(1)
    drive(plant, np.zeros(ARM.n), 0.3)
    moved = plant.q - q
    assert np.sign(moved[1]) == falling[1] and abs(moved[1]) > 0.05
    assert np.abs(np.delete(moved, 1)).max() < 0.05  # the others are held by their drives
    plant.lock(1)  # a brake stops it
    drive(plant, np.zeros(ARM.n), 0.1)
    assert plant.swinging == set() and abs(plant.qd[1]) < 1e-3


def test_a_model_without_inertias_is_refused_with_the_way_out() -> None:
    with pytest.raises(physics.PhysicsError, match="panda_inertial"):
        PhysicsPlant(robots.load("panda"), robots.load("panda").home())


def test_gravity_directions_need_inertias_and_skip_a_vertical_axis() -> None:
    assert swing.falling_directions(robots.load("panda"), ARM.home()) is None
    falling = swing.falling_directions(ARM, ARM.home())
    assert falling is not None and falling[0] == 0.0  # joint 1's axis is vertical
    assert set(falling.tolist()) <= {-1.0, 0.0, 1.0} and np.count_nonzero(falling) >= 2


def test_the_driver_brakes_every_joint_the_monitor_declares_and_frees_it_on_reset() -> None:
    q = ARM.home()
    plant = PhysicsPlant(ARM, q, PlantConfig(response_time=0.03))
    plant.swing(1)
    plant.lock(3)  # an injected lock: its own brake
    drive(plant, np.zeros(ARM.n), 0.1)
    assert plant.follow_declared({1, 3, 5}) == ([1, 5], [])  # 5: a healthy joint
    at = plant.q[1]
    v = drive(plant, unit(5, 0.3), 0.3)
    assert abs(plant.q[1] - at) < 1e-3 and plant.held == {1, 5}
    assert np.abs(v[50:, 5]).max() < 1e-3  # braked: it no longer follows its command
    assert plant.follow_declared(set()) == ([], [1, 5])  # the monitor's ~/reset
    v = drive(plant, unit(5, 0.3), 0.3)
    assert plant.swinging == {1} and abs(plant.q[1] - at) > 0.01  # it falls again
    assert abs(v[-1, 5] - 0.3) < 0.03  # and 5 follows again
    assert set(plant.locked) == {3}
