"""``wm_manager``: the ROS wrapper of the core WM Manager (docs/semantics.md sections 2 and 7).

The buffers live in the consultant processes; what each domain forgets, and when,
is decided by the core :class:`~fsreg_ros.core.wm_manager.WMManager` (policies,
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
* ``decay`` sends a run of ticks ``{"origin", "period", "first", "count"}``: a few
  numbers however many ticks, so a clock far ahead costs what one tick costs.

Time: the decay grid starts at the node's clock when it starts managing (under
``use_sim_time`` that is 0 until the first ``/clock``, so a scripted replay ticks
at k * delta from t = 0, as the simulator does); ticks fall at origin + k * delta,
and a new ``decay_period`` restarts the grid at the change.  A one-shot ROS timer is
armed for each domain's next tick.  A clock that goes backwards applies nothing
(ticks are never undone or applied twice) and is logged once; under ``use_sim_time``
a clock that does not move is reported (``common.watch_clock``).

Parameters (all but ``domains`` changeable at run time; a change is validated as the
effective policy of every domain and rejected with a reason if any is invalid;
unsetting a parameter or changing its type is refused, by rclpy's static typing):
    ``domains`` (string array, required, read-only): the consultant domains managed;
    one parameter per memory setting (``policy``, ``decay_period``, ``capacity``, ...:
    the settings table :mod:`fsreg_ros.core.settings`, with its defaults, bounds as
    declared ranges, and help as descriptions): the setting of every domain;
    ``<domain>.<setting>`` the same per domain, defaulting to the table's inherit marker
    (``""``, 0, or -1 for ``seed``: use the node-wide value), the range widened to it;
    ``service_timeout`` (10.0 s, in [0.01, 3600]): deadline of each consultant call.

Services (JSON in ``AddDiagnostics``):
    ``/wm_manager/sync`` ``{"time": t}`` -> ``{"time", "memory": {domain: policy},
    "applied": {domain: n_ticks}}``: the race-free hand-off of a scripted player.
    Applies every tick due at or before t in every domain (t from the request: no
    waiting on ``/clock``), waits until every consultant has acknowledged everything
    sent to it so far; then, if any domain has ``shared-capacity``, asks the pool's
    consultants their sizes and sends the evictions the core decides (``evict``),
    and waits for those too; then replies.  A t that is not finite, beyond 1e12 s, or more
    than a day (``core.wm_manager.SYNC_AHEAD``) ahead of the node's clock is rejected
    with a reason and changes nothing.  Before the consultants are configured it
    waits for them (up to ``service_timeout``), then replies an error.
    ``/wm_manager/status`` -> ``{"time", "domains", "memory", "configured", "running",
    "incarnation", "next_tick"}``: ``memory`` is each domain's setting from the
    parameters; ``running`` what its consultant last acknowledged (configure reply) or
    announced, null until known; ``configured`` true once the consultant's current
    incarnation has acknowledged the current setting.

Topics: in ``consultant/announce`` (latched) from every consultant.
"""

from __future__ import annotations

import time as wallclock
from dataclasses import dataclass, field
from functools import partial
from typing import Any, Optional

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    InvalidServiceNameException,
    InvalidTopicNameException,
    ParameterUninitializedException,
)
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.task import Future
from rclpy.validate_topic_name import validate_topic_name

from .. import contract
from ..carrier import CarrierError, JsonClient, serve, subscribe, wait_until
from ..contract import manage_service
from ..core.decay import TIME_EPSILON, TickError, TickRun
from ..core import settings
from ..core.forgetting import ForgettingPolicy, PolicyError, check_setting
from ..core.wm_manager import WMManager
from .common import StartupError, accepted, descriptor, now_seconds, rejected, run_node, watch_clock

#: The memory settings, each a node-wide parameter and one per domain (core/settings.py).
SETTINGS = settings.names()
#: Range of ``service_timeout``, seconds.
TIMEOUT_RANGE = (0.01, 3600.0)
#: How often unconfigured consultants are looked for and stale calls expired (s).
SUPERVISE_PERIOD = 0.25
#: Longest one-shot timer delay, ns (rcl timers take an int64 period).
MAX_DELAY_NS = 10**18


