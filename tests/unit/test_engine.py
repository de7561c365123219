"""ft_core.engine: one control cycle, its invariants, limits and locked joints."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from ft_core import limits, measures, robots, velocity_jump
from ft_core.engine import RESOLUTIONS, EngineConfig, ResolutionEngine, check_config
from ft_core.engine_config import BRAKING_SHARE
from ft_core.pseudoinverse import Damping, damped_pinv
from hypothesis import given, settings
from hypothesis import strategies as st
from models import straight_chain

ROBOTS = {name: robots.load(name) for name in ("planar3r", "puma560", "panda")}
PANDA_POSITION = robots.load("panda", task_space="position")


def snapshot(q: np.ndarray) -> robots.Kinematics:
    """A snapshot made by hand, for a q that `Robot.kinematics` itself would refuse."""
    return robots.Kinematics(q, np.eye(4), np.zeros((6, q.size)))


def in_bounds(robot: robots.Robot, q: np.ndarray, qd: np.ndarray, dt: float,
              velocity_scale: float = 1.0, tol: float = 1e-9) -> bool:
    nxt = q + qd * dt
    return bool(np.all(np.abs(qd) <= velocity_scale * robot.velocity_limits + tol)
                and np.all(nxt >= np.minimum(robot.lower, q) - tol)
                and np.all(nxt <= np.maximum(robot.upper, q) + tol))


@pytest.mark.parametrize("mode", RESOLUTIONS)
@pytest.mark.parametrize("name", ROBOTS)
def test_task_is_tracked_exactly_when_no_limit_is_active(name: str, mode: str) -> None:
    robot = ROBOTS[name]
    engine = ResolutionEngine(robot, EngineConfig(resolution=mode))
    rng = np.random.default_rng(3)
    checked = 0
    while checked < 5:
        q = robot.random_configuration(rng, margin=0.4)
        xd = rng.normal(scale=0.05, size=robot.m)
        result = engine.step(robot.kinematics(q), xd)
        if result.saturated.any() or result.status != "ok":
            continue
        np.testing.assert_allclose(robot.jacobian(q) @ result.qd, xd, atol=1e-9)
        assert result.task_scale == 1.0
        checked += 1


def test_min_jump_with_all_probability_on_one_joint_keeps_it_still() -> None:
    robot = ROBOTS["planar3r"]
    engine = ResolutionEngine(robot, EngineConfig(resolution="min_jump",
                                                  failure_probabilities=[0, 1, 0]))
    q, xd = np.array([0.3, 1.2, 1.0]), np.array([0.1, -0.05])
    result = engine.step(robot.kinematics(q), xd)
    assert result.qd[1] == pytest.approx(0.0, abs=1e-10)
    assert result.jump_index == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_allclose(robot.jacobian(q) @ result.qd, xd, atol=1e-10)


@pytest.mark.parametrize("mode", RESOLUTIONS)
def test_locked_joints_get_exactly_zero_and_the_rest_track(mode: str) -> None:
    robot = PANDA_POSITION
    engine = ResolutionEngine(robot, EngineConfig(resolution=mode))
    q = np.array([0.2, 0.3, -0.4, -1.8, 0.5, 1.6, 0.3])
    xd = np.array([0.05, -0.03, 0.02])
    for locked in ([1], [0, 4], [2, 3, 6]):
        result = engine.step(robot.kinematics(q), xd, locked)
        assert np.all(result.qd[locked] == 0.0)
        np.testing.assert_allclose(robot.jacobian(q) @ result.qd, xd, atol=1e-9)
        assert np.isnan(result.post_failure_sigmas[locked]).all()
    # n - |locked| - 1 < m: nothing can tolerate a further failure, exactly.
    assert engine.step(robot.kinematics(q), xd, [0, 2, 3, 6]).kfm == 0.0


@pytest.mark.parametrize("task", ["position", "pose"])
@pytest.mark.parametrize("name", ["panda", "iiwa14"])
def test_kfm_is_exactly_zero_by_structure_and_an_svd_elsewhere(name: str, task: str) -> None:
    """Issue 27: every locked set at seeded configurations, in every resolution mode.

    kfm is 0.0 where fewer than m + 1 joints are free; elsewhere it, every s_i and
    sigma_min agree with an SVD of the same post-failure matrices within 1e-10 of the
    largest singular value, whatever BLAS kernel the machine runs (the suite runs again
    under other OpenBLAS kernels in `make test-kernels`).
    """
    robot = robots.load(name, task_space=task)
    n, m = robot.n, robot.m
    engines = [ResolutionEngine(robot, EngineConfig(resolution=mode)) for mode in RESOLUTIONS]
    rng = np.random.default_rng(27)
    structural = 0
    for _ in range(3):
        q = robot.random_configuration(rng, margin=0.1)
        Js = robot.scale_task(robot.jacobian(q))
        tolerance = 1e-10 * np.linalg.svd(Js, compute_uv=False)[0]
        for count in range(n - m + 1):
            for locked in itertools.combinations(range(n), count):
                healthy = [j for j in range(n) if j not in locked]
                sigmas = measures.post_failure_sigmas(Js, locked)
                smallest = np.linalg.svd(Js[:, healthy], compute_uv=False)[-1]
                for engine in engines:
                    result = engine.step(robot.kinematics(q), np.zeros(m), locked)
                    if n - count < m + 1:
                        structural += 1
                        assert result.kfm == 0.0, (locked, result.kfm)
                    else:
                        assert result.kfm == pytest.approx(np.nanmin(sigmas), abs=tolerance)
                    np.testing.assert_allclose(result.post_failure_sigmas, sigmas, rtol=0,
                                               atol=tolerance)
                    assert result.sigma_min == pytest.approx(smallest, abs=tolerance)
    assert structural > 0


def test_too_many_locks_give_a_least_squares_best_effort_marked_infeasible() -> None:
    robot = ROBOTS["panda"]
    engine = ResolutionEngine(robot)
    q = np.array([0.2, 0.3, -0.4, -1.8, 0.5, 1.6, 0.3])
    xd = np.array([0.05, -0.03, 0.02, 0.1, 0.0, -0.1])
    result = engine.step(robot.kinematics(q), xd, locked=[1, 5])
    assert result.status == "infeasible"
    assert np.all(np.isfinite(result.qd)) and np.all(result.qd[[1, 5]] == 0.0)
    healthy = [0, 2, 3, 4, 6]
    Js = robot.scale_task(robot.jacobian(q))[:, healthy]
    best = np.linalg.lstsq(Js, robot.task_scale * xd, rcond=None)[0]
    direction = result.qd[healthy] / np.linalg.norm(result.qd[healthy])
    assert direction @ (best / np.linalg.norm(best)) > 0.99
    assert in_bounds(robot, q, result.qd, engine.config.dt)


def test_exact_singularity_gives_finite_bounded_velocities() -> None:
    robot = ROBOTS["planar3r"]
    engine = ResolutionEngine(robot)
    for xd in (np.array([1.0, 0.0]), np.array([0.0, 1.0]), np.zeros(2)):
        result = engine.step(robot.kinematics(np.zeros(3)), xd)  # stretched out: rank 1
        assert np.all(np.isfinite(result.qd))
        assert result.status in ("near_singularity", "limited")
        assert in_bounds(robot, np.zeros(3), result.qd, engine.config.dt)


def test_configuration_exactly_on_a_limit_never_goes_further() -> None:
    robot = ROBOTS["panda"]
    engine = ResolutionEngine(robot, EngineConfig(resolution="blend"))
    q = np.array([0.2, robot.upper[1], -0.4, robot.lower[3], 0.5, 1.6, 0.3])
    rng = np.random.default_rng(5)
    for _ in range(20):
        xd = rng.normal(scale=0.2, size=6)
        result = engine.step(robot.kinematics(q), xd)
        assert result.qd[1] <= 1e-12 and result.qd[3] >= -1e-12
        assert in_bounds(robot, q, result.qd, engine.config.dt)
        assert result.at_hard_limit[[1, 3]].all()


def test_the_velocity_bounds_leave_room_to_brake_before_a_limit() -> None:
    """Flacco, De Luca & Khatib 2012 sec. III with a lead: v lead + v^2 / (2 a) = room."""
    lower, upper = np.full(3, -1.0), np.full(3, 1.0)
    q, none = np.array([0.99, -0.999, 0.0]), np.zeros(3)
    lead, deceleration, speed = np.full(3, 0.006), np.full(3, 5.0), np.full(3, 2.0)
    lo, hi = limits.velocity_bounds(q, none, lower, upper, speed, lead, deceleration)
    for v, room in ((hi[0], 0.01), (-lo[1], 0.001)):
        assert 0 < v < room / 0.006  # slower than one lead to the limit
        assert v * 0.006 + v * v / (2 * 5.0) == pytest.approx(room, rel=1e-12)
    assert hi[2] == 2.0 and lo[2] == -2.0  # a metre of room: the speed limit
    assert lo[0] == -2.0 and hi[1] == 2.0
    # The motion commanded ahead of q: the room from the furthest of the two.
    lo, hi = limits.velocity_bounds(q, np.array([0.005, -0.002, 0.0]), lower, upper, speed,
                                    lead, deceleration)
    v = hi[0]
    assert v * 0.006 + v * v / (2 * 5.0) == pytest.approx(0.005, rel=1e-12)
    assert lo[1] == 0.0 and hi[1] == 2.0  # commanded beyond the limit: no further
    # Without a deceleration limit, one lead to the limit; beyond a limit, only back.
    lo, hi = limits.velocity_bounds(np.array([0.99, -1.2, 50.0]), none, lower,
                                    np.array([1.0, 1.0, np.inf]), speed, lead,
                                    np.full(3, np.inf))
    assert hi[0] == pytest.approx(0.01 / 0.006) and lo[1] == 0.0 and hi[1] == 2.0
    assert hi[2] == 2.0


def test_with_command_limits_the_bounds_brake_at_a_share_of_them() -> None:
    """`engine_config.braking`: lead dt + 2 a / j, deceleration `BRAKING_SHARE` a."""
    robot = ROBOTS["panda"]
    a, j = np.linspace(5.0, 20.0, 7), np.full(7, 5000.0)
    engine = ResolutionEngine(robot, EngineConfig(acceleration=tuple(a), jerk=tuple(j)))
    q = robot.home().copy()
    q[1] = robot.upper[1] - 0.01
    hi = engine.velocity_bounds(q, engine.bounds())[1]
    v, lead, brake = hi[1], 0.004 + 2 * a[1] / j[1], BRAKING_SHARE * a[1]
    assert v * lead + v * v / (2 * brake) == pytest.approx(0.01, rel=1e-12)
    result = engine.step(robot.kinematics(q), np.zeros(6))
    assert result.qd[1] <= v + 1e-12
    with pytest.raises(ValueError, match="jerk limits need 7"):
        ResolutionEngine(robot, EngineConfig(acceleration=tuple(a)))


def test_fast_task_is_scaled_with_its_direction_kept() -> None:
    robot = ROBOTS["panda"]
    engine = ResolutionEngine(robot, EngineConfig(velocity_scale=0.5))
    q = np.array([0.2, 0.3, -0.4, -1.8, 0.5, 1.6, 0.3])
    xd = np.array([1.5, -1.0, 0.8, 2.0, 0.0, -2.0])
    result = engine.step(robot.kinematics(q), xd)
    assert result.status == "limited" and 0 < result.task_scale < 1
    assert result.saturated.any()
    np.testing.assert_allclose(robot.jacobian(q) @ result.qd, result.task_scale * xd, atol=1e-9)
    assert in_bounds(robot, q, result.qd, engine.config.dt, velocity_scale=0.5)


def test_soft_limits_hold_while_healthy_and_are_released_on_failure() -> None:
    robot = ROBOTS["planar3r"]
    q = np.array([0.3, 1.2, 1.0])
    lower, upper = q - 0.25, q + 0.25
    config = EngineConfig(resolution="blend", soft_lower=lower, soft_upper=upper, dt=0.01)
    engine = ResolutionEngine(robot, config)
    statuses = set()
    for step in range(400):  # a circle wider than the box allows
        t = step * 0.01
        xd = 0.6 * np.array([-math.sin(t * 2), math.cos(t * 2)])
        result = engine.step(robot.kinematics(q), xd)
        statuses.add(result.status)
        q = q + result.qd * config.dt
        assert np.all(q >= lower - 1e-9) and np.all(q <= upper + 1e-9), step
        assert result.soft_limit_margin >= -1e-9
    assert "limited" in statuses  # the null space alone could not keep the joints inside
    # After a failure the box is released (default) and only the URDF limits remain.
    released = engine.step(robot.kinematics(q), np.array([0.0, 0.4]), locked=[2])
    assert released.soft_limit_margin == math.inf
    kept = ResolutionEngine(robot, EngineConfig(soft_lower=lower, soft_upper=upper,
                                                release_soft_limits_on_failure=False))
    assert kept.step(robot.kinematics(q), np.zeros(2), locked=[2]).soft_limit_margin < math.inf


def test_avoidance_is_zero_away_from_the_edges_and_smooth() -> None:
    lower, upper = np.array([-1.0]), np.array([1.0])
    inside = np.linspace(-0.89, 0.89, 50)
    assert all(limits.avoidance(np.array([x]), lower, upper, 0.1)[0] == 0.0 for x in inside)
    assert limits.avoidance(np.array([-0.95]), lower, upper, 0.1)[0] > 0
    assert limits.avoidance(np.array([0.95]), lower, upper, 0.1)[0] < 0
    edge = np.array([-0.9])  # C1 at the zone boundary: value and slope vanish
    h = 1e-6
    assert limits.avoidance(edge - h, lower, upper, 0.1)[0] < 1e-9
    slope = (limits.avoidance(edge - h, lower, upper, 0.1) - limits.avoidance(edge, lower, upper,
                                                                              0.1)) / h
    assert abs(slope[0]) < 1e-3


def test_a_preference_yields_to_the_nearest_edge_it_moves_a_joint_towards() -> None:
    lower, upper = np.array([-1.0, -1.0]), np.array([1.0, 1.0])
    q = np.array([0.95, -0.98])  # 50 and 20 mrad from an edge, within a 0.1 rad zone
    assert limits.edge_yield(np.array([-0.1, 0.1]), q, lower, upper, 0.1) == 1.0  # away
    assert limits.edge_yield(np.array([0.1, 0.1]), q, lower, upper, 0.1) == pytest.approx(0.25)
    assert limits.edge_yield(np.array([0.1, -0.1]), q, lower, upper, 0.1) == pytest.approx(0.04)
    assert limits.edge_yield(np.array([0.1, 0.0]), np.array([1.0, 0.0]), lower, upper,
                             0.1) == 0.0  # on the edge, nothing of it is left
    assert limits.edge_yield(np.array([0.1, 0.1]), np.zeros(2), lower, upper, 0.1) == 1.0


def test_the_kfm_ascent_leaves_no_joint_on_its_edge() -> None:
    """The Panda's kfm grows beyond joint 6's upper limit (3.7525 rad) from this pose.

    Holding the goal (xd = 0) for 10 s, an ascent that outweighs the avoidance drives
    joint 6 onto that limit; yielding at the edges, it stops where the avoidance balances
    it, inside the avoidance's zone but clear of the edge.
    """
    robot = PANDA_POSITION
    engine = ResolutionEngine(robot, EngineConfig())
    q = np.array([-1.713, -1.73, 1.519, -1.913, 2.505, 3.70, 0.785])
    start = engine.step(robot.kinematics(q), np.zeros(3)).kfm
    for _ in range(2500):
        result = engine.step(robot.kinematics(q), np.zeros(3))
        q = q + result.qd * engine.config.dt
    clearance = np.minimum(q - robot.lower, robot.upper - q)
    assert clearance.min() > 0.03
    assert clearance[5] < engine.config.limit_buffer  # the ascent still uses the zone
    assert result.kfm > 0.99 * start


def test_damped_pseudo_inverse_is_exact_away_from_singularities() -> None:
    damping = Damping(threshold=0.1, max_damping=0.2)
    A = np.array([[1.0, 0.0, 0.2], [0.0, 0.5, 0.1]])
    np.testing.assert_allclose(damped_pinv(A, damping), np.linalg.pinv(A), atol=1e-12)
    singular = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    result = damped_pinv(singular, damping)
    assert np.all(np.isfinite(result))
    near = np.array([[1.0, 0.0, 0.0], [0.0, 1e-9, 0.0]])
    np.testing.assert_allclose(damped_pinv(near, damping), result, atol=1e-6)  # continuous
    with pytest.raises(ValueError, match="positive"):
        Damping(threshold=0.0)


@pytest.mark.parametrize(("hi", "expected", "scale", "saturated"), [
    ([5.0, 5.0], [1.5, 1.5], 1.0, [False, False]),  # nothing binds: the least-norm solution
    ([1.0, 5.0], [1.0, 2.0], 1.0, [True, False]),  # joint 0 held, joint 1 does the rest
    ([1.0, 1.0], [1.0, 1.0], 2.0 / 3.0, [True, True]),  # both held: the task is scaled
])
def test_saturation_in_the_null_space_by_hand(hi: list, expected: list, scale: float,
                                              saturated: list) -> None:
    """J = [1 1], xd = 3, lo = -hi, z = 0 (Flacco et al.'s Algorithm 1, worked by hand)."""
    J, hi_ = np.array([[1.0, 1.0]]), np.array(hi)
    pinv = damped_pinv(J, Damping())
    qd, s, held = limits.saturate_in_null_space(J, np.array([3.0]), np.zeros(2), -hi_, hi_,
                                                Damping().threshold, Damping().max_damping,
                                                pinv)
    np.testing.assert_allclose(qd, expected, atol=1e-12)
    assert s == pytest.approx(scale, abs=1e-12)
    assert held.tolist() == saturated


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**31), m=st.integers(1, 3), extra=st.integers(0, 4),
       speed=st.floats(0.0, 50.0))
