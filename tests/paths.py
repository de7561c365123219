"""Where the tests find the workspace, its colcon install space and the real-world URDF."""

from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
WORKSPACE = REPO / "ros_ws"
INSTALL = WORKSPACE / "install"
PACKAGES = ("ft_core", "ft_msgs_py", "ft_controller", "ft_monitor", "ft_sim")
#: The built-in "panda_inertial" (`ft_core.robots.BUILTINS`) as a user's file.
PANDA_URDF = WORKSPACE / "src" / "ft_core" / "ft_core" / "urdf" / \
    "panda_from_example_robot_data.urdf"
