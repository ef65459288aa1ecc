"""Lexicon, realiser and text parser (the robot's words and the human's ``text:`` turns)."""

from __future__ import annotations

import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from fsreg_ros.core.io.paths import config_path
from fsreg_ros.core.lexicon import Lexicon, LexiconError, ParseResult, tokenize

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
FACES = [
    "light-hair",
    "male",
    "short-hair",
    "lab-coat",
    "glasses",
    "female",
    "dark-hair",
    "t-shirt",
    "hoodie",
    "no-glasses",
]


@pytest.fixture(scope="module")
def lex() -> Lexicon:
    return Lexicon.load()


def shipped() -> Lexicon:
    return Lexicon.load(REPO / "config" / "lexicon.yaml")


# -- Table 1 ------------------------------------------------------------------------

TABLE1_TEXTS = [
    (["light-hair", "lab-coat", "glasses"], "the person with light hair, a lab coat and glasses"),
    (["male", "dark-hair"], "the man with dark hair"),
    (["female", "glasses"], "the woman with glasses"),
    (["short-hair", "lab-coat", "glasses"], "the person with short hair, a lab coat and glasses"),
    (["female", "hoodie"], "the woman with a hoodie"),
    (["lab-coat", "glasses"], "the person with a lab coat and glasses"),
]


@pytest.mark.parametrize("description, text", TABLE1_TEXTS)
def test_table1_robot_texts(lex, description, text):
    assert lex.realise(description, "faces") == text
    result = lex.parse(text, FACES)
    assert set(result.properties) == set(description) and result.unknown_words == []


def test_table1_text_parses_to_table1_descriptions(lex, table1_path, table1_text_path):
    plain = yaml.safe_load(table1_path.read_text())
    text = yaml.safe_load(table1_text_path.read_text())
    props = text["domains"]["faces"]["preference"]
    humans = [t for t in plain["dialogue"] if t["speaker"] == "human"]
    spoken = [t for t in text["dialogue"] if t["speaker"] == "human"]
    assert len(humans) == len(spoken) == 6
    for want, turn in zip(humans, spoken):
        result = lex.parse(turn["text"], props)
        assert result.properties == want["description"], turn["text"]
        assert result.unknown_words == (["he"] if " he " in turn["text"] else []), turn["text"]


@pytest.mark.parametrize(
    "text, properties, unknown",
    [
        ("the man in a lab coat with light hair and glasses", ["male", "lab-coat", "light-hair", "glasses"], []),
        ("the one in a hoodie, a woman without glasses", ["hoodie", "female", "no-glasses"], []),
        (
            "the one with short hair, light hair, a lab coat and no glasses",
            ["short-hair", "light-hair", "lab-coat", "no-glasses"],
            [],
        ),
        ("dark hair, short hair, a t-shirt, and he is a man", ["dark-hair", "short-hair", "t-shirt", "male"], ["he"]),
        ("short hair, glasses and a hoodie", ["short-hair", "glasses", "hoodie"], []),
        ("the woman with glasses", ["female", "glasses"], []),
    ],
)
def test_brief_examples(lex, text, properties, unknown):
    assert lex.parse(text, FACES) == ParseResult(properties, unknown)


# -- realisation ------------------------------------------------------------------


def test_empty_description_and_default_nouns(lex):
    assert lex.realise([], "faces") == "the person"
    assert lex.realise([], "objects") == "the object"
    assert lex.realise([], "locations") == "the place"
    assert lex.realise([], "kitchen-robots") == "the thing"
    assert [lex.noun_for(d) for d in ("faces", "objects", "locations", "elsewhere")] == [
        "person",
        "object",
        "place",
        "thing",
    ]


def test_built_in_nouns_without_domains_section():
    lex = Lexicon.from_mapping({})
    assert [lex.noun_for(d) for d in ("faces", "objects", "locations", "x")] == ["person", "object", "place", "thing"]
    assert Lexicon.from_mapping({"default_noun": "entity"}).noun_for("x") == "entity"


