"""The executables' entry point: spin a node until SIGINT, then stop it and shut down."""

from __future__ import annotations

from collections.abc import Callable

import rclpy
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions


def run_node(make_node: Callable[[], Node], args: list[str] | None = None) -> None:
    """Spin the node until SIGINT; then its `stop()` (if any: e.g. command zeros) and exit.

    rclpy's own SIGINT handler is off so the node can still publish in `stop()`.
    """
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = make_node()
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
    finally:
        stop = getattr(node, "stop", None)
        if stop is not None:
            stop()
        node.destroy_node()
        rclpy.try_shutdown()
