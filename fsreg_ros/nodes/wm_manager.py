"""``wm_manager``: the one place that decides what each domain forgets (SPEC §2, §7).

The buffers live in the consultant processes; this node owns every domain's
forgetting policy and decay schedule and drives the consultants through their
``/consultant/<domain>/manage`` services:

* ``configure`` installs a domain's policy; the consultant trims every queue at once
  (displacement / global-capacity limits, ``none`` empties WM).  Sent when the
  consultant first answers and after every accepted parameter change.
* ``decay`` applies decay ticks.  Each decaying domain has a core
  :class:`~fsreg_ros.core.forgetting.DecayClock` (ticks at k * delta from t = 0; a new
  ``decay_period`` restarts it: next tick one new period after the change) and a
  one-shot ROS timer armed for the next tick (so it follows ``/clock`` under
  ``use_sim_time``).  Timer and barrier run the same idempotent catch-up,
  ``ticks = clock.due(now)`` (:func:`due_ticks`), so a tick is never applied twice or skipped, however
  late a timer fires or however far ``/clock`` jumps.

Parameters (all but ``domains`` changeable at run time; a change is validated as the
effective policy of every domain and rejected with a reason if any is invalid):
    ``domains`` (string array, required, read-only): the consultant domains managed;
    ``policy`` (default ``none``), ``decay_period`` (10.0 s), ``capacity`` (2),
    ``global_capacity`` (6): defaults for every domain;
    ``<domain>.policy`` (``""`` = inherit), ``<domain>.decay_period`` (0 = inherit),
    ``<domain>.capacity`` (0 = inherit), ``<domain>.global_capacity`` (0 = inherit);
    ``service_timeout`` (10.0 s): deadline of each consultant call.

Services (JSON in ``AddDiagnostics``):
    ``/wm_manager/sync`` ``{"time": t}`` -> ``{"time", "memory": {domain: policy},
    "applied": {domain: n_ticks}}``: the race-free hand-off of a scripted player.
    Applies every tick due at or before t in every domain (t from the request: no
    waiting on ``/clock``), waits until every consultant has acknowledged everything
    sent to it so far, then replies.  Before the consultants are configured it waits
    for them (up to ``service_timeout``), then replies an error.
    ``/wm_manager/status`` -> ``{"time", "domains", "memory", "configured", "next_tick"}``.
"""

from __future__ import annotations

import math
import time as wallclock
from dataclasses import dataclass, field
from functools import partial
from typing import Any, Optional

from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import InvalidServiceNameException, InvalidTopicNameException, ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.task import Future
from rclpy.validate_topic_name import validate_topic_name

from .. import contract
from ..carrier import CarrierError, JsonClient, serve, wait_until
from ..codec import NUMBER, check_fields
from ..core.forgetting import (
    RULE_PARAMETER,
    TIME_EPSILON,
    DecayClock,
    ForgettingPolicy,
    PolicyError,
    check_setting,
)
from ..contract import manage_service
from .common import StartupError, accepted, descriptor, now_seconds, rejected, run_node

#: Defaults for every domain (SPEC §5 names).
DEFAULTS: dict[str, Any] = {"policy": "none", "decay_period": 10.0, "capacity": 2, "global_capacity": 6}
#: Per-domain "inherit" markers.
UNSET: dict[str, Any] = {"policy": "", "decay_period": 0.0, "capacity": 0, "global_capacity": 0}
SETTINGS = tuple(DEFAULTS)
#: How often unconfigured consultants are looked for and stale calls expired (s).
SUPERVISE_PERIOD = 0.25
#: Most tick times sent in one decay request (see :func:`due_ticks`).
MAX_TICKS = 10_000


