"""An in-process closed loop: sim, controller and monitor nodes, in simulated time.

The sim owns the clock and is stepped by hand, so a run is as fast as the
computation allows and the same on every machine. Each step: the sim integrates
and publishes `/clock` and `joint_states`; the controller's timer fires and
commands; the monitor filters the command and hands it to the sim; the step ends
once the sim holds the command for the new instant.

The nodes are wired as `ft-stack` wires them (`ft_sim.stack.compose`: the command and
the joint states pass between controller and monitor by calls), the monitor hands its
command to the sim by a call too (`MonitorNode.hand_commands_to`), the record reads
the controller's command and metrics from the node, and no node serves parameters
(nothing here asks): the wait set the executor rebuilds at every wave of a step holds
only the entities a run needs, and a step runs only their callbacks (docs/campaign.md
has what a run costs). The topics are still published while anyone subscribes
(`--record`, `ft-demo --live`).

A driver visits the task points in turn with `ft/target_pose` (the next one once the
tool is within `goal_tolerance`, or after `goal_timeout`) and locks `lock_joint`
through `ft/inject_failure` `lock_time` after the task started (or injects the `fault`
the config names there through `ft/inject_fault`). The task starts once
the controller has its soft limits (the critical points' boxes are traced in the
background while the arm holds still), so that runs with and without them wander for
the same time. After the lock it tours the critical points once, each until reached
or `goal_timeout` (Lewis & Maciejewski 1997 sec. V: can every critical point still be
reached?), and the run ends. Every step is recorded for the report.
"""

from __future__ import annotations

import math
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import rclpy
from ft_controller.controller_node import ControllerNode
from ft_core import faults, recovery, robots, selfmotion
from ft_monitor.monitor_node import MonitorNode
from ft_msgs_py import convert, names, qos, spin
from geometry_msgs.msg import PoseStamped
from rclpy.context import Context
from sensor_msgs.msg import JointState

from ft_sim.bag import Recorder
from ft_sim.injection import Injection
from ft_sim.live import LiveServer
from ft_sim.planner_pool import PLANNER_CHECK, planner, stop_planner
from ft_sim.scenario_config import (
    ANGLE_PER_METRE,
    PHYSICS_ROBOT,
    TASK_POINTS,
    Record,
    ScenarioConfig,
)
from ft_sim.sim_node import SimNode
from ft_sim.stack import compose

__all__ = ["ANGLE_PER_METRE", "PHYSICS_ROBOT", "PLANNER_CHECK", "PLAN_WAIT", "REACH_ATTEMPTS",
           "REACH_SAMPLES", "TASK_POINTS", "WAIT_PERIOD", "Record", "Scenario",
           "ScenarioConfig", "planner", "run", "stop_planner"]

#: Wall-clock period (s) at which a step polls the work it waits for (`Scenario.step`).
WAIT_PERIOD = 0.005
#: Longest wall-clock wait (s) of the simulated clock for a recovery plan or a write.
PLAN_WAIT = 60.0
#: Inverse-kinematics starts that decide whether the locked arm reaches a tour point.
REACH_ATTEMPTS = 30
#: Random configurations searched for the nearest replacement of an unreachable point.
REACH_SAMPLES = 2000



