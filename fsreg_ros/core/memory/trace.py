"""One entry's ACT-R base-level activation: its encoding history (:class:`Trace`) and crossing time.

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

This module is the arithmetic of one trace (no buffer, no queue): :func:`activation`,
:func:`lifetime`, :func:`crossing`.  The rule that forgets by it is
:mod:`fsreg_ros.core.memory.activation`; the traces of column queues are
:mod:`fsreg_ros.core.memory.trace_columns`, decided many at once by
:mod:`fsreg_ros.core.memory.crossings`.
"""

from __future__ import annotations

import math

#: Encoding times an entry keeps exactly (the Petrov approximation covers older ones; a power of 2).
HISTORY = 8
#: No crossing (an entry that never falls below the threshold within the clock's range).
NEVER = math.inf
#: Crossings further than this after the last encoding are :data:`NEVER` (decay.MAX_TIME).
LONGEST = 1e12
#: The crossing time is solved to this relative precision (of the logarithm of its age).
_PRECISION = 1e-15
#: ln(LONGEST).
LOG_LONGEST = math.log(LONGEST)


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
            total += older_terms(older, t - oldest, oldest - self.first, d)[0]
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
            term, dterm = older_terms(older, age + (last - oldest), oldest - self.first, d)
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


def older_terms(older: int, age: float, spread: float, d: float) -> tuple[float, float]:
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
        return NEVER if span > LONGEST else last + span
    lo = -tau / d  # ln of the ages bracketing the root
    hi = lo + math.log(trace.n) / d
    if lo > LOG_LONGEST:
        return NEVER
    if hi > LOG_LONGEST:
        hi = LOG_LONGEST
        if excess(trace, hi, d, tau)[0] > 0.0:  # still above the threshold there
            return NEVER
    if math.exp(hi) + last == last:  # the whole bracket is below the last time's resolution
        return last + math.exp(hi)
    v = hi
    for _ in range(200):
        value, slope = excess(trace, v, d, tau)
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


def excess(trace: Trace, v: float, d: float, tau: float) -> tuple[float, float]:
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
