"""Small test robots, the open-loop control of Maciejewski et al. Theorem 1, a Panda command.

The robots as URDF strings; the Panda's command from rest is shared by the detection tests.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from ft_core import robots
from ft_core.task_channel import TaskChannel


def planar_arm(links: Sequence[float], limit: float | None = None,
               velocity: float = 2.0) -> robots.Robot:
    """Planar arm with joints about z and the given link lengths (m), planar task.

    `limit` None: continuous joints; otherwise joints 2.. are limited to +-limit
    and joint 1 to +-pi.
    """
    parts = ['<robot name="planar">'] + [f'<link name="l{i}"/>' for i in range(len(links) + 2)]
    offset = 0.0
    for i, length in enumerate(links):
        if limit is None:
            kind, bounds = "continuous", ""
        else:
            bound = 3.14159 if i == 0 else limit
            kind, bounds = "revolute", f'lower="{-bound}" upper="{bound}" '
        parts.append(
            f'<joint name="j{i + 1}" type="{kind}"><parent link="l{i}"/><child link="l{i + 1}"/>'
            f'<origin xyz="{offset} 0 0"/><axis xyz="0 0 1"/>'
            f'<limit {bounds}velocity="{velocity}" effort="1"/></joint>')
        offset = length
    parts.append(f'<joint name="tool" type="fixed"><parent link="l{len(links)}"/>'
                 f'<child link="l{len(links) + 1}"/><origin xyz="{offset} 0 0"/></joint></robot>')
    return robots.load("".join(parts), task_space="planar")


def chain_urdf(axes: Sequence[str], link: float = 0.2, name: str = "straight") -> str:
    """URDF of revolute joints j1.. with the given axes ("x", "y" or "z"), links along z.

    Links of `link` m, limits +-2.9 rad and 2 rad/s, and a fixed tool link one link
    past the last joint.
    """
    vectors = {"x": "1 0 0", "y": "0 1 0", "z": "0 0 1"}
    parts = [f'<robot name="{name}">'] + [f'<link name="l{i}"/>' for i in range(len(axes) + 2)]
    for i, axis in enumerate(axes):
        parts.append(
            f'<joint name="j{i + 1}" type="revolute"><parent link="l{i}"/>'
            f'<child link="l{i + 1}"/><origin xyz="0 0 {link if i else 0}"/>'
            f'<axis xyz="{vectors[axis]}"/>'
            '<limit lower="-2.9" upper="2.9" velocity="2" effort="1"/></joint>')
    parts.append(f'<joint name="tool" type="fixed"><parent link="l{len(axes)}"/>'
                 f'<child link="l{len(axes) + 1}"/><origin xyz="0 0 {link}"/></joint></robot>')
    return "".join(parts)


def straight_chain(axes: Sequence[str], link: float = 0.2,
                   task_space: str = "pose") -> robots.Robot:
    """`chain_urdf` loaded: at q = 0 it stands straight up, an exactly singular pose."""
    return robots.load(chain_urdf(axes, link), task_space=task_space)


PLANAR = robots.load("planar3r")
DT = 0.005


def pseudoinverse_control(q0, x_d, locked: int, seconds: float = 20.0, gain: float = 1.0):
    """Maciejewski et al. eq 15 with G = J+ (W = I): qd_c = J+ gain (x_d - x).

    The locked joint does not move and nobody knows. Returns (final q, final command,
    channel, first suspicion).
    """
    q = np.array(q0, dtype=float)
    channel = TaskChannel(PLANAR)
    suspected_at = None
    qd = np.zeros(3)
    for k in range(round(seconds / DT)):
        error = x_d - PLANAR.forward(q)
        qd = np.linalg.pinv(PLANAR.jacobian(q)) @ (gain * error)
        if channel.update(k * DT, q, qd, float(np.linalg.norm(error))) is not None and (
                suspected_at is None):
            suspected_at = (k * DT, channel.suspect)
        moved = qd.copy()
        moved[locked] = 0.0
        q = q + DT * moved
    return q, qd, channel, suspected_at


def panda_from_rest(t: float) -> np.ndarray:
    """A Panda's command (rad/s, 7 joints) at t s after starting from rest.

    Joint 1 ramps to -0.3 rad/s at 1 rad/s^2; joints 2, 5 and 7 move at 0.1, 0.3 and
    0.3 rad/s from the first command (witnesses that the plant follows).
    """
    command = np.zeros(7)
    command[[0, 1, 4, 6]] = [-min(0.3, t), 0.1, 0.3, 0.3]
    return command
