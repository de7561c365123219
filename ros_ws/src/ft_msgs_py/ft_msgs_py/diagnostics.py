"""`diagnostic_msgs` statuses with key values (shown by rqt_robot_monitor and friends)."""

from __future__ import annotations

from collections.abc import Mapping

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

OK, WARN, ERROR, STALE = (DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR,
                          DiagnosticStatus.STALE)


def status(name: str, level: bytes, message: str, values: Mapping[str, object] | None = None,
           hardware_id: str = "") -> DiagnosticStatus:
    """One status; values are turned into text."""
    msg = DiagnosticStatus(level=level, name=name, message=message, hardware_id=hardware_id)
    msg.values = [KeyValue(key=str(k), value=_text(v)) for k, v in (values or {}).items()]
    return msg


def array(statuses: list[DiagnosticStatus], stamp: Time) -> DiagnosticArray:
    """A DiagnosticArray with the given statuses."""
    msg = DiagnosticArray(status=statuses)
    msg.header.stamp = stamp
    return msg


def _text(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_text(v) for v in value) + "]"
    return str(value)
