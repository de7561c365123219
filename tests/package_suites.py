"""The part of the repository's suite that covers each ROS package, for `colcon test`.

`make test` runs the whole suite (`tests/`), the single source of tests; each package's
`test/test_<package>.py` runs its part here, so that `colcon test` in `ros_ws` does what
ROS users expect of a package.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: package -> the suite's paths that test it (pytest arguments, from the repository root)
SUITES = {
    "ft_core": ["tests/unit", "--ignore=tests/unit/test_msgs.py"],
    "ft_msgs_py": ["tests/unit/test_msgs.py", "tests/nodes/test_spin.py",
                   "tests/nodes/test_thread_priority.py", "tests/nodes/test_parameter_dump.py"],
    "ft_controller": ["tests/nodes/test_controller.py", "tests/nodes/test_observability_node.py",
                      "tests/nodes/test_task_channel_node.py",
                      "tests/processes/test_controller_process.py"],
    "ft_monitor": ["tests/nodes/test_monitor.py", "tests/nodes/test_swing_node.py"],
    "ft_sim": ["tests/nodes/test_stack.py", "tests/nodes/test_story.py"],
}


def run_for(package: str) -> None:
    """Run `package`'s part of the suite; AssertionError if any of it fails."""
    result = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                             *SUITES[package]], cwd=REPO)
    assert result.returncode == 0, f"the suite's tests of {package} failed (output above)"
