"""ft_core.robots: loading, chain selection, kinematics checked against independent formulas."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from ft_core import robots
from ft_core.robots import RobotModelError
from paths import PANDA_URDF

EPS = 1e-6
RNG_SEED = 7


def dh_standard(rows: list[tuple[float, float, float]], q: np.ndarray) -> np.ndarray:
    """Tool transform from a standard DH table (a, d, alpha): prod Rz(q) Tz(d) Tx(a) Rx(alpha)."""
    T = np.eye(4)
    for (a, d, alpha), theta in zip(rows, q, strict=True):
        ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
        T = T @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                          [0, sa, ca, d], [0, 0, 0, 1]])
    return T


def dh_modified(rows: list[tuple[float, float, float]], q: np.ndarray) -> np.ndarray:
    """Craig's modified DH (a_{i-1}, d_i, alpha_{i-1}): prod Rx(alpha) Tx(a) Rz(q) Tz(d)."""
    T = np.eye(4)
    for (a, d, alpha), theta in zip(rows, q, strict=True):
        ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
        T = T @ np.array([[ct, -st, 0, a], [st * ca, ct * ca, -sa, -d * sa],
                          [st * sa, ct * sa, ca, d * ca], [0, 0, 0, 1]])
    return T


def numeric_jacobian(robot: robots.Robot, q: np.ndarray) -> np.ndarray:
    """Central differences of the tool transform: linear rows, then angular rows (log map)."""
    columns = []
    for e in np.eye(robot.n):
        plus, minus = robot.transform(q + EPS * e), robot.transform(q - EPS * e)
        linear = (plus[:3, 3] - minus[:3, 3]) / (2 * EPS)
        angular = pin.log3(plus[:3, :3] @ minus[:3, :3].T) / (2 * EPS)
        columns.append(np.concatenate([linear, angular]))
    full = np.array(columns).T
    return full[: {"pose": 6, "position": 3, "planar": 2}[robot.task_space]]


MODELS = [
    ("planar3r", {}),
    ("puma560", {}),
    ("puma560", {"task_space": "pose"}),
    ("panda", {}),
    ("panda", {"task_space": "position"}),
    ("iiwa14", {}),
    (str(PANDA_URDF), {}),
    (str(PANDA_URDF), {"base_link": "panda_link2", "tip_link": "panda_hand_tcp"}),
]


@pytest.mark.parametrize(("spec", "kwargs"), MODELS)
def test_jacobian_matches_finite_differences(spec: str, kwargs: dict) -> None:
    robot = robots.load(spec, **kwargs)
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(3):
        q = robot.random_configuration(rng)
        J = robot.jacobian(q)
        assert J.shape == (robot.m, robot.n)
        np.testing.assert_allclose(J, numeric_jacobian(robot, q), atol=1e-7)


@pytest.mark.parametrize(("spec", "kwargs"), MODELS)
def test_jacobian_derivatives_match_finite_differences(spec: str, kwargs: dict) -> None:
    robot = robots.load(spec, **kwargs)
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(3):
        q = robot.random_configuration(rng)
        dJ = robot.jacobian_derivatives(q)
        numeric = np.stack([(robot.jacobian(q + EPS * e) - robot.jacobian(q - EPS * e)) / (2 * EPS)
                            for e in np.eye(robot.n)])
        assert dJ.shape == (robot.n, robot.m, robot.n)
        np.testing.assert_allclose(dJ, numeric, atol=1e-7)


def test_planar3r_is_the_unit_link_arm() -> None:
    robot = robots.load("planar3r")
    assert (robot.n, robot.m, robot.task_space) == (3, 2, "planar")
    q = np.array([0.3, -1.1, 2.0])
    angles = np.cumsum(q)
    np.testing.assert_allclose(robot.forward(q), [np.cos(angles).sum(), np.sin(angles).sum()],
                               atol=1e-12)
    assert np.all(np.isinf(robot.lower)) and np.all(np.isinf(robot.upper))  # continuous
    assert robot.reach == pytest.approx(3.0)


