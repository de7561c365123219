"""ft_msgs_py.huge_pages: the suite's processes keep out of transparent huge pages."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

#: Allocates an 8 MiB numpy array (numpy advises huge pages for it), touches it, and
#: prints how many of the process's mappings may take huge pages and whether they are off
#: (`THP_enabled` in its status).
PROBE = """
import re
import sys
from ft_msgs_py import huge_pages
if sys.argv[1] == "refuse":
    assert huge_pages.refuse_huge_pages() is None
else:  # cleared: a process inherits the setting from the one that started it
    import ctypes
    ctypes.CDLL(None).prctl(huge_pages.PR_SET_THP_DISABLE, 0, 0, 0, 0)
import numpy as np
a = np.ones(1 << 20)
smaps = open("/proc/self/smaps").read()
status = open("/proc/self/status").read()
print(len(re.findall(r"THPeligible: +1", smaps)), "THP_enabled:\t0" in status, float(a.sum()))
"""
MODE = Path("/sys/kernel/mm/transparent_hugepage/enabled")


def _probe(mode: str) -> tuple[int, bool]:
    out = subprocess.run([sys.executable, "-c", PROBE, mode], check=True, capture_output=True,
                         text=True, timeout=60).stdout.split()
    assert float(out[2]) == 1 << 20
    return int(out[0]), out[1] == "True"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="Linux prctl")
def test_a_process_that_refuses_huge_pages_has_no_memory_that_may_take_them() -> None:
    eligible, refused = _probe("refuse")
    assert refused and eligible == 0
    if MODE.is_file() and "[never]" not in MODE.read_text():
        eligible, refused = _probe("keep")  # numpy's advice, taken (khugepaged's to scan)
        assert not refused and eligible >= 1
