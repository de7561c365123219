"""The labelled `ft/metrics` array.

`layout.dim[0].label` holds the comma-separated labels, in the order of `data`:
`kfm`, `sigma_min`, `jump_index`, `task_scale`, `soft_limit_margin`, then
`s_<joint>` for every joint. Every value is finite: a locked joint's post-failure
singular value (undefined) is published as -1, and `soft_limit_margin` with no
active soft box as `NO_SOFT_BOX`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from std_msgs.msg import Float64MultiArray, MultiArrayDimension

FIXED_LABELS = ("kfm", "sigma_min", "jump_index", "task_scale", "soft_limit_margin")
#: Published `soft_limit_margin` when no soft box is active (rad).
NO_SOFT_BOX = 1.0e9
#: Published `s_<joint>` of a locked joint.
LOCKED = -1.0


def labels(joints: Sequence[str]) -> list[str]:
    """All labels, in order, for a robot with these joints."""
    return [*FIXED_LABELS, *(f"s_{joint}" for joint in joints)]


def template(labels_: Sequence[str]) -> Float64MultiArray:
    """An array with the labels' layout and zero data, built once and refilled by `fill`."""
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label=",".join(labels_), size=len(labels_),
                                          stride=len(labels_))]
    msg.data = [0.0] * len(labels_)
    return msg


def fill(msg: Float64MultiArray, data: Sequence[float]) -> None:
    """Put `data` (in label order) into a `template` message.

    Raises:
        ValueError: a wrong number of values, or non-finite ones (named by label).
    """
    values = [float(v) for v in data]
    count = msg.layout.dim[0].size
    if len(values) != count:
        raise ValueError(f"{len(values)} metrics for {count} labels")
    if not all(math.isfinite(v) for v in values):  # the labels are read only to say which
        bad = [label for label, v in zip(msg.layout.dim[0].label.split(","), values,
                                         strict=True) if not math.isfinite(v)]
        raise ValueError(f"non-finite metrics {bad}")
    msg.data = values


def values(msg: Float64MultiArray) -> dict[str, float]:
    """{label: value} of a metrics message."""
    names = msg.layout.dim[0].label.split(",") if msg.layout.dim else []
    return dict(zip(names, msg.data, strict=True))
