"""The WM buffer: one domain's per-entity queues and the paper's Encode (Algorithm 1).

:class:`WMBuffer` is the mechanism of working memory: ``Q[entity]`` queues (LRU at
the front, MRU at the back; :mod:`fsreg_ros.core.memory.queue`), Encode, reads, and
the forgetting primitives every rule uses (pop a front, remove a property, forget
everything), with its collaborators:

* ``lazy_decay`` (:mod:`fsreg_ros.core.memory.decay`): Algorithm 2's pops, lazy;
* ``activation`` (:mod:`fsreg_ros.core.memory.activation`, while rule ``activation``
  is in force): ACT-R base-level activation, its clock and lazy pops;
* ``interference`` (:mod:`fsreg_ros.core.memory.displacement`): Algorithm 3,
  similarity and the global and shared limits, enforced after every encoding event
  (new limits are installed by :mod:`fsreg_ros.core.memory.install`);
* ``origin_log`` (:mod:`fsreg_ros.core.memory.origins`), ``changes``
  (:mod:`fsreg_ros.core.memory.changes`) and ``columns``
  (:mod:`fsreg_ros.core.memory.columns`): the records kept beside the queues and the
  numpy form of the queues of a large domain.

The collaborators share the buffer's queue state (``_queues``, ``_nonempty``,
``_size``, ``_stamp``: package-private, read and written only inside this package).
"""

from __future__ import annotations

import sys
from typing import Callable, Iterable, Mapping, Optional, Sequence

from . import bitset
from .ticks import TickLedger, TickRun
from .activation import LazyActivation
from .changes import ChangeRecord
from .columns import COLUMN_MIN, ColumnQueues
from .decay import NO_ROWS, LazyDecay, pop_quietly
from .displacement import Interference
from .install import install_limits
from .limits import UNLIMITED, Limits
from . import persistence
from .origins import OriginLog
from .episodes import EntryStamps, EpisodeLog, Strength
from .activation import activation as activation_at, Trace
from .queue import EventSink, Origin, Queue, QueueItem, WMEvent, entry_entered, entry_stamp


