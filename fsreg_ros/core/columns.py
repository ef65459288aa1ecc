"""WM queues as numpy columns: rule 2 and 3 encodings into thousands of queues at once.

Reference resolution and REG encode one affirmed property for every candidate or
distractor it holds for (docs/semantics.md section 2, rules 2 and 3): thousands of
queues per call in a large domain.  Done queue by queue in Python, each encoding
touches a few scattered objects, and at 10,000 entities the cache misses make every
encoding about three times dearer than at 1,000 (measured with a bare dict loop).
:class:`QueueColumns` keeps such queues as arrays instead, so one call of
:meth:`QueueColumns.encode` is Encode(e, [p]) (Algorithm 1) with displacement
(Algorithm 3, LRU) for every row at once, and :meth:`QueueColumns.pop_owed` applies
owed decay ticks (Algorithm 2) to many rows at once.

Row r holds the queue of the r-th entity of the buffer's entity list in ``width``
slots (the displacement capacity).  A slot holds a property id (-1: empty), the
entry's stamp and its origin reference: the stamp of the encoding that made the
property enter the queue, or ``-(i + 1)`` for the buffer's i-th explicit origin (one
restored from a store).  Slots are unordered: stamps are unique and grow, so a
queue's order, LRU first, is its stamps' order, and an encoding writes one slot and
shifts nothing.  :class:`fsreg_ros.core.memory.WMBuffer` decides which queues live
here and moves a queue to a plain dict whenever anything else touches it; this
module knows nothing about names, events or limits beyond the width.
"""

from __future__ import annotations

import numpy as np

#: Larger than any stamp: an empty slot is never a queue's front.
_NO_STAMP = np.iinfo(np.int64).max


class QueueColumns:
    """Queues of ``width`` slots, one row per entity (see the module docstring)."""

    def __init__(self, width: int, rows: int) -> None:
        self.width = width
        self.prop = np.full((width, rows), -1, dtype=np.int32)
        self.stamp = np.zeros((width, rows), dtype=np.int64)
        self.entry = np.zeros((width, rows), dtype=np.int64)
        self.length = np.zeros(rows, dtype=np.int64)
        self.synced = np.zeros(rows, dtype=np.int64)  # decay ticks the row is up to date with
        self.held = np.zeros(rows, dtype=bool)  # the row's queue lives here
        self.changed = np.zeros(rows, dtype=np.int64)  # change-record mark of its first change (0: none)

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

    # ------------------------------------------------------------ one row
    def read(self, row: int) -> list[tuple[int, int, int]]:
        """Return row ``row``'s entries as ``(property id, stamp, origin reference)``, LRU first."""
        if not self.length[row]:
            return []
        items = [
            (prop, stamp, entry)
            for prop, stamp, entry in zip(self.prop[:, row].tolist(), self.stamp[:, row].tolist(),
                                          self.entry[:, row].tolist())
            if prop >= 0
        ]
        items.sort(key=lambda item: item[1])
        return items

    def write(self, row: int, items: list[tuple[int, int, int]], synced: int) -> None:
        """Hold ``items`` (at most ``width``, any order) as row ``row``, up to date with ``synced`` ticks."""
        self.prop[:, row] = -1
        for k, (prop, stamp, entry) in enumerate(items):
            self.prop[k, row], self.stamp[k, row], self.entry[k, row] = prop, stamp, entry
        self.length[row] = len(items)
        self.synced[row] = synced
        self.held[row] = True

    def start_empty(self, rows: np.ndarray, synced: int) -> None:
        """Hold ``rows`` as empty queues, up to date with ``synced`` ticks."""
        self.prop[:, rows] = -1
        self.length[rows] = 0
        self.synced[rows] = synced
        self.held[rows] = True

    def release(self, row: int) -> None:
        """Stop holding row ``row`` (its queue moves elsewhere)."""
        self.prop[:, row] = -1
        self.length[row] = 0
        self.held[row] = False

    # ---------------------------------------------------------- many rows
    def pop_owed(self, rows: np.ndarray, ticks: int) -> np.ndarray:
        """Apply the decay ticks the held ``rows`` owe, up to ``ticks`` (Algorithm 2, deferred).

        Each owed tick pops the row's front (its oldest stamp); returns the number of
        properties popped per row.
        """
        owed = np.minimum(ticks - self.synced[rows], self.length[rows])
        self.synced[rows] = ticks
        self.pop_fronts(rows, owed)
        return owed

    def pop_fronts(self, rows: np.ndarray, counts: np.ndarray) -> None:
        """Pop ``counts[i]`` fronts (oldest stamps first) of each held row ``rows[i]`` (at most its length)."""
        if not counts.any():
            return
        popping = counts > 0
        targets, counts = rows[popping], counts[popping]
        emptied = counts >= self.length[targets]
        gone = targets[emptied]
        self.prop[:, gone] = -1
        self.length[gone] = 0
        partial, counts = targets[~emptied], counts[~emptied]
        for done in range(int(counts.max(initial=0))):  # fewer than width rounds
            now = partial[counts > done]
            stamps = np.where(np.take(self.prop, now, axis=1) >= 0, np.take(self.stamp, now, axis=1), _NO_STAMP)
            self.prop.reshape(-1)[_first_minimum(stamps)[0] * self.rows + now] = -1
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

    def encode(self, rows: np.ndarray, prop: int, first_stamp: int) -> tuple[np.ndarray, np.ndarray]:
        """Encode(e, [prop]) for each held row, in order, stamps from ``first_stamp`` on (Algorithms 1, 3).

        The rows must be up to date with decay (:meth:`pop_owed`) and distinct.  A
        property present is refreshed (new stamp, same origin); otherwise it takes an
        empty slot or, in a full row, the front's (LRU displacement).  Returns, per row,
        whether the queue grew and whether it was empty before.  The slot is found with
        one key per slot (the property itself -2, an empty slot -1, else its stamp) and
        its column minimum (:func:`_first_minimum`): one reduction, where ``argmin`` and
        ``argmax`` along the short axis would each cost more than the whole encoding.
        """
        props = np.take(self.prop, rows, axis=1)
        key = np.where(props == prop, -2, np.where(props < 0, -1, np.take(self.stamp, rows, axis=1)))
        slot, best = _first_minimum(key)
        present, grew = best == -2, best == -1  # refreshed; took an empty slot (else displaced the front)
        flat = slot * self.rows + rows
        stamps = np.arange(first_stamp, first_stamp + len(rows), dtype=np.int64)
        entries = self.entry.reshape(-1)
        kept = np.where(present, np.take(entries, flat), stamps)
        self.prop.reshape(-1)[flat] = prop
        self.stamp.reshape(-1)[flat] = stamps
        entries[flat] = kept
        length = self.length[rows]
        self.length[rows] = length + grew
        return grew, length == 0

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


#: Up to this many slots per row, :func:`_first_minimum` finds the slot by one comparison per slot.
_LOOP_WIDTH = 16


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
