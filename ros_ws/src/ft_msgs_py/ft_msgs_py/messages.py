"""What the suite reads from a message: the error for one it refuses, and plain values.

`MessageError` and `MAX_NAMES` are the refusal every reader shares (`convert`, the
bytes of `wire`); `Stamp`, `Header` and `JointStateView` are a `sensor_msgs/JointState`
read from its bytes, which reads like the message where the suite reads one.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from ft_core.errors import SuiteError

#: Most joint names a message may carry: a whole robot's joint_state_broadcaster has
#: tens; more is an attack or a bug, refused before any per-name work.
MAX_NAMES = 1024


class MessageError(SuiteError):
    """A message that cannot be used; the text says why."""


class Stamp(NamedTuple):
    """A message stamp as `builtin_interfaces/Time` has it (s, ns)."""

    sec: int
    nanosec: int

    @classmethod
    def of(cls, nanoseconds: int) -> Stamp:
        """The stamp of a clock reading in integer nanoseconds (`SuiteNode.now_ns`)."""
        return cls(*divmod(nanoseconds, 1_000_000_000))


class Header(NamedTuple):
    """`std_msgs/Header`: stamp and frame."""

    stamp: Stamp
    frame_id: str


class JointStateView(NamedTuple):
    """A `JointState` read from its bytes: the message's fields, its arrays read-only.

    Reads like the message where the suite reads one (`convert.joint_vector`,
    `Episodes.message_time`): `header.stamp.sec` / `.nanosec`, `name` (a tuple),
    `position`, `velocity`, `effort` (float64 arrays, rad, rad/s, N m).
    """

    header: Header
    name: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray
