"""Canaries of `ft_msgs_py.rclpy_private`: what the suite uses beneath rclpy's public API.

Each test fails, saying what changed, when a new rclpy (or middleware) no longer has or
does what the module relies on.
"""

from __future__ import annotations

import inspect

import numpy as np
import pytest
import rclpy
from builtin_interfaces.msg import Time
from ft_msgs_py import rclpy_private, spin
from ft_msgs_py.rclpy_private import CDR_LE, CommandWriter, JointStateReader
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock as ClockMessage
from rosutil import ros_context
from sensor_msgs.msg import JointState
from std_msgs.msg import String

SEE = "see ft_msgs_py/rclpy_private.py"


def changed(what: str, how: str) -> str:
    """The failure message of a canary."""
    return f"rclpy's {what} changed: {how}; {SEE}"


def test_set_parameters_atomically_common_takes_what_set_as_declared_passes() -> None:
    method = getattr(Node, "_set_parameters_atomically_common", None)
    assert method is not None, changed("Node._set_parameters_atomically_common", "it is gone")
    names = list(inspect.signature(method).parameters)
    assert names[:4] == ["self", "parameter_list", "descriptors", "allow_not_set_type"], (
        changed("Node._set_parameters_atomically_common", f"its parameters are now {names}"))


def test_set_as_declared_gives_a_read_only_typed_parameter_an_empty_value() -> None:
    with ros_context() as (context, _executor):
        node = rclpy.create_node("set_as_declared", context=context)
        node.declare_parameter("values", Parameter.Type.DOUBLE_ARRAY,
                               ParameterDescriptor(read_only=True))
        assert node.get_parameter_or("values").type_ == Parameter.Type.NOT_SET
        rclpy_private.set_as_declared(node, Parameter("values", Parameter.Type.DOUBLE_ARRAY, []))
        what = "Node._set_parameters_atomically_common"
        got = node.get_parameter_or("values")
        assert got.type_ == Parameter.Type.DOUBLE_ARRAY and list(got.value) == [], changed(
            what, f"a typed empty array set as a declaration does reads back as {got.type_} "
                  f"{got.value!r}")
        assert node.describe_parameter("values").read_only, changed(
            what, "the parameter is no longer read-only")
        node.destroy_node()


@pytest.mark.parametrize("kind", [ClockType.SYSTEM_TIME, ClockType.STEADY_TIME,
                                  ClockType.ROS_TIME])
def test_a_clock_handle_reads_what_clock_now_reads(kind: ClockType) -> None:
    clock = Clock(clock_type=kind)
    read = rclpy_private.clock_nanoseconds(clock)
    before, now, after = clock.now().nanoseconds, read(), clock.now().nanoseconds
    assert isinstance(now, int) and before <= now <= after, changed(
        "Clock.handle.get_now()", f"{now!r} read between {before} and {after} ns ({kind})")


def test_a_clock_handle_reads_simulated_time() -> None:
    with ros_context() as (context, executor):
        node = rclpy.create_node("sim_clock", context=context, parameter_overrides=[
            Parameter("use_sim_time", value=True)])
        source = rclpy.create_node("clock_source", context=context)
        for each in (node, source):
            executor.add_node(each)
        publisher = source.create_publisher(ClockMessage, "/clock", 10)
        read = rclpy_private.clock_nanoseconds(node.get_clock())
        stamp = ClockMessage(clock=Time(sec=42, nanosec=5))

        def arrived() -> bool:
            publisher.publish(stamp)
            return node.get_clock().now().nanoseconds == 42_000_000_005

        assert spin.spin_until(executor, arrived, 5.0), "no /clock reached the node"
        assert read() == 42_000_000_005, changed(
            "Clock.handle.get_now()", f"{read()} ns with the simulated clock at 42.000000005 s")
        for each in (node, source):
            executor.remove_node(each)
            each.destroy_node()


@pytest.mark.parametrize("raw", [False, True], ids=["message", "raw"])
def test_a_subscription_handle_takes_its_queue_in_order(raw: bool) -> None:
    with ros_context() as (context, executor):
        node = rclpy.create_node("taker", context=context)
        subscription = node.create_subscription(String, "queued", lambda _m: None, 10, raw=raw)
        take = rclpy_private.message_taker(subscription)
        sender = rclpy.create_node("sender", context=context)
        executor.add_node(sender)
        publisher = sender.create_publisher(String, "queued", 10)
        assert spin.spin_until(executor, lambda: publisher.get_subscription_count() == 1, 5.0)
        for text in ("first", "second"):
            publisher.publish(String(data=text))
        assert publisher.wait_for_all_acked(Duration(seconds=5.0))  # all in the queue
        what = "Subscription.handle.take_message"
        taken = [take(), take(), take()]
        if raw:
            assert all(isinstance(m, bytes) for m in taken[:2]), changed(
                what, f"a raw subscription's messages are taken as {taken[:2]!r}, not bytes")
            taken[:2] = [deserialize_message(m, String) for m in taken[:2]]
        assert [getattr(m, "data", m) for m in taken[:2]] == ["first", "second"], changed(
            what, f"the messages are taken as {taken[:2]!r}")
        assert taken[2] is None, changed(what, f"an empty queue gives {taken[2]!r}, not None")
        executor.remove_node(sender)
        sender.destroy_node()
        node.destroy_node()