def test_joining_and_selection_order(lex):
    assert lex.realise(["glasses"], "faces") == "the person with glasses"
    assert lex.realise(["glasses", "hoodie"], "faces") == "the person with glasses and a hoodie"
    assert lex.realise(["hoodie", "glasses"], "faces") == "the person with a hoodie and glasses"
    assert lex.realise(["t-shirt", "no-glasses", "dark-hair", "hat"], "faces") == (
        "the person with a t-shirt, no glasses, dark hair and a hat"
    )


def test_head_noun_anywhere_in_description(lex):
    assert lex.realise(["glasses", "female", "hoodie"], "faces") == "the woman with glasses and a hoodie"


def test_second_noun_keeps_content(lex):
    # male has an adjective: a pre-modifier; a noun without one becomes a post-modifier.
    assert lex.realise(["female", "male"], "faces") == "the male woman"
    assert lex.realise(["chair", "table", "red"], "objects") == "the red chair with a table"
    for description, domain, props in [
        (["female", "male", "hat"], "faces", FACES + ["hat"]),
        (["chair", "table"], "objects", lex.domain_properties("objects")),
    ]:
        assert set(lex.parse(lex.realise(description, domain), props).properties) == set(description)


def test_adjectives_ordered_by_lexicon_order(lex):
    assert lex.realise(["red", "chair", "large"], "objects") == "the large red chair"
    assert lex.realise(["red", "large", "handle"], "objects") == "the large red object with a handle"
    assert lex.realise(["large", "red", "chair"], "objects") == "the large red chair"
    assert lex.realise(["colour=red", "orientation=left", "type=chair", "size=large"], "furniture") == (
        "the large red left-facing chair"
    )
    assert lex.realise(["hasBeard=1", "age=old", "hasGlasses=1"], "people") == "the old one with a beard and glasses"


def test_equal_adjective_order_keeps_description_order():
    lex = Lexicon.from_mapping({"properties": {"p": {"adjective": "shiny"}, "q": {"adjective": "dull"}}})
    assert lex.realise(["p", "q"], "objects") == "the shiny dull object"
    assert lex.realise(["q", "p"], "objects") == "the dull shiny object"


def test_property_not_in_lexicon_is_said_as_its_name(lex):
    assert lex.realise(["wears-scarf", "glasses"], "faces") == "the person with wears scarf and glasses"
    result = lex.parse("the person with wears scarf and glasses", ["wears-scarf", "glasses"])
    assert result == ParseResult(["wears-scarf", "glasses"], [])


def test_repeated_property_said_once(lex):
    assert lex.realise(["glasses", "glasses", "male"], "faces") == "the man with glasses"


# -- parsing ------------------------------------------------------------------------


def test_tokenize():
    assert tokenize('The "T-Shirt", glasses. Man\u2019s!') == ["the", "t-shirt", "glasses", "man's"]
    assert tokenize("colour=red --- a-") == ["colour", "red", "a"]


def test_case_punctuation_and_hyphen_variants(lex):
    assert lex.parse('THE Man, in a "Lab-Coat".', FACES).properties == ["male", "lab-coat"]
    assert lex.parse("a t shirt and a tshirt and a T-shirt", FACES) == ParseResult(["t-shirt"], [])
    assert lex.parse("no-glasses", FACES).properties == ["no-glasses"]


def test_longest_phrase_first(lex):
    assert lex.parse("no glasses", FACES).properties == ["no-glasses"]
    assert lex.parse("glasses", FACES).properties == ["glasses"]
    assert lex.parse("light hair", FACES).properties == ["light-hair"]


def test_first_occurrence_wins(lex):
    result = lex.parse("glasses, a woman, glasses and a lady", FACES)
    assert result == ParseResult(["glasses", "female"], [])


