"""The graph fuzzer's inputs: every endpoint's name and valid message, and the hostile inputs made from them.

:func:`templates` gives each endpoint's valid messages (:class:`Template`); the
strategies and catalogues make :class:`Input` s from them (random JSON, structure-aware
mutations, hostile numbers, non-JSON text), each saying whether it must be rejected.
:mod:`fuzzgraph` sends them to a running graph and checks what it did.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

from hypothesis import strategies as st

from fsreg_ros import contract
from fsreg_ros.core.scenario import Scenario

# Every name the fuzzer uses, resolved from the contract (the graph runs un-namespaced).
CONSULTANT = "/" + contract.CONSULTANT.name.replace("<domain>", "{domain}")
MANAGE = "/" + contract.MANAGE.name.replace("<domain>", "{domain}")
DEBUG = "/" + contract.DEBUG.name.replace("<domain>", "{domain}")
SYNC = "/" + contract.SYNC.name
STATUS = "/" + contract.STATUS.name
HUMAN = "/" + contract.HUMAN.name
SEMANTICS = "/" + contract.SEMANTICS.name
REG_REQUEST = "/" + contract.REG_REQUEST.name
LTM_ASSERT = "/" + contract.LTM_ASSERT.name
RR_RESULT = "/" + contract.RR_RESULT.name
REG_EXPRESSION = "/" + contract.REG_EXPRESSION.name
LTM_RESULT = "/" + contract.LTM_ASSERT_RESULT.name
ANNOUNCE = "/" + contract.ANNOUNCE.name
ALIVE = "/" + contract.alive_topic("faces").name
READY = "/" + contract.READY.name
#: Every endpoint fuzzed, for Table 1's one domain.
ENDPOINTS = [CONSULTANT.format(domain="faces"), MANAGE.format(domain="faces"), DEBUG.format(domain="faces"), SYNC,
             STATUS, HUMAN, SEMANTICS, REG_REQUEST, LTM_ASSERT, ANNOUNCE, ALIVE]
#: Topic -> the topic its answers (and rejections) come back on (None: no answers by contract).
REPLY_TOPIC = {HUMAN: RR_RESULT, SEMANTICS: RR_RESULT, REG_REQUEST: REG_EXPRESSION, LTM_ASSERT: LTM_RESULT,
               ANNOUNCE: None, ALIVE: None}

TIME = 1.0  # the sim time the graph stands at while fuzzed
SESSION = "<session>"  # stands for the id of a consultant session the fuzzer keeps open
INCARNATION = 424242  # stands for the consultant's current incarnation (replaced when sent)
LONG = 100_000  # characters in a "very long" string
DEEP = 5_000  # nesting depth of a "deep" value
HUGE = "1" + "0" * 400  # an integer no float can hold
HOSTILE_NUMBERS = ["1e999", "-1e999", "NaN", "Infinity", "-Infinity", "1e308", "-1e308", str(2**64), "-1", HUGE,
                   "-" + HUGE]
#: Hostile numbers every endpoint must refuse (not JSON numbers, or no float holds them).
NON_FINITE = {"1e999", "-1e999", "NaN", "Infinity", "-Infinity", HUGE, "-" + HUGE}
NOT_JSON = ["", "{", "}", "[1,", "null", "nul", "\x00", "{'a': 1}", '{"a": 1}}', "\\ud800", "{\"id\": 1,}"]


@dataclass
class Template:
    """A valid message of one endpoint: which fields it needs and which strings name things."""

    payload: dict
    required: tuple[str, ...]
    names: tuple[str, ...] = ()  # fields holding names the graph must know (str or list of str)
    numbers: tuple[str, ...] = ()  # numeric fields
    mapped_numbers: tuple[tuple[str, str], ...] = ()  # (field, key) of numbers inside a mapping field
    valid_numbers: bool = True  # False: only numbers that must be refused are tried (any other is a change)


@dataclass
class Input:
    """One generated input: JSON text, whether it must be rejected, and how it was made."""

    text: str
    invalid: bool
    how: str


def templates(scenario: Scenario) -> dict[str, list[Template]]:
    """Return valid messages for every endpoint, built from the scenario's names."""
    domain = next(iter(scenario.domains))
    spec = scenario.domains[domain]
    entity, prop = next(iter(spec.entities)), spec.preference[0]
    debug = [
        Template({"op": "snapshot"}, ("op",)),
        Template({"op": "holds", "property": prop, "entities": [entity]}, ("op", "property", "entities"),
                 ("property", "entities")),
        Template({"op": "wm", "entity": entity}, ("op", "entity"), ("entity",)),
        Template({"op": "affirm", "property": prop, "entities": [entity], "cause": "rr", "time": TIME},
                 ("op", "property", "entities", "cause"), ("property", "entities", "cause"), ("time",)),
        Template({"op": "encode", "entity": entity, "properties": [prop], "cause": "speaker", "time": TIME},
                 ("op", "entity", "properties", "cause"), ("entity", "properties", "cause"), ("time",)),
    ]
    consultant = [
        Template({"op": "info"}, ("op",)),
        Template({"op": "open", "target": entity, "context": list(spec.entities)}, ("op",), ("target", "context")),
        Template({"op": "open", "first": {"property": prop, "cause": "rr", "time": TIME}}, ("op",)),
        # A session the fuzzer keeps open (SESSION is replaced by its id when sent).
        # 'cause' must be present but may be null (check without encoding): not "required" here.
        Template({"op": "narrow", "session": SESSION, "property": prop, "cause": "reg-distractor", "time": TIME},
                 ("op", "session", "property"), ("session", "property", "cause"), ("time",)),
        Template({"op": "walk", "session": SESSION, "steps": [{"property": prop, "group": prop}],
                  "cause": "reg-distractor", "time": TIME}, ("op", "session", "steps"), ("session",), ("time",)),
        Template({"op": "rule_out", "session": SESSION}, ("op", "session"), ("session",)),
        Template({"op": "close", "session": SESSION, "encode": [prop], "time": TIME}, ("op", "session"),
                 ("session", "encode"), ("time",)),
    ]
    manage = [
        Template({"op": "configure", "policy": {"policy": "decay", "decay_period": 10.0}, "time": TIME},
                 ("op", "policy"), ("op",)),
        Template({"op": "decay", "ticks": [TIME]}, ("op", "ticks"), ("op",), ("ticks",)),
        Template({"op": "advance", "time": TIME}, ("op",), ("op",), ("time",)),
        Template({"op": "evict", "count": 1, "time": TIME}, ("op", "count"), ("op",), ("count", "time")),
        Template({"op": "size"}, ("op",), ("op",)),
        Template({"op": "reset", "client": "fuzzer"}, ("op",), ("op",)),
    ]
    return {
        CONSULTANT.format(domain=domain): consultant,
        MANAGE.format(domain=domain): manage,
        DEBUG.format(domain=domain): debug,
        SYNC: [Template({"time": TIME}, ("time",), (), ("time",))],
        STATUS: [Template({}, ())],
        HUMAN: [
            Template({"id": 0, "description": [prop], "time": TIME}, ("id", "description"), ("description",),
                     ("time",)),
            Template({"id": 0, "text": f"the {prop} one", "time": TIME}, ("id", "text"), (), ("time",)),
        ],
        SEMANTICS: [Template({"id": 0, "description": [prop], "time": TIME}, ("id", "description"),
                             ("description",), ("time",))],
        REG_REQUEST: [Template({"id": 0, "target": entity, "time": TIME}, ("id", "target"), ("target",),
                               ("time",))],
        LTM_ASSERT: [Template({"domain": domain, "entity": entity, "properties": {prop: 0.9}, "id": 0},
                              ("domain", "entity", "properties"), ("domain", "properties"),
                              mapped_numbers=(("properties", prop),))],
        # The consultant's current incarnation, ready: what a consultant announces after a configure.
        ANNOUNCE: [Template({"domain": domain, "incarnation": INCARNATION, "ready": True,
                             "memory": {"policy": "decay", "decay_period": 10.0}},
                            ("domain", "incarnation", "ready"), (), ("incarnation",), valid_numbers=False)],
        ALIVE: [Template({"domain": domain, "incarnation": INCARNATION, "ready": True,
                          "memory": {"policy": "decay", "decay_period": 10.0}},
                         ("domain", "incarnation", "ready"), (), ("incarnation",), valid_numbers=False)],
    }


