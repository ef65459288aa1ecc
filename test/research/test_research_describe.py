"""The one-call generation API (core/simulation/describe.py) and the one-value-per-attribute rule."""

import pytest

from fsreg_ros.core.consultant.consultant import Consultant
from fsreg_ros.core.simulation.describe import describe, expand_order, knowledge_base
from fsreg_ros.core.algorithms.generation import GenerationError
from fsreg_ros.core.memory import attribute_of

BOARD = {
    "t": {"type": "chair", "colour": "red", "orientation": "front", "size": "large"},
    "d1": {"type": "chair", "colour": "blue", "orientation": "front", "size": "small"},
    "d2": {"type": "chair", "colour": "red", "orientation": "back", "size": "small"},
    "d3": {"type": "desk", "colour": "red", "orientation": "front", "size": "large"},
}


def test_attribute_of():
    # REG's one-value-per-attribute rule (own=True): a plain name is its own attribute.
    assert attribute_of("colour=red", own=True) == "colour"
    assert attribute_of("glasses", own=True) == "glasses"
    assert attribute_of("light-hair", {"light-hair": "hair-colour"}, own=True) == "hair-colour"
    # Similarity interference (the default): a plain name has none, so it interferes with nothing.
    assert attribute_of("colour=red") == "colour" and attribute_of("colour=red", {}) == "colour"
    assert attribute_of("glasses") is None and attribute_of("glasses", {"other": "x"}) is None
    assert attribute_of("light-hair", {"light-hair": "hair-colour"}) == "hair-colour"


def test_expand_order_lists_values_of_named_attributes():
    props = ["type=chair", "colour=red", "colour=blue", "size=large"]
    assert expand_order(["colour", "type"], props) == ["colour=red", "colour=blue", "type=chair"]
    assert expand_order(["size=large", "colour"], props) == ["size=large", "colour=red", "colour=blue"]


@pytest.mark.parametrize(
    "algorithm, expected",
    [
        ("dist-pia", ["type=chair", "colour=red", "orientation=front"]),
        ("full-brevity", ["type=chair", "size=large"]),
        ("greedy", ["type=chair", "size=large"]),
        ("sd-pia", ["type=chair", "colour=red", "orientation=front"]),
    ],
)
def test_forced_head_and_per_call_order(algorithm, expected):
    kb = knowledge_base("furniture", BOARD)
    got = describe("t", kb, algorithm, preference=["type", "colour", "orientation", "size"], forced=["type"])
    assert got.description == expected and got.distinguishing
    assert got.sources[0] == "forced"


def test_order_changes_per_call_without_touching_the_consultant():
    kb = knowledge_base("furniture", BOARD)
    before = list(kb.preference)
    assert describe("t", kb, preference=["size", "type"]).description == ["size=large", "type=chair"]
    assert describe("t", kb, preference=["colour", "orientation", "type"]).description == [
        "colour=red", "orientation=front", "type=chair"]
    assert kb.preference == before


def test_forced_head_is_kept_when_it_rules_out_nothing():
    kb = knowledge_base("furniture", {k: v for k, v in BOARD.items() if k != "d3"})
    got = describe("t", kb, preference=["colour", "orientation"], forced=["type"])
    assert got.description == ["type=chair", "colour=red", "orientation=front"]


def test_read_only_leaves_wm_alone_and_writes_encode():
    kb = knowledge_base("furniture", BOARD)
    describe("t", kb, "sd-pia", preference=["colour", "orientation", "type"])
    assert all(not q for q in kb.wm.snapshot().values())
    got = describe("t", kb, "sd-pia", preference=["colour", "orientation", "type"], writes=True)
    assert list(kb.wm.queue("t")) == got.description == ["colour=red", "orientation=front", "type=chair"]
    # rule 3: colour=red was encoded for the distractors it could not rule out
    assert "colour=red" in kb.wm.queue("d2")
    # SD-PIA now reads WM (Phase 1) without writing
    again = describe("t", kb, "sd-pia", preference=["size"])
    assert again.sources[0] == "wm" and list(kb.wm.queue("t")) == got.description


@pytest.mark.parametrize("algorithm", ["dist-pia", "greedy", "full-brevity", "sd-pia"])
def test_never_two_values_of_one_attribute(algorithm):
    kb = Consultant(
        "shades",
        {
            "t": {"colour=red": 1, "colour=crimson": 1, "size=large": 1},
            "d1": {"colour=red": 1, "size=large": 1},
            "d2": {"colour=crimson": 1, "size=large": 1},
        },
        ["colour=red", "colour=crimson", "size=large"],
    )
    got = describe("t", kb, algorithm)  # two colours would distinguish; one value per attribute cannot
    assert got.description == ["colour=red"]
    assert not got.distinguishing and got.distractors_left == ["d1"]


def test_bad_input_is_a_generation_error():
    kb = knowledge_base("furniture", BOARD)
    with pytest.raises(GenerationError, match="no entity 'nobody'"):
        describe("nobody", kb)
    with pytest.raises(GenerationError, match="unknown algorithm 'best'"):
        describe("t", kb, "best")


@pytest.mark.parametrize("algorithm", ["full-brevity", "greedy"])
def test_baselines_consider_only_the_attributes_the_order_names(algorithm):
    """The issue's case: a ``loc`` attribute the call's order does not name must never be used."""
    kb = knowledge_base("f", {"t": {"type": "chair", "colour": "red", "loc": "1"},
                              "d": {"type": "chair", "colour": "red", "loc": "2"}})
    got = describe("t", kb, algorithm, preference=["type", "colour"], forced=["type"])
    assert got.description == ["type=chair"] and not got.distinguishing and got.distractors_left == ["d"]
    named = describe("t", kb, algorithm, preference=["type", "loc"], forced=["type"])
    assert named.description == ["type=chair", "loc=1"] and named.distinguishing


@pytest.mark.parametrize("algorithm", ["full-brevity", "greedy"])
def test_baselines_break_ties_by_the_calls_order_not_the_file_order(algorithm):
    # colour and size each rule out the one distractor; the knowledge base lists colour first.
    kb = knowledge_base("f", {"t": {"colour": "red", "size": "large"}, "d": {"colour": "blue", "size": "small"}})
    assert describe("t", kb, algorithm, preference=["size", "colour"]).description == ["size=large"]
    assert describe("t", kb, algorithm, preference=["colour", "size"]).description == ["colour=red"]
