"""Forgetting policies and the WM Manager (docs/semantics.md sections 2 and 7, paper Algs. 2 and 3)."""

from __future__ import annotations

import math

import pytest

from fsreg_ros.core.consultant.consultant import Consultant
from fsreg_ros.core.forgetting.policies import (
    BOUNDS, NONE, ForgettingPolicy, PolicyError, check_parameter, merge_settings, parse_rules,
)
from fsreg_ros.core.memory import WMBuffer
from fsreg_ros.core.forgetting.wm_manager import WMManager


def keys(events):
    return [(e.op, e.entity, e.property, e.cause, e.time, e.turn) for e in events]


def managed(policy: ForgettingPolicy, now: float = 0.0):
    events: list = []
    buffer = WMBuffer("faces", events.append)
    manager = WMManager()
    manager.manage(buffer, policy, now)
    return manager, buffer, events


def forgets(events, cause=None):
    return [k for k in keys(events) if k[0] == "forget" and (cause is None or k[3] == cause)]


# ------------------------------------------------------------------ parsing
def test_parse_none_and_single_rules():
    none = ForgettingPolicy.parse("none")
    assert none.rules == () and none.name == "none" and not none.retains and not none.decays
    assert none == NONE
    assert none.to_json() == {"policy": "none"}
    decay = ForgettingPolicy.parse("decay", decay_period=10.0)
    assert decay.rules == ("decay",) and decay.decays and decay.retains
    assert decay.to_json() == {"policy": "decay", "decay_period": 10.0}


def test_parse_combined_rules_in_canonical_order():
    a = ForgettingPolicy.parse("displacement+decay", decay_period=10.0, capacity=2)
    b = ForgettingPolicy.parse(" decay + displacement ", decay_period=10.0, capacity=2)
    assert a == b
    assert a.rules == ("decay", "displacement") and a.name == "decay+displacement"
    assert a.to_json() == {"policy": "decay+displacement", "decay_period": 10.0, "capacity": 2}
    g = ForgettingPolicy.parse("global-capacity+displacement", capacity=2, global_capacity=6)
    assert g.rules == ("displacement", "global-capacity")
    assert parse_rules("decay+global-capacity") == ("decay", "global-capacity")


def test_unused_parameters_are_kept_but_not_reported():
    p = ForgettingPolicy.parse("displacement", decay_period=5.0, capacity=3)
    assert p.value("decay_period") == 5.0
    assert p.to_json() == {"policy": "displacement", "capacity": 3}


@pytest.mark.parametrize(
    "policy, params, message",
    [
        ("forgetful", {}, "unknown forgetting rule 'forgetful'"),
        ("decay+lru", {"decay_period": 1.0}, "unknown forgetting rule 'lru'"),
        ("none+decay", {"decay_period": 1.0}, "unknown forgetting rule 'none'"),
        ("decay+decay", {"decay_period": 1.0}, "names a rule twice"),
        ("displacement+decay+displacement", {"decay_period": 1.0, "capacity": 1}, "names a rule twice"),
        ("", {}, "non-empty string"),
        ("   ", {}, "non-empty string"),
        ("decay", {}, "needs 'decay_period'"),
        ("displacement", {}, "needs 'capacity'"),
        ("global-capacity", {}, "needs 'global_capacity'"),
        ("decay+displacement", {"decay_period": 1.0}, "needs 'capacity'"),
        ("decay", {"decay_period": 0.0}, "decay_period must be > 0"),
        ("decay", {"decay_period": -3.0}, "decay_period must be > 0"),
        ("decay", {"decay_period": math.inf}, "decay_period must be a number"),
        ("decay", {"decay_period": math.nan}, "decay_period must be a number"),
        ("decay", {"decay_period": "10"}, "decay_period must be a number"),
        ("decay", {"decay_period": True}, "decay_period must be a number"),
        ("displacement", {"capacity": 0}, "capacity must be >= 1"),
        ("displacement", {"capacity": -1}, "capacity must be >= 1"),
        ("displacement", {"capacity": True}, "capacity must be a whole number"),
        ("displacement", {"capacity": 2.0}, "capacity must be a whole number"),
        ("global-capacity", {"global_capacity": 0}, "global_capacity must be >= 1"),
        ("global-capacity", {"global_capacity": False}, "global_capacity must be a whole number"),
        # Parameters are validated even when the policy does not use them.
        ("none", {"capacity": 0}, "capacity must be >= 1"),
        # Bounds (BOUNDS): CPU below, float exactness and ROS Duration above.
        ("decay", {"decay_period": 0.001}, "decay_period must be >= 0.01 seconds"),
        ("decay", {"decay_period": 1e300}, "decay_period must be <= 1e[+]06 seconds"),
        ("displacement", {"capacity": 10_001}, "capacity must be <= 10000"),
        ("global-capacity", {"global_capacity": 10**6 + 1}, "global_capacity must be <= 1000000,"),
        ("displacement-random", {"capacity": 1, "seed": -1}, "seed must be >= 0"),
        ("displacement+displacement-lfu", {"capacity": 1}, "choose one displacement rule"),
    ],
)
def test_parse_errors(policy, params, message):
    with pytest.raises(PolicyError, match=message):
        ForgettingPolicy.parse(policy, **params)


