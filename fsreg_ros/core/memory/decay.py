"""Decay's pops (the paper's Algorithm 2): lazy catch-up, flush and eager ticks, for one buffer.

Decay pops the front of every non-empty queue once per tick.  Done eagerly that
costs O(number of queues) per tick.  A buffer applies ticks lazily instead: a tick
only enters a :class:`~fsreg_ros.core.memory.ticks.TickLedger` (:meth:`LazyDecay.add`),
and each queue catches up (pops one front per missed tick, at most its length) the
next time it is touched (:meth:`LazyDecay.sync`; a column queue with the others,
:func:`pop_owed`).  Because nothing else touches a queue in between, the result is
exactly the eager one; the tests compare it against a naive eager implementation on
random event sequences.  :meth:`LazyDecay.now` applies ticks eagerly instead, in
the canonical event order (tick by tick, entity order within a tick), for a
consultant that publishes every event as it happens.

Tick *times* (the schedule, runs of ticks, the ledger) are arithmetic of
:mod:`fsreg_ros.core.memory.ticks`; this module does the pops.
"""

from __future__ import annotations

from itertools import islice
from typing import Any, Optional, Sequence

import numpy as np

from .ticks import TickLedger, TickRun
from .host import HostBuffer
from .queue import Queue, WMEvent

#: No column rows.
NO_ROWS = np.zeros(0, dtype=np.intp)


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


def pop_owed(columns: Any, rows: np.ndarray, ticks: int) -> np.ndarray:  # a QueueColumns (columns imports this)
    """Apply the decay ticks the held column ``rows`` owe, up to ``ticks``; return the pops per row.

    Each owed tick pops the row's front (its oldest stamp).
    """
    owed = np.minimum(ticks - columns.synced[rows], columns.length[rows])
    columns.synced[rows] = ticks
    columns.pop_fronts(rows, owed)
    return owed


