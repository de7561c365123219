r"""The closed loop as separate processes: sim (owning the clock), controller and monitor.

    ros2 launch ft_sim demo.launch.py
    ros2 topic pub --once /ft/target_pose geometry_msgs/PoseStamped \\
      "{pose: {position: {x: 0.45, y: -0.15, z: 0.35}, orientation: {w: 1.0}}}"
    ros2 topic pub --once /ft/inject_failure sensor_msgs/JointState "{name: [panda_joint2]}"

Watch `ft/locked_joints`, `ft/metrics` and `/diagnostics`. (`ros2 run ft_sim demo`
runs the scripted story with its report and figure in one process.) The sim behaves
like a real driver: 20 ms command latency, a 30 ms velocity response time and a
command watchdog (`tests/processes/test_deployment.py` runs this graph as separate processes).

A sim session starts with no locked joint: the monitor keeps its locked set in a new
temporary directory each launch, never in the real arm's (`state_directory:=<dir>` to
keep it across launches).
"""

import tempfile

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

MODEL = {"robot_model": "panda", "task_space": "position"}


def generate_launch_description():
    """Sim, controller and monitor."""
    return LaunchDescription([
        DeclareLaunchArgument("state_directory",
                              default_value=tempfile.mkdtemp(prefix="ft_sim_session_"),
                              description="the monitor's state directory (default: new)"),
        Node(package="ft_sim", executable="sim_node", name="sim",
             parameters=[{**MODEL, "publish_clock": True, "rate": 250.0,
                          "position_noise": 0.001, "command_latency": 0.02,
                          "response_time": 0.03, "command_timeout": 0.1}]),
        Node(package="ft_controller", executable="controller_node", name="controller",
             parameters=[{**MODEL, "use_sim_time": True, "resolution": "blend",
                          "critical_points": [0.5, 0.1, 0.4, 0.45, -0.15, 0.35]}]),
        Node(package="ft_monitor", executable="monitor_node", name="monitor",
             respawn=True, respawn_delay=1.0,
             parameters=[{**MODEL, "use_sim_time": True,
                          "state_directory": LaunchConfiguration("state_directory")}]),
    ])
