"""Decay's pops (the paper's Algorithm 2): lazy catch-up, flush and eager ticks, for one buffer.

Decay pops the front of every non-empty queue once per tick.  Done eagerly that
costs O(number of queues) per tick.  A buffer applies ticks lazily instead: a tick
only enters a :class:`~fsreg_ros.core.memory.ticks.TickLedger` (:meth:`LazyDecay.add`),
and each queue catches up (pops one front per missed tick, at most its length) the
next time it is touched (:meth:`LazyDecay.sync`; a column queue with the others,
:meth:`QueueStore.pop_owed <fsreg_ros.core.memory.queues.QueueStore.pop_owed>`).  Because nothing else
touches a queue in between, the result is
exactly the eager one; the tests compare it against a naive eager implementation on
random event sequences.  :meth:`LazyDecay.now` applies ticks eagerly instead, in
the canonical event order (tick by tick, entity order within a tick), for a
consultant that publishes every event as it happens.

Tick *times* (the schedule, runs of ticks, the ledger) are arithmetic of
:mod:`fsreg_ros.core.memory.ticks`; this module does the pops.
"""

from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from .host import HostBuffer
from .queue import Queue, WMEvent
from .queues import NO_ROWS
from .ticks import TickLedger, TickRun


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
        store = self.wm.store
        q = store.get(entity)
        if q is None and store.in_columns(entity):
            q = store.to_dict(entity)
        if q is not None and q.synced != self.ticks.count:
            self.sync(entity, q)

    def sync(self, entity: str, q: Queue) -> None:
        """Apply the ticks since ``q.synced``: one front pop per tick, each reported at its tick's own time."""
        wm = self.wm
        synced = q.synced
        if not q:  # an empty queue owes nothing (and never needs a tick's time)
            wm.store.sync(q, self.ticks.count)
            return
        wm.changes.record(entity, q)
        sink, watchers = wm.sink, wm.watchers
        if sink is None and not watchers:  # no events to report: just drop the fronts
            wm.store.drop_fronts(entity, q, self.ticks.count)
            return
        victims = wm.store.take_fronts(entity, q, self.ticks.count)  # the fronts, LRU first
        for k, prop in enumerate(victims):
            time = self.ticks.time(synced + k)
            for watcher in watchers:
                watcher.forgot(entity, prop, "decay", time)
            if sink is not None:
                sink(WMEvent("forget", wm.domain, entity, prop, "decay", time, None))

    def settle_columns(self, rows: np.ndarray) -> None:
        """Apply the ticks the column ``rows`` owe (no events: only called without a sink)."""
        if not len(rows):
            return
        wm = self.wm
        popped = wm.store.pop_owed(rows, self.ticks.count)
        wm.store.emptied(rows)
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
        columns = wm.store.columns
        if columns.entities:
            arrays = columns.store
            owing = np.flatnonzero(arrays.held & (arrays.length > 0) & (arrays.synced != count))
            if wm.quiet:
                self.settle_columns(owing)
            else:  # the pops must be reported: those queues become dict queues, caught up below
                for row in owing.tolist():
                    wm.store.to_dict(columns.bound[row])
        get = wm.store.lookup
        for entity in wm.store.nonempty():
            q = get(entity)  # None: a column queue, caught up above
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
        columns = wm.store.columns
        rows = columns.store.non_empty() if columns.entities else NO_ROWS
        pending = [(entity, q) for entity, q in wm.store.dict_queues() if q]
        if wm.quiet and (entity_order is columns.bound or not len(rows)):
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
        store = wm.store
        ticks = self.ticks.count
        if len(rows):
            store.pop_owed(rows, ticks)
            store.emptied(rows)
        rank = store.columns.ranks(entity_order)
        last = len(rank)
        ordered = sorted(pending, key=lambda item: rank.get(item[0], last))
        # Where each dict queue falls among the column rows (in entity order).
        cuts = np.searchsorted(rows, [rank.get(e, last) for e, _ in ordered]).tolist() if len(rows) else []
        start = 0
        for i, (entity, q) in enumerate(ordered):
            if cuts and cuts[i] > start:
                wm.changes.mark_rows(rows[start:cuts[i]])
                start = cuts[i]
            store.drop_fronts(entity, q, ticks, count)  # (flushed: up to date before these ticks)
            wm.changes.record(entity, q)
        wm.changes.mark_rows(rows[start:])

    def _in_order(self, ticks: TickRun, entity_order: Sequence[str], rows: np.ndarray,
                  pending: list[tuple[str, Queue]]) -> None:
        """Pop the ticks' fronts tick by tick, in ``entity_order``, reporting each (the general path).

        The fronts each queue loses are popped first and listed (a column queue's by
        one sort of its slots, then all of theirs at once); the change record and the
        events follow tick by tick in entity order.
        """
        wm = self.wm
        store = wm.store
        columns = store.columns
        count = self.ticks.count
        rank = columns.ranks(entity_order)
        last = len(rank)
        # (rank, tie, entity, fronts it loses LRU first, its dict queue or None for a column queue)
        plan: list[tuple[int, int, str, list[str], Optional[Queue]]] = []
        for tie, (entity, q) in enumerate(pending):
            plan.append((rank.get(entity, last), tie, entity, store.take_fronts(entity, q, count, ticks.count), q))
        if len(rows):
            arrays, names, bound = columns.store, columns.prop_name, columns.bound
            fronts = arrays.in_order(rows, min(ticks.count, arrays.width))
            for row, ids in zip(rows.tolist(), fronts):
                name = bound[row]
                plan.append((rank.get(name, last), len(pending) + row, name, [names[i] for i in ids], None))
            store.pop_owed(rows, count)
            store.emptied(rows)
        plan.sort(key=lambda step: step[:2])
        sink, watchers, domain, changes = wm.sink, wm.watchers, wm.domain, wm.changes
        for i in range(max((len(step[3]) for step in plan), default=0)):
            time = ticks.time(i)
            for _, _, entity, fronts, q in plan:
                if i >= len(fronts):
                    continue
                if i == 0:
                    if q is None:  # a column queue
                        changes.note(entity)
                    else:
                        changes.record(entity, q)
                for watcher in watchers:
                    watcher.forgot(entity, fronts[i], "decay", time)
                if sink is not None:
                    sink(WMEvent("forget", domain, entity, fronts[i], "decay", time, None))
