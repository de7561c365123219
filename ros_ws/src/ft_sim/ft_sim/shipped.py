"""The controller's shipped parameters file: the defaults every way of starting the suite shares.

ft_controller's config/controller.yaml (keyed `/**:`) is what `ros2 launch ft_controller
controller.launch.py` gives its nodes unless told otherwise; `demo.launch.py` and
`ft-stack` (`ros2 run ft_sim stack`) take their task space, and the launch file its
controller's parameters, from the same file, so that the same arm starts on the same task
whichever way it is started.
"""

from __future__ import annotations

from pathlib import Path

import yaml
from ament_index_python.packages import get_package_share_directory


def parameters_file() -> Path:
    """The file's path.

    The installed copy (share/ft_controller/config) where the ament index lists the
    package, else the one beside the package's sources (a virtual environment on the
    source tree).
    """
    try:
        share = Path(get_package_share_directory("ft_controller"))
    except (LookupError, OSError, ValueError):  # not installed, or no ament index at all
        import ft_controller

        share = Path(ft_controller.__file__).resolve().parents[1]
    return share / "config" / "controller.yaml"


def parameters() -> dict[str, object]:
    """The file's parameters (name -> value) for every node (`/**`)."""
    return yaml.safe_load(parameters_file().read_text())["/**"]["ros__parameters"]
