"""Helpers for in-process ROS 2 tests: a private context and spinning until a condition holds."""

from __future__ import annotations

import contextlib
import itertools
import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from ft_msgs_py import convert, qos
from ft_msgs_py.spin import LockStepExecutor, harness_node, spin_until
from rclpy.context import Context
from rclpy.executors import Executor
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

_contexts = itertools.count()


@contextmanager
def ros_context(shared: bool = False, executor_type: type[Executor] = LockStepExecutor,
                domain: int | None = None) -> Iterator[tuple[Context, Executor]]:
    """A fresh rclpy context with its own executor, shut down afterwards.

    Each context gets a DDS domain of its own, so a latched message of a node from
    an earlier test cannot reach this one; `shared` uses the session's
    ROS_DOMAIN_ID instead, to talk with nodes in subprocesses, and `domain` a given
    one (a restart in the same domain, from `fresh_domain`). `executor_type` is the
    lock-step harnesses' `LockStepExecutor` or the EventsExecutor the executables
    spin.
    """
    if domain is None:
        domain = int(os.environ["ROS_DOMAIN_ID"]) if shared else fresh_domain()
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    executor = executor_type(context=context)
    try:
        yield context, executor
    finally:
        # Destroyed here, not when garbage collected: a node alive after its context (a
        # test's local, a thread's reference) keeps its DDS entities, and its latched
        # locked set reached a later test's context in the same domain.
        for node in executor.get_nodes():
            with contextlib.suppress(Exception):  # destroyed by the test already
                node.destroy_node()
        executor.shutdown()
        rclpy.shutdown(context=context)


def fresh_domain() -> int:
    """A DDS domain for one test context: never the session's, the next of its block each call.

    The block (conftest.py) is this pytest process's alone, so workers of one run never
    meet; within it the domains come round again after size - 1 contexts.
    """
    start, size = (int(v) for v in os.environ["FT_TEST_DOMAINS"].split(","))
    return 1 + (start + 1 + next(_contexts) % (size - 1)) % 100


class FakePlant:
    """A kinematic plant for node tests, in simulated time.

    Each `step()` advances the clock by dt, integrates the last velocity command
    (unless `frozen`), publishes `/clock` and a stamped `joint_states`, then spins
    until a command stamped with the new time arrives (or `timeout`). It also
    records the commands, metrics and diagnostics it sees.
    """

    def __init__(self, context: Context, executor: Executor,
                 joints: list[str], q0, dt: float = 0.01, command_topic: str = "ft/command_raw"):
        self.node = harness_node("fake_plant", context)
        self.executor = executor
        executor.add_node(self.node)
        self.joints, self.q, self.dt = list(joints), np.array(q0, dtype=float), dt
        self.t_ns = 1_000_000_000
        self.frozen = False
        self.publish_states = True
        self.commands: list[JointState] = []
        self.metrics: list[Float64MultiArray] = []
        self.diagnostics: list[DiagnosticArray] = []
        self._clock = self.node.create_publisher(Clock, "/clock", 10)
        self.state_pub = self.node.create_publisher(JointState, "joint_states", qos.RELIABLE)
        self.node.create_subscription(JointState, command_topic, self.commands.append,
                                      qos.SENSOR_INPUT)
        self.node.create_subscription(Float64MultiArray, "ft/metrics", self.metrics.append,
                                      qos.SENSOR_INPUT)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self.diagnostics.append,
                                      qos.SENSOR_INPUT)

    @property
    def t(self) -> float:
        return self.t_ns * 1e-9

    def stamp(self):
        return convert.stamp_from_nanoseconds(self.t_ns)

    def velocity(self):
        """The last command as a vector in `joints` order (zeros before any)."""
        if not self.commands:
            return np.zeros(len(self.joints))
        last = self.commands[-1]
        by_name = dict(zip(last.name, last.velocity, strict=True))
        return np.array([by_name[j] for j in self.joints])

    def publish_state(self, **overrides) -> None:
        msg = convert.joint_state(self.joints, self.stamp(), position=self.q)
        for field, value in overrides.items():
            setattr(msg, field, value)
        self.state_pub.publish(msg)

    def step(self, timeout: float = 2.0) -> bool:
        if not self.frozen:
            self.q = self.q + self.dt * self.velocity()
        self.t_ns += round(self.dt * 1e9)
        if self.publish_states:
            self.publish_state()
        self._clock.publish(Clock(clock=self.stamp()))
        target = self.t_ns

        def fresh() -> bool:
            if not self.commands:
                return False
            stamp = self.commands[-1].header.stamp
            return stamp.sec * 1_000_000_000 + stamp.nanosec >= target

        return spin_until(self.executor, fresh, timeout)

    def run(self, steps: int, each=None) -> None:
        """`steps` steps, calling `each(plant)` before every one; each must get its command."""
        for step in range(steps):
            if each is not None:
                each(self)
            assert self.step(), f"no fresh command at step {step} of {steps}"


def in_thread(work):
    """Run `work()` in a fresh thread (never on pytest's own) and return what it returned."""
    result = []
    thread = threading.Thread(target=lambda: result.append(work()))
    thread.start()
    thread.join(10.0)
    assert result, "the thread did not finish"
    return result[0]
