"""DDS domains leased per run, so that runs on one machine never see each other.

A run of the closed loop (`scenario`) joins a DDS domain of its own with discovery on
localhost only: runs on different machines cannot meet, and on one machine each holds a
lease on its domain, an exclusive lock on a file per domain id in the temporary folder.
The lock goes with the process that holds it, also when it crashes, so a lease is never
left behind; concurrent campaigns, a campaign's local workers and a cluster's workers on
one machine all take different domains.

A process killed in a run leaves its DDS participant behind for a while: the others
still see its nodes until its liveliness lease runs out. A run in that domain would find
a second `controller` and `monitor` (and refuse the locked set from two publishers, as
it should). So the holder writes its pid in the file and clears it on release; a domain
whose file still names a holder that is gone is left alone for `QUARANTINE` s.
"""

from __future__ import annotations

import fcntl
import os
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

#: Domain ids ROS 2 can use with its default ports: 0 to 232.
DOMAINS = 233
#: Where the lock files are.
LOCKS = Path(tempfile.gettempdir()) / "ft_arms_domains"
#: s a domain rests after its holder died in it (longer than Fast DDS's 20 s lease).
QUARANTINE = 30.0


@contextmanager
def lease(first: int, count: int) -> Iterator[int]:
    """The first domain id from `first` on (`count` of them, modulo `DOMAINS`) free to use.

    Free: no one holds it, and its last holder released it or died more than
    `QUARANTINE` s ago. Held for the block. Raises RuntimeError when none of the `count`
    is free.
    """
    LOCKS.mkdir(exist_ok=True)
    for k in range(count):
        domain = (first + k) % DOMAINS
        path = LOCKS / f"{domain}.lock"
        with open(path, "a+") as handle:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                continue
            handle.seek(0)
            if handle.read().strip() and time.time() - path.stat().st_mtime < QUARANTINE:
                continue  # its holder died in it a moment ago
            handle.truncate(0)
            handle.write(f"{os.getpid()}\n")
            handle.flush()
            try:
                yield domain
            finally:
                handle.truncate(0)
            return
    raise RuntimeError(f"no free DDS domain among the {count} from {first} on")
