"""ACT-R base-level activation as a forgetting rule (rule ``activation``): traces, crossing times, lazy pops.

An entry (e, p) of WM keeps the times t_1 <= ... <= t_n of the encodings of p into
Q[e] since p entered Q[e] (the entering encoding and every refresh; a forgotten
property's history goes with it).  Its base-level activation at time t > t_n is

    A(t) = ln sum_j (t - t_j)^(-d)

(Anderson & Lebiere 1998; d = ``activation_decay``).  A(t) decreases strictly from
+inf to -inf between encodings, so it crosses the threshold tau
(``activation_threshold``) exactly once: at the *crossing time* c, the unique
t > t_n with A(t) = tau.  The entry is forgotten at c (cause ``activation``, event
time c), before any event stamped c, as a decay tick is.  With one encoding,
c = t_1 + exp(-tau / d) (:func:`lifetime`).

A :class:`Trace` keeps the count n, the first time t_1 and the last
:data:`HISTORY` times exactly; beyond that, the older presentations are
approximated as spread evenly between t_1 and the oldest time kept (Petrov 2006,
"Computationally efficient approximation of the base-level learning equation in
ACT-R", eq. 4; exact while n <= HISTORY).

Nothing is computed per tick: a buffer pops an entry lazily, when its queue is next
touched at or after c (:class:`LazyActivation`), the way lazy decay pops owed fronts,
so the clock costs nothing while no queue is touched.  Nor is c solved at every
encoding: an encoding at t only sets the lower bound ``t + exp(-tau / d)`` (the last
term alone keeps activation above tau until then; for one encoding it is c itself),
and c is solved (:func:`crossing`, a few Newton steps on the logarithm of the age
c - t_n, Petrov's term written without cancellation) once the clock passes that
bound, if the entry was not encoded again meanwhile.  An entry refreshed more often
than its lifetime is never solved for.

The queues of a large domain's rule 2 and 3 encodings are column queues
(:mod:`fsreg_ros.core.memory.columns`): there each slot keeps its entry's trace
(:class:`TraceColumns`), the encodings of all the calls made at one time and clock
(a REG call's rule-3 encodings) update the traces in one batch, when the traces are
next read or the clock moves on (:meth:`TraceColumns.settle`), each row keeps a lower
bound of its slots' crossings (so a row with nothing due costs one number to check),
and the entries of many rows whose bound passed are solved at once (:func:`crossings`,
Newton's method in numpy).  numpy's ``pow`` is not Python's, so a numpy root is only
kept as a lower bound a hair (:data:`_MARGIN`) below it; where the clock falls within
that hair, :func:`crossing` itself decides, so an entry goes exactly when it would
from a dict queue (:meth:`LazyActivation.passed`; test_core_fast_paths).
"""

from __future__ import annotations

import math
from typing import Any, Optional

import numpy as np

from ..decay import TIME_EPSILON
from .host import HostBuffer
from .limits import Limits
from .queue import Queue

#: Encoding times an entry keeps exactly (the Petrov approximation covers older ones; a power of 2).
HISTORY = 8
#: No crossing (an entry that never falls below the threshold within the clock's range).
NEVER = math.inf
#: Crossings further than this after the last encoding are :data:`NEVER` (decay.MAX_TIME).
_LONGEST = 1e12
#: The crossing time is solved to this relative precision (of the logarithm of its age).
_PRECISION = 1e-15
#: ln(_LONGEST).
_LOG_LONGEST = math.log(_LONGEST)
#: No column slots.
_NO_SLOTS = np.zeros(0, dtype=np.intp)