def test_only_properties_in_play_match(lex):
    result = lex.parse("the man with glasses", ["glasses"])
    assert result == ParseResult(["glasses"], ["man"])
    assert lex.parse("the man with glasses", []) == ParseResult([], ["man", "glasses"])


def test_pronouns_are_reported(lex):
    assert lex.parse("she has glasses", FACES) == ParseResult(["glasses"], ["she"])


def test_synonyms_and_plurals(lex):
    assert lex.parse("the guy with specs", FACES).properties == ["male", "glasses"]
    assert lex.parse("a lady in a hoody", FACES).properties == ["female", "hoodie"]
    assert lex.parse("blond", FACES).properties == ["light-hair"]


def test_without_means_negation_where_it_exists(lex):
    assert lex.parse("a woman without glasses", FACES).properties == ["female", "no-glasses"]
    assert lex.parse("not wearing any glasses", FACES).properties == ["no-glasses"]
    props = lex.domain_properties("people")
    assert lex.parse("the man without a beard", props).properties == ["type=person", "hasBeard=0"]
    # No negation of X in play: never read "without X" as X, report it.
    assert lex.parse("without glasses", ["glasses"]) == ParseResult([], ["without", "glasses"])
    assert lex.parse("not wearing a hat", ["hat"]) == ParseResult([], ["not", "hat"])
    # The negation is found even when X itself is not in play.
    assert lex.parse("without glasses", ["no-glasses"]).properties == ["no-glasses"]
    assert lex.parse("no", FACES) == ParseResult([], ["no"])


def test_unknown_hyphenated_word_split(lex):
    assert lex.parse("glasses-wearing man", FACES) == ParseResult(["glasses", "male"], [])
    assert lex.parse("a purple-ish hat", ["hat"]) == ParseResult(["hat"], ["purple", "ish"])


def test_property_name_always_a_phrase(lex):
    assert lex.parse("the female one with dark-hair", FACES).properties == ["female", "dark-hair"]
    assert lex.parse("colour=grey, type=desk", lex.domain_properties("furniture")).properties == [
        "colour=grey",
        "type=desk",
    ]


def test_function_words_come_from_the_lexicon():
    lex = Lexicon.from_mapping({"function_words": ["le"], "properties": {"hat": {"article": "le"}}})
    assert lex.parse("le hat", ["hat"]) == ParseResult(["hat"], [])
    assert lex.parse("the hat", ["hat"]) == ParseResult(["hat"], ["the"])
    default = Lexicon.from_mapping({})
    assert default.parse("the one with a hat", ["hat"]) == ParseResult(["hat"], [])


def test_shared_phrase_is_deterministic():
    data = {"properties": {"a": {"phrases": ["x"]}, "b": {"phrases": ["x"]}}}
    lex = Lexicon.from_mapping(data)
    assert lex.parse("x", ["b", "a"]).properties == ["a"]
    assert lex.parse("x", ["b"]).properties == ["b"]
    # A property's own name beats another's extra phrase.
    lex = Lexicon.from_mapping({"properties": {"a": {"phrases": ["b"]}}})
    assert lex.parse("b", ["a", "b"]).properties == ["b"]


def test_parse_against_every_lexicon_property(lex):
    """The parser node without a KB parses against all properties: lexicon order decides."""
    assert lex.properties("faces") == lex.domain_properties("faces")
    everything = lex.properties()
    assert {"male", "type=person", "colour=red", "red"} <= set(everything)
    assert lex.parse("the man in a lab coat without glasses", everything) == ParseResult(
        ["male", "lab-coat", "no-glasses"], []
    )
    assert lex.parse("a large red chair", everything).properties == ["large", "red", "chair"]


def test_phrase_table_is_cached(lex):
    assert lex._table(["glasses", "male"]) is lex._table(("male", "glasses"))


