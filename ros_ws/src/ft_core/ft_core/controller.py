"""The controller's per-cycle logic without ROS: a core with a step function.

The pattern of MoveIt Servo (a `Servo` core whose node only wires topics and
parameters): `Controller.step(q, state_age, now)` turns the latest joint positions and
their age, the latest target and the locked set into one command, and owns everything a
cycle needs besides the engine's arithmetic (`ft_core.engine`):

- the joints' health (`ft_core.adaptation`): a degraded joint's speed and weight lowered,
  usable ranges as hard limits, joints locked or free-swinging by health pinned; zeros
  (on the ramp) and the reason while the joints left cannot do the task;
- the target: a twist (feed-forward, decaying once stale, `targets.staleness_scale`)
  or a pose goal (tracked proportionally, `targets.pose_velocity`);
- holding still with no target (unless `idle_null_space_motion`);
- the observability excursions (`ft_core.observability`) in the null space;
- the task-space channel (`ft_core.task_channel`), fed the pose goal's error and the
  cycle's own command (before smoothing: what the engine asks of the joints): its
  suspect is returned for whoever decides (the monitor);
- the recovery (`ft_core.recovery`): when a pose goal's error stops improving, a joint
  path to an IK solution with the locked joints pinned, planned in the worker process and
  followed in the cycle, then the pose goal is tracked again;
- the soft limits from critical points: the intersected self-motion boxes of Lewis
  and Maciejewski (1997), traced in a worker process (never in the cycle) and
  switched in atomically, in the cycle, once ready;
- on request, with no target, the start configuration of best dexterity after a
  failure (`ft_core.start_configuration`, Zhao & Li sec. III-D step i): planned in the
  worker process, then followed with the tool held still; a target or a lock ends it;
- the command smoother (`ft_core.smoothing`): every command, zeros included, reaches
  the cycle's velocity within the arm's acceleration and jerk limits
  (`ft_core.command_limits`), so a stale state or target brings the arm to rest on a
  ramp; a joint that locks gets 0 at once (it is stopped anyway), the healthy ones go
  to the reduced solution within their limits.

Every input is checked by the caller or by the engine; the step never raises on a
bad state or target: it commands zeros (reached on a ramp) and says why (`Step.problems`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from ft_core import recovery, start_configuration, workers
from ft_core.adaptation import INFEASIBLE, Adaptation
from ft_core.controller_config import ControllerConfig
from ft_core.critical_limits import CriticalPointLimits
from ft_core.engine import CycleResult, EngineConfig, ResolutionEngine
from ft_core.health import JointHealth
from ft_core.input_checks import all_finite
from ft_core.observability import Excursions
from ft_core.recovery import Recovery, RecoveryConfig
from ft_core.reference import CommandedConfiguration
from ft_core.robots import Kinematics, Robot
from ft_core.smoothing import Smoother
from ft_core.start_configuration import StartPhase
from ft_core.targets import (
    PoseTarget,
    Target,
    TwistTarget,
    norm,
    pose_velocity,
    stale_state,
    staleness_scale,
)
from ft_core.task_channel import TaskChannel

#: How the start-configuration path moves and how long its plan may take: as a recovery
#: path (`recovery.RecoveryConfig`'s acceleration, jerk, gain and timeout).
_START = RecoveryConfig()
_NONE = np.zeros(0, dtype=np.int64)
#: m and rad: a pose goal this close to a critical point is that point (its traced
#: configurations seed the recovery's inverse kinematics).
_SAME_POINT = 1e-6


@dataclass
class Step:
    """What one cycle decided.

    Attributes:
        qd: the command (rad/s, chain order), within the arm's acceleration and jerk
            limits; towards zeros, on a ramp, when no motion is safe.
        result: the engine's cycle (None when zeros were commanded without one).
        problems: why zeros were commanded, by input: "joint_states" (stale), "engine" (a
            state or target it refuses; None once it accepts again) or "task infeasible"
            (`adaptation.INFEASIBLE`: the joints left cannot do the task; None once, after).
        suspect: the joint the task channel suspects now (None: none).
        new_suspect: `suspect` differs from the previous cycle's.
        announce: publish the suspect now (new, or again once per channel window).
    """

    qd: np.ndarray
    result: CycleResult | None
    problems: dict[str, str | None]
    suspect: int | None = None
    new_suspect: bool = False
    announce: bool = False


#: Reports a problem of a named input (None: solved), `warning` for a WARN, not an ERROR.
Report = Callable[..., None]


class Controller:
    """The per-cycle logic of the controller node; see the module docstring.

    Args:
        robot: the chain.
        engine_config: the engine's configuration (without the critical points' box).
        config: the rest of the cycle's settings.
        model_source: (spec, chain arguments) that `robots.load` rebuilds the robot
            from in the worker process tracing the critical points' boxes.
        report: called with (input name, problem or None) when a background job
            fails or recovers ("critical points").
        log: called with an informational message.
        background: the worker process pool for the boxes and the plans (its jobs are
            pure functions of their arguments); None: one of its own, started on first
            use and stopped by `close`. A pool given is left running by `close`: a
            harness that runs many controllers in turn shares one (`ft_sim.scenario`).
    """

    def __init__(self, robot: Robot, engine_config: EngineConfig, config: ControllerConfig,
                 model_source: tuple[str, Sequence],
                 report: Report = lambda *_args, **_kwargs: None,
                 log: Callable[[str], None] = lambda _message: None,
                 background: ProcessPoolExecutor | None = None):
        self.robot = robot
        self.config = config
        #: The worker process of the boxes and the plans (`background`, if given).
        self.worker = workers.Worker(background)
        self._engine_config = engine_config
        self.adaptation = Adaptation(robot)
        self.smoother = self._smoother(self.config)
        self.engine = self._engine(engine_config)
        self._model_source = model_source
        self.excursions = self._excursions(self.config)
        self.recovery = self._recovery(self.config)
        #: Where the commands sent are taking the arm (`reference`).
        self.commanded = CommandedConfiguration(robot.n)
        self._q: np.ndarray | None = None  # rad, the last configuration measured
        self._ahead: np.ndarray | None = None  # this cycle's commanded minus measured, rad
        self.start_phase = StartPhase(self._submit_start, _START.gain, _START.timeout)
        self.channel = TaskChannel(robot)
        self.target: Target | None = None
        self.locked: tuple[int, ...] = ()
        #: The joints not used: `locked` and those pinned by health (`Adaptation.pinned`).
        self.pinned: tuple[int, ...] = ()
        self.last: CycleResult | None = None
        self.suspect: int | None = None
        self._suspect_sent = -math.inf
        #: Soft limits from critical points, computed in the worker process.
        self.critical = CriticalPointLimits(self.worker.submit, model_source, report, log)

    # ------------------------------------------------------------ configuration
    def _excursions(self, config: ControllerConfig) -> Excursions | None:
        if config.observability is None:
            return None
        return Excursions(self.robot.n, config.observability)

    def _recovery(self, config: ControllerConfig) -> Recovery | None:
        if config.recovery is None:
            return None
        # The follower's compiled velocity bounds are loaded already: the engine's
        # constructor runs its infeasible path, which uses them.
        return Recovery(config.recovery, partial(self._submit_plan, config.recovery))

    def _smoother(self, config: ControllerConfig) -> Smoother | None:
        """The command smoother for `config.limits` (ValueError: limits it refuses)."""
        if config.limits is None:
            return None
        robot = self.robot
        return Smoother(config.limits.build(robot.name, robot.joint_names,
                                            robot.velocity_limits))

    def configure(self, engine_config: EngineConfig, config: ControllerConfig) -> None:
        """New settings: the engine is rebuilt (keeping the critical points' box)."""
        if config.observability != self.config.observability:
            self.excursions = self._excursions(config)
        if config.recovery != self.config.recovery:
            self.recovery = self._recovery(config)
        if config.limits != self.config.limits:
            old, self.smoother = self.smoother, self._smoother(config)
            if old is not None and self.smoother is not None:
                self.smoother.reset(old.velocity)
        self.config = config
        self._engine_config = engine_config
        self._rebuild_engine()

    def _rebuild_engine(self) -> None:
        config, critical = self._engine_config, self.critical.limits
        if critical is not None:
            box = critical.box
            if len(config.soft_lower):
                box = (np.maximum(config.soft_lower, box[0]),
                       np.minimum(config.soft_upper, box[1]))
            config = replace(config, soft_lower=tuple(box[0]), soft_upper=tuple(box[1]))
        self.engine = self._engine(config)

    def _engine(self, config: EngineConfig) -> ResolutionEngine:
        """The engine for `config` adapted to the joints' health (`Adaptation.adapt`).

        Its velocity bounds brake within the smoother's acceleration and jerk limits where
        `config` gives none of its own.
        """
        if self.smoother is not None and not len(config.acceleration):
            limits = self.smoother.limits
            config = replace(config, acceleration=tuple(limits.acceleration),
                             jerk=tuple(limits.jerk))
        return ResolutionEngine(self.robot, self.adaptation.adapt(config))

    # ------------------------------------------------------------------- inputs
    def set_twist(self, velocity: np.ndarray, stamp: float) -> None:
        """A task velocity (`targets.twist_velocity`) stamped `stamp` (s)."""
        self.start_phase.cancel("a twist arrived")
        self.target = TwistTarget(velocity, stamp)

    def set_pose_goal(self, goal: np.ndarray, now: float) -> None:
        """A pose goal (`targets.goal_from_transform`), received at `now` (s).

        A goal other than the one tracked restarts the task channel's window (its
        progress test is towards one goal); the same goal again changes nothing there.
        """
        self.start_phase.cancel("a pose goal arrived")
        held = self.target
        if not isinstance(held, PoseTarget) or not np.array_equal(held.value, goal):
            self.channel.restart()
        self.target = PoseTarget(goal, now)
        if self.recovery is not None:
            self.recovery.reset(now)

    def set_locked(self, locked: Sequence[int], now: float = math.nan) -> None:
        """The locked joints (chain indices), as the monitor announced them at `now` (s)."""
        self.locked = tuple(sorted(locked))
        self._pin(now)

    def set_health(self, health: Mapping[int, JointHealth], now: float = math.nan) -> None:
        """Every joint's health ({chain index: health}; `ft_core.adaptation`) at `now` (s).

        The engine is rebuilt with the limits and weights derived from it, if they change.
        """
        if self.adaptation.set_health(health):
            self._rebuild_engine()
        self._pin(now)

    def _pin(self, now: float) -> None:
        """Take the joints not to use now; a change drops the recovery's plan."""
        pinned = self.adaptation.pinned(self.locked)
        if pinned != self.pinned and self.recovery is not None:
            self.recovery.reset(now)
        if pinned:
            self.start_phase.cancel("a joint is locked")
        self.pinned = pinned

    def optimize_start(self, q: np.ndarray | None, now: float) -> str | None:
        """Move the idle arm to its start configuration of best dexterity; None: started.

        `start_configuration`: planned in the worker process, then followed with the
        tool held still. Otherwise the reason it does not start: no joint state, a
        target in force, a locked joint, or a phase under way already.
        """
        if q is None:
            return "no joint state yet"
        if self.target is not None:
            return "a target is in force: the start configuration is for an idle arm"
        if self.pinned:
            return f"joints {list(self.pinned)} are locked: the start phase is for a healthy arm"
        try:
            self.start_phase.request(q, now)
        except RuntimeError as problem:
            return str(problem)
        return None

    def _submit_start(self, q: np.ndarray) -> Future:
        """Plan the start configuration in the worker process."""
        return self.worker.submit(start_configuration.plan_for_model, *self._model_source, q,
                                  self.engine.speeds, self.engine.config.dt,
                                  _START.acceleration, _START.jerk)

    def set_critical_points(self, flat: Sequence[float]) -> None:
        """Task points (`selfmotion.targets_from_flat`) whose boxes become soft limits.

        Traced from the next cycle's configuration, in a worker process; empty: none.
        """
        self.critical.set_points(flat)

    @property
    def recovery_note(self) -> str:
        """What the recovery after a lock does now ("off" when disabled)."""
        return "off" if self.recovery is None else self.recovery.note

    @property
    def soft_limits_pending(self) -> bool:
        """Whether soft limits from the critical points are still to be computed or taken."""
        return self.critical.pending

    @property
    def soft_limits_note(self) -> str:
        """The soft limits in force (`CriticalPointLimits.note`)."""
        return self.critical.note

    # -------------------------------------------------------------------- cycle
    def stopper(self, velocity: np.ndarray) -> Callable[[float], np.ndarray]:
        """A stop from `velocity` (rad/s, chain order) held steady, within this core's limits.

        For commands this core did not make (the guard's of a dead monitor, from the
        monitor's last command): each call returns the next command (rad/s, chain order)
        stamped with the time given (s); zeros at once without smoothing.
        """
        zeros = np.zeros(self.robot.n)
        if self.smoother is None:
            return lambda _now: zeros.copy()
        smoother = Smoother(self.smoother.limits)
        smoother.reset(velocity)
        return lambda now: smoother.step(zeros, now)

    def smooth(self, qd: np.ndarray, now: float) -> np.ndarray:
        """The command stamped `now` (s) towards `qd` (rad/s) within the limits.

        Locked and pinned joints get 0 at once; joints braking for a position limit
        (`_braking`) are smoothed on their own. `qd` itself without a smoother.
        """
        if self.smoother is not None:
            qd = self.smoother.step(qd, now, self.pinned, self._braking(self.smoother.velocity))
        self.commanded.sent(now, qd)
        return qd

    def _braking(self, velocity: np.ndarray) -> np.ndarray:
        """The joints moving at `velocity` (rad/s) towards a position limit they brake for.

        Those whose velocity bound on that side, at the last configuration measured, is
        below their speed limit (`ResolutionEngine.velocity_bounds`): within stopping
        distance of the limit. No joint before a configuration is measured.
        """
        if self._q is None:
            return _NONE
        lo, hi = self._velocity_bounds(self._q, self.engine.bounds(self.pinned))
        speeds = self.engine.speeds
        return np.flatnonzero(((velocity > 0) & (hi < speeds)) | ((velocity < 0) & (lo > -speeds)))

    def _commanded_at(self, q: np.ndarray, measured_at: float, now: float,
                      ) -> Kinematics | None:
        """Where the commands sent are taking the arm (`reference`): None at q itself.

        Keeps the motion q does not show yet for this cycle's velocity bounds.
        """
        commanded = self.commanded.update(q, measured_at, now, self.pinned)
        if commanded is None or not all_finite(commanded):
            self._ahead = None
            return None
        self._ahead = commanded - q
        return self.robot.kinematics(commanded)

    def step(self, q: np.ndarray | None, state_age: float, now: float) -> Step:
        """One cycle: the command for joint positions `q` (rad) measured `state_age` s ago.

        `q` None (no state yet) or older than `state_timeout` commands zeros (reached
        within the limits, as every command).
        """
        robot = self.robot
        zeros = np.zeros(robot.n)
        if q is None:
            self.last = None
            return Step(self.smooth(zeros, now), None, {})
        if state_age > self.config.state_timeout:
            self.last = None
            return Step(self.smooth(zeros, now), None, {"joint_states": stale_state(state_age)})
        if self.critical.update(q):
            self._rebuild_engine()
        pinned = self.pinned
        locked = list(pinned)
        try:
            kinematics = robot.kinematics(q)  # the measured configuration's pass
            xd, idle, task_error = self._task_velocity(kinematics, now)
            result = self.engine.step(kinematics, xd, locked, self._commanded_at(
                q, now - state_age, now))
        except ValueError as problem:  # non-finite or physically absurd state or target
            self.last = None
            return Step(self.smooth(zeros, now), None, {"engine": f"{problem}: commanding zeros"})
        self._q = kinematics.q
        self.last, infeasible = result, self.adaptation.judge(result, pinned, q, xd, now)
        if infeasible.get(INFEASIBLE):  # the joints left cannot do the task: to rest
            return Step(self.smooth(zeros, now), result, {"engine": None, **infeasible})
        qd = result.qd
        if idle and not self.config.idle_null_space_motion:
            qd = zeros
            result.jump_index = 0.0
        qd = self._excite(kinematics, qd, locked, now)
        if self.start_phase.active:
            qd = self._start(kinematics, qd, now)
        error = None
        if task_error is not None:
            error = norm(task_error)
            if self.recovery is not None and self.target:
                qd = self._recover(self.recovery, self.target.value, kinematics, qd, locked,
                                   now, task_error, error, idle)
        if not all_finite(qd):
            qd = zeros
        step = Step(qd, result, {"engine": None, **infeasible})
        if error is not None:
            self._watch_task(step, kinematics, locked, now, error)
        step.qd = self.smooth(qd, now)
        return step

    def _task_velocity(self, kinematics: Kinematics, now: float,
                       ) -> tuple[np.ndarray, bool, np.ndarray | None]:
        """(task velocity, idle, the pose goal's error e or None) from the latest target."""
        target, robot = self.target, self.robot
        if target is None:
            return np.zeros(robot.m), True, None
        if isinstance(target, PoseTarget):
            error = robot.task_error(target.value, kinematics)
            xd, reached = pose_velocity(robot, error, self.config.tracking)
            return xd, reached, error
        scale = staleness_scale(now - target.stamp, self.config.target_timeout)
        # The twist itself while fresh (the cycle only reads it): no product each cycle.
        return target.value if scale == 1.0 else scale * target.value, scale == 0.0, None

    def _excite(self, kinematics: Kinematics, qd: np.ndarray, locked: list[int], now: float,
                ) -> np.ndarray:
        """The command with the observability excursion under way, if any (null space only)."""
        if self.excursions is None:
            return qd
        for k, (joint, speed) in enumerate(self.excursions.update(now, qd, locked)):
            moved = self.engine.excursion(kinematics, qd, joint, speed, locked)
            if moved is not None:
                qd = moved
            elif k == 0:  # the idle joint itself cannot move: no excursion now
                self.excursions.cannot_move(joint, now)
                return qd
        return qd

    def _watch_task(self, step: Step, kinematics: Kinematics, locked: list[int], now: float,
                    error: float) -> None:
        """Feed the task channel the pose goal's error (m); its suspect goes into `step`.

        Announced when new, and again every channel window while it lasts (the
        monitor may not have had the evidence the first time).
        """
        joint = self.channel.update(now, kinematics, step.qd, error, tuple(locked))
        step.suspect, step.new_suspect = joint, joint is not None and joint != self.suspect
        step.announce = joint is not None and (
            joint != self.suspect or now - self._suspect_sent >= self.channel.config.window)
        if step.announce:
            self._suspect_sent = now
        self.suspect = joint

    def _recover(self, rec: Recovery, goal: np.ndarray, kinematics: Kinematics,
                 qd: np.ndarray, locked: list[int], now: float, task_error: np.ndarray,
                 error: float, reached: bool) -> np.ndarray:
        """The recovery path's command while one is followed, else `qd` unchanged.

        `task_error`: the pose goal's error e; `error`: its norm.
        """
        q = kinematics.q
        descent = self.robot.jacobian(kinematics).T @ task_error
        bounds = self.engine.bounds(locked)
        command = rec.step(now, q, goal, error, descent, reached, tuple(locked), bounds,
                           self._velocity_bounds(q, bounds))
        return qd if command is None else command

    def _start(self, kinematics: Kinematics, qd: np.ndarray, now: float) -> np.ndarray:
        """The start path's command while it is followed, else `qd` unchanged."""
        q = kinematics.q
        command = self.start_phase.step(now, q, self._velocity_bounds(q, self.engine.bounds([])))
        return qd if command is None else command

    def _velocity_bounds(self, q: np.ndarray, bounds: tuple[np.ndarray, np.ndarray],
                         ) -> tuple[np.ndarray, np.ndarray]:
        """The engine's joint-velocity bounds at q within `bounds` (rad/s), this cycle's."""
        return self.engine.velocity_bounds(q, bounds, self._ahead)

    def _submit_plan(self, config: RecoveryConfig, goal: np.ndarray, q: np.ndarray,
                     locked: tuple[int, ...], lower: np.ndarray, upper: np.ndarray) -> Future:
        """Plan a recovery in the worker process (`recovery.plan_for_model`).

        A goal that is a critical point gets its traced configurations as IK seeds.
        """
        critical = self.critical.limits
        traced = None if critical is None else next(
            (samples for target, samples in zip(critical.targets, critical.traced, strict=True)
             if max(recovery.mismatch(self.robot, goal, target)) < _SAME_POINT), None)
        return self.worker.submit(recovery.plan_for_model, *self._model_source, goal, q,
                                  locked, lower, upper, self.engine.speeds,
                                  self.engine.config.dt, config, 0, traced)

    def start_worker(self) -> Future | None:
        """Start the worker process now (`workers.Worker.start`)."""
        return self.worker.start()

    def close(self) -> None:
        """Stop the background work."""
        self.worker.close()