def test_puma560_follows_table_i_of_lewis_and_maciejewski() -> None:
    robot = robots.load("puma560")
    rows = [(0.0, 0.0, -np.pi / 2), (0.432, 0.149, 0.0), (0.0, 0.0, np.pi / 2),
            (0.0, 0.433, -np.pi / 2), (0.0, 0.0, np.pi / 2), (0.0, 0.392, 0.0)]
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(5):
        q = robot.random_configuration(rng)
        np.testing.assert_allclose(robot.transform(q), dh_standard(rows, q), atol=1e-12)
        # The tool point lies on the sixth joint's axis: joint 6 cannot move it.
        np.testing.assert_allclose(robot.jacobian(q)[:, 5], 0.0, atol=1e-12)
    np.testing.assert_allclose(robot.lower, [-2.79, -5 * np.pi / 4, -np.pi / 4, -1.92, -1.745,
                                             -4.625])
    np.testing.assert_allclose(robot.upper, [2.79, np.pi / 4, 5 * np.pi / 4, 2.967, 1.745, 4.625])


def test_panda_follows_franka_published_kinematics() -> None:
    robot = robots.load("panda", tip_link="panda_link8")
    rows = [(0, 0.333, 0), (0, 0, -np.pi / 2), (0, 0.316, np.pi / 2), (0.0825, 0, np.pi / 2),
            (-0.0825, 0.384, -np.pi / 2), (0, 0, np.pi / 2), (0.088, 0, np.pi / 2)]
    flange = np.eye(4)
    flange[2, 3] = 0.107
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(5):
        q = robot.random_configuration(rng)
        np.testing.assert_allclose(robot.transform(q), dh_modified(rows, q) @ flange, atol=1e-12)
    np.testing.assert_allclose(robot.velocity_limits, [2.175] * 4 + [2.61] * 3)
    np.testing.assert_allclose(robot.upper[3], -0.0698)


def test_iiwa14_is_a_second_seven_dof_arm() -> None:
    robot = robots.load("iiwa14")
    assert (robot.n, robot.m) == (7, 6)
    straight_up = robot.forward(np.zeros(7))
    np.testing.assert_allclose(straight_up[:3, 3], [0, 0, 0.36 + 0.42 + 0.4 + 0.126], atol=1e-12)


def test_real_world_panda_urdf_agrees_with_the_builtin() -> None:
    user = robots.load(str(PANDA_URDF))
    builtin = robots.load("panda")
    # Fingers (prismatic) and fixed joints are not part of the arm chain.
    assert user.joint_names == builtin.joint_names == tuple(f"panda_joint{i}" for i in range(1, 8))
    assert user.tip_link == "panda_hand"  # the tree branches into the fingers there
    np.testing.assert_allclose(user.lower, builtin.lower)
    np.testing.assert_allclose(user.upper, builtin.upper)
    np.testing.assert_allclose(user.velocity_limits, builtin.velocity_limits)
    tcp_user = robots.load(PANDA_URDF.read_text(), tip_link="panda_hand_tcp")
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(5):
        q = builtin.random_configuration(rng)
        np.testing.assert_allclose(tcp_user.transform(q), builtin.transform(q), atol=1e-12)
        np.testing.assert_allclose(tcp_user.jacobian(q), builtin.jacobian(q), atol=1e-12)


def test_base_link_below_the_root_expresses_the_task_in_that_frame() -> None:
    full = robots.load("panda", task_space="position")
    sub = robots.load("panda", base_link="panda_link3", task_space="position")
    assert sub.joint_names == tuple(f"panda_joint{i}" for i in range(4, 8))
    # Joints above the base stay at their neutral value 0.
    q = np.array([0.0, 0.0, 0.0, -1.5, 0.4, 1.2, 0.3])
    base_pose = robots.load("panda", tip_link="panda_link3").transform(np.zeros(3))
    expected = np.linalg.solve(base_pose, np.append(full.forward(q), 1.0))[:3]
    np.testing.assert_allclose(sub.forward(q[3:]), expected, atol=1e-12)


def test_characteristic_length_scales_angular_rows_only() -> None:
    robot = robots.load("panda")
    assert robot.characteristic_length == pytest.approx(robot.reach)
    assert 1.0 < robot.reach < 1.2
    J = robot.jacobian(np.full(7, 0.2) - np.array([0, 0, 0, 2.0, 0, -1.0, 0]))
    scaled = robot.scale_task(J)
    np.testing.assert_allclose(scaled[:3], J[:3])
    np.testing.assert_allclose(scaled[3:], robot.reach * J[3:])
    custom = robots.load("panda", characteristic_length=0.5)
    np.testing.assert_allclose(custom.scale_task(J)[3:], 0.5 * J[3:])
    planar = robots.load("planar3r")
    np.testing.assert_allclose(planar.scale_task(np.ones((2, 3))), 1.0)


