"""Model-selection parameters shared by every node, and where the model comes from.

`robot_description` (URDF XML) if set, else `robot_model` (a built-in name or a URDF
path), else the `robot_description` topic (std_msgs/String, transient local, as
robot_state_publisher provides it): the first description the node can use is
kept, and a different one arriving later is refused with an ERROR (a node never
changes robots, limits included, on its own) until `~/reload_model` is called.
They are read-only once the node runs.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import String
from std_srvs.srv import Trigger

from ft_msgs_py import names, qos, rclpy_private, thread_priority

#: Most values an array parameter may hold (critical points: 1365 positions).
MAX_ARRAY = 4096


def float_range(low: float, high: float) -> dict:
    """Descriptor fields for a floating-point parameter allowed in [low, high]."""
    return {"floating_point_range": [FloatingPointRange(from_value=low, to_value=high)]}


def int_range(low: int, high: int) -> dict:
    """Descriptor fields for an integer parameter allowed in [low, high]."""
    return {"integer_range": [IntegerRange(from_value=low, to_value=high, step=1)]}


#: The nodes on the command path (controller, monitor): `thread_priority.apply` at start.
THREAD_PRIORITY = {
    "thread_priority": (0, "SCHED_FIFO priority (1-99) of the thread running the callbacks; "
                        "0: the normal scheduler. Needs root or an rtprio limit (refused: a "
                        "warning)",
                        {"read_only": True, **int_range(0, thread_priority.MAX_PRIORITY)}),
}

#: The limits of the commands of the nodes on the command path (controller, monitor):
#: `ft_core.command_limits.limits_config` makes their configuration.
COMMAND_LIMITS = {
    "smooth_commands": (True, "keep every command within the arm's acceleration and jerk "
                        "limits (false: raw steps, which a real driver refuses; for "
                        "comparisons)", {"read_only": True}),
    "limits.preset": ("auto", "acceleration and jerk limits: auto (franka_panda, ur or xarm "
                      "recognised from the URDF, else default), franka_panda, xarm, ur or "
                      "default", {"read_only": True}),
    "limits.acceleration": (Parameter.Type.DOUBLE_ARRAY, "rad/s^2, one for all joints or one "
                            "per joint in `joints` order (empty: the preset's)",
                            {"read_only": True}),
    "limits.jerk": (Parameter.Type.DOUBLE_ARRAY, "rad/s^3, one for all joints or one per "
                    "joint in `joints` order (empty: the preset's)", {"read_only": True}),
}

#: name -> (default, description, extra descriptor fields)
MODEL_PARAMETERS: dict[str, tuple[object, str, dict]] = {
    "robot_description": ("", "URDF XML; empty: use robot_model", {"read_only": True}),
    "robot_model": ("", "built-in name (planar3r, puma560, panda, panda_inertial, iiwa14) or "
                    "URDF path; "
                    "empty too: wait for the robot_description topic", {"read_only": True}),
    "base_link": ("", "first link of the chain (empty: the URDF root)", {"read_only": True}),
    "tip_link": ("", "tool link (empty: where the chain branches)", {"read_only": True}),
    "joints": (Parameter.Type.STRING_ARRAY, "command order of the chain's joints (empty: "
               "base to tip)", {"read_only": True}),
    "task_space": ("", "pose, position or planar (empty: the model's default)",
                   {"read_only": True}),
    "characteristic_length": (0.0, "m; scales angular rows (0: the robot's reach)",
                              {"read_only": True, **float_range(0.0, 100.0)}),
}


def declare(node: Node, parameters: dict[str, tuple[object, str, dict]]) -> None:
    """Declare parameters with descriptions, types and ranges; every one has a value.

    A default given as a `Parameter.Type` (the arrays) declares a typed parameter whose
    value is an empty array of that type unless set: `[]` in a parameters file (as `ros2
    param dump` writes it) loads back as that. Never "not set": rclpy's get_parameters
    service answers nothing at all to a request that names an uninitialized parameter,
    so `ros2 param dump` would print `ros__parameters: {}` for the whole node. An invalid
    start-up value is logged and replaced by the default, so a typo in a launch file
    does not stop the node.
    """
    for name, (default, description, extra) in parameters.items():
        descriptor = ParameterDescriptor(description=description, **extra)
        try:
            node.declare_parameter(name, default, descriptor)
        except (InvalidParameterValueException, InvalidParameterTypeException) as error:
            shown = "an empty list" if isinstance(default, Parameter.Type) else repr(default)
            node.get_logger().error(f"{error}; using the default, {shown}")
            node.declare_parameter(name, default, descriptor, ignore_override=True)
        if node.get_parameter_or(name).type_ == Parameter.Type.NOT_SET:
            # rclpy's public declare_parameter takes no typed empty value.
            rclpy_private.set_as_declared(node, Parameter(name, default, []))


def value(node: Node, name: str):
    """A parameter's value."""
    return node.get_parameter(name).value


