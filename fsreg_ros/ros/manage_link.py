"""The WM Manager's links to the consultants' manage services (``consultant/<domain>/manage``).

:class:`ManagePort` is the core manager's :class:`~fsreg_ros.core.forgetting.wm_manager.MemoryPort`
in the graph: each decision (``configure``, ``decay``, ``advance``, ``evict``) becomes a request,
sent at once and tracked with a deadline by :class:`ManageLinks`, which also handles
the replies: a configure acknowledged by the consultant's current incarnation marks the
domain configured; a failed ``decay`` is owed again (the consultant skips ticks it had
applied) and a failed ``decay`` or ``configure`` detaches the domain, so it is attached
(and configured) again when the consultant answers or announces itself.  The requests
and replies are the contract's manage ops (:mod:`fsreg_ros.contract.consultant`), encoded and
decoded by its codec (:mod:`fsreg_ros.contract.consultant_codec`).
"""

from __future__ import annotations

import time as wallclock
from dataclasses import dataclass, field
from functools import partial
from typing import Any, Callable, Optional

from rclpy.task import Future

from .carrier import CarrierError, ServiceCaller, log_error
from ..contract import consultant_codec as codec, manage_service
from ..core.memory.ticks import TickRun
from ..core.forgetting.policies import ForgettingPolicy
from ..core.forgetting.wm_manager import WMManager


@dataclass
class ConsultantLink:
    """What the WM Manager knows of one domain's consultant, and its calls in flight."""

    name: str
    caller: ServiceCaller
    timer: Any = None  # the domain's one-shot decay timer
    configured: bool = False  # a configure has been acknowledged by the current incarnation
    configuring: Optional[Future] = None
    inflight: list = field(default_factory=list)  # [(future, payload, deadline)]
    incarnation: Optional[int] = None  # the consultant's, from its announce or configure reply
    running: Optional[dict] = None  # the policy it acknowledged or announced
    restored: Optional[dict] = None  # what its incarnation restored at start (its stored state's ``restored``)
    #: Its liveliness on ``consultant/<domain>/alive`` (1 s lease): None until heard of, False while lapsed.
    alive: Optional[bool] = None
    alive_sub: Any = None

    def lost(self) -> None:
        """Forget that the consultant is configured (it went away): it is configured again when it is back."""
        self.configured = False
        self.configuring = None


class ManageLinks:
    """Every managed domain's link: sending, deadlines, replies."""

    def __init__(self, node, names: list[str], callback_group, timeout: Callable[[], float]) -> None:
        self.node = node
        self.timeout = timeout
        self.manager: Optional[WMManager] = None  # set by the node once it made the manager
        self.links = {n: ConsultantLink(n, ServiceCaller(node, manage_service(n), callback_group)) for n in names}

    def send(self, link: ConsultantLink, payload: dict) -> Future:
        """Send one manage request now; its reply is handled when it comes (or its deadline passes)."""
        future = link.caller.send(payload)
        entry = (future, payload, wallclock.monotonic() + self.timeout())
        link.inflight.append(entry)
        future.add_done_callback(partial(self._on_reply, link, entry))
        return future

    def _on_reply(self, link: ConsultantLink, entry: tuple, future: Future) -> None:
        if entry in link.inflight:
            link.inflight.remove(entry)
        payload = entry[1]
        op = payload["op"]
        try:
            reply = link.caller.decode(future)
        except CarrierError as err:
            log_error(self.node.get_logger(), f"consultant '{link.name}' failed '{op}': {err}")
            if op == "decay":  # maybe never applied: owed again (the consultant skips what it applied)
                self.manager.owe(link.name, *codec.decay_args(payload))
            if op in ("decay", "configure"):  # start over: attach again when it answers or announces itself
                self.manager.detach(link.name)
                link.lost()
            return
        if op == "configure" and future is link.configuring:
            link.running, incarnation, restored = codec.configured_of(reply)
            if incarnation is not None:
                link.incarnation = incarnation
            if restored is not None:  # a first configure may drop WM
                link.restored = restored
            if not link.configured:
                self.node.get_logger().info(
                    f"consultant '{link.name}' (incarnation {link.incarnation}) configured: {link.running}")
            # Configured only while it lives: an acknowledgement that arrives after its liveliness lapsed
            # (a reply in flight) is the dead incarnation's; it is configured again when it is back.
            link.configured = (link.alive is not False
                               and link.running == self.manager.domains[link.name].policy.to_json())
            link.configuring = None

    def expire(self) -> None:
        """Fail the calls whose deadline passed (kind ``timeout``)."""
        now = wallclock.monotonic()
        for link in self.links.values():
            for future, _, deadline in list(link.inflight):
                if now > deadline and not future.done():
                    link.caller.expire(future, self.timeout())

    async def settle(self, deadline: float) -> None:
        """Wait for everything sent so far (ticks, a timer's, configures, evictions)."""
        pending = [(link, entry[0]) for link in self.links.values() for entry in list(link.inflight)]
        for link, future in pending:
            await self.result(link, future, deadline)

    async def size(self, link: ConsultantLink, deadline: float) -> int:
        """Ask ``link``'s consultant how many properties its WM holds (manage op ``size``), until ``deadline``."""
        return codec.size_of(await self.result(link, self.send(link, codec.size_request()), deadline))

    async def result(self, link: ConsultantLink, future: Future, deadline: float) -> dict:
        """Await one reply until ``deadline`` (monotonic); CarrierError naming the consultant."""
        remaining = max(deadline - wallclock.monotonic(), 0.05)
        try:
            return await link.caller.result(future, remaining)
        except CarrierError as err:
            raise CarrierError(f"consultant '{link.name}' did not apply the change: {err}", kind=err.kind) from None


class ManagePort:
    """The core manager's :class:`~fsreg_ros.core.forgetting.wm_manager.MemoryPort` in the graph."""

    def __init__(self, links: ManageLinks) -> None:
        self.links = links

    def configure(self, domain: str, policy: ForgettingPolicy, time: float) -> None:
        link = self.links.links[domain]
        link.configuring = self.links.send(link, codec.configure_request(policy, time))

    def decay(self, domain: str, ticks: TickRun) -> None:
        self.links.send(self.links.links[domain], codec.decay_request(ticks))

    def advance(self, domain: str, time: float) -> None:
        self.links.send(self.links.links[domain], codec.advance_request(time))

    def evict(self, domain: str, count: int, time: float) -> None:
        self.links.send(self.links.links[domain], codec.evict_request(count, time))

    def sizes(self, domains: list[str]) -> None:
        return None  # needs service calls: the sync barrier asks, then calls manager.share
