"""The labelled `ft/metrics` array.

`layout.dim[0].label` holds the comma-separated labels, in the order of `data`:
`kfm`, `sigma_min`, `jump_index`, `task_scale`, `soft_limit_margin`, then
`s_<joint>` for every joint. Every value is finite: a locked joint's post-failure
singular value (undefined) is published as -1, and `soft_limit_margin` with no
active soft box as `NO_SOFT_BOX`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from std_msgs.msg import Float64MultiArray, MultiArrayDimension

FIXED_LABELS = ("kfm", "sigma_min", "jump_index", "task_scale", "soft_limit_margin")
#: Published `soft_limit_margin` when no soft box is active (rad).
NO_SOFT_BOX = 1.0e9
#: Published `s_<joint>` of a locked joint.
LOCKED = -1.0


def labels(joints: Sequence[str]) -> list[str]:
    """All labels, in order, for a robot with these joints."""
    return [*FIXED_LABELS, *(f"s_{joint}" for joint in joints)]


def message(labels_: Sequence[str], values: Mapping[str, float]) -> Float64MultiArray:
    """The array for `values` (by label); missing or non-finite values raise ValueError."""
    data = [float(values[label]) for label in labels_]
    bad = [label for label, v in zip(labels_, data, strict=True) if not math.isfinite(v)]
    if bad:
        raise ValueError(f"non-finite metrics {bad}")
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label=",".join(labels_), size=len(data),
                                          stride=len(data))]
    msg.data = data
    return msg


def values(msg: Float64MultiArray) -> dict[str, float]:
    """{label: value} of a metrics message."""
    names = msg.layout.dim[0].label.split(",") if msg.layout.dim else []
    return dict(zip(names, msg.data, strict=True))
