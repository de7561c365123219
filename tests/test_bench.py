"""`make bench` runs and writes its table and JSON (numbers are not asserted: noisy machines)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from paths import REPO


def test_engine_benchmark_writes_its_outputs(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, str(REPO / "bench" / "engine_cycle.py"), "--out", str(tmp_path),
         "--configurations", "5", "--repeats", "1"],
        capture_output=True, text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    table = (tmp_path / "engine_cycle.md").read_text()
    assert "pink" in table and "ft engine blend" in table
    figures = json.loads((tmp_path / "engine_cycle.json").read_text())
    assert set(figures["results"]) >= {"ft engine least_norm", "ft engine blend"}
    assert all(r["median_us"] > 0 for r in figures["results"].values())
    assert figures["machine"]["cores"]


def test_selfmotion_benchmark_writes_its_outputs(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, str(REPO / "bench" / "selfmotion_trace.py"), "--out", str(tmp_path),
         "--repeats", "1"], capture_output=True, text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    figures = json.loads((tmp_path / "selfmotion_trace.json").read_text())["results"]
    assert {f["method"] for f in figures.values()} == {"curve", "extremal", "spiral"}
    assert all(f["median_s"] > 0 for f in figures.values())


def test_nodes_benchmark_writes_its_outputs(tmp_path: Path) -> None:
    session = os.environ["ROS_DOMAIN_ID"]  # parts A and B run one after the other
    env = {**os.environ, "FT_BENCH_DOMAIN": session, "FT_BENCH_DOMAIN_PROCESSES": session}
    result = subprocess.run(
        [sys.executable, str(REPO / "bench" / "nodes.py"), "--out", str(tmp_path),
         "--seconds", "2", "--memory-seconds", "2", "--repeats", "1"],
        capture_output=True, text=True, timeout=300, check=False, env=env)
    assert result.returncode == 0, result.stderr[-2000:]
    figures = json.loads((tmp_path / "nodes.json").read_text())
    runs = figures["one_process"]
    assert len(runs) == 4 and all(r["achieved_rate_hz"] > 0 and r["runs"] == 1
                                  for r in runs.values())
    assert runs["sim + controller + monitor, EventsExecutor"]["state_to_command_ms"]["samples"]
    assert set(figures["separate_processes"]["rss_kib_at_end"]) == {"sim", "controller",
                                                                    "monitor"}


def test_detection_benchmark_compares_both_detectors_on_the_same_data(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, str(REPO / "bench" / "detection.py"), "--out", str(tmp_path),
         "--healthy-seconds", "3", "--trials", "1"],
        capture_output=True, text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stderr[-2000:]
    figures = json.loads((tmp_path / "detection.json").read_text())
    assert set(figures["false_locks"]) == {"new", "old (fixed latency)"}
    new = figures["detection"]["new"]["0.2 rad/s"]
    assert new["trials"] == 12 and new["detected"] + new["missed"] + new["wrong"] == 12
    assert new["detected"] > 0 and new["p99_ms"] >= new["p50_ms"] > 0
    assert "| new | 0.2 rad/s |" in (tmp_path / "detection.md").read_text()


def test_observability_benchmark_writes_its_outputs(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, str(REPO / "bench" / "observability.py"), "--out", str(tmp_path),
         "--trials", "1"],
        capture_output=True, text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stderr[-2000:]
    figures = json.loads((tmp_path / "observability.json").read_text())
    assert figures["summary"]["trials"] == 1 and len(figures["trials"]) == 1
    latency, deviation = figures["trials"][0]
    assert latency is None or latency > 0
    assert 0 < deviation < 0.01
    assert "| trials | detected |" in (tmp_path / "observability.md").read_text()