class Scenario(Injection):
    """Builds the nodes in their own context (and DDS domain) and runs them.

    With `bag`, every topic of the run is also written there as a rosbag2 (MCAP). With
    `live_port`, every topic and the nodes' markers are served to Foxglove on that port
    (`live.LiveServer`; 0: any free one), and simulated time is paced to the wall clock
    (no faster than real time), so that a viewer sees the run as it happens.
    """

    def __init__(self, config: ScenarioConfig, domain_id: int | None = None,
                 bag: Path | None = None, live_port: int | None = None):
        self.robot = robots.load(config.robot, config.base_link or None,
                                 config.tip_link or None, task_space=config.task_space)
        start = (np.array(config.start, dtype=float) if config.start
                 else selfmotion.bent_configuration(self.robot))
        if not config.points and self.robot.name in TASK_POINTS and (
                config.task_space == "position"):
            config = replace(config, points=TASK_POINTS[self.robot.name])
        elif not config.points:
            flat = selfmotion.flat_from_targets(self.robot, selfmotion.points_around(
                self.robot, start))
            size = selfmotion.point_size(self.robot)
            config = replace(config, points=tuple(tuple(flat[i:i + size])
                                                  for i in range(0, len(flat), size)))
        self.config = config
        self._targets = selfmotion.targets_from_flat(
            self.robot, [v for point in config.points for v in point])
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.executor = spin.LockStepExecutor(context=self.context)
        model = {"robot_model": config.robot, "task_space": config.task_space,
                 **{name: value for name, value in (("base_link", config.base_link),
                                                    ("tip_link", config.tip_link)) if value}}
        critical = config.critical if config.critical is not None else range(len(config.points))
        self.critical = list(critical)
        flat = [v for i in self.critical for v in config.points[i]]
        self.sim = SimNode.stepped_by_hand(self.context, {
            **model, "plant": config.plant, "rate": config.rate,
            "position_noise": config.noise, "seed": config.seed,
            "command_latency": config.command_latency, "response_time": config.response_time,
            "hold_last_command": config.hold_last_command,
            "refuse_over_limits": config.refuse_over_limits,
            "initial_positions": [float(v) for v in start]}, services=False)
        # Lock-step on simulated time: wall-clock gaps between steps (a busy machine) are not
        # stalls of the loop, so no steady-time watchdog may fire in them (the controller's
        # is max(state_timeout, 2 periods), its guard of a dead monitor monitor_timeout;
        # states are always fresh here).
        controller = {**model, "use_sim_time": True, "control_rate": config.rate,
                      "resolution": config.resolution, "state_timeout": 60.0,
                      "monitor_timeout": 60.0, "recovery.enabled": config.recovery,
                      "smooth_commands": config.smooth_commands,
                      **self._soft_limits(flat)}
        self.controller = ControllerNode(background=planner(), context=self.context,
                                         **spin.node_arguments(controller, services=False))
        # A state directory of its own: a run never starts from an earlier run's locks.
        self._state = tempfile.TemporaryDirectory(prefix="ft_scenario_")
        monitor = {**model, "use_sim_time": True, "state_directory": self._state.name,
                   "command_timeout": 60.0, "smooth_commands": config.smooth_commands}
        self.monitor = MonitorNode(context=self.context,
                                   **spin.node_arguments(monitor, services=False))
        compose(self.controller, self.monitor)
        self.monitor.hand_commands_to(self.sim.take_commands_by_call())
        self.driver = spin.harness_node("driver", self.context)
        self._goal_pub = self.driver.create_publisher(PoseStamped, names.TARGET_POSE,
                                                      qos.RELIABLE)
        self._create_injectors()
        self.driver.create_subscription(JointState, names.LOCKED_JOINTS, self._on_locked,
                                        qos.LATCHED)
        self.recorder = None if bag is None else Recorder(
            self.driver, bag, lambda: round(self.sim.t * 1e9))
        self.live = None if live_port is None else LiveServer(self.driver, live_port)
        self._pace: tuple[float, float] | None = None  # (wall s, simulated s) pacing starts
        for node in (self.sim, self.controller, self.monitor, self.driver):
            self.executor.add_node(node)
        self.record = Record(list(self.robot.joint_names))

    # ----------------------------------------------------------------- inputs
    def _on_locked(self, msg: JointState) -> None:
        if msg.name and self.record.injected_at is None:
            self.record.false_locks = sorted(set(self.record.false_locks) | set(msg.name))
        if msg.name and self.record.detected_at is None and self.record.injected_at is not None:
            self.record.detected_at = convert.stamp_seconds(msg.header.stamp)
            self.record.detected = list(msg.name)

    # ------------------------------------------------------------------- loop
    @property
    def command(self) -> np.ndarray:
        """The controller's latest command (rad/s, chain order; zeros before the first).

        Read from the node, not from `ft/command_raw`: a message between nodes is taken
        in the step it was sent or in the next, as it happens, and a record of it would
        differ from run to run.
        """
        last = self.controller.last_command
        return last.copy() if last is not None else np.zeros(self.robot.n)

    def send_goal(self, index: int) -> None:
        """Publish task point `index` as the pose goal."""
        msg = PoseStamped()
        msg.header.stamp = convert.stamp_from_nanoseconds(round(self.sim.t * 1e9))
        point = self.config.points[index]
        msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (
            float(v) for v in (*point[:3], 0.0, 0.0)[:3])  # a planar point has z = 0
        msg.pose.orientation.w = 1.0
        if len(point) == 7:
            o = msg.pose.orientation
            o.x, o.y, o.z, o.w = (float(v) for v in point[3:])
        self._goal_pub.publish(msg)

    def keep_reachable(self, joint: str, points: list[int]) -> None:
        """Replace those of `points` the arm cannot reach with `joint` held where it is.

        Reachable: `recovery.reachable`, seeded with the configurations that reached the
        point before the lock, `REACH_ATTEMPTS` starts besides. A replacement is
        `recovery.nearest_reachable` (`REACH_SAMPLES` random configurations; orientation
        weighed as for a goal's tolerance, `ANGLE_PER_METRE`). The run is in simulated
        time: this wall time does not count.
        """
        robot, cfg, q = self.robot, self.config, self.sim.q.copy()
        locked = [robot.joint_names.index(joint)]
        points_now = list(cfg.points)
        for p in points:
            target = self._targets[p]
            visits = [self.record.q[int(np.searchsorted(self.record.t, t))]
                      for t, point, reached in self.record.visits if point == p and reached]
            if recovery.reachable(robot, target, q, locked, visits, REACH_ATTEMPTS):
                continue
            replacement = recovery.nearest_reachable(robot, target, q, locked, REACH_ATTEMPTS,
                                                     REACH_SAMPLES, ANGLE_PER_METRE, cfg.seed)
            self.record.replaced[p] = recovery.mismatch(robot, target, replacement)
            self._targets[p] = replacement
            points_now[p] = tuple(selfmotion.flat_from_targets(robot, [replacement]))
        self.config = replace(cfg, points=tuple(points_now))

    def distance(self, index: int) -> float:
        """Position distance (m) of the tool from task point `index`."""
        return float(np.linalg.norm(self.robot.task_error(self._targets[index], self.sim.q)[:3]))

    def reach(self, index: int, tolerance: float, timeout: float) -> bool:
        """Send task point `index` and step until the tool is within `tolerance` (m, s)."""
        self.send_goal(index)
        for _ in range(round(timeout * self.config.rate)):
            if self.distance(index) < tolerance:
                return True
            self.step()
        return self.distance(index) < tolerance

    def hold(self, index: int, seconds: float) -> float:
        """Step for `seconds` (the goal unchanged); the largest distance from point `index` (m)."""
        deviation = 0.0
        for _ in range(round(seconds * self.config.rate)):
            self.step()
            deviation = max(deviation, self.distance(index))
        return deviation

    def until_detected(self, timeout: float) -> float | None:
        """Step until the monitor declares a lock after the injection; its latency (s) or None."""
        deadline = self.sim.t + timeout
        while self.record.detected_at is None and self.sim.t < deadline:
            self.step()
        if self.record.detected_at is None or self.record.injected_at is None:
            return None
        return self.record.detected_at - self.record.injected_at

    def step(self) -> None:
        """One period of the loop: the sim steps, then holds the command for the new instant.

        While the controller computes in its worker process (the critical points' soft
        limits, a start plan, a recovery plan) or the monitor writes a new locked set (in
        its writer thread), all in wall time, the simulated clock waits for them, at most
        `PLAN_WAIT` s: in simulated time a planner and a disk are as fast as the computer
        allows, like the rest of the loop, so the step at which a result is taken, and with
        it the whole run (the noise drawn at each step included), does not depend on the
        machine's load.
        """
        core, monitor = self.controller.core, self.monitor.core
        deadline = time.monotonic() + PLAN_WAIT
        while time.monotonic() < deadline and (
                (core is not None and (core.critical.computing or core.start_phase.planning
                                       or (core.recovery is not None
                                           and core.recovery.planning)))
                or (monitor is not None and monitor.writing)):
            time.sleep(WAIT_PERIOD)
        self.sim.advance(self.executor)
        if not np.isfinite(self.command).all():
            self.record.non_finite += 1
        if monitor is not None:
            self._deliver_locked_set(monitor)
        if self.live is not None:
            self._keep_pace()
        if core is not None and (not self.record.recovery
                                 or self.record.recovery[-1][1] != core.recovery_note):
            self.record.recovery.append((self.sim.t, core.recovery_note))

    def _deliver_locked_set(self, monitor) -> None:
        """Spin until the controller holds the locked set the monitor has found.

        The monitor announces a lock once it is on disk, from its writer's thread as the
        write ends (or at its next joint state), in wall time. Waiting here for the
        write and for the controller to take it makes a lock found in one step reach the
        controller's next cycle, wherever and however fast the run goes (campaign runs
        are reproducible, run for run, on any machine and on a cluster).

        Raises:
            TimeoutError: not within `PLAN_WAIT` s of wall clock.
        """
        def delivered() -> bool:
            return (not monitor.writing
                    and set(self.controller.locked_joints) == set(monitor.locked))

        if not spin.spin_until(self.executor, delivered, PLAN_WAIT):
            raise TimeoutError(f"the controller did not take the locked set "
                               f"{sorted(monitor.locked)} within {PLAN_WAIT:g} s")

    def _keep_pace(self) -> None:
        """Sleep while simulated time is ahead of the wall clock since the first step."""
        if self._pace is None:
            self._pace = (time.monotonic(), self.sim.t)
        ahead = (self.sim.t - self._pace[1]) - (time.monotonic() - self._pace[0])
        if ahead > 0:
            time.sleep(ahead)

    def start(self) -> float:
        """Wait for the model and the soft limits (if any); the simulated start time (s)."""
        if not spin.spin_until(self.executor, lambda: self.controller.robot is not None
                               and self.monitor.robot is not None, 10.0):
            raise TimeoutError("the controller and the monitor did not load the model in 10 s")
        if self.config.soft_limits and self.critical and self.config.soft_box is None:
            self._wait_for_soft_limits()
        elif self.config.soft_limits and self.critical:
            self.record.soft_limits = f"{len(self.critical)} critical points (box given)"
        self.record.started_at = self.sim.t
        return self.sim.t

    def run(self) -> Record:
        """Run until the post-lock tour ends (or `duration`); return the record."""
        cfg, rec, robot = self.config, self.record, self.robot
        start = self.start()
        goal, since = 0, start
        tour: list[int] = []  # critical points still to visit after the lock
        self.send_goal(goal)
        for _ in range(round(cfg.duration * cfg.rate)):
            if (cfg.lock_joint and rec.injected_at is None
                    and self.sim.t >= start + cfg.lock_time):
                self._inject_configured()
                tour = [p for p in range(goal, len(cfg.points)) if p in self.critical]
                tour += [p for p in range(goal) if p in self.critical]
                if cfg.reachable_tour and faults.parse_spec(cfg.fault)[0] is faults.FaultKind.LOCK:
                    self.keep_reachable(cfg.lock_joint, tour)
                goal, since = tour[0], self.sim.t
                self.send_goal(goal)
            # The controller's command in force during this step, before the monitor.
            command = self.command
            before = self.sim.q.copy()
            self.step()
            q = self.sim.q.copy()
            rec.t.append(self.sim.t)
            rec.q.append(q)
            rec.qd_actual.append(self.sim.qd.copy())
            rec.qd_command.append(command)
            rec.kfm.append(self.controller.last_metrics.get("kfm", math.nan))
            rec.tool_velocity_error.append(float(np.linalg.norm(
                robot.jacobian(before)[:3] @ (self.sim.qd - command))))
            rec.goal.append(goal)
            error = robot.task_error(self._targets[goal], q)
            reached = bool(np.linalg.norm(error[:3]) < cfg.goal_tolerance
                           and np.linalg.norm(error[3:]) < ANGLE_PER_METRE * cfg.goal_tolerance)
            timeout = cfg.goal_timeout if rec.injected_at is None else cfg.tour_timeout
            if not reached and self.sim.t - since <= timeout:
                continue
            if rec.injected_at is None:
                rec.visits.append((self.sim.t, goal, reached))
                goal = (goal + 1) % len(cfg.points)
            else:
                rec.tour[tour.pop(0)] = reached
                if not tour:
                    break
                goal = tour[0]
            since = self.sim.t
            self.send_goal(goal)
        rec.reflex = self.sim.reflex
        if self.sim.driver is not None:  # None only without a model
            rec.peaks = self.sim.driver.peaks.tolist()
        return rec

    def _soft_limits(self, flat: list[float]) -> dict:
        """The controller's soft-limit parameters: the box if known, else the points."""
        config = self.config
        if not config.soft_limits or not flat:
            return {}
        if config.soft_box is not None:
            lower, upper = config.soft_box
            return {"soft_limits.lower": [float(v) for v in lower],
                    "soft_limits.upper": [float(v) for v in upper]}
        return {"critical_points": flat}

    def _wait_for_soft_limits(self, timeout: float = 120.0) -> None:
        """Step the still arm until the controller has computed its soft limits (or failed).

        The computation runs in a worker process; `step` waits for it in wall time, so the
        task starts at the same simulated instant in every run, however long it took. The
        outcome is `Record.soft_limits` (the controller's note, e.g. "3 critical points" or
        "none (critical points failed)").
        """
        deadline = time.monotonic() + timeout
        self.step()  # the controller starts the computation at its first joint state
        while self.controller.core.soft_limits_pending:
            if time.monotonic() > deadline:
                raise TimeoutError(f"the controller had no soft limits after {timeout:g} s "
                                   "(see its 'critical points' diagnostics)")
            self.step()
        self.record.soft_limits = self.controller.core.soft_limits_note

    def close(self) -> None:
        """Shut the nodes and the context down."""
        self.executor.shutdown()
        if self.recorder is not None:
            self.recorder.close()
        if self.live is not None:
            self.live.close()
        for node in (self.sim, self.controller, self.monitor, self.driver):
            node.destroy_node()
        rclpy.shutdown(context=self.context)
        self._state.cleanup()



def run(config: ScenarioConfig, domain_id: int | None = None, bag: Path | None = None,
        ) -> Record:
    """Build, run and close a scenario (recorded to `bag` if given)."""
    scenario = Scenario(config, domain_id, bag)
    try:
        return scenario.run()
    finally:
        scenario.close()
