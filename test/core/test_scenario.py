"""Scenario files: loading, the data model and validation."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import Collection

import pytest

from fsreg_ros.core.forgetting.policies import NONE, ForgettingPolicy
from fsreg_ros.core.scenario import (
    COMMAND_LINE,
    Scenario,
    ScenarioError,
    Turn,
    load_scenario,
    parse_scenario,
    render_path,
    scenario_json_schema,
)

REPO = Path(__file__).resolve().parents[2]
DATA = Path(__file__).resolve().parents[1] / "support" / "data" / "scenarios"


# ------------------------------------------------------------------ helpers
@dataclass
class FakeParse:
    properties: list[str]
    unknown_words: list[str]


class FakeLexicon:
    """Maps each word that is a property name to that property; records calls."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, set[str]]] = []

    def parse(self, text: str, properties: Collection[str]) -> FakeParse:
        self.calls.append((text, set(properties)))
        words = text.replace(",", " ").split()
        return FakeParse([w for w in words if w in properties], [w for w in words if w not in properties])


FACES = """\
domains:
  faces:
    preference: [light-hair, dark-hair, male, female, glasses]
    entities:
      f1: [light-hair, male, glasses]
      f2: [dark-hair, female]
      f3: [light-hair, female, glasses]
"""

TWO = """\
domains:
  faces:
    preference: [light-hair, dark-hair, male, female, small]
    entities:
      f1: [light-hair, male]
      f2: [dark-hair, female, small]
  objects:
    preference: [red, blue, mug, small]
    entities:
      o1: [red, mug]
      o2: [blue, mug, small]
"""


def snippet(base: str, extra: str = "") -> str:
    return base + textwrap.dedent(extra)


def settle(scenario: Scenario) -> Scenario:
    """Compute every domain's effective policy (where a missing parameter is reported)."""
    for domain in scenario.domains:
        scenario.policy_for(domain)
    return scenario


def error_of(text: str, lexicon: object = None) -> ScenarioError:
    """The error of a scenario text: while loading, or when its effective policies are computed."""
    with pytest.raises(ScenarioError) as info:
        settle(parse_scenario(text, source="t.yaml", lexicon=lexicon if lexicon is not None else FakeLexicon()))
    return info.value


def test_missing_parameter_is_not_a_load_error_so_the_command_line_can_give_it():
    scenario = parse_scenario(FACES + "memory: {policy: decay+global-capacity, decay_period: 5}\n", source="t.yaml")
    policy = scenario.policy_for("faces", {"global_capacity": 3})
    got = (policy.name, policy.value("decay_period"), policy.value("global_capacity"))
    assert got == ("decay+global-capacity", 5.0, 3)
    assert scenario.policy_for("faces", {"policy": "decay"}).name == "decay"
    with pytest.raises(
        ScenarioError, match=r"t\.yaml:\d+: memory: .*needs 'global_capacity' \(add --global-capacity N"
    ):
        scenario.policy_for("faces")


# ------------------------------------------------------------ ScenarioError
def test_error_str_has_source_line_path_and_message():
    err = ScenarioError("table1.yaml", "dialogue[3].description[1]", "unknown property 'foo'", 12)
    assert str(err) == "table1.yaml:12: dialogue[3].description[1]: unknown property 'foo'"
    assert (err.source, err.path, err.message, err.line) == (
        "table1.yaml",
        "dialogue[3].description[1]",
        "unknown property 'foo'",
        12,
    )
    assert isinstance(err, ValueError)


def test_error_str_without_line_or_path():
    assert str(ScenarioError("a.yaml", "memory", "bad")) == "a.yaml: memory: bad"
    assert str(ScenarioError("a.yaml", "", "file not found")) == "a.yaml: file not found"
    assert str(ScenarioError("a.yaml", "", "not valid YAML", 3)) == "a.yaml:3: not valid YAML"
    assert "\n" not in str(ScenarioError("a.yaml", "x", "m", 1))


def test_error_pickles():
    import pickle

    err = pickle.loads(pickle.dumps(ScenarioError("a.yaml", "memory", "bad", 4)))
    assert (err.source, err.path, err.message, err.line, str(err)) == (
        "a.yaml",
        "memory",
        "bad",
        4,
        "a.yaml:4: memory: bad",
    )


def test_render_path():
    assert render_path(("dialogue", 3, "description", 1)) == "dialogue[3].description[1]"
    assert render_path(("domains", "faces", "entities", "face2", "glasses")) == "domains.faces.entities.face2.glasses"
    assert render_path(()) == ""


# ------------------------------------------------------------------ table 1
def test_table1_loads(table1_path):
    scenario = load_scenario(table1_path)
    assert scenario.name == "guess-who-table1"
    assert scenario.source == str(table1_path)
    assert list(scenario.domains) == ["faces"]
    faces = scenario.domains["faces"]
    assert list(faces.entities) == [f"face{i}" for i in range(1, 17)]
    assert faces.entities["face1"] == {p: 1.0 for p in ["glasses", "lab-coat", "light-hair", "male", "short-hair"]}
    assert faces.preference[:3] == ("light-hair", "male", "short-hair")
    assert faces.threshold == 0.5
    assert faces.memory is None
    assert scenario.memory == {"policy": "decay", "decay_period": 10.0, "capacity": 2}
    assert len(scenario.dialogue) == 12
    first, second = scenario.dialogue[:2]
    assert first == Turn(0, 8.0, "human", "face1", ("male", "lab-coat", "light-hair", "glasses"))
    assert second == Turn(1, 11.0, "robot", "face1")
    assert [t.index for t in scenario.dialogue] == list(range(12))
    assert [t.speaker for t in scenario.dialogue] == ["human", "robot"] * 6


