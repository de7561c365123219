"""ft_msgs_py.spin: the executables' entry point, run in-process."""

from __future__ import annotations

import gc
import os
import signal
from pathlib import Path

import pytest
from ft_msgs_py import spin
from rclpy.node import Node


def test_run_node_freezes_start_up_objects_and_stops_cleanly_on_sigint() -> None:
    seen: dict[str, int | bool] = {}

    class Probe(Node):
        """Records what a callback sees, then asks the process to stop."""

        def __init__(self) -> None:
            super().__init__("spin_probe")
            self.create_timer(0.01, self._tick)

        def _tick(self) -> None:
            seen["frozen"] = gc.get_freeze_count()
            signal.raise_signal(signal.SIGINT)

        def stop(self) -> None:
            seen["stopped"] = True

    previous = signal.getsignal(signal.SIGINT)
    # run_node sets the process's Fast DDS transport (`ft_msgs_py.transport`) in os.environ:
    # restored afterwards, or every process the later tests of this worker start inherits it.
    environment = dict(os.environ)
    try:
        spin.run_node(Probe, [])
    finally:
        gc.unfreeze()
        os.environ.clear()
        os.environ.update(environment)
    # The start-up objects (modules, rclpy's entities, the node) are out of the
    # collector's sight; the node's stop() ran; our SIGINT handler is back.
    assert seen["frozen"] > 10_000
    assert seen["stopped"] is True
    assert signal.getsignal(signal.SIGINT) is previous


def test_the_lock_step_executor_drops_qos_event_handlers_and_still_delivers() -> None:
    import rclpy
    from rosutil import ros_context
    from std_msgs.msg import String

    with ros_context() as (context, executor):
        assert isinstance(executor, spin.LockStepExecutor)
        node = rclpy.create_node("lock_step_probe", context=context)
        heard: list[str] = []
        publisher = node.create_publisher(String, "probe", 10)
        executor.add_node(node)
        # An entity created after add_node: its handlers go at the next spin too.
        node.create_subscription(String, "probe", lambda m: heard.append(m.data), 10)
        assert publisher.event_handlers and len(list(node.waitables)) > 1  # rclpy's defaults
        executor.spin_once(timeout_sec=0.0)
        assert list(node.waitables) == []
        assert all(e.event_handlers == [] for e in (*node.publishers, *node.subscriptions))
        publisher.publish(String(data="step"))
        assert spin.spin_until(executor, lambda: heard == ["step"], 5.0), heard
        executor.remove_node(node)
        assert node.destroy_publisher(publisher)
        node.destroy_node()


@pytest.mark.parametrize("events", [False, True], ids=["lock-step", "events"])
def test_an_audience_counts_subscribers_as_they_come_and_go(events: bool) -> None:
    """`SuiteNode.create_counted_publisher`: the count of the matched events, as rmw's.

    Under the executables' EventsExecutor and under the lock-step executor, which drops
    rclpy's default event handlers but keeps these.
    """
    import rclpy
    from ft_msgs_py.node import SuiteNode
    from rclpy.experimental import EventsExecutor
    from rosutil import ros_context
    from std_msgs.msg import String

    with ros_context(executor_type=EventsExecutor if events else spin.LockStepExecutor) as (
            context, executor):
        node = SuiteNode("counted", context=context)
        publisher, audience = node.create_counted_publisher(String, "counted", 10)
        executor.add_node(node)
        other = rclpy.create_node("listener", context=context)
        executor.add_node(other)
        subscriptions = []
        for expected in (1, 2):
            subscriptions.append(other.create_subscription(String, "counted", print, 10))
            assert spin.spin_until(executor, lambda e=expected: audience.count == e, 5.0), (
                audience.count)
            assert publisher.get_subscription_count() == expected
        other.destroy_subscription(subscriptions.pop())
        assert spin.spin_until(executor, lambda: audience.count == 1, 5.0), audience.count
        executor.remove_node(other)
        executor.remove_node(node)
        other.destroy_node()
        node.destroy_node()


