"""What a scenario injects into its sim: failures, faults of any kind, an obstacle.

`Injection` is the part of `ft_sim.scenario.Scenario` that publishes on the sim's
injection topics (`ft/inject_failure`, `ft/inject_free_swing`, `ft/inject_fault`,
`ft/obstacle`) as a user would, and returns once the sim has taken each one, so that a
scenario's steps after it see the fault in force.
"""

from __future__ import annotations

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from ft_core import faults, robots
from ft_core.errors import SuiteError
from ft_msgs_py import faults as fault_messages
from ft_msgs_py import names, qos, spin
from rclpy.executors import Executor
from rclpy.node import Node
from sensor_msgs.msg import JointState
from visualization_msgs.msg import Marker

from ft_sim.scenario_config import Record, ScenarioConfig
from ft_sim.sim_node import SimNode


class Injection:
    """Failures and obstacles by topic, each waited for (a mixin of `Scenario`)."""

    config: ScenarioConfig
    robot: robots.Robot
    record: Record
    sim: SimNode
    driver: Node
    executor: Executor

    def _create_injectors(self) -> None:
        """The driver's publishers on the sim's injection topics."""
        self._inject_pub = self.driver.create_publisher(JointState, names.INJECT_FAILURE,
                                                        qos.RELIABLE)
        self._swing_pub = self.driver.create_publisher(JointState, names.INJECT_FREE_SWING,
                                                       qos.RELIABLE)
        self._fault_pub = self.driver.create_publisher(DiagnosticArray, names.INJECT_FAULT,
                                                       qos.RELIABLE)
        self._obstacle_pub = self.driver.create_publisher(Marker, names.OBSTACLE, qos.RELIABLE)

    def inject(self, joint: str) -> None:
        """Lock `joint` through `ft/inject_failure`; returns once the sim has it locked."""
        self._publish_failure(self._inject_pub, joint, lambda: joint in self.sim.locked)
        self.record.injected_at = self.sim.t

    def _publish_failure(self, publisher, joint: str, done) -> None:
        publisher.publish(JointState(name=[joint]))
        if not spin.spin_until(self.executor, done, 5.0):
            raise TimeoutError(f"the sim did not take the failure of {joint} within 5 s")

    def inject_free_swing(self, joint: str) -> None:
        """`joint` loses its torque (`ft/inject_free_swing`); returns once the sim has it."""
        self._publish_failure(self._swing_pub, joint, lambda: joint in self.sim.swinging)

    def inject_fault(self, kind: str, joint: str, **numbers: float) -> None:
        """A fault of `kind` on `joint` through `ft/inject_fault`; returns once the sim has it.

        `numbers`: `severity`, `lower`, `upper`, `period` as the kind takes them
        (`ft_core.faults.Fault`). The first injection of a run is `Record.injected_at`.

        Raises:
            ft_core.faults.FaultError: a fault with wrong numbers.
            TimeoutError: the sim did not take it within 5 s (see its warning).
        """
        fault = faults.Fault(kind, joint, **numbers)
        self._fault_pub.publish(fault_messages.message([fault]))
        if not spin.spin_until(self.executor,
                               lambda: fault.kind in self.sim.faults.get(joint, []), 5.0):
            raise TimeoutError(f"the sim did not take {fault.describe()} on {joint} within 5 s")
        if self.record.injected_at is None:
            self.record.injected_at = self.sim.t

    def place_obstacle(self, pose: np.ndarray, size: tuple[float, float, float]) -> None:
        """A box of edges `size` (m) at `pose` (4x4, base frame) through `ft/obstacle`.

        Returns once the sim has it. Raises SuiteError on the kinematic plant (it has
        no contacts) and TimeoutError if the sim did not take it within 5 s.
        """
        if self.config.plant != "physics":
            raise SuiteError("obstacles need the physics plant")
        self._obstacle_pub.publish(fault_messages.obstacle_message(pose, size,
                                                                   self.robot.base_link))
        obstacle = self.sim.plant.obstacle if self.sim.plant is not None else None
        if not spin.spin_until(self.executor, lambda: self.sim.plant.obstacle is not obstacle
                               and self.sim.plant.obstacle is not None, 5.0):
            raise TimeoutError("the sim did not place the obstacle within 5 s")

    def remove_obstacle(self) -> None:
        """Remove the obstacle through `ft/obstacle`; returns once the sim has."""
        self._obstacle_pub.publish(Marker(action=Marker.DELETE))
        if not spin.spin_until(self.executor, lambda: self.sim.plant.obstacle is None, 5.0):
            raise TimeoutError("the sim did not remove the obstacle within 5 s")

    def _inject_configured(self) -> None:
        """The config's `fault` on `lock_joint`, now: a lock by `ft/inject_failure`."""
        cfg, robot = self.config, self.robot
        j = robot.joint_names.index(cfg.lock_joint)
        fault = faults.from_spec(cfg.fault, cfg.lock_joint, float(self.sim.q[j]),
                                 float(robot.lower[j]), float(robot.upper[j]))
        if fault.kind is faults.FaultKind.LOCK:
            self.inject(cfg.lock_joint)
        else:
            self.inject_fault(fault.kind, fault.joint, **{
                key: getattr(fault, key) for key in fault.kind.fields})
