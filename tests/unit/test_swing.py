"""Issue 16, part 3 (in part): the swing angles and measure of Maciejewski et al. eqs 11-14."""

from __future__ import annotations

import math

import numpy as np
import pytest
from ft_core import robots, swing
from paths import PANDA_URDF

#: In a vertical plane: joints about z, gravity along -y.
DOWN_Y = (0.0, -9.81, 0.0)


def rods(count: int = 3) -> robots.Robot:
    """Planar arm of unit links, each a uniform 1 kg rod (centre of mass at its middle)."""
    parts = ['<robot name="rods">', '<link name="l0"/>']
    for i in range(1, count + 1):
        parts.append(f'<link name="l{i}"><inertial><origin xyz="0.5 0 0"/><mass value="1"/>'
                     '<inertia ixx="0.001" iyy="0.084" izz="0.084" ixy="0" ixz="0" iyz="0"/>'
                     '</inertial></link>')
        parts.append(f'<joint name="j{i}" type="continuous"><parent link="l{i - 1}"/>'
                     f'<child link="l{i}"/><origin xyz="{0 if i == 1 else 1} 0 0"/>'
                     '<axis xyz="0 0 1"/><limit velocity="2" effort="10"/></joint>')
    parts.append(f'<link name="tool"/><joint name="t" type="fixed"><parent link="l{count}"/>'
                 '<child link="tool"/><origin xyz="1 0 0"/></joint></robot>')
    return robots.load("".join(parts), task_space="planar")


ARM = rods()


@pytest.mark.parametrize(("q", "expected"), [
    # Stretched out horizontally: every outboard part falls a quarter turn, clockwise.
    ((0.0, 0.0, 0.0), (-math.pi / 2, -math.pi / 2, -math.pi / 2)),
    # Hanging down: nothing moves.
    ((-math.pi / 2, 0.0, 0.0), (0.0, 0.0, 0.0)),
    # Elbow up at 90 deg: links 1-3 have their centre of mass at (2.5, 2) / 3 from joint 1,
    # links 2-3 at (0, 2) / 2 from joint 2 (straight up), link 3 at (0, 0.5) from joint 3.
    ((0.0, math.pi / 2, 0.0), (-math.pi / 2 - math.atan2(2.0, 2.5), math.pi, math.pi)),
    # Joint 3 folded down: link 3 hangs from joint 3; first moments (4, -0.5) about joint 1
    # (rods centred at 0.5, 1.5 and (2, -0.5)) and (1.5, -0.5) about joint 2.
    ((0.0, 0.0, -math.pi / 2), (-math.pi / 2 - math.atan2(-0.5, 4.0),
                                -math.pi / 2 - math.atan2(-0.5, 1.5), 0.0)),
])
def test_swing_angles_match_values_worked_by_hand(q, expected) -> None:
    theta = swing.swing_angles(ARM, np.array(q), DOWN_Y)
    # +-pi are the same upright equilibrium.
    np.testing.assert_allclose(np.angle(np.exp(1j * (theta - expected))), 0.0, atol=1e-9)
    assert swing.swing_measure(ARM, np.array(q), None, DOWN_Y) == pytest.approx(
        float(np.sum(theta ** 2)))


def test_no_swing_about_a_vertical_axis_or_without_mass() -> None:
    assert np.all(swing.swing_angles(ARM, np.zeros(3)) == 0)  # gravity along the axes
    assert np.all(swing.swing_angles(robots.load("planar3r"), np.zeros(3), DOWN_Y) == 0)
    assert np.all(swing.swing_gradient(ARM, np.zeros(3)) == 0)


@pytest.mark.parametrize("name", ["rods", "panda"])
def test_gradient_matches_finite_differences(name: str) -> None:
    """On the rods and on the real-world Panda URDF (with its links' inertias)."""
    robot = ARM if name == "rods" else robots.load(str(PANDA_URDF))
    gravity = DOWN_Y if name == "rods" else swing.STANDARD_GRAVITY
    rng = np.random.default_rng(7)
    weights = rng.uniform(0.5, 2.0, robot.n)
    for _ in range(10):
        q = robot.random_configuration(rng, margin=0.2)
        theta = swing.swing_angles(robot, q, gravity)
        if np.any(np.abs(np.abs(theta) - math.pi) < 0.05):
            continue  # next to the upright equilibrium atan2 wraps: no derivative
        assert swing.swing_measure(robot, q, weights, gravity) > 0.01
        analytic = swing.swing_gradient(robot, q, weights, gravity)
        numeric = np.zeros(robot.n)
        for k in range(robot.n):
            step = np.zeros(robot.n)
            step[k] = 1e-6
            numeric[k] = (swing.swing_measure(robot, q + step, weights, gravity)
                          - swing.swing_measure(robot, q - step, weights, gravity)) / 2e-6
        np.testing.assert_allclose(analytic, numeric, rtol=1e-5, atol=1e-6)


def test_on_the_real_world_panda_descent_reduces_the_swings() -> None:
    """A small step against the gradient lowers h.

    Away from the upright +-pi, where the angle wraps (the Panda's home holds joints 2
    and 3 nearly upright).
    """
    panda = robots.load(str(PANDA_URDF))
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(30):
        q = panda.random_configuration(rng, margin=0.2)
        if np.max(np.abs(swing.swing_angles(panda, q))) > 2.5:
            continue
        before = swing.swing_measure(panda, q)
        assert swing.swing_measure(panda, q - 1e-3 * swing.swing_gradient(panda, q)) < before
        checked += 1
    assert checked >= 5


def test_the_engine_descends_the_swing_measure_in_the_null_space() -> None:
    """`swing_gain` (Maciejewski et al.: grad h in eq 3): with the tool held still, h falls.

    The tool stays where it was, to the integration error of 0.4 s at 4 ms.
    """
    from ft_core import engine

    panda = robots.load(str(PANDA_URDF), task_space="position")
    rng = np.random.default_rng(5)
    q = panda.random_configuration(rng, margin=0.4)
    while np.max(np.abs(swing.swing_angles(panda, q))) > 2.5:
        q = panda.random_configuration(rng, margin=0.4)
    tool, before = panda.forward(q), swing.swing_measure(panda, q)
    cycle = engine.ResolutionEngine(panda, engine.EngineConfig(
        resolution="least_norm", swing_gain=0.2))
    for _ in range(100):
        q = q + 0.004 * cycle.step(panda.kinematics(q), np.zeros(3)).qd
    assert swing.swing_measure(panda, q) < 0.95 * before
    assert np.linalg.norm(panda.forward(q) - tool) < 5e-4
    idle = engine.ResolutionEngine(panda, engine.EngineConfig(resolution="least_norm"))
    assert np.all(idle.step(panda.kinematics(q), np.zeros(3)).qd == 0)  # off by default
    with pytest.raises(ValueError, match="swing_gain"):
        engine.EngineConfig(swing_gain=-1.0)