def test_tuna_people_and_furniture_phrases(lex):
    furniture = lex.domain_properties("furniture")
    assert lex.parse("red chair facing right", furniture) == ParseResult(
        ["colour=red", "type=chair", "orientation=right"], []
    )
    assert lex.parse("grey frontal table", furniture).properties == ["colour=grey", "orientation=front", "type=desk"]
    people = lex.domain_properties("people")
    assert lex.parse("man with glasses", people).properties == ["type=person", "hasGlasses=1"]
    assert lex.parse("beard, glasses, old", people).properties == ["hasBeard=1", "hasGlasses=1", "age=old"]


def test_tuna_string_descriptions_mostly_parse(lex, tuna_dir):
    """Sanity check against people: mean Dice of parsed vs. annotated attribute sets."""
    for domain in ("furniture", "people"):
        props = lex.domain_properties(domain)
        scores = []
        for path in sorted((tuna_dir / domain).glob("*.xml")):
            root = ET.parse(path).getroot()
            text = (root.findtext("STRING-DESCRIPTION") or "").strip()
            if root.get("CONDITION") != "-LOC" or not text:
                continue
            gold = {f"{a.get('NAME')}={a.get('VALUE').strip()}" for a in root.find("ATTRIBUTE-SET")}
            got = set(lex.parse(text, props).properties)
            scores.append(2 * len(gold & got) / (len(gold) + len(got)) if gold or got else 1.0)
        assert len(scores) > 100
        assert sum(scores) / len(scores) > 0.7, domain


# -- round trip ------------------------------------------------------


def _round_trip(lex: Lexicon, description: list[str], domain: str, props) -> None:
    text = lex.realise(description, domain)
    result = lex.parse(text, props)
    assert set(result.properties) == set(description), text
    assert result.unknown_words == [], text


@pytest.mark.parametrize("domain", shipped().domains)
def test_round_trip_every_single_property_and_all(lex, domain):
    props = lex.domain_properties(domain)
    assert props
    _round_trip(lex, [], domain, props)
    for prop in props:
        _round_trip(lex, [prop], domain, props)
    _round_trip(lex, list(props), domain, props)
    _round_trip(lex, list(reversed(props)), domain, props)


@pytest.mark.parametrize("domain", shipped().domains)
@settings(max_examples=300, deadline=None)
@given(data=st.data())
def test_round_trip_random_subsets(lex, domain, data):
    props = lex.domain_properties(domain)
    description = data.draw(st.lists(st.sampled_from(props), unique=True).flatmap(st.permutations))
    _round_trip(lex, description, domain, props)


_OUTSIDE_NAMES = st.from_regex(r"zq[a-z]{1,6}(-[a-z]{1,6}){0,2}", fullmatch=True)


@settings(max_examples=200, deadline=None)
@given(
    known=st.lists(st.sampled_from(FACES), unique=True),
    extra=st.lists(_OUTSIDE_NAMES, unique=True, max_size=3),
    data=st.data(),
)
def test_round_trip_with_properties_outside_the_lexicon(lex, known, extra, data):
    description = data.draw(st.permutations(known + extra))
    _round_trip(lex, description, "faces", FACES + extra)


@settings(max_examples=300, deadline=None)
@given(text=st.text(max_size=80), props=st.lists(st.sampled_from(FACES), unique=True))
def test_parse_never_fails_and_stays_in_play(lex, text, props):
    result = lex.parse(text, props)
    assert set(result.properties) <= set(props)
    assert len(result.properties) == len(set(result.properties))
    words = set(tokenize(text)) | {part for w in tokenize(text) for part in w.split("-")}
    assert set(result.unknown_words) <= words


def test_parse_of_a_long_text(lex):
    """4,000 repetitions: the properties once each, every unknown word kept (its speed is no test's business)."""
    sentence = "the woman in a hoodie with dark hair, a hat and no glasses, he said. "
    result = lex.parse(sentence * 4000, FACES)
    assert result.properties == ["female", "hoodie", "dark-hair", "no-glasses"]
    assert result.unknown_words[:3] == ["hat", "he", "said"]  # hat is not in FACES
    assert len(result.unknown_words) == 3 * 4000


