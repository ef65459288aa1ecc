"""Schemas of a consultant's protocol: its announcement, its query ops and the WM Manager's manage ops."""

from __future__ import annotations

from typing import Any, Literal, Optional, Union

from .base import Message, Number, Stamp
from .wm import Origin


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
