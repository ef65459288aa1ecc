"""The fsreg message contract: every topic and service, its QoS and its JSON schema.

This module is the one owner of the wire contract (docs/semantics.md §7).  Nodes, the remote
consultant port, the graph runner and the tests take names, QoS profiles and schemas
from here; ``docs/design.md`` lists them (a test checks the table against
:func:`message_table`), and ``scripts/export_schemas.py`` writes their JSON Schemas.

Names are **relative** (``rr/result``, ``consultant/faces``): a node started with
``--ros-args -r __ns:=/robot1`` (or ``fsreg-graph --namespace robot1``) uses
``/robot1/rr/result``, so two graphs in different namespaces share a ROS domain without
hearing each other.  ``/clock`` is the one absolute name (the ROS convention): every
sim-time node of the domain follows it, so a namespaced *sim-time* graph is given its
own clock by remapping ``/clock`` into its namespace (see :func:`clock_remap`).

Every topic carries ``std_msgs/msg/String`` whose ``data`` is one JSON object; every
service is ``diagnostic_msgs/srv/AddDiagnostics`` with the request JSON in
``load_namespace`` and the reply JSON in ``message`` (``success=false`` means the reply
is an :class:`ErrorReply`).  The pydantic models below are the JSON schemas; they
allow extra fields (a newer peer may add some) but fix the type of every named one.
"""

from __future__ import annotations

from dataclasses import dataclass
import types
from typing import Any, Literal, Optional, Union, get_args, get_origin

from pydantic import BaseModel, ConfigDict, TypeAdapter, ValidationError, model_validator
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from .codec import MessageError, describe, printable

Id = Union[str, int]
Number = Union[int, float]


def _qos(depth: int, latched: bool = False) -> QoSProfile:
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


# ------------------------------------------------------------------ QoS profiles
#: ``wm/state`` readers: latched, reliable, depth 10 so a late joiner gets the state of
#: up to 10 consultants (a reader's depth must be at least the number of writers).
STATE_QOS = _qos(10, latched=True)
#: ``wm/state`` writer (one per consultant): latched, only its latest state kept.
STATE_PUB_QOS = _qos(1, latched=True)
#: ``wm/events``: reliable, volatile, deep (one reset or decay tick emits many events).
EVENTS_QOS = _qos(1000)
#: The dialogue pipeline (human, semantics, RR results, REG requests and expressions).
PIPELINE_QOS = _qos(100)
#: Everything else: reliable, volatile, depth 10 (the rclpy default).
DEFAULT_QOS = _qos(10)


# ------------------------------------------------------------------ schemas
class Message(BaseModel):
    """Base of every schema: strict types, no NaN/Infinity, extra fields allowed."""

    model_config = ConfigDict(strict=True, allow_inf_nan=False, extra="allow")


class ErrorReply(Message):
    """A failed service call (``success=false``) or an error on a reply topic."""

    error: str
    kind: Optional[str] = None
    id: Optional[Id] = None


class Stamp(Message):
    """When and in which turn something was said (robot-clock seconds; turn index)."""

    time: Optional[Number] = None
    turn: Optional[int] = None


class HumanUtterance(Stamp):
    """``dialogue/human``: what the human said, as text or as properties."""

    id: Id
    text: Optional[str] = None
    description: Optional[list[str]] = None
    domain: Optional[str] = None

    @model_validator(mode="after")
    def _one_form(self) -> "HumanUtterance":
        if (self.text is None) == (self.description is None):
            raise ValueError("give exactly one of 'text' and 'description'")
        return self


class Semantics(Stamp):
    """``dialogue/semantics``: the parser's reading of one utterance, for RR."""

    id: Id
    description: list[str]
    domain: Optional[str] = None
    text: Optional[str] = None
    unknown_words: Optional[list[str]] = None


class RRResult(Message):
    """``rr/result``: which entity the human meant (``status`` says how sure)."""

    id: Optional[Id] = None
    time: Optional[Number] = None
    status: Literal["resolved", "ambiguous", "no-match", "error"]
    resolved: Optional[str] = None
    candidates: list[str] = []
    description: list[str] = []
    domain: Optional[str] = None
    text: Optional[str] = None
    unknown_words: Optional[list[str]] = None
    error: Optional[str] = None


