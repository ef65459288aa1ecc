"""Decay time (the paper's Algorithm 2): the tick schedule and tick arithmetic.

The pops themselves (a tick pops the front of every non-empty queue, lazily) are
:mod:`fsreg_ros.core.memory.decay`.  This is the one module that does arithmetic on
decay tick times:

* :class:`DecaySchedule` says which ticks are due at a time: tick k falls at
  ``origin + k * period`` (k = 1, 2, ...) and is due at T iff
  ``origin + k * period <= T + 1e-9`` (:data:`TIME_EPSILON`, the boundary
  correction: the rounded quotient ``(T - origin) / period`` can be one off right
  at a tick, so the count is settled on the exact test).  O(1) however far the
  clock moved: it never enumerates ticks.
* :class:`TickRun` is a run of consecutive ticks of one schedule, ``count`` of
  them from tick ``first``: what the WM Manager sends (a few numbers, never a list
  of every tick, so a clock far ahead costs the same as one tick).
* :class:`TickLedger` numbers every tick a buffer has been given and answers "at
  what time was tick n?" for lazy catch-up.  It stores runs, merged while they
  continue one another, so its memory grows with the number of schedule changes,
  never with the number of ticks.

The origin of the grid is where the WM Manager starts managing (its clock then; 0
for the simulator and for a sim-time graph before the first ``/clock``); a new
decay period restarts the grid at the time of the change.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass
from typing import Optional

#: Slack when comparing tick times with event times (docs/semantics.md section 2).
TIME_EPSILON = 1e-9
#: Largest clock reading accepted, in seconds (~31,700 years): with a period of at
#: least ``forgetting.MIN_DECAY_PERIOD`` the tick index stays below 2**53, so
#: ``origin + k * period`` is computed from an exactly represented k.
MAX_TIME = 1e12
#: Largest tick index a run may name (indices up to this are exact as floats).
MAX_TICK_INDEX = 2**53


class TickError(ValueError):
    """A malformed tick run or an unusable time; the message says which and why."""


def check_time(name: str, value: object) -> float:
    """Return ``value`` as a float if it is a finite number of seconds, else raise TickError."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TickError(f"{name} must be a number of seconds, got {value!r}")
    try:
        value = float(value)
    except OverflowError:
        raise TickError(f"{name} is too large: {value!r}") from None
    if not math.isfinite(value):
        raise TickError(f"{name} must be finite, got {value!r}")
    if abs(value) > MAX_TIME:
        raise TickError(f"{name} is out of range: |{value!r}| > {MAX_TIME:g} s")
    return value


@dataclass(frozen=True)
class TickRun:
    """Ticks ``origin + k * period`` for k = ``first`` .. ``first + count - 1``, in order."""

    origin: float
    period: float
    first: int
    count: int

    @classmethod
    def single(cls, time: float) -> "TickRun":
        """One tick at ``time``."""
        return cls(float(time), 1.0, 0, 1)

    def time(self, i: int) -> float:
        """Return the time of the run's ``i``-th tick (0-based)."""
        return self.origin + (self.first + i) * self.period

    @property
    def last(self) -> float:
        return self.time(self.count - 1)

    def tail(self, i: int) -> Optional["TickRun"]:
        """Return the run without its first ``i`` ticks, or None if nothing is left."""
        if i >= self.count:
            return None
        return TickRun(self.origin, self.period, self.first + i, self.count - i)

    def continues(self, other: "TickRun") -> bool:
        """Tell whether this run starts right where ``other`` ends, on the same grid."""
        return (self.origin, self.period) == (other.origin, other.period) and self.first == other.first + other.count

    def to_json(self) -> dict:
        return {"origin": self.origin, "period": self.period, "first": self.first, "count": self.count}

    @classmethod
    def from_json(cls, data: object) -> "TickRun":
        """Validate a ``{"origin", "period", "first", "count"}`` object; TickError if malformed."""
        if not isinstance(data, dict) or set(data) != {"origin", "period", "first", "count"}:
            raise TickError("ticks must be an object with exactly origin, period, first and count")
        origin = check_time("ticks.origin", data["origin"])
        period = check_time("ticks.period", data["period"])
        if period <= 0:
            raise TickError(f"ticks.period must be > 0, got {period!r}")
        for key in ("first", "count"):
            if isinstance(data[key], bool) or not isinstance(data[key], int) or not 0 <= data[key] <= MAX_TICK_INDEX:
                raise TickError(f"ticks.{key} must be a whole number in [0, 2**53], got {data[key]!r}")
        if data["count"] < 1:
            raise TickError("ticks.count must be >= 1")
        run = cls(origin, period, data["first"], data["count"])
        check_time("ticks (last tick time)", run.last)
        return run


