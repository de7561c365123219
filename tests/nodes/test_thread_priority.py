"""`thread_priority`: SCHED_FIFO for the thread that spins a node and the threads it starts."""

from __future__ import annotations

import os

import pytest
from ft_core import workers
from ft_msgs_py import thread_priority
from rosutil import in_thread


def policy() -> int:
    return os.sched_getscheduler(0)


def test_zero_leaves_the_scheduler_alone() -> None:
    assert in_thread(lambda: (thread_priority.apply(0), policy())) == (None, os.SCHED_OTHER)


def test_a_priority_out_of_range_is_refused_with_the_reason() -> None:
    refused, after = in_thread(lambda: (thread_priority.apply(150), policy()))
    assert refused is not None and "150" in refused
    assert after == os.SCHED_OTHER


def test_fifo_for_the_calling_thread_and_what_it_starts_unless_lowered() -> None:
    def work():
        refused = thread_priority.apply(5)
        if refused is not None:
            return refused, None, None, None
        mine = policy(), os.sched_getparam(0).sched_priority
        child = in_thread(policy)  # the executor's threads are started after: they inherit
        with workers.lowered():  # how the controller starts its tracing worker
            started_lowered = in_thread(policy)
            during = policy()
        return None, mine, child, (started_lowered, during, policy())

    refused, mine, child, lowered = in_thread(work)
    if refused is not None:
        assert "refused" in refused
        pytest.skip(f"this machine does not allow SCHED_FIFO: {refused}")
    assert mine == (os.SCHED_FIFO, 5)
    assert child == os.SCHED_FIFO
    assert lowered == (os.SCHED_OTHER, os.SCHED_OTHER, os.SCHED_FIFO)  # then restored
    assert policy() == os.SCHED_OTHER  # pytest's thread untouched


def test_lowered_leaves_a_normal_thread_alone() -> None:
    def work():
        with workers.lowered():
            during = policy()
        return during, policy()

    assert in_thread(work) == (os.SCHED_OTHER, os.SCHED_OTHER)