# -- the lexicon file -------------------------------------------------------------------


def test_default_path_is_config_lexicon(lex):
    assert Path(lex.source) == config_path("lexicon.yaml")
    assert Path(lex.source).resolve() == (REPO / "config" / "lexicon.yaml").resolve()


def test_config_dir_override(tmp_path, monkeypatch):
    (tmp_path / "lexicon.yaml").write_text("domains: {faces: {noun: face}}\n")
    monkeypatch.setenv("FSREG_CONFIG_DIR", str(tmp_path))
    assert Lexicon.load().noun_for("faces") == "face"


def test_shipped_lexicon_covers_the_brief(lex):
    faces = set(lex.domain_properties("faces"))
    assert {
        "light-hair",
        "dark-hair",
        "short-hair",
        "long-hair",
        "male",
        "female",
        "lab-coat",
        "glasses",
        "no-glasses",
        "t-shirt",
        "hoodie",
        "hat",
        "beard",
    } <= faces
    assert {"red", "green", "blue", "large", "small", "chair", "table", "mug", "ball", "box"} <= set(
        lex.domain_properties("objects")
    )
    assert {"faces", "objects", "locations", "furniture", "people"} <= set(lex.domains)


@pytest.mark.parametrize(
    "data, message",
    [
        ([], "x.yaml: must be a mapping"),
        ({"propertys": {}}, "x.yaml: propertys: unknown key"),
        ({"properties": {"male": {"noun": 3}}}, "x.yaml: properties.male.noun: must be a string"),
        ({"properties": {"male": {"nuon": "man"}}}, "x.yaml: properties.male.nuon: unknown key"),
        ({"properties": {"male": "man"}}, "x.yaml: properties.male: must be a mapping"),
        ({"properties": {"red": {"adjective": "red", "order": "1"}}}, "properties.red.order: must be a whole number"),
        ({"properties": {"red": {"adjective": "red", "order": True}}}, "properties.red.order: must be a whole number"),
        ({"properties": {"red": {"order": 1}}}, "properties.red.order: only used with an adjective"),
        ({"properties": {"hat": {"phrases": "cap"}}}, "properties.hat.phrases: must be a list"),
        ({"properties": {"hat": {"phrases": ["cap", False]}}}, "properties.hat.phrases[1]: must be a string"),
        ({"properties": {"hat": {"phrases": ["..."]}}}, "properties.hat.phrases[0]: '...' has no words"),
        ({"properties": {"hat": {"article": "da"}}}, "properties.hat.article: 'da' is not a function word"),
        ({"properties": {"hat": {"phrases": ["with"]}}}, "properties.hat: phrase 'with' uses only the realiser"),
        ({"properties": {"hat": {"negates": "hat"}}}, "properties.hat.negates: a property cannot negate itself"),
        ({"properties": {1: {}}}, "x.yaml: properties.1: key must be a string"),
        ({"negators": ["without", False]}, "x.yaml: negators[1]: must be a string"),
        ({"function_words": "the"}, "x.yaml: function_words: must be a list"),
        ({"default_noun": 7}, "x.yaml: default_noun: must be a string"),
        ({"domains": {"faces": {"properties": ["hat"]}}}, "domains.faces.properties[0]: 'hat' is not in properties"),
        ({"domains": {"faces": {"colour": "x"}}}, "domains.faces.colour: unknown key"),
        ({"domains": {"faces": ["hat"]}}, "domains.faces: must be a mapping"),
        (
            {"domains": {"faces": {"properties": ["hat", "hat"]}}, "properties": {"hat": {}}},
            "domains.faces.properties[1]: 'hat' listed twice",
        ),
        (
            {
                "domains": {"faces": {"properties": ["hat", "cap"]}},
                "properties": {"hat": {"phrases": ["cap"]}, "cap": {}},
            },
            "domains.faces.properties[1]: phrase 'cap' belongs to both 'hat' and 'cap'",
        ),
        (
            {"domains": {"faces": {"properties": ["male"]}}, "properties": {"male": {"phrases": ["person"]}}},
            "domains.faces.noun: default noun 'person' is also a phrase of 'male'",
        ),
    ],
)
def test_lexicon_errors_name_file_and_path(data, message):
    with pytest.raises(LexiconError) as info:
        Lexicon.from_mapping(data, "x.yaml")
    assert message in str(info.value)