def test_continuous_joints_have_infinite_limits() -> None:
    xml = """<robot name="wheel"><link name="a"/><link name="b"/><link name="c"/>
      <joint name="spin" type="continuous"><parent link="a"/><child link="b"/>
        <axis xyz="0 0 1"/><limit effort="1" velocity="3"/></joint>
      <joint name="arm" type="revolute"><parent link="b"/><child link="c"/>
        <origin xyz="1 0 0"/><axis xyz="0 0 1"/>
        <limit lower="-1" upper="1" effort="1" velocity="2"/>
      </joint></robot>"""
    robot = robots.load(xml, task_space="planar")
    assert robot.joint_names == ("spin", "arm")
    assert np.isinf(robot.lower[0]) and np.isinf(robot.upper[0])
    np.testing.assert_allclose(robot.velocity_limits, [3.0, 2.0])
    np.testing.assert_allclose(robot.forward(np.array([np.pi / 2, 0.0])), [0.0, 1.0], atol=1e-12)


@pytest.mark.parametrize(("spec", "kwargs", "message"), [
    ("no_such_robot", {}, "unknown robot model"),
    ("<robot name='x'><link name='a'></robot>", {}, "does not parse"),
    ("<model/>", {}, "expected <robot>"),
    ("panda", {"tip_link": "panda_link99"}, "panda_link99"),
    ("panda", {"base_link": "nowhere"}, "nowhere"),
    ("panda", {"base_link": "panda_link5", "tip_link": "panda_link2"}, "not below"),
    ("panda", {"base_link": "panda_link8", "tip_link": "panda_hand_tcp"}, "no movable joint"),
    ("panda", {"task_space": "joint"}, "task_space"),
    ("panda", {"characteristic_length": -1.0}, "characteristic_length"),
    ("", {}, "empty"),
])
def test_bad_models_raise_a_clear_error(spec: str, kwargs: dict, message: str) -> None:
    with pytest.raises(RobotModelError, match=message):
        robots.load(spec, **kwargs)


def test_bad_configurations_raise_before_any_arithmetic() -> None:
    robot = robots.load("planar3r")
    with pytest.raises(ValueError, match="shape"):
        robot.jacobian(np.zeros(4))
    with pytest.raises(ValueError, match="non-finite"):
        robot.forward(np.array([0.0, np.nan, 0.0]))


def _urdf(joints: list[tuple[str, str, str, str]]) -> str:
    """A URDF from (name, type, parent, child) joints, links along z, axes about z."""
    links = {link for _, _, parent, child in joints for link in (parent, child)}
    parts = ['<robot name="t">', *(f'<link name="{link}"/>' for link in sorted(links))]
    for name, kind, parent, child in joints:
        limit = ('<limit lower="-2" upper="2" velocity="1" effort="1"/>'
                 if kind in ("revolute", "prismatic") else "")
        parts.append(f'<joint name="{name}" type="{kind}"><parent link="{parent}"/>'
                     f'<child link="{child}"/><origin xyz="0.1 0 0.2"/><axis xyz="0 1 0"/>'
                     f'{limit}</joint>')
    return "".join([*parts, "</robot>"])


def test_default_chain_passes_fixed_side_branches_like_ur_urdfs() -> None:
    """Issue 14: UR URDFs failed: "the chain from 'world' to 'base_link' has no movable joint".

    Their base_link also carries a fixed `base` frame. The joint named like its child
    link (`flange`) is Unitree Z1's pattern, which made Pinocchio raise ValueError.
    """
    arm = [(f"j{i}", "revolute", f"l{i - 1}" if i > 1 else "base_link_inertia", f"l{i}")
           for i in range(1, 7)]
    urdf = _urdf([("world_joint", "fixed", "world", "base_link"),
                  ("base_fixed", "fixed", "base_link", "base"),
                  ("inertia", "fixed", "base_link", "base_link_inertia"), *arm,
                  ("flange", "fixed", "l6", "flange"), ("tool", "fixed", "flange", "tool0")])
    robot = robots.load(urdf)
    assert robot.joint_names == tuple(f"j{i}" for i in range(1, 7))
    assert robot.tip_link == "tool0"


def test_a_tree_that_branches_before_the_arm_names_the_branch_and_candidate_tips() -> None:
    urdf = _urdf([("wheel_left", "revolute", "base_footprint", "wheel_l"),
                  ("wheel_right", "revolute", "base_footprint", "wheel_r"),
                  ("torso", "prismatic", "base_footprint", "torso_link"),
                  ("a1", "revolute", "torso_link", "arm1"), ("a2", "revolute", "arm1", "hand")])
    with pytest.raises(robots.RobotModelError, match="branches at 'base_footprint'") as error:
        robots.load(urdf)
    assert "candidate tip links: ['hand', 'wheel_l', 'wheel_r']" in str(error.value)
    assert robots.load(urdf, tip_link="hand").joint_names == ("torso", "a1", "a2")


