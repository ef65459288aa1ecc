"""Consultants: LTM with certainty thresholds, affirm/holds, run-time updates, ports."""

from __future__ import annotations

import math

import pytest

from fsreg_ros.core.consultant.consultant import AssertResult, Consultant, KnowledgeError
from fsreg_ros.core.consultant.local_port import LocalPort
from fsreg_ros.core.algorithms.port import Narrowed, run_sync
from fsreg_ros.core.forgetting.policies import ForgettingPolicy
from fsreg_ros.core.forgetting.wm_manager import WMManager

PREF = ["light-hair", "male", "glasses", "female", "hoodie"]


def keys(events):
    return [(e.op, e.entity, e.property, e.cause, e.time, e.turn) for e in events]


def make(policy="displacement", **params):
    events: list = []
    entities = {
        "f1": {"light-hair": 1.0, "male": 0.9, "glasses": 0.5},
        "f2": {"female": 1.0, "glasses": 0.49, "light-hair": 0.7},
        "f3": {"male": 1.0, "hoodie": 0.0},
    }
    c = Consultant("faces", entities, PREF, sink=events.append)
    params = params or ({"capacity": 5} if policy == "displacement" else {})
    WMManager().manage(c.wm, ForgettingPolicy.parse(policy, **params))
    return c, events


# -------------------------------------------------------------------- LTM
def test_threshold_semantics():
    c, _ = make()
    assert c.threshold == 0.5
    assert c.holds("glasses", ["f1", "f2", "f3"]) == ["f1"]  # 0.5 holds, 0.49 does not
    assert c.holds("hoodie", ["f1", "f2", "f3"]) == []  # listed with certainty 0
    assert c.certainty("f3", "glasses") == 0.0  # not listed: 0
    assert c.certainty("f1", "male") == 0.9
    assert c.properties_of("f1") == ["light-hair", "male", "glasses"]  # preference order
    assert c.properties_of("f2") == ["light-hair", "female"]
    assert c.holders("male") == {"f1", "f3"}


def test_holds_keeps_the_given_order_and_never_encodes():
    c, events = make()
    assert c.holds("male", ["f3", "f2", "f1"]) == ["f3", "f1"]
    assert c.holds("male", ("f1",)) == ["f1"]
    assert c.holds("male", iter(["f3"])) == ["f3"]
    assert events == [] and c.wm.snapshot() == {}


def test_affirm_encodes_each_holder_in_order():
    c, events = make()
    assert c.affirm("light-hair", ["f2", "f3", "f1"], "rr", 4.0, 2) == ["f2", "f1"]
    assert keys(events) == [
        ("encode", "f2", "light-hair", "rr", 4.0, 2),
        ("encode", "f1", "light-hair", "rr", 4.0, 2),
    ]
    assert c.wm.snapshot() == {"f2": ["light-hair"], "f1": ["light-hair"]}


def test_unknown_property_or_entity_is_an_error_and_changes_nothing():
    c, events = make()
    with pytest.raises(KnowledgeError, match="knows no property 'beard'"):
        c.holds("beard", ["f1"])
    with pytest.raises(KnowledgeError, match="has no entity 'f9'"):
        c.holds("male", ["f1", "f9"])
    with pytest.raises(KnowledgeError, match="has no entity 'f9'"):
        c.affirm("male", ["f1", "f9"], "rr", 0.0)
    with pytest.raises(KnowledgeError):
        c.certainty("f9", "male")
    with pytest.raises(KnowledgeError):
        c.properties_of("f9")
    with pytest.raises(KnowledgeError):
        c.holders("beard")
    assert events == [] and c.wm.snapshot() == {}
    assert c.knows_property("male") and not c.knows_property("beard")
    assert c.knows_entity("f1") and not c.knows_entity("f9")


@pytest.mark.parametrize(
    "entities, preference, threshold, message",
    [
        ({"a": {"p": 1.0}}, ["p", "p"], 0.5, "preference order lists a property twice"),
        ({"a": {"q": 1.0}}, ["p"], 0.5, "unknown property 'q'"),
        ({"a": {"p": 1.5}}, ["p"], 0.5, r"must be in \[0, 1\]"),
        ({"a": {"p": -0.1}}, ["p"], 0.5, r"must be in \[0, 1\]"),
        ({"a": {"p": True}}, ["p"], 0.5, "must be a number"),
        ({"a": {"p": "1"}}, ["p"], 0.5, "must be a number"),
        ({"a": {"p": math.nan}}, ["p"], 0.5, "must be a number"),
        ({"a": {"p": 1.0}}, ["p"], 1.5, r"threshold must be in \[0, 1\]"),
    ],
)
def test_constructor_validation(entities, preference, threshold, message):
    with pytest.raises(KnowledgeError, match=message):
        Consultant("d", entities, preference, threshold)


