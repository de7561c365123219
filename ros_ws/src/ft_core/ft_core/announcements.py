"""Persist, then announce: changes of the locked set, handed over once they are on disk.

A change of the locked set takes effect at once where it is decided (the monitor's
command filter); what may be published is only what its file holds. `Announcements`
submits each changed set to the writer thread (`ft_core.locked_set.Writer`) without
waiting for the disk, holds the `Change` meanwhile, and hands it over from `settled`
once the write of its generation (or of a newer set, which holds it) has ended. A
change that leaves the set as it is (lines to log only) waits behind those being
written, so the lines keep their order (docs/monitor.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from ft_core import locked_set


@dataclass
class Change:
    """What a call did to the locked set.

    Attributes:
        changed: the locked set changed (and is on disk unless `report` said otherwise).
        events: what happened to the arm, one line each, for the error log.
        time: s, when the newest of its decisions was taken (the stamp to announce it
            with; nan when nothing was decided).
    """

    changed: bool = False
    events: list[str] = field(default_factory=list)
    time: float = math.nan

    @staticmethod
    def of(changes: Sequence[Change]) -> Change:
        """Several changes as one, in order."""
        return Change(any(c.changed for c in changes), [e for c in changes for e in c.events],
                      changes[-1].time if changes else math.nan)


class Announcements:
    """The changes of the locked set, held until written (the module).

    Args:
        writer: the state file's writer thread; None: kept in memory only (every change
            is handed over at once).
        report: called with ("state_directory", problem or None) after each write
            (`ft_core.monitor.Report`).
    """

    def __init__(self, writer: locked_set.Writer | None, report: Callable[..., None]):
        self._writer = writer
        self._report = report
        #: (generation, change, the set it leaves) submitted, not yet handed over
        self._held: list[tuple[int, Change, dict[str, float]]] = []
        self._announced: dict[str, float] = {}

    @property
    def announced(self) -> dict[str, float]:
        """The locked set as the changes handed over so far leave it: on disk, to publish."""
        return dict(self._announced)

    @property
    def writing(self) -> bool:
        """Whether a change waits for a write of the locked set still under way."""
        if not self._held or self._writer is None:
            return False
        return self._writer.done()[0] < self._held[-1][0]

    def on_disk(self, locked: dict[str, float]) -> None:
        """`locked` was read from the file: announced as it is, and written back.

        The write back puts the file in the writer's format (created if missing, an older
        version's migrated), so that a later change costs one write in place.
        """
        if self._writer is not None:
            self._writer.submit(locked)
        self._announced = dict(locked)

    def hold(self, change: Change, now: float, locked: dict[str, float]) -> None:
        """Queue `change`, decided at `now` s and leaving the set `locked`, for `settled`."""
        change.time = now
        if change.changed:
            generation = self._writer.submit(locked) if self._writer is not None else 0
            self._held.append((generation, change, dict(locked)))
        elif change.events:
            generation, left = ((self._held[-1][0], self._held[-1][2]) if self._held
                                else (0, self._announced))
            self._held.append((generation, change, left))

    def drop(self) -> None:
        """Forget every change not yet handed over (a reset supersedes them)."""
        self._held.clear()

    def settled(self) -> Change:
        """The changes written since the last call, in order (nothing to announce: empty)."""
        if not self._held:
            return Change()
        written, error = self._writer.done() if self._writer is not None else (math.inf, None)
        ready = [held for held in self._held if held[0] <= written]
        if not ready:
            return Change()
        del self._held[:len(ready)]
        if self._writer is not None:
            self._report("state_directory",
                         None if error is None else f"cannot keep the locked set: {error}")
        self._announced = ready[-1][2]
        return Change.of([change for _, change, _ in ready])

    def flush(self, timeout: float) -> Change:
        """Wait up to `timeout` s for the writes under way; then `settled`."""
        if self._writer is not None:
            self._writer.flush(timeout)
        return self.settled()

    def close(self, timeout: float) -> Change:
        """Finish the last write (at most `timeout` s) and end the writer thread."""
        change = self.flush(timeout)
        if self._writer is not None:
            self._writer.close()
        return change
