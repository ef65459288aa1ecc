"""Fuzzing the running node graph: endpoints, generated inputs, and the checks on each.

Used by ``test/ros/test_fuzz_graph.py`` (bounded, fixed seed) and ``scripts/fuzz.py``
(longer runs).  The graph is the runner's (``graph.graph_nodes``) in one process on
sim time (``rosutil.RosSession``), the player left out; the test talks through the probe.

Every input is one of:

* random JSON (any value, any object) or non-JSON text;
* a structure-aware mutation of a valid message of that endpoint: a required field
  dropped or given the wrong type, a known name replaced by an unknown one, a number
  replaced by a hostile one (``1e999``, ``NaN``, ``Infinity``, 1e308, 2**64, a 401-digit
  integer, also as a certainty in ``ltm/assert``), a lone surrogate, a very long string,
  deep nesting, extra fields;
* each hostile input right after a malformed message on the same endpoint
  (:func:`fuzz_after_malformed`: a node once died when one logging call site saw a
  warning and then an error).

Each input carries whether it MUST be rejected (``invalid``) or may be accepted.  The
checks (:meth:`Fuzzer.check`): the call or message is answered (topics: a message on
the reply topic; ``/ltm/assert`` naming no consultant's domain has no reply by
contract), an invalid input is rejected with a reason (an ``error`` field), a
rejected input leaves every domain's WM and LTM and the WM Manager's status exactly
as they were (a consultant's liveliness lapse under load, which the WM Manager's status
shows and heals with a configure, is not counted: after a lapse, or a difference only in
the liveliness and configuration flags, the fuzzer waits until the graph is ready with every
consultant reachable and configured and compares what matters, :meth:`Fuzzer.healed`), and no callback
raised (an exception out of a callback is a node that dies in a real process).  A message
that has no reply by contract (``consultant/announce``, an ``ltm/assert`` for no consultant's
domain) is followed by one that must be answered or seen after it on the same topic, so the
check never waits on a silence.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Optional

import itertools

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rosutil import RosSession, Timeout

from fsreg_ros import contract
from fsreg_ros.ros.carrier import CarrierError
from fsreg_ros.core.scenario import Scenario, load_scenario

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
REPLY_TIMEOUT = 5.0
HEAL_TIMEOUT = 15.0  # at most this long for the graph to be ready again after a consultant's liveliness lapse
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


@dataclass
class Outcome:
    """What one endpoint did with the inputs it was sent."""

    tried: int = 0
    rejected: int = 0
    accepted: int = 0
    unanswered: list[str] = field(default_factory=list)
    crashes: list[str] = field(default_factory=list)
    accepted_invalid: list[str] = field(default_factory=list)
    changed_by_rejected: list[str] = field(default_factory=list)
    reasonless: list[str] = field(default_factory=list)

    def failures(self) -> list[str]:
        return [
            *(f"unanswered: {s}" for s in self.unanswered),
            *(f"crash: {s}" for s in self.crashes),
            *(f"accepted an invalid input: {s}" for s in self.accepted_invalid),
            *(f"a rejected input changed memory: {s}" for s in self.changed_by_rejected),
            *(f"rejected without a reason: {s}" for s in self.reasonless),
        ]


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


# ---------------------------------------------------------------------- runner
class Fuzzer:
    """Sends inputs to one in-process graph and checks what it does with them."""

    def __init__(self, start: Callable[[], RosSession], scenario: Scenario) -> None:
        self.start = start
        self.scenario = scenario
        self.domains = list(scenario.domains)
        self.outcomes: dict[str, Outcome] = {}
        self.restarts = 0
        self._markers = itertools.count()
        self.state: Optional[dict] = None  # the last snapshot, while nothing has been accepted since
        self._open()
        spec = scenario.domains[self.domains[0]]
        self.seed_wm = {"op": "encode", "entity": next(iter(spec.entities)), "properties": list(spec.preference[:2]),
                        "cause": "speaker", "time": TIME}

    def _open(self) -> None:
        self.state = None
        self.g = self.start()
        self.inboxes = {topic: self.g.listen(topic) for topic in set(REPLY_TOPIC.values()) if topic is not None}
        # Every readiness the WM Manager publishes (a deeper reader than the latched writer's 1: none is missed).
        self.readiness = self.g.listen(READY, replace(contract.READY_QOS, depth=100))
        self._lapses_seen = 0

    def restart(self) -> None:
        """Start a fresh graph after a callback raised (a real node process would have died)."""
        self.close()
        self.restarts += 1
        self._open()

    def close(self) -> None:
        self.g.close()

    def session(self, service: str) -> str:
        """Open a REG session at ``service`` (its target: the first entity); return its id."""
        spec = self.scenario.domains[self.domains[0]]
        return self.g.call(service, {"op": "open", "target": next(iter(spec.entities))},
                           timeout=REPLY_TIMEOUT)["session"]

    # ----------------------------------------------------------- memory state
    def snapshot(self) -> dict:
        """Every domain's WM queues and LTM, and the WM Manager's status.

        LTM is seen through ``info``: its ``version`` changes whenever LTM does, and it
        lists the entities, the preference order, the threshold and the events published.
        """
        state: dict[str, Any] = {"status": self.g.call(STATUS, {}, timeout=REPLY_TIMEOUT)}
        for domain in self.domains:
            service, debug = CONSULTANT.format(domain=domain), DEBUG.format(domain=domain)
            state[domain] = {"info": self.g.call(service, {"op": "info"}, timeout=REPLY_TIMEOUT),
                             "wm": self.g.call(debug, {"op": "snapshot"}, timeout=REPLY_TIMEOUT)}
        return state

    def lapsed(self) -> bool:
        """Whether the WM Manager found a consultant's liveliness lapsed since the last call.

        In this one-process graph a consultant's liveliness shows only through its alive
        writes (every 0.25 s, lease 1 s), which wait on the one executor: under load the
        lease can run out and heal, the status flipping to unreachable and back.
        """
        lapses = sum(1 for ready in self.readiness for dom in ready["domains"].values() if dom["reachable"] is False)
        seen, self._lapses_seen = self._lapses_seen, lapses
        return lapses > seen

    def healed(self) -> dict:
        """Return a snapshot taken while the graph is ready, every consultant reachable and configured.

        Waits (at most ``HEAL_TIMEOUT`` s) until the snapshot's own status shows it: a lapse
        that heals is followed by a configure, and under load another lapse may begin while
        a snapshot is taken, so the status is judged inside the snapshot compared.
        """
        taken: list[dict] = []

        def steady() -> bool:
            taken[:] = [self.snapshot()]
            return _healthy(taken[0])
        self.g.spin_until(steady, HEAL_TIMEOUT, what="the graph ready, every consultant reachable and configured")
        self.lapsed()
        return taken[0]

    def state_before(self) -> dict:
        """Return the snapshot before an input, with something in WM so that a change to it can be seen."""
        if self.state is None or not _healthy(self.state):  # never compare with a snapshot taken in a lapse
            self.state = self.healed()
        domain = self.domains[0]
        if not self.state[domain]["wm"]["queues"]:
            self.g.call(MANAGE.format(domain=domain),
                        {"op": "configure", "policy": {"policy": "decay", "decay_period": 10.0}, "time": TIME})
            self.g.call(DEBUG.format(domain=domain), self.seed_wm)
            self.state = self.healed()
        return self.state

    # ------------------------------------------------------------------ sending
    def call(self, service: str, text: str) -> tuple[Optional[dict], Optional[str]]:
        """Call ``service`` with raw JSON text: (reply, None) or (None, error reason); Timeout if unanswered."""
        from diagnostic_msgs.srv import AddDiagnostics

        if SESSION in text:
            text = text.replace(SESSION, self.session(service))
        client = self.g.client(service)
        self.g.wait_service(service, REPLY_TIMEOUT)
        future = client.client.call_async(AddDiagnostics.Request(load_namespace=text))
        try:
            return self.g.run(client.result(future, REPLY_TIMEOUT), REPLY_TIMEOUT + 1.0), None
        except CarrierError as err:
            if err.kind == "timeout":
                raise Timeout(f"{service}: no answer in {REPLY_TIMEOUT} s") from None
            return None, str(err)

    def publish(self, topic: str, text: str) -> tuple[Optional[dict], Optional[str]]:
        """Publish raw text on ``topic``; (reply, None), (None, reason), or (None, None) if no reply is due.

        A message with no reply by contract is followed by one that must be answered
        (or seen) after it, so that it has been handled when this returns.
        """
        if topic == ANNOUNCE:
            self.g.publish(topic, text.replace(str(INCARNATION), str(self.incarnation())), contract.ANNOUNCE.qos)
            self._announce_marker()
            return None, None
        if topic == ALIVE:  # read by RR's and REG's consultant ports: a REG answer comes after it
            self.g.publish(topic, text.replace(str(INCARNATION), str(self.incarnation())), contract.ALIVE.qos)
            self._reg_marker()
            return None, None
        inbox = self.inboxes[REPLY_TOPIC[topic]]
        before = len(inbox)
        self.g.publish(topic, text)
        if topic == LTM_ASSERT and not self._names_a_consultant(text):
            self._ltm_marker(inbox)
            return None, None
        self.g.spin_until(lambda: len(inbox) > before, REPLY_TIMEOUT, what=f"a reply on {REPLY_TOPIC[topic]}")
        reply = inbox[before]
        if reply.get("error"):
            return None, str(reply["error"])
        return reply, None

    def incarnation(self) -> int:
        """Return the current incarnation of the first domain's consultant (the WM Manager's view)."""
        return self.g.call(STATUS, {}, timeout=REPLY_TIMEOUT)["incarnation"][self.domains[0]]

    def _ltm_marker(self, inbox) -> None:
        """Publish an assertion the consultant must refuse (no entity) and wait for its refusal."""
        marker = f"fuzz-sync-{next(self._markers)}"
        self.g.publish(LTM_ASSERT, {"domain": self.domains[0], "id": marker})
        self.g.spin_until(lambda: inbox.latest(id=marker) is not None, REPLY_TIMEOUT, what=f"the reply to {marker}")

    def _reg_marker(self) -> None:
        """Ask REG for a description (through its consultant port) and wait for the answer."""
        marker = f"fuzz-sync-{next(self._markers)}"
        inbox = self.inboxes[REG_EXPRESSION]
        entity = next(iter(self.scenario.domains[self.domains[0]].entities))
        self.g.publish(REG_REQUEST, {"id": marker, "target": entity, "time": TIME})
        self.g.spin_until(lambda: inbox.latest(id=marker) is not None, REPLY_TIMEOUT, what=f"the reply to {marker}")
        self.state = None  # REG encoded what it said

    def _announce_marker(self) -> None:
        """Announce the current incarnation with a marked setting; wait until the WM Manager reports it."""
        marker = next(self._markers)
        domain = self.domains[0]
        self.g.publish(ANNOUNCE, {"domain": domain, "incarnation": self.incarnation(), "ready": True,
                                  "memory": {"policy": "none", "fuzz_marker": marker}}, contract.ANNOUNCE.qos)
        self.g.spin_until(
            lambda: (self.g.call(STATUS, {}, timeout=REPLY_TIMEOUT)["running"][domain] or {}).get("fuzz_marker")
            == marker, REPLY_TIMEOUT, what=f"announce marker {marker}")
        self.state = None  # the status now reports the marker

    def _configured(self, incarnation: int) -> None:
        """After an accepted ``reset``: wait until the WM Manager has configured the new incarnation.

        (The reset's reply comes before that configure, so a snapshot taken at once would
        see the graph become ready again and blame the next input.)
        """
        domain = self.domains[0]

        def configured() -> bool:
            status = self.g.call(STATUS, {}, timeout=REPLY_TIMEOUT)
            return status["incarnation"][domain] == incarnation and status["ready"] is True
        self.g.spin_until(configured, REPLY_TIMEOUT, what=f"incarnation {incarnation} configured after a reset")

    def _names_a_consultant(self, text: str) -> bool:
        """Whether an ``/ltm/assert`` message is due a reply: malformed, or for a known domain."""
        try:
            data = json.loads(text)
        except (ValueError, RecursionError):
            return True
        if not isinstance(data, dict) or not isinstance(data.get("domain"), str):
            return True
        return data["domain"] in self.domains

    # ------------------------------------------------------------------ checking
    def check(self, endpoint: str, given: Input, verify_memory: bool = True) -> None:
        """Send one input to ``endpoint`` and record what happened (never raises for a finding).

        ``verify_memory`` false: a rejection is not compared with a snapshot (for inputs
        whose effect on memory is checked elsewhere).
        """
        outcome = self.outcomes.setdefault(endpoint, Outcome())
        outcome.tried += 1
        label = f"{given.how}: {_clip(given.text)}"
        try:
            before = self.state_before()
        except Exception as err:  # noqa: BLE001 - the graph was already broken by an earlier input
            outcome.crashes.append(f"before {label}: {type(err).__name__}: {_clip(str(err))}")
            self.restart()
            return
        try:
            send = self.publish if endpoint in REPLY_TOPIC else self.call
            reply, reason = send(endpoint, given.text)
        except Timeout as err:
            outcome.unanswered.append(f"{label} ({err})")
            return
        except Exception as err:  # noqa: BLE001 - a callback raised: the node would have died
            outcome.crashes.append(f"{label}: {type(err).__name__}: {_clip(str(err))}")
            self.restart()
            return
        if reply is None and reason is None:  # nobody's message: no reply by contract
            return
        if reason is None:
            outcome.accepted += 1
            self.state = None
            if endpoint == MANAGE.format(domain=self.domains[0]) and "cleared" in reply:
                self._configured(reply["incarnation"])
            if given.invalid:
                outcome.accepted_invalid.append(f"{label} -> {_clip(json.dumps(reply))}")
            return
        outcome.rejected += 1
        if not reason.strip():
            outcome.reasonless.append(label)
        if not verify_memory:
            return
        try:
            after = self.snapshot()
        except Exception as err:  # noqa: BLE001
            outcome.crashes.append(f"after {label}: {type(err).__name__}: {_clip(str(err))}")
            self.restart()
            return
        was, now = before, after
        lapsed = self.lapsed()  # (always asked: a lapse is counted once, at the first check after it)
        if after != before and (lapsed or not _healthy(after) or _reconfigured(after) == _reconfigured(before)):
            # a lapse under load is no change of state: compare what matters once healed and configured
            try:
                after = self.healed()
            except Timeout as err:  # never healed: the input left the graph unready
                outcome.changed_by_rejected.append(f"{label} ({_diff(before, after)}; {err})")
                self.state = None
                return
            was, now = _reconfigured(before), _reconfigured(after)
        self.state = after
        if now != was:
            outcome.changed_by_rejected.append(f"{label} ({_diff(was, now)})")

    def report(self, endpoints: Optional[list[str]] = None) -> str:
        lines = []
        for endpoint, o in sorted(self.outcomes.items()):
            if endpoints is not None and endpoint not in endpoints:
                continue
            lines.append(f"{endpoint}: {o.tried} inputs, {o.rejected} rejected, {o.accepted} accepted, "
                         f"{len(o.crashes)} crashes, {len(o.unanswered)} unanswered, "
                         f"{len(o.accepted_invalid)} invalid accepted, "
                         f"{len(o.changed_by_rejected)} changed by rejected")
            lines += [f"    {f}" for f in _dedupe(o.failures())]
        return "\n".join(lines)


#: The status fields a consultant's liveliness lapse and the configure after it change by themselves.
LIVELINESS_FIELDS = ("ready", "configured", "reachable", "running")


def _healthy(state: dict) -> bool:
    """Whether a snapshot's status shows the graph ready, every consultant reachable and configured."""
    status = state["status"]
    return (status["ready"] is True and all(v is True for v in status["reachable"].values())
            and all(v is True for v in status["configured"].values()))


