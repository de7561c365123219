"""Robot models: a serial chain of a URDF, its forward kinematics and task Jacobians.

`load` accepts a built-in name, a URDF file path or URDF XML and returns a
`Robot` for the chain from `base_link` to `tip_link`. All kinematics goes through
Pinocchio; the rest of the URDF (gripper fingers, other branches, joints above
`base_link`) is locked at its neutral value with `pinocchio.buildReducedModel`.

Conventions (docs/robots.md):

- Joint vectors are in chain order, base to tip. Revolute joints in rad,
  prismatic in m.
- Task coordinates are expressed in the `base_link` frame at the tool point
  (the origin of `tip_link`): `pose` rows are linear velocity (m/s) then angular
  velocity (rad/s); `position` keeps the three linear rows; `planar` keeps x and y.
- `jacobian_derivatives(q)[k]` is dJ/dq_k (same rows and columns as `jacobian`).
- Before singular values of a pose Jacobian are compared, its angular rows are
  multiplied by a characteristic length L (m): `Robot.scale_task` is the one
  place that does it (Lewis & Maciejewski 1997 eq 5 remark; Xie 2019 normalises by the reach).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from importlib import resources
from itertools import pairwise
from pathlib import Path

import numpy as np
import pinocchio as pin
from numba import njit

from ft_core.input_checks import all_finite

#: Task-space name -> number of task coordinates m.
TASK_DIMENSIONS = {"pose": 6, "position": 3, "planar": 2}

#: Built-in models: URDF resource in ft_core/urdf and the default task space. All but
#: two are kinematic (no inertias). "planar3r_rods" is "planar3r" with a uniform 1 kg
#: rod for each link (the free-swinging example of Maciejewski et al. sec. 3.3).
#: "panda_inertial" is the Franka Emika Panda as the `example-robot-data` package
#: distributes it (URDF under Apache-2.0 from Franka Emika GmbH, unchanged): with
#: inertias (what the physics plant, `ft_core.physics`, needs), gripper finger joints,
#: fixed joints and `package://` mesh URIs, i.e. what a user's `robot_description`
#: looks like; its kinematics agree with "panda"'s.
BUILTINS = {
    "planar3r": ("planar3r.urdf", "planar"),
    "planar3r_rods": ("planar3r_rods.urdf", "planar"),
    "puma560": ("puma560.urdf", "position"),
    "panda": ("panda.urdf", "pose"),
    "panda_inertial": ("panda_from_example_robot_data.urdf", "pose"),
    "iiwa14": ("iiwa14.urdf", "pose"),
}

#: A typical working configuration of each built-in (rad), by URDF robot name, so a
#: user's Panda URDF gets the Panda's.
HOME = {
    "planar3r": (0.3, 1.2, 1.0),
    "planar3r_rods": (0.3, 1.2, 1.0),
    "puma560": (0.2, -0.8, 1.6, 0.3, 0.6, 0.0),
    "panda": (0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4),
    "iiwa14": (0.0, 0.6, 0.0, -1.2, 0.0, 0.8, 0.0),
}

_MOVABLE = {"revolute", "continuous", "prismatic"}
_SUPPORTED = _MOVABLE | {"fixed"}


@njit(cache=True, error_model="numpy")
def task_jacobians(J: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Task rows of a chain's Jacobian and of its derivatives: (m, n) and dJ/dq_k (n, m, n).

    J (6, n) is the tool point's Jacobian, linear rows v above angular rows w, every
    column in the same axes. For a serial chain the kinematic Hessian follows from
    the columns alone (the identity Pinocchio's kinematic Hessians compute):
        k <= j: dJ_j/dq_k = (w_k x v_j, w_k x w_j),   k > j: dJ_j/dq_k = (w_j x v_k, 0).
    A prismatic joint has w = 0, which makes its terms vanish. O(n^2); compiled
    (numba), 1 us at 7 joints and 15 at 48, against 60 for Pinocchio's Hessian and its
    copy at 48.
    """
    n = J.shape[1]
    dJ = np.zeros((n, 6, n))
    for k in range(n):
        wx, wy, wz = J[3, k], J[4, k], J[5, k]
        for j in range(n):
            if k <= j:  # joint k turns column j: w_k x (v_j, w_j)
                vx, vy, vz = J[0, j], J[1, j], J[2, j]
                dJ[k, 0, j] = wy * vz - wz * vy
                dJ[k, 1, j] = wz * vx - wx * vz
                dJ[k, 2, j] = wx * vy - wy * vx
                ax, ay, az = J[3, j], J[4, j], J[5, j]
                dJ[k, 3, j] = wy * az - wz * ay
                dJ[k, 4, j] = wz * ax - wx * az
                dJ[k, 5, j] = wx * ay - wy * ax
            else:  # joint k moves the tool point along v_k: w_j x v_k
                ax, ay, az = J[3, j], J[4, j], J[5, j]
                vx, vy, vz = J[0, k], J[1, k], J[2, k]
                dJ[k, 0, j] = ay * vz - az * vy
                dJ[k, 1, j] = az * vx - ax * vz
                dJ[k, 2, j] = ax * vy - ay * vx
    return np.ascontiguousarray(J[:m]), np.ascontiguousarray(dJ[:, :m, :])