class _Hiding(Node):
    """A node that lists none of its subscriptions to executors."""

    @property
    def subscriptions(self):
        return iter(())


@pytest.mark.parametrize("executor_type", [SingleThreadedExecutor, EventsExecutor],
                         ids=["single-threaded", "events"])
def test_executors_dispatch_only_the_subscriptions_a_node_lists(
        executor_type: type[Executor]) -> None:
    with ros_context(executor_type=executor_type) as (context, executor):
        heard: list[str] = []
        node = _Hiding("hiding", context=context)
        node.create_subscription(String, "hidden", lambda m: heard.append(m.data), 10)
        executor.add_node(node)
        sender = rclpy.create_node("sender", context=context)
        executor.add_node(sender)
        publisher = sender.create_publisher(String, "hidden", 10)
        assert spin.spin_until(executor, lambda: publisher.get_subscription_count() == 1, 5.0)
        publisher.publish(String(data="dispatched?"))
        spin.spin_for(executor, 0.2)
        assert heard == [], changed(
            f"{executor_type.__name__}", "it dispatches a subscription that Node.subscriptions "
            "does not list (SuiteNode.take_on_demand no longer keeps it from the executor)")
        for each in (sender, node):
            executor.remove_node(each)
            each.destroy_node()


#: Joint sets a command is written for: none, odd and even name lengths (string padding),
#: non-ASCII names, a 7-joint arm.
JOINT_SETS = [[], ["a"], ["ab", "c"], ["é", "joint_ü", "xyz"],
              [f"panda_joint{k}" for k in range(1, 8)]]


@pytest.mark.parametrize("joints", JOINT_SETS, ids=lambda joints: f"{len(joints)} joints")
def test_the_command_writer_writes_rclpys_own_bytes(joints: list[str]) -> None:
    velocity = np.linspace(-1.5, 2.5, len(joints))
    msg = JointState(name=joints, velocity=velocity.tolist())
    msg.header.stamp.sec, msg.header.stamp.nanosec = -3, 999_999_999
    theirs = serialize_message(msg)
    assert theirs[:2] == CDR_LE, changed(
        "serialize_message", f"its encapsulation is {theirs[:2].hex()}, not plain "
                             "little-endian CDR")
    ours = CommandWriter(joints).serialize(-3, 999_999_999, velocity)
    # rclpy's buffer may hold a few bytes past the message's end.
    assert theirs[:len(ours)] == ours, changed(
        "serialize_message", f"JointState {joints} is {theirs.hex()}, written here "
                             f"{ours.hex()}")
    back = deserialize_message(ours, JointState)
    assert (list(back.name), list(back.velocity), back.header.stamp) == (
        joints, velocity.tolist(), msg.header.stamp), changed(
        "deserialize_message", f"it reads the command written here as {back}")


#: JointStates read from rclpy's bytes: frames of 0-4 characters (every alignment), arrays
#: of different lengths, positions alone.
READ = [JointState(name=["a", "bc"], position=[1.0, -2.0], velocity=[0.5, 0.25],
                   effort=[3.0, 4.0]),
        JointState(name=[f"panda_joint{k}" for k in range(1, 8)], position=[0.1] * 7),
        JointState(name=[], position=[], velocity=[1.0], effort=[])]


@pytest.mark.parametrize("frame", ["", "w", "wo", "wor", "worl"])
@pytest.mark.parametrize("msg", READ, ids=["two joints", "panda", "uneven"])
def test_the_reader_reads_rclpys_bytes(msg: JointState, frame: str) -> None:
    msg.header.frame_id, msg.header.stamp.sec, msg.header.stamp.nanosec = frame, 7, 11
    raw = serialize_message(msg)
    assert raw[:2] == CDR_LE, changed(
        "serialize_message", f"its encapsulation is {raw[:2].hex()}, not plain "
                             "little-endian CDR")
    view = JointStateReader().read(raw)
    read = (view.header.stamp, view.header.frame_id, view.name, view.position.tolist(),
            view.velocity.tolist(), view.effort.tolist())
    assert read == ((7, 11), frame, tuple(msg.name), list(msg.position), list(msg.velocity),
                    list(msg.effort)), changed(
        "serialize_message", f"{raw.hex()} is read here as {read}, not as {msg}")