def test_bounds_are_inclusive_and_shared():
    for name, (low, high) in BOUNDS.items():
        check_parameter(name, low)
        check_parameter(name, high)
    with pytest.raises(PolicyError, match="unknown memory setting 'speed'"):
        check_parameter("speed", 1)


def test_new_rules_report_their_parameters():
    p = ForgettingPolicy.parse("displacement-random+similarity", capacity=2)
    assert p.to_json() == {"policy": "displacement-random+similarity", "capacity": 2, "seed": 0}
    assert p.limits().victim == "random" and p.limits().similarity and p.limits().seed == 0
    lfu = ForgettingPolicy.parse("displacement-lfu", capacity=3, seed=5)
    assert lfu.to_json() == {"policy": "displacement-lfu", "capacity": 3}
    assert lfu.settings() == {"policy": "displacement-lfu", "capacity": 3, "seed": 5}
    assert ForgettingPolicy.from_settings(lfu.settings()) == lfu
    with pytest.raises(PolicyError, match="unknown memory setting 'speed'"):
        ForgettingPolicy.from_settings({"policy": "none", "speed": 1})


def test_policy_error_is_a_value_error():
    assert issubclass(PolicyError, ValueError)
    with pytest.raises(ValueError):
        ForgettingPolicy.parse(None)  # type: ignore[arg-type]


def test_with_changes_validates():
    p = ForgettingPolicy.parse("decay", decay_period=10.0)
    q = p.with_changes(policy="decay+displacement", capacity=3)
    assert q.rules == ("decay", "displacement") and q.value("capacity") == 3 and q.value("decay_period") == 10.0
    assert p.rules == ("decay",)  # frozen original unchanged
    with pytest.raises(PolicyError, match="needs 'capacity'"):
        p.with_changes(policy="displacement")
    with pytest.raises(PolicyError, match="decay_period must be > 0"):
        p.with_changes(decay_period=0.0)


def test_merge_settings_layers_key_by_key():
    top = {"policy": "decay", "decay_period": 10, "capacity": 2}
    own = {"policy": "displacement"}
    assert merge_settings(top, own) == ForgettingPolicy.parse("displacement", decay_period=10.0, capacity=2)
    period = merge_settings(top).value("decay_period")
    assert period == 10.0 and isinstance(period, float)
    cli = {"policy": "decay+displacement", "decay_period": 4.0, "capacity": None}
    merged = merge_settings(top, own, cli)
    assert merged.rules == ("decay", "displacement")
    assert merged.value("decay_period") == 4.0 and merged.value("capacity") == 2
    assert merge_settings() == NONE
    assert merge_settings(None, {}) == NONE
    with pytest.raises(PolicyError, match="needs 'decay_period'"):
        merge_settings({"policy": "decay"})


