"""``wm_manager``: the ROS wrapper of the core WM Manager (docs/semantics.md sections 2 and 7).

The buffers live in the consultant processes; what each domain forgets, and when,
is decided by the core :class:`~fsreg_ros.core.forgetting.wm_manager.WMManager` (policies,
decay schedules, the ticks owed to a consultant that was away).  This node only
supplies its clock, timers, parameters and service transport: the manager's port
sends each decision to ``/consultant/<domain>/manage``:

* ``configure`` installs a domain's policy (the consultant trims every queue at
  once).  Sent when the consultant first answers (``attach``), after every accepted
  parameter change, and at once when ``consultant/announce`` shows a new incarnation
  (a restarted consultant), preceded by the ticks owed while it was away and the ticks
  of any ``decay`` it never acknowledged (the consultant skips ticks it had applied,
  so none is applied twice).  A restarted consultant refuses query ops (kind
  ``not-ready``) until that configure arrives.
* Reachability, under every policy: each consultant's announcements and liveliness on
  ``consultant/<domain>/alive`` (a 1 s DDS lease) are followed by
  :class:`~fsreg_ros.ros.consultant_watch.ConsultantWatch`; while it lapses, the domain
  is not configured (``ready`` false, decay ticks owed, not lost).
* ``decay`` sends a run of ticks ``{"origin", "period", "first", "count"}``: a few
  numbers however many ticks, so a clock far ahead costs what one tick costs.

Time: the decay grid starts at the node's clock when it starts managing (under
``use_sim_time`` that is 0 until the first ``/clock``, so a scripted replay ticks
at k * delta from t = 0, as the simulator does); ticks fall at origin + k * delta,
and a new ``decay_period`` restarts the grid at the change.  A one-shot ROS timer is
armed for each domain's next tick.  A clock that goes backwards applies nothing
(ticks are never undone or applied twice) and is logged once; under ``use_sim_time``
a clock that does not move is reported (``common.watch_clock``).

Parameters (:class:`~fsreg_ros.ros.manager_parameters.ManagerParameters`; all but ``domains``
and ``use_sim_time`` changeable at run time, a change validated as the effective policy of
every domain first; unsetting a parameter or changing its type is refused, by rclpy's
static typing): ``domains`` (string array, required, read-only): the consultant domains
managed; the memory settings, node-wide and per domain (:mod:`fsreg_ros.ros.memory_parameters`,
from the settings table); ``service_timeout`` (10.0 s, in [0.01, 3600]): deadline of
each consultant call, and of sync's wait for the consultants to be configured.

Services (schemas: :class:`~fsreg_ros.contract.SyncRequest`/``SyncReply``,
``StatusRequest``/``StatusReply``): ``wm_manager/sync`` is the race-free hand-off of a
scripted player (docs/design.md, "Forgetting without races"): it applies every tick due
at or before the request's time in every domain (no waiting on ``/clock``), waits until
every consultant acknowledged everything sent to it so far, then trims the shared pool
if a domain has ``shared-capacity``, and replies; a time that is not finite, beyond
1e12 s, or more than a day ahead of the node's clock is refused and changes nothing.
``wm_manager/status`` reports each domain's setting, what its consultant runs, whether
its current incarnation is configured, the next tick, ``ready`` (every domain configured)
and this node's ``graph`` identity.  Topic in: ``consultant/announce`` (latched), from every
consultant; ``ltm/assert``, only to answer one naming a domain no consultant serves
(:class:`~fsreg_ros.ros.foreign_asserts.ForeignAsserts`).  Topic out: ``wm_manager/ready``
(latched, :class:`~fsreg_ros.contract.ManagerReady`):
``ready``, each domain's ``configured``/``incarnation``/``running`` and the ``recorders`` it sees, at start and at every
change, so a client waits for readiness instead of retrying (``fsreg-up``, ``fsreg-ctl``,
``fsreg_ros.testing``).
"""

from __future__ import annotations