class Trace:
    """One entry's encoding history: count ``n``, ``first`` time, the last :data:`HISTORY` times; crossing ``due``."""

    __slots__ = ("n", "first", "recent", "due", "exact")

    def __init__(self, time: float) -> None:
        self.n = 1
        self.first = time
        self.recent = [time]
        self.due = NEVER
        self.exact = False  # due is the crossing itself (else a lower bound of it)

    def add(self, time: float) -> None:
        """Note one more encoding at ``time`` (not before the last one)."""
        self.n += 1
        self.recent.append(time)
        if len(self.recent) > HISTORY:
            del self.recent[0]

    def strength(self, t: float, d: float) -> float:
        """Return sum_j (t - t_j)^(-d) at ``t`` (> every encoding time), older presentations approximated."""
        total = 0.0
        for r in self.recent:
            total += (t - r) ** -d
        older = self.n - len(self.recent)
        if older > 0:
            oldest = self.recent[0]
            total += _older_terms(older, t - oldest, oldest - self.first, d)[0]
        return total

    def strength_at_age(self, age: float, d: float) -> tuple[float, float]:
        """Return :meth:`strength` ``age`` after the last encoding and its derivative there (negative).

        The ages are ``age`` plus each encoding's distance from the last one, so a small
        ``age`` keeps its own precision however large the times are.
        """
        last = self.recent[-1]
        total = slope = 0.0
        for r in self.recent:
            since = age + (last - r)
            term = since ** -d
            total += term
            slope -= d * term / since
        older = self.n - len(self.recent)
        if older > 0:
            oldest = self.recent[0]
            term, dterm = _older_terms(older, age + (last - oldest), oldest - self.first, d)
            total += term
            slope += dterm
        return total, slope

    def to_json(self) -> list:
        """Return ``[n, first, recent...]`` (what a store keeps)."""
        return [self.n, self.first, *self.recent]

    @classmethod
    def from_json(cls, data: object) -> "Trace":
        """Rebuild a trace from :meth:`to_json`'s list; ValueError if malformed."""
        if (not isinstance(data, (list, tuple)) or len(data) < 3 or len(data) > HISTORY + 2
                or isinstance(data[0], bool) or not isinstance(data[0], int) or data[0] < len(data) - 2
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                           for x in data[1:])
                or any(a > b for a, b in zip(data[1:], data[2:]))):
            raise ValueError(f"activation trace {data!r} is not [count, first time, recent times...] in order")
        trace = cls(float(data[1]))
        trace.n, trace.recent = data[0], [float(x) for x in data[2:]]
        return trace


def activation(trace: Trace, t: float, d: float) -> float:
    """Return the entry's base-level activation ln sum_j (t - t_j)^(-d) at ``t`` (+inf at an encoding time)."""
    if t <= trace.recent[-1]:
        return math.inf
    return math.log(trace.strength(t, d))


def lifetime(d: float, tau: float) -> float:
    """Return how long one encoding stays above the threshold: exp(-tau / d) (inf if it overflows)."""
    try:
        return math.exp(-tau / d)
    except OverflowError:
        return math.inf


def _older_terms(older: int, age: float, spread: float, d: float) -> tuple[float, float]:
    """Return Petrov's term for ``older`` presentations spread evenly over ages [age, age + spread], and its slope.

    The term is ``older`` times the mean of x^(-d) over that interval,
    ``((age + spread)^(1-d) - age^(1-d)) / ((1-d) spread)`` (``age^(-d)`` for no spread).
    Written as ``age^(-d) ((1+s)^(1-d) - 1) / ((1-d) s)`` with s = spread / age and
    ``log1p``/``expm1``, nothing cancels when the spread is small beside the age, and a
    subnormal spread divides nothing by zero (below s = 1e-8 the series to s, whose next
    term is under 1e-16).  The slope (in t) is ``older ((age + spread)^(-d) - age^(-d)) / spread``,
    written the same way.
    """
    s = spread / age
    term = age ** -d
    if s < 1e-8:
        mean = 1.0 - 0.5 * d * s
        change = -d * (1.0 - 0.5 * (1.0 + d) * s)
    else:
        log = math.log1p(s)
        mean = math.expm1((1.0 - d) * log) / ((1.0 - d) * s)
        change = math.expm1(-d * log) / s
    return older * term * mean, older * term * change / age


