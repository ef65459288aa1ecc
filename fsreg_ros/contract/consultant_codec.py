"""The consultant protocol's codec: every op's request and reply, both ways, as pure functions (ROS-free).

The ops, their names and their request and reply schemas are
:mod:`fsreg_ros.contract.consultant`'s (:data:`~.consultant.CONSULTANT_OPS`,
:data:`~.consultant.DEBUG_OPS`, :data:`~.consultant.MANAGE_OPS`); what follows from
them is read off those schemas, not listed again: the ops whose replies carry the LTM
``version`` (:data:`VERSIONED_OPS`, replies that are :class:`~.consultant.Versioned`),
those that list exactly the queues they changed (:data:`COUNTED_OPS`, replies with
``queues_changed``), and those a consultant answers before the WM Manager configured it
(:data:`UNGUARDED_OPS`: the manage ops and ``info``).

Each op's four functions sit together, so each of its fields is spelled in one place:

* ``<op>_request(...)`` encodes a call (the caller's side: :class:`~fsreg_ros.ros.remote.RemotePort`,
  the WM Manager's :mod:`~fsreg_ros.ros.manage_link`, :mod:`~fsreg_ros.ros.graph_queries`);
* ``<op>_args(request)`` decodes a request the schema validated into the arguments of the
  op's typed call (:mod:`fsreg_ros.core.consultant.ops`; a time left out is None: the
  service's now);
* ``<op>_reply(result)`` encodes that call's result (:data:`SERVED` pairs them by op);
* ``<result>_of(reply)`` decodes a reply into the core's types (:mod:`fsreg_ros.core.algorithms.port`),
  raising :class:`ReplyError` for a reply the schema admits but that is unusable.

Nothing here holds a session, reads a clock or a consultant: running an op (decode, call,
encode) is :func:`fsreg_ros.ros.consultant_ops.apply`.  The wire format is what it was (the
graph equals the simulator byte for byte).
"""

from __future__ import annotations

from typing import Any, Callable, Mapping, Optional, Sequence

from ..core.memory import Strength
from ..core.algorithms.port import Narrowed, Reference, Step, View, Walked, WalkStep
from ..core.consultant.ops import Configured, Info, Opened
from ..core.forgetting.policies import ForgettingPolicy
from ..core.memory.ticks import TickRun
from .codec import MessageError
from .consultant import CONSULTANT_OPS, DEBUG_OPS, MANAGE_OPS, Versioned, version_incarnation

#: Every op: op -> (request schema, reply schema).
ALL_OPS = {**CONSULTANT_OPS, **DEBUG_OPS, **MANAGE_OPS}
#: Ops whose replies carry the LTM ``version``.
VERSIONED_OPS = frozenset(op for op, (_, reply) in ALL_OPS.items() if issubclass(reply, Versioned))
#: Ops whose change set is listed exactly (their replies say how many queues changed).
COUNTED_OPS = frozenset(op for op, (_, reply) in ALL_OPS.items() if "queues_changed" in reply.model_fields)
#: Ops answered before the WM Manager configured the consultant (the others are refused: ``not-ready``).
UNGUARDED_OPS = frozenset(MANAGE_OPS) | {"info"}


class ReplyError(MessageError):
    """A reply its schema admits but that cannot be what the op answers (a caller reports it as ``protocol``)."""


def completed(op: str, reply: dict, queues_changed: int, version: Callable[[], str]) -> dict:
    """Add what a reply of ``op`` carries besides its result: ``queues_changed``, ``version()``, as it has them."""
    if op in COUNTED_OPS:
        reply["queues_changed"] = queues_changed
    if op in VERSIONED_OPS:
        reply["version"] = version()
    return reply


# ----------------------------------------------------------------------- info
def info_request(entities_from: Optional[int] = None) -> dict:
    """Encode ``info`` (the entities from ``entities_from`` on; None: all, the field left out)."""
    return {"op": "info"} if entities_from is None else {"op": "info", "entities_from": entities_from}


