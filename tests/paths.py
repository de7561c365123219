"""Where the tests find the workspace, its colcon install space and the shared test data."""

from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
WORKSPACE = REPO / "ros_ws"
INSTALL = WORKSPACE / "install"
PACKAGES = ("ft_core", "ft_msgs_py", "ft_controller", "ft_monitor", "ft_sim")
PANDA_URDF = REPO / "tests" / "data" / "panda_from_example_robot_data.urdf"
