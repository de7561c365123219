"""The arm itself, in 3D (matplotlib): before the lock, at the lock and after recovery.

For any URDF: the chain is drawn as the segments from the base through its joints'
origins to the tool (`Robot.skeleton`), with the tool path of the run and the task points (critical
ones as stars). The locked joint is marked in red from the lock on.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from ft_core.robots import Robot

from ft_sim.scenario import Record


def moments(record: Record) -> list[tuple[str, int]]:
    """(title, step index) of the three views: 1 s before the lock, at it, at the end."""
    t = np.asarray(record.t)
    if record.injected_at is None:
        return [("start", 0), ("middle", len(t) // 2), ("end", len(t) - 1)]
    at = min(int(np.searchsorted(t, record.injected_at)), len(t) - 1)
    before = max(int(np.searchsorted(t, record.injected_at - 1.0)), 0)
    return [("before the lock", before), ("at the lock", at), ("after recovery", len(t) - 1)]


def draw(robot: Robot, record: Record, points: tuple[tuple[float, ...], ...],
         critical: list[int], locked_joint: str, path: Path) -> None:
    """Write the three views to `path` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    q = np.asarray(record.q)
    tool = np.array([robot.transform(qi)[:3, 3] for qi in q[::5]])
    skeletons = {index: np.vstack([np.zeros(3), robot.skeleton(q[index])])  # from the base
                 for _, index in moments(record)}
    xyz = np.array([(*point[:3], 0.0)[:3] for point in points])  # a planar point: z = 0
    every = np.vstack([tool, *skeletons.values(), xyz])
    centre = (every.max(axis=0) + every.min(axis=0)) / 2
    half = float((every.max(axis=0) - every.min(axis=0)).max()) / 2 + 0.05
    locked = robot.joint_names.index(locked_joint) if locked_joint in robot.joint_names else None
    others = [i for i in range(len(points)) if i not in critical]
    fig = plt.figure(figsize=(15, 5))
    for k, (title, index) in enumerate(moments(record)):
        ax = fig.add_subplot(1, 3, k + 1, projection="3d")
        chain = skeletons[index]
        ax.plot(*tool.T, color="0.75", lw=0.8, label="tool path")
        ax.plot(*tool[: index // 5 + 1].T, color="tab:blue", lw=1.2, label="path so far")
        ax.plot(*chain.T, "-o", color="k", lw=3, ms=4, label="arm")
        ax.scatter(*chain[0], color="k", marker="s", s=40)
        if locked is not None and title != "before the lock":
            ax.scatter(*chain[locked + 1], color="r", s=90, zorder=5,
                       label=f"{locked_joint} locked")
        for kind, chosen, style in (
                ("critical point", critical, {"marker": "*", "s": 140, "color": "tab:orange"}),
                ("waypoint", others, {"marker": "o", "s": 20, "color": "tab:green"})):
            if chosen:
                ax.scatter(*xyz[chosen].T, label=kind, **style)
        for axis, c in zip("xyz", centre, strict=True):
            getattr(ax, f"set_{axis}lim")(c - half, c + half)
            getattr(ax, f"set_{axis}label")(f"{axis} (m)")
        ax.set_title(f"{title} (t = {record.t[index]:.1f} s)")
        if k == 0:
            ax.legend(fontsize=7, loc="upper left")
    fig.suptitle(f"{robot.name}: {locked_joint or 'no joint'} locks")
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    fig.savefig(path, dpi=100)
    plt.close(fig)
