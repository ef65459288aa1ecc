"""``consultant``: one domain's LTM and WM buffer behind its services (DIARC's consultant pattern).

One process per domain (``--ros-args -r __node:=consultant_faces -p domain:=faces -p kb:=kb.yaml``).
The node is wiring: it validates each request with the contract's models
(:mod:`fsreg_ros.contract.consultant`: ops, fields, replies), runs it through the
protocol's codec (:func:`fsreg_ros.contract.consultant_codec.apply`) on the core
:class:`~fsreg_ros.core.consultant.service.ConsultantService` (which keeps sessions, policy,
readiness, the decay mark and the state database) and publishes what came of it:
``wm/events`` (numbered ``seq`` per incarnation, only while someone subscribes; a call's
events go out right after its reply, so listening costs the caller nothing),
``wm/state`` (latched, so it always holds the current state: after every request that
changed WM, whether or not anyone listens, coalesced to at most one per ``state_period``;
a session's steps wait for its ``close``), ``ltm/assert/result``, and its announcement on
``consultant/announce`` and ``consultant/<domain>/alive`` (latched; the latter with a
1 s liveliness lease, so RR and REG learn within a second that the process died).

Facts on ``ltm/assert`` are drained and checked on the executor thread, stored by a
:class:`~fsreg_ros.core.state.fact_writer.FactWriter` thread (one fsynced transaction for every
batch waiting), then applied and answered back on the executor thread (a guard
condition), so RR and REG are answered while the disk works; the services answer the
requests waiting behind one ahead of the next round (``serve(drain=...)``).

Services: ``consultant/<domain>`` (RR, REG), ``consultant/<domain>/manage`` (the WM
Manager) and, only with ``debug`` true, ``consultant/<domain>/debug``.  Until the WM
Manager configures this incarnation, every query but ``info`` is refused with kind
``not-ready``.  Parameters are declared below with descriptions and ranges
(``ros2 param describe``); where the state lives and what survives a restart is in
docs/deployment.md ("State").
"""

from __future__ import annotations

import gc
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from time import monotonic, thread_time
from typing import Any, Optional

from rclpy.clock import Clock, ClockType
from rclpy.exceptions import InvalidServiceNameException, InvalidTopicNameException
from rclpy.node import Node
from rclpy.validate_topic_name import validate_topic_name

from ..ros.clock_parameter import fix_use_sim_time
from .. import contract
from ..contract import consultant_codec
from ..contract.codec import MessageError, printable
from ..core.consultant.consultant import Consultant
from ..core.scenario import ScenarioError, load_scenario
from ..core.state.fact_writer import FactWriter
from ..core.consultant.service import ConsultantService, NotReady, Outcome, PreparedFacts, RequestError
from ..core.state.store import DomainStore, StoreError, default_state_dir, fingerprint, legacy_state_path, state_path
from ..core.consultant.views import DEFAULT_CAPACITY, DEFAULT_PER_CLIENT, DEFAULT_TIMEOUT, ViewTable
from ..ros.asking import declare_limits
from ..ros.batches import subscribe_batches
from ..ros.carrier import CarrierError, publish, publisher
from ..ros.serving import serve
from ..ros.diagnostics import ERROR, OK, WARN
from ..ros.node_base import StartupError, declare_number, descriptor, now_seconds, run_node, watch_clock

#: Ops whose WM changes are published with the session's ``close``.
SESSION_STEPS = ("open", "narrow", "walk", "rule_out")
#: Longest a due /wm/state waits for open sessions to close, seconds.
MAX_STATE_DELAY = 1.0
#: Seconds between two writes of the alive topic (its liveliness lease is 1 s).
ALIVE_PERIOD = 0.25
#: Least seconds between two log lines about facts applied (steady clock): a stream is summarised.
FACTS_LOG_PERIOD = 5.0
#: Most requests waiting on a service answered in one go, ahead of the executor's next round (queries are not
#: served one per round behind the facts: :func:`~fsreg_ros.ros.serving.serve`'s ``drain``).
MAX_DRAIN_REQUESTS = 64
#: Most facts one ``ltm/assert`` batch takes from the messages waiting, and the most CPU seconds spent taking them
#: (RR's and REG's calls wait meanwhile; the writer thread groups batches into one commit whatever their size;
#: docs/semantics.md, "Facts in batches").
MAX_DRAIN_FACTS, MAX_DRAIN_SECONDS = 250, 0.005
#: Seconds between two takes of a stream of ``ltm/assert`` messages (the first of a stream is taken at once):
#: one fact a message at 1,000/s is then ~10 messages a round, one commit and one apply, instead of a round,
#: a commit and an apply each (:func:`~fsreg_ros.ros.batches.subscribe_batches`' ``gather``).
FACTS_GATHER = 0.01


