"""Worker processes for CPU-heavy work beside a control loop.

A process pool's worker blocks on its task queue; when its parent is killed (kill -9,
the OOM killer) nobody closes that queue and the worker lives on, an orphan, one per
crash. `exit_with_parent` as the pool's initializer ends it within `PERIOD`; `pool`
makes such a pool, whose worker also runs `NICENESS` steps below its parent, so that on
a busy machine its heavy work waits for the loops, not the loops for it (a control
cycle beside a planning worker on 2 cores). A worker inherits the scheduling of the
thread that starts it: a loop on SCHED_FIFO (`ft_msgs_py.thread_priority`) starts it
`lowered`, so the heavy work never runs at the loop's priority, not even its start-up
imports. Ctrl-C in a terminal signals the whole process group, workers included: a
worker of `SPAWN` (every pool of the suite's) then ends at once and quietly, exit status
130 (a node's worker, `pool`, ignores it: the node stops it), and its parent says what was
interrupted, instead of each worker printing a
KeyboardInterrupt traceback (also one still importing its modules when Ctrl-C came).
A `Worker` holds a loop's pool, started on first use.
A `Job` is a computation submitted to such a pool that the control cycle polls (never
waits on), with one set of failures (`JOB_FAILURES`).
"""

from __future__ import annotations

import math
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass
from enum import Enum
from multiprocessing.context import SpawnContext, SpawnProcess
from typing import Any, cast

#: How often (s) a worker checks that its parent still runs.
PERIOD = 0.5
#: How much nicer (lower priority) a worker runs than the process that starts it.
NICENESS = 10
#: Longest wait (s) for a stopped pool's manager thread to end (`stop`).
STOP_TIMEOUT = 5.0


def exit_with_parent(parent: int) -> None:
    """Pool initializer: a daemon thread ends this process once `parent` is gone."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PERIOD)
        os._exit(0)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


class QuietProcess(SpawnProcess):
    """A spawned process that SIGINT ends at once and quietly (exit status 130).

    It starts with SIGINT ignored (an ignored signal stays so across exec, and Python
    then installs no KeyboardInterrupt handler), so that a Ctrl-C while it imports its
    modules does nothing; `run` then makes SIGINT end it.
    """

    def start(self) -> None:
        """Start it, SIGINT ignored meanwhile (in the main thread: only it may say so)."""
        if threading.current_thread() is not threading.main_thread():
            super().start()
            return
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            super().start()
        finally:
            signal.signal(signal.SIGINT, previous)

    def run(self) -> None:
        """SIGINT from now on ends this process quietly, then the target runs."""
        signal.signal(signal.SIGINT, lambda *_: os._exit(130))
        super().run()


class _QuietSpawn(SpawnContext):
    Process = QuietProcess


#: The start method of every worker pool of the suite: spawned `QuietProcess`es.
SPAWN = _QuietSpawn()


def _start_worker(parent: int) -> None:
    """Pool initializer: `NICENESS` below the parent, ending with it (`exit_with_parent`).

    A node's worker ignores SIGINT: the node stops it, and a worker gone under the pool
    at a Ctrl-C made Python 3.11's pool race its own exit handler ("Exception ignored
    ... Bad file descriptor" from concurrent.futures at the node's exit).
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.nice(NICENESS)
    exit_with_parent(parent)


def pool() -> ProcessPoolExecutor:
    """One spawned worker process, `NICENESS` below this one, that ends with it.

    Spawned, not forked: a fork of a process running rclpy or numba threads may
    inherit a lock held by a thread that does not exist in the child.
    """
    return ProcessPoolExecutor(max_workers=1, mp_context=SPAWN,
                               initializer=_start_worker, initargs=(os.getpid(),))


