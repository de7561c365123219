"""Test-session set-up: an isolated ROS 2 graph and deterministic property tests.

Each session gets its own block of DDS domains (from its process id, or with
pytest-xdist one block per worker of the run), the first as its ROS_DOMAIN_ID, and
keeps discovery on this machine, so parallel sessions and CI runs do not see each other,
and its own ROS_HOME, so no test reads or writes the user's ~/.ros.
"""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
import zlib

import pytest
from hypothesis import settings


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

# Property-based tests draw the same examples on every run: failures reproduce.
settings.register_profile("deterministic", derandomize=True, print_blob=True)
settings.load_profile("deterministic")


#: The tiers, one folder each (markers registered in pyproject.toml).
TIERS = ("unit", "nodes", "processes")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark every test with the tier of its folder: `-m unit` selects that folder's tests."""
    for item in items:
        tier = item.path.parent.name
        assert tier in TIERS, f"{item.nodeid}: every test lives in one of {TIERS}"
        item.add_marker(tier)
