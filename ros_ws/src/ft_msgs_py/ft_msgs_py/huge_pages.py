"""Keep the suite's processes out of transparent huge pages (`refuse_huge_pages`).

numpy asks the kernel for transparent huge pages on every array of 4 MiB or more
(`madvise(MADV_HUGEPAGE)`; the monitor's detector keeps its streams in such arrays).
Linux then hands the process to `khugepaged`, a kernel thread at nice 19 that collapses
the process's pages into huge ones, taking the process's memory-map lock. On a machine
whose cores are busy, a thread that low may wait long for a core; a thread of the process
that needs that lock to write (an `mprotect` as a malloc arena grows) queues behind it,
and every thread that needs the lock after that (an `madvise`, a page fault) queues too,
so the whole process can stand still for as long. A real-time setup disables huge pages
machine-wide; `refuse_huge_pages` does it for this process alone
(`prctl(PR_SET_THP_DISABLE)`, Linux 3.15 and later), and the processes it starts inherit
it. The arrays lose nothing that matters: a few MiB each, read in small windows.
"""

from __future__ import annotations

import ctypes
import os
import sys

#: prctl option (linux/prctl.h).
PR_SET_THP_DISABLE = 41


def _prctl(option: int, value: int) -> int:
    libc = ctypes.CDLL(None, use_errno=True)
    return int(libc.prctl(option, value, 0, 0, 0))


def refuse_huge_pages() -> str | None:
    """Disable transparent huge pages for this process; None on success or off Linux.

    Else why the kernel refused.
    """
    if not sys.platform.startswith("linux"):
        return None
    if _prctl(PR_SET_THP_DISABLE, 1) != 0:
        return f"prctl(PR_SET_THP_DISABLE) refused ({os.strerror(ctypes.get_errno())})"
    return None