# ------------------------------------------------------ displacement (Alg. 3)
def test_displacement_keeps_queue_at_capacity_lru_out():
    _, buffer, events = managed(ForgettingPolicy.parse("displacement", capacity=2))
    buffer.encode("f1", ["a", "b", "c", "d"], "rr", 1.0, 0)
    assert buffer.queue("f1") == ("c", "d")
    assert keys(events) == [
        ("encode", "f1", "a", "rr", 1.0, 0),
        ("encode", "f1", "b", "rr", 1.0, 0),
        ("encode", "f1", "c", "rr", 1.0, 0),
        ("forget", "f1", "a", "displacement", 1.0, 0),
        ("encode", "f1", "d", "rr", 1.0, 0),
        ("forget", "f1", "b", "displacement", 1.0, 0),
    ]


def test_displacement_reencoding_protects_a_property():
    _, buffer, events = managed(ForgettingPolicy.parse("displacement", capacity=2))
    buffer.encode("f1", ["a", "b"], "rr", 0.0)
    buffer.encode("f1", ["a"], "speaker", 1.0)  # a becomes MRU: b is now LRU
    buffer.encode("f1", ["c"], "speaker", 2.0)
    assert buffer.queue("f1") == ("a", "c")
    assert forgets(events) == [("forget", "f1", "b", "displacement", 2.0, None)]


def test_displacement_is_per_entity():
    _, buffer, _ = managed(ForgettingPolicy.parse("displacement", capacity=1))
    buffer.encode_each(["f1", "f2", "f3"], "a", "rr", 0.0)
    buffer.encode_each(["f1", "f3"], "b", "rr", 0.0)
    assert buffer.snapshot() == {"f1": ["b"], "f2": ["a"], "f3": ["b"]}


# --------------------------------------------------------- global capacity
def test_global_capacity_evicts_globally_oldest_front():
    _, buffer, events = managed(ForgettingPolicy.parse("global-capacity", global_capacity=2))
    buffer.encode("f1", ["x"], "rr", 0.0)  # stamp 1
    buffer.encode("f2", ["y"], "rr", 0.0)  # stamp 2
    buffer.encode("f1", ["x"], "rr", 1.0)  # x refreshed: stamp 3, f2's y is now oldest
    buffer.encode("f3", ["w"], "rr", 2.0, 5)  # stamp 4 -> 3 > 2
    assert buffer.snapshot() == {"f1": ["x"], "f3": ["w"]}
    assert forgets(events) == [("forget", "f2", "y", "global-capacity", 2.0, 5)]
    assert len(buffer) == 2


def test_global_capacity_victim_can_be_the_queue_just_encoded():
    _, buffer, events = managed(ForgettingPolicy.parse("global-capacity", global_capacity=2))
    buffer.encode("f1", ["x"], "rr", 0.0)  # stamp 1
    buffer.encode("f2", ["y"], "rr", 0.0)  # stamp 2
    buffer.encode("f1", ["z"], "rr", 1.0)  # stamp 3: oldest front is f1's x
    assert buffer.snapshot() == {"f1": ["z"], "f2": ["y"]}
    assert forgets(events) == [("forget", "f1", "x", "global-capacity", 1.0, None)]


def test_global_capacity_with_encode_each_matches_order_of_events():
    _, buffer, events = managed(ForgettingPolicy.parse("global-capacity", global_capacity=2))
    buffer.encode_each(["a", "b", "c"], "p", "reg-distractor", 3.0, 1)
    assert buffer.snapshot() == {"b": ["p"], "c": ["p"]}
    assert keys(events) == [
        ("encode", "a", "p", "reg-distractor", 3.0, 1),
        ("encode", "b", "p", "reg-distractor", 3.0, 1),
        ("encode", "c", "p", "reg-distractor", 3.0, 1),
        ("forget", "a", "p", "global-capacity", 3.0, 1),
    ]


