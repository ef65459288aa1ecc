"""WMBuffer: Encode (Algorithm 1), reads, lazy decay ticks, events (docs/semantics.md section 2)."""

from __future__ import annotations

import pytest

from fsreg_ros.core.forgetting import ForgettingPolicy
from fsreg_ros.core.decay import TickRun
from fsreg_ros.core.memory import ENCODE_CAUSES, FORGET_CAUSES, UNLIMITED, WMBuffer, WMEvent


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
        "decay", "displacement", "similarity", "global-capacity", "shared-capacity", "reset", "retract"
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
