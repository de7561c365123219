"""Test-session set-up: an isolated ROS 2 graph and deterministic property tests.

Each session gets its own block of DDS domains (from its process id, or with
pytest-xdist one block per worker of the run), the first as its ROS_DOMAIN_ID, and
keeps discovery on this machine, so parallel sessions and CI runs do not see each other,
and its own ROS_HOME, so no test reads or writes the user's ~/.ros.
"""

from __future__ import annotations

import atexit
import fcntl
import os
import shutil
import tempfile
import zlib

import pytest
from _pytest.fixtures import FixtureRequest


def _domain_block() -> tuple[int, int]:
    """(start, size): this pytest process's block of DDS domains 1 + (start + k) % 100.

    A run's workers (pytest-xdist) share a start drawn from the run's id and take
    disjoint blocks of 100 // workers; a plain run draws it from its process id.
    """
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    worker = int(os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw"))
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID", str(os.getpid()))
    size = 100 // workers
    return zlib.crc32(run.encode()) % 100 + worker * size, size


_start, _size = _domain_block()
os.environ["FT_TEST_DOMAINS"] = f"{_start},{_size}"  # read by rosutil.fresh_domain
os.environ["ROS_DOMAIN_ID"] = str(1 + _start % 100)
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.pop("ROS_STATIC_PEERS", None)
# Nodes keep state under ROS_HOME (the monitor's locked set): never the user's own.
os.environ["ROS_HOME"] = tempfile.mkdtemp(prefix="ft_tests_ros_home_")
atexit.register(shutil.rmtree, os.environ["ROS_HOME"], ignore_errors=True)

# Property-based tests draw the same examples on every run (failures reproduce), unless a
# long fuzz run asks for more from fresh seeds (`fuzzing.SCALE`): its profile, loaded.
import fuzzing  # noqa: E402,F401

#: The tiers, one folder each (markers registered in pyproject.toml).
TIERS = ("unit", "nodes", "processes")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark every test with its folder's tier, then order them for two workers.

    `-m unit` selects the unit folder's tests; the order is `_two_queues`.
    """
    for item in items:
        tier = item.path.parent.name
        assert tier in TIERS, f"{item.nodeid}: every test lives in one of {TIERS}"
        item.add_marker(tier)
    items[:] = _two_queues(items)


def _two_queues(items: list[pytest.Item]) -> list[pytest.Item]:
    """The order for `make test`'s `-n 2 --dist worksteal`: long tests first, on both cores.

    Worksteal hands the first len // 2 tests to one worker and the rest to the other;
    a worker that runs dry steals from the end of the other's. So each half starts with
    its share of the slow tests (the quick ones fill in at the end).
    The `busy_machine` tests open the first half while the second starts with
    simulated-time tests, so their exclusive lock (`_machine_share`) waits for nothing.
    Any other run (one process, `-n 4`, `--random-order`) is only ordered differently.
    """
    def has(item: pytest.Item, name: str) -> bool:
        return item.get_closest_marker(name) is not None

    busy = [item for item in items if has(item, "busy_machine")]
    rest = [item for item in items if not has(item, "busy_machine")]
    # Slow first; among equals, separate-process tests (wall time) before simulated time.
    rest.sort(key=lambda item: (not has(item, "slow"), not has(item, "processes")))
    first, second = list(busy), []
    for item in rest:
        (first if len(first) < len(items) // 2 and len(first) <= len(second)
         else second).append(item)
    second.sort(key=lambda item: (not has(item, "slow"), has(item, "processes")))
    return first + second


@pytest.fixture(autouse=True)
def _machine_share(request: FixtureRequest, tmp_path_factory: pytest.TempPathFactory):
    """Wall-time tests (the processes tier) never run beside a test that loads every core.

    A `busy_machine` test (of any tier: a campaign on two workers in the nodes tier too)
    holds an exclusive lock for its duration, every other processes-tier test a shared one
    (flock on a file all workers of the run see), so
    with `-n 2` the other worker runs simulated-time tests meanwhile: a separate-process
    graph judged on wall time beside a full CPU load *and* another graph measured how
    two graphs on two cores starve each other, not how the nodes hold up on a busy machine.
    A `no_other_graph` test holds the exclusive lock too: it asserts that the controller's
    guard of a dead monitor never fires on a live one, which a second graph starting on the
    other core (its processes' imports, 0.1 s without joint states for the whole graph
    measured) can falsify without any fault of the nodes.
    """
    exclusive = any(request.node.get_closest_marker(name) is not None
                    for name in ("busy_machine", "no_other_graph"))
    if request.node.get_closest_marker("processes") is None and not exclusive:
        yield
        return
    with open(tmp_path_factory.getbasetemp().parent / "ft-wall-time.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
