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
and the rows encoded again at one clock are not checked again
(:meth:`LazyActivation.forget_members`).  Column queues report no events, so there only
whether an entry's crossing passed matters, not when: the entries of many rows whose
bound passed are decided at once (:func:`passages`, Newton's method in numpy, stopped
for each entry as soon as it is decided), a few one by one (:meth:`LazyActivation._gone`).
numpy's ``pow`` is not Python's, so an entry is only decided where the clock is more
than a hair (:data:`_MARGIN`) from its crossing; within that hair :func:`crossing`
itself decides, so an entry goes exactly when it would from a dict queue
(:meth:`LazyActivation.passed`; test_core_fast_paths).
"""

from __future__ import annotations

import itertools
import math
from typing import Any, Optional

import numpy as np

from .ticks import TIME_EPSILON
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
                or isinstance(data[0], bool) or not isinstance(data[0], int) or min(data[0], HISTORY) != len(data) - 2
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                           for x in data[1:])
                or any(a > b for a, b in zip(data[1:], data[2:]))):
            raise ValueError(f"activation trace {data!r} is not [count, first time, the last min(count, {HISTORY}) "
                             "times...] in order")
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
        self.swept: tuple[Optional[tuple[float, int]], int] = (None, 0)  # (clock, traces' edit), member rows

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
        """Note an encoding of ``prop`` into Q[entity] at ``time`` (``present``: a refresh).

        An encoding stamped before the clock (a late message) counts at the clock: an
        entry's encoding times never go back.
        """
        time = max(time, self.clock)
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
        bound passed is decided in numpy (:func:`passages`, all at once) or, for a few,
        one by one (:meth:`_bracket`, :meth:`_gone`); a crossing within :data:`_MARGIN`
        of the clock, or one :func:`passages` leaves out, is solved by :func:`crossing`
        itself.  A slot that stays keeps a new lower bound.
        """
        traces = store.traces
        now = self.clock + TIME_EPSILON
        if not len(rows):
            return _NO_SLOTS
        if self.clock != traces.pending_clock:
            traces.settle()  # (at the clock they were made at, encodings not noted yet are not due)
        soon = traces._row_due.take(rows)
        due_rows = soon <= now
        if not due_rows.any():  # one number per row: most calls end here
            return _NO_SLOTS
        rows = rows.compress(due_rows)
        width = max(store.used, 1)  # (slots never used are never due)
        due = traces._due[:width].take(rows, axis=1)
        at = np.flatnonzero(due <= now)  # places in ``due`` (an empty slot's due is NEVER)
        starts = np.arange(0, width * store.rows, store.rows)[:, None]  # each slot's flat index in row 0
        flat = (starts + rows).reshape(-1).take(at)  # (a 2-D nonzero would cost four times more)
        vague = ~traces._flat_exact.take(flat)
        if vague.any():
            unsure = flat[vague]
            self._solve(traces, unsure, now)
            renewed = traces._flat_due.take(unsure)
            due.reshape(-1)[at[vague]] = renewed
            staying = renewed > now
            at = np.concatenate((at[~vague], at[vague][~staying]))
            flat = np.concatenate((flat[~vague], unsure[~staying]))
        # The rows' bounds anew, the slots passed left out (they go, or their queue becomes a dict queue).
        due.reshape(-1)[at] = NEVER
        traces._row_due[rows] = due.min(axis=0)
        return flat

    def _solve(self, traces: TraceColumns, flat: np.ndarray, now: float) -> None:
        due, exact = traces.flat_due, traces.flat_exact
        if self.span > _LONGEST:
            due[flat], exact[flat] = NEVER, True
            return
        width_rows = traces.n.shape[1]
        if len(flat) <= _FEW:  # one by one is cheaper for a few (read as Python numbers at once)
            rings = traces._recent.reshape(-1, HISTORY).take(flat, axis=0).tolist()
            for f, n, first, ring in zip(flat.tolist(), traces._flat_n.take(flat).tolist(),
                                         traces._flat_first.take(flat).tolist(), rings):
                trace = _ring_trace(n, first, ring)
                found = self._bracket(n, trace.recent, now)
                if found is None:
                    gone, bound = self._gone(trace, now)
                    if gone:  # (its bound stays: at most the clock)
                        continue
                    found = (bound, False) if bound is not None else (crossing(trace, self.decay, self.threshold), True)
                due[f], exact[f] = found
            return
        n, first, times = traces.ordered(flat)
        gone, bound = passages(n, first, times, self.decay, self.threshold, now)
        staying = bound > -np.inf
        later = bound[staying]
        due[flat[staying]] = later - _MARGIN * np.maximum(1.0, np.abs(later))  # a lower bound of crossing()'s root
        # (what went keeps its bound, at most the clock; too close to call: crossing() itself)
        for f in flat[~(gone | staying)].tolist():
            trace = traces.get(f // width_rows, f % width_rows)
            due[f], exact[f] = crossing(trace, self.decay, self.threshold), True

    def _gone(self, trace: Trace, now: float) -> tuple[bool, Optional[float]]:
        """Decide ``trace`` by one evaluation of its activation just before ``now`` (``now`` less :data:`_MARGIN`).

        Returns ``(True, None)``: below the threshold there, so the crossing is before it;
        ``(False, bound)``: one step of Newton's method on :class:`_Newton`'s F from there,
        a lower bound of the crossing (F is increasing and concave: from the left a step
        lands at most on the root), passed ``now`` by the margin (``bound`` is the step
        less it); ``(False, None)``: neither, :func:`crossing` decides.  Where
        :func:`crossing` would iterate to the root, one evaluation mostly decides.
        """
        start = now - _MARGIN * max(1.0, abs(now))
        age = start - trace.recent[-1]
        if age <= 0.0:
            return False, None
        value, slope = _excess(trace, math.log(age), self.decay, self.threshold)  # ln strength - tau, d/d(ln age)
        if value < 0.0:
            return True, None
        if not (slope < 0.0 and value < _LOG_LONGEST):
            return False, None
        # F = span (exp(-value/d) - 1) and F' = -(span/d) exp(-value/d) slope/age, so -F/F' is:
        step = -self.decay * age * math.expm1(value / self.decay) / slope
        later = start + step
        bound = later - _MARGIN * max(1.0, abs(later))
        return False, (bound if bound > now else None)

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
                return upper, False  # gone (the upper bound, not exact: crossing() solves it if a queue must say when)
            if n <= HISTORY:
                lower = math.fsum(recent) / n + reach
                lower -= _MARGIN * max(1.0, abs(lower))
                if lower > now:
                    return lower, False
        return None

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
        traces = self.wm.columns.store.traces
        now = self.clock
        at = (now, traces.edit) if now + self.span > now + TIME_EPSILON else None
        then, swept = self.swept
        if at is not None and at == then and not members & ~swept:
            return
        self.forget_rows(rows)
        self.swept = (at, (swept if at == then else 0) | members) if at is not None else (None, 0)

    def forget_row(self, row: int) -> None:
        """As :meth:`forget_rows` for one column row, its bound checked first as one number (most rows: nothing due)."""
        traces = self.wm.columns.store.traces
        if self.clock != traces.pending_clock:
            traces.settle()  # (at the clock they were made at, encodings not noted yet are not due)
        if traces._row_due[row] <= self.clock + TIME_EPSILON:
            self.forget_rows(np.array([row]))

    def noting(self) -> tuple[float, float, float, float]:
        """Return ``(time, lifetime, d, clock)`` of an encoding made now, as column queues note it.

        An encoding counts at the clock at the earliest (:meth:`record`), and the clock
        has reached the encoding's time (:meth:`advance`).
        """
        return self.clock, self.span, self.decay, self.clock

    def forget_rows(self, rows: np.ndarray) -> np.ndarray:
        """Forget (no events) the entries of column ``rows`` whose crossing passed; return the rows that lost some.

        A row may recur in the result.  The buffer's size follows; its non-empty queues
        and change record are the caller's.
        """
        store = self.wm.columns.store
        flat = self.passed(store, rows)
        if not len(flat):
            return _NO_SLOTS
        store.clear_slots(flat)
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


#: numpy's arithmetic (another ``pow``) may place a crossing a few last bits from :func:`crossing`'s (Python
#: floats); a crossing is only decided in numpy, or by one evaluation, this far (relative) from the clock.
_MARGIN = 1e-9
#: :func:`passages` leaves to :func:`crossing` the traces whose older presentations span less than
#: 1/_ILL of their age (the Petrov term's rounding grows as that share shrinks).
_ILL = 1e4
#: k -> 1/k for k <= HISTORY (index 0 unused): the last of k kept times' share of a lower bound of their mean.
_SHARE = np.array([0.0] + [1.0 / k for k in range(1, HISTORY + 1)])
#: k -> the oldest kept time's share of it, 1 - 1/k.
_KEEP = 1.0 - _SHARE
#: Numbers :attr:`TraceColumns.edit` (unique across stores: a store made anew never repeats an old one's).
_EDITS = itertools.count()
#: Up to this many entries whose bound passed, one by one decides them (cheaper than numpy's fixed cost).
_FEW = 24
#: :func:`passages` gives up on a trace when a step is this small (relative): converged, too close to call.
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
    bound found in numpy (:func:`passages`) is kept only as a lower bound a margin below
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
        self.edit = next(_EDITS)  # renewed whenever a trace comes in from outside (:meth:`put_row`)
        self.reach_of: Optional[tuple[float, float]] = None
        self._pending: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # encodings not noted yet
        self._ones: list[tuple[int, int]] = []  # and those given one slot at a time (encoded_one): slot, row
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
        trace = _ring_trace(int(self._n[slot, row]), float(self._first[slot, row]), self._recent[slot, row].tolist())
        trace.due, trace.exact = float(self._due[slot, row]), bool(self._exact[slot, row])
        return trace

    def row(self, row: int, slots: list[int]) -> list[Trace]:
        """Return the traces of ``slots`` of row ``row`` (as :meth:`get`, reading the row once)."""
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
        lost whatever was due at that clock (see :meth:`LazyActivation.passed`), none is.
        The arrays given are kept: the caller does not change them.

        ``origins`` (the store's array of each slot's origin reference, slots x rows, as
        it is after this encoding), ``stamp`` (this encoding's first stamp) and ``prop`` (its
        property id) let the calls of one batch encode a slot more than once (a row
        displacing its own new entry): a batch holds each property once, so a slot is
        refreshed at most once in it, before any displacement, and its entry at the end is
        new exactly when its origin is a stamp of the batch (:meth:`settle`).  Without
        them, each call is a batch of its own.
        """
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

    def pending_since(self, stamp: int) -> bool:
        """Tell whether an entry stamped ``stamp`` may have been encoded in the pending batch (stamps only grow)."""
        return bool(self._pending or self._ones) and stamp >= self._first_stamp

    def settle(self) -> None:
        """Note the pending encodings (:meth:`encoded`, :meth:`encoded_one`) as one batch."""
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

    def _note(self, flat: np.ndarray, present: np.ndarray, rows: np.ndarray, time: float, span: float,
              d: float) -> None:
        """Note one encoding at ``time`` in each slot ``flat`` (``rows`` may recur; a slot only as a new entry).

        A slot recurs (:meth:`settle`) only where each place notes a new entry: the same
        writes, in whatever order numpy makes them.

        A new entry's ``due`` is its crossing; a refreshed one's a lower bound of it: the
        later of ``time + span`` (the last term alone) and ``m + k^(1/d) span``, less
        :data:`_MARGIN`.  There the k = min(n, :data:`HISTORY`) kept times, the oldest
        t_o and the last ``time``, have a mean of at least m = t_o + (time - t_o) / k,
        and x^-d is convex: their terms alone sum to at least k (t - m)^-d, and the
        Petrov term of older presentations only adds to them.  Leaving that term out,
        the bound needs no look at how well :func:`crossing` rounds it, and costs the
        same few array operations for every slot (in a long session most are past
        HISTORY encodings).
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
        begin += self._bounds(d, span, time).take(k)  # m + reach[k], m = t_o + (time - t_o) / k
        due = np.maximum(begin, time + span)  # (reach[1] < span)
        self._flat_due[flat] = due
        self._flat_exact[flat] = ~present
        np.minimum.at(self._row_due, rows, due)  # (rows recur in a batch)

    def _bounds(self, d: float, span: float, time: float) -> np.ndarray:
        """Return the table ``add`` of :meth:`_note`'s bound ``t_o _KEEP[k] + add[k]`` at ``time``.

        That is ``m + reach[k]`` for k <= :data:`HISTORY` kept times, the oldest t_o:
        m = t_o + (time - t_o) / k, and reach[k] = ``k^(1/d) span`` less a margin,
        ``_MARGIN (1 + |time| + k^(1/d) span)``, which keeps the bound below
        :func:`crossing`'s own root (within 1e-13 of that size of the true one).  Made
        once per (d, span) and shifted once per encoding time.
        """
        if self.reach_of != (d, span):
            reach = [-math.inf]
            for k in range(1, HISTORY + 1):
                try:
                    reach.append(k ** (1.0 / d) * span * (1.0 - _MARGIN))
                except OverflowError:
                    reach.append(math.inf)
            self.reach, self.reach_of, self.shifted_at = np.array(reach), (d, span), None
        if self.shifted_at != time:
            self.shifted = time * _SHARE + self.reach - _MARGIN * (1.0 + abs(time))
            self.shifted_at = time
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


class _Newton:
    """Newton's method on ``F(t) = strength(t)^(-1/d) - lifetime`` for many traces at once (numpy).

    F is increasing and concave in t, and its root is the crossing: a step from any t
    lands at most on the root (the tangent lies above F), so from the left every iterate
    is a lower bound of the crossing.  Built from :meth:`TraceColumns.ordered`'s arrays
    for traces of at least two encodings; ``other`` marks those left to
    :func:`crossing` (the crossing is past ``_LONGEST``, or the Petrov term is
    ill-conditioned: older presentations spanning less than 1/:data:`_ILL` of their age,
    where its rounding, another ``pow``'s, could move the root past :data:`_MARGIN`).
    """

    def __init__(self, n: np.ndarray, first: np.ndarray, times: np.ndarray, d: float, tau: float) -> None:
        self.d, self.span, self.times, self.first = d, lifetime(d, tau), times, first
        kept = np.minimum(n, HISTORY)
        self.last = times[kept - 1, np.arange(len(n))]
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            right = self.last + self.span * n.astype(float) ** (1.0 / d)  # at least the crossing
            self.other = ~np.isfinite(right) | (right - self.last > _LONGEST) | (self.span > _LONGEST)
            self.older = (n - kept).astype(float)
            self.with_older = self.older > 0
            self.oldest = times[0]
            self.spread = self.oldest - first
            self.other |= self.with_older & (self.spread > 0.0) & (self.spread * _ILL < right - first)
        self.floor = self.last + self.span  # the last term alone: at most the crossing
        self.half = d == 0.5  # ACT-R's default: a square root is cheaper than a power

    def step(self, t: np.ndarray, active: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return F at times ``t`` of traces ``active`` and Newton's step there, -F/F' (call under np.errstate)."""
        d = self.d
        ages = t - self.times[:, active]  # unused times are -inf: age inf, term 0
        terms = 1.0 / np.sqrt(ages) if self.half else ages ** -d
        total = terms.sum(axis=0)
        slope = -d * (terms / ages).sum(axis=0)
        wo = self.with_older[active]
        if wo.any():
            sub = np.flatnonzero(wo)
            idx = active[sub]
            tt = t[sub]
            f = self.first[idx]
            o = self.oldest[idx]
            sp = self.spread[idx]
            k = self.older[idx]
            first_term = (tt - f) ** -d
            oldest_term = (tt - o) ** -d
            flat_case = sp <= 0.0
            add = np.where(flat_case, k * first_term,
                           k * ((tt - f) * first_term - (tt - o) * oldest_term) / ((1.0 - d) * sp))
            ds = np.where(flat_case, -(k * d * first_term / (tt - f)), k * (first_term - oldest_term) / sp)
            total[sub] += add
            slope[sub] += ds
        power = total ** (-1.0 / d)
        value = power - self.span
        # F'(t) = -(1/d) strength^(-1/d - 1) strength'(t) > 0
        return value, -value / (-(1.0 / d) * (power / total) * slope)


def passages(n: np.ndarray, first: np.ndarray, times: np.ndarray, d: float, tau: float,
             now: float) -> tuple[np.ndarray, np.ndarray]:
    """Decide for many traces of at least two encodings whether each crossed the threshold by ``now``.

    ``n``, ``first`` and ``times`` as :meth:`TraceColumns.ordered` returns them.  Only the
    answer is needed, not the crossing itself (column queues report no events), so
    Newton's method (:class:`_Newton`, in numpy arithmetic) stops for each trace as soon
    as it is decided:

    * gone: F is above 0 at ``now`` less :data:`_MARGIN` (relative), so the crossing is
      before ``now`` by more than numpy's arithmetic may move it from :func:`crossing`'s;
    * staying: an iterate from the left, a lower bound of the crossing, passed ``now``
      by that margin (returned: keep it, less the margin, as the trace's new bound).

    Returns ``gone`` (a mask) and ``bound`` (the staying traces' iterate, -inf for
    the rest); a trace neither gone nor staying is :func:`crossing`'s to decide (too
    close to ``now`` to call, or one :class:`_Newton` leaves out).  Most traces are
    decided by one evaluation, where solving for the crossing would take several.
    """
    newton = _Newton(n, first, times, d, tau)
    gone = np.zeros(len(n), dtype=bool)
    bound = np.full(len(n), -np.inf)
    start = now - _MARGIN * max(1.0, abs(now))
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        t = np.maximum(start, newton.floor)
        active = np.flatnonzero(~newton.other)
        ta = t[active]
        for i in range(100):
            if not len(active):
                break
            value, step = newton.step(ta, active)
            if i == 0:  # F(now - margin) > 0: crossed before
                over = (value > 0.0) & (ta == start)
                gone[active[over]] = True
                active, ta, step = active[~over], ta[~over], step[~over]
            ta = np.maximum(ta + step, newton.floor[active])  # from the left: at most the crossing
            later = ta - _MARGIN * np.maximum(1.0, np.abs(ta)) > now
            bound[active[later]] = ta[later]
            going = ~later & (np.abs(step) > _SOLVED * np.maximum(1.0, np.abs(ta)))  # (converged near now: too close)
            active, ta = active[going], ta[going]
    return gone, bound
