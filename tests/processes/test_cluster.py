"""Issue 33: the batch tools on a Dask cluster (`ft_core.offline.batch`, `--cluster`).

A local cluster of two worker processes stands for a cluster of machines: a scheduler
and workers that are other processes, reached over TCP. Workers are started as users
start them (docs/campaign.md, "Past one machine"): not daemonic, one job at a time.
"""

from __future__ import annotations

import json
import os
import re
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import dask
import numpy as np
import pytest
from distributed import Client, LocalCluster
from ft_core.offline import batch, placement
from ft_sim import campaign
from rosutil import fresh_domain

#: A cluster of worker processes loads every core: no other separate-process graph beside it
#: (a deployment test's plant stalled 0.2 s beside a campaign on a cluster).
pytestmark = pytest.mark.busy_machine


@pytest.fixture
def cluster(monkeypatch: pytest.MonkeyPatch) -> Iterator[LocalCluster]:
    # As docs/campaign.md starts workers: through the environment, which a worker that
    # its nanny restarts (after a crash) inherits too.
    monkeypatch.setenv("DASK_DISTRIBUTED__WORKER__DAEMON", "False")
    dask.config.refresh()
    local = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                         dashboard_address=None)
    try:
        yield local
    finally:
        local.close()
        monkeypatch.delenv("DASK_DISTRIBUTED__WORKER__DAEMON")
        dask.config.refresh()


def _map(prefix: Path, *where: str) -> dict:
    args = ["--robot", "planar3r", "--x=-1:1:3", "--y", "0:1:2", "--step", "0.05",
            "--no-plot", "--output", str(prefix), *where]
    assert placement.main(args) == 0
    with np.load(f"{prefix}.npz") as data:
        return {key: data[key] for key in data.files}


def test_a_map_on_a_cluster_is_the_map_of_the_local_pool(cluster: LocalCluster,
                                                         tmp_path: Path, capsys) -> None:
    on_cluster = _map(tmp_path / "cluster", "--cluster", cluster.scheduler_address)
    assert "on the Dask cluster at " in capsys.readouterr().err
    local = _map(tmp_path / "pool", "--workers", "2")
    assert set(on_cluster) == set(local) and "volume" in local
    for key in set(on_cluster) - {"meta"}:  # the command line differs, nothing else
        np.testing.assert_array_equal(on_cluster[key], local[key], err_msg=key)


def test_no_scheduler_is_one_clear_line() -> None:
    with pytest.raises(OSError, match=re.escape("no Dask scheduler answers at tcp://127.0.0.1:9")):
        batch.results(abs, [1, 2], batch.Where(cluster="tcp://127.0.0.1:9"))


def test_a_campaign_refuses_daemonic_workers_with_the_fix(tmp_path: Path, capsys) -> None:
    """Dask's default workers are daemons: each run refuses to run there, saying why.

    The controller of a run could not start the process that traces its soft limits
    there, and would run without them.
    """
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=None) as daemonic:
        status = campaign.main(["--runs", "1", "--modes", "blend", "--cluster",
                                daemonic.scheduler_address, "--out", str(tmp_path)])
    assert status == 1
    assert "DASK_DISTRIBUTED__WORKER__DAEMON=False" in capsys.readouterr().err


@pytest.mark.slow
def test_a_campaign_on_a_cluster_loses_nothing_when_a_worker_dies(
        cluster: LocalCluster, tmp_path: Path, capsys) -> None:
    """Two runs on two workers; one worker is killed (SIGKILL) while both run.

    Dask runs the lost run again on a worker (the killed one's nanny starts a new one);
    the campaign keeps both runs, each once, written by the client, with its recording.
    Each run's result is the one a local campaign with the same seeds gives.
    """
    with Client(cluster.scheduler_address) as client:
        pids = client.run(os.getpid)
    killed: list[int] = []

    def kill_one_while_running() -> None:
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline:  # both runs under way: a ROS graph each
            if all(_ros_threads(pid) for pid in pids.values()):
                time.sleep(2.0)
                victim = sorted(pids.values())[0]
                os.kill(victim, signal.SIGKILL)
                killed.append(victim)
                return
            time.sleep(0.2)

    killer = threading.Thread(target=kill_one_while_running, daemon=True)
    killer.start()
    status = campaign.main(["--runs", "1", "--modes", "blend", "--record",
                            "--cluster", cluster.scheduler_address,
                            "--first-domain", str(fresh_domain()), "--out", str(tmp_path)])
    killer.join(5.0)
    assert killed, "no worker was killed: the test did not happen"
    assert status == 0
    results = json.loads((tmp_path / "campaign.json").read_text())
    assert sorted((r["seed"], r["soft_limits"]) for r in results) == [(0, False), (0, True)]
    kept = sorted(p.name for p in (tmp_path / "runs").glob("*/*.json"))
    assert kept == ["0-blend-free.json", "0-blend-soft.json"]
    for path in (tmp_path / "runs").glob("*/*.json"):
        assert (path.with_suffix("") / "metadata.yaml").exists()  # the recording, here
    assert "2 runs in " in (tmp_path / "campaign.md").read_text()
    local = tmp_path / "local"
    assert campaign.main(["--runs", "1", "--modes", "blend", "--record", "--workers", "2",
                          "--first-domain", str(fresh_domain()), "--out", str(local)]) == 0
    assert json.loads((local / "campaign.json").read_text()) == results


def _ros_threads(pid: int) -> bool:
    """Whether process `pid` runs more than a handful of threads (a ROS graph's)."""
    try:
        return len(os.listdir(f"/proc/{pid}/task")) > 12
    except FileNotFoundError:
        return False