# ------------------------------------------------------------------ strategies
def json_values(max_leaves: int = 12) -> st.SearchStrategy:
    """Any JSON value (finite numbers; strings may hold any code point but a surrogate)."""
    leaves = st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False, allow_infinity=False) | st.text()
    return st.recursive(leaves, lambda kids: st.lists(kids, max_size=4) | st.dictionaries(st.text(), kids, max_size=4),
                        max_leaves=max_leaves)


WRONG = {  # a value of each JSON kind, to give a field the wrong type
    "null": "null", "bool": "true", "int": "7", "float": "2.5", "str": '"x"', "list": "[]", "object": "{}",
    "list-of-ints": "[1, 2]",
}


def kinds(value: Any, name: str) -> set[str]:
    """Return the JSON kinds a field accepts, judged from its valid value."""
    if name == "id":
        return {"int", "str"}
    if isinstance(value, bool):
        return {"bool"}
    if isinstance(value, (int, float)):
        return {"int", "float"}
    if isinstance(value, str):
        return {"str"}
    if isinstance(value, list):
        return {"list"}
    return {"object"}


def _string_list(value: Any) -> bool:
    return isinstance(value, list) and bool(value) and isinstance(value[0], str)


def _with(payload: dict, key: str, raw: str) -> str:
    """``payload`` as JSON text with field ``key`` set to the raw JSON ``raw``."""
    marker = "\u0000fuzz\u0000"
    return json.dumps({**payload, key: marker}).replace(json.dumps(marker), raw)


