"""The queue store: one buffer's queues, in either form, and the counts kept beside them.

:class:`QueueStore` owns working memory's state: ``Q[entity]`` for every entity of a
domain, each either a dict :class:`~fsreg_ros.core.memory.queue.Queue` or a row of the
numpy column form (:class:`~fsreg_ros.core.memory.columns.ColumnQueues`, for the rule 2
and 3 encodings of a large domain), and keeps, on every path, its invariants:

* ``size``: the properties held, including pops still owed to lazy decay;
* the *non-empty set*: the entities whose queue may hold something (a queue owing
  decay pops may be empty once caught up), insertion-ordered by when each last became
  non-empty (the order :meth:`WMBuffer.snapshot` and eager ticks read);
* the *stamp counter*: every push gets the next stamp, so stamps grow front to back
  within a queue and never tie across the domain;
* each queue's ``synced`` tick count (the decay ticks it has been brought up to) and
  where each queue lives (a queue is in exactly one form at a time).

The rules (decay, displacement, activation) and the records kept beside the queues
(the origin log, the change record, persistence) change queues only through its
methods: put (push or refresh), remove, drop fronts (decay's pops), the column
operations (encode rows, pop rows' fronts, clear slots) and the moves between the two
forms.  What a rule *decides* (which entry goes, when) stays in the rule's module; what
the store does is keep its counts true.  The quiet fast path of rules 2 and 3 in dict
form (:meth:`QueueStore.encode_quiet`) lives here, over the same state.

Traces kept beside entries (rule ``activation``'s, or any side log's) move with their
queue between the forms through :attr:`QueueStore.keeper` (:class:`TraceKeeper`), and
whoever refers to column rows by mark (the change record) folds its marks before the
column form is given up (:attr:`QueueStore.on_drop`).
"""

from __future__ import annotations

import sys
from itertools import islice
from typing import Callable, ItemsView, Iterable, KeysView, Mapping, Optional, Protocol, Sequence

import numpy as np

from .columns import ColumnQueues
from .limits import Limits
from .queue import Queue
from .trace import Trace

#: No column rows.
NO_ROWS = np.zeros(0, dtype=np.intp)


class TraceKeeper(Protocol):
    """What keeps per-entry data beside dict queues and hands it over when a queue changes form."""

    def release(self, entity: str) -> dict[str, Trace]:
        """Hand over the data of Q[entity] (moving to the column form)."""

    def take(self, entity: str, traces: dict[str, Trace]) -> None:
        """Keep ``traces``, those of Q[entity] (back from the column form)."""

    def release_clocks(self, entities: list[str]) -> Optional[tuple[list[int], list[Optional[float]]]]:
        """Hand over the entities' own clocks and when each moved (queues moving to the column form); None: one."""

    def take_clock(self, entity: str, clock: int, moved: Optional[float]) -> None:
        """Keep the entity's own clock and when it moved (its queue back from the column form)."""


class EncodeWatcher(Protocol):
    """What the quiet fast path (:meth:`QueueStore.encode_quiet`) tells of each encoding and displacement."""

    def sync(self, entity: str, q: Queue) -> None:
        """Bring Q[entity] up to the clock first (a lazy rule's own pops)."""

    def record(self, entity: str, prop: str, time: float, present: bool) -> None:
        """Note an encoding of ``prop`` into Q[entity] (``present``: a refresh)."""

    def forget(self, entity: str, prop: str) -> None:
        """Note that ``prop`` left Q[entity]."""


def pop_quietly(q: Queue, ticks: int) -> int:
    """Bring ``q`` up to ``ticks`` ticks, dropping one front per owed tick, no events; return how many went."""
    owed = min(ticks - q.synced, len(q))
    q.synced = ticks
    if owed == len(q):
        q.clear()
    else:
        for _ in range(owed):
            del q[next(iter(q))]
    return owed