def test_load_errors_name_the_file(tmp_path):
    path = tmp_path / "lexicon.yaml"
    path.write_text("properties:\n  male: {noun: man}\n  male: {noun: guy}\n")
    with pytest.raises(
        LexiconError, match=r"lexicon\.yaml:3: properties\.male: duplicate key 'male' \(first at line 2\)"
    ):
        Lexicon.load(path)
    path.write_text("properties: [unclosed\n")
    with pytest.raises(LexiconError, match=r"lexicon\.yaml:\d+: not valid YAML"):
        Lexicon.load(path)
    path.write_text("properties:\n  male:\n    noun: [man]\n")
    with pytest.raises(LexiconError, match=r"lexicon\.yaml:3: properties\.male\.noun: must be a string"):
        Lexicon.load(path)
    with pytest.raises(LexiconError, match=r"missing\.yaml: file not found"):
        Lexicon.load(tmp_path / "missing.yaml")
    path.write_text("")
    assert Lexicon.load(path).noun_for("faces") == "person"


def test_lexicon_error_is_a_value_error():
    assert issubclass(LexiconError, ValueError)


# -- own domains: attribute=value defaults, the coverage warning, the template (issue 15, item 5) -----------

TABLETOP = """\
domains:
  tabletop:
    preference: [shape=cube, shape=ball, colour=red, colour=blue, size=small, size=large, material=wood,
                 side=left, legs=4, shelf]
    entities:
      o1: [shape=cube, colour=red, size=small]
      o2: [shape=cube, colour=blue, size=small]
      o3: [shape=ball, colour=red, size=large, shelf]
      o4: [shape=cube, colour=red, size=large, legs=4, material=wood, side=left]
dialogue:
  - {time: 1, speaker: robot, target: o1}
  - {time: 2, speaker: human, text: "the large red ball", target: o3}
"""


@pytest.mark.parametrize("description, text", [
    (["colour=red", "shape=cube"], "the red cube"),
    (["shape=cube", "size=small", "colour=red"], "the small red cube"),
    (["material=wood", "type=box", "size=big", "side=left"], "the left big wood box"),
    (["kind=lamp", "state=lit", "hue=amber"], "the lit amber lamp"),
    (["hairColour=auburn", "category=doll"], "the auburn doll"),
    (["shape=cube", "legs=4", "shelf"], "the cube with legs 4 and shelf"),
    (["colour=red", "lit=true"], "the red thing with lit true"),
])
def test_attribute_value_properties_are_said_by_the_default(lex, description, text):
    """attribute=value names the lexicon does not list: the value is the head noun (type, kind, shape, category,
    class) or an adjective in conventional order; anything else is said as its name, read as words."""
    assert lex.realise(description, "tabletop") == text
    sayable = [p for p in description if "=" in p and not p.startswith(("legs=", "lit="))]
    assert all(lex.can_say(p) for p in sayable) and not lex.can_say("shelf") and not lex.can_say("legs=4")


def test_the_parser_hears_what_the_default_says(lex):
    props = ["shape=cube", "shape=ball", "colour=red", "colour=blue", "size=small", "size=large"]
    assert lex.parse("the large red ball", props).properties == ["size=large", "colour=red", "shape=ball"]
    assert set(lex.parse(lex.realise(["shape=cube", "size=small", "colour=blue"], "t"), props).properties) == {
        "shape=cube", "size=small", "colour=blue"}