def _reconfigured(state: dict) -> dict:
    """``state`` without what a consultant's liveliness lapse and the WM Manager's configure after it change.

    The status's liveliness and configuration flags (``ready``, ``configured``,
    ``reachable``), its ``running`` (the consultant announces what it runs after a
    configure, over the fuzzer's own announcements), and each domain's ``wm_version`` (a
    configure is a call that touches WM).  What matters is still compared: each domain's
    WM queues (the same policy keeps them), LTM (``info``), and the status's configuration
    values (``memory``, ``incarnation``, ...).
    """
    return {key: {**value, **dict.fromkeys(LIVELINESS_FIELDS)} if key == "status"
            else {**value, "info": {**value["info"], "wm_version": None}} for key, value in state.items()}


def _clip(text: str, limit: int = 160) -> str:
    text = text.encode("unicode_escape", "backslashreplace").decode("ascii")
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} chars)"


def _diff(before: dict, after: dict) -> str:
    keys = [f"{k}.{j}" for k in before for j in before[k] if before[k][j] != after.get(k, {}).get(j)]
    return "changed: " + ", ".join(keys)


def _dedupe(lines: list[str], limit: int = 12) -> list[str]:
    counts = Counter(lines)
    out = [f"{line}" + (f" (x{n})" if n > 1 else "") for line, n in counts.items()]
    return out[:limit] + ([f"... {len(out) - limit} more"] if len(out) > limit else [])


