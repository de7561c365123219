"""A physics plant: the arm's rigid-body dynamics in MuJoCo, driven as a joint servo drives it.

Where `ft_core.plant.Plant` moves the joints as the velocity loop says, this plant
integrates the URDF's masses and inertias under gravity (MuJoCo, 1 ms steps, the
implicit-fast integrator) and makes the velocity loop a torque controller that can
fall short of it. Every 1 ms, for the commands of `ft_core.plant.CommandPath`
(latency, watchdog or held last command, velocity limits), each chain joint j gets

    r_j += u_j h                                  (the reference, within +-0.1 rad of q_j)
    tau_j = (1 - e) b_j(q, qd) + M_jj w^2 (r_j - q_j) + 2 z M_jj w (u_j - qd_j)

clipped to the URDF's effort limit: u the command (its rate of change within the
acceleration limits), b the bias torques (gravity and Coriolis, one step old) of which
the servo compensates a share 1 - e = 90 % (a drive's gravity model is never exact),
M_jj the joint-space inertia at the home configuration (with the drive's rotor
inertia, `ARMATURE`), w = 1 / response_time
(response_time below 10 ms counts as 10 ms: no physical servo is instantaneous) and
z = 1 (critical damping). A velocity command thus becomes a reference trajectory the
joint tracks with a lag of about 2 / w, overshoots a little when the command reverses
(the proportional term's integral action), and sags under an unmodelled load until
the reference error balances it: the transients a velocity-commanded arm shows.

Failures are physical:
- `lock`: a brake (a MuJoCo joint equality constraint, stiff: time constant 2 ms) holds
  the joint where it is, while its drive goes on pushing against it as commanded (the
  tracking error, and with it the torque, stays bounded by the 0.1 rad above);
- `swing`: the drive's torque drops to zero; the joint moves as gravity, the links'
  coupling and the URDF's joint damping make it, until the joint limits stop it;
joints off the chain (a gripper's fingers) are held by brakes throughout.
Degradations (`inject`, `ft_core.faults`) are physical too: viscous friction adds to the
joint's MuJoCo `damping` (integrated implicitly), dry friction is its `frictionloss` (a
constraint as stiff as the brake: it sticks until the drive's torque exceeds it, without
chattering), a loss of authority scales the drive's effort limit, a range fault moves the
joint's MuJoCo limit (as stiff as the brake) to the new stop, and an intermittent jam
engages and releases the brake by plant time. The drive does not know of any of them.

Contact: the only geometry is a sphere of `TOOL_RADIUS` on the tip link and one box, the
obstacle (`place_obstacle`), which exists from the start with its contacts off and is
moved, sized and switched on at run time (no recompilation: the state stays continuous).

What it does not imitate: motor and gear dynamics (elasticity, backlash), torque ripple,
contacts of the links (only the tool's sphere touches the obstacle), and the drives'
safety reflexes that stop a real arm on a large tracking error.
Times are seconds on the plant's clock; positions rad, velocities rad/s, torques N m.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from ft_core.errors import SuiteError
from ft_core.faults import Fault, FaultError, FaultKind
from ft_core.plant import BasePlant, PlantConfig
from ft_core.robots import Robot

#: s, MuJoCo's integration step and the servo's period.
TIMESTEP = 0.001
#: Share of the bias torques the servo's model misses (e above).
GRAVITY_MODEL_ERROR = 0.1
#: s, the fastest servo (the smallest response_time used).
MIN_RESPONSE_TIME = 0.01
#: The servo's damping ratio (z above).
DAMPING_RATIO = 1.0
#: kg m^2, the motor's rotor inertia seen through its gear, on every chain joint (URDFs
#: leave it out; MuJoCo Menagerie's Panda uses this value). Without it the joint-space
#: inertia of an arm with nearly aligned axes (a Panda with joint 2 near 0) is far from
#: diagonal and independent joint servos, as drives are, would fight each other.
ARMATURE = 0.1
#: rad, how far the reference may run ahead of the joint (bounds the wind-up of a jam).
TRACKING_LIMIT = 0.1
#: MuJoCo solref (time constant s, damping ratio) of the brakes: stiff, 2 MuJoCo steps.
BRAKE_SOLREF = (2 * TIMESTEP, 1.0)
#: rad, the stand-in for no limit on a side of a range fault's stop on an unlimited joint.
BIG = 1e10
#: m, radius of the tool's collision sphere on the tip link's origin.
TOOL_RADIUS = 0.035
#: MuJoCo solref of the tool's contact with the obstacle: a rigid box, 4 MuJoCo steps.
CONTACT_SOLREF = (4 * TIMESTEP, 1.0)


class PhysicsError(SuiteError):
    """The model cannot be simulated (no inertias, or MuJoCo refuses it)."""


def _dynamics_urdf(robot: Robot) -> str:
    """The robot's URDF without geometry.

    MuJoCo needs only the inertias, and a user's mesh files (`package://` URIs) are
    neither found nor trusted here.
    """
    root = ET.fromstring(robot.urdf)
    for link in root.findall("link"):
        for element in link.findall("visual") + link.findall("collision"):
            link.remove(element)
    return ET.tostring(root, encoding="unicode")


def _add_contact_geometry(spec: mujoco.MjSpec, robot: Robot) -> None:
    """The tool's sphere, the obstacle (contacts off) and a site on the base link.

    The sphere touches only the obstacle: contype 1, conaffinity 0 (nothing touches it),
    the obstacle contype 0 and conaffinity 0 until `PhysicsPlant.place_obstacle` sets 1.
    """
    tool = spec.body(robot.tip_link).add_geom(
        name="tool", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[TOOL_RADIUS, 0, 0])
    tool.contype, tool.conaffinity, tool.solref = 1, 0, CONTACT_SOLREF
    body = spec.worldbody.add_body(name="obstacle", mocap=True, pos=[0, 0, -100])
    box = body.add_geom(name="obstacle", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 0.1, 0.1])
    box.contype, box.conaffinity, box.solref = 0, 0, CONTACT_SOLREF
    spec.body(robot.base_link).add_site(name="base")


def check_inertias(robot: Robot) -> None:
    """Raise `PhysicsError` unless every chain joint moves something with inertia."""
    _, inertia = robot.gravity_dynamics(robot.home())
    missing = [name for name, i in zip(robot.joint_names, inertia, strict=True) if not i > 0]
    if missing:
        raise PhysicsError(f"the physics plant needs the URDF's inertias: nothing with mass "
                           f"moves with {missing[:3]} (a kinematic model such as the built-in "
                           "'panda'? the built-in 'panda_inertial' has them)")


class PhysicsPlant(BasePlant):
    """The arm in MuJoCo under servo torques; see the module docstring.

    Attributes:
        q, qd: chain joint positions (rad) and velocities (rad/s), `robot.joint_names` order.
        torque: the drive torques (N m) of the last step.
        obstacle: (pose 4x4 in the base frame, edges (3,) m) of the box placed, or None.
    """

    def __init__(self, robot: Robot, q0: np.ndarray, config: PlantConfig | None = None,
                 time: float = 0.0):
        super().__init__(robot.lower, robot.upper, robot.velocity_limits, config, time)
        check_inertias(robot)
        try:
            spec = mujoco.MjSpec.from_string(_dynamics_urdf(robot))
            spec.option.timestep = TIMESTEP
            spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
            # Links without an <inertial> between moving ones get a negligible mass.
            spec.compiler.boundmass, spec.compiler.boundinertia = 1e-6, 1e-9
            spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
            spec.compiler.discardvisual = False  # the obstacle, contacts off, stays
            _add_contact_geometry(spec, robot)
            chain = set(robot.joint_names)
            for joint in spec.joints:
                if joint.name in chain:
                    joint.armature = ARMATURE
                brake = spec.add_equality()
                brake.type, brake.name1 = mujoco.mjtEq.mjEQ_JOINT, joint.name
                brake.solref = BRAKE_SOLREF
                brake.active = joint.name not in chain  # fingers are held throughout
            self._model = spec.compile()
        except ValueError as error:
            raise PhysicsError(f"MuJoCo cannot simulate the URDF: {error}") from error
        model = self._model
        ids = [model.joint(name).id for name in robot.joint_names]
        self._qadr = model.jnt_qposadr[ids].copy()
        self._dof = model.jnt_dofadr[ids].copy()
        self._brake = {j: int(np.flatnonzero(model.eq_obj1id == joint_id)[0])
                       for j, joint_id in enumerate(ids)}
        effort = np.where(model.jnt_actfrclimited[ids], model.jnt_actfrcrange[ids, 1], 0.0)
        self._effort = np.where(effort > 0, effort, math.inf)
        self._data = mujoco.MjData(model)
        for k in np.flatnonzero(model.eq_active0):  # fingers: held where the model has them
            self._model.eq_data[k, 0] = self._data.qpos[model.jnt_qposadr[model.eq_obj1id[k]]]
        self._data.qpos[self._qadr] = robot.home()
        full = np.zeros((model.nv, model.nv))
        mujoco.mj_forward(model, self._data)
        mujoco.mj_fullM(model, self._data, full)
        self._mass = np.diag(full)[self._dof].copy()
        self._data.qpos[self._qadr] = np.clip(np.asarray(q0, float), self.lower, self.upper)
        mujoco.mj_forward(model, self._data)
        self._reference = self.q
        self._reference_velocity = np.zeros(self.n)
        self.torque = np.zeros(self.n)
        self._joint_ids = np.array(ids)
        self._healthy = (model.dof_damping.copy(), model.dof_frictionloss.copy(),
                         np.where(model.jnt_limited[:, None], model.jnt_range, [-BIG, BIG]),
                         model.jnt_solref.copy(), model.jnt_limited.copy(),
                         model.dof_solref.copy())
        self._obstacle = model.geom("obstacle").id
        self._obstacle_body = int(model.body_mocapid[model.geom_bodyid[self._obstacle]])
        self._base = model.site("base").id
        self.obstacle: tuple[np.ndarray, np.ndarray] | None = None
        self._clock = time  # time of MuJoCo's state, within one step of t
        self.configure(self.path.config)

    def configure(self, config: PlantConfig) -> None:
        """Use new plant options from the next step on (the servo gains with them)."""
        super().configure(config)
        w = 1.0 / max(config.response_time, MIN_RESPONSE_TIME)
        self._kp = self._mass * w * w
        self._kd = 2 * DAMPING_RATIO * self._mass * w

    @property
    def q(self) -> np.ndarray:
        """Chain joint positions (rad)."""
        return self._data.qpos[self._qadr].copy()

    @property
    def qd(self) -> np.ndarray:
        """Chain joint velocities (rad/s)."""
        return self._data.qvel[self._dof].copy()

    def position(self, joint: int) -> float:
        """Joint index `joint`'s position (rad)."""
        return float(self._data.qpos[self._qadr[joint]])

    def lock(self, joint: int) -> None:
        """Brake a joint where it is (a free-swinging one too); its drive keeps pushing."""
        if joint in self.locked:
            return
        self.locked[joint] = self.position(joint)
        self._brake_on(joint)
        self.swinging.discard(joint)

    def unlock(self, joint: int) -> None:
        """Release one joint's brake (an intermittent jam's follows its own clock)."""
        if self.locked.pop(joint, None) is not None:
            self._data.eq_active[self._brake[joint]] = int(
                joint in self.faults.braked(self._clock))
            self._reference[joint] = self.position(joint)

    def _brake_on(self, joint: int) -> None:
        """Engage joint index `joint`'s brake where the joint is."""
        k = self._brake[joint]
        self._model.eq_data[k, 0] = self.position(joint)
        self._data.eq_active[k] = 1

    def check_fault(self, joint: int, fault: Fault) -> None:
        """Raise `FaultError` if `fault` cannot be injected (authority needs an effort limit)."""
        super().check_fault(joint, fault)
        if fault.kind is FaultKind.AUTHORITY and not math.isfinite(self._effort[joint]):
            raise FaultError(f"authority of {fault.joint}: the URDF gives it no effort limit")

    def _degrade(self, joint: int) -> None:
        """Set joint index `joint`'s MuJoCo friction and limits from its faults."""
        model, faults = self._model, self.faults
        dof, jid = self._dof[joint], self._joint_ids[joint]
        damping, frictionloss, ranges, solref, limited, friction_solref = self._healthy
        model.dof_damping[dof] = damping[dof] + faults.viscous[joint]
        model.dof_frictionloss[dof] = frictionloss[dof] + faults.dry[joint]
        model.dof_solref[dof] = BRAKE_SOLREF if faults.dry[joint] else friction_solref[dof]
        lower, upper = faults.lower[joint], faults.upper[joint]
        stopped = math.isfinite(lower) or math.isfinite(upper)
        model.jnt_range[jid] = (max(ranges[jid, 0], lower), min(ranges[jid, 1], upper))
        model.jnt_limited[jid] = limited[jid] or stopped
        model.jnt_solref[jid] = BRAKE_SOLREF if stopped else solref[jid]

    def place_obstacle(self, pose: np.ndarray, size: np.ndarray) -> None:
        """A rigid box of `size` (m, full edges) at `pose` (4x4, in the base frame), from now on.

        The tool's sphere touches it; placed across the sphere, it pushes the tool out.
        """
        model, data = self._model, self._data
        g, half = self._obstacle, 0.5 * np.asarray(size, float)
        model.geom_size[g] = half
        model.geom_rbound[g] = float(np.linalg.norm(half))
        model.geom_aabb[g] = (0.0, 0.0, 0.0, *half)
        body = model.geom_bodyid[g]
        if model.body_bvhnum[body]:
            model.bvh_aabb[model.body_bvhadr[body]] = (0.0, 0.0, 0.0, *half)
        base = data.site_xmat[self._base].reshape(3, 3)
        data.mocap_pos[self._obstacle_body] = data.site_xpos[self._base] + base @ pose[:3, 3]
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, (base @ pose[:3, :3]).flatten())
        data.mocap_quat[self._obstacle_body] = quat
        model.geom_conaffinity[g] = model.body_conaffinity[body] = 1
        self.obstacle = (np.array(pose, float), half * 2)

    def remove_obstacle(self) -> None:
        """No obstacle from now on."""
        model, g = self._model, self._obstacle
        model.geom_conaffinity[g] = model.body_conaffinity[model.geom_bodyid[g]] = 0
        self.obstacle = None

    def swing(self, joint: int) -> None:
        """The joint's drive loses its torque (a braked joint stays braked)."""
        if joint not in self.locked:
            self.swinging.add(joint)

    def release(self) -> list[int]:
        """Release every brake and give every drive its torque back, tracking from here."""
        for joint in set(self.locked) | set(self.faults.intermittent):
            self._data.eq_active[self._brake[joint]] = 0
        self._reference = self.q
        degraded = list(self.faults.faults)
        released = super().release()
        for joint in degraded:
            self._degrade(joint)
        return released

    def step(self, time: float) -> None:
        """Advance to `time` (s) in 1 ms steps (MuJoCo's state stays within 1 ms of it)."""
        self.t = max(time, self.t)
        while self._clock + TIMESTEP <= self.t + 1e-9:
            self._clock += TIMESTEP
            if self.faults.intermittent:
                self._jam(self._clock)
            self._servo(self.path.in_force(self._clock))
            mujoco.mj_step(self._model, self._data)

    def _jam(self, time: float) -> None:
        """Engage or release the brakes of intermittent jams for plant time `time` (s)."""
        braked = self.faults.braked(time)
        for joint in self.faults.intermittent:
            if joint in self.locked:
                continue
            active = bool(self._data.eq_active[self._brake[joint]])
            if joint in braked and not active:
                self._brake_on(joint)
            elif joint not in braked and active:
                self._data.eq_active[self._brake[joint]] = 0

    def _servo(self, u: np.ndarray) -> None:
        """The drive torques for command u (rad/s) over the next step."""
        h, q, qd = TIMESTEP, self.q, self.qd
        limited = self.path.acceleration > 0
        if np.any(limited):
            step = self.path.acceleration * h
            previous = self._reference_velocity
            u = np.where(limited, np.clip(u, previous - step, previous + step), u)
        self._reference_velocity = u
        reference = np.clip(self._reference + u * h, q - TRACKING_LIMIT, q + TRACKING_LIMIT)
        free = sorted(self.swinging)
        reference[free] = q[free]
        self._reference = np.clip(reference, self.lower, self.upper)
        bias = self._data.qfrc_bias[self._dof]
        torque = ((1 - GRAVITY_MODEL_ERROR) * bias + self._kp * (self._reference - q)
                  + self._kd * (u - qd))
        effort = self._effort * self.faults.authority
        torque = np.clip(torque, -effort, effort)
        torque[free] = 0.0
        self.torque = torque
        self._data.qfrc_applied[self._dof] = torque
