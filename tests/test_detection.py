"""ft_core.detection offline: no false locks, the right joint fast, limits and gaps."""

from __future__ import annotations

import numpy as np
import pytest
from ft_core import robots
from ft_core.detection import DetectorConfig, LockDetector

PANDA = robots.load("panda")
START = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
DT = 1 / 250


def run(commands, seconds: float, lock: tuple[int, float] | None = None, noise: float = 1e-3,
        latency: float = 0.0, seed: int = 0, detector: LockDetector | None = None):
    """Integrate `commands(t)` for `seconds`; returns (detector, [(time, joints)])."""
    rng = np.random.default_rng(seed)
    detector = detector or LockDetector(PANDA.lower, PANDA.upper,
                                        DetectorConfig(latency=latency))
    q, events, pending = START.copy(), [], []
    for k in range(round(seconds / DT)):
        t = k * DT
        qd = commands(t)
        detector.command(t, qd)
        pending.append((t + latency, qd))
        applied = next(v for s, v in reversed(pending) if s <= t) if pending[0][0] <= t else 0 * qd
        move = np.array(applied, dtype=float)
        if lock is not None and t >= lock[1]:
            move[lock[0]] = 0.0
        q = np.clip(q + move * DT, PANDA.lower, PANDA.upper)
        new = detector.measure(t + DT, q + rng.normal(scale=noise, size=7))
        if new:
            events.append((t + DT, new))
    return detector, events


def sweeping(t: float) -> np.ndarray:
    """Speeds sweeping 0.05 .. 1 rad/s per joint, direction flipping every half second."""
    speed = 0.05 + 0.95 * (0.5 + 0.5 * np.sin(2 * np.pi * t / 7 + np.arange(7)))
    return speed * np.where(np.sin(2 * np.pi * t + np.arange(7)) >= 0, 1.0, -1.0)


def test_sixty_healthy_seconds_with_noise_declare_nothing() -> None:
    _, events = run(sweeping, 60.0)
    assert events == []


@pytest.mark.parametrize("joint", range(7))
def test_each_locked_joint_is_found_within_100_ms(joint: int) -> None:
    _, events = run(lambda t: np.full(7, 0.2), 1.5, lock=(joint, 1.0))
    assert events, "not detected"
    time, joints = events[0]
    print(f"\njoint {joint + 1}: detected after {1000 * (time - 1.0):.0f} ms")
    assert joints == [joint]
    assert time - 1.0 < 0.1


def test_plant_latency_is_tolerated_when_configured() -> None:
    _, healthy = run(sweeping, 10.0, latency=0.03)
    assert healthy == []
    _, events = run(lambda t: np.full(7, 0.2), 1.5, lock=(2, 1.0), latency=0.03)
    assert events and events[0][1] == [2]


def test_small_commands_are_unobservable() -> None:
    detector, events = run(lambda t: np.full(7, 0.02), 2.0, lock=(1, 0.5))
    assert events == [] and not detector.joints[1].observable


def test_a_stall_at_a_joint_limit_is_not_a_lock() -> None:
    push = np.zeros(7)
    push[3] = 0.3  # joint 4 runs into its upper limit (-0.0698) after ~7 s
    detector, events = run(lambda t: push, 9.0)
    assert events == []
    assert detector.joints[3].at_limit


def test_gaps_and_out_of_order_data_give_no_decision() -> None:
    detector = LockDetector(PANDA.lower, PANDA.upper)
    detector.command(0.0, np.full(7, 0.5))
    for t in (0.0, 0.004, 0.2, 0.204, 0.208):  # a 0.2 s gap: no positions in most windows
        assert detector.measure(t, START) == []
    assert detector.measure(0.1, START) == []  # out of order: ignored


def test_declared_locks_and_reset() -> None:
    detector = LockDetector(PANDA.lower, PANDA.upper)
    detector.lock(4, 0.25, 1.0)
    assert detector.locked == {4: 0.25}
    detector.reset()
    assert detector.locked == {}


@pytest.mark.parametrize("field", ["window", "ratio", "confidence", "min_samples"])
def test_invalid_configurations_are_rejected(field: str) -> None:
    with pytest.raises(ValueError, match=field):
        DetectorConfig(**{field: 0})
