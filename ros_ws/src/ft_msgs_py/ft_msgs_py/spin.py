"""The executables' entry point: spin a node until SIGINT or SIGTERM, stop it, shut down.

rclpy's own signal handling is off, and so is Python's KeyboardInterrupt: a signal
only sets a flag, which the loop checks between short spins. An exception raised
by a signal inside rclpy's C++ layer (while it converts a message) would surface as
an unrelated RuntimeError and end the process with an error; with the flag it
cannot happen, and the node always gets to run its `stop()` (e.g. command zeros).

The executor is rclpy's EventsExecutor (`rclpy.experimental`, shipped with Jazzy):
it queues ready entities in C++ instead of rebuilding a wait set in Python on
every spin, which at 500 Hz is the difference between keeping the control rate and
losing cycles (docs/benchmarks.md). Timers on simulated time
(`use_sim_time`) fire as with the SingleThreadedExecutor: node tests run on both.

Once every node has stopped (its zeros sent and acknowledged), the middleware's
teardown gets TEARDOWN_TIMEOUT s; after that the process exits anyway, saying so on
stderr. Fast DDS 2.14 can deadlock destroying a participant while its discovery thread
handles a remote endpoint going away (the main thread waiting in
`DomainParticipant::set_listener` for a listener blocked on a mutex it holds, at
most of a core, forever): a process asked to stop must not outlive its work.

Before spinning, the objects built at start-up (the robot model, numba's compiled
code, rclpy's entities: over a hundred thousand objects in one process running the
whole stack) are frozen out of the cyclic garbage collector's sight (`settle_heap`).
Otherwise every full collection, every minute or two, walks all of them: tens of
milliseconds with the control loop stalled, some tens of missed cycles at 500 Hz.
"""

from __future__ import annotations

import gc
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import Protocol, cast, runtime_checkable

import rclpy
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.event_handler import EventHandler, QoSPublisherEventType
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.experimental.events_executor import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.signals import SignalHandlerOptions
from rclpy.subscription import Subscription
from rclpy.type_description_service import START_TYPE_DESCRIPTION_SERVICE_PARAM

from ft_msgs_py.huge_pages import refuse_huge_pages
from ft_msgs_py.transport import avoid_shared_memory

#: Longest time (s) between two checks of the stop flag.
CHECK_PERIOD = 0.1
#: s each reliable publisher waits, on shutdown, for its last messages to be acknowledged.
DELIVERY_TIMEOUT = 1.0
#: s the middleware's teardown may take once the nodes stopped; then the process exits.
TEARDOWN_TIMEOUT = 5.0


def settle_heap() -> None:
    """Collect start-up garbage, then exclude every live object from later collections.

    `gc.freeze()`: full collections then walk only what was allocated since, so
    they take microseconds instead of tens of milliseconds (docs/benchmarks.md).
    Frozen objects are still freed by reference counting.
    """
    gc.collect()
    gc.freeze()


class LockStepExecutor(SingleThreadedExecutor):
    """rclpy's SingleThreadedExecutor for the harnesses that step simulated time by hand.

    The sim, the controller, the monitor and a driver in one process, in lock-step
    (`ft_sim.scenario`, the node tests): the SingleThreadedExecutor (not the
    EventsExecutor the executables spin, whose timers live on a thread of their own)
    keeps every run deterministic, but rebuilds its wait set in Python on each spin,
    some 9 times a simulated step, at a cost that grows with its entities. It drops
    the QoS-event handlers rclpy gives every publisher and subscription by default
    (incompatible QoS or type): in one process, on topics whose QoS the harness chose,
    they never fire, and they are many of the wait set's entities, each adding to every
    spin's cost. Entities created after
    `add_node` lose theirs at the next spin. A publisher's matched events stay: a node
    asked for them, to count its subscribers (`ft_msgs_py.audience`).
    """

    def spin_once(self, timeout_sec: float | None = None) -> None:
        """Spin once (as rclpy does), after dropping the event handlers of new entities."""
        nodes = self.get_nodes()
        if any(not _asked_for(waitable) for node in nodes for waitable in node.waitables):
            for node in nodes:
                _drop_event_handlers(node)
        super().spin_once(timeout_sec)