def test_table1_policy_is_decay_with_period_10(table1_path):
    policy = load_scenario(table1_path).policy_for("faces")
    assert policy.rules == ("decay",)
    assert policy.value("decay_period") == 10.0
    assert policy == ForgettingPolicy(("decay",), decay_period=10.0, capacity=2)


def test_table1_consultants(table1_path):
    events = []
    consultants = load_scenario(table1_path).consultants(sink=events.append)
    faces = consultants["faces"]
    assert faces.entities == [f"face{i}" for i in range(1, 17)]
    assert faces.preference[0] == "light-hair"
    assert faces.properties_of("face2") == ["glasses", "female", "dark-hair", "t-shirt"]
    faces.affirm("glasses", ["face1", "face3"], "rr", 1.0)
    assert [e.entity for e in events] == ["face1"]


def test_table1_text_loads_with_real_lexicon(table1_path, table1_text_path):
    pytest.importorskip("fsreg_ros.core.lexicon")
    text = load_scenario(table1_text_path)  # lexicon=None: Lexicon.load()
    plain = load_scenario(table1_path)
    assert text.name == "guess-who-table1-text"
    assert len(text.dialogue) == 12
    assert text.dialogue[0].text == "the man in a lab coat with light hair and glasses"
    assert text.dialogue[0].description is None
    assert text.domains == plain.domains


def test_real_lexicon_rejects_text_without_properties():
    realisation = pytest.importorskip("fsreg_ros.core.lexicon")
    lexicon = realisation.Lexicon.load()
    text = snippet(FACES, "dialogue:\n- {time: 0, speaker: human, text: 'the thing over there'}\n")
    with pytest.raises(ScenarioError) as info:
        parse_scenario(text, source="t.yaml", lexicon=lexicon)
    assert info.value.path == "dialogue[0].text"
    assert "no known property" in info.value.message


# ------------------------------------------------------ well-formed scenarios
def test_two_domain_file():
    scenario = load_scenario(DATA / "good" / "two_domains.yaml")
    assert list(scenario.domains) == ["faces", "objects"]
    assert scenario.domain_of("carol") == "faces"
    assert scenario.domain_of("ball1") == "objects"
    assert scenario.properties() == {
        "light-hair",
        "dark-hair",
        "male",
        "female",
        "glasses",
        "red",
        "blue",
        "mug",
        "ball",
    }
    assert scenario.entities() == ["alice", "bob", "carol", "mug1", "mug2", "ball1"]
    assert scenario.domains["faces"].entities["carol"] == {"light-hair": 1.0, "female": 0.9, "glasses": 0.3}
    assert scenario.domains["objects"].threshold == 0.6
    consultants = scenario.consultants()
    assert set(consultants) == {"faces", "objects"}
    assert consultants["objects"].threshold == 0.6
    assert consultants["objects"].properties_of("ball1") == ["red", "ball"]
    assert consultants["faces"].properties_of("carol") == ["light-hair", "female"]
    turns = scenario.dialogue
    assert turns[1].domain == "objects" and turns[0].domain is None
    assert turns[3].context == ("mug1", "ball1")  # context without the target
    assert turns[4].context == ("carol", "alice")  # context with the target
    assert [t.time for t in turns] == [0.0, 1.5, 1.5, 3.0, 4.0]  # equal times allowed
    assert all(isinstance(t.time, float) for t in turns)


def test_domain_of_unknown_entity():
    scenario = load_scenario(DATA / "good" / "two_domains.yaml")
    with pytest.raises(ScenarioError) as info:
        scenario.domain_of("zed")
    assert info.value.path == ""
    assert "unknown entity 'zed'" in info.value.message


def test_kb_file_without_dialogue_name_or_memory():
    scenario = load_scenario(DATA / "good" / "kb_only.yaml")
    assert scenario.name == "kb_only"  # the file stem
    assert scenario.dialogue == ()
    assert scenario.memory is None
    assert scenario.policy_for("locations") == NONE
    assert scenario.policy_for("locations").name == "none"


def test_ints_accepted_for_floats():
    scenario = parse_scenario(
        snippet(
            FACES.replace("    preference:", "    threshold: 1\n    preference:"),
            """\
            memory: {policy: decay, decay_period: 3}
            dialogue:
            - {time: 2, speaker: robot, target: f1}
            """,
        )
    )
    assert scenario.domains["faces"].threshold == 1.0
    assert scenario.policy_for("faces").value("decay_period") == 3.0
    assert scenario.dialogue[0].time == 2.0


def test_empty_or_null_dialogue_and_entities():
    text = "domains:\n  faces:\n    preference: [male]\n    entities: {}\ndialogue: []\n"
    scenario = parse_scenario(text, source="dir/kb.yaml")
    assert scenario.name == "kb"
    assert scenario.dialogue == ()
    assert scenario.domains["faces"].entities == {}
    assert parse_scenario("domains:\n  faces: {preference: [male]}\ndialogue:\n").dialogue == ()


def test_yaml_merge_keys_are_not_duplicates():
    text = snippet(
        FACES,
        """\
        defaults: &defaults {policy: decay, decay_period: 4}
        """,
    )
    # ``defaults`` is not a scenario key; merges inside allowed keys are fine:
    assert error_of(text).path == "defaults"
    merged = snippet(
        FACES.replace("    entities:", "    memory: &m {policy: decay, decay_period: 4}\n    entities:"),
        "memory: {<<: *m, decay_period: 8}\n",
    )
    scenario = parse_scenario(merged)
    assert scenario.memory == {"policy": "decay", "decay_period": 8.0}
    assert scenario.policy_for("faces").value("decay_period") == 4.0


