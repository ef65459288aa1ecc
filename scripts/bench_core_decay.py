"""The decay benchmarks of ``scripts/bench_core.py`` (run that script; this module only holds them).

:func:`bench_decay`: the lazy decay tick of the real buffer under the real WM Manager
against the naive eager reference, over many mostly idle queues; :func:`bench_eager_decay`:
one eager tick (``decay_now``) after rule-3 bursts, column queues against dict queues.
Both check that the final state is the naive reference's.
"""

from __future__ import annotations

import gc
import random
import statistics
import time

from fsreg_ros.core.forgetting.policies import ForgettingPolicy
from fsreg_ros.core.forgetting.wm_manager import WMManager
from fsreg_ros.core.memory import WMBuffer
from naive_wm import NaiveWM

#: Share of the queues touched between two ticks (the rest stay idle).
IDLE_TOUCHED = 0.01


# ================================================================= decay
def bench_decay(n_queues: int, ticks: int, seed: int) -> dict:
    rng = random.Random(seed + n_queues)
    names = [f"e{i}" for i in range(n_queues)]
    initial = [f"p{j}" for j in range(ticks + 1)]
    extra = [f"x{j}" for j in range(8)]
    touched = max(1, int(n_queues * IDLE_TOUCHED))
    plan = [(rng.sample(names, touched), rng.choice(extra)) for _ in range(ticks)]

    # Lazy: the real buffer under the real WM Manager (decay every 1 s from t = 0).
    buffer = WMBuffer("d")
    manager = WMManager()
    manager.manage(buffer, ForgettingPolicy.parse("decay", decay_period=1.0))
    for prop in initial:
        buffer.encode_each(names, prop, "rr", 0.0)
    lazy_tick, lazy_touch = [], []
    gc.collect()
    for k, (sample, prop) in enumerate(plan, start=1):
        t = float(k)
        start = time.perf_counter()
        manager.advance(t)
        lazy_tick.append(time.perf_counter() - start)
        start = time.perf_counter()
        for name in sample:
            buffer.encode(name, (prop,), "rr", t + 0.5)
        lazy_touch.append(time.perf_counter() - start)
    start = time.perf_counter()
    buffer.flush()
    lazy_flush = time.perf_counter() - start
    lazy_state = buffer.snapshot()
    del buffer, manager
    gc.collect()

    # Naive eager reference on exactly the same plan.
    naive = NaiveWM({"decay"}, record=False)
    for name in names:
        naive.encode(name, initial, "rr", 0.0)
    naive_tick, naive_touch = [], []
    gc.collect()
    for k, (sample, prop) in enumerate(plan, start=1):
        t = float(k)
        start = time.perf_counter()
        naive.tick(t)
        naive_tick.append(time.perf_counter() - start)
        start = time.perf_counter()
        for name in sample:
            naive.encode(name, (prop,), "rr", t + 0.5)
        naive_touch.append(time.perf_counter() - start)
    same = naive.snapshot() == lazy_state
    del naive
    gc.collect()

    def us(values):
        return statistics.median(values) * 1e6

    lazy_cycle = [a + b for a, b in zip(lazy_tick, lazy_touch)]
    naive_cycle = [a + b for a, b in zip(naive_tick, naive_touch)]
    lazy_total = sum(lazy_cycle) + lazy_flush
    return {
        "queues": n_queues,
        "ticks": ticks,
        "touched_per_tick": touched,
        "lazy_tick_us": us(lazy_tick),
        "naive_tick_us": us(naive_tick),
        "tick_ratio": statistics.median(naive_tick) / statistics.median(lazy_tick),
        "lazy_cycle_us": us(lazy_cycle),
        "naive_cycle_us": us(naive_cycle),
        "cycle_ratio": statistics.median(naive_cycle) / statistics.median(lazy_cycle),
        "lazy_final_flush_us": lazy_flush * 1e6,
        "lazy_total_incl_flush_us": lazy_total * 1e6,
        "naive_total_us": sum(naive_cycle) * 1e6,
        "total_ratio_incl_flush": sum(naive_cycle) / lazy_total,
        "same_final_state": same,
    }


# ========================================================== eager decay
def bench_eager_decay(n_entities: int, ticks: int, burst: int, seed: int, policy: ForgettingPolicy) -> dict:
    """One eager decay tick (``decay_now``, as the consultant node applies it) over a domain after rule-3 bursts.

    Each cycle: two rule-3 encodings of a property into ``burst`` random members
    (``encode_members``, as ``Consultant.narrow`` calls it), a rule-1 description of one
    entity, then one tick timed.  Three buffers play the same plan in turn: column
    queues with no event sink (nobody listens), column queues reporting every pop to
    a sink, and dict queues (``column_min`` above the domain: how the buffer worked
    before column queues, and still works for a domain under ``memory.COLUMN_MIN``).
    The naive eager reference plays it too: every final state must be its.  ``policy``: the
    WM policy of the REG benchmark (decay+displacement).
    """
    from fsreg_ros.core.memory.bitset import from_indices
    from fsreg_ros.core.memory.ticks import TickRun

    rng = random.Random(seed + n_entities)
    names = [f"e{i}" for i in range(n_entities)]
    props = [f"p{j}" for j in range(12)]
    plan = [([from_indices(sorted(rng.sample(range(n_entities), burst)), n_entities) for _ in range(2)],
             [rng.choice(props) for _ in range(2)], rng.choice(names), rng.sample(props, 2)) for _ in range(ticks)]
    results: dict = {}
    states = {}
    for label, columns, sink in (("columns", True, False), ("columns+sink", True, True), ("dicts", False, False)):
        events: list = []
        buffer = WMBuffer("d", events.append if sink else None)
        # Column queues at any size (the default from memory.COLUMN_MIN entities on), or never.
        buffer.column_min = min(buffer.column_min, n_entities) if columns else n_entities + 1
        buffer.set_limits(policy.limits(), 0.0)
        times = []
        gc.collect()
        for k, (bursts, burst_props, target, said) in enumerate(plan, start=1):
            t = float(k)
            mute, buffer.sink = buffer.sink, None  # rule-3 bursts: nobody listens (the quiet path)
            for members, prop in zip(bursts, burst_props):
                buffer.encode_members(members, names, prop, "reg-distractor", t - 0.5, k)
            buffer.sink = mute
            buffer.encode(target, said, "speaker", t - 0.5, k)
            start = time.perf_counter()
            buffer.decay_now(TickRun(0.0, 1.0, k, 1), names)
            times.append(time.perf_counter() - start)
            events.clear()
        states[label] = buffer.snapshot()
        results[label] = {"median_ms": statistics.median(times) * 1e3, "max_ms": max(times) * 1e3,
                          "held": len(buffer), "in_columns": len(buffer.columns.entities)}
        del buffer
        gc.collect()
    naive = NaiveWM(policy.rules, policy.value("capacity"), record=False)
    for k, (bursts, burst_props, target, said) in enumerate(plan, start=1):
        for members, prop in zip(bursts, burst_props):
            for i in range(n_entities):
                if members >> i & 1:
                    naive.encode(names[i], [prop], "reg-distractor", k - 0.5, k)
        naive.encode(target, said, "speaker", k - 0.5, k)
        naive.tick(float(k))
    return {
        "entities": n_entities, "ticks": ticks, "burst": burst, "detail": results,
        **{f"{label}_ms": figures["median_ms"] for label, figures in results.items()},
        "dicts_over_columns": results["dicts"]["median_ms"] / results["columns"]["median_ms"],
        "same_final_state": all(state == naive.snapshot() for state in states.values()),
    }