def _asked_for(waitable: object) -> bool:
    """Whether a node's waitable is a publisher's matched event, which a node asks for."""
    kind = getattr(waitable, "event_type", None)  # pybind11 enums of two types compare
    return (isinstance(kind, QoSPublisherEventType)  # by value: the type first
            and kind == QoSPublisherEventType.RCL_PUBLISHER_MATCHED)


def _drop_event_handlers(node: Node) -> None:
    """Remove the QoS-event handlers rclpy gives the node's publishers and subscriptions."""
    entities: list[Publisher | Subscription] = [*node.publishers, *node.subscriptions]
    for entity in entities:
        # A list of handlers, whatever rclpy's annotation (one EventHandler) says.
        handlers = cast("list[EventHandler]", entity.event_handlers)
        for handler in [h for h in handlers if not _asked_for(h)]:
            node.remove_waitable(handler)
            handler.destroy()
            handlers.remove(handler)  # so destroy_publisher/subscription skips it too


def harness_node(name: str, context: Context) -> Node:
    """A plain node for a lock-step harness's own publishers and subscriptions.

    No parameter or type-description services (`node_arguments`).
    """
    return rclpy.create_node(name, context=context, **node_arguments({}, services=False))


def node_arguments(values: dict, services: bool = True) -> dict:
    """A node's keyword arguments: `values` (name -> value) as its parameter overrides.

    With `services` False the node serves neither its parameters nor its type
    description, as a harness's nodes need not (nobody calls them, and each service is
    one more entity in every wait set the LockStepExecutor rebuilds).
    """
    overrides = values if services else {**values, START_TYPE_DESCRIPTION_SERVICE_PARAM: False}
    return {"parameter_overrides": [Parameter(k, value=v) for k, v in overrides.items()],
            "start_parameter_services": services}


def spin_until(executor: Executor, condition: Callable[[], bool],
               timeout: float = 10.0) -> bool:
    """Spin until `condition()` holds or `timeout` s of wall clock pass; whether it holds.

    The one wait of the suite's harnesses (node tests, the scenario of the demo and the
    campaign, the benchmarks): callers fail, with what they waited for, when it is False.
    """
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            return condition()
        executor.spin_once(timeout_sec=0.01)
    return True


def spin_for(executor: Executor, seconds: float) -> float:
    """Spin for `seconds` of wall clock; returns the time actually spun (s)."""
    start = time.monotonic()
    while time.monotonic() - start < seconds:
        executor.spin_once(timeout_sec=0.01)
    return time.monotonic() - start


def run_node(make_node: Callable[[], Node], args: list[str] | None = None) -> None:
    """Spin the node until SIGINT or SIGTERM; then its `stop()` (if any) and exit cleanly."""
    run_nodes([make_node], args)


@runtime_checkable
class Ticked(Protocol):
    """A node this loop ticks itself (`run_nodes`), instead of an rclpy timer.

    The executor's timer thread wakes the loop once per tick besides the messages; a
    deadline the loop waits for in `spin_once` costs no other thread (docs/benchmarks.md).
    """

    def next_tick(self) -> float:
        """Steady time (s, `time.monotonic`) of the next tick; `math.inf`: none."""

    def tick(self, now: float) -> None:
        """The tick due at or before `now` (steady s)."""


