"""Reading small input files safely: only regular files, bounded in size and nesting.

A FIFO or a device in a file's place would hang the reader, a huge file exhaust it, and
JSON nested tens of thousands deep overflows the parser's recursion.
"""

from __future__ import annotations

import json
import stat
from pathlib import Path


def load_bytes(path: Path, most_bytes: int) -> bytes:
    """The bytes of `path`, a regular file of at most `most_bytes`.

    Raises ValueError otherwise (not regular, too large), and OSError when it cannot be
    read at all.
    """
    status = path.stat()
    if not stat.S_ISREG(status.st_mode):
        raise ValueError(f"{path} is not a regular file")
    if status.st_size > most_bytes:
        raise ValueError(f"{path} is larger than {most_bytes} bytes")
    with path.open("rb") as file:
        data = file.read(most_bytes + 1)
    if len(data) > most_bytes:
        raise ValueError(f"{path} is larger than {most_bytes} bytes")
    return data


def parse_json(data: bytes, path: Path) -> object:
    """The JSON in `data` (read from `path`); ValueError if nested too deep or not JSON."""
    try:
        return json.loads(data)
    except RecursionError:
        raise ValueError(f"{path} is nested too deep") from None


def load_json(path: Path, most_bytes: int) -> object:
    """The JSON in `path`, a regular file of at most `most_bytes`.

    Raises ValueError otherwise (not regular, too large, nested too deep, not JSON), and
    OSError when it cannot be read at all.
    """
    return parse_json(load_bytes(path, most_bytes), path)