@dataclass(frozen=True)
class Kinematics:
    """The tool's kinematics at one configuration (`Robot.kinematics`), computed once.

    Attributes:
        q: the configuration (rad).
        transform: 4x4 transform of the tool link in the base link.
        base_jacobian: the tool point's 6 x n Jacobian in the base's axes, linear rows
            first (`Robot.base_jacobian`).
    """

    q: np.ndarray
    transform: np.ndarray
    base_jacobian: np.ndarray


def configuration(at: np.ndarray | Kinematics) -> np.ndarray:
    """The joint positions (rad) of a configuration or of its kinematics snapshot."""
    return at.q if isinstance(at, Kinematics) else np.asarray(at, dtype=float)


class RobotModelError(ValueError):
    """A robot model could not be built; the message names the problem."""


@dataclass(frozen=True)
class _UrdfJoint:
    name: str
    kind: str
    parent: str
    child: str


def builtin_urdf(name: str) -> str:
    """Return the URDF XML of a built-in model (`BUILTINS`)."""
    return resources.files("ft_core").joinpath("urdf").joinpath(BUILTINS[name][0]).read_text()


#: Largest URDF accepted (bytes): real arms' URDFs are tens of kilobytes.
MAX_URDF_BYTES = 10_000_000
#: Most joints a URDF may declare (the tree walks are quadratic in them at worst).
MAX_URDF_JOINTS = 2000


def _resolve(spec: str) -> tuple[str, str | None]:
    """Turn a model spec into (URDF XML, default task space of a built-in or None)."""
    if not isinstance(spec, str) or not spec.strip():
        raise RobotModelError("robot model spec is empty: give a built-in name, a URDF path or XML")
    if spec in BUILTINS:
        return builtin_urdf(spec), BUILTINS[spec][1]
    if len(spec) > MAX_URDF_BYTES:
        raise RobotModelError(f"robot model spec of {len(spec)} characters is larger than "
                              f"{MAX_URDF_BYTES}")
    if spec.lstrip().startswith("<"):
        return spec, None
    try:  # a long or odd string is not a path: OSError (name too long), ValueError (NUL)
        path = Path(spec).expanduser()
        if path.is_file():
            if path.stat().st_size > MAX_URDF_BYTES:
                raise RobotModelError(f"URDF file {path} is larger than {MAX_URDF_BYTES} bytes")
            return path.read_text(), None
    except (OSError, ValueError):
        pass
    raise RobotModelError(
        f"unknown robot model {spec[:80]!r}: not a built-in ({', '.join(sorted(BUILTINS))}), "
        "not an existing file and not URDF XML"
    )


def _parse_tree(xml: str) -> tuple[ET.Element, dict[str, _UrdfJoint], set[str]]:
    """Parse URDF XML into (root element, joints by child link, link names)."""
    try:
        root = ET.fromstring(xml)
    except ET.ParseError as exc:
        raise RobotModelError(f"URDF does not parse: {exc}") from exc
    if root.tag != "robot":
        raise RobotModelError(f"URDF root element is <{root.tag}>, expected <robot>")
    links = {link.get("name", "") for link in root.findall("link")}
    by_child: dict[str, _UrdfJoint] = {}
    elements = root.findall("joint")
    if len(elements) > MAX_URDF_JOINTS:
        raise RobotModelError(f"URDF declares {len(elements)} joints (at most "
                              f"{MAX_URDF_JOINTS})")
    for element in elements:
        parent, child = element.find("parent"), element.find("child")
        if parent is None or child is None:
            raise RobotModelError(f"URDF joint {element.get('name')!r} lacks <parent> or <child>")
        joint = _UrdfJoint(element.get("name", ""), element.get("type", ""),
                           parent.get("link", ""), child.get("link", ""))
        if joint.child in by_child:
            raise RobotModelError(f"URDF link {joint.child!r} has two parent joints")
        by_child[joint.child] = joint
    if not links:
        raise RobotModelError("URDF has no links")
    _check_acyclic(by_child)
    return root, by_child, links


def _check_acyclic(by_child: dict[str, _UrdfJoint]) -> None:
    """Raise RobotModelError if the joints form a cycle (the tree walks would not end).

    Each link has one parent at most, so a cycle is a walk up the parents that comes
    back to a link of the same walk. Every link is walked once: linear in the joints.
    """
    done: set[str] = set()
    for start in by_child:
        walk: list[str] = []
        seen: set[str] = set()
        link = start
        while link in by_child and link not in done:
            if link in seen:
                cycle = walk[walk.index(link):]
                raise RobotModelError(f"URDF joints form a cycle through links "
                                      f"{[name[:64] for name in cycle[:6]]}"
                                      f"{' ...' if len(cycle) > 6 else ''}")
            seen.add(link)
            walk.append(link)
            link = by_child[link].parent
        done.update(walk)


def _children(by_child: dict[str, _UrdfJoint]) -> dict[str, list[_UrdfJoint]]:
    """Joints below each link."""
    children: dict[str, list[_UrdfJoint]] = {}
    for joint in by_child.values():
        children.setdefault(joint.parent, []).append(joint)
    return children


def _below(link: str, children: dict[str, list[_UrdfJoint]]) -> list[_UrdfJoint]:
    """Every joint of the subtree below `link`, without recursion (a URDF may be deep)."""
    found, stack = [], list(children.get(link, []))
    while stack:
        joint = stack.pop()
        found.append(joint)
        stack.extend(children.get(joint.child, []))
    return found


def _moving_subtrees(link: str, children: dict[str, list[_UrdfJoint]]) -> list[_UrdfJoint]:
    """The joints below `link` whose subtree holds at least one movable joint."""
    return [j for j in children.get(link, []) if j.kind in _MOVABLE
            or any(k.kind in _MOVABLE for k in _below(j.child, children))]


def _leaves(link: str, children: dict[str, list[_UrdfJoint]]) -> list[str]:
    """The links without children below `link` (candidate tool links)."""
    leaves = [j.child for j in _below(link, children) if j.child not in children]
    return leaves or [link]


def _is_gripper(joint: _UrdfJoint) -> bool:
    """A movable joint named as a gripper's or a finger's (Unitree Z1's `jointGripper`)."""
    return joint.kind in _MOVABLE and any(word in joint.name.lower()
                                          for word in ("gripper", "finger"))


def _default_tip(base: str, by_child: dict[str, _UrdfJoint]) -> str:
    """Walk down from `base` along the only subtree that moves; return where that ends.

    Branches with fixed joints only (sensor frames, UR's `base` frame) are passed
    by; past the last movable joint a lone chain of fixed joints (the tool frame) is
    followed to its end. A lone movable joint named like a gripper's or a finger's
    after the arm (Unitree Z1's `jointGripper`) ends the arm: it is not a joint of
    the task (give `tip_link` to include it). A two-finger gripper makes the tree
    branch into moving subtrees at the hand, so the default tip of a Panda with
    fingers is `panda_hand`, the link that carries them.
    Raises RobotModelError, naming the branch and candidate tips, when the tree
    branches into moving subtrees before any movable joint (a mobile base, two arms).
    """
    children = _children(by_child)
    tip, moved = base, False
    while True:
        moving = _moving_subtrees(tip, children)
        below = children.get(tip, [])
        if len(moving) == 1 and not (moved and _is_gripper(moving[0])):
            step = moving[0]
        elif not moving and len(below) == 1:  # a fixed tool frame past the last joint
            step = below[0]
        else:
            break
        moved = moved or step.kind in _MOVABLE
        tip = step.child
    if len(moving) > 1 and not moved:
        candidates = sorted({leaf for j in moving for leaf in _leaves(j.child, children)})
        raise RobotModelError(
            f"the URDF tree branches at {tip!r} into {len(moving)} moving subtrees "
            f"({', '.join(j.child for j in moving)}) before any movable joint: set tip_link "
            f"(and base_link if needed) to choose the arm; candidate tip links: "
            f"{candidates[:12]}{' ...' if len(candidates) > 12 else ''}")
    return tip


