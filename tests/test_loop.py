"""ft_msgs_py.loop: compute times and missed cycles, on a controlled clock."""

from __future__ import annotations

import pytest
from ft_msgs_py import loop


def test_missed_cycles_and_compute_times(monkeypatch: pytest.MonkeyPatch) -> None:
    clock = iter([0.000, 0.001, 0.004, 0.005, 0.008, 0.0095,  # two cycles on time
                  0.020, 0.0215])  # 12 ms gap at 4 ms: two cycles missed
    monkeypatch.setattr(loop.time, "perf_counter", lambda: next(clock))
    accounting = loop.LoopAccounting(period=0.004)
    for _ in range(4):
        accounting.start()
        accounting.end()
    assert accounting.cycles == 4
    assert accounting.missed == 2
    assert accounting.compute_ms(50) == pytest.approx(1.25)
    assert accounting.compute_ms(100) == pytest.approx(1.5)


def test_simulated_time_counts_no_missed_cycles(monkeypatch: pytest.MonkeyPatch) -> None:
    clock = iter([0.0, 0.001, 10.0, 10.001])
    monkeypatch.setattr(loop.time, "perf_counter", lambda: next(clock))
    accounting = loop.LoopAccounting(period=0.004, count_missed=False)
    for _ in range(2):
        accounting.start()
        accounting.end()
    assert accounting.missed == 0
