"""Interference: what an encoding makes a buffer forget, and the domain-wide limits.

After every single encoding event the buffer enforces its :class:`Limits`
(:meth:`Interference.enforce`), in this order:

* similarity: encoding a property of an attribute forgets the entity's other
  properties of that attribute (cause ``similarity``);
* displacement, the paper's Algorithm 3: while ``len(Q[R]) > capacity`` forget a
  victim of ``Q[R]`` (cause ``displacement``): its front (``lru``), its least
  frequently encoded property but the one just encoded (``lfu``), or a random such
  property (``random``);
* the global limit: while the domain holds more than ``global_capacity``
  properties, forget the front encoded least recently in the whole domain (cause
  ``global-capacity``).

:meth:`Interference.evict_oldest` is the shared pool's trim (cause
``shared-capacity``, decided by the WM Manager): the domain's oldest fronts, as a
column operation where the queues live in columns.
"""

from __future__ import annotations

import heapq
import random
from typing import Callable, Optional

import numpy as np

from .host import HostBuffer
from .limits import Limits, attribute_of
from .queue import Queue, WMEvent


def lru_victim(q: Queue, newest: str) -> str:
    """Return the front (capacity >= 1, so never the property just encoded)."""
    return next(iter(q))


def lfu_victim(q: Queue, newest: str) -> str:
    """Return the property encoded least often since it entered (not ``newest``); ties to the least recent."""
    hits = q.hits or {}
    # min keeps the first of equals: ties go to the least recently encoded.
    return min((p for p in q if p != newest), key=lambda p: hits.get(p, 1))


class Interference:
    """One buffer's displacement victim choice and trimming primitives (see the module docstring)."""

    def __init__(self, wm: HostBuffer) -> None:
        self.wm = wm
        self.install(wm.limits)

    def install(self, limits: Limits) -> None:
        """Choose the victim rule of ``limits``; a random victim's generator starts anew from its seed."""
        limits.check()
        self.rng = random.Random(limits.seed)
        self.victim: Callable[[Queue, str], str] = {
            "lru": lru_victim, "lfu": lfu_victim, "random": self.random_victim}[limits.victim]

    def random_victim(self, q: Queue, newest: str) -> str:
        """Return a random property of ``q`` other than ``newest``."""
        candidates = [p for p in q if p != newest]
        return candidates[self.rng.randrange(len(candidates))]

    def enforce(self, entity: str, q: Queue, prop: str, time: float, turn: Optional[int]) -> None:
        """Enforce the limits after one encoding event of ``prop`` into Q[entity]."""
        limits = self.wm.limits
        if limits.similarity:
            self.interfere(entity, q, prop, time, turn)
        if limits.capacity is not None and len(q) > limits.capacity:
            self.displace(entity, q, limits.capacity, prop, time, turn)
        if limits.global_capacity is not None and self.wm.store.size > limits.global_capacity:
            self.evict_global(limits.global_capacity, time, turn)

    def interfere(self, entity: str, q: Queue, prop: str, time: float, turn: Optional[int]) -> None:
        """Similarity: forget Q[entity]'s other properties of ``prop``'s attribute, LRU first."""
        attributes = self.wm.attributes
        attribute = attribute_of(prop, attributes)
        if attribute is None:
            return
        for other in [p for p in q if p != prop and attribute_of(p, attributes) == attribute]:
            self.wm.forget_entry(entity, q, other, "similarity", time, turn)

    def displace(self, entity: str, q: Queue, capacity: int, newest: str, time: float, turn: Optional[int]) -> None:
        """Algorithm 3 (interference by displacement): keep |Q[entity]| <= capacity.

        ``newest`` (the property just encoded, or "" when trimming) is never the LFU
        or random victim; the LRU victim is the front (capacity >= 1, so never it).
        """
        while len(q) > capacity:
            self.wm.forget_entry(entity, q, self.victim(q, newest), "displacement", time, turn)

    def evict_global(self, limit: int, time: float, turn: Optional[int], cause: str = "global-capacity") -> None:
        """Keep the domain at ``limit`` properties or fewer, globally least recent out.

        While the domain holds more than ``limit`` properties, forget the front
        property with the oldest encoding stamp (possibly in the queue just encoded).
        Queues are sorted by stamp, so this is the oldest property in the whole domain.
        The domain never holds more than ``limit + 1`` properties here, so the scan over
        non-empty queues costs O(limit), independent of the number of entities.
        """
        wm = self.wm
        while len(wm) > limit:
            victim = min(wm.store.holding(), key=wm.front_stamp)
            wm.pop_entry(victim, cause, time, turn)

    def evict_oldest(self, count: int, cause: str, time: float) -> None:
        """Forget the ``count`` least recently encoded fronts of the domain (a shared pool's trim).

        One at a time, the front with the oldest stamp goes: since every queue is in
        stamp order, those are the ``count`` oldest entries of the whole domain, so
        column queues are trimmed as a column operation (:meth:`_evict_columns`).
        """
        total = len(self.wm)  # flushes
        if count <= 0 or not total:
            return
        if not self.wm.store.columns.entities:
            self.evict_global(max(total - count, 0), time, None, cause)
            return
        self._evict_columns(min(count, total), cause, time)

    def _evict_columns(self, count: int, cause: str, time: float) -> None:
        """Forget the ``count`` oldest entries of the domain, oldest first, with column queues.

        Each is the front of its queue when it goes.  The column queues' oldest are
        found by one partial sort of their stamps, the dict queues' by a heap.
        """
        wm = self.wm
        columns = wm.store.columns
        arrays = columns.store
        rows = arrays.non_empty()
        stamps, owners, props = arrays.entries(rows)
        if len(stamps) > count:
            oldest = np.argpartition(stamps, count - 1)[:count]
            stamps, owners, props = stamps[oldest], owners[oldest], props[oldest]
        victims: list[tuple] = [(stamp, row, pid, None) for stamp, row, pid in
                                zip(stamps.tolist(), owners.tolist(), props.tolist())]
        victims += heapq.nsmallest(count, ((value if value.__class__ is int else value[0], entity, prop, q)
                                           for entity, q in wm.store.dict_queues() for prop, value in q.items()),
                                   key=lambda victim: victim[0])
        victims.sort(key=lambda victim: victim[0])  # stamps are unique
        popped: dict[int, int] = {}  # column row -> fronts it loses
        for _, where, prop, q in victims[:count]:
            if q is not None:  # a dict queue's front
                wm.forget_entry(where, q, prop, cause, time, None)
                continue
            name = columns.bound[where]
            if where not in popped:
                wm.changes.note(name)
            popped[where] = popped.get(where, 0) + 1
            if wm.sink is not None:
                wm.sink(WMEvent("forget", wm.domain, name, columns.prop_name[prop], cause, time, None))
        if popped:
            touched = np.fromiter(popped, dtype=np.intp, count=len(popped))
            wm.store.pop_rows(touched, np.fromiter(popped.values(), dtype=np.int64, count=len(popped)))
