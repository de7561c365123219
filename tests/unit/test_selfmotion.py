"""ft_core.selfmotion: traced manifolds against analytic and brute-force references."""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import pytest
from ft_core import robots, selfmotion
from ft_core.selfmotion import UnreachableError
from models import planar_arm

PLANAR = robots.load("planar3r")


def brute_force_box(links: int, radius: float, grid: int = 1601) -> tuple[np.ndarray, ...]:
    """Box of the manifold of (radius, 0) for a unit-link planar arm with 3 or 4 joints.

    Dense grid over the first joints, the last two solved in closed form (both
    elbows). Valid where the manifold is one closed curve or surface that does not
    cross +-pi, as for the radii used here.
    """
    g = np.linspace(-np.pi, np.pi, grid)
    heads = np.stack(np.meshgrid(*[g] * (links - 2), indexing="ij"), -1).reshape(-1, links - 2)
    angles = np.cumsum(heads, axis=1)
    wrist = np.stack([np.cos(angles).sum(1), np.sin(angles).sum(1)], -1)
    gap = np.array([radius, 0.0]) - wrist
    distance = np.linalg.norm(gap, axis=1)
    ok = distance <= 2.0
    cosine = np.clip((distance[ok] ** 2 - 2.0) / 2.0, -1.0, 1.0)
    points = []
    for sign in (1.0, -1.0):
        last = sign * np.arccos(cosine)
        middle = (np.arctan2(gap[ok, 1], gap[ok, 0]) - np.arctan2(np.sin(last), 1 + np.cos(last))
                  - angles[ok, -1])
        middle = (middle + np.pi) % (2 * np.pi) - np.pi
        points.append(np.column_stack([heads[ok], middle, last]))
    points = np.vstack(points)
    return points.min(axis=0), points.max(axis=0)


def test_point_one_link_from_the_base_spans_every_joints_full_range() -> None:
    target = np.array([0.6, 0.8])  # distance 1 (Lewis & Maciejewski 1997 sec. II)
    manifold = selfmotion.trace(PLANAR, target, np.array([0.5, 1.5, 1.5]))
    assert manifold.method == "curve" and manifold.closed
    lower, upper = manifold.box
    assert np.all(np.isinf(lower)) and np.all(np.isinf(upper))
    assert selfmotion.box_volume(PLANAR, lower, upper) == pytest.approx(1.0)


@pytest.mark.parametrize("seed", [None, [0.0, 0.5, math.pi], [0.0, 0.0, math.pi],
                                  [0.3, 1.0, 2.0]])
def test_branches_crossing_at_singular_configurations_are_all_followed(seed) -> None:
    """Issue 15: the planar 3R at (1, 0), whose branches cross at singular configurations.

    The folded branch (q1 = 0, q3 = pi, joint 2 turning freely with the tool on its
    axis) meets the branch where q1 turns through the singular configurations q2 = 0
    and q2 = pi; the component is both, spanning every joint's full circle. Without a
    seed `find_seed` lands on the folded branch; the second seed is on it, the third
    is a crossing itself, the last a regular point.
    """
    target = np.array([1.0, 0.0])
    manifold = selfmotion.trace(PLANAR, target, None if seed is None else np.array(seed))
    assert len(manifold.paths) >= 2  # a branch beside the seed's was followed
    lower, upper = manifold.box
    assert np.all(np.isinf(lower)) and np.all(np.isinf(upper))
    assert selfmotion.box_volume(PLANAR, lower, upper) == pytest.approx(1.0)
    assert np.all([np.linalg.norm(PLANAR.forward(q) - target) < 1e-8
                   for q in manifold.samples])
    folded = np.abs(np.abs(manifold.samples[:, 2]) - math.pi) < 1e-6
    assert folded.any() and (~folded).any()  # on both branches


@pytest.mark.parametrize("radius", [1.5, 2.0, 2.5])
def test_intermediate_radii_match_the_brute_force_box(radius: float) -> None:
    manifold = selfmotion.trace(PLANAR, np.array([radius, 0.0]), np.array([0.3, -0.8, 0.5]))
    assert manifold.closed
    lower, upper = manifold.box
    expected_lower, expected_upper = brute_force_box(3, radius)
    np.testing.assert_allclose(lower, expected_lower, atol=0.01)
    np.testing.assert_allclose(upper, expected_upper, atol=0.01)