class RegRequest(Stamp):
    """``reg/request``: describe ``target`` (optionally against a context set)."""

    id: Id
    target: str
    context: Optional[list[str]] = None


class Origin(Message):
    """What made a property enter a WM queue: the encoding's cause and dialogue turn."""

    cause: str
    turn: Optional[int] = None


class RegExpression(Message):
    """``reg/expression``: the referring expression for one request.

    ``origins`` is parallel to ``description``: for a property taken from WM, what had made
    it enter Q[target]; null for the others (alignment names it, core/alignment.py).
    """

    id: Id
    target: str
    time: Number
    domain: str
    algorithm: str
    description: list[str]
    sources: list[str]
    distinguishing: bool
    distractors_left: list[str]
    wm_before: list[str]
    text: str
    origins: list[Optional[Origin]] = []


class RegError(Message):
    """``reg/expression`` for a request REG could not answer."""

    error: str
    id: Optional[Id] = None
    target: Optional[str] = None
    time: Optional[Number] = None


class WMState(Message):
    """``wm/state``: one domain's non-empty WM queues (LRU first) and its event count."""

    domain: str
    time: Number
    queues: dict[str, list[str]]
    events: int


class ConsultantAnnounce(Message):
    """``consultant/announce`` (latched): a consultant's incarnation and what it runs.

    Published at start (``ready`` false: it answers query ops with kind ``not-ready``
    until the WM Manager configures it) and after each configure (``ready`` true).
    ``incarnation`` grows by one at every start (it is kept in the state database).
    """

    domain: str
    incarnation: int
    ready: bool
    memory: Optional[dict[str, Any]] = None


class WMEventMessage(Message):
    """``wm/events``: one encode or forget event (docs/semantics.md section 2)."""

    op: str
    domain: str
    entity: str
    property: str
    cause: str
    time: Number
    turn: Optional[int] = None


class LtmAssert(Message):
    """``ltm/assert``: facts (property -> certainty) about an entity, new or known."""

    domain: str
    entity: str
    properties: dict[str, Number]
    id: Optional[Id] = None


class LtmAssertResult(Message):
    """``ltm/assert/result``: what an assertion changed, or why it was refused."""

    domain: Optional[str] = None
    entity: Optional[str] = None
    ok: bool
    new_entity: Optional[bool] = None
    updated: Optional[dict[str, Number]] = None
    retracted: Optional[list[str]] = None
    error: Optional[str] = None
    id: Optional[Id] = None


class InfoRequest(Message):
    """``consultant/<domain>`` op ``info``: the domain's entities, preference order and memory.

    ``entities_from`` (default 0) skips the first entities: entities are only ever
    appended, so a caller that knows the first k asks for the rest only.
    """

    op: Literal["info"]
    entities_from: Optional[int] = None


class HoldsRequest(Message):
    """Op ``holds``: for which of ``entities`` does ``property`` hold (nothing is encoded)."""

    op: Literal["holds"]
    property: str
    entities: list[str]


class AffirmRequest(Stamp):
    """Op ``affirm``: as ``holds``, and encode ``property`` for each entity it holds for."""

    op: Literal["affirm"]
    property: str
    entities: list[str]
    cause: str


class StepRequest(Stamp):
    """One narrowing step: keep the members ``property`` holds for, encoding it (``cause``; null: no encoding)."""

    property: str
    cause: Optional[str]


class OpenRequest(Message):
    """Op ``open``: open a session holding RR's candidates or REG's distractors.

    No ``target``: every entity; else every entity but ``target``, or the ``context``
    set's.  ``first``: narrow it by that step at once (RR's first property).
    """

    op: Literal["open"]
    target: Optional[str] = None
    context: Optional[list[str]] = None
    first: Optional[StepRequest] = None


class NarrowRequest(Stamp):
    """Op ``narrow``: keep the session's members ``property`` holds for, encoding it for each.

    ``cause`` null: no encoding.  With a target, only if it holds for the target.
    """

    op: Literal["narrow"]
    session: str
    property: str
    cause: Optional[str]


