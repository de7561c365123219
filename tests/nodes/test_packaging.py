"""What a ROS 2 install needs of the packages: dependencies, the Docker files (issue 32).

Every module a package imports is declared in its package.xml (as the rosdep key that
installs it), every key rosdep cannot resolve from rosdistro is in docker/rosdep.yaml,
and the Dockerfile installs through rosdep from those files. No Docker engine runs
here (docker/README.md): the files are checked, not built.
"""

from __future__ import annotations

import ast
import importlib.util
import sys
import tempfile
import types
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import pytest
import yaml
from paths import REPO

SOURCES = REPO / "ros_ws" / "src"
PACKAGES = sorted(p.parent.name for p in SOURCES.glob("*/package.xml"))
#: Python module -> the rosdep key that installs it (a ROS package's key is its name).
KEYS = {"numpy": "python3-numpy", "scipy": "python3-scipy", "matplotlib": "python3-matplotlib",
        "yaml": "python3-yaml", "numba": "python3-numba", "tqdm": "python3-tqdm",
        "pinocchio": "pinocchio", "mujoco": "python3-mujoco-pip",
        "rosbags": "python3-rosbags-pip", "ruckig": "python3-ruckig-pip",
        "foxglove": "python3-foxglove-sdk-pip", "distributed": "python3-distributed-pip",
        "dask": "python3-distributed-pip"}
#: pip keys in rosdistro's rosdep/python.yaml (checked against ros/rosdistro of 2026-08).
UPSTREAM_PIP_KEYS = {"python3-mujoco-pip", "python3-rosbags-pip"}


