"""The suite's node base: parameter values, clock seconds and once-per-episode problems."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Sequence
from typing import TypeAlias

import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from rclpy.subscription import Subscription
from rclpy.timer import Timer
from sensor_msgs.msg import JointState

from ft_msgs_py import convert, diagnostics, parameters, rclpy_private, thread_priority, wire
from ft_msgs_py.audience import Audience
from ft_msgs_py.episodes import FUTURE_TOLERANCE, FUTURE_TOLERANCE_SIM_TIME, Episodes

#: A joint state as a callback gets it: read from its bytes (`SuiteNode.subscribe_joint_states`)
#: or, from a harness calling the callback, the message itself.
JointStateLike: TypeAlias = JointState | wire.JointStateView

#: A joint state as a node of the same process read it: positions (rad), the joints they
#: are of, stamp (s).
StateReading = tuple[np.ndarray, tuple[str, ...], float]
#: Given each joint state a node takes, with its reading (None: the message failed that
#: node's checks of the message itself, `SuiteNode.parse_joint_state`).
StateListener = Callable[[JointStateLike, StateReading | None], None]
#: Publishes the next command of a stop ramp stamped with the given node-clock time (ns);
#: returns whether the commands are at rest.
RampStep = Callable[[int], bool]
#: s (steady) between two commands of a stop ramp (`SuiteNode.ramp`).
RAMP_PERIOD = 0.004


class SuiteNode(Node):
    """A rclpy Node with the small helpers every suite node uses."""

    def __init__(self, name: str, **kwargs):
        super().__init__(name, **kwargs)
        sim_time = self.get_parameter("use_sim_time").value
        self.problems = Episodes(self.get_logger(), FUTURE_TOLERANCE_SIM_TIME if sim_time
                                 else FUTURE_TOLERANCE)
        self.state_stamp = -math.inf  #: stamp (s) of the last joint state accepted
        self._read_clock = rclpy_private.clock_nanoseconds(self.get_clock())  # `now_ns`
        self._on_demand: set[Subscription] = set()  # kept from executors (`take_on_demand`)
        self._ramp_timer: Timer | None = None  # the stop ramp under way (`ramp`)

    def ramp(self, step: RampStep) -> None:
        """Call `step` every RAMP_PERIOD s (steady) until it says the commands are at rest.

        A stop ramp while no other command comes (a watchdog's): one at a time, the
        newest `step` in charge; `stop_ramp` ends it early (commands came back).
        """
        def tick() -> None:
            if step(self.now_ns()):
                self.stop_ramp()

        self.stop_ramp()
        self._ramp_timer = self.create_timer(RAMP_PERIOD, tick,
                                             clock=Clock(clock_type=ClockType.STEADY_TIME))

    def stop_ramp(self) -> None:
        """End the stop ramp under way, if any."""
        if self._ramp_timer is not None:
            self.destroy_timer(self._ramp_timer)
            self._ramp_timer = None

    def ramp_now(self, step: RampStep, bound: float) -> None:
        """On shutdown: a stop ramp in this thread, at most `bound` s (steady).

        The stamps advance with steady time from the node clock's reading now: a
        simulated clock may have stopped with the simulation.
        """
        self.stop_ramp()
        start, start_ns = time.monotonic(), self.now_ns()
        while True:
            elapsed = time.monotonic() - start
            if step(start_ns + round(elapsed * 1e9)) or elapsed > bound:
                return
            time.sleep(RAMP_PERIOD)

    def apply_thread_priority(self) -> str:
        """Apply the `thread_priority` parameter to the calling thread; how it is scheduled.

        Call it from the thread that will spin the node (the executables construct
        their nodes there). A refusal is logged as a warning; the node runs on.
        """
        priority = self.param("thread_priority")
        refused = thread_priority.apply(priority)
        if refused is not None:
            self.get_logger().warning(f"thread_priority: {refused}; running on the normal "
                                      "scheduler")
            return "normal (SCHED_FIFO refused)"
        return f"SCHED_FIFO {priority}" if priority else "normal"

    def param(self, name: str):
        """The current value of a parameter."""
        return parameters.value(self, name)

    def status(self, level: bytes, message: str, values: dict | None = None,
               joint: str | None = None):
        """A diagnostic status named after this node, or after one of its joints.

        The name is the node's fully qualified name (so namespaced arms stay apart),
        hardware_id the robot's name.
        """
        name = self.get_fully_qualified_name() + (f": joint {joint}" if joint else "")
        robot = getattr(self, "robot", None)
        return diagnostics.status(name, level, message, values,
                                  hardware_id=robot.name if robot is not None else "")

    def now(self) -> float:
        """The node clock (wall or simulated) in seconds."""
        return self.now_ns() * 1e-9

    def now_ns(self) -> int:
        """The node clock (wall or simulated) in nanoseconds.

        The same value `get_clock().now()` has, read without building an
        `rclpy.time.Time` (`rclpy_private.clock_nanoseconds`).
        """
        return self._read_clock()

    @property
    def subscriptions(self) -> Iterator[Subscription]:
        """The subscriptions an executor dispatches: all but those taken on demand."""
        return (s for s in super().subscriptions if s not in self._on_demand)

    def take_on_demand(self, subscription: Subscription) -> Callable[[], None]:
        """Keep `subscription` from the executor; returns the call that takes its messages now.

        The call hands the messages waiting in the subscription's queue (oldest first, at
        most its QoS depth) to its callback, as the executor would have on their arrival.
        For a loop that reads its inputs at the top of each cycle, as ros2_control's
        controllers read their state interfaces (`ControllerNode.cycle_on_loop_ticks`):
        a message does not wake the executor, whose every wake-up costs the process
        CPU (docs/benchmarks.md). The subscription stays the node's: in the graph,
        remapped, with its QoS events, destroyed with the node.
        Executors read `subscriptions`, and the messages are taken beneath rclpy's public
        API (`rclpy_private.message_taker`); call this before the node spins (an executor
        spinning already keeps dispatching it until the node's next change of entities).
        """
        self._on_demand.add(subscription)
        take_one = rclpy_private.message_taker(subscription)
        callback, depth = subscription.callback, max(subscription.qos_profile.depth, 1)

        def take() -> None:
            for _ in range(depth):  # bounded: what arrives meanwhile waits for the next call
                msg = take_one()
                if msg is None:
                    return
                callback(msg)
        return take

    def create_counted_publisher(self, msg_type: type, topic: str, qos_profile: QoSProfile,
                                 ) -> tuple[Publisher, Audience]:
        """A publisher and its `Audience`: its subscription count without a middleware call."""
        audience = Audience()
        publisher = self.create_publisher(
            msg_type, topic, qos_profile,
            event_callbacks=PublisherEventCallbacks(matched=audience.matched))
        return publisher, audience

    def subscribe_joint_states(
            self, topic: str, callback: Callable[[JointStateLike], None],
            qos_profile: QoSProfile,
            malformed: Callable[[convert.MessageError], None] | None = None,
            publishers: Audience | None = None) -> Subscription:
        """Take `topic`'s JointStates as bytes: `callback` gets what a JointStateReader reads.

        Bytes that are not a JointState go to `malformed`, or by default are reported
        under `topic` and go no further. `publishers` counts the publishers matched.
        """
        reader = wire.JointStateReader()

        def take(raw: bytes) -> None:
            try:
                msg = reader.read(raw)
            except convert.MessageError as error:
                if malformed is not None:
                    malformed(error)
                else:
                    self.problems.report(topic, f"{error}: message ignored")
                return
            callback(msg)
        return self.create_subscription(
            JointState, topic, take, qos_profile, raw=True,
            event_callbacks=None if publishers is None else SubscriptionEventCallbacks(
                matched=publishers.matched))

    def read_joint_state(self, msg: JointStateLike, joints: Sequence[str],
                         absurd: Callable[[np.ndarray], str | None] | None = None,
                         ) -> np.ndarray | None:
        """Positions of `joints` from a joint state, or None (reported under `joint_states`).

        Rejected: a stamp ahead of the clock or going backwards, what
        `convert.joint_vector` rejects, and positions `absurd` gives a reason for. On
        success `state_stamp` is the message's time.
        """
        reading = self.parse_joint_state(msg, joints)
        return None if reading is None else self.accept_joint_state(*reading, absurd)

    def parse_joint_state(self, msg: JointStateLike, joints: Sequence[str],
                          ) -> tuple[np.ndarray, float] | None:
        """`read_joint_state`'s checks of the message alone: (positions, stamp in s) or None.

        Nothing is accepted yet (`accept_joint_state`); what is rejected is reported.
        """
        stamp = self.problems.message_time("joint_states", msg.header.stamp, self.now())
        if stamp is None or not self._in_order(stamp):
            return None
        try:
            return convert.joint_vector(msg, joints), stamp
        except convert.MessageError as error:
            self.problems.report("joint_states", str(error))
            return None

    def accept_joint_state(self, q: np.ndarray, stamp: float,
                           absurd: Callable[[np.ndarray], str | None] | None = None,
                           ) -> np.ndarray | None:
        """Positions parsed (here or by a node of the same process) at `stamp` (s), or None.

        Rejected, and reported: a stamp before this node's `state_stamp`, positions
        `absurd` gives a reason for. On success `state_stamp` is `stamp`.
        """
        if not self._in_order(stamp):
            return None
        reason = None if absurd is None else absurd(q)
        if reason is not None:
            self.problems.report("joint_states", f"{reason}: joint state ignored")
            return None
        self.problems.report("joint_states", None)
        self.state_stamp = stamp
        return q

    def _in_order(self, stamp: float) -> bool:
        if stamp < self.state_stamp:
            self.problems.report("joint_states", f"stamp {stamp:.3f} s goes backwards "
                                                 f"(last {self.state_stamp:.3f} s)")
            return False
        return True
