"""Decay time (core/memory/ticks.py): the schedule, tick runs and the lazy-decay ledger."""

from __future__ import annotations

import math

import pytest

from fsreg_ros.core.memory.ticks import MAX_TIME, TIME_EPSILON, DecaySchedule, TickError, TickLedger, TickRun


def times(run):
    return [] if run is None else [run.time(i) for i in range(run.count)]


def test_schedule_is_idempotent():
    schedule = DecaySchedule(10.0)
    assert schedule.take(9.99) is None
    assert times(schedule.take(10.0)) == [10.0]
    assert schedule.take(10.0) is None
    assert schedule.take(15.0) is None
    assert schedule.next_tick() == 20.0
    assert times(schedule.take(35.0)) == [20.0, 30.0]
    assert schedule.take(20.0) is None  # asking about the past never re-applies


def test_jump_over_many_periods_is_one_run():
    schedule = DecaySchedule(2.5)
    run = schedule.take(1000.0)
    assert run == TickRun(0.0, 2.5, 1, 400)
    assert times(run) == [k * 2.5 for k in range(1, 401)]


def test_clock_far_ahead_costs_o1_and_decay_goes_on():
    schedule = DecaySchedule(0.01)
    run = schedule.take(1e9)
    assert run.count == 10**11 and run.first == 1
    assert schedule.next_tick() == pytest.approx(1e9 + 0.01)
    assert times(schedule.take(1e9 + 0.02)) == pytest.approx([1e9 + 0.01, 1e9 + 0.02])


def test_slack_of_one_nanosecond():
    assert times(DecaySchedule(10.0).take(10.0 - 0.5 * TIME_EPSILON)) == [10.0]
    assert DecaySchedule(10.0).take(10.0 - 10 * TIME_EPSILON) is None
    # 3 * 0.1 = 0.30000000000000004 > 0.3, but within the slack: three ticks at t = 0.3.
    assert times(DecaySchedule(0.1).take(0.3)) == [0.1, 0.2, 3 * 0.1]


@pytest.mark.parametrize("period, now, count", [(0.1, 567.899999999, 5679), (0.3, 9253.199999998998, 30844)])
def test_schedule_uses_the_spec_test_literally(period, now, count):
    # k * delta <= T + 1e-9 holds for k = count, although floor((T + 1e-9) / delta)
    # rounds down to count - 1 for these values (issue 9's disagreement).
    assert count * period <= now + TIME_EPSILON
    assert math.floor((now + TIME_EPSILON) / period) == count - 1
    run = DecaySchedule(period).take(now)
    assert run.count == count and run.last == count * period


def test_restart_and_origin():
    schedule = DecaySchedule(10.0)
    assert times(schedule.take(25.0)) == [10.0, 20.0]
    schedule.restart(4.0, 25.0)
    assert schedule.next_tick() == 29.0
    assert schedule.take(28.9) is None
    assert times(schedule.take(37.0)) == [29.0, 33.0, 37.0]
    started = DecaySchedule(10.0, origin=1.7e9)
    assert started.take(1.7e9 + 0.04) is None  # the grid starts at the origin, not at the epoch
    assert times(started.take(1.7e9 + 10.0)) == [1.7e9 + 10.0]


@pytest.mark.parametrize("bad", [math.inf, -math.inf, math.nan, 1e308, 2 * MAX_TIME, "1", True])
def test_unusable_times_are_refused(bad):
    schedule = DecaySchedule(1.0)
    with pytest.raises(TickError):
        schedule.take(bad)
    assert schedule.applied == 0


def test_tick_run_json_round_trip_and_validation():
    run = TickRun(0.0, 0.1, 5, 3)
    assert TickRun.from_json(run.to_json()) == run
    assert run.tail(1) == TickRun(0.0, 0.1, 6, 2) and run.tail(3) is None
    assert TickRun.single(4.5).last == 4.5
    for bad, message in [
        ([1.0, 2.0], "exactly origin"),
        ({"origin": 0.0, "period": 0.0, "first": 1, "count": 1}, "period must be > 0"),
        ({"origin": 0.0, "period": 1.0, "first": 1, "count": 0}, "count must be >= 1"),
        ({"origin": 0.0, "period": 1.0, "first": -1, "count": 1}, "first must be a whole number"),
        ({"origin": 0.0, "period": 1.0, "first": 10**400, "count": 1}, "first must be a whole number"),
        ({"origin": 1e999, "period": 1.0, "first": 1, "count": 1}, "origin must be finite"),
        ({"origin": 0.0, "period": 1e11, "first": 1, "count": 100}, "out of range"),
    ]:
        with pytest.raises(TickError, match=message):
            TickRun.from_json(bad)


def test_ledger_memory_grows_with_schedule_changes_not_ticks():
    ledger = TickLedger()
    schedule = DecaySchedule(0.01)
    for step in range(1, 1001):
        ledger.add(schedule.take(step * 0.05))
    assert ledger.count == 5000
    assert len(ledger._runs) == 1  # consecutive runs merge
    assert ledger.time(0) == 0.01 and ledger.time(4999) == pytest.approx(50.0)
    schedule.restart(1.0, 50.0)
    ledger.add(schedule.take(52.0))
    assert len(ledger._runs) == 2 and ledger.time(5001) == 52.0
    ledger.drop_before(5000)
    assert len(ledger._runs) == 1 and ledger.time(5000) == 51.0


def test_bounds_keep_tick_indices_exact():
    from fsreg_ros.core.forgetting.policies import MIN_DECAY_PERIOD

    assert MAX_TIME / MIN_DECAY_PERIOD < 2**53  # k * delta computed from an exact k
