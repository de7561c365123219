"""The colcon install space has the layout `ros2 run` uses, and its executables run."""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib
from importlib.metadata import PathDistribution
from pathlib import Path

import pytest
from ament_index_python.packages import get_package_prefix, get_package_share_directory
from paths import INSTALL, PACKAGES, REPO


@pytest.fixture
def install_space(monkeypatch: pytest.MonkeyPatch) -> Path:
    """AMENT_PREFIX_PATH as `source ros_ws/install/setup.bash` would set it."""
    assert (INSTALL / "setup.bash").is_file(), "no colcon install space: run `make build`"
    prefixes = [str(INSTALL / pkg) for pkg in PACKAGES]
    monkeypatch.setenv("AMENT_PREFIX_PATH", os.pathsep.join(prefixes))
    return INSTALL


def site_packages(prefix: Path) -> Path:
    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    return prefix / "lib" / version / "site-packages"


def console_scripts(pkg: str) -> list[str]:
    """Executables declared by the package, read from the metadata colcon installed."""
    (info,) = site_packages(INSTALL / pkg).glob(f"{pkg}-*.egg-info")
    return [ep.name for ep in PathDistribution(info).entry_points
            if ep.group == "console_scripts"]


@pytest.mark.parametrize("pkg", PACKAGES)
def test_package_is_in_the_ament_index(install_space: Path, pkg: str) -> None:
    prefix = Path(get_package_prefix(pkg))
    assert prefix == install_space / pkg
    assert (Path(get_package_share_directory(pkg)) / "package.xml").is_file()


@pytest.mark.parametrize("pkg", PACKAGES)
def test_executables_are_where_ros2_run_looks(install_space: Path, pkg: str) -> None:
    prefix = Path(get_package_prefix(pkg))
    for name in console_scripts(pkg):
        script = prefix / "lib" / pkg / name
        assert script.is_file() and os.access(script, os.X_OK), f"{script} missing"


def test_demo_runs_from_the_install_space(install_space: Path) -> None:
    """`ros2 run ft_sim demo` runs the installed script with the install space's packages."""
    assert "demo" in console_scripts("ft_sim")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(str(site_packages(install_space / p)) for p in PACKAGES)
    script = install_space / "ft_sim" / "lib" / "ft_sim" / "demo"
    result = subprocess.run([sys.executable, str(script), "--help"], env=env,
                            capture_output=True, text=True, timeout=120, check=False)
    assert result.returncode == 0, result.stderr
    assert "--lock-time" in result.stdout


def test_every_executable_is_also_an_ft_console_script_in_the_venv(install_space: Path) -> None:
    """`controller_node` -> `ft-controller`, `demo` -> `ft-demo` (the README's table), on PATH."""
    declared = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["scripts"]
    bin_dir = Path(sys.executable).parent
    for pkg in PACKAGES:
        (info,) = site_packages(INSTALL / pkg).glob(f"{pkg}-*.egg-info")
        for ep in PathDistribution(info).entry_points:
            if ep.group != "console_scripts":
                continue
            name = "ft-" + ep.name.removesuffix("_node").replace("_", "-")
            assert declared.get(name) == ep.value, f"{name} should run {ep.value}"
            assert (bin_dir / name).is_file(), f"{name} is not installed in {bin_dir}"
    result = subprocess.run([str(bin_dir / "ft-demo"), "--help"],
                            capture_output=True, text=True, timeout=120, check=False)
    assert result.returncode == 0 and "--lock-time" in result.stdout, result.stderr
