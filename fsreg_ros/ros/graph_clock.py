"""The graph's clock set and read by a client (:class:`ClockControl`, a part of ``GraphClient``).

A graph on simulated time follows ``/clock``: :meth:`ClockControl.set_clock` publishes
it once the nodes subscribe, waits until the forgetting due by then is applied (the WM
Manager's ``sync`` barrier) and, with ``confirm``, until the WM Manager's clock reads
it; later requests of the client are stamped with it.
"""

from __future__ import annotations

import time
from typing import Any, Optional

from rosgraph_msgs.msg import Clock

from .. import contract
from ..contract.codec import printable
from ..core.memory.ticks import MAX_TIME
from .client_base import ClientError, Spinning
from .readiness import GRAPH_NODES

#: Seconds ``set_clock`` waits for the graph's nodes to subscribe the clock topic before publishing.
CLOCK_DISCOVERY = 2.5
#: Seconds between two ``/clock`` messages while ``set_clock`` waits for the graph's clock to reach the time.
CLOCK_RESEND = 0.25


def clock_message(seconds: float) -> Clock:
    """Return a ``/clock`` message for a time in seconds (nanoseconds always < 1e9)."""
    stamp = Clock()
    stamp.clock.sec, stamp.clock.nanosec = divmod(int(round(seconds * 1e9)), 10**9)
    return stamp


class ClockControl(Spinning):
    """Publish the graph's clock and confirm it (state set up by ``GraphClient``: ``_clock``, ``time``)."""

    def publish_clock(self, t: float) -> None:
        """Publish the graph's clock = ``t`` (nothing waits: see :meth:`set_clock`)."""
        self.reach_recorders(self._clock)
        self._clock.publish(clock_message(t))
        self._note_sent(self._clock, lambda: self._clock.publish(clock_message(t)))

    def set_clock(self, t: float, timeout: Optional[float] = None, *, confirm: bool = False) -> dict:
        """Publish the graph's clock = ``t`` and wait until the forgetting due by then is applied; the sync reply.

        ``t`` must be a finite number of seconds in [0, 1e12] (ClientError ``usage``).
        The clock is published once the graph's nodes subscribe it (a message published
        before that is lost).  With ``confirm``: refused (ClientError ``refused``) when no
        node follows the clock topic (a wall-clock graph) or ``t`` is earlier than the
        graph's clock (a clock does not go back), and the call returns only when the WM
        Manager's clock reads ``t`` or later (the clock is sent again until it does), so a
        request sent afterwards is stamped ``t`` or later.  Later requests from this
        client are stamped with ``t``.
        """
        timeout = self.timeout if timeout is None else timeout
        t = check_clock(t)
        deadline = time.monotonic() + timeout
        expected = len(GRAPH_NODES) - 1 + len(self.domains()) if self.readiness() is not None else 1
        try:
            self.spin_until(lambda: self._clock.get_subscription_count() >= expected,
                            min(CLOCK_DISCOVERY, timeout), "clock subscribers")
        except ClientError:
            if confirm and self._clock.get_subscription_count() == 0:
                raise ClientError(f"clock {t:g} s refused: no node of the graph follows "
                                  f"{self.node.resolve_topic_name(contract.CLOCK)} (it runs on wall-clock time, or "
                                  "follows another clock topic: --clock)", "refused") from None
        if confirm:
            now = float(self.status(timeout)["time"])
            if t < now - 1e-9:
                raise ClientError(f"clock {t:g} s refused: the graph's clock is at {now:g} s and does not go back "
                                  "(forgetting already applied is never undone)", "refused")
        self.publish_clock(t)
        reply = self.sync(t, max(0.0, deadline - time.monotonic()))
        if confirm:
            def reached() -> bool:
                if float(self.status(max(0.0, deadline - time.monotonic()))["time"]) >= t - 1e-9:
                    return True
                self.publish_clock(t)  # /clock is best effort for the nodes' time sources: send it again
                self.spin_for(CLOCK_RESEND)
                return False

            self.spin_until(reached, max(0.0, deadline - time.monotonic()),
                            f"the graph's clock at {t:g} s (does it follow "
                            f"{self.node.resolve_topic_name(contract.CLOCK)}?)", "refused")
        self.time = t
        return reply

    def graph_time(self, timeout: Optional[float] = None) -> float:
        """Return the graph's clock (its WM Manager's, from ``wm_manager/status``), seconds."""
        return float(self.status(timeout)["time"])


def check_clock(t: Any) -> float:
    """Return ``t`` if a graph can take it as its clock (finite seconds in [0, 1e12]); else ClientError ``usage``."""
    try:
        value = float(t)
    except (TypeError, ValueError, OverflowError):
        raise ClientError(f"clock: expected a number of seconds, got {printable(repr(t), 60)}", "usage") from None
    if isinstance(t, bool) or not value == value or abs(value) == float("inf"):
        raise ClientError(f"clock: expected a finite number of seconds, got {printable(repr(t), 60)}", "usage")
    if not 0.0 <= value <= MAX_TIME:
        raise ClientError(f"clock: {value:g} s is out of range: a clock is in [0, {MAX_TIME:g}] s", "usage")
    return value
