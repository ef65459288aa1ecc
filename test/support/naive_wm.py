"""A deliberately naive, eager reference working memory (tests and benchmark only).

It follows docs/semantics.md section 2 as literally as possible and shares no code with
:mod:`fsreg_ros.core.memory` / :mod:`fsreg_ros.core.forgetting.policies`:

* ``queues`` is a plain ``dict`` of Python lists, LRU first;
* a decay tick pops the front of *every* non-empty queue right away (O(queues));
* similarity, displacement and the global limit run after every single encoding
  event, in that order; the global victim is the non-empty queue whose front was
  encoded least recently (one stamp counter per domain, so no ties);
* displacement's victim: the front (``displacement``), the property encoded least
  often since it entered the queue or since the policy was set, other than the one
  just encoded, first in queue order on ties (``displacement-lfu``), or one drawn
  with ``random.Random(seed).randrange`` among the others (``displacement-random``);
* similarity: an encoded property's attribute (declared, or ``attribute=`` in its
  name) forgets the entity's other properties of that attribute, front first;
* the decay schedule is "tick k at k * delta while k * delta <= T + 1e-9";
* activation (``activation=(d, tau)``): every entry keeps *all* the times its property
  was encoded since it entered; :meth:`NaiveWM.advance` to T forgets, eagerly and
  in order of time (ties: entity order, then queue order), every entry whose
  activation ln sum (t - t_j)^-d fell to tau at some c <= T + 1e-9, with event time
  c found by plain bisection on the exact sum (no approximation, no shared code);
* an entry's origin is the ``(cause, turn)`` of the encoding that made its property
  enter the queue (kept while it stays, replaced when it enters again);
* the change record lists, in first-change order, every entity that had an encode or
  forget event, or whose LFU counts a new policy reset (only counts other than 1 of
  properties in its queue, and only if the old policy was ``displacement-lfu``),
  since :meth:`NaiveWM.take_changes` was last called.

Events are recorded as plain tuples ``(op, entity, property, cause, time, turn)``;
:func:`event_key` turns a :class:`fsreg_ros.core.memory.WMEvent` into the same form.
"""

from __future__ import annotations

import math
import random
from typing import Iterable, Mapping, Optional

EPSILON = 1e-9


def event_key(event) -> tuple:
    """Return a WMEvent (or an equivalent object) as ``(op, entity, property, cause, time, turn)``."""
    return (event.op, event.entity, event.property, event.cause, event.time, event.turn)


