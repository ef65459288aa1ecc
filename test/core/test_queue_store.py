"""The queue store (core/memory/queues.py) keeps WM's counts itself; a side log hears every change (EntryWatcher)."""

from __future__ import annotations

from typing import Optional

import pytest

from fsreg_ros.core.memory import Limits, QueueStore, WMBuffer, WMEvent
from fsreg_ros.core.memory.ticks import TickRun

NAMES = [f"e{i}" for i in range(6)]


class Log:
    """An :class:`EntryWatcher` writing down what it hears, as event keys."""

    def __init__(self) -> None:
        self.heard: list[tuple] = []

    def encoded(self, entity: str, prop: str, cause: str, time: float, turn: Optional[int], present: bool) -> None:
        self.heard.append(("encode", entity, prop, cause, time))

    def forgot(self, entity: str, prop: str, cause: str, time: float) -> None:
        self.heard.append(("forget", entity, prop, cause, time))

    def sync(self, entity: str, q) -> None:
        return None

    def flush(self) -> None:
        return None


class Window(Log):
    """A forgetting rule written over the buffer's interface alone (no change to the store or the buffer).

    An entry stays while its last encoding is within ``span`` seconds of the latest encoding heard;
    evaluated lazily, when a queue is read or encoded into (``sync``) or WM is read whole (``flush``).
    """

    def __init__(self, wm: WMBuffer, span: float) -> None:
        super().__init__()
        self.wm, self.span, self.clock = wm, span, float("-inf")
        self.last: dict[tuple[str, str], float] = {}

    def encoded(self, entity: str, prop: str, cause: str, time: float, turn: Optional[int], present: bool) -> None:
        super().encoded(entity, prop, cause, time, turn, present)
        self.last[(entity, prop)] = time
        self.clock = max(self.clock, time)

    def forgot(self, entity: str, prop: str, cause: str, time: float) -> None:
        super().forgot(entity, prop, cause, time)
        del self.last[(entity, prop)]

    def sync(self, entity: str, q) -> None:
        for prop in [p for p in q if self.last[(entity, p)] < self.clock - self.span]:
            self.wm.forget_entry(entity, q, prop, "window", self.clock, None)

    def flush(self) -> None:
        for entity in self.wm.store.nonempty():
            q = self.wm.store.get(entity)
            if q:
                self.sync(entity, q)


def keys(events: list[WMEvent]) -> list[tuple]:
    return [(e.op, e.entity, e.property, e.cause, e.time) for e in events]


def script(b: WMBuffer, limits: Limits) -> None:
    """Every way a queue changes: rules 1-3, lazy and eager decay, activation, displacement, retraction, reset."""
    b.set_limits(limits, 0.0)
    b.encode("e0", ["a", "b", "colour=red"], "speaker", 1.0, 1)
    b.encode_members(0b111111, NAMES, "colour=green", "rr", 2.0, 2)
    b.encode_each(NAMES[:3], "size=big", "reg-distractor", 3.0, 3)
    b.encode("e0", ["a", "d"], "speaker", 4.0, 4)
    b.decay(TickRun(0.0, 10.0, 1, 1))
    assert b.queue("e0") is not None
    b.advance(12.0)
    b.encode_members(0b000110, NAMES, "size=small", "rr", 12.0, 5)
    b.decay_now(TickRun(0.0, 10.0, 2, 1), NAMES)
    b.remove("e1", "size=small", "retract", 21.0, 6)
    b.encode("e2", ["colour=blue", "e"], "speaker", 22.0, 7)
    b.evict_oldest(1, "shared-capacity", 23.0)
    b.advance(40.0)
    b.set_limits(Limits(capacity=1), 41.0)
    b.clear("reset", 50.0, 8)


LIMITS = [
    Limits(),
    Limits(capacity=2),
    Limits(capacity=2, victim="lfu"),
    Limits(capacity=3, similarity=True),
    Limits(global_capacity=5),
    Limits(activation=(0.5, -1.0)),
    Limits(capacity=2, activation=(0.5, -1.0)),
]


