"""sim_node: a plant for any model the suite loads, with failure injection.

Every step (at `rate`) advances the plant under the velocity commands from
`ft/command`, as real drivers execute them. `plant` chooses it: `kinematic`
(`ft_core.plant.Plant`, any model) moves the joints as the velocity loop below says;
`physics` (`ft_core.physics.PhysicsPlant`, needs a URDF with inertias such as the
built-in `panda_inertial`) integrates the arm's dynamics in MuJoCo under a joint servo
with finite gains, an imperfect gravity compensation and torque limits, with a brake as
the lock and a drive without torque as the free swing. Both plants take:
- `command_latency` (s): transport and driver delay (5-50 ms on real arms);
- `response_time` (s): the velocity loop as a first-order lag (a joint servo
  tracking a velocity reference: 10-50 ms on Franka, KUKA and UR arms);
- `acceleration_limit` (rad/s^2, one value or one per joint): what ros2_control's
  joint limits interface and most drivers' trajectory smoothing enforce;
- `command_timeout` (s): the driver's command watchdog stops the arm when commands
  pause (Franka FCI, KUKA FRI, UR RTDE's `speedj` with its timeout), unless
  `hold_last_command`: ros2_control's JointGroupVelocityController keeps the last
  command forever.
On the physics plant, `response_time` sets the servo's gains (`ft_core.physics`).
With `refuse_over_limits` (on in the demo, the campaign and the demo's launch file) the
driver refuses what a real one refuses, as Franka's reflex does: a command whose
velocity, acceleration or jerk, read by its stamp, is over the arm's limits (`limits.*`,
`ft_core.command_limits.DriverCheck`; the joints the plant holds failed, by any fault,
are not judged: the monitor stops a joint it declares at once) stops the arm, and it
takes no command until `~/reset`; the refusal is logged as an ERROR and kept in `reflex`.
Velocities are clipped to the URDF limits and positions to the URDF limits; locked
joints do not move (behind the physics plant's brake: by a fraction of a mrad). It
publishes `joint_states` (positions with optional Gaussian `position_noise`, and the
plant's velocities). Plant options may change at run time.

With `publish_clock` the sim owns the time: it starts at 0, advances exactly one
period per step and publishes `/clock` (run the other nodes with use_sim_time);
otherwise it follows its node clock. `step()` is public, so tests and the demo can
run the plant faster than real time.

`ft/inject_failure` (JointState, names) locks those joints where they are, from the
next step, until `~/reset`; unknown names are rejected with a warning.
`ft/inject_free_swing` (JointState, names) makes those joints lose their torque: they
ignore the commands and swing under gravity, as `ft_core.swing.pendulum_acceleration`
says on the kinematic plant and as MuJoCo integrates it on the physics one (needs the
URDF's inertias: a joint without outboard inertia is refused with a warning); a lock
injected on a swinging joint brakes it; `~/reset` ends both. A lock can also be
scheduled with `failure.joint` and `failure.time` (s of plant time).

`ft/inject_fault` (DiagnosticArray, `ft_msgs_py.faults`) injects faults of any kind
(`ft_core.faults`: lock, free swing, viscous and dry friction, lost torque authority, a
new stop, an intermittent jam), several at once; each message adds to the faults in
force until `~/reset`. A message with anything wrong (an unknown joint, kind or key, a
number out of range, a stop outside the joint's range, a free swing without inertia) is
refused whole with one rate-limited warning. `ft/obstacle` (Marker: ADD a CUBE, DELETE)
places or removes a rigid box the tool touches, on the physics plant only; `~/reset`
leaves it. The physics plant's `joint_states` carry its drive torques as `effort` (N m).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from ft_core import robots, swing
from ft_core.command_limits import DriverCheck, limits_config
from ft_core.errors import SuiteError
from ft_core.faults import Fault, FaultKind
from ft_core.physics import PhysicsPlant
from ft_core.plant import CommandPath, Plant
from ft_msgs_py import (
    convert,
    markers,
    names,
    parameter_table,
    parameters,
    publishers,
    qos,
    spin,
)
from ft_msgs_py import faults as fault_messages
from ft_msgs_py.node import JointStateLike, SuiteNode
from rclpy.clock import Clock, ClockType
from rclpy.executors import Executor
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock as ClockMessage
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from visualization_msgs.msg import Marker, MarkerArray

from ft_sim import settings
from ft_sim.settings import PARAMETERS


class SimNode(SuiteNode):
    """The kinematic plant; see the module docstring."""

    def __init__(self, **kwargs):
        super().__init__("sim", **kwargs)
        parameter_table.declare(self, PARAMETERS)
        self.robot: robots.Robot | None = None
        self.plant: Plant | PhysicsPlant | None = None
        #: The driver's test of every command (its `peaks` measure the stream); a refusal
        #: stops the arm with `refuse_over_limits`.
        self.driver: DriverCheck | None = None
        self.reflex: str | None = None  #: why the driver stopped the arm (until ~/reset)
        self._refuse = self.param("refuse_over_limits")
        self._physics = self.param("plant") == "physics"
        self._rng = np.random.default_rng(self.param("seed"))
        self._own_clock = self.param("publish_clock")
        self.period = 1.0 / self.param("rate")
        self._start = 0.0 if self._own_clock else self.now()
        self._state_pub = self.create_publisher(JointState, names.JOINT_STATES, qos.RELIABLE)
        self._markers_pub = self.create_publisher(MarkerArray, names.MARKERS, qos.RELIABLE)
        self._trail = markers.Trail()
        self._steps_per_view = max(1, round(self.param("rate") * markers.PERIOD))
        self._steps = 0
        self._clock_pub = (self.create_publisher(ClockMessage, names.CLOCK, 10)
                           if self._own_clock else None)
        self._command_subscription = self.subscribe_joint_states(
            names.COMMAND, self._on_command, qos.SENSOR_INPUT)
        self.create_subscription(JointState, names.INJECT_FAILURE, self._on_inject, qos.RELIABLE)
        self.create_subscription(JointState, names.INJECT_FREE_SWING, self._on_free_swing,
                                 qos.RELIABLE)
        self.create_subscription(DiagnosticArray, names.INJECT_FAULT, self._on_fault,
                                 qos.RELIABLE)
        self.create_subscription(Marker, names.OBSTACLE, self._on_obstacle, qos.RELIABLE)
        self.create_subscription(JointState, names.LOCKED_JOINTS, self._on_declared,
                                 qos.LATCHED)
        self.create_service(Trigger, names.RESET, self._on_reset)
        parameter_table.on_change(self, PARAMETERS, self._check, self._configure)
        parameters.request_model(self, self._set_model)
        # Owning the clock, the sim must not wait for it: its timer runs on steady time.
        self.timer = self.create_timer(self.period, self.step,
                                       clock=Clock(clock_type=ClockType.STEADY_TIME)
                                       if self._own_clock else None)

    def _check(self, values: dict) -> None:
        config = settings.plant_config(values)
        if self.plant is not None:  # per-joint values must match the model
            CommandPath(self.plant.n, self.plant.velocity_limits, config)
        if values["failure.joint"] and self.robot is not None \
                and values["failure.joint"] not in self.robot.joint_names:
            raise ValueError(f"failure.joint {values['failure.joint']!r} is not one of "
                             f"{list(self.robot.joint_names)}")

    def _configure(self, _changed: set[str]) -> None:
        if self.plant is not None:
            self.plant.configure(settings.plant_config(parameter_table.values(self,
                                                                              PARAMETERS)))

    @property
    def t(self) -> float:
        """Plant time (s)."""
        return self.plant.t if self.plant is not None else self._start

    @property
    def q(self) -> np.ndarray:
        """Joint positions (rad), model order."""
        return self.plant.q if self.plant is not None else np.zeros(0)

    @property
    def qd(self) -> np.ndarray:
        """Joint velocities (rad/s), model order."""
        return self.plant.qd if self.plant is not None else np.zeros(0)

    @property
    def locked(self) -> dict[str, float]:
        """{joint name: position where it locked} of the injected locks."""
        if self.plant is None:
            return {}
        return {self.robot.joint_names[j]: p for j, p in self.plant.locked.items()}

    def _set_model(self, spec: str, source: str) -> None:
        try:
            robot = robots.load(spec, *parameters.chain_arguments(self))
            joints = [robot.joint_names[i] for i in parameters.joint_order(self, robot.joint_names)]
            initial = list(parameters.value(self, "initial_positions"))
            q = robot.home()
            if initial:
                by_name = dict(zip(joints, initial, strict=True))
                q = np.array([float(by_name[j]) for j in robot.joint_names])
                if not np.all(np.isfinite(q)):
                    raise ValueError("initial_positions must be finite")
            plant = self._plant(robot, q)
            limits = limits_config(True, self.param("limits.preset"),
                                   self.param("limits.acceleration") or (),
                                   self.param("limits.jerk") or (),
                                   parameters.joint_order(self, robot.joint_names)).build(
                robot.name, robot.joint_names, robot.velocity_limits)
        except (robots.RobotModelError, ValueError) as error:
            self.get_logger().error(f"cannot use the model from {source}: {error}")
            return
        self.robot, self.plant, self.driver = robot, plant, DriverCheck(limits)
        scheduled = self.param("failure.joint")
        if scheduled and scheduled not in robot.joint_names:
            self.get_logger().error(f"failure.joint {scheduled!r} is not one of "
                                    f"{list(robot.joint_names)}: no failure scheduled")
            self.set_parameters([Parameter("failure.joint", value="")])
        if self._refuse:
            self.get_logger().info(f"driver: refusing commands over the {limits.describe()}")
        self.get_logger().info(f"simulating {robot.name} ({robot.n} joints) from {source}")

    def _plant(self, robot: robots.Robot, q: np.ndarray) -> Plant | PhysicsPlant:
        """The plant the `plant` parameter names, at q (rad).

        Raises:
            ft_core.physics.PhysicsError: a physics plant for a model MuJoCo cannot simulate.
        """
        config = settings.plant_config(parameter_table.values(self, PARAMETERS))
        if self._physics:
            return PhysicsPlant(robot, q, config, time=self.t)
        plant = Plant(robot.lower, robot.upper, robot.velocity_limits, q, config, time=self.t)
        plant.free_swing_acceleration = lambda q, qd: swing.pendulum_acceleration(robot, q, qd)
        return plant

    def _on_command(self, msg: JointStateLike) -> None:
        if self.robot is None:
            return
        try:
            velocity = convert.joint_vector(msg, self.robot.joint_names, "velocity")
        except convert.MessageError as error:
            self.get_logger().warning(f"ft/command ignored: {error}", throttle_duration_sec=5.0)
            return
        if not self._accepted(msg, velocity):
            return
        self.plant.command(self.t, velocity)

    def _accepted(self, msg: JointStateLike, velocity: np.ndarray) -> bool:
        """Whether the plant takes the command (`refuse_over_limits`: a refusal stops it)."""
        if self.reflex is not None:
            return False
        plant = self.plant
        stamp = msg.header.stamp
        refusal = self.driver.check(velocity, stamp.sec + stamp.nanosec * 1e-9,
                                    exempt=(*plant.locked, *plant.swinging,
                                            *plant.faults.faults))
        if refusal is None or not self._refuse:
            return True
        self.reflex = f"{refusal} (t = {self.t:.3f} s)"
        self.get_logger().error(f"driver reflex: command refused and the arm stopped: "
                                f"{self.reflex}; call ~/reset to take commands again")
        plant.command(self.t, np.zeros(plant.n))
        return False

    def take_commands_by_call(self) -> Callable[[JointStateLike], None]:
        """Stop subscribing to `ft/command`; returns what to call with each command instead.

        For a harness with the monitor in the same process (`ft_sim.scenario`).
        """
        self.destroy_subscription(self._command_subscription)
        return self._on_command

    @property
    def command_time(self) -> float:
        """Plant time (s) at which the newest command arrived; -inf before any."""
        return self.plant.command_time if self.plant is not None else -math.inf

    def _known(self, topic: str, joint_names: list[str]) -> dict[str, int]:
        """{name: index} of the model's joints among an injection's names.

        More than `convert.MAX_NAMES` names, or a duplicate, refuse the whole request
        unread; unknown names are dropped. Either is one rate-limited warning.
        """
        try:
            known = convert.names_to_indices(joint_names, self.robot.joint_names)
        except convert.MessageError as error:
            self.get_logger().warning(f"{topic} ignored: {error}", throttle_duration_sec=5.0)
            return {}
        if len(known) < len(joint_names):
            unknown = [name[:64] for name in joint_names if name not in known]
            self.get_logger().warning(f"{topic}: {len(unknown)} unknown joints rejected "
                                      f"{unknown[:10]}", throttle_duration_sec=5.0)
        return known

    def lock(self, joint_names: list[str]) -> None:
        """Lock joints where they are (failure injection)."""
        for name, j in self._known("inject_failure", joint_names).items():
            if name not in self.locked:
                self.plant.lock(j)
                self.get_logger().warning(f"joint {name} locked at {self.locked[name]:.4f} rad "
                                          f"(t = {self.t:.3f} s)")

    def _on_inject(self, msg: JointState) -> None:
        if self.robot is not None:
            self.lock(list(msg.name))

    def _on_declared(self, msg: JointState) -> None:
        """The driver's brakes on the monitor's word (`BasePlant.follow_declared`).

        Taken from a single publisher only, as the controller takes it (`publishers.judge`):
        a second one (a forger, a stale monitor) leaves the brakes as they are.
        """
        if self.robot is None or self.plant is None:
            return
        topic = self.resolve_topic_name(names.LOCKED_JOINTS)
        verdict = publishers.judge([publishers.full_name(p.node_namespace, p.node_name)
                                    for p in self.get_publishers_info_by_topic(topic)], None)
        if verdict.take != publishers.Take.ALL:
            self.get_logger().warning(f"locked_joints: {verdict.problem}",
                                      throttle_duration_sec=5.0)
            return
        known = self._known("locked_joints", list(msg.name))
        braked, released = self.plant.follow_declared(set(known.values()))
        for j in braked:
            self.get_logger().warning(f"joint {self.robot.joint_names[j]} braked at "
                                      f"{self.plant.position(j):.4f} rad: declared locked "
                                      f"(t = {self.t:.3f} s)")
        for j in released:
            self.get_logger().warning(f"joint {self.robot.joint_names[j]} released: no "
                                      f"longer declared locked (t = {self.t:.3f} s)")

    @property
    def swinging(self) -> list[str]:
        """Names of the joints injected free-swinging (and not braked since)."""
        if self.plant is None:
            return []
        return sorted(self.robot.joint_names[j] for j in self.plant.swinging)

    def free_swing(self, joint_names: list[str]) -> None:
        """Joints lose their torque and swing under gravity (failure injection)."""
        known = self._known("inject_free_swing", joint_names)
        if not known:
            return
        _, inertia = self.robot.gravity_dynamics(self.plant.q)
        for name, j in known.items():
            if inertia[j] <= 0:
                self.get_logger().warning(f"inject_free_swing: {name} has no inertia outboard "
                                          "in the URDF, so it cannot swing: rejected")
            elif j not in self.plant.swinging:
                self.plant.swing(j)
                self.get_logger().warning(f"joint {name} free-swinging from "
                                          f"{self.plant.q[j]:.4f} rad (t = {self.t:.3f} s)")

    def _on_free_swing(self, msg: JointState) -> None:
        if self.robot is not None:
            self.free_swing(list(msg.name))

    @property
    def faults(self) -> dict[str, list[str]]:
        """{joint name: the kinds of its faults in force} (locks and free swings included)."""
        if self.plant is None:
            return {}
        return {self.robot.joint_names[j]: kinds for j, kinds in self.plant.failures().items()}

    def inject_faults(self, faults: list[Fault]) -> None:
        """Inject `faults` together, or none of them (one warning says why).

        Raises nothing: a fault that cannot act on its joint refuses them all.
        """
        plant, index = self.plant, {n: j for j, n in enumerate(self.robot.joint_names)}
        try:
            _, inertia = self.robot.gravity_dynamics(plant.q)
            for fault in faults:
                if fault.joint not in index:
                    raise SuiteError(f"unknown joint {fault.joint[:64]!r}")
                plant.check_fault(index[fault.joint], fault)
                if fault.kind is FaultKind.FREE_SWING and inertia[index[fault.joint]] <= 0:
                    raise SuiteError(f"{fault.joint} has no inertia outboard in the URDF, so "
                                     "it cannot swing")
        except SuiteError as error:
            self.get_logger().warning(f"ft/inject_fault ignored: {error}",
                                      throttle_duration_sec=5.0)
            return
        for fault in faults:
            plant.inject(index[fault.joint], fault)
            self.get_logger().warning(f"joint {fault.joint}: {fault.describe()} from "
                                      f"{self.plant.position(index[fault.joint]):.4f} rad "
                                      f"(t = {self.t:.3f} s)")

    def _on_fault(self, msg: DiagnosticArray) -> None:
        if self.robot is None:
            return
        try:
            faults = fault_messages.read(msg, self.robot.joint_names)
        except convert.MessageError as error:
            self.get_logger().warning(f"ft/inject_fault ignored: {error}",
                                      throttle_duration_sec=5.0)
            return
        self.inject_faults(faults)

    def _on_obstacle(self, msg: Marker) -> None:
        if self.robot is None:
            return
        if not isinstance(self.plant, PhysicsPlant):
            self.get_logger().warning("ft/obstacle ignored: obstacles need the physics plant "
                                      "(plant:=physics)", once=True)
            return
        try:
            if msg.header.frame_id not in ("", self.robot.base_link):
                raise convert.MessageError(f"frame {msg.header.frame_id[:64]!r} is not the "
                                           f"base link {self.robot.base_link!r}")
            box = fault_messages.read_obstacle(msg)
        except convert.MessageError as error:
            self.get_logger().warning(f"ft/obstacle ignored: {error}", throttle_duration_sec=5.0)
            return
        if box is None:
            self.plant.remove_obstacle()
            self.get_logger().info(f"obstacle removed (t = {self.t:.3f} s)")
        else:
            self.plant.place_obstacle(*box)
            self.get_logger().info(f"obstacle: a box of {np.round(box[1], 3).tolist()} m at "
                                   f"{np.round(box[0][:3, 3], 3).tolist()} m (t = {self.t:.3f} s)")

    def _on_reset(self, _request: Trigger.Request, response: Trigger.Response):
        released = ([self.robot.joint_names[j] for j in self.plant.release()]
                    if self.plant is not None else [])
        if self.driver is not None:
            self.reflex = None
            self.driver.reset()
        response.success, response.message = True, f"released {released or 'nothing'}"
        return response

    @classmethod
    def stepped_by_hand(cls, context, values: dict, services: bool = True) -> SimNode:
        """A sim that owns the clock and moves only when `step` or `advance` is called.

        The harness of the node tests, the demo and the campaign: simulated time, as
        fast as the nodes answer. `values`: parameter name -> value; `services`: whether
        it serves its parameters (and its type description).
        """
        sim = cls(context=context, **spin.node_arguments({**values, "publish_clock": True},
                                                         services))
        sim.timer.cancel()
        return sim

    def advance(self, executor: Executor, timeout: float = 5.0) -> None:
        """One `step`, then spin until a command for the new instant has arrived.

        Raises:
            TimeoutError: no such command within `timeout` s of wall clock.
        """
        self.step()
        now = self.t
        if not spin.spin_until(executor, lambda: self.command_time >= now, timeout):
            raise TimeoutError(f"no command for simulated time {now:.3f} s within {timeout:g} s")

    def step(self) -> None:
        """Advance the plant by one period (or to the node clock) and publish."""
        if self.robot is None:
            return
        robot, plant = self.robot, self.plant
        plant.step(self.t + self.period if self._own_clock else self.now())
        scheduled = self.param("failure.joint")
        if scheduled and self.param("failure.time") <= self.t:
            self.lock([scheduled])
            self.set_parameters([Parameter("failure.joint", value="")])
        stamp = convert.stamp_from_nanoseconds(round(self.t * 1e9))
        if self._clock_pub is not None:
            self._clock_pub.publish(ClockMessage(clock=stamp))
        noise = self.param("position_noise")
        measured = plant.q + (self._rng.normal(scale=noise, size=robot.n) if noise > 0 else 0.0)
        effort = plant.torque if isinstance(plant, PhysicsPlant) else None
        self._state_pub.publish(convert.joint_state(robot.joint_names, stamp, measured,
                                                    plant.qd, effort))
        self._steps += 1
        if self._steps % self._steps_per_view == 0:
            self._publish_markers(stamp)

    def _publish_markers(self, stamp) -> None:
        """The live view (`ft_msgs_py.markers`): the arm, its failures, the tool's path.

        The path grows every `markers.PERIOD` s of plant time; the markers go out only
        while someone subscribes.
        """
        robot, plant = self.robot, self.plant
        skeleton = robot.skeleton(plant.q)
        self._trail.add(skeleton[-1])
        if not self._markers_pub.get_subscription_count():
            return
        colours = {**{j: markers.DEGRADED for j in plant.faults.faults},
                   **{j: markers.SWINGING for j in plant.swinging},
                   **{j: markers.LOCKED for j in plant.locked}}
        self._markers_pub.publish(markers.array(robot.base_link, stamp, lambda header: [
            *markers.arm(header, "arm", skeleton, colours),
            markers.line(header, "tool_path", self._trail.positions)]))


def main(args: list[str] | None = None) -> None:
    """Run the sim until SIGINT."""
    spin.run_node(SimNode, args)


if __name__ == "__main__":
    main()
