"""The change record: which queues changed since a consultant last persisted them.

:meth:`WMBuffer.take_changes` returns the entities whose queue changed since it was
last called, in first-change order, so a consultant persists exactly those queues
without listening to events.  A queue changed when an encoding or a forgetting
touched it (any cause), or when new limits reset its LFU counts.  A lazily caught-up
queue counts as changed when its owed decay pops are applied, so its place in the
order is then, not the tick's; with eager ticks (:meth:`WMBuffer.decay_now`) it is
the tick's.  A restore records nothing and clears the record.

The record is kept whatever event sink is attached (or none), on every code path:
a dict queue notes itself once (its ``marked`` flag), a column queue by name, and a
column operation over many rows by one int *mark* that stands for the rows it
changed first (:meth:`QueueColumns.mark_changed`), expanded into names when the
record is taken.
"""

from __future__ import annotations

from typing import Union

import numpy as np

from .host import HostBuffer
from .queue import Queue

#: The record is compacted when it holds this many column-operation marks.
CHANGE_MARKS_MAX = 4096


class ChangeRecord:
    """Entity names and column marks, in first-change order (a name may recur)."""

    def __init__(self, wm: HostBuffer) -> None:
        self.wm = wm
        self.entries: list[Union[str, int]] = []
        self.marks = 0

    def clear(self) -> None:
        self.entries, self.marks = [], 0

    def record(self, entity: str, q: Queue) -> None:
        """Note that Q[entity] (a dict queue) changed."""
        if not q.marked:
            q.marked = True
            self.entries.append(entity)

    def note(self, entity: str) -> None:
        """Note that the column queue of ``entity`` changed."""
        self.entries.append(entity)

    def mark_rows(self, rows: np.ndarray) -> None:
        """Record the column ``rows`` as changed now (one mark stands for them)."""
        if not len(rows):
            return
        if self.marks >= CHANGE_MARKS_MAX:  # bounded: fold the marks into names
            self.compact()
        self.marks += 1
        self.entries.append(self.marks)
        self.wm.store.columns.store.mark_changed(rows, self.marks)

    def take(self) -> list[str]:
        """Return the changed entities, distinct, in first-change order, and clear the record."""
        changed = self.expand()
        store = self.wm.store
        for entity in changed:  # out of the record: the next change records it again
            q = store.get(entity)
            if q is not None:
                q.marked = False
        self.clear()
        return changed

    def expand(self) -> list[str]:
        """Return the record as distinct entity names, in order, and clear its column part."""
        if self.marks:
            columns = self.wm.store.columns
            rows, marks = columns.store.take_changed()
            bound = columns.bound
        out: dict[str, None] = {}
        for key in self.entries:
            if key.__class__ is int:
                end = int(np.searchsorted(marks, key, side="right"))
                start = int(np.searchsorted(marks, key, side="left"))
                out.update(dict.fromkeys([bound[r] for r in rows[start:end].tolist()]))
            elif key not in out:
                out[key] = None
        return list(out)

    def compact(self) -> None:
        """Replace the record's column marks by the names they stand for."""
        if self.marks:
            self.entries = self.expand()  # type: ignore[assignment]
            self.marks = 0