def test_hostile_model_strings_are_refused_quickly() -> None:
    """Issue 14: a long non-XML string was taken as a path; entity bombs must not expand."""
    import time

    laughs = ('<?xml version="1.0"?><!DOCTYPE r [<!ENTITY a "aaaaaaaaaa">'
              + "".join(f'<!ENTITY {chr(98 + i)} "{("&" + chr(97 + i) + ";") * 10}">'
                        for i in range(9))
              + ']><robot name="&j;"><link name="l"/></robot>')
    for spec in ("x" * 300, "a\0b", laughs, "<robot>" * 10, " " * 20_000_000):
        start = time.perf_counter()
        with pytest.raises(robots.RobotModelError):
            robots.load(spec)
        assert time.perf_counter() - start < 2.0


def test_cyclic_deep_and_huge_joint_trees_are_refused_or_walked_without_recursion() -> None:
    """Issue 31 item 9: URDF trees are checked and walked iteratively.

    A cycle made the tip search loop forever (deaf to SIGINT), and the subtree walk
    recursed without bound.
    """
    import threading

    arm = [(f"j{i}", "revolute", f"l{i}", f"l{i + 1}") for i in range(3)]
    cycles = [_urdf([*arm, ("back", "fixed", "l3", "l1")]),  # l1's parent was l0: two
              _urdf([("a", "revolute", "x", "y"), ("b", "revolute", "y", "x"),
                     *arm]),  # a loop, taken as the base: the old walk never ended
              _urdf([("self", "revolute", "l", "l")])]
    deep = _urdf([*arm, *((f"f{i}", "fixed", f"l{i}", f"l{i + 1}") for i in range(3, 1500))])
    huge = _urdf([(f"f{i}", "fixed", f"m{i}", f"m{i + 1}") for i in range(2500)])
    outcomes: list[str] = []

    def work() -> None:
        for urdf in [*cycles, huge]:
            try:
                robots.load(urdf, base_link="x" if urdf is cycles[1] else None)
                outcomes.append("loaded")
            except robots.RobotModelError as error:
                outcomes.append(str(error))
        outcomes.append(robots.load(deep).tip_link)

    worker = threading.Thread(target=work, daemon=True)
    worker.start()
    worker.join(timeout=60)
    assert not worker.is_alive(), f"a URDF walk did not end: {outcomes}"
    assert "two parent joints" in outcomes[0]
    assert all("form a cycle" in text for text in outcomes[1:3]), outcomes
    assert "2500 joints (at most 2000)" in outcomes[3]
    assert outcomes[4] == "l1500"  # the fixed tool chain followed to its end, 1500 deep


def test_a_lone_gripper_joint_after_the_arm_is_not_taken_into_the_chain() -> None:
    """Issue 14: Unitree Z1's `jointGripper` (one revolute finger) joined the arm chain."""
    arm = [(f"joint{i}", "revolute", f"link0{i - 1}", f"link0{i}") for i in range(1, 7)]
    urdf = _urdf([*arm, ("jointGripper", "revolute", "link06", "gripperMover"),
                  ("tip", "fixed", "gripperMover", "gripperTip")])
    robot = robots.load(urdf)
    assert robot.joint_names == tuple(f"joint{i}" for i in range(1, 7))
    assert robot.tip_link == "link06"
    with_gripper = robots.load(urdf, tip_link="gripperTip")
    assert with_gripper.joint_names[-1] == "jointGripper"



