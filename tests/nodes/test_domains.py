"""Issue 33: DDS domains leased per run (`ft_sim.domains`)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from ft_sim import domains


@pytest.fixture(autouse=True)
def locks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setattr(domains, "LOCKS", tmp_path / "locks")
    return tmp_path / "locks"


def test_concurrent_leases_take_different_domains_and_a_release_frees_one() -> None:
    with domains.lease(40, 3) as first, domains.lease(40, 3) as second:
        assert (first, second) == (40, 41)
        with domains.lease(40, 3) as third, pytest.raises(RuntimeError, match="no free DDS"):
            assert third == 42
            with domains.lease(40, 3):
                pass
    with domains.lease(40, 3) as again:
        assert again == 40  # released cleanly: free at once


def test_a_domain_whose_holder_was_killed_rests_for_the_quarantine(locks: Path) -> None:
    """The killed holder's DDS participant lingers: the next run takes another domain."""
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time\nfrom pathlib import Path\n"
         "from ft_sim import domains\ndomains.LOCKS = Path(sys.argv[1])\n"
         "with domains.lease(40, 3) as d:\n    print(d, flush=True)\n    time.sleep(60)\n",
         str(locks)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "40"
        holder.send_signal(signal.SIGKILL)
        holder.wait(timeout=10)
        with domains.lease(40, 3) as domain:
            assert domain == 41
        past = time.time() - domains.QUARANTINE - 1
        os.utime(locks / "40.lock", (past, past))
        with domains.lease(40, 3) as domain:
            assert domain == 40  # rested long enough
    finally:
        holder.kill()
        holder.wait()
