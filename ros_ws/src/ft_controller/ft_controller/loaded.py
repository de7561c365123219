"""What the controller node builds once it adopts a robot model, and what it reports of it.

`Loaded` holds the model, the core and the command-order wiring; `metric_values`,
`core_values`, `joint_statuses` and `level_and_message` turn the core's state into
`ft/metrics` and `/diagnostics` (`ft_msgs_py.metrics`, `ft_msgs_py.diagnostics`), `view`
into the live view's markers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from ft_core import selfmotion
from ft_core.controller import Controller
from ft_core.engine import CycleResult
from ft_core.health import Health
from ft_core.robots import Robot
from ft_core.targets import PoseTarget
from ft_msgs_py import diagnostics, markers, metrics, wire
from ft_msgs_py.episodes import Episodes
from ft_msgs_py.loop import LoopAccounting
from std_msgs.msg import Float64MultiArray


@dataclass
class Loaded:
    """The robot model in use and what is built from it.

    Attributes:
        robot: the chain.
        core: the per-cycle logic (`ft_core.controller.Controller`).
        order: order[k] is the chain index of the k-th joint of the command order.
        joints: joint names in command order.
        labels: `ft/metrics` labels (`ft_msgs_py.metrics.labels`).
        writer: the command's bytes, refilled each cycle (`wire.CommandWriter`).
        metrics_msg: `ft/metrics`, refilled each cycle.
    """

    robot: Robot
    core: Controller
    order: np.ndarray
    joints: list[str] = field(init=False)
    labels: list[str] = field(init=False)
    writer: wire.CommandWriter = field(init=False)
    metrics_msg: Float64MultiArray = field(init=False)
    last_result: CycleResult | None = None  #: the last cycle's engine result

    @property
    def last_metrics(self) -> dict[str, float]:
        """The last cycle's `ft/metrics` by label, published or not (empty before any)."""
        if self.last_result is None:
            return {}
        return dict(zip(self.labels, metric_values(self.last_result, self.order), strict=True))

    def suspect_message(self, joint: int) -> str:
        """The log line of a lock the task-space channel suspects (chain index `joint`)."""
        return (f"task error not decreasing while joints are commanded: "
                f"{self.robot.joint_names[joint]}'s loss explains the motion (residual "
                f"{self.core.channel.residuals[joint]:.2f} of the unexplained motion); "
                "suspected, for the monitor to decide")

    def __post_init__(self) -> None:
        self.joints = [self.robot.joint_names[i] for i in self.order]
        self.labels = metrics.labels(self.joints)
        self.writer = wire.CommandWriter(self.joints)
        self.metrics_msg = metrics.template(self.labels)

    @property
    def suspected_lock(self) -> str | None:
        """The joint the task-space channel suspects now, if any."""
        suspect = self.core.suspect
        return None if suspect is None else self.robot.joint_names[suspect]

    def names(self, joints: object) -> list[str]:
        """Chain indices to joint names."""
        return [self.robot.joint_names[j] for j in joints]  # type: ignore[attr-defined]

    def indices(self, names: object) -> list[int]:
        """Joint names to chain indices."""
        return [self.robot.joint_names.index(name) for name in names]  # type: ignore[attr-defined]


def metric_values(result: CycleResult, order: np.ndarray) -> list[float]:
    """A cycle's `ft/metrics` values, in label order (`ft_msgs_py.metrics`)."""
    sigmas = result.post_failure_sigmas[order]
    return [result.kfm, result.sigma_min, result.jump_index, result.task_scale,
            result.soft_limit_margin if math.isfinite(result.soft_limit_margin)
            else metrics.NO_SOFT_BOX,
            *np.where(np.isfinite(sigmas), sigmas, metrics.LOCKED).tolist()]


