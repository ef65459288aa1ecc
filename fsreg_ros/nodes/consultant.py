"""``consultant``: one domain's LTM and WM buffer behind its services (DIARC's consultant pattern).

One process per domain (``--ros-args -r __node:=consultant_faces -p domain:=faces -p kb:=kb.yaml``).
The node is wiring: it validates each request with the contract's models
(:mod:`fsreg_ros.contract.consultant`: ops, fields, replies), runs it through the
protocol's codec (:func:`fsreg_ros.ros.consultant_ops.apply`) on the core
:class:`~fsreg_ros.core.consultant.service.ConsultantService` (which keeps sessions, policy,
readiness, the decay mark and the state database) and publishes what came of it
(:class:`~fsreg_ros.ros.consultant_outbox.ConsultantOutbox`: ``wm/events``, ``wm/state``,
``consultant/announce`` and ``consultant/<domain>/alive``).  Facts on ``ltm/assert`` are
drained, checked, stored off the serving thread, applied and answered by
:class:`~fsreg_ros.ros.fact_intake.FactIntake`, so RR and REG are answered while the disk
works; the services answer the requests waiting behind one ahead of the next round
(``serve(drain=...)``).

Services: ``consultant/<domain>`` (RR, REG), ``consultant/<domain>/manage`` (the WM
Manager) and, only with ``debug`` true, ``consultant/<domain>/debug``.  Until the WM
Manager configures this incarnation, every query but ``info`` is refused with kind
``not-ready``.  Parameters are declared below with descriptions and ranges
(``ros2 param describe``); where the state lives and what survives a restart is in
docs/deployment.md ("State").
"""

from __future__ import annotations

import gc
from functools import partial
from pathlib import Path
from typing import Any, Optional

from rclpy.clock import Clock, ClockType
from rclpy.exceptions import InvalidServiceNameException, InvalidTopicNameException
from rclpy.node import Node
from rclpy.validate_topic_name import validate_topic_name

from ..ros.clock_parameter import fix_use_sim_time
from .. import contract
from ..contract import consultant_codec
from ..ros.consultant_ops import apply
from ..contract.codec import MessageError, printable
from ..core.consultant.consultant import Consultant
from ..core.scenario import ScenarioError, load_scenario
from ..core.consultant.service import ConsultantService, NotReady, Outcome, RequestError
from ..core.state.store import DomainStore, StoreError, default_state_dir, fingerprint, legacy_state_path, state_path
from ..core.consultant.views import DEFAULT_CAPACITY, DEFAULT_PER_CLIENT, DEFAULT_TIMEOUT, ViewTable
from ..ros.asking import declare_limits
from ..ros.carrier import CarrierError
from ..ros.consultant_outbox import ConsultantOutbox
from ..ros.diagnostics import ERROR, OK, WARN
from ..ros.fact_intake import FactIntake
from ..ros.node_base import StartupError, declare_number, descriptor, now_seconds, run_node, watch_clock
from ..ros.serving import serve

#: Ops whose WM changes are published with the session's ``close``.
SESSION_STEPS = ("open", "narrow", "walk", "rule_out")
#: Seconds between two writes of the alive topic (its liveliness lease is 1 s).
ALIVE_PERIOD = 0.25
#: Most requests waiting on a service answered in one go, ahead of the executor's next round (queries are not
#: served one per round behind the facts: :func:`~fsreg_ros.ros.serving.serve`'s ``drain``).
MAX_DRAIN_REQUESTS = 64


