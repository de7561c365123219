"""The controller's parameters: one declarative table, and the core's configurations from it.

`PARAMETERS` writes each parameter once (`ft_msgs_py.parameter_table.Setting`):
`ControllerNode` declares and checks it (`ft_msgs_py.parameter_table`),
docs/controller.md's table is generated from it (tools/param_tables.py), and every
default that configures the core is its dataclass's own (`EngineConfig`,
`ControllerConfig`, `PoseTracking`, `ObservabilityConfig`, `RecoveryConfig`).
`engine_config` and `controller_config` turn parameter values into the core's
configurations without a node; the node validates a change by building them (and
`check_config`), never an engine.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np
from ft_core import limits
from ft_core.command_limits import limits_config
from ft_core.controller import ControllerConfig
from ft_core.engine import RESOLUTIONS, EngineConfig
from ft_core.observability import ObservabilityConfig
from ft_core.recovery import RecoveryConfig
from ft_core.targets import PoseTracking
from ft_msgs_py import parameters
from ft_msgs_py.parameter_table import Setting
from rclpy.parameter import Parameter

#: s of steady time without the monitor's echo before the guard commands zeros
#: (`ft_msgs_py.monitor_guard`): 5 cycles at 100 Hz; the echo normally takes a few ms.
#: Each 10 ms more lets a dead monitor's last command run on 10 ms longer.
MONITOR_TIMEOUT = 0.05

#: The defaults of every parameter that configures the core: its dataclasses' own.
_ENGINE, _CYCLE = EngineConfig(), ControllerConfig()
_TRACKING, _OBSERVABILITY = _CYCLE.tracking, ObservabilityConfig()
_RECOVERY = RecoveryConfig()

#: Largest soft limit magnitude (rad, m for a prismatic joint): beyond it, no joint's.
SOFT_LIMIT_BOUND = 1e3
#: Smallest useful gain: a positive gain below it moves no joint measurably (0: off).
SMALLEST_GAIN = 1e-3

#: The controller's parameters, in declaration order.
PARAMETERS: dict[str, Setting] = {
    **parameters.MODEL_PARAMETERS,
    **parameters.THREAD_PRIORITY,
    **parameters.COMMAND_LIMITS,
    "resolution": Setting(_ENGINE.resolution, "redundancy resolution", choices=RESOLUTIONS),
    "kfm_gain": Setting(_ENGINE.kfm_gain, "kfm gradient ascent, rad/s per (m/rad)",
                        (SMALLEST_GAIN, 1e4), off=0.0),
    "swing_gain": Setting(_ENGINE.swing_gain, "swing-measure descent for free-swinging "
                          "failures, rad/s per rad (0: off; needs the URDF's inertias, "
                          "refused without)", (SMALLEST_GAIN, 100.0), off=0.0),
    "jump_gain": Setting(_ENGINE.jump_gain, "minimum-jump term (1 = exact)",
                         (SMALLEST_GAIN, 100.0), off=0.0),
    "limit_gain": Setting(_ENGINE.limit_gain, "soft/hard limit avoidance, rad/s at a box edge",
                          (SMALLEST_GAIN, 100.0), off=0.0),
    "failure_probabilities": Setting(Parameter.Type.DOUBLE_ARRAY, "one per joint in `joints` "
                                     "order (empty: equal)", (0.0, 1e6)),
    "soft_limits.lower": Setting(Parameter.Type.DOUBLE_ARRAY, "rad, `joints` order (empty: "
                                 "none)", (-SOFT_LIMIT_BOUND, SOFT_LIMIT_BOUND)),
    "soft_limits.upper": Setting(Parameter.Type.DOUBLE_ARRAY, "rad, `joints` order (empty: "
                                 "none)", (-SOFT_LIMIT_BOUND, SOFT_LIMIT_BOUND)),
    "critical_points": Setting(Parameter.Type.DOUBLE_ARRAY, "task points concatenated (pose: "
                               "x y z qx qy qz qw); their intersected self-motion boxes become "
                               "soft limits", (-limits.ABSURD_DISTANCE, limits.ABSURD_DISTANCE)),
    "release_soft_limits_on_failure": Setting(_ENGINE.release_soft_limits_on_failure,
                                              "drop the soft limits once a joint is locked"),
    "control_rate": Setting(1.0 / _ENGINE.dt, "Hz", (1.0, 2000.0)),
    "target_timeout": Setting(_CYCLE.target_timeout, "s; an older twist decays to 0 over one "
                              "more timeout", (0.001, 60.0)),
    "state_timeout": Setting(_CYCLE.state_timeout, "s; older joint states stop the arm",
                             (0.001, 60.0)),
    "monitor_timeout": Setting(MONITOR_TIMEOUT, "s (steady) without the monitor's answer to a "
                               "command before the controller publishes zeros on ft/command "
                               "and ft/command_array itself (the monitor answers every 5 ms, "
                               "so keep it well above that)", (0.01, 60.0)),
    "position_gain": Setting(_TRACKING.gain, "1/s, pose-goal tracking", (0.01, 100.0)),
    "max_linear_speed": Setting(_TRACKING.max_linear, "m/s, pose-goal tracking",
                                (0.001, 10.0)),
    "max_angular_speed": Setting(_TRACKING.max_angular, "rad/s, pose-goal tracking",
                                 (0.001, 10.0)),
    "velocity_scale": Setting(_ENGINE.velocity_scale, "fraction of the URDF velocity limits",
                              (0.01, 1.0)),
    "monitor_name": Setting("monitor", "node name of the only accepted ft/locked_joints "
                            "publisher, in this namespace unless absolute (empty: any single "
                            "publisher)", read_only=True),
    "idle_null_space_motion": Setting(_CYCLE.idle_null_space_motion, "with no target, allow "
                                      "null-space motion (kfm ascent, limit avoidance); "
                                      "otherwise hold still"),
    "recovery.enabled": Setting(_CYCLE.recovery is not None, "when a pose goal's error stops "
                                "improving, move along a joint path to an IK solution with the "
                                "locked joints pinned (planned in a worker process)"),
    "recovery.stall_time": Setting(_RECOVERY.stall_time, "s without progress towards a pose "
                                   "goal before recovering", (0.05, 60.0)),
    "observability.enabled": Setting(_CYCLE.observability is not None, "null-space excursions "
                                     "of joints not commanded for observability.idle_time, so "
                                     "that a lock on them shows up"),
    "observability.idle_time": Setting(_OBSERVABILITY.idle_time, "s a joint may go uncommanded "
                                       "before an excursion", (0.01, 3600.0)),
    "observability.speed": Setting(_OBSERVABILITY.speed, "rad/s, peak joint velocity of an "
                                   "excursion", (0.06, 10.0)),
    "observability.duration": Setting(_OBSERVABILITY.duration, "s, one excursion (out and "
                                      "back)", (0.01, 60.0)),
}


def engine_config(value: Mapping[str, object], order: np.ndarray) -> EngineConfig:
    """The engine's configuration from every parameter's `value` (name -> value).

    `order[k]`: the chain index of the k-th joint of the command order, in which the
    per-joint parameters are given. Without the critical points' box: the core
    intersects it with these limits. Raises ValueError for per-joint values of the wrong
    length or not finite, and what `EngineConfig` refuses.
    """
    probabilities = list(value["failure_probabilities"] or [])
    if probabilities:
        probabilities = list(_chain(probabilities, order, "failure_probabilities"))
    sides = [_chain(value[name], order, name) if value[name] else None
             for name in ("soft_limits.lower", "soft_limits.upper")]
    # One side alone (set one at a time through SetParameters): no soft limits yet.
    box = None if any(side is None for side in sides) else tuple(sides)
    return EngineConfig(
        resolution=value["resolution"], kfm_gain=value["kfm_gain"],
        swing_gain=value["swing_gain"],
        jump_gain=value["jump_gain"], limit_gain=value["limit_gain"],
        failure_probabilities=tuple(probabilities),
        soft_lower=() if box is None else box[0], soft_upper=() if box is None else box[1],
        release_soft_limits_on_failure=value["release_soft_limits_on_failure"],
        dt=1.0 / value["control_rate"], velocity_scale=value["velocity_scale"])


def controller_config(value: Mapping[str, object],
                      order: np.ndarray | None = None) -> ControllerConfig:
    """The core's settings from every parameter's `value`; ValueError where they refuse it.

    `order` as for `engine_config` (None: per-joint values in chain order).
    """
    observability = ObservabilityConfig(value["observability.idle_time"],
                                        value["observability.speed"],
                                        value["observability.duration"])
    return ControllerConfig(
        state_timeout=value["state_timeout"], target_timeout=value["target_timeout"],
        idle_null_space_motion=value["idle_null_space_motion"],
        tracking=PoseTracking(value["position_gain"], value["max_linear_speed"],
                              value["max_angular_speed"]),
        observability=observability if value["observability.enabled"] else None,
        recovery=replace(_RECOVERY, stall_time=value["recovery.stall_time"])
        if value["recovery.enabled"] else None,
        limits=limits_config(value["smooth_commands"], value["limits.preset"],
                             value["limits.acceleration"] or (), value["limits.jerk"] or (),
                             order))


def _chain(values: object, order: np.ndarray, what: str) -> np.ndarray:
    """Per-joint values given in command order, put in chain order."""
    values = np.asarray(values, dtype=float)
    if values.shape != (order.size,) or not np.all(np.isfinite(values)):
        raise ValueError(f"{what} needs {order.size} finite values, got {values.size}"
                         + (" with a non-finite one" if values.size == order.size else ""))
    chain = np.empty(order.size)
    chain[order] = values
    return chain
