"""The monitor's diagnostics: its own status, then one per joint (`Monitor.joint_report`).

`Unseen` says when joints become unseen (a lock there could not be seen).
"""

from __future__ import annotations

from collections.abc import Callable

from diagnostic_msgs.msg import DiagnosticStatus
from ft_core.health import JointCondition
from ft_core.monitor import UNSEEN_AFTER, Monitor
from ft_msgs_py import diagnostics

#: Diagnostic level of each joint state of `Monitor.joint_report`.
LEVELS = {JointCondition.OK: diagnostics.OK, JointCondition.LOCKED: diagnostics.ERROR,
          JointCondition.DEGRADED: diagnostics.WARN,
          JointCondition.FREE_SWINGING: diagnostics.ERROR,
          JointCondition.AT_LIMIT: diagnostics.WARN}


def statuses(core: Monitor | None, joints: list[str], order: list[int], values: dict,
             problems: str | None, stale: bool, status: Callable[..., DiagnosticStatus],
             ) -> list[DiagnosticStatus]:
    """The monitor's status with `values` (updated here), then one per joint.

    `joints` and `order`: the command order's names and chain indices; `problems`: the
    node's active problems (None: none); `stale`: no fresh command.
    `status(level, message, values, joint=None)` makes each (`SuiteNode.status`).
    """
    locked = {} if core is None else core.announced
    swinging = [] if core is None else core.swinging
    values["free_swinging_joints"] = swinging
    stalls, joint_statuses = [], []
    if core is not None:
        values.update(core.plant_values())
        for name, j in zip(joints, order, strict=True):
            joint = core.joint_report(j)
            if joint.state == JointCondition.AT_LIMIT:
                stalls.append(name)
            evidence = joint.evidence
            joint_statuses.append(status(LEVELS[joint.state], joint.state, {
                "observable": evidence.observable, "following": evidence.following,
                "measured_velocity": evidence.measured,
                "expected_velocity": evidence.commanded,
                "standard_error": evidence.standard_error}, joint=name))
    if problems:
        level, message = diagnostics.ERROR, problems
    elif locked or swinging:
        level, message = diagnostics.ERROR, "; ".join(
            [f"locked: {sorted(locked)}"] * bool(locked)
            + [f"free-swinging: {swinging}"] * bool(swinging))
    elif stalls:
        level, message = diagnostics.WARN, f"stalled at a limit: {stalls}"
    elif stale:
        level, message = diagnostics.WARN, "no fresh command: publishing zeros"
    elif core is not None and core.detector.not_observing:
        level, message = diagnostics.OK, f"not observing: {core.detector.not_observing}"
    else:
        level, message = diagnostics.OK, "no locked joint"
    return [status(level, message, values), *joint_statuses]


class Unseen:
    """The joints a lock cannot be seen on now (`Monitor.unseen`), said when they change."""

    def __init__(self, log: Callable[[str], object]):
        """`log`: an INFO line, once per joint that joins the unseen ones."""
        self._log, self._unseen = log, []

    def update(self, unseen: list[str]) -> list[str]:
        """The unseen joints now, said (INFO) when some join them."""
        if set(unseen) - set(self._unseen):
            self._log(f"a lock of {unseen} cannot be seen now: not commanded for "
                      f"{UNSEEN_AFTER:.0f} s or more (a lock shows only while its joint is "
                      "commanded; the controller's observability.enabled excites idle joints)")
        self._unseen = unseen
        return unseen
