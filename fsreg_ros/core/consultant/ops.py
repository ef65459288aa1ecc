"""The consultant protocol's ops as the core runs them: one typed call per op on a :class:`ConsultantService`.

What a served op does beyond the service's typed method, and nothing about the wire: the
session it opens, names or closes (:attr:`ConsultantService.sessions`, timed by the steady
clock), its request time (the robot clock's now when a request gives none, checked:
:meth:`ConsultantService.request_time`), the time it notes (:meth:`ConsultantService.touch`)
and what it reads of the consultant for its answer (:class:`Info`, :class:`Opened`).
Each function takes the op's decoded fields (their types and ranges checked by the
contract's schemas) and returns what its reply says; the
decoding and encoding are :mod:`fsreg_ros.contract.consultant_codec`'s, the dispatch
(decode, run here, encode, inside :meth:`ConsultantService.run`) is
:mod:`fsreg_ros.ros.consultant_ops`'s.  A refusal (KnowledgeError, PolicyError,
RequestError for a time out of range, SessionError) is raised before anything changed.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Optional, Sequence

from ..algorithms.port import Narrowed, Reference, Step, View, Walked, WalkStep
from ..forgetting.policies import ForgettingPolicy
from ..memory.ticks import TickRun
from .service import ConsultantService


@dataclass
class Info:
    """What ``info`` reports: the catalogue (from entity ``start`` on), memory, events and stored state."""

    domain: str
    entities: list[str]
    entity_count: int
    preference: list[str]
    threshold: float
    policy: str
    memory: dict[str, Any]
    events: int
    wm_version: int
    state: dict


@dataclass
class Opened:
    """An opened view: its session id, the view, and what holds for its target in preference order (None: no target)."""

    session: str
    view: View
    holding: Optional[list[str]]


@dataclass
class Configured:
    """A configure's result: the policy now running (its JSON form), the incarnation, the stored state."""

    memory: dict[str, Any]
    incarnation: int
    state: dict


# ----------------------------------------------------------------------- query ops
def info(s: ConsultantService, start: int) -> Info:
    """Report the domain's entities from ``start`` on, its preference order, memory, events and stored state."""
    c = s.consultant
    return Info(s.domain, c.entities[start:], len(c.entities), list(c.preference), c.threshold, s.policy.name,
                s.policy.to_json(), s.seq, s.wm_version, s.status())


def open_session(s: ConsultantService, target: Optional[str], context: Optional[Sequence[str]],
                 first: Optional[Step], client: str, refer: Optional[Reference] = None) -> Opened:
    """Open a view as a session of ``client`` (``first``, ``refer``: their time None means now)."""
    if first is not None:
        first = replace(first, time=s.request_time(first.time, "first.time"))
    if refer is not None:
        refer = replace(refer, time=s.request_time(refer.time, "refer.time"))
    view = s.open(target, context, first, refer)
    session = s.sessions.open(view.handle, s.steady(), client)
    for stamp in (first, refer):
        if stamp is not None:
            s.touch(stamp.time, wm=False)
    holding = None if view.holding is None else [p for p in s.consultant.preference if p in view.holding]
    return Opened(session, view, holding)


def narrow(s: ConsultantService, session: str, prop: str, cause: Optional[str], time: Optional[float],
           turn: Optional[int]) -> Narrowed:
    """Narrow the session's view by ``prop`` (:meth:`ConsultantService.narrow`)."""
    when = s.request_time(time)
    step = s.narrow(s.sessions.get(session, s.steady()), prop, cause, when, turn)
    s.touch(when, wm=False)
    return step


def walk(s: ConsultantService, session: str, steps: Sequence[WalkStep], cause: Optional[str],
         time: Optional[float], turn: Optional[int]) -> Walked:
    """Walk the session's view by ``steps`` (:meth:`ConsultantService.walk`)."""
    when = s.request_time(time)
    walked = s.walk(s.sessions.get(session, s.steady()), steps, cause, when, turn)
    s.touch(when, wm=False)
    return walked


def rule_out(s: ConsultantService, session: str) -> tuple[list[str], list[int]]:
    """For each property holding for the session's target, the members it rules out."""
    return s.rule_out(s.sessions.get(session, s.steady()))


def close_session(s: ConsultantService, session: str, encode: Sequence[str], time: Optional[float],
                  turn: Optional[int]) -> list[str]:
    """Close the session: its members; ``encode`` encoded for the target (rule 1)."""
    when = s.request_time(time)
    members = s.close(s.sessions.get(session, s.steady()), encode, when, turn)
    s.sessions.close(session, s.steady())
    s.touch(when, wm=bool(encode) and s.buffer.retains)
    return members


# ----------------------------------------------------------------------- debug ops
def holds(s: ConsultantService, prop: str, entities: Sequence[str]) -> list[str]:
    """Return the entities ``prop`` holds for (nothing encoded)."""
    return s.consultant.holds(prop, entities)


def affirm(s: ConsultantService, prop: str, entities: Sequence[str], cause: str, time: Optional[float],
           turn: Optional[int]) -> list[str]:
    """As :func:`holds`, encoding ``prop`` for each entity it holds for."""
    when = s.request_time(time)
    held = s.affirm(prop, entities, cause, when, turn)
    s.touch(when, wm=bool(held))
    return held


def queue(s: ConsultantService, entity: str) -> list[str]:
    """Q[entity], LRU first (reading never refreshes)."""
    return s.consultant.queue(entity)


def encode(s: ConsultantService, entity: str, properties: Sequence[str], cause: str, time: Optional[float],
           turn: Optional[int]) -> None:
    """Encode ``properties`` for ``entity`` (Algorithm 1)."""
    when = s.request_time(time)
    s.encode(entity, properties, cause, when, turn)
    s.touch(when)


def snapshot(s: ConsultantService) -> tuple[dict[str, list[str]], int]:
    """Every non-empty queue, and the number of the last event published."""
    return s.buffer.snapshot(), s.seq


# ----------------------------------------------------------------------- manage ops
def configure(s: ConsultantService, policy: ForgettingPolicy, time: Optional[float]) -> Configured:
    """Install ``policy`` and serve."""
    s.configure(policy, s.request_time(time))
    return Configured(policy.to_json(), s.incarnation, s.status())


def decay(s: ConsultantService, ticks: TickRun) -> str:
    """Apply ``ticks`` now (those applied already are skipped); the installed policy's name."""
    s.decay_now(ticks)
    return s.policy.name


def advance(s: ConsultantService, time: Optional[float]) -> str:
    """Note that the clock reached ``time``; return the installed policy's name."""
    s.advance(s.request_time(time))
    return s.policy.name


def evict(s: ConsultantService, count: int, time: Optional[float]) -> int:
    """Forget the ``count`` least recently encoded fronts; the size WM is left with."""
    s.evict(count, s.request_time(time))
    return len(s.buffer)


def size(s: ConsultantService) -> int:
    """How many properties WM holds."""
    return len(s.buffer)
