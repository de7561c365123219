r"""The closed loop as separate processes: sim (owning the clock), controller and monitor.

    ros2 launch ft_sim demo.launch.py
    ros2 launch ft_sim demo.launch.py robot:=panda_inertial plant:=physics namespace:=arm1
    ros2 launch ft_sim demo.launch.py rviz:=true
    ros2 launch ft_sim demo.launch.py --show-args
    ros2 topic pub --once /ft/target_pose geometry_msgs/PoseStamped \\
      "{pose: {position: {x: 0.45, y: -0.15, z: 0.35}, orientation: {w: 1.0}}}"
    ros2 topic pub --once /ft/inject_failure sensor_msgs/JointState "{name: [panda_joint2]}"

Watch `ft/locked_joints`, `ft/metrics` and `/diagnostics`. (`ros2 run ft_sim demo`
runs the scripted story with its report and figure in one process.) The sim behaves
like a real driver: 20 ms command latency, a 30 ms velocity response time and a
command watchdog (`tests/processes/test_deployment.py` runs this graph as separate processes).

Arguments (`--show-args`): `robot` (a built-in name or a URDF path), `namespace` (the
three nodes and their topics under it: two arms side by side), `use_sim_time` (the sim
publishes /clock and the controller and monitor follow it; false: the wall clock),
`params_file` (a YAML parameters file applied to all three after the defaults: key it
`/**:` so that it applies under any namespace), `plant` (`kinematic`, or `physics`:
MuJoCo, for a robot with inertias such as `panda_inertial`), `state_directory` and `rviz`
(also start RViz 2 with the shipped view, `config/ft_arms.rviz`, fixed on the model's base
link: the nodes' `~/markers`, docs/sim.md "Live view"; needs the `rviz2` package, which
the suite does not depend on).

The controller starts from the controller's shipped parameters file, ft_controller's
config/controller.yaml (`ft_sim.shipped`: its resolution and critical points, as
`ros2 launch ft_controller controller.launch.py` gives them), and all three nodes from its
task space; `robot` replaces its model.

A sim session starts with no locked joint: unless `state_directory:=<dir>` is given (to
keep the locked set across launches), the monitor keeps it in a new temporary directory,
made when the launch runs (not when its arguments are only shown), never in the real
arm's.
"""

import tempfile

from ft_sim import shipped
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

#: name -> (default, description) of every argument.
ARGUMENTS = {
    "robot": ("panda", "built-in robot name or URDF path"),
    "namespace": ("", "namespace of the three nodes and their topics"),
    "use_sim_time": ("true", "the sim publishes /clock, the others follow it"),
    "params_file": ("", "YAML parameters for all three nodes, after the defaults (key it /**:)"),
    "plant": ("kinematic", "the sim's plant: kinematic, or physics (MuJoCo; a robot with "
              "inertias)"),
    "state_directory": ("", "the monitor's state directory (empty: a new one each launch)"),
    "rviz": ("false", "also start rviz2 with the shipped view of the nodes' markers"),
}


def nodes(context) -> list[Node]:
    """The three nodes (and RViz with `rviz:=true`), from the arguments' values."""
    value = {name: LaunchConfiguration(name).perform(context) for name in ARGUMENTS}
    sim_time = value["use_sim_time"].lower() == "true"
    defaults = shipped.parameters()
    model = {"robot_model": value["robot"], "task_space": defaults["task_space"]}
    state = value["state_directory"] or tempfile.mkdtemp(prefix="ft_sim_session_")
    files = [value["params_file"]] if value["params_file"] else []
    common = {"namespace": value["namespace"], "output": "screen"}
    viewer = [rviz(value["robot"], sim_time, common)] if value["rviz"].lower() == "true" else []
    return [
        *viewer,
        Node(package="ft_sim", executable="sim_node", name="sim", **common,
             parameters=[{**model, "publish_clock": sim_time, "rate": 250.0,
                          "plant": value["plant"], "position_noise": 0.001,
                          "command_latency": 0.02, "response_time": 0.03,
                          "command_timeout": 0.1, "refuse_over_limits": True}, *files]),
        Node(package="ft_controller", executable="controller_node", name="controller",
             **common,
             parameters=[{**defaults, **model, "use_sim_time": sim_time}, *files]),
        Node(package="ft_monitor", executable="monitor_node", name="monitor", **common,
             respawn=True, respawn_delay=1.0,
             parameters=[{**model, "use_sim_time": sim_time,
                          "state_directory": state}, *files]),
    ]


def rviz(robot: str, sim_time: bool, common: dict) -> Node:
    """RViz 2 with the shipped view, fixed on `robot`'s base link (the markers' frame)."""
    from pathlib import Path

    from ament_index_python.packages import get_package_share_directory
    from ft_core import robots

    view = Path(get_package_share_directory("ft_sim")) / "config" / "ft_arms.rviz"
    return Node(package="rviz2", executable="rviz2", name="rviz", **common,
                arguments=["-d", str(view), "-f", robots.load(robot).base_link],
                parameters=[{"use_sim_time": sim_time}])


def generate_launch_description():
    """Sim, controller and monitor, with the arguments of `ARGUMENTS`."""
    return LaunchDescription([
        *[DeclareLaunchArgument(name, default_value=default, description=description)
          for name, (default, description) in ARGUMENTS.items()],
        OpaqueFunction(function=nodes),
    ])