def test_saturation_keeps_the_bounds_and_the_task_direction(seed: int, m: int, extra: int,
                                                            speed: float) -> None:
    rng = np.random.default_rng(seed)
    n = m + extra
    J = rng.normal(size=(m, n))
    xd, z = rng.normal(size=m) * speed, rng.normal(size=n)
    lo, hi = -rng.uniform(0.0, 2.0, n), rng.uniform(0.0, 2.0, n)
    damping = Damping()
    qd, scale, held = limits.saturate_in_null_space(J, xd, z, lo, hi, damping.threshold,
                                                    damping.max_damping, damped_pinv(J, damping))
    assert np.all(np.isfinite(qd)) and 0.0 <= scale <= 1.0
    assert np.all(qd >= lo - 1e-9) and np.all(qd <= hi + 1e-9)
    assert held.shape == (n,)
    free = ~held
    if scale > 0 and free.sum() >= m and np.linalg.svd(
            J[:, free], compute_uv=False)[-1] > 2 * damping.threshold:
        np.testing.assert_allclose(J @ qd, scale * xd, atol=1e-7)  # direction kept


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"resolution": "fastest"}, "resolution"),
    ({"kfm_gain": -1.0}, "kfm_gain"),
    ({"jump_gain": math.nan}, "jump_gain"),
    ({"dt": 0.0}, "dt"),
    ({"velocity_scale": 1.5}, "velocity_scale"),
    ({"soft_lower": [0.0], "soft_upper": []}, "same length"),
])
def test_invalid_configurations_are_rejected(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        EngineConfig(**kwargs)


def test_invalid_engine_inputs_are_rejected_before_arithmetic() -> None:
    robot = ROBOTS["planar3r"]
    for config, match in ((EngineConfig(soft_lower=[0.0], soft_upper=[1.0]), "soft limits"),
                          (EngineConfig(soft_lower=[1.0] * 3, soft_upper=[0.0] * 3), "above"),
                          (EngineConfig(failure_probabilities=[1.0, 1.0]), "probabilities")):
        # The same refusal with and without building an engine (the node's validation).
        with pytest.raises(ValueError, match=match):
            check_config(robot, config)
        with pytest.raises(ValueError, match=match):
            ResolutionEngine(robot, config)
    probabilities, soft = check_config(robot, EngineConfig(failure_probabilities=[1, 2, 1]))
    assert probabilities.tolist() == [1, 2, 1] and soft[0].size == 0
    engine = ResolutionEngine(robot)
    with pytest.raises(ValueError, match="finite"):
        engine.step(snapshot(np.array([0.0, np.nan, 0.0])), np.zeros(2))
    with pytest.raises(ValueError, match="finite"):
        engine.step(robot.kinematics(np.zeros(3)), np.array([np.inf, 0.0]))
    with pytest.raises(ValueError, match="xd must have 2"):
        engine.step(robot.kinematics(np.zeros(3)), np.zeros(3))
    with pytest.raises(ValueError, match="q must have 3"):
        engine.step(snapshot(np.zeros(2)), np.zeros(2))
    with pytest.raises(ValueError, match="locked joint index"):
        engine.step(robot.kinematics(np.zeros(3)), np.zeros(2), locked=[3])


@settings(max_examples=80, deadline=None)
@given(name=st.sampled_from(["planar3r", "panda"]), mode=st.sampled_from(RESOLUTIONS),
       seed=st.integers(0, 2**31), speed=st.floats(0.0, 3.0),
       locked=st.lists(st.integers(0, 6), max_size=2, unique=True),
       on_limit=st.booleans())
def test_invariants_hold_everywhere(name: str, mode: str, seed: int, speed: float,
                                    locked: list[int], on_limit: bool) -> None:
    robot = ROBOTS[name]
    locked = [i for i in locked if i < robot.n]
    rng = np.random.default_rng(seed)
    q = robot.random_configuration(rng)
    if on_limit and np.isfinite(robot.upper[0]):
        q[0] = robot.upper[0]
    xd = rng.normal(size=robot.m) * speed
    engine = ResolutionEngine(robot, EngineConfig(resolution=mode))
    result = engine.step(robot.kinematics(q), xd, locked)
    assert np.all(np.isfinite(result.qd))
    assert np.all(result.qd[locked] == 0.0)
    assert in_bounds(robot, q, result.qd, engine.config.dt)
    assert 0.0 <= result.task_scale <= 1.0
    if result.status == "ok" and not result.saturated.any():
        np.testing.assert_allclose(robot.jacobian(q) @ result.qd, xd, atol=1e-8)


def simulate_panda(mode: str) -> dict[str, float]:
    """10 s on the Panda (position task): a 0.1 m vertical circle every 5 s, Euler at 100 Hz.

    Also returns the largest excess of the cycle's jump index over least norm's at
    the same configuration (Zhao & Li eq 14 says it is never positive for min_jump).
    """
    robot = PANDA_POSITION
    dt = 0.01
    engine = ResolutionEngine(robot, EngineConfig(resolution=mode, dt=dt))
    q = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
    start = robot.forward(q)
    kfm, jump, excess = [], [], -math.inf
    for step in range(1000):
        w = 2 * math.pi / 5
        t = step * dt
        xd = np.array([0.0, 0.1 * w * math.cos(w * t), -0.1 * w * math.sin(w * t)])
        result = engine.step(robot.kinematics(q), xd)
        assert result.status == "ok"
        assert in_bounds(robot, q, result.qd, dt)
        J = robot.jacobian(q)
        here = velocity_jump.jump_index(J, np.linalg.pinv(J) @ xd, xd)
        excess = max(excess, result.jump_index - here)
        kfm.append(result.kfm)
        jump.append(result.jump_index)
        q = q + result.qd * dt
        assert np.all(q >= robot.lower) and np.all(q <= robot.upper)
    np.testing.assert_allclose(robot.forward(q), start, atol=2e-3)  # two full circles
    return {"kfm": float(np.mean(kfm)), "jump": float(np.mean(jump)), "excess": excess}


def test_panda_trajectory_max_kfm_and_min_jump_beat_least_norm() -> None:
    """Same task path, three modes; no limit is crossed in any.

    max_kfm nearly doubles the mean K of least norm (0.22 against 0.12). min_jump's
    jump index is below least norm's at every configuration it passes (eq 14); its
    mean over the run is lower too, but only just (0.2734 against 0.2737): with four
    degrees of redundancy least norm is already close to the minimum, as Zhao & Li
    remarks, and the two modes follow different joint paths.
    """
    runs = {mode: simulate_panda(mode) for mode in ("least_norm", "max_kfm", "min_jump")}
    print({mode: {k: round(v, 4) for k, v in r.items()} for mode, r in runs.items()})
    assert runs["max_kfm"]["kfm"] > 1.5 * runs["least_norm"]["kfm"]
    assert runs["min_jump"]["excess"] <= 1e-12
    assert runs["min_jump"]["jump"] < runs["least_norm"]["jump"]


@pytest.mark.parametrize(("robot", "locked"), [(ROBOTS["panda"], ()), (PANDA_POSITION, (2,))])
def test_compiled_cycle_equals_the_svd_reference_composition(robot: robots.Robot,
                                                           locked: tuple[int, ...]) -> None:
    """The blend cycle's qd, sigmas and jump index against `measures` and `resolution` (SVD based).

    Configurations 0.3 rad inside the limits (no avoidance) and a modest gain, so no
    bound is active and the cycle is the plain formula: qd = J# x + (I - J# J) z with
    z = kfm_gain grad K + jump_gain sum_i w_i iqd'.
    """
    config = EngineConfig(resolution="blend", kfm_gain=2.0)
    engine, rng, checked = ResolutionEngine(robot, config), np.random.default_rng(11), 0
    healthy = np.setdiff1d(np.arange(robot.n), locked)
    for _ in range(30):
        q = robot.random_configuration(rng, margin=0.3)
        xd = rng.normal(scale=0.05, size=robot.m)
        result = engine.step(robot.kinematics(q), xd, locked)
        J, dJ = robot.jacobian_and_derivatives(q)
        J = robot.scale_task(J)[:, healthy]
        dJ = robot.scale_task(dJ)[np.ix_(healthy, np.arange(robot.m), healthy)]
        x = robot.task_scale * xd
        weights = np.full(healthy.size, 1.0 / healthy.size)
        reduced = velocity_jump.post_failure_velocities(J, x, config.damping)
        z = (config.kfm_gain * measures.kfm_gradient(J, dJ, temperature=config.kfm_temperature)
             + config.jump_gain * weights @ reduced)
        pinv = damped_pinv(J, config.damping)
        qd = pinv @ x + z - pinv @ (J @ z)
        if result.status != "ok":
            continue  # a bound or the damping is active: not the plain formula
        checked += 1
        np.testing.assert_allclose(result.qd[healthy], qd, atol=1e-7)
        assert np.all(result.qd[list(locked)] == 0.0)
        np.testing.assert_allclose(result.post_failure_sigmas[healthy],
                                   measures.post_failure_sigmas(J), atol=1e-7)
        assert result.jump_index == pytest.approx(
            velocity_jump.jump_index(J, qd, x, damping=config.damping), rel=1e-6)
    assert checked >= 20


@pytest.mark.parametrize("axes", ["zyzyzyz", "yyyyyyy", "zzzyyyz", "xyzxyzx"])
@pytest.mark.parametrize("mode", RESOLUTIONS)
def test_engine_starts_from_exactly_singular_straight_chains(axes: str, mode: str) -> None:
    """Axis-aligned chains at q = 0: repeated exact-zero eigenvalues of J J^T (issue 14)."""
    robot = straight_chain(list(axes))
    engine = ResolutionEngine(robot, EngineConfig(resolution=mode))
    q = np.zeros(robot.n)
    for xd in (np.zeros(robot.m), np.array([0.1, 0.0, 0.0, 0.0, 0.0, 0.2])):
        result = engine.step(robot.kinematics(q), xd)
        assert np.all(np.isfinite(result.qd))
        assert np.all(np.abs(result.qd) <= robot.velocity_limits + 1e-12)
        assert np.all(np.isfinite(result.post_failure_sigmas))
        assert math.isfinite(result.kfm) and math.isfinite(result.jump_index)


def test_relative_failure_probabilities_up_to_1e308_give_finite_commands() -> None:
    """Found by the 30-minute fuzz run (issue 31): 7 x 1e308 overflowed a sum."""
    robot = robots.load("panda")
    for resolution in ("blend", "max_kfm"):
        engine = ResolutionEngine(robot, EngineConfig(resolution=resolution,
                                                      failure_probabilities=[1e308] * 7))
        for locked in ((), (2,)):
            result = engine.step(robot.kinematics(robot.home()), np.array([0.05, 0, 0, 0, 0, 0.1]),
                                 locked)
            assert np.all(np.isfinite(result.qd)) and np.any(result.qd != 0)


def test_a_continuous_joint_beyond_a_million_radians_is_absurd() -> None:
    """Issue 31 item 2: no limits to be outside of, yet 1e300 rad squares to inf."""
    planar = robots.load("planar3r")
    assert np.all(np.isinf(planar.lower))
    assert limits.absurd_joint(np.array([0.0, 1e5, -9e5]), planar.lower, planar.upper) == -1
    assert limits.absurd_joint(np.array([0.0, 1e300, 0.0]), planar.lower, planar.upper) == 1
    reason = limits.absurd_position(np.array([-2e6, 0.0, 0.0]), planar.lower, planar.upper,
                                    planar.joint_names)
    assert reason is not None and reason.startswith(planar.joint_names[0])
    with pytest.raises(ValueError, match="beyond 1e\\+06 rad"):
        ResolutionEngine(planar, EngineConfig()).step(
            planar.kinematics(np.array([0.0, 0.0, 1e300])), np.zeros(planar.m))


@pytest.mark.parametrize("mode", RESOLUTIONS)
def test_huge_inputs_are_refused_or_bounded_and_never_hang(mode: str) -> None:
    """Issue 14: a twist of 1e306 or a position of 1e300 never ended the null-space loop."""
    import threading

    robot = robots.load("panda")
    engine = ResolutionEngine(robot, EngineConfig(resolution=mode))
    home = robot.home()
    absurd = [(home, np.full(6, 1e306)), (np.full(7, 1e300), np.full(6, 0.1)),
              (robot.upper + 1.5, np.zeros(6))]
    largest = [(home, np.full(6, 1e3)), (home, np.array([1e3, 0, 0, 0, 0, 0])),
               (robot.upper + 0.9, np.full(6, 1e3)), (robot.lower - 0.9, -np.full(6, 1e3))]
    outcomes: list = []

    def work() -> None:
        for q, xd in absurd:
            try:
                engine.step(robot.kinematics(q), xd)
                outcomes.append("accepted")
            except ValueError as error:
                outcomes.append(str(error))
        outcomes.extend(engine.step(robot.kinematics(q), xd) for q, xd in largest)

    worker = threading.Thread(target=work)
    worker.start()
    worker.join(timeout=60)
    assert not worker.is_alive(), "the engine did not return"
    assert len(outcomes) == len(absurd) + len(largest)
    assert "no arm can do that" in outcomes[0]
    assert all("outside the joint limits" in text for text in outcomes[1:3])
    for result in outcomes[3:]:
        assert np.all(np.isfinite(result.qd))
        assert np.all(np.abs(result.qd) <= robot.velocity_limits + 1e-9)
        assert math.isfinite(result.kfm) and math.isfinite(result.jump_index)


def test_a_new_engine_has_loaded_the_compiled_code_of_every_path() -> None:
    """The code a cycle with too few healthy joints runs is loaded at construction.

    In a fresh interpreter, so that nothing else loaded it: a pose task's first cycle
    after a second lock (5 healthy joints for 6 coordinates: `_infeasible`) used to
    load numba's cached code then, 12 ms on an idle machine and 87 ms on a busy one (a
    fuzz run caught it), inside the control cycle.
    """
    import subprocess
    import sys

    code = ("from ft_core import engine, limits, pseudoinverse, robots\n"
            "engine.ResolutionEngine(robots.load('panda'))\n"
            "print(*[len(f.signatures) for f in (limits.velocity_bounds, "
            "limits.largest_scale, pseudoinverse.squared_damping)])\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert all(int(count) >= 1 for count in out.split()) and len(out.split()) == 3, out