def info_args(req: Mapping[str, Any]) -> tuple[int]:
    """Decode ``info``: the first entity asked for (0: all)."""
    return (req.get("entities_from") or 0,)


def info_reply(info: Info) -> dict:
    """Encode what ``info`` reports (``event_listeners`` is the node's: :func:`with_listeners`)."""
    return {"domain": info.domain, "entities": info.entities, "entity_count": info.entity_count,
            "preference": info.preference, "threshold": info.threshold, "policy": info.policy,
            "memory": info.memory, "events": info.events, "wm_version": info.wm_version, "state": info.state}


def with_listeners(reply: dict, listeners: int) -> dict:
    """Add to an ``info`` reply how many subscriptions hear the consultant's events."""
    reply["event_listeners"] = listeners
    return reply


def entities_of(reply: Mapping[str, Any]) -> list[str]:
    """Decode the entities an ``info`` reply lists."""
    return list(reply.get("entities") or ())


def catalogue_of(reply: Mapping[str, Any]) -> tuple[str, list[str], list[str]]:
    """Decode an ``info`` reply's catalogue: its version, the preference order, the entities it lists."""
    return reply["version"], list(reply["preference"]), list(reply["entities"])


def wm_as_of(reply: Mapping[str, Any]) -> tuple[int, int]:
    """Decode which WM an ``info`` reply speaks for: ``(incarnation, wm_version)`` (``wm/state`` compares so)."""
    return version_incarnation(reply["version"]), reply["wm_version"]


def version_of(reply: Mapping[str, Any]) -> Optional[str]:
    """Decode the LTM ``version`` a reply carries (None: the op's replies carry none)."""
    return reply.get("version")


# ----------------------------------------------------------------------- open
def open_request(target: Optional[str], context: Optional[Sequence[str]], first: Optional[Step],
                 client: str, refer: Optional[Reference] = None) -> dict:
    """Encode :meth:`~fsreg_ros.core.algorithms.port.ConsultantPort.open` for ``client``."""
    payload: dict[str, Any] = {"op": "open", "client": client}
    if target is not None:
        payload["target"] = target
    if context is not None:
        payload["context"] = list(context)
    if first is not None:
        payload["first"] = {"property": first.prop, "cause": first.cause, "time": first.time, "turn": first.turn}
    if refer is not None:
        payload["refer"] = {"id": refer.id, "time": refer.time, "turn": refer.turn}
    return payload


def open_args(req: Mapping[str, Any]) -> tuple:
    """Decode ``open``: target, context, the first step, the client and the reference (their times None: now)."""
    step, first = req.get("first"), None
    if step is not None:
        first = Step(step["property"], step.get("cause"), step.get("time"), step.get("turn"))
    act, refer = req.get("refer"), None
    if act is not None:
        refer = Reference(act.get("time"), act.get("turn"), act.get("id"))
    return req.get("target"), req.get("context"), first, req.get("client") or "", refer


def open_reply(opened: Opened) -> dict:
    """Encode an opened session."""
    view = opened.view
    reply = {"session": opened.session, "size": view.size, "queue": view.queue, "retains": view.retains,
             "holding": opened.holding, "origins": [{"cause": c, "turn": t} for c, t in view.origins],
             "strength": [entry.to_json() for entry in view.strength]}
    if view.first is not None:
        reply["first"] = narrow_reply(view.first)
    return reply


def view_of(reply: Mapping[str, Any], first: bool) -> View:
    """Decode an ``open`` reply (``first``: the request gave a first step) into a :class:`~.port.View`."""
    holding = reply.get("holding")
    view = View(reply["session"], reply["size"], list(reply["queue"]), reply["retains"],
                frozenset(holding) if holding is not None else None,
                origins=[(o["cause"], o["turn"]) for o in reply.get("origins", ())],
                strength=[Strength.from_json(s) for s in reply.get("strength", ())])
    if first:
        if reply.get("first") is None:
            raise ReplyError("no 'first'")
        view.first = narrowed_of(reply["first"])
    return view


