"""DDS domains leased per run, so that runs on one machine never see each other.

A run of the closed loop (`scenario`) joins a DDS domain of its own with discovery on
localhost only: runs on different machines cannot meet, and on one machine each holds a
lease on its domain, an exclusive lock on a file per domain id in the temporary folder.
The lock goes with the process that holds it, also when it crashes, so a lease is never
left behind; concurrent campaigns, a campaign's local workers and a cluster's workers on
one machine all take different domains.
"""

from __future__ import annotations

import fcntl
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

#: Domain ids ROS 2 can use with its default ports: 0 to 232.
DOMAINS = 233
#: Where the lock files are.
LOCKS = Path(tempfile.gettempdir()) / "ft_arms_domains"


@contextmanager
def lease(first: int, count: int) -> Iterator[int]:
    """The first domain id from `first` on (`count` of them, modulo `DOMAINS`) no one holds.

    Held for the block. Raises RuntimeError when all `count` are in use.
    """
    LOCKS.mkdir(exist_ok=True)
    for k in range(count):
        domain = (first + k) % DOMAINS
        with open(LOCKS / f"{domain}.lock", "w") as handle:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                continue
            yield domain
            return
    raise RuntimeError(f"all {count} DDS domains from {first} on are in use on this machine")
