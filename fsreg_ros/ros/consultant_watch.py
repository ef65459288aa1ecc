"""The WM Manager's watch over its consultants: who is there, who restarted, who must be (re)configured.

Owns reachability under every policy: :class:`ConsultantWatch` follows each consultant's
announcements on ``consultant/announce`` (a new incarnation is a restarted consultant:
detached, then attached and configured at once) and its liveliness on
``consultant/<domain>/alive`` (a 1 s DDS lease, kept by the consultant's DDS threads).
When it lapses, the domain stops counting as configured (``ready`` turns false, the domain
is detached so decay ticks are owed, not lost) until the consultant is back and has
acknowledged a configure again: without it, a policy that sends nothing on its own
(displacement, none) never noticed an outage.  :meth:`ConsultantWatch.supervise` (a steady
timer) attaches consultants that became reachable.  The decisions are the core
:class:`~fsreg_ros.core.forgetting.wm_manager.WMManager`'s (``attach``/``detach``); the
calls go through :class:`~fsreg_ros.ros.manage_link.ManageLinks`.
"""

from __future__ import annotations

from functools import partial
from typing import Callable

from rclpy.event_handler import SubscriptionEventCallbacks

from .. import contract
from ..core.forgetting.wm_manager import WMManager
from ..core.memory.ticks import TickError
from .carrier import subscribe
from .manage_link import ConsultantLink, ManageLinks


class ConsultantWatch:
    """Every managed domain's consultant followed on ``node``; ``arm(name)`` re-arms its decay timer after an attach.

    ``changed()`` is called when readiness may have changed (the node publishes
    ``wm_manager/ready`` if it did).
    """

    def __init__(self, node, manager: WMManager, links: ManageLinks, arm: Callable[[str], None],
                 changed: Callable[[], None]) -> None:
        self.node, self.manager, self.links = node, manager, links
        self.domains: dict[str, ConsultantLink] = links.links
        self.arm, self.changed = arm, changed
        subscribe(node, contract.ANNOUNCE, self.on_announce)
        for name, dom in self.domains.items():
            dom.alive_sub = subscribe(
                node, contract.alive_topic(name), partial(self.on_alive, dom),
                event_callbacks=SubscriptionEventCallbacks(liveliness=partial(self.on_liveliness, dom)))

    def on_announce(self, announce: dict) -> None:
        """Attach a consultant's new incarnation at once (it (re)started); note what a configured one runs."""
        dom = self.domains.get(announce["domain"])
        if dom is None:
            return  # not managed here
        incarnation = announce["incarnation"]
        if incarnation == dom.incarnation or dom.incarnation is None or incarnation > dom.incarnation:
            dom.restored = (announce.get("state") or {}).get("restored", dom.restored)
        if announce["ready"] and incarnation == dom.incarnation:
            dom.running = announce.get("memory")
            return
        if incarnation == dom.incarnation and (dom.configuring is not None or dom.configured):
            return  # already being configured
        self.node.get_logger().info(
            f"consultant '{dom.name}' announced incarnation {incarnation} (was {dom.incarnation}), "
            f"running {announce.get('memory')}: configuring it")
        dom.incarnation = incarnation
        dom.running = announce.get("memory")
        dom.configured = False
        dom.alive = True  # it just spoke
        self.manager.detach(dom.name)
        self.attach(dom)
        self.changed()

    def on_alive(self, dom: ConsultantLink, announce: dict) -> None:
        """Take an alive message as proof of life (in one process DDS liveliness shows only through writes)."""
        if dom.alive is False:
            self.reachable(dom, True)
        dom.alive = True

    def on_liveliness(self, dom: ConsultantLink, info) -> None:
        """Follow a consultant's liveliness: a lapse makes its domain unconfigured until it is back."""
        alive = info.alive_count > 0
        if alive != dom.alive and (dom.alive is not None or not alive):
            self.reachable(dom, alive)
        dom.alive = alive

    def reachable(self, dom: ConsultantLink, alive: bool) -> None:
        """Note that ``dom``'s consultant came back (attach it again) or went away (detach it, not ready)."""
        log = self.node.get_logger()
        if alive:
            log.info(f"consultant '{dom.name}' is reachable again (liveliness back): configuring it")
            dom.alive = True
            attached = self.manager.domains[dom.name].attached
            if attached and not dom.configured and dom.configuring is None:
                self.manager.detach(dom.name)  # acknowledged while it seemed gone: configure it again
                attached = False
            if not attached and dom.caller.ready():
                self.attach(dom)
            return
        log.warning(f"consultant '{dom.name}' is unreachable (its liveliness lapsed): the graph is not ready "
                    "until it is back and configured")
        dom.alive = False
        self.manager.detach(dom.name)
        dom.lost()
        self.changed()

    def attach(self, dom: ConsultantLink) -> None:
        """Attach ``dom`` in the core manager (owed ticks, then its policy) and re-arm its decay timer."""
        try:
            self.manager.attach(dom.name, None, self.node.now())
        except TickError as err:
            self.node.get_logger().error(f"consultant '{dom.name}' not attached: {err}", throttle_duration_sec=10.0)
        self.arm(dom.name)

    def supervise(self) -> None:
        """Attach consultants that became reachable; expire unanswered calls."""
        self.links.expire()
        for dom in self.domains.values():
            if not self.manager.domains[dom.name].attached and dom.alive is not False and dom.caller.ready():
                self.attach(dom)
        self.changed()  # a configure acknowledged since (ManageLinks marks it) shows within a period

    def all_configured(self) -> bool:
        """Whether every domain's current consultant has acknowledged its configuration."""
        return all(dom.configured for dom in self.domains.values())
