"""The consultant protocol written once: each op's request and reply, both ways (ROS-free).

The ops, their names and their request and reply schemas are
:mod:`fsreg_ros.contract.consultant`'s (:data:`~.consultant.CONSULTANT_OPS`,
:data:`~.consultant.DEBUG_OPS`, :data:`~.consultant.MANAGE_OPS`); what follows from
them is read off those schemas, not listed again: the ops whose replies carry the LTM
``version`` (:data:`VERSIONED_OPS`, replies that are :class:`~.consultant.Versioned`),
those that list exactly the queues they changed (:data:`COUNTED_OPS`, replies with
``queues_changed``), and those a consultant answers before the WM Manager configured it
(:data:`UNGUARDED_OPS`: the manage ops and ``info``).

This module turns the JSON objects of the wire into the core's typed calls and back:

* the **consultant's side** (the node): :func:`apply` decodes one validated request,
  runs it on a :class:`~fsreg_ros.core.consultant.service.ConsultantService` and encodes the reply
  (an op's ``_serve_<op>`` below);
* the **caller's side** (:class:`~fsreg_ros.ros.remote.RemotePort`): ``<op>_request``
  encodes a port call, and ``view_of``, ``narrowed_of``, ``walked_of``, ``rule_out_of``
  and ``members_of`` decode the reply into the port's types (:mod:`fsreg_ros.core.algorithms.port`),
  raising :class:`ReplyError` for a reply the schema admits but that is unusable.

Each op's encoders and decoders sit together, so a field is named in one place.  The
wire format is what it was (the graph equals the simulator byte for byte).
"""

from __future__ import annotations

from typing import Any, Callable, Mapping, Optional, Sequence

from ..core.memory.ticks import TickError, TickRun
from ..core.forgetting.policies import ForgettingPolicy
from ..core.memory import ENCODE_CAUSES, Strength
from ..core.algorithms.port import Narrowed, Step, View, Walked, WalkStep
from ..core.consultant.service import ConsultantService, Outcome, RequestError
from .codec import MessageError
from .consultant import CONSULTANT_OPS, DEBUG_OPS, MANAGE_OPS, Versioned

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


# ======================================================================= the consultant's side
def apply(service: ConsultantService, op: str, request: Mapping[str, Any], client: str = "",
          listening: bool = False) -> Outcome:
    """Run one op of the consultant protocol on ``service``; return its :class:`~.service.Outcome`.

    ``request`` holds the op's fields (types checked by the contract's models);
    ``client`` names the caller (sessions are counted per client); ``listening``
    whether anyone hears the events.  Raises KnowledgeError, PolicyError, RequestError,
    NotReady or SessionError, having changed nothing, for a request it refuses.
    """
    serve = _SERVE.get(op)
    if serve is None:
        raise RequestError(f"unknown op {op!r}")
    if op not in UNGUARDED_OPS:
        service.require_ready()
    counted = op in COUNTED_OPS
    outcome = service.run(lambda: serve(service, request, client), listening, counted)
    if counted:
        outcome.reply["queues_changed"] = len(outcome.changes.queues)
    if op in VERSIONED_OPS:
        outcome.reply["version"] = service.version()
    return outcome


def _cause(cause: Any, optional: bool = False) -> Optional[str]:
    if cause is None and optional:
        return None
    if cause not in ENCODE_CAUSES:
        raise RequestError(f"field 'cause': expected one of {', '.join(ENCODE_CAUSES)}, got {cause!r}")
    return cause


# ----------------------------------------------------------------------- info
def info_request(entities_from: Optional[int] = None) -> dict:
    """Encode ``info`` (the entities from ``entities_from`` on; None: all, the field left out)."""
    return {"op": "info"} if entities_from is None else {"op": "info", "entities_from": entities_from}


