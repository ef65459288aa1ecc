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
* ``origin_log`` (:mod:`fsreg_ros.core.memory.origins`) and ``changes``
  (:mod:`fsreg_ros.core.memory.changes`): the records kept beside the queues.

The queues themselves (a dict queue each, or, for the rule 2 and 3 encodings of a
large domain, a row of the numpy column form: :mod:`fsreg_ros.core.memory.columns`,
encoded by :mod:`fsreg_ros.core.memory.column_encoding`), their size, non-empty set
and stamp counter are the buffer's :class:`~fsreg_ros.core.memory.queues.QueueStore`
(``store``); the buffer and every collaborator change them only through its methods.
A side log kept per entry hears every encoding and forgetting through ``watchers``
(:class:`EntryWatcher`; see :mod:`fsreg_ros.core.memory`).  The episode log
(:mod:`fsreg_ros.core.memory.episodes`) needs no watcher: it reads the entries' stamps
(:meth:`WMBuffer.entry_stamps`) when an episode begins or a strength is read.
"""

from __future__ import annotations

from typing import Callable, Iterable, Mapping, Optional, Protocol, Sequence

from . import bitset, column_encoding, entity_clock, persistence
from .changes import ChangeRecord
from .columns import COLUMN_MIN, ColumnQueues
from .decay import LazyDecay
from .displacement import Interference
from .host import ActivationRule, ChangeLog, DecayRule, EpisodeActivationRule, InterferenceRule, OriginRecord
from .install import install_limits
from .limits import UNLIMITED, Limits
from .origins import OriginLog
from .episodes import EntryStamps, EpisodeLog, Strength
from .queue import EventSink, Origin, Queue, QueueItem, WMEvent, entry_entered, entry_stamp
from .queues import QueueStore
from .ticks import TickLedger, TickRun


class EntryWatcher(Protocol):
    """A side log kept per entry (see :mod:`fsreg_ros.core.memory`): what the buffer tells it.

    While a watcher is attached the buffer takes its general paths (the quiet fast
    paths and the column form are off, as for an event sink), so every entry that
    enters, is refreshed or leaves is told here, in event order; and a watcher may be
    a forgetting rule of its own, evaluated lazily (:meth:`sync`, :meth:`flush`).
    """

    def encoded(self, entity: str, prop: str, cause: str, time: float, turn: Optional[int], present: bool) -> None:
        """Note an encoding of ``prop`` into Q[entity] (``present``: a refresh; the store gave it the last stamp)."""

    def forgot(self, entity: str, prop: str, cause: str, time: float) -> None:
        """Note that ``prop`` left Q[entity] (any cause)."""

    def sync(self, entity: str, q: Queue) -> None:
        """Bring the dict queue Q[entity] up to date before it is read or encoded into.

        Called after decay and activation caught it up; a rule evaluated lazily (as
        activation is) forgets what it no longer keeps here, with
        :meth:`WMBuffer.forget_entry`.  A log that forgets nothing does nothing.
        """

    def flush(self) -> None:
        """Bring every queue up to date (before the whole of WM is read: :meth:`WMBuffer.flush`)."""


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
        self.store = QueueStore()
        self.watchers: tuple[EntryWatcher, ...] = ()
        # The collaborators, typed by what the others may call on them (:mod:`.host`).
        self.lazy_decay: DecayRule = LazyDecay(self)
        self.activation: Optional[ActivationRule] = None  # a LazyActivation (:mod:`.activation`) while in force
        self.episode_activation: Optional[EpisodeActivationRule] = None  # the same on the episodes clock
        self.interference: InterferenceRule = Interference(self)
        self.origin_log: OriginRecord = OriginLog(self)
        self.episodes = EpisodeLog(self)  # reference episodes (:mod:`.episodes`)
        self.changes: ChangeLog = ChangeRecord(self)
        self.store.on_drop = self.changes.compact

    @property
    def columns(self) -> ColumnQueues:
        """The column form of the queues (which entities' queues live in rows; :mod:`.columns`)."""
        return self.store.columns

    def watch(self, watcher: EntryWatcher) -> None:
        """Attach a side log kept per entry (:class:`EntryWatcher`); column queues move back to dicts."""
        self.store.drop()
        self.watchers = (*self.watchers, watcher)

    @property
    def quiet(self) -> bool:
        """True when nobody must hear single encodings and forgettings (no event sink, no watcher)."""
        return self.sink is None and not self.watchers

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
        q = self.readable(entity)
        return tuple(q) if q else ()

    def origins(self, entity: str) -> list[Origin]:
        """Return the origin ``(cause, turn)`` of each entry of Q[entity], parallel to :meth:`queue`.

        An entry's origin is the encoding that made its property enter the queue
        (Algorithm 1's push of a property not in Q); a refresh while present keeps it.
        """
        q = self.readable(entity)
        return [self.origin_log.of(value) for value in q.values()] if q else []

    def queue_with_origins(self, entity: str) -> tuple[tuple[str, ...], list[Origin]]:
        """Return :meth:`queue` and :meth:`origins` of Q[entity] from one read (what a view opens with)."""
        q = self.readable(entity)
        if not q:
            return (), []
        return tuple(q), [self.origin_log.of(value) for value in q.values()]

    def episode(self, entity: str) -> int:
        """Return the entity's current episode: how many have begun (:meth:`begin_episode`; 0 before the first)."""
        return self.episodes.current(entity)

    def entry_stamps(self, entity: str, since: int = 0) -> list[EntryStamps]:
        """Return each entry of Q[entity] as (property, latest stamp, stamp it entered with or None), LRU first.

        ``since``: only the entries encoded after that stamp (their latest stamp is larger):
        the back of the queue, read from the back without building the rest.
        """
        q = self.readable(entity)
        if not q:
            return []
        if since <= 0:
            return [EntryStamps(p, entry_stamp(v), entry_entered(v)) for p, v in q.items()]
        out = []
        for p in reversed(q):  # stamps increase from front to back
            v = q[p]
            stamp = entry_stamp(v)
            if stamp <= since:
                break
            out.append(EntryStamps(p, stamp, entry_entered(v)))
        out.reverse()
        return out

    def strength(self, entity: str) -> list[Strength]:
        """Return how strongly each entry of Q[entity] is held, parallel to :meth:`queue` (:class:`Strength`).

        Its episode age and the number of episodes it was used in
        (:mod:`fsreg_ros.core.memory.episodes`), and its activation on the rule's clock under
        rule ``activation``.  Does not refresh recency.
        """
        return persistence.strengths(self, entity)

    def length(self, entity: str) -> int:
        """len(Q[entity]) after applying owed decay."""
        q = self.readable(entity)
        return len(q) if q else 0

    def __len__(self) -> int:
        """Total number of properties held by the domain's queues."""
        self.flush()
        return self.store.size

    def snapshot(self) -> dict[str, list[str]]:
        """Every non-empty queue, LRU first, keyed by entity (insertion order; :mod:`.persistence`)."""
        return persistence.snapshot(self)

    def front_stamp(self, entity: str) -> int:
        """Stamp of Q[entity]'s front (call only on a caught-up, non-empty queue)."""
        q = self.store.get(entity)
        if q is None:
            q = self.store.to_dict(entity)
        return entry_stamp(next(iter(q.values())))

    def nonempty_entities(self) -> list[str]:
        """Entities whose queues are non-empty, after applying owed decay."""
        self.flush()
        return self.store.nonempty()

    def readable(self, entity: str) -> Optional[Mapping]:
        """Return Q[entity] up to date with decay and the clock, for reading: its dict queue, or a copy of its row."""
        q = self.store.get(entity)
        if q is not None:
            if q.synced != self.lazy_decay.ticks.count:
                self.lazy_decay.sync(entity, q)
            if self.activation is not None:
                self.activation.sync(entity, q)
            if self.watchers:
                self._sync_watchers(entity, q)
            return q
        return column_encoding.readable_row(self, entity) if self.store.in_columns(entity) else None

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

        Call it before the act of referring encodes anything (docs/semantics.md section 2).
        Under rule ``episodes`` the entries of Q[entity] not used in the entity's last
        ``episode_window`` episodes are forgotten now (cause ``episodes``,
        :mod:`fsreg_ros.core.memory.episodes`); under rule ``activation`` on the episodes
        clock, those whose activation it takes to the threshold (:mod:`.entity_clock`).
        """
        return entity_clock.begin_episode(self, entity, time, turn)

    def encode(self, entity: str, properties: Iterable[str], cause: str, time: float,
               turn: Optional[int] = None) -> None:
        """Encode properties into Q[R]: Encode(R, P), the paper's Algorithm 1.

        For each p in P, in order: remove p from Q[R] if present and push it to the
        back.  Each push is one encoding event, after which the limits are enforced
        (:meth:`Interference.enforce`: similarity, Algorithm 3, the global limit).
        """
        if not self.retains:
            return
        if self.quiet and self.limits.lru_only:
            if not isinstance(properties, (list, tuple)):
                properties = list(properties)
            if self.store.in_columns(entity) and column_encoding.encode_in_row(
                    self, entity, properties, cause, time, turn):
                return  # (a column queue with room: encoded in its row, as the loop below would)
            if properties:
                self._encode_quiet((entity,), properties, cause, time, turn)
            return
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
        :meth:`QueueStore.encode_quiet`); events are only built when a sink listens, and every
        other case goes through :meth:`Interference.enforce`, Algorithm 3's one
        implementation.
        """
        limits = self.limits
        if not limits.retains:
            return
        if self.quiet and limits.lru_only:
            self._encode_quiet(entities, (prop,), cause, time, turn)
            return
        store = self.store
        self.origin_log.log(store.stamp + 1, cause, turn)
        act = self.activation
        if act is not None:
            act.advance(time)
        lfu = limits.victim == "lfu"
        ticks, decay_sync, record, enforce = self.lazy_decay.ticks.count, self.lazy_decay.sync, \
            self.changes.record, self.interference.enforce
        get, put, watchers = store.lookup, store.put, self.watchers
        for entity in entities:
            q = get(entity)
            if q is None and store.in_columns(entity):
                q = store.to_dict(entity)
            if q is None:
                q = store.new(entity, ticks)  # ticks before a queue existed are not owed
            else:
                if q.synced != ticks:  # lazy decay catch-up (Algorithm 2)
                    decay_sync(entity, q)
                if act is not None:
                    act.sync(entity, q)
                if watchers:
                    self._sync_watchers(entity, q)
            present = put(entity, q, prop)
            record(entity, q)
            if lfu:  # encodings since prop entered Q (or since the limits were set)
                if q.hits is None:
                    q.hits = {}
                q.hits[prop] = q.hits.get(prop, 1) + 1 if present else 1
            if act is not None:
                act.record(entity, prop, time, present)
            if watchers:
                for watcher in watchers:
                    watcher.encoded(entity, prop, cause, time, turn, present)
            if self.sink is not None:
                self.sink(WMEvent("encode", self.domain, entity, prop, cause, time, turn))
            enforce(entity, q, prop, time, turn)

    def _encode_quiet(self, entities: Iterable[str], props: Sequence[str], cause: str, time: float,
                      turn: Optional[int]) -> None:
        """Encode each of ``props`` (at least one), in order, for each entity: no listener, at most an LRU capacity.

        :meth:`QueueStore.encode_quiet` per property; the origin run (one cause and turn)
        and the activation clock (one time) are noted once for them all.  ``entities`` is
        iterated once per property (a single property for a generator).
        """
        store, act = self.store, self.activation
        self.origin_log.log(store.stamp + 1, cause, turn)
        if act is not None:
            act.advance(time)
        capacity, ticks, changes = self.limits.capacity, self.lazy_decay.ticks.count, self.changes
        for prop in props:  # (the change record's list is read each time: a column drop may replace it)
            store.encode_quiet(entities, prop, capacity, time, ticks, changes.entries, act)

    def encode_members(self, members: int, entities: Sequence[str], prop: str, cause: str, time: float,
                       turn: Optional[int] = None) -> None:
        """Encode(e, [prop]) (Algorithm 1) for each member e, in entity order: rules 2 and 3.

        ``members`` is a bitset over ``entities`` (:mod:`fsreg_ros.core.memory.bitset`; the
        domain's entity list, which may only grow by appending).  Exactly
        ``self.encode_each(bitset.names(members, entities), prop, ...)``: same queues,
        stamps, origins, sizes and change record.  With no event sink, limits of at
        most an LRU capacity (Algorithm 3) and rule ``activation`` (with a capacity or
        without) and a domain of at least ``column_min`` entities, it is one column operation over the
        members' queues (:mod:`fsreg_ros.core.memory.column_encoding`), with their owed decay
        (Algorithm 2) and activation crossings applied the same way, instead of Python
        work per entity.
        """
        if not self.limits.retains or not members:
            return
        if not column_encoding.encode_rows(self, members, entities, prop, cause, time, turn):
            # a small domain, events, other limits, a queue longer than the capacity (restored so), or
            # (activation without a capacity) longer than the columns' widest
            self.encode_each(bitset.names(members, entities), prop, cause, time, turn)

    def pop_front(self, entity: str, cause: str, time: float, turn: Optional[int] = None) -> Optional[str]:
        """Forget Q[entity]'s LRU property; returns it, or None if Q is empty."""
        self._catch_up(entity, time)
        return self.pop_entry(entity, cause, time, turn)

    def remove(self, entity: str, prop: str, cause: str, time: float, turn: Optional[int] = None) -> bool:
        """Forget one property wherever it is in Q[entity] (retraction, rule ``episodes``)."""
        self._catch_up(entity, time)
        q = self.store.get(entity)
        if not q or prop not in q:
            return False
        self.forget_entry(entity, q, prop, cause, time, turn)
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
        for watcher in self.watchers:
            watcher.flush()

    def clear(self, cause: str, time: float, turn: Optional[int] = None) -> None:
        """Forget everything (e.g. a reset)."""
        self.advance(time)
        self.forget_everything(cause, time, turn)

    # ------------------------------------------------- forgetting primitives
    def forget_everything(self, cause: str, time: float, turn: Optional[int]) -> None:
        """Forget every property: queue by queue as :meth:`nonempty_entities` lists them, LRU first.

        Column queues are emptied at once; their properties are listed one by one only
        when an event sink must hear them.
        """
        column_encoding.forget_all(self, cause, time, turn)

    def pop_entry(self, entity: str, cause: str, time: float, turn: Optional[int]) -> Optional[str]:
        """Forget the front of Q[entity] (a dict queue, caught up); return it, or None if it is empty."""
        q = self.store.get(entity)
        if not q:
            return None
        prop = next(iter(q))
        self.forget_entry(entity, q, prop, cause, time, turn)
        return prop

    def forget_entry(self, entity: str, q: Queue, prop: str, cause: str, time: float, turn: Optional[int]) -> None:
        """Forget ``prop`` of the dict queue Q[entity]: the store, the rules, the record and the sink hear it."""
        self.store.remove(entity, q, prop)
        if self.activation is not None:
            self.activation.forget(entity, prop)
        if self.watchers:
            for watcher in self.watchers:
                watcher.forgot(entity, prop, cause, time)
        self.changes.record(entity, q)
        if self.sink is not None:
            self.sink(WMEvent("forget", self.domain, entity, prop, cause, time, turn))

    def _catch_up(self, entity: str, time: float) -> None:
        """Bring Q[entity] up to date with the ticks given and the clock (at least ``time``)."""
        self.lazy_decay.catch_up(entity)
        if self.activation is not None:
            self.activation.advance(time)
            q = self.store.get(entity)
            if q:
                self.activation.sync(entity, q)
        if self.watchers:
            q = self.store.get(entity)
            if q:
                self._sync_watchers(entity, q)

    def _sync_watchers(self, entity: str, q: Queue) -> None:
        """Let each watcher bring Q[entity] up to date (a lazy rule forgets here), the queue caught up with decay."""
        for watcher in self.watchers:
            if q:
                watcher.sync(entity, q)

    # ------------------------------------------------------------ persistence
    def export_queue(self, entity: str) -> list[QueueItem]:
        """Return Q[entity] as :class:`QueueItem` items, LRU first (for a store; :mod:`.persistence`)."""
        return persistence.export_queue(self, entity)

    def counters(self) -> tuple[int, int]:
        """Return ``(stamp counter, decay ticks applied so far)``: the buffer's state beside its queues."""
        return self.store.stamp, self.lazy_decay.ticks.count

    def restore(self, queues: Mapping[str, Sequence[Sequence]], stamp: int, ticks: int, limits: Limits) -> None:
        """Replace the buffer's state with a stored one (no events, no changes; :mod:`.persistence`).

        The episode log is emptied (:meth:`restore_episodes` takes a stored one back).
        """
        persistence.restore(self, queues, stamp, ticks, limits)
        self.episodes.clear()

    def export_episodes(self) -> dict:
        """Return the entities' own clocks as a store keeps them: episodes and words clocks (:mod:`.entity_clock`)."""
        return entity_clock.export_clocks(self)

    def restore_episodes(self, data: Mapping, keep: Optional[Callable[[str], bool]] = None) -> list[str]:
        """Take back :meth:`export_episodes`'s dict (after :meth:`restore`); ValueError (nothing changed) if malformed.

        ``keep``: a predicate on entity names; the others' clocks are dropped and returned.
        """
        return entity_clock.restore_clocks(self, data, keep)
