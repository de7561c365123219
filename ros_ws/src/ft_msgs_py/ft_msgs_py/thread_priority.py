"""Real-time scheduling of the thread that runs a node's callbacks (`thread_priority`).

On a busy Linux machine the normal scheduler may hold a runnable process back for
a few milliseconds; an rclpy timer that runs more than one period late skips the
missed periods (rcl's rule), so a 1 kHz control loop on a 2-core machine loses
cycles even with only the sim beside it, and many with a busy process per core
(docs/benchmarks.md has the figures). As ros2_control's
controller manager does with its `thread_priority`, the controller and the monitor
can put the thread that runs their callbacks on SCHED_FIFO: it then runs as soon
as it is ready, ahead of every normal process.

Only the calling thread changes (Linux schedules threads), and what it starts later
inherits its priority: the executors' own threads (the EventsExecutor's timer thread,
which wakes the loop, is created when the nodes are added), so a busy machine cannot
hold the wake-up back either. CPU-heavy work must not: the controller starts its
self-motion tracing workers with the thread `ft_core.workers.lowered` to the normal
scheduler, so they run on it from their first instruction (their start-up imports alone
take a second of CPU). The kernel's real-time throttling (by default 5 % of each second kept
for normal processes) still applies. Needs root or an rtprio limit for the user (for
example `@realtime - rtprio 99` in /etc/security/limits.conf, as ros2_control's
documentation describes); refused, the node logs a warning and keeps running on the
normal scheduler.
"""

from __future__ import annotations

import os

#: Highest SCHED_FIFO priority on Linux.
MAX_PRIORITY = 99


def apply(priority: int) -> str | None:
    """Run the calling thread on SCHED_FIFO at `priority` (1-99); 0 leaves it as it is.

    Returns None on success (or for 0), else why the system refused (no permission, a
    priority outside 1-`MAX_PRIORITY`, not Linux).
    """
    if priority == 0:
        return None
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (OSError, AttributeError) as error:  # no permission, or not Linux
        return f"SCHED_FIFO {priority} refused ({error})"
    return None

