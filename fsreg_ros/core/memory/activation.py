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
and c is solved (:func:`crossing`, a few Newton steps) once the clock passes that
bound, if the entry was not encoded again meanwhile.  An entry refreshed more often
than its lifetime is never solved for.
"""

from __future__ import annotations

import math
from typing import Optional

from ..decay import TIME_EPSILON
from .host import HostBuffer
from .limits import Limits
from .queue import Queue

#: Encoding times an entry keeps exactly (the Petrov approximation covers older ones).
HISTORY = 8
#: No crossing (an entry that never falls below the threshold within the clock's range).
NEVER = math.inf
#: Crossings further than this after the last encoding are :data:`NEVER` (decay.MAX_TIME).
_LONGEST = 1e12
#: The crossing time is solved to this relative precision.
_PRECISION = 1e-13


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
            span = oldest - self.first
            if span <= 0.0:
                total += older * (t - self.first) ** -d
            else:
                total += older * ((t - self.first) ** (1.0 - d) - (t - oldest) ** (1.0 - d)) / ((1.0 - d) * span)
        return total

    def strength_and_slope(self, t: float, d: float) -> tuple[float, float]:
        """Return :meth:`strength` at ``t`` and its derivative there (negative), in one pass."""
        total = slope = 0.0
        for r in self.recent:
            age = t - r
            term = age ** -d
            total += term
            slope -= d * term / age
        older = self.n - len(self.recent)
        if older > 0:
            oldest = self.recent[0]
            span = oldest - self.first
            first_term = (t - self.first) ** -d
            if span <= 0.0:
                total += older * first_term
                slope -= older * d * first_term / (t - self.first)
            else:
                oldest_term = (t - oldest) ** -d
                total += older * ((t - self.first) * first_term - (t - oldest) * oldest_term) / ((1.0 - d) * span)
                slope += older * (first_term - oldest_term) / span
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


def crossing(trace: Trace, d: float, tau: float) -> float:
    """Return the time activation falls to ``tau`` after the last encoding (:data:`NEVER` past ``MAX_TIME``).

    With one encoding it is ``t_1 + lifetime``.  Otherwise the root of
    ``F(t) = strength(t)^(-1/d) - exp(-tau/d)`` on ``(t_n, inf)``.  F increases and is
    concave there (``strength^(-1/d)`` is n^(-1/d) times the power mean of order -d of
    the ages, concave in t; linear for one encoding), and ``F(t_n + lifetime) <= 0``
    (the last term alone reaches the threshold there).  So Newton's method started
    from the left climbs to the root without overshooting, quadratically near it;
    started from the right (at the bound ``t_n + n^(1/d) lifetime``: ``strength`` is at
    most n times its last term), its first step lands left of the root, closer than
    ``t_n + lifetime`` is.  Three or four steps per encoding.
    """
    last, span = trace.recent[-1], lifetime(d, tau)
    if span > _LONGEST:
        return NEVER
    if trace.n == 1:
        return last + span
    try:
        t = last + span * trace.n ** (1.0 / d)
    except OverflowError:
        return NEVER
    if t - last > _LONGEST:
        t = last + _LONGEST
        if trace.strength(t, d) ** (-1.0 / d) < span:
            return NEVER
    for _ in range(100):
        total, slope = trace.strength_and_slope(t, d)
        value = total ** (-1.0 / d) - span
        # F'(t) = -(1/d) strength^(-1/d - 1) strength'(t) > 0
        step = -value / (-(1.0 / d) * total ** (-1.0 / d - 1.0) * slope)
        t = max(t + step, last + span)  # from the right, never left of the lower bound
        if abs(step) <= _PRECISION * max(1.0, abs(t)):
            break
    return t


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
        queues = self.wm._queues
        for entity in [e for e, due in self.due.items() if due <= now]:
            q = queues.get(entity)
            if q is not None:
                self.sync(entity, q)
        self.settled = self.clock

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
        act.adopt(entity, wm._queues[entity], time, old.traces.get(entity) if old is not None else None)
    wm.activation = act