class RuleOutRequest(Message):
    """Op ``rule_out``: for each property holding for the session's target, the members it rules out."""

    op: Literal["rule_out"]
    session: str


class CloseRequest(Stamp):
    """Op ``close``: end a session and return its members.

    ``encode`` is encoded (cause ``speaker``) for the target, or for the only member of
    a session without one.
    """

    op: Literal["close"]
    session: str
    encode: Optional[list[str]] = None


class WMRequest(Message):
    """Op ``wm``: one entity's WM queue, LRU first (reading never refreshes)."""

    op: Literal["wm"]
    entity: str


class EncodeRequest(Stamp):
    """Op ``encode``: encode ``properties`` for ``entity`` in WM."""

    op: Literal["encode"]
    entity: str
    properties: list[str]
    cause: str


class SnapshotRequest(Message):
    """Op ``snapshot``: every non-empty WM queue of the domain."""

    op: Literal["snapshot"]


class Versioned(Message):
    """A reply that says which LTM it was answered from: ``"<incarnation>:<changes>"``.

    It changes whenever LTM does (``ltm/assert``, the threshold) and when the consultant
    restarts, so a caller's cached preference order and entity list are known stale.
    """

    version: str


class InfoReply(Versioned):
    """Reply to ``info``: ``entities`` from ``entities_from`` on; ``entity_count`` in all."""

    domain: str
    entities: list[str]
    entity_count: int
    preference: list[str]
    threshold: Number
    policy: str
    memory: dict[str, Any]
    events: int


class HoldsReply(Message):
    """Reply to ``holds`` and ``affirm``: the entities the property holds for."""

    holds: list[str]


class Narrowing(Message):
    """What one narrowing step did: whether the property holds for the target (true without one), members left."""

    target_holds: bool
    size: int


class OpenReply(Versioned):
    """Reply to ``open``: the session id, its size, Q[target] and what holds for the target.

    ``queue`` is LRU first ([] without a target); ``retains`` whether the domain's WM
    retains anything (policy not ``none``); ``holding`` the properties holding for the
    target (preference order; null without a target); ``origins`` what made each
    property of ``queue`` enter it (parallel to ``queue``).
    """

    session: str
    size: int
    queue: list[str]
    retains: bool
    holding: Optional[list[str]] = None
    first: Optional[Narrowing] = None
    origins: list[Origin] = []


class NarrowReply(Narrowing, Versioned):
    """Reply to ``narrow``."""


class RuleOutReply(Versioned):
    """Reply to ``rule_out``: properties (preference order) and the members each rules out.

    Each mask is hexadecimal; bit k = the k-th member in entity order.
    """

    properties: list[str]
    masks: list[str]


class CloseReply(Versioned):
    """Reply to ``close``: the session's members, in entity order."""

    members: list[str]


class QueueReply(Message):
    """Reply to ``wm``."""

    queue: list[str]


class EncodeReply(Message):
    """Reply to ``encode``: empty."""


class SnapshotReply(Message):
    """Reply to ``snapshot``: non-empty queues, LRU first, and the events published so far."""

    queues: dict[str, list[str]]
    events: int


#: The consultant's query ops: op -> (request schema, reply schema).
CONSULTANT_OPS: dict[str, tuple[type[Message], type[Message]]] = {
    "info": (InfoRequest, InfoReply),
    "open": (OpenRequest, OpenReply),
    "narrow": (NarrowRequest, NarrowReply),
    "rule_out": (RuleOutRequest, RuleOutReply),
    "close": (CloseRequest, CloseReply),
    "holds": (HoldsRequest, HoldsReply),
    "affirm": (AffirmRequest, HoldsReply),
    "wm": (WMRequest, QueueReply),
    "encode": (EncodeRequest, EncodeReply),
    "snapshot": (SnapshotRequest, SnapshotReply),
}
ConsultantRequest = Union[InfoRequest, OpenRequest, NarrowRequest, RuleOutRequest, CloseRequest, HoldsRequest,
                          AffirmRequest, WMRequest, EncodeRequest, SnapshotRequest]