# ----------------------------------------------------------------------- narrow
def narrow_request(session: str, prop: str, cause: Optional[str], time: float, turn: Optional[int]) -> dict:
    """Encode :meth:`~fsreg_ros.core.algorithms.port.ConsultantPort.narrow` of the view named ``session``."""
    return {"op": "narrow", "session": session, "property": prop, "cause": cause, "time": time, "turn": turn}


def narrow_args(req: Mapping[str, Any]) -> tuple:
    """Decode ``narrow``: session, property, cause, time, turn."""
    return req["session"], req["property"], req.get("cause"), req.get("time"), req.get("turn")


def narrow_reply(step: Narrowed) -> dict:
    """Encode what a ``narrow`` did."""
    return {"target_holds": step.target_holds, "size": step.size}


def narrowed_of(reply: Mapping[str, Any]) -> Narrowed:
    """Decode a ``narrow`` reply."""
    return Narrowed(reply["target_holds"], reply["size"])


# ----------------------------------------------------------------------- walk
def walk_request(session: str, steps: Sequence[WalkStep], cause: Optional[str], time: float,
                 turn: Optional[int]) -> dict:
    """Encode :meth:`~fsreg_ros.core.algorithms.port.ConsultantPort.walk` of the view named ``session``."""
    return {"op": "walk", "session": session, "cause": cause, "time": time, "turn": turn,
            "steps": [{"property": s.prop} if s.group is None else {"property": s.prop, "group": s.group}
                      for s in steps]}


def walk_args(req: Mapping[str, Any]) -> tuple:
    """Decode ``walk``: session, steps, cause, time, turn."""
    steps = [WalkStep(step["property"], step.get("group")) for step in req["steps"]]
    return req["session"], steps, req.get("cause"), req.get("time"), req.get("turn")


def walk_reply(walked: Walked) -> dict:
    """Encode what a ``walk`` did."""
    return {"taken": list(walked.taken), "size": walked.size, "narrowed": walked.narrowed}


def walked_of(reply: Mapping[str, Any], steps: int) -> Walked:
    """Decode a ``walk`` reply to a walk of ``steps`` steps (``taken``: increasing step indices)."""
    taken = reply["taken"]
    if any(not 0 <= i < steps for i in taken) or taken != sorted(set(taken)):
        raise ReplyError("'taken' is not increasing step indices")
    return Walked(tuple(taken), reply["size"], reply["narrowed"])


# ----------------------------------------------------------------------- rule_out
def rule_out_request(session: str) -> dict:
    """Encode :meth:`~fsreg_ros.core.algorithms.port.ConsultantPort.rule_out` of the view named ``session``."""
    return {"op": "rule_out", "session": session}


def rule_out_args(req: Mapping[str, Any]) -> tuple[str]:
    """Decode ``rule_out``: the session."""
    return (req["session"],)


def rule_out_reply(ruled: tuple[list[str], list[int]]) -> dict:
    """Encode the properties and the members each rules out (hexadecimal masks)."""
    props, masks = ruled
    return {"properties": props, "masks": [format(mask, "x") for mask in masks]}


def rule_out_of(reply: Mapping[str, Any]) -> tuple[list[str], list[int]]:
    """Decode a ``rule_out`` reply: the properties and the members each rules out (hexadecimal masks)."""
    try:
        masks = [int(mask, 16) for mask in reply["masks"]]
    except ValueError:
        raise ReplyError("a mask is not hexadecimal") from None
    return list(reply["properties"]), masks


# ----------------------------------------------------------------------- close
def close_request(session: str, encode: Sequence[str], time: Optional[float], turn: Optional[int]) -> dict:
    """Encode :meth:`~fsreg_ros.core.algorithms.port.ConsultantPort.close` of the view named ``session``."""
    payload: dict[str, Any] = {"op": "close", "session": session, "time": time, "turn": turn}
    if encode:
        payload["encode"] = list(encode)
    return payload


def close_args(req: Mapping[str, Any]) -> tuple:
    """Decode ``close``: session, what to encode, time, turn."""
    return req["session"], req.get("encode") or (), req.get("time"), req.get("turn")


