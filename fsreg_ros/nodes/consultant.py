"""``consultant``: one domain's LTM and WM buffer (DIARC's consultant pattern).

One process per domain (give each its own node name, e.g.
``--ros-args -r __node:=consultant_faces -p domain:=faces -p kb:=kb.yaml``).

Parameters
    ``domain`` (string, required, read-only), ``kb`` (scenario/KB YAML, required,
    read-only), ``threshold`` (number in [0, 1]; default: the KB's threshold for the
    domain; changeable at run time; it changes what holds, it does not touch WM), the
    size limits ``max_message_bytes``, ``max_name_chars``, ``max_list_items``, and (all
    read-only) ``max_sessions`` (open RR/REG sessions, default 64), ``session_timeout``
    (s unused before a session is dropped, default 30) and ``state_period`` (least s
    between two ``wm/state`` messages, default 0.1).

Services (JSON in ``AddDiagnostics``, names and schemas in :mod:`fsreg_ros.contract`)
    ``consultant/<domain>`` -- queries from RR and REG, ``{"op": ...}``:
      ``info`` ``{"entities_from"?}`` -> ``{"domain", "entities", "entity_count", "preference",
      "threshold", "policy", "memory", "events", "version"}`` (entities from index
      ``entities_from`` on: they are only ever appended)
      ``open`` ``{"target"?, "context"?, "first"?}`` -> ``{"session", "size", "queue", "retains",
      "holding", "first"?, "version"}``: a session holding RR's candidates (no target) or
      REG's distractors; ``first`` (``{"property", "cause", "time"?, "turn"?}``) narrows it at
      once (RR's first property), its ``{"target_holds", "size"}`` in the reply
      ``narrow`` ``{"session", "property", "cause" (null: no encoding), "time"?, "turn"?}`` ->
      ``{"target_holds", "size", "version"}``: rules 2 and 3 (one call per considered property)
      ``rule_out`` ``{"session"}`` -> ``{"properties", "masks", "version"}`` (baselines; hex bitmasks
      by member rank)
      ``close`` ``{"session", "encode"?, "time"?, "turn"?}`` -> ``{"members", "version"}``: ends
      the session; ``encode`` is rule 1 for the target, or for a session's only member
      ``holds`` ``{"property", "entities"}`` -> ``{"holds"}`` (no encoding)
      ``affirm`` ``{"property", "entities", "cause", "time"?, "turn"?}`` -> ``{"holds"}``
      ``wm`` ``{"entity"}`` -> ``{"queue"}`` (LRU first; reading never refreshes)
      ``encode`` ``{"entity", "properties", "cause", "time"?, "turn"?}`` -> ``{}``
      ``snapshot`` -> ``{"queues", "events"}`` (non-empty queues only)
    ``consultant/<domain>/manage`` -- the WM Manager's:
      ``configure`` ``{"policy": {"policy", "decay_period"?, "capacity"?,
      "global_capacity"?, "seed"?}, "time"?}`` -> ``{"memory", "queues_changed",
      "incarnation"}``: installs the policy and trims every queue at once (``none``
      empties WM, cause ``reset``; the policy already installed changes nothing);
      ``decay`` ``{"ticks": {"origin", "period", "first", "count"}}`` ->
      ``{"queues_changed", "policy"}``: decay ticks (Algorithm 2) at ``origin + k *
      period`` for k = first .. first + count - 1, applied now (at most as many as
      the longest queue holds can pop anything; ticks at or before the last one
      applied are skipped); ``policy`` is the installed policy's name;
      ``evict`` ``{"count", "time"?}`` -> ``{"queues_changed", "size"}``: forget the
      domain's ``count`` least recently encoded fronts (cause ``shared-capacity``);
      ``size`` -> ``{"size"}``: how many properties WM holds.

Sessions (docs/semantics.md sections 3 and 4 keep their order: members are visited in entity
order) are kept at most ``max_sessions`` at once (the least recently used is dropped)
and for ``session_timeout`` seconds unused, so a caller that dies leaks nothing.
``version`` (``"<incarnation>:<LTM changes>"``) changes when LTM does (``ltm/assert``,
``threshold``) or the consultant restarts: callers cache the preference order and the
entity list until it does.

``wm/events`` is a volatile topic: while it has no subscriber nothing is sent (and
RR's and REG's encodings take the buffer's quiet path, building no events), so
``events`` is how many ``/wm/events`` messages this consultant has published so far:
a listener that must have every event (a trace) asks ``info`` after the last change
and waits until it has heard that many from the domain (topics are not ordered with
respect to service replies or to each other).  Unknown entities and properties are
refused by the core :class:`~fsreg_ros.core.consultant.Consultant`; the node only
translates its ``KnowledgeError`` into the error reply.

Encoding causes are ``speaker``, ``rr`` and ``reg-distractor``.  ``time`` defaults to
the node's clock, ``turn`` to null.  Every request is validated before anything
changes; a rejected one gets ``{"error", "kind"}`` (kind ``KnowledgeError`` for an
unknown entity or property, ``MessageError`` for a malformed request).

Topics
    out ``wm/events`` -- every encode/forget event (docs/semantics.md section 2), one message each;
    out ``wm/state`` (latched) ``{"domain", "time", "queues", "events"}`` -- at start
    and at most once per request that changed WM (after the op, or, for a session, at its
    ``close``) and per ``state_period``, while someone subscribes (a late joiner gets the
    current state within ``state_period``; ``wm/events`` carries every single change);
    in ``ltm/assert`` ``{"domain", "entity", "properties": {name: certainty}, "id"?}``
    -- messages for other domains are ignored; out ``ltm/assert/result``
    ``{"domain", "entity", "ok", "new_entity", "updated", "retracted", "id"?}`` or
    ``{"domain", "entity", "ok": false, "error", "id"?}``.

Until the WM Manager configures it the consultant runs policy ``none``: it retains
nothing (a buffer without a policy would retain everything, unmanaged).

Recovery (:mod:`fsreg_ros.core.store`): ``state_dir`` (string, read-only; default
``$XDG_STATE_HOME/fsreg_ros``, i.e. ``~/.local/state/fsreg_ros``) holds one SQLite
database per consultant, ``<state_dir>/<node's full name>/<domain>.sqlite3``, created
on first use.  Facts accepted on ``ltm/assert`` are written there before the result
is published; with ``persist_wm`` (bool, default true) so is every change to WM, in
one transaction per request, before the reply.  At start the consultant reads it back
(the KB's runtime facts, entities added at run time, WM, the installed policy, the
last decay tick applied), counts a new *incarnation* and publishes
``consultant/announce`` (latched) ``{"domain", "incarnation", "ready": false,
"memory"}``.  Until the WM Manager configures it in this incarnation, every query op
but ``info`` is answered with kind ``not-ready``; each ``configure`` is acknowledged
with ``{"memory", "queues_changed", "incarnation"}`` and announced with ``ready``
true.  ``decay`` skips the ticks at or before the last one applied, so ticks sent
again after a restart are applied once.
"""

