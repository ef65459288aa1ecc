"""Working memory: one buffer of per-entity property queues per domain.

This module is the *mechanism* of working memory (WM): queues, the Encode
operation of the paper's Algorithm 1, and the primitive "pop the front" that
every forgetting rule uses. *What* is forgotten, and when, is decided in
:mod:`fsreg_ros.core.forgetting` (the WM Manager's policies).

Queue order is LRU at the front and MRU at the back.  Reading a queue never
refreshes recency; only encoding does.

Decay (Algorithm 2) pops the front of every non-empty queue once per tick.  Done
eagerly that costs O(number of queues) per tick.  This buffer applies ticks
lazily instead: a tick only increments a counter, and each queue catches up
(pops one front per missed tick) the next time it is touched.  Because nothing
else touches a queue in between, the result is exactly the eager one; the tests
compare it against a naive eager implementation on random event sequences.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Iterable, Optional

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .forgetting import ForgettingPolicy

#: Causes an event can have (SPEC section 2).
ENCODE_CAUSES = ("speaker", "rr", "reg-distractor")
FORGET_CAUSES = ("decay", "displacement", "global-capacity", "reset", "retract")


@dataclass(frozen=True)
class WMEvent:
    """One encoding or forgetting in a domain's WM buffer.

    ``time`` is the robot-clock time the change happened at (a decay tick's own
    time, even when a lazy queue catches up later); ``turn`` is the dialogue turn
    index that caused it, or ``None`` for clock-driven and administrative changes.
    """

    op: str  # "encode" | "forget"
    domain: str
    entity: str
    property: str
    cause: str
    time: float
    turn: Optional[int] = None

    def to_json(self) -> dict:
        return {
            "op": self.op,
            "domain": self.domain,
            "entity": self.entity,
            "property": self.property,
            "cause": self.cause,
            "time": self.time,
            "turn": self.turn,
        }


EventSink = Callable[[WMEvent], None]


class WMBuffer:
    """A domain's WM buffer: ``Q[entity]`` queues plus the encoding stamp counter.

    Every single push gets the next value of one counter (its *stamp*), so within a
    queue stamps increase from front to back and across the domain there are no
    ties; ``global-capacity`` uses this to find the least recently encoded front.

    ``policy`` is installed by the WM Manager.  The buffer calls
    :func:`forgetting.enforce_limits` after every encoding event so that the
    size limits of Algorithm 3 (and the global limit) hold at all times.
    """

    def __init__(self, domain: str, sink: Optional[EventSink] = None) -> None:
        self.domain = domain
        self.sink = sink
        self.policy: Optional["ForgettingPolicy"] = None
        self._queues: dict[str, OrderedDict[str, int]] = {}
        self._stamp = 0
        self._size = 0  # properties stored, including ones still owed to lazy decay
        # Lazy decay: number of ticks so far, the time of each, and per queue the
        # tick count it has been brought up to.
        self._ticks = 0
        self._tick_times: list[float] = []
        self._synced: dict[str, int] = {}
        # Queues that may hold something (insertion-ordered set).
        self._nonempty: dict[str, None] = {}

    # ------------------------------------------------------------------ reads
    @property
    def retains(self) -> bool:
        """False under policy ``none``: nothing is ever retained."""
        return self.policy is None or self.policy.retains

    def queue(self, entity: str) -> tuple[str, ...]:
        """Q[entity], LRU first.  Does not refresh recency."""
        self._catch_up(entity)
        q = self._queues.get(entity)
        return tuple(q) if q else ()

    def length(self, entity: str) -> int:
        """len(Q[entity]) after applying owed decay."""
        self._catch_up(entity)
        q = self._queues.get(entity)
        return len(q) if q else 0

    def __len__(self) -> int:
        """Total number of properties held by the domain's queues."""
        self.flush()
        return self._size

    def snapshot(self) -> dict[str, list[str]]:
        """Every non-empty queue, LRU first, keyed by entity (insertion order)."""
        self.flush()
        return {e: list(self._queues[e]) for e in self._nonempty}

    def front_stamp(self, entity: str) -> int:
        """Stamp of Q[entity]'s front (call only on a caught-up, non-empty queue)."""
        return next(iter(self._queues[entity].values()))

    def nonempty_entities(self) -> list[str]:
        """Entities whose queues are non-empty, after applying owed decay."""
        self.flush()
        return list(self._nonempty)

    # ---------------------------------------------------------------- writes
    def encode(
        self,
        entity: str,
        properties: Iterable[str],
        cause: str,
        time: float,
        turn: Optional[int] = None,
    ) -> None:
        """Encode(R, P), the paper's Algorithm 1.

        For each p in P, in order: remove p from Q[R] if present and push it to the
        back.  Each push is one encoding event, after which the WM Manager's size
        limits are enforced (Algorithm 3 and the global limit).
        """
        if not self.retains:
            return
        from .forgetting import enforce_limits  # local: forgetting imports memory

        self._catch_up(entity)
        for prop in properties:
            q = self._queues.get(entity)
            if q is None:
                q = self._queues[entity] = OrderedDict()
            if prop in q:
                del q[prop]
                self._size -= 1
            self._stamp += 1
            q[prop] = self._stamp
            self._size += 1
            self._nonempty[entity] = None
            if self.sink is not None:
                self.sink(WMEvent("encode", self.domain, entity, prop, cause, time, turn))
            if self.policy is not None:
                enforce_limits(self, entity, self.policy, time, turn)

    def pop_front(
        self, entity: str, cause: str, time: float, turn: Optional[int] = None
    ) -> Optional[str]:
        """Forget Q[entity]'s LRU property; returns it, or None if Q is empty."""
        self._catch_up(entity)
        return self._pop(entity, cause, time, turn)

    def remove(
        self, entity: str, prop: str, cause: str, time: float, turn: Optional[int] = None
    ) -> bool:
        """Forget one property wherever it is in Q[entity] (used for retraction)."""
        self._catch_up(entity)
        q = self._queues.get(entity)
        if not q or prop not in q:
            return False
        del q[prop]
        self._size -= 1
        if not q:
            self._nonempty.pop(entity, None)
        self._emit_forget(entity, prop, cause, time, turn)
        return True

    def decay(self, tick_times: Iterable[float]) -> None:
        """Apply decay ticks (Algorithm 2) at the given times, lazily: O(1) each."""
        for t in tick_times:
            self._ticks += 1
            self._tick_times.append(t)

    def clear(self, cause: str, time: float, turn: Optional[int] = None) -> None:
        """Forget everything (e.g. when the policy becomes ``none``)."""
        for entity in self.nonempty_entities():
            while self._pop(entity, cause, time, turn) is not None:
                pass

    def flush(self) -> None:
        """Bring every queue up to date with the decay ticks applied so far."""
        for entity in list(self._nonempty):
            self._catch_up(entity)

    # -------------------------------------------------------------- internals
    def _catch_up(self, entity: str) -> None:
        synced = self._synced.get(entity, 0)
        owed = self._ticks - synced
        if owed:
            self._synced[entity] = self._ticks
            q = self._queues.get(entity)
            if q:
                for k in range(min(owed, len(q))):
                    self._pop(entity, "decay", self._tick_times[synced + k], None)
        elif entity not in self._synced:
            self._synced[entity] = self._ticks

    def _pop(self, entity: str, cause: str, time: float, turn: Optional[int]) -> Optional[str]:
        q = self._queues.get(entity)
        if not q:
            return None
        prop, _ = q.popitem(last=False)
        self._size -= 1
        if not q:
            self._nonempty.pop(entity, None)
        self._emit_forget(entity, prop, cause, time, turn)
        return prop

    def _emit_forget(
        self, entity: str, prop: str, cause: str, time: float, turn: Optional[int]
    ) -> None:
        if self.sink is not None:
            self.sink(WMEvent("forget", self.domain, entity, prop, cause, time, turn))
