"""Arrays that grow along their first axis, for the detector's streams of entries."""

from __future__ import annotations

import numpy as np


class _Buffers:
    """Arrays that grow along their first axis: entries [start, end) are in use.

    Old entries are dropped by moving `start`; when `end` reaches the capacity, the
    entries in use move to the front, into arrays twice as large if more than half
    of the capacity is in use. Subclasses name their arrays in `NAMES`.
    """

    NAMES: tuple[str, ...] = ()
    times: np.ndarray
    start: int = 0
    end: int = 0

    def __len__(self) -> int:
        return self.end - self.start

    def make_room_for_one(self) -> None:
        """Room for one more entry at index `end`."""
        if self.end == self.times.size:
            self._make_room()

    def _make_room(self) -> None:
        size = len(self)
        for name in self.NAMES:
            old = getattr(self, name)
            new = (np.zeros((2 * old.shape[0], *old.shape[1:])) if size > old.shape[0] // 2
                   else old)
            # One copy, no temporary: numpy copies overlapping ranges (a move within
            # `old`) correctly, and a temporary's fresh pages cost time to touch.
            new[:size] = old[self.start:self.end]
            setattr(self, name, new)
        self.start, self.end = 0, size