class ConsultantNode(Node):
    """A core :class:`ConsultantService` behind its services and topics."""

    NODE_NAME = "consultant"

    def __init__(self, node_name: str = NODE_NAME, *, namespace: Optional[str] = None, **kwargs: Any) -> None:
        super().__init__(node_name, namespace=namespace, **kwargs)
        fix_use_sim_time(self)  # one clock for the whole graph
        spec, threshold, reset, debug, state_period = self._declare()
        self.service = self._open_state(spec, threshold, reset)
        self._warn_legacy_state()
        self.service.maintain()  # compact a replayed journal now
        self.outbox = ConsultantOutbox(self, self.domain, lambda: self.service, state_period)
        self.facts = FactIntake(self, self.limits, self.outbox)
        services = [(contract.CONSULTANT, contract.CONSULTANT_OPS), (contract.MANAGE, contract.MANAGE_OPS)]
        if debug:
            services.append((contract.DEBUG, contract.DEBUG_OPS))
        for service, ops in services:  # each request validated once, by serve(), against its op's schema
            serve(self, service, {op: self._reset if op == "reset" else partial(self._call, op) for op in ops},
                  limits=self.limits, domain=self.domain, drain=MAX_DRAIN_REQUESTS)
        self.add_post_set_parameters_callback(self._after_set_parameters)
        self._clock_watch = watch_clock(self)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timer = self.create_timer(max(state_period, 0.02), self._tick, clock=steady)
        # Across processes DDS keeps the alive topic's liveliness itself; a reader in this
        # process (a composed graph) sees it only through writes: repeat the announcement.
        self._alive_timer = self.create_timer(ALIVE_PERIOD, self.outbox.alive, clock=steady)
        self.outbox.publish_state()
        gc.freeze()  # the KB's objects live as long as the node: keep the cyclic GC off them
        self.outbox.announce()
        consultant = self.service.consultant
        self.get_logger().info(
            f"consultant of '{self.domain}': {len(consultant.entities)} entities, {len(consultant.preference)} "
            f"properties, threshold {threshold:g}, from {self._kb}" + (" (debug service on)" if debug else ""))

    def _declare(self) -> tuple:
        """Declare the parameters, load the domain; (spec, threshold, reset, debug, state_period)."""
        domain = self._text("domain", "the domain this consultant owns (required)")
        kb = self._text("kb", "scenario/KB YAML file with the domain's LTM (required)")
        if not domain or not kb:
            raise StartupError(f"parameter '{'domain' if not domain else 'kb'}' is required "
                               "(e.g. -p domain:=faces -p kb:=kb.yaml)")
        try:
            validate_topic_name(contract.consultant_service(domain), is_service=True)
        except (InvalidServiceNameException, InvalidTopicNameException):
            raise StartupError(f"domain {domain!r} cannot be part of a ROS service name") from None
        try:
            spec = load_scenario(kb).domains.get(domain)
        except (ScenarioError, OSError) as err:
            raise StartupError(str(err)) from None
        if spec is None:
            raise StartupError(f"{kb}: no domain '{domain}'")
        threshold = declare_number(self, "threshold", float(spec.threshold), 0.0, 1.0,
                                   "a property holds iff its certainty >= threshold (default: the KB's)")
        self.limits = declare_limits(self)
        self._session_limits = (
            declare_number(self, "max_sessions", DEFAULT_CAPACITY, 1, 100_000, "open RR/REG sessions kept at most",
                           integer=True, read_only=True),
            declare_number(self, "session_timeout", DEFAULT_TIMEOUT, 0.01, 3600.0,
                           "a session unused this long (s, steady clock) is dropped", read_only=True),
            declare_number(self, "max_sessions_per_client", DEFAULT_PER_CLIENT, 1, 100_000,
                           "open sessions per client (one more drops that client's least recently used)",
                           integer=True, read_only=True))
        state_period = declare_number(self, "state_period", 0.1, 0.0, 60.0,
                                      "least time between two /wm/state messages (s, steady clock)", read_only=True)
        state_dir = self._text("state_dir", "directory of the state databases ('' = $XDG_STATE_HOME/fsreg_ros)")
        self._persist_wm = self._flag("persist_wm", True,
                                      "also keep WM in the state database (false: facts and policy)")
        reset = self._flag("reset_state", False, "move the state database aside at start and begin afresh")
        debug = self._flag("debug", False, "serve consultant/<domain>/debug (holds, affirm, wm, encode, snapshot)")
        self._retract = self._flag("retract_on_update", True,
                                   "an LTM change that makes a property stop holding removes it from WM")
        self.domain, self._kb, self._spec = domain, kb, spec
        self._state_base = Path(state_dir).expanduser() if state_dir else default_state_dir()
        self._state_path = state_path(self._state_base, self.context.get_domain_id(), self.get_fully_qualified_name(),
                                      domain)
        return spec, threshold, reset, debug, state_period

    def _warn_legacy_state(self) -> None:
        legacy = legacy_state_path(self._state_base, self.get_fully_qualified_name(), self.domain)
        if self.service.persistence.restored.run is None and legacy.exists():  # a database created now
            self.get_logger().warning(
                f"a state database from before ROS domain ids were part of the path is at {legacy}; "
                f"not used: move it to {self._state_path} if it belongs to this robot")

    def _open_state(self, spec, threshold: float, reset: bool, after: int = 0) -> ConsultantService:
        """Build the domain's consultant from ``spec`` and take up its state database (``reset``: moved aside first).

        Raises StartupError naming the database when it cannot be used; logs what was restored.
        """
        consultant = Consultant(self.domain, spec.entities, spec.preference, threshold, attributes=spec.attributes,
                                retract_on_update=self._retract, exclusive=spec.exclusive)
        path = self._state_path
        kb_digest = fingerprint(spec.preference, spec.entities, spec.threshold, spec.attributes, spec.exclusive)
        store = DomainStore(path, kb_digest)
        clock = "sim" if self.get_parameter("use_sim_time").value else "system"
        service = ConsultantService(consultant, sessions=ViewTable(*self._session_limits), store=store,
                                    persist_wm=self._persist_wm, clock=clock, now=self.now)
        try:
            stored = store.open(reset=reset, after=after)
            restored = service.restore(stored)
        except StoreError as err:
            store.close()
            raise StartupError(str(err)) from None
        log = self.get_logger()
        if stored.moved_aside is not None:
            log.warning(f"reset_state: {path} moved to {stored.moved_aside}; starting afresh")
        if restored.migrated:
            log.warning(printable(f"state {path}: {restored.summary()}", 4000))
        else:
            log.info(printable(f"state {path}: {restored.summary()}"))
        return service

    def _reset(self, request: dict) -> dict:
        """Manage op ``reset``: set the state database aside, serve the KB file's domain afresh (a new incarnation).

        The KB file is read again (a file that no longer loads, or lost the domain, is
        refused and nothing changes); the old state is checkpointed, its database moved
        aside (never deleted), WM and the runtime facts are gone, and the new incarnation
        is announced (not ready until the WM Manager configures it).
        """
        try:
            spec = load_scenario(self._kb).domains.get(self.domain)
        except (ScenarioError, OSError) as err:
            raise MessageError(f"reset refused, nothing changed: {err}") from None
        if spec is None:
            raise MessageError(f"reset refused, nothing changed: {self._kb} has no domain '{self.domain}' any more")
        self.facts.pause()  # every fact in flight applied and answered before the state is set aside
        old = self.service
        cleared = {**old.consultant.differences(self._spec.entities),
                   "queues": len(old.buffer.nonempty_entities())}
        threshold = float(self.get_parameter("threshold").value)
        old.shutdown()  # a last checkpoint: the database set aside holds everything
        try:
            self.service = self._open_state(spec, threshold, reset=True, after=old.incarnation)
        except StartupError as err:  # the old database is still in place: serve it again
            self.get_logger().error(printable(f"reset failed: {err}; serving the old state again"))
            self.service = self._open_state(self._spec, threshold, reset=False, after=old.incarnation)
            raise CarrierError(printable(f"reset failed: {err}; the old state is served again"),
                               kind="not-stored") from None
        finally:
            self.facts.resume()
        self._spec = spec
        self.service.maintain()
        restored = self.service.persistence.restored
        self.get_logger().warning(printable(
            f"state reset by {request.get('client') or 'a client'}: {cleared['runtime_facts']} runtime facts, "
            f"{cleared['queues']} WM queues set aside in {restored.moved_aside}; incarnation "
            f"{self.service.incarnation} serves {self._kb} afresh"))
        self.outbox.publish_state()
        self.outbox.announce()
        return consultant_codec.reset_reply(self.service.incarnation, restored.moved_aside, cleared,
                                            self.service.status())

    # ----------------------------------------------------------------- calls
    def _call(self, op: str, request: dict) -> dict:
        """Run one validated request (its ``op``), publish what came of it; return the reply."""
        outcome = self.guarded(lambda listening: apply(self.service, op, request, listening))
        if op == "info":
            consultant_codec.with_listeners(outcome.reply, self.outbox.listeners())
        self.outbox.published(outcome, wait=op in SESSION_STEPS)
        return outcome.reply

    def guarded(self, run) -> Outcome:
        """Run a service call with the current listener state; translate its refusals for the carrier."""
        try:
            return run(self.outbox.listeners() > 0)
        except NotReady as err:
            raise CarrierError(str(err), kind="not-ready") from None
        except RequestError as err:
            raise MessageError(str(err)) from None
        finally:
            self._log_notices()

    def _after_set_parameters(self, params) -> None:
        for param in params:
            if param.name == "threshold" and float(param.value) != self.service.consultant.threshold:
                self.facts.settle_all()  # the facts in flight were checked against the old threshold
                outcome = self.guarded(lambda listening: self.service.set_threshold(
                    float(param.value), listening=listening))
                retracted = outcome.reply["retracted"]
                self.get_logger().info(f"threshold {float(param.value):g}"
                                       + (f", retracted {retracted}" if retracted else ""))
                self.outbox.published(outcome)

    # ----------------------------------------------------------- publishing
    def diagnostic_values(self) -> tuple[int, str, dict]:
        """``/diagnostics``: readiness, WM sizes and the state database's health."""
        health = self.service.health()
        buffer = self.service.buffer
        values = {"domain": self.domain, "ready": self.service.ready, "entities_in_wm": len(buffer.nonempty_entities()),
                  "wm_properties": len(buffer), **health}
        if not health["last_write_ok"]:
            return ERROR, f"the last write to the state database failed, retrying: {health['store_error']}", values
        if not self.service.ready:
            return WARN, "not configured by the WM Manager yet", values
        return OK, "ready", values

    def now(self) -> float:
        return now_seconds(self)

    def _tick(self) -> None:
        self.facts.log.summary()
        self.outbox.publish_due(waiting=True)
        self.service.maintain()
        self._log_notices()
        self.outbox.announce(only_if_changed=True)

    def _log_notices(self) -> None:
        notices, self.service.notices = self.service.notices, []
        for level, text in notices:  # one call site per severity: rclpy refuses to mix them
            if level == "warning":
                self.get_logger().warning(printable(text))
            else:
                self.get_logger().info(printable(text))

    # ------------------------------------------------------------ parameters
    def _text(self, name: str, description: str) -> str:
        return self.declare_parameter(name, "", descriptor(description, read_only=True)).value

    def _flag(self, name: str, default: bool, description: str) -> bool:
        return bool(self.declare_parameter(name, default, descriptor(description, read_only=True)).value)

    def destroy_node(self) -> None:
        facts = getattr(self, "facts", None)
        if facts is not None:  # what was submitted is stored; answered if the node still can
            facts.close()
        outbox = getattr(self, "outbox", None)
        if outbox is not None and outbox.unsent:
            outbox.flush()  # stopping: what was answered is published
        service = getattr(self, "service", None)
        if service is not None:
            service.shutdown()
        super().destroy_node()


def main(args: Optional[list[str]] = None) -> int:
    return run_node(ConsultantNode, args)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
