"""The locked set on disk, so that it survives a restart of the monitor.

One small file per monitor, robot and ROS domain in a state directory (default
`$ROS_HOME/ft_arms`, `~/.ros/ft_arms` without ROS_HOME, as ROS 2 keeps its own
per-user state), named after the monitor's fully qualified node name, the robot and
the domain (`arm1__monitor--panda--domain0.state` for `/arm1/monitor` on a Panda in
domain 0), so namespaced arms on one machine, and graphs in other domains (a sim
session beside the real arm), keep separate sets.

The file holds two slots of `SLOT_BYTES` (A at 0, B after it), each a copy of the set
with a generation number and a CRC-32: `MAGIC`, generation (u64), payload length (u32),
CRC-32 of generation, length and payload (u32), all little-endian, then the payload
(JSON: {"robot": name, "locked": {joint: position at lock in rad, or null}}), zeros to
the slot's end. A change is written in place into the slot the newest copy is not in,
then `os.fdatasync`: one write into blocks the file already has, so no metadata to
commit (no new file, no rename, no directory to sync), the cheapest durable write a
file system offers. A write torn by a crash leaves a slot whose CRC fails, and the
reader takes the other, the set before; once `save` returns, the set survives a power
cut. The file is created whole (a temporary file fsynced, renamed, the directory
fsynced) only when it is missing or not in this format: at the monitor's start
(`Monitor.restore` writes the set it restored), not when a lock is decided.

Files of older versions held the set as JSON alone, under the same name ending in
`.json` (`legacy_path`): read where no `.state` file exists, and removed once the set is
in the new file. A file that cannot be read or does not match the robot is reported and
ignored.

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
import stat
import struct
import tempfile
import threading
import traceback
import zlib
from collections.abc import Callable
from pathlib import Path

from ft_core import files
from ft_core.errors import SuiteError

#: Largest file read back (bytes): a locked set of a few joints is far smaller.
MAX_BYTES = 65536
#: Bytes of one slot (two pages): a copy of a set of over a hundred joints fits.
SLOT_BYTES = 8192
#: What every slot starts with (the format's name and version).
MAGIC = b"ft-locked-set-2\n"
_HEADER = struct.Struct("<16sQII")  # magic, generation, payload length, CRC-32
_PAYLOAD_BYTES = SLOT_BYTES - _HEADER.size


class LockedSetError(SuiteError):
    """The stored file cannot be used (unreadable, malformed or for another robot)."""


def default_directory() -> Path:
    """`$ROS_HOME/ft_arms`, or `~/.ros/ft_arms`."""
    home = os.environ.get("ROS_HOME") or os.path.join(os.path.expanduser("~"), ".ros")
    return Path(home) / "ft_arms"


def path_for(directory: str | Path, node_name: str, robot: str, domain: int) -> Path:
    """The file of one monitor (fully qualified node name), robot and ROS domain."""
    return Path(directory or default_directory()) / (
        f"{_clean(node_name)}--{_clean(robot)}--domain{int(domain)}.state")


def legacy_path(path: Path) -> Path:
    """Where versions before the slot format kept the set of `path` (JSON alone)."""
    return path.with_suffix(".json")


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
    """Write {joint name: position at lock (rad)} durably, into the older slot of `path`.

    The file is created whole first if it is missing or not in the slot format (the
    older version's JSON file removed once it is). Raises OSError, or LockedSetError for
    a set too large for a slot.
    """
    payload = json.dumps({"robot": robot, "locked": {
        name: (position if math.isfinite(position) else None)
        for name, position in sorted(locked.items())}}, separators=(",", ":")).encode()
    if len(payload) > _PAYLOAD_BYTES:
        raise LockedSetError(f"a locked set of {len(locked)} joints does not fit in "
                             f"{SLOT_BYTES} bytes")
    try:
        handle = os.open(path, os.O_RDWR | os.O_NONBLOCK)
    except FileNotFoundError:
        _create(path, payload)
        return
    try:
        regular = stat.S_ISREG(os.fstat(handle).st_mode)
        data = os.pread(handle, 2 * SLOT_BYTES + 1, 0) if regular else b""
        copies = _copies(data) if len(data) == 2 * SLOT_BYTES else []
        if copies:
            generation = max(copies)[0] + 1
            os.pwrite(handle, _slot(generation, payload), generation % 2 * SLOT_BYTES)
            os.fdatasync(handle)
            return
    finally:
        os.close(handle)
    _create(path, payload)


def _slot(generation: int, payload: bytes) -> bytes:
    """One slot: header, payload, zeros to `SLOT_BYTES`."""
    crc = zlib.crc32(payload, zlib.crc32(struct.pack("<QI", generation, len(payload))))
    return _HEADER.pack(MAGIC, generation, len(payload), crc) + payload.ljust(
        _PAYLOAD_BYTES, b"\0")


def _copies(data: bytes) -> list[tuple[int, bytes]]:
    """The intact copies (generation, payload) in a file of two slots."""
    found = []
    for offset in (0, SLOT_BYTES):
        magic, generation, length, crc = _HEADER.unpack_from(data, offset)
        start = offset + _HEADER.size
        payload = data[start:start + length]
        if (magic == MAGIC and length <= _PAYLOAD_BYTES and crc == zlib.crc32(
                payload, zlib.crc32(struct.pack("<QI", generation, length)))):
            found.append((generation, payload))
    return found


def _create(path: Path, payload: bytes) -> None:
    """Write a whole new file atomically, the set in both slots (generations 0 and 1).

    The older version's file (`legacy_path`) is removed once the new one is in place.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(handle, "wb") as file:
            file.write(_slot(0, payload) + _slot(1, payload))
            file.flush()
            os.fsync(file.fileno())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    legacy = legacy_path(path)
    if legacy != path:
        legacy.unlink(missing_ok=True)
    directory = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(directory)  # the rename (and the removal) themselves, on disk
    finally:
        os.close(directory)


def load(path: Path, robot: str, joint_names: list[str]) -> dict[str, float]:
    """{joint name: position (rad; nan if unknown)} stored for this robot; {} if no file.

    The newest intact copy of a slot file, or the JSON of an older version's file
    (`legacy_path` where `path` is missing). Raises LockedSetError for anything but a
    regular file of at most `MAX_BYTES` (a FIFO in its place hung the monitor at start),
    a slot file without an intact copy, JSON nested too deep to parse (60 000 levels
    crashed it), or content that is not this robot's locked set.
    """
    if not path.exists():
        path = legacy_path(path)
        if not path.exists():
            return {}
    try:
        data = files.load_bytes(path, MAX_BYTES)
        if data.startswith(MAGIC):
            copies = _copies(data) if len(data) == 2 * SLOT_BYTES else []
            if not copies:
                raise LockedSetError(f"{path} holds no intact copy of a locked set")
            data = max(copies)[1]
        return _parse(files.parse_json(data, path), path, robot, joint_names)
    except (OSError, ValueError) as error:
        if isinstance(error, LockedSetError):
            raise
        raise LockedSetError(f"cannot read {path}: {error}") from error


def _parse(data: object, path: Path, robot: str, joint_names: list[str]) -> dict[str, float]:
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


class Writer:
    """`save` in a thread of its own: the newest submitted set first, older ones skipped.

    `submit` returns at once with the set's generation (1, 2, ...); `done` gives the
    newest generation the thread has finished with, and the error if that write failed
    (None: on disk); `written`, if given, says so as soon as it is. A set submitted while
    another is being written waits for it, then only the newest of those waiting is
    written: it holds everything before it.
    """

    def __init__(self, path: Path, robot: str, written: Callable[[], object] | None = None):
        """`written()` is called in the writer's thread after each write, failed or not."""
        self.path = path
        self._robot = robot
        self._written = written
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
            except (OSError, LockedSetError) as problem:
                error = str(problem)
            with self._condition:
                self._done = (generation, error)
                self._condition.notify_all()
            if self._written is not None:
                try:
                    self._written()
                except Exception:  # the caller's problem: the writing goes on
                    traceback.print_exc()
