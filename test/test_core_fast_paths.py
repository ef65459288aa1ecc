"""The core's fast paths equal their plain definitions.

* ``simulation.dumps`` writes exactly ``json.dumps(sort_keys=True, indent=2, ensure_ascii=False)``;
* a :class:`Consultant` built from facts (checked by set operations, holders packed from
  (property, entity) pairs) holds and refuses exactly what a fact-by-fact build would;
* ``bitset.rows_from_pairs`` equals one ``from_indices`` per row, in one block or many.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fsreg_ros.core import bitset
from fsreg_ros.core.consultant import Consultant, KnowledgeError, check_certainty
from fsreg_ros.core.simulation import dumps

# ------------------------------------------------------------------ dumps
LEAVES = st.none() | st.booleans() | st.integers() | st.floats() | st.text()
TREES = st.recursive(
    LEAVES, lambda inner: st.lists(inner) | st.tuples(inner, inner) | st.dictionaries(st.text(), inner), max_leaves=40
)


@settings(max_examples=400, deadline=None)
@given(TREES)
def test_dumps_is_the_standard_librarys_indented_sorted_text(value):
    assert dumps(value) == json.dumps(value, sort_keys=True, indent=2, ensure_ascii=False) + "\n"


@pytest.mark.parametrize("value", [
    {"turns": [{"candidates": ["e1", "é2", "a\"b\\c\n"], "x": [1, 2.5, None, True]}]},
    {"a": [float("nan"), float("inf"), -float("inf"), -0.0, 10**30, 1e-300]},
    {"empty": [], "nested": {}, "tuple": ("a", 1), "mixed": ["a", {"b": ["c"]}, ["d", "e"]]},
    {1: "int key", 2: None},  # not string keys: the standard library writes them
    {"sub": type("S", (str,), {})("subclass")},  # a str subclass, likewise
])
def test_dumps_of_edge_values(value):
    assert dumps(value) == json.dumps(value, sort_keys=True, indent=2, ensure_ascii=False) + "\n"


@pytest.mark.parametrize("value", [{"a": {1, 2}}, {1: "a", "b": 2}])
def test_dumps_refuses_what_json_refuses(value):
    with pytest.raises(TypeError):
        dumps(value)


# --------------------------------------------------------------- consultant
PROPS = ["p0", "p1", "p2", "p3"]
CERTAINTIES = (
    st.sampled_from([1.0, 0.5, 0.0, -0.0, 0.25, 0.75, 1, 0, True, False, float("nan"), float("inf"), 1.5, -0.1, 2])
    | st.floats(0.0, 1.0)
)
FACTS = st.dictionaries(st.sampled_from(PROPS + ["unknown"]), CERTAINTIES, max_size=5)


def reference_build(entities: dict, threshold: float) -> tuple:
    """The consultant's LTM as a fact-by-fact build defines it: (certainties, holders) or the error's text."""
    certainty = {}
    for entity, facts in entities.items():
        for prop, c in facts.items():
            if prop not in PROPS:
                return (f"domain 'd', entity '{entity}': unknown property '{prop}' "
                        "(not in the domain's preference order)")
            try:
                check_certainty(f"certainty of '{prop}' for '{entity}'", c)
            except KnowledgeError as err:
                return str(err)
        certainty[entity] = {p: float(c) for p, c in facts.items() if c > 0}
    names = list(entities)
    holders = {}
    for prop in PROPS:
        held = [i for i, e in enumerate(names) if threshold <= 0.0 or certainty[e].get(prop, 0.0) >= threshold]
        holders[prop] = sum(1 << i for i in held)
    return certainty, holders


@settings(max_examples=300, deadline=None)
@given(st.dictionaries(st.sampled_from([f"e{i}" for i in range(12)]), FACTS, max_size=12),
       st.sampled_from([0.5, 0.0, 1.0, 0.3]))
def test_consultant_build_equals_fact_by_fact(entities, threshold):
    expected = reference_build(entities, threshold)
    if isinstance(expected, str):
        with pytest.raises(KnowledgeError) as err:
            Consultant("d", entities, PROPS, threshold)
        assert str(err.value) == expected
        return
    consultant = Consultant("d", entities, PROPS, threshold)
    certainty, holders = expected
    assert consultant.entities == list(entities)
    assert consultant._certainty == certainty
    for entity, facts in certainty.items():  # floats, not ints or bools
        assert all(type(c) is float for c in facts.values()), entity
    assert consultant._holders == holders
    for prop in PROPS:
        assert consultant.holders(prop) == {e for i, e in enumerate(entities) if holders[prop] >> i & 1}
    assert consultant.members(consultant.open_set()) == list(entities)


def test_consultant_build_keeps_its_own_copy_of_the_facts():
    facts = {"e1": {"p0": 1.0, "p1": 0.0}, "e2": {"p1": 1.0}}
    consultant = Consultant("d", facts, PROPS)
    consultant.assert_facts("e1", {"p0": 0.0}, 0.0)
    assert facts["e1"] == {"p0": 1.0, "p1": 0.0}  # the caller's mapping is not changed
    assert consultant.holders("p0") == set() and consultant.holders("p1") == {"e2"}


def test_names_follow_entities_appended_later():
    consultant = Consultant("d", {"e1": {"p0": 1.0}}, PROPS)
    assert consultant.members(consultant.open_set()) == ["e1"]
    consultant.assert_facts("e2", {"p0": 1.0}, 0.0)
    assert consultant.members(consultant.open_set()) == ["e1", "e2"]
    assert consultant.holders("p0") == {"e1", "e2"}


# ------------------------------------------------------------------ bitsets
@settings(max_examples=200, deadline=None)
@given(st.integers(1, 70), st.integers(1, 9), st.data())
def test_rows_from_pairs_equals_one_bitset_per_row(size, nrows, data):
    pairs = data.draw(st.lists(st.tuples(st.integers(0, nrows - 1), st.integers(0, size - 1)), max_size=200))
    rows = np.array([r for r, _ in pairs], dtype=np.intp)
    columns = np.array([c for _, c in pairs], dtype=np.intp)
    expected = [bitset.from_indices([c for r, c in pairs if r == k], size) for k in range(nrows)]
    assert bitset.rows_from_pairs(rows, columns, nrows, size) == expected


def test_rows_from_pairs_in_many_blocks(monkeypatch):
    monkeypatch.setattr(bitset, "BLOCK_BYTES", 16)  # 16 flags per block: one row per block at size 10
    rows = np.array([2, 0, 1, 2, 0], dtype=np.intp)
    columns = np.array([9, 0, 3, 1, 5], dtype=np.intp)
    assert bitset.rows_from_pairs(rows, columns, 3, 10) == [0b100001, 0b1000, 0b1000000010]