def test_custom_and_changed_threshold():
    c = Consultant("d", {"a": {"p": 0.3}, "b": {"p": 0.8}}, ["p"], threshold=0.25)
    assert c.holds("p", ["a", "b"]) == ["a", "b"]
    c.set_threshold(0.5)
    assert c.holds("p", ["a", "b"]) == ["b"]
    with pytest.raises(KnowledgeError):
        c.set_threshold(-1)
    assert c.threshold == 0.5


# --------------------------------------------------------- run-time updates
def test_assert_facts_updates_and_adds_entities():
    c, events = make()
    result = c.assert_facts("f3", {"glasses": 0.8}, 5.0)
    assert result == AssertResult("f3", False, {"glasses": 0.8}, [])
    assert c.holds("glasses", ["f1", "f2", "f3"]) == ["f1", "f3"]
    result = c.assert_facts("f4", {"hoodie": 1, "female": 0.6}, 6.0)
    assert result.new_entity and result.to_json() == {
        "entity": "f4",
        "new_entity": True,
        "updated": {"hoodie": 1.0, "female": 0.6},
        "retracted": [],
    }
    assert c.entities == ["f1", "f2", "f3", "f4"]  # a new entity joins last
    assert c.holds("female", ["f1", "f2", "f3", "f4"]) == ["f2", "f4"]
    assert events == []


def test_retraction_removes_the_property_from_wm():
    c, events = make()
    c.wm.encode("f1", ["light-hair", "male", "glasses"], "speaker", 1.0)
    events.clear()
    # certainty 0 retracts male; glasses drops below the threshold; light-hair stays.
    result = c.assert_facts("f1", {"male": 0, "glasses": 0.2, "light-hair": 0.6}, 9.0)
    assert result.retracted == ["male", "glasses"]  # preference order
    assert c.wm.queue("f1") == ("light-hair",)
    assert sorted(keys(events)) == [
        ("forget", "f1", "glasses", "retract", 9.0, None),
        ("forget", "f1", "male", "retract", 9.0, None),
    ]
    assert c.properties_of("f1") == ["light-hair"]
    assert c.certainty("f1", "male") == 0.0 and c.certainty("f1", "glasses") == 0.2


def test_retraction_of_a_property_not_in_wm_emits_nothing():
    c, events = make()
    result = c.assert_facts("f2", {"female": 0.0}, 3.0)
    assert result.retracted == ["female"]
    assert events == []


@pytest.mark.parametrize(
    "entity, facts, message",
    [
        ("f1", {"male": 0.0, "beard": 1.0}, "unknown property 'beard'"),
        ("f1", {"male": 0.0, "glasses": 2.0}, r"must be in \[0, 1\]"),
        ("f1", {"male": 0.0, "glasses": None}, "must be a number"),
        ("f1", {}, "non-empty mapping"),
        ("f1", ["male"], "non-empty mapping"),
        ("", {"male": 1.0}, "non-empty string"),
        (None, {"male": 1.0}, "non-empty string"),
        ("f9", {"hoodie": 1.0, "cape": 1.0}, "unknown property 'cape'"),
    ],
)
def test_assert_facts_is_atomic(entity, facts, message):
    c, events = make()
    c.wm.encode("f1", ["male"], "speaker", 0.0)
    events.clear()
    before = (list(c.entities), {e: c.properties_of(e) for e in c.entities}, c.wm.snapshot())
    with pytest.raises(KnowledgeError, match=message):
        c.assert_facts(entity, facts, 1.0)
    after = (list(c.entities), {e: c.properties_of(e) for e in c.entities}, c.wm.snapshot())
    assert after == before
    assert c.certainty("f1", "male") == 0.9
    assert events == []


# ------------------------------------------------------------------- ports
def test_local_port_answers_and_copies():
    c, events = make()
    port = LocalPort(c)
    assert port.domain == "faces"
    preference = run_sync(port.preference())
    preference.clear()
    assert run_sync(port.preference()) == PREF
    view = run_sync(port.open())
    assert view.size == 3 and view.queue == [] and view.retains
    # RR's narrowing: every member 'male' holds for is encoded, in entity order (rule 2)
    assert run_sync(port.narrow(view, "male", "rr", 1.0, 0)) == Narrowed(True, 2)
    assert run_sync(port.close(view)) == ["f1", "f3"]
    run_sync(port.encode("f2", ["female", "glasses"], "speaker", 1.0, 0))
    assert run_sync(port.wm("f2")) == ["female", "glasses"]
    assert run_sync(port.wm("f1")) == ["male"]
    assert len(events) == 4


