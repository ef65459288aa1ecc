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

from itertools import islice
from typing import TYPE_CHECKING, Callable, Iterable, NamedTuple, Optional

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .forgetting import ForgettingPolicy

#: Causes an event can have (SPEC section 2).
ENCODE_CAUSES = ("speaker", "rr", "reg-distractor")
FORGET_CAUSES = ("decay", "displacement", "global-capacity", "reset", "retract")


class WMEvent(NamedTuple):
    """One encoding or forgetting in a domain's WM buffer (immutable).

    ``time`` is the robot-clock time the change happened at (a decay tick's own
    time, even when a lazy queue catches up later); ``turn`` is the dialogue turn
    index that caused it, or ``None`` for clock-driven and administrative changes.
    A named tuple rather than a frozen dataclass: one is built per encoding, and a
    tuple is about three times cheaper to build.
    """

    op: str  # "encode" | "forget"
    domain: str
    entity: str
    property: str
    cause: str
    time: float
    turn: Optional[int] = None

    def to_json(self) -> dict:
        return self._asdict()


EventSink = Callable[[WMEvent], None]


_enforce_limits: Optional[Callable[..., None]] = None


def _limits() -> Callable[..., None]:
    """:func:`forgetting.enforce_limits`, imported once (forgetting imports memory, so a
    module-level import would be circular; a function-level one costs ~1 us per call)."""
    global _enforce_limits
    if _enforce_limits is None:
        from .forgetting import enforce_limits

        _enforce_limits = enforce_limits
    return _enforce_limits


class _Queue(dict):
    """Q[entity]: an insertion-ordered dict property -> stamp, front (LRU) first.

    ``synced`` is the number of decay ticks this queue has been brought up to (lazy
    decay).  Keeping it in the queue object itself, rather than in a second
    entity-keyed table, halves the memory touched per encoding, which dominates
    when thousands of distractors are encoded at once (rule 3).  A plain dict
    subclass, not an OrderedDict, for the same reason.
    """

    __slots__ = ("synced",)


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
        self._queues: dict[str, _Queue] = {}
        self._stamp = 0
        self._size = 0  # properties stored, including ones still owed to lazy decay
        # Lazy decay: number of ticks so far and the time of each (each queue keeps
        # the tick count it has been brought up to: _Queue.synced).
        self._ticks = 0
        self._tick_times: list[float] = []  # times of ticks _tick_base, _tick_base + 1, ...
        self._tick_base = 0
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
        enforce_limits = _limits()
        self._catch_up(entity)
        for prop in properties:
            q = self._queues.get(entity)
            if q is None:
                q = self._new_queue(entity)
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

    def encode_each(
        self,
        entities: Iterable[str],
        prop: str,
        cause: str,
        time: float,
        turn: Optional[int] = None,
    ) -> None:
        """Encode(e, [prop]) (Algorithm 1) for each entity e, in the given order.

        Exactly equivalent to ``for e in entities: self.encode(e, (prop,), ...)``,
        with the same events in the same order, but cheaper per entity: this is the
        hot path of rules 2 and 3, where one affirmed property is encoded for
        thousands of candidates or distractors.  The size limits are the same as
        :func:`forgetting.enforce_limits` applies: displacement (Algorithm 3, LRU
        out of Q[e]) first, then the global limit (global LRU) after each event.
        """
        if not self.retains:
            return
        policy = self.policy
        rules = policy.rules if policy is not None else ()
        capacity = policy.capacity if "displacement" in rules else None  # type: ignore[union-attr]
        global_limit = policy.global_capacity if "global-capacity" in rules else None  # type: ignore[union-attr]
        queues = self._queues
        nonempty = self._nonempty
        sink = self.sink
        domain = self.domain
        ticks = self._ticks  # nothing below applies new ticks
        for entity in entities:
            q = queues.get(entity)
            if q is None:
                q = self._new_queue(entity)
                nonempty[entity] = None
            else:
                if q.synced != ticks:
                    self._sync(entity, q)
                # Caught up, so: entity in _nonempty  <=>  Q[entity] is non-empty.
                if not q:
                    nonempty[entity] = None
                elif prop in q:
                    del q[prop]
                    self._size -= 1
            stamp = self._stamp = self._stamp + 1
            q[prop] = stamp
            self._size += 1
            if sink is not None:
                sink(WMEvent("encode", domain, entity, prop, cause, time, turn))
            if capacity is not None:  # Algorithm 3, as forgetting.displace: LRU out
                while len(q) > capacity:  # capacity >= 1, so q never empties here
                    old = next(iter(q))
                    del q[old]
                    self._size -= 1
                    if sink is not None:
                        sink(WMEvent("forget", domain, entity, old, "displacement", time, turn))
            # _size counts properties still owed to lazy decay, so it only over-states
            # the total: at or under the limit there is nothing to evict.
            if global_limit is not None and self._size > global_limit:
                from .forgetting import evict_global

                evict_global(self, global_limit, time, turn)

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
        # Every non-empty queue is now up to date, and an empty one never needs a
        # tick's time, so the times seen so far can go (bounded memory for long runs).
        self._tick_base = self._ticks
        self._tick_times.clear()

    # -------------------------------------------------------------- internals
    def _new_queue(self, entity: str) -> _Queue:
        q = self._queues[entity] = _Queue()
        q.synced = self._ticks  # ticks before a queue existed are not owed
        return q

    def _catch_up(self, entity: str) -> None:
        """Apply the decay ticks Q[entity] still owes (if any)."""
        q = self._queues.get(entity)
        if q is not None and q.synced != self._ticks:
            self._sync(entity, q)

    def _sync(self, entity: str, q: _Queue) -> None:
        """Apply the ticks since ``q.synced``: one front pop per tick, each reported at
        its tick's own time (the eager Algorithm 2, deferred)."""
        synced = q.synced
        q.synced = ticks = self._ticks
        if not q:  # an empty queue owes nothing (and never needs a tick's time)
            return
        owed = min(ticks - synced, len(q))
        sink = self.sink
        if sink is None:  # no events to report: just drop the fronts
            self._size -= owed
            if owed == len(q):
                q.clear()
                self._nonempty.pop(entity, None)
            else:
                for _ in range(owed):
                    del q[next(iter(q))]
            return
        victims = list(islice(q, owed))  # the fronts, LRU first
        for prop in victims:
            del q[prop]
        self._size -= owed
        if not q:
            self._nonempty.pop(entity, None)
        first = synced - self._tick_base  # each pop is reported at its tick's time
        times = self._tick_times
        for k, prop in enumerate(victims):
            sink(WMEvent("forget", self.domain, entity, prop, "decay", times[first + k], None))

    def _pop(self, entity: str, cause: str, time: float, turn: Optional[int]) -> Optional[str]:
        q = self._queues.get(entity)
        if not q:
            return None
        prop = next(iter(q))
        del q[prop]
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
