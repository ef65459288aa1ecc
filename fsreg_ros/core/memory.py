"""Working memory: one buffer of per-entity property queues per domain.

This module is the *mechanism* of working memory (WM): queues, the Encode
operation of the paper's Algorithm 1, and the trimming primitives every forgetting
rule uses (pop the front, displace out of one queue, evict the globally least
recently encoded front).  *What* is forgotten, and when, is decided by the WM
Manager (:mod:`fsreg_ros.core.wm_manager`, with the policies of
:mod:`fsreg_ros.core.forgetting`): it sets the buffer's :class:`Limits` (data), and
the buffer enforces them after every single encoding event.  This module imports
neither of those (dependencies run one way).

Queue order is LRU at the front and MRU at the back.  Reading a queue never
refreshes recency; only encoding does.

Decay (Algorithm 2) pops the front of every non-empty queue once per tick.  Done
eagerly that costs O(number of queues) per tick.  This buffer applies ticks
lazily instead: a tick only enters a :class:`~fsreg_ros.core.decay.TickLedger`, and
each queue catches up (pops one front per missed tick, at most its length) the
next time it is touched.  Because nothing else touches a queue in between, the
result is exactly the eager one; the tests compare it against a naive eager
implementation on random event sequences.  :meth:`WMBuffer.decay_now` applies
ticks eagerly instead, in the canonical event order (tick by tick, entity order
within a tick), for a consultant that publishes every event as it happens.

Two records are kept beside the queues, whatever event sink is attached (or none):

* **changes**: the entities whose queue changed since :meth:`WMBuffer.take_changes`
  was last called, so a consultant persists exactly those queues without listening
  to events;
* **origins**: every queue entry knows the cause and turn of the encoding that made
  its property *enter* the queue (a refresh while present keeps it; after it is
  forgotten, the next encoding sets a new one): :meth:`WMBuffer.origins`.

In a large domain, rule 2 and 3 encodings (:meth:`WMBuffer.encode_members`) keep the
queues they touch as numpy columns (:mod:`fsreg_ros.core.columns`) while no event
sink listens and the limits are at most an LRU capacity: one vectorised operation per
encoding call instead of Python work per entity, with exactly the same results.
"""

from __future__ import annotations

import heapq
import random
import sys
from dataclasses import dataclass
from bisect import bisect_right
from itertools import islice
from typing import Callable, Iterable, Mapping, NamedTuple, Optional, Sequence, Union

import numpy as np

from . import bitset
from .columns import QueueColumns
from .decay import TickLedger, TickRun

#: Causes an event can have (docs/semantics.md section 2).
ENCODE_CAUSES = ("speaker", "rr", "reg-distractor")
FORGET_CAUSES = ("decay", "displacement", "similarity", "global-capacity", "shared-capacity", "reset", "retract")
#: How displacement chooses the property it forgets from an over-full queue.
VICTIMS = ("lru", "lfu", "random")
#: The origin log is pruned when it reaches twice its size after the last pruning, or this.
_ORIGIN_LOG_MIN = 1024
#: :meth:`WMBuffer.encode_members` keeps the queues of a domain of at least this many
#: entities as columns (:mod:`fsreg_ros.core.columns`); smaller domains go queue by
#: queue.  A column operation costs tens of microseconds however few its members, and
#: a queue moved between the two forms costs more than an encoding, so the choice is
#: made per domain, not per call (bench_core, scripts/bench_encode.py).
COLUMN_MIN = 4096
#: Column queues are used up to this displacement capacity (their width), and while
#: width x entities stays within this many slots (20 bytes each, held for every entity).
COLUMN_MAX_WIDTH = 64
COLUMN_MAX_SLOTS = 2**22
#: The change record is compacted when it holds this many column-operation marks.
_CHANGE_MARKS_MAX = 4096
#: No column rows.
_NO_ROWS = np.zeros(0, dtype=np.intp)


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

#: ``(cause, turn)`` of the encoding that made a property enter a queue.
Origin = tuple[str, Optional[int]]
#: The origin of entries restored from a store that kept none (items of three fields).
UNKNOWN_ORIGIN: Origin = ("unknown", None)


class QueueItem(NamedTuple):
    """One entry of an exported queue (:meth:`WMBuffer.export_queue`), for a store.

    ``stamp`` is the entry's latest encoding stamp; ``hits`` its LFU count (1 when LFU
    is not in force); ``cause`` and ``turn`` its origin: the encoding that made the
    property enter the queue.  The first three fields keep the order of the former
    ``(property, stamp, hits)`` tuples.
    """

    property: str
    stamp: int
    hits: int
    cause: str
    turn: Optional[int]


@dataclass(frozen=True)
class Limits:
    """What a buffer may hold, enforced after every encoding event (set by the WM Manager).

    * ``retains``: False forgets everything and encodes nothing (policy ``none``);
    * ``capacity``: at most this many properties per queue (Algorithm 3); the victim
      is the queue's front (``lru``), its least frequently encoded property other
      than the one just encoded (``lfu``, ties to the LRU one), or a random such
      property (``random``, drawn from ``random.Random(seed)``, created anew each
      time the limits are set);
    * ``similarity``: encoding a property of an attribute forgets the entity's other
      properties of that attribute (interference by similarity);
    * ``global_capacity``: at most this many properties in the domain; the victim is
      the front encoded least recently in the whole domain.

    Order after one encoding event: similarity, then capacity, then the global limit.
    """

    retains: bool = True
    capacity: Optional[int] = None
    victim: str = "lru"
    similarity: bool = False
    global_capacity: Optional[int] = None
    seed: int = 0


UNLIMITED = Limits()


def attribute_of(prop: str, attributes: Mapping[str, str]) -> Optional[str]:
    """Return the attribute ``prop`` belongs to, or None if it has none.

    It is declared in ``attributes``, or the part before ``=`` in an
    ``attribute=value`` name.
    """
    found = attributes.get(prop)
    if found is None and "=" in prop:
        found = prop.split("=", 1)[0]
    return found