ConsultantReply = Union[InfoReply, OpenReply, NarrowReply, RuleOutReply, CloseReply, HoldsReply, QueueReply,
                        SnapshotReply, EncodeReply]


class ManageRequest(Stamp):
    """``consultant/<domain>/manage`` (the WM Manager's): ``configure``, ``decay``, ``evict`` or ``size``."""

    op: str


class SyncRequest(Message):
    """``wm_manager/sync``: apply every decay tick due at or before ``time``."""

    time: Number


class SyncReply(Message):
    """``wm_manager/sync`` reply: the effective memory settings once all is applied."""

    time: Optional[Number] = None
    memory: Optional[dict[str, Any]] = None


class StatusRequest(Message):
    """``wm_manager/status``: no fields."""


class StatusReply(Message):
    """``wm_manager/status`` reply: effective memory settings per domain."""

    memory: Optional[dict[str, Any]] = None


# ------------------------------------------------------------------ limits
@dataclass(frozen=True)
class Limits:
    """Bounds on what a node accepts; each is a parameter of the nodes that take input.

    ``max_message_bytes`` bounds a message or request (UTF-8 bytes of its JSON);
    ``max_name_chars`` any entity, property, domain or target name; ``max_list_items``
    any list (descriptions, context sets, entity lists, LTM assertions).  RR and REG also
    bound their answer caches by entries and by bytes (``answer_cache_*``).
    """

    max_message_bytes: int = 65_536
    max_name_chars: int = 256
    max_list_items: int = 1_000
    answer_cache_entries: int = 1_024
    answer_cache_bytes: int = 4 * 1024 * 1024


#: Declared ranges of the limit parameters (low, high).
LIMIT_RANGES = {
    "max_message_bytes": (256, 16 * 1024 * 1024),
    "max_name_chars": (8, 65_536),
    "max_list_items": (1, 1_000_000),
    "answer_cache_entries": (0, 1_000_000),
    "answer_cache_bytes": (0, 1024 * 1024 * 1024),
}


def check_sizes(data: Any, limits: Limits, names: tuple[str, ...] = (), lists: tuple[str, ...] = ()) -> None:
    """Raise :class:`MessageError` if a named field is too long a name or a list is too long.

    ``names`` are fields holding one name; ``lists`` fields holding a list of names (or
    an object whose keys are names); every item of those is a name too.
    """
    for field in names:
        value = data.get(field)
        if isinstance(value, str) and len(value) > limits.max_name_chars:
            raise MessageError(f"field '{field}': a name of {len(value)} characters, over the limit of "
                               f"{limits.max_name_chars}")
    for field in lists:
        value = data.get(field)
        if isinstance(value, (list, dict)):
            if len(value) > limits.max_list_items:
                raise MessageError(f"field '{field}': {len(value)} items, over the limit of {limits.max_list_items}")
            for item in value:
                if isinstance(item, str) and len(item) > limits.max_name_chars:
                    raise MessageError(f"field '{field}': a name of {len(item)} characters, over the limit of "
                                       f"{limits.max_name_chars}")


# ------------------------------------------------------------------ topics/services
@dataclass(frozen=True)
class Topic:
    """One topic: relative name, JSON schema of ``String.data``, QoS, who talks."""

    name: str
    schema: Any
    qos: QoSProfile
    publishers: str
    subscribers: str
    reader_qos: Optional[QoSProfile] = None

    @property
    def subscriber_qos(self) -> QoSProfile:
        return self.reader_qos if self.reader_qos is not None else self.qos


@dataclass(frozen=True)
class Service:
    """One JSON service: relative name (``<domain>`` filled in per consultant), schemas."""

    name: str
    request: Any
    reply: Any
    server: str
    clients: str


HUMAN = Topic("dialogue/human", HumanUtterance, PIPELINE_QOS, "the robot's speech input", "parser")
SEMANTICS = Topic("dialogue/semantics", Semantics, PIPELINE_QOS, "parser", "reference_resolution")
RR_RESULT = Topic("rr/result", Union[RRResult, ErrorReply], PIPELINE_QOS, "reference_resolution, parser (errors)",
                  "dialogue manager")
