"""The suite's node base: parameter values, clock seconds and once-per-episode problems."""

from __future__ import annotations

from rclpy.node import Node

from ft_msgs_py.episodes import Episodes


class SuiteNode(Node):
    """A rclpy Node with the small helpers every suite node uses."""

    def __init__(self, name: str, **kwargs):
        super().__init__(name, **kwargs)
        self.problems = Episodes(self.get_logger())

    def param(self, name: str):
        """The current value of a parameter."""
        return self.get_parameter(name).value

    def now(self) -> float:
        """The node clock (wall or simulated) in seconds."""
        return self.get_clock().now().nanoseconds * 1e-9
