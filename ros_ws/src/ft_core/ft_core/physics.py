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

What it does not imitate: friction other than the URDF's, motor and gear dynamics
(rotor inertia, elasticity, backlash), torque ripple, contacts (no geometry is loaded),
and the drives' safety reflexes that stop a real arm on a large tracking error.
Times are seconds on the plant's clock; positions rad, velocities rad/s, torques N m.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from ft_core.errors import SuiteError
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

    def lock(self, joint: int) -> None:
        """Brake a joint where it is (a free-swinging one too); its drive keeps pushing."""
        if joint in self.locked:
            return
        k = self._brake[joint]
        self.locked[joint] = float(self._data.qpos[self._qadr[joint]])
        self._model.eq_data[k, 0] = self.locked[joint]
        self._data.eq_active[k] = 1
        self.swinging.discard(joint)

    def swing(self, joint: int) -> None:
        """The joint's drive loses its torque (a braked joint stays braked)."""
        if joint not in self.locked:
            self.swinging.add(joint)

    def release(self) -> list[int]:
        """Release every brake and give every drive its torque back, tracking from here."""
        for joint in self.locked:
            self._data.eq_active[self._brake[joint]] = 0
        self._reference = self.q
        return super().release()

    def step(self, time: float) -> None:
        """Advance to `time` (s) in 1 ms steps (MuJoCo's state stays within 1 ms of it)."""
        self.t = max(time, self.t)
        while self._clock + TIMESTEP <= self.t + 1e-9:
            self._clock += TIMESTEP
            self._servo(self.path.in_force(self._clock))
            mujoco.mj_step(self._model, self._data)

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
        torque = np.clip(torque, -self._effort, self._effort)
        torque[free] = 0.0
        self.torque = torque
        self._data.qfrc_applied[self._dof] = torque
