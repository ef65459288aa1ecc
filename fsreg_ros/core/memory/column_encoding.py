"""The column paths of Encode and of reading: rules 2 and 3 over many rows at once, rule 1 in a row.

:meth:`WMBuffer.encode_members` encodes one property for the members of a large
domain as one column operation (:func:`encode_rows`), and :meth:`WMBuffer.encode`
encodes a description into a queue that lives in a row without moving it
(:func:`encode_in_row`); :func:`readable_row` reads such a queue up to date.  Each does
what the dict path does, in the same order: the owed decay ticks (Algorithm 2), then
what crossed the activation threshold, then the encodings (Algorithms 1 and 3), with
the same stamps, origins, sizes, non-empty set and change record.  The state changes
go through the buffer's :class:`~fsreg_ros.core.memory.queues.QueueStore`; the rules
decide (decay's ticks, :class:`~fsreg_ros.core.memory.activation.LazyActivation`).
"""

from __future__ import annotations

from typing import Mapping, Optional, Sequence

import numpy as np

from . import bitset
from .host import HostBuffer
from .queue import WMEvent
from .queues import NO_ROWS


def encode_rows(wm: HostBuffer, members: int, entities: Sequence[str], prop: str, cause: str, time: float,
                turn: Optional[int]) -> bool:
    """Encode(e, [prop]) for each member e of ``entities`` as one column operation; False if it cannot.

    Not possible (nothing done): a domain under ``column_min`` entities, a listener
    (event sink or watcher), limits beyond an LRU capacity and rule ``activation``, a
    queue longer than the rows (restored so) or, for rows that widen, longer than the
    widest.  Otherwise the members' queues move into the rows if not there yet, their
    owed decay and activation crossings are applied first, as queue by queue, then the
    same stamps, origins, sizes and change record as Encode queue by queue would leave.
    """
    store = wm.store
    columns = store.columns
    if not store.usable(entities, wm.limits, wm.column_min, wm.quiet, wm.activation is not None):
        return False
    rows = bitset.index_array(members)
    if not store.adopt(rows, wm.ticks.count) or not columns.room(rows):
        return False
    wm.origin_log.log(store.stamp + 1, cause, turn)
    store.pop_owed(rows, wm.lazy_decay.ticks.count)
    act = wm.activation
    traced = None
    if act is not None:  # entries whose activation fell below the threshold go first, as queue by queue
        act.advance(time)
        act.forget_members(rows, members)
        traced = act.noting()
    store.encode_rows(rows, prop, traced)
    wm.changes.mark_rows(rows)
    return True


def encode_in_row(wm: HostBuffer, entity: str, props: Sequence[str], cause: str, time: float,
                  turn: Optional[int]) -> bool:
    """Encode(entity, props) (Algorithm 1) into its column queue, property by property; False if it needs room.

    :meth:`WMBuffer.encode`'s column path (no listener, at most an LRU capacity and
    rule ``activation``): a description's rule-1 encodings leave the queue in its row
    instead of moving it to a dict queue and back.  Its owed decay (Algorithm 2) and
    activation crossings are applied first, then each property as
    :meth:`WMBuffer.encode_each` would (same stamps, origins, size, non-empty queues
    and change record).  A row that widens without room for every property is left to
    the dict path (False, nothing done).
    """
    store = wm.store
    columns = store.columns
    row, arrays = columns.row[entity], columns.store
    if not props:
        return True
    if not arrays.bounded and arrays.length[row] + len(props) > arrays.width:
        return False
    ticks = wm.lazy_decay.ticks.count
    if arrays.synced[row] != ticks:  # lazy decay catch-up (Algorithm 2)
        store.pop_owed(np.array([row]), ticks)
    act = wm.activation
    traced = None
    if act is not None:
        act.advance(time)
        traced = act.noting()
    for k, prop in enumerate(props):
        if act is not None and (k == 0 or traced[0] is None):  # what crossed goes first, as queue by queue
            act.forget_row(row)  # (again before each property when the row's own clock moved)
        wm.origin_log.log(store.stamp + 1, cause, turn)
        store.encode_row(entity, prop, traced)
    wm.changes.note(entity)
    return True


def readable_row(wm: HostBuffer, entity: str) -> Optional[Mapping]:
    """Return the column queue of ``entity`` up to date with decay and the clock, for reading.

    A copy of its row; with a listener, owed pops must be reported, so it becomes a
    dict queue (caught up, returned).
    """
    store = wm.store
    columns = store.columns
    row, arrays = columns.row[entity], columns.store
    quiet = wm.quiet
    if arrays.synced[row] != wm.lazy_decay.ticks.count and arrays.length[row]:
        if not quiet:
            wm.lazy_decay.catch_up(entity)
            return wm.readable(entity)
        wm.lazy_decay.settle_columns(np.array([row]))
    act = wm.activation
    if act is not None and arrays.length[row] and arrays.traces.row_due_by(row, act.column_clock()):
        if not quiet:  # what went must be reported: as a dict queue
            store.to_dict(entity)
            return wm.readable(entity)
        act.settle_columns(np.array([row]))
    return columns.row_dict(row)


def forget_all(wm: HostBuffer, cause: str, time: float, turn: Optional[int]) -> None:
    """Forget every property of ``wm`` (:meth:`WMBuffer.forget_everything`): queue by queue, LRU first.

    In the order :meth:`WMBuffer.nonempty_entities` lists them; column queues are
    emptied at once, their properties listed one by one only when an event sink must
    hear them.
    """
    order = wm.nonempty_entities()  # flushes
    store = wm.store
    columns = store.columns
    rows = columns.store.non_empty() if columns.entities else NO_ROWS
    fronts: dict[int, list[int]] = {}
    if len(rows) and wm.sink is not None:
        fronts = dict(zip(rows.tolist(), columns.store.in_order(rows, columns.store.width)))
    for entity in order:
        if store.get(entity) is not None:
            while wm.pop_entry(entity, cause, time, turn) is not None:
                pass
            continue
        wm.changes.note(entity)  # a column queue
        for pid in fronts.get(columns.row[entity], ()):
            wm.sink(WMEvent("forget", wm.domain, entity, columns.prop_name[pid], cause, time, turn))
    if len(rows):
        store.pop_rows(rows, columns.store.length[rows].copy())
