"""Open RR and REG requests at a consultant: a bounded table of candidate sets, with expiry.

A request opens a session (its candidate or distractor set stays at the consultant),
names it by id in every later call, and closes it at the end.  So that a caller that
crashes or loses its connection leaks nothing, a session not used for ``timeout``
seconds expires, and at most ``capacity`` sessions are open: opening one more drops
the least recently used.  A call naming a closed, expired or dropped session is
refused (:class:`SessionError`) and changes nothing.  Time is a monotonic clock in
seconds, given by the caller (so tests can drive it).
"""

from __future__ import annotations

import secrets
from collections import OrderedDict
from typing import Generic, TypeVar

from .consultant import KnowledgeError

S = TypeVar("S")

DEFAULT_CAPACITY = 64
DEFAULT_TIMEOUT = 30.0


class SessionError(KnowledgeError):
    """A call names a session that is not open (never was, closed, expired or dropped)."""


class SessionTable(Generic[S]):
    """Open sessions by id, least recently used first."""

    def __init__(self, capacity: int = DEFAULT_CAPACITY, timeout: float = DEFAULT_TIMEOUT) -> None:
        self.capacity = max(1, int(capacity))
        self.timeout = float(timeout)
        self._prefix = secrets.token_hex(3)  # ids of a restarted consultant never match old ones
        self._next = 0
        self._open: OrderedDict[str, tuple[S, float]] = OrderedDict()

    def __len__(self) -> int:
        return len(self._open)

    def open(self, state: S, now: float) -> str:
        """Store ``state`` as a new session; return its id."""
        self.expire(now)
        while len(self._open) >= self.capacity:
            self._open.popitem(last=False)
        self._next += 1
        session = f"{self._prefix}-{self._next}"
        self._open[session] = (state, now)
        return session

    def get(self, session: str, now: float) -> S:
        """Return an open session's state (and count this as a use); SessionError if not open."""
        self.expire(now)
        entry = self._open.get(session)
        if entry is None:
            raise SessionError(f"no open session {session!r} (closed, expired after {self.timeout:g} s "
                               f"unused, or dropped: at most {self.capacity} are open)")
        self._open[session] = (entry[0], now)
        self._open.move_to_end(session)
        return entry[0]

    def close(self, session: str, now: float) -> S:
        """Return an open session's state and forget the session; SessionError if not open."""
        state = self.get(session, now)
        del self._open[session]
        return state

    def expire(self, now: float) -> int:
        """Forget every session unused for longer than the timeout; return how many."""
        dropped = 0
        while self._open:
            session, (_, used) = next(iter(self._open.items()))
            if now - used <= self.timeout:
                break
            del self._open[session]
            dropped += 1
        return dropped