def test_views_check_the_target_encode_distractors_and_close_with_rule_1():
    c, events = make()
    port = LocalPort(c)
    view = run_sync(port.open("f1"))  # distractors f2, f3
    assert (view.size, view.queue) == (2, [])
    # 'female' does not hold for the target: nothing is encoded or narrowed (rule 4)
    assert run_sync(port.narrow(view, "female", "reg-distractor", 1.0, 3)) == Narrowed(False, 2)
    assert events == []
    # 'male' holds for f1 and f3: encoded for f3 only (rule 3), f2 ruled out
    assert run_sync(port.narrow(view, "male", "reg-distractor", 1.0, 3)) == Narrowed(True, 1)
    assert [(e.entity, e.property, e.cause) for e in events] == [("f3", "male", "reg-distractor")]
    # a check without a cause encodes nothing
    assert run_sync(port.narrow(view, "glasses", None, 1.0, 3)) == Narrowed(True, 0)  # f3: no glasses
    assert len(events) == 1
    assert run_sync(port.close(view, ["male", "glasses"], 2.0, 3)) == []
    assert c.wm.queue("f1") == ("male", "glasses")
    # baselines: rule-out sets by member rank
    view = run_sync(port.open("f1", context=["f3", "f2", "f1"]))
    props, masks = run_sync(port.rule_out(view))
    assert props == ["light-hair", "male", "glasses"]
    assert masks == [0b10, 0b01, 0b11]  # members f2 (bit 0), f3 (bit 1)
    assert run_sync(port.close(view)) == ["f2", "f3"]
    # a view without a target encodes rule 1 for its only member, and refuses otherwise
    view = run_sync(port.open())
    with pytest.raises(KnowledgeError, match="3 members remain"):
        run_sync(port.close(view, ["male"], 3.0, 4))
    run_sync(port.narrow(view, "female", "rr", 3.0, 4))
    assert run_sync(port.close(view, ["female"], 3.0, 4)) == ["f2"]
    with pytest.raises(KnowledgeError, match="no entity 'f9'"):
        run_sync(port.open("f9"))
    with pytest.raises(KnowledgeError, match="unknown entities of domain 'faces': f9"):
        run_sync(port.open("f1", ["f2", "f9"]))


def test_local_port_rejects_unknown_entities():
    c, events = make()
    port = LocalPort(c)
    with pytest.raises(KnowledgeError, match="no entity 'f9'"):
        run_sync(port.wm("f9"))
    with pytest.raises(KnowledgeError, match="no entity 'f9'"):
        run_sync(port.encode("f9", ["male"], "speaker", 0.0, None))
    assert events == [] and c.wm.snapshot() == {}


def test_run_sync_refuses_a_coroutine_that_really_waits():
    class RealIO:  # an awaitable that suspends, as a service call would
        def __await__(self):
            yield None
            return 1

    async def waits():
        return await RealIO()

    with pytest.raises(RuntimeError, match="awaited real I/O"):
        run_sync(waits())

    async def immediate():
        return 42

    assert run_sync(immediate()) == 42


def test_raising_the_threshold_retracts_from_wm():
    from fsreg_ros.core.consultant.consultant import Consultant

    events = []
    c = Consultant("d", {"e1": {"a": 0.6, "b": 0.9}, "e2": {"a": 0.9}}, ["a", "b"], threshold=0.5, sink=events.append)
    c.wm.encode("e1", ["a", "b"], "speaker", 1.0)
    c.wm.encode("e2", ["a"], "speaker", 1.0)
    retracted = c.set_threshold(0.7, time=2.0)
    assert retracted == [("e1", "a")]
    assert c.wm.queue("e1") == ("b",) and c.wm.queue("e2") == ("a",)
    assert c.holds("a", ["e1", "e2"]) == ["e2"]
    assert [(e.op, e.entity, e.property, e.cause, e.time) for e in events[-1:]] == [
        ("forget", "e1", "a", "retract", 2.0)]


# ----------------------------------------------------------- exclusive properties
def guess_who(policy="decay", **params):
    """The Guess-Who board of scenarios/guess_who_table1.yaml, as the scenario's consultant."""
    from pathlib import Path

    from fsreg_ros.core.scenario import load_scenario

    root = Path(__file__).resolve().parents[2]
    events: list = []
    c = load_scenario(root / "scenarios" / "guess_who_table1.yaml").consultants(events.append)["faces"]
    WMManager().manage(c.wm, ForgettingPolicy.parse(policy, **(params or {"decay_period": 10.0})))
    return c, events


