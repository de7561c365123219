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


def test_a_late_cycle_within_its_period_is_not_missed(monkeypatch: pytest.MonkeyPatch) -> None:
    """Jitter is not a miss: rcl's timer keeps its schedule unless a whole period passes."""
    starts = [0.000, 0.0065, 0.008, 0.0125, 0.016, 0.0285, 0.0321]  # late 2.5 ms, then on time,
    clock = iter(t for start in starts for t in (start, start + 1e-4))  # one 8.5 ms late: 2
    monkeypatch.setattr(loop.time, "perf_counter", lambda: next(clock))
    accounting = loop.LoopAccounting(period=0.004)
    for _ in starts:
        accounting.start()
        accounting.end()
    assert accounting.missed == 2


def test_simulated_time_counts_no_missed_cycles(monkeypatch: pytest.MonkeyPatch) -> None:
    clock = iter([0.0, 0.001, 10.0, 10.001])
    monkeypatch.setattr(loop.time, "perf_counter", lambda: next(clock))
    accounting = loop.LoopAccounting(period=0.004, count_missed=False)
    for _ in range(2):
        accounting.start()
        accounting.end()
    assert accounting.missed == 0