def _is_origin(cause: object, turn: object) -> bool:
    """Tell whether ``(cause, turn)`` can be an origin: a cause name and a turn index or None."""
    return isinstance(cause, str) and (turn is None or isinstance(turn, int) and not isinstance(turn, bool))


class _Queue(dict):
    """Q[entity]: an insertion-ordered dict property -> entry, front (LRU) first.

    An entry is its stamp (an ``int``) while the property has not been encoded again
    since it entered the queue: its origin is then the encoding with that very stamp,
    found in the buffer's origin log (:meth:`WMBuffer._origin_at`).  A refreshed entry
    is the pair ``(stamp, reference)``, the reference being the stamp its property
    entered with, or, for an entry restored from a store, its origin itself.  So the
    common encoding, a property entering a queue, stores one int and builds no
    per-entry object (measured: a pair per entry made rule-3 encodings into 10,000
    queues half again as slow).

    ``synced`` is the number of decay ticks this queue has been brought up to (lazy
    decay).  Keeping it in the queue object itself, rather than in a second
    entity-keyed table, halves the memory touched per encoding, which dominates
    when thousands of distractors are encoded at once (rule 3).  A plain dict
    subclass, not an OrderedDict, for the same reason.  ``hits`` counts encodings per
    property for LFU displacement (only kept while LFU is in force).  ``marked``: the
    queue is in the buffer's change record already (so recording a change is one
    attribute test on an object just touched, not a store into a table).
    """

    __slots__ = ("synced", "hits", "marked")


