"""Lewis & Maciejewski 1997's guarantee: inside a critical point's box, any one lock is survivable.

For critical points of the Panda (position task) and of the PUMA 560, random
configurations inside the point's bounding box that reach a nearby task point
get a random joint locked; the remaining joints then drive to the critical
point. Every trial must succeed. The same from configurations outside the box
(the locked joint outside its box range) fails for a measurable fraction; both
rates are printed (run pytest with -s to see them).
"""

from __future__ import annotations

import numpy as np
import pytest
from ft_core import robots, selfmotion

CASES = [
    ("panda", [0.5, 0.1, 0.4]),
    ("panda", [0.35, -0.3, 0.55]),
    ("puma560", [0.0, 0.9, 0.5]),
    ("puma560", [0.5, 0.5, 0.2]),
]
TRIALS = 25


def nearby_configuration(robot: robots.Robot, manifold: selfmotion.Manifold,
                         lower: np.ndarray, upper: np.ndarray,
                         rng: np.random.Generator) -> np.ndarray | None:
    """A configuration inside [lower, upper] reaching a point within 10 cm of the target."""
    start = manifold.samples[rng.integers(len(manifold.samples))]
    start = np.clip(start + rng.normal(scale=0.3, size=robot.n), lower, upper)
    nearby = manifold.target + rng.uniform(-0.1, 0.1, size=3)
    return selfmotion.project(robot, nearby, start, lower=lower, upper=upper)


def success(robot: robots.Robot, manifold: selfmotion.Manifold, q: np.ndarray,
            joint: int) -> bool:
    final = selfmotion.recover(manifold, q, joint)
    return bool(final is not None and final[joint] == q[joint]
                and np.linalg.norm(robot.forward(final) - manifold.target) < 1e-6
                and np.all(final >= robot.lower) and np.all(final <= robot.upper))


@pytest.mark.parametrize(("name", "point"), CASES)
def test_any_lock_inside_the_box_can_still_reach_the_point(name: str, point: list) -> None:
    robot = robots.load(name, task_space="position")
    manifold = selfmotion.trace(robot, np.array(point))
    lower, upper = manifold.box
    rng = np.random.default_rng(21)
    inside = outside = inside_ok = outside_ok = 0
    while inside < TRIALS:
        q = nearby_configuration(robot, manifold, lower, upper, rng)
        if q is None:
            continue
        inside += 1
        inside_ok += success(robot, manifold, q, int(rng.integers(robot.n)))
    attempts = 0
    while outside < TRIALS and attempts < 40 * TRIALS:
        attempts += 1
        q = selfmotion.project(robot, manifold.target + rng.uniform(-0.1, 0.1, size=3),
                               robot.random_configuration(rng))
        if q is None:
            continue
        beyond = np.flatnonzero((q < lower - 1e-3) | (q > upper + 1e-3))
        if not beyond.size:
            continue
        outside += 1
        outside_ok += success(robot, manifold, q, int(rng.choice(beyond)))
    print(f"\n{name} {point}: inside the box {inside_ok}/{inside} reached, "
          f"outside {outside_ok}/{outside} reached")
    assert inside_ok == inside
    assert outside == TRIALS and outside_ok < outside