@st.composite
def mutations(draw, template: Template, fresh_id: int) -> Input:
    """One structure-aware mutation of ``template``."""
    payload = dict(template.payload)
    if "id" in payload:
        payload["id"] = fresh_id
    fields = list(payload)
    kind = draw(st.sampled_from(["drop", "wrong-type", "unknown-name", "hostile-number", "surrogate", "long",
                                 "deep", "extra", "valid"]))
    if kind == "drop" and template.required:
        key = draw(st.sampled_from(template.required))
        del payload[key]
        return Input(json.dumps(payload), True, f"drop {key}")
    if kind == "wrong-type" and template.required:
        key = draw(st.sampled_from(template.required))
        options = sorted(k for k in WRONG if k not in kinds(payload[key], key)
                         and (k != "list-of-ints" or _string_list(payload[key])))
        wrong = draw(st.sampled_from(options))
        return Input(_with(payload, key, WRONG[wrong]), True, f"{key} as {wrong}")
    if kind in ("unknown-name", "surrogate", "long") and template.names:
        key = draw(st.sampled_from(template.names))
        name = {"unknown-name": draw(st.text(min_size=1, max_size=20).map(lambda s: "zz-" + s)),
                "surrogate": "face\ud800", "long": "n" * LONG}[kind]
        value = [name] if isinstance(payload[key], list) else (
            {name: 0.9} if isinstance(payload[key], dict) else name)
        return Input(json.dumps({**payload, key: value}), True, f"{key} {kind}")
    if kind == "hostile-number" and template.numbers:
        key = draw(st.sampled_from(template.numbers))
        number = draw(st.sampled_from(hostile_numbers(template)))
        raw = f"[{number}]" if isinstance(payload[key], list) else number
        return Input(_with(payload, key, raw), number in NON_FINITE, f"{key} = {number}")
    if kind == "surrogate" or kind == "long":  # no name field: into any string field (may be accepted)
        strings = [k for k in fields if isinstance(payload[k], str)] or ["extra"]
        key = draw(st.sampled_from(strings))
        value = "x\ud800" if kind == "surrogate" else "x" * LONG
        return Input(json.dumps({**payload, key: value}), False, f"{key} {kind} (free text)")
    if kind == "deep":
        key = draw(st.sampled_from(fields)) if fields else "deep"
        raw = "[" * DEEP + "]" * DEEP
        return Input(_with(payload, key, raw), key in template.required, f"{key} nested {DEEP} deep")
    if kind == "extra":
        extra = draw(st.dictionaries(st.text(min_size=1, max_size=8).filter(lambda k: k not in payload),
                                     json_values(4), min_size=1, max_size=3))
        return Input(json.dumps({**payload, **extra}), False, f"extra fields {sorted(extra)}")
    return Input(json.dumps(payload), False, "valid")


def hostile_numbers(template: Template) -> list[str]:
    """Return the hostile numbers to try on ``template``'s numeric fields."""
    return HOSTILE_NUMBERS if template.valid_numbers else [n for n in HOSTILE_NUMBERS if n in NON_FINITE]


