"""Column queues: the numpy form of WM queues (the arrays, and which queues live in which rows).

Reference resolution and REG encode one affirmed property for every candidate or
distractor it holds for (docs/semantics.md section 2, rules 2 and 3): thousands of
queues per call in a large domain.  Done queue by queue in Python, each encoding
touches a few scattered objects, and at 10,000 entities the cache misses make every
encoding about three times dearer than at 1,000 (measured with a bare dict loop).
:class:`QueueColumns` keeps such queues as arrays instead, so one call of
:meth:`QueueColumns.encode` is Encode(e, [p]) (Algorithm 1) with displacement
(Algorithm 3, LRU) for every row at once; owed decay ticks (Algorithm 2) are popped
from many rows at once (:meth:`~fsreg_ros.core.memory.queues.QueueStore.pop_owed`), and,
under rule ``activation``, entries whose activation fell below the threshold by
:meth:`~fsreg_ros.core.memory.activation.LazyActivation.forget_rows` (each slot keeps
its entry's trace: :class:`~fsreg_ros.core.memory.trace_columns.TraceColumns`).

Row r holds the queue of the r-th entity of the buffer's entity list in ``width``
slots (the displacement capacity; rule ``activation`` without a capacity: as many as
the longest queue needs, :meth:`ColumnQueues.room`).  A slot holds a property id (-1: empty), the
entry's stamp and its origin reference: the stamp of the encoding that made the
property enter the queue, or ``-(i + 1)`` for the buffer's i-th explicit origin (one
restored from a store).  Slots are unordered: stamps are unique and grow, so a
queue's order, LRU first, is its stamps' order, and an encoding writes one slot and
shifts nothing.  :class:`QueueColumns` knows nothing about names, events or limits
beyond the width.

:class:`ColumnQueues` names the rows: which entities' queues live in the columns
(each queue lives in exactly one place, a dict :class:`Queue` or a row), the entity
list the rows are numbered by, property ids and restored origins.  The buffer's
:class:`~fsreg_ros.core.memory.queues.QueueStore` holds it, moves queues between the
two forms and keeps the counts.  :meth:`WMBuffer.encode_members` puts the members of
rule 2 and 3 encodings of a domain of at least :data:`COLUMN_MIN` entities here while
no event sink listens and the limits are at most an LRU capacity and rule
``activation``, and :meth:`WMBuffer.encode` then encodes a column queue in its row
(a description's rule-1 encodings, :mod:`fsreg_ros.core.memory.encoding`); anything
else that touches a column queue first moves it back to a dict
(:meth:`QueueStore.to_dict`), so every other code path only ever sees dicts.
"""

from __future__ import annotations

from typing import Mapping, Optional, Sequence

import numpy as np

from .limits import Limits
from .queue import Entry, Origin
from .trace import HISTORY, NEVER, Trace
from .trace_columns import TraceColumns

#: :meth:`WMBuffer.encode_members` keeps the queues of a domain of at least this many
#: entities as columns; smaller domains go queue by queue.  A column operation costs
#: tens of microseconds however few its members, and a queue moved between the two
#: forms costs more than an encoding, so the choice is made per domain, not per call
#: (bench_core, scripts/bench_encode.py).
COLUMN_MIN = 4096
#: Column queues are used up to this displacement capacity (their width), and while
#: width x entities stays within this many slots (20 bytes each, held for every entity).
COLUMN_MAX_WIDTH = 64
COLUMN_MAX_SLOTS = 2**22
#: Under rule ``activation`` each slot also keeps its entry's trace (HISTORY + 4 numbers).
COLUMN_MAX_TRACED_SLOTS = COLUMN_MAX_SLOTS // (HISTORY + 4)

#: The first width of rows that widen (rule ``activation`` without a capacity).
_FIRST_WIDTH = 4
#: Rows that widen find a property's slot in a map (property id x row -> slot, a byte
#: each) while it takes at most this many bytes (:meth:`QueueColumns.encode`); past it,
#: by reading their slots.
SLOT_MAP_MAX = 2**24

#: Larger than any stamp: an empty slot is never a queue's front.
_NO_STAMP = np.iinfo(np.int64).max