def test_asserting_no_glasses_retracts_glasses_from_ltm_and_wm():
    c, events = guess_who()
    c.wm.encode("face2", ["glasses", "female"], "speaker", 1.0)
    events.clear()
    result = c.assert_facts("face2", {"no-glasses": 1.0}, 5.0)
    assert result.to_json() == {"entity": "face2", "new_entity": False,
                                "updated": {"no-glasses": 1.0, "glasses": 0.0}, "retracted": ["glasses"]}
    assert c.properties_of("face2") == ["female", "dark-hair", "t-shirt", "no-glasses"]
    assert c.certainty("face2", "glasses") == 0.0 and c.certainty("face2", "no-glasses") == 1.0
    assert c.queue("face2") == ["female"]
    assert keys(events) == [("forget", "face2", "glasses", "retract", 5.0, None)]
    assert "face2" not in c.holders("glasses") and "face2" in c.holders("no-glasses")
    # asserting what already holds excludes nothing more; a group of three retracts the one held
    assert c.assert_facts("face2", {"no-glasses": 1.0}, 6.0).retracted == []
    result = c.assert_facts("face2", {"hoodie": 0.9}, 7.0)
    assert result.updated == {"hoodie": 0.9, "t-shirt": 0.0} and result.retracted == ["t-shirt"]


def test_an_exclusive_retraction_clears_a_fact_below_the_threshold_and_leaves_other_groups_alone():
    c = Consultant("faces", {"f1": {"glasses": 0.3, "male": 1.0}}, ["glasses", "no-glasses", "male", "female"],
                   exclusive=[["glasses", "no-glasses"], ["male", "female"]])
    result = c.assert_facts("f1", {"no-glasses": 0.8}, 1.0)
    assert result.updated == {"no-glasses": 0.8, "glasses": 0.0} and result.retracted == []  # glasses never held
    assert c.properties_of("f1") == ["no-glasses", "male"] and c.certainty("f1", "glasses") == 0.0
    # certainty 0 or below the threshold asserts nothing to hold: nothing is excluded
    assert c.assert_facts("f1", {"female": 0.4}, 2.0).updated == {"female": 0.4}
    assert c.properties_of("f1") == ["no-glasses", "male"]
    # a property named in the update keeps its given certainty
    assert c.assert_facts("f1", {"female": 1.0, "male": 0.2}, 3.0).updated == {"female": 1.0, "male": 0.2}


def test_attr_value_properties_exclude_each_other_by_default():
    c = Consultant("things", {"t1": {"colour=red": 1.0, "size=big": 1.0}},
                   ["colour=red", "colour=blue", "size=big", "shape"])
    assert c.excludes == {"colour=red": ("colour=blue",), "colour=blue": ("colour=red",)}  # size=big: a group of one
    result = c.assert_facts("t1", {"colour=blue": 1.0, "shape": 1.0}, 1.0)
    assert result.updated == {"colour=blue": 1.0, "shape": 1.0, "colour=red": 0.0}
    assert c.properties_of("t1") == ["colour=blue", "size=big", "shape"]


def test_two_exclusive_properties_asserted_together_are_refused_and_change_nothing():
    c, events = guess_who()
    c.wm.encode("face2", ["glasses"], "speaker", 1.0)
    events.clear()
    before = ({e: c.properties_of(e) for e in c.entities}, c.wm.snapshot(), c.version)
    with pytest.raises(KnowledgeError, match="'glasses' and 'no-glasses' exclude each other") as err:
        c.assert_facts("face2", {"glasses": 1.0, "no-glasses": 1.0}, 2.0)
    assert err.value.kind == "contradiction"
    with pytest.raises(KnowledgeError, match="exclude each other"):
        c.assert_facts("face99", {"male": 1.0, "female": 0.9}, 2.0)  # a new entity too
    assert ({e: c.properties_of(e) for e in c.entities}, c.wm.snapshot(), c.version) == before
    assert events == []


@pytest.mark.parametrize("groups, message", [
    ([["glasses"]], "at least two distinct properties"),
    ([["glasses", "glasses"]], "at least two distinct properties"),
    ([["glasses", "monocle"]], "unknown property 'monocle'"),
    ([["glasses", "male"], ["male", "female"]], "property 'male' of exclusive group 1 is already in group 0"),
])
def test_bad_exclusive_groups_are_refused(groups, message):
    with pytest.raises(KnowledgeError, match=message):
        Consultant("faces", {}, PREF, exclusive=groups)