@dataclass
class _Domain:
    """The WM Manager's view of one domain's pool."""

    name: str
    client: JsonClient
    policy: ForgettingPolicy
    clock: Optional[DecayClock] = None
    timer: Any = None
    contacted: bool = False  # a configure has been sent
    configured: bool = False  # ... and acknowledged
    configuring: Optional[Future] = None
    inflight: list = field(default_factory=list)  # [(future, op, deadline)]


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

        self.declare_parameter("policy", DEFAULTS["policy"], descriptor(
            "default forgetting policy: none, or decay / displacement / global-capacity joined by +"))
        self.declare_parameter("decay_period", DEFAULTS["decay_period"], descriptor(
            "default decay period delta, seconds (> 0)", dynamic_typing=True))
        self.declare_parameter("capacity", DEFAULTS["capacity"], descriptor(
            "default per-entity queue limit alpha (>= 1)"))
        self.declare_parameter("global_capacity", DEFAULTS["global_capacity"], descriptor(
            "default per-domain total limit (>= 1)"))
        for name in names:
            self.declare_parameter(f"{name}.policy", UNSET["policy"], descriptor(
                f"domain '{name}' policy; '' = inherit 'policy'"))
            self.declare_parameter(f"{name}.decay_period", UNSET["decay_period"], descriptor(
                f"domain '{name}' decay period, s; 0 = inherit 'decay_period'", dynamic_typing=True))
            self.declare_parameter(f"{name}.capacity", UNSET["capacity"], descriptor(
                f"domain '{name}' queue limit; 0 = inherit 'capacity'"))
            self.declare_parameter(f"{name}.global_capacity", UNSET["global_capacity"], descriptor(
                f"domain '{name}' total limit; 0 = inherit 'global_capacity'"))
        self.declare_parameter("service_timeout", 10.0, descriptor(
            "deadline of each consultant call, and of sync's wait for configuration, s", dynamic_typing=True))

        self._names = names
        self._param_names = list(SETTINGS) + [f"{d}.{k}" for d in names for k in SETTINGS] + ["service_timeout"]
        try:
            policies = self._validate(self._values())
        except ValueError as err:
            raise StartupError(str(err)) from None

        # Callback groups: consultant clients (and their deadline timers) reentrant, so
        # their replies arrive while the barrier awaits them; the barrier services in
        # their own group, so decay timers and parameter changes are never blocked by
        # a sync waiting for a slow consultant.
        self._client_group = ReentrantCallbackGroup()
        self._barrier_group = MutuallyExclusiveCallbackGroup()
        now = self.now()
        self._domains: dict[str, _Domain] = {}
        for name in names:
            dom = _Domain(name, JsonClient(self, manage_service(name), self._client_group), policies[name])
            self._domains[name] = dom
            self._install_clock(dom, None, now)
            dom.timer = self.create_timer(1.0, partial(self._on_decay_timer, name), autostart=False)
            self._arm(dom)

        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)
        serve(self, contract.SYNC.name, self._sync, self._barrier_group)
        serve(self, contract.STATUS.name, self._status)
        self.create_timer(SUPERVISE_PERIOD, self._supervise, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            "managing " + ", ".join(f"{d}: {p.to_json()}" for d, p in policies.items()) + "; waiting for consultants"
        )
        self._supervise()

    # ------------------------------------------------------------------ time
    def now(self) -> float:
        return now_seconds(self)

    @property
    def timeout(self) -> float:
        return float(self.get_parameter("service_timeout").value)

    # ------------------------------------------------------------ parameters
    def _values(self) -> dict[str, Any]:
        return {name: self.get_parameter(name).value for name in self._param_names}

    def _validate(self, values: dict[str, Any]) -> dict[str, ForgettingPolicy]:
        """Check every managed parameter; the effective policies, or ValueError."""
        timeout = values["service_timeout"]
        if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not timeout > 0:
            raise ValueError(f"service_timeout must be a number of seconds > 0, got {timeout!r}")
        return self._effective(values)

    def _effective(self, values: dict[str, Any]) -> dict[str, ForgettingPolicy]:
        """Every domain's effective policy from parameter values; ValueError if invalid."""
        _check_global(values)
        policies = {}
        for d in self._names:
            merged = {}
            for key in SETTINGS:
                own = values[f"{d}.{key}"]
                _check_own(d, key, own)
                merged[key] = values[key] if own == UNSET[key] else own
            try:
                policies[d] = ForgettingPolicy.parse(
                    merged["policy"],
                    decay_period=float(merged["decay_period"]),
                    capacity=merged["capacity"],
                    global_capacity=merged["global_capacity"],
                )
            except PolicyError as err:
                raise ValueError(f"domain '{d}': {err}") from None
        return policies

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        values = self._values()
        touched = False
        for param in params:
            if param.name in values:
                values[param.name] = param.value
                touched = True
        if not touched:
            return accepted()
        try:
            self._validate(values)
        except ValueError as err:
            self.get_logger().warning(f"rejected parameter change: {err}")
            return rejected(str(err))
        return accepted()

    def _after_set_parameters(self, params: list[Parameter]) -> None:
        if not any(p.name in self._param_names for p in params):
            return
        policies = self._effective(self._values())
        now = self.now()
        for name, policy in policies.items():
            dom = self._domains[name]
            if policy.to_json() != dom.policy.to_json():
                self.set_policy(name, policy, now)
            else:  # only a setting its rules do not use changed: nothing to do now
                dom.policy = policy

    # ---------------------------------------------------------------- policy
    def set_policy(self, name: str, policy: ForgettingPolicy, now: float) -> None:
        """Change a domain's policy; in effect at once (as core ``WMManager.set_policy``)."""
        dom = self._domains[name]
        self._catch_up(dom, now)  # ticks due under the old schedule happen first
        old, dom.policy = dom.policy, policy
        self._install_clock(dom, old, now)
        self._arm(dom)
        self.get_logger().info(f"domain '{name}': memory {policy.to_json()}")
        if dom.contacted:
            self._configure(dom, now)

    @staticmethod
    def _install_clock(dom: _Domain, old: Optional[ForgettingPolicy], now: float) -> None:
        policy = dom.policy
        if not policy.decays:
            dom.clock = None
        elif dom.clock is None:
            # Decay switched on: ticks stay on the k * delta grid from t = 0 (as the
            # core's WMManager.set_policy); ticks before now are not owed.
            dom.clock = DecayClock(policy.decay_period, origin=0.0)  # type: ignore[arg-type]
            due_ticks(dom.clock, now)
        elif old is not None and old.decay_period != policy.decay_period:
            dom.clock.restart(policy.decay_period, now)  # type: ignore[arg-type]

    # ----------------------------------------------------------------- decay
    def _arm(self, dom: _Domain) -> None:
        """(Re)arm the domain's one-shot timer for its next tick (ROS clock)."""
        if dom.clock is None:
            dom.timer.cancel()
            return
        now_ns = self.get_clock().now().nanoseconds
        delay_ns = max(int(round(dom.clock.next_tick() * 1e9)) - now_ns, 1)
        dom.timer.timer_period_ns = delay_ns
        dom.timer.reset()

    def _on_decay_timer(self, name: str) -> None:
        dom = self._domains[name]
        self._catch_up(dom, self.now())
        self._arm(dom)

    def _catch_up(self, dom: _Domain, t: float) -> int:
        """Send every tick due at or before ``t`` not sent yet; how many."""
        if dom.clock is None:
            return 0
        ticks, count = due_ticks(dom.clock, t)
        if ticks and dom.contacted:
            # Before the first configure the consultant runs policy none: nothing to decay.
            self._send(dom, {"op": "decay", "ticks": ticks})
        return count

    # ------------------------------------------------------------ consultants
    def _send(self, dom: _Domain, payload: dict) -> Future:
        future = dom.client.send(payload)
        entry = (future, payload["op"], wallclock.monotonic() + self.timeout)
        dom.inflight.append(entry)
        future.add_done_callback(partial(self._on_reply, dom, entry))
        return future

    def _configure(self, dom: _Domain, now: float) -> None:
        policy = dom.policy
        settings = {"policy": policy.name}
        for param in RULE_PARAMETER.values():
            if getattr(policy, param) is not None:
                settings[param] = getattr(policy, param)
        dom.contacted = True
        dom.configuring = self._send(dom, {"op": "configure", "policy": settings, "time": now})

    def _on_reply(self, dom: _Domain, entry: tuple, future: Future) -> None:
        if entry in dom.inflight:
            dom.inflight.remove(entry)
        op = entry[1]
        try:
            reply = dom.client.decode(future)
        except CarrierError as err:
            self.get_logger().error(f"consultant '{dom.name}' failed '{op}': {err}")
            if op == "configure" and future is dom.configuring:
                # Start over: configure again when the consultant answers.
                dom.contacted = dom.configured = False
                dom.configuring = None
            return
        if op == "decay" and dom.configured and dom.configuring is None and reply.get("policy") != dom.policy.name:
            # The consultant lost its setting (e.g. it was restarted): configure it again.
            self.get_logger().warning(
                f"consultant '{dom.name}' runs policy {reply.get('policy')!r}, not '{dom.policy.name}': reconfiguring"
            )
            dom.configured = False
            self._configure(dom, self.now())
            return
        if op == "configure" and future is dom.configuring:
            if not dom.configured:
                self.get_logger().info(f"consultant '{dom.name}' configured: {dom.policy.to_json()}")
            dom.configured = True
            dom.configuring = None

    def _supervise(self) -> None:
        """Configure consultants that became reachable; expire unanswered calls."""
        now_wall = wallclock.monotonic()
        for dom in self._domains.values():
            for future, op, deadline in list(dom.inflight):
                if now_wall > deadline and not future.done():
                    dom.client.expire(future, self.timeout)
            if not dom.contacted and dom.client.ready():
                now = self.now()
                if dom.clock is not None:
                    due_ticks(dom.clock, now)  # ticks before the first configure are not owed (WM was empty)
                    self._arm(dom)
                self._configure(dom, now)

    def _all_configured(self) -> bool:
        return all(dom.configured for dom in self._domains.values())

    # --------------------------------------------------------------- services
    async def _sync(self, request: dict) -> dict:
        check_fields(request, {"time": NUMBER})
        t = float(request["time"])
        timeout = self.timeout
        deadline = wallclock.monotonic() + timeout
        if not await wait_until(self, self._all_configured, timeout, callback_group=self._client_group):
            missing = [d for d, dom in self._domains.items() if not dom.configured]
            raise CarrierError(
                f"consultant(s) not configured within {timeout:g} s: {', '.join(missing)} "
                f"(is {', '.join(manage_service(d) for d in missing)} up?)",
                kind="not-ready",
            )
        applied = {name: self._catch_up(dom, t) for name, dom in self._domains.items()}
        for dom in self._domains.values():
            self._arm(dom)
        # Wait for everything sent so far (this sync's ticks, a timer's, configures).
        pending = [(dom, entry[0]) for dom in self._domains.values() for entry in list(dom.inflight)]
        for dom, future in pending:
            remaining = max(deadline - wallclock.monotonic(), 0.05)
            try:
                await dom.client.result(future, remaining)
            except CarrierError as err:
                raise CarrierError(f"consultant '{dom.name}' did not apply the change: {err}", kind=err.kind) from None
        return {"time": t, "memory": self.memory(), "applied": applied}

    def _status(self, request: dict) -> dict:
        return {
            "time": self.now(),
            "domains": list(self._names),
            "memory": self.memory(),
            "configured": {d: dom.configured for d, dom in self._domains.items()},
            "next_tick": {d: (dom.clock.next_tick() if dom.clock else None) for d, dom in self._domains.items()},
        }

    def memory(self) -> dict[str, dict]:
        """Each domain's effective setting (SPEC §6 ``memory``), sorted by domain."""
        return {d: self._domains[d].policy.to_json() for d in sorted(self._domains)}