def test_one_warning_names_what_the_lexicon_cannot_say(tmp_path):
    from fsreg_ros.core.scenario import coverage_warning, unsayable
    from fsreg_ros.core.scenario import load_scenario

    (tmp_path / "tabletop.yaml").write_text(TABLETOP)
    lexicon = Lexicon.load()
    scenario = load_scenario(tmp_path / "tabletop.yaml", lexicon)
    assert unsayable(lexicon, scenario) == {"tabletop": ["legs=4", "shelf"]}
    assert coverage_warning(lexicon, scenario) == (
        'the lexicon has no words for 2 properties, said as their names (e.g. "with legs 4"): legs=4 (tabletop), '
        "shelf (tabletop); write a lexicon for them with --lexicon-template OUT.yaml and give it with --lexicon "
        "OUT.yaml")
    proc = subprocess.run([str(BIN / "fsreg-sim"), str(tmp_path / "tabletop.yaml"), "--json"], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0
    assert proc.stderr == f"fsreg-sim: warning: {coverage_warning(lexicon, scenario)}\n"  # once, not per run
    assert json.loads(proc.stdout)["turns"][0]["text"] == "the small red cube"


def test_the_lexicon_template_is_valid_and_silences_the_warning(tmp_path):
    (tmp_path / "tabletop.yaml").write_text(TABLETOP)
    out = tmp_path / "tabletop-lexicon.yaml"
    written = subprocess.run([str(BIN / "fsreg-sim"), str(tmp_path / "tabletop.yaml"), "--lexicon-template",
                              str(out)], capture_output=True, text=True, timeout=60)
    assert written.returncode == 0 and written.stderr == ""
    assert written.stdout == f"fsreg-sim: wrote {out}: a lexicon skeleton for 2 properties\n"
    text = out.read_text()
    assert text.startswith(f"# Lexicon for {tmp_path / 'tabletop.yaml'}: how to say the 2 properties")
    assert "  legs=4:\n    words: legs 4\n  shelf:\n    words: shelf\n" in text
    assert "  tabletop:\n    noun: thing\n    properties:\n    - legs=4\n    - shelf\n" in text
    used = subprocess.run([str(BIN / "fsreg-sim"), str(tmp_path / "tabletop.yaml"), "--lexicon", str(out)],
                          capture_output=True, text=True, timeout=60)
    assert used.returncode == 0 and used.stderr == ""  # no warning: the lexicon says them now


def test_the_template_of_a_scenario_the_lexicon_fully_covers(table1_path, tmp_path):
    from fsreg_ros.core.scenario import lexicon_template
    from fsreg_ros.core.scenario import load_scenario

    lexicon = Lexicon.load()
    text = lexicon_template(lexicon, load_scenario(table1_path, lexicon), "table1")
    assert text.endswith("# The lexicon can say every property of the scenario: nothing to add.\n{}\n")
    path = tmp_path / "empty.yaml"
    path.write_text(text)
    Lexicon.load(path)


@pytest.mark.parametrize("text, where", [
    ("domains:\n  faces:\n    properties: [unknown-prop]\n",
     "lex.yaml:3: domains.faces.properties[0]: 'unknown-prop' is not in properties"),
    ("properties:\n  stripes: {words: stripes}\ndomains:\n  faces:\n    properties:\n      - stripes\n"
     "      - glasses2\n",
     "lex.yaml:7: domains.faces.properties[1]: 'glasses2' is not in properties"),
    ("properties:\n  stripes: {words: glasses}\ndomains:\n  faces:\n    properties:\n      - stripes\n",
     "lex.yaml:6: domains.faces.properties[0]: phrase 'glasses' belongs to both 'glasses' and 'stripes'"),
])
def test_an_error_in_a_users_lexicon_names_its_own_line_and_item(tmp_path, text, where):
    """Not the index of the merged built-in list (issue 15: ``properties[10]``)."""
    path = tmp_path / "lex.yaml"
    path.write_text(text)
    with pytest.raises(LexiconError) as info:
        Lexicon.load(path)
    assert str(info.value) == f"{tmp_path}/{where}"
