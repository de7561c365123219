"""The sim's fault and obstacle topics: `ft/inject_fault` and `ft/obstacle` (docs/sim.md).

`ft/inject_fault` is a `diagnostic_msgs/DiagnosticArray`, one `DiagnosticStatus` per
fault (`ft_core.faults.Fault`): `name` the joint, `message` the kind (`lock`,
`free_swing`, `viscous`, `dry`, `authority`, `range`, `intermittent`), `values` the key
values `severity`, `lower`, `upper`, `period` the kind takes (numbers as text). A message
is taken whole or refused whole (`MessageError` saying why): more than `MAX_FAULTS`
statuses, an unknown joint, kind or key, a key twice, a number that is not one or out of
its range, or one joint given the same kind twice.

`ft/obstacle` is a `visualization_msgs/Marker`: action ADD with type CUBE places a box
(`pose` in the chain's base frame, `scale` its edges in m); DELETE or DELETEALL removes it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from ft_core.faults import DEFAULTS, Fault, FaultError
from visualization_msgs.msg import Marker

from ft_msgs_py import convert, diagnostics
from ft_msgs_py.messages import MessageError

#: Most faults one `ft/inject_fault` message may carry.
MAX_FAULTS = 64
#: m, the largest edge of an obstacle.
MAX_OBSTACLE = 10.0


def read(msg: DiagnosticArray, joints: Sequence[str]) -> list[Fault]:
    """The faults of an `ft/inject_fault` message on a robot with these joints.

    Raises:
        MessageError: the message is refused (module docstring); the text says why.
    """
    if len(msg.status) > MAX_FAULTS:
        raise MessageError(f"{len(msg.status)} faults (at most {MAX_FAULTS})")
    known = set(joints)
    faults: list[Fault] = []
    for status in msg.status:
        joint = status.name
        if joint not in known:
            raise MessageError(f"unknown joint {joint[:64]!r} (one of {list(joints)})")
        if len(status.values) > len(DEFAULTS):
            raise MessageError(f"{joint}: {len(status.values)} key values (at most "
                               f"{len(DEFAULTS)}: {', '.join(DEFAULTS)})")
        numbers: dict[str, float] = {}
        for kv in status.values:
            if kv.key not in DEFAULTS:
                raise MessageError(f"{joint}: unknown key {kv.key[:40]!r} (one of "
                                   f"{', '.join(DEFAULTS)})")
            if kv.key in numbers:
                raise MessageError(f"{joint}: {kv.key} given twice")
            try:
                numbers[kv.key] = float(kv.value)
            except ValueError:
                raise MessageError(f"{joint}: {kv.key} {kv.value[:40]!r} is not a number") \
                    from None
        try:
            fault = Fault(status.message, joint, **numbers)
        except FaultError as error:
            raise MessageError(str(error)) from None
        if any(f.joint == joint and f.kind is fault.kind for f in faults):
            raise MessageError(f"{joint}: {fault.kind} given twice")
        faults.append(fault)
    return faults


def message(faults: Sequence[Fault], stamp: Time | None = None) -> DiagnosticArray:
    """The `ft/inject_fault` message for `faults`."""
    statuses = [diagnostics.status(f.joint, diagnostics.ERROR, str(f.kind),
                                   {key: repr(getattr(f, key)) for key in f.kind.fields})
                for f in faults]
    return diagnostics.array(statuses, stamp or Time())


def read_obstacle(msg: Marker) -> tuple[np.ndarray, np.ndarray] | None:
    """(pose 4x4 in the base frame, edges (3,) m) of an ADD CUBE, None for DELETE(ALL).

    Raises:
        MessageError: another action or type, a non-finite or zero-quaternion pose, or an
            edge not in (0, `MAX_OBSTACLE`] m.
    """
    if msg.action in (Marker.DELETE, Marker.DELETEALL):
        return None
    if msg.action != Marker.ADD or msg.type != Marker.CUBE:
        raise MessageError(f"action {msg.action} type {msg.type}: only ADD (0) of a CUBE (1), "
                           "DELETE (2) or DELETEALL (3)")
    size = np.array([msg.scale.x, msg.scale.y, msg.scale.z])
    if not np.all((size > 0) & (size <= MAX_OBSTACLE)):
        raise MessageError(f"scale {size.tolist()} m: each edge in (0, {MAX_OBSTACLE:g}]")
    return convert.pose_matrix(msg.pose), size


def obstacle_message(pose: np.ndarray, size: Sequence[float], frame: str = "") -> Marker:
    """The `ft/obstacle` message placing a box of edges `size` (m) at `pose` (4x4)."""
    msg = Marker(action=Marker.ADD, type=Marker.CUBE, pose=convert.pose_message(pose))
    msg.header.frame_id = frame
    msg.scale.x, msg.scale.y, msg.scale.z = (float(v) for v in size)
    msg.color.r, msg.color.a = 0.6, 0.5
    return msg
