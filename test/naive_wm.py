"""A deliberately naive, eager reference working memory (tests and benchmark only).

It follows SPEC.md section 2 as literally as possible and shares no code with
:mod:`fsreg_ros.core.memory` / :mod:`fsreg_ros.core.forgetting`:

* ``queues`` is a plain ``dict`` of Python lists, LRU first;
* a decay tick pops the front of *every* non-empty queue right away (O(queues));
* displacement and the global limit run after every single encoding event,
  displacement first; the global victim is the non-empty queue whose front was
  encoded least recently (one stamp counter per domain, so no ties);
* the decay schedule is "tick k at k * delta while k * delta <= T + 1e-9".

Events are recorded as plain tuples ``(op, entity, property, cause, time, turn)``;
:func:`event_key` turns a :class:`fsreg_ros.core.memory.WMEvent` into the same form.
"""

from __future__ import annotations

from typing import Iterable, Optional

EPSILON = 1e-9


def event_key(event) -> tuple:
    """A WMEvent (or an equivalent object) as ``(op, entity, property, cause, time, turn)``."""
    return (event.op, event.entity, event.property, event.cause, event.time, event.turn)


class NaiveWM:
    """Eager reference implementation of one domain's WM buffer and its policy.

    ``rules`` is a set of rule names (``decay``, ``displacement``,
    ``global-capacity``); ``None`` means "unmanaged, keep everything" (like a
    :class:`WMBuffer` without a policy) and an empty set means policy ``none``.
    """

    def __init__(
        self,
        rules: Optional[Iterable[str]] = None,
        capacity: Optional[int] = None,
        global_capacity: Optional[int] = None,
        record: bool = True,
    ) -> None:
        self.queues: dict[str, list[str]] = {}
        self.stamps: dict[tuple[str, str], int] = {}
        self.counter = 0
        self.rules: Optional[set[str]] = None if rules is None else set(rules)
        self.capacity = capacity
        self.global_capacity = global_capacity
        self.record = record
        self.events: list[tuple] = []

    # ---------------------------------------------------------------- policy
    def set_policy(
        self,
        rules: Iterable[str],
        capacity: Optional[int] = None,
        global_capacity: Optional[int] = None,
        time: float = 0.0,
    ) -> None:
        """Install a policy and apply it at once: ``none`` forgets everything (cause
        ``reset``), the size limits trim every queue (turn ``None``)."""
        self.rules = set(rules)
        self.capacity = capacity
        self.global_capacity = global_capacity
        if not self.rules:
            for entity in list(self.queues):
                while self.queues[entity]:
                    self._forget(entity, 0, "reset", time, None)
            return
        if "displacement" in self.rules:
            for entity in list(self.queues):
                while len(self.queues[entity]) > self.capacity:
                    self._forget(entity, 0, "displacement", time, None)
        if "global-capacity" in self.rules:
            self._global(time, None)

    @property
    def retains(self) -> bool:
        return self.rules is None or bool(self.rules)

    # ------------------------------------------------------------ operations
    def encode(
        self, entity: str, properties: Iterable[str], cause: str, time: float, turn: Optional[int] = None
    ) -> None:
        """Algorithm 1, one encoding event per property, limits after each event."""
        if not self.retains:
            return
        for prop in properties:
            queue = self.queues.setdefault(entity, [])
            if prop in queue:
                queue.remove(prop)
            queue.append(prop)
            self.counter += 1
            self.stamps[(entity, prop)] = self.counter
            self._log("encode", entity, prop, cause, time, turn)
            if self.rules and "displacement" in self.rules:
                while len(queue) > self.capacity:
                    self._forget(entity, 0, "displacement", time, turn)
            if self.rules and "global-capacity" in self.rules:
                self._global(time, turn)

    def tick(self, time: float) -> None:
        """One decay tick (Algorithm 2), eagerly: pop the front of every non-empty queue."""
        for entity, queue in self.queues.items():
            if queue:
                self._forget(entity, 0, "decay", time, None)

    def remove(self, entity: str, prop: str, cause: str, time: float, turn: Optional[int] = None) -> bool:
        queue = self.queues.get(entity)
        if not queue or prop not in queue:
            return False
        self._forget(entity, queue.index(prop), cause, time, turn)
        return True

    def queue(self, entity: str) -> list[str]:
        return list(self.queues.get(entity, ()))

    def snapshot(self) -> dict[str, list[str]]:
        return {e: list(q) for e, q in self.queues.items() if q}

    def total(self) -> int:
        return sum(len(q) for q in self.queues.values())

    # ------------------------------------------------------------- internals
    def _global(self, time: float, turn: Optional[int]) -> None:
        while self.total() > self.global_capacity:
            victim = min(
                (e for e, q in self.queues.items() if q),
                key=lambda e: self.stamps[(e, self.queues[e][0])],
            )
            self._forget(victim, 0, "global-capacity", time, turn)

    def _forget(self, entity: str, index: int, cause: str, time: float, turn: Optional[int]) -> None:
        prop = self.queues[entity].pop(index)
        self._log("forget", entity, prop, cause, time, turn)

    def _log(self, op: str, entity: str, prop: str, cause: str, time: float, turn: Optional[int]) -> None:
        if self.record:
            self.events.append((op, entity, prop, cause, time, turn))


class NaiveClock:
    """SPEC section 2's decay schedule, literally: tick k at origin + k * period, due
    at T iff origin + k * period <= T + 1e-9; each tick is handed out once."""

    def __init__(self, period: float, origin: float = 0.0) -> None:
        self.period = period
        self.origin = origin
        self.k = 0

    def due(self, now: float) -> list[float]:
        out = []
        while self.origin + (self.k + 1) * self.period <= now + EPSILON:
            self.k += 1
            out.append(self.origin + self.k * self.period)
        return out
