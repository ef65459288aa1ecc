"""The traces of column queues' entries (rule ``activation``): one per slot, as arrays.

The queues of a large domain's rule 2 and 3 encodings are column queues
(:mod:`fsreg_ros.core.memory.columns`): there each slot keeps its entry's trace
(:class:`TraceColumns`), the encodings of all the calls made at one time and clock
(a REG call's rule-3 encodings) update the traces in one batch, when the traces are
next read or the clock moves on (:meth:`TraceColumns.settle`), and each row keeps a
lower bound of its slots' crossings (so a row with nothing due costs one number to
check).  On an entity's own clock (``activation_clock`` = ``words``,
:mod:`fsreg_ros.core.memory.entity_clock`) each row keeps its entity's clock too
(``own_clocks``): an encoding is noted at its row's clock, which it moves by one, and a
row's crossings are decided at its own clock (every time in its traces is in its units).
Which entries passed their crossing is decided by :meth:`TraceColumns.passed`
(with :mod:`fsreg_ros.core.memory.crossings`).
"""

from __future__ import annotations

import itertools
import math
from typing import Optional, Sequence, Union

import numpy as np

from . import crossings
from .crossings import MARGIN, bracket, gone_by, passages
from .ticks import TIME_EPSILON
from .trace import HISTORY, LONGEST, NEVER, Trace, crossing

#: No column slots.
NO_SLOTS = np.zeros(0, dtype=np.intp)
#: k -> 1/k for k <= HISTORY (index 0 unused): the last of k kept times' share of a lower bound of their mean.
_SHARE = np.array([0.0] + [1.0 / k for k in range(1, HISTORY + 1)])
#: k -> the oldest kept time's share of it, 1 - 1/k.
_KEEP = 1.0 - _SHARE
#: Numbers :attr:`TraceColumns.edit` (unique across stores: a store made anew never repeats an old one's).
_EDITS = itertools.count()