from __future__ import annotations

import gc
import secrets
from time import monotonic
from pathlib import Path
from typing import Any, Callable, Optional

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.exceptions import InvalidServiceNameException, InvalidTopicNameException
from rclpy.validate_topic_name import validate_topic_name

from .. import contract
from ..carrier import CarrierError, publish, publisher, serve, subscribe
from ..codec import NUMBER, MessageError, check_fields, printable
from ..contract import consultant_service, manage_service
from ..core.consultant import CandidateSet, Consultant, KnowledgeError, Step, close_view, open_view
from ..core.decay import TickError, TickRun
from ..core.forgetting import NONE, ForgettingPolicy
from ..core.memory import ENCODE_CAUSES, WMEvent
from ..core.store import SUFFIX, DomainStore, StoreError, default_state_dir, fingerprint
from ..core.wm_manager import apply_ticks, configure_buffer, unapplied
from ..core.scenario import ScenarioError, load_scenario
from ..core.sessions import DEFAULT_CAPACITY, SessionTable
from ..core.sessions import DEFAULT_TIMEOUT as DEFAULT_SESSION_TIMEOUT
from .asking import declare_limits
from .common import StartupError, declare_number, descriptor, now_seconds, run_node, watch_clock

TIME = {"time": NUMBER, "turn": (int, None)}
#: Ops that change WM within a session: /wm/state waits for the session's close.
SESSION_STEPS = ("open", "narrow", "rule_out")
#: Ops whose replies carry the LTM ``version``.
VERSIONED_OPS = ("info", "open", "narrow", "rule_out", "close")
#: Default least time between two /wm/state messages, seconds.
DEFAULT_STATE_PERIOD = 0.1
#: Longest a due /wm/state waits for open sessions to close, seconds.
MAX_STATE_DELAY = 1.0
POLICY_FIELDS = {"policy": str}
POLICY_OPTIONAL = {
    "decay_period": (NUMBER, None),
    "capacity": (int, None),
    "global_capacity": (int, None),
    "seed": (int, None),
}