REG_REQUEST = Topic("reg/request", RegRequest, PIPELINE_QOS, "dialogue manager", "reg")
REG_EXPRESSION = Topic("reg/expression", Union[RegExpression, RegError], PIPELINE_QOS, "reg", "dialogue manager")
WM_STATE = Topic("wm/state", WMState, STATE_PUB_QOS, "consultants", "anyone", reader_qos=STATE_QOS)
WM_EVENTS = Topic("wm/events", WMEventMessage, EVENTS_QOS, "consultants", "dialogue_player (trace)")
ANNOUNCE = Topic("consultant/announce", ConsultantAnnounce, STATE_PUB_QOS, "consultants", "wm_manager",
                 reader_qos=STATE_QOS)
LTM_ASSERT = Topic("ltm/assert", LtmAssert, DEFAULT_QOS, "perception, dialogue manager", "consultants")
LTM_ASSERT_RESULT = Topic("ltm/assert/result", Union[LtmAssertResult, ErrorReply], DEFAULT_QOS, "consultants",
                          "asserter")

CONSULTANT = Service("consultant/<domain>", ConsultantRequest, ConsultantReply, "consultant",
                     "reference_resolution, reg")
MANAGE = Service("consultant/<domain>/manage", ManageRequest, Message, "consultant", "wm_manager only")
SYNC = Service("wm_manager/sync", SyncRequest, SyncReply, "wm_manager", "dialogue_player")
STATUS = Service("wm_manager/status", StatusRequest, StatusReply, "wm_manager", "anyone")

TOPICS: tuple[Topic, ...] = (HUMAN, SEMANTICS, RR_RESULT, REG_REQUEST, REG_EXPRESSION, WM_STATE, WM_EVENTS,
                             ANNOUNCE, LTM_ASSERT, LTM_ASSERT_RESULT)
SERVICES: tuple[Service, ...] = (CONSULTANT, MANAGE, SYNC, STATUS)

#: The simulated clock: absolute (ROS convention), ``rosgraph_msgs/msg/Clock``.
CLOCK = "/clock"


def consultant_service(domain: str) -> str:
    """Return the (relative) query service of a domain's consultant."""
    return CONSULTANT.name.replace("<domain>", domain)


def manage_service(domain: str) -> str:
    """Return the (relative) WM Manager service of a domain's consultant."""
    return MANAGE.name.replace("<domain>", domain)


def clock_remap(namespace: str) -> list[str]:
    """Return the ``--ros-args`` remapping that gives a namespaced graph its own ``/clock``.

    Two sim-time graphs on one domain would otherwise follow one clock driven by two
    players, each jumping the other's time.  The runner passes this to every node
    (player included) when it runs a graph under a namespace; an un-namespaced graph
    keeps the global ``/clock``.
    """
    ns = normalise_namespace(namespace)
    return ["-r", f"{CLOCK}:={ns}{CLOCK}"] if ns else []


def normalise_namespace(namespace: Optional[str]) -> str:
    """Return ``namespace`` as ``/a/b`` ('' for none); ValueError if it is not a ROS namespace."""
    text = (namespace or "").strip().strip("/")
    if not text:
        return ""
    for part in text.split("/"):
        if not part or not (part[0].isalpha() or part[0] == "_") or not all(c.isalnum() or c == "_" for c in part):
            raise ValueError(f"namespace {namespace!r}: each part must be letters, digits and '_', "
                             "not starting with a digit")
    return "/" + text


# ------------------------------------------------------------------ checking
def check(model: type[BaseModel], data: dict) -> dict:
    """Return ``data`` unchanged if it fits ``model``; else raise :class:`MessageError` naming the field."""
    try:
        model.model_validate(data)
    except ValidationError as err:
        raise MessageError(_first_problem(model, err)) from None
    return data


def _field_spec(annotation: Any) -> Any:
    """Return a :func:`~fsreg_ros.codec.describe` spec for a schema field's annotation."""
    origin, args = get_origin(annotation), get_args(annotation)
    if origin is Union:
        members = [a for a in args if a is not type(None)]
        nullable = len(members) < len(args)
        if set(members) == {int, float}:
            members = [float]
        specs = tuple(_field_spec(a) for a in members) + ((None,) if nullable else ())
        return specs[0] if len(specs) == 1 else specs
    if origin is Literal:
        return str
    if origin in (list, dict):
        return origin[tuple(_field_spec(a) for a in args)] if args else origin
    return annotation if isinstance(annotation, type) and annotation is not Any else object