def due_ticks(clock: DecayClock, t: float, limit: int = MAX_TICKS) -> tuple[list[float], int]:
    """``DecayClock.due(t)`` without building a list of every tick after a long gap.

    Returns the times of the first ``limit`` ticks due at or before ``t`` and not yet
    applied, and how many were due; all of them are marked applied.  Sending only the
    first ``limit`` is exact: a queue holds distinct properties of the domain, so after
    as many ticks as the domain has properties every queue is empty, and nothing can
    be encoded between the ticks of one catch-up.  (A wall clock starts ~1.7e9 s after
    the origin: without this, the first catch-up would list every tick since 1970.)
    """
    elapsed = math.floor((t - clock.origin + TIME_EPSILON) / clock.period)
    count = max(elapsed - clock.applied, 0)
    first = clock.applied + 1
    times = [clock.origin + k * clock.period for k in range(first, first + min(count, limit))]
    clock.applied = max(clock.applied, elapsed)
    return times, count


def _check_global(values: dict[str, Any]) -> None:
    try:
        for key in SETTINGS:
            check_setting(key, values[key])
    except PolicyError as err:
        raise ValueError(str(err)) from None


def _check_own(domain: str, key: str, value: Any) -> None:
    """A per-domain value: its 'inherit' marker, or a valid setting."""
    inherit = value == "" if key == "policy" else (not isinstance(value, bool) and value == 0)
    if inherit:
        return
    try:
        check_setting(key, value)
    except PolicyError as err:
        raise ValueError(f"{domain}.{key}: {err} ({UNSET[key]!r} inherits '{key}')") from None


def main(args: Optional[list[str]] = None) -> int:
    return run_node(WMManagerNode, args)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