def test_derivatives_of_a_chain_with_prismatic_joints_and_turned_frames() -> None:
    """The cross-product Hessian (`task_jacobians`) holds for prismatic joints too."""
    kinds = [("revolute", "0 0 1", "0.2 0.1 0.3"), ("prismatic", "1 0 0", "0.3 0 0"),
             ("revolute", "0 1 0", "0 0.4 0"), ("prismatic", "0 0.6 0.8", "0.1 0.2 0.3"),
             ("revolute", "1 0 0", "0 0 0.5"), ("revolute", "0 0 1", "0.2 0 0")]
    parts = ['<robot name="mixed">', *(f'<link name="l{i}"/>' for i in range(len(kinds) + 1))]
    for i, (kind, axis, rpy) in enumerate(kinds):
        parts.append(f'<joint name="j{i}" type="{kind}"><parent link="l{i}"/>'
                     f'<child link="l{i + 1}"/><origin xyz="0.1 0.05 0.2" rpy="{rpy}"/>'
                     f'<axis xyz="{axis}"/><limit lower="-1" upper="1" velocity="1" '
                     'effort="1"/></joint>')
    urdf = "".join([*parts, "</robot>"])
    for task in ("pose", "position"):
        robot = robots.load(urdf, base_link="l1", task_space=task)  # a turned base
        assert robot.n == 5 and not robot._base_aligned
        rng = np.random.default_rng(RNG_SEED)
        q = robot.random_configuration(rng)
        numeric = np.stack([(robot.jacobian(q + EPS * e) - robot.jacobian(q - EPS * e))
                            / (2 * EPS) for e in np.eye(robot.n)])
        J, dJ = robot.jacobian_and_derivatives(q)
        np.testing.assert_allclose(J, robot.jacobian(q), atol=1e-12)
        assert np.abs(dJ).max() > 0.1
        np.testing.assert_allclose(dJ, numeric, atol=1e-7)


def test_one_kinematics_snapshot_gives_what_the_separate_calls_give() -> None:
    """`Robot.kinematics` (one Pinocchio pass a cycle, issue 28) against the separate calls.

    On the Panda and on a sub-chain whose base is turned (the rotated-axes path).
    """
    rng = np.random.default_rng(RNG_SEED)
    for robot in (robots.load("panda"),
                  robots.load("panda", base_link="panda_link3", task_space="position")):
        for _ in range(5):
            q = robot.random_configuration(rng)
            snapshot = robot.kinematics(q)
            np.testing.assert_allclose(snapshot.transform, robot.transform(q), atol=1e-14)
            np.testing.assert_allclose(snapshot.base_jacobian, robot.base_jacobian(q),
                                       atol=1e-14)
            # Every consumer takes the snapshot in place of q (the same to rounding: other
            # Pinocchio algorithms).
            np.testing.assert_allclose(robot.jacobian(snapshot), robot.jacobian(q), atol=1e-14)
            np.testing.assert_allclose(robot.forward(snapshot), robot.forward(q), atol=1e-14)
            goal = robot.forward(robot.random_configuration(rng))
            np.testing.assert_allclose(robot.task_error(goal, snapshot),
                                       robot.task_error(goal, q), atol=1e-12)


def test_gravity_alone_is_the_gravity_of_the_dynamics() -> None:
    """`Robot.gravity` (the monitor's every-cycle call) against `Robot.gravity_dynamics`.

    And against statics: on the Panda at home, g(q) is the torque that holds the links
    up, so joint 1 (a vertical axis) carries none and joint 2 (horizontal) a real one.
    """
    robot = robots.load("panda_inertial", tip_link="panda_link8")
    rng = np.random.default_rng(RNG_SEED)
    for q in [robot.home()] + [robot.random_configuration(rng) for _ in range(5)]:
        np.testing.assert_allclose(robot.gravity(q), robot.gravity_dynamics(q)[0], atol=1e-12)
    g = robot.gravity(robot.home())
    assert abs(g[0]) < 1e-9 and abs(g[1]) > 1.0, g


def test_the_dynamics_are_pinocchios_inverse_dynamics() -> None:
    """M(q) qdd + C(q, qd) qd + g(q) is RNEA's torque; M is symmetric, its diagonal CRBA's."""
    robot = robots.load("panda_inertial", tip_link="panda_link8")
    rng = np.random.default_rng(RNG_SEED)
    model = pin.buildModelFromXML(robot.urdf)  # the fingers too, held at 0 here
    data, extra = model.createData(), np.zeros(model.nq - robot.n)
    for _ in range(5):
        q = robot.random_configuration(rng)
        qd, qdd = rng.uniform(-1.0, 1.0, robot.n), rng.uniform(-5.0, 5.0, robot.n)
        inertia, nonlinear = robot.dynamics(q, qd)
        np.testing.assert_allclose(inertia, inertia.T, atol=1e-12)
        np.testing.assert_allclose(np.diag(inertia), robot.gravity_dynamics(q)[1], atol=1e-12)
        torque = pin.rnea(model, data, np.append(q, extra), np.append(qd, extra),
                          np.append(qdd, extra))[:robot.n]
        assert np.abs(torque).max() > 1.0  # the check has something to check
        np.testing.assert_allclose(inertia @ qdd + nonlinear, torque, atol=1e-9)
