"""Every use of rclpy's private API in the suite, each with a canary test.

rclpy_private.set_declared: placeholder, merged with the gathered module.
"""

from __future__ import annotations

from rclpy.node import Node
from rclpy.parameter import Parameter


def set_declared(node: Node, parameter: Parameter) -> None:
    """Set a declared parameter the way a declaration does, read-only ones included."""
    node._set_parameters_atomically_common(
        [parameter], {parameter.name: node.describe_parameter(parameter.name)},
        allow_not_set_type=True)
