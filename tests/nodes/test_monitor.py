"""monitor_node and sim_node in-process: detection, remap, declared failures, watchdog."""

from __future__ import annotations

import math
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from ft_core import robots
from ft_core.command_limits import DriverCheck, command_limits
from ft_core.health import Health
from ft_core.smoothing import Smoother
from ft_monitor.handover import ABSENT, HANDOVER, LISTEN, Handover
from ft_monitor.monitor_node import MonitorNode
from ft_msgs_py import convert, diagnostics, health, names, qos, wire
from ft_msgs_py.monitor_guard import ECHO_PERIOD
from ft_msgs_py.spin import harness_node, spin_until
from ft_sim.sim_node import SimNode
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosutil import fresh_domain, ros_context
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

PANDA = robots.load("panda")
START = [0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]


class Loop:
    """Sim (owning the clock, stepped by hand), monitor and a test-side commander."""

    def __init__(self, context, executor, sim: SimNode, monitor: MonitorNode):
        self.executor, self.sim, self.monitor = executor, sim, monitor
        self.node = harness_node("commander", context)
        executor.add_node(self.node)
        self.raw = self.node.create_publisher(JointState, "ft/command_raw", qos.RELIABLE)
        self.inject = self.node.create_publisher(JointState, "ft/inject_failure", qos.RELIABLE)
        self.declare = self.node.create_publisher(JointState, "ft/declare_failure", qos.RELIABLE)
        self.commands: list[JointState] = []
        self.arrays: list[Float64MultiArray] = []
        self.locked: list[JointState] = []
        self.node.create_subscription(JointState, "ft/command", self.commands.append,
                                      qos.SENSOR_INPUT)
        self.node.create_subscription(Float64MultiArray, "ft/command_array", self.arrays.append,
                                      qos.SENSOR_INPUT)
        self.node.create_subscription(JointState, "ft/locked_joints", self.locked.append,
                                      qos.LATCHED)
        self.diagnostics: list[DiagnosticArray] = []
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self.diagnostics.append,
                                      qos.RELIABLE)

    def stamp(self):
        return convert.stamp_from_nanoseconds(round(self.sim.t * 1e9))

    def send(self, velocity, names=None) -> None:
        self.last_raw = np.asarray(velocity, dtype=float)
        self.raw.publish(convert.joint_state(names or PANDA.joint_names, self.stamp(),
                                             velocity=velocity))

    def step(self, command: Callable[[Loop], None] | None = None) -> None:
        before = len(self.commands)
        if command is not None:
            measured = self.monitor.core.q
            self.q_at_command = None if measured is None else measured.copy()
            command(self)
            assert spin_until(self.executor, lambda: len(self.commands) > before, 2.0), (
                "no command from the monitor within 2 s")
            # The sim has the monitor's output once its buffer holds it.
            assert spin_until(self.executor, lambda: self.sim.command_time >= self.sim.t, 2.0), (
                "the sim did not receive the monitor's command within 2 s")
        self.sim.step()
        detector = self.monitor.core.detector
        assert spin_until(self.executor, lambda: detector.latest_time >= self.sim.t - 1e-9, 2.0), (
            "the monitor did not take the sim's joint state within 2 s")

    def diagnostics_after(self, time: float, command: Callable[[Loop], None] | None = None,
                          ) -> DiagnosticStatus:
        """The monitor's own status from the first /diagnostics stamped after `time` (s).

        The diagnostics timer runs on the sim's clock: the loop steps on meanwhile,
        with `command` each step (none: no command).
        """
        def fresh() -> DiagnosticStatus | None:
            for msg in self.diagnostics:
                if convert.stamp_seconds(msg.header.stamp) > time:
                    return next(s for s in msg.status if s.name == "/monitor")
            return None

        for _ in range(round(0.6 * 250)):
            if fresh() is not None:
                break
            self.step(command)
        status = fresh()
        assert status is not None, f"no /diagnostics after t = {time:.3f} s"
        return status

    def locked_names(self) -> list[str]:
        return list(self.locked[-1].name) if self.locked else []

    def announced_names(self) -> list[str]:
        """`locked_names` once the monitor announced every lock it decided.

        The locked set is written by a thread of its own and announced once on disk:
        on wall-clock time, however fast the lock-step runs (10 s at most).
        """
        decided = sorted(self.monitor.core.locked)
        assert spin_until(self.executor, lambda: sorted(self.locked_names()) == decided,
                          10.0), f"the locked set {decided} was never announced"
        return self.locked_names()


@contextmanager
def loop(noise: float = 0.0, monitor_parameters: dict | None = None,
         sim_parameters: dict | None = None, domain: int | None = None) -> Iterator[Loop]:
    # The directory outlives the nodes: the monitor's writer thread ends with its node.
    with tempfile.TemporaryDirectory() as state, \
            ros_context(domain=domain) as (context, executor):
        sim = SimNode.stepped_by_hand(context, {
            "robot_model": "panda", "rate": 250.0, "position_noise": noise,
            "initial_positions": START, "seed": 3, **(sim_parameters or {})})
        monitor = MonitorNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in {"robot_model": "panda", "use_sim_time": True,
                                               "state_directory": state,
                                               # lock-step: the steady-time watchdog must
                                               # not fire in a busy machine's pauses (as in
                                               # ft_sim.scenario); tests of it set their own
                                               "command_timeout": 60.0,
                                               **(monitor_parameters or {})}.items()])
        executor.add_node(sim)
        executor.add_node(monitor)
        yield Loop(context, executor, sim, monitor)


def constant(velocity) -> Callable[[Loop], None]:
    return lambda lp: lp.send(velocity)


def sweep(lp: Loop) -> None:
    """Speeds sweeping 0.05 .. 1 rad/s per joint, direction flipping every half second."""
    t = lp.sim.t
    speed = 0.05 + 0.95 * (0.5 + 0.5 * np.sin(2 * np.pi * t / 7 + np.arange(7)))
    lp.send(speed * np.where(np.sin(2 * np.pi * t + np.arange(7)) >= 0, 1.0, -1.0))


