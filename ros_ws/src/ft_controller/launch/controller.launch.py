"""Controller and monitor for a robot driven by ros2_control.

    ros2 launch ft_controller controller.launch.py params:=/path/to/controller.yaml
    ros2 launch ft_controller controller.launch.py namespace:=arm1 --show-args

The controller's parameters come from the YAML file (default: this package's
config/controller.yaml, installed as share/ft_controller/config/controller.yaml; key a
file of your own `/**:` as that one is, so that it applies under any namespace); the
monitor shares the model selection. `namespace` puts both nodes and their topics under
it (the plant's topic stays absolute). The monitor's
`ft/command_array` (and the controller's, for its zeros when the monitor is gone) is
remapped to a JointGroupVelocityController named
`forward_velocity_controller`; `joint_states` comes from joint_state_broadcaster.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

#: The velocity controller's command topic (ros2_control's forward_command_controller).
PLANT = ("ft/command_array", "/forward_velocity_controller/commands")


def generate_launch_description():
    """The controller and monitor nodes."""
    default = os.path.join(get_package_share_directory("ft_controller"), "config",
                           "controller.yaml")
    params, namespace = LaunchConfiguration("params"), LaunchConfiguration("namespace")
    return LaunchDescription([
        DeclareLaunchArgument("params", default_value=default,
                              description="YAML parameters file of the controller"),
        DeclareLaunchArgument("namespace", default_value="",
                              description="namespace of both nodes and their topics"),
        # The plant's topic, for both: the monitor's commands, and the controller's zeros
        # while the monitor does not answer (its `monitor_timeout`, docs/controller.md).
        Node(package="ft_controller", executable="controller_node", name="controller",
             namespace=namespace, parameters=[params], output="screen", remappings=[PLANT]),
        # Respawned if it dies.
        Node(package="ft_monitor", executable="monitor_node", name="monitor",
             namespace=namespace, parameters=[params], output="screen", respawn=True,
             respawn_delay=1.0, remappings=[PLANT]),
    ])
