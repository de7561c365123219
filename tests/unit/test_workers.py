"""ft_core.workers: a `pool` worker ends when the process that started it is killed."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

import pytest
from ft_core import workers

PARENT = """
import multiprocessing, os, sys, time
from concurrent.futures import ProcessPoolExecutor
from ft_core import workers
if __name__ == "__main__":
    pool = (workers.pool() if sys.argv[1] == "watch"
            else ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")))
    print(pool.submit(os.getpid).result(), flush=True)
    time.sleep(60)
"""


def running(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def orphan_after_kill(tmp_path: Path, mode: str) -> tuple[int, bool]:
    """(worker pid, whether it still runs 1.5 s (3 watch periods) after its parent's kill -9)."""
    script = tmp_path / "parent.py"
    script.write_text(PARENT)
    parent = subprocess.Popen([sys.executable, str(script), mode], stdout=subprocess.PIPE,
                              text=True)
    worker = int(parent.stdout.readline())
    assert running(worker)
    parent.kill()
    parent.wait(timeout=10)
    deadline = time.monotonic() + 3 * workers.PERIOD
    while running(worker) and time.monotonic() < deadline:
        time.sleep(0.05)
    alive = running(worker)
    if alive:
        os.kill(worker, signal.SIGKILL)
    return worker, alive


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads Linux /proc")
def test_a_worker_ends_with_its_killed_parent_and_would_not_by_itself(tmp_path: Path) -> None:
    _, orphaned = orphan_after_kill(tmp_path, "plain")
    assert orphaned, "a plain pool worker was expected to outlive its parent"
    _, orphaned = orphan_after_kill(tmp_path, "watch")
    assert not orphaned


def test_a_worker_runs_nicer_than_its_parent() -> None:
    """Its heavy work yields the CPU to the control loops beside it."""
    pool = workers.pool()
    try:
        worker_niceness = pool.submit(os.nice, 0).result(timeout=60)
    finally:
        pool.shutdown()
    assert worker_niceness == min(19, os.nice(0) + workers.NICENESS)


def test_a_stopped_pool_leaves_nothing_running_even_mid_job() -> None:
    """`stop` ends the worker and the pool's manager thread before it returns.

    Python 3.11's exit handler races a manager thread still closing its pipe (the
    "Bad file descriptor" a Ctrl-C printed): after `stop` there is no such thread.
    """
    pool = workers.pool()
    worker = pool.submit(os.getpid).result(timeout=60)
    job = pool.submit(time.sleep, 30.0)
    deadline = time.monotonic() + 10.0
    while not job.running():
        assert time.monotonic() < deadline, "the job never started"
        time.sleep(0.01)
    manager = pool._executor_manager_thread
    assert manager is not None and manager.is_alive()
    workers.stop(pool)
    assert not manager.is_alive()
    assert not running(worker)
    assert job.done() and not job.cancelled()  # ended by the worker's end, not by a cancel
    with pytest.raises(BrokenProcessPool):
        job.result(timeout=0)