def crossing(trace: Trace, d: float, tau: float) -> float:
    """Return the time activation falls to ``tau`` after the last encoding (:data:`NEVER` past ``MAX_TIME``).

    With one encoding it is ``t_1 + lifetime``.  Otherwise ``t_n + a``, a the age (time
    since the last encoding) where ``ln strength = tau``: Newton's method on ``ln a`` (ln
    strength is nearly linear in it: exactly, for one encoding), kept within the bracket
    ``lifetime <= a <= n^(1/d) lifetime`` (strength is at least the last term and at
    most n times it), bisecting where a step would leave it.  Solved in logarithms, no
    intermediate overflows or underflows however small the lifetime; solved for the age,
    a crossing close to the last encoding keeps its precision however late the clock.
    The root is within 1e-12 of its age of the exact one, plus one rounding of the sum
    (test_activation's 50-digit reference).
    """
    last = trace.recent[-1]
    if trace.n == 1:
        span = lifetime(d, tau)
        return NEVER if span > _LONGEST else last + span
    lo = -tau / d  # ln of the ages bracketing the root
    hi = lo + math.log(trace.n) / d
    if lo > _LOG_LONGEST:
        return NEVER
    if hi > _LOG_LONGEST:
        hi = _LOG_LONGEST
        if _excess(trace, hi, d, tau)[0] > 0.0:  # still above the threshold there
            return NEVER
    if math.exp(hi) + last == last:  # the whole bracket is below the last time's resolution
        return last + math.exp(hi)
    v = hi
    for _ in range(200):
        value, slope = _excess(trace, v, d, tau)
        if value > 0.0:
            lo = v
        else:
            hi = v
        if slope < 0.0:  # (not where the age underflowed or a term overflowed: far left of the root)
            step = -value / slope
            if abs(step) <= _PRECISION * max(1.0, abs(v)):
                v += step
                break
            if lo < v + step < hi:
                v += step
                continue
        if hi - lo <= _PRECISION * max(1.0, abs(lo)):
            break
        v = 0.5 * (lo + hi)
    return last + math.exp(v)


def _excess(trace: Trace, v: float, d: float, tau: float) -> tuple[float, float]:
    """Return ``ln strength - tau`` at age ``exp(v)`` and its derivative in v (+inf, 0 where the age underflows)."""
    age = math.exp(v)
    if age == 0.0:
        return math.inf, 0.0
    try:
        total, slope = trace.strength_at_age(age, d)
    except (OverflowError, ZeroDivisionError):  # an age so small a term overflows: far above the threshold
        return math.inf, 0.0
    if total == math.inf:
        return math.inf, 0.0
    return math.log(total) - tau, age * slope / total


