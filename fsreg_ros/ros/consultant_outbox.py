"""What a consultant node publishes, and when: :class:`ConsultantOutbox`.

Owns the consultant's outgoing topics: ``wm/events`` (numbered ``seq`` per incarnation,
only while someone subscribes; a call's events go out right after its reply, so listening
costs the caller nothing), ``wm/state`` (latched, so it always holds the current state:
after every request that changed WM, whether or not anyone listens, coalesced to at most
one per ``state_period``; a session's steps wait for its ``close``), and the announcement
on ``consultant/announce`` and ``consultant/<domain>/alive`` (latched; the latter with a 1 s
liveliness lease, so RR and REG learn within a second that the process died).
"""

from __future__ import annotations

from time import monotonic
from typing import Callable, Optional

from .. import contract
from ..core.consultant.service import ConsultantService, Outcome
from .carrier import publish, publisher

#: Longest a due /wm/state waits for open sessions to close, seconds.
MAX_STATE_DELAY = 1.0


class ConsultantOutbox:
    """The events, state and announcements of the consultant node ``node`` serving ``service()`` for ``domain``."""

    def __init__(self, node, domain: str, service: Callable[[], ConsultantService], state_period: float) -> None:
        self.domain, self.service, self.state_period = domain, service, state_period
        self.events = publisher(node, contract.WM_EVENTS)
        self.state = publisher(node, contract.WM_STATE)
        self.announcers = [publisher(node, contract.ANNOUNCE), publisher(node, contract.alive_topic(domain))]
        self.announced: Optional[tuple] = None
        self.announcement: dict = {}
        self.state_due, self.state_sent = False, float("-inf")
        self.unsent: list[dict] = []  # events of calls answered, published by flush right after
        self.flush_wait = True  # every call since the last flush was a session step (wm/state waits for close)
        self.flush_guard = node.create_guard_condition(self.flush)

    def listeners(self) -> int:
        """Return how many subscribers ``wm/events`` has now (a consultant publishes events only to someone)."""
        return self.events.get_subscription_count()

    def published(self, outcome: Outcome, wait: bool = False, later: bool = True) -> None:
        """Publish what came of a call right after its reply (the executor's next step: :meth:`flush`).

        A call's events (a dozen per turn, hundreds for a decay tick) cost the call's caller
        nothing this way: measured while a recorder listened, publishing them before the
        reply added their cost to every RR and REG round trip.  Their order, their ``seq``
        and what follows them (``wm/state``, the announcement) are unchanged.
        ``later=False``: the caller flushes itself once its answers are out (no round of its own).
        """
        self.unsent.extend(outcome.events)
        if outcome.changes.wm:
            self.state_due = True
        self.flush_wait = self.flush_wait and wait
        if later:
            self.flush_guard.trigger()

    def flush(self) -> None:
        """Publish the events of the calls answered since the last flush, a due ``wm/state``, the announcement."""
        events, self.unsent = self.unsent, []
        for event in events:
            publish(self.events, event)
        wait, self.flush_wait = self.flush_wait, True
        if not wait:
            self.publish_due()
        self.announce(only_if_changed=True)

    def announce(self, only_if_changed: bool = False) -> None:
        """Announce this incarnation, whether it serves, the policy it runs and its stored state."""
        s = self.service()
        message = {"domain": self.domain, "incarnation": s.incarnation, "ready": s.ready,
                   "memory": s.policy.to_json(), "state": s.status()}
        key = (s.ready, str(message["memory"]), str(message["state"]))
        if only_if_changed and key == self.announced:
            return
        self.announced, self.announcement = key, message
        for pub in self.announcers:
            publish(pub, message)

    def alive(self) -> None:
        """Repeat the announcement on the alive topic (a reader in this process sees liveliness only through writes)."""
        publish(self.announcers[1], self.announcement)

    def publish_state(self) -> None:
        """``/wm/state``: this domain's non-empty queues, LRU first."""
        self.state_due, self.state_sent = False, monotonic()
        s = self.service()
        publish(self.state, {"domain": self.domain, "time": s.time, "queues": s.buffer.snapshot(), "events": s.seq,
                             "incarnation": s.incarnation, "wm_version": s.wm_version})

    def publish_due(self, waiting: bool = False) -> None:
        """Publish a due /wm/state unless one went out less than ``state_period`` ago.

        Published whether or not anyone reads it now: the topic is latched, so the sample
        DDS keeps for a late joiner (``ros2 topic echo --once``) must be the current state,
        never an older one.  ``state_period`` coalesces: a burst of changes costs one
        message, and the timer sends the last one once the period has passed.
        ``waiting`` (the timer): also wait while a session is open, for at most a second.
        """
        now = monotonic()
        if not self.state_due or now - self.state_sent < self.state_period:
            return
        sessions = self.service().sessions
        sessions.expire(now)
        if waiting and len(sessions) and now - self.state_sent < MAX_STATE_DELAY:
            return
        self.publish_state()
