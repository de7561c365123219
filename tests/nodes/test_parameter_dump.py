"""`ros2 param dump`, then a node restarted from the file: the same parameters (issue 32).

The dump is made as ros2param's `dump` verb (Jazzy) makes it: the node's
list_parameters and get_parameters services, values converted to Python, nested at
each '.', `yaml.dump` under the node's full name and `ros__parameters`. The ros2 CLI is
not on PyPI, so the test asks the services itself.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from ft_controller.controller_node import ControllerNode
from ft_monitor.monitor_node import MonitorNode
from ft_msgs_py.spin import spin_until
from ft_sim.fault_injector_node import FaultInjectorNode
from ft_sim.sim_node import SimNode
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from rosutil import ros_context

NODES = {"controller": ControllerNode, "monitor": MonitorNode, "sim": SimNode,
         "fault_injector": FaultInjectorNode}


def nest(tree: dict, name: str, value: object) -> None:
    """Put `value` at `name` in `tree`, one level per '.' (as the dump verb does)."""
    head, _, rest = name.partition(".")
    if rest:
        nest(tree.setdefault(head, {}), rest, value)
    else:
        tree[name] = value


def dump(probe: Node, executor, name: str) -> dict:
    """What `ros2 param dump /<name>` prints, parsed."""
    client = AsyncParameterClient(probe, name)
    assert client.wait_for_services(timeout_sec=10.0), f"no parameter services of /{name}"
    listed = client.list_parameters()
    assert spin_until(executor, listed.done, 10.0), "list_parameters unanswered"
    names = sorted(listed.result().result.names)
    answered = client.get_parameters(names)
    assert spin_until(executor, answered.done, 10.0), "get_parameters unanswered"
    values = answered.result().values
    assert len(values) == len(names), (
        f"/{name}: get_parameters answered {len(values)} of {len(names)} parameters")
    tree: dict = {}
    for parameter, value in zip(names, values, strict=True):
        nest(tree, parameter, parameter_value_to_python(value))
    return yaml.safe_load(yaml.dump({f"/{name}": {"ros__parameters": tree}},
                                    default_flow_style=False))


@pytest.mark.parametrize("name", sorted(NODES))
def test_a_dump_restarts_an_identical_node(name: str, tmp_path: Path) -> None:
    overrides = [] if name == "fault_injector" else [Parameter("robot_model", value="panda")]
    if name == "monitor":
        overrides.append(Parameter("state_directory", value=str(tmp_path / "state")))
    with ros_context(executor_type=SingleThreadedExecutor) as (context, executor):
        probe = Node("probe", context=context)
        executor.add_node(probe)
        first = NODES[name](context=context, parameter_overrides=overrides)
        executor.add_node(first)
        try:
            dumped = dump(probe, executor, name)
        finally:
            executor.remove_node(first)
            first.destroy_node()
        values = dumped[f"/{name}"]["ros__parameters"]
        assert values.get("robot_model", "panda") == "panda"
        # Every parameter is there, the typed arrays too (as empty lists, not "not set").
        assert set(first.get_parameters_by_prefix("")) <= set(values) | {
            f"{k}.{v}" for k, sub in values.items() if isinstance(sub, dict) for v in sub}
        assert values["joints"] == []
        path = tmp_path / f"{name}.yaml"
        path.write_text(yaml.dump(dumped, default_flow_style=False))
        again = NODES[name](context=context, cli_args=["--ros-args", "--params-file", str(path)])
        executor.add_node(again)
        try:
            assert dump(probe, executor, name) == dumped
            assert again.get_parameter("joints").type_ == Parameter.Type.STRING_ARRAY
        finally:
            executor.remove_node(again)
            again.destroy_node()
