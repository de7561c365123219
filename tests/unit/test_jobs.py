"""ft_core.workers.Job: a background computation polled from the cycle, never waited on."""

from __future__ import annotations

from concurrent.futures import Future
from concurrent.futures.process import BrokenProcessPool

import pytest
from ft_core.errors import SuiteError
from ft_core.workers import Job, JobState


def test_a_job_is_pending_then_late_past_its_timeout_without_blocking() -> None:
    job = Job(Future(), submitted=10.0, timeout=2.0)
    assert job.running and job.poll(11.0) == (JobState.PENDING, None)
    assert job.poll(12.5) == (JobState.LATE, None)
    assert Job(Future(), 10.0).poll(1e9) == (JobState.PENDING, None)  # no timeout


def test_a_finished_job_gives_its_result_or_its_failure() -> None:
    done = Future()
    done.set_result((1, 2))
    assert Job(done, 0.0).poll(5.0) == (JobState.DONE, (1, 2))
    for error in (SuiteError("unreachable"), ValueError("bad"), BrokenProcessPool("gone")):
        failed = Future()
        failed.set_exception(error)
        job = Job(failed, 0.0, timeout=1.0)
        assert not job.running
        assert job.poll(100.0) == (JobState.FAILED, error)  # done beats late


def test_a_bug_in_the_job_is_not_swallowed() -> None:
    failed = Future()
    failed.set_exception(KeyError("a bug"))
    with pytest.raises(KeyError):
        Job(failed, 0.0).poll(0.0)