class ConsultantNode(Node):
    """A core :class:`ConsultantService` behind its services and topics."""

    NODE_NAME = "consultant"

    def __init__(self, node_name: str = NODE_NAME, *, namespace: Optional[str] = None, **kwargs: Any) -> None:
        super().__init__(node_name, namespace=namespace, **kwargs)
        fix_use_sim_time(self)  # one clock for the whole graph
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
        self._state_period = declare_number(self, "state_period", 0.1, 0.0, 60.0,
                                            "least time between two /wm/state messages (s, steady clock)",
                                            read_only=True)
        state_dir = self._text("state_dir", "directory of the state databases ('' = $XDG_STATE_HOME/fsreg_ros)")
        self._persist_wm = self._flag("persist_wm", True,
                                      "also keep WM in the state database (false: facts and policy)")
        reset = self._flag("reset_state", False, "move the state database aside at start and begin afresh")
        debug = self._flag("debug", False, "serve consultant/<domain>/debug (holds, affirm, wm, encode, snapshot)")
        self._retract = self._flag("retract_on_update", True,
                                   "an LTM change that makes a property stop holding removes it from WM")
        self.domain = domain
        self._kb = kb
        base = Path(state_dir).expanduser() if state_dir else default_state_dir()
        self._state_path = state_path(base, self.context.get_domain_id(), self.get_fully_qualified_name(), domain)
        self._spec = spec
        self.service = self._open_state(spec, threshold, reset)
        consultant = self.service.consultant
        log = self.get_logger()
        legacy = legacy_state_path(base, self.get_fully_qualified_name(), domain)
        if self.service.persistence.restored.run is None and legacy.exists():  # a database created now
            log.warning(
                f"a state database from before ROS domain ids were part of the path is at {legacy}; "
                f"not used: move it to {self._state_path} if it belongs to this robot")
        self.service.maintain()  # compact a replayed journal now
        self._facts_logged, self._facts_unlogged = float("-inf"), [0] * 5  # see _log_facts
        self._committed = self.create_guard_condition(self._on_committed)  # the writer's batches, back here
        self._writer = self._start_writer()
        self._events = publisher(self, contract.WM_EVENTS)
        self._state = publisher(self, contract.WM_STATE)
        self._assert_results = publisher(self, contract.LTM_ASSERT_RESULT)
        self._announce = [publisher(self, contract.ANNOUNCE), publisher(self, contract.alive_topic(domain))]
        self._announced: Optional[tuple] = None
        self._announcement: dict = {}
        self._state_due, self._state_sent = False, float("-inf")
        self._unsent: list[dict] = []  # events of calls answered, published by _flush right after
        self._flush_wait = True  # every call since the last flush was a session step (wm/state waits for close)
        self._flush_guard = self.create_guard_condition(self._flush)
        services = [(contract.CONSULTANT, contract.CONSULTANT_OPS), (contract.MANAGE, contract.MANAGE_OPS)]
        if debug:
            services.append((contract.DEBUG, contract.DEBUG_OPS))
        for service, ops in services:  # each request validated once, by serve(), against its op's schema
            serve(self, service, {op: self._reset if op == "reset" else partial(self._call, op) for op in ops},
                  limits=self.limits, domain=domain, drain=MAX_DRAIN_REQUESTS)
        subscribe_batches(self, contract.LTM_ASSERT, self._on_asserts, reject=self._reject_assert, limits=self.limits,
                          accept=lambda data: not isinstance(data.get("domain"), str) or data["domain"] == self.domain,
                          size=lambda data: len(data.get("facts") or ()) or 1, max_size=MAX_DRAIN_FACTS,
                          max_seconds=MAX_DRAIN_SECONDS, clock=thread_time, gather=FACTS_GATHER)
        self.add_post_set_parameters_callback(self._after_set_parameters)
        self._clock_watch = watch_clock(self)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timer = self.create_timer(max(self._state_period, 0.02), self._tick, clock=steady)
        # Across processes DDS keeps the alive topic's liveliness itself; a reader in this
        # process (a composed graph) sees it only through writes: repeat the announcement.
        self._alive_timer = self.create_timer(ALIVE_PERIOD, lambda: publish(self._announce[1], self._announcement),
                                              clock=steady)
        self.publish_state()
        gc.freeze()  # the KB's objects live as long as the node: keep the cyclic GC off them
        self.announce()
        log.info(f"consultant of '{domain}': {len(consultant.entities)} entities, {len(consultant.preference)} "
                 f"properties, threshold {threshold:g}, from {kb}" + (" (debug service on)" if debug else ""))

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

    def _start_writer(self) -> FactWriter:
        """Start the thread that stores this incarnation's facts (each group of batches in one fsynced commit)."""
        store = self.service.persistence.store_facts
        return FactWriter(lambda batches: store([fact for b in batches for fact in b.prepared.stored]),
                          self._committed.trigger, name=f"facts-{self.domain}")

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
        self._settle_all()  # every fact in flight applied and answered before the state is set aside
        self._writer.close()
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
            self._writer = self._start_writer()
        self._spec = spec
        self.service.maintain()
        restored = self.service.persistence.restored
        self.get_logger().warning(printable(
            f"state reset by {request.get('client') or 'a client'}: {cleared['runtime_facts']} runtime facts, "
            f"{cleared['queues']} WM queues set aside in {restored.moved_aside}; incarnation "
            f"{self.service.incarnation} serves {self._kb} afresh"))
        self.publish_state()
        self.announce()
        return {"incarnation": self.service.incarnation, "moved_aside": restored.moved_aside, "cleared": cleared,
                "state": self.service.status()}

    # ----------------------------------------------------------------- calls
    def _call(self, op: str, request: dict) -> dict:
        """Run one validated request (its ``op``), publish what came of it; return the reply."""
        client = request.get("client") or ""
        outcome = self._guarded(lambda listening: consultant_codec.apply(self.service, op, request, client, listening))
        if op == "info":
            outcome.reply["event_listeners"] = self._events.get_subscription_count()
        self._published(outcome, wait=op in SESSION_STEPS)
        return outcome.reply

    def _guarded(self, run) -> Outcome:
        """Run a service call with the current listener state; translate its refusals for the carrier."""
        try:
            return run(self._events.get_subscription_count() > 0)
        except NotReady as err:
            raise CarrierError(str(err), kind="not-ready") from None
        except RequestError as err:
            raise MessageError(str(err)) from None
        finally:
            self._log_notices()

    def _published(self, outcome: Outcome, wait: bool = False, later: bool = True) -> None:
        """Publish what came of a call right after its reply (the executor's next step: :meth:`_flush`).

        A call's events (a dozen per turn, hundreds for a decay tick) cost the call's caller
        nothing this way: measured while a recorder listened, publishing them before the
        reply added their cost to every RR and REG round trip.  Their order, their ``seq``
        and what follows them (``wm/state``, the announcement) are unchanged.
        ``later=False``: the caller flushes itself once its answers are out (no round of its own).
        """
        self._unsent.extend(outcome.events)
        if outcome.changes.wm:
            self._state_due = True
        self._flush_wait = self._flush_wait and wait
        if later:
            self._flush_guard.trigger()

    def _flush(self) -> None:
        """Publish the events of the calls answered since the last flush, a due ``wm/state``, the announcement."""
        events, self._unsent = self._unsent, []
        for event in events:
            publish(self._events, event)
        wait, self._flush_wait = self._flush_wait, True
        if not wait:
            self._publish_due()
        self.announce(only_if_changed=True)

    # ------------------------------------------------------------- LTM topic
    def _reject_assert(self, request_id: Any, error: str, kind: str = "bad-request") -> None:
        reply = {"domain": None, "consultant": self.domain, "entity": None, "ok": False, "error": error, "kind": kind}
        if request_id is not None:
            reply["id"] = request_id
        publish(self._assert_results, reply)

    def _on_asserts(self, messages: list[dict]) -> None:
        """Prepare ``ltm/assert`` messages of this domain as ONE batch and hand it to the writer thread.

        They were routed by ``accept``, validated and drained together by
        :func:`~fsreg_ros.ros.batches.subscribe_batches`.  A message holds one entity's facts
        or a batch (``facts``); every fact of every message is one fact of one
        :meth:`~fsreg_ros.core.consultant.service.ConsultantService.prepare_facts` (all-or-nothing per
        fact, checked against LTM as the batches already in flight leave it).  The
        :class:`~fsreg_ros.core.state.fact_writer.FactWriter` stores it (with whatever else
        waits, in one fsynced transaction) while this thread serves RR and REG;
        :meth:`_on_committed` then applies it and answers each message.
        """
        facts: list[tuple[str, dict]] = []
        for data in messages:
            facts.extend(_facts_of(data))
        try:
            prepared = self.service.prepare_facts(facts)
        except RequestError as err:
            raise MessageError(str(err)) from None
        try:
            self._writer.submit(_Submitted(messages, prepared, self.service))
        except RuntimeError as err:  # the writer is closed (shutting down): nothing stored, nothing applied
            self.service.abandon_facts(prepared)
            raise CarrierError(f"not stored: {err}", kind="not-stored") from None

    def _on_committed(self) -> None:
        """Apply and answer the batches the writer is done with, up to MAX_DRAIN_FACTS a round (queries go between).

        What they changed is published right after their answers, in this round (at 1,000
        single facts/s a flush of its own cost an executor round per batch).
        """
        facts = 0
        while facts < MAX_DRAIN_FACTS and (done := self._writer.take_done(1)):
            submitted, error = done[0]
            facts += max(1, len(submitted.prepared.facts))
            try:
                self._settle(submitted, error)
            except Exception as err:  # noqa: BLE001 - a guard condition's error would stop the node: answer, serve on
                text = printable(f"internal error: {type(err).__name__}: {err}")
                self.get_logger().error(f"{contract.LTM_ASSERT.name}: {text}")
                for data in submitted.messages:
                    self._answer_assert(data, ok=False, error=text, kind="internal")
        self._flush()
        if self._writer.has_done():
            self._committed.trigger()

    def _settle(self, submitted: "_Submitted", error: Optional[StoreError]) -> None:
        """Apply a committed batch and answer each of its messages, or answer them all ``not-stored``."""
        messages, prepared = submitted.messages, submitted.prepared
        log = self.get_logger()
        if submitted.service is not self.service:  # stored before a reset set that database aside: not served
            error = StoreError("the state was reset before this batch was applied; it is in the database set aside")
        if error is not None:  # memory unchanged: nothing was applied
            submitted.service.abandon_facts(prepared)
            log.error(printable(f"{contract.LTM_ASSERT.name}: not stored ({len(prepared.facts)} facts): {error}"))
            for data in messages:
                self._answer_assert(data, ok=False, error=printable(f"not stored: {error}"), kind="not-stored")
            return
        outcome = self._guarded(lambda listening: self.service.apply_facts(prepared, listening=listening))
        results = iter(outcome.reply["results"])
        for data in messages:
            mine = [next(results) for _ in range(len(data["facts"]) if data.get("facts") is not None else 1)]
            for result in mine:
                if not result["ok"]:
                    log.warning(printable(f"{contract.LTM_ASSERT.name}: {result['error']}"))
            if data.get("facts") is None:
                self._answer_assert(data, **{k: v for k, v in mine[0].items() if k != "entity"})
            else:
                applied = sum(r["ok"] for r in mine)
                self._answer_assert(data, ok=applied == len(mine), results=mine, applied=applied,
                                    refused=len(mine) - applied)
        applied = outcome.reply["applied"]
        if applied:
            new = sum(1 for _, _, is_new in outcome.changes.facts if is_new)
            retracted = sum(len(r.get("retracted") or ()) for r in outcome.reply["results"] if r["ok"])
            self._log_facts(outcome, applied, len(messages), new, retracted)
            self._published(outcome, later=False)  # _on_committed flushes once the round's answers are out

    def _log_facts(self, outcome: Outcome, applied: int, messages: int, new: int, retracted: int) -> None:
        """Log what a batch changed: at once after a quiet FACTS_LOG_PERIOD, else in the period's summary.

        A perception stream would otherwise log hundreds of lines a second (and rclpy's
        logging, which inspects the caller's frame, cost a tenth of the consultant's CPU).
        """
        now = monotonic()
        if now - self._facts_logged >= FACTS_LOG_PERIOD and not self._facts_unlogged[0]:
            self._facts_logged = now
            if applied == 1:
                entity, updated, is_new = outcome.changes.facts[0]
                self.get_logger().info(printable(
                    f"LTM {'added' if is_new else 'updated'} '{entity}': {updated}"
                    + (f", retracted {retracted} propert{'y' if retracted == 1 else 'ies'}" if retracted else "")))
            else:
                self.get_logger().info(f"LTM: {applied} facts applied in one batch ({messages} messages, {new} new "
                                       f"entities, {retracted} properties retracted)")
            return
        for i, n in enumerate((applied, 1, messages, new, retracted)):
            self._facts_unlogged[i] += n

    def _log_facts_summary(self) -> None:
        """Log the facts applied since the last line, once FACTS_LOG_PERIOD has passed (the timer calls it)."""
        now = monotonic()
        if self._facts_unlogged[0] and now - self._facts_logged >= FACTS_LOG_PERIOD:
            facts, batches, messages, new, retracted = self._facts_unlogged
            self.get_logger().info(f"LTM: {facts} facts applied in {batches} batches in the last "
                                   f"{now - self._facts_logged:.1f} s ({messages} messages, {new} new entities, "
                                   f"{retracted} properties retracted)")
            self._facts_unlogged = [0] * 5
            self._facts_logged = now

    def _settle_all(self) -> None:
        """Wait for the writer, then apply and answer every batch in flight (before LTM changes otherwise)."""
        self._writer.flush()
        for submitted, error in self._writer.take_done():
            self._settle(submitted, error)

    def _answer_assert(self, data: dict, **fields: Any) -> None:
        reply: dict[str, Any] = {"domain": self.domain}
        if data.get("facts") is None:
            reply["entity"] = data.get("entity")
        if "id" in data:
            reply["id"] = data["id"]
        reply.update(fields)
        publish(self._assert_results, reply)

    def _after_set_parameters(self, params) -> None:
        for param in params:
            if param.name == "threshold" and float(param.value) != self.service.consultant.threshold:
                self._settle_all()  # the facts in flight were checked against the old threshold
                outcome = self._guarded(lambda listening: self.service.set_threshold(
                    float(param.value), listening=listening))
                retracted = outcome.reply["retracted"]
                self.get_logger().info(f"threshold {float(param.value):g}"
                                       + (f", retracted {retracted}" if retracted else ""))
                self._published(outcome)

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

    def announce(self, only_if_changed: bool = False) -> None:
        """Announce this incarnation, whether it serves, the policy it runs and its stored state."""
        s = self.service
        message = {"domain": self.domain, "incarnation": s.incarnation, "ready": s.ready,
                   "memory": s.policy.to_json(), "state": s.status()}
        key = (s.ready, str(message["memory"]), str(message["state"]))
        if only_if_changed and key == self._announced:
            return
        self._announced, self._announcement = key, message
        for pub in self._announce:
            publish(pub, message)

    def publish_state(self) -> None:
        """``/wm/state``: this domain's non-empty queues, LRU first."""
        self._state_due, self._state_sent = False, monotonic()
        s = self.service
        publish(self._state, {"domain": self.domain, "time": s.time, "queues": s.buffer.snapshot(), "events": s.seq,
                              "incarnation": s.incarnation, "wm_version": s.wm_version})

    def _publish_due(self, waiting: bool = False) -> None:
        """Publish a due /wm/state unless one went out less than ``state_period`` ago.

        Published whether or not anyone reads it now: the topic is latched, so the sample
        DDS keeps for a late joiner (``ros2 topic echo --once``) must be the current state,
        never an older one.  ``state_period`` coalesces: a burst of changes costs one
        message, and the timer sends the last one once the period has passed.
        ``waiting`` (the timer): also wait while a session is open, for at most a second.
        """
        now = monotonic()
        if not self._state_due or now - self._state_sent < self._state_period:
            return
        sessions = self.service.sessions
        sessions.expire(now)
        if waiting and len(sessions) and now - self._state_sent < MAX_STATE_DELAY:
            return
        self.publish_state()

    def _tick(self) -> None:
        self._log_facts_summary()
        self._publish_due(waiting=True)
        self.service.maintain()
        self._log_notices()
        self.announce(only_if_changed=True)

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
        writer = getattr(self, "_writer", None)
        if writer is not None:  # what was submitted is stored; answered if the node still can
            writer.close()
            try:
                for submitted, error in writer.take_done():
                    self._settle(submitted, error)
            except Exception as err:  # noqa: BLE001 - shutting down: the facts are stored, the answers may not go
                self.get_logger().warning(printable(f"{contract.LTM_ASSERT.name}: stored, not answered at shutdown: "
                                                    f"{type(err).__name__}: {err}"))
        if getattr(self, "_unsent", None):
            self._flush()  # stopping: what was answered is published
        service = getattr(self, "service", None)
        if service is not None:
            service.shutdown()
        super().destroy_node()


@dataclass
class _Submitted:
    """A batch handed to the writer: its messages (to answer), the prepared facts and the service that made them."""

    messages: list[dict]
    prepared: PreparedFacts
    service: ConsultantService

    @property
    def generation(self) -> int:
        return self.prepared.generation


def _facts_of(data: dict) -> list[tuple[str, dict]]:
    """Return the facts of a validated ``ltm/assert``: (entity, properties) per fact, in order."""
    if data.get("facts") is not None:
        return [(fact["entity"], fact["properties"]) for fact in data["facts"]]
    return [(data["entity"], data["properties"])]


def main(args: Optional[list[str]] = None) -> int:
    return run_node(ConsultantNode, args)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