# ----------------------------------------------------------------- combos
def test_displacement_applies_before_global_capacity():
    policy = ForgettingPolicy.parse("displacement+global-capacity", capacity=2, global_capacity=3)
    _, buffer, events = managed(policy)
    buffer.encode("f1", ["p", "q"], "rr", 0.0)
    buffer.encode("f2", ["r"], "rr", 0.0)
    buffer.encode("f1", ["s"], "rr", 1.0)
    # Displacement first drops f1's p; the domain then holds 3, within the global limit.
    # (Global first would have dropped the same p but with cause global-capacity.)
    assert buffer.snapshot() == {"f1": ["q", "s"], "f2": ["r"]}
    assert forgets(events) == [("forget", "f1", "p", "displacement", 1.0, None)]
    buffer.encode("f3", ["t"], "rr", 2.0)
    assert forgets(events)[1:] == [("forget", "f1", "q", "global-capacity", 2.0, None)]


def test_decay_plus_displacement():
    manager, buffer, events = managed(ForgettingPolicy.parse("decay+displacement", decay_period=10.0, capacity=2))
    buffer.encode("f1", ["a", "b", "c"], "rr", 1.0)
    assert buffer.queue("f1") == ("b", "c")
    manager.advance(10.0)
    assert buffer.queue("f1") == ("c",)
    assert forgets(events) == [
        ("forget", "f1", "a", "displacement", 1.0, None),
        ("forget", "f1", "b", "decay", 10.0, None),
    ]


# -------------------------------------------------------------- WM Manager
def test_manager_applies_decay_ticks_at_k_delta_from_zero():
    manager, buffer, events = managed(ForgettingPolicy.parse("decay", decay_period=10.0))
    buffer.encode("f1", ["a", "b", "c"], "rr", 8.0)
    manager.advance(9.0)
    assert buffer.queue("f1") == ("a", "b", "c")
    manager.advance(25.0)
    assert buffer.queue("f1") == ("c",)
    assert [(k[2], k[4]) for k in forgets(events, "decay")] == [("a", 10.0), ("b", 20.0)]


def test_tick_at_an_events_time_applies_before_the_event():
    manager, buffer, _ = managed(ForgettingPolicy.parse("decay", decay_period=10.0))
    buffer.encode("f1", ["old"], "rr", 5.0)
    manager.advance(10.0)  # the tick at 10 comes first ...
    buffer.encode("f1", ["new"], "speaker", 10.0)  # ... then the event stamped 10
    assert buffer.queue("f1") == ("new",)
    manager.advance(10.0)  # asking again at the same time applies nothing twice
    assert buffer.queue("f1") == ("new",)


def test_lazy_decay_events_have_tick_times_through_the_manager():
    manager, buffer, events = managed(ForgettingPolicy.parse("decay", decay_period=10.0))
    buffer.encode("f1", ["a", "b", "c"], "rr", 1.0)
    buffer.encode("f2", ["d", "e"], "rr", 1.0)
    manager.advance(35.0)  # three ticks, nothing touched since
    assert forgets(events) == []  # lazy: nothing materialised yet ...
    assert buffer.snapshot() == {}  # ... until read
    decay = forgets(events, "decay")
    assert sorted((k[1], k[2], k[4]) for k in decay) == [
        ("f1", "a", 10.0),
        ("f1", "b", 20.0),
        ("f1", "c", 30.0),
        ("f2", "d", 10.0),
        ("f2", "e", 20.0),
    ]
    assert all(k[5] is None for k in decay)


