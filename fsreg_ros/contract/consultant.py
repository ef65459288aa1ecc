"""Schemas of a consultant's protocol: its announcements, query ops, debug ops and the WM Manager's manage ops.

Three services per domain (``<domain>`` filled in):

* ``consultant/<domain>`` -- RR's and REG's: ``info``, ``open``, ``narrow``, ``walk``,
  ``rule_out``, ``close`` (:data:`CONSULTANT_OPS`);
* ``consultant/<domain>/manage`` -- the WM Manager's: ``configure``, ``decay``,
  ``advance``, ``evict``, ``size`` (:data:`MANAGE_OPS`, the discriminated union :data:`ManageRequest`);
* ``consultant/<domain>/debug`` -- tests' and tools': ``holds``, ``affirm``, ``wm``,
  ``encode``, ``snapshot`` (:data:`DEBUG_OPS`); served only when the consultant's
  read-only parameter ``debug`` is true.

Every request is one of the models below, chosen by its ``op``; a reply is the op's
reply model.  Semantics: docs/semantics.md sections 2-4 (encoding rules 1-3, RR, REG),
:mod:`fsreg_ros.core.consultant.service` (sessions, readiness, persistence).  Encoding and decoding
them, for the consultant and its callers alike: :mod:`fsreg_ros.contract.consultant_codec`.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Optional, Union

from pydantic import Field, PlainValidator

from ..core.memory.ticks import TickRun
from .base import Count, Message, Name, Names, Number, Stamp, bounded_list
from .policy import PolicySettings  # generated from the memory settings table
from .wm import EntryStrength, Origin

#: Causes a request may give an encoding (docs/semantics.md section 2).
Cause = Literal["speaker", "rr", "reg-distractor"]


class RestoredState(Message):
    """What a consultant took up from its state database at start (its ``restored`` stored state).

    ``fresh``: nothing (the scenario alone); ``runtime_entities`` / ``runtime_facts``: the
    facts asserted at run time it restored (``runtime_facts`` counts properties, on
    entities of the KB and runtime ones); ``queues``: the WM queues restored (after the
    first configure dropped them as of another clock or run, they count in
    ``queues_dropped``); ``run``: the incarnation that wrote the state (null: a new
    database); ``clock`` and ``latest``: its clock epoch (the kind of clock WM was stored
    on, and the latest time it reflects, seconds); ``moved_aside``: where a reset moved
    the old database; ``migrated`` / ``dropped``: it was written for another KB, and
    how many items could not be kept.
    """

    fresh: bool
    runtime_entities: int
    runtime_facts: int
    queues: int
    run: Optional[int] = None
    clock: Optional[str] = None
    latest: Optional[Number] = None
    queues_dropped: Optional[int] = None
    moved_aside: Optional[str] = None
    migrated: Optional[bool] = None
    dropped: Optional[int] = None


class StoredState(Message):
    """What a consultant reports of its stored state (``info``, announcements, ``configure``).

    ``wm``: ``restored`` (WM taken up from the database), ``dropped`` (it belonged to
    another clock or run: see ``note``), ``empty`` or ``not-persisted``; ``persisted``
    false while writes to the database fail (``error`` says why): the consultant
    serves on and retries; ``restored``: what was taken up at start (:class:`RestoredState`).
    """

    wm: str
    persisted: bool
    note: Optional[str] = None
    error: Optional[str] = None
    restored: Optional[RestoredState] = None


class ConsultantAnnounce(Message):
    """``consultant/announce`` and ``consultant/<domain>/alive`` (latched): an incarnation and what it runs.

    Published at start (``ready`` false: it answers query ops with kind ``not-ready``
    until the WM Manager configures it) and after each configure (``ready`` true).
    ``incarnation`` grows by one at every start (it is kept in the state database).
    On ``consultant/<domain>/alive`` the writer's DDS liveliness (automatic, lease
    1 s) says whether the process lives.
    """

    domain: str
    incarnation: int
    ready: bool
    memory: Optional[dict[str, Any]] = None
    state: Optional[StoredState] = None


# ------------------------------------------------------------------ query ops
class InfoRequest(Message):
    """Op ``info``: the domain's entities, preference order, memory, events and stored state.

    ``entities_from`` (default 0) skips the first entities: entities are only ever
    appended, so a caller that knows the first k asks for the rest only.
    """

    op: Literal["info"]
    entities_from: Optional[Count] = None


class StepRequest(Stamp):
    """One narrowing step: keep the members ``property`` holds for, encoding it (``cause``; null: no encoding)."""

    property: Name
    cause: Optional[Cause]


class ReferRequest(Stamp):
    """REG's act of referring to the ``open``'s target: its episode begins at ``time`` (null: now) in ``turn``.

    ``id`` names the act (REG sends one per request id): an ``open`` whose ``id`` began the
    target's current episode begins no other (a retried request).  docs/semantics.md section 2.
    """

    id: Optional[Name] = None


class OpenRequest(Message):
    """Op ``open``: open a session holding RR's candidates or REG's distractors.

    No ``target``: every entity; else every entity but ``target``, or the ``context``
    set's.  ``first``: narrow it by that step at once (RR's first property).
    ``refer`` (needs a ``target``): the target's next reference episode begins before the
    session reads Q[target], and closing the session begins none; without it (RR, an older
    REG) the episode begins at ``close`` with rule 1's encoding.
    ``client`` names the caller: each client holds at most ``max_sessions_per_client``
    sessions (opening one more drops its own least recently used, never another's).
    """

    op: Literal["open"]
    target: Optional[Name] = None
    context: Optional[Names] = None
    first: Optional[StepRequest] = None
    refer: Optional[ReferRequest] = None
    client: Optional[Name] = None


class NarrowRequest(Stamp):
    """Op ``narrow``: keep the session's members ``property`` holds for, encoding it for each.

    ``cause`` null: no encoding.  With a target, only if it holds for the target.
    """

    op: Literal["narrow"]
    session: Name
    property: Name
    cause: Optional[Cause]


class WalkStepRequest(Message):
    """One step of a walk: a property, and the group (attribute) it belongs to (null: none)."""

    property: Name
    group: Optional[Name] = None


class WalkRequest(Stamp):
    """Op ``walk``: narrow the session by ``steps`` in order, as the Incremental Algorithm walks.

    A step is taken when it holds for the target (always, without one) and leaves fewer
    members; a step whose ``group`` was taken already is skipped; nothing is asked once
    no member is left (:class:`fsreg_ros.core.algorithms.port.Walk`).  Each narrowing encodes as
    ``narrow`` does (``cause``; null: no encoding).  One call for what would be one
    ``narrow`` per step.  A step naming an unknown property refuses the call, changing nothing.
    """

    op: Literal["walk"]
    session: Name
    steps: bounded_list(WalkStepRequest)
    cause: Optional[Cause]


class RuleOutRequest(Message):
    """Op ``rule_out``: for each property holding for the session's target, the members it rules out."""

    op: Literal["rule_out"]
    session: Name


class CloseRequest(Stamp):
    """Op ``close``: end a session and return its members.

    ``encode`` is encoded (cause ``speaker``) for the target, or for the only member of
    a session without one.
    """

    op: Literal["close"]
    session: Name
    encode: Optional[Names] = None


class Versioned(Message):
    """A reply that says which catalogue it was answered from: ``"<incarnation>:<entities>"``.

    It changes whenever the catalogue does (an entity added by ``ltm/assert``) and when the
    consultant restarts, so a caller's cached preference order and entity list are known
    stale; facts about known entities and the threshold do not change it.
    """

    version: str


def version_incarnation(version: str) -> int:
    """Return the consultant incarnation a :class:`Versioned` reply's ``version`` names."""
    return int(version.split(":", 1)[0])


class InfoReply(Versioned):
    """Reply to ``info``.

    ``entities`` from ``entities_from`` on; ``entity_count`` in all; ``events`` the
    ``seq`` of the last ``wm/events`` message published in this incarnation;
    ``wm_version`` how many calls of this incarnation changed WM (``wm/state`` carries
    the count it shows, so a client can wait for the state as of now);
    ``event_listeners`` how many subscriptions the ``wm/events`` publisher is matched
    with now (events are published only while there is one); ``state`` the stored state.
    """

    domain: str
    entities: list[str]
    entity_count: int
    preference: list[str]
    threshold: Number
    policy: str
    memory: dict[str, Any]
    events: int
    wm_version: int
    event_listeners: int
    state: StoredState


class Narrowing(Message):
    """What one narrowing step did: whether the property holds for the target (true without one), members left."""

    target_holds: bool
    size: int


class OpenReply(Versioned):
    """Reply to ``open``: the session id, its size, Q[target] and what holds for the target.

    ``queue`` is LRU first ([] without a target); ``origins`` parallel to it, the
    ``cause`` and ``turn`` of the encoding that made each property enter Q[target];
    ``retains`` whether the domain's WM retains anything (policy not ``none``);
    ``holding`` the properties holding for the target (preference order; null without
    a target); ``strength`` parallel to ``queue``, how strongly each entry is held.
    """

    session: str
    size: int
    queue: list[str]
    origins: list[Origin] = []
    strength: list[EntryStrength] = []
    retains: bool
    holding: Optional[list[str]] = None
    first: Optional[Narrowing] = None


class NarrowReply(Narrowing, Versioned):
    """Reply to ``narrow``."""


class WalkReply(Versioned):
    """Reply to ``walk``: the indices of the steps taken (in order), the members left, the steps narrowed by."""

    taken: list[int]
    size: int
    narrowed: int


class RuleOutReply(Versioned):
    """Reply to ``rule_out``: properties (preference order) and the members each rules out.

    Each mask is hexadecimal; bit k = the k-th member in entity order.
    """

    properties: list[str]
    masks: list[str]


class CloseReply(Versioned):
    """Reply to ``close``: the session's members, in entity order."""

    members: list[str]


# ------------------------------------------------------------------ debug ops
class HoldsRequest(Message):
    """Debug op ``holds``: for which of ``entities`` does ``property`` hold (nothing is encoded)."""

    op: Literal["holds"]
    property: Name
    entities: Names


class AffirmRequest(Stamp):
    """Debug op ``affirm``: as ``holds``, and encode ``property`` for each entity it holds for."""

    op: Literal["affirm"]
    property: Name
    entities: Names
    cause: Cause


class WMRequest(Message):
    """Debug op ``wm``: one entity's WM queue, LRU first (reading never refreshes)."""

    op: Literal["wm"]
    entity: Name


class EncodeRequest(Stamp):
    """Debug op ``encode``: encode ``properties`` for ``entity`` in WM (Algorithm 1)."""

    op: Literal["encode"]
    entity: Name
    properties: Names
    cause: Cause


class SnapshotRequest(Message):
    """Debug op ``snapshot``: every non-empty WM queue of the domain."""

    op: Literal["snapshot"]


class HoldsReply(Message):
    """Reply to ``holds`` and ``affirm``: the entities the property holds for."""

    holds: list[str]


class QueueReply(Message):
    """Reply to ``wm``."""

    queue: list[str]


class EncodeReply(Message):
    """Reply to ``encode``: empty."""


class SnapshotReply(Message):
    """Reply to ``snapshot``: non-empty queues, LRU first, and the ``seq`` of the last event published."""

    queues: dict[str, list[str]]
    events: int


# ------------------------------------------------------------------ manage ops
#: A run of decay ticks on the wire: the core's :class:`~fsreg_ros.core.memory.ticks.TickRun` in its JSON
#: form ``{"origin", "period", "first", "count"}`` (ticks at ``origin + k * period`` for k = ``first`` ..
#: ``first + count - 1``, Algorithm 2), checked by :meth:`TickRun.from_json
#: <fsreg_ros.core.memory.ticks.TickRun.from_json>` (its TickError, a ValueError, names what is wrong).
Ticks = Annotated[TickRun, PlainValidator(TickRun.from_json, json_schema_input_type=TickRun)]


class ConfigureRequest(Stamp):
    """Manage op ``configure``: install ``policy`` (its limits trim every queue at once) and serve."""

    op: Literal["configure"]
    policy: PolicySettings


class DecayRequest(Message):
    """Manage op ``decay``: apply ``ticks`` now; ticks at or before the last one applied are skipped."""

    op: Literal["decay"]
    ticks: Ticks


class AdvanceRequest(Stamp):
    """Manage op ``advance``: the clock reached ``time`` (rule ``activation``: entries below the threshold go)."""

    op: Literal["advance"]


class EvictRequest(Stamp):
    """Manage op ``evict``: forget the domain's ``count`` least recently encoded fronts (cause ``shared-capacity``)."""

    op: Literal["evict"]
    count: Count


class SizeRequest(Message):
    """Manage op ``size``: how many properties WM holds."""

    op: Literal["size"]


class ConfigureReply(Message):
    """Reply to ``configure``: the policy now running, queues it changed, the incarnation, the stored state."""

    memory: dict[str, Any]
    queues_changed: int
    incarnation: int
    state: StoredState


class DecayReply(Message):
    """Reply to ``decay``: queues changed and the installed policy's name."""

    queues_changed: int
    policy: str


class AdvanceReply(Message):
    """Reply to ``advance``: queues changed and the installed policy's name."""

    queues_changed: int
    policy: str


class EvictReply(Message):
    """Reply to ``evict``: queues changed and the size WM is left with."""

    queues_changed: int
    size: int


class SizeReply(Message):
    """Reply to ``size``."""

    size: int


class ResetRequest(Message):
    """Manage op ``reset`` (``fsreg-ctl state reset``): move the state database aside, start from the KB again.

    The consultant re-reads its KB file, moves its database aside (never deleting it),
    and serves as a new incarnation (not ready until the WM Manager configures it).
    """

    op: Literal["reset"]
    client: Optional[str] = None


class ResetReply(Message):
    """Reply to ``reset``: the new incarnation, where the old database went, what it held, the new stored state.

    ``cleared``: what the state set aside held (``runtime_entities``, ``runtime_facts``:
    properties whose certainty differed from the KB's, ``queues``: non-empty WM queues).
    """

    incarnation: int
    moved_aside: Optional[str] = None
    cleared: dict[str, int]
    state: StoredState


# ------------------------------------------------------------------ by op
#: Each service's ops: op -> (request schema, reply schema).
CONSULTANT_OPS: dict[str, tuple[type[Message], type[Message]]] = {
    "info": (InfoRequest, InfoReply),
    "open": (OpenRequest, OpenReply),
    "narrow": (NarrowRequest, NarrowReply),
    "walk": (WalkRequest, WalkReply),
    "rule_out": (RuleOutRequest, RuleOutReply),
    "close": (CloseRequest, CloseReply),
}
DEBUG_OPS: dict[str, tuple[type[Message], type[Message]]] = {
    "holds": (HoldsRequest, HoldsReply),
    "affirm": (AffirmRequest, HoldsReply),
    "wm": (WMRequest, QueueReply),
    "encode": (EncodeRequest, EncodeReply),
    "snapshot": (SnapshotRequest, SnapshotReply),
}
MANAGE_OPS: dict[str, tuple[type[Message], type[Message]]] = {
    "configure": (ConfigureRequest, ConfigureReply),
    "decay": (DecayRequest, DecayReply),
    "advance": (AdvanceRequest, AdvanceReply),
    "evict": (EvictRequest, EvictReply),
    "size": (SizeRequest, SizeReply),
    "reset": (ResetRequest, ResetReply),
}

ConsultantRequest = Annotated[Union[InfoRequest, OpenRequest, NarrowRequest, WalkRequest, RuleOutRequest,
                                    CloseRequest], Field(discriminator="op")]
ConsultantReply = Union[InfoReply, OpenReply, NarrowReply, WalkReply, RuleOutReply, CloseReply]
DebugRequest = Annotated[Union[HoldsRequest, AffirmRequest, WMRequest, EncodeRequest, SnapshotRequest],
                         Field(discriminator="op")]
DebugReply = Union[HoldsReply, QueueReply, EncodeReply, SnapshotReply]
ManageRequest = Annotated[Union[ConfigureRequest, DecayRequest, AdvanceRequest, EvictRequest, SizeRequest,
                                ResetRequest], Field(discriminator="op")]
ManageReply = Union[ConfigureReply, DecayReply, AdvanceReply, EvictReply, SizeReply, ResetReply]
