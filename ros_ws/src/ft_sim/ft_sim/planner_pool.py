"""The worker process the controllers of one process's scenarios share, one after another."""

from __future__ import annotations

import multiprocessing.util
import os
import threading
from concurrent.futures import ProcessPoolExecutor

from ft_core import workers

#: The worker process the scenarios of this process share (`planner`), and its lock.
_PLANNER: list[ProcessPoolExecutor] = []
_PLANNER_LOCK = threading.Lock()
#: Longest wait (s) for the shared worker to answer before a scenario starts.
PLANNER_CHECK = 60.0


def planner() -> ProcessPoolExecutor:
    """The worker process of the controllers of this process's scenarios, one after another.

    Started once and kept: a campaign worker runs many scenarios, and starting a worker
    and importing the planner's modules in it costs more CPU than a short run's whole
    control loop (docs/campaign.md). Its jobs (boxes, plans) are pure functions of their
    arguments, seeded, so sharing it changes no result. Checked before each scenario (a
    job a run left behind ends first); one that died, or that cannot run (in a daemonic
    process the controller then says it cannot plan, as with a pool of its own), is
    replaced. It ends with the process (`stop_planner`): a process of a pool (a campaign
    worker) would otherwise wait at its exit for a child that waits for work.
    """
    with _PLANNER_LOCK:
        if _PLANNER:
            try:
                _PLANNER[0].submit(os.getpid).result(timeout=PLANNER_CHECK)
                return _PLANNER[0]
            except (RuntimeError, OSError, AssertionError, TimeoutError):  # broken, no child
                workers.stop(_PLANNER.pop())
        _PLANNER.append(workers.pool())
        # At the exit of a process of a pool, before multiprocessing closes the pool's
        # queues (their finalizers have priority 10) and joins the children.
        multiprocessing.util.Finalize(None, stop_planner, exitpriority=100)
        return _PLANNER[0]


def stop_planner() -> None:
    """End the shared worker process (`planner`), if any, and wait for it."""
    with _PLANNER_LOCK:
        while _PLANNER:
            _PLANNER.pop().shutdown(wait=True, cancel_futures=True)