def imported(package: str) -> set[str]:
    """Top-level modules the package's code imports, other than the standard library's."""
    found = set()
    for path in (SOURCES / package).rglob("*.py"):
        if path.name == "setup.py" or "test" in path.relative_to(SOURCES / package).parts:
            continue  # the build tool (ament_python) and `colcon test`'s files: not the code
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                found |= {alias.name.split(".")[0] for alias in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                found.add(node.module.split(".")[0])
    return {name for name in found if name not in sys.stdlib_module_names and name != package}


def declared(package: str) -> set[str]:
    root = ElementTree.parse(SOURCES / package / "package.xml").getroot()
    return {e.text.strip() for e in root if e.tag in ("depend", "exec_depend") and e.text}


@pytest.mark.parametrize("package", PACKAGES)
def test_every_import_is_a_declared_dependency(package: str) -> None:
    modules = imported(package)
    assert "numpy" in modules  # the scan sees the code
    keys = declared(package)
    for module in sorted(modules):
        key = KEYS.get(module, module)
        assert module in KEYS or module in PACKAGES or module.endswith(
            ("_msgs", "_interfaces", "_srvs")) or module in {
            "rclpy", "launch", "launch_ros", "ament_index_python"}, (
            f"{package} imports {module}: add its rosdep key to KEYS and to package.xml")
        assert key in keys, f"{package} imports {module} but its package.xml lacks {key}"


def test_every_rosdep_key_resolves_and_the_image_installs_through_rosdep() -> None:
    local = yaml.safe_load((REPO / "docker" / "rosdep.yaml").read_text())
    keys = set().union(*(declared(p) for p in PACKAGES))
    pip = {k for k in keys if k.endswith("-pip")}
    assert pip, "no pip key found: the scan is broken"
    assert pip <= UPSTREAM_PIP_KEYS | set(local), pip - UPSTREAM_PIP_KEYS - set(local)
    for key, rule in local.items():
        assert rule["ubuntu"]["pip"]["packages"], key
    dockerfile = (REPO / "docker" / "Dockerfile").read_text()
    lines = dockerfile.splitlines()
    assert next(line for line in lines if line.startswith("FROM")) == "FROM ros:jazzy"
    assert "COPY docker/rosdep.yaml /etc/ros/rosdep/" in dockerfile
    assert "/etc/ros/rosdep/sources.list.d/" in dockerfile
    assert "rosdep install --from-paths src --ignore-src" in dockerfile
    assert dockerfile.index("rosdep install") < dockerfile.index("colcon build")
    assert "install/setup.sh" in dockerfile
    assert lines[-1] == 'CMD ["ros2", "run", "ft_sim", "demo"]'


def test_the_build_context_leaves_out_the_local_environment() -> None:
    ignored = {line.strip() for line in (REPO / ".dockerignore").read_text().splitlines()
               if line.strip() and not line.startswith("#")}
    assert {".venv", ".git", "ros_ws/build", "ros_ws/install", "ros_ws/log"} <= ignored
    dockerfile = (REPO / "docker" / "Dockerfile").read_text()
    copied = [line.split()[1] for line in dockerfile.splitlines() if line.startswith("COPY")]
    assert copied == ["docker/rosdep.yaml", "ros_ws/src"]
    assert not any(Path(c).parts[0] in ignored for c in copied)


def test_compose_runs_what_the_workspace_provides() -> None:
    compose = yaml.safe_load((REPO / "docker" / "compose.yaml").read_text())
    services = compose["services"]
    assert set(services) == {"sim", "controller", "monitor"}
    installed = {(p.parent.name, p.name) for p in (REPO / "ros_ws" / "install").glob("*/lib/*/*")}
    for service in services.values():
        words = service["command"].split()
        assert words[:2] == ["ros2", "run"]
        assert (words[2], words[3]) in installed, words[:4]
        assert service["environment"]["ROS_DOMAIN_ID"] == "42"


def declared_arguments(path: Path) -> dict[str, str]:
    """{name: description} of every DeclareLaunchArgument a launch file makes.

    Read from the file (`launch` is not on PyPI): calls written out, and the
    `ARGUMENTS` table (name -> (default, description)) that demo.launch.py declares.
    """
    tree = ast.parse(path.read_text(), str(path))
    found = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and getattr(node.func, "id", "") == "DeclareLaunchArgument" \
                and isinstance(node.args[0], ast.Constant):
            keywords = {k.arg: k.value for k in node.keywords}
            found[node.args[0].value] = ast.literal_eval(keywords["description"])
        if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "ARGUMENTS":
            found |= {name: description
                      for name, (_, description) in ast.literal_eval(node.value).items()}
    return found


def test_launch_files_take_the_arguments_a_ros_user_expects() -> None:
    """Issue 32: robot, namespace, use_sim_time, params_file and plant, each described."""
    demo = declared_arguments(SOURCES / "ft_sim" / "launch" / "demo.launch.py")
    assert {"robot", "namespace", "use_sim_time", "params_file", "plant",
            "state_directory"} <= set(demo)
    controller = declared_arguments(SOURCES / "ft_controller" / "launch" /
                                    "controller.launch.py")
    assert {"params", "namespace"} <= set(controller)
    assert all(len(text) > 10 for text in (demo | controller).values())
    shipped = yaml.safe_load((SOURCES / "ft_controller" / "config" / "controller.yaml")
                             .read_text())
    assert list(shipped) == ["/**"]  # applies under any namespace


class _Action:
    """A stubbed launch action: it keeps what it was made with."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


class _Declare(_Action):
    pass


class _Configuration:
    def __init__(self, name: str):
        self.name = name

    def perform(self, context: dict[str, str]) -> str:
        return context[self.name]


def demo_launch(monkeypatch: pytest.MonkeyPatch) -> types.ModuleType:
    """demo.launch.py with `launch` and `launch_ros` stubbed (not on PyPI)."""
    stubs = {"launch": {"LaunchDescription": list},
             "launch.actions": {"DeclareLaunchArgument": _Declare, "OpaqueFunction": _Action},
             "launch.substitutions": {"LaunchConfiguration": _Configuration},
             "launch_ros": {}, "launch_ros.actions": {"Node": _Action}}
    for name, attributes in stubs.items():
        module = types.ModuleType(name)
        module.__dict__.update(attributes)
        monkeypatch.setitem(sys.modules, name, module)
    path = SOURCES / "ft_sim" / "launch" / "demo.launch.py"
    spec = importlib.util.spec_from_file_location("demo_launch", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_demo_launch_makes_its_session_folder_only_when_it_runs_without_one(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Describing the launch (`--show-args`, or a launch with `state_directory:=`) makes none.

    Without `state_directory`, running it (its OpaqueFunction) makes one new folder, the
    monitor's; with it, the monitor gets that one and nothing is made.
    """
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    demo = demo_launch(monkeypatch)
    described = demo.generate_launch_description()
    assert list(tmp_path.iterdir()) == []
    defaults = {a.args[0]: a.kwargs["default_value"] for a in described
                if isinstance(a, _Declare)}
    assert defaults["state_directory"] == ""
    kept = str(tmp_path / "kept")
    *_, monitor = demo.nodes({**defaults, "state_directory": kept})
    assert list(tmp_path.iterdir()) == []
    assert monitor.kwargs["parameters"][0]["state_directory"] == kept
    *_, monitor = demo.nodes(defaults)
    [made] = tmp_path.iterdir()
    assert made.name.startswith("ft_sim_session_") and made.is_dir()
    assert monitor.kwargs["parameters"][0]["state_directory"] == str(made)


def test_the_demo_launch_starts_from_the_controllers_shipped_parameters(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The controller gets controller.yaml's critical points, all three nodes its task space."""
    shipped = yaml.safe_load((SOURCES / "ft_controller" / "config" / "controller.yaml")
                             .read_text())["/**"]["ros__parameters"]
    demo = demo_launch(monkeypatch)
    defaults = {a.args[0]: a.kwargs["default_value"] for a in demo.generate_launch_description()
                if isinstance(a, _Declare)}
    sim, controller, monitor = demo.nodes({**defaults, "state_directory": str(tmp_path)})
    values = controller.kwargs["parameters"][0]
    assert values["critical_points"] == shipped["critical_points"]
    assert len(values["critical_points"]) == 9  # three points of a position task
    assert values["resolution"] == shipped["resolution"]
    assert values["robot_model"] == defaults["robot"]
    assert {node.kwargs["parameters"][0]["task_space"] for node in (sim, controller, monitor)} \
        == {shipped["task_space"]}


def test_the_rviz_view_ships_with_the_launch_file_and_shows_both_nodes_markers() -> None:
    """Issue 32: an RViz config, installed, whose displays are the markers the nodes publish.

    Topics relative (RViz runs in the stack's namespace), the default arm's base link as
    the fixed frame, and `rviz:=true` of demo.launch.py starts it.
    """
    from ft_sim.live import MARKER_TOPICS

    installed = REPO / "ros_ws" / "install" / "ft_sim" / "share" / "ft_sim" / "config"
    view = yaml.safe_load((installed / "ft_arms.rviz").read_text())
    manager = view["Visualization Manager"]
    shown = {d["Topic"]["Value"] for d in manager["Displays"]
             if d["Class"] == "rviz_default_plugins/MarkerArray" and d["Enabled"]}
    assert shown == {topic for topic, _, _ in MARKER_TOPICS}
    assert manager["Global Options"]["Fixed Frame"] == "panda_link0"
    assert "rviz" in declared_arguments(SOURCES / "ft_sim" / "launch" / "demo.launch.py")


def test_colcon_test_runs_each_packages_part_of_the_suite() -> None:
    """Issue 32: `colcon test` finds a test in each package, which runs the suite's part."""
    from package_suites import SUITES

    assert sorted(SUITES) == PACKAGES
    for package, arguments in SUITES.items():
        test = SOURCES / package / "test" / f"test_{package}.py"
        assert f'run_for("{package}")' in test.read_text(), test
        for path in (a for a in arguments if not a.startswith("-")):
            assert (REPO / path).exists(), path