class NaiveWM:
    """Eager reference implementation of one domain's WM buffer and its policy.

    ``rules`` is a set of rule names (``decay``, ``displacement``, ...);
    ``None`` means "unmanaged, keep everything" (like a :class:`WMBuffer` without a
    policy) and an empty set means policy ``none``.
    """

    def __init__(
        self,
        rules: Optional[Iterable[str]] = None,
        capacity: Optional[int] = None,
        global_capacity: Optional[int] = None,
        record: bool = True,
        seed: int = 0,
        attributes: Optional[Mapping[str, str]] = None,
        activation: Optional[tuple[float, float]] = None,
    ) -> None:
        self.activation = activation
        self.times: dict[tuple[str, str], list[float]] = {}
        self.queues: dict[str, list[str]] = {}
        self.stamps: dict[tuple[str, str], int] = {}
        self.counts: dict[tuple[str, str], int] = {}
        self.counter = 0
        self.rules: Optional[set[str]] = None if rules is None else set(rules)
        self.capacity = capacity
        self.global_capacity = global_capacity
        self.rng = random.Random(seed)
        self.attributes = dict(attributes or {})
        self.record = record
        self.events: list[tuple] = []
        self.origins: dict[tuple[str, str], tuple[str, Optional[int]]] = {}
        self.changed: dict[str, None] = {}

    # ---------------------------------------------------------------- policy
    def set_policy(
        self,
        rules: Iterable[str],
        capacity: Optional[int] = None,
        global_capacity: Optional[int] = None,
        time: float = 0.0,
        seed: int = 0,
    ) -> None:
        """Install a policy and apply it at once.

        ``none`` forgets everything (cause ``reset``), the size limits trim every
        queue (turn ``None``).
        """
        if self._displacing() == "displacement-lfu":  # the counts restart: exported ones may change
            for entity, queue in self.queues.items():
                if any(self.counts.get((entity, p), 1) != 1 for p in queue):
                    self.changed[entity] = None
        self.rules = set(rules)
        self.capacity = capacity
        self.global_capacity = global_capacity
        self.rng = random.Random(seed)
        self.counts = {}
        if not self.rules:
            for entity in list(self.queues):
                while self.queues[entity]:
                    self._forget(entity, 0, "reset", time, None)
            return
        if self._displacing():
            for entity in list(self.queues):
                self._displace(entity, None, time, None)
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
        self.advance(time)
        for prop in properties:
            queue = self.queues.setdefault(entity, [])
            if self.activation is not None:
                self.times.setdefault((entity, prop), []).append(time)
            if prop in queue:
                queue.remove(prop)
                self.counts[(entity, prop)] = self.counts.get((entity, prop), 1) + 1
            else:
                self.counts[(entity, prop)] = 1
                self.origins[(entity, prop)] = (cause, turn)
            queue.append(prop)
            self.counter += 1
            self.stamps[(entity, prop)] = self.counter
            self._log("encode", entity, prop, cause, time, turn)
            if self.rules and "similarity" in self.rules:
                mine = self._attribute(prop)
                for other in list(queue):
                    if mine is not None and other != prop and self._attribute(other) == mine:
                        self._forget(entity, queue.index(other), "similarity", time, turn)
            if self.rules and self._displacing():
                self._displace(entity, prop, time, turn)
            if self.rules and "global-capacity" in self.rules:
                self._global(time, turn)

    def tick(self, time: float) -> None:
        """Apply one decay tick of Algorithm 2 eagerly: pop the front of every non-empty queue."""
        for entity, queue in self.queues.items():
            if queue:
                self._forget(entity, 0, "decay", time, None)

    def remove(self, entity: str, prop: str, cause: str, time: float, turn: Optional[int] = None) -> bool:
        queue = self.queues.get(entity)
        if not queue or prop not in queue:
            return False
        self._forget(entity, queue.index(prop), cause, time, turn)
        return True

    def advance(self, now: float) -> None:
        """Forget, eagerly and in time order, every entry whose activation fell below tau at or before ``now``."""
        if self.activation is None:
            return
        while True:
            due = []
            for rank, (entity, queue) in enumerate(self.queues.items()):
                for position, prop in enumerate(queue):
                    c = self.crossing(self.times[(entity, prop)])
                    if c <= now + EPSILON:
                        due.append((c, rank, position, entity, prop))
            if not due:
                return
            c, _, _, entity, prop = min(due)
            self._forget(entity, self.queues[entity].index(prop), "activation", c, None)

    def crossing(self, times: list[float]) -> float:
        """Return when ln sum (t - t_j)^-d falls to tau after the last time: bisection on the exact sum."""
        d, tau = self.activation

        def above(t: float) -> bool:
            return sum((t - tj) ** -d for tj in times) > math.exp(tau)

        lo = hi = max(times)
        step = 1.0
        while above(hi + step):
            step *= 2.0
        hi = hi + step
        for _ in range(200):
            mid = (lo + hi) / 2
            if mid in (lo, hi):
                break
            if above(mid):
                lo = mid
            else:
                hi = mid
        return hi

    def queue(self, entity: str) -> list[str]:
        return list(self.queues.get(entity, ()))

    def origins_of(self, entity: str) -> list[tuple[str, Optional[int]]]:
        """Return the origin of each entry of the entity's queue, front first."""
        return [self.origins[(entity, p)] for p in self.queues.get(entity, ())]

    def take_changes(self) -> list[str]:
        """Return the entities changed since the last call, in first-change order, and forget them."""
        changed, self.changed = list(self.changed), {}
        return changed

    def snapshot(self) -> dict[str, list[str]]:
        return {e: list(q) for e, q in self.queues.items() if q}

    def total(self) -> int:
        return sum(len(q) for q in self.queues.values())

    # ------------------------------------------------------------- internals
    def _displacing(self) -> Optional[str]:
        found = [r for r in self.rules or () if r.startswith("displacement")]
        return found[0] if found else None

    def _displace(self, entity: str, newest: Optional[str], time: float, turn: Optional[int]) -> None:
        rule = self._displacing()
        queue = self.queues[entity]
        while len(queue) > self.capacity:
            others = [i for i, p in enumerate(queue) if p != newest]
            if rule == "displacement":
                index = 0
            elif rule == "displacement-lfu":
                fewest = min(self.counts.get((entity, queue[i]), 1) for i in others)
                index = next(i for i in others if self.counts.get((entity, queue[i]), 1) == fewest)
            else:
                index = others[self.rng.randrange(len(others))]
            self._forget(entity, index, "displacement", time, turn)

    def _attribute(self, prop: str) -> Optional[str]:
        if prop in self.attributes:
            return self.attributes[prop]
        return prop.split("=", 1)[0] if "=" in prop else None

    def _global(self, time: float, turn: Optional[int]) -> None:
        while self.total() > self.global_capacity:
            victim = min(
                (e for e, q in self.queues.items() if q),
                key=lambda e: self.stamps[(e, self.queues[e][0])],
            )
            self._forget(victim, 0, "global-capacity", time, turn)

    def _forget(self, entity: str, index: int, cause: str, time: float, turn: Optional[int]) -> None:
        prop = self.queues[entity].pop(index)
        self.times.pop((entity, prop), None)
        self._log("forget", entity, prop, cause, time, turn)

    def _log(self, op: str, entity: str, prop: str, cause: str, time: float, turn: Optional[int]) -> None:
        self.changed[entity] = None
        if self.record:
            self.events.append((op, entity, prop, cause, time, turn))


class NaiveClock:
    """docs/semantics.md section 2's decay schedule, literally.

    Tick k at origin + k * period, due at T iff origin + k * period <= T + 1e-9; each
    tick is handed out once.
    """

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