def close_reply(members: list[str]) -> dict:
    """Encode a closed session's members."""
    return {"members": members}


def members_of(reply: Mapping[str, Any]) -> list[str]:
    """Decode a ``close`` reply."""
    return list(reply["members"])


# ----------------------------------------------------------------------- debug ops
def holds_request(prop: str, entities: Sequence[str]) -> dict:
    """Encode ``holds``: for which of ``entities`` does ``prop`` hold."""
    return {"op": "holds", "property": prop, "entities": list(entities)}


def holds_args(req: Mapping[str, Any]) -> tuple:
    """Decode ``holds``: property, entities."""
    return req["property"], req["entities"]


def holds_reply(held: list[str]) -> dict:
    """Encode the entities a property holds for (``holds``, ``affirm``)."""
    return {"holds": held}


def held_of(reply: Mapping[str, Any]) -> list[str]:
    """Decode a ``holds`` or ``affirm`` reply: the entities the property holds for."""
    return list(reply["holds"])


def affirm_request(prop: str, entities: Sequence[str], cause: str, time: Optional[float],
                   turn: Optional[int]) -> dict:
    """Encode ``affirm``: as ``holds``, encoding ``prop`` (``cause``) for each entity it holds for."""
    return {"op": "affirm", "property": prop, "entities": list(entities), "cause": cause, "time": time, "turn": turn}


def affirm_args(req: Mapping[str, Any]) -> tuple:
    """Decode ``affirm``: property, entities, cause, time, turn."""
    return req["property"], req["entities"], req["cause"], req.get("time"), req.get("turn")


def wm_request(entity: str) -> dict:
    """Encode ``wm``: one entity's queue."""
    return {"op": "wm", "entity": entity}


def wm_args(req: Mapping[str, Any]) -> tuple[str]:
    """Decode ``wm``: the entity."""
    return (req["entity"],)


def queue_reply(queue: list[str]) -> dict:
    """Encode one entity's queue, LRU first."""
    return {"queue": queue}


def queue_of(reply: Mapping[str, Any]) -> list[str]:
    """Decode a ``wm`` reply."""
    return list(reply["queue"])


def encode_request(entity: str, properties: Sequence[str], cause: str, time: Optional[float],
                   turn: Optional[int]) -> dict:
    """Encode ``encode``: ``properties`` into ``entity``'s queue (Algorithm 1)."""
    return {"op": "encode", "entity": entity, "properties": list(properties), "cause": cause, "time": time,
            "turn": turn}


def encode_args(req: Mapping[str, Any]) -> tuple:
    """Decode ``encode``: entity, properties, cause, time, turn."""
    return req["entity"], req["properties"], req["cause"], req.get("time"), req.get("turn")


def encode_reply(_: None) -> dict:
    """Encode the (empty) reply to ``encode``."""
    return {}


def snapshot_request() -> dict:
    """Encode ``snapshot``."""
    return {"op": "snapshot"}


def no_args(req: Mapping[str, Any]) -> tuple:
    """Decode an op without fields (``snapshot``, ``size``)."""
    return ()


def snapshot_reply(snapshot: tuple[dict[str, list[str]], int]) -> dict:
    """Encode every non-empty queue and the ``seq`` of the last event published."""
    queues, events = snapshot
    return {"queues": queues, "events": events}


def snapshot_of(reply: Mapping[str, Any]) -> dict[str, list[str]]:
    """Decode a ``snapshot`` reply's queues."""
    return dict(reply["queues"])


# ----------------------------------------------------------------------- manage ops
def configure_request(policy: ForgettingPolicy, time: float) -> dict:
    """Encode ``configure``: install ``policy`` as of ``time``."""
    return {"op": "configure", "policy": policy.settings(), "time": time}


def configure_args(req: Mapping[str, Any]) -> tuple:
    """Decode ``configure``: the policy (its schema checked it is one) and the time."""
    return ForgettingPolicy.from_settings(req["policy"]), req.get("time")