def run_nodes(makers: Sequence[Callable[[], Node]], args: list[str] | None = None,
              wire: Callable[[list[Node]], None] = lambda _nodes: None) -> None:
    """`run_node` for several nodes in one process, on one executor (a component container).

    Messages between them go through the middleware (the same topics, QoS and remappings as
    in separate processes) unless `wire`, called with the nodes once made, connects some of
    them by calls instead; no process boundary either way: one interpreter, one heap, no
    context switch between them. On SIGINT or SIGTERM every node's `stop()` runs, in order,
    and its reliable publishers get up to DELIVERY_TIMEOUT s each for their subscribers to
    acknowledge what it sent (the zeros: a driver that holds its last command must have them
    before the process is gone); the teardown that follows is bounded by TEARDOWN_TIMEOUT
    (`exit_if_stuck`). A node that is `Ticked`, or whose `cycles` (`loop.CycleDriver`) is,
    gets its ticks from this loop, which waits for the next one in `spin_once` (messages are
    taken meanwhile). The process keeps off Fast DDS's shared memory
    (`ft_msgs_py.transport`) and out of transparent huge pages (`ft_msgs_py.huge_pages`).
    """
    stop_requested = threading.Event()
    previous = {sig: signal.signal(sig, lambda *_: stop_requested.set())
                for sig in (signal.SIGINT, signal.SIGTERM)}
    transport = avoid_shared_memory()  # before the participant is made
    huge = refuse_huge_pages()  # before the arrays are made
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    nodes = [make() for make in makers]
    if huge is not None:
        nodes[0].get_logger().warning(f"transparent huge pages left on: {huge}")
    if transport is not None:
        nodes[0].get_logger().info(f"Fast DDS without shared memory: {transport} "
                                   "(a killed process cannot stall this one)")
    wire(nodes)
    settle_heap()
    executor = EventsExecutor()
    for node in nodes:
        executor.add_node(node)
    ticked: list[Ticked] = [driver for node in nodes
                            if isinstance(driver := getattr(node, "cycles", node), Ticked)]
    try:
        while not stop_requested.is_set() and rclpy.ok():
            now, wait = time.monotonic(), CHECK_PERIOD
            for driver in ticked:
                if driver.next_tick() <= now:
                    driver.tick(now)
                    now = time.monotonic()
                wait = min(wait, driver.next_tick() - now)
            executor.spin_once(timeout_sec=max(wait, 0.0))
    finally:
        for node in nodes:
            stop = getattr(node, "stop", None)
            if stop is not None:
                stop()
                for publisher in node.publishers:
                    publisher.wait_for_all_acked(Duration(seconds=DELIVERY_TIMEOUT))
        guard = exit_if_stuck(TEARDOWN_TIMEOUT)
        executor.shutdown()
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown()
        guard.cancel()
        for sig, handler in previous.items():
            signal.signal(sig, handler)


class StuckGuard:
    """Ends the process (status 0) unless cancelled within `seconds` (`exit_if_stuck`)."""

    def __init__(self, seconds: float):
        self._timer = threading.Timer(seconds, self._give_up, (seconds,))
        self._timer.daemon = True
        self._timer.start()
        # The timer needs the interpreter lock; rclpy's node teardown can spin in C++
        # holding it (`destroy_when_not_in_use` under the EventsExecutor). SIGALRM's default
        # action ends the process from the kernel, lock or not, a timeout later.
        self._alarm = threading.current_thread() is threading.main_thread()
        if self._alarm:
            signal.signal(signal.SIGALRM, signal.SIG_DFL)
            signal.alarm(math.ceil(2 * seconds))

    @staticmethod
    def _give_up(seconds: float) -> None:
        sys.stderr.write(f"[ft] the middleware's teardown took more than {seconds:g} s "
                         "(nodes already stopped): exiting without it\n")
        sys.stderr.flush()
        os._exit(0)

    def cancel(self) -> None:
        """The teardown finished: the process goes on."""
        self._timer.cancel()
        if self._alarm:
            signal.alarm(0)


def exit_if_stuck(seconds: float) -> StuckGuard:
    """A guard that ends the process unless cancelled within `seconds`.

    For a teardown that may hang in the middleware after the work is done: the process
    says on stderr that it gave up waiting and exits with status 0; where the hang holds
    the interpreter lock, SIGALRM ends it (status 142) after twice `seconds`.
    """
    return StuckGuard(seconds)