def _serve_info(s: ConsultantService, req: Mapping[str, Any], client: str) -> dict:
    start = req.get("entities_from") or 0
    if start < 0:
        raise RequestError(f"field 'entities_from': expected a whole number >= 0, got {start}")
    c = s.consultant
    return {"domain": s.domain, "entities": c.entities[start:], "entity_count": len(c.entities),
            "preference": list(c.preference), "threshold": c.threshold, "policy": s.policy.name,
            "memory": s.policy.to_json(), "events": s.seq, "wm_version": s.wm_version, "state": s.status()}


# ----------------------------------------------------------------------- open
def open_request(target: Optional[str], context: Optional[Sequence[str]], first: Optional[Step],
                 client: str) -> dict:
    """Encode :meth:`~fsreg_ros.core.algorithms.port.ConsultantPort.open` for ``client``."""
    payload: dict[str, Any] = {"op": "open", "client": client}
    if target is not None:
        payload["target"] = target
    if context is not None:
        payload["context"] = list(context)
    if first is not None:
        payload["first"] = {"property": first.prop, "cause": first.cause, "time": first.time, "turn": first.turn}
    return payload


def _serve_open(s: ConsultantService, req: Mapping[str, Any], client: str) -> dict:
    step, first = req.get("first"), None
    if step is not None:
        first = Step(step["property"], _cause(step.get("cause"), optional=True), s.request_time(step.get("time")),
                     step.get("turn"))
    view = s.open(req.get("target"), req.get("context"), first)
    session = s.sessions.open(view.handle, s.steady(), client)
    if first is not None:
        s.touch(first.time, wm=False)
    holding = None if view.holding is None else [p for p in s.consultant.preference if p in view.holding]
    reply = {"session": session, "size": view.size, "queue": view.queue, "retains": view.retains,
             "holding": holding, "origins": [{"cause": c, "turn": t} for c, t in view.origins],
             "strength": [s.to_json() for s in view.strength]}
    if view.first is not None:
        reply["first"] = {"target_holds": view.first.target_holds, "size": view.first.size}
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
        view.first = Narrowed(reply["first"]["target_holds"], reply["first"]["size"])
    return view


# ----------------------------------------------------------------------- narrow
def narrow_request(session: str, prop: str, cause: Optional[str], time: float, turn: Optional[int]) -> dict:
    """Encode :meth:`~fsreg_ros.core.algorithms.port.ConsultantPort.narrow` of the view named ``session``."""
    return {"op": "narrow", "session": session, "property": prop, "cause": cause, "time": time, "turn": turn}


def _serve_narrow(s: ConsultantService, req: Mapping[str, Any], client: str) -> dict:
    cause = _cause(req.get("cause"), optional=True)
    when = s.request_time(req.get("time"))
    candidates = s.sessions.get(req["session"], s.steady())
    step = s.narrow(candidates, req["property"], cause, when, req.get("turn"))
    s.touch(when, wm=False)
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


def _serve_walk(s: ConsultantService, req: Mapping[str, Any], client: str) -> dict:
    cause = _cause(req.get("cause"), optional=True)
    when = s.request_time(req.get("time"))
    candidates = s.sessions.get(req["session"], s.steady())
    steps = [WalkStep(step["property"], step.get("group")) for step in req["steps"]]
    walked = s.walk(candidates, steps, cause, when, req.get("turn"))
    s.touch(when, wm=False)
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


def _serve_rule_out(s: ConsultantService, req: Mapping[str, Any], client: str) -> dict:
    props, masks = s.rule_out(s.sessions.get(req["session"], s.steady()))
    return {"properties": props, "masks": [format(mask, "x") for mask in masks]}


def rule_out_of(reply: Mapping[str, Any]) -> tuple[list[str], list[int]]:
    """Decode a ``rule_out`` reply: the properties and the members each rules out (hexadecimal masks)."""
    try:
        masks = [int(mask, 16) for mask in reply["masks"]]
    except ValueError:
        raise ReplyError("a mask is not hexadecimal") from None
    return list(reply["properties"]), masks