class QueueStore:
    """One buffer's queues and their invariants (see the module docstring).

    ``columns`` is the column form (its binding and arrays, read by the rules that work
    on rows); ``keeper`` the rule keeping traces beside dict queues (or None);
    ``on_drop`` is called before the column form is given up.
    """

    def __init__(self) -> None:
        self._dicts: dict[str, Queue] = {}  # the dict queues (a column queue is not here)
        self._nonempty: dict[str, None] = {}  # queues that may hold something (insertion-ordered set)
        self._size = 0  # properties stored, including ones still owed to lazy decay
        self._stamp = 0
        self.columns = ColumnQueues()
        self.keeper: Optional[TraceKeeper] = None
        self.on_drop: Callable[[], None] = _nothing

    # ------------------------------------------------------------------ reads
    @property
    def size(self) -> int:
        """Properties stored (owed decay pops included)."""
        return self._size

    @property
    def stamp(self) -> int:
        """The last stamp given (the next push gets this plus one)."""
        return self._stamp

    def nonempty(self) -> list[str]:
        """Return the entities whose queue may hold something, in the order they became non-empty."""
        return list(self._nonempty)

    def holding(self) -> KeysView[str]:
        """Return the non-empty set itself (a live view: iterate it without changing the store)."""
        return self._nonempty.keys()

    def get(self, entity: str) -> Optional[Queue]:
        """Return Q[entity] if it is a dict queue, else None (a column queue or none)."""
        return self._dicts.get(entity)

    @property
    def lookup(self) -> Callable[[str], Optional[Queue]]:
        """Return the dict queues' lookup, entity -> queue or None (no Python frame: for loops over many entities)."""
        return self._dicts.get

    def dict_queues(self) -> ItemsView[str, Queue]:
        """Return the dict queues, (entity, queue) in creation order (a live view)."""
        return self._dicts.items()

    def in_columns(self, entity: str) -> bool:
        """Tell whether Q[entity] lives in the column form."""
        return entity in self.columns.entities

    # --------------------------------------------------------- dict queues
    def new(self, entity: str, synced: int) -> Queue:
        """Create an empty dict queue for ``entity``, up to date with ``synced`` ticks (earlier ones are not owed)."""
        q = self._dicts[entity] = Queue()
        q.synced = synced
        q.hits = None
        q.marked = False
        return q

    def put(self, entity: str, q: Queue, prop: str) -> bool:
        """Push ``prop`` to the back of Q[entity] with the next stamp (Algorithm 1); True if it was a refresh.

        A refresh keeps the entry's origin reference (:mod:`fsreg_ros.core.memory.queue`).
        """
        old = q.pop(prop, None)
        self._stamp += 1
        present = old is not None
        if present:
            q[prop] = (self._stamp, old if old.__class__ is int else old[1])
        else:
            q[prop] = self._stamp
            self._size += 1
        self._nonempty[entity] = None
        return present

    def remove(self, entity: str, q: Queue, prop: str) -> None:
        """Take ``prop`` out of Q[entity] (a dict queue holding it)."""
        del q[prop]
        self._size -= 1
        if not q:
            self._nonempty.pop(entity, None)

    def drop_fronts(self, entity: str, q: Queue, ticks: int, owed: int = -1) -> int:
        """Bring Q[entity] up to ``ticks`` ticks, one front dropped per owed tick; return how many went.

        ``owed``: the ticks it owes, when the caller knows (else ``ticks`` less its ``synced``).
        """
        n = len(q)
        owed = min(ticks - q.synced if owed < 0 else owed, n)
        q.synced = ticks
        if owed == n:
            q.clear()
            self._nonempty.pop(entity, None)
        else:
            for _ in range(owed):
                del q[next(iter(q))]
        self._size -= owed
        return owed

    def take_fronts(self, entity: str, q: Queue, ticks: int, owed: int = -1) -> list[str]:
        """As :meth:`drop_fronts`, returning the fronts dropped, LRU first (to report them)."""
        victims = list(islice(q, min(ticks - q.synced if owed < 0 else owed, len(q))))
        q.synced = ticks
        for prop in victims:
            del q[prop]
        self._size -= len(victims)
        if not q:
            self._nonempty.pop(entity, None)
        return victims

    def sync(self, q: Queue, ticks: int) -> None:
        """Note that ``q`` is up to date with ``ticks`` ticks (its pops applied by the caller through the store)."""
        q.synced = ticks

    def encode_quiet(self, entities: Iterable[str], prop: str, capacity: Optional[int], time: float, ticks: int,
                     changed: list, watcher: Optional[EncodeWatcher]) -> None:
        """Encode(e, [prop]) for each entity, with no events and at most an LRU capacity (rules 2 and 3's hot path).

        Exactly what pushing queue by queue (owed decay first, then :meth:`put`, then an
        LRU displacement) leaves.  Per entity: the decay ticks it owes (only when it owes
        some), one dict assignment and, when the queue is full, one front deletion; the
        entity joins ``changed`` (the change record's entries; the queue's ``marked`` flag).
        No event objects, no calls per entity otherwise, no object per entry (see
        :class:`Queue`).  ``watcher`` (rule ``activation``): what crossed goes first
        (:meth:`EncodeWatcher.sync`), and it hears each encoding and displaced front.
        """
        queues = self._dicts
        nonempty = self._nonempty
        in_columns = self.columns.entities
        limit = capacity if capacity is not None else sys.maxsize
        act = watcher
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
                q = self.to_dict(entity)
            if not q.marked:
                q.marked = True
                changed.append(entity)
            if q.synced != ticks:  # lazy decay catch-up (Algorithm 2)
                if q:
                    size -= pop_quietly(q, ticks)
                    if not q:
                        del nonempty[entity]
                q.synced = ticks
            if act is not None and q:  # what crossed goes (through remove: the counts are kept there)
                self._size = size
                act.sync(entity, q)
                size = self._size
            # Caught up, so: entity in the non-empty set  <=>  Q[entity] is non-empty.
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

    # ------------------------------------------------------------ restore
    def reset(self, stamp: int) -> None:
        """Hold nothing, the stamp counter at ``stamp`` (a restore; the column form's ids stay)."""
        self._dicts, self._nonempty, self._size, self._stamp = {}, {}, 0, stamp
        self.columns.clear()

    def load(self, entity: str, entries: dict, hits: Optional[dict[str, int]], synced: int) -> Queue:
        """Hold a restored dict queue: ``entries`` (property -> entry, LRU first), LFU ``hits``, ``synced`` ticks."""
        q = self.new(entity, synced)
        q.update(entries)
        q.hits = hits
        if q:
            self._nonempty[entity] = None
            self._size += len(q)
        return q

    # --------------------------------------------------------- column form
    def usable(self, entities: Sequence[str], limits: Limits, column_min: int, quiet: bool, traced: bool) -> bool:
        """Tell whether members of ``entities`` may be encoded as a column operation (:meth:`ColumnQueues.usable`).

        Binding the rows may give up a column form of another shape first (:meth:`drop`).
        Traced rows keep their entities' own clocks on any clock but the buffer's seconds.
        """
        columns = self.columns
        if not columns.eligible(entities, limits, column_min, quiet):
            return False
        own = traced and limits.activation_clock != "seconds"
        if columns.reshape(entities, limits.capacity, traced, own):
            self.drop()
        return columns.bind(entities, limits.capacity, traced, own)

    def adopt(self, rows: np.ndarray, ticks: int) -> bool:
        """Move the queues of ``rows`` into the column form (those not there yet); False, moving none, if one is longer.

        Rows whose entity has no dict queue start empty (up to date with ``ticks``), all
        at once; the few that have one take its entries (and the keeper's traces).
        """
        columns = self.columns
        store = columns.store
        fresh = rows[~store.held[rows]]
        if not len(fresh):
            return True
        names = list(map(columns.bound.__getitem__, fresh.tolist()))
        queues = self._dicts
        moving = sorted(queues.keys() & names, key=columns.row.__getitem__)  # in entity order
        longest = max((len(queues[name]) for name in moving), default=0)
        if longest > store.width and (store.bounded or not columns.room(rows[:0], longest)):
            return False
        store.start_empty(fresh, ticks)  # ticks before a queue existed are not owed
        keeper = self.keeper
        if keeper is not None and store.traces is not None and store.traces.own_clocks:
            store.traces.set_clocks(fresh, *keeper.release_clocks(names))  # (names: fresh's, in order)
        for name in moving:
            q = queues.pop(name)
            row = columns.row[name]
            store.write(row, [columns.item(prop, value) for prop, value in q.items()], q.synced)
            if keeper is not None:  # each entry's trace goes with it (slot k: the k-th item written)
                traces = keeper.release(name)
                store.traces.put_row(row, [traces[prop] for prop in q])
        columns.entities.update(names)
        return True

    def to_dict(self, entity: str) -> Queue:
        """Move Q[entity] from its row to a dict queue (same content, owed ticks still owed)."""
        columns = self.columns
        row, store = columns.row[entity], columns.store
        q = self._dicts[entity] = Queue(columns.row_dict(row))
        q.synced = int(store.synced[row])
        q.hits = None
        q.marked = False  # if it changed since the last take, a column mark says so
        if self.keeper is not None and store.traces is not None:
            self.keeper.take(entity, columns.traces_of(entity))
            if store.traces.own_clocks:
                self.keeper.take_clock(entity, store.traces.clock_of(row), store.traces.moved_of(row))
        store.release(row)
        columns.entities.discard(entity)
        return q

    def drop(self) -> None:
        """Move every column queue back to a dict queue (before any code path that only knows dicts)."""
        columns = self.columns
        if columns.store is None:
            return
        self.on_drop()
        for entity in [e for e in columns.bound if e in columns.entities]:
            self.to_dict(entity)
        columns.forget_rows()

    def encode_rows(self, rows: np.ndarray, prop: str, traced: Optional[tuple[float, float, float, float]]) -> None:
        """Encode(e, [prop]) (Algorithms 1, 3) for the held, caught-up, distinct ``rows``, stamps from the next on.

        Those that were empty (re)join the non-empty set last, in row order, as queue by
        queue.  ``traced``: as :meth:`QueueColumns.encode`.
        """
        columns = self.columns
        grew, was_empty = columns.store.encode(rows, columns.prop(prop), self._stamp + 1, traced)
        self._stamp += len(rows)
        self._size += int(grew.sum())
        self._rejoin(list(map(columns.bound.__getitem__, rows[was_empty].tolist())))

    def encode_row(self, entity: str, prop: str, traced: Optional[tuple[float, float, float, float]]) -> None:
        """Encode(entity, [prop]) into its row (held, caught up, with room), with the next stamp."""
        columns = self.columns
        row = columns.row[entity]
        store = columns.store
        was_empty = not store.length[row]
        self._stamp += 1
        self._size += store.encode_one(row, columns.prop(prop), self._stamp, traced)
        if was_empty:
            self._rejoin([entity])

    def _rejoin(self, names: list[str]) -> None:
        nonempty = self._nonempty
        for name in names:  # (re)joins the non-empty queues last, as queue by queue
            nonempty.pop(name, None)
        nonempty.update(dict.fromkeys(names))

    def pop_owed(self, rows: np.ndarray, ticks: int) -> np.ndarray:
        """Apply the decay ticks the held ``rows`` owe, up to ``ticks`` (a front per tick); return the pops per row.

        Rows left empty stay in the non-empty set (the caller encodes into them or calls
        :meth:`emptied`).
        """
        store = self.columns.store
        owed = np.minimum(ticks - store.synced[rows], store.length[rows])
        store.synced[rows] = ticks
        store.pop_fronts(rows, owed)
        self._size -= int(owed.sum())
        return owed

    def pop_rows(self, rows: np.ndarray, counts: np.ndarray) -> None:
        """Pop ``counts[i]`` fronts of each held row ``rows[i]`` (at most its length); rows emptied leave the set."""
        store = self.columns.store
        store.pop_fronts(rows, counts)
        self._size -= int(counts.sum())
        self.emptied(rows)

    def clear_slots(self, flat: np.ndarray) -> np.ndarray:
        """Empty the held slots ``flat`` (flat indices, distinct); return their rows (a row may recur).

        Rows left empty stay in the non-empty set (as :meth:`pop_owed`).
        """
        store = self.columns.store
        store.clear_slots(flat)
        owners = flat % store.rows  # a row may recur
        np.subtract.at(store.length, owners, 1)  # (one number per entry gone, not the row's every slot)
        self._size -= len(flat)
        return owners

    def emptied(self, rows: np.ndarray) -> None:
        """Take the ``rows`` left empty out of the non-empty set."""
        nonempty, bound = self._nonempty, self.columns.bound
        for row in rows[self.columns.store.length[rows] == 0].tolist():
            nonempty.pop(bound[row], None)

    def row_of(self, entity: str) -> Mapping:
        """Return a column queue as a dict queue's entries (property -> entry), LRU first (a copy)."""
        return self.columns.row_dict(self.columns.row[entity])


def _nothing() -> None:
    return None