def setting_descriptor(key: str, domain: Optional[str] = None) -> ParameterDescriptor:
    """Return a memory setting's descriptor, from its row of the settings table.

    A numeric setting's range is its bounds; a per-domain setting's range is widened
    down to its inherit marker (which is below the bounds, so it is never a real value).
    """
    row = settings.setting(key)
    text = row.description
    if domain is not None:
        text = f"domain '{domain}' {text}; {row.inherit!r} = inherit '{key}'"
    out = ParameterDescriptor(description=text)
    if not row.is_parameter:
        return out
    low = row.inherit if domain is not None else row.low
    if row.kind is float:
        out.floating_point_range = [FloatingPointRange(from_value=float(low), to_value=float(row.high), step=0.0)]
    else:
        out.integer_range = [IntegerRange(from_value=int(low), to_value=int(row.high), step=1)]
    if domain is not None:
        out.additional_constraints = f"{row.inherit!r} (inherit) or {row.bounds_text}"
    return out


@dataclass
class _Domain:
    """The transport state of one domain's consultant."""

    name: str
    client: JsonClient
    timer: Any = None
    configured: bool = False  # a configure has been acknowledged by the current incarnation
    configuring: Optional[Future] = None
    inflight: list = field(default_factory=list)  # [(future, payload, deadline)]
    incarnation: Optional[int] = None  # the consultant's, from its announce or configure reply
    running: Optional[dict] = None  # the policy it acknowledged or announced


class _ManagePort:
    """The core manager's :class:`~fsreg_ros.core.wm_manager.MemoryPort` in the graph.

    Each decision becomes a request to the consultant's manage service.
    """

    def __init__(self, node: "WMManagerNode") -> None:
        self.node = node

    def configure(self, domain: str, policy: ForgettingPolicy, time: float) -> None:
        dom = self.node._domains[domain]
        dom.configuring = self.node._send(dom, {"op": "configure", "policy": policy.settings(), "time": time})

    def decay(self, domain: str, ticks: TickRun) -> None:
        self.node._send(self.node._domains[domain], {"op": "decay", "ticks": ticks.to_json()})

    def evict(self, domain: str, count: int, time: float) -> None:
        self.node._send(self.node._domains[domain], {"op": "evict", "count": count, "time": time})

    def sizes(self, domains: list[str]) -> None:
        return None  # needs service calls: the sync barrier asks, then calls manager.share