class QueueColumns:
    """Queues of ``width`` slots, one row per entity (see the module docstring).

    ``bounded``: the width is the displacement capacity (a full row loses its front);
    otherwise (rule ``activation`` without a capacity) no queue is ever full, the
    caller widening the rows first (:meth:`widen`).  ``traces`` (rule ``activation``): each slot's entry's trace
    (:class:`~fsreg_ros.core.memory.activation.TraceColumns`; ``own_clocks``: and each row's
    own clock, the words clock's), else None.  ``slot_of``
    (rows that widen, within :data:`SLOT_MAP_MAX`): ``slot_of[p, r]`` is the slot of row r
    holding property id p, -1 if none; kept by every write and clear of a slot.
    """

    def __init__(self, width: int, rows: int, traced: bool = False, bounded: bool = True,
                 own_clocks: bool = False) -> None:
        self.width = width
        self.bounded = bounded  # width is the displacement capacity (else it grows: widen)
        self.traces = TraceColumns(width, rows, own_clocks) if traced else None
        self.prop = np.full((width, rows), -1, dtype=np.int32)
        self.stamp = np.zeros((width, rows), dtype=np.int64)
        self.entry = np.zeros((width, rows), dtype=np.int64)
        self.length = np.zeros(rows, dtype=np.int64)
        self.synced = np.zeros(rows, dtype=np.int64)  # decay ticks the row is up to date with
        self.held = np.zeros(rows, dtype=bool)  # the row's queue lives here
        self.changed = np.zeros(rows, dtype=np.int64)  # change-record mark of its first change (0: none)
        self.used = 0  # slots ever written, in any row: slots used..width-1 are empty in every row
        self.slot_of: Optional[np.ndarray] = None if bounded else np.full((0, rows), -1, dtype=np.int8)

    def widen(self, width: int) -> None:
        """Give every row ``width`` slots (more than now; the new ones empty)."""
        extra, rows = width - self.width, self.rows
        self.prop = np.concatenate([self.prop, np.full((extra, rows), -1, dtype=np.int32)])
        self.stamp = np.concatenate([self.stamp, np.zeros((extra, rows), dtype=np.int64)])
        self.entry = np.concatenate([self.entry, np.zeros((extra, rows), dtype=np.int64)])
        if self.traces is not None:
            self.traces.widen(extra)
        self.width = width

    @property
    def rows(self) -> int:
        """Rows allocated (at least the number of entities bound)."""
        return self.length.shape[0]

    def grow(self, rows: int) -> None:
        """Make room for at least ``rows`` rows (new rows empty, not held)."""
        if rows <= self.rows:
            return
        extra = max(rows, 2 * self.rows) - self.rows  # doubling: appending entities stays cheap
        self.prop = np.concatenate([self.prop, np.full((self.width, extra), -1, dtype=np.int32)], axis=1)
        self.stamp = np.concatenate([self.stamp, np.zeros((self.width, extra), dtype=np.int64)], axis=1)
        self.entry = np.concatenate([self.entry, np.zeros((self.width, extra), dtype=np.int64)], axis=1)
        self.length = np.concatenate([self.length, np.zeros(extra, dtype=np.int64)])
        self.synced = np.concatenate([self.synced, np.zeros(extra, dtype=np.int64)])
        self.changed = np.concatenate([self.changed, np.zeros(extra, dtype=np.int64)])
        self.held = np.concatenate([self.held, np.zeros(extra, dtype=bool)])
        if self.slot_of is not None:
            self.slot_of = self._within_map(np.concatenate(
                [self.slot_of, np.full((self.slot_of.shape[0], extra), -1, dtype=np.int8)], axis=1))
        if self.traces is not None:
            self.traces.grow(extra)

    # ------------------------------------------------------------ slot map
    def _within_map(self, slot_of: np.ndarray) -> Optional[np.ndarray]:
        """Return ``slot_of`` if it fits :data:`SLOT_MAP_MAX`, else None (no map from then on)."""
        return slot_of if slot_of.size <= SLOT_MAP_MAX else None

    def _map_line(self, prop: int) -> Optional[np.ndarray]:
        """Return the slot map's line of property id ``prop`` (a view: writable), growing the map; None without one."""
        if self.slot_of is None:
            return None
        if prop >= self.slot_of.shape[0]:
            lines = max(prop + 1, 2 * self.slot_of.shape[0], 4)
            self.slot_of = self._within_map(np.concatenate(
                [self.slot_of, np.full((lines - self.slot_of.shape[0], self.rows), -1, dtype=np.int8)]))
            if self.slot_of is None:
                return None
        return self.slot_of[prop]

    def _unmap_slots(self, flat: np.ndarray) -> None:
        """Take the entries of slots ``flat`` (flat indices) out of the slot map (before they are cleared)."""
        if self.slot_of is not None:
            props = self.prop.reshape(-1).take(flat)
            held = props >= 0
            self.slot_of[props[held], (flat % self.rows)[held]] = -1

    def clear_slots(self, flat: np.ndarray) -> None:
        """Empty slots ``flat`` (flat indices): out of the slot map, no property, a trace never due.

        The rows' lengths are the caller's.
        """
        self._unmap_slots(flat)
        self.prop.reshape(-1)[flat] = -1
        if self.traces is not None:
            self.traces.forget_slots(flat)

    def clear_rows(self, rows: np.ndarray) -> None:
        """Empty every slot of ``rows`` as :meth:`clear_slots` does (lengths: the caller's)."""
        if self.slot_of is not None:
            props = self.prop[:self.used].take(rows, axis=1)
            held = props >= 0
            self.slot_of[props[held], np.broadcast_to(rows, props.shape)[held]] = -1
        self.prop[:, rows] = -1
        if self.traces is not None:
            self.traces.due[:, rows] = NEVER

    # ------------------------------------------------------------ one row
    def read(self, row: int) -> list[tuple[int, int, int]]:
        """Return row ``row``'s entries as ``(property id, stamp, origin reference)``, LRU first."""
        if not self.length[row]:
            return []
        used = self.used  # (slots never used hold nothing)
        items = [
            (prop, stamp, entry)
            for prop, stamp, entry in zip(self.prop[:used, row].tolist(), self.stamp[:used, row].tolist(),
                                          self.entry[:used, row].tolist())
            if prop >= 0
        ]
        items.sort(key=lambda item: item[1])
        return items

    def slots(self, row: int) -> list[int]:
        """Return the slots of row ``row`` that hold an entry, LRU first."""
        stamps = self.stamp[:self.used, row].tolist()
        return sorted((k for k, prop in enumerate(self.prop[:self.used, row].tolist()) if prop >= 0),
                      key=stamps.__getitem__)

    def write(self, row: int, items: list[tuple[int, int, int]], synced: int) -> None:
        """Hold ``items`` (at most ``width``, any order) as row ``row``, up to date with ``synced`` ticks."""
        self.clear_rows(np.array([row]))
        for k, (prop, stamp, entry) in enumerate(items):
            self.prop[k, row], self.stamp[k, row], self.entry[k, row] = prop, stamp, entry
            line = self._map_line(prop)
            if line is not None:
                line[row] = k
        self.length[row] = len(items)
        self.synced[row] = synced
        self.held[row] = True
        self.used = max(self.used, len(items))

    def start_empty(self, rows: np.ndarray, synced: int) -> None:
        """Hold ``rows`` as empty queues, up to date with ``synced`` ticks."""
        self.clear_rows(rows)
        self.length[rows] = 0
        self.synced[rows] = synced
        self.held[rows] = True

    def release(self, row: int) -> None:
        """Stop holding row ``row`` (its queue moves elsewhere)."""
        self.clear_rows(np.array([row]))
        self.length[row] = 0
        self.held[row] = False

    # ---------------------------------------------------------- many rows
    def pop_fronts(self, rows: np.ndarray, counts: np.ndarray) -> None:
        """Pop ``counts[i]`` fronts (oldest stamps first) of each held row ``rows[i]`` (at most its length)."""
        if not counts.any():
            return
        popping = counts > 0
        targets, counts = rows[popping], counts[popping]
        emptied = counts >= self.length[targets]
        gone = targets[emptied]
        self.clear_rows(gone)
        self.length[gone] = 0
        partial, counts = targets[~emptied], counts[~emptied]
        for done in range(int(counts.max(initial=0))):  # fewer than width rounds
            now = partial[counts > done]
            stamps = np.where(np.take(self.prop, now, axis=1) >= 0, np.take(self.stamp, now, axis=1), _NO_STAMP)
            popped = _first_minimum(stamps)[0] * self.rows + now
            self.clear_slots(popped)
            self.length[now] -= 1

    def in_order(self, rows: np.ndarray, depth: int) -> list[list[int]]:
        """Return the first ``depth`` property ids of each of ``rows``, LRU first (fewer for a shorter row)."""
        stamps = np.where(np.take(self.prop, rows, axis=1) >= 0, np.take(self.stamp, rows, axis=1), _NO_STAMP)
        order = np.argsort(stamps, axis=0, kind="stable")[:depth]
        props = np.take_along_axis(np.take(self.prop, rows, axis=1), order, axis=0).T.tolist()
        return [[p for p in row if p >= 0] for row in props]

    def non_empty(self) -> np.ndarray:
        """Return the held rows holding something (ascending)."""
        return np.flatnonzero(self.held & (self.length > 0))

    def entries(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return every entry of ``rows`` as parallel arrays: its stamp, its row and its property id."""
        props = np.take(self.prop, rows, axis=1)
        where = props >= 0
        return np.take(self.stamp, rows, axis=1)[where], np.broadcast_to(rows, props.shape)[where], props[where]

    def encode(self, rows: np.ndarray, prop: int, first_stamp: int,
               traced: Optional[tuple[float, float, float, float]] = None
               ) -> tuple[np.ndarray, np.ndarray]:
        """Encode(e, [prop]) for each held row, in order, stamps from ``first_stamp`` on (Algorithms 1, 3).

        The rows must be up to date with decay (:meth:`QueueStore.pop_owed`)
        and distinct.  A property present is refreshed (new stamp, same origin); otherwise it takes an
        empty slot or, in a full row, the front's (LRU displacement).  Returns, per row,
        whether the queue grew and whether it was empty before.  The slot is found with
        one key per slot (the property itself -2, an empty slot -1, else its stamp) and
        its column minimum (:func:`_first_minimum`): one reduction, where ``argmin`` and
        ``argmax`` along the short axis would each cost more than the whole encoding.
        ``traced`` (rule ``activation``): ``(time, lifetime, d, clock)`` of the encoding, noted
        in the encoded slots' traces (a displaced front's slot starts a new one).

        Rows that widen (not ``bounded``) always have room, so no front is displaced: the
        slot map (``slot_of``) says which rows hold the property and where, and only the
        others read their slots for the first empty one (:meth:`_slots_for`), and
        of those only the slots ever used (``used``) and the first beyond: a row with
        none of them empty holds ``used`` entries, so slot ``used`` is its first empty one.
        """
        if self.bounded:
            props = np.take(self.prop, rows, axis=1)
            key = np.where(props == prop, -2, np.where(props < 0, -1, np.take(self.stamp, rows, axis=1)))
            slot, best = _first_minimum(key)
            present, grew = best == -2, best == -1  # refreshed; took an empty slot (else displaced the front)
        else:
            slot, present = self._slots_for(rows, prop)
            grew = ~present
        self.used = max(self.used, int(slot.max(initial=-1)) + 1)
        flat = slot * self.rows + rows
        stamps = np.arange(first_stamp, first_stamp + len(rows), dtype=np.int64)
        entries = self.entry.reshape(-1)
        kept = np.where(present, np.take(entries, flat), stamps)
        self.prop.reshape(-1)[flat] = prop
        self.stamp.reshape(-1)[flat] = stamps
        entries[flat] = kept
        if traced is not None:
            time, span, d, clock = traced
            self.traces.encoded(flat, present, time, span, d, rows, clock, self.entry, first_stamp, prop)
        length = self.length[rows]
        self.length[rows] = length + grew
        return grew, length == 0

    def _slots_for(self, rows: np.ndarray, prop: int) -> tuple[np.ndarray, np.ndarray]:
        """Rows that widen: per row of ``rows``, the slot holding ``prop``, else its first empty one; and which.

        With a slot map, one byte per row says where ``prop`` is, and only the rows
        without it read their slots (for the first empty one, which it then maps);
        without, every row reads its slots (:func:`_held_or_empty`).
        """
        read = self.prop[:min(self.used + 1, self.width)]  # the slots ever used and the first beyond
        line = self._map_line(prop)
        if line is None:
            return _held_or_empty(np.take(read, rows, axis=1), prop)
        slot = line.take(rows).astype(np.intp)
        present = slot >= 0
        new = np.flatnonzero(~present)
        if len(new):
            fresh = rows.take(new)
            empty = _held_or_empty(np.take(read, fresh, axis=1), -2)[0]
            slot[new] = empty
            line[fresh] = empty
        return slot, present

    def encode_one(self, row: int, prop: int, stamp: int,
                   traced: Optional[tuple[float, float, float, float]] = None) -> bool:
        """Encode(e, [prop]) for held row ``row`` alone, with Python scalars (:meth:`encode` for one row).

        The row must be up to date with decay and, if it widens, have room.  Returns
        whether the queue grew.  The slot is the one :meth:`encode` picks: the
        property's, else the first empty one, else (a full bounded row) the front's.
        """
        width = self.width if self.bounded else min(self.used + 1, self.width)
        props = self.prop[:width, row].tolist()
        present = prop in props
        if present:
            slot = props.index(prop)
        elif -1 in props:
            slot = props.index(-1)
        else:  # a full row: its front (stamps are unique)
            stamps = self.stamp[:width, row].tolist()
            slot = stamps.index(min(stamps))
        grew = not present and props[slot] < 0
        entry = int(self.entry[slot, row]) if present else stamp
        before = int(self.stamp[slot, row])
        self.prop[slot, row], self.stamp[slot, row], self.entry[slot, row] = prop, stamp, entry
        self.used = max(self.used, slot + 1)
        if not present and self.slot_of is not None:  # (rows that widen never displace)
            line = self._map_line(prop)
            if line is not None:
                line[row] = slot
        if traced is not None:
            time, span, d, clock = traced
            traces = self.traces
            if time is None:  # on the row's own clock (a refresh as it is now)
                traces.encoded_own(slot * self.rows + row, row, present, span, d, clock)
            else:
                traces.encoded_one(slot * self.rows + row, row, time, span, d, clock, self.entry, stamp, prop,
                                   not (present and traces.pending_since(before)))
        self.length[row] += grew
        return grew

    def mark_changed(self, rows: np.ndarray, mark: int) -> None:
        """Record ``mark`` as the first change of each of ``rows`` not changed yet."""
        fresh = rows[self.changed[rows] == 0]
        self.changed[fresh] = mark

    def take_changed(self) -> tuple[np.ndarray, np.ndarray]:
        """Return the changed rows and their marks, by mark then row; clear the record."""
        rows = np.flatnonzero(self.changed)
        marks = self.changed[rows]
        order = np.argsort(marks, kind="stable")
        self.changed[rows] = 0
        return rows[order], marks[order]

    def origin_stamps(self) -> np.ndarray:
        """Return every origin reference that is a stamp (> 0) held in any slot."""
        refs = self.entry[self.prop >= 0]
        return refs[refs > 0]


def _columnar(limits: Limits) -> bool:
    """Tell whether column queues can hold queues under ``limits``: an LRU capacity at most, and activation.

    Activation on the seconds clock or the words clock (each row keeps its entity's:
    :class:`~fsreg_ros.core.memory.trace_columns.TraceColumns`); the episodes clock
    notes nothing in the queues (:mod:`fsreg_ros.core.memory.entity_clock`).
    """
    return limits.victim == "lru" and not limits.similarity and limits.global_capacity is None


#: Up to this many slots per row, :func:`_first_minimum` finds the slot by one comparison per slot.
_LOOP_WIDTH = 16


def _held_or_empty(props: np.ndarray, prop: int) -> tuple[np.ndarray, np.ndarray]:
    """Return, per column of ``props`` (slots x rows), the slot holding ``prop``, else the first empty one; and which.

    One byte per slot, ``held`` 128 + ``empty`` 64 + (63 - slot) (at most :data:`COLUMN_MAX_WIDTH`
    slots), and its column maximum: the first slot of the best kind.  Rows that widen read
    some 17 slots where a capacity's read 4, and three int64 ``where`` passes and a strided
    ``argmax`` over them cost four times this one byte-wide pass.
    """
    code = (props == prop).view(np.uint8) << 7
    code |= (props < 0).view(np.uint8) << 6
    code |= _DOWN[:len(props), None]
    best = np.maximum.reduce(code, axis=0)
    return (63 - (best & 63)).astype(np.intp), best >= 128


#: 63 - k for slot k (:func:`_held_or_empty`; six bits: :data:`COLUMN_MAX_WIDTH` is 64).
_DOWN = np.arange(63, -1, -1, dtype=np.uint8)


def _first_minimum(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return, per column of ``values`` (slots x rows), the first row holding the column's minimum, and the minimum.

    ``np.minimum.reduce`` runs across the columns at once; ``argmin(axis=0)`` walks each
    short column on its own and costs several times more for the few slots of a queue.
    """
    best = np.minimum.reduce(values, axis=0)
    if values.shape[0] > _LOOP_WIDTH:
        return (values == best).argmax(axis=0), best
    slot = np.zeros(values.shape[1], dtype=np.intp)
    for k in range(values.shape[0] - 1, 0, -1):  # the last assignment wins: the first such slot
        slot[values[k] == best] = k
    return slot, best


