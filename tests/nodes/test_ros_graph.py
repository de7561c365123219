"""Real ROS 2 is there: JointState messages cross an executor and a process boundary."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest
import rclpy
from ft_msgs_py.spin import spin_until
from rosutil import ros_context
from sensor_msgs.msg import JointState


def test_two_nodes_in_one_process_exchange_joint_states() -> None:
    with ros_context() as (context, executor):
        talker = rclpy.create_node("talker", context=context)
        listener = rclpy.create_node("listener", context=context)
        received: list[JointState] = []
        listener.create_subscription(JointState, "joint_states", received.append, 10)
        publisher = talker.create_publisher(JointState, "joint_states", 10)
        executor.add_node(talker)
        executor.add_node(listener)
        message = JointState(name=["a", "b"], position=[0.5, -1.0])

        def arrived() -> bool:
            publisher.publish(message)
            return bool(received)

        assert spin_until(executor, arrived, timeout=10.0)
        assert list(received[0].name) == ["a", "b"]
        assert list(received[0].position) == pytest.approx([0.5, -1.0])


def test_publisher_in_another_process_reaches_this_one() -> None:
    script = textwrap.dedent("""
        import time, rclpy
        from sensor_msgs.msg import JointState
        rclpy.init()
        node = rclpy.create_node("remote_talker")
        pub = node.create_publisher(JointState, "remote_joint_states", 10)
        end = time.monotonic() + 30.0
        while time.monotonic() < end:
            pub.publish(JointState(name=["remote"], position=[1.25]))
            time.sleep(0.05)
    """)
    process = subprocess.Popen([sys.executable, "-c", script])
    try:
        with ros_context(shared=True) as (context, executor):
            listener = rclpy.create_node("listener", context=context)
            received: list[JointState] = []
            listener.create_subscription(JointState, "remote_joint_states", received.append, 10)
            executor.add_node(listener)
            assert spin_until(executor, lambda: bool(received), timeout=25.0)
            assert list(received[0].name) == ["remote"]
            assert received[0].position[0] == pytest.approx(1.25)
    finally:
        process.kill()
        process.wait(timeout=10)
