"""Referring expression generation, its encodings (WM encoding
rules 1, 3, 4) and the paper's Table 1 case study (scenarios/guess_who_table1.yaml)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import pytest
import yaml

from fsreg_ros.core.consultant.consultant import Consultant
from fsreg_ros.core.consultant.local_port import LocalPort
from fsreg_ros.core.algorithms.port import run_sync
from fsreg_ros.core.forgetting.policies import ForgettingPolicy
from fsreg_ros.core.forgetting.wm_manager import WMManager
from fsreg_ros.core.algorithms.generation import (
    ALGORITHMS, Expression, GenerationError, dist_pia, full_brevity, generate, greedy, sd_pia,
)
from fsreg_ros.core.algorithms.resolution import RESOLVED, resolve


def keys(events):
    return [(e.op, e.entity, e.property, e.cause, e.time, e.turn) for e in events]


def domain(entities: dict, preference: list, policy: Optional[ForgettingPolicy] = None, threshold=0.5):
    """A consultant over {entity: [properties]} (certainty 1) or {entity: {p: c}}."""
    events: list = []
    facts = {e: (dict(v) if isinstance(v, dict) else {p: 1.0 for p in v}) for e, v in entities.items()}
    c = Consultant("d", facts, preference, threshold, sink=events.append)
    WMManager().manage(c.wm, policy or ForgettingPolicy.parse("displacement", capacity=50))
    return c, LocalPort(c), events


def gen(target, port, algorithm="sd-pia", **kw):
    return run_sync(generate(target, port, algorithm, **kw))


# =========================================================== Table 1 (paper)
#: Robot turns of Table 1: (target, description in selection order, sources).
#: Sets are the paper's; order and sources follow the generation rules on scenarios/guess_who_table1.yaml.
TABLE1_EXPECTED = {
    "decay": [
        ("face1", ["lab-coat", "light-hair", "glasses"], ["wm", "wm", "wm"]),
        ("face5", ["male", "dark-hair"], ["ltm", "ltm"]),
        ("face2", ["glasses", "female"], ["ltm", "ltm"]),
        ("face1", ["glasses", "short-hair", "lab-coat"], ["wm", "wm", "wm"]),
        ("face3", ["female", "hoodie"], ["ltm", "ltm"]),
        ("face1", ["lab-coat", "glasses"], ["wm", "wm"]),
    ],
    "displacement": [
        ("face1", ["light-hair", "glasses", "lab-coat"], ["wm", "wm", "ltm"]),
        ("face5", ["male", "dark-hair"], ["wm", "ltm"]),
        ("face2", ["female", "glasses"], ["wm", "wm"]),
        ("face1", ["light-hair", "lab-coat", "glasses"], ["wm", "wm", "ltm"]),
        ("face3", ["female", "hoodie"], ["wm", "ltm"]),
        ("face1", ["short-hair", "glasses", "lab-coat"], ["wm", "wm", "ltm"]),
    ],
    "none": [
        ("face1", ["light-hair", "lab-coat", "glasses"], ["ltm"] * 3),
        ("face5", ["male", "dark-hair"], ["ltm"] * 2),
        ("face2", ["glasses", "female"], ["ltm"] * 2),
        ("face1", ["light-hair", "lab-coat", "glasses"], ["ltm"] * 3),
        ("face3", ["female", "hoodie"], ["ltm"] * 2),
        ("face1", ["light-hair", "lab-coat", "glasses"], ["ltm"] * 3),
    ],
}
#: The table itself, as sets (the header of scenarios/guess_who_table1.yaml).
TABLE1_SETS = {
    "decay": [
        {"light-hair", "lab-coat", "glasses"},
        {"dark-hair", "male"},
        {"female", "glasses"},
        {"short-hair", "lab-coat", "glasses"},
        {"female", "hoodie"},
        {"lab-coat", "glasses"},
    ],
    "displacement": [
        {"light-hair", "lab-coat", "glasses"},
        {"dark-hair", "male"},
        {"female", "glasses"},
        {"light-hair", "lab-coat", "glasses"},
        {"female", "hoodie"},
        {"short-hair", "lab-coat", "glasses"},
    ],
    "none": [
        {"light-hair", "lab-coat", "glasses"},
        {"dark-hair", "male"},
        {"female", "glasses"},
        {"light-hair", "lab-coat", "glasses"},
        {"female", "hoodie"},
        {"light-hair", "lab-coat", "glasses"},
    ],
}
TABLE1_POLICIES = {
    "decay": (ForgettingPolicy.parse("decay", decay_period=10.0), "sd-pia"),
    "displacement": (ForgettingPolicy.parse("displacement", capacity=2), "sd-pia"),
    "none": (ForgettingPolicy.parse("none"), "dist-pia"),
}


def load_table1(path: Path) -> dict:
    """The Guess-Who scenario as plain data (the ``table1_path`` fixture finds it)."""
    return yaml.safe_load(path.read_text(encoding="utf-8"))


def table1_consultant(data: dict, sink=None) -> Consultant:
    faces = data["domains"]["faces"]
    entities = {
        e: (dict(v) if isinstance(v, dict) else {p: 1.0 for p in v}) for e, v in faces["entities"].items()
    }
    return Consultant("faces", entities, faces["preference"], faces.get("threshold", 0.5), sink=sink)


def play_table1(path: Path, policy_name: str):
    """Play the dialogue; returns (human results, robot expressions, Q[face1] before the
    last robot turn, events)."""
    data = load_table1(path)
    events: list = []
    c = table1_consultant(data, events.append)
    policy, algorithm = TABLE1_POLICIES[policy_name]
    manager = WMManager()
    manager.manage(c.wm, policy)
    port = LocalPort(c)
    humans, robots, wm_face1 = [], [], None
    for i, turn in enumerate(data["dialogue"]):
        t = float(turn["time"])
        manager.advance(t)
        if turn["speaker"] == "human":
            result = run_sync(resolve(turn["description"], {"faces": port}, time=t, turn=i))
            humans.append((turn["target"], result))
        else:
            wm_face1 = c.wm.queue("face1")
            robots.append(run_sync(generate(turn["target"], port, algorithm, time=t, turn=i)))
    return humans, robots, wm_face1, events


@pytest.mark.parametrize("policy_name", ["decay", "displacement", "none"])
def test_table1_robot_descriptions(table1_path, policy_name):
    humans, robots, _, _ = play_table1(table1_path, policy_name)
    expected = TABLE1_EXPECTED[policy_name]
    assert len(robots) == len(expected) == 6
    for n, (expression, (target, description, sources), table_set) in enumerate(
        zip(robots, expected, TABLE1_SETS[policy_name]), start=1
    ):
        got = (expression.target, expression.description, expression.sources)
        assert got == (target, description, sources), f"robot turn {n} under {policy_name}"
        assert set(expression.description) == table_set, f"robot turn {n} under {policy_name}"
        assert expression.distinguishing and expression.distractors_left == []
        assert expression.algorithm == TABLE1_POLICIES[policy_name][1]


@pytest.mark.parametrize("policy_name", ["decay", "displacement", "none"])
def test_table1_every_human_turn_resolves_to_its_target(table1_path, policy_name):
    humans, _, _, _ = play_table1(table1_path, policy_name)
    assert len(humans) == 6
    for target, result in humans:
        assert result.status == RESOLVED and result.resolved == target


@pytest.mark.parametrize(
    "policy_name, wm",
    [
        ("decay", ("lab-coat", "short-hair", "glasses")),
        ("displacement", ("short-hair", "glasses")),
        ("none", ()),
    ],
)
def test_table1_wm_of_face1_before_turn_6(table1_path, policy_name, wm):
    _, robots, wm_face1, events = play_table1(table1_path, policy_name)
    assert wm_face1 == wm
    assert tuple(robots[-1].wm_before) == wm
    if policy_name == "none":
        assert events == []


def test_table1_is_deterministic(table1_path):
    first = play_table1(table1_path, "decay")[3]
    second = play_table1(table1_path, "decay")[3]
    assert first == second and len(first) > 100


# ==================================================== Dale & Reiter (1995)
# Their worked example: three objects described by type, colour and size, with the
# preferred attributes type > colour > size.  Attribute values become unary properties.
DR_ENTITIES = {
    "object1": ["dog", "small", "black"],
    "object2": ["dog", "large", "white"],
    "object3": ["cat", "small", "black"],
}
DR_PREFERENCE = ["dog", "cat", "black", "white", "small", "large"]


@pytest.mark.parametrize("algorithm", ["dist-pia", "sd-pia", "full-brevity", "greedy"])
def test_dale_reiter_small_black_dog(algorithm):
    # dog rules out object3 (a cat); black then rules out object2 (white): "the black dog".
    # "small" is never needed.  Every algorithm agrees on this domain.
    _, port, _ = domain(DR_ENTITIES, DR_PREFERENCE)
    expression = gen("object1", port, algorithm)
    assert expression.description == ["dog", "black"]
    assert expression.distinguishing


def test_dale_reiter_large_white_dog():
    _, port, _ = domain(DR_ENTITIES, DR_PREFERENCE)
    assert gen("object2", port, "dist-pia").description == ["dog", "white"]
    assert gen("object3", port, "dist-pia").description == ["cat"]


def test_dist_pia_does_not_force_the_head_noun():
    # Among object1 and object2 only, "dog" rules nothing out.  Dale & Reiter's IA
    # would still add the type ("the black dog"); our DIST-PIA includes a
    # property only if it rules something out, so it says just "black" and realisation
    # supplies the domain's default noun.  The type is still considered: rule 3
    # encodes it for object2.
    _, port, events = domain(DR_ENTITIES, DR_PREFERENCE)
    expression = gen("object1", port, "dist-pia", context=["object1", "object2"], time=1.0)
    assert expression.description == ["black"] and expression.distinguishing
    assert keys(events) == [
        ("encode", "object2", "dog", "reg-distractor", 1.0, None),
        ("encode", "object1", "black", "speaker", 1.0, None),
    ]


# ============================================== IA vs the classic baselines
def test_ia_is_not_minimal_unlike_full_brevity():
    # a rules out d1, then c rules out d2 -- and c alone would have ruled out both.
    # The IA never backtracks, so it keeps the now redundant a.
    entities = {"t": ["a", "c"], "d1": [], "d2": ["a"]}
    _, port, _ = domain(entities, ["a", "c"])
    assert gen("t", port, "dist-pia").description == ["a", "c"]
    assert gen("t", port, "full-brevity").description == ["c"]
    assert gen("t", port, "greedy").description == ["c"]


FB_TIE = {
    # p0 rules out {d1, d2}, p1 {d1, d3}, p2 {d2, d4}, p4 {d3, d4}; p3 fails for t.
    "t": ["p0", "p1", "p2", "p4"],
    "d1": ["p2", "p3", "p4"],
    "d2": ["p1", "p3", "p4"],
    "d3": ["p0", "p2"],
    "d4": ["p0", "p1"],
}
FB_PREF = ["p0", "p1", "p2", "p3", "p4"]


def test_full_brevity_tie_break_is_lexicographic_on_sorted_ranks():
    # Two distinguishing pairs: {p0, p4} (ranks 0, 4; sum 4) and {p1, p2} (ranks 1, 2;
    # sum 3).  Lexicographically (0, 4) < (1, 2), so {p0, p4} wins.
    _, port, events = domain(FB_TIE, FB_PREF)
    expression = gen("t", port, "full-brevity", time=2.0, turn=9)
    assert expression.description == ["p0", "p4"] and expression.sources == ["ltm", "ltm"]
    assert expression.distinguishing
    # Baselines ignore WM and encode only their final description (rule 1).
    assert keys(events) == [
        ("encode", "t", "p0", "speaker", 2.0, 9),
        ("encode", "t", "p4", "speaker", 2.0, 9),
    ]


def test_ia_and_greedy_on_the_tie_domain():
    _, port, _ = domain(FB_TIE, FB_PREF)
    # IA: p0 (d1, d2), p1 (d3), p2 (d4): three properties where two would do.
    assert gen("t", port, "dist-pia").description == ["p0", "p1", "p2"]
    # Greedy: everything rules out two; the tie goes to p0.  Then p4 rules out two
    # of what is left (d3, d4), p1 and p2 only one each.
    assert gen("t", port, "greedy").description == ["p0", "p4"]


def test_full_brevity_output_is_in_preference_order():
    # The only distinguishing set is {z, a}; it is reported in preference order.
    entities = {"t": ["a", "z"], "d1": ["a"], "d2": ["z"]}
    _, port, _ = domain(entities, ["z", "a"])
    assert gen("t", port, "full-brevity").description == ["z", "a"]
    _, port, _ = domain(entities, ["a", "z"])
    assert gen("t", port, "full-brevity").description == ["a", "z"]


UNDIST = {
    # twin has everything t has; c rules out all the others at once.
    "t": ["a", "b", "c"],
    "twin": ["a", "b", "c"],
    "d1": ["b"],
    "d2": ["a"],
    "d3": [],
}


def test_undistinguishable_target_ia():
    _, port, events = domain(UNDIST, ["a", "b", "c"])
    for algorithm in ("dist-pia", "sd-pia"):
        expression = gen("t", port, algorithm)
        assert expression.description == ["a", "b"]
        assert not expression.distinguishing and expression.distractors_left == ["twin"]


def test_undistinguishable_target_full_brevity_rules_out_the_most():
    _, port, _ = domain(UNDIST, ["a", "b", "c"])
    expression = gen("t", port, "full-brevity")
    assert expression.description == ["c"]
    assert not expression.distinguishing and expression.distractors_left == ["twin"]


def test_greedy_stops_when_nothing_rules_out_any():
    _, port, events = domain(UNDIST, ["a", "b", "c"])
    expression = gen("t", port, "greedy", time=1.0)
    assert expression.description == ["c"]
    assert not expression.distinguishing and expression.distractors_left == ["twin"]
    assert keys(events) == [("encode", "t", "c", "speaker", 1.0, None)]


def test_greedy_ties_go_to_the_more_preferred():
    entities = {"t": ["a", "b"], "d1": ["b"], "d2": ["a"]}
    _, port, _ = domain(entities, ["b", "a"])
    assert gen("t", port, "greedy").description == ["b", "a"]
    _, port, _ = domain(entities, ["a", "b"])
    assert gen("t", port, "greedy").description == ["a", "b"]


def test_greedy_does_not_add_after_distinguishing():
    entities = {"t": ["a", "b", "c"], "d1": ["b"], "d2": ["b", "c"]}
    _, port, _ = domain(entities, ["b", "c", "a"])
    # a rules out both at once: chosen first even though least preferred, then stop.
    assert gen("t", port, "greedy").description == ["a"]
    assert gen("t", port, "dist-pia").description == ["c", "a"]


# ============================================== encodings during REG (rules)
RULES_ENTITIES = {
    "d1": ["s", "p", "q"],
    "t": ["p", "q", "r"],
    "d2": ["q"],
    "d3": ["p", "q"],
}
RULES_PREF = ["s", "p", "q", "r"]


@pytest.mark.parametrize("algorithm", ["sd-pia", "dist-pia"])
def test_reg_encodes_distractors_then_the_description(algorithm):
    c, port, events = domain(RULES_ENTITIES, RULES_PREF)
    expression = gen("t", port, algorithm, time=5.0, turn=2)
    assert expression.description == ["p", "r"] and expression.sources == ["ltm", "ltm"]
    assert keys(events) == [
        # s fails for t: skipped, not encoded for d1 although it holds for d1.
        # p holds for t: encoded for the distractors it cannot rule out (entity order);
        # it rules out d2, so it is selected.
        ("encode", "d1", "p", "reg-distractor", 5.0, 2),
        ("encode", "d3", "p", "reg-distractor", 5.0, 2),
        # q rules out nobody: still encoded for both (rule 3), not selected.
        ("encode", "d1", "q", "reg-distractor", 5.0, 2),
        ("encode", "d3", "q", "reg-distractor", 5.0, 2),
        # r rules out d1 and d3; nothing is encoded for them.
        # Rule 1: the description for the target, in selection order.
        ("encode", "t", "p", "speaker", 5.0, 2),
        ("encode", "t", "r", "speaker", 5.0, 2),
    ]
    # Rule 4: checking q for the target did not encode it for the target.
    assert c.wm.queue("t") == ("p", "r")
    assert c.wm.snapshot() == {"d1": ["p", "q"], "d3": ["p", "q"], "t": ["p", "r"]}


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_policy_none_stores_nothing_and_emits_nothing(algorithm):
    c, port, events = domain(RULES_ENTITIES, RULES_PREF, ForgettingPolicy.parse("none"))
    expression = gen("t", port, algorithm)
    # (r alone would do: the IA keeps p, selected before r made it redundant.)
    assert expression.description == (["p", "r"] if algorithm.endswith("pia") else ["r"])
    assert expression.distinguishing
    assert events == [] and c.wm.snapshot() == {}


def test_context_set_limits_distractors_and_keeps_entity_order():
    c, port, events = domain(RULES_ENTITIES, RULES_PREF)
    expression = gen("t", port, "dist-pia", context=["d3", "t", "d1"], time=1.0)
    # Only d1 and d3 compete: p rules out nobody, q neither, r both.
    assert expression.description == ["r"] and expression.distinguishing
    assert [(k[1], k[2]) for k in keys(events) if k[3] == "reg-distractor"] == [
        ("d1", "p"),
        ("d3", "p"),
        ("d1", "q"),
        ("d3", "q"),
    ]


def test_context_with_only_the_target_or_empty():
    _, port, events = domain(RULES_ENTITIES, RULES_PREF)
    for context in (["t"], []):
        for algorithm in ALGORITHMS:
            expression = gen("t", port, algorithm, context=context)
            assert expression.description == [] and expression.distinguishing
            assert expression.distractors_left == []
    assert events == []


def test_no_distractors_gives_an_empty_distinguishing_description():
    _, port, events = domain({"only": ["a", "b"]}, ["a", "b"])
    for algorithm in ALGORITHMS:
        expression = gen("only", port, algorithm)
        assert expression.description == [] and expression.sources == []
        assert expression.distinguishing and expression.distractors_left == []
    assert events == []


def test_certainty_threshold_applies_to_reg():
    entities = {"t": {"a": 0.4, "b": 0.9}, "d": {"a": 0.0, "b": 0.2}}
    _, port, _ = domain(entities, ["a", "b"])
    assert gen("t", port, "dist-pia").description == ["b"]
    _, port, _ = domain(entities, ["a", "b"], threshold=0.3)
    assert gen("t", port, "dist-pia").description == ["a"]


def test_new_entity_from_assert_facts_becomes_a_distractor():
    c, port, _ = domain(DR_ENTITIES, DR_PREFERENCE)
    c.assert_facts("object4", {"dog": 1.0, "small": 1.0, "black": 1.0}, 3.0)
    expression = gen("object1", port, "dist-pia")
    assert not expression.distinguishing and expression.distractors_left == ["object4"]


# ========================================================= SD-PIA and WM
WM_ORDER_ENTITIES = {
    # Q[t] = [a, b, c]; each property rules out two of the three distractors.
    "t": ["a", "b", "c"],
    "d1": ["b"],
    "d2": ["c"],
    "d3": ["a"],
}
WM_ORDER_PREF = ["b", "c", "a"]


@pytest.mark.parametrize(
    "wm_order, description",
    [
        ("lru-first", ["a", "b"]),  # a rules out d1, d2; b then d3
        ("mru-first", ["c", "b"]),  # c rules out d1, d3; b then d2
        ("preference", ["b", "c"]),  # b rules out d2, d3; c then d1
    ],
)
def test_wm_order_changes_the_result(wm_order, description):
    c, port, _ = domain(WM_ORDER_ENTITIES, WM_ORDER_PREF)
    c.wm.encode("t", ["a", "b", "c"], "speaker", 0.0)
    expression = gen("t", port, "sd-pia", wm_order=wm_order)
    assert expression.description == description
    assert expression.sources == ["wm", "wm"]
    assert expression.wm_before == ["a", "b", "c"]


def test_wm_order_default_is_lru_first_and_dist_pia_ignores_wm():
    c, port, _ = domain(WM_ORDER_ENTITIES, WM_ORDER_PREF)
    c.wm.encode("t", ["a", "b", "c"], "speaker", 0.0)
    assert gen("t", port).description == ["a", "b"]
    c.wm.encode("t", ["a", "b", "c"], "speaker", 0.0)
    expression = gen("t", port, "dist-pia", wm_order="mru-first")
    assert expression.description == ["b", "c"] and expression.sources == ["ltm", "ltm"]
    assert expression.wm_before == ["a", "b", "c"]


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_every_algorithm_reports_wm_before(algorithm):
    # The result object: wm_before is Q[target] just before REG, whatever the algorithm
    # (the baselines report it but do not use it).
    c, port, events = domain(WM_ORDER_ENTITIES, WM_ORDER_PREF)
    c.wm.encode("t", ["c", "a"], "speaker", 0.0)
    expression = gen("t", port, algorithm)
    assert expression.wm_before == ["c", "a"]
    if algorithm != "sd-pia":
        assert set(expression.sources) == {"ltm"}


def test_phase_2_skips_properties_considered_in_phase_1():
    entities = {"t": ["q", "r"], "d1": ["q"], "d2": ["q"]}
    c, port, events = domain(entities, ["q", "r"])
    c.wm.encode("t", ["q"], "speaker", 0.0)
    events.clear()
    expression = gen("t", port, "sd-pia", time=1.0)
    assert expression.description == ["r"] and expression.sources == ["ltm"]
    # q was considered once (Phase 1): one rule-3 encoding per distractor, not two.
    assert [(k[1], k[2], k[3]) for k in keys(events)] == [
        ("d1", "q", "reg-distractor"),
        ("d2", "q", "reg-distractor"),
        ("t", "r", "speaker"),
    ]


def test_phase_1_skips_wm_properties_that_no_longer_hold():
    entities = {"t": {"a": 0.6, "b": 1.0}, "d": {"b": 0.0}}
    c, port, events = domain(entities, ["a", "b"])
    c.wm.encode("t", ["a"], "speaker", 0.0)
    c.set_threshold(0.7)  # a stops holding for t, but WM still lists it
    events.clear()
    expression = gen("t", port, "sd-pia")
    assert expression.description == ["b"] and expression.sources == ["ltm"]


def test_phase_2_only_if_distractors_remain():
    entities = {"t": ["a", "b"], "d": ["b"]}
    c, port, events = domain(entities, ["b", "a"])
    c.wm.encode("t", ["a", "b"], "speaker", 0.0)
    events.clear()
    expression = gen("t", port, "sd-pia", time=1.0)
    # a (from WM) rules out d at once: b is never considered, nothing encoded for d.
    assert expression.description == ["a"] and expression.sources == ["wm"]
    assert [(k[1], k[2], k[3]) for k in keys(events)] == [("t", "a", "speaker")]


def test_sd_pia_with_empty_wm_equals_dist_pia():
    for target in DR_ENTITIES:
        _, port1, events1 = domain(DR_ENTITIES, DR_PREFERENCE)
        _, port2, events2 = domain(DR_ENTITIES, DR_PREFERENCE)
        a, b = gen(target, port1, "sd-pia"), gen(target, port2, "dist-pia")
        assert (a.description, a.sources, a.distinguishing) == (b.description, b.sources, b.distinguishing)
        assert keys(events1) == keys(events2)


def test_direct_entry_points_agree_with_generate():
    _, port, _ = domain(DR_ENTITIES, DR_PREFERENCE, ForgettingPolicy.parse("none"))
    assert run_sync(sd_pia("object1", port)).description == ["dog", "black"]
    assert run_sync(dist_pia("object1", port, wm_order="mru-first")).algorithm == "dist-pia"
    assert run_sync(full_brevity("object1", port)).algorithm == "full-brevity"
    assert run_sync(greedy("object1", port)).algorithm == "greedy"


def test_expression_json():
    _, port, _ = domain(DR_ENTITIES, DR_PREFERENCE)
    out = gen("object2", port, "sd-pia").to_json()
    assert out == {
        "target": "object2",
        "domain": "d",
        "algorithm": "sd-pia",
        "description": ["dog", "white"],
        "sources": ["ltm", "ltm"],
        "distinguishing": True,
        "distractors_left": [],
        "wm_before": [],
        "text": "",
        "origins": [None, None],
        "strengths": [None, None],
    }
    assert Expression("x", "d", "greedy").to_json()["distinguishing"] is True
    # Asked again, WM holds what the first call said (rule 1): each WM property carries the encoding that made
    # it enter.
    again = gen("object2", port, "sd-pia", time=5.0, turn=4).to_json()
    assert again["sources"] == ["wm", "wm"]
    assert again["origins"] == [{"cause": "speaker", "turn": None}, {"cause": "speaker", "turn": None}]
    # ... and how strongly it was held: used in the first description's episode, one before the episode this
    # description began when its view opened (age 1).
    assert again["strengths"] == [{"age": 1, "episodes": 1, "activation": None}] * 2


# ================================================================= errors
@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_unknown_target_and_context(algorithm):
    _, port, events = domain(DR_ENTITIES, DR_PREFERENCE)
    with pytest.raises(GenerationError, match="has no entity 'object9'"):
        gen("object9", port, algorithm)
    with pytest.raises(GenerationError, match="context names unknown entities of domain 'd': ghost"):
        gen("object1", port, algorithm, context=["object2", "ghost"])
    assert events == []


def test_unknown_algorithm_and_wm_order():
    _, port, events = domain(DR_ENTITIES, DR_PREFERENCE)
    with pytest.raises(GenerationError, match="unknown algorithm 'fast'"):
        gen("object1", port, "fast")
    with pytest.raises(GenerationError, match="unknown wm_order 'random'"):
        gen("object1", port, "sd-pia", wm_order="random")
    with pytest.raises(GenerationError, match="unknown wm_order 'random'"):
        run_sync(sd_pia("object1", port, wm_order="random"))
    assert events == []
    assert issubclass(GenerationError, ValueError)


class RecordingPort(LocalPort):
    """A LocalPort that records every call (each is one service call over the graph)."""

    def __init__(self, consultant):
        super().__init__(consultant)
        self.calls: list[tuple] = []

    async def open(self, target=None, context=None, first=None, refer=None):
        self.calls.append(("open", target) + ((first.prop,) if first else ()))
        return await super().open(target, context, first, refer)

    async def narrow(self, view, prop, cause, time, turn):
        self.calls.append(("narrow", prop))
        return await super().narrow(view, prop, cause, time, turn)

    async def walk(self, view, steps, cause, time, turn, size=None):
        walked = self.service.walk(view.handle, steps, cause, time, turn)  # one call, as the consultant node runs it
        self.calls.append(("walk", tuple(step.prop for step in steps), walked.narrowed))
        return walked

    async def close(self, view, encode=(), time=0.0, turn=None):
        self.calls.append(("close", tuple(encode)))
        return await super().close(view, encode, time, turn)


def test_reg_and_rr_ask_once_per_considered_property_and_nothing_twice():
    c, _, events = domain(
        {"t": ["red", "big", "cup"], "a": ["red", "small", "cup"], "b": ["blue", "big", "cup"]},
        ["blue", "red", "small", "big", "cup"],
    )
    port = RecordingPort(c)
    expression = run_sync(generate("t", port, "dist-pia", time=1.0))
    assert expression.description == ["red", "big"]
    # 'blue' and 'small' do not hold for t: not even sent; one walk narrows by 'red' and 'big' ('cup' is never
    # reached: no distractor is left), so the request costs three calls however many properties it considers
    assert port.calls == [("open", "t"), ("walk", ("red", "big", "cup"), 2), ("close", ("red", "big"))]
    assert keys(events) == [("encode", "a", "red", "reg-distractor", 1.0, None),
                            ("encode", "t", "red", "speaker", 1.0, None), ("encode", "t", "big", "speaker", 1.0, None)]
    port.calls.clear()
    result = run_sync(resolve(["red", "big"], {"d": port}, time=2.0))
    assert result.status == RESOLVED and result.resolved == "t"
    # RR: opening checks the first property; one walk the others; close (rule 1)
    assert port.calls == [("open", None, "red"), ("walk", ("big",), 1), ("close", ("red", "big"))]