class WMBuffer:
    """A domain's WM buffer: ``Q[entity]`` queues plus the encoding stamp counter.

    Every single push gets the next value of one counter (its *stamp*), so within a
    queue stamps increase from front to back and across the domain there are no
    ties; the global limit uses this to find the least recently encoded front.

    ``limits`` are installed by the WM Manager (:meth:`set_limits`); a buffer never
    configured keeps everything (:data:`UNLIMITED`).  ``attributes`` maps property
    -> attribute for similarity interference.

    The origin log maps stamps to origins: ``_origin_starts[i]`` is the first stamp
    of a run of encodings that all had origin ``_origin_runs[i]`` (consecutive calls
    with the same cause and turn share one run).  It only has to answer for entries
    that refer to an entering stamp, so it is pruned to those from time to time.

    Each queue lives in exactly one place: a :class:`_Queue` in ``_queues``, or a row
    of the column store (:class:`~fsreg_ros.core.columns.QueueColumns`, entities in
    ``_in_columns``), where :meth:`encode_members` puts the members of rule 2 and 3
    encodings in a large domain while no event sink listens and the limits are at
    most an LRU capacity.  Anything else that touches a column queue first moves it back to a
    dict (:meth:`_to_dict`), so every other code path only ever sees dicts.
    """

    def __init__(
        self, domain: str, sink: Optional[EventSink] = None, attributes: Optional[Mapping[str, str]] = None
    ) -> None:
        self.domain = domain
        self.sink = sink
        self.attributes: dict[str, str] = dict(attributes or {})
        self.limits = UNLIMITED
        self._rng = random.Random(0)
        self._victim: Callable[[_Queue, str], str] = self._lru_victim
        self._queues: dict[str, _Queue] = {}
        self._stamp = 0
        self._size = 0  # properties stored, including ones still owed to lazy decay
        # Lazy decay: every tick so far (each queue keeps the tick count it has been
        # brought up to: _Queue.synced).
        self.ticks = TickLedger()
        # Queues that may hold something (insertion-ordered set).
        self._nonempty: dict[str, None] = {}
        # Entities whose queue changed since take_changes, in first-change order (an int
        # is a column operation's mark, see _expand_changes; a name may recur), and the
        # tick count every queue has been brought up to (flush, decay_now, restore).
        self._changed: list[Union[str, int]] = []
        self._settled = 0
        self._origin_starts: list[int] = []
        self._origin_runs: list[Origin] = []
        self._origin_prune_at = _ORIGIN_LOG_MIN
        # The column store (None until encode_members uses it), the entity list its rows
        # are numbered by, property ids, origins restored from a store (column
        # references -(i + 1)), and the number of column marks in _changed.
        self.column_min = COLUMN_MIN
        self._columns: Optional[QueueColumns] = None
        self._bound: Optional[list[str]] = None
        self._row: dict[str, int] = {}
        self._in_columns: set[str] = set()
        self._prop_id: dict[str, int] = {}
        self._prop_name: list[str] = []
        self._explicit: list[Origin] = []
        self._explicit_id: dict[Origin, int] = {}
        self._marks = 0

    # ------------------------------------------------------------------ reads
    @property
    def retains(self) -> bool:
        """False under policy ``none``: nothing is ever retained."""
        return self.limits.retains

    def queue(self, entity: str) -> tuple[str, ...]:
        """Q[entity], LRU first.  Does not refresh recency."""
        q = self._readable(entity)
        return tuple(q) if q else ()

    def origins(self, entity: str) -> list[Origin]:
        """Return the origin ``(cause, turn)`` of each entry of Q[entity], parallel to :meth:`queue`.

        An entry's origin is the encoding that made its property enter the queue
        (Algorithm 1's push of a property not in Q); a refresh while present keeps it.
        """
        q = self._readable(entity)
        return [self._origin_of(value) for value in q.values()] if q else []

    def length(self, entity: str) -> int:
        """len(Q[entity]) after applying owed decay."""
        q = self._readable(entity)
        return len(q) if q else 0

    def __len__(self) -> int:
        """Total number of properties held by the domain's queues."""
        self.flush()
        return self._size

    def snapshot(self) -> dict[str, list[str]]:
        """Every non-empty queue, LRU first, keyed by entity (insertion order)."""
        self.flush()
        if not self._in_columns:
            return {e: list(self._queues[e]) for e in self._nonempty}
        return {
            e: list(self._row_dict(self._row[e])) if e in self._in_columns else list(self._queues[e])
            for e in self._nonempty
        }

    def front_stamp(self, entity: str) -> int:
        """Stamp of Q[entity]'s front (call only on a caught-up, non-empty queue)."""
        if entity in self._in_columns:
            self._to_dict(entity)
        value = next(iter(self._queues[entity].values()))
        return value if value.__class__ is int else value[0]

    def nonempty_entities(self) -> list[str]:
        """Entities whose queues are non-empty, after applying owed decay."""
        self.flush()
        return list(self._nonempty)

    # --------------------------------------------------------------- changes
    def take_changes(self) -> list[str]:
        """Return the entities whose queue changed since the last call, in first-change order; reset the record.

        A queue changed when an encoding or a forgetting touched it (any cause), or
        when new limits reset its LFU counts: after this call, :meth:`export_queue` of
        each entity returned, with :meth:`counters`, is all a store needs to hold the
        buffer's state (an entity returned with an empty queue: delete it).  The record
        is kept whatever event sink is attached, on every code path.

        Decay ticks given lazily (:meth:`decay`) are applied first (a :meth:`flush`,
        O(non-empty queues), only when ticks arrived since the last one): a queue that
        still owed a tick would otherwise be restored without it.  A lazily caught-up
        queue counts as changed when the pops are applied, so its place in the order
        is then, not the tick's; with :meth:`decay_now` it is the tick's.
        :meth:`restore` records nothing and clears the record.
        """
        if self.ticks.count != self._settled:
            self.flush()
        changed = self._expand_changes()
        queues = self._queues
        for entity in changed:  # out of the record: the next change records it again
            q = queues.get(entity)
            if q is not None:
                q.marked = False
        self._changed, self._marks = [], 0
        return changed

    def _expand_changes(self) -> list[str]:
        """Return the change record as distinct entity names, in order, and clear its column part.

        ``_changed`` holds entity names (a queue moved to the columns and back may be
        named twice), and for each column operation an int mark standing for the rows
        it changed first (in row order, which is entity order).
        """
        if self._marks:
            rows, marks = self._columns.take_changed()
            bound = self._bound
        out: dict[str, None] = {}
        for key in self._changed:
            if key.__class__ is int:
                end = int(np.searchsorted(marks, key, side="right"))
                start = int(np.searchsorted(marks, key, side="left"))
                out.update(dict.fromkeys([bound[r] for r in rows[start:end].tolist()]))
            elif key not in out:
                out[key] = None
        return list(out)

    def _compact_changes(self) -> None:
        """Replace the change record's column marks by the names they stand for."""
        if self._marks:
            self._changed = self._expand_changes()
            self._marks = 0

    def _record(self, entity: str, q: _Queue) -> None:
        """Note that Q[entity] (a dict queue) changed."""
        if not q.marked:
            q.marked = True
            self._changed.append(entity)

    # ---------------------------------------------------------------- limits
    def set_limits(self, limits: Limits, time: float) -> None:
        """Install new limits and apply them to every queue at once (docs/semantics.md section 7).

        Not retaining forgets everything (cause ``reset``); a capacity trims every
        queue; a global limit trims the domain.  Similarity applies from the next
        encoding on.  Queues are trimmed one after the other, in no specified order
        (what each loses depends on itself only; the global victims on stamps only).
        """
        if limits.victim not in VICTIMS:
            raise ValueError(f"unknown displacement victim {limits.victim!r} (known: {', '.join(VICTIMS)})")
        if not self._columns_fit(limits):
            self._drop_columns()
        self.limits = limits
        self._rng = random.Random(limits.seed)
        self._victim = {"lru": self._lru_victim, "lfu": self._lfu_victim, "random": self._random_victim}[limits.victim]
        for entity, q in self._queues.items():
            hits = q.hits
            if hits is not None:  # the LFU counts restart: an exported count may change
                if any(hits.get(prop, 1) != 1 for prop in q):
                    self._record(entity, q)
                q.hits = None
        if not limits.retains:
            self._forget_all("reset", time, None)
            return
        if limits.capacity is not None:
            self.flush()
            for entity, q in self._queues.items():
                self._displace(entity, q, limits.capacity, "", time, None)
        if limits.global_capacity is not None:
            self._evict_global(limits.global_capacity, time, None)

    def evict_oldest(self, count: int, cause: str, time: float) -> None:
        """Forget the ``count`` least recently encoded fronts of the domain (a shared pool's trim).

        One at a time, the front with the oldest stamp goes: since every queue is in
        stamp order, those are the ``count`` oldest entries of the whole domain, so
        column queues are trimmed as a column operation (:meth:`_evict_columns`).
        """
        total = len(self)  # flushes
        if count <= 0 or not total:
            return
        if not self._in_columns:
            self._evict_global(max(total - count, 0), time, None, cause)
            return
        self._evict_columns(min(count, total), cause, time)

    # ---------------------------------------------------------------- writes
    def encode(
        self,
        entity: str,
        properties: Iterable[str],
        cause: str,
        time: float,
        turn: Optional[int] = None,
    ) -> None:
        """Encode properties into Q[R]: Encode(R, P), the paper's Algorithm 1.

        For each p in P, in order: remove p from Q[R] if present and push it to the
        back.  Each push is one encoding event, after which the limits are enforced
        (:meth:`_enforce`: similarity, Algorithm 3, the global limit).
        """
        if not self.retains:
            return
        for prop in properties:
            self.encode_each((entity,), prop, cause, time, turn)

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
        with the same events in the same order: this is the hot path of rules 2 and
        3, where one affirmed property is encoded for thousands of candidates or
        distractors.  With no event sink and no limit beyond an LRU capacity, each
        entity costs one dict assignment (plus the displaced front, if any:
        :meth:`_encode_quiet`); events are only built when a sink listens, and every
        other case goes through :meth:`_enforce`, Algorithm 3's one implementation.
        """
        limits = self.limits
        if not limits.retains:
            return
        self._log_origin(cause, turn)
        if self.sink is None and limits.victim == "lru" and not limits.similarity and limits.global_capacity is None:
            self._encode_quiet(entities, prop, limits.capacity)
            return
        lfu = limits.victim == "lfu"
        for entity in entities:
            q = self._queues.get(entity)
            if q is None and entity in self._in_columns:
                q = self._to_dict(entity)
            if q is None:
                q = self._new_queue(entity)
            else:
                self._catch_up(entity)
            old = q.pop(prop, None)
            present = old is not None
            self._stamp += 1
            if present:  # a refresh keeps the entry's origin
                q[prop] = (self._stamp, old if old.__class__ is int else old[1])
            else:
                q[prop] = self._stamp
                self._size += 1
            self._nonempty[entity] = None
            self._record(entity, q)
            if lfu:  # encodings since prop entered Q (or since the limits were set)
                if q.hits is None:
                    q.hits = {}
                q.hits[prop] = q.hits.get(prop, 1) + 1 if present else 1
            if self.sink is not None:
                self.sink(WMEvent("encode", self.domain, entity, prop, cause, time, turn))
            self._enforce(entity, q, prop, time, turn)

    def _encode_quiet(self, entities: Iterable[str], prop: str, capacity: Optional[int]) -> None:
        """Run :meth:`encode_each` with no events and at most an LRU capacity.

        Per entity: the decay ticks it owes (inline), one dict assignment and, when the
        queue is full, one front deletion; the entity joins the change record.  No
        event objects, no calls per entity, no object per entry (see :class:`_Queue`).
        """
        queues = self._queues
        nonempty = self._nonempty
        changed = self._changed
        in_columns = self._in_columns
        ticks = self.ticks.count  # nothing below applies new ticks
        limit = capacity if capacity is not None else sys.maxsize
        stamp = self._stamp
        size = self._size
        for entity in entities:
            q = queues.get(entity)
            if q is None:
                if entity not in in_columns:
                    q = queues[entity] = _Queue()
                    q.synced = ticks
                    q.hits = None
                    q.marked = True
                    changed.append(entity)
                    nonempty[entity] = None
                    stamp += 1
                    q[prop] = stamp
                    size += 1
                    continue
                q = self._to_dict(entity)
            if not q.marked:
                q.marked = True
                changed.append(entity)
            owed = ticks - q.synced
            if owed:  # lazy decay catch-up, inline (:meth:`_sync` without a sink)
                q.synced = ticks
                if owed >= len(q):
                    if q:
                        size -= len(q)
                        q.clear()
                        del nonempty[entity]
                else:
                    size -= owed
                    for _ in range(owed):
                        del q[next(iter(q))]
            # Caught up, so: entity in _nonempty  <=>  Q[entity] is non-empty.
            if prop in q:  # a refresh: same size, the entry keeps its origin
                old = q.pop(prop)
                stamp += 1
                q[prop] = (stamp, old if old.__class__ is int else old[1])
                continue
            if not q:
                nonempty[entity] = None
            stamp += 1
            q[prop] = stamp
            if len(q) > limit:  # Algorithm 3, LRU out (capacity >= 1: never prop itself)
                del q[next(iter(q))]
            else:
                size += 1
        self._stamp, self._size = stamp, size

    def encode_members(
        self,
        members: int,
        entities: Sequence[str],
        prop: str,
        cause: str,
        time: float,
        turn: Optional[int] = None,
    ) -> None:
        """Encode(e, [prop]) (Algorithm 1) for each member e, in entity order: rules 2 and 3.

        ``members`` is a bitset over ``entities`` (:mod:`fsreg_ros.core.bitset`; the
        domain's entity list, which may only grow by appending).  Exactly
        ``self.encode_each(bitset.names(members, entities), prop, ...)``: same queues,
        stamps, origins, sizes and change record.  With no event sink, limits of at
        most an LRU capacity (Algorithm 3) and a domain of at least :data:`COLUMN_MIN`
        entities, it is one column operation over the members' queues
        (:class:`~fsreg_ros.core.columns.QueueColumns`), with their owed decay
        (Algorithm 2) applied the same way, instead of Python work per entity.
        """
        limits = self.limits
        if not limits.retains or not members:
            return
        capacity = limits.capacity
        if (
            len(entities) < self.column_min
            or self.sink is not None
            or limits.victim != "lru"
            or limits.similarity
            or limits.global_capacity is not None
            or capacity is None
            or capacity > COLUMN_MAX_WIDTH
            or capacity * len(entities) > COLUMN_MAX_SLOTS
            or not self._bind(entities, capacity)
        ):
            self.encode_each(bitset.names(members, entities), prop, cause, time, turn)
            return
        rows = bitset.index_array(members)
        if not self._adopt(rows):  # a queue longer than the capacity (restored so): queue by queue
            self.encode_each(bitset.names(members, entities), prop, cause, time, turn)
            return
        self._log_origin(cause, turn)
        columns = self._columns
        pid = self._prop_id.get(prop)
        if pid is None:
            pid = self._prop_id[prop] = len(self._prop_name)
            self._prop_name.append(prop)
        popped = columns.pop_owed(rows, self.ticks.count)
        grew, was_empty = columns.encode(rows, pid, self._stamp + 1)
        self._stamp += len(rows)
        self._size += int(grew.sum()) - int(popped.sum())
        nonempty, bound = self._nonempty, self._bound
        for row in rows[was_empty].tolist():  # (re)joins the non-empty queues last, as queue by queue
            nonempty.pop(bound[row], None)
            nonempty[bound[row]] = None
        self._mark_changed(rows)

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
        self._forget(entity, q, prop, cause, time, turn)
        return True

    def decay(self, ticks: TickRun) -> None:
        """Apply decay ticks (Algorithm 2) lazily: O(1) however many."""
        self.ticks.add(ticks)

    def decay_now(self, ticks: TickRun, entity_order: Sequence[str]) -> None:
        """Apply decay ticks (Algorithm 2) at once, in the canonical event order.

        Tick by tick, and within a tick in ``entity_order`` (the domain's entity
        order, docs/semantics.md section 2; entities it does not list come last), not in
        the order the queues happened to fill: that is the order of the events and of
        the change record.  Costs O(properties held) however many ticks: after as many
        ticks as the longest queue holds, WM is empty and the remaining ticks pop
        nothing.  Column queues decay as a column operation (their pops are only
        listed one by one when an event sink must hear them), so a tick over a large
        domain after rule 3 bursts moves no queue out of the columns.
        """
        self.flush()
        if ticks.count <= 0:
            return
        self.ticks.add(ticks)
        now = self.ticks.count
        rows = self._columns.non_empty() if self._in_columns else _NO_ROWS
        pending = [(entity, q) for entity, q in self._queues.items() if q]
        if self.sink is None and (entity_order is self._bound or not len(rows)):
            self._decay_quietly(ticks.count, entity_order, rows, pending)
        else:
            self._decay_in_order(ticks, entity_order, rows, pending)
        self.ticks.drop_before(now)
        self._settled = now

    def _decay_quietly(self, count: int, entity_order: Sequence[str], rows: np.ndarray,
                       pending: list[tuple[str, "_Queue"]]) -> None:
        """Pop ``count`` ticks' fronts with no events: columns at once, dict queues one by one.

        ``rows`` are numbered in ``entity_order`` (or there are none), so the change
        record follows entity order with one column mark per run of rows between two
        dict queues.
        """
        now = self.ticks.count
        if len(rows):
            popped = self._columns.pop_owed(rows, now)
            self._size -= int(popped.sum())
            for name in map(self._bound.__getitem__, rows[self._columns.length[rows] == 0].tolist()):
                self._nonempty.pop(name, None)
        rank = self._ranks(entity_order)
        last = len(rank)
        ordered = sorted(pending, key=lambda item: rank.get(item[0], last))
        # Where each dict queue falls among the column rows (in entity order).
        cuts = np.searchsorted(rows, [rank.get(e, last) for e, _ in ordered]).tolist() if len(rows) else []
        start = 0
        for i, (entity, q) in enumerate(ordered):
            if cuts and cuts[i] > start:
                self._mark_changed(rows[start:cuts[i]])
                start = cuts[i]
            owed = min(count, len(q))
            for _ in range(owed):
                del q[next(iter(q))]
            q.synced = now
            self._size -= owed
            self._record(entity, q)
            if not q:
                del self._nonempty[entity]
        self._mark_changed(rows[start:])

    def _decay_in_order(self, ticks: TickRun, entity_order: Sequence[str], rows: np.ndarray,
                        pending: list[tuple[str, "_Queue"]]) -> None:
        """Pop the ticks' fronts tick by tick, in ``entity_order``, reporting each (the general path).

        The fronts each queue loses are listed first (a column queue's by one sort of
        its slots); the column queues then lose theirs at once, and the events, the
        change record and the dict queues' pops follow tick by tick in entity order.
        """
        now = self.ticks.count
        rank = self._ranks(entity_order)
        last = len(rank)
        # (rank, tie, entity, fronts it loses LRU first, its dict queue or None for a column queue)
        plan: list[tuple[int, int, str, list[str], Optional[_Queue]]] = []
        for tie, (entity, q) in enumerate(pending):
            plan.append((rank.get(entity, last), tie, entity, list(islice(q, ticks.count)), q))
        if len(rows):
            columns, names, bound = self._columns, self._prop_name, self._bound
            fronts = columns.in_order(rows, min(ticks.count, columns.width))
            for row, ids in zip(rows.tolist(), fronts):
                name = bound[row]
                plan.append((rank.get(name, last), len(pending) + row, name, [names[i] for i in ids], None))
            self._size -= int(columns.pop_owed(rows, now).sum())
            for name in map(bound.__getitem__, rows[columns.length[rows] == 0].tolist()):
                self._nonempty.pop(name, None)
        plan.sort(key=lambda step: step[:2])
        for i in range(max((len(step[3]) for step in plan), default=0)):
            time = ticks.time(i)
            for _, _, entity, fronts, q in plan:
                if i >= len(fronts):
                    continue
                if q is None:  # popped already, with the other column queues
                    if i == 0:
                        self._changed.append(entity)
                else:
                    del q[fronts[i]]
                    self._size -= 1
                    self._record(entity, q)
                if self.sink is not None:
                    self.sink(WMEvent("forget", self.domain, entity, fronts[i], "decay", time, None))
        for entity, q in pending:
            q.synced = now
            if not q:
                del self._nonempty[entity]

    def clear(self, cause: str, time: float, turn: Optional[int] = None) -> None:
        """Forget everything (e.g. a reset)."""
        self._forget_all(cause, time, turn)

    def flush(self) -> None:
        """Bring every queue up to date with the decay ticks applied so far.

        Nothing to do when no tick arrived since the last flush (every queue is then up
        to date): a large domain is not walked for nothing.
        """
        if self.ticks.count == self._settled:
            return
        if self._in_columns:
            columns = self._columns
            owing = np.flatnonzero(columns.held & (columns.length > 0) & (columns.synced != self.ticks.count))
            if self.sink is None:
                self._settle_columns(owing)
            else:  # the pops must be reported: those queues become dict queues, caught up below
                for row in owing.tolist():
                    self._to_dict(self._bound[row])
        ticks = self.ticks.count
        for entity in list(self._nonempty):
            q = self._queues.get(entity)  # None: a column queue, caught up above
            if q is not None and q.synced != ticks:
                self._sync(entity, q)
        # Every non-empty queue is now up to date, and an empty one never needs a
        # tick's time, so older runs can go (bounded memory for long runs).
        self.ticks.drop_before(self.ticks.count)
        self._settled = self.ticks.count

    def _forget_all(self, cause: str, time: float, turn: Optional[int]) -> None:
        """Forget every property: queue by queue as :meth:`nonempty_entities` lists them, LRU first.

        Column queues are emptied at once; their properties are listed one by one only
        when an event sink must hear them.
        """
        order = self.nonempty_entities()  # flushes
        rows = self._columns.non_empty() if self._in_columns else _NO_ROWS
        fronts: dict[int, list[int]] = {}
        if len(rows) and self.sink is not None:
            fronts = dict(zip(rows.tolist(), self._columns.in_order(rows, self._columns.width)))
        for entity in order:
            q = self._queues.get(entity)
            if q is not None:
                while self._pop(entity, cause, time, turn) is not None:
                    pass
                continue
            self._changed.append(entity)  # a column queue
            for pid in fronts.get(self._row[entity], ()):
                self.sink(WMEvent("forget", self.domain, entity, self._prop_name[pid], cause, time, turn))
        if len(rows):
            columns = self._columns
            self._size -= int(columns.length[rows].sum())
            columns.pop_fronts(rows, columns.length[rows].copy())
            for name in map(self._bound.__getitem__, rows.tolist()):
                self._nonempty.pop(name, None)

    def _evict_columns(self, count: int, cause: str, time: float) -> None:
        """Forget the ``count`` oldest entries of the domain, oldest first (:meth:`evict_oldest`, with column queues).

        Each is the front of its queue when it goes.  The column queues' oldest are
        found by one partial sort of their stamps, the dict queues' by a heap.
        """
        columns = self._columns
        rows = columns.non_empty()
        stamps, owners, props = columns.entries(rows)
        if len(stamps) > count:
            oldest = np.argpartition(stamps, count - 1)[:count]
            stamps, owners, props = stamps[oldest], owners[oldest], props[oldest]
        victims: list[tuple] = [(stamp, row, pid, None) for stamp, row, pid in
                                zip(stamps.tolist(), owners.tolist(), props.tolist())]
        victims += heapq.nsmallest(count, ((value if value.__class__ is int else value[0], entity, prop, q)
                                           for entity, q in self._queues.items() for prop, value in q.items()),
                                   key=lambda victim: victim[0])
        victims.sort(key=lambda victim: victim[0])  # stamps are unique
        popped: dict[int, int] = {}  # column row -> fronts it loses
        for _, where, prop, q in victims[:count]:
            if q is not None:  # a dict queue's front
                self._forget(where, q, prop, cause, time, None)
                continue
            name = self._bound[where]
            if where not in popped:
                self._changed.append(name)
            popped[where] = popped.get(where, 0) + 1
            if self.sink is not None:
                self.sink(WMEvent("forget", self.domain, name, self._prop_name[prop], cause, time, None))
        if popped:
            touched = np.fromiter(popped, dtype=np.intp, count=len(popped))
            columns.pop_fronts(touched, np.fromiter(popped.values(), dtype=np.int64, count=len(popped)))
            self._size -= sum(popped.values())
            for name in map(self._bound.__getitem__, touched[columns.length[touched] == 0].tolist()):
                self._nonempty.pop(name, None)

    def _columns_fit(self, limits: Limits) -> bool:
        """Tell whether the column queues can stay under ``limits``: nothing kept, or an LRU capacity of their width.

        Under any other limits a queue may have to lose another property than its
        front, or more than one, which only a dict queue does.
        """
        columns = self._columns
        if columns is None or not limits.retains:
            return True
        return (limits.victim == "lru" and not limits.similarity and limits.global_capacity is None
                and limits.capacity == columns.width)

    def _ranks(self, entity_order: Sequence[str]) -> Mapping[str, int]:
        """Return entity -> rank in ``entity_order`` (the column rows' own numbering when that is their list)."""
        if entity_order is self._bound:
            for i in range(len(self._row), len(entity_order)):  # entities appended since the last bind
                self._row[entity_order[i]] = i
            return self._row
        return {entity: i for i, entity in enumerate(entity_order)}

    # ------------------------------------------------------- trimming primitives
    def _enforce(self, entity: str, q: _Queue, prop: str, time: float, turn: Optional[int]) -> None:
        """Enforce the limits after one encoding event of ``prop`` into Q[entity]."""
        limits = self.limits
        if limits.similarity:
            self._interfere(entity, q, prop, time, turn)
        if limits.capacity is not None and len(q) > limits.capacity:
            self._displace(entity, q, limits.capacity, prop, time, turn)
        if limits.global_capacity is not None and self._size > limits.global_capacity:
            self._evict_global(limits.global_capacity, time, turn)

    def _interfere(self, entity: str, q: _Queue, prop: str, time: float, turn: Optional[int]) -> None:
        """Similarity: forget Q[entity]'s other properties of ``prop``'s attribute, LRU first."""
        attribute = attribute_of(prop, self.attributes)
        if attribute is None:
            return
        for other in [p for p in q if p != prop and attribute_of(p, self.attributes) == attribute]:
            self._forget(entity, q, other, "similarity", time, turn)

    def _displace(self, entity: str, q: _Queue, capacity: int, newest: str, time: float, turn: Optional[int]) -> None:
        """Algorithm 3 (interference by displacement): keep |Q[entity]| <= capacity.

        ``newest`` (the property just encoded, or "" when trimming) is never the LFU
        or random victim; the LRU victim is the front (capacity >= 1, so never it).
        """
        while len(q) > capacity:
            self._forget(entity, q, self._victim(q, newest), "displacement", time, turn)

    @staticmethod
    def _lru_victim(q: _Queue, newest: str) -> str:
        return next(iter(q))

    @staticmethod
    def _lfu_victim(q: _Queue, newest: str) -> str:
        hits = q.hits or {}
        # min keeps the first of equals: ties go to the least recently encoded.
        return min((p for p in q if p != newest), key=lambda p: hits.get(p, 1))

    def _random_victim(self, q: _Queue, newest: str) -> str:
        candidates = [p for p in q if p != newest]
        return candidates[self._rng.randrange(len(candidates))]

    def _evict_global(self, limit: int, time: float, turn: Optional[int], cause: str = "global-capacity") -> None:
        """Keep the domain at ``limit`` properties or fewer, globally least recent out.

        While the domain holds more than ``limit`` properties, forget the front
        property with the oldest encoding stamp (possibly in the queue just encoded).

        Queues are sorted by stamp, so this is the oldest property in the whole domain.
        The domain never holds more than ``limit + 1`` properties here, so the scan over
        non-empty queues costs O(limit), independent of the number of entities.
        """
        while len(self) > limit:
            victim = min(self._nonempty, key=self.front_stamp)
            self._pop(victim, cause, time, turn)

    # -------------------------------------------------------------- internals
    def _new_queue(self, entity: str) -> _Queue:
        q = self._queues[entity] = _Queue()
        q.synced = self.ticks.count  # ticks before a queue existed are not owed
        q.hits = None
        q.marked = False
        return q

    def _catch_up(self, entity: str) -> None:
        """Apply the decay ticks Q[entity] still owes (if any); a column queue becomes a dict first."""
        q = self._queues.get(entity)
        if q is None and entity in self._in_columns:
            q = self._to_dict(entity)
        if q is not None and q.synced != self.ticks.count:
            self._sync(entity, q)

    # ------------------------------------------------------------ column queues
    def _bind(self, entities: Sequence[str], width: int) -> bool:
        """Bind column rows to ``entities`` (the first list given) and size the store; False for another list."""
        if self._bound is None:
            self._bound = entities
        elif entities is not self._bound:
            return False
        if self._columns is not None and self._columns.width != width:
            self._drop_columns()
        if len(self._row) < len(entities):  # new entities were appended
            for i in range(len(self._row), len(entities)):
                self._row[entities[i]] = i
        if self._columns is None:
            self._columns = QueueColumns(width, len(entities))
        self._columns.grow(len(entities))
        return True

    def _adopt(self, rows: np.ndarray) -> bool:
        """Move the queues of ``rows`` into the columns (those not there yet); False, moving none, if one is longer.

        Rows whose entity has no dict queue start empty, all at once; the few that have
        one take its entries.
        """
        columns = self._columns
        fresh = rows[~columns.held[rows]]
        if not len(fresh):
            return True
        names = list(map(self._bound.__getitem__, fresh.tolist()))
        queues = self._queues
        moving = sorted(queues.keys() & names, key=self._row.__getitem__)  # in entity order
        if any(len(queues[name]) > columns.width for name in moving):
            return False
        columns.start_empty(fresh, self.ticks.count)  # ticks before a queue existed are not owed
        for name in moving:
            q = queues.pop(name)
            columns.write(self._row[name], [self._column_item(prop, value) for prop, value in q.items()], q.synced)
        self._in_columns.update(names)
        return True

    def _column_item(self, prop: str, value: Union[int, tuple]) -> tuple[int, int, int]:
        """Return a dict queue's entry as a column item ``(property id, stamp, origin reference)``."""
        pid = self._prop_id.get(prop)
        if pid is None:
            pid = self._prop_id[prop] = len(self._prop_name)
            self._prop_name.append(prop)
        if value.__class__ is int:
            return pid, value, value
        stamp, ref = value
        if ref.__class__ is not int:  # an origin restored from a store
            index = self._explicit_id.get(ref)
            if index is None:
                index = self._explicit_id[ref] = len(self._explicit)
                self._explicit.append(ref)
            ref = -(index + 1)
        return pid, stamp, ref

    def _row_dict(self, row: int) -> dict:
        """Return a column row's queue as a dict queue's entries (property -> entry), LRU first."""
        names, explicit = self._prop_name, self._explicit
        return {
            names[pid]: stamp if ref == stamp else (stamp, ref if ref > 0 else explicit[-ref - 1])
            for pid, stamp, ref in self._columns.read(row)
        }

    def _readable(self, entity: str) -> Optional[Mapping]:
        """Return Q[entity] up to date with decay, for reading: its dict queue, or a copy of its column row."""
        q = self._queues.get(entity)
        if q is not None:
            if q.synced != self.ticks.count:
                self._sync(entity, q)
            return q
        if entity not in self._in_columns:
            return None
        row, columns = self._row[entity], self._columns
        if columns.synced[row] != self.ticks.count and columns.length[row]:
            if self.sink is not None:  # the pops must be reported: it becomes a dict queue
                self._catch_up(entity)
                return self._queues[entity]
            self._settle_columns(np.array([row]))
        return self._row_dict(row)

    def _to_dict(self, entity: str) -> _Queue:
        """Move Q[entity] from its column row to a dict queue (same content, owed ticks still owed)."""
        row, columns = self._row[entity], self._columns
        q = self._queues[entity] = _Queue(self._row_dict(row))
        q.synced = int(columns.synced[row])
        q.hits = None
        q.marked = False  # if it changed since the last take, a column mark says so
        columns.release(row)
        self._in_columns.discard(entity)
        return q

    def _drop_columns(self) -> None:
        """Move every column queue back to a dict queue (before any code path that only knows dicts)."""
        if self._columns is None:
            return
        self._compact_changes()
        for entity in [e for e in self._bound if e in self._in_columns]:
            self._to_dict(entity)
        self._columns = None
        self._in_columns = set()

    def _settle_columns(self, rows: np.ndarray) -> None:
        """Apply the decay ticks the column ``rows`` owe (no events: only called without a sink)."""
        if not len(rows):
            return
        columns = self._columns
        popped = columns.pop_owed(rows, self.ticks.count)
        self._size -= int(popped.sum())
        for row in rows[columns.length[rows] == 0].tolist():
            self._nonempty.pop(self._bound[row], None)
        self._mark_changed(rows[popped > 0])

    def _mark_changed(self, rows: np.ndarray) -> None:
        """Record the column ``rows`` as changed now (one mark in the change record stands for them)."""
        if not len(rows):
            return
        if self._marks >= _CHANGE_MARKS_MAX:  # bounded: fold the marks into names
            self._compact_changes()
        self._marks += 1
        mark = self._marks
        self._changed.append(mark)
        self._columns.mark_changed(rows, mark)

    def _sync(self, entity: str, q: _Queue) -> None:
        """Apply the ticks since ``q.synced``: one front pop per tick (Algorithm 2, deferred).

        Each pop is reported at its tick's own time.
        """
        synced = q.synced
        q.synced = ticks = self.ticks.count
        if not q:  # an empty queue owes nothing (and never needs a tick's time)
            return
        owed = min(ticks - synced, len(q))
        self._record(entity, q)
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
        for k, prop in enumerate(victims):  # each pop is reported at its tick's time
            sink(WMEvent("forget", self.domain, entity, prop, "decay", self.ticks.time(synced + k), None))

    def _pop(self, entity: str, cause: str, time: float, turn: Optional[int]) -> Optional[str]:
        q = self._queues.get(entity)
        if not q:
            return None
        prop = next(iter(q))
        self._forget(entity, q, prop, cause, time, turn)
        return prop

    def _forget(self, entity: str, q: _Queue, prop: str, cause: str, time: float, turn: Optional[int]) -> None:
        del q[prop]
        self._size -= 1
        self._record(entity, q)
        if not q:
            self._nonempty.pop(entity, None)
        if self.sink is not None:
            self.sink(WMEvent("forget", self.domain, entity, prop, cause, time, turn))

    # ---------------------------------------------------------------- origins
    def _log_origin(self, cause: str, turn: Optional[int]) -> None:
        """Note that the encodings from the next stamp on have origin ``(cause, turn)``."""
        starts, runs = self._origin_starts, self._origin_runs
        first = self._stamp + 1
        if runs and runs[-1] == (cause, turn):
            return  # the run goes on
        if starts and starts[-1] == first:  # the previous run pushed nothing
            runs[-1] = (cause, turn)
            return
        if len(starts) >= self._origin_prune_at:
            self._prune_origins()
        starts.append(first)
        runs.append((cause, turn))

    def _origin_at(self, stamp: int) -> Origin:
        """Return the origin of the encoding with this stamp (one still referenced by an entry)."""
        return self._origin_runs[bisect_right(self._origin_starts, stamp) - 1]

    def _origin_of(self, value: Union[int, tuple]) -> Origin:
        """Return the origin of a dict queue's entry (see :class:`_Queue`)."""
        if value.__class__ is int:
            return self._origin_at(value)
        ref = value[1]
        return self._origin_at(ref) if ref.__class__ is int else ref

    def _prune_origins(self) -> None:
        """Keep only the origin runs some entry still stored as a bare stamp falls in.

        O(entries stored); run when the log has doubled since the last pruning, so
        its cost per encoding call stays bounded and the log's size follows WM's.
        """
        live = [v if v.__class__ is int else v[1] for q in self._queues.values() for v in q.values()]
        live = [ref for ref in live if ref.__class__ is int]
        if self._in_columns:
            live += self._columns.origin_stamps().tolist()
        live.sort()
        starts, runs = self._origin_starts, self._origin_runs
        kept_starts: list[int] = []
        kept_runs: list[Origin] = []
        i = 0
        for stamp in live:
            while i + 1 < len(starts) and starts[i + 1] <= stamp:
                i += 1
            if not kept_starts or kept_starts[-1] != starts[i]:
                kept_starts.append(starts[i])
                kept_runs.append(runs[i])
        self._origin_starts, self._origin_runs = kept_starts, kept_runs
        self._origin_prune_at = max(_ORIGIN_LOG_MIN, 2 * len(kept_starts))

    # ------------------------------------------------------------ persistence
    def export_queue(self, entity: str) -> list[QueueItem]:
        """Return Q[entity] as :class:`QueueItem` items, LRU first (for a store).

        ``hits`` is the LFU count (1 when LFU is not in force); ``cause`` and ``turn``
        the entry's origin (:meth:`origins`).
        """
        q = self._readable(entity)
        if not q:
            return []
        hits = ((q.hits if q.__class__ is _Queue else None) or {}).get  # a column queue's copy has none (LRU)
        starts, runs = self._origin_starts, self._origin_runs
        items = []
        for prop, value in q.items():  # _origin_of and QueueItem(...) inlined: a store exports thousands
            if value.__class__ is int:
                stamp = ref = value
            else:
                stamp, ref = value
            origin = runs[bisect_right(starts, ref) - 1] if ref.__class__ is int else ref
            items.append(tuple.__new__(QueueItem, (prop, stamp, hits(prop, 1), origin[0], origin[1])))
        return items

    def counters(self) -> tuple[int, int]:
        """Return ``(stamp counter, decay ticks applied so far)``: the buffer's state beside its queues."""
        return self._stamp, self.ticks.count

    def restore(self, queues: Mapping[str, Sequence[Sequence]], stamp: int, ticks: int, limits: Limits) -> None:
        """Replace the buffer's state with a stored one (queues LRU first, no events, no changes).

        Items are :class:`QueueItem` (or tuples of its five fields); items of only
        ``(property, stamp, hits)``, from a store that kept no origins, get origin
        :data:`UNKNOWN_ORIGIN`.  The queues are taken as up to date with ``ticks`` decay
        ticks; ``limits`` are installed without trimming (the stored queues already
        respect them).  The change record is cleared: the state now equals the stored one.
        """
        if limits.victim not in VICTIMS:
            raise ValueError(f"unknown displacement victim {limits.victim!r} (known: {', '.join(VICTIMS)})")
        for entity, items in queues.items():  # all checked before anything changes
            if not isinstance(entity, str):
                raise ValueError(f"queue of {entity!r}: an entity is named by a string")
            for item in items:
                if len(item) not in (3, 5) or len(item) == 5 and not _is_origin(item[3], item[4]):
                    raise ValueError(f"queue of {entity!r}: item {item!r} is not (property, stamp, hits, cause, turn)")
        self.limits = limits
        self._rng = random.Random(limits.seed)
        self._victim = {"lru": self._lru_victim, "lfu": self._lfu_victim, "random": self._random_victim}[limits.victim]
        self._queues, self._nonempty, self._size, self._changed, self._marks = {}, {}, 0, [], 0
        self._columns, self._in_columns, self._explicit, self._explicit_id = None, set(), [], {}
        self.ticks = TickLedger()
        self.ticks.count = self._settled = ticks
        self._stamp = stamp
        self._origin_starts, self._origin_runs, self._origin_prune_at = [], [], _ORIGIN_LOG_MIN
        shared: dict[Origin, Origin] = {}  # one origin object per distinct (cause, turn)
        for entity, items in queues.items():
            q = self._new_queue(entity)
            for item in items:
                prop, prop_stamp, hits = item[0], item[1], item[2]
                origin = (item[3], item[4]) if len(item) == 5 else UNKNOWN_ORIGIN
                q[prop] = (prop_stamp, shared.setdefault(origin, origin))
                if limits.victim == "lfu":
                    q.hits = q.hits or {}
                    q.hits[prop] = hits
            if q:
                self._nonempty[entity] = None
                self._size += len(q)