@pytest.mark.parametrize("limits", LIMITS, ids=repr)
@pytest.mark.parametrize("column_min", [1, 10**9])
def test_a_watcher_hears_every_encoding_and_forgetting_as_a_sink_does(limits, column_min):
    """A side log attached with ``watch`` hears what an event sink hears, in the same order, whatever the cause.

    Without a sink, attaching it turns the quiet and column paths off (a domain of at least
    ``column_min`` entities would otherwise keep its queues in columns and report nothing), and the
    buffer holds what a quiet one does.
    """
    events: list[WMEvent] = []
    told = WMBuffer("d", events.append)
    watched, quiet = WMBuffer("d"), WMBuffer("d")
    log = Log()
    watched.watch(log)
    for b in (told, watched, quiet):
        b.column_min = column_min
        script(b, limits)
    assert log.heard == keys(events)
    assert {op for op, *_ in log.heard} == {"encode", "forget"} and len(log.heard) > 20
    assert watched.counters() == quiet.counters() == told.counters()


def test_a_watcher_moves_column_queues_back_to_dicts():
    b = WMBuffer("d")
    b.column_min = 1
    b.set_limits(Limits(capacity=2), 0.0)
    b.encode_members(0b111, NAMES[:3], "a", "rr", 1.0, 1)
    assert b.columns.entities == {"e0", "e1", "e2"}
    log = Log()
    b.watch(log)
    assert b.columns.entities == set() and b.snapshot() == {"e0": ["a"], "e1": ["a"], "e2": ["a"]}
    b.encode("e1", ["b", "c"], "speaker", 2.0, 2)
    assert log.heard == [("encode", "e1", "b", "speaker", 2.0), ("encode", "e1", "c", "speaker", 2.0),
                         ("forget", "e1", "a", "displacement", 2.0)]


def test_the_store_keeps_size_non_empty_set_and_stamps():
    store = QueueStore()
    q = store.new("x", synced=0)
    assert (store.size, store.stamp, store.nonempty()) == (0, 0, [])
    assert store.put("x", q, "a") is False and store.put("x", q, "b") is False
    assert store.put("x", q, "a") is True  # a refresh: same size, keeps the entry's origin (stamp 1)
    assert (store.size, store.stamp, store.nonempty(), list(q.items())) == (2, 3, ["x"], [("b", 2), ("a", (3, 1))])
    y = store.new("y", synced=0)
    store.put("y", y, "c")
    store.remove("x", q, "b")
    assert (store.size, store.nonempty()) == (2, ["x", "y"])
    assert store.drop_fronts("x", q, 5) == 1 and q.synced == 5  # five owed ticks, one entry: it goes
    assert (store.size, store.nonempty(), dict(q)) == (1, ["y"], {})
    assert store.take_fronts("y", y, 1) == ["c"] and (store.size, store.nonempty()) == (0, [])


def test_a_rule_plugs_in_as_a_watcher_and_forgets_lazily():
    b = WMBuffer("d")
    window = Window(b, 5.0)
    b.watch(window)
    b.encode("e0", ["a"], "speaker", 0.0, 1)
    b.encode("e1", ["b"], "speaker", 1.0, 2)
    b.encode("e0", ["c"], "speaker", 7.0, 3)  # e0 was brought up to the clock before (then 1.0): a stays
    assert window.heard[-1] == ("encode", "e0", "c", "speaker", 7.0)
    assert b.queue("e0") == ("c",)  # read: a, encoded at 0.0, is more than 5 s before 7.0
    assert window.heard[-1] == ("forget", "e0", "a", "window", 7.0)
    assert b.snapshot() == {"e0": ["c"]} and len(b) == 1  # read whole: e1's b (1.0) went too
    assert b.take_changes() == ["e0", "e1"]