def test_manage_later_does_not_owe_earlier_ticks():
    manager, buffer, events = managed(ForgettingPolicy.parse("decay", decay_period=10.0), now=25.0)
    buffer.encode("f1", ["a"], "rr", 25.0)
    manager.advance(29.99)
    assert buffer.queue("f1") == ("a",)
    manager.advance(30.0)  # the schedule still counts from t = 0
    assert buffer.queue("f1") == ()
    assert forgets(events) == [("forget", "f1", "a", "decay", 30.0, None)]


def test_new_decay_period_restarts_the_schedule():
    manager, buffer, events = managed(ForgettingPolicy.parse("decay", decay_period=10.0))
    buffer.encode("f1", ["a", "b", "c"], "rr", 1.0)
    manager.advance(25.0)  # ticks at 10, 20
    manager.set_policy("faces", ForgettingPolicy.parse("decay", decay_period=4.0), 25.0)
    manager.advance(28.9)  # neither 28 (multiple of 4) nor 30 (old schedule)
    assert buffer.queue("f1") == ("c",)
    manager.advance(29.0)
    assert buffer.queue("f1") == ()
    assert [k[4] for k in forgets(events, "decay")] == [10.0, 20.0, 29.0]


def test_same_period_keeps_the_schedule():
    manager, buffer, _ = managed(ForgettingPolicy.parse("decay", decay_period=10.0))
    buffer.encode("f1", ["a", "b", "c"], "rr", 1.0)
    manager.advance(25.0)
    manager.set_policy("faces", ForgettingPolicy.parse("decay+displacement", decay_period=10.0, capacity=5), 25.0)
    manager.advance(29.9)
    assert buffer.queue("f1") == ("c",)
    manager.advance(30.0)
    assert buffer.queue("f1") == ()


def test_lowering_capacity_trims_at_once():
    manager, buffer, events = managed(ForgettingPolicy.parse("displacement", capacity=4))
    buffer.encode("f1", ["a", "b", "c", "d"], "rr", 0.0)
    buffer.encode("f2", ["e", "f"], "rr", 0.0)
    manager.set_policy("faces", ForgettingPolicy.parse("displacement", capacity=1), 7.0)
    assert buffer.snapshot() == {"f1": ["d"], "f2": ["f"]}
    assert sorted(forgets(events)) == sorted(
        [
            ("forget", "f1", "a", "displacement", 7.0, None),
            ("forget", "f1", "b", "displacement", 7.0, None),
            ("forget", "f1", "c", "displacement", 7.0, None),
            ("forget", "f2", "e", "displacement", 7.0, None),
        ]
    )


def test_switching_to_global_capacity_trims_globally_oldest():
    manager, buffer, events = managed(ForgettingPolicy.parse("decay", decay_period=100.0))
    buffer.encode("f1", ["a", "b"], "rr", 0.0)
    buffer.encode("f2", ["c"], "rr", 0.0)
    buffer.encode("f1", ["d"], "rr", 0.0)
    manager.set_policy("faces", ForgettingPolicy.parse("global-capacity", global_capacity=2), 3.0)
    assert buffer.snapshot() == {"f1": ["d"], "f2": ["c"]}
    assert forgets(events) == [
        ("forget", "f1", "a", "global-capacity", 3.0, None),
        ("forget", "f1", "b", "global-capacity", 3.0, None),
    ]
    assert manager.domains["faces"].schedule is None


def test_switching_to_none_resets_and_stops_retaining():
    manager, buffer, events = managed(ForgettingPolicy.parse("decay", decay_period=10.0))
    buffer.encode("f1", ["a", "b"], "rr", 1.0)
    buffer.encode("f2", ["c"], "rr", 1.0)
    manager.advance(12.0)  # one tick owed lazily: it is applied (at 10) before the reset
    manager.set_policy("faces", NONE, 12.0)
    assert buffer.snapshot() == {}
    assert sorted(forgets(events)) == sorted(
        [
            ("forget", "f1", "a", "decay", 10.0, None),
            ("forget", "f2", "c", "decay", 10.0, None),
            ("forget", "f1", "b", "reset", 12.0, None),
        ]
    )
    events.clear()
    buffer.encode("f1", ["x"], "speaker", 13.0)
    assert buffer.snapshot() == {} and events == []
    assert manager.effective() == {"faces": {"policy": "none"}}