def start_graph(scenario_path: Path, tmp_path: Path, service_timeout: float = 2.0) -> RosSession:
    """Start the runner's nodes (not the player) in one in-process graph on sim time, at TIME, synced.

    The WM Manager's deadline per consultant call is short, so a stuck call costs the
    fuzz little.
    """
    from fsreg_ros.core.simulation.simulator import Options
    from fsreg_ros.tools.graph import graph_nodes
    from test_graph import NODE_CLASSES

    g = RosSession()
    scenario = load_scenario(scenario_path)
    for spec in graph_nodes(scenario, scenario_path, Options(memory={"policy": "decay"}), tmp_path / "r.json")[:-1]:
        params = dict(spec.parameters)
        if spec.executable == "wm_manager":
            params["service_timeout"] = service_timeout
        if spec.executable == "consultant":
            params["debug"] = True  # the fuzzer reads WM and LTM through the debug service
        sim_time = params.pop("use_sim_time", False)
        g.add(NODE_CLASSES[spec.executable], use_sim_time=sim_time, name=spec.name, **params)
    g.set_time(TIME)
    g.call(SYNC, {"time": TIME}, timeout=10.0)
    return g


#: Sent before each hostile input by :func:`fuzz_after_malformed`.
MALFORMED = Input("{", True, "malformed (before a hostile input)")


