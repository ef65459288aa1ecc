"""ACT-R base-level activation as a forgetting rule (rule ``activation``): the clock and lazy pops.

Each entry of WM keeps its encoding history (a :class:`~fsreg_ros.core.memory.trace.Trace`;
the arithmetic, :func:`~fsreg_ros.core.memory.trace.crossing` included, is
:mod:`fsreg_ros.core.memory.trace`), and is forgotten at its *crossing time* c, when
its activation falls below the threshold (cause ``activation``, event time c),
before any event stamped c, as a decay tick is.

Nothing is computed per tick: a buffer pops an entry lazily, when its queue is next
touched at or after c (:class:`LazyActivation`), the way lazy decay pops owed fronts,
so the clock costs nothing while no queue is touched.  Nor is c solved at every
encoding: an encoding at t only sets the lower bound ``t + exp(-tau / d)`` (the last
term alone keeps activation above tau until then; for one encoding it is c itself),
and c is solved (:func:`crossing`, a few Newton steps on the logarithm of the age
c - t_n, Petrov's term written without cancellation) once the clock passes that
bound, if the entry was not encoded again meanwhile.  An entry refreshed more often
than its lifetime is never solved for.

Column queues keep their entries' traces as arrays
(:mod:`fsreg_ros.core.memory.trace_columns`), and the rows encoded again at one clock
are not checked again (:meth:`LazyActivation.forget_members`).
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from .columns import QueueColumns
from .host import HostBuffer
from .queue import Queue
from .ticks import TIME_EPSILON
from .trace import NEVER, Trace, crossing, lifetime
from .trace_columns import NO_SLOTS


class LazyActivation:
    """One buffer's activation rule: the clock, each entry's :class:`Trace`, lazy pops at crossing times.

    ``clock`` is the latest time the buffer was told (:meth:`WMBuffer.advance`, and
    every encoding's or forgetting's own time).  ``traces[entity][prop]`` is the trace
    of each entry of Q[entity]; ``due[entity]`` is at most the earliest crossing among
    them (so a touched queue with nothing due costs one lookup).  Kept here, not in the
    queues, so the other rules' hot paths carry nothing for it.
    """

    #: The clock the rule counts on (:mod:`fsreg_ros.core.memory.entity_clock` has the others).
    counting = "seconds"

    def __init__(self, wm: HostBuffer, decay: float, threshold: float, clock: float) -> None:
        self.wm = wm
        self.decay, self.threshold = decay, threshold
        self.span = lifetime(decay, threshold)  # one encoding's stay; NEVER-long spans give inf
        self.clock = clock
        self.settled = -math.inf  # the clock every queue was last brought up to (flush)
        self.traces: dict[str, dict[str, Trace]] = {}
        self.due: dict[str, float] = {}
        self.swept: tuple[Optional[tuple[float, int]], int] = (None, 0)  # (clock, traces' edit), member rows

    def advance(self, time: float) -> None:
        """Note that the clock reached ``time`` (it never goes back)."""
        if time > self.clock:
            self.clock = time

    def now_of(self, entity: str) -> float:
        """Return the time Q[entity]'s traces are read at: the buffer's clock (one clock for every entity)."""
        return self.clock

    def clocks(self) -> dict[str, int]:
        """Return the per-entity clocks a store keeps beside the episode log (none on the seconds clock)."""
        return {}

    def restore_clocks(self, words: dict[str, int]) -> None:
        """Take back :meth:`clocks`'s dict (nothing on the seconds clock)."""

    def adopt(self, entity: str, q: Queue, time: float, traces: Optional[dict[str, Trace]] = None) -> None:
        """Take Q[entity] under the rule: ``traces`` kept (e.g. restored), one encoding at ``time`` for the others."""
        mine = self.traces[entity] = {}
        for prop in q:
            trace = (traces or {}).get(prop)
            mine[prop] = trace = trace if trace is not None else Trace(time)
            trace.due, trace.exact = trace.recent[-1] + self.span, trace.n == 1
        self._refresh(entity)

    def record(self, entity: str, prop: str, time: float, present: bool) -> None:
        """Note an encoding of ``prop`` into Q[entity] at ``time`` (``present``: a refresh).

        An encoding stamped before the clock (a late message) counts at the clock: an
        entry's encoding times never go back.
        """
        self.note(entity, prop, max(time, self.clock), present)

    def note(self, entity: str, prop: str, time: float, present: bool) -> None:
        """Note an encoding of ``prop`` into Q[entity] at ``time`` on the rule's clock (:meth:`record`'s work)."""
        traces = self.traces.get(entity)
        if traces is None:
            traces = self.traces[entity] = {}
        trace = traces.get(prop) if present else None
        if trace is None:
            trace = traces[prop] = Trace(time)
            trace.exact = True
        else:
            trace.add(time)
            trace.exact = False
        due = trace.due = time + self.span  # the crossing (one encoding) or a lower bound of it
        if due < self.due.get(entity, NEVER):
            self.due[entity] = due

    def forget(self, entity: str, prop: str) -> None:
        """Drop the trace of an entry that left Q[entity] (any cause); ``due`` may stay early (harmless)."""
        traces = self.traces.get(entity)
        if traces is not None:
            traces.pop(prop, None)

    def sync(self, entity: str, q: Queue) -> None:
        """Forget the entries of ``q`` whose crossing is at or before the clock, in crossing order (ties: LRU first)."""
        self.forget_crossed(entity, q, self.clock + TIME_EPSILON, None)

    def forget_crossed(self, entity: str, q: Queue, now: float, when: Optional[float]) -> None:
        """Forget the entries of ``q`` whose crossing is at or before ``now`` (:meth:`sync`'s work).

        Each forgetting is an event at ``when`` (None: at the entry's crossing itself, as on
        the buffer's seconds clock).
        """
        if self.due.get(entity, NEVER) > now:
            return
        traces = self.traces[entity]
        gone = []
        for i, prop in enumerate(q):
            trace = traces[prop]
            if trace.due <= now:
                if not trace.exact:  # only a lower bound passed: solve for the crossing itself
                    trace.due, trace.exact = crossing(trace, self.decay, self.threshold), True
                if trace.due <= now:
                    gone.append((trace.due, i, prop))
        gone.sort()
        for due, _, prop in gone:
            self.wm.forget_entry(entity, q, prop, "activation", due if when is None else when, None)
        self._refresh(entity)

    def flush(self) -> None:
        """Bring every queue up to the clock (nothing to do when it has not moved since the last flush)."""
        if self.settled == self.clock:
            return
        now = self.clock + TIME_EPSILON
        store = self.wm.store
        self.flush_columns()
        for entity in [e for e, due in self.due.items() if due <= now]:
            q = store.get(entity)
            if q is not None:
                self.sync(entity, q)
        self.settled = self.clock

    # ------------------------------------------------------------ column queues
    def flush_columns(self) -> list[str]:
        """Bring the column queues up to their clock (:meth:`flush`'s part for them).

        Without a listener what crossed goes at once; with one (it must hear what went)
        the rows that lost something become dict queues, returned (the caller brings them up).
        """
        store = self.wm.store
        columns = store.columns
        moved: list[str] = []
        if columns.entities and columns.store.traces is not None:
            rows = columns.store.non_empty()
            if self.wm.quiet:
                self.settle_columns(rows)
            else:
                arrays = columns.store
                for row in np.unique(self.passed(arrays, rows) % arrays.rows).tolist():  # (in row order)
                    moved.append(columns.bound[row])
                    store.to_dict(moved[-1])
        return moved

    def release_clocks(self, entities: list[str]) -> Optional[tuple[list[int], list[Optional[float]]]]:
        """Return None: the seconds clock is one for all entities (no clock moves with a queue)."""
        return None

    def take_clock(self, entity: str, clock: int, moved: Optional[float]) -> None:
        """Keep nothing (the seconds clock is one for all entities)."""

    def carry_clocks(self, old: "LazyActivation") -> None:
        """Take over the per-entity clocks of ``old``, the rule this one replaces on the same clock (none here)."""

    def column_clock(self) -> Optional[float]:
        """Return the clock column rows are read and noted at (None: each row's own, :mod:`.entity_clock`)."""
        return self.clock

    def release(self, entity: str) -> dict[str, Trace]:
        """Hand over the traces of Q[entity] (moving to the column queues); this rule keeps them no longer."""
        self.due.pop(entity, None)
        return self.traces.pop(entity, {})

    def take(self, entity: str, traces: dict[str, Trace]) -> None:
        """Keep ``traces``, those of Q[entity] (back from the column queues)."""
        self.traces[entity] = traces
        self._refresh(entity)

    def traces_of(self, entity: str) -> dict[str, Trace]:
        """Return the traces of the entries of the dict queue Q[entity] (none: empty)."""
        return self.traces.get(entity, {})

    def passed(self, store: QueueColumns, rows: np.ndarray) -> np.ndarray:
        """Return the slots (flat indices) of column ``rows`` whose entry's crossing is at or before the clock.

        Decided exactly as :meth:`sync` decides for a dict queue
        (:meth:`~fsreg_ros.core.memory.trace_columns.TraceColumns.passed`).
        """
        return store.traces.passed(rows, store.used, self.column_clock(), self.decay, self.threshold, self.span)

    def forget_members(self, rows: np.ndarray, members: int) -> None:
        """Before encoding into the column rows ``rows`` (bitset ``members``), forget what is due there.

        As :meth:`forget_rows`, skipped when every member was brought up to this clock
        already and nothing came into the columns since (:attr:`TraceColumns.edit`): the
        rules 2 and 3 encodings of one REG call or resolution turn are made at one
        clock, each into a subset of the rows before, and what they encoded is not due
        before the clock plus a lifetime (encodings count at the clock at the earliest).
        Only for a lifetime that takes them past the clock's
        :data:`~fsreg_ros.core.memory.ticks.TIME_EPSILON`.
        """
        traces = self.wm.store.columns.store.traces
        now = self.clock
        at = (now, traces.edit) if now + self.span > now + TIME_EPSILON else None
        then, swept = self.swept
        if at is not None and at == then and not members & ~swept:
            return
        self.forget_rows(rows)
        self.swept = (at, (swept if at == then else 0) | members) if at is not None else (None, 0)

    def forget_row(self, row: int) -> None:
        """As :meth:`forget_rows` for one column row, its bound checked first as one number (most rows: nothing due)."""
        if self.wm.store.columns.store.traces.row_due_by(row, self.column_clock()):
            self.forget_rows(np.array([row]))

    def noting(self) -> tuple[Optional[float], float, float, Optional[float]]:
        """Return ``(time, lifetime, d, clock)`` of an encoding made now, as column queues note it.

        An encoding counts at the clock at the earliest (:meth:`record`), and the clock
        has reached the encoding's time (:meth:`advance`).  None, None: at each row's own
        clock, which the encoding moves, at the seconds clock (:meth:`column_clock`).
        """
        clock = self.column_clock()
        return clock, self.span, self.decay, self.clock if clock is None else clock

    def forget_rows(self, rows: np.ndarray) -> np.ndarray:
        """Forget (no events) the entries of column ``rows`` whose crossing passed; return the rows that lost some.

        A row may recur in the result.  The store keeps its size; its non-empty set and
        the change record are the caller's.
        """
        store = self.wm.store
        flat = self.passed(store.columns.store, rows)
        if not len(flat):
            return NO_SLOTS
        return store.clear_slots(flat)

    def settle_columns(self, rows: np.ndarray) -> None:
        """Bring column ``rows`` up to the clock (no events: only called without a sink)."""
        if not len(rows):
            return
        owners = self.forget_rows(rows)
        if len(owners):
            self.wm.store.emptied(owners)
            self.wm.changes.mark_rows(owners)

    def _refresh(self, entity: str) -> None:
        traces = self.traces.get(entity)
        if traces:
            self.due[entity] = min(t.due for t in traces.values())
        else:
            self.traces.pop(entity, None)
            self.due.pop(entity, None)