class WMManagerNode(Node):
    """Forgetting policies and decay schedules of every managed domain."""

    NODE_NAME = "wm_manager"

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(self.NODE_NAME, **kwargs)
        self.declare_parameter(
            "domains",
            Parameter.Type.STRING_ARRAY,
            descriptor("consultant domains to manage (one consultant node each)", read_only=True),
        )
        try:
            names = [d for d in (self.get_parameter("domains").value or []) if d]
        except ParameterUninitializedException:
            names = []
        if not names:
            raise StartupError("parameter 'domains' must name at least one consultant domain")
        if len(set(names)) != len(names):
            raise StartupError(f"parameter 'domains' names a domain twice: {names}")
        for name in names:
            try:
                validate_topic_name(manage_service(name), is_service=True)
            except (InvalidServiceNameException, InvalidTopicNameException):
                raise StartupError(f"domain {name!r} cannot be part of a ROS service name") from None
            if name in SETTINGS or name == "service_timeout":
                raise StartupError(f"domain {name!r} clashes with a parameter name")

        self._names = names
        self._param_names = list(SETTINGS) + [f"{d}.{k}" for d in names for k in SETTINGS] + ["service_timeout"]
        timeout = ParameterDescriptor(
            description="deadline of each consultant call, and of sync's wait for configuration, s",
            floating_point_range=[FloatingPointRange(from_value=TIMEOUT_RANGE[0], to_value=TIMEOUT_RANGE[1], step=0.0)],
        )
        try:
            for row in settings.TABLE:
                self.declare_parameter(row.name, row.default, setting_descriptor(row.name))
            for name in names:
                for row in settings.TABLE:
                    self.declare_parameter(f"{name}.{row.name}", row.inherit, setting_descriptor(row.name, name))
            self.declare_parameter("service_timeout", 10.0, timeout)
            policies = self._effective(self._values())
        except (InvalidParameterTypeException, InvalidParameterValueException) as err:
            raise StartupError(" ".join(str(err).split())) from None
        except ValueError as err:
            raise StartupError(str(err)) from None

        # Callback groups: consultant clients (and their deadline timers) reentrant, so
        # their replies arrive while the barrier awaits them; the barrier services in
        # their own group, so decay timers and parameter changes are never blocked by
        # a sync waiting for a slow consultant.
        self._client_group = ReentrantCallbackGroup()
        self._barrier_group = MutuallyExclusiveCallbackGroup()
        now = self.now()
        self._latest = now
        self._warned_backwards = False
        self._domains: dict[str, _Domain] = {}
        self.manager = WMManager(_ManagePort(self), origin=now)
        for name in names:
            self._domains[name] = _Domain(name, JsonClient(self, manage_service(name), self._client_group))
            self.manager.manage_domain(name, policies[name], now)
            self._domains[name].timer = self.create_timer(1.0, partial(self._on_decay_timer, name), autostart=False)
            self._arm(name)

        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)
        serve(self, contract.SYNC, self._sync, self._barrier_group)
        serve(self, contract.STATUS, self._status)
        subscribe(self, contract.ANNOUNCE, self._on_announce)
        self._clock_watch = watch_clock(self)
        self.create_timer(SUPERVISE_PERIOD, self._supervise, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f"managing (decay grid from t = {now:g}) "
            + ", ".join(f"{d}: {p.to_json()}" for d, p in policies.items())
            + "; waiting for consultants"
        )
        self._supervise()

    # ------------------------------------------------------------------ time
    def now(self) -> float:
        return now_seconds(self)

    @property
    def timeout(self) -> float:
        return float(self.get_parameter("service_timeout").value)

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
    def _values(self) -> dict[str, Any]:
        return {name: self.get_parameter(name).value for name in self._param_names}

    def _effective(self, values: dict[str, Any]) -> dict[str, ForgettingPolicy]:
        """Every domain's effective policy from parameter values; ValueError if invalid."""
        try:
            for key in SETTINGS:
                check_setting(key, values[key])
        except PolicyError as err:
            raise ValueError(str(err)) from None
        policies = {}
        for d in self._names:
            merged = {}
            for row in settings.TABLE:
                key = row.name
                own = values[f"{d}.{key}"]
                if own != row.inherit:
                    try:
                        check_setting(key, own)
                    except PolicyError as err:
                        raise ValueError(f"{d}.{key}: {err} ({row.inherit!r} inherits '{key}')") from None
                merged[key] = values[key] if own == row.inherit else own
            try:
                policies[d] = ForgettingPolicy.from_settings(merged)
            except PolicyError as err:
                raise ValueError(f"domain '{d}': {err}") from None
        return policies

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        values = self._values()
        touched = False
        for param in params:
            if param.name not in values:
                continue
            values[param.name] = param.value
            touched = True
        if not touched:
            return accepted()
        try:
            self._effective(values)
        except ValueError as err:
            self.get_logger().warning(f"rejected parameter change: {err}")
            return rejected(str(err))
        return accepted()

    def _after_set_parameters(self, params: list[Parameter]) -> None:
        if not any(p.name in self._param_names and p.name != "service_timeout" for p in params):
            return
        try:
            policies = self._effective(self._values())
            now = self.now()
            for name, policy in policies.items():
                if policy.to_json() != self.manager.domains[name].policy.to_json():
                    self._advance(name, now)
                    self.manager.set_policy(name, policy, now)
                    self._arm(name)
                    self.get_logger().info(f"domain '{name}': memory {policy.to_json()}")
        except (ValueError, TickError) as err:  # validated above: only a clock fault gets here
            self.get_logger().error(f"parameter change not applied: {err}")

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
    def _send(self, dom: _Domain, payload: dict) -> Future:
        future = dom.client.send(payload)
        entry = (future, payload, wallclock.monotonic() + self.timeout)
        dom.inflight.append(entry)
        future.add_done_callback(partial(self._on_reply, dom, entry))
        return future

    def _on_reply(self, dom: _Domain, entry: tuple, future: Future) -> None:
        if entry in dom.inflight:
            dom.inflight.remove(entry)
        payload = entry[1]
        op = payload["op"]
        try:
            reply = dom.client.decode(future)
        except CarrierError as err:
            self.get_logger().error(f"consultant '{dom.name}' failed '{op}': {err}")
            if op == "decay":  # maybe never applied: owed again (the consultant skips what it applied)
                self.manager.owe(dom.name, TickRun.from_json(payload["ticks"]))
            if op in ("decay", "configure"):
                # Start over: attach again when the consultant answers or announces itself.
                self.manager.detach(dom.name)
                dom.configured = False
                dom.configuring = None
            return
        policy = self.manager.domains[dom.name].policy
        if op == "configure" and future is dom.configuring:
            dom.running = reply.get("memory")
            if isinstance(reply.get("incarnation"), int):
                dom.incarnation = reply["incarnation"]
            if not dom.configured:
                self.get_logger().info(
                    f"consultant '{dom.name}' (incarnation {dom.incarnation}) configured: {dom.running}")
            dom.configured = dom.running == policy.to_json()
            dom.configuring = None

    def _on_announce(self, announce: dict) -> None:
        """Attach a consultant's new incarnation at once (it (re)started); note what a configured one runs."""
        dom = self._domains.get(announce["domain"])
        if dom is None:
            return  # not managed here
        incarnation = announce["incarnation"]
        if announce["ready"] and incarnation == dom.incarnation:
            dom.running = announce.get("memory")
            return
        if incarnation == dom.incarnation and (dom.configuring is not None or dom.configured):
            return  # already being configured
        self.get_logger().info(
            f"consultant '{dom.name}' announced incarnation {incarnation} (was {dom.incarnation}), "
            f"running {announce.get('memory')}: configuring it")
        dom.incarnation = incarnation
        dom.running = announce.get("memory")
        dom.configured = False
        self.manager.detach(dom.name)
        self._attach(dom)

    def _attach(self, dom: _Domain) -> None:
        try:
            self.manager.attach(dom.name, None, self.now())
        except TickError as err:
            self.get_logger().error(f"consultant '{dom.name}' not attached: {err}", throttle_duration_sec=10.0)
        self._arm(dom.name)

    def _supervise(self) -> None:
        """Attach consultants that became reachable; expire unanswered calls."""
        now_wall = wallclock.monotonic()
        for dom in self._domains.values():
            for future, _, deadline in list(dom.inflight):
                if now_wall > deadline and not future.done():
                    dom.client.expire(future, self.timeout)
            if not self.manager.domains[dom.name].attached and dom.client.ready():
                self._attach(dom)

    def _all_configured(self) -> bool:
        return all(dom.configured for dom in self._domains.values())

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
        await self._settle(deadline)
        sharing = self.manager.sharing()
        if sharing:  # the shared pool, after the ticks (as core WMManager.advance)
            sizes = {}
            for name in sharing:
                dom = self._domains[name]
                reply = await self._await(dom, self._send(dom, {"op": "size"}), deadline)
                sizes[name] = reply["size"]
            self.manager.share(sizes, t)
            await self._settle(deadline)
        return contract.SyncReply(time=t, memory=self.memory(), applied=applied)

    async def _settle(self, deadline: float) -> None:
        """Wait for everything sent so far (ticks, a timer's, configures, evictions)."""
        pending = [(dom, entry[0]) for dom in self._domains.values() for entry in list(dom.inflight)]
        for dom, future in pending:
            await self._await(dom, future, deadline)

    async def _await(self, dom: _Domain, future: Future, deadline: float) -> dict:
        remaining = max(deadline - wallclock.monotonic(), 0.05)
        try:
            return await dom.client.result(future, remaining)
        except CarrierError as err:
            raise CarrierError(f"consultant '{dom.name}' did not apply the change: {err}", kind=err.kind) from None

    def _status(self, request: dict) -> contract.StatusReply:
        return contract.StatusReply(
            time=self.now(),
            domains=list(self._names),
            memory=self.memory(),
            configured={d: dom.configured for d, dom in self._domains.items()},
            running={d: dom.running for d, dom in self._domains.items()},
            incarnation={d: dom.incarnation for d, dom in self._domains.items()},
            next_tick={d: self.manager.next_tick(d) for d in self._domains},
        )

    def memory(self) -> dict[str, dict]:
        """Each domain's effective setting (docs/semantics.md section 6 ``memory``), sorted by domain."""
        return self.manager.effective()


def main(args: Optional[list[str]] = None) -> int:
    return run_node(WMManagerNode, args)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
