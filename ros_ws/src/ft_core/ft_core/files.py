"""Reading small input files safely: only regular files, bounded in size and nesting.

A FIFO or a device in a file's place would hang the reader, a huge file exhaust it, and
JSON nested tens of thousands deep overflows the parser's recursion.
"""

from __future__ import annotations

import json
import stat
from pathlib import Path


def load_json(path: Path, most_bytes: int) -> object:
    """The JSON in `path`, a regular file of at most `most_bytes`.

    Raises ValueError otherwise (not regular, too large, nested too deep, not JSON), and
    OSError when it cannot be read at all.
    """
    status = path.stat()
    if not stat.S_ISREG(status.st_mode):
        raise ValueError(f"{path} is not a regular file")
    if status.st_size > most_bytes:
        raise ValueError(f"{path} is larger than {most_bytes} bytes")
    with path.open("rb") as file:
        text = file.read(most_bytes + 1)
    if len(text) > most_bytes:
        raise ValueError(f"{path} is larger than {most_bytes} bytes")
    try:
        return json.loads(text)
    except RecursionError:
        raise ValueError(f"{path} is nested too deep") from None
