"""Small test robots built as URDF strings."""

from __future__ import annotations

from collections.abc import Sequence

from ft_core import robots


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
