"""The monitor's parameters: one declarative table, and the core's configurations from it.

`PARAMETERS` writes each parameter once (`ft_msgs_py.parameter_table.Setting`):
`MonitorNode` declares and checks it, docs/monitor.md's table is generated from it
(tools/param_tables.py), and every default that configures the core is its dataclass's
own (`DetectorConfig`, `MonitorConfig`). `configs` turns parameter values into the
core's configurations without a node.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from ft_core.command_limits import limits_config
from ft_core.detection import DECISION_PERIOD, IDENTIFY_PERIOD, DetectorConfig
from ft_core.monitor import MonitorConfig
from ft_msgs_py import parameters
from ft_msgs_py.parameter_table import Setting
from rclpy.parameter import Parameter

_DETECTION, _MONITOR = DetectorConfig(), MonitorConfig()

#: The monitor's parameters, in declaration order.
PARAMETERS: dict[str, Setting] = {
    **parameters.MODEL_PARAMETERS,
    **parameters.THREAD_PRIORITY,
    **parameters.COMMAND_LIMITS,
    "detection.window": Setting(_DETECTION.window, "s, sliding window of the comparison",
                                (0.005, 10.0)),
    "detection.min_command": Setting(_DETECTION.min_command, "rad/s; smaller predicted motion "
                                     "is unobservable (no decision)", (0.0, 10.0)),
    "detection.latency": Setting(Parameter.Type.DOUBLE_ARRAY, "s from a command to its effect "
                                 "on the measurements: one value (empty: identified online)",
                                 (0.0, 1.0)),
    "detection.response_time": Setting(Parameter.Type.DOUBLE_ARRAY, "s, first-order time "
                                       "constant of the plant's velocity loop: one value "
                                       "(empty: identified online)", (0.0, 1.0)),
    "detection.persistence": Setting(_DETECTION.persistence, "s the lock evidence must hold "
                                     "(at least one decision period)",
                                     (DECISION_PERIOD, 10.0)),
    "detection.ratio": Setting(_DETECTION.ratio, "measured over predicted velocity below "
                               "which a joint looks locked", (0.01, 0.99)),
    "detection.confidence": Setting(_DETECTION.confidence, "separation in standard errors",
                                    (0.5, 50.0)),
    "detection.follow_time": Setting(_DETECTION.follow_time, "s the plant must be seen "
                                     "following commands before any decision (at least one "
                                     "identification period)", (IDENTIFY_PERIOD, 10.0)),
    "brake_free_swinging": Setting(_MONITOR.brake_free_swinging, "declare a free-swinging "
                                   "joint locked where it is (ask for its brake) instead of "
                                   "only reporting it"),
    "remap_commands": Setting(_MONITOR.remap_commands, "remap commands through the reduced "
                              "Jacobian once joints lock"),
    "command_timeout": Setting(0.2, "s without a command before the watchdog publishes zeros",
                               (0.001, 60.0)),
    "velocity_scale": Setting(_MONITOR.velocity_scale, "fraction of the URDF velocity limits "
                              "for remapped commands", (0.01, 1.0)),
    "state_directory": Setting("", "directory of the persisted locked set (empty: "
                               "$ROS_HOME/ft_arms, or ~/.ros/ft_arms)", read_only=True),
}


def _one(values: object, name: str) -> float | None:
    """The value of a parameter given as one value or none (None: identified online)."""
    given = list(values or [])
    if len(given) > 1:
        raise ValueError(f"{name} takes one value or none (identified online), got "
                         f"{len(given)}")
    return float(given[0]) if given else None


def configs(value: Mapping[str, object], order: np.ndarray | None = None,
            ) -> tuple[DetectorConfig, MonitorConfig]:
    """The core's configurations from every parameter's `value` (name -> value).

    `order[k]`: the chain index of the k-th joint of the command order, in which the
    per-joint limits are given (None: chain order). Raises ValueError where the
    configurations refuse the values.
    """
    detection = DetectorConfig(
        window=value["detection.window"], min_command=value["detection.min_command"],
        latency=_one(value["detection.latency"], "detection.latency"),
        response_time=_one(value["detection.response_time"], "detection.response_time"),
        persistence=value["detection.persistence"], ratio=value["detection.ratio"],
        confidence=value["detection.confidence"], follow_time=value["detection.follow_time"])
    return detection, MonitorConfig(
        remap_commands=value["remap_commands"], velocity_scale=value["velocity_scale"],
        brake_free_swinging=value["brake_free_swinging"],
        limits=limits_config(value["smooth_commands"], value["limits.preset"],
                             value["limits.acceleration"] or (), value["limits.jerk"] or (),
                             order))