def test_boxes_shrink_to_a_configuration_at_the_workspace_boundary() -> None:
    """Near the reach boundary the manifold's width goes like sqrt(3 - radius) (unit links)."""
    volumes, widths = [], []
    for radius in (2.9, 2.99, 2.999, 2.9999):
        lower, upper = selfmotion.bounding_box(PLANAR, np.array([radius, 0.0]))
        volumes.append(selfmotion.box_volume(PLANAR, lower, upper))
        widths.append(float(np.max(upper - lower)))
    assert all(a > b for a, b in pairwise(volumes))
    for wider, narrower in pairwise(widths):
        assert narrower == pytest.approx(wider / math.sqrt(10), rel=0.1)
    assert widths[-1] < 0.05  # a single stretched-out configuration in the limit


def test_spiral_on_a_two_dimensional_manifold_matches_brute_force() -> None:
    arm = planar_arm([1.0, 1.0, 1.0, 1.0])
    manifold = selfmotion.trace(arm, np.array([3.0, 0.0]), np.array([0.3, 0.5, 0.5, 0.5]))
    assert manifold.method == "spiral"
    lower, upper = manifold.box
    expected_lower, expected_upper = brute_force_box(4, 3.0, grid=801)
    np.testing.assert_allclose(lower, expected_lower, atol=0.01)
    np.testing.assert_allclose(upper, expected_upper, atol=0.01)


def test_only_the_seeds_component_is_traced() -> None:
    arm = planar_arm([1.0, 1.0, 1.0], limit=2.0)  # the limits cut the closed curve in two
    target = np.array([1.5, 0.0])
    up = selfmotion.trace(arm, target, np.array([-0.9, 1.2, 1.2]))
    down = selfmotion.trace(arm, target, np.array([0.9, -1.2, -1.2]))
    assert up.box[0][1] > 0.4 and down.box[1][1] < -0.4  # elbow up and elbow down apart
    assert np.all(up.samples[:, 1] > 0) and np.all(down.samples[:, 1] < 0)
    assert np.isclose(up.box[1][1], 2.0) and np.isclose(down.box[0][1], -2.0)  # limit met


