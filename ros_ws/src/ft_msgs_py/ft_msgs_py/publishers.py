"""Whom to believe on a topic only one node should publish (the locked set).

rclpy (Jazzy) tells a subscriber nothing of a message's sender, only the graph does: the
publishers of the topic, by full node name. `judge` decides from them how much of a message
to take, and `LockedSetTrust` which locked set the controller adopts. While the configured
monitor publishes beside a stranger, a message's new locks are taken once the monitor's own
command path shows them (a stranger must not make the controller deaf to the monitor). The
monitor zeros a locked joint in each command it forwards, and the controller recognises
those forwards by their stamps (`ft_msgs_py.monitor_guard`): a stranger that merely
publishes cannot make them. So the monitor's new locks still arrive, a forged one does not;
a release (the monitor's reset after a repair, or a forged empty set) waits until the
stranger is gone. Several publishers that all bear the monitor's name are a restart: a
killed monitor's participant stays in the graph until its lease runs out (Fast DDS: 20 s),
beside the new one; only the living one publishes, and its messages are taken whole. Names
can be forged: SROS2 closes the rest (docs/security.md).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from enum import Enum


def full_name(namespace: str, name: str) -> str:
    """`/ns/name` from a node's namespace and name (`/name` in the root namespace)."""
    return f"{namespace.rstrip('/')}/{name}"


def expected(monitor_name: str, namespace: str) -> str:
    """The monitor's full name: `monitor_name` if absolute, else in `namespace`."""
    return monitor_name if monitor_name.startswith("/") else full_name(namespace, monitor_name)


class Take(Enum):
    """How much of a locked-set message to take."""

    ALL = "all"
    ADDITIONS = "additions"  #: only new locks, once the monitor's commands show them
    NONE = "none"


@dataclass(frozen=True)
class Verdict:
    """How much of a message to take, and why not all of it."""

    take: Take
    problem: str | None = None


def judge(publishers: list[str], monitor: str | None) -> Verdict:
    """The verdict on a locked-set message, given the topic's publishers (full names).

    `monitor`: the full name of the only node to believe (None: any single publisher).
    No publisher listed yet (discovery lags the first message): taken.
    """
    named = sorted(publishers)
    if monitor is not None and named and set(named) == {monitor}:
        return Verdict(Take.ALL)  # the monitor, and a dead predecessor still in the graph
    if len(named) <= 1:
        if monitor is None or not named or named[0] == monitor:
            return Verdict(Take.ALL)
        return Verdict(Take.NONE, f"published by {named[0]}, not by the monitor '{monitor}'; "
                               "ignored")
    shown = f"{len(named)} publishers {named[:10]}"
    if monitor is not None and monitor in named:
        return Verdict(Take.ADDITIONS, f"{shown}: only the monitor may publish the locked set "
                                    "(see docs/security.md on SROS2); new locks are taken as "
                                    "the monitor's commands show them, releases wait until "
                                    "it is alone")
    return Verdict(Take.NONE, f"{shown}: only the monitor may publish the locked set (see "
                           "docs/security.md on SROS2); ignored")


class LockedSetTrust:
    """Which locked set a controller adopts from the messages and the monitor's commands.

    A message judged `Take.ALL` is adopted as it is. One judged `Take.ADDITIONS` is
    contested: of its locks, those the controller does not hold yet are adopted as the
    monitor's command echoes show them zeroed (`corroborated`); its releases wait. A
    message judged `Take.NONE` changes nothing.
    """

    def __init__(self) -> None:
        self.contested: set[str] = set()  #: the contested message's locks still unshown

    def heard(self, take: Take, locked: Iterable[str], current: set[str],
              shown: set[str]) -> set[str] | None:
        """The locked set to adopt on a message (None: keep `current`).

        `locked`: the message's joints; `current`: the set in force; `shown`: the joints
        the monitor's latest echo zeroed.
        """
        if take == Take.NONE:
            return None
        if take == Take.ADDITIONS:
            self.contested = set(locked)
            return self.corroborated(current, shown)
        self.contested = set()
        return set(locked)

    def corroborated(self, current: set[str], shown: set[str]) -> set[str] | None:
        """The set to adopt once echoes show contested locks zeroed (None: nothing new)."""
        confirmed = (self.contested - current) & shown
        self.contested -= confirmed
        return current | confirmed if confirmed else None