def stop(pool: ProcessPoolExecutor) -> None:
    """End `pool` now, its work thrown away: worker processes terminated, then waited for.

    For a node's background work at the node's end, and for a worker that no longer
    answers. Shutting a pool down without waiting leaves its manager thread to close the
    pool's wake-up pipe while the interpreter may be exiting, and Python 3.11's exit
    handler writes to that pipe without the lock that would order the two (CPython issue
    gh-125451, fixed in 3.12.8 and 3.13.1): "Exception ignored ... Bad file descriptor"
    at a Ctrl-C. Waiting for the manager thread closes that window; terminating the
    workers first keeps the wait short while a job runs (a self-motion trace takes
    seconds), and bounded (`STOP_TIMEOUT`). The workers and the manager thread are the
    pool's private attributes in 3.11 (3.14 adds `terminate_workers` for the first half).
    """
    processes = list((pool._processes or {}).values())
    # typeshed has this attribute as a _ThreadWakeup; it holds the manager thread.
    manager = cast("threading.Thread | None", pool._executor_manager_thread)
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.terminate()
    if manager is not None:
        manager.join(STOP_TIMEOUT)


class Worker:
    """A control loop's worker process (`pool`), started on first use.

    Args:
        shared: a pool to use instead of one of its own; its giver's to stop (a harness
            running many loops in turn shares one), so `close` leaves it running.
    """

    def __init__(self, shared: ProcessPoolExecutor | None = None):
        self._pool, self._owned = shared, shared is None

    def start(self) -> Future | None:
        """Start the process now, off the control loop (a node does at model load).

        Otherwise the first job starts it inside a cycle: some ms of spawning. Returns
        the future of a first, empty job (done once the worker runs), or None where no
        process can start (inside a daemon process): the jobs report that when submitted.
        """
        try:
            return self.submit(os.getpid)
        except (AssertionError, RuntimeError, OSError):
            return None

    def submit(self, fn: Callable, *args: Any) -> Future:
        """Run fn(*args) in the worker process (started `lowered`: never at the loop's)."""
        if self._pool is None:
            self._pool = pool()
        with lowered():
            return self._pool.submit(fn, *args)

    def close(self) -> None:
        """Stop the process (`stop`), unless the pool was given."""
        if self._pool is not None and self._owned:
            stop(self._pool)


@contextmanager
def lowered() -> Iterator[None]:
    """The calling thread on the normal scheduler for the block, then as before.

    For starting processes and threads that must not inherit a real-time priority.
    Lowering is always allowed; restoring needs the permission that raised it.
    """
    policy, parameters = os.sched_getscheduler(0), os.sched_getparam(0)
    if policy == os.SCHED_OTHER:
        yield
        return
    os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    try:
        yield
    finally:
        os.sched_setscheduler(0, policy, parameters)


#: How a background job fails: its inputs refused (ValueError, `SuiteError` included) or
#: its worker process gone.
JOB_FAILURES = (ValueError, BrokenProcessPool)


class JobState(Enum):
    """Where a background job stands when polled (`Job.poll`)."""

    PENDING = "pending"  #: still running, within its time
    LATE = "late"  #: still running past its timeout: the caller gives up on it
    DONE = "done"  #: finished with a result
    FAILED = "failed"  #: finished with one of `JOB_FAILURES`


@dataclass(frozen=True)
class Job:
    """A computation in a worker process, polled from the control cycle, never waited on.

    Attributes:
        future: the submitted computation.
        submitted: when it was submitted (s, the caller's clock).
        timeout: s after `submitted` the caller waits for it at most (inf: no limit).
    """

    future: Future
    submitted: float
    timeout: float = math.inf

    @property
    def running(self) -> bool:
        """Whether the computation has not finished yet."""
        return not self.future.done()

    def poll(self, now: float) -> tuple[JobState, Any]:
        """The job's state at `now` (s) with its result or its error (None otherwise).

        Never blocks: a computation not done is PENDING, or LATE past its timeout.
        """
        if not self.future.done():
            return (JobState.LATE if now - self.submitted > self.timeout
                    else JobState.PENDING), None
        try:
            return JobState.DONE, self.future.result()
        except JOB_FAILURES as error:
            return JobState.FAILED, error