# ------------------------------------------------------------------ memory
MEMORY = """\
domains:
  faces:
    preference: [male, female]
    entities: {bob: [male]}
    memory: {policy: displacement, capacity: 3}
  objects:
    preference: [red]
    entities: {ball: [red]}
    memory: {policy: displacement}
  places:
    preference: [kitchen]
    entities: {room: [kitchen]}
memory: {policy: decay, decay_period: 10.0, capacity: 2, global_capacity: 6}
"""


def test_domain_memory_merges_key_by_key_over_top_level():
    scenario = parse_scenario(MEMORY)
    assert scenario.domains["objects"].memory == {"policy": "displacement"}
    faces = scenario.policy_for("faces")
    assert (faces.name, faces.value("capacity")) == ("displacement", 3)
    objects = scenario.policy_for("objects")
    assert (objects.name, objects.value("capacity")) == ("displacement", 2)  # capacity from the top level
    places = scenario.policy_for("places")
    assert (places.name, places.value("decay_period")) == ("decay", 10.0)
    assert places.to_json() == {"policy": "decay", "decay_period": 10.0}


def test_overrides_win_over_both_layers():
    scenario = parse_scenario(MEMORY)
    assert scenario.policy_for("faces", {"capacity": 1}).value("capacity") == 1
    assert scenario.policy_for("objects", {"policy": "decay", "decay_period": 2}).to_json() == {
        "policy": "decay",
        "decay_period": 2.0,
    }
    assert scenario.policy_for("places", {"policy": "none"}) == NONE.with_changes(
        decay_period=10.0, capacity=2, global_capacity=6
    )
    # None values (unset command-line options) change nothing.
    assert scenario.policy_for("faces", {"policy": None, "capacity": None}).value("capacity") == 3
    assert scenario.policy_for("faces", {}) == scenario.policy_for("faces")


def test_no_memory_anywhere_means_none():
    scenario = parse_scenario(FACES)
    assert scenario.memory is None
    assert scenario.policy_for("faces") == NONE


def test_null_memory_setting_means_unset():
    scenario = parse_scenario(snippet(FACES, "memory: {policy: decay, decay_period: 5, capacity: null}\n"))
    assert scenario.memory == {"policy": "decay", "decay_period": 5.0}


@pytest.mark.parametrize(
    "overrides, fragment",
    [
        ({"policy": "forget"}, "unknown forgetting rule 'forget'"),
        ({"decay_period": 0}, "decay_period must be > 0"),
        ({"capacity": 0}, "capacity must be >= 1"),
        ({"capacity": True}, "capacity must be a whole number"),
        ({"global_capacity": -2}, "global_capacity must be >= 1"),
        ({"colour": "red"}, "unknown memory setting 'colour'"),
        ({"policy": "global-capacity"}, "domain 'faces': policy 'global-capacity' needs 'global_capacity'"),
    ],
)
def test_bad_overrides_name_the_command_line(overrides, fragment):
    scenario = parse_scenario(snippet(FACES, "memory: {policy: decay, decay_period: 5}\n"), source="t.yaml")
    with pytest.raises(ScenarioError) as info:
        scenario.policy_for("faces", overrides)
    assert info.value.path == COMMAND_LINE
    assert fragment in info.value.message
    assert info.value.source == "t.yaml"


def test_policy_for_unknown_domain():
    with pytest.raises(ScenarioError) as info:
        parse_scenario(FACES).policy_for("objects")
    assert "unknown domain 'objects'" in info.value.message


# --------------------------------------------------------------- bad files
def test_file_not_found(tmp_path):
    missing = tmp_path / "nope.yaml"
    with pytest.raises(ScenarioError) as info:
        load_scenario(missing)
    assert (info.value.source, info.value.path, info.value.line) == (str(missing), "", None)
    assert info.value.message == "file not found"


def test_directory_is_not_a_file(tmp_path):
    with pytest.raises(ScenarioError) as info:
        load_scenario(tmp_path)
    assert "directory" in info.value.message


