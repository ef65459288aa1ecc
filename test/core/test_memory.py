"""WMBuffer: Encode (Algorithm 1), reads, lazy decay ticks, events (docs/semantics.md section 2)."""

from __future__ import annotations

import pytest

from fsreg_ros.core.forgetting.policies import ForgettingPolicy
from fsreg_ros.core.memory import changes
from fsreg_ros.core.memory.ticks import TickRun
from fsreg_ros.core.memory import (
    ENCODE_CAUSES, FORGET_CAUSES, UNKNOWN_ORIGIN, UNLIMITED, QueueItem, WMBuffer, WMEvent,
)


def ticks(*times: float) -> TickRun:
    """Consecutive ticks on the 10 s grid, e.g. ticks(20.0, 30.0)."""
    return TickRun(0.0, 10.0, int(times[0] // 10), len(times))


def keys(events):
    return [(e.op, e.entity, e.property, e.cause, e.time, e.turn) for e in events]


@pytest.fixture
def buf():
    events: list[WMEvent] = []
    buffer = WMBuffer("faces", events.append)
    buffer.events = events  # type: ignore[attr-defined]  # test convenience
    return buffer


# ---------------------------------------------------------------- Encode
def test_encode_pushes_in_order_one_event_per_push(buf):
    buf.encode("f1", ["a", "b", "c"], "speaker", 3.0, 7)
    assert buf.queue("f1") == ("a", "b", "c")
    assert keys(buf.events) == [
        ("encode", "f1", "a", "speaker", 3.0, 7),
        ("encode", "f1", "b", "speaker", 3.0, 7),
        ("encode", "f1", "c", "speaker", 3.0, 7),
    ]
    assert all(e.domain == "faces" for e in buf.events)


def test_encode_moves_existing_property_to_the_back(buf):
    buf.encode("f1", ["a", "b", "c"], "rr", 0.0)
    buf.events.clear()
    buf.encode("f1", ["a"], "speaker", 1.0)
    assert buf.queue("f1") == ("b", "c", "a")
    # Moving is a single encoding event, not a forget plus an encode.
    assert keys(buf.events) == [("encode", "f1", "a", "speaker", 1.0, None)]
    assert len(buf) == 3


def test_encode_of_a_repeated_property_within_one_call(buf):
    buf.encode("f1", ["a", "b", "a"], "speaker", 0.0)
    assert buf.queue("f1") == ("b", "a")
    assert [e.property for e in buf.events] == ["a", "b", "a"]


def test_encode_each_is_encode_per_entity_in_order():
    ev1: list = []
    ev2: list = []
    policy = ForgettingPolicy.parse("displacement+global-capacity", capacity=2, global_capacity=4)
    b1, b2 = WMBuffer("d", ev1.append), WMBuffer("d", ev2.append)
    b1.set_limits(policy.limits(), 0.0)
    b2.set_limits(policy.limits(), 0.0)
    for prop in ["p", "q", "r", "p"]:
        b1.encode_each(["x", "y", "z"], prop, "rr", 1.0, 2)
        for entity in ["x", "y", "z"]:
            b2.encode(entity, [prop], "rr", 1.0, 2)
    assert ev1 == ev2
    assert b1.snapshot() == b2.snapshot()
    assert len(b1) == 4


def test_queues_are_per_entity_and_independent(buf):
    buf.encode("f1", ["a", "b"], "rr", 0.0)
    buf.encode("f2", ["b"], "rr", 0.0)
    assert buf.queue("f1") == ("a", "b")
    assert buf.queue("f2") == ("b",)
    assert buf.queue("never") == ()
    assert buf.length("never") == 0
    assert buf.snapshot() == {"f1": ["a", "b"], "f2": ["b"]}
    assert buf.nonempty_entities() == ["f1", "f2"]


def test_stamps_increase_across_the_domain(buf):
    buf.encode("f1", ["a"], "rr", 0.0)
    buf.encode("f2", ["b"], "rr", 0.0)
    buf.encode("f1", ["c"], "rr", 0.0)
    assert buf.front_stamp("f1") < buf.front_stamp("f2")
    buf.encode("f1", ["a"], "rr", 0.0)  # re-encoding refreshes a's stamp: front is now c
    assert buf.queue("f1") == ("c", "a")
    assert buf.front_stamp("f1") > buf.front_stamp("f2")


# ----------------------------------------------------------------- reads
def test_reads_never_refresh_recency(buf):
    buf.encode("f1", ["a", "b", "c"], "rr", 0.0)
    for _ in range(3):
        assert buf.queue("f1") == ("a", "b", "c")
        assert buf.length("f1") == 3
        buf.snapshot()
    buf.decay(ticks(10.0))
    assert buf.queue("f1") == ("b", "c")  # "a" is still the LRU one despite the reads
    assert [e.op for e in buf.events].count("encode") == 3


# ----------------------------------------------------------------- decay
def test_decay_tick_pops_the_front_of_every_nonempty_queue(buf):
    buf.encode("f1", ["a", "b"], "rr", 0.0)
    buf.encode("f2", ["c"], "rr", 0.0)
    buf.encode("f3", ["d", "e", "f"], "rr", 0.0)
    buf.events.clear()
    buf.decay(ticks(10.0))
    assert buf.snapshot() == {"f1": ["b"], "f3": ["e", "f"]}
    assert sorted(keys(buf.events)) == sorted(
        [
            ("forget", "f1", "a", "decay", 10.0, None),
            ("forget", "f2", "c", "decay", 10.0, None),
            ("forget", "f3", "d", "decay", 10.0, None),
        ]
    )


def test_more_ticks_than_properties_empty_the_queue(buf):
    buf.encode("f1", ["a", "b"], "rr", 0.0)
    buf.decay(ticks(10.0, 20.0, 30.0, 40.0))
    assert buf.queue("f1") == ()
    assert len(buf) == 0
    assert keys(buf.events)[2:] == [
        ("forget", "f1", "a", "decay", 10.0, None),
        ("forget", "f1", "b", "decay", 20.0, None),
    ]


def test_lazy_decay_events_carry_the_tick_times(buf):
    buf.encode("f1", ["a", "b", "c"], "rr", 0.0)
    buf.decay(ticks(10.0))
    buf.decay(ticks(20.0))
    # Nothing touched f1 until now; its catch-up reports each tick's own time.
    buf.encode("f1", ["d"], "speaker", 25.0, 4)
    assert keys(buf.events)[3:] == [
        ("forget", "f1", "a", "decay", 10.0, None),
        ("forget", "f1", "b", "decay", 20.0, None),
        ("encode", "f1", "d", "speaker", 25.0, 4),
    ]
    assert buf.queue("f1") == ("c", "d")


def test_tick_before_a_queue_exists_does_not_touch_it_later(buf):
    buf.encode("f1", ["a"], "rr", 0.0)
    buf.decay(ticks(10.0))
    buf.encode("f2", ["x", "y"], "rr", 11.0)  # f2 was empty at the tick
    buf.encode("f1", ["b"], "rr", 12.0)  # f1's "a" went at 10, "b" is new
    assert buf.snapshot() == {"f2": ["x", "y"], "f1": ["b"]}
    buf.decay(ticks(20.0))
    assert buf.snapshot() == {"f2": ["y"]}


def test_queue_emptied_then_refilled_between_ticks(buf):
    buf.encode("f1", ["a"], "rr", 0.0)
    buf.decay(ticks(10.0))
    assert buf.queue("f1") == ()
    buf.encode("f1", ["b", "c"], "rr", 12.0)
    buf.decay(ticks(20.0))
    assert buf.queue("f1") == ("c",)


def test_tick_times_stay_right_across_flushes(buf):
    buf.encode("f1", ["a", "b", "c"], "rr", 0.0)
    buf.encode("f2", ["x"], "rr", 0.0)
    buf.decay(ticks(10.0))
    assert buf.snapshot() == {"f1": ["b", "c"]}  # flush: f2 emptied at 10
    buf.decay(ticks(20.0, 30.0))
    buf.encode("f2", ["y"], "rr", 31.0)  # f2 was empty through 20 and 30
    buf.decay(ticks(40.0))
    assert len(buf) == 0  # flush again
    buf.decay(ticks(50.0))
    buf.encode("f1", ["d"], "rr", 51.0)
    decay = [(k[1], k[2], k[4]) for k in keys(buf.events) if k[3] == "decay"]
    assert sorted(decay) == [
        ("f1", "a", 10.0),
        ("f1", "b", 20.0),
        ("f1", "c", 30.0),
        ("f2", "x", 10.0),
        ("f2", "y", 40.0),
    ]
    assert buf.snapshot() == {"f1": ["d"]}


def test_len_counts_after_owed_decay(buf):
    buf.encode("f1", ["a", "b"], "rr", 0.0)
    buf.encode("f2", ["c"], "rr", 0.0)
    buf.decay(ticks(10.0))
    assert len(buf) == 1
    assert buf.nonempty_entities() == ["f1"]


# ------------------------------------------------------- other forgetting
def test_pop_front_remove_and_clear(buf):
    buf.encode("f1", ["a", "b", "c"], "rr", 0.0)
    buf.encode("f2", ["d"], "rr", 0.0)
    buf.events.clear()
    assert buf.pop_front("f1", "displacement", 1.0, 3) == "a"
    assert buf.pop_front("nobody", "displacement", 1.0) is None
    assert buf.remove("f1", "c", "retract", 2.0) is True
    assert buf.remove("f1", "c", "retract", 2.0) is False
    assert buf.remove("f1", "zzz", "retract", 2.0) is False
    assert buf.queue("f1") == ("b",)
    buf.clear("reset", 5.0)
    assert buf.snapshot() == {}
    assert len(buf) == 0
    assert keys(buf.events) == [
        ("forget", "f1", "a", "displacement", 1.0, 3),
        ("forget", "f1", "c", "retract", 2.0, None),
        ("forget", "f1", "b", "reset", 5.0, None),
        ("forget", "f2", "d", "reset", 5.0, None),
    ]


def test_policy_none_stores_nothing_and_emits_nothing(buf):
    buf.set_limits(ForgettingPolicy.parse("none").limits(), 0.0)
    assert not buf.retains
    buf.encode("f1", ["a", "b"], "speaker", 0.0)
    buf.encode_each(["f1", "f2"], "a", "rr", 0.0)
    assert buf.queue("f1") == ()
    assert buf.snapshot() == {}
    assert buf.events == []


def test_unmanaged_buffer_keeps_everything(buf):
    assert buf.limits == UNLIMITED and buf.retains
    buf.encode("f1", [f"p{i}" for i in range(50)], "rr", 0.0)
    assert buf.length("f1") == 50


def test_no_sink_is_fine():
    buffer = WMBuffer("d")
    buffer.set_limits(ForgettingPolicy.parse("displacement", capacity=1).limits(), 0.0)
    buffer.encode("x", ["a", "b"], "rr", 0.0)
    buffer.encode_each(["x", "y"], "c", "rr", 0.0)
    buffer.decay(TickRun.single(1.0))
    assert buffer.snapshot() == {}


def test_event_json_and_causes():
    event = WMEvent("forget", "faces", "f1", "glasses", "decay", 10.0, None)
    assert event.to_json() == {
        "op": "forget",
        "domain": "faces",
        "entity": "f1",
        "property": "glasses",
        "cause": "decay",
        "time": 10.0,
        "turn": None,
    }
    assert set(ENCODE_CAUSES) == {"speaker", "rr", "reg-distractor"}
    assert set(FORGET_CAUSES) == {
        "decay", "activation", "displacement", "similarity", "global-capacity", "shared-capacity", "reset", "retract",
        "episodes",
    }


def test_hot_path_events_equal_constructed_ones(buf):
    buf.encode("f1", ["a"], "rr", 1.5, 2)
    made = WMEvent("encode", "faces", "f1", "a", "rr", 1.5, 2)
    assert buf.events == [made]
    assert hash(buf.events[0]) == hash(made)
    assert repr(buf.events[0]) == repr(made)
    assert buf.events[0].to_json()["property"] == "a"
    with pytest.raises(AttributeError):
        buf.events[0].cause = "x"  # type: ignore[misc]


# ------------------------------------------------------------- changes
def lru(capacity=None, global_capacity=None, rules="displacement"):
    return ForgettingPolicy.parse(rules, capacity=capacity, global_capacity=global_capacity).limits()


@pytest.mark.parametrize("sink", [True, False])
def test_take_changes_lists_changed_entities_in_first_change_order_and_resets(sink):
    buffer = WMBuffer("d", [].append if sink else None)
    buffer.set_limits(lru(capacity=2), 0.0)
    assert buffer.take_changes() == []
    buffer.encode_each(["b", "a", "b"], "p", "rr", 1.0, 1)  # quiet path without a sink
    buffer.encode("c", ["p", "q", "r"], "speaker", 1.0, 1)  # displaces c's p
    buffer.encode("a", ["p"], "speaker", 1.0, 1)  # a refresh is a change too
    assert buffer.take_changes() == ["b", "a", "c"]
    assert buffer.take_changes() == []
    buffer.queue("a"), buffer.snapshot(), buffer.origins("c"), buffer.export_queue("b")  # reads change nothing
    assert buffer.take_changes() == []
    assert buffer.remove("c", "q", "retract", 2.0) and not buffer.remove("c", "zzz", "retract", 2.0)
    assert buffer.pop_front("b", "displacement", 2.0) == "p"
    assert buffer.pop_front("nobody", "displacement", 2.0) is None
    assert buffer.take_changes() == ["c", "b"]
    buffer.clear("reset", 3.0)
    assert buffer.take_changes() == ["a", "c"]  # b was already empty


def test_lazy_decay_is_applied_and_reported_by_take_changes():
    buffer = WMBuffer("d")
    buffer.encode("e1", ["a", "b"], "rr", 0.0)
    buffer.encode("e2", ["c"], "rr", 0.0)
    buffer.encode("e3", ["d"], "rr", 0.0)
    buffer.take_changes()
    buffer.decay(ticks(10.0))
    buffer.encode("e3", ["x"], "rr", 11.0)  # catches up first: its pop and the encoding
    # e1 and e2 still owe the tick; take_changes applies it, so what a store saves from
    # export_queue and counters() is the whole state.
    assert buffer.take_changes() == ["e3", "e1", "e2"]
    assert [buffer.export_queue(e) for e in ("e1", "e2")] == [[("b", 2, 1, "rr", None)], []]
    assert buffer.counters() == (5, 1)
    buffer.decay(ticks(20.0))
    buffer.decay(ticks(30.0))
    assert buffer.queue("e3") == ()
    assert buffer.take_changes() == ["e3", "e1"]  # e2 was empty: nothing to pop


def test_decay_now_reports_popped_queues_in_canonical_order():
    buffer = WMBuffer("d")
    buffer.encode("e2", ["a", "b"], "rr", 0.0)
    buffer.encode("e1", ["c"], "rr", 0.0)
    buffer.encode("e3", ["d"], "rr", 0.0)
    buffer.remove("e3", "d", "retract", 0.0)
    buffer.take_changes()
    buffer.decay_now(TickRun(0.0, 10.0, 1, 3), ["e1", "e2", "e3"])
    assert buffer.take_changes() == ["e1", "e2"]  # e3 empty: not popped, not reported
    buffer.decay_now(TickRun(0.0, 10.0, 4, 1), ["e1", "e2", "e3"])
    assert buffer.take_changes() == []


def test_limits_report_what_they_trim():
    buffer = WMBuffer("d")
    buffer.encode("e1", ["a", "b", "c"], "rr", 0.0)
    buffer.encode("e2", ["a"], "rr", 0.0)
    buffer.encode("e3", ["a", "b"], "rr", 0.0)
    buffer.take_changes()
    buffer.set_limits(lru(capacity=1), 1.0)  # trims e1 and e3
    assert buffer.take_changes() == ["e1", "e3"]
    buffer.set_limits(lru(capacity=1, global_capacity=2, rules="displacement+global-capacity"), 2.0)
    assert buffer.take_changes() == ["e1"]  # e1's c is the oldest front
    buffer.encode("e4", ["z"], "rr", 3.0)  # the global limit forgets e2's a
    assert buffer.take_changes() == ["e4", "e2"]
    buffer.evict_oldest(1, "shared-capacity", 4.0)  # e3's b
    assert buffer.take_changes() == ["e3"]
    buffer.set_limits(ForgettingPolicy.parse("none").limits(), 5.0)
    assert buffer.take_changes() == ["e4"]
    assert len(buffer) == 0


def test_similarity_reports_the_entity_once():
    buffer = WMBuffer("d", attributes={"red": "colour", "blue": "colour"})
    buffer.set_limits(ForgettingPolicy.parse("similarity").limits(), 0.0)
    buffer.encode("e1", ["red", "x"], "rr", 0.0)
    buffer.encode("e2", ["y"], "rr", 0.0)
    buffer.take_changes()
    buffer.encode("e1", ["blue"], "speaker", 1.0)
    assert buffer.queue("e1") == ("x", "blue")
    assert buffer.take_changes() == ["e1"]


def test_new_limits_resetting_lfu_counts_are_a_change():
    buffer = WMBuffer("d")
    buffer.set_limits(ForgettingPolicy.parse("displacement-lfu", capacity=3).limits(), 0.0)
    buffer.encode("e1", ["a", "a"], "rr", 0.0, 1)
    buffer.encode("e2", ["a"], "rr", 0.0, 1)
    assert buffer.export_queue("e1")[0].hits == 2
    assert buffer.take_changes() == ["e1", "e2"]
    buffer.set_limits(ForgettingPolicy.parse("displacement", capacity=3).limits(), 1.0)
    assert buffer.export_queue("e1")[0].hits == 1
    assert buffer.take_changes() == ["e1"]  # e2's count was 1 already: its export is the same


def test_restore_records_nothing_and_clears_the_record():
    original = WMBuffer("d")
    original.encode("e1", ["a", "b"], "rr", 0.0, 1)
    stored = {"e1": original.export_queue("e1")}
    copy = WMBuffer("d")
    copy.encode("e9", ["z"], "rr", 0.0)
    copy.restore(stored, *original.counters(), UNLIMITED)
    assert copy.take_changes() == []
    assert copy.snapshot() == {"e1": ["a", "b"]}


# ------------------------------------------------------------- origins
@pytest.mark.parametrize("sink", [True, False])
def test_origin_is_the_encoding_that_made_the_property_enter(sink):
    buffer = WMBuffer("d", [].append if sink else None)
    buffer.set_limits(lru(capacity=2), 0.0)
    buffer.encode_each(["e1", "e2"], "a", "rr", 1.0, 0)
    buffer.encode("e1", ["b"], "reg-distractor", 2.0, 1)
    buffer.encode_each(["e1"], "a", "speaker", 3.0, 2)  # a refresh keeps rr, turn 0
    assert buffer.queue("e1") == ("b", "a")
    assert buffer.origins("e1") == [("reg-distractor", 1), ("rr", 0)]
    buffer.encode("e1", ["c"], "speaker", 4.0, 3)  # displaces b
    buffer.encode("e1", ["b"], "speaker", 5.0, 4)  # b enters again: a new origin; a is displaced
    assert buffer.queue("e1") == ("c", "b")
    assert buffer.origins("e1") == [("speaker", 3), ("speaker", 4)]
    assert buffer.origins("e2") == [("rr", 0)]
    assert buffer.origins("nobody") == []
    assert buffer.queue_with_origins("e1") == (("c", "b"), [("speaker", 3), ("speaker", 4)])  # one read, both
    assert buffer.queue_with_origins("nobody") == ((), [])
    assert buffer.export_queue("e1") == [("c", 5, 1, "speaker", 3), ("b", 6, 1, "speaker", 4)]
    item = buffer.export_queue("e2")[0]
    assert item == QueueItem("a", 2, 1, "rr", 0)
    assert (item.property, item.stamp, item.hits, item.cause, item.turn) == ("a", 2, 1, "rr", 0)
    assert item[:3] == ("a", 2, 1)  # the former (property, stamp, hits) tuple comes first


def test_origins_survive_a_round_trip_and_refreshes_after_it():
    buffer = WMBuffer("d")
    buffer.encode("e1", ["a", "b"], "speaker", 0.0, 7)
    buffer.encode("e2", ["a"], "rr", 0.0, None)
    copy = WMBuffer("d")
    copy.restore({e: buffer.export_queue(e) for e in ("e1", "e2")}, *buffer.counters(), UNLIMITED)
    assert copy.export_queue("e1") == buffer.export_queue("e1")
    assert copy.origins("e2") == [("rr", None)]
    copy.encode("e1", ["a"], "rr", 1.0, 8)  # refresh after restore: still the speaker's
    assert copy.origins("e1") == [("speaker", 7), ("speaker", 7)]
    assert copy.front_stamp("e1") == 2 and copy.export_queue("e1")[-1].stamp == 4


def test_restore_of_items_without_origins_and_of_bad_items():
    buffer = WMBuffer("d")
    buffer.restore({"e1": [("a", 3, 1)]}, 3, 0, UNLIMITED)  # a store that kept no origins
    assert buffer.origins("e1") == [UNKNOWN_ORIGIN]
    before = buffer.export_queue("e1")
    for bad in ([("a", 1)], [("a", 1, 1, 5, None)], [("a", 1, 1, "rr", "7")], [("a", 1, 1, "rr", True)]):
        with pytest.raises(ValueError, match="queue of 'e2': item"):
            buffer.restore({"e3": [("b", 1, 1, "rr", 1)], "e2": bad}, 9, 0, UNLIMITED)
        assert buffer.export_queue("e1") == before and buffer.counters() == (3, 0)  # nothing changed


def test_origin_log_stays_bounded_over_many_turns():
    buffer = WMBuffer("d")
    buffer.set_limits(lru(capacity=2), 0.0)
    for turn in range(20_000):
        buffer.encode_each([f"e{turn % 50}"], f"p{turn % 3}", ENCODE_CAUSES[turn % 3], float(turn), turn)
    assert len(buffer.origin_log.starts) <= 2_048  # one run per call would be 20,000
    expected = []  # e49's queue by hand: (property, origin), capacity 2
    for turn in range(20_000):
        if turn % 50 == 49:
            prop = f"p{turn % 3}"
            expected = [e for e in expected if e[0] != prop] + [(prop, (ENCODE_CAUSES[turn % 3], turn))]
            expected = expected[-2:]
    assert list(buffer.queue("e49")) == [p for p, _ in expected]
    assert buffer.origins("e49") == [o for _, o in expected]


def test_view_origins_parallel_to_the_queue():
    from fsreg_ros.core.consultant.consultant import Consultant
    from fsreg_ros.core.consultant.views import open_view

    consultant = Consultant("d", {"x": {"a": 1.0, "b": 1.0}, "y": {"a": 1.0}}, ["a", "b"])
    consultant.encode("x", ["b"], "speaker", 0.0, 0)
    consultant.wm.encode_each(["x", "y"], "a", "rr", 1.0, 1)
    view = open_view(consultant, "x", None)
    assert view.queue == ["b", "a"] and view.origins == [("speaker", 0), ("rr", 1)]
    assert open_view(consultant, None, None).origins == []


# ------------------------------------------------------------- column queues
def column_buffer(sink=None, capacity=2):
    buffer = WMBuffer("d", sink)
    buffer.column_min = 1  # column queues however small the domain
    buffer.set_limits(ForgettingPolicy.parse("decay+displacement", decay_period=10.0, capacity=capacity).limits(), 0)
    return buffer


NAMES = ["e0", "e1", "e2", "e3"]


def test_encode_members_with_column_queues_is_encode_each_in_entity_order():
    columns, plain = column_buffer(), WMBuffer("d")
    plain.set_limits(columns.limits, 0.0)
    for prop, members, turn in [("a", 0b1011, 1), ("b", 0b0011, 2), ("a", 0b0110, 3), ("c", 0b1111, 4)]:
        columns.encode_members(members, NAMES, prop, "rr", 1.0, turn)
        plain.encode_each([e for i, e in enumerate(NAMES) if members >> i & 1], prop, "rr", 1.0, turn)
    assert columns.columns.entities == set(NAMES)  # the queues live in the columns
    assert [columns.export_queue(e) for e in NAMES] == [plain.export_queue(e) for e in NAMES]
    assert columns.snapshot() == plain.snapshot() and len(columns) == len(plain) == 8
    assert columns.counters() == plain.counters()
    assert columns.take_changes() == plain.take_changes() == NAMES[:2] + ["e3", "e2"]
    assert columns.origins("e1") == [("rr", 1), ("rr", 4)]  # a refreshed in turn 3 kept turn 1
    assert columns.columns.entities == set(NAMES)  # reads leave them there


def test_column_queue_owing_decay_reports_its_pops_once_a_sink_listens():
    events: list = []
    buffer = column_buffer()
    buffer.encode_members(0b0011, NAMES, "a", "rr", 1.0, 1)
    buffer.encode_members(0b0001, NAMES, "b", "rr", 1.0, 1)
    buffer.decay(TickRun(0.0, 10.0, 1, 1))  # lazily: owed by the column queues
    buffer.sink = events.append
    assert buffer.queue("e0") == ("b",)  # the read applies e0's tick and reports it
    assert keys(events) == [("forget", "e0", "a", "decay", 10.0, None)]
    assert len(buffer) == 1  # e1's tick too
    assert keys(events)[1:] == [("forget", "e1", "a", "decay", 10.0, None)]
    assert buffer.take_changes() == ["e0", "e1"]


def test_column_queues_come_back_as_dicts_when_another_path_needs_them():
    events: list = []
    buffer = column_buffer(capacity=3)
    buffer.encode_members(0b0111, NAMES, "a", "rr", 1.0, 1)
    buffer.encode_members(0b0101, NAMES, "b", "reg-distractor", 2.0, 2)
    buffer.sink = events.append
    buffer.encode("e0", ["c", "a"], "speaker", 3.0, 3)  # rule 1, with events: a dict queue again
    assert "e0" not in buffer.columns.entities
    assert buffer.export_queue("e0") == [("b", 4, 1, "reg-distractor", 2), ("c", 6, 1, "speaker", 3),
                                         ("a", 7, 1, "rr", 1)]
    buffer.set_limits(ForgettingPolicy.parse("displacement", capacity=1).limits(), 4.0)  # all become dicts
    assert buffer.columns.entities == set() and buffer.snapshot() == {"e0": ["a"], "e1": ["a"], "e2": ["b"]}
    assert [k[2] for k in keys(events) if k[3] == "displacement"] == ["b", "c", "a"]


def test_column_queues_restore_and_round_trip():
    buffer = column_buffer()
    buffer.restore({"e1": [("x", 3, 1, "speaker", 0), ("y", 4, 1)]}, 4, 0, buffer.limits)
    buffer.encode_members(0b0011, NAMES, "x", "rr", 1.0, 1)  # e1's x: a refresh, origin kept
    assert buffer.columns.entities == {"e0", "e1"}
    assert buffer.export_queue("e1") == [("y", 4, 1, "unknown", None), ("x", 6, 1, "speaker", 0)]
    assert buffer.export_queue("e0") == [("x", 5, 1, "rr", 1)]
    copy = column_buffer()
    copy.restore({e: buffer.export_queue(e) for e in buffer.nonempty_entities()}, *buffer.counters(), buffer.limits)
    assert copy.snapshot() == buffer.snapshot() == {"e0": ["x"], "e1": ["y", "x"]}


def test_columns_only_for_large_domains_and_the_bound_entity_list():
    buffer = WMBuffer("d")
    buffer.set_limits(ForgettingPolicy.parse("displacement", capacity=2).limits(), 0.0)
    buffer.encode_members(0b11, NAMES, "a", "rr", 0.0)
    assert buffer.columns.entities == set()  # four entities: queue by queue
    buffer.column_min = 1
    buffer.encode_members(0b11, NAMES, "b", "rr", 0.0)
    assert buffer.columns.entities == {"e0", "e1"}
    buffer.encode_members(0b100, list(NAMES), "c", "rr", 0.0)  # another list: queue by queue
    assert buffer.columns.entities == {"e0", "e1"} and buffer.queue("e2") == ("c",)
    NAMES_GROWN = NAMES + ["e4"]
    grown = WMBuffer("d")
    grown.column_min = 1
    grown.set_limits(buffer.limits, 0.0)
    entities = list(NAMES)
    grown.encode_members(0b1, entities, "a", "rr", 0.0)
    entities.append("e4")  # the domain grows (a new entity joins last)
    grown.encode_members(0b10001, entities, "b", "rr", 0.0)
    assert grown.snapshot() == {"e0": ["a", "b"], "e4": ["b"]} and entities == NAMES_GROWN


def test_restored_queue_longer_than_the_columns_goes_queue_by_queue():
    stored = {"e0": [("x", 1, 1, "rr", 0), ("y", 2, 1, "rr", 0), ("z", 3, 1, "rr", 0)]}
    buffer, plain = column_buffer(capacity=2), column_buffer(capacity=2)
    for b in (buffer, plain):  # stored under a larger capacity (restore does not trim)
        b.restore(stored, 3, 0, b.limits)
    buffer.encode_members(0b0011, NAMES, "a", "rr", 1.0, 1)
    plain.encode_each(["e0", "e1"], "a", "rr", 1.0, 1)
    assert buffer.columns.entities == set()  # nothing moved: e0 does not fit in two slots
    assert [buffer.export_queue(e) for e in NAMES] == [plain.export_queue(e) for e in NAMES]


def test_change_record_keeps_its_order_when_compacted(monkeypatch):
    monkeypatch.setattr(changes, "CHANGE_MARKS_MAX", 2)
    buffer = column_buffer(capacity=3)
    for members, prop in [(0b1000, "a"), (0b0001, "b"), (0b0110, "c"), (0b1001, "d"), (0b0100, "e")]:
        buffer.encode_members(members, NAMES, prop, "rr", 1.0, 1)
    buffer.encode("e1", ["f"], "speaker", 2.0, 2)  # by name, between column operations
    buffer.encode_members(0b0010, NAMES, "g", "rr", 3.0, 3)
    assert buffer.changes.marks <= 2
    assert buffer.take_changes() == ["e3", "e0", "e1", "e2"]
    assert buffer.take_changes() == []