#: The slowest plant of issue 13's grid, and the grid: latency x response time (s).
LAGGING = {"command_latency": 0.05, "response_time": 0.05}
GRID = [(latency, response) for latency in (0.0, 0.01, 0.03, 0.05)
        for response in (0.0, 0.02, 0.05)]


@pytest.mark.slow
def test_healthy_motion_with_noise_declares_no_lock() -> None:
    """15 s of simulated time at 250 Hz, 1e-3 rad noise, speeds 0.05 to 1 rad/s.

    On the slowest plant of issue 13's grid (50 ms latency, 50 ms response time).
    """
    with loop(noise=1e-3, sim_parameters=LAGGING) as lp:
        for _ in range(15 * 250):
            lp.step(sweep)
        assert lp.locked_names() == [] and lp.monitor.locked == {}
        assert lp.monitor.core.detector.not_observing is None
        estimate = lp.monitor.core.detector.estimate()
        assert estimate.identified
        assert estimate.latency + estimate.response_time == pytest.approx(0.1, abs=0.03)


@pytest.mark.parametrize(("latency", "response"), GRID)
def test_a_lock_is_found_within_300_ms_on_every_plant_of_the_grid(latency: float,
                                                                  response: float) -> None:
    """The real nodes in lock-step, default parameters, after healthy sweeping motion."""
    plant = {"command_latency": latency, "response_time": response}
    with loop(noise=1e-3, sim_parameters=plant) as lp:
        for _ in range(3 * 250):
            lp.step(sweep)
        assert lp.locked_names() == []
        for _ in range(250):
            lp.step(constant(np.full(7, 0.2)))
        lp.inject.publish(JointState(name=["panda_joint6"]))
        assert spin_until(lp.executor, lambda: "panda_joint6" in lp.sim.locked, 2.0)
        injected = lp.sim.t
        while not lp.monitor.core.locked and lp.sim.t < injected + 1.0:
            lp.step(constant(np.full(7, 0.2)))
        assert lp.announced_names() == ["panda_joint6"]
        assert convert.stamp_seconds(lp.locked[-1].header.stamp) - injected <= 0.3


def test_a_plant_that_stops_is_a_plant_fault_in_diagnostics_not_locks() -> None:
    with loop(noise=1e-3) as lp:
        for _ in range(300):
            lp.step(constant(np.full(7, 0.2)))
        lp.inject.publish(JointState(name=list(PANDA.joint_names)))  # the whole arm stops
        assert spin_until(lp.executor, lambda: len(lp.sim.locked) == 7, 2.0)
        for _ in range(250):
            lp.step(constant(np.full(7, 0.2)))
        assert lp.locked_names() == [] and lp.monitor.locked == {}
        assert "plant not following commands" in lp.monitor.problems.active["plant"]
        diagnostics = lp.diagnostics_after(lp.sim.t, constant(np.full(7, 0.2)))
        assert diagnostics.level == DiagnosticStatus.ERROR
        assert "plant not following commands" in diagnostics.message


def test_diagnostics_show_the_identified_plant_and_why_nothing_is_decided() -> None:
    with loop(noise=1e-3, sim_parameters={"command_latency": 0.03, "response_time": 0.02}) as lp:
        lp.step(sweep)
        first = lp.diagnostics_after(lp.sim.t, sweep)
        values = {kv.key: kv.value for kv in first.values}
        assert first.message == f"not observing: {values['observing']}"
        assert values["observing"].startswith("settling after the command stream")
        assert values["plant_model"] == "prior (not yet identified)"
        for _ in range(10 * 250):
            lp.step(sweep)
        values = {kv.key: kv.value for kv in lp.diagnostics_after(lp.sim.t, sweep).values}
        assert values["plant_model"] == "identified" and values["observing"] == "yes"
        assert float(values["latency_s"]) + float(values["response_time_s"]) == pytest.approx(
            0.05, abs=0.02)


def test_no_decision_while_nobody_subscribes_to_the_command_output(tmp_path) -> None:
    with ros_context() as (context, executor):
        monitor = MonitorNode(context=context, parameter_overrides=[
            Parameter("robot_model", value="panda"),
            Parameter("state_directory", value=str(tmp_path))])
        node = harness_node("lonely_plant", context)
        for n in (monitor, node):
            executor.add_node(n)
        raw = node.create_publisher(JointState, "ft/command_raw", qos.RELIABLE)
        states = node.create_publisher(JointState, "joint_states", qos.RELIABLE)

        def exchange() -> bool:
            stamp = node.get_clock().now().to_msg()
            raw.publish(convert.joint_state(PANDA.joint_names, stamp, velocity=[0.2] * 7))
            states.publish(convert.joint_state(PANDA.joint_names, stamp, position=START))
            return monitor.core.detector.latest_time > -math.inf

        assert spin_until(executor, exchange, 5.0)
        assert monitor.core.detector.not_observing == "nobody subscribes to ft/command(_array)"
        assert monitor.locked == {}


def test_the_monitor_echoes_what_it_sends_at_most_once_per_echo_period() -> None:
    """`ft/command_echo`, for the controller's guard of a dead monitor: copies of `ft/command`.

    Commands sent back to back, faster than one per `ECHO_PERIOD`, get fewer echoes than
    commands; each echo is one of the commands the plant got, stamp and velocities.
    """
    every = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    with loop(monitor_parameters={"smooth_commands": False}) as lp:
        echoes: list[JointState] = []
        plant: list[JointState] = []
        lp.node.create_subscription(JointState, names.COMMAND_ECHO, echoes.append, every)
        lp.node.create_subscription(JointState, names.COMMAND, plant.append, every)
        assert spin_until(lp.executor, lambda: (lp.send([0.1] * 7), bool(echoes))[1], 10.0), (
            "no echo from the monitor")
        spin_until(lp.executor, lambda: False, 0.2)
        echoes.clear()
        plant.clear()
        count, stamp = 100, wire.Stamp.of(round(lp.sim.t * 1e9))
        start = time.monotonic()
        for k in range(count):
            lp.monitor.outputs.send(lp.monitor.wiring, np.full(7, 0.001 * (k + 1)), lp.sim.t, stamp)
        span = time.monotonic() - start
        assert spin_until(lp.executor, lambda: len(plant) >= count, 10.0), (
            f"the plant got {len(plant)} of {count} commands")
        spin_until(lp.executor, lambda: False, 0.1)  # the last echo, if any, arrives
        sent = {tuple(m.velocity) for m in plant}
        assert echoes, "no echo of the commands"
        for echo in echoes:
            assert tuple(echo.velocity) in sent and list(echo.name) == list(PANDA.joint_names)
            assert (echo.header.stamp.sec, echo.header.stamp.nanosec) == tuple(stamp)
        assert len(echoes) <= span / ECHO_PERIOD + 1 < count, (
            f"{len(echoes)} echoes of {count} commands sent in {span * 1e3:.1f} ms")