def configure_reply(configured: Configured) -> dict:
    """Encode a configure's result."""
    return {"memory": configured.memory, "incarnation": configured.incarnation, "state": configured.state}


def configured_of(reply: Mapping[str, Any]) -> tuple[Any, Optional[int], Any]:
    """Decode a ``configure`` reply: the policy running (JSON form), the incarnation, what it restored at start.

    What the reply lacks is None (the incarnation if it is not a whole number, ``restored``
    without a stored state).
    """
    incarnation = reply.get("incarnation")
    restored = (reply.get("state") or {}).get("restored")
    return reply.get("memory"), incarnation if isinstance(incarnation, int) else None, restored


def decay_request(ticks: TickRun) -> dict:
    """Encode ``decay``: apply ``ticks`` (the core's JSON form of a :class:`TickRun`)."""
    return {"op": "decay", "ticks": ticks.to_json()}


def decay_args(req: Mapping[str, Any]) -> tuple[TickRun]:
    """Decode ``decay`` (request or sent payload): its ticks."""
    return (TickRun.from_json(req["ticks"]),)


def policy_reply(policy: str) -> dict:
    """Encode the installed policy's name (``decay``, ``advance``)."""
    return {"policy": policy}


def policy_of(reply: Mapping[str, Any]) -> str:
    """Decode a ``decay`` or ``advance`` reply: the installed policy's name."""
    return reply["policy"]


def advance_request(time: float) -> dict:
    """Encode ``advance``: the clock reached ``time``."""
    return {"op": "advance", "time": time}


def advance_args(req: Mapping[str, Any]) -> tuple:
    """Decode ``advance``: the time."""
    return (req.get("time"),)


def evict_request(count: int, time: float) -> dict:
    """Encode ``evict``: forget ``count`` fronts as of ``time``."""
    return {"op": "evict", "count": count, "time": time}


def evict_args(req: Mapping[str, Any]) -> tuple:
    """Decode ``evict``: count, time."""
    return req["count"], req.get("time")


def size_request() -> dict:
    """Encode ``size``."""
    return {"op": "size"}


def size_reply(size: int) -> dict:
    """Encode how many properties WM holds (``size``, ``evict``)."""
    return {"size": size}


def size_of(reply: Mapping[str, Any]) -> int:
    """Decode a ``size`` reply."""
    return reply["size"]


def reset_request(client: str) -> dict:
    """Encode ``reset`` (``client`` names who asked, for the consultant's log)."""
    return {"op": "reset", "client": client}


def reset_args(req: Mapping[str, Any]) -> tuple[str]:
    """Decode ``reset``: who asked ("" if unnamed)."""
    return (req.get("client") or "",)


def reset_reply(incarnation: int, moved_aside: Optional[str], cleared: dict[str, int], state: dict) -> dict:
    """Encode a reset: the new incarnation, where the old database went, what it held, the new stored state."""
    return {"incarnation": incarnation, "moved_aside": moved_aside, "cleared": cleared, "state": state}


#: The consultant's side of each op the service runs: op -> (decode its request, encode its result).
#: (``reset`` is not one: the node serves it itself, replacing the service, with :func:`reset_reply`.)
SERVED: dict[str, tuple[Callable[[Mapping[str, Any]], tuple], Callable[[Any], dict]]] = {
    "info": (info_args, info_reply),
    "open": (open_args, open_reply),
    "narrow": (narrow_args, narrow_reply),
    "walk": (walk_args, walk_reply),
    "rule_out": (rule_out_args, rule_out_reply),
    "close": (close_args, close_reply),
    "holds": (holds_args, holds_reply),
    "affirm": (affirm_args, holds_reply),
    "wm": (wm_args, queue_reply),
    "encode": (encode_args, encode_reply),
    "snapshot": (no_args, snapshot_reply),
    "configure": (configure_args, configure_reply),
    "decay": (decay_args, policy_reply),
    "advance": (advance_args, policy_reply),
    "evict": (evict_args, size_reply),
    "size": (no_args, size_reply),
}
