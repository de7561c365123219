"""`ft/joint_health`: every joint's `ft_core.health.JointHealth` as a DiagnosticArray.

One `diagnostic_msgs/DiagnosticStatus` per joint, in the monitor's command order:
`name` the joint, `message` its state (`healthy`, `degraded`, `locked`,
`free-swinging`), `level` OK, WARN (degraded) or ERROR (locked, free-swinging),
`hardware_id` the robot, and the key values `follows`, `torque_margin`,
`usable_lower`, `usable_upper` (numbers; `nan`, `inf` and `-inf` allowed), `since`
(s, the stamp of the declaration), `braked` (`true`/`false`) and `evidence` (text).
Published reliable and transient local, depth 1 (`qos.LATCHED`), so a controller
that starts later gets the last one; any ROS tool echoes it, rqt_robot_monitor shows it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from ft_core.health import Health, JointHealth

from ft_msgs_py import diagnostics
from ft_msgs_py.messages import MAX_NAMES, MessageError

_LEVEL = {Health.HEALTHY: diagnostics.OK, Health.DEGRADED: diagnostics.WARN,
          Health.LOCKED: diagnostics.ERROR, Health.FREE_SWINGING: diagnostics.ERROR}
#: Key values read back as numbers.
_NUMBERS = ("follows", "torque_margin", "usable_lower", "usable_upper", "since")


def message(health: Mapping[str, JointHealth], stamp: Time, robot: str = "") -> DiagnosticArray:
    """The `ft/joint_health` message for {joint: health}, in the mapping's order."""
    statuses = []
    for joint, h in health.items():
        values: dict[str, object] = {key: repr(float(getattr(h, key))) for key in _NUMBERS}
        values["braked"] = "true" if h.braked else "false"
        values["evidence"] = h.evidence
        statuses.append(diagnostics.status(joint, _LEVEL[h.state], str(h.state), values,
                                           hardware_id=robot))
    return diagnostics.array(statuses, stamp)


def read(msg: DiagnosticArray, joints: Sequence[str]) -> tuple[dict[str, JointHealth], list[str]]:
    """({joint: health}, [names not in `joints`]) from an `ft/joint_health` message.

    Raises MessageError for more than `MAX_NAMES` statuses, a joint named twice, an
    unknown state or a key value that is not a number (missing keys take the defaults).
    """
    if len(msg.status) > MAX_NAMES:
        raise MessageError(f"ft/joint_health has {len(msg.status)} statuses (at most {MAX_NAMES})")
    known = set(joints)
    health: dict[str, JointHealth] = {}
    unknown: list[str] = []
    for status in msg.status:
        if status.name in health:
            raise MessageError(f"ft/joint_health names {status.name!r} twice")
        if status.name not in known:
            unknown.append(status.name)
            continue
        try:
            state = Health(status.message)
        except ValueError:
            raise MessageError(f"ft/joint_health: unknown state {status.message[:40]!r} for "
                               f"{status.name!r}") from None
        values = {kv.key: kv.value for kv in status.values}
        fields: dict[str, float] = {}
        for key in _NUMBERS:
            if key in values:
                try:
                    fields[key] = float(values[key])
                except ValueError:
                    raise MessageError(f"ft/joint_health: {key} of {status.name!r} is "
                                       f"{values[key][:40]!r}, not a number") from None
        lower = fields.get("usable_lower", -math.inf)
        upper = fields.get("usable_upper", math.inf)
        if isinstance(lower, float) and isinstance(upper, float) and not lower <= upper:
            raise MessageError(f"ft/joint_health: usable range of {status.name!r} is "
                               f"[{lower}, {upper}]")
        health[status.name] = JointHealth(state, braked=values.get("braked") == "true",
                                          evidence=values.get("evidence", ""), **fields)
    return health, unknown