import os
import socket
import time as wallclock
from functools import partial
from typing import Any, Optional

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..ros.clock_parameter import fix_use_sim_time
from .. import contract
from ..ros.carrier import CarrierError, graph_identity, log_error, publish, publisher, wait_until
from ..ros.serving import serve
from ..contract import manage_service
from ..core.memory.ticks import TIME_EPSILON, TickError
from ..core.forgetting.wm_manager import WMManager
from ..ros.diagnostics import OK, WARN
from ..ros.consultant_watch import ConsultantWatch
from ..ros.foreign_asserts import ForeignAsserts
from ..ros.node_base import now_seconds, run_node, watch_clock
from ..ros.manage_link import ConsultantLink, ManageLinks, ManagePort
from ..ros.manager_parameters import ManagerParameters, declare_domains
from ..ros.recorders import recorders_of

#: How often unconfigured consultants are looked for and stale calls expired (s).
SUPERVISE_PERIOD = 0.25
#: Longest one-shot timer delay, ns (rcl timers take an int64 period).
MAX_DELAY_NS = 10**18


class WMManagerNode(Node):
    """Forgetting policies and decay schedules of every managed domain."""

    NODE_NAME = "wm_manager"

    def __init__(self, node_name: str = NODE_NAME, *, namespace: Optional[str] = None, **kwargs: Any) -> None:
        super().__init__(node_name, namespace=namespace, **kwargs)
        fix_use_sim_time(self)  # one clock for the whole graph
        names = declare_domains(self)
        self._names = names
        self._config = ManagerParameters(self, names)
        policies = self._config.policies()

        # Callback groups: consultant clients (and their deadline timers) reentrant, so
        # their replies arrive while the barrier awaits them; the barrier services in
        # their own group, so decay timers and parameter changes are never blocked by
        # a sync waiting for a slow consultant.
        self._client_group = ReentrantCallbackGroup()
        self._barrier_group = MutuallyExclusiveCallbackGroup()
        now = self.now()
        self._latest = now
        self._warned_backwards = False
        self._links = ManageLinks(self, names, self._client_group, lambda: self.timeout)
        self._domains: dict[str, ConsultantLink] = self._links.links
        self.manager = self._links.manager = WMManager(ManagePort(self._links), origin=now)
        for name in names:
            self.manager.manage_domain(name, policies[name], now)
            self._domains[name].timer = self.create_timer(1.0, partial(self._on_decay_timer, name), autostart=False)
            self._arm(name)

        self.add_on_set_parameters_callback(self._config.on_set)
        self.add_post_set_parameters_callback(self._after_set_parameters)
        self._ready = publisher(self, contract.READY)
        self._ready_sent: Optional[dict] = None
        serve(self, contract.SYNC, self._sync, self._barrier_group)
        serve(self, contract.STATUS, self._status)
        self._watch = ConsultantWatch(self, self.manager, self._links, self._arm, self._publish_ready)
        self._foreign = ForeignAsserts(self, names)  # an ltm/assert no consultant would answer
        self._clock_watch = watch_clock(self)
        self.create_timer(SUPERVISE_PERIOD, self._watch.supervise, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f"managing (decay grid from t = {now:g}) "
            + ", ".join(f"{d}: {p.to_json()}" for d, p in policies.items())
            + "; waiting for consultants"
        )
        self._watch.supervise()

    # ------------------------------------------------------------------ time
    def now(self) -> float:
        return now_seconds(self)

    @property
    def timeout(self) -> float:
        return self._config.timeout

    def _advance(self, name: str, t: float) -> int:
        """Send the domain's ticks due at or before ``t`` (the core decides); how many."""
        if t < self._latest - TIME_EPSILON and not self._warned_backwards:
            self._warned_backwards = True
            self.get_logger().warning(
                f"the clock went backwards ({t:g} s after {self._latest:g} s): no decay tick is undone or applied "
                "again (logged once)"
            )
        self._latest = max(self._latest, t)
        return self.manager.advance_domain(name, t)

    # ------------------------------------------------------------ parameters
    def _after_set_parameters(self, params: list[Parameter]) -> None:
        if not self._config.memory_changed(params):
            return
        try:
            policies = self._config.policies()
            now = self.now()
            for name, policy in policies.items():
                if policy.to_json() != self.manager.domains[name].policy.to_json():
                    self._advance(name, now)
                    self.manager.set_policy(name, policy, now)
                    self._arm(name)
                    self.get_logger().info(f"domain '{name}': memory {policy.to_json()}")
        except (ValueError, TickError) as err:  # validated above: only a clock fault gets here
            log_error(self.get_logger(), f"parameter change not applied: {err}")

    # ----------------------------------------------------------------- decay
    def _arm(self, name: str) -> None:
        """(Re)arm the domain's one-shot timer for its next tick (ROS clock)."""
        dom = self._domains[name]
        next_tick = self.manager.next_tick(name)
        if next_tick is None:
            dom.timer.cancel()
            return
        now_ns = self.get_clock().now().nanoseconds
        delay_ns = min(max(int(round(next_tick * 1e9)) - now_ns, 1), MAX_DELAY_NS)
        dom.timer.timer_period_ns = delay_ns
        dom.timer.reset()

    def _on_decay_timer(self, name: str) -> None:
        try:
            self._advance(name, self.now())
        except TickError as err:
            self.get_logger().error(f"decay of '{name}' not applied: {err}", throttle_duration_sec=10.0)
        self._arm(name)

    # ------------------------------------------------------------ consultants
    def diagnostic_values(self) -> tuple[int, str, dict]:
        """``/diagnostics``: readiness, and each domain's consultant (configured, incarnation)."""
        missing = sorted(d for d, dom in self._domains.items() if not dom.configured)
        values = {f"{d}.configured": dom.configured for d, dom in sorted(self._domains.items())}
        values.update({f"{d}.incarnation": dom.incarnation for d, dom in sorted(self._domains.items())})
        if missing:
            return WARN, f"not ready: {', '.join(missing)} not configured", {"ready": False, **values}
        return OK, "ready", {"ready": True, **values}

    def _all_configured(self) -> bool:
        return all(dom.configured for dom in self._domains.values())

    def _publish_ready(self) -> None:
        """Publish ``wm_manager/ready`` when readiness or a domain's configuration changed."""
        state = {"ready": self._all_configured(),
                 "domains": {d: {"configured": dom.configured, "incarnation": dom.incarnation, "running": dom.running,
                                 "reachable": dom.alive} for d, dom in self._domains.items()},
                 "recorders": recorders_of(self)}
        if state == self._ready_sent:
            return
        self._ready_sent = state
        publish(self._ready, {**state, "time": self.now(), "pid": os.getpid(), "host": socket.gethostname()})

    # --------------------------------------------------------------- services
    async def _sync(self, request: dict) -> contract.SyncReply:
        t = self.manager.check_sync_time(request["time"], self.now())  # TickError -> error reply
        timeout = self.timeout
        deadline = wallclock.monotonic() + timeout
        if not await wait_until(self, self._all_configured, timeout, callback_group=self._client_group):
            missing = [d for d, dom in self._domains.items() if not dom.configured]
            raise CarrierError(
                f"consultant(s) not configured within {timeout:g} s: {', '.join(missing)} "
                f"(is {', '.join(manage_service(d) for d in missing)} up?)",
                kind="not-ready",
            )
        applied = {name: self._advance(name, t) for name in self._domains}
        for name in self._domains:
            self._arm(name)
        await self._links.settle(deadline)
        sharing = self.manager.sharing()
        if sharing:  # the shared pool, after the ticks (as core WMManager.advance)
            sizes = {}
            for name in sharing:
                dom = self._domains[name]
                sizes[name] = await self._links.size(dom, deadline)
            self.manager.share(sizes, t)
            await self._links.settle(deadline)
        return contract.SyncReply(time=t, memory=self.memory(), applied=applied)

    def _status(self, request: dict) -> contract.StatusReply:
        return contract.StatusReply(
            time=self.now(),
            domains=list(self._names),
            memory=self.memory(),
            configured={d: dom.configured for d, dom in self._domains.items()},
            running={d: dom.running for d, dom in self._domains.items()},
            incarnation={d: dom.incarnation for d, dom in self._domains.items()},
            next_tick={d: self.manager.next_tick(d) for d in self._domains},
            ready=self._all_configured(),
            graph=graph_identity(self),
            reachable={d: dom.alive for d, dom in self._domains.items()},
            restored={d: dom.restored for d, dom in self._domains.items()},
        )

    def memory(self) -> dict[str, dict]:
        """Each domain's effective setting (docs/semantics.md section 6 ``memory``), sorted by domain."""
        return self.manager.effective()


def main(args: Optional[list[str]] = None) -> int:
    return run_node(WMManagerNode, args)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