def test_not_utf8(tmp_path):
    path = tmp_path / "latin1.yaml"
    path.write_bytes(b"name: caf\xe9\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert "not UTF-8" in info.value.message


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root reads anything")
def test_unreadable_file(tmp_path):
    path = tmp_path / "secret.yaml"
    path.write_text(FACES)
    path.chmod(0)
    try:
        with pytest.raises(ScenarioError) as info:
            load_scenario(path)
    finally:
        path.chmod(0o600)
    assert "cannot read" in info.value.message


def _expectations(path: Path) -> dict[str, str]:
    out = {}
    for line in path.read_text().splitlines():
        if line.startswith("# expect-"):
            key, _, value = line[len("# expect-"):].partition(":")
            out[key] = value.strip()
    return out


@pytest.mark.parametrize("path", sorted((DATA / "bad").glob("*.yaml")), ids=lambda p: p.stem)
def test_bad_fixture_files(path):
    expect = _expectations(path)
    with pytest.raises(ScenarioError) as info:
        settle(load_scenario(path))
    err = info.value
    assert err.source == str(path)
    assert err.path == expect["path"]
    assert expect["message"] in err.message
    assert err.line == int(expect["line"])
    assert str(err).startswith(f"{path}:{expect['line']}: ")


@pytest.mark.parametrize("path", sorted((DATA / "good").glob("*.yaml")), ids=lambda p: p.stem)
def test_good_fixture_files(path):
    assert isinstance(load_scenario(path), Scenario)


DIALOGUE = "dialogue:\n"

# (id, YAML text, expected path, message fragment, expected line or None = not checked)
CASES = [
    # --- YAML and the top level
    ("yaml-syntax", "domains: [faces\nname: x\n", "", "not valid YAML", 2),
    ("yaml-tab", "domains:\n\tfaces: {}\n", "", "not valid YAML", 2),
    ("yaml-two-documents", FACES + "---\nname: x\n", "", "not valid YAML", None),
    ("empty-file", "", "", "empty file", 1),
    ("comment-only", "# nothing\n", "", "empty file", None),
    ("top-level-list", "- domains\n", "", "top level must be a mapping", 1),
    ("top-level-scalar", "hello\n", "", "top level must be a mapping", 1),
    ("duplicate-top-key", "name: a\nname: b\n" + FACES, "name", "duplicate key 'name' (first at line 1)", 2),
    (
        "duplicate-entity-key",
        FACES + "      f1: [male]\n",
        "domains.faces.entities.f1",
        "duplicate key 'f1' (first at line 5)",
        8,
    ),
    (
        "duplicate-key-in-turn",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: robot, target: f1, time: 1}\n"),
        "dialogue[0].time",
        "duplicate key 'time'",
        9,
    ),
    # --- structure (unknown keys, types)
    (
        "unknown-top-key",
        FACES + "colour: red\n",
        "colour",
        "unknown key 'colour' (known: name, domains, memory, dialogue)",
        8,
    ),
    (
        "unknown-domain-key",
        FACES.replace("    preference:", "    prefs: []\n    preference:"),
        "domains.faces.prefs",
        "unknown key 'prefs'",
        3,
    ),
    (
        "unknown-memory-key",
        FACES + "memory: {policy: decay, period: 3}\n",
        "memory.period",
        "unknown key 'period' (known: policy, decay_period, capacity, global_capacity, seed, shared_capacity, "
        "activation_decay, activation_threshold, activation_clock, episode_window)",
        8,
    ),
    (
        "unknown-turn-key",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: robot, target: f1, tagret: f2}\n"),
        "dialogue[0].tagret",
        "unknown key 'tagret'",
        9,
    ),
    ("missing-domains", "name: x\n", "", "missing required key 'domains'", 1),
    (
        "missing-preference",
        "domains:\n  faces:\n    entities: {}\n",
        "domains.faces",
        "missing required key 'preference'",
        2,
    ),
    (
        "missing-time",
        snippet(FACES, "dialogue:\n- {speaker: robot, target: f1}\n"),
        "dialogue[0]",
        "missing required key 'time'",
        9,
    ),
    (
        "missing-speaker",
        snippet(FACES, "dialogue:\n- {time: 0, target: f1}\n"),
        "dialogue[0]",
        "missing required key 'speaker'",
        None,
    ),
    (
        "bad-speaker",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: narrator, target: f1}\n"),
        "dialogue[0].speaker",
        "must be 'human' or 'robot', got 'narrator'",
        9,
    ),
    ("domains-not-mapping", "domains: [faces]\n", "domains", "must be a mapping", 1),
    ("dialogue-not-list", FACES + "dialogue: {time: 0}\n", "dialogue", "must be a list", 8),
    ("turn-not-mapping", FACES + "dialogue: [hello]\n", "dialogue[0]", "must be a mapping", 8),
    ("name-not-string", "name: [a]\n" + FACES, "name", "must be a string", 1),
    ("name-empty", "name: ''\n" + FACES, "name", "must not be empty", 1),
    (
        "capacity-bool",
        FACES + "memory: {policy: displacement, capacity: true}\n",
        "memory.capacity",
        "must be a whole number, got the boolean true",
        8,
    ),
    (
        "capacity-float",
        FACES + "memory: {policy: displacement, capacity: 2.5}\n",
        "memory.capacity",
        "must be a whole number, got 2.5",
        8,
    ),
    (
        "period-string",
        FACES + "memory: {policy: decay, decay_period: ten}\n",
        "memory.decay_period",
        "must be a number, got 'ten'",
        8,
    ),
    (
        "period-bool",
        FACES + "memory: {policy: decay, decay_period: yes}\n",
        "memory.decay_period",
        "must be a number, got the boolean true",
        8,
    ),
    ("policy-not-string", FACES + "memory: {policy: 3}\n", "memory.policy", "must be a string", 8),
    (
        "threshold-string",
        FACES.replace("    preference:", "    threshold: high\n    preference:"),
        "domains.faces.threshold",
        "must be a number",
        3,
    ),
    (
        "threshold-bool",
        FACES.replace("    preference:", "    threshold: on\n    preference:"),
        "domains.faces.threshold",
        "must be a number",
        3,
    ),
    (
        "time-string",
        snippet(FACES, "dialogue:\n- {time: soon, speaker: robot, target: f1}\n"),
        "dialogue[0].time",
        "must be a number",
        9,
    ),
    (
        "time-nan",
        snippet(FACES, "dialogue:\n- {time: .nan, speaker: robot, target: f1}\n"),
        "dialogue[0].time",
        "finite",
        9,
    ),
    (
        "time-inf",
        snippet(FACES, "dialogue:\n- {time: .inf, speaker: robot, target: f1}\n"),
        "dialogue[0].time",
        "finite",
        9,
    ),
    (
        "facts-scalar",
        FACES.replace("f2: [dark-hair, female]", "f2: 5"),
        "domains.faces.entities.f2",
        "must be a list of properties or a mapping of property to certainty",
        6,
    ),
    (
        "facts-item-not-string",
        FACES.replace("f2: [dark-hair, female]", "f2: [dark-hair, 3]"),
        "domains.faces.entities.f2[1]",
        "must be a string, got 3",
        6,
    ),
    (
        "facts-item-bool",
        FACES.replace("f2: [dark-hair, female]", "f2: [dark-hair, no]"),
        "domains.faces.entities.f2[1]",
        "quote it",
        6,
    ),
    (
        "certainty-string",
        FACES.replace("f2: [dark-hair, female]", "f2: {female: high}"),
        "domains.faces.entities.f2.female",
        "must be a number, got 'high'",
        6,
    ),
    (
        "certainty-bool",
        FACES.replace("f2: [dark-hair, female]", "f2: {female: true}"),
        "domains.faces.entities.f2.female",
        "must be a number",
        6,
    ),
    (
        "entity-key-not-string",
        FACES.replace("f2: [dark-hair, female]", "2: [dark-hair, female]"),
        "domains.faces.entities.2",
        "key must be a string, got 2",
        6,
    ),
    ("preference-not-list", "domains:\n  faces: {preference: male}\n", "domains.faces.preference", "must be a list", 2),
    (
        "description-not-list",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: human, description: male}\n"),
        "dialogue[0].description",
        "must be a list",
        9,
    ),
    (
        "context-not-list",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: robot, target: f1, context: f2}\n"),
        "dialogue[0].context",
        "must be a list",
        9,
    ),
    (
        "target-empty",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: robot, target: ''}\n"),
        "dialogue[0].target",
        "must not be empty",
        9,
    ),
    # --- domains
    ("no-domains", "domains: {}\n", "domains", "no domains", 1),
    (
        "threshold-above-1",
        FACES.replace("    preference:", "    threshold: 1.5\n    preference:"),
        "domains.faces.threshold",
        "threshold must be in [0, 1], got 1.5",
        3,
    ),
    (
        "threshold-below-0",
        FACES.replace("    preference:", "    threshold: -0.1\n    preference:"),
        "domains.faces.threshold",
        "threshold must be in [0, 1]",
        3,
    ),
    (
        "certainty-above-1",
        FACES.replace("f2: [dark-hair, female]", "f2: {female: 1.2}"),
        "domains.faces.entities.f2.female",
        "certainty of 'female' for 'f2' must be in [0, 1], got 1.2",
        6,
    ),
    (
        "certainty-below-0",
        FACES.replace("f2: [dark-hair, female]", "f2: {female: -0.5}"),
        "domains.faces.entities.f2.female",
        "must be in [0, 1]",
        6,
    ),
    (
        "preference-twice",
        FACES.replace("male, female, glasses]", "male, female, male]"),
        "domains.faces.preference[4]",
        "property 'male' is listed twice in the preference order (also at preference[2])",
        3,
    ),
    (
        "fact-in-no-preference-order",
        FACES.replace("f2: [dark-hair, female]", "f2: [dark-hair, wings]"),
        "domains.faces.entities.f2[1]",
        "unknown property 'wings' (it is in no preference order)",
        6,
    ),
    (
        "fact-names-known-properties",
        FACES.replace("f2: [dark-hair, female]", "f2: {wings: 1.0}"),
        "domains.faces.entities.f2.wings",
        "domain 'faces' knows: light-hair, dark-hair, male, female, glasses",
        6,
    ),
    (
        "fact-from-other-domain",
        TWO.replace("o1: [red, mug]", "o1: [red, male]"),
        "domains.objects.entities.o1[1]",
        "unknown property 'male' (it is in another domain's preference order)",
        10,
    ),
    (
        "fact-twice",
        FACES.replace("f2: [dark-hair, female]", "f2: [female, dark-hair, female]"),
        "domains.faces.entities.f2[2]",
        "property 'female' is listed twice for entity 'f2'",
        6,
    ),
    (
        "duplicate-entity-across-domains",
        TWO.replace("o2: [blue, mug, small]", "f1: [blue, mug]"),
        "domains.objects.entities.f1",
        "duplicate entity 'f1': already in domain 'faces'",
        11,
    ),
    # --- memory settings
    ("bad-policy", FACES + "memory: {policy: forgetful}\n", "memory.policy", "unknown forgetting rule 'forgetful'", 8),
    (
        "bad-policy-part",
        FACES + "memory: {policy: decay+lru, decay_period: 2}\n",
        "memory.policy",
        "unknown forgetting rule 'lru'",
        8,
    ),
    (
        "policy-rule-twice",
        FACES + "memory: {policy: decay+decay, decay_period: 2}\n",
        "memory.policy",
        "names a rule twice",
        8,
    ),
    (
        "period-zero",
        FACES + "memory: {policy: decay, decay_period: 0}\n",
        "memory.decay_period",
        "decay_period must be > 0",
        8,
    ),
    (
        "period-negative",
        FACES + "memory: {policy: decay, decay_period: -1}\n",
        "memory.decay_period",
        "decay_period must be > 0",
        8,
    ),
    (
        "capacity-zero",
        FACES + "memory: {policy: displacement, capacity: 0}\n",
        "memory.capacity",
        "capacity must be >= 1",
        8,
    ),
    (
        "global-capacity-zero",
        FACES + "memory: {policy: global-capacity, global_capacity: 0}\n",
        "memory.global_capacity",
        "global_capacity must be >= 1",
        8,
    ),
    (
        "domain-capacity-zero",
        FACES.replace("    entities:", "    memory: {capacity: 0}\n    entities:"),
        "domains.faces.memory.capacity",
        "capacity must be >= 1",
        4,
    ),
    (
        "decay-without-period",
        FACES + "memory: {policy: decay, capacity: 2}\n",
        "memory",
        "domain 'faces': policy 'decay' needs 'decay_period'",
        8,
    ),
    (
        "displacement-without-capacity",
        FACES + "memory: {policy: decay+displacement, decay_period: 1}\n",
        "memory",
        "needs 'capacity'",
        8,
    ),
    ("global-without-limit", FACES + "memory: {policy: global-capacity}\n", "memory", "needs 'global_capacity'", 8),
    (
        "domain-policy-without-parameter",
        FACES.replace("    entities:", "    memory: {policy: displacement}\n    entities:")
        + "memory: {policy: decay, decay_period: 1}\n",
        "domains.faces.memory",
        "policy 'displacement' needs 'capacity'",
        4,
    ),
    (
        "top-policy-domain-params",
        FACES.replace("    entities:", "    memory: {capacity: 3}\n    entities:") + "memory: {policy: decay}\n",
        "memory",
        "needs 'decay_period'",
        9,
    ),
    # --- dialogue: time
    (
        "negative-time",
        snippet(FACES, "dialogue:\n- {time: -1, speaker: robot, target: f1}\n"),
        "dialogue[0].time",
        "negative time",
        9,
    ),
    (
        "decreasing-time",
        snippet(
            FACES, "dialogue:\n- {time: 3, speaker: robot, target: f1}\n- {time: 2.5, speaker: robot, target: f2}\n"
        ),
        "dialogue[1].time",
        "decreasing time: 2.5 is before the previous turn's 3.0",
        10,
    ),
    # --- dialogue: turn shapes
    (
        "human-description-and-text",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: human, description: [male], text: the man}\n"),
        "dialogue[0]",
        "either description or text, not both",
        9,
    ),
    (
        "human-neither",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: human, target: f1}\n"),
        "dialogue[0]",
        "needs a description",
        9,
    ),
    (
        "human-context",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: human, description: [male], context: [f1]}\n"),
        "dialogue[0].context",
        "only robot turns have a context",
        9,
    ),
    (
        "empty-description",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: human, description: []}\n"),
        "dialogue[0].description",
        "empty description",
        9,
    ),
    (
        "empty-text",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: human, text: '  '}\n"),
        "dialogue[0].text",
        "empty text",
        9,
    ),
    (
        "robot-without-target",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: robot}\n"),
        "dialogue[0]",
        "a robot turn needs a target",
        9,
    ),
    (
        "robot-description",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: robot, target: f1, description: [male]}\n"),
        "dialogue[0].description",
        "a robot turn has no description",
        9,
    ),
    (
        "robot-text",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: robot, target: f1, text: hi}\n"),
        "dialogue[0].text",
        "a robot turn has no text",
        9,
    ),
    # --- dialogue: entities
    (
        "robot-unknown-target",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: robot, target: f9}\n"),
        "dialogue[0].target",
        "unknown entity 'f9' (known: f1, f2, f3)",
        9,
    ),
    (
        "context-unknown-entity",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: robot, target: f1, context: [f2, f9]}\n"),
        "dialogue[0].context[1]",
        "unknown entity 'f9' (domain 'faces' has: f1, f2, f3)",
        9,
    ),
    (
        "context-other-domain",
        snippet(TWO, "dialogue:\n- {time: 0, speaker: robot, target: f1, context: [f2, o1]}\n"),
        "dialogue[0].context[1]",
        "entity 'o1' is in domain 'objects', not in the target's domain 'faces'",
        13,
    ),
    (
        "robot-wrong-domain",
        snippet(TWO, "dialogue:\n- {time: 0, speaker: robot, target: f1, domain: objects}\n"),
        "dialogue[0].domain",
        "domain 'objects' is not the target's domain",
        13,
    ),
    (
        "human-unknown-target",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: human, target: f7, description: [male]}\n"),
        "dialogue[0].target",
        "unknown entity 'f7'",
        9,
    ),
    (
        "human-target-other-domain",
        snippet(TWO, "dialogue:\n- {time: 0, speaker: human, target: o1, description: [male]}\n"),
        "dialogue[0].target",
        "entity 'o1' is in domain 'objects', not in the description's domain 'faces'",
        13,
    ),
    # --- dialogue: properties and domains
    (
        "description-unknown-property",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: human, description: [male, wings]}\n"),
        "dialogue[0].description[1]",
        "unknown property 'wings' (domain 'faces' knows: light-hair, dark-hair, male, female, glasses)",
        9,
    ),
    (
        "description-unknown-in-every-domain",
        snippet(TWO, "dialogue:\n- {time: 0, speaker: human, description: [wings]}\n"),
        "dialogue[0].description[0]",
        "unknown property 'wings' (domain 'faces' knows: light-hair, dark-hair, male, female, small; "
        "domain 'objects' knows",
        13,
    ),
    (
        "unknown-domain",
        snippet(TWO, "dialogue:\n- {time: 0, speaker: human, description: [male], domain: people}\n"),
        "dialogue[0].domain",
        "unknown domain 'people' (known: faces, objects)",
        13,
    ),
    (
        "property-not-in-named-domain",
        snippet(TWO, "dialogue:\n- {time: 0, speaker: human, description: [small, male], domain: objects}\n"),
        "dialogue[0].description[1]",
        "unknown property 'male' (domain 'objects' knows: red, blue, mug, small)",
        13,
    ),
    (
        "domain-not-determined-several",
        snippet(TWO, "dialogue:\n- {time: 0, speaker: human, description: [small]}\n"),
        "dialogue[0].description",
        "domain not determined: several domains know every property (faces, objects)",
        13,
    ),
    (
        "domain-not-determined-none",
        snippet(TWO, "dialogue:\n- {time: 0, speaker: human, description: [male, red]}\n"),
        "dialogue[0].description",
        "domain not determined: no domain knows every property "
        "(candidate domains per property: 'male': faces; 'red': objects)",
        13,
    ),
    (
        "text-without-property",
        snippet(FACES, "dialogue:\n- {time: 0, speaker: human, text: the tall one}\n"),
        "dialogue[0].text",
        "no known property in text 'the tall one'",
        9,
    ),
    (
        "text-domain-not-determined",
        snippet(TWO, "dialogue:\n- {time: 0, speaker: human, text: the small one}\n"),
        "dialogue[0].text",
        "domain not determined: several domains",
        13,
    ),
    (
        "text-not-in-named-domain",
        snippet(TWO, "dialogue:\n- {time: 0, speaker: human, text: the red man, domain: faces}\n"),
        "dialogue[0].text",
        "unknown property 'red' (domain 'faces' knows",
        13,
    ),
]