def joint_statuses(loaded: Loaded, status) -> list[DiagnosticStatus]:
    """One diagnostic per joint (command order) from the last cycle: locked, health, limits.

    `status(level, message, values, joint=name)` makes each (`SuiteNode.status`).
    """
    last = loaded.core.last
    if last is None:
        return []
    locked_names = set(loaded.names(loaded.core.locked))
    health, pinned = loaded.core.adaptation.health, loaded.core.pinned
    statuses = []
    for joint, i in zip(loaded.joints, loaded.order, strict=True):
        locked = joint in locked_names
        state = health[i].state if i in health else Health.HEALTHY
        level = (diagnostics.ERROR if locked or i in pinned else
                 diagnostics.WARN if last.at_hard_limit[i] or state != Health.HEALTHY
                 else diagnostics.OK)
        message = "locked" if locked else "ok" if state == Health.HEALTHY else str(state)
        statuses.append(status(level, message, {
            "locked": locked, "health": str(state), "at_soft_limit": bool(last.at_soft_limit[i]),
            "at_hard_limit": bool(last.at_hard_limit[i]),
            "post_failure_sigma": float(last.post_failure_sigmas[i]) if not locked
            else "n/a"}, joint=joint))
    return statuses


def observability_note(loaded: Loaded | None) -> str:
    """"off", "waiting" or "exciting <joint>": the observability excursions."""
    if loaded is None or loaded.core.excursions is None:
        return "off"
    joint = loaded.core.excursions.active
    return "waiting" if joint is None else f"exciting {loaded.robot.joint_names[joint]}"


def level_and_message(loaded: Loaded | None, problems: str | None) -> tuple[bytes, str]:
    """The controller's diagnostic level and message: problems first, then its state."""
    last = None if loaded is None else loaded.core.last
    if problems:
        return diagnostics.ERROR, problems
    if loaded is None:
        return diagnostics.WARN, "waiting for the robot model"
    if last is None:
        return diagnostics.WARN, "waiting for joint states"
    return diagnostics.OK, last.status


def core_values(loaded: Loaded | None, now: float) -> dict[str, object]:
    """The diagnostics' values of the core's state at node time `now` (s)."""
    core = None if loaded is None else loaded.core
    target = None if core is None else core.target
    values: dict[str, object] = {
        "target": target.kind if target else "none",
        "target_age_s": now - target.stamp if target else "none",
        "locked_joints": [] if loaded is None else sorted(loaded.names(loaded.core.locked)),
        "soft_limits": "none" if core is None else core.soft_limits_note,
        "observability": observability_note(loaded),
        "recovery": "off" if core is None else core.recovery_note,
        "joint_health": "none" if core is None else core.adaptation.note,
        "start_configuration": "idle" if core is None else core.start_phase.note,
        "suspected_lock": (loaded and loaded.suspected_lock) or "none",
        "kfm_ascent_at": "none" if core is None else core.commanded.note}
    last = None if core is None else core.last
    if last is not None:
        values.update(kfm=last.kfm, task_scale=last.task_scale, status=last.status)
    return values


def view(loaded: Loaded, q: np.ndarray, critical_points: list[float], header) -> list:
    """The live view's markers (`ft_msgs_py.markers`): goal, critical points, locks."""
    robot, target = loaded.robot, loaded.core.target
    goal = [robot.target_position(target.value)] if isinstance(target, PoseTarget) else []
    critical = [robot.target_position(point)
                for point in selfmotion.targets_from_flat(robot, critical_points)]
    locked = robot.skeleton(q)[list(loaded.core.locked)]
    return [markers.spheres(header, "goal", goal, markers.GOAL),
            markers.spheres(header, "critical_points", critical, markers.CRITICAL),
            markers.spheres(header, "locked_joints", locked, markers.ANNOUNCED,
                            markers.HALO_DIAMETER)]


def loop_values(accounting: LoopAccounting) -> dict[str, object]:
    """The diagnostics' values of the control loop's timing (`LoopAccounting`)."""
    return {"cycle_compute_median_ms": accounting.compute_ms(50),
            "cycle_compute_p99_ms": accounting.compute_ms(99),
            "missed_cycles": accounting.missed if accounting.count_missed
            else "n/a (simulated time)"}


def statuses(loaded: Loaded | None, status, values: dict, problems: Episodes,
             ) -> list[DiagnosticStatus]:
    """The controller's diagnostics: its own status with `values`, then one per joint.

    `status(level, message, values, joint=None)` makes each (`SuiteNode.status`).
    """
    level, message = level_and_message(loaded, problems.summary() if problems.active
                                       else None)
    return [status(level, message, values),
            *([] if loaded is None else joint_statuses(loaded, status))]