def test_the_monitor_holds_off_while_the_guard_commands_then_goes_on_from_its_stop() -> None:
    """`ft/command_guard`: the controller's guard commands the plant; the monitor is back.

    Each command that comes meanwhile is echoed alone (the guard, answered, stops) and
    nothing goes on `ft/command`; `HANDOVER` after the guard's last command the monitor
    commands again, from it: the guard's commands and the monitor's make one stream
    within Franka's limits. A `ft/command_guard` from a node that does not publish on
    `ft/command` is refused and changes nothing.
    """
    limits = command_limits(PANDA.name, PANDA.joint_names, PANDA.velocity_limits)
    every = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    with loop() as lp:
        echoes: list[JointState] = []
        lp.node.create_subscription(JointState, names.COMMAND_ECHO, echoes.append, every)
        stranger = harness_node("stranger", lp.monitor.context)
        lp.executor.add_node(stranger)
        guard = lp.node.create_publisher(JointState, names.COMMAND_GUARD, qos.RELIABLE)
        assert spin_until(lp.executor, lambda: lp.monitor.count_publishers(
            names.COMMAND_GUARD) == 1, 10.0), "the guard's publisher never seen"
        for _ in range(100):
            lp.step(constant(np.full(7, 0.6)))

        def answered(velocity: np.ndarray, publisher) -> JointState:
            """A guard command stamped now, then a command; the echo that answers it."""
            publisher.publish(convert.joint_state(PANDA.joint_names, lp.stamp(),
                                                  velocity=velocity.tolist()))
            time.sleep(ECHO_PERIOD)  # echoes go out at most once per period
            echoed = len(echoes)
            lp.send(np.full(7, 0.6))
            assert spin_until(lp.executor, lambda: len(echoes) > echoed, 5.0), "no echo"
            return echoes[-1]

        # A stranger's: refused, the monitor keeps commanding.
        foreign = stranger.create_publisher(JointState, names.COMMAND_GUARD, qos.RELIABLE)
        assert spin_until(lp.executor, lambda: lp.monitor.count_publishers(
            names.COMMAND_GUARD) == 2, 10.0)
        sent = len(lp.commands)
        lp.sim.step()
        answered(np.zeros(7), foreign)
        assert spin_until(lp.executor, lambda: len(lp.commands) > sent, 5.0)
        assert "ft/command_guard" in lp.monitor.problems.active
        stranger.destroy_publisher(foreign)
        assert spin_until(lp.executor, lambda: lp.monitor.count_publishers(
            names.COMMAND_GUARD) == 1, 10.0)
        # The guard of the plant's stream (it publishes on ft/command too).
        lp.node.create_publisher(JointState, names.COMMAND, qos.RELIABLE)
        assert spin_until(lp.executor, lambda: lp.monitor.count_publishers(names.COMMAND) == 2,
                          10.0)
        stream = [(convert.stamp_seconds(m.header.stamp), np.array(m.velocity))
                  for m in lp.commands]
        ramp = Smoother(limits)
        ramp.reset(stream[-1][1])
        before = len(lp.commands)
        for _ in range(15):
            lp.sim.step()
            stream.append((lp.sim.t, ramp.step(np.zeros(7), lp.sim.t)))
            echo = answered(stream[-1][1], guard)
            np.testing.assert_array_equal(echo.velocity, stream[-1][1])
        assert len(lp.commands) == before, "the monitor commanded while the guard did"
        assert "guard" in lp.monitor.problems.active
        time.sleep(HANDOVER)
        lp.sim.step()
        for _ in range(50):
            lp.step(constant(np.full(7, 0.6)))
        assert "guard" not in lp.monitor.problems.active
        after = [(convert.stamp_seconds(m.header.stamp), np.array(m.velocity))
                 for m in lp.commands[before:]]
        assert 0.0 < after[0][1][0] - stream[-1][1][0] < 0.1, "not from the guard's last"
        np.testing.assert_array_equal(after[-1][1], np.full(7, 0.6))  # the target again
        driver = DriverCheck(limits)
        for stamp, velocity in sorted(stream + after, key=lambda c: c[0]):
            assert driver.check(velocity, stamp) is None, f"at {stamp:.3f} s"


