"""ft-stack: the controller and the monitor (and optionally the sim) as nodes of one process.

    ft-stack --ros-args --params-file arm.yaml
    ft-stack --sim --ros-args -p robot_model:=panda

Like a component container: one interpreter and one executor (rclpy's
EventsExecutor) spin the nodes, which keep their names (`controller`, `monitor`,
`sim`), topics, parameters and services. A parameters file addresses each by name
(`controller:`, `monitor:`, `sim:`) or all with `/**:`; `-p name:=value` on the
command line sets it in every node. The task space starts as the controller's shipped
parameters file sets it (`shipped_defaults`; `ros2 launch ft_controller controller.launch.py`
and `ros2 launch ft_sim demo.launch.py` start from that file too); a parameters file or
`-p task_space:=...` on the command line overrides it.

The controller and the monitor are connected by calls (`compose`), not through the
middleware: the controller hands each command to the monitor's command filter as an
array (`ft/command_raw` is still published while anyone else subscribes to it, for
observers and recorders), and the monitor passes each `joint_states` message it
takes to the controller with its reading of it, so the message is parsed once; the
controller does not subscribe to `joint_states` itself. The control cycle runs as each
joint state is taken (after the monitor observed it,
`ControllerNode.cycle_on_joint_states`), as ros2_control reads the hardware and then
updates its controllers: the command follows the freshest state, and the executor wakes
once per cycle. A cycle then pays for
the messages exchanged with the plant and little else; the Python interpreter,
Pinocchio and numba's code are loaded once (`make bench` measures both layouts:
docs/benchmarks.md).
"""

from __future__ import annotations

import argparse
import sys

from ft_controller.controller_node import ControllerNode
from ft_monitor.monitor_node import MonitorNode
from ft_msgs_py import spin
from rclpy.utilities import remove_ros_args

from ft_sim import shipped
from ft_sim.sim_node import SimNode


def main(args: list[str] | None = None) -> None:
    """Run the nodes until SIGINT or SIGTERM; each commands zeros as it stops."""
    argv = sys.argv if args is None else [sys.argv[0], *args]
    parser = argparse.ArgumentParser(prog="ft-stack", description=__doc__.splitlines()[0])
    parser.add_argument("--sim", action="store_true",
                        help="also run the kinematic sim (for trials without hardware)")
    own = parser.parse_args(remove_ros_args(args=argv)[1:])
    makers = [ControllerNode, MonitorNode, *([SimNode] if own.sim else [])]
    spin.run_nodes(makers, shipped_defaults(argv),
                   wire=lambda nodes: compose(nodes[0], nodes[1]))


def shipped_defaults(argv: list[str]) -> list[str]:
    """`argv` with the shipped file's `task_space` set for every node, before the rest.

    A ROS argument section of its own (`--ros-args -p task_space:=... --`) placed first:
    the parameters files and `-p` of `argv` come later and override it. The file's other
    values are not taken: its `robot_model` and `critical_points` are a Panda's, and
    without `robot_model` the nodes take the arm's URDF from `robot_description`. Without
    the file (a broken install), `argv` as it is.
    """
    task_space = shipped.parameters().get("task_space")
    if not task_space:
        return argv
    return [argv[0], "--ros-args", "-p", f"task_space:={task_space}", "--", *argv[1:]]


def compose(controller: ControllerNode, monitor: MonitorNode) -> None:
    """Connect the two nodes by calls: commands to the monitor, joint states to both.

    The controller gets each joint state with the monitor's reading of it, once the
    monitor has observed it, and runs its cycle on it (wall time; with `use_sim_time` the
    clock's ticks drive the cycles: `ControllerNode.cycle_on_joint_states`).
    """
    controller.hand_commands_to(monitor.take_commands_by_call())
    monitor.share_joint_states(controller.use_shared_joint_states())
    controller.cycle_on_joint_states()


if __name__ == "__main__":
    main()