class LazyActivation:
    """One buffer's activation rule: the clock, each entry's :class:`Trace`, lazy pops at crossing times.

    ``clock`` is the latest time the buffer was told (:meth:`WMBuffer.advance`, and
    every encoding's or forgetting's own time).  ``traces[entity][prop]`` is the trace
    of each entry of Q[entity]; ``due[entity]`` is at most the earliest crossing among
    them (so a touched queue with nothing due costs one lookup).  Kept here, not in the
    queues, so the other rules' hot paths carry nothing for it.
    """

    def __init__(self, wm: HostBuffer, decay: float, threshold: float, clock: float) -> None:
        self.wm = wm
        self.decay, self.threshold = decay, threshold
        self.span = lifetime(decay, threshold)  # one encoding's stay; NEVER-long spans give inf
        self.clock = clock
        self.settled = -math.inf  # the clock every queue was last brought up to (flush)
        self.traces: dict[str, dict[str, Trace]] = {}
        self.due: dict[str, float] = {}

    def advance(self, time: float) -> None:
        """Note that the clock reached ``time`` (it never goes back)."""
        if time > self.clock:
            self.clock = time

    def adopt(self, entity: str, q: Queue, time: float, traces: Optional[dict[str, Trace]] = None) -> None:
        """Take Q[entity] under the rule: ``traces`` kept (e.g. restored), one encoding at ``time`` for the others."""
        mine = self.traces[entity] = {}
        for prop in q:
            trace = (traces or {}).get(prop)
            mine[prop] = trace = trace if trace is not None else Trace(time)
            trace.due, trace.exact = trace.recent[-1] + self.span, trace.n == 1
        self._refresh(entity)

    def record(self, entity: str, prop: str, time: float, present: bool) -> None:
        """Note an encoding of ``prop`` into Q[entity] at ``time`` (``present``: a refresh)."""
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
        now = self.clock + TIME_EPSILON
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
            self.wm._forget(entity, q, prop, "activation", due, None)
        self._refresh(entity)

    def flush(self) -> None:
        """Bring every queue up to the clock (nothing to do when it has not moved since the last flush)."""
        if self.settled == self.clock:
            return
        now = self.clock + TIME_EPSILON
        columns = self.wm.columns
        if columns.entities and columns.store.traces is not None:
            rows = columns.store.non_empty()
            if self.wm.sink is None:
                self.settle_columns(rows)
            else:  # what went must be reported: those queues become dict queues, brought up below
                store = columns.store
                for row in np.unique(self.passed(store, rows) % store.rows).tolist():  # (in row order)
                    columns.to_dict(columns.bound[row])
        queues = self.wm._queues
        for entity in [e for e, due in self.due.items() if due <= now]:
            q = queues.get(entity)
            if q is not None:
                self.sync(entity, q)
        self.settled = self.clock

    # ------------------------------------------------------------ column queues
    def release(self, entity: str) -> dict[str, Trace]:
        """Hand over the traces of Q[entity] (moving to the column queues); this rule keeps them no longer."""
        self.due.pop(entity, None)
        return self.traces.pop(entity, {})

    def take(self, entity: str, traces: dict[str, Trace]) -> None:
        """Keep ``traces``, those of Q[entity] (back from the column queues)."""
        self.traces[entity] = traces
        self._refresh(entity)

    def passed(self, store: Any, rows: np.ndarray) -> np.ndarray:  # store: a QueueColumns (columns imports this)
        """Return the slots (flat indices) of column ``rows`` whose entry's crossing is at or before the clock.

        Decided exactly as :meth:`sync` decides for a dict queue: a slot whose lower
        bound passed is solved in numpy (:func:`crossings`, all at once); a root within
        :data:`_MARGIN` of the clock, or one :func:`crossings` does not handle, is solved
        by :func:`crossing` itself.  A numpy root is kept as a lower bound just below it.
        """
        traces = store.traces
        now = self.clock + TIME_EPSILON
        if not len(rows):
            return _NO_SLOTS
        if self.clock != traces.pending_clock:
            traces.settle()  # (at the clock they were made at, encodings not noted yet are not due)
        row_due = traces._row_due
        soon = np.take(row_due, rows)
        if soon.min() > now:  # one number per row: most calls end here
            return _NO_SLOTS
        rows = rows[soon <= now]
        due = np.take(traces._due[:max(store.used, 1)], rows, axis=1)  # (slots never used are never due)
        hit = due <= now  # an empty slot's due is NEVER
        slot, col = np.nonzero(hit)
        flat = slot * store.rows + rows[col]
        vague = ~np.take(traces._flat_exact, flat)
        if vague.any():
            self._solve(traces, flat[vague], now)
            due = np.take(traces._due[:max(store.used, 1)], rows, axis=1)
            flat = flat[np.take(traces._flat_due, flat) <= now]
        # The rows' bounds anew, the slots passed left out (they go, or their queue becomes a dict queue).
        traces._row_due[rows] = np.where(due <= now, NEVER, due).min(axis=0)
        return flat

    def _solve(self, traces: TraceColumns, flat: np.ndarray, now: float) -> None:
        due, exact = traces.flat_due, traces.flat_exact
        if self.span > _LONGEST:
            due[flat], exact[flat] = NEVER, True
            return
        width_rows = traces.n.shape[1]
        if len(flat) <= _FEW:  # one by one is cheaper for a few
            counts, recent = traces._flat_n, traces._flat_recent
            for f in flat.tolist():
                n = int(counts[f])
                ring = recent[f * HISTORY:(f + 1) * HISTORY].tolist()
                times = [ring[i & (HISTORY - 1)] for i in range(max(0, n - HISTORY), n)]
                found = self._bracket(n, times, now)
                if found is None:
                    found = crossing(traces.get(f // width_rows, f % width_rows), self.decay, self.threshold), True
                due[f], exact[f] = found
            return
        n, first, times = traces.ordered(flat)
        roots, other = crossings(n, first, times, self.decay, self.threshold, np.take(due, flat))
        margin = _MARGIN * np.maximum(1.0, np.abs(roots))
        due[flat] = roots - margin  # a lower bound of crossing()'s root
        close = other | (np.abs(roots - now) <= margin)
        for f in flat[close].tolist():  # too close to call: crossing() itself
            trace = traces.get(f // width_rows, f % width_rows)
            due[f], exact[f] = crossing(trace, self.decay, self.threshold), True

    def _bracket(self, n: int, recent: list[float], now: float) -> Optional[tuple[float, bool]]:
        """Return ``(due, False)`` for a trace whose lower bound passed, if two bounds decide it; else None.

        ``n`` and ``recent`` are the trace's count and kept times (:class:`Trace`); None:
        solve :func:`crossing`.

        :func:`crossing`'s root lies between two bounds: at most
        ``t_n + n^(1/d) lifetime`` (strength is at most n times its last term), and,
        while n <= HISTORY, at least
        ``mean(t_j) + n^(1/d) lifetime`` (x^-d is convex: the sum is at least n times the
        term of the mean age).  With the clock clearly past the first (gone) or clearly
        before the second (a new lower bound), no Newton step is needed.
        """
        try:
            reach = self.span * n ** (1.0 / self.decay)
        except OverflowError:
            reach = math.inf
        if reach <= _LONGEST:
            upper = recent[-1] + reach
            if upper + _MARGIN * max(1.0, abs(upper)) <= now:
                return upper, False  # gone (a lower bound still: crossing() solves it if a queue must say when)
            if n <= HISTORY:
                lower = math.fsum(recent) / n + reach
                lower -= _MARGIN * max(1.0, abs(lower))
                if lower > now:
                    return lower, False
        return None

    def forget_rows(self, rows: np.ndarray) -> np.ndarray:
        """Forget (no events) the entries of column ``rows`` whose crossing passed; return the rows that lost some.

        A row may recur in the result.  The buffer's size follows; its non-empty queues
        and change record are the caller's.
        """
        store = self.wm.columns.store
        flat = self.passed(store, rows)
        if not len(flat):
            return _NO_SLOTS
        store.prop.reshape(-1)[flat] = -1
        store.traces.due.reshape(-1)[flat] = NEVER
        owners = flat % store.rows  # a row may recur
        np.subtract.at(store.length, owners, 1)  # (one number per entry gone, not the row's every slot)
        self.wm._size -= len(flat)
        return owners

    def settle_columns(self, rows: np.ndarray) -> None:
        """Bring column ``rows`` up to the clock (no events: only called without a sink)."""
        if not len(rows):
            return
        owners = self.forget_rows(rows)
        if len(owners):
            self.wm.columns.emptied(owners)
            self.wm.changes.mark_rows(owners)

    def _refresh(self, entity: str) -> None:
        traces = self.traces.get(entity)
        if traces:
            self.due[entity] = min(t.due for t in traces.values())
        else:
            self.traces.pop(entity, None)
            self.due.pop(entity, None)


def install_activation(wm: HostBuffer, limits: Limits, time: float) -> None:
    """Start, change or stop ``wm``'s activation rule per ``limits``; entries without a trace get one at ``time``."""
    old = wm.activation
    if limits.activation is None:
        wm.activation = None
        return
    wm.flush()
    decay, threshold = limits.activation
    act = LazyActivation(wm, decay, threshold, max(time, old.clock) if old is not None else time)
    for entity in wm._nonempty:
        q = wm._queues.get(entity)
        if q is not None:  # a column queue keeps its traces (the limits' d and tau did not change: columns.fits)
            act.adopt(entity, q, time, old.traces.get(entity) if old is not None else None)
    wm.activation = act


#: A root found by :func:`crossings` (numpy) may differ from :func:`crossing`'s (Python floats, another
#: ``pow``) in its last bits; both are within this relative distance of each other by far.
_MARGIN = 1e-9
#: :func:`crossings` leaves to :func:`crossing` the traces whose older presentations span less than
#: 1/_ILL of their age (the Petrov term's rounding grows as that share shrinks).
_ILL = 1e4
#: Encoding counts up to which the crossing's lower bound ``n^(1/d)`` lifetimes is tabled (a larger count
#: takes the last entry's, still a lower bound).
_REACH = 1024
#: Up to this many crossings at once, :func:`crossing` solves them one by one (cheaper than numpy's fixed cost).
_FEW = 24
#: :func:`crossings` stops when a step is this small (relative): Newton's error after it is far smaller.
_SOLVED = 1e-11


class TraceColumns:
    """The :class:`Trace` of every entry of column queues: one per slot, as arrays (slots x rows).

    Slot (k, r) holds the trace of the entry in slot k of row r (meaningless where that
    slot is empty, whose ``due`` is :data:`NEVER`; an encoding into an empty or
    displaced slot starts a new trace).  ``n`` counts its encodings, ``recent[k, r, i %
    HISTORY]`` is the time of its i-th encoding (from 0; the last :data:`HISTORY` are
    kept), so ``recent[k, r, 0]`` is its first time until the ring wraps; ``first`` keeps
    the first time from then on (n > HISTORY).  ``due`` and ``exact`` are as in
    :class:`Trace`; ``row_due[r]`` is at most the earliest ``due`` of row r (so a row with
    nothing due costs one number to check; :meth:`LazyActivation.passed` renews it).  A
    crossing solved in numpy (:func:`crossings`) is kept only as a lower bound just below
    it, ``exact`` False: so whether and when an entry goes is decided exactly as for a
    dict queue (see :meth:`LazyActivation.passed`).
    """

    def __init__(self, width: int, rows: int) -> None:
        self._n = np.zeros((width, rows), dtype=np.int64)
        self._first = np.zeros((width, rows))
        self._recent = _lines((width, rows))  # a slot's ring in one cache line
        self._due = np.full((width, rows), NEVER)
        self._exact = np.zeros((width, rows), dtype=bool)
        self._row_due = np.full(rows, NEVER)  # per row: at most its slots' earliest due
        self.reach_of: Optional[tuple[float, float]] = None
        self._pending: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # encodings not noted yet
        self._pending_of: tuple[float, float, float] = (0.0, 0.0, 0.0)  # their (time, span, d)
        self.pending_clock = -math.inf  # the clock when they were made
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
        self._mark = np.zeros(self._flat_due.shape[0], dtype=np.intp)  # scratch: which pending slots recur

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

    def get(self, slot: int, row: int) -> Trace:
        """Return slot ``(slot, row)``'s trace as a :class:`Trace`."""
        self.settle()
        n = int(self._n[slot, row])
        ring = self._recent[slot, row].tolist()
        trace = Trace(float(self._first[slot, row]) if n > HISTORY else ring[0])
        trace.n = n
        trace.recent = [ring[i & (HISTORY - 1)] for i in range(max(0, n - HISTORY), n)]
        trace.due, trace.exact = float(self._due[slot, row]), bool(self._exact[slot, row])
        return trace

    def row(self, row: int, slots: list[int]) -> list[Trace]:
        """Return the traces of ``slots`` of row ``row`` (as :meth:`get`, reading the row once)."""
        self.settle()
        ns, firsts = self._n[:, row].tolist(), self._first[:, row].tolist()
        rings, dues, exacts = self._recent[:, row].tolist(), self._due[:, row].tolist(), self._exact[:, row].tolist()
        out = []
        for k in slots:
            n, ring = ns[k], rings[k]
            trace = Trace(firsts[k] if n > HISTORY else ring[0])
            trace.n = n
            trace.recent = [ring[i & (HISTORY - 1)] for i in range(max(0, n - HISTORY), n)]
            trace.due, trace.exact = dues[k], exacts[k]
            out.append(trace)
        return out

    def put(self, slot: int, row: int, trace: Trace) -> None:
        """Keep ``trace`` in slot ``(slot, row)``."""
        self.settle()
        n = trace.n
        self._n[slot, row], self._first[slot, row] = n, trace.first
        ring = [0.0] * HISTORY
        for i, time in zip(range(n - len(trace.recent), n), trace.recent):
            ring[i & (HISTORY - 1)] = time
        self._recent[slot, row] = ring
        self._due[slot, row], self._exact[slot, row] = trace.due, trace.exact
        self._row_due[row] = min(self._row_due[row], trace.due)

    def encoded(self, flat: np.ndarray, present: np.ndarray, time: float, span: float, d: float,
                rows: Optional[np.ndarray] = None, clock: float = -math.inf) -> None:
        """Note one encoding at ``time`` in each slot ``flat`` (flat index; of ``rows``): a refresh where ``present``.

        ``span`` is one encoding's :func:`lifetime` under decay ``d``; ``clock`` the
        activation clock then.  Noted lazily: the encodings of the calls made at one time
        and clock (a REG call's rule-3 encodings) are noted together, by the first read or
        write of the traces from outside (:meth:`settle`) or :meth:`LazyActivation.passed`
        at a later clock.  Until then a slot keeps its previous ``due``: after the queue
        lost whatever was due at that clock (see :meth:`LazyActivation.passed`), none is.
        The arrays given are kept: the caller does not change them.
        """
        if self._pending and (self._pending_of != (time, span, d) or clock != self.pending_clock):
            self.settle()
        if not self._pending:
            self._pending_of, self.pending_clock = (time, span, d), clock
        self._pending.append((flat, present, flat % self._n.shape[1] if rows is None else rows))

    def settle(self) -> None:
        """Note the pending encodings (:meth:`encoded`) as one batch (call by call if a slot is refreshed twice)."""
        pending = self._pending
        if not pending:
            return
        self._pending = []
        time, span, d = self._pending_of
        if len(pending) == 1:
            self._note(*pending[0], time, span, d)
            return
        flat = np.concatenate([p[0] for p in pending])
        present = np.concatenate([p[1] for p in pending])
        rows = np.concatenate([p[2] for p in pending])
        order = np.arange(len(flat))
        mark = self._mark
        mark[flat] = order  # (of a slot that recurs, the last place wins)
        last = mark[flat] == order
        if not last.all():  # a slot encoded again at that time
            if present[mark[flat[~last]]].any():  # refreshed again: the encodings in turn
                for p in pending:
                    self._note(*p, time, span, d)
                return
            # Displaced (or emptied and refilled) again: only the new entry's encoding counts.
            flat, present, rows = flat[last], present[last], rows[last]
        self._note(flat, present, rows, time, span, d)

    def _note(self, flat: np.ndarray, present: np.ndarray, rows: np.ndarray, time: float, span: float,
              d: float) -> None:
        """Note one encoding at ``time`` in each slot ``flat`` (distinct slots; ``rows`` may recur).

        A new entry's ``due`` is its crossing; a refreshed one's a lower bound of it: the
        later of ``time + span`` (the last term alone) and ``first + n^(1/d) span`` (every
        term is at least the first one's, the Petrov terms too), less :data:`_MARGIN`; the
        latter not where :func:`crossing`'s rounding of an ill-conditioned Petrov term
        (older presentations spanning little of their age, :data:`_ILL`) may undercut it.
        """
        n, recent = self._flat_n, self._flat_recent
        old = n[flat]
        old *= present  # encodings before this one (a new entry: none)
        counts = old + 1
        n[flat] = counts
        wrapping = counts.max() > HISTORY
        if wrapping:
            first = self._flat_first
            wraps = flat[counts == HISTORY + 1]
        at = flat * HISTORY
        if wrapping:  # the first time leaves the ring: keep it
            first[wraps] = recent[wraps * HISTORY]
        old &= HISTORY - 1
        old += at
        recent[old] = time
        begin = recent[at]  # the first time (while n <= HISTORY)
        reach = np.take(self._reach(d, span, time), counts, mode="clip")  # reach[1] < span
        if wrapping:  # (the few slots with older presentations only)
            older = np.flatnonzero(counts > HISTORY)
            many = counts[older]
            start = begin[older] = first[flat[older]]
            spread = recent[((many - HISTORY) & (HISTORY - 1)) + at[older]] - start
            with np.errstate(over="ignore", invalid="ignore"):
                right = time + span * many.astype(float) ** (1.0 / d) - start  # an age at the root, at most
            reach[older[(spread > 0.0) & (spread * _ILL < right)]] = -np.inf
        begin += reach
        due = np.maximum(begin, time + span)
        self._flat_due[flat] = due
        self._flat_exact[flat] = ~present
        np.minimum.at(self._row_due, rows, due)  # (rows recur in a batch)

    def _reach(self, d: float, span: float, time: float) -> np.ndarray:
        """Return ``k -> k^(1/d) span`` for k <= :data:`_REACH` (a larger k: take the last), less a margin.

        The margin, ``_MARGIN (1 + |time| + k^(1/d) span)``, keeps ``first + reach[k]``
        below :func:`crossing`'s own root, which is within 1e-13 of that size of the
        true one.  Made once per (d, span) and shifted once per encoding time.
        """
        if self.reach_of != (d, span):
            reach = [-math.inf]
            for k in range(1, _REACH + 1):
                try:
                    reach.append(k ** (1.0 / d) * span * (1.0 - _MARGIN))
                except OverflowError:
                    reach.append(math.inf)
            self.reach, self.reach_of, self.shifted_at = np.array(reach), (d, span), None
        if self.shifted_at != time:
            self.shifted, self.shifted_at = self.reach - _MARGIN * (1.0 + abs(time)), time
        return self.shifted

    def ordered(self, flat: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return the counts, first times and kept times of ``flat``.

        The times are a (k x len(flat)) array, oldest first, k the most any of them keeps;
        unused places hold -inf.
        """
        self.settle()
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


def crossings(n: np.ndarray, first: np.ndarray, times: np.ndarray, d: float, tau: float,
              start: Optional[np.ndarray] = None) -> tuple[np.ndarray, np.ndarray]:
    """Solve :func:`crossing` for many traces of at least two encodings at once (numpy; see :class:`TraceColumns`).

    ``n``, ``first`` and ``times`` as :meth:`TraceColumns.ordered` returns them; ``start``:
    lower bounds of the roots, if known.  Newton's method on
    ``F(t) = strength(t)^(-1/d) - lifetime`` (the root :func:`crossing` solves for in the
    logarithm of the age), in numpy arithmetic (another ``pow``), from the lower bound
    when given (F is concave and increasing: from the left it climbs to the root), stopped
    at :data:`_SOLVED`: the roots are :func:`crossing`'s within :data:`_MARGIN`
    (relative), not bit for bit.  Returns the roots and a mask of the traces this does
    not handle (the crossing is past ``_LONGEST``, the start overflows, or the Petrov
    term is ill-conditioned): solve those with :func:`crossing`.
    """
    span = lifetime(d, tau)
    kept = np.minimum(n, HISTORY)
    last = times[kept - 1, np.arange(len(n))]
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        t = last + span * n.astype(float) ** (1.0 / d)  # crossing()'s start, right of the root
        other = ~np.isfinite(t) | (t - last > _LONGEST) | (span > _LONGEST)
        older = (n - kept).astype(float)
        with_older = older > 0
        oldest = times[0]
        spread = oldest - first
        # The Petrov term cancels when the older presentations span little of their age: its
        # rounding (another pow's) could move the root past _MARGIN.  Those go to crossing().
        other |= with_older & (spread > 0.0) & (spread * _ILL < t - first)
        floor = last + span
        if start is not None:
            t = np.maximum(np.minimum(start, t), floor)
        t[other] = last[other]
        root = t.copy()
        active = np.flatnonzero(~other)
        half = d == 0.5  # ACT-R's default: a square root is cheaper than a power
        for _ in range(100):
            if not len(active):
                break
            ta = t[active]
            ages = ta - times[:, active]  # unused times are -inf: age inf, term 0
            terms = 1.0 / np.sqrt(ages) if half else ages ** -d
            total = terms.sum(axis=0)
            slope = -d * (terms / ages).sum(axis=0)
            wo = with_older[active]
            if wo.any():
                sub = np.flatnonzero(wo)
                idx = active[sub]
                tt = ta[sub]
                f = first[idx]
                o = oldest[idx]
                sp = spread[idx]
                k = older[idx]
                first_term = (tt - f) ** -d
                oldest_term = (tt - o) ** -d
                flat_case = sp <= 0.0
                add = np.where(flat_case, k * first_term,
                               k * ((tt - f) * first_term - (tt - o) * oldest_term) / ((1.0 - d) * sp))
                ds = np.where(flat_case, -(k * d * first_term / (tt - f)), k * (first_term - oldest_term) / sp)
                total[sub] += add
                slope[sub] += ds
            power = total ** (-1.0 / d)
            # F(t) = strength^(-1/d) - span, F'(t) = -(1/d) strength^(-1/d - 1) strength'(t) > 0
            step = -(power - span) / (-(1.0 / d) * (power / total) * slope)
            ta = np.maximum(ta + step, floor[active])
            t[active] = ta
            done = np.abs(step) <= _SOLVED * np.maximum(1.0, np.abs(ta))
            root[active[done]] = ta[done]
            active = active[~done]
        root[active] = t[active]
    return root, other