@dataclass
class DecaySchedule:
    """Algorithm 2's schedule for one domain: ticks at ``origin + k * period``, k >= 1.

    One schedule per domain, shared by the whole buffer (docs/semantics.md section 8), not one
    timer per queue.  :meth:`take` is idempotent: it derives the number of elapsed
    periods from the time and subtracts those already applied, so a timer that fires
    late, or once for several periods, and a barrier that asks again, never apply a
    tick twice or miss one; a time earlier than ticks already taken takes nothing.
    """

    period: float
    origin: float = 0.0
    applied: int = 0

    def elapsed(self, now: float) -> int:
        """Count the ticks at or before ``now`` (the docs/semantics.md's test, in O(1))."""
        now = check_time("time", now)
        limit = now + TIME_EPSILON
        if limit < self.origin + self.period:
            return 0
        k = math.floor((limit - self.origin) / self.period)
        # The rounded quotient can be one off right at the slack's edge; settle on
        # the docs/semantics.md's own test: tick k is due iff origin + k * period <= now + 1e-9.
        while self.origin + (k + 1) * self.period <= limit:
            k += 1
        while k > 0 and self.origin + k * self.period > limit:
            k -= 1
        return k

    def take(self, now: float) -> Optional[TickRun]:
        """Take the ticks due at or before ``now`` not taken yet (None if none)."""
        elapsed = self.elapsed(now)
        if elapsed <= self.applied:
            return None
        run = TickRun(self.origin, self.period, self.applied + 1, elapsed - self.applied)
        self.applied = elapsed
        return run

    def skip(self, now: float) -> None:
        """Mark every tick due at or before ``now`` as taken, without returning them."""
        self.applied = max(self.applied, self.elapsed(now))

    def next_tick(self) -> float:
        return self.origin + (self.applied + 1) * self.period

    def restart(self, period: float, now: float) -> None:
        """Restart the schedule with a new period: next tick one new period after ``now``."""
        self.period, self.origin, self.applied = period, check_time("time", now), 0


class TickLedger:
    """Every decay tick a buffer was given, numbered 0, 1, 2, ..., as arithmetic runs.

    Lazy decay (:mod:`fsreg_ros.core.memory.decay`) applies a tick to a queue when the
    queue is next touched, reporting it at the tick's own time: :meth:`time` finds it.
    """

    def __init__(self) -> None:
        self.count = 0  # ticks so far
        self._starts: list[int] = []  # ledger number of each run's first tick
        self._runs: list[TickRun] = []

    def add(self, run: TickRun) -> None:
        if self._runs and run.continues(self._runs[-1]):
            last = self._runs[-1]
            self._runs[-1] = TickRun(last.origin, last.period, last.first, last.count + run.count)
        else:
            self._starts.append(self.count)
            self._runs.append(run)
        self.count += run.count

    def time(self, n: int) -> float:
        """Return the time of tick number ``n`` (0-based; must not have been dropped)."""
        i = bisect_right(self._starts, n) - 1
        return self._runs[i].time(n - self._starts[i])

    def drop_before(self, n: int) -> None:
        """Forget the runs that end before tick number ``n`` (no queue owes them)."""
        keep = max(bisect_right(self._starts, n) - 1, 0)
        if keep:
            del self._starts[:keep]
            del self._runs[:keep]