class ConsultantNode(Node):
    """A core :class:`Consultant` behind two JSON services and the LTM/WM topics."""

    NODE_NAME = "consultant"
    _pending_meta: tuple = (None, None)  # (decay_until, policy settings) the current request changed

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(self.NODE_NAME, **kwargs)
        self.declare_parameter("domain", "", descriptor("the domain this consultant owns (required)", read_only=True))
        self.declare_parameter(
            "kb", "", descriptor("scenario/KB YAML file with the domain's LTM (required)", read_only=True)
        )
        domain = self.get_parameter("domain").value
        kb = self.get_parameter("kb").value
        if not domain:
            raise StartupError("parameter 'domain' is required (e.g. -p domain:=faces)")
        if not kb:
            raise StartupError("parameter 'kb' is required (a scenario/KB YAML file)")
        try:
            validate_topic_name(consultant_service(domain), is_service=True)
        except (InvalidServiceNameException, InvalidTopicNameException):
            raise StartupError(f"domain {domain!r} cannot be part of a ROS service name") from None
        try:
            scenario = load_scenario(kb)
        except (ScenarioError, OSError) as err:
            raise StartupError(str(err)) from None
        spec = scenario.domains.get(domain)
        if spec is None:
            raise StartupError(f"{kb}: no domain '{domain}' (domains: {', '.join(scenario.domains) or 'none'})")
        threshold = declare_number(
            self, "threshold", float(spec.threshold), 0.0, 1.0,
            "a property holds iff its certainty >= threshold (default: the KB's)",
        )
        self.limits = declare_limits(self)
        self.sessions: SessionTable[CandidateSet] = SessionTable(
            declare_number(self, "max_sessions", DEFAULT_CAPACITY, 1, 100_000,
                           "open RR/REG sessions kept at most (opening one more drops the least recently used)",
                           integer=True, read_only=True),
            declare_number(self, "session_timeout", DEFAULT_SESSION_TIMEOUT, 0.01, 3600.0,
                           "a session unused this long (s, steady clock) is dropped", read_only=True),
        )
        self._incarnation = secrets.token_hex(4)  # so callers notice a restart
        self._state_period = declare_number(
            self, "state_period", DEFAULT_STATE_PERIOD, 0.0, 60.0,
            "least time between two /wm/state messages (s, steady clock); a change within it is "
            "published at its end", read_only=True)
        self.declare_parameter("state_dir", "", descriptor(
            "directory of the state databases ('' = $XDG_STATE_HOME/fsreg_ros)", read_only=True))
        self.declare_parameter("persist_wm", True, descriptor(
            "write every WM change to the state database before replying (false: only LTM facts and the "
            "policy survive a crash)", read_only=True))
        self.persist_wm = bool(self.get_parameter("persist_wm").value)

        self.domain = domain
        self._events = publisher(self, contract.WM_EVENTS)
        self._state = publisher(self, contract.WM_STATE)
        self._assert_results = publisher(self, contract.LTM_ASSERT_RESULT)
        self._announce = publisher(self, contract.ANNOUNCE)
        self._event_count = 0  # /wm/events messages published
        self._listened = True  # whether /wm/events has a subscriber (checked per request)
        self._state_due = False  # WM changed since the last /wm/state
        self._state_sent = float("-inf")  # monotonic time of the last /wm/state
        self._last_time = 0.0  # time of the latest change, for /wm/state
        self._dirty: dict[str, None] = {}  # entities whose queues changed during the current request
        self._muted = False
        self.consultant = Consultant(
            domain, spec.entities, spec.preference, threshold, sink=self._on_event, attributes=spec.attributes
        )
        # Retain nothing until the WM Manager says otherwise.
        self.policy = NONE
        configure_buffer(self.consultant.wm, NONE, 0.0)
        self.ready = False  # configured by the WM Manager in this incarnation
        self.decay_until = float("-inf")
        self.store = self._open_store(spec, self.get_parameter("state_dir").value)

        self.add_post_set_parameters_callback(self._after_set_parameters)
        self._query_ops: dict[str, Callable[[dict], dict]] = {
            "info": self._info,
            "open": self._open,
            "narrow": self._narrow,
            "rule_out": self._rule_out,
            "close": self._close,
            "holds": self._holds,
            "affirm": self._affirm,
            "wm": self._wm,
            "encode": self._encode,
            "snapshot": self._snapshot,
        }
        self._manage_ops: dict[str, Callable[[dict], dict]] = {
            "configure": self._configure,
            "decay": self._decay,
            "evict": self._evict,
            "size": self._size,
        }
        size = self.limits.max_message_bytes
        serve(self, consultant_service(domain), lambda req: self._dispatch(req, self._query_ops), max_bytes=size)
        serve(self, manage_service(domain), lambda req: self._dispatch(req, self._manage_ops), max_bytes=size)
        subscribe(self, contract.LTM_ASSERT, self._on_assert, reject=self._reject_assert, max_bytes=size)
        self._clock_watch = watch_clock(self)
        self._state_timer = self.create_timer(max(self._state_period, 0.02), lambda: self._publish_due(True),
                                              clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.publish_state(self.now())
        # The KB's objects live as long as the node: keep the cyclic GC from scanning
        # them again and again (a full collection over 10,000 entities' facts costs ms).
        gc.freeze()
        self.announce()
        self.get_logger().info(
            f"consultant of '{domain}': {len(self.consultant.entities)} entities, "
            f"{len(self.consultant.preference)} properties, threshold {threshold:g}, from {kb}"
        )

    # ----------------------------------------------------------------- helpers
    def now(self) -> float:
        return now_seconds(self)

    def _on_event(self, event: WMEvent) -> None:
        if self._muted:
            return
        self._dirty[event.entity] = None
        self._state_due = True
        if self._listened:  # a volatile topic nobody reads: nothing to send
            self._event_count += 1
            publish(self._events, event.to_json())

    def _check_listeners(self) -> None:
        self._listened = self._events.get_subscription_count() > 0

    def _publish_due(self, waiting: bool = False) -> None:
        """Publish a /wm/state that is due, unless one went out less than ``state_period`` ago.

        ``waiting`` (the timer): also wait while a session is open (its close publishes),
        for at most a second (a caller that never closes must not hold the state back).
        While ``wm/state`` has no subscriber the state stays due: a late joiner gets the
        latched start state at once and the current one within ``state_period``.
        """
        now = monotonic()
        if not self._state_due or now - self._state_sent < self._state_period:
            return
        if not self._state.get_subscription_count():
            return  # nobody reads it now: the timer sends it once someone subscribes
        self.sessions.expire(now)
        if waiting and len(self.sessions) and now - self._state_sent < MAX_STATE_DELAY:
            return
        self.publish_state(self._last_time)

    # ------------------------------------------------------------- recovery
    def _open_store(self, spec, state_dir: str) -> DomainStore:
        """Open the domain's state database and restore what it holds (LTM facts, WM, policy)."""
        base = Path(state_dir).expanduser() if state_dir else default_state_dir()
        path = base / self.get_fully_qualified_name().strip("/") / f"{self.domain}{SUFFIX}"
        store = DomainStore(path, fingerprint(spec.preference, spec.entities, spec.threshold, spec.attributes))
        try:
            state = store.open()
        except StoreError as err:
            raise StartupError(str(err)) from None
        if state.discarded is not None:
            self.get_logger().warning(f"{path} was written for another KB: moved to {state.discarded}, starting fresh")
        self.incarnation = state.incarnation
        self._muted = True  # restoring is not news: no events
        try:
            for entity in state.entities + [e for e in state.facts if e not in state.entities]:
                if entity in state.facts:
                    self.consultant.assert_facts(entity, state.facts[entity], 0.0)
            if state.policy is not None:
                self.policy = ForgettingPolicy.from_settings(state.policy)
            if self.persist_wm:
                self.consultant.wm.restore(state.queues, state.stamp, state.ticks, self.policy.limits())
                self.decay_until = state.decay_until
            else:
                configure_buffer(self.consultant.wm, self.policy, 0.0)
        except (KnowledgeError, ValueError) as err:
            raise StartupError(f"{path}: cannot restore: {err}") from None
        finally:
            self._muted = False
        self.get_logger().info(
            f"state {path}: incarnation {state.incarnation}, {len(state.entities)} runtime entities, "
            f"{sum(len(f) for f in state.facts.values())} runtime facts, {len(state.queues)} WM queues"
            + ("" if self.persist_wm else " (persist_wm false: WM not restored)")
        )
        return store

    def destroy_node(self) -> None:
        store = getattr(self, "store", None)
        if store is not None:
            store.close()
        super().destroy_node()

    def announce(self) -> None:
        """``consultant/announce``: this incarnation, whether it serves, and the policy it runs."""
        publish(self._announce, {"domain": self.domain, "incarnation": self.incarnation, "ready": self.ready,
                                 "memory": self.policy.to_json()})

    def _persist(self, decay_until: Optional[float] = None, policy: Optional[dict] = None) -> None:
        """Write the queues changed by the current request (and the counters) before the reply."""
        dirty, self._dirty = self._dirty, {}
        if not self.persist_wm:
            if policy is not None:
                self.store.save_wm({}, self.consultant.wm.counters(), policy=policy)
            return
        if not dirty and decay_until is None and policy is None:
            return
        wm = self.consultant.wm
        self.store.save_wm({e: wm.export_queue(e) for e in dirty}, wm.counters(), decay_until, policy)

    def publish_state(self, time: float) -> None:
        """``/wm/state``: this domain's non-empty queues, LRU first."""
        self._state_due = False
        self._state_sent = monotonic()
        publish(
            self._state,
            {"domain": self.domain, "time": time, "queues": self.consultant.wm.snapshot(), "events": self._event_count},
        )

    def _dispatch(self, request: dict, ops: dict[str, Callable[[dict], dict]]) -> dict:
        op = check_fields(request, {"op": str})["op"]
        handler = ops.get(op)
        if handler is None:
            raise MessageError(f"unknown op {printable(repr(op), 80)} (known: {', '.join(ops)})")
        contract.check_sizes(request, self.limits, names=("entity", "property", "cause", "target", "session"),
                             lists=("entities", "properties", "context", "encode"))
        if ops is self._query_ops and not self.ready and op != "info":
            raise CarrierError(
                f"consultant '{self.domain}' (incarnation {self.incarnation}) is not configured by the WM Manager "
                "yet; try again", kind="not-ready")
        self._check_listeners()
        self._dirty = {}
        try:
            reply = handler(request)
        finally:  # a handler that changed WM and then failed still persists what changed
            self._persist(*self._pending_meta)
            self._pending_meta = (None, None)
        # /wm/state at most once per request (a session's steps wait for its close) and
        # at most once per state_period (the timer sends what is left due).
        if op not in SESSION_STEPS:
            self._publish_due()
        if op in VERSIONED_OPS:
            reply["version"] = f"{self._incarnation}:{self.consultant.version}"
        return reply

    def _time(self, request: dict) -> tuple[float, Optional[int]]:
        """Return the request's ``time`` (default: now) and ``turn`` (default: null)."""
        check_fields(request, {}, TIME)
        time = float(request["time"]) if request.get("time") is not None else self.now()
        self._last_time = time
        return time, request.get("turn")

    @staticmethod
    def _encode_cause(cause: str) -> str:
        if cause not in ENCODE_CAUSES:
            raise MessageError(f"field 'cause': expected one of {', '.join(ENCODE_CAUSES)}, got {cause!r}")
        return cause

    # ------------------------------------------------------------- query ops
    def _info(self, request: dict) -> dict:
        contract.check(contract.InfoRequest, request)
        start = request.get("entities_from") or 0
        if start < 0:
            raise MessageError(f"field 'entities_from': expected a whole number >= 0, got {start}")
        c = self.consultant
        policy = self.policy
        return {
            "domain": self.domain,
            "entities": c.entities[start:],
            "entity_count": len(c.entities),
            "preference": list(c.preference),
            "threshold": c.threshold,
            "policy": policy.name,
            "memory": policy.to_json(),
            "events": self._event_count,
        }

    def _open(self, request: dict) -> dict:
        contract.check(contract.OpenRequest, request)
        step = request.get("first")
        first = None
        if step is not None:
            contract.check_sizes(step, self.limits, names=("property", "cause"))
            if step["cause"] is not None:
                self._encode_cause(step["cause"])
            when, turn = self._time(step)
            first = Step(step["property"], step["cause"], when, turn)
        # The session is stored only once everything (the first step too) succeeded.
        view = self._quietly(open_view, self.consultant, request.get("target"), request.get("context"), first)
        if first is not None and first.cause is not None and view.first.target_holds and view.first.size:
            self._state_due = self._state_due or self.consultant.wm.retains
        session = self.sessions.open(view.handle, monotonic())
        holding = None if view.holding is None else [p for p in self.consultant.preference if p in view.holding]
        reply = {"session": session, "size": view.size, "queue": view.queue, "retains": view.retains,
                 "holding": holding, "origins": [{"cause": c, "turn": t} for c, t in view.origins]}
        if view.first is not None:
            reply["first"] = {"target_holds": view.first.target_holds, "size": view.first.size}
        return reply

    def _narrow(self, request: dict) -> dict:
        contract.check(contract.NarrowRequest, request)
        cause = request["cause"]
        if cause is not None:
            self._encode_cause(cause)
        when, turn = self._time(request)
        candidates = self.sessions.get(request["session"], monotonic())
        # Consultant.narrow validates the property before anything changes.
        holds = self._quietly(self.consultant.narrow, candidates, request["property"], cause, when, turn)
        if holds and cause is not None and candidates.members and self.consultant.wm.retains:
            self._state_due = True
        return {"target_holds": holds, "size": candidates.size}

    def _quietly(self, action: Callable[..., Any], *args: Any) -> Any:
        """Run ``action(*args)``; with nobody listening to /wm/events, without an event sink.

        Rule 2 and 3 encodings then take the buffer's quiet path (no event objects).
        """
        buffer = self.consultant.wm
        sink = buffer.sink
        if not self._listened and not self.persist_wm:  # persistence needs the events (dirty queues)
            buffer.sink = None
        try:
            return action(*args)
        finally:
            buffer.sink = sink

    def _rule_out(self, request: dict) -> dict:
        contract.check(contract.RuleOutRequest, request)
        props, masks = self.consultant.rule_out(self.sessions.get(request["session"], monotonic()))
        return {"properties": props, "masks": [format(mask, "x") for mask in masks]}

    def _close(self, request: dict) -> dict:
        contract.check(contract.CloseRequest, request)
        when, turn = self._time(request)
        candidates = self.sessions.get(request["session"], monotonic())
        members = close_view(self.consultant, candidates, request.get("encode") or (), when, turn)
        self.sessions.close(request["session"], monotonic())
        return {"members": members}

    def _holds(self, request: dict) -> dict:
        contract.check(contract.HoldsRequest, request)
        return {"holds": self.consultant.holds(request["property"], request["entities"])}

    def _affirm(self, request: dict) -> dict:
        contract.check(contract.AffirmRequest, request)
        self._encode_cause(request["cause"])
        time, turn = self._time(request)
        # Consultant.affirm validates the property and every entity before encoding.
        return {"holds": self.consultant.affirm(request["property"], request["entities"], request["cause"], time, turn)}

    def _wm(self, request: dict) -> dict:
        contract.check(contract.WMRequest, request)
        return {"queue": self.consultant.queue(request["entity"])}

    def _encode(self, request: dict) -> dict:
        contract.check(contract.EncodeRequest, request)
        self._encode_cause(request["cause"])
        time, turn = self._time(request)
        self.consultant.encode(request["entity"], request["properties"], request["cause"], time, turn)
        return {}

    def _snapshot(self, request: dict) -> dict:
        return {"queues": self.consultant.wm.snapshot(), "events": self._event_count}

    # ------------------------------------------------------------ manage ops
    def _configure(self, request: dict) -> dict:
        check_fields(request, {"policy": dict})
        check_fields(request["policy"], POLICY_FIELDS, POLICY_OPTIONAL)
        policy = ForgettingPolicy.from_settings(request["policy"])  # PolicyError -> error reply, nothing installed
        time, _ = self._time(request)
        buffer = self.consultant.wm
        before = buffer.snapshot()
        if policy != self.policy:  # the same policy again (a restart's reconfigure) changes nothing
            configure_buffer(buffer, policy, time)
            self.policy = policy
            self._pending_meta = (None, policy.settings())
            self.get_logger().info(f"memory policy {policy.to_json()}")
        newly = not self.ready
        self.ready = True
        if newly:
            self.get_logger().info(f"configured by the WM Manager (incarnation {self.incarnation}): serving")
            self.announce()
        return {"memory": policy.to_json(), "queues_changed": _changed(before, buffer.snapshot()),
                "incarnation": self.incarnation}

    def _decay(self, request: dict) -> dict:
        check_fields(request, {"ticks": dict})
        try:
            ticks = TickRun.from_json(request["ticks"])
        except TickError as err:
            raise MessageError(f"field 'ticks': {err}") from None
        buffer = self.consultant.wm
        before = buffer.snapshot()
        # Applied now (the buffer is lazy otherwise), so the events and the state go
        # out now, in the canonical order; ticks already applied (sent again after a
        # restart) are skipped.
        due = unapplied(ticks, self.decay_until)
        if due is not None:
            apply_ticks(buffer, due, self.consultant.entities)
            self.decay_until = due.last
            self._pending_meta = (due.last, None)
        self._last_time = ticks.last
        return {"queues_changed": _changed(before, buffer.snapshot()), "policy": self.policy.name}

    def _evict(self, request: dict) -> dict:
        check_fields(request, {"count": int})
        if request["count"] < 0:
            raise MessageError(f"field 'count': expected a whole number >= 0, got {request['count']}")
        time, _ = self._time(request)
        buffer = self.consultant.wm
        before = buffer.snapshot()
        buffer.evict_oldest(request["count"], "shared-capacity", time)
        return {"queues_changed": _changed(before, buffer.snapshot()), "size": len(buffer)}

    def _size(self, request: dict) -> dict:
        return {"size": len(self.consultant.wm)}

    # ------------------------------------------------------------- LTM topic
    def _reject_assert(self, request_id: Any, error: str) -> None:
        reply = {"domain": None, "consultant": self.domain, "entity": None, "ok": False, "error": error}
        if request_id is not None:
            reply["id"] = request_id
        publish(self._assert_results, reply)

    def _on_assert(self, data: dict) -> None:
        check_fields(data, {"domain": str})
        if data["domain"] != self.domain:
            return  # another consultant's
        reply: dict[str, Any] = {"domain": self.domain, "entity": data.get("entity")}
        if "id" in data:
            reply["id"] = data["id"]
        try:
            contract.check(contract.LtmAssert, data)
            contract.check_sizes(data, self.limits, names=("entity",), lists=("properties",))
            _check_storable([data["entity"], *data["properties"]])
            time = self.now()
            self._check_listeners()
            self._dirty = {}
            result = self.consultant.assert_facts(data["entity"], data["properties"], time)
            dirty, self._dirty = self._dirty, {}
            wm = self.consultant.wm
            # Durable before it is acknowledged (and the queues a retraction changed).
            self.store.save_facts(result.entity, result.updated, result.new_entity,
                                  {e: wm.export_queue(e) for e in dirty} if self.persist_wm else {},
                                  wm.counters() if self.persist_wm else None)
        except StoreError as err:
            self.get_logger().error(printable(f"{contract.LTM_ASSERT.name}: not stored: {err}"))
            reply.update(ok=False, error=printable(f"not stored: {err}"))
            publish(self._assert_results, reply)
            return
        except (MessageError, KnowledgeError) as err:
            self.get_logger().warning(printable(f"{contract.LTM_ASSERT.name}: {err}"))
            reply.update(ok=False, error=printable(err))
            publish(self._assert_results, reply)
            return
        reply.update(ok=True, new_entity=result.new_entity, updated=result.updated, retracted=result.retracted)
        publish(self._assert_results, reply)
        self.get_logger().info(printable(
            f"LTM {'added' if result.new_entity else 'updated'} '{result.entity}': {result.updated}"
            + (f", retracted {result.retracted}" if result.retracted else "")
        ))
        if self._state_due:
            self._last_time = time
            self._publish_due()

    # ------------------------------------------------------------ parameters
    def _after_set_parameters(self, params) -> None:
        for param in params:
            if param.name == "threshold":
                value = float(param.value)  # typed and ranged by its descriptor
                if value != self.consultant.threshold:
                    now = now_seconds(self)
                    self._check_listeners()
                    self._dirty = {}
                    retracted = self.consultant.set_threshold(value, now)
                    self._persist()
                    self.get_logger().info(f"threshold {value:g}" + (f", retracted {retracted}" if retracted else ""))
                    if retracted:
                        self._last_time = now
                        self._publish_due()


def _check_storable(names: list[str]) -> None:
    """Raise MessageError for a name the state database cannot hold (not valid UTF-8, e.g. a lone surrogate)."""
    for name in names:
        try:
            name.encode("utf-8")
        except UnicodeEncodeError:
            raise MessageError(f"name {printable(repr(name), 80)} is not valid UTF-8 (a lone surrogate?)") from None


def _changed(before: dict[str, list[str]], after: dict[str, list[str]]) -> int:
    """How many entities' queues differ between two snapshots."""
    return sum(1 for e in set(before) | set(after) if before.get(e) != after.get(e))


def main(args: Optional[list[str]] = None) -> int:
    return run_node(ConsultantNode, args)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
