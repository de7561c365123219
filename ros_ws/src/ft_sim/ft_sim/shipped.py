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


def parameters_file() -> Path | None:
    """The file's path, None where no copy of it is found.

    The installed copy (share/ft_controller/config) where the ament index lists the
    package or beside the installed package (an install space without the index set up),
    else the one beside the package's sources (a virtual environment on the source tree).
    """
    import ft_controller

    package = Path(ft_controller.__file__).resolve().parent
    candidates = [package.parents[3] / "share" / "ft_controller",  # lib/pythonX.Y/site-packages
                  package.parent]  # the source tree
    try:
        candidates.insert(0, Path(get_package_share_directory("ft_controller")))
    except (LookupError, OSError, ValueError):  # not installed, or no ament index at all
        pass
    return next((path for share in candidates
                 if (path := share / "config" / "controller.yaml").is_file()), None)


def parameters() -> dict[str, object]:
    """The file's parameters (name -> value) for every node (`/**`); empty without the file."""
    path = parameters_file()
    if path is None:
        return {}
    return yaml.safe_load(path.read_text())["/**"]["ros__parameters"]