_UNION_TAGS = {"str", "int", "float", "bool", "none"}


def _is_tag(part: Any) -> bool:
    """Return True for a pydantic location part that names a union member, not a key."""
    return isinstance(part, str) and (part in _UNION_TAGS or "[" in part)


def _item_spec(spec: Any) -> Any:
    """Return the spec of one item of a list/dict spec (or of the first such member of a union)."""
    for member in spec if isinstance(spec, tuple) else (spec,):
        if isinstance(member, types.GenericAlias):
            return member.__args__[-1]
    return object


def _first_problem(model: type[BaseModel], err: ValidationError) -> str:
    first = err.errors(include_url=False)[0]
    loc = first.get("loc", ())
    message = str(first.get("msg", "invalid")).removeprefix("Value error, ")
    field = loc[0] if loc and isinstance(loc[0], str) and loc[0] in model.model_fields else None
    if field is None:  # a check of the whole message (e.g. "exactly one of text and description")
        return printable(message, 200)
    if first.get("type") == "missing":
        return f"missing field '{field}'"
    keys = [p for p in loc[1:] if not _is_tag(p)]
    where = f"field '{field}'" + "".join(f"[{p!r}]" for p in keys)
    spec = _field_spec(model.model_fields[field].annotation)
    for _ in keys:
        spec = _item_spec(spec)
    got = printable(repr(first.get("input")), 60)
    if first.get("type") in ("literal_error", "value_error") or spec is object:
        return printable(f"{where}: {message}, got {got}", 300)
    return printable(f"{where}: expected {describe(spec)}, got {got}", 300)


# ------------------------------------------------------------------ schemas out
def _schema_of(model: Any) -> dict:
    return TypeAdapter(model).json_schema()


def json_schemas() -> dict[str, dict]:
    """Return every message's JSON Schema, keyed by file stem (``topic.rr.result``, ``service.wm_manager.sync``)."""
    out: dict[str, dict] = {}
    for topic in TOPICS:
        out["topic." + topic.name.replace("/", ".")] = _schema_of(topic.schema)
    for service in SERVICES:
        stem = "service." + service.name.replace("/", ".").replace("<domain>", "DOMAIN")
        out[stem + ".request"] = _schema_of(service.request)
        out[stem + ".reply"] = _schema_of(service.reply)
    out["service.error_reply"] = _schema_of(ErrorReply)
    return out


def fields_of(schema: Any) -> list[str]:
    """Return the field names a schema (model or union of models) names, in order, without duplicates."""
    models = getattr(schema, "__args__", None) or (schema,)
    names: list[str] = []
    for model in models:
        for name in getattr(model, "model_fields", {}):
            if name not in names:
                names.append(name)
    return names


def _qos_text(qos: QoSProfile) -> str:
    latched = "latched" if qos.durability == DurabilityPolicy.TRANSIENT_LOCAL else "volatile"
    return f"{latched}, depth {qos.depth}"


def message_table() -> list[str]:
    """Return the rows of the docs' message table: ``| name | from -> to | QoS | fields |``."""
    rows = []
    for topic in TOPICS:
        qos = _qos_text(topic.qos) + (f" (readers {topic.reader_qos.depth})" if topic.reader_qos else "")
        fields = ", ".join(f"`{f}`" for f in fields_of(topic.schema))
        rows.append(f"| `{topic.name}` | {topic.publishers} -> {topic.subscribers} | {qos} | {fields} |")
    for service in SERVICES:
        request = ", ".join(f"`{f}`" for f in fields_of(service.request)) or "(none)"
        reply = ", ".join(f"`{f}`" for f in fields_of(service.reply)) or "(by op)"
        rows.append(f"| `{service.name}` | {service.clients} -> {service.server} | service | {request} -> {reply} |")
    return rows