def test_a_monitor_that_was_away_listens_before_it_commands_where_a_guard_is() -> None:
    """`Handover`: after a gap in its commands it sends nothing for `LISTEN` s.

    The gap counts against the commands' usual interval (a slow controller is not an
    absence), only where a guard's publisher is matched and on wall time; the guard's
    queue is taken at each command, and a guard command holds it off for `HANDOVER` s.
    """
    def handover(guards: int = 1, wall_time: bool = True) -> tuple[Handover, list[float]]:
        taken: list[float] = []
        h = Handover()
        h.take_guard = lambda: taken.append(1.0)
        h.guards.count, h.wall_time = guards, wall_time
        return h, taken

    h, taken = handover()
    steady = [k * 0.004 for k in range(10)]
    assert not any(h.held_off(t) for t in steady) and len(taken) == 10
    back = steady[-1] + 0.1  # the process stopped for 0.1 s
    listening = [back + k * 0.004 for k in range(math.ceil(LISTEN / 0.004))]
    assert all(h.held_off(t) for t in listening)
    assert not h.held_off(back + LISTEN + 1e-4)
    h.guarded(back + 0.012)  # then commands every 4 ms, as before
    after = [back + 0.012 + k * 0.004 for k in range(1, 12)]
    assert [h.held_off(t) for t in after] == [t - back - 0.012 < HANDOVER for t in after]
    # A controller at 10 Hz: its 0.1 s intervals are no absence once they are usual.
    h, _ = handover()
    held = [h.held_off(k * 0.1) for k in range(10)]
    assert held[1] and not any(held[3:]), held
    # A command held up past ABSENT between its take and its send: not sent, and the
    # monitor listens from then on, as after a gap.
    h, _ = handover()
    assert not any(h.held_off(k * 0.004) for k in range(10))
    assert not h.late(ABSENT - 1e-4, 0.037)
    assert h.late(ABSENT + 1e-4, 0.04)
    after = 0.04 + np.arange(0.0, 2 * LISTEN, 0.004)
    assert [h.held_off(t) for t in after] == list(after - after[0] < LISTEN)
    # No guard matched, or simulated time: never held off after a gap, nor late.
    for h, _ in (handover(guards=0), handover(wall_time=False)):
        assert not h.held_off(0.0) and not h.held_off(1.0)
        assert not h.late(1.0, 1.0)


