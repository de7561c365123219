"""Conversions between standard messages and the suite's arrays.

Joint vectors are matched by name: any order, extra joints ignored; a missing,
unknown-only or duplicate name, a length mismatch or a non-finite value raises
`MessageError` naming the problem, so the caller can log it and stop the arm.
`MessageError` and `MAX_NAMES` are `ft_msgs_py.messages`'s, named here too.
"""

from __future__ import annotations

import functools
import math
from collections import Counter
from collections.abc import Mapping, Sequence

import numpy as np
from builtin_interfaces.msg import Time
from ft_core.rotations import quaternion_from_rotation, rotation_from_quaternion
from geometry_msgs.msg import Pose, Twist
from sensor_msgs.msg import JointState

from ft_msgs_py.messages import MAX_NAMES, JointStateView, MessageError, Stamp


def stamp_seconds(stamp: Time | Stamp) -> float:
    """A message stamp in seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def stamp_from_nanoseconds(nanoseconds: int) -> Time:
    """A message stamp from integer nanoseconds (e.g. `Clock.now().nanoseconds`)."""
    return Time(sec=int(nanoseconds // 1_000_000_000), nanosec=int(nanoseconds % 1_000_000_000))


def names_to_indices(names: Sequence[str], joints: Sequence[str]) -> dict[str, int]:
    """Index in `joints` of every name; raises MessageError for duplicates or too many names.

    Linear in the number of names; more than `MAX_NAMES` are refused unread.
    """
    if len(names) > MAX_NAMES:
        raise MessageError(f"{len(names)} joint names (more than {MAX_NAMES})")
    if len(set(names)) != len(names):
        duplicates = sorted(name for name, count in Counter(names).items() if count > 1)
        raise MessageError(f"duplicate joint names {_few(duplicates)}")
    index = {name: i for i, name in enumerate(joints)}
    return {name: index[name] for name in names if name in index}


def _few(names: Sequence[str], most: int = 10) -> str:
    """A list of names for a log line: at most `most`, then how many more."""
    shown = ", ".join(repr(n[:64]) for n in names[:most])
    return f"[{shown}{f', ... {len(names) - most} more' if len(names) > most else ''}]"


@functools.lru_cache(maxsize=32)
def _positions(names: tuple[str, ...], joints: tuple[str, ...]) -> np.ndarray | None:
    """Where each of `joints` is in `names` (MessageError for duplicates or missing joints).

    None where `names` are `joints`, in order (the values are taken as they are).
    Cached: a driver sends the same names in every message. Read-only, an index array
    (numpy's `take` uses it as it is; a tuple would be converted at every message).
    """
    if names == joints:
        return None
    found = names_to_indices(names, joints)
    missing = [j for j in joints if j not in found]
    if missing:
        unknown = [n for n in names if n not in found]
        raise MessageError(f"joint state lacks {missing}" + (f" (it has {_few(unknown)})" if unknown
                                                            else ""))
    position = {name: i for i, name in enumerate(names)}
    index = np.array([position[j] for j in joints], dtype=np.intp)
    index.flags.writeable = False
    return index


def joint_vector(msg: JointState | JointStateView, joints: Sequence[str],
                 field: str = "position") -> np.ndarray:
    """The `field` values of `joints`, in that order, from a JointState.

    Raises MessageError for duplicate names, a field whose length differs from
    the names, missing joints or non-finite values of the wanted joints.
    """
    names = msg.name
    values = np.asarray(getattr(msg, field), dtype=float)
    if values.size != len(names):
        raise MessageError(f"joint state has {len(names)} names but {values.size} {field} values")
    if len(names) > MAX_NAMES:
        raise MessageError(f"{len(names)} joint names (more than {MAX_NAMES})")
    positions = _positions(tuple(names), tuple(joints))
    vector = values.copy() if positions is None else values.take(positions)
    if not all(map(math.isfinite, vector.tolist())):  # each cycle: cheaper than numpy's
        bad = [j for j, v in zip(joints, vector, strict=True) if not np.isfinite(v)]
        raise MessageError(f"non-finite {field} for {bad}")
    return vector


def array_vector(values: Sequence[float], order: Sequence[int]) -> np.ndarray:
    """Values given in command order (a Float64MultiArray's data), put in chain order.

    `order[k]` is the chain index of command entry k. Raises MessageError for a wrong
    length or non-finite values.
    """
    indices = np.asarray(order, dtype=int)
    if len(values) != indices.size:
        raise MessageError(f"array has {len(values)} values for {indices.size} joints")
    data = np.asarray(values, dtype=float)
    if not np.isfinite(data).all():
        raise MessageError(f"non-finite values at {np.flatnonzero(~np.isfinite(data))[:10]}")
    vector = np.empty(indices.size)
    vector[indices] = data
    return vector


def joint_state(joints: Sequence[str], stamp: Time, position: Sequence[float] | None = None,
                velocity: Sequence[float] | None = None,
                effort: Sequence[float] | None = None) -> JointState:
    """A JointState with the given names, stamp and (optional) positions, velocities, efforts."""
    msg = JointState()
    msg.header.stamp = stamp
    msg.name = list(joints)
    if position is not None:
        msg.position = [float(v) for v in position]
    if velocity is not None:
        msg.velocity = [float(v) for v in velocity]
    if effort is not None:
        msg.effort = [float(v) for v in effort]
    return msg


def locked_joints(msg: JointState, joints: Sequence[str]) -> tuple[dict[str, float], list[str]]:
    """({locked joint: position at lock}, [unknown names]) from an `ft/locked_joints` message.

    Positions are optional (nan when absent). Raises MessageError for duplicates.
    """
    names = list(msg.name)
    known = names_to_indices(names, joints)
    positions = list(msg.position) if len(msg.position) == len(names) else [np.nan] * len(names)
    locked = {n: float(p) for n, p in zip(names, positions, strict=True) if n in known}
    return locked, [n for n in names if n not in known]


def locked_message(locked: Mapping[str, float], stamp: Time) -> JointState:
    """The `ft/locked_joints` message: names, positions at lock, stamp of detection.

    While any position is unknown (nan: declared before any joint state) the
    message carries names only: every published number is finite.
    """
    positions = list(locked.values())
    known = all(math.isfinite(p) for p in positions)
    return joint_state(list(locked), stamp, position=positions if known else None)


def twist_vector(msg: Twist) -> np.ndarray:
    """[vx, vy, vz, wx, wy, wz] (m/s, rad/s); raises MessageError if non-finite."""
    v = np.array([msg.linear.x, msg.linear.y, msg.linear.z,
                  msg.angular.x, msg.angular.y, msg.angular.z])
    if not np.all(np.isfinite(v)):
        raise MessageError("twist has non-finite values")
    return v


def pose_matrix(msg: Pose) -> np.ndarray:
    """4x4 transform of a Pose; raises MessageError if non-finite or a zero quaternion."""
    p, o = msg.position, msg.orientation
    values = np.array([p.x, p.y, p.z, o.x, o.y, o.z, o.w])
    if not np.all(np.isfinite(values)):
        raise MessageError("pose has non-finite values")
    largest = np.max(np.abs(values[3:]))
    if largest < 1e-9:
        raise MessageError("pose has a zero quaternion")
    matrix = np.eye(4)
    matrix[:3, :3] = rotation_from_quaternion(values[3:])
    matrix[:3, 3] = values[:3]
    return matrix


def pose_message(matrix: np.ndarray) -> Pose:
    """Pose of a 4x4 transform."""
    msg = Pose()
    msg.position.x, msg.position.y, msg.position.z = (float(v) for v in matrix[:3, 3])
    x, y, z, w = (float(v) for v in quaternion_from_rotation(matrix[:3, :3]))
    msg.orientation.x, msg.orientation.y, msg.orientation.z, msg.orientation.w = x, y, z, w
    return msg


def message_time(stamp: Time | Stamp, now: float, future_tolerance: float) -> float | None:
    """Seconds of a message stamp; 0 means `now`; None when it is ahead of `now`.

    `future_tolerance` (s) allows for clock skew between machines.
    """
    seconds = stamp_seconds(stamp)
    if seconds == 0.0:
        return now
    return None if seconds > now + future_tolerance else seconds
