"""Robot models: a serial chain of a URDF, its forward kinematics and task Jacobians.

`load` accepts a built-in name, a URDF file path or URDF XML and returns a
`Robot` for the chain from `base_link` to `tip_link` (the URDF is read by
`ft_core.urdf_model`). All kinematics goes through
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

import enum
import math
from dataclasses import dataclass
from importlib import resources
from itertools import pairwise
from pathlib import Path

import numpy as np
import pinocchio as pin
from numba import njit

from ft_core.input_checks import all_finite
from ft_core.urdf_model import MAX_URDF_BYTES, MAX_URDF_JOINTS, RobotModelError, read_chain

__all__ = ["BUILTINS", "HOME", "MAX_URDF_BYTES", "MAX_URDF_JOINTS", "TASK_DIMENSIONS",
           "Kinematics", "Robot", "RobotModelError", "TaskSpace", "builtin_urdf",
           "configuration", "load", "task_jacobians"]


class TaskSpace(enum.StrEnum):
    """The task coordinates of the tool point, in `base_link` (equal to their names).

    POSE: position and orientation (m = 6); POSITION: the position (m = 3); PLANAR:
    x and y (m = 2).
    """

    POSE = "pose"
    POSITION = "position"
    PLANAR = "planar"


#: Task space -> number of task coordinates m.
TASK_DIMENSIONS = {TaskSpace.POSE: 6, TaskSpace.POSITION: 3, TaskSpace.PLANAR: 2}

#: Built-in models: URDF resource in ft_core/urdf and the default task space. All but
#: two are kinematic (no inertias). "planar3r_rods" is "planar3r" with a uniform 1 kg
#: rod for each link (the free-swinging example of Maciejewski et al. sec. 3.3).
#: "panda_inertial" is the Franka Emika Panda as the `example-robot-data` package
#: distributes it (URDF under Apache-2.0 from Franka Emika GmbH, unchanged): with
#: inertias (what the physics plant, `ft_core.physics`, needs), gripper finger joints,
#: fixed joints and `package://` mesh URIs, i.e. what a user's `robot_description`
#: looks like; its kinematics agree with "panda"'s.
BUILTINS = {
    "planar3r": ("planar3r.urdf", TaskSpace.PLANAR),
    "planar3r_rods": ("planar3r_rods.urdf", TaskSpace.PLANAR),
    "puma560": ("puma560.urdf", TaskSpace.POSITION),
    "panda": ("panda.urdf", TaskSpace.POSE),
    "panda_inertial": ("panda_from_example_robot_data.urdf", TaskSpace.POSE),
    "iiwa14": ("iiwa14.urdf", TaskSpace.POSE),
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


def builtin_urdf(name: str) -> str:
    """Return the URDF XML of a built-in model (`BUILTINS`)."""
    return resources.files("ft_core").joinpath("urdf").joinpath(BUILTINS[name][0]).read_text()


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


class Robot:
    """Kinematics of one serial chain for one task space.

    Attributes:
        name: the URDF robot name.
        joint_names: movable joints from base to tip (the order of every joint vector).
        lower, upper: position limits (rad or m; +-inf for continuous joints).
        velocity_limits: |qd| limits (rad/s or m/s; inf where the URDF gives none).
        effort_limits: |effort| limits (N m or N; inf where the URDF gives none).
        base_link, tip_link: the chain's end links; task coordinates are in base_link.
        task_space: the `TaskSpace`; m is the task dimension, n the joint count.
        has_inertias: whether any link that the chain moves has a mass in the URDF (its
            gravity and dynamics are known).
        urdf: the URDF the model was built from, its chain's continuous joints rewritten
            as revolute ones (what a dynamics engine loads: `ft_core.physics`).
        characteristic_length: L (m) scaling angular rows in `scale_task`.
        reach: sum of the distances between successive joint origins and the tool
            point (m), an upper bound of the distance from joint 1 to the tool.
    """

    def __init__(self, xml: str, base_link: str | None = None, tip_link: str | None = None,
                 task_space: str = TaskSpace.POSE, characteristic_length: float | None = None):
        if task_space not in TASK_DIMENSIONS:
            raise RobotModelError(
                f"task_space {task_space!r} is not one of {', '.join(TASK_DIMENSIONS)}"
            )
        chain = read_chain(xml, base_link, tip_link)
        self.name = chain.name
        self.joint_names = chain.joint_names
        self.lower, self.upper = chain.lower, chain.upper
        self.velocity_limits = chain.velocity_limits
        self.effort_limits = chain.effort_limits
        self.base_link, self.tip_link = chain.base_link, chain.tip_link
        self.task_space = TaskSpace(task_space)
        self.n, self.m = len(chain.joint_names), TASK_DIMENSIONS[self.task_space]
        self.urdf = chain.urdf
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
        self._rows = {TaskSpace.POSE: slice(0, 6), TaskSpace.POSITION: slice(0, 3),
                      TaskSpace.PLANAR: slice(0, 2)}[self.task_space]

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
        if self.task_space != TaskSpace.POSE:
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
        gravity = self.gravity(q)
        inertia = np.diag(pin.crba(self._model, self._data, self._check(q))).copy()
        return gravity, inertia

    def dynamics(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """M(q) (n, n; kg m^2) and C(q, qd) qd + g(q) ((n,); N m): tau = M qdd + C qd + g.

        From the URDF's inertias (Pinocchio's CRBA, its upper triangle mirrored, and
        nonLinearEffects).
        """
        model, data = self._model, self._data
        q = self._check(q)
        upper = pin.crba(model, data, q)
        inertia = np.triu(upper) + np.triu(upper, 1).T
        return inertia, pin.nonLinearEffects(model, data, q, np.asarray(qd, float)).copy()

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """The gravity torques g(q) (N m) alone, as in `gravity_dynamics`, without the CRBA."""
        return pin.computeGeneralizedGravity(self._model, self._data, self._check(q)).copy()

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
        if self.task_space == TaskSpace.POSE:
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
        task_space: a `TaskSpace` value, "pose", "position" or "planar" (default: the
            built-in's own, else pose).
        characteristic_length: L in m for angular rows (default: the robot's reach).

    Raises:
        RobotModelError: unknown spec, URDF that does not parse, missing link, no joint.
    """
    xml, default_space = _resolve(spec)
    return Robot(xml, base_link, tip_link, task_space or default_space or TaskSpace.POSE,
                 characteristic_length)