class WMBuffer:
    """A domain's WM buffer: ``Q[entity]`` queues plus the encoding stamp counter.

    Every single push gets the next value of one counter (its *stamp*), so within a
    queue stamps increase from front to back and across the domain there are no
    ties; the global limit uses this to find the least recently encoded front.

    ``limits`` are installed by the WM Manager (:meth:`set_limits`); a buffer never
    configured keeps everything (:data:`UNLIMITED`).  ``attributes`` maps property
    -> attribute for similarity interference.  ``column_min``: domains of at least
    this many entities keep rule 2 and 3 encodings' queues as columns.
    """

    def __init__(
        self, domain: str, sink: Optional[EventSink] = None, attributes: Optional[Mapping[str, str]] = None
    ) -> None:
        self.domain = domain
        self.sink = sink
        self.attributes: dict[str, str] = dict(attributes or {})
        self.limits = UNLIMITED
        self.column_min = COLUMN_MIN
        self._queues: dict[str, Queue] = {}  # the dict queues (a column queue is not here)
        self._nonempty: dict[str, None] = {}  # queues that may hold something (insertion-ordered set)
        self._stamp = 0
        self._size = 0  # properties stored, including ones still owed to lazy decay
        self.lazy_decay = LazyDecay(self)
        self.activation: Optional[LazyActivation] = None
        self.interference = Interference(self)
        self.origin_log = OriginLog(self)
        self.episodes = EpisodeLog(self)
        self.changes = ChangeRecord(self)
        self.columns = ColumnQueues(self)

    # ------------------------------------------------------------------ reads
    @property
    def retains(self) -> bool:
        """False under policy ``none``: nothing is ever retained."""
        return self.limits.retains

    @property
    def ticks(self) -> TickLedger:
        """Every decay tick given so far (:mod:`fsreg_ros.core.memory.ticks`)."""
        return self.lazy_decay.ticks

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
        return [self.origin_log.of(value) for value in q.values()] if q else []

    def queue_with_origins(self, entity: str) -> tuple[tuple[str, ...], list[Origin]]:
        """Return :meth:`queue` and :meth:`origins` of Q[entity] from one read (what a view opens with)."""
        q = self._readable(entity)
        if not q:
            return (), []
        return tuple(q), [self.origin_log.of(value) for value in q.values()]

    def episode(self, entity: str) -> int:
        """Return the entity's current episode: how many have begun (:meth:`begin_episode`; 0 before the first)."""
        return self.episodes.current(entity)

    def entry_stamps(self, entity: str) -> list[EntryStamps]:
        """Return each entry of Q[entity] as (property, latest stamp, stamp it entered with or None), LRU first."""
        q = self._readable(entity)
        return [EntryStamps(p, entry_stamp(v), entry_entered(v)) for p, v in q.items()] if q else []

    def strength(self, entity: str) -> list[Strength]:
        """Return how strongly each entry of Q[entity] is held, parallel to :meth:`queue` (:class:`Strength`).

        Its episode age and the number of episodes it was used in
        (:mod:`fsreg_ros.core.memory.episodes`), and its activation at the clock under rule
        ``activation``.  Does not refresh recency.
        """
        counted = self.episodes.strength(entity, self.entry_stamps(entity))
        if self.activation is None or not counted:
            return [Strength(age, n) for age, n in counted]
        d, clock = self.limits.activation[0], self.activation.clock  # type: ignore[index]
        traces = [Trace.from_json(item.trace) for item in self.export_queue(entity)]  # type: ignore[attr-defined]
        return [Strength(age, n, activation_at(t, clock, d)) for (age, n), t in zip(counted, traces)]

    def length(self, entity: str) -> int:
        """len(Q[entity]) after applying owed decay."""
        q = self._readable(entity)
        return len(q) if q else 0

    def __len__(self) -> int:
        """Total number of properties held by the domain's queues."""
        self.flush()
        return self._size

    def snapshot(self) -> dict[str, list[str]]:
        """Every non-empty queue, LRU first, keyed by entity (insertion order; :mod:`.persistence`)."""
        return persistence.snapshot(self)

    def front_stamp(self, entity: str) -> int:
        """Stamp of Q[entity]'s front (call only on a caught-up, non-empty queue)."""
        if entity in self.columns.entities:
            self.columns.to_dict(entity)
        return entry_stamp(next(iter(self._queues[entity].values())))

    def nonempty_entities(self) -> list[str]:
        """Entities whose queues are non-empty, after applying owed decay."""
        self.flush()
        return list(self._nonempty)

    def _readable(self, entity: str) -> Optional[Mapping]:
        """Return Q[entity] up to date with decay, for reading: its dict queue, or a copy of its column row."""
        q = self._queues.get(entity)
        if q is not None:
            if q.synced != self.lazy_decay.ticks.count:
                self.lazy_decay.sync(entity, q)
            if self.activation is not None:
                self.activation.sync(entity, q)
            return q
        return self.columns.readable(entity) if entity in self.columns.entities else None

    # --------------------------------------------------------------- changes
    def take_changes(self) -> list[str]:
        """Return the entities whose queue changed since the last call, in first-change order; reset the record.

        After this call, :meth:`export_queue` of each entity returned, with
        :meth:`counters`, is all a store needs (an entity returned with an empty queue:
        delete it); :mod:`fsreg_ros.core.memory.changes` says what counts as a change.
        Decay ticks given lazily are applied first (a :meth:`flush`).
        """
        self.flush()
        return self.changes.take()

    # ---------------------------------------------------------------- limits
    def set_limits(self, limits: Limits, time: float) -> None:
        """Install new limits and apply them to every queue at once (:mod:`.install`; docs/semantics.md section 7)."""
        install_limits(self, limits, time)

    def evict_oldest(self, count: int, cause: str, time: float) -> None:
        """Forget the ``count`` least recently encoded fronts of the domain (a shared pool's trim)."""
        self.advance(time)
        self.interference.evict_oldest(count, cause, time)

    def advance(self, time: float) -> None:
        """Note that the clock reached ``time``: entries whose activation fell below the threshold go (lazily).

        Only the activation rule reads the clock (every encoding's and forgetting's own
        time also moves it); otherwise this does nothing.
        """
        if self.activation is not None:
            self.activation.advance(time)

    # ---------------------------------------------------------------- writes
    def begin_episode(self, entity: str, time: float = 0.0, turn: Optional[int] = None) -> int:
        """Begin the entity's next reference episode and return its number (1, 2, ...).

        Call it before the act of referring encodes anything (docs/semantics.md section 8).
        Under rule ``episodes`` the entries of Q[entity] not used in the entity's last
        ``episode_window`` episodes are forgotten now (cause ``episodes``,
        :mod:`fsreg_ros.core.memory.episodes`).
        """
        window = self.limits.episode_window if self.limits.retains else None
        return self.episodes.begin(entity, window, time, turn)

    def encode(self, entity: str, properties: Iterable[str], cause: str, time: float,
               turn: Optional[int] = None) -> None:
        """Encode properties into Q[R]: Encode(R, P), the paper's Algorithm 1.

        For each p in P, in order: remove p from Q[R] if present and push it to the
        back.  Each push is one encoding event, after which the limits are enforced
        (:meth:`Interference.enforce`: similarity, Algorithm 3, the global limit).
        """
        if not self.retains:
            return
        if self.sink is None and self.limits.lru_only and entity in self.columns.entities:
            if not isinstance(properties, (list, tuple)):
                properties = list(properties)
            if self.columns.encode_entity(entity, properties, cause, time, turn):
                return  # (a column queue with room: encoded in its row, as the loop below would)
        for prop in properties:
            self.encode_each((entity,), prop, cause, time, turn)

    def encode_each(self, entities: Iterable[str], prop: str, cause: str, time: float,
                    turn: Optional[int] = None) -> None:
        """Encode(e, [prop]) (Algorithm 1) for each entity e, in the given order.

        Exactly equivalent to ``for e in entities: self.encode(e, (prop,), ...)``,
        with the same events in the same order: this is the hot path of rules 2 and
        3, where one affirmed property is encoded for thousands of candidates or
        distractors.  With no event sink and no limit beyond an LRU capacity, each
        entity costs one dict assignment (plus the displaced front, if any:
        :meth:`_encode_quiet`); events are only built when a sink listens, and every
        other case goes through :meth:`Interference.enforce`, Algorithm 3's one
        implementation.
        """
        limits = self.limits
        if not limits.retains:
            return
        self.origin_log.log(self._stamp + 1, cause, turn)
        if self.sink is None and limits.lru_only:
            self._encode_quiet(entities, prop, limits.capacity, time)
            return
        lfu = limits.victim == "lfu"
        act = self.activation
        if act is not None:
            act.advance(time)
        columns, catch_up, record, enforce = self.columns, self.lazy_decay.catch_up, self.changes.record, \
            self.interference.enforce
        for entity in entities:
            q = self._queues.get(entity)
            if q is None and entity in columns.entities:
                q = columns.to_dict(entity)
            if q is None:
                q = self._new_queue(entity)
            else:
                catch_up(entity)
                if act is not None:
                    act.sync(entity, q)
            old = q.pop(prop, None)
            present = old is not None
            self._stamp += 1
            if present:  # a refresh keeps the entry's origin
                q[prop] = (self._stamp, old if old.__class__ is int else old[1])
            else:
                q[prop] = self._stamp
                self._size += 1
            self._nonempty[entity] = None
            record(entity, q)
            if lfu:  # encodings since prop entered Q (or since the limits were set)
                if q.hits is None:
                    q.hits = {}
                q.hits[prop] = q.hits.get(prop, 1) + 1 if present else 1
            if act is not None:
                act.record(entity, prop, time, present)
            if self.sink is not None:
                self.sink(WMEvent("encode", self.domain, entity, prop, cause, time, turn))
            enforce(entity, q, prop, time, turn)

    def _encode_quiet(self, entities: Iterable[str], prop: str, capacity: Optional[int], time: float) -> None:
        """Run :meth:`encode_each` with no events and at most an LRU capacity and rule ``activation``.

        Per entity: the decay ticks it owes (:func:`~fsreg_ros.core.memory.decay.pop_quietly`,
        only when it owes some), one dict assignment and, when the queue is full, one
        front deletion; the entity joins the change record.  No event objects, no
        calls per entity otherwise, no object per entry (see :class:`Queue`).  Under
        rule ``activation``, what crossed goes first (:meth:`LazyActivation.sync`) and
        the rule notes the encoding and the displaced front.
        """
        queues = self._queues
        nonempty = self._nonempty
        changed = self.changes.entries
        in_columns = self.columns.entities
        ticks = self.lazy_decay.ticks.count  # nothing below gives new ticks
        limit = capacity if capacity is not None else sys.maxsize
        act = self.activation
        if act is not None:
            act.advance(time)
        stamp = self._stamp
        size = self._size
        for entity in entities:
            q = queues.get(entity)
            if q is None:
                if entity not in in_columns:
                    q = queues[entity] = Queue()
                    q.synced = ticks
                    q.hits = None
                    q.marked = True
                    changed.append(entity)
                    nonempty[entity] = None
                    stamp += 1
                    q[prop] = stamp
                    size += 1
                    if act is not None:
                        act.record(entity, prop, time, False)
                    continue
                q = self.columns.to_dict(entity)
            if not q.marked:
                q.marked = True
                changed.append(entity)
            if q.synced != ticks:  # lazy decay catch-up (Algorithm 2)
                if q:
                    size -= pop_quietly(q, ticks)
                    if not q:
                        del nonempty[entity]
                q.synced = ticks
            if act is not None and q:  # what crossed goes (its size and non-empty queues kept by _forget)
                self._size = size
                act.sync(entity, q)
                size = self._size
            # Caught up, so: entity in _nonempty  <=>  Q[entity] is non-empty.
            if prop in q:  # a refresh: same size, the entry keeps its origin
                old = q.pop(prop)
                stamp += 1
                q[prop] = (stamp, old if old.__class__ is int else old[1])
                if act is not None:
                    act.record(entity, prop, time, True)
                continue
            if not q:
                nonempty[entity] = None
            stamp += 1
            q[prop] = stamp
            if len(q) > limit:  # Algorithm 3, LRU out (capacity >= 1: never prop itself)
                front = next(iter(q))
                del q[front]
                if act is not None:
                    act.forget(entity, front)
            else:
                size += 1
            if act is not None:
                act.record(entity, prop, time, False)
        self._stamp, self._size = stamp, size

    def encode_members(self, members: int, entities: Sequence[str], prop: str, cause: str, time: float,
                       turn: Optional[int] = None) -> None:
        """Encode(e, [prop]) (Algorithm 1) for each member e, in entity order: rules 2 and 3.

        ``members`` is a bitset over ``entities`` (:mod:`fsreg_ros.core.memory.bitset`; the
        domain's entity list, which may only grow by appending).  Exactly
        ``self.encode_each(bitset.names(members, entities), prop, ...)``: same queues,
        stamps, origins, sizes and change record.  With no event sink, limits of at
        most an LRU capacity (Algorithm 3) and rule ``activation`` (with a capacity or
        without) and a domain of at least ``column_min`` entities, it is one column operation over the
        members' queues (:mod:`fsreg_ros.core.memory.columns`), with their owed decay
        (Algorithm 2) and activation crossings applied the same way, instead of Python
        work per entity.
        """
        if not self.limits.retains or not members:
            return
        columns = self.columns
        rows = bitset.index_array(members) if columns.usable(entities, self.limits) else None
        if rows is None or not columns.adopt(rows) or not columns.room(rows):
            # a small domain, events, other limits, a queue longer than the capacity (restored so), or
            # (activation without a capacity) longer than the columns' widest
            self.encode_each(bitset.names(members, entities), prop, cause, time, turn)
            return
        columns.encode_rows(rows, members, prop, cause, time, turn)

    def pop_front(self, entity: str, cause: str, time: float, turn: Optional[int] = None) -> Optional[str]:
        """Forget Q[entity]'s LRU property; returns it, or None if Q is empty."""
        self._catch_up(entity, time)
        return self._pop(entity, cause, time, turn)

    def remove(self, entity: str, prop: str, cause: str, time: float, turn: Optional[int] = None) -> bool:
        """Forget one property wherever it is in Q[entity] (retraction, rule ``episodes``)."""
        if entity in self.columns.entities:
            self.columns.to_dict(entity)
        self._catch_up(entity, time)
        q = self._queues.get(entity)
        if not q or prop not in q:
            return False
        self._forget(entity, q, prop, cause, time, turn)
        return True

    def decay(self, ticks: TickRun) -> None:
        """Apply decay ticks (Algorithm 2) lazily: O(1) however many (:mod:`fsreg_ros.core.memory.decay`)."""
        self.lazy_decay.add(ticks)

    def decay_now(self, ticks: TickRun, entity_order: Sequence[str]) -> None:
        """Apply decay ticks (Algorithm 2) at once: tick by tick, within a tick in ``entity_order``.

        The canonical event order (docs/semantics.md section 2; :meth:`LazyDecay.now`).
        """
        self.lazy_decay.now(ticks, entity_order)

    def flush(self) -> None:
        """Bring every queue up to date with the decay ticks given so far and the clock (activation)."""
        if self.lazy_decay.ticks.count != self.lazy_decay.settled:
            self.lazy_decay.flush()
        if self.activation is not None:
            self.activation.flush()

    def clear(self, cause: str, time: float, turn: Optional[int] = None) -> None:
        """Forget everything (e.g. a reset)."""
        self.advance(time)
        self._forget_all(cause, time, turn)

    def _forget_all(self, cause: str, time: float, turn: Optional[int]) -> None:
        """Forget every property: queue by queue as :meth:`nonempty_entities` lists them, LRU first.

        Column queues are emptied at once; their properties are listed one by one only
        when an event sink must hear them.
        """
        order = self.nonempty_entities()  # flushes
        columns = self.columns
        rows = columns.store.non_empty() if columns.entities else NO_ROWS
        fronts: dict[int, list[int]] = {}
        if len(rows) and self.sink is not None:
            fronts = dict(zip(rows.tolist(), columns.store.in_order(rows, columns.store.width)))
        for entity in order:
            q = self._queues.get(entity)
            if q is not None:
                while self._pop(entity, cause, time, turn) is not None:
                    pass
                continue
            self.changes.note(entity)  # a column queue
            for pid in fronts.get(columns.row[entity], ()):
                self.sink(WMEvent("forget", self.domain, entity, columns.prop_name[pid], cause, time, turn))
        if len(rows):
            store = columns.store
            self._size -= int(store.length[rows].sum())
            store.pop_fronts(rows, store.length[rows].copy())
            columns.emptied(rows)

    # -------------------------------------------------------------- internals
    def _catch_up(self, entity: str, time: float) -> None:
        """Bring Q[entity] up to date with the ticks given and the clock (at least ``time``)."""
        self.lazy_decay.catch_up(entity)
        if self.activation is not None:
            self.activation.advance(time)
            q = self._queues.get(entity)
            if q:
                self.activation.sync(entity, q)

    def _new_queue(self, entity: str) -> Queue:
        q = self._queues[entity] = Queue()
        q.synced = self.lazy_decay.ticks.count  # ticks before a queue existed are not owed
        q.hits = None
        q.marked = False
        return q

    def _pop(self, entity: str, cause: str, time: float, turn: Optional[int]) -> Optional[str]:
        q = self._queues.get(entity)
        if not q:
            return None
        prop = next(iter(q))
        self._forget(entity, q, prop, cause, time, turn)
        return prop

    def _forget(self, entity: str, q: Queue, prop: str, cause: str, time: float, turn: Optional[int]) -> None:
        del q[prop]
        self._size -= 1
        if self.activation is not None:
            self.activation.forget(entity, prop)
        self.changes.record(entity, q)
        if not q:
            self._nonempty.pop(entity, None)
        if self.sink is not None:
            self.sink(WMEvent("forget", self.domain, entity, prop, cause, time, turn))

    # ------------------------------------------------------------ persistence
    def export_queue(self, entity: str) -> list[QueueItem]:
        """Return Q[entity] as :class:`QueueItem` items, LRU first (for a store; :mod:`.persistence`)."""
        return persistence.export_queue(self, entity)

    def counters(self) -> tuple[int, int]:
        """Return ``(stamp counter, decay ticks applied so far)``: the buffer's state beside its queues."""
        return self._stamp, self.lazy_decay.ticks.count

    def restore(self, queues: Mapping[str, Sequence[Sequence]], stamp: int, ticks: int, limits: Limits) -> None:
        """Replace the buffer's state with a stored one (no events, no changes; :mod:`.persistence`).

        The episode log is emptied (:meth:`restore_episodes` takes a stored one back).
        """
        persistence.restore(self, queues, stamp, ticks, limits)
        self.episodes.clear()

    def export_episodes(self) -> dict:
        """Return the episode log as a store keeps it (:meth:`EpisodeLog.export <.episodes.EpisodeLog.export>`)."""
        return self.episodes.export()

    def restore_episodes(self, data: Mapping, keep: Optional[Callable[[str], bool]] = None) -> list[str]:
        """Take back :meth:`export_episodes`'s dict (after :meth:`restore`); ValueError if malformed.

        ``keep``: a predicate on entity names; the others' episodes are dropped and returned.
        """
        return self.episodes.restore(data, keep)
