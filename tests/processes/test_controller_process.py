"""The controller's installed executable as its own process: it runs and stops on SIGINT."""

from __future__ import annotations

import os
import signal
import subprocess
import sys

import numpy as np
import rclpy
from ft_core import robots
from ft_msgs_py import convert, qos
from ft_msgs_py.spin import spin_until
from paths import INSTALL, PACKAGES
from rosutil import ros_context
from sensor_msgs.msg import JointState

PANDA = robots.load("panda")
Q0 = np.array([0.4, 0.3, -0.5, -1.9, 0.6, 1.4, -0.2])


def test_executable_runs_from_the_install_space_and_stops_on_sigint() -> None:
    env = dict(os.environ)
    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    env["PYTHONPATH"] = os.pathsep.join(
        str(INSTALL / p / "lib" / version / "site-packages") for p in PACKAGES)
    script = INSTALL / "ft_controller" / "lib" / "ft_controller" / "controller_node"
    assert script.is_file(), "run `make build`"
    process = subprocess.Popen([sys.executable, str(script), "--ros-args", "-p",
                                "robot_model:=panda", "-p", "state_timeout:=60.0"], env=env,
                               stderr=subprocess.PIPE, text=True)
    try:
        with ros_context(shared=True) as (context, executor):
            node = rclpy.create_node("probe", context=context)
            executor.add_node(node)
            commands: list[JointState] = []
            node.create_subscription(JointState, "ft/command_raw", commands.append, qos.RELIABLE)
            states = node.create_publisher(JointState, "joint_states", qos.RELIABLE)

            def state_then_commands() -> bool:
                states.publish(convert.joint_state(PANDA.joint_names,
                                                   node.get_clock().now().to_msg(), Q0))
                return len(commands) >= 3

            assert spin_until(executor, state_then_commands, 30.0)
            process.send_signal(signal.SIGINT)
            _, errors = process.communicate(timeout=20)
            assert process.returncode == 0, errors[-3000:]
            # Delivered before the process ended (acknowledged), taken by the probe's spin.
            assert spin_until(executor, lambda: np.all(np.array(commands[-1].velocity) == 0.0),
                              10.0), f"the last command is not zeros: {commands[-1].velocity}"
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
