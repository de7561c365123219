"""Worker processes that end with the process that started them.

A process pool's worker blocks on its task queue; when its parent is killed (kill -9,
the OOM killer) nobody closes that queue and the worker lives on, an orphan, one per
crash. `exit_with_parent` as the pool's initializer ends it within `PERIOD`.
"""

from __future__ import annotations

import os
import threading
import time

#: How often (s) a worker checks that its parent still runs.
PERIOD = 0.5


def exit_with_parent(parent: int) -> None:
    """Pool initializer: a daemon thread ends this process once `parent` is gone."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PERIOD)
        os._exit(0)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()
