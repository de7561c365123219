"""A busy machine on demand, for tests and benchmarks that must run where users run."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def busy_cores() -> Iterator[None]:
    """One process spinning in Python per core for as long as the block runs.

    They run on the normal scheduler: a node with `thread_priority` runs ahead of them.
    """
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"])
            for _ in range(os.cpu_count() or 2)]
    try:
        yield
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
