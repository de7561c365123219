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


def test_the_loop_rate_is_measured_over_a_span_not_between_two_close_calls() -> None:
    """A diagnostics timer catching up after a hold calls twice within milliseconds."""
    accounting = loop.LoopAccounting(period=0.004)
    assert accounting.rate(10.0) == 0.0  # the first call: nothing measured yet
    for _ in range(125):
        accounting.start()
        accounting.end()
    assert accounting.rate(10.5) == pytest.approx(250.0)  # 125 cycles in 0.5 s
    assert accounting.rate(10.502) == pytest.approx(250.0)  # no cycle since: not a stop
    for _ in range(50):
        accounting.start()
        accounting.end()
    assert accounting.rate(10.5 + loop.RATE_SPAN) == pytest.approx(50 / loop.RATE_SPAN)
    assert accounting.rate(11.5) == 0.0  # a whole second without a cycle: stopped
    assert accounting.rate(5.0) == 0.0  # time went back: measured anew from there


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


def test_a_state_schedule_passes_a_jittery_stream_and_thins_a_fast_one() -> None:
    period = 1_000_000  # 1 kHz, ns
    jitter = [0, 400_000, -600_000, 700_000, -300_000, 0, 650_000, -700_000]
    schedule = loop.StateSchedule(period)
    ran = 0
    for k, shift in enumerate(jitter * 25):  # 200 states at the control rate, jittered
        if schedule.ready(k * period + shift):
            schedule.ran(k * period + shift)
            ran += 1
    assert ran == 200, "states at the control rate within the slack lost cycles"
    # Three times the rate: the long-run rate is the control rate.
    schedule, ran = loop.StateSchedule(period), 0
    for k in range(3000):
        now = k * period // 3
        if schedule.ready(now):
            schedule.ran(now)
            ran += 1
    assert 999 <= ran <= 1002, ran
    # A burst of states at one instant: one cycle.
    schedule = loop.StateSchedule(period)
    assert [schedule.ready(5 * period) and (schedule.ran(5 * period) or True)
            for _ in range(5)] == [True, False, False, False, False]


def test_a_state_schedule_follows_a_pause_and_a_clock_that_went_back() -> None:
    period = 4_000_000
    schedule = loop.StateSchedule(period)
    assert schedule.quiet(0)
    schedule.ran(0)
    assert not schedule.quiet(period - 1) and schedule.quiet(period)
    # A pause of 10 periods, then the stream again: its phase, not the old slots'.
    schedule.ran(10 * period + 3_500_000)
    assert not schedule.ready(11 * period)  # 0.5 periods after: not yet
    assert schedule.ready(11 * period + 3_500_000)
    # The clock jumps back by a minute: the schedule starts again.
    back = -60 * 10**9
    assert schedule.ready(back) and schedule.quiet(back)
    schedule.ran(back)
    assert not schedule.ready(back + period // 10) and schedule.ready(back + period)
