"""Open views at a consultant: opening and closing one, and the bounded table that holds them.

A view is one RR or REG request's candidate (or distractor) set kept at the consultant
(:class:`~fsreg_ros.core.algorithms.port.View` is what the port reports of it).  :func:`open_view`
opens one over a :class:`~fsreg_ros.core.consultant.consultant.Consultant` and :func:`close_view`
closes it (rule 1's encoding); the service calls both.

Over the graph a view is named by a *session* id (the wire field ``session``, the error
kind ``SessionError``): :class:`ViewTable` keeps them.  A request opens a session (its
candidate or distractor set stays at the consultant), names it by id in every later
call, and closes it at the end.  So that a caller that crashes or loses its connection
leaks nothing, a session not used for ``timeout`` seconds expires.  So that one busy
client cannot starve the others, each client (the ``client`` id an ``open`` carries;
requests without one share the anonymous client ``""``) may hold at most ``per_client``
sessions: opening one more drops *its own* least recently used session, never another
client's.  At most ``capacity`` sessions are open in all; when the table is full, the
least recently used session of the client holding the most is dropped (the opener's own
on a tie), so a client within its fair share keeps its sessions.  A call naming a closed,
expired or dropped session is refused (:class:`SessionError`) and changes nothing.  Time
is a monotonic clock in seconds, given by the caller (so tests can drive it).
"""

from __future__ import annotations

import secrets
from collections import OrderedDict
from dataclasses import dataclass
from typing import Generic, Optional, Sequence, TypeVar

from .consultant import CandidateSet, Consultant, KnowledgeError
from ..algorithms.port import Narrowed, Reference, Step, View

S = TypeVar("S")

DEFAULT_CAPACITY = 256
DEFAULT_PER_CLIENT = 16
DEFAULT_TIMEOUT = 30.0


class SessionError(KnowledgeError):
    """A call names a session that is not open (never was, closed, expired or dropped)."""


@dataclass
class _Entry(Generic[S]):
    state: S
    used: float
    client: str


class ViewTable(Generic[S]):
    """Open views by session id, least recently used first, with a quota per client."""

    def __init__(self, capacity: int = DEFAULT_CAPACITY, timeout: float = DEFAULT_TIMEOUT,
                 per_client: int = DEFAULT_PER_CLIENT) -> None:
        self.capacity = max(1, int(capacity))
        self.per_client = max(1, min(int(per_client), self.capacity))
        self.timeout = float(timeout)
        self._prefix = secrets.token_hex(3)  # ids of a restarted consultant never match old ones
        self._next = 0
        self._open: OrderedDict[str, _Entry[S]] = OrderedDict()
        self._clients: dict[str, OrderedDict[str, None]] = {}  # client -> its sessions, LRU first
        self.dropped = 0  # sessions dropped to make room (not expired, not closed)

    def __len__(self) -> int:
        return len(self._open)

    def held(self, client: str) -> int:
        """Return how many sessions ``client`` holds."""
        return len(self._clients.get(client, ()))

    def open(self, state: S, now: float, client: str = "") -> str:
        """Store ``state`` as a new session of ``client``; return its id."""
        self.expire(now)
        mine = self._clients.get(client)
        if mine is not None and len(mine) >= self.per_client:
            self._drop(next(iter(mine)))
        while len(self._open) >= self.capacity:
            self._drop(self._victim(client))
        self._next += 1
        session = f"{self._prefix}-{self._next}"
        self._open[session] = _Entry(state, now, client)
        self._clients.setdefault(client, OrderedDict())[session] = None
        return session

    def get(self, session: str, now: float) -> S:
        """Return an open session's state (and count this as a use); SessionError if not open."""
        self.expire(now)
        entry = self._open.get(session)
        if entry is None:
            raise SessionError(f"no open session {session!r} (closed, expired after {self.timeout:g} s "
                               f"unused, or dropped: at most {self.per_client} per client and {self.capacity} "
                               "in all are open)")
        entry.used = now
        self._open.move_to_end(session)
        self._clients[entry.client].move_to_end(session)
        return entry.state

    def close(self, session: str, now: float) -> S:
        """Return an open session's state and forget the session; SessionError if not open."""
        state = self.get(session, now)
        self._forget(session)
        return state

    def expire(self, now: float) -> int:
        """Forget every session unused for longer than the timeout; return how many."""
        dropped = 0
        while self._open:
            session, entry = next(iter(self._open.items()))
            if now - entry.used <= self.timeout:
                break
            self._forget(session)
            dropped += 1
        return dropped

    # ------------------------------------------------------------ internals
    def _victim(self, opener: str) -> str:
        """Return the session to drop from a full table: the LRU one of the client holding the most."""
        most = max(len(sessions) for sessions in self._clients.values())
        if len(self._clients.get(opener, ())) == most:
            return next(iter(self._clients[opener]))
        for session, entry in self._open.items():  # LRU first
            if len(self._clients[entry.client]) == most:
                return session
        raise AssertionError("unreachable: a full table has a client holding the most")

    def _drop(self, session: str) -> None:
        self._forget(session)
        self.dropped += 1

    def _forget(self, session: str) -> None:
        entry = self._open.pop(session)
        sessions = self._clients[entry.client]
        del sessions[session]
        if not sessions:
            del self._clients[entry.client]


def open_view(
    consultant: Consultant, target: Optional[str], context: Optional[Sequence[str]], first: Optional[Step] = None,
    refer: Optional[Reference] = None, begin: bool = True,
) -> View:
    """Open a candidate set at ``consultant`` and describe it as a :class:`View` (its handle is the set).

    With ``first``, narrow it by that step (as :meth:`ConsultantPort.open` says).  With
    ``refer`` (REG's act of referring; the caller checked there is a target), the set is
    marked referred and, when ``begin``, the target's next reference episode begins at
    ``refer``'s time and turn *before* Q[target] is read (docs/semantics.md section 2):
    what the view reports is WM as the episode found it.
    """
    candidates = consultant.open_set(target, context)
    size = candidates.size
    if target is None:
        view = View(candidates, size, [], consultant.wm.retains)
    else:
        if refer is not None:
            candidates.referred = True
            if begin:
                consultant.wm.begin_episode(target, refer.time, refer.turn)
        holding = frozenset(consultant.properties_of(target))
        queue, origins = consultant.wm.queue_with_origins(target)  # (open_set checked the target)
        view = View(candidates, size, list(queue), consultant.wm.retains, holding, origins=origins,
                    strength=consultant.wm.strength(target) if queue else [])
    if first is not None:
        holds = consultant.narrow(candidates, first.prop, first.cause, first.time, first.turn)
        view.first = Narrowed(holds, candidates.size)
    return view


def close_view(
    consultant: Consultant, candidates: CandidateSet, encode: Sequence[str], time: float, turn: Optional[int]
) -> list[str]:
    """Return a candidate set's members after encoding ``encode`` as :meth:`ConsultantPort.close` says.

    Encoding ``encode`` (rule 1) is an act of referring to the target (REG) or to the
    resolved referent (RR): the entity's next reference episode begins just before it
    (docs/semantics.md section 2), unless it began when the set was opened (``referred``:
    REG's open with a reference).
    """
    members = consultant.members(candidates)
    if encode:
        if candidates.target is not None:
            speaker = consultant.entities[candidates.target]
        elif len(members) == 1:
            speaker = members[0]
        else:
            raise KnowledgeError(f"cannot encode for the only member: {len(members)} members remain")
        # A reference episode begins first, unless REG's open began it.
        consultant.encode(speaker, encode, "speaker", time, turn, episode=not candidates.referred)
    return members