class LazyDecay:
    """One buffer's decay ticks so far and the pops they owe (see the module docstring).

    ``ticks`` numbers every tick given; each dict queue's ``synced`` (and each column
    row's) is the tick count it has been brought up to; ``settled`` the count every
    queue has been brought up to (by :meth:`flush`, :meth:`now` or a restore).
    """

    def __init__(self, wm: HostBuffer) -> None:
        self.wm = wm
        self.ticks = TickLedger()
        self.settled = 0

    def reset(self, count: int) -> None:
        """Start over with ``count`` ticks given, every queue up to date with them (a restore)."""
        self.ticks = TickLedger()
        self.ticks.count = self.settled = count

    def add(self, ticks: TickRun) -> None:
        """Give ticks lazily: O(1) however many."""
        self.ticks.add(ticks)

    # ------------------------------------------------------------ one queue
    def catch_up(self, entity: str) -> None:
        """Apply the ticks Q[entity] still owes (if any); a column queue becomes a dict first."""
        wm = self.wm
        q = wm._queues.get(entity)
        if q is None and entity in wm.columns.entities:
            q = wm.columns.to_dict(entity)
        if q is not None and q.synced != self.ticks.count:
            self.sync(entity, q)

    def sync(self, entity: str, q: Queue) -> None:
        """Apply the ticks since ``q.synced``: one front pop per tick, each reported at its tick's own time."""
        wm = self.wm
        synced = q.synced
        if not q:  # an empty queue owes nothing (and never needs a tick's time)
            q.synced = self.ticks.count
            return
        wm.changes.record(entity, q)
        sink = wm.sink
        if sink is None:  # no events to report: just drop the fronts
            wm._size -= pop_quietly(q, self.ticks.count)
            if not q:
                wm._nonempty.pop(entity, None)
            return
        q.synced = self.ticks.count
        victims = list(islice(q, min(q.synced - synced, len(q))))  # the fronts, LRU first
        for prop in victims:
            del q[prop]
        wm._size -= len(victims)
        if not q:
            wm._nonempty.pop(entity, None)
        for k, prop in enumerate(victims):
            sink(WMEvent("forget", wm.domain, entity, prop, "decay", self.ticks.time(synced + k), None))

    def settle_columns(self, rows: np.ndarray) -> None:
        """Apply the ticks the column ``rows`` owe (no events: only called without a sink)."""
        if not len(rows):
            return
        wm = self.wm
        popped = pop_owed(wm.columns.store, rows, self.ticks.count)
        wm._size -= int(popped.sum())
        wm.columns.emptied(rows)
        wm.changes.mark_rows(rows[popped > 0])

    # -------------------------------------------------------------- every queue
    def flush(self) -> None:
        """Bring every queue up to date with the ticks given so far.

        Nothing to do when no tick arrived since the last flush (every queue is then up
        to date): a large domain is not walked for nothing.
        """
        count = self.ticks.count
        if count == self.settled:
            return
        wm = self.wm
        if wm.columns.entities:
            store = wm.columns.store
            owing = np.flatnonzero(store.held & (store.length > 0) & (store.synced != count))
            if wm.sink is None:
                self.settle_columns(owing)
            else:  # the pops must be reported: those queues become dict queues, caught up below
                for row in owing.tolist():
                    wm.columns.to_dict(wm.columns.bound[row])
        for entity in list(wm._nonempty):
            q = wm._queues.get(entity)  # None: a column queue, caught up above
            if q is not None and q.synced != count:
                self.sync(entity, q)
        # Every non-empty queue is now up to date, and an empty one never needs a
        # tick's time, so older runs can go (bounded memory for long runs).
        self.ticks.drop_before(count)
        self.settled = count

    def now(self, ticks: TickRun, entity_order: Sequence[str]) -> None:
        """Apply ticks at once, in the canonical event order.

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
        wm = self.wm
        self.ticks.add(ticks)
        count = self.ticks.count
        rows = wm.columns.store.non_empty() if wm.columns.entities else NO_ROWS
        pending = [(entity, q) for entity, q in wm._queues.items() if q]
        if wm.sink is None and (entity_order is wm.columns.bound or not len(rows)):
            self._quietly(ticks.count, entity_order, rows, pending)
        else:
            self._in_order(ticks, entity_order, rows, pending)
        self.ticks.drop_before(count)
        self.settled = count

    def _quietly(self, count: int, entity_order: Sequence[str], rows: np.ndarray,
                 pending: list[tuple[str, Queue]]) -> None:
        """Pop ``count`` ticks' fronts with no events: columns at once, dict queues one by one.

        ``rows`` are numbered in ``entity_order`` (or there are none), so the change
        record follows entity order with one column mark per run of rows between two
        dict queues.
        """
        wm = self.wm
        ticks = self.ticks.count
        if len(rows):
            wm._size -= int(pop_owed(wm.columns.store, rows, ticks).sum())
            wm.columns.emptied(rows)
        rank = wm.columns.ranks(entity_order)
        last = len(rank)
        ordered = sorted(pending, key=lambda item: rank.get(item[0], last))
        # Where each dict queue falls among the column rows (in entity order).
        cuts = np.searchsorted(rows, [rank.get(e, last) for e, _ in ordered]).tolist() if len(rows) else []
        start = 0
        for i, (entity, q) in enumerate(ordered):
            if cuts and cuts[i] > start:
                wm.changes.mark_rows(rows[start:cuts[i]])
                start = cuts[i]
            q.synced = ticks - count
            wm._size -= pop_quietly(q, ticks)
            wm.changes.record(entity, q)
            if not q:
                del wm._nonempty[entity]
        wm.changes.mark_rows(rows[start:])

    def _in_order(self, ticks: TickRun, entity_order: Sequence[str], rows: np.ndarray,
                  pending: list[tuple[str, Queue]]) -> None:
        """Pop the ticks' fronts tick by tick, in ``entity_order``, reporting each (the general path).

        The fronts each queue loses are listed first (a column queue's by one sort of
        its slots); the column queues then lose theirs at once, and the events, the
        change record and the dict queues' pops follow tick by tick in entity order.
        """
        wm = self.wm
        count = self.ticks.count
        rank = wm.columns.ranks(entity_order)
        last = len(rank)
        # (rank, tie, entity, fronts it loses LRU first, its dict queue or None for a column queue)
        plan: list[tuple[int, int, str, list[str], Optional[Queue]]] = []
        for tie, (entity, q) in enumerate(pending):
            plan.append((rank.get(entity, last), tie, entity, list(islice(q, ticks.count)), q))
        if len(rows):
            store, names, bound = wm.columns.store, wm.columns.prop_name, wm.columns.bound
            fronts = store.in_order(rows, min(ticks.count, store.width))
            for row, ids in zip(rows.tolist(), fronts):
                name = bound[row]
                plan.append((rank.get(name, last), len(pending) + row, name, [names[i] for i in ids], None))
            wm._size -= int(pop_owed(store, rows, count).sum())
            wm.columns.emptied(rows)
        plan.sort(key=lambda step: step[:2])
        sink = wm.sink
        for i in range(max((len(step[3]) for step in plan), default=0)):
            time = ticks.time(i)
            for _, _, entity, fronts, q in plan:
                if i >= len(fronts):
                    continue
                if q is None:  # popped already, with the other column queues
                    if i == 0:
                        wm.changes.note(entity)
                else:
                    del q[fronts[i]]
                    wm._size -= 1
                    wm.changes.record(entity, q)
                if sink is not None:
                    sink(WMEvent("forget", wm.domain, entity, fronts[i], "decay", time, None))
        for entity, q in pending:
            q.synced = count
            if not q:
                del wm._nonempty[entity]