@pytest.mark.parametrize(("name", "task", "target", "seed"), [
    ("panda", "position", [0.5, 0.1, 0.4], None),
    ("puma560", "position", [0.9, 0.0, 0.5], None),
    ("panda", "pose", None, [0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]),
])
def test_every_sample_reaches_the_target_inside_the_limits(name: str, task: str, target: list,
                                                           seed: list | None) -> None:
    robot = robots.load(name, task_space=task)
    if target is None:
        target = robot.forward(np.array(seed))
    manifold = selfmotion.trace(robot, np.asarray(target), None if seed is None else seed)
    for q in manifold.samples[:: max(1, len(manifold.samples) // 200)]:
        assert np.linalg.norm(robot.task_error(target, q)) < 1e-8
    assert np.all(manifold.samples >= robot.lower - 1e-12)
    assert np.all(manifold.samples <= robot.upper + 1e-12)
    lower, upper = manifold.box
    assert np.all(lower <= manifold.seed) and np.all(manifold.seed <= upper)


def test_recovery_configuration_puts_the_locked_joint_where_it_locked() -> None:
    robot = robots.load("panda", task_space="position")
    target = np.array([0.5, 0.1, 0.4])
    manifold = selfmotion.trace(robot, target)
    lower, upper = manifold.box
    rng = np.random.default_rng(4)
    for _ in range(20):
        joint = int(rng.integers(robot.n))
        value = float(rng.uniform(lower[joint], upper[joint]))
        q = selfmotion.recovery_configuration(manifold, joint, value)
        assert q[joint] == value
        assert np.linalg.norm(robot.task_error(target, q)) < 1e-9
        assert robot.lower[joint] <= value <= robot.upper[joint]
    with pytest.raises(ValueError, match="outside"):
        selfmotion.recovery_configuration(manifold, 3, upper[3] + 0.2)


def test_unreachable_points_and_bad_targets_are_reported() -> None:
    with pytest.raises(UnreachableError, match="out of reach"):
        selfmotion.trace(PLANAR, np.array([3.5, 0.0]))
    with pytest.raises(UnreachableError, match="out of reach"):
        selfmotion.bounding_box(robots.load("panda", task_space="position"),
                                np.array([1.5, 0.0, 0.3]))
    with pytest.raises(ValueError, match="shape"):
        selfmotion.trace(PLANAR, np.array([1.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="non-finite"):
        selfmotion.trace(PLANAR, np.array([np.nan, 0.0]))
    with pytest.raises(UnreachableError, match="seed"):
        selfmotion.trace(PLANAR, np.array([1.0, 0.0]), np.array([0.0, 0.0, 0.0]))


def test_intersection_volume_and_reachability() -> None:
    robot = robots.load("panda", task_space="position")
    points = [np.array([0.5, 0.1, 0.4]), np.array([0.45, -0.15, 0.35])]
    boxes = [selfmotion.bounding_box(robot, p) for p in points]
    lower, upper = selfmotion.intersect(boxes)
    assert selfmotion.empty_joints((lower, upper)) == []
    assert 0 < selfmotion.box_volume(robot, lower, upper) <= min(
        selfmotion.box_volume(robot, *b) for b in boxes)
    found = selfmotion.reachability(robot, points, lower, upper)
    for q, p in zip(found, points, strict=True):
        assert q is not None
        assert np.all(q >= lower - 1e-12) and np.all(q <= upper + 1e-12)
        np.testing.assert_allclose(robot.forward(q), p, atol=1e-8)
    far = selfmotion.reachability(robot, [np.array([0.0, 0.0, 1.3])], lower, upper)
    assert far == [None]
    disjoint = selfmotion.intersect([(np.zeros(2), np.ones(2)), (np.full(2, 2.0), np.full(2, 3.0))])
    assert selfmotion.empty_joints(disjoint) == [0, 1]
    assert selfmotion.box_volume(robots.load("planar3r"), np.zeros(3), np.full(3, math.pi)) == (
        pytest.approx(1 / 8))


#: Lewis & Maciejewski 1997 Table II, point P1: (min, max) of joints 1-5 (rad) and volume (rad^5).
TABLE_II_P1 = [(-0.64, 0.27), (-0.98, 0.75), (0.06, 3.53), (-1.89, 2.94), (-1.72, 1.72)]
TABLE_II_P1_VOLUME = 91.0


def test_puma_first_task_point_compared_with_table_ii() -> None:
    """PUMA 560 at P1: 0.9 m from joint 1's axis, 0.5 m high (Lewis & Maciejewski 1997 sec. V).

    As in the paper, joint 6 is held (the tool point lies on its axis), leaving the
    2-D self-motion surface of joints 1-5, traced with the spiral. The paper does
    not give P1's azimuth: we put P1 at 90 degrees and compare joint 1 relative to
    it, from a seed facing the point (elbow up), as the paper's Fig. 9.

    Reported, not asserted exactly. Found: widths 0.88, 1.84, 3.08, 4.89, 3.22 rad
    and 79 rad^5, against 0.91, 1.73, 3.47, 4.83, 3.44 and 91 in Table II. Joint 1
    matches, joint 4 spans its limits in both; the gaps in joints 2, 3 and 5 and in
    the volume come from (i) the joint zero and sign conventions of the authors'
    PUMA model, which the DH table alone does not fix (our joint 2 range is shifted
    against theirs by about 0.4 rad), (ii) the garbled joint 2 lower limit
    (we use -5 pi/4, see docs/robots.md), and (iii) the spiral and the extremal polish
    being local estimates of the bounds, which the paper also notes.
    """
    xml = robots.builtin_urdf("puma560").replace('name="puma_joint6" type="revolute"',
                                                 'name="puma_joint6" type="fixed"')
    puma = robots.load(xml, task_space="position")
    azimuth = np.pi / 2
    target = np.array([0.9 * np.cos(azimuth), 0.9 * np.sin(azimuth), 0.5])
    seed = selfmotion.find_seed(puma, target, np.array([azimuth, -1.0, 2.0, 0.0, 0.5]))
    manifold = selfmotion.trace(puma, target, seed)
    assert manifold.method == "spiral"
    lower, upper = manifold.box
    lower[0] -= azimuth
    upper[0] -= azimuth
    volume = selfmotion.box_volume(puma, lower, upper, normalized=False)
    print("\njoint   ours (min, max)     Table II (min, max)")
    for joint, (low, high) in enumerate(TABLE_II_P1):
        print(f"  {joint + 1}   ({lower[joint]:6.2f}, {upper[joint]:5.2f})"
              f"    ({low:6.2f}, {high:5.2f})")
    print(f"volume  {volume:.1f} rad^5          {TABLE_II_P1_VOLUME:.1f} rad^5")
    widths = upper - lower
    paper = np.array([high - low for low, high in TABLE_II_P1])
    assert widths[0] == pytest.approx(paper[0], abs=0.1)
    assert widths[3] == pytest.approx(paper[3], abs=0.1)
    assert 0.6 * TABLE_II_P1_VOLUME < volume < 1.4 * TABLE_II_P1_VOLUME
