"""ft_msgs_py.spin: the executables' entry point, run in-process."""

from __future__ import annotations

import gc
import signal

from ft_msgs_py import spin
from rclpy.node import Node


def test_run_node_freezes_start_up_objects_and_stops_cleanly_on_sigint() -> None:
    seen: dict[str, int | bool] = {}

    class Probe(Node):
        """Records what a callback sees, then asks the process to stop."""

        def __init__(self) -> None:
            super().__init__("spin_probe")
            self.create_timer(0.01, self._tick)

        def _tick(self) -> None:
            seen["frozen"] = gc.get_freeze_count()
            signal.raise_signal(signal.SIGINT)

        def stop(self) -> None:
            seen["stopped"] = True

    previous = signal.getsignal(signal.SIGINT)
    try:
        spin.run_node(Probe, [])
    finally:
        gc.unfreeze()
    # The start-up objects (modules, rclpy's entities, the node) are out of the
    # collector's sight; the node's stop() ran; our SIGINT handler is back.
    assert seen["frozen"] > 10_000
    assert seen["stopped"] is True
    assert signal.getsignal(signal.SIGINT) is previous