def check_sizes(changes: dict) -> None:
    """Refuse an array parameter of more than `MAX_ARRAY` values (ValueError, short reason).

    Checked before anything reads the values, so a huge array costs neither the time
    to check every value nor a reason as long as the array.
    """
    for name, given in changes.items():
        if isinstance(given, (list, tuple, np.ndarray)) and len(given) > MAX_ARRAY:
            raise ValueError(f"{name} has {len(given)} values (at most {MAX_ARRAY})")


def on_change(node: Node, check: Callable[[dict], object], apply: Callable[[], None]) -> None:
    """Validate parameter changes with `check({name: value})`, then `apply()` them.

    `check` raises ValueError or TypeError to refuse the whole change, with its
    message as the reason; the node keeps its previous configuration. Arrays are
    bounded first (`check_sizes`).
    """
    def validate(params: list) -> SetParametersResult:
        try:
            changes = {p.name: p.value for p in params}
            check_sizes(changes)
            check(changes)
        except (ValueError, TypeError) as error:
            return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(validate)
    node.add_post_set_parameters_callback(lambda _: apply())


def request_model(node: Node, use: Callable[[str, str], None]) -> None:
    """Call `use(spec, source)` with the model spec from the parameters or, later, the topic.

    From the topic, the first description the node can use is kept; a different one
    arriving later is refused with an ERROR until someone calls `~/reload_model`
    (std_srvs/Trigger), which adopts the newest description (the node must then get
    joint states of the new robot). A model from the parameters is never reloaded.
    """
    description = node.get_parameter("robot_description").value
    model = node.get_parameter("robot_model").value
    state: dict[str, str | None] = {"accepted": None, "newest": None}

    def adopt(text: str, source: str) -> bool:
        before = getattr(node, "robot", None)
        use(text, source)
        robot = getattr(node, "robot", None)
        if robot is not None and robot is not before:
            state["accepted"] = text
            return True
        return False

    def on_description(msg: String) -> None:
        state["newest"] = msg.data
        if state["accepted"] is None:
            adopt(msg.data, "the robot_description topic")
        elif msg.data != state["accepted"]:
            node.get_logger().error(
                "a different robot_description arrived while running: ignored (call "
                f"{names.RELOAD_MODEL} to adopt it, with the commands stopped)",
                throttle_duration_sec=10.0)

    def reload(_request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        if description or model:
            response.success, response.message = False, (
                "the model comes from the robot_description or robot_model parameter: "
                "restart the node to change it")
        elif state["newest"] is None or state["newest"] == state["accepted"]:
            response.success, response.message = True, "already using the newest description"
        elif adopt(state["newest"], "the robot_description topic (reload)"):
            robot = getattr(node, "robot", None)
            response.success, response.message = True, f"now using {getattr(robot, 'name', '?')}"
        else:
            response.success, response.message = False, ("the newest description cannot be "
                                                         "used (see the log): model kept")
        return response

    node.create_service(Trigger, names.RELOAD_MODEL, reload)
    if description:
        use(description, "the robot_description parameter")
    elif model:
        use(model, f"robot_model '{model}'")
    else:
        node.get_logger().info("no robot_description or robot_model parameter: waiting for "
                               f"the '{names.ROBOT_DESCRIPTION}' topic")
        node.create_subscription(String, names.ROBOT_DESCRIPTION, on_description, qos.LATCHED)


def joint_order(node: Node, chain: Sequence[str]) -> np.ndarray:
    """Chain index of each name of the `joints` parameter (command order).

    Empty `joints`: the chain's own order. Raises ValueError unless `joints` lists
    each of the chain's joints exactly once.
    """
    joints = [str(j) for j in value(node, "joints")]
    if not joints:
        return np.arange(len(chain))
    if sorted(joints) != sorted(chain):
        raise ValueError(f"joints {joints} must list each of {list(chain)} once")
    return np.array([list(chain).index(j) for j in joints])


def chain_arguments(node: Node) -> tuple[str | None, str | None, str | None, float | None]:
    """(base_link, tip_link, task_space, characteristic_length) for `ft_core.robots.load`.

    Each is None where the parameter holds its "use the model's own" value.
    """
    base, tip, task, length = (value(node, name) or None for name in
                               ("base_link", "tip_link", "task_space", "characteristic_length"))
    return base, tip, task, length