class TraceColumns:
    """The :class:`Trace` of every entry of column queues: one per slot, as arrays (slots x rows).

    Slot (k, r) holds the trace of the entry in slot k of row r (meaningless where that
    slot is empty, whose ``due`` is :data:`NEVER`; an encoding into an empty or
    displaced slot starts a new trace).  ``n`` counts its encodings, ``recent[k, r, i %
    HISTORY]`` is the time of its i-th encoding (from 0; the last :data:`HISTORY` are
    kept), so ``recent[k, r, 0]`` is its first time until the ring wraps; ``first`` keeps
    the first time from then on (n > HISTORY).  ``due`` and ``exact`` are as in
    :class:`Trace`; ``row_due[r]`` is at most the earliest ``due`` of row r (so a row with
    nothing due costs one number to check; :meth:`passed` renews it).  A
    bound found in numpy (:func:`passages`) is kept only as a lower bound a margin below
    it, ``exact`` False: so whether and when an entry goes is decided exactly as for a
    dict queue (see :meth:`passed`).
    """

    def __init__(self, width: int, rows: int, own_clocks: bool = False) -> None:
        self._n = np.zeros((width, rows), dtype=np.int64)
        self._first = np.zeros((width, rows))
        self._recent = _lines((width, rows))  # a slot's ring in one cache line
        self._due = np.full((width, rows), NEVER)
        self._exact = np.zeros((width, rows), dtype=bool)
        self._row_due = np.full(rows, NEVER)  # per row: at most its slots' earliest due
        self._clock = np.zeros(rows) if own_clocks else None  # per row: its entity's own clock
        self._moved = np.full(rows, np.nan) if own_clocks else None  # and the time (seconds) it last moved
        self.edit = next(_EDITS)  # renewed whenever a trace comes in from outside (:meth:`put_row`)
        self.reach_of: Optional[tuple[float, float]] = None
        self._pending: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # encodings not noted yet
        self._ones: list[tuple[int, int]] = []  # and those given one slot at a time (encoded_one): slot, row
        # Encodings on the rows' own clocks not noted yet (:meth:`_own_later`): arrays (slots, present, rows,
        # times), those given one at a time as numbers, how many calls they are, their (span, d), their slots
        self._own: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        self._own_ones: list[tuple[int, bool, int, float]] = []
        self._own_calls = 0
        self._own_of: tuple[float, float] = (0.0, 0.0)
        self._own_slots = np.zeros(0, dtype=bool)
        self._pending_of: tuple[float, float, float] = (0.0, 0.0, 0.0)  # their (time, span, d)
        self.pending_clock = -math.inf  # the clock when they were made
        self._origins: Optional[np.ndarray] = None  # their store's origin references
        self._first_stamp = 0  # the first stamp among them
        self._props: set[int] = set()  # their properties
        self._flatten()

    # Every read or write from outside notes the pending encodings first (:meth:`settle`).
    n = property(lambda self: self.settle() or self._n)
    first = property(lambda self: self.settle() or self._first)
    recent = property(lambda self: self.settle() or self._recent)
    due = property(lambda self: self.settle() or self._due)
    exact = property(lambda self: self.settle() or self._exact)
    row_due = property(lambda self: self.settle() or self._row_due)
    flat_due = property(lambda self: self.settle() or self._flat_due)
    flat_exact = property(lambda self: self.settle() or self._flat_exact)

    def _flatten(self) -> None:
        self._flat_n, self._flat_first, self._flat_recent = self._n.reshape(-1), self._first.reshape(-1), \
            self._recent.reshape(-1)
        self._flat_due, self._flat_exact = self._due.reshape(-1), self._exact.reshape(-1)

    def grow(self, extra: int) -> None:
        """Add ``extra`` rows."""
        self.settle()
        width = self._n.shape[0]
        self._n = np.concatenate([self._n, np.zeros((width, extra), dtype=np.int64)], axis=1)
        self._first = np.concatenate([self._first, np.zeros((width, extra))], axis=1)
        self._recent = _lines((width, self._recent.shape[1] + extra), self._recent)
        self._due = np.concatenate([self._due, np.full((width, extra), NEVER)], axis=1)
        self._exact = np.concatenate([self._exact, np.zeros((width, extra), dtype=bool)], axis=1)
        self._row_due = np.concatenate([self._row_due, np.full(extra, NEVER)])
        if self._clock is not None:
            self._clock = np.concatenate([self._clock, np.zeros(extra)])
            self._moved = np.concatenate([self._moved, np.full(extra, np.nan)])
        self._flatten()

    def widen(self, extra: int) -> None:
        """Add ``extra`` slots to every row."""
        self.settle()
        rows = self._n.shape[1]
        self._n = np.concatenate([self._n, np.zeros((extra, rows), dtype=np.int64)])
        self._first = np.concatenate([self._first, np.zeros((extra, rows))])
        self._recent = _lines((self._recent.shape[0] + extra, rows), self._recent)
        self._due = np.concatenate([self._due, np.full((extra, rows), NEVER)])
        self._exact = np.concatenate([self._exact, np.zeros((extra, rows), dtype=bool)])
        self._flatten()

    @property
    def own_clocks(self) -> bool:
        """Tell whether each row keeps its entity's own clock (else every row reads the rule's one clock)."""
        return self._clock is not None

    def clock_of(self, row: int) -> int:
        """Return row ``row``'s own clock (``own_clocks``): the encodings made into it, as the rule counts them."""
        return int(self._clock[row])

    def moved_of(self, row: int) -> Optional[float]:
        """Return the time (seconds) row ``row``'s own clock last moved (None: not known)."""
        moved = float(self._moved[row])
        return None if math.isnan(moved) else moved

    def set_clocks(self, rows: np.ndarray, clocks: Sequence[int], moved: Sequence[Optional[float]]) -> None:
        """Set the own clocks of ``rows`` and when each last moved (queues moving in; ``own_clocks``)."""
        self._clock[rows] = clocks
        self._moved[rows] = [math.nan if m is None else m for m in moved]

    def get(self, slot: int, row: int) -> Trace:
        """Return slot ``(slot, row)``'s trace as a :class:`Trace`."""
        self.settle()
        return self._trace(slot, row)

    def _trace(self, slot: int, row: int) -> Trace:
        """:meth:`get` of a slot no pending encoding wrote."""
        trace = _ring_trace(int(self._n[slot, row]), float(self._first[slot, row]), self._recent[slot, row].tolist())
        trace.due, trace.exact = float(self._due[slot, row]), bool(self._exact[slot, row])
        return trace

    def row(self, row: int, slots: list[int]) -> list[Trace]:
        """Return the traces of ``slots`` of row ``row`` (as :meth:`get`, reading the row once).

        Encodings on the rows' own clocks pending in other rows stay pending.
        """
        if self._own_calls and not self._own_slots.reshape(-1, self._n.shape[1])[:, row].any():
            self._settle_shared()
        else:
            self.settle()
        ns, firsts = self._n[:, row].tolist(), self._first[:, row].tolist()
        rings, dues, exacts = self._recent[:, row].tolist(), self._due[:, row].tolist(), self._exact[:, row].tolist()
        out = []
        for k in slots:
            trace = _ring_trace(ns[k], firsts[k], rings[k])
            trace.due, trace.exact = dues[k], exacts[k]
            out.append(trace)
        return out

    def put_row(self, row: int, traces: list[Trace]) -> None:
        """Keep ``traces`` in slots 0, 1, ... of row ``row`` (the others are the caller's)."""
        self.settle()
        if not traces:
            return
        k = len(traces)
        rings = []
        for trace in traces:  # encoding i at i % HISTORY (_ring_trace's inverse)
            recent = trace.recent
            if trace.n <= HISTORY:
                rings.append(recent + [0.0] * (HISTORY - len(recent)))
            else:
                turn = HISTORY - (trace.n & (HISTORY - 1))
                rings.append(recent[turn:] + recent[:turn])
        dues = [trace.due for trace in traces]
        self._n[:k, row] = [trace.n for trace in traces]
        self._first[:k, row] = [trace.first for trace in traces]
        self._recent[:k, row] = rings
        self._due[:k, row] = dues
        self._exact[:k, row] = [trace.exact for trace in traces]
        self._row_due[row] = min(self._row_due[row], min(dues))
        self.edit = next(_EDITS)

    def encoded(self, flat: np.ndarray, present: np.ndarray, time: float, span: float, d: float,
                rows: Optional[np.ndarray] = None, clock: float = -math.inf,
                origins: Optional[np.ndarray] = None, stamp: int = 0, prop: int = -1) -> None:
        """Note one encoding at ``time`` in each slot ``flat`` (flat index; of ``rows``): a refresh where ``present``.

        ``span`` is one encoding's :func:`lifetime` under decay ``d``; ``clock`` the
        activation clock then.  Noted lazily: the encodings of the calls made at one time
        and clock (a REG call's rule-3 encodings) are noted together, by the first read or
        write of the traces from outside (:meth:`settle`) or :meth:`LazyActivation.passed`
        at a later clock.  Until then a slot keeps its previous ``due``: after the queue
        lost whatever was due at that clock (see :meth:`passed`), none is.
        The arrays given are kept: the caller does not change them.

        ``origins`` (the store's array of each slot's origin reference, slots x rows, as
        it is after this encoding), ``stamp`` (this encoding's first stamp) and ``prop`` (its
        property id) let the calls of one batch encode a slot more than once (a row
        displacing its own new entry): a batch holds each property once, so a slot is
        refreshed at most once in it, before any displacement, and its entry at the end is
        new exactly when its origin is a stamp of the batch (:meth:`settle`).  Without
        them, each call is a batch of its own.

        ``time`` None (``own_clocks``): each row's encoding is at the row's own clock,
        which it moves by one now (``rows`` distinct), at ``clock`` (seconds); noted later
        (:meth:`_own_later`).
        """
        if time is None:
            rows = flat % self._n.shape[1] if rows is None else rows
            self._own_later(flat, span, d)
            times = self._clock.take(rows)
            self._clock[rows] = times + 1.0
            self._moved[rows] = clock
            self._own.append((flat, present, rows, times))
            return
        self._join(time, span, d, clock, origins, stamp, prop, False)
        self._pending.append((flat, present, flat % self._n.shape[1] if rows is None else rows))

    def encoded_one(self, flat: int, row: int, time: float, span: float, d: float, clock: float,
                    origins: np.ndarray, stamp: int, prop: int, fresh: bool) -> None:
        """As :meth:`encoded` for one slot given as Python numbers (:meth:`QueueColumns.encode_one`: rule 1).

        Whether it is a refresh is told by its origin when the batch is noted (:meth:`settle`).
        ``fresh``: the slot is not one the batch wrote and refreshed here (:meth:`pending_since`),
        so it joins whatever its property (a new entry displacing one the batch wrote is
        noted as new wherever it recurs).
        """
        self._join(time, span, d, clock, origins, stamp, prop, fresh)
        self._ones.append((flat, row))

    def _join(self, time: float, span: float, d: float, clock: float, origins: Optional[np.ndarray], stamp: int,
              prop: int, fresh: bool) -> None:
        """Settle the pending batch if the next encoding cannot join it (:meth:`encoded`); start one if none."""
        pending = self._pending or self._ones
        if pending and (self._pending_of != (time, span, d) or clock != self.pending_clock
                        or origins is None or origins is not self._origins or (prop in self._props and not fresh)):
            self.settle()
            pending = False
        if not pending:
            self._pending_of, self.pending_clock = (time, span, d), clock
            self._origins, self._first_stamp, self._props = origins, stamp, set()
        self._props.add(prop)

    def encoded_own(self, flat: int, row: int, present: bool, span: float, d: float, clock: float) -> None:
        """As :meth:`encoded` with ``time`` None for one slot given as numbers (:meth:`QueueColumns.encode_one`)."""
        self._own_later(flat, span, d)
        time = float(self._clock[row])
        self._clock[row] = time + 1.0
        self._moved[row] = clock
        self._own_ones.append((flat, present, row, time))

    def _own_later(self, flat, span: float, d: float) -> None:
        """Make room for one more call's encodings on the rows' own clocks in the pending ones (slots ``flat``).

        They are noted together (one :meth:`_note`) by the next read or write of the
        traces from outside (:meth:`settle`), by :meth:`passed` when a row may have
        something due, or first if a slot of theirs was written already (noted in order)
        or (span, d) changed.  Until then each slot keeps its previous ``due``, and the
        rows their bound, which :meth:`passed` and :meth:`row_due_by` may still read alone:
        a refreshed entry's crossing only comes later for the new presentation (its old
        one was after the clock: the queue lost what was due first); a displaced entry's
        bound is one more slot that may be due (read, the batch is noted first); and a new
        entry noted at time m is due at m + span, its row's clock at most m plus the calls
        pending, so none is due while span passes their number (else they are noted first:
        :meth:`_own_soon`).
        """
        slots = self._own_slots
        if slots.size != self._flat_n.size:
            slots = self._own_slots = np.zeros(self._flat_n.size, dtype=bool)  # (after a settle: none marked)
        if self._own_calls and (self._own_of != (span, d) or slots[flat].any()):
            self.settle()
        slots[flat] = True
        self._own_of = (span, d)
        self._own_calls += 1

    def _own_soon(self) -> bool:
        """Tell whether an encoding on the rows' own clocks not noted yet may be due (:meth:`_own_later`)."""
        return bool(self._own_calls) and self._own_of[0] <= self._own_calls + TIME_EPSILON

    def pending_since(self, stamp: int) -> bool:
        """Tell whether an entry stamped ``stamp`` may have been encoded in the pending batch (stamps only grow)."""
        return bool(self._pending or self._ones) and stamp >= self._first_stamp

    def forget_slots(self, flat: np.ndarray) -> None:
        """Make slots ``flat`` (flat indices) never due: their entries left.

        The pending encodings are noted first unless none of them is on the rows' own
        clocks in these slots (the slots a crossing emptied are never pending ones: :meth:`passed`).
        """
        if self._pending or self._ones or self._own_calls and self._own_slots[flat].any():
            self.settle()
        self._flat_due[flat] = NEVER

    def settle(self) -> None:
        """Note the pending encodings (:meth:`encoded`, :meth:`encoded_one`, on own clocks) as one batch."""
        if self._own_calls:
            own = self._own
            if self._own_ones:
                flats, present, rows, times = zip(*self._own_ones)
                own.append((np.array(flats, dtype=np.intp), np.array(present), np.array(rows, dtype=np.intp),
                            np.array(times)))
            self._own, self._own_ones, self._own_calls = [], [], 0
            flat = np.concatenate([o[0] for o in own]) if len(own) > 1 else own[0][0]
            self._own_slots[flat] = False
            if len(own) == 1:
                self._note(*own[0], *self._own_of)
            else:
                self._note(flat, *(np.concatenate([o[k] for o in own]) for k in (1, 2, 3)), *self._own_of)
        self._settle_shared()

    def _settle_shared(self) -> None:
        """Note the pending encodings made at one clock (:meth:`encoded`, :meth:`encoded_one`) as one batch."""
        pending, ones = self._pending, self._ones
        if not (pending or ones):
            return
        self._pending, self._ones = [], []
        time, span, d = self._pending_of
        if len(pending) == 1 and not ones:
            self._note(*pending[0], time, span, d)
            return
        if ones:
            flats, rows = zip(*ones)
            pending.append((np.array(flats, dtype=np.intp), None, np.array(rows, dtype=np.intp)))
        # A slot's entry at the end is a refresh (once) if it entered before the batch, else new
        # however often its slot was written: every place a slot recurs notes the same thing.
        flat = np.concatenate([p[0] for p in pending])
        present = np.take(self._origins.reshape(-1), flat) < self._first_stamp
        self._note(flat, present, np.concatenate([p[2] for p in pending]), time, span, d)

    def _note(self, flat: np.ndarray, present: np.ndarray, rows: np.ndarray, time: Union[float, np.ndarray],
              span: float, d: float) -> None:
        """Note one encoding at ``time`` in each slot ``flat`` (``rows`` may recur; a slot only as a new entry).

        A slot recurs (:meth:`settle`) only where each place notes a new entry: the same
        writes, in whatever order numpy makes them.

        A new entry's ``due`` is its crossing; a refreshed one's a lower bound of it: the
        later of ``time + span`` (the last term alone) and ``m + k^(1/d) span``, less
        :data:`MARGIN`.  There the k = min(n, :data:`HISTORY`) kept times, the oldest
        t_o and the last ``time``, have a mean of at least m = t_o + (time - t_o) / k,
        and x^-d is convex: their terms alone sum to at least k (t - m)^-d, and the
        Petrov term of older presentations only adds to them.  Leaving that term out,
        the bound needs no look at how well :func:`crossing` rounds it, and costs the
        same few array operations for every slot (in a long session most are past
        HISTORY encodings).  ``time`` may be one per slot (rows on their own clocks).
        """
        n, recent = self._flat_n, self._flat_recent
        old = n[flat]
        old *= present  # encodings before this one (a new entry: none)
        counts = old + 1
        n[flat] = counts
        at = flat * HISTORY
        wraps = flat[counts == HISTORY + 1]  # the first time leaves the ring: keep it (crossing()'s Petrov term)
        if len(wraps):
            self._flat_first[wraps] = recent[wraps * HISTORY]
        old &= HISTORY - 1
        old += at
        recent[old] = time
        oldest = counts - HISTORY  # the oldest kept encoding's place in the ring: max(n - HISTORY, 0) % HISTORY
        np.maximum(oldest, 0, out=oldest)
        oldest &= HISTORY - 1
        oldest += at
        begin = np.take(recent, oldest)  # (k = min(n, HISTORY))
        k = np.minimum(counts, HISTORY)
        begin *= _KEEP.take(k)
        if isinstance(time, np.ndarray):  # per slot: the table at time 0, shifted slot by slot
            begin += self._bounds(d, span, 0.0).take(k) + time * _SHARE.take(k) - MARGIN * np.abs(time)
        else:
            begin += self._bounds(d, span, time).take(k)  # m + reach[k], m = t_o + (time - t_o) / k
        due = np.maximum(begin, time + span)  # (reach[1] < span)
        self._flat_due[flat] = due
        self._flat_exact[flat] = ~present
        np.minimum.at(self._row_due, rows, due)  # (rows recur in a batch)

    def _bounds(self, d: float, span: float, time: float) -> np.ndarray:
        """Return the table ``add`` of :meth:`_note`'s bound ``t_o _KEEP[k] + add[k]`` at ``time``.

        That is ``m + reach[k]`` for k <= :data:`HISTORY` kept times, the oldest t_o:
        m = t_o + (time - t_o) / k, and reach[k] = ``k^(1/d) span`` less a margin,
        ``MARGIN (1 + |time| + k^(1/d) span)``, which keeps the bound below
        :func:`crossing`'s own root (within 1e-13 of that size of the true one).  Made
        once per (d, span) and shifted once per encoding time.
        """
        if self.reach_of != (d, span):
            reach = [-math.inf]
            for k in range(1, HISTORY + 1):
                try:
                    reach.append(k ** (1.0 / d) * span * (1.0 - MARGIN))
                except OverflowError:
                    reach.append(math.inf)
            self.reach, self.reach_of, self.shifted_at = np.array(reach), (d, span), None
        if self.shifted_at != time:
            self.shifted = time * _SHARE + self.reach - MARGIN * (1.0 + abs(time))
            self.shifted_at = time
        return self.shifted

    def ordered(self, flat: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return the counts, first times and kept times of ``flat``.

        The times are a (k x len(flat)) array, oldest first, k the most any of them keeps;
        unused places hold -inf.
        """
        self.settle()
        return self._ordered(flat)

    def _ordered(self, flat: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`ordered` of slots no pending encoding wrote."""
        n = np.take(self._flat_n, flat)
        kept = np.minimum(n, HISTORY)
        start = n - kept  # index of the oldest encoding kept
        depth = int(kept.max(initial=1))
        times = np.full((depth, len(flat)), -np.inf)
        recent = self._flat_recent
        at = flat * HISTORY
        for j in range(depth):
            use = j < kept
            times[j, use] = np.take(recent, (start[use] + j) % HISTORY + at[use])
        first = np.where(n > HISTORY, np.take(self._flat_first, flat), np.take(recent, at))
        return n, first, times

    def row_due_by(self, row: int, clock: Optional[float]) -> bool:
        """Tell whether something of row ``row`` may be due at ``clock`` (its bound: one number; None: its own clock).

        At the clock they were made at, encodings not noted yet are not due (so they stay pending).
        """
        if clock is None:  # (own clocks: what is pending is noted first only if it may be due)
            clock = self._clock[row]
            if self._own_soon():
                self.settle()
        elif clock != self.pending_clock:
            self.settle()
        return bool(self._row_due[row] <= clock + TIME_EPSILON)

    def passed(self, rows: np.ndarray, used: int, clock: Optional[float], d: float, tau: float,
               span: float) -> np.ndarray:
        """Return the slots (flat indices) of ``rows`` whose entry's crossing is at or before ``clock``.

        ``clock`` None (``own_clocks``): each row's own clock.

        ``used``: the slots ever written in any row (slots beyond are never due); ``d``,
        ``tau`` and ``span`` the rule's decay, threshold and one encoding's lifetime.
        Decided exactly as :meth:`LazyActivation.sync
        <fsreg_ros.core.memory.activation.LazyActivation.sync>` decides for a dict queue:
        a slot whose lower bound passed is decided in numpy
        (:func:`~fsreg_ros.core.memory.crossings.passages`, all at once) or, for a few,
        one by one (:func:`~fsreg_ros.core.memory.crossings.bracket`,
        :func:`~fsreg_ros.core.memory.crossings.gone_by`); a crossing within
        :data:`~fsreg_ros.core.memory.crossings.MARGIN` of the clock, or one
        :func:`~fsreg_ros.core.memory.crossings.passages` leaves out, is solved by
        :func:`~fsreg_ros.core.memory.trace.crossing` itself.  A slot that stays keeps a
        new lower bound.
        """
        if not len(rows):
            return NO_SLOTS
        if clock is None:  # (own clocks: what is pending is noted first only if it may be due, or once read)
            if self._own_soon():
                self.settle()
            now = self._clock.take(rows) + TIME_EPSILON
        else:
            now = clock + TIME_EPSILON
            if clock != self.pending_clock:
                self.settle()  # (at the clock they were made at, encodings not noted yet are not due)
        soon = self._row_due.take(rows)
        due_rows = soon <= now
        if not due_rows.any():  # one number per row: most calls end here
            return NO_SLOTS
        rows = rows.compress(due_rows)
        width = max(used, 1)  # (slots never used are never due)
        all_rows = self._n.shape[1]
        due = self._due[:width].take(rows, axis=1)
        if clock is None:
            now = now.compress(due_rows)
            if self._own_calls:  # pending ones are not due (:meth:`_own_later`); settle adds them to the bounds
                due[self._own_slots.reshape(-1, all_rows)[:width].take(rows, axis=1)] = NEVER
        at = np.flatnonzero(due <= now)  # places in ``due`` (an empty slot's due is NEVER)
        starts = np.arange(0, width * all_rows, all_rows)[:, None]  # each slot's flat index in row 0
        flat = (starts + rows).reshape(-1).take(at)  # (a 2-D nonzero would cost four times more)
        vague = ~self._flat_exact.take(flat)
        if vague.any():
            unsure = flat[vague]
            now_unsure = now if clock is not None else now.take(at[vague] % len(rows))  # (each slot's row's)
            self._solve(unsure, now_unsure, d, tau, span)
            renewed = self._flat_due.take(unsure)
            due.reshape(-1)[at[vague]] = renewed
            staying = renewed > now_unsure
            at = np.concatenate((at[~vague], at[vague][~staying]))
            flat = np.concatenate((flat[~vague], unsure[~staying]))
        # The rows' bounds anew, the slots passed left out (they go, or their queue becomes a dict queue).
        due.reshape(-1)[at] = NEVER
        self._row_due[rows] = due.min(axis=0)
        return flat

    def _solve(self, flat: np.ndarray, now: Union[float, np.ndarray], d: float, tau: float, span: float) -> None:
        """Decide the slots ``flat`` whose lower bound passed ``now``: a new bound or the crossing (:meth:`passed`).

        ``now``: one clock, or one per slot (rows on their own clocks; none of ``flat`` pending).
        """
        self._settle_shared()
        due, exact = self._flat_due, self._flat_exact
        if span > LONGEST:
            due[flat], exact[flat] = NEVER, True
            return
        width_rows = self._n.shape[1]
        if len(flat) <= crossings.FEW:  # one by one is cheaper for a few (read as Python numbers at once)
            rings = self._recent.reshape(-1, HISTORY).take(flat, axis=0).tolist()
            nows = now.tolist() if isinstance(now, np.ndarray) else [now] * len(flat)
            for f, n, first, ring, at in zip(flat.tolist(), self._flat_n.take(flat).tolist(),
                                             self._flat_first.take(flat).tolist(), rings, nows):
                trace = _ring_trace(n, first, ring)
                found = bracket(n, trace.recent, at, d, span)
                if found is None:
                    gone, bound = gone_by(trace, at, d, tau)
                    if gone:  # (its bound stays: at most the clock)
                        continue
                    found = (bound, False) if bound is not None else (crossing(trace, d, tau), True)
                due[f], exact[f] = found
            return
        n, first, times = self._ordered(flat)
        gone, bound = passages(n, first, times, d, tau, now)
        staying = bound > -np.inf
        later = bound[staying]
        due[flat[staying]] = later - MARGIN * np.maximum(1.0, np.abs(later))  # a lower bound of crossing()'s root
        # (what went keeps its bound, at most the clock; too close to call: crossing() itself)
        for f in flat[~(gone | staying)].tolist():
            trace = self._trace(f // width_rows, f % width_rows)
            due[f], exact[f] = crossing(trace, d, tau), True


def _ring_trace(n: int, first: float, ring: list[float]) -> Trace:
    """Return the :class:`Trace` of ``n`` encodings kept in ``ring`` (encoding i at ``i % HISTORY``).

    ``first`` is the first time, read only once the ring has wrapped (n > HISTORY);
    ``due`` and ``exact`` are the caller's.
    """
    if n <= HISTORY:
        kept = ring[:n]
    else:  # encoding n - HISTORY + j is at (n + j) % HISTORY
        turn = n & (HISTORY - 1)
        kept = ring[turn:] + ring[:turn]
    trace = Trace(first if n > HISTORY else ring[0])
    trace.n, trace.recent = n, kept
    return trace


def _lines(shape: tuple[int, int], old: Optional[np.ndarray] = None) -> np.ndarray:
    """Return zeros of ``shape`` x :data:`HISTORY` floats, each ring on one 64-byte cache line (``old`` copied in).

    numpy aligns an array to 16 bytes only: a ring starting elsewhere than a line's start
    would span two lines, and noting an encoding would touch both.
    """
    size = shape[0] * shape[1] * HISTORY
    raw = np.zeros(size + HISTORY)
    skip = (-raw.ctypes.data % 64) // raw.itemsize
    lines = raw[skip:skip + size].reshape(*shape, HISTORY)
    if old is not None:
        lines[:old.shape[0], :old.shape[1]] = old
    return lines