@pytest.mark.parametrize("events", [False, True], ids=["lock-step", "events"])
def test_a_subscription_taken_on_demand_is_not_dispatched_and_gives_its_queue_in_order(
        events: bool) -> None:
    """`SuiteNode.take_on_demand`: the executor leaves the messages; the call takes them.

    At most the QoS depth per call, oldest first; still the node's subscription (the
    publisher matches it).
    """
    import rclpy
    from ft_msgs_py.node import SuiteNode
    from rclpy.duration import Duration
    from rclpy.experimental import EventsExecutor
    from rosutil import ros_context
    from std_msgs.msg import String

    with ros_context(executor_type=EventsExecutor if events else spin.LockStepExecutor) as (
            context, executor):
        node = SuiteNode("on_demand", context=context)
        heard: list[tuple[bool, str]] = []
        taking = [False]
        subscription = node.create_subscription(
            String, "queued", lambda m: heard.append((taking[0], m.data)), 4)
        take = node.take_on_demand(subscription)
        assert subscription in node._subscriptions and subscription not in node.subscriptions
        executor.add_node(node)
        other = rclpy.create_node("sender", context=context)
        executor.add_node(other)
        publisher = other.create_publisher(String, "queued", 10)
        assert spin.spin_until(executor, lambda: publisher.get_subscription_count() == 1, 5.0)
        for k in range(6):
            publisher.publish(String(data=str(k)))
        assert publisher.wait_for_all_acked(Duration(seconds=5.0))  # all in the queue
        spin.spin_for(executor, 0.2)  # the executor's chance to dispatch them
        assert heard == []
        taking[0] = True
        take()
        assert heard == [(True, "2"), (True, "3"), (True, "4"), (True, "5")]  # depth 4
        take()
        assert len(heard) == 4  # the queue is empty
        executor.remove_node(other)
        executor.remove_node(node)
        other.destroy_node()
        node.destroy_node()


def test_a_harness_node_offers_no_services() -> None:
    from rosutil import ros_context

    with ros_context() as (context, _executor):
        node = spin.harness_node("bare", context)
        assert list(node.services) == []
        plain_services = len(list(spin.rclpy.create_node("plain", context=context).services))
        assert plain_services >= 7  # six parameter services and the type description
        node.destroy_node()


def _stopped_by_sigterm(script: Path, teardown: str,
                        extra: str = "") -> tuple[int, float, str, str]:
    """Run a node whose `destroy_node` is `teardown`; stop it by SIGTERM as launch does.

    Returns (exit status, s from the signal to the end, stdout after "spinning", stderr).
    """
    import subprocess
    import sys
    import time

    script.write_text(
        "import re, threading\n"
        "from ft_msgs_py import spin\n"
        "from rclpy.node import Node\n"
        "class Stuck(Node):\n"
        "    def __init__(self):\n"
        "        super().__init__('stuck_on_teardown')\n"
        "        print('spinning', flush=True)\n"
        f"{extra}"
        "    def destroy_node(self):\n"
        f"        {teardown}\n"
        "spin.TEARDOWN_TIMEOUT = 1.0\n"
        "spin.run_node(Stuck, [])\n")
    process = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    try:
        assert process.stdout.readline() == "spinning\n"
        process.send_signal(signal.SIGTERM)
        start = time.monotonic()
        status = process.wait(timeout=30)
        took = time.monotonic() - start
    finally:
        process.kill()
    out, err = process.communicate()
    return status, took, out, err


def test_a_teardown_that_hangs_ends_the_process_after_the_timeout(tmp_path) -> None:
    """The middleware's teardown may deadlock (Fast DDS, `spin` docstring): the process still ends.

    A node whose `destroy_node` never returns stands in for it, in a process of its own
    stopped by SIGTERM as a launch system stops it.
    """
    status, took, out, err = _stopped_by_sigterm(
        tmp_path / "hang.py", "threading.Event().wait()",
        "    def stop(self):\n        print('stopped', flush=True)\n")
    assert status == 0, err
    assert out == "stopped\n"  # the node's stop() (its zeros) ran before the teardown
    assert "teardown took more than 1 s" in err
    assert 1.0 <= took < 20.0


def test_a_teardown_that_holds_the_interpreter_lock_is_ended_by_the_kernel(tmp_path) -> None:
    """A teardown stuck in C holding the interpreter lock still ends the process.

    rclpy's node teardown can spin in C++ holding the lock, where the guard's timer thread
    never runs: SIGALRM ends the process after twice the timeout.
    """
    status, took, _, _ = _stopped_by_sigterm(
        tmp_path / "hold.py", "re.match(r'(a+)+$', 'a' * 64 + 'b')  # hours in C, lock held")
    assert status == -signal.SIGALRM, status
    assert 2.0 <= took < 20.0, took