class ColumnQueues:
    """The column form of a buffer's queues: which entities' queues live in rows, and how rows are named.

    ``store`` (the arrays, :class:`QueueColumns`) is None until :meth:`bind` first sizes
    it; ``bound`` is the entity list its rows are numbered by (the first list
    :meth:`WMBuffer.encode_members` got; it may only grow by appending), ``row`` entity
    -> row, ``entities`` the entities whose queue lives in the arrays.  Property ids and
    the origins restored from a store (referred to as ``-(i + 1)``) are numbered here.
    Held by the buffer's :class:`~fsreg_ros.core.memory.queues.QueueStore`, which moves
    queues in and out and keeps the counts; this class knows rows, not counts.
    """

    def __init__(self) -> None:
        self.clear()
        self.bound: Optional[list[str]] = None
        self.row: dict[str, int] = {}
        self.prop_id: dict[str, int] = {}
        self.prop_name: list[str] = []

    def clear(self) -> None:
        """Hold no queue (a restore); the entity list and property ids stay."""
        self.store: Optional[QueueColumns] = None
        self.entities: set[str] = set()
        self.explicit: list[Origin] = []
        self.explicit_id: dict[Origin, int] = {}

    def forget_rows(self) -> None:
        """Give the arrays up (every queue moved out first: :meth:`QueueStore.drop`)."""
        self.store = None
        self.entities = set()

    def fits(self, limits: Limits, current: Limits) -> bool:
        """Tell whether the column queues can stay under ``limits`` (``current``: those in force).

        Nothing kept, or an LRU capacity of their width (and the same activation d and
        tau: the traces'); under any other limits a queue may have to lose another
        property than its front, or more than one, which only a dict queue does.
        """
        if self.store is None or not limits.retains:
            return True
        store = self.store
        return (_columnar(limits) and limits.capacity == (store.width if store.bounded else None)
                and limits.activation == current.activation
                and (limits.activation is None or limits.activation_clock == current.activation_clock))

    def eligible(self, entities: Sequence[str], limits: Limits, column_min: int, quiet: bool) -> bool:
        """Tell whether members of ``entities`` may be encoded as a column operation under ``limits``, by size.

        ``quiet``: no event sink listens.  An LRU capacity is the rows' width; rule
        ``activation`` without a capacity keeps rows that widen as their queues grow
        (:meth:`room`).  The entity list must still be bound (:meth:`bind`).
        """
        capacity = limits.capacity
        if capacity is None and limits.activation is None:
            return False
        width = capacity if capacity is not None else _FIRST_WIDTH
        return (
            len(entities) >= column_min
            and quiet
            and _columnar(limits)
            and width <= COLUMN_MAX_WIDTH
            and width * len(entities) <= self._max_slots(limits.activation is not None)
        )

    def reshape(self, entities: Sequence[str], capacity: Optional[int], traced: bool, own_clocks: bool = False) -> bool:
        """Tell whether binding ``entities`` needs arrays of another shape (the column queues must go first)."""
        store = self.store
        return (store is not None and (self.bound is None or entities is self.bound)
                and (store.bounded != (capacity is not None) or (store.traces is not None) != traced
                     or store.bounded and store.width != capacity
                     or traced and store.traces.own_clocks != own_clocks))

    def bind(self, entities: Sequence[str], capacity: Optional[int], traced: bool, own_clocks: bool = False) -> bool:
        """Bind rows to ``entities`` (the first list given) and size the arrays; False for another list.

        ``capacity`` is the rows' width, or None for rows that widen (:meth:`room`);
        ``traced``: each slot keeps a trace (rule ``activation``; ``own_clocks``: each row
        its entity's clock too).  Arrays of another shape must have been given up first (:meth:`reshape`).
        """
        if self.bound is None:
            self.bound = entities  # type: ignore[assignment]
        elif entities is not self.bound:
            return False
        if len(self.row) < len(entities):  # new entities were appended
            for i in range(len(self.row), len(entities)):
                self.row[entities[i]] = i
        if self.store is None:
            self.store = QueueColumns(capacity if capacity is not None else _FIRST_WIDTH, len(entities), traced,
                                      capacity is not None, own_clocks)
        self.store.grow(len(entities))
        return True

    def room(self, rows: np.ndarray, longest: int = 0) -> bool:
        """Make room for one more entry in each of ``rows`` (and for ``longest`` entries) in rows that widen.

        False if that would pass :data:`COLUMN_MAX_WIDTH` or the slot limit (the caller
        then goes queue by queue).  Bounded rows always have room (a full one displaces).
        """
        store = self.store
        if store.bounded or max(store.used + 1, longest) <= store.width:  # (no row holds more than ``used``)
            return True
        need = max(int(store.length[rows].max(initial=0)) + 1, longest)
        if need <= store.width:
            return True
        width = max(2 * store.width, need)
        if width > COLUMN_MAX_WIDTH or width * store.rows > self._max_slots(store.traces is not None):
            return False
        store.widen(width)
        return True

    @staticmethod
    def _max_slots(traced: bool) -> int:
        return COLUMN_MAX_TRACED_SLOTS if traced else COLUMN_MAX_SLOTS

    def prop(self, name: str) -> int:
        """Return the id of property ``name`` (numbered on first use)."""
        pid = self.prop_id.get(name)
        if pid is None:
            pid = self.prop_id[name] = len(self.prop_name)
            self.prop_name.append(name)
        return pid

    def item(self, prop: str, value: Entry) -> tuple[int, int, int]:
        """Return a dict queue's entry as a column item ``(property id, stamp, origin reference)``."""
        pid = self.prop(prop)
        if value.__class__ is int:
            return pid, value, value
        stamp, ref = value
        if ref.__class__ is not int:  # an origin restored from a store
            index = self.explicit_id.get(ref)
            if index is None:
                index = self.explicit_id[ref] = len(self.explicit)
                self.explicit.append(ref)
            ref = -(index + 1)
        return pid, stamp, ref

    def row_dict(self, row: int) -> dict:
        """Return a row's queue as a dict queue's entries (property -> entry), LRU first."""
        names, explicit = self.prop_name, self.explicit
        return {
            names[pid]: stamp if ref == stamp else (stamp, ref if ref > 0 else explicit[-ref - 1])
            for pid, stamp, ref in self.store.read(row)
        }

    def traces_of(self, entity: str) -> dict[str, Trace]:
        """Return the traces of the entries of the column queue of ``entity`` (rule ``activation``)."""
        row, store = self.row[entity], self.store
        names, props, slots = self.prop_name, store.prop[:, row].tolist(), store.slots(row)
        return dict(zip([names[props[k]] for k in slots], store.traces.row(row, slots)))

    def ranks(self, entity_order: Sequence[str]) -> Mapping[str, int]:
        """Return entity -> rank in ``entity_order`` (the rows' own numbering when that is their list)."""
        if entity_order is self.bound:
            for i in range(len(self.row), len(entity_order)):  # entities appended since the last bind
                self.row[entity_order[i]] = i
            return self.row
        return {entity: i for i, entity in enumerate(entity_order)}
