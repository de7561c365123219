"""The unit tier is what it says: no test module in tests/unit imports rclpy."""

from __future__ import annotations

import subprocess
import sys

from paths import REPO


def test_unit_tests_run_without_rclpy() -> None:
    unit = REPO / "tests" / "unit"
    modules = sorted(path.stem for path in unit.glob("test_*.py"))
    assert "test_engine" in modules
    script = (f"import sys; sys.path[:0] = [{str(REPO / 'tests')!r}, {str(unit)!r}]\n"
              f"for name in {modules!r}: __import__(name)\n"
              "print(sorted(m for m in sys.modules if m.split('.')[0] == 'rclpy'))")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            timeout=120, check=False)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.strip() == "[]"