def test_a_command_held_up_in_the_monitor_is_not_sent_where_a_guard_may_have_fired() -> None:
    """A monitor stopped between taking a command and sending it sends nothing late.

    Its command would carry the stamp of its take, before any the guard sent meanwhile:
    a driver reading stamps refuses it. Its stamp older than `ABSENT` at the moment
    before the publish, it is not sent, the next commands are held off for `LISTEN`
    (echoed alone), then the monitor commands again. Without a guard's publisher the
    same command goes out.
    """
    with loop() as lp:
        echoes: list[JointState] = []
        lp.node.create_subscription(JointState, names.COMMAND_ECHO, echoes.append,
                                    QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
        for _ in range(20):
            lp.step(constant(np.full(7, 0.3)))
        sends: list[bool] = []  # what `Outputs.send` said of each command it was given
        send = lp.monitor.outputs.send
        lp.monitor.outputs.send = lambda *args, **kwargs: sends.append(
            send(*args, **kwargs)) or sends[-1]

        def answer() -> bool:
            """A command in; whether it went out (else held off: echoed alone; or late)."""
            given = len(sends)
            time.sleep(ECHO_PERIOD)  # echoes go out at most once per period
            lp.sim.step()
            stamp = lp.stamp()
            lp.send(np.full(7, 0.3))
            assert spin_until(lp.executor, lambda: len(sends) > given or any(
                e.header.stamp == stamp for e in echoes[-3:]), 5.0), "no answer"
            return len(sends) > given and sends[-1]

        path = lp.monitor.commands
        path.handover.wall_time = True
        # The loop's clock is the sim's, stepped by hand: held up, a command sees it run on.
        clock, held = path.clock, [0.0]
        path.clock = lambda: clock() + held[0]
        core = lp.monitor.core
        command = core.command

        def held_up(qd: np.ndarray, now: float) -> np.ndarray:
            held[0] = ABSENT + 0.01
            return command(qd, now)

        core.command = held_up
        assert answer(), "no guard: the command goes out however long it took"
        held[0] = 0.0
        lp.node.create_publisher(JointState, names.COMMAND_GUARD, qos.RELIABLE)
        assert spin_until(lp.executor, lambda: path.handover.guards.count == 1, 10.0)
        late = "held up"
        for _ in range(10):  # after regular commands (a wait is an absence: held off)
            core.command = command
            assert spin_until(lp.executor, lambda: all(answer() for _ in range(3)), 10.0)
            core.command = held_up
            given = len(sends)
            assert not answer(), "the late command went out"
            core.command, held[0] = command, 0.0
            if late in lp.monitor.problems.active.get("guard", ""):
                break
            assert len(sends) == given  # held off after a pause of the test: again
        else:
            pytest.fail("no held-up command was taken while the monitor was not held off")
        assert sends[-1] is False
        refused = time.monotonic()
        assert not answer(), "a command went out while listening"
        assert spin_until(lp.executor, answer, 5.0), "the monitor never commanded again"
        assert time.monotonic() - refused > LISTEN
        assert "guard" not in lp.monitor.problems.active


def test_the_locked_set_survives_a_monitor_restart(tmp_path) -> None:
    state = {"state_directory": str(tmp_path)}
    domain = fresh_domain()
    with loop(monitor_parameters=state, domain=domain) as lp:
        lp.step(constant(np.full(7, 0.1)))
        lp.declare.publish(JointState(name=["panda_joint5"]))
        # Announced once written (its own thread: 1.9 s once, on a loaded machine).
        assert spin_until(lp.executor, lambda: lp.locked_names() == ["panda_joint5"], 10.0)
        lp.step(constant(np.full(7, 0.1)))  # its position, unknown until a state arrives
        assert spin_until(lp.executor, lambda: math.isfinite(
            lp.monitor.locked.get("panda_joint5", math.nan)), 10.0)
        position = lp.monitor.locked["panda_joint5"]
        assert math.isfinite(position)
    assert [p.name for p in tmp_path.iterdir()] == [f"monitor--panda--domain{domain}.state"]
    # Another ROS domain (a sim session beside the arm): nothing inherited.
    with loop(monitor_parameters=state) as lp:
        assert spin_until(lp.executor, lambda: bool(lp.locked), 2.0)
        assert lp.monitor.context.get_domain_id() != domain
        assert lp.locked_names() == [] and lp.monitor.locked == {}
    # The same domain: a new monitor process, the same directory.
    with loop(monitor_parameters=state, domain=domain) as lp:
        assert spin_until(lp.executor, lambda: lp.locked_names() == ["panda_joint5"], 2.0)
        assert lp.locked[-1].position[0] == pytest.approx(position)
        lp.step(constant(np.full(7, 0.1)))
        assert lp.commands[-1].velocity[4] == 0.0
        client = lp.node.create_client(Trigger, "monitor/reset")
        assert client.wait_for_service(timeout_sec=5.0)
        future = client.call_async(Trigger.Request())
        assert spin_until(lp.executor, future.done, 5.0) and future.result().success
        # Answered at once; the empty set is announced once on disk.
        assert spin_until(lp.executor, lambda: lp.locked_names() == [], 10.0)
    with loop(monitor_parameters=state, domain=domain) as lp:  # reset cleared the file too
        spin_until(lp.executor, lambda: bool(lp.locked), 2.0)
        assert lp.locked and lp.locked_names() == []


def test_a_corrupt_state_file_is_reported_and_ignored(tmp_path) -> None:
    domain = fresh_domain()
    (tmp_path / f"monitor--panda--domain{domain}.json").write_text("{not json")
    with loop(monitor_parameters={"state_directory": str(tmp_path)}, domain=domain) as lp:
        assert spin_until(lp.executor, lambda: bool(lp.locked), 2.0)
        assert lp.locked_names() == []
        assert "cannot read" in lp.monitor.problems.active["state_directory"]


def test_each_injected_lock_is_detected_on_the_right_joint_quickly() -> None:
    latencies = {}
    for joint in PANDA.joint_names:
        with loop(noise=1e-3) as lp:
            command = constant(np.full(7, 0.2))
            for _ in range(250):  # the detector first sees the plant follow (start-up)
                lp.step(command)
            assert lp.monitor.core.detector.not_observing is None
            lp.inject.publish(JointState(name=[joint]))
            assert spin_until(lp.executor, lambda j=joint: j in lp.sim.locked, 2.0)
            injected = lp.sim.t
            while not lp.monitor.core.locked and lp.sim.t < injected + 1.0:
                lp.step(command)
            assert lp.announced_names() == [joint]
            latencies[joint] = convert.stamp_seconds(lp.locked[-1].header.stamp) - injected
            lp.step(command)  # the next command: the locked joint gets exactly 0
            assert lp.commands[-1].velocity[PANDA.joint_names.index(joint)] == 0.0
    print("\ndetection latency (ms):",
          {j.removeprefix("panda_"): round(1000 * v) for j, v in latencies.items()})
    assert max(latencies.values()) < 0.15


def test_remap_keeps_the_tool_velocity_behind_a_failure_unaware_controller() -> None:
    xd = np.array([0.1, -0.06, 0.06, 0.0, 0.0, 0.3])  # joint 3 moves at about 0.05 rad/s
    with loop(monitor_parameters={"detection.min_command": 0.02}) as lp:
        def least_norm(lp: Loop) -> None:  # ignores ft/locked_joints
            lp.send(np.linalg.pinv(PANDA.jacobian(lp.sim.q)) @ xd)

        for _ in range(250):  # start-up: the detector sees the plant follow first
            lp.step(least_norm)
        lp.inject.publish(JointState(name=["panda_joint3"]))
        spin_until(lp.executor, lambda: "panda_joint3" in lp.sim.locked, 2.0)
        for _ in range(60):
            lp.step(least_norm)
        assert lp.announced_names() == ["panda_joint3"]
        out = np.array(lp.commands[-1].velocity)
        assert out[2] == 0.0
        q = lp.q_at_command  # what the monitor had measured when it remapped
        reduced = np.delete(PANDA.scale_task(PANDA.jacobian(q)), 2, axis=1)
        assert np.linalg.svd(reduced, compute_uv=False)[-1] > 0.01  # it can produce xd
        J = PANDA.jacobian(q)
        np.testing.assert_allclose(J @ out, J @ lp.last_raw, atol=1e-9)
        np.testing.assert_allclose(J @ out, xd, atol=1e-3)
        np.testing.assert_allclose(lp.arrays[-1].data, out)


def test_declared_failure_reset_and_the_latched_locked_set() -> None:
    with loop() as lp:
        command = constant(np.full(7, 0.1))
        lp.step(command)
        lp.declare.publish(JointState(name=["panda_joint5", "not_a_joint"]))
        assert spin_until(lp.executor, lambda: lp.locked_names() == ["panda_joint5"], 2.0)
        lp.step(command)
        assert lp.commands[-1].velocity[4] == 0.0
        # A node that starts later still learns the locked set (transient local).
        late: list[JointState] = []
        lp.node.create_subscription(JointState, "ft/locked_joints", late.append, qos.LATCHED)
        assert spin_until(lp.executor, lambda: bool(late), 2.0)
        assert list(late[-1].name) == ["panda_joint5"]
        client = lp.node.create_client(Trigger, "monitor/reset")
        assert client.wait_for_service(timeout_sec=5.0)
        future = client.call_async(Trigger.Request())
        assert spin_until(lp.executor, future.done, 5.0) and future.result().success
        assert spin_until(lp.executor, lambda: lp.locked_names() == [], 2.0)
        lp.step(command)
        assert lp.commands[-1].velocity[4] != 0.0


def test_a_flood_of_declarations_is_answered_once_per_period() -> None:
    """Issue 31 item 4: each repeated declaration was published again, 10 kHz of them."""
    from ft_monitor.monitor_node import REANNOUNCE_PERIOD

    with loop() as lp:
        lp.step(constant(np.full(7, 0.1)))
        lp.declare.publish(JointState(name=["panda_joint5"]))
        assert spin_until(lp.executor, lambda: lp.locked_names() == ["panda_joint5"], 2.0)
        before, started = len(lp.locked), time.monotonic()
        for _ in range(2000):
            lp.declare.publish(JointState(name=["panda_joint5"]))
        lp.declare.publish(JointState(name=["panda_joint6"]))  # behind the flood
        assert spin_until(lp.executor, lambda: "panda_joint6" in lp.locked_names(), 20.0)
        elapsed = time.monotonic() - started
        repeats = len(lp.locked) - before - 1
        assert 1 <= repeats <= elapsed / REANNOUNCE_PERIOD + 2, (repeats, elapsed)


def test_watchdog_publishes_zeros_until_commands_return() -> None:
    """Unsmoothed (the ramp: `test_with_smoothing_every_command_passes_the_driver_...`)."""
    with loop(monitor_parameters={"command_timeout": 0.05, "smooth_commands": False}) as lp:
        command = constant(np.full(7, 0.1))
        for _ in range(5):
            lp.step(command)
        before = len(lp.commands)
        # The watchdog runs on steady time: it fires even while simulated time stands still.
        assert spin_until(lp.executor, lambda: len(lp.commands) >= before + 2, 2.0)
        zeros = lp.commands[before:]
        assert len(zeros) >= 2 and all(np.all(np.array(c.velocity) == 0.0) for c in zeros)
        lp.step(command)
        assert np.all(np.array(lp.commands[-1].velocity) == 0.1)


def test_with_smoothing_every_command_passes_the_driver_and_a_stop_is_a_ramp() -> None:
    """The default: `ft/command` within Franka's limits read by its stamps, a lock too.

    A command step is reached on a ramp, then passed as it is; the locked joint gets 0 at
    once; with no command for `command_timeout` the watchdog brings the arm to rest on a
    ramp (simulated time runs meanwhile: the ramp's stamps are the monitor's clock).
    """
    limits = command_limits(PANDA.name, PANDA.joint_names, PANDA.velocity_limits)
    with loop(monitor_parameters={"command_timeout": 0.05}) as lp:
        for _ in range(100):
            lp.step(constant(np.full(7, 0.3)))
        assert np.all(np.array(lp.commands[-1].velocity) == 0.3)
        lp.declare.publish(JointState(name=["panda_joint2"]))
        assert spin_until(lp.executor, lambda: lp.locked_names() == ["panda_joint2"], 10.0)
        for _ in range(50):
            lp.step(constant(np.full(7, 0.3)))
        assert lp.commands[-1].velocity[1] == 0.0
        before = len(lp.commands)
        assert spin_until(lp.executor, lambda: (lp.sim.step(), len(lp.commands) > before + 3
                                                and not np.any(lp.commands[-1].velocity))[1],
                          10.0), "the watchdog's ramp never came to rest"
        # A ramp, not a step, by the stamps (simulated time runs at the spin's pace here:
        # a ramp can take one command or many).
        driver = DriverCheck(limits)
        for message in lp.commands:
            stamp = message.header.stamp.sec + message.header.stamp.nanosec * 1e-9
            # panda_joint2 is locked from its first zero on: its command is moot.
            refusal = driver.check(np.array(message.velocity), stamp,
                                   exempt=(1,) if message.velocity[1] == 0.0 else ())
            assert refusal is None, f"{refusal} at {stamp:.3f} s"
        assert driver.peaks[1].max() > 0.1  # judged while moving


def test_malformed_commands_become_explicit_zeros() -> None:
    # The command filter's own output.
    with loop(monitor_parameters={"smooth_commands": False}) as lp:
        lp.step(constant(np.full(7, 0.1)))
        for bad in ([np.nan] * 7, [0.1] * 6):
            lp.step(lambda lp, bad=bad: lp.raw.publish(JointState(
                header=JointState().header, name=list(PANDA.joint_names), velocity=bad)))
            assert np.all(np.array(lp.commands[-1].velocity) == 0.0)
        lp.step(lambda lp: lp.send([0.1] * 7, [*PANDA.joint_names[:6], "elbow"]))
        assert np.all(np.array(lp.commands[-1].velocity) == 0.0)
        # Issue 31 item 13: 1e308 rad/s was forwarded at the velocity limit; refused now.
        array = lp.node.create_publisher(Float64MultiArray, "ft/command_raw_array",
                                         qos.RELIABLE)
        for topic, send in (
                ("ft/command_raw", lambda lp: lp.send([0.1] * 6 + [1e308])),
                ("ft/command_raw_array", lambda lp: array.publish(Float64MultiArray(
                    data=[-2e3] + [0.1] * 6)))):
            lp.step(send)
            assert np.all(np.array(lp.commands[-1].velocity) == 0.0)
            assert "beyond 1000" in lp.monitor.problems.active[topic]
        lp.step(constant(np.full(7, 5.0)))  # above the velocity limits: scaled, not refused
        assert np.all(np.abs(lp.commands[-1].velocity) > 0.0)
        lp.step(constant(np.full(7, 0.1)))
        assert np.all(np.array(lp.commands[-1].velocity) == 0.1)  # recovered


def test_sim_limits_timeout_latency_and_scheduled_failure() -> None:
    with loop(sim_parameters={"command_timeout": 0.02, "command_latency": 0.008,
                              "failure.joint": "panda_joint1", "failure.time": 0.1}) as lp:
        direct = lp.node.create_publisher(JointState, "ft/command", qos.RELIABLE)
        direct.publish(convert.joint_state(PANDA.joint_names, lp.stamp(),
                                           velocity=np.full(7, 100.0)))  # beyond the limits
        assert spin_until(lp.executor, lambda: lp.sim.command_time > -math.inf, 2.0)
        lp.sim.step()  # latency 8 ms: 2 periods
        assert np.all(lp.sim.qd == 0.0)
        lp.sim.step()
        np.testing.assert_allclose(np.abs(lp.sim.qd[1:]), PANDA.velocity_limits[1:])
        for _ in range(10):  # no new command: after 20 ms the arm stops
            lp.sim.step()
        assert np.all(lp.sim.qd == 0.0)
        for _ in range(30):
            lp.step(constant(np.full(7, 0.1)))
        assert "panda_joint1" in lp.sim.locked and lp.sim.qd[0] == 0.0
        lp.inject.publish(JointState(name=["no_such_joint"]))
        spin_until(lp.executor, lambda: False, 0.2)
        assert set(lp.sim.locked) == {"panda_joint1"}


def test_fault_injector_zeroes_the_locked_joints_on_the_command_path() -> None:
    from ft_sim.fault_injector_node import FaultInjectorNode

    joints = list(PANDA.joint_names)
    with ros_context() as (context, executor):
        proxy = FaultInjectorNode(context=context,
                                  parameter_overrides=[Parameter("joints", value=joints)])
        node = harness_node("plant_side", context)
        for n in (proxy, node):
            executor.add_node(n)
        commands, arrays = [], []
        node.create_subscription(JointState, "faulty/command", commands.append, qos.RELIABLE)
        node.create_subscription(Float64MultiArray, "faulty/command_array", arrays.append,
                                 qos.RELIABLE)
        command = node.create_publisher(JointState, "ft/command", qos.RELIABLE)
        array = node.create_publisher(Float64MultiArray, "ft/command_array", qos.RELIABLE)
        inject = node.create_publisher(JointState, "ft/inject_failure", qos.RELIABLE)

        def send() -> None:
            command.publish(convert.joint_state(joints, convert.stamp_from_nanoseconds(1),
                                                velocity=np.full(7, 0.3)))
            array.publish(Float64MultiArray(data=[0.3] * 7))

        assert spin_until(executor, lambda: (send(), bool(commands) and bool(arrays))[1], 5.0)
        assert list(commands[-1].velocity) == [0.3] * 7
        inject.publish(JointState(name=["panda_joint2", "bogus"]))
        assert spin_until(executor, lambda: proxy.locked == {"panda_joint2"}, 5.0)
        def zeroed() -> bool:  # commands sent before the lock may still be in flight
            send()
            return (bool(commands) and commands[-1].velocity[1] == 0.0
                    and bool(arrays) and arrays[-1].data[1] == 0.0)

        assert spin_until(executor, zeroed, 5.0)
        assert commands[-1].velocity[0] == 0.3 and arrays[-1].data[0] == 0.3
        # Malformed commands never reach the plant: explicit zeros instead (issue 14).
        def zeros_arrive(publish) -> bool:
            def condition() -> bool:
                publish()
                return (bool(commands) and all(v == 0.0 for v in commands[-1].velocity)
                        and all(v == 0.0 for v in arrays[-1].data))
            return spin_until(executor, condition, 5.0)

        for bad in ([math.nan] * 7, [1e300] * 7, [math.inf] * 7):
            assert zeros_arrive(lambda bad=bad: command.publish(convert.joint_state(
                joints, convert.stamp_from_nanoseconds(1), velocity=bad)))
        assert zeros_arrive(lambda: command.publish(JointState(  # a duplicate name
            name=[*joints, joints[0]], velocity=[0.3] * 8)))
        assert list(commands[-1].name) == joints
        assert zeros_arrive(lambda: array.publish(Float64MultiArray(data=[math.nan] * 7)))
        forwarded = [v for c in commands for v in c.velocity] + [v for a in arrays for v in a.data]
        assert all(math.isfinite(v) and abs(v) <= 100.0 for v in forwarded)


def test_velocity_arrays_in_joints_order_are_accepted_as_commands() -> None:
    with loop(monitor_parameters={"smooth_commands": False}) as lp:
        array = lp.node.create_publisher(Float64MultiArray, "ft/command_raw_array", qos.RELIABLE)
        lp.step(lambda lp: array.publish(Float64MultiArray(data=[0.1] * 7)))
        assert np.all(np.array(lp.commands[-1].velocity) == 0.1)
        lp.step(lambda lp: array.publish(Float64MultiArray(data=[0.1] * 5)))
        assert np.all(np.array(lp.commands[-1].velocity) == 0.0)  # malformed: zeros


def test_joint_states_going_back_in_time_are_rejected() -> None:
    with loop() as lp:
        lp.step(constant(np.full(7, 0.1)))
        latest = lp.monitor.core.q.copy()
        old = convert.joint_state(PANDA.joint_names, convert.stamp_from_nanoseconds(1),
                                  position=np.zeros(7))
        lp.node.create_publisher(JointState, "joint_states", qos.RELIABLE).publish(old)
        assert spin_until(lp.executor, lambda: "joint_states" in lp.monitor.problems.active, 2.0)
        np.testing.assert_array_equal(lp.monitor.core.q, latest)  # the older state is not used


def test_physically_absurd_joint_states_are_refused_and_never_reach_diagnostics() -> None:
    """Issue 31 items 1 and 2: absurd positions never reach the detector.

    A position of 1e308 made the monitor exit (an empty selection in the detector's
    identification), 1e300 put inf and nan in diagnostics.
    """
    with loop() as lp:
        for _ in range(50):
            lp.step(sweep)
        latest = lp.monitor.core.q.copy()
        states = lp.node.create_publisher(JointState, "joint_states", qos.RELIABLE)
        for huge in (1e308, -1e300, 3.5):  # 3.5 rad: more than 1 rad past panda_joint4's 0.07
            position = latest.copy()
            position[3] = huge
            states.publish(convert.joint_state(PANDA.joint_names, lp.stamp(), position=position))
            assert spin_until(lp.executor, lambda: "outside its limits" in lp.monitor.problems
                              .active.get("joint_states", ""), 2.0), huge
            np.testing.assert_array_equal(lp.monitor.core.q, latest)  # not used
            lp.monitor.problems.report("joint_states", None)
        status = lp.diagnostics_after(lp.sim.t, sweep)  # the loop goes on
        assert "joint_states" not in lp.monitor.problems.active
        for item in status.values:
            try:
                value = float(item.value)
            except ValueError:
                continue
            assert math.isfinite(value), (item.key, item.value)


def test_an_injection_naming_a_hundred_thousand_joints_is_refused_at_once() -> None:
    """Issue 31 item 3: one warning per unknown name froze the sim for 15.5 s."""
    with loop() as lp:
        swing = lp.node.create_publisher(JointState, "ft/inject_free_swing", qos.RELIABLE)
        flood = JointState(name=[f"bogus_{k}" for k in range(100_000)])
        swing.publish(flood)
        lp.inject.publish(flood)
        lp.inject.publish(JointState(name=["bogus", "panda_joint2"]))  # one unknown: dropped
        assert spin_until(lp.executor, lambda: set(lp.sim.locked) == {"panda_joint2"}, 5.0), (
            "the sim did not take the next injection within 5 s")
        assert lp.sim.swinging == []


def test_sim_plant_options_take_effect_and_invalid_ones_are_refused() -> None:
    with loop(sim_parameters={"response_time": 0.05, "hold_last_command": True},
              monitor_parameters={"smooth_commands": False}) as lp:
        lp.step(constant(np.full(7, 0.2)))
        for _ in range(125):  # 0.5 s with no new command: held, and the lag has settled
            lp.sim.step()
        np.testing.assert_allclose(lp.sim.qd, 0.2, rtol=1e-3)
        sim = lp.sim
        refused = sim.set_parameters([Parameter("acceleration_limit", value=[1.0, 2.0])])[0]
        assert not refused.successful and "2 values for 7 joints" in refused.reason
        assert not sim.set_parameters([Parameter("response_time", value=-1.0)])[0].successful
        assert sim.set_parameters([Parameter("acceleration_limit", value=[0.5])])[0].successful
        before = lp.sim.qd.copy()
        lp.step(constant(np.full(7, -0.2)))  # reversing at 0.5 rad/s^2
        np.testing.assert_allclose(lp.sim.qd, before - 0.5 / 250, rtol=1e-9)


def test_stale_huge_and_duplicate_inputs_cost_little_and_change_nothing() -> None:
    # command_timeout also decides what is stale (its default here, not the loop's 60 s).
    with loop(monitor_parameters={"command_timeout": 0.2, "smooth_commands": False}) as lp:
        for _ in range(100):
            lp.step(constant(np.full(7, 0.1)))
        old = convert.joint_state(PANDA.joint_names, convert.stamp_from_nanoseconds(1),
                                  velocity=[0.1] * 7)  # stamped in 1970
        lp.step(lambda lp: lp.raw.publish(old))
        assert np.all(np.array(lp.commands[-1].velocity) == 0.0)
        assert "stale" in lp.monitor.problems.active["ft/command_raw"]
        duplicates = convert.joint_state(["panda_joint1"] * 20_000, lp.stamp(),
                                         velocity=[0.1] * 20_000)
        start = time.perf_counter()
        lp.step(lambda lp: lp.raw.publish(duplicates))
        assert time.perf_counter() - start < 1.0
        assert np.all(np.array(lp.commands[-1].velocity) == 0.0)
        start = time.perf_counter()
        lp.declare.publish(JointState(name=[f"no_joint_{i}" for i in range(100_000)]))
        lp.declare.publish(JointState(name=[f"no_joint_{i % 500}" for i in range(1000)]))
        lp.step(constant(np.full(7, 0.1)))
        assert time.perf_counter() - start < 2.0
        assert lp.monitor.locked == {}
        assert np.all(np.array(lp.commands[-1].velocity) == 0.1)  # recovered


def test_a_model_from_the_parameters_is_never_reloaded() -> None:
    with loop() as lp:
        client = lp.node.create_client(Trigger, "monitor/reload_model")
        assert client.wait_for_service(timeout_sec=5.0)
        future = client.call_async(Trigger.Request())
        assert spin_until(lp.executor, future.done, 5.0)
        assert not future.result().success
        assert "restart the node" in future.result().message


def test_joint_health_is_latched_says_what_each_joint_is_and_never_flaps() -> None:
    """`ft/joint_health`: one status per joint; a lock found and one declared, then reset."""
    with loop(noise=1e-3) as lp:
        command = constant(np.full(7, 0.2))
        for _ in range(250):  # the detector first sees the plant follow (start-up)
            lp.step(command)
        lp.inject.publish(JointState(name=["panda_joint3"]))
        assert spin_until(lp.executor, lambda: "panda_joint3" in lp.sim.locked, 2.0)
        injected = lp.sim.t
        while not lp.monitor.core.locked and lp.sim.t < injected + 1.0:
            lp.step(command)
        assert lp.announced_names() == ["panda_joint3"]
        lp.declare.publish(JointState(name=["panda_joint6"]))
        assert spin_until(lp.executor, lambda: sorted(lp.locked_names()) == [
            "panda_joint3", "panda_joint6"], 2.0)
        for _ in range(150):  # 0.6 s more: the locked joint never becomes healthy again
            lp.step(command)
        late: list[DiagnosticArray] = []  # a node that starts later gets the last one
        lp.node.create_subscription(DiagnosticArray, "ft/joint_health", late.append,
                                    qos.LATCHED)
        assert spin_until(lp.executor, lambda: bool(late), 2.0), "ft/joint_health not latched"
        states, unknown = health.read(late[-1], PANDA.joint_names)
        assert unknown == [] and list(states) == list(PANDA.joint_names)
        assert {n: str(s.state) for n, s in states.items() if s.state != Health.HEALTHY} == {
            "panda_joint3": "locked", "panda_joint6": "locked"}
        assert "locked at" in states["panda_joint3"].evidence
        assert "ft/declare_failure" in states["panda_joint6"].evidence
        assert states["panda_joint3"].since == pytest.approx(
            convert.stamp_seconds(lp.locked[-1].header.stamp), abs=0.2)
        assert 0.8 < states["panda_joint1"].follows <= 1.0  # a healthy joint follows
        assert (states["panda_joint1"].usable_lower, states["panda_joint1"].usable_upper) == (
            pytest.approx(PANDA.lower[0]), pytest.approx(PANDA.upper[0]))
        levels = {s.name: s.level for s in late[-1].status}
        assert levels["panda_joint3"] == diagnostics.ERROR
        assert levels["panda_joint1"] == diagnostics.OK
        client = lp.node.create_client(Trigger, "monitor/reset")
        assert client.wait_for_service(timeout_sec=5.0)
        count = len(late)
        future = client.call_async(Trigger.Request())
        assert spin_until(lp.executor, future.done, 5.0) and future.result().success

        def healthy() -> bool:
            return len(late) > count and all(s.message == "healthy" for s in late[-1].status)

        for _ in range(200):
            if healthy():
                break
            lp.step(command)
        assert healthy(), "the joints were not healthy again after ~/reset"
