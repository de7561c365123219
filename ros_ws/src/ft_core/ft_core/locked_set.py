"""The locked set on disk, so that it survives a restart of the monitor.

One small JSON file per monitor, robot and ROS domain in a state directory (default
`$ROS_HOME/ft_arms`, `~/.ros/ft_arms` without ROS_HOME, as ROS 2 keeps its own
per-user state), named after the monitor's fully qualified node name, the robot and
the domain (`arm1__monitor--panda--domain0.json` for `/arm1/monitor` on a Panda in
domain 0), so namespaced arms on one machine, and graphs in other domains (a sim
session beside the real arm), keep separate sets. It is written atomically (a
temporary file in the same directory, flushed and fsynced, renamed over the old one,
then the directory fsynced): a crash mid-write leaves the previous set, never half a
file, and once `save` returns the set survives a power cut. A file that cannot be
read or does not match the robot is reported and ignored.

`Writer` does the writing in a thread of its own, so that the monitor's command path
never waits for the disk (an fsync under load took seconds in the soak of
docs/benchmarks.md): the caller submits each new set and announces it once `done`
says its generation is on disk.
"""

from __future__ import annotations

import json
import math
import os
import re
import tempfile
import threading
from pathlib import Path

from ft_core import files
from ft_core.errors import SuiteError

#: Largest file read back (bytes): a locked set of a few joints is far smaller.
MAX_BYTES = 65536


class LockedSetError(SuiteError):
    """The stored file cannot be used (unreadable, malformed or for another robot)."""


def default_directory() -> Path:
    """`$ROS_HOME/ft_arms`, or `~/.ros/ft_arms`."""
    home = os.environ.get("ROS_HOME") or os.path.join(os.path.expanduser("~"), ".ros")
    return Path(home) / "ft_arms"


def path_for(directory: str | Path, node_name: str, robot: str, domain: int) -> Path:
    """The file of one monitor (fully qualified node name), robot and ROS domain."""
    return Path(directory or default_directory()) / (
        f"{_clean(node_name)}--{_clean(robot)}--domain{int(domain)}.json")


def unkeyed_path(directory: str | Path, node_name: str, robot: str) -> Path:
    """Where versions before the domain key kept the set (read by nobody: reported)."""
    return Path(directory or default_directory()) / f"{_clean(node_name)}--{_clean(robot)}.json"


def unkeyed_warning(directory: str | Path, node_name: str, robot: str) -> str | None:
    """What to tell the user when an unkeyed file (`unkeyed_path`) exists, else None."""
    old = unkeyed_path(directory, node_name, robot)
    if not old.exists():
        return None
    return (f"{old} (a locked set of an older version, for no particular ROS domain) is not "
            "restored: declare on ft/declare_failure any joint still locked, then delete "
            "the file")


def _clean(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]", "_", text.strip("/").replace("/", "__")) or "_"


def save(path: Path, robot: str, locked: dict[str, float]) -> None:
    """Write {joint name: position at lock (rad)} atomically."""
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps({"robot": robot, "locked": {
        name: (position if math.isfinite(position) else None)
        for name, position in sorted(locked.items())}}, indent=1)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(handle, "w") as file:
            file.write(text)
            file.flush()
            os.fsync(file.fileno())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    directory = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(directory)  # the rename itself, on disk
    finally:
        os.close(directory)


def load(path: Path, robot: str, joint_names: list[str]) -> dict[str, float]:
    """{joint name: position (rad; nan if unknown)} stored for this robot; {} if no file.

    Raises LockedSetError for anything but a regular file of at most `MAX_BYTES` (a FIFO
    in its place hung the monitor at start), JSON nested too deep to parse (60 000
    levels crashed it), or content that is not this robot's locked set.
    """
    if not path.exists():
        return {}
    try:
        data = files.load_json(path, MAX_BYTES)
        if not isinstance(data, dict) or data.get("robot") != robot:
            raise LockedSetError(f"{path} is not a locked set of robot {robot!r}")
        locked = data.get("locked")
        if not isinstance(locked, dict):
            raise LockedSetError(f"{path} has no 'locked' mapping")
        result = {}
        for name, position in locked.items():
            if name not in joint_names:
                raise LockedSetError(f"{path} names {name!r}, not a joint of {robot!r}")
            value = float(position) if isinstance(position, int | float) else math.nan
            result[name] = value if math.isfinite(value) else math.nan
        return result
    except (OSError, ValueError) as error:
        if isinstance(error, LockedSetError):
            raise
        raise LockedSetError(f"cannot read {path}: {error}") from error


class Writer:
    """`save` in a thread of its own: the newest submitted set first, older ones skipped.

    `submit` returns at once with the set's generation (1, 2, ...); `done` gives the
    newest generation the thread has finished with, and the error if that write failed
    (None: on disk). A set submitted while another is being written waits for it, then
    only the newest of those waiting is written: it holds everything before it.
    """

    def __init__(self, path: Path, robot: str):
        self.path = path
        self._robot = robot
        self._condition = threading.Condition()
        self._waiting: tuple[int, dict[str, float]] | None = None
        self._submitted = 0
        self._done: tuple[int, str | None] = (0, None)
        self._closed = False
        threading.Thread(target=self._run, name="locked set writer", daemon=True).start()

    def submit(self, locked: dict[str, float]) -> int:
        """Queue {joint name: position (rad)} for writing; its generation."""
        with self._condition:
            self._submitted += 1
            self._waiting = (self._submitted, dict(locked))
            self._condition.notify_all()
            return self._submitted

    def done(self) -> tuple[int, str | None]:
        """(newest generation finished, its error or None)."""
        with self._condition:
            return self._done

    def flush(self, timeout: float) -> bool:
        """Wait up to `timeout` s for every submitted set; whether all are finished."""
        with self._condition:
            return self._condition.wait_for(lambda: self._done[0] >= self._submitted, timeout)

    def close(self) -> None:
        """End the thread once the set waiting, if any, is written (see `flush`)."""
        with self._condition:
            self._closed = True
            self._condition.notify_all()

    def _run(self) -> None:
        while True:
            with self._condition:
                self._condition.wait_for(lambda: self._waiting is not None or self._closed)
                if self._waiting is None:
                    return
                (generation, locked), self._waiting = self._waiting, None
            try:
                save(self.path, self._robot, locked)
                error = None
            except OSError as problem:
                error = str(problem)
            with self._condition:
                self._done = (generation, error)
                self._condition.notify_all()
