"""Deciding whether entries' activation crossed the threshold by a time, without solving for when.

Column queues (:mod:`fsreg_ros.core.memory.columns`) report no events, so for their
entries only *whether* a crossing passed matters, not when: the entries of many rows
whose bound passed are decided at once (:func:`passages`, Newton's method in numpy,
stopped for each entry as soon as it is decided), a few one by one (:func:`gone_by`,
:func:`bracket`).  numpy's ``pow`` is not Python's, so an entry is only decided where
the clock is more than a hair (:data:`MARGIN`) from its crossing; within that hair
:func:`~fsreg_ros.core.memory.trace.crossing` itself decides, so an entry goes exactly
when it would from a dict queue (:meth:`TraceColumns.passed
<fsreg_ros.core.memory.trace_columns.TraceColumns.passed>`; test_core_fast_paths).
"""

from __future__ import annotations

import math
from typing import Optional, Union

import numpy as np

from .trace import HISTORY, LOG_LONGEST, LONGEST, Trace, excess, lifetime

#: numpy's arithmetic (another ``pow``) may place a crossing a few last bits from :func:`crossing`'s (Python
#: floats); a crossing is only decided in numpy, or by one evaluation, this far (relative) from the clock.
MARGIN = 1e-9
#: :func:`passages` leaves to :func:`crossing` the traces whose older presentations span less than
#: 1/_ILL of their age (the Petrov term's rounding grows as that share shrinks).
_ILL = 1e4
#: Up to this many entries whose bound passed, one by one decides them (cheaper than numpy's fixed cost).
FEW = 24
#: :func:`passages` gives up on a trace when a step is this small (relative): converged, too close to call.
_SOLVED = 1e-11


def gone_by(trace: Trace, now: float, d: float, tau: float) -> tuple[bool, Optional[float]]:
    """Decide ``trace`` by one evaluation of its activation just before ``now`` (``now`` less :data:`MARGIN`).

    Returns ``(True, None)``: below the threshold there, so the crossing is before it;
    ``(False, bound)``: one step of Newton's method on :class:`_Newton`'s F from there,
    a lower bound of the crossing (F is increasing and concave: from the left a step
    lands at most on the root), passed ``now`` by the margin (``bound`` is the step
    less it); ``(False, None)``: neither, :func:`crossing` decides.  Where
    :func:`crossing` would iterate to the root, one evaluation mostly decides.
    """
    start = now - MARGIN * max(1.0, abs(now))
    age = start - trace.recent[-1]
    if age <= 0.0:
        return False, None
    value, slope = excess(trace, math.log(age), d, tau)  # ln strength - tau, d/d(ln age)
    if value < 0.0:
        return True, None
    if not (slope < 0.0 and value < LOG_LONGEST):
        return False, None
    # F = span (exp(-value/d) - 1) and F' = -(span/d) exp(-value/d) slope/age, so -F/F' is:
    step = -d * age * math.expm1(value / d) / slope
    later = start + step
    bound = later - MARGIN * max(1.0, abs(later))
    return False, (bound if bound > now else None)


def bracket(n: int, recent: list[float], now: float, d: float, span: float) -> Optional[tuple[float, bool]]:
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
        reach = span * n ** (1.0 / d)
    except OverflowError:
        reach = math.inf
    if reach <= LONGEST:
        upper = recent[-1] + reach
        if upper + MARGIN * max(1.0, abs(upper)) <= now:
            return upper, False  # gone (the upper bound, not exact: crossing() solves it if a queue must say when)
        if n <= HISTORY:
            lower = math.fsum(recent) / n + reach
            lower -= MARGIN * max(1.0, abs(lower))
            if lower > now:
                return lower, False
    return None


class _Newton:
    """Newton's method on ``F(t) = strength(t)^(-1/d) - lifetime`` for many traces at once (numpy).

    F is increasing and concave in t, and its root is the crossing: a step from any t
    lands at most on the root (the tangent lies above F), so from the left every iterate
    is a lower bound of the crossing.  Built from :meth:`TraceColumns.ordered`'s arrays
    for traces of at least two encodings; ``other`` marks those left to
    :func:`crossing` (the crossing is past ``LONGEST``, or the Petrov term is
    ill-conditioned: older presentations spanning less than 1/:data:`_ILL` of their age,
    where its rounding, another ``pow``'s, could move the root past :data:`MARGIN`).
    """

    def __init__(self, n: np.ndarray, first: np.ndarray, times: np.ndarray, d: float, tau: float) -> None:
        self.d, self.span, self.times, self.first = d, lifetime(d, tau), times, first
        kept = np.minimum(n, HISTORY)
        self.last = times[kept - 1, np.arange(len(n))]
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            right = self.last + self.span * n.astype(float) ** (1.0 / d)  # at least the crossing
            self.other = ~np.isfinite(right) | (right - self.last > LONGEST) | (self.span > LONGEST)
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
             now: Union[float, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Decide for many traces of at least two encodings whether each crossed the threshold by ``now``.

    ``n``, ``first`` and ``times`` as :meth:`TraceColumns.ordered` returns them.  Only the
    answer is needed, not the crossing itself (column queues report no events), so
    Newton's method (:class:`_Newton`, in numpy arithmetic) stops for each trace as soon
    as it is decided:

    * gone: F is above 0 at ``now`` less :data:`MARGIN` (relative), so the crossing is
      before ``now`` by more than numpy's arithmetic may move it from :func:`crossing`'s;
    * staying: an iterate from the left, a lower bound of the crossing, passed ``now``
      by that margin (returned: keep it, less the margin, as the trace's new bound).

    Returns ``gone`` (a mask) and ``bound`` (the staying traces' iterate, -inf for
    the rest); a trace neither gone nor staying is :func:`crossing`'s to decide (too
    close to ``now`` to call, or one :class:`_Newton` leaves out).  Most traces are
    decided by one evaluation, where solving for the crossing would take several.
    ``now`` is one time for all, or one per trace (rows on their own clocks).
    """
    newton = _Newton(n, first, times, d, tau)
    gone = np.zeros(len(n), dtype=bool)
    bound = np.full(len(n), -np.inf)
    each = isinstance(now, np.ndarray)
    start = now - MARGIN * (np.maximum(1.0, np.abs(now)) if each else max(1.0, abs(now)))
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        t = np.maximum(start, newton.floor)
        active = np.flatnonzero(~newton.other)
        ta = t[active]
        for i in range(100):
            if not len(active):
                break
            value, step = newton.step(ta, active)
            if i == 0:  # F(now - margin) > 0: crossed before
                over = (value > 0.0) & (ta == (start[active] if each else start))
                gone[active[over]] = True
                active, ta, step = active[~over], ta[~over], step[~over]
            ta = np.maximum(ta + step, newton.floor[active])  # from the left: at most the crossing
            later = ta - MARGIN * np.maximum(1.0, np.abs(ta)) > (now[active] if each else now)
            bound[active[later]] = ta[later]
            going = ~later & (np.abs(step) > _SOLVED * np.maximum(1.0, np.abs(ta)))  # (converged near now: too close)
            active, ta = active[going], ta[going]
    return gone, bound
