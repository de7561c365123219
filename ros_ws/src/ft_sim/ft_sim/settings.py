"""The sim's and the fault injector's parameters: one declarative table each.

`PARAMETERS` (the sim) and `FAULT_INJECTOR` write each parameter once
(`ft_msgs_py.parameter_table.Setting`): the nodes declare and check them, docs/sim.md's
tables are generated from them (tools/param_tables.py), and the plant's defaults are
`PlantConfig`'s own. `plant_config` turns parameter values into the plant's
configuration without a node.
"""

from __future__ import annotations

from collections.abc import Mapping

from ft_core.plant import PlantConfig
from ft_msgs_py import parameters
from ft_msgs_py.parameter_table import Setting
from rclpy.parameter import Parameter

#: The plants the `plant` parameter names.
PLANTS = ("kinematic", "physics")
#: Latest plant time (s) a failure may be scheduled at: about eleven days.
LATEST_FAILURE = 1e6

_PLANT = PlantConfig()

#: The sim's parameters, in declaration order.
PARAMETERS: dict[str, Setting] = {
    **parameters.MODEL_PARAMETERS,
    "plant": Setting("kinematic", "kinematic (any model) or physics (MuJoCo; needs the URDF's "
                     "inertias)", choices=PLANTS, read_only=True),
    "initial_positions": Setting(Parameter.Type.DOUBLE_ARRAY, "rad, `joints` order (empty: the "
                                 "model's home configuration)", read_only=True),
    "rate": Setting(500.0, "Hz, integration and joint_states rate", (1.0, 10000.0),
                    read_only=True),
    "position_noise": Setting(0.0, "rad, standard deviation of the published positions",
                              (0.0, 1.0)),
    "command_latency": Setting(_PLANT.latency, "s from a command's arrival to its effect",
                               (0.0, 10.0)),
    "command_timeout": Setting(_PLANT.timeout, "s; older commands are dropped (the arm stops)",
                               (0.001, 60.0)),
    "response_time": Setting(_PLANT.response_time, "s, first-order time constant of the "
                             "velocity loop (0: instant)", (0.0, 10.0)),
    "acceleration_limit": Setting(list(_PLANT.acceleration_limit), "rad/s^2, one for all "
                                  "joints or one per joint (0: none)", (0.0, 1e6)),
    "hold_last_command": Setting(_PLANT.hold_last_command, "execute the last command forever "
                                 "(ros2_control) instead of stopping after command_timeout"),
    "publish_clock": Setting(False, "own the time: start at 0 and publish /clock",
                             read_only=True),
    "seed": Setting(0, "seed of the position noise", (0, 2**31 - 1), read_only=True),
    "refuse_over_limits": Setting(False, "refuse (and stop the arm on) a command over the "
                                  "arm's velocity, acceleration or jerk limits, as a real "
                                  "driver does", read_only=True),
    **{k: v for k, v in parameters.COMMAND_LIMITS.items() if k.startswith("limits.")},
    "failure.joint": Setting("", "joint to lock at failure.time (empty: none); one of the "
                             "model's joints"),
    "failure.time": Setting(0.0, "s of plant time at which failure.joint locks (at the next "
                            "step if already past)", (0.0, LATEST_FAILURE)),
}

#: The fault injector's parameters.
FAULT_INJECTOR: dict[str, Setting] = {
    "joints": Setting(Parameter.Type.STRING_ARRAY, "joint order of ft/command_array (needed "
                      "only for the array)", read_only=True),
}


def plant_config(value: Mapping[str, object]) -> PlantConfig:
    """The plant's configuration from the parameters' `value` (name -> value)."""
    return PlantConfig(latency=value["command_latency"], response_time=value["response_time"],
                       acceleration_limit=tuple(float(a) for a in value["acceleration_limit"]),
                       timeout=value["command_timeout"],
                       hold_last_command=value["hold_last_command"])
