"""fault_injector_node: lock joints of a plant we do not own (Gazebo, hardware).

A proxy on the command path: it forwards `ft/command` (JointState) to
`faulty/command` and `ft/command_array` (Float64MultiArray, in `joints` order) to
`faulty/command_array`, with the commands of locked joints forced to exactly 0.
Remap the outputs to the plant's command topics. `ft/inject_failure` (names) locks
joints from now on; `~/reset` releases them. Unknown names are rejected with a
warning. A malformed command (non-finite or beyond `MAX_SPEED`, duplicate names,
names outside `joints`, wrong lengths, more than `convert.MAX_NAMES` names) never
reaches the plant: explicit zeros for `joints` go out instead (with `joints` unset,
nothing: the plant's own timeout then stops it).
"""

from __future__ import annotations

import numpy as np
from ft_msgs_py import convert, names, parameter_table, qos, spin
from ft_msgs_py.node import SuiteNode
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from ft_sim.settings import FAULT_INJECTOR

#: Fastest joint velocity forwarded (rad/s or m/s): beyond it no arm joint moves.
MAX_SPEED = 100.0
OUTPUT_COMMAND = "faulty/command"
OUTPUT_COMMAND_ARRAY = "faulty/command_array"


#: Its parameters (`ft_sim.settings.FAULT_INJECTOR`).
PARAMETERS = FAULT_INJECTOR


class FaultInjectorNode(SuiteNode):
    """The command-path proxy; see the module docstring."""

    def __init__(self, **kwargs):
        super().__init__("fault_injector", **kwargs)
        parameter_table.declare(self, PARAMETERS)
        self.joints = [str(j) for j in self.param("joints")]
        self.locked: set[str] = set()
        self._out = self.create_publisher(JointState, OUTPUT_COMMAND, qos.RELIABLE)
        self._out_array = self.create_publisher(Float64MultiArray, OUTPUT_COMMAND_ARRAY,
                                                qos.RELIABLE)
        self.create_subscription(JointState, names.COMMAND, self._on_command, qos.SENSOR_INPUT)
        self.create_subscription(Float64MultiArray, names.COMMAND_ARRAY, self._on_array,
                                 qos.SENSOR_INPUT)
        self.create_subscription(JointState, names.INJECT_FAILURE, self._on_inject, qos.RELIABLE)
        self.create_service(Trigger, names.RESET, self._on_reset)

    def _on_inject(self, msg: JointState) -> None:
        known = set(self.joints) if self.joints else None
        for name in msg.name:
            if known is not None and name not in known:
                self.get_logger().warning(f"inject_failure: unknown joint {name!r} rejected")
                continue
            if name not in self.locked:
                self.locked.add(name)
                self.get_logger().warning(f"joint {name} locked on the command path")

    def _on_reset(self, _request: Trigger.Request, response: Trigger.Response):
        response.success, response.message = True, f"released {sorted(self.locked) or 'nothing'}"
        self.locked.clear()
        return response

    def _check(self, names: list[str], velocity: np.ndarray) -> str | None:
        """Why a command must not reach the plant, or None."""
        try:
            convert.names_to_indices(names, self.joints or names)
        except convert.MessageError as error:
            return str(error)
        if self.joints and not set(names) <= set(self.joints):
            return f"unknown joints {sorted(set(names) - set(self.joints))[:10]}"
        if velocity.size != len(names):
            return f"{len(names)} names but {velocity.size} velocities"
        if not np.all(np.isfinite(velocity)) or np.any(np.abs(velocity) > MAX_SPEED):
            return f"velocities not finite or beyond {MAX_SPEED:g} rad/s"
        return None

    def _refuse(self, topic: str, reason: str) -> None:
        """Explicit zeros (for the known joints) instead of a malformed command."""
        self.get_logger().error(f"{topic}: {reason}: forwarding zeros", throttle_duration_sec=5.0)
        if self.joints:
            zeros = np.zeros(len(self.joints))
            self._out.publish(convert.joint_state(self.joints, self.get_clock().now().to_msg(),
                                                  velocity=zeros))
            self._out_array.publish(Float64MultiArray(data=zeros.tolist()))

    def _on_command(self, msg: JointState) -> None:
        names, velocity = list(msg.name), np.asarray(msg.velocity, dtype=float)
        reason = self._check(names, velocity)
        if reason is not None:
            self._refuse("ft/command", reason)
            return
        velocity[[i for i, name in enumerate(names) if name in self.locked]] = 0.0
        self._out.publish(convert.joint_state(names, msg.header.stamp, velocity=velocity))

    def _on_array(self, msg: Float64MultiArray) -> None:
        data = np.asarray(msg.data, dtype=float)
        if len(data) != len(self.joints):
            reason = f"needs {len(self.joints)} values (the `joints` parameter), got {len(data)}"
        else:
            reason = self._check(self.joints, data)
        if reason is not None:
            self._refuse("ft/command_array", reason)
            return
        data[[i for i, j in enumerate(self.joints) if j in self.locked]] = 0.0
        self._out_array.publish(Float64MultiArray(layout=msg.layout, data=data.tolist()))


def main(args: list[str] | None = None) -> None:
    """Run the proxy until SIGINT."""
    spin.run_node(FaultInjectorNode, args)


if __name__ == "__main__":
    main()