def test_set_policy_rejects_invalid_policy_and_keeps_the_old_one():
    manager, _, _ = managed(ForgettingPolicy.parse("displacement", capacity=2))
    bad = ForgettingPolicy(("displacement",), capacity=0)
    with pytest.raises(PolicyError):
        manager.set_policy("faces", bad, 1.0)
    assert manager.policies["faces"].value("capacity") == 2


def test_domains_are_independent_pools():
    manager = WMManager()
    a, b = WMBuffer("faces"), WMBuffer("objects")
    manager.manage(a, ForgettingPolicy.parse("decay", decay_period=10.0))
    manager.manage(b, ForgettingPolicy.parse("displacement", capacity=1))
    a.encode("f1", ["x", "y"], "rr", 0.0)
    b.encode("o1", ["x", "y"], "rr", 0.0)
    manager.advance(10.0)
    assert a.queue("f1") == ("y",)
    assert b.queue("o1") == ("y",)
    manager.advance(50.0)
    assert a.queue("f1") == () and b.queue("o1") == ("y",)
    assert manager.effective() == {
        "faces": {"policy": "decay", "decay_period": 10.0},
        "objects": {"policy": "displacement", "capacity": 1},
    }


# ------------------------------------------------------------ new rules (issue 12)
def test_lfu_displaces_the_least_frequently_encoded_ties_to_lru():
    _, buffer, events = managed(ForgettingPolicy.parse("displacement-lfu", capacity=2))
    buffer.encode("f1", ["a", "a", "b", "c"], "rr", 1.0)  # a twice, b once: c displaces b
    assert buffer.queue("f1") == ("a", "c")
    buffer.encode("f1", ["d"], "rr", 2.0)  # c once (LRU among the once-encoded): out
    assert buffer.queue("f1") == ("a", "d")
    assert forgets(events) == [("forget", "f1", "b", "displacement", 1.0, None),
                               ("forget", "f1", "c", "displacement", 2.0, None)]


def test_random_displacement_is_seeded_and_reproducible():
    def run(seed):
        _, buffer, events = managed(ForgettingPolicy.parse("displacement-random", capacity=2, seed=seed))
        for i in range(30):
            buffer.encode(f"f{i % 3}", [f"p{i % 7}"], "rr", float(i))
        return keys(events)

    assert run(1) == run(1)
    assert run(1) != run(2)
    _, buffer, _ = managed(ForgettingPolicy.parse("displacement-random", capacity=1, seed=0))
    buffer.encode("f1", ["a", "b"], "rr", 0.0)
    assert buffer.queue("f1") == ("b",)  # never the property just encoded


def test_similarity_displaces_other_values_of_the_attribute():
    _, buffer, events = managed(ForgettingPolicy.parse("similarity"))
    buffer.encode("f1", ["colour=red", "size=big", "glasses", "colour=blue"], "speaker", 1.0)
    assert buffer.queue("f1") == ("size=big", "glasses", "colour=blue")
    assert forgets(events) == [("forget", "f1", "colour=red", "similarity", 1.0, None)]
    declared = WMBuffer("faces", attributes={"light-hair": "hair", "dark-hair": "hair"})
    WMManager().manage(declared, ForgettingPolicy.parse("similarity"))
    declared.encode("f1", ["light-hair", "glasses", "dark-hair"], "speaker", 1.0)
    assert declared.queue("f1") == ("glasses", "dark-hair")
    consultant = Consultant("faces", {"f1": {"light-hair": 1.0}}, ["light-hair", "dark-hair"],
                            attributes={"light-hair": "hair", "dark-hair": "hair"})
    assert consultant.wm.attributes == {"light-hair": "hair", "dark-hair": "hair"}
