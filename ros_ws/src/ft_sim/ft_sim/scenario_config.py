"""What a scenario runs (`ScenarioConfig`) and what happened in it (`Record`).

The defaults are the demo's: the Panda's position task between its `TASK_POINTS`, a lock
of panda_joint2 5 s after the task starts, then a tour of the critical points.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Critical points of the built-in 7-DOF arms for a position task (m, base frame): a
#: pick place, a place place and a tool rest, all reachable inside their intersected
#: bounding boxes from the arm's home configuration.
TASK_POINTS = {
    "panda": ((0.5, 0.1, 0.4), (0.45, -0.15, 0.35), (0.4, 0.05, 0.55)),
    "iiwa14": ((0.55, 0.1, 0.5), (0.5, -0.15, 0.45), (0.45, 0.05, 0.65)),
}


#: The default model of a run on the physics plant: the built-in with inertias.
PHYSICS_ROBOT = "panda_inertial"

#: A pose goal is reached within this many rad of orientation per m of position tolerance.
ANGLE_PER_METRE = 10.0


@dataclass
class ScenarioConfig:
    """What to run.

    Attributes:
        robot: model (built-in name or URDF path); base_link, tip_link ("": the
            defaults) choose the chain; task_space its task.
        resolution: the controller's mode.
        points: task points visited in turn (m: x, y, z; a pose task adds the
            orientation qx, qy, qz, qw; default the robot's position `TASK_POINTS`, or
            `selfmotion.points_around` its `selfmotion.bent_configuration`); all
            critical unless `critical` says otherwise. The arm starts at
            `selfmotion.bent_configuration` (a built-in's home).
        critical: indices of the critical points (default: all).
        soft_limits: give the controller the critical points (bounding-box soft limits).
        soft_box: their box (rad, lower and upper, chain order) when it is known already:
            the controller then takes it as its `soft_limits.lower`/`upper` instead of
            tracing the points' self-motion manifolds at the start (a campaign traces
            them once per design: `campaign.design_of`).
        lock_joint: name of the joint to lock ("" for none); lock_time: when (simulated s
            after the task starts).
        fault: what fails there: `KIND[:VALUE]` (`ft_core.faults.parse_spec`), a lock by
            default.
        duration: longest run (simulated s after the task starts); rate: sim, controller
            and joint-state rate (Hz).
        noise: position noise (rad); seed: noise seed.
        goal_tolerance: m (a pose goal also within `ANGLE_PER_METRE` x as many rad);
            goal_timeout: s per visit.
        plant: the sim's plant, "kinematic" or "physics" (MuJoCo; needs a model with
            inertias, such as "panda_inertial").
        command_latency, response_time (s), hold_last_command: the sim's plant options.
        start: the initial configuration (rad, chain order; default the bent one).
        recovery: the controller's recovery after a lock (`recovery.enabled`).
        tour_timeout: s per visit of the tour after the lock: room for the controller's
            recovery (a stall, a plan and a joint path of a few seconds) before the point
            counts as missed.
        reachable_tour: at the lock, replace each tour point the locked arm cannot reach
            (no inverse kinematics with the joint pinned at its locked value) by a
            reachable one near it (`Scenario.keep_reachable`; `Record.replaced` says
            which). The demo does: where a pose task leaves no redundancy after the lock, a
            point is generally out of reach. A campaign does not: it counts such points.
        smooth_commands: the controller's and the monitor's command smoothing.
        refuse_over_limits: the sim's driver refuses commands over the arm's limits and
            stops the arm, as a real one does (`Record.reflex`).
    """

    robot: str = "panda"
    base_link: str = ""
    tip_link: str = ""
    task_space: str = "position"
    resolution: str = "blend"
    points: tuple[tuple[float, ...], ...] = ()
    critical: tuple[int, ...] | None = None
    soft_limits: bool = True
    soft_box: tuple[tuple[float, ...], tuple[float, ...]] | None = None
    lock_joint: str = "panda_joint2"
    lock_time: float = 5.0
    fault: str = "lock"
    duration: float = 60.0
    rate: float = 250.0
    noise: float = 1e-3
    seed: int = 0
    goal_tolerance: float = 2e-3
    goal_timeout: float = 4.0
    command_latency: float = 0.0
    response_time: float = 0.0
    plant: str = "kinematic"
    hold_last_command: bool = False
    start: tuple[float, ...] = ()
    recovery: bool = True
    tour_timeout: float = 12.0
    reachable_tour: bool = False
    smooth_commands: bool = True
    refuse_over_limits: bool = True


@dataclass
class Record:
    """What happened, step by step (arrays over steps) and at the failure."""

    joint_names: list[str]
    t: list[float] = field(default_factory=list)
    q: list[np.ndarray] = field(default_factory=list)
    qd_actual: list[np.ndarray] = field(default_factory=list)
    qd_command: list[np.ndarray] = field(default_factory=list)
    kfm: list[float] = field(default_factory=list)
    tool_velocity_error: list[float] = field(default_factory=list)
    goal: list[int] = field(default_factory=list)
    #: Visits before the lock: (time the visit ended, point index, reached).
    visits: list[tuple[float, int, bool]] = field(default_factory=list)
    started_at: float = 0.0  #: simulated time the task started (s)
    soft_limits: str = "none"  #: the controller's soft limits when the task started
    tour: dict[int, bool] = field(default_factory=dict)  #: critical point -> reached after lock
    injected_at: float | None = None
    detected_at: float | None = None
    detected: list[str] = field(default_factory=list)
    false_locks: list[str] = field(default_factory=list)  #: declared before the injection
    #: Why the sim's driver stopped the arm (None: it took every command).
    reflex: str | None = None
    #: Largest |commanded velocity, acceleration, jerk| / limit per joint (3 lists), by
    #: the commands' stamps (the sim's driver), the joints the plant held locked left out.
    peaks: list[list[float]] = field(default_factory=list)
    non_finite: int = 0
    #: The controller's recovery notes as they changed (`Controller.recovery_note`):
    #: (simulated time s, note).
    recovery: list[tuple[float, str]] = field(default_factory=list)
    #: Tour points out of the locked arm's reach, replaced (`ScenarioConfig.reachable_tour`):
    #: index -> how far the replacement is (`recovery.mismatch`: m, rad).
    replaced: dict[int, tuple[float, float]] = field(default_factory=dict)

    def arrays(self) -> dict[str, np.ndarray]:
        """The step series as arrays."""
        return {k: np.array(getattr(self, k)) for k in
                ("t", "q", "qd_actual", "qd_command", "kfm", "tool_velocity_error", "goal")}