def number_inputs(template: Template, payload) -> list[Input]:
    """Every hostile number in every numeric field of ``template`` (``payload()`` gives a fresh valid one)."""
    out = []
    for key in template.numbers:
        for number in hostile_numbers(template):
            raw = f"[{number}]" if isinstance(template.payload[key], list) else number
            out.append(Input(_with(payload(), key, raw), number in NON_FINITE, f"{key} = {number}"))
    for key, inner in template.mapped_numbers:
        for number in hostile_numbers(template):
            mapping = _with(template.payload[key], inner, number)
            out.append(Input(_with(payload(), key, mapping), number in NON_FINITE, f"{key}.{inner} = {number}"))
    return out


def catalogue(template: Template, fresh_ids, raw: bool = True) -> list[Input]:
    """Every hostile mutation of ``template`` once, field by field (the deterministic part of a run).

    ``raw``: also the texts that are not JSON (they do not depend on the template, so
    an endpoint needs them once).
    """
    base = dict(template.payload)
    out = []

    def payload() -> dict:
        return {**base, "id": next(fresh_ids)} if "id" in base else dict(base)

    for key in template.required:
        out.append(Input(json.dumps({k: v for k, v in payload().items() if k != key}), True, f"drop {key}"))
        for wrong in sorted(k for k in WRONG if k not in kinds(base[key], key)):
            if wrong != "list-of-ints" or _string_list(base[key]):
                out.append(Input(_with(payload(), key, WRONG[wrong]), True, f"{key} as {wrong}"))
    for key in template.names:
        for kind, name in (("unknown-name", "zz-unknown"), ("surrogate", "face\ud800"), ("long", "n" * LONG)):
            value = [name] if isinstance(base[key], list) else ({name: 0.9} if isinstance(base[key], dict) else name)
            out.append(Input(json.dumps({**payload(), key: value}), True, f"{key} {kind}"))
    out += number_inputs(template, payload)
    for key in base:
        if isinstance(base[key], str) and key not in template.names:
            out.append(Input(json.dumps({**payload(), key: "x\ud800"}), False, f"{key} surrogate (free text)"))
            out.append(Input(json.dumps({**payload(), key: "x" * LONG}), False, f"{key} long (free text)"))
    for key in list(base) or ["deep"]:
        out.append(Input(_with(payload(), key, "[" * DEEP + "]" * DEEP), key in template.required,
                         f"{key} nested {DEEP} deep"))
    out.append(Input(json.dumps({**payload(), "zz-extra": {"a": [1, None]}}), False, "extra field"))
    out += [Input(text, True, f"not JSON {text[:12]!r}") for text in NOT_JSON] if raw else []
    return out


def hostile(template: Template, fresh_ids, extra: bool = True) -> list[Input]:
    """Return the hostile inputs of ``template``.

    Numbers (in every numeric field, and with ``extra`` in an extra field), surrogate and
    overlong names.
    """
    base = dict(template.payload)

    def payload() -> dict:
        return {**base, "id": next(fresh_ids)} if "id" in base else dict(base)

    out = number_inputs(template, payload)
    for number in HOSTILE_NUMBERS if extra else ():
        out.append(Input(_with(payload(), "zz-extra", number), number in NON_FINITE - {HUGE, "-" + HUGE},
                         f"extra field = {number}"))
    for key in template.names:
        for kind, name in (("surrogate", "face\ud800"), ("long", "n" * LONG)):
            value = [name] if isinstance(base[key], list) else ({name: 0.9} if isinstance(base[key], dict) else name)
            out.append(Input(json.dumps({**payload(), key: value}), True, f"{key} {kind}"))
    return out


def raw_inputs() -> st.SearchStrategy:
    """Random JSON (a non-object must be rejected) and text that is not JSON at all."""
    any_json = json_values().map(
        lambda v: Input(json.dumps(v), not isinstance(v, dict), f"random JSON {type(v).__name__}"))
    not_json = st.sampled_from(NOT_JSON).map(lambda s: Input(s, True, f"not JSON {s[:12]!r}"))
    return any_json | not_json


def inputs(endpoint_templates: list[Template], fresh_ids) -> st.SearchStrategy:
    """Generate inputs for one endpoint: mostly mutations of its valid messages, some raw."""
    mutated = st.sampled_from(endpoint_templates).flatmap(lambda t: mutations(t, next(fresh_ids)))
    return st.one_of(mutated, mutated, mutated, raw_inputs())
