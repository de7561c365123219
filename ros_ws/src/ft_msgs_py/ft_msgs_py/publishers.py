"""Whom to believe on a topic only one node should publish (the locked set).

rclpy (Jazzy) tells a subscriber nothing of a message's sender, only the graph does: the
publishers of the topic, by full node name. `judge` decides from them how much of a
message to take. A stray publisher on `ft/locked_joints` neither makes the controller
deaf to the monitor nor forges a lock: while the configured monitor publishes beside a
stranger, a message's new locks are taken once the monitor's own command path shows
them. The monitor zeros a locked joint in each command it forwards, and the controller
recognises those forwards by their stamps (`ft_msgs_py.monitor_guard`): a stranger that
merely publishes cannot make them. So the monitor's new locks still arrive, a forged one
does not; a release (the monitor's reset after a repair, or a forged empty set) waits
until the stranger is gone. Several publishers that all bear the monitor's name are a
restart: a killed monitor's participant stays in the graph until its lease runs out
(Fast DDS: 20 s), beside the new one; only the living one publishes, and its messages
are taken whole. Names can be forged: SROS2 closes the rest (docs/security.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal


def full_name(namespace: str, name: str) -> str:
    """`/ns/name` from a node's namespace and name (`/name` in the root namespace)."""
    return f"{namespace.rstrip('/')}/{name}"


def expected(monitor_name: str, namespace: str) -> str:
    """The monitor's full name: `monitor_name` if absolute, else in `namespace`."""
    return monitor_name if monitor_name.startswith("/") else full_name(namespace, monitor_name)


@dataclass(frozen=True)
class Verdict:
    """How much of a message to take: all of it, only added locks, or nothing; and why."""

    take: Literal["all", "additions", "none"]
    problem: str | None = None


def judge(publishers: list[str], monitor: str | None) -> Verdict:
    """The verdict on a locked-set message, given the topic's publishers (full names).

    `monitor`: the full name of the only node to believe (None: any single publisher).
    No publisher listed yet (discovery lags the first message): taken.
    """
    named = sorted(publishers)
    if monitor is not None and named and set(named) == {monitor}:
        return Verdict("all")  # the monitor, and a dead predecessor still in the graph
    if len(named) <= 1:
        if monitor is None or not named or named[0] == monitor:
            return Verdict("all")
        return Verdict("none", f"published by {named[0]}, not by the monitor '{monitor}'; "
                               "ignored")
    shown = f"{len(named)} publishers {named[:10]}"
    if monitor is not None and monitor in named:
        return Verdict("additions", f"{shown}: only the monitor may publish the locked set "
                                    "(see docs/security.md on SROS2); new locks are taken as "
                                    "the monitor's commands show them, releases wait until "
                                    "it is alone")
    return Verdict("none", f"{shown}: only the monitor may publish the locked set (see "
                           "docs/security.md on SROS2); ignored")