@pytest.mark.parametrize("text, path, fragment, line", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_validation_error(text, path, fragment, line):
    err = error_of(text)
    assert err.path == path
    assert fragment in err.message
    if line is not None:
        assert err.line == line
    assert err.source == "t.yaml"
    assert "\n" not in str(err)


def test_case_ids_are_unique():
    ids = [c[0] for c in CASES]
    assert len(ids) == len(set(ids))


def test_text_turns_use_the_given_lexicon():
    lexicon = FakeLexicon()
    scenario = parse_scenario(
        snippet(TWO, "dialogue:\n- {time: 0, speaker: human, target: o1, text: the red mug please}\n"), lexicon=lexicon
    )
    turn = scenario.dialogue[0]
    assert (turn.text, turn.description, turn.domain) == ("the red mug please", None, None)
    # parsed against every property, as the simulator does
    assert lexicon.calls == [("the red mug please", scenario.properties())]


def test_lexicon_is_not_loaded_without_text_turns(monkeypatch):
    realisation = pytest.importorskip("fsreg_ros.core.lexicon")

    def refuse(*args, **kwargs):
        raise AssertionError("Lexicon.load called")

    monkeypatch.setattr(realisation.Lexicon, "load", classmethod(refuse))
    assert len(parse_scenario(snippet(FACES, "dialogue:\n- {time: 0, speaker: robot, target: f1}\n")).dialogue) == 1


def test_lexicon_that_cannot_load_is_a_scenario_error(monkeypatch):
    realisation = pytest.importorskip("fsreg_ros.core.lexicon")

    def missing(cls, path=None):
        raise FileNotFoundError("config file 'lexicon.yaml' not found")

    monkeypatch.setattr(realisation.Lexicon, "load", classmethod(missing))
    with pytest.raises(ScenarioError) as info:
        parse_scenario(snippet(FACES, "dialogue:\n- {time: 0, speaker: human, text: the man}\n"))
    assert info.value.path == "dialogue[0].text"
    assert "lexicon" in info.value.message


# -------------------------------------------------------------- robustness
def _mutations(text: str):
    lines = text.splitlines(keepends=True)
    for i in range(len(lines)):
        yield "".join(lines[:i] + lines[i + 1:])  # drop a line
        yield "".join(lines[: i + 1] + lines[i:])  # repeat a line
        yield "".join(lines[:i]) + lines[i].replace(":", "", 1) + "".join(lines[i + 1:])  # drop a colon
    for cut in range(0, len(text), 13):
        yield text[:cut]  # truncate


def test_damaged_files_give_scenario_errors_never_tracebacks(table1_path):
    text = Path(table1_path).read_text()
    outcomes = {"ok": 0, "error": 0}
    for mutant in _mutations(text):
        try:
            parse_scenario(mutant, source="mutant.yaml", lexicon=FakeLexicon())
        except ScenarioError as err:
            assert err.source == "mutant.yaml" and "\n" not in str(err)
            outcomes["error"] += 1
        else:
            outcomes["ok"] += 1
    assert outcomes["error"] > 100 and outcomes["ok"] > 10


# -------------------------------------------------------------- JSON Schema
def test_json_schema_describes_the_format():
    schema = scenario_json_schema()
    assert schema["$schema"].startswith("https://json-schema.org/")
    assert schema["required"] == ["domains"]
    assert schema["additionalProperties"] is False
    assert set(schema["properties"]) == {"name", "domains", "memory", "dialogue"}
    turn = schema["$defs"]["TurnEntry"]
    assert turn["properties"]["speaker"]["enum"] == ["human", "robot"]
    assert set(turn["required"]) == {"time", "speaker"}
    json.dumps(schema)


@pytest.mark.slow  # runs the script as a process
def test_export_schemas_script(tmp_path):
    out = tmp_path / "scenario.schema.json"
    script = REPO / "scripts" / "export_schemas.py"
    done = subprocess.run([sys.executable, str(script), str(out)], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert json.loads(out.read_text()) == scenario_json_schema()
    to_stdout = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, check=True)
    assert json.loads(to_stdout.stdout) == scenario_json_schema()


# ------------------------------------------------------------------ attributes
ATTRS = """\
domains:
  t:
    preference: [colour=red, size=big, male, female, glasses]
"""


def test_attributes_map_each_property_to_its_attribute():
    scenario = parse_scenario(ATTRS + "    attributes: {sex: [male, female]}\n", source="t.yaml")
    assert scenario.domains["t"].attributes == {
        "colour=red": "colour",
        "size=big": "size",
        "male": "sex",
        "female": "sex",
    }
    assert parse_scenario(ATTRS, source="t.yaml").domains["t"].attributes == {
        "colour=red": "colour",
        "size=big": "size",
    }


@pytest.mark.parametrize(
    "block, path, fragment",
    [
        ("{sex: [male, hat]}", "domains.t.attributes.sex[1]", "unknown property 'hat'"),
        ("{sex: [male], who: [male]}", "domains.t.attributes.who[0]", "property 'male' is already in attribute 'sex'"),
        ("{hue: [colour=red]}", "domains.t.attributes.hue[0]", "belongs to attribute 'colour' by its name"),
        ("[male]", "domains.t.attributes", "must be a mapping"),
    ],
)
def test_attribute_errors(block, path, fragment):
    err = error_of(ATTRS + f"    attributes: {block}\n")
    assert (err.path, err.line) == (path, 4)
    assert fragment in err.message


# ------------------------------------------------------------------ exclusive groups
EXCL = """\
domains:
  t:
    preference: [colour=red, colour=blue, size=big, male, female, glasses, no-glasses]
"""


def test_exclusive_groups_are_kept_as_declared_and_the_consultant_adds_the_attr_value_ones():
    scenario = parse_scenario(EXCL + "    exclusive: [[glasses, no-glasses], [male, female]]\n"
                              "    entities: {p1: [male, glasses, colour=red]}\n", source="t.yaml")
    assert scenario.domains["t"].exclusive == (("glasses", "no-glasses"), ("male", "female"))
    consultant = scenario.consultants()["t"]
    assert consultant.excludes == {
        "glasses": ("no-glasses",), "no-glasses": ("glasses",), "male": ("female",), "female": ("male",),
        "colour=red": ("colour=blue",), "colour=blue": ("colour=red",),
    }
    assert parse_scenario(EXCL, source="t.yaml").domains["t"].exclusive == ()


def test_the_guess_who_scenarios_declare_their_exclusive_groups():
    root = Path(__file__).resolve().parents[2]
    for name in ("guess_who_table1.yaml", "guess_who_table1_text.yaml"):
        spec = load_scenario(root / "scenarios" / name, lexicon=FakeLexicon()).domains["faces"]
        assert spec.exclusive == (("glasses", "no-glasses"), ("light-hair", "dark-hair"), ("male", "female"),
                                  ("lab-coat", "t-shirt", "hoodie")), name


@pytest.mark.parametrize(
    "block, path, fragment",
    [
        ("[[glasses, monocle]]", "domains.t.exclusive[0][1]", "unknown property 'monocle'"),
        ("[[male, female], [female, glasses]]", "domains.t.exclusive[1][0]",
         "property 'female' is in exclusive group 0 too (a property is in one group at most)"),
        ("[[male, female, male]]", "domains.t.exclusive[0][2]", "property 'male' is in this group already"),
        ("[[male]]", "domains.t.exclusive[0]", "a group of one (male)"),
        ("[[glasses, colour=red]]", "domains.t.exclusive[0][1]",
         "property 'colour=red' is in the group of attribute 'colour' by its name"),
        ("{a: [male]}", "domains.t.exclusive", "must be a list"),
    ],
)
def test_exclusive_group_errors(block, path, fragment):
    err = error_of(EXCL + f"    exclusive: {block}\n")
    assert (err.path, err.line) == (path, 4)
    assert fragment in err.message
    assert str(err).startswith(f"t.yaml:4: {path}: ") and "\n" not in str(err)


@pytest.mark.parametrize("facts, fragment", [
    ("[male, female]", "entity 'p1' holds both 'male' and 'female', which exclude each other"),
    ("[colour=red, colour=blue]", "entity 'p1' holds both 'colour=red' and 'colour=blue'"),
    # two properties in no group besides the pair (the check's second tier)
    ("[glasses, male, no-glasses, female]", "entity 'p1' holds both 'male' and 'female', which exclude each other"),
])
def test_an_entity_holding_two_exclusive_properties_is_refused(facts, fragment):
    err = error_of(EXCL + "    exclusive: [[male, female]]\n    entities:\n      p1: " + facts + "\n")
    assert (err.path, err.line) == ("domains.t.entities.p1", 6)
    assert fragment in err.message


def test_properties_in_no_group_or_in_distinct_groups_go_together():
    text = EXCL + "    exclusive: [[male, female]]\n    entities:\n      p1: [glasses, no-glasses, male, colour=red]\n"
    assert parse_scenario(text, source="t.yaml").domains["t"].entities["p1"] == {
        "glasses": 1.0, "no-glasses": 1.0, "male": 1.0, "colour=red": 1.0}


def test_an_entity_may_have_an_exclusive_property_below_the_threshold():
    text = EXCL + "    exclusive: [[male, female]]\n    entities:\n      p1: {male: 1.0, female: 0.4}\n"
    assert parse_scenario(text, source="t.yaml").domains["t"].entities["p1"] == {"male": 1.0, "female": 0.4}