def fuzz_after_malformed(fuzzer: Fuzzer, endpoint: str, first_id: int = 50_000) -> None:
    """Send each hostile input of ``endpoint`` right after a malformed message."""
    ids = itertools.count(first_id)
    for i, template in enumerate(templates(fuzzer.scenario)[endpoint]):
        for given_input in hostile(template, ids, extra=i == 0):  # extra fields: the endpoint's, once
            fuzzer.check(endpoint, MALFORMED, verify_memory=False)  # the catalogue checks it changes nothing
            fuzzer.check(endpoint, given_input)


def fuzz_catalogue(fuzzer: Fuzzer, endpoint: str, first_id: int = 10_000) -> None:
    """Send every catalogued hostile input to ``endpoint``."""
    ids = itertools.count(first_id)
    for i, template in enumerate(templates(fuzzer.scenario)[endpoint]):
        for given_input in catalogue(template, ids, raw=i == 0):
            fuzzer.check(endpoint, given_input)


def fuzz_generated(fuzzer: Fuzzer, endpoint: str, examples: int, first_id: int = 30_000) -> None:
    """Send ``examples`` generated inputs (fixed seed) to ``endpoint``."""
    strategy = inputs(templates(fuzzer.scenario)[endpoint], itertools.count(first_id))

    @settings(max_examples=examples, derandomize=True, deadline=None, database=None,
              suppress_health_check=list(HealthCheck))
    @given(strategy)
    def fuzz(given_input):
        fuzzer.check(endpoint, given_input)

    fuzz()


def fuzz_endpoint(fuzzer: Fuzzer, endpoint: str, examples: int, first_id: int = 10_000) -> None:
    """Send every catalogued hostile input, then ``examples`` generated ones (fixed seed), to ``endpoint``."""
    fuzz_catalogue(fuzzer, endpoint, first_id)
    fuzz_generated(fuzzer, endpoint, examples, first_id + 500)