def _chain(base: str, tip: str, by_child: dict[str, _UrdfJoint]) -> list[_UrdfJoint]:
    """Joints on the path from `base` down to `tip`, base first (fixed ones included)."""
    path, link = [], tip
    while link != base:
        if link not in by_child:
            raise RobotModelError(f"tip_link {tip!r} is not below base_link {base!r} in the URDF")
        joint = by_child[link]
        path.append(joint)
        link = joint.parent
    return path[::-1]


def _limits(root: ET.Element, names: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position (lower, upper) and velocity limits of the named joints, from <limit>.

    Continuous joints have infinite position limits; a missing velocity limit is
    infinite (no limit).
    """
    elements = {j.get("name"): j for j in root.findall("joint")}
    lower, upper, velocity = [], [], []
    for name in names:
        joint = elements[name]
        limit = joint.find("limit")
        if joint.get("type") == "continuous":
            lo, hi = -math.inf, math.inf
        elif limit is None or limit.get("lower") is None or limit.get("upper") is None:
            raise RobotModelError(f"URDF joint {name!r} has no position <limit>")
        else:
            lo, hi = float(limit.get("lower", "")), float(limit.get("upper", ""))
        vel = float(limit.get("velocity", "0") or 0.0) if limit is not None else 0.0
        if not lo <= hi:
            raise RobotModelError(f"URDF joint {name!r} has lower limit {lo} above upper {hi}")
        lower.append(lo)
        upper.append(hi)
        velocity.append(vel if vel > 0 else math.inf)
    return np.array(lower), np.array(upper), np.array(velocity)


def _as_revolute(root: ET.Element, names: list[str]) -> str:
    """Rewrite the named continuous joints as revolute ones, so that q has one entry each.

    Joints off the chain named like a link are renamed (see below).

    Pinocchio models a continuous joint by (cos, sin); the suite works with angles.
    The wide placeholder limits written here are never used: `_limits` reports them
    as infinite.
    """
    links = {link.get("name", "") for link in root.findall("link")}
    for joint in root.findall("joint"):
        if joint.get("name") in links and joint.get("name") not in names:
            # A joint named like a link (Unitree Z1) makes Pinocchio's frame lookups by
            # name ambiguous; joints off the chain are never referred to by name.
            joint.set("name", f"{joint.get('name')}__joint")
        if joint.get("name") in names and joint.get("type") == "continuous":
            joint.set("type", "revolute")
            limit = joint.find("limit")
            if limit is None:
                limit = ET.SubElement(joint, "limit", effort="0", velocity="0")
            limit.set("lower", "-1e9")
            limit.set("upper", "1e9")
    return ET.tostring(root, encoding="unicode")


class Robot:
    """Kinematics of one serial chain for one task space.

    Attributes:
        name: the URDF robot name.
        joint_names: movable joints from base to tip (the order of every joint vector).
        lower, upper: position limits (rad or m; +-inf for continuous joints).
        velocity_limits: |qd| limits (rad/s or m/s; inf where the URDF gives none).
        base_link, tip_link: the chain's end links; task coordinates are in base_link.
        task_space: "pose", "position" or "planar"; m is the task dimension, n the joint count.
        has_inertias: whether any link that the chain moves has a mass in the URDF (its
            gravity and dynamics are known).
        urdf: the URDF the model was built from, its chain's continuous joints rewritten
            as revolute ones (what a dynamics engine loads: `ft_core.physics`).
        characteristic_length: L (m) scaling angular rows in `scale_task`.
        reach: sum of the distances between successive joint origins and the tool
            point (m), an upper bound of the distance from joint 1 to the tool.
    """

    def __init__(self, xml: str, base_link: str | None = None, tip_link: str | None = None,
                 task_space: str = "pose", characteristic_length: float | None = None):
        if task_space not in TASK_DIMENSIONS:
            raise RobotModelError(
                f"task_space {task_space!r} is not one of {', '.join(TASK_DIMENSIONS)}"
            )
        root, by_child, links = _parse_tree(xml)
        roots = sorted(links - set(by_child))
        if len(roots) != 1:
            raise RobotModelError(f"URDF must have exactly one root link, found {roots}")
        base = base_link or roots[0]
        for role, link in (("base_link", base), ("tip_link", tip_link)):
            if link is not None and link not in links:
                raise RobotModelError(f"{role} {link!r} is not a link of the URDF")
        tip = tip_link or _default_tip(base, by_child)
        chain = _chain(base, tip, by_child)
        for joint in chain:
            if joint.kind not in _SUPPORTED:
                raise RobotModelError(
                    f"joint {joint.name!r} of type {joint.kind!r} on the chain is not supported"
                )
        names = [j.name for j in chain if j.kind in _MOVABLE]
        if not names:
            raise RobotModelError(f"the chain from {base!r} to {tip!r} has no movable joint")

        self.name = root.get("name", "robot")
        self.joint_names = tuple(names)
        self.lower, self.upper, self.velocity_limits = _limits(root, names)
        self.base_link, self.tip_link, self.task_space = base, tip, task_space
        self.n, self.m = len(names), TASK_DIMENSIONS[task_space]
        self.urdf = _as_revolute(root, names)
        self._build_model(self.urdf)
        self.reach = self._reach()
        length = self.reach if characteristic_length is None else float(characteristic_length)
        if not (math.isfinite(length) and length > 0):
            raise RobotModelError(f"characteristic_length must be positive, got {length}")
        self.characteristic_length = length
        scale = np.ones(6)
        scale[3:] = length
        self.task_scale = scale[self._rows]

    def _build_model(self, xml: str) -> None:
        try:
            full = pin.buildModelFromXML(xml)
        except (RuntimeError, ValueError) as exc:
            raise RobotModelError(f"Pinocchio cannot build the URDF: {exc}") from exc
        keep = set(self.joint_names)
        locked = [full.getJointId(name) for name in full.names[1:] if name not in keep]
        try:
            model = pin.buildReducedModel(full, locked, pin.neutral(full))
        except (RuntimeError, ValueError) as exc:
            raise RobotModelError(f"Pinocchio cannot reduce the URDF to the chain: {exc} "
                                  "(does a chain joint share its name with a link?)") from exc
        if tuple(model.names[1:]) != self.joint_names or model.nq != self.n or model.nv != self.n:
            raise RobotModelError(
                f"chain joints {self.joint_names} do not form a serial chain in the model"
            )
        self._model, self._data = model, model.createData()
        self.has_inertias = any(inertia.mass > 0 for inertia in model.inertias[1:])
        # Links are BODY frames: a joint of the same name (Unitree Z1) is another frame.
        self._tip = model.getFrameId(self.tip_link, pin.FrameType.BODY)
        pin.framesForwardKinematics(model, self._data, pin.neutral(model))
        base_pose = self._data.oMf[model.getFrameId(self.base_link, pin.FrameType.BODY)]
        # The base is above every chain joint, so its placement is constant.
        self._base_inverse = base_pose.inverse()
        #: the base link is the model's root: placements need no change of frame
        self._base_at_root = bool(self._base_inverse.isIdentity(0.0))
        rotation = base_pose.rotation.T
        self._rotate = np.zeros((6, 6))
        self._rotate[:3, :3] = self._rotate[3:, 3:] = rotation
        self._base_aligned = bool(np.array_equal(rotation, np.eye(3)))
        self._rows = {"pose": slice(0, 6), "position": slice(0, 3), "planar": slice(0, 2)}[
            self.task_space
        ]

    def task_error(self, target: np.ndarray, q: np.ndarray | Kinematics) -> np.ndarray:
        """Task error e (m,) from q to `target`, in the rows of `jacobian`.

        `target` is what `forward` returns: x-y or a position (m), or a 4x4 transform
        for pose, where the angular rows are log3(R_target R(q)^T) (rad, base axes),
        so that J+ e is a Newton step towards the target.
        """
        return self.displacement(self.forward(q), np.asarray(target, dtype=float))

    def displacement(self, start: np.ndarray, end: np.ndarray) -> np.ndarray:
        """From task target `start` to `end` (what `forward` returns), in `jacobian`'s rows.

        The difference; for pose the position's and log3(R_end R_start^T) (rad, base
        axes), which a constant angular velocity integrates to.
        """
        if self.task_space != "pose":
            return end - start
        return np.concatenate([end[:3, 3] - start[:3, 3],
                               pin.log3(end[:3, :3] @ start[:3, :3].T)])

    def _reach(self) -> float:
        points = self.skeleton(pin.neutral(self._model))
        return float(sum(np.linalg.norm(b - a) for a, b in pairwise(points)))

    def outboard_moments(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(axes, moments), each (n, 3), in the URDF root frame, from the URDF's inertias.

        axes[i]: the unit axis of joint i (zero for a prismatic joint); moments[i]: the
        first moment of inertia m (c - p_i) (kg m) of everything outboard of joint i
        about its origin p_i, c being that composite body's centre of mass (Maciejewski et al.'s
        s*_{i-1}). Through Pinocchio's subtree centres of mass.
        """
        model, data = self._model, self._data
        q = self._check(q)
        pin.centerOfMass(model, data, q, True)
        J = pin.computeJointJacobians(model, data, q)
        axes = np.zeros((self.n, 3))
        moments = np.zeros((self.n, 3))
        for i in range(self.n):
            joint = i + 1  # Pinocchio's joint 0 is the universe
            angular = J[3:, model.joints[joint].idx_v]
            if np.linalg.norm(angular) > 0.5:  # revolute: a unit axis; prismatic: zero
                axes[i] = angular
            # Subtree centres of mass of joints other than the root are in the joint's frame.
            moments[i] = data.mass[joint] * (data.oMi[joint].rotation @ data.com[joint])
        return axes, moments

    def gravity_dynamics(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(gravity torques g(q) in N m, diagonal of the joint-space inertia in kg m^2).

        From the URDF's inertias, gravity along the root's -z (Pinocchio's
        computeGeneralizedGravity and CRBA).
        """
        q = self._check(q)
        gravity = pin.computeGeneralizedGravity(self._model, self._data, q).copy()
        inertia = np.diag(pin.crba(self._model, self._data, q)).copy()
        return gravity, inertia

    def skeleton(self, q: np.ndarray) -> np.ndarray:
        """The chain as points (n + 1, 3; m, base frame): each joint's origin, then the tool."""
        pin.framesForwardKinematics(self._model, self._data, self._check(q))
        placements = [self._data.oMi[j] for j in range(1, self._model.njoints)]
        placements.append(self._data.oMf[self._tip])
        return np.array([(self._base_inverse * pose).translation for pose in placements])

    def _check(self, q: np.ndarray) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        if q.shape != (self.n,):
            raise ValueError(f"q must have shape ({self.n},), got {q.shape}")
        if not all_finite(q):
            raise ValueError(f"q has non-finite entries: {q}")
        return q

    def kinematics(self, q: np.ndarray) -> Kinematics:
        """The tool's transform and Jacobian at q from one Pinocchio pass (a cycle's snapshot).

        Every method below that takes a configuration also takes this snapshot, so the
        consumers of one control cycle (task error, engine, task channel, excursions)
        share one forward-kinematics pass instead of one each.
        """
        model, data, tip = self._model, self._data, self._tip
        q = self._check(q)
        pin.computeJointJacobians(model, data, q)
        placement = pin.updateFramePlacement(model, data, tip)
        J = pin.getFrameJacobian(model, data, tip, pin.LOCAL_WORLD_ALIGNED)
        if not self._base_at_root:
            placement = self._base_inverse * placement
        return Kinematics(q, placement.homogeneous,
                          self._rotate @ J if not self._base_aligned
                          else np.ascontiguousarray(J))

    def transform(self, q: np.ndarray | Kinematics) -> np.ndarray:
        """Homogeneous transform (4x4) of `tip_link` in `base_link` at q."""
        if isinstance(q, Kinematics):
            return q.transform
        pin.framesForwardKinematics(self._model, self._data, self._check(q))
        return (self._base_inverse * self._data.oMf[self._tip]).homogeneous

    def forward(self, q: np.ndarray | Kinematics) -> np.ndarray:
        """Task coordinates at q: (2,) x-y for planar, (3,) position (m), pose a 4x4 transform."""
        return self.task_coordinates(self.transform(q))

    def target_position(self, target: np.ndarray) -> np.ndarray:
        """The position (3,; m, base frame) of a task target in `forward`'s form.

        A pose's translation, a position itself, a planar point at z = 0.
        """
        target = np.asarray(target, dtype=float)
        if target.shape == (4, 4):
            return target[:3, 3].copy()
        return np.array([*target[:3], *np.zeros(3 - min(target.size, 3))])

    def task_coordinates(self, pose: np.ndarray) -> np.ndarray:
        """A tool transform (4x4, base frame) as `forward` gives it for this task space."""
        if self.task_space == "pose":
            return pose
        return pose[self._rows, 3].copy()

    def base_jacobian(self, q: np.ndarray | Kinematics) -> np.ndarray:
        """The tool point's full Jacobian (6 x n), axes of `base_link`.

        Linear rows above angular ones; C-contiguous (one layout for the compiled code).
        """
        if isinstance(q, Kinematics):
            return q.base_jacobian
        J = pin.computeFrameJacobian(self._model, self._data, self._check(q), self._tip,
                                     pin.LOCAL_WORLD_ALIGNED)
        return self._rotate @ J if not self._base_aligned else np.ascontiguousarray(J)

    def jacobian(self, q: np.ndarray | Kinematics) -> np.ndarray:
        """Task Jacobian (m x n) at the tool point, axes of `base_link`."""
        return np.ascontiguousarray(self.base_jacobian(q)[self._rows])

    def jacobian_derivatives(self, q: np.ndarray) -> np.ndarray:
        """dJ/dq_k for every joint k, shape (n, m, n) (see `jacobian_and_derivatives`)."""
        return self.jacobian_and_derivatives(q)[1]

    def jacobian_and_derivatives(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Task Jacobian (m, n) and dJ/dq_k (n, m, n) from one Pinocchio Jacobian.

        The full 6-row Jacobian is turned to the base's axes first (rows are then
        selected): the derivatives (`task_jacobians`) are cross products of its
        columns, which hold in any fixed axes.
        """
        return task_jacobians(self.base_jacobian(q), self.m)

    def scale_task(self, A: np.ndarray) -> np.ndarray:
        """Multiply the angular task rows of A (..., m, k) by the characteristic length.

        Measures that compare singular values across rows must see `scale_task(J)`,
        so every row is in m/s (Lewis & Maciejewski 1997, remark on eq 5).
        """
        return np.asarray(A) * self.task_scale[:, None]

    def home(self) -> np.ndarray:
        """A working configuration, moved into the limits.

        The built-in's (`HOME`, matched by robot name and joint count), else all zeros.
        """
        home = HOME.get(self.name)
        q = np.array(home) if home is not None and len(home) == self.n else np.zeros(self.n)
        return np.clip(q, self.lower, self.upper)

    def random_configuration(self, rng: np.random.Generator, margin: float = 0.0) -> np.ndarray:
        """Uniform configuration inside the limits shrunk by `margin` (continuous: +-pi)."""
        lower = np.where(np.isfinite(self.lower), self.lower, -math.pi) + margin
        upper = np.where(np.isfinite(self.upper), self.upper, math.pi) - margin
        return rng.uniform(lower, upper)

    def __repr__(self) -> str:
        return (f"Robot({self.name!r}, {self.base_link!r} -> {self.tip_link!r}, "
                f"{self.task_space}, n={self.n}, m={self.m})")


def load(spec: str, base_link: str | None = None, tip_link: str | None = None,
         task_space: str | None = None, characteristic_length: float | None = None) -> Robot:
    """Build a `Robot` from a built-in name, a URDF file path or URDF XML.

    Args:
        spec: "planar3r", "puma560", "panda", "iiwa14", a path to a .urdf file or the XML.
        base_link: first link of the chain (default: the URDF's root link).
        tip_link: tool link (default: walk down from base_link until the tree branches).
        task_space: "pose", "position" or "planar" (default: the built-in's own, else pose).
        characteristic_length: L in m for angular rows (default: the robot's reach).

    Raises:
        RobotModelError: unknown spec, URDF that does not parse, missing link, no joint.
    """
    xml, default_space = _resolve(spec)
    return Robot(xml, base_link, tip_link, task_space or default_space or "pose",
                 characteristic_length)
