"""The dialogue player's event sources: every consultant's ``wm/events`` heard whole, or the run fails (issue 20).

Owns the two waits around a played run.  A consultant publishes ``wm/events`` only while
its publisher is matched with a subscriber, so before turn 1 :meth:`EventSources.wait`
waits until every consultant reports ``event_listeners >= 1 + listeners`` (its ``info``)
and the player's own subscription is matched with every consultant, then notes where each
stands (:meth:`~fsreg_ros.ros.event_audit.EventAudit.start`).  After the last turn
:meth:`EventSources.drain` waits until every event each consultant published during the run
has been heard and checks it (:meth:`~fsreg_ros.ros.event_audit.EventAudit.check`).
"""

from __future__ import annotations

import time as wallclock
from typing import Callable

from .. import contract
from ..contract import consultant_codec as codec
from .carrier import CarrierError, ServiceCaller, subscribe, wait_until
from .event_audit import EventAudit


class PlayerError(RuntimeError):
    """The graph did not answer in time, answered with an error, or its event stream was incomplete or foreign."""


class EventSources:
    """The ``wm/events`` of ``domains``' consultants, heard on ``node`` into ``audit``; ``listeners``: other readers."""

    def __init__(self, node, domains: list[str], audit: EventAudit, hear: Callable[[dict], None], callback_group,
                 listeners: int) -> None:
        self.node, self.domains, self.audit, self.listeners = node, list(domains), audit, listeners
        self.consultants = {d: ServiceCaller(node, contract.consultant_service(d), callback_group) for d in domains}
        self.subscription = subscribe(node, contract.WM_EVENTS, hear, callback_group=callback_group)

    async def wait(self, status: dict, timeout: float) -> None:
        """Wait until every consultant's ``wm/events`` publisher is matched with this player; note where each stands.

        A consultant sends events only while its publisher sees a subscriber, so turn 1
        must not start before each one sees this player's (``event_listeners`` in its
        ``info``) and this player's subscription sees each consultant.
        """
        deadline = wallclock.monotonic() + timeout
        waiting = list(self.domains)
        while waiting:
            matched = self.subscription.get_publisher_count() >= len(self.domains)
            for domain in list(waiting):
                info = await self.info(domain, max(0.1, deadline - wallclock.monotonic()), "graph not ready")
                if matched and info.get("event_listeners", 0) >= 1 + self.listeners:
                    incarnation = (status.get("incarnation") or {}).get(domain)
                    self.audit.start(domain, incarnation if isinstance(incarnation, int) else None,
                                     int(info.get("events", 0)))
                    waiting.remove(domain)
            if waiting:
                if wallclock.monotonic() > deadline:
                    raise PlayerError(
                        f"graph not ready: the {contract.WM_EVENTS.name} publisher of {', '.join(waiting)} is not "
                        f"matched with this player (its events would be lost)")
                await wait_until(self.node, lambda: False, 0.05)
        publishers = self.subscription.get_publisher_count()
        if publishers > len(self.domains):  # one per consultant: a writer more is not this graph's
            raise PlayerError(f"{contract.WM_EVENTS.name} has {publishers} publishers for this run's "
                              f"{len(self.domains)} consultant(s): another graph publishes in this namespace")

    async def drain(self, timeout: float) -> None:
        """Wait until every event each consultant published during the run has been heard; check it.

        An answer can overtake the last events, which come from another process.  Then
        each consultant's events must be exactly those numbered after where it stood
        before turn 1, up to its last ``seq`` now, from the same incarnation.
        """
        for domain in self.domains:
            last = int((await self.info(domain, timeout, f"cannot check the events of '{domain}'"))["events"])
            wanted = last - self.audit.base[domain]
            done = lambda: self.audit.fault is not None or self.audit.heard(domain) >= wanted  # noqa: E731
            await wait_until(self.node, done, timeout)
            self.check_fault()
            problem = self.audit.check(domain, last)
            if problem is not None:
                raise PlayerError(f"incomplete {contract.WM_EVENTS.name}: {problem}; the run's trace, origins and "
                                  "alignment would be wrong")

    async def info(self, domain: str, timeout: float, failure: str) -> dict:
        """Return the ``info`` of ``domain``'s consultant (one real round trip); PlayerError ``failure: why`` if not."""
        try:
            return await self.consultants[domain].wait_ready(codec.info_request(), timeout)
        except CarrierError as err:
            raise PlayerError(f"{failure}: {err}") from None

    def check_fault(self) -> None:
        """Raise the audit's fault (a foreign or malformed event heard) as a PlayerError."""
        if self.audit.fault is not None:
            raise PlayerError(self.audit.fault)
