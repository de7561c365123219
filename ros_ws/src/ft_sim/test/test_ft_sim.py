"""`colcon test` of ft_sim: its part of the repository's suite (tests/package_suites.py)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[4] / "tests"))
from package_suites import run_for


def test_ft_sim() -> None:
    """The suite's tests of ft_sim pass."""
    run_for("ft_sim")