# ----------------------------------------------------------------------- close
def close_request(session: str, encode: Sequence[str], time: float, turn: Optional[int]) -> dict:
    """Encode :meth:`~fsreg_ros.core.algorithms.port.ConsultantPort.close` of the view named ``session``."""
    payload: dict[str, Any] = {"op": "close", "session": session, "time": time, "turn": turn}
    if encode:
        payload["encode"] = list(encode)
    return payload


def _serve_close(s: ConsultantService, req: Mapping[str, Any], client: str) -> dict:
    when = s.request_time(req.get("time"))
    candidates = s.sessions.get(req["session"], s.steady())
    encode = req.get("encode") or ()
    members = s.close(candidates, encode, when, req.get("turn"))
    s.sessions.close(req["session"], s.steady())
    s.touch(when, wm=bool(encode) and s.buffer.retains)
    return {"members": members}


def members_of(reply: Mapping[str, Any]) -> list[str]:
    """Decode a ``close`` reply."""
    return list(reply["members"])


# ----------------------------------------------------------------------- debug ops
def _serve_holds(s: ConsultantService, req: Mapping[str, Any], client: str) -> dict:
    return {"holds": s.consultant.holds(req["property"], req["entities"])}


def _serve_affirm(s: ConsultantService, req: Mapping[str, Any], client: str) -> dict:
    cause, when = _cause(req.get("cause")), s.request_time(req.get("time"))
    held = s.affirm(req["property"], req["entities"], cause, when, req.get("turn"))
    s.touch(when, wm=bool(held))
    return {"holds": held}


def _serve_wm(s: ConsultantService, req: Mapping[str, Any], client: str) -> dict:
    return {"queue": s.consultant.queue(req["entity"])}


def _serve_encode(s: ConsultantService, req: Mapping[str, Any], client: str) -> dict:
    cause, when = _cause(req.get("cause")), s.request_time(req.get("time"))
    s.encode(req["entity"], req["properties"], cause, when, req.get("turn"))
    s.touch(when)
    return {}


def _serve_snapshot(s: ConsultantService, req: Mapping[str, Any], client: str) -> dict:
    return {"queues": s.buffer.snapshot(), "events": s.seq}


# ----------------------------------------------------------------------- manage ops
def _serve_configure(s: ConsultantService, req: Mapping[str, Any], client: str) -> dict:
    policy = ForgettingPolicy.from_settings(req["policy"])  # PolicyError: nothing installed
    s.configure(policy, s.request_time(req.get("time")))
    return {"memory": policy.to_json(), "incarnation": s.incarnation, "state": s.status()}


def _serve_decay(s: ConsultantService, req: Mapping[str, Any], client: str) -> dict:
    try:
        ticks = TickRun.from_json(req["ticks"])
    except TickError as err:
        raise RequestError(f"field 'ticks': {err}") from None
    s.decay_now(ticks)
    return {"policy": s.policy.name}


def _serve_advance(s: ConsultantService, req: Mapping[str, Any], client: str) -> dict:
    s.advance(s.request_time(req.get("time")))
    return {"policy": s.policy.name}


def _serve_evict(s: ConsultantService, req: Mapping[str, Any], client: str) -> dict:
    count = req["count"]
    if isinstance(count, bool) or not isinstance(count, int) or count < 0:
        raise RequestError(f"field 'count': expected a whole number >= 0, got {count!r}")
    s.evict(count, s.request_time(req.get("time")))
    return {"size": len(s.buffer)}


def _serve_size(s: ConsultantService, req: Mapping[str, Any], client: str) -> dict:
    return {"size": len(s.buffer)}


#: Ops the consultant node serves itself, not the service: ``reset`` replaces the service (a new incarnation).
NODE_OPS = frozenset({"reset"})
#: The consultant's side of each op (its request decoded, the service's typed call, its reply encoded).
_SERVE: dict[str, Callable[[ConsultantService, Mapping[str, Any], str], dict]] = {
    op: globals()[f"_serve_{op}"] for op in ALL_OPS if op not in NODE_OPS
}
