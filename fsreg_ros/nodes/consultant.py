"""``consultant``: one domain's LTM and WM buffer (DIARC's consultant pattern).

One process per domain (give each its own node name, e.g.
``--ros-args -r __node:=consultant_faces -p domain:=faces -p kb:=kb.yaml``).

Parameters
    ``domain`` (string, required, read-only), ``kb`` (scenario/KB YAML, required,
    read-only), ``threshold`` (number in [0, 1]; default: the KB's threshold for the
    domain; changeable at run time; it changes what holds, it does not touch WM), and
    the size limits ``max_message_bytes``, ``max_name_chars``, ``max_list_items``.

Services (JSON in ``AddDiagnostics``, names and schemas in :mod:`fsreg_ros.contract`)
    ``consultant/<domain>`` -- queries from RR and REG, ``{"op": ...}``:
      ``info`` -> ``{"domain", "entities", "preference", "threshold", "policy", "memory", "events"}``
      ``holds`` ``{"property", "entities"}`` -> ``{"holds"}`` (no encoding)
      ``affirm`` ``{"property", "entities", "cause", "time"?, "turn"?}`` -> ``{"holds"}``
      ``wm`` ``{"entity"}`` -> ``{"queue"}`` (LRU first; reading never refreshes)
      ``encode`` ``{"entity", "properties", "cause", "time"?, "turn"?}`` -> ``{}``
      ``snapshot`` -> ``{"queues", "events"}`` (non-empty queues only)
    ``consultant/<domain>/manage`` -- the WM Manager's:
      ``configure`` ``{"policy": {"policy", "decay_period"?, "capacity"?,
      "global_capacity"?, "seed"?}, "time"?}`` -> ``{"memory", "queues_changed"}``:
      installs the policy and trims every queue at once (``none`` empties WM, cause
      ``reset``);
      ``decay`` ``{"ticks": {"origin", "period", "first", "count"}}`` ->
      ``{"queues_changed", "policy"}``: decay ticks (Algorithm 2) at ``origin + k *
      period`` for k = first .. first + count - 1, applied now (at most as many as
      the longest queue holds can pop anything); ``policy`` is the installed policy's
      name (so the WM Manager notices a restarted consultant);
      ``evict`` ``{"count", "time"?}`` -> ``{"queues_changed", "size"}``: forget the
      domain's ``count`` least recently encoded fronts (cause ``shared-capacity``);
      ``size`` -> ``{"size"}``: how many properties WM holds.

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
    out ``wm/events`` -- every encode/forget event (SPEC section 2), one message each;
    out ``wm/state`` (latched) ``{"domain", "time", "queues", "events"}`` -- at start
    and after every request that changed WM;
    in ``ltm/assert`` ``{"domain", "entity", "properties": {name: certainty}, "id"?}``
    -- messages for other domains are ignored; out ``ltm/assert/result``
    ``{"domain", "entity", "ok", "new_entity", "updated", "retracted", "id"?}`` or
    ``{"domain", "entity", "ok": false, "error", "id"?}``.

Until the WM Manager configures it the consultant runs policy ``none``: it retains
nothing (a buffer without a policy would retain everything, unmanaged).
"""

from __future__ import annotations

from typing import Any, Callable, Optional

from rclpy.node import Node
from rclpy.exceptions import InvalidServiceNameException, InvalidTopicNameException
from rclpy.validate_topic_name import validate_topic_name

from .. import contract
from ..carrier import publish, publisher, serve, subscribe
from ..codec import NUMBER, MessageError, check_fields, printable
from ..contract import consultant_service, manage_service
from ..core.consultant import Consultant, KnowledgeError
from ..core.decay import TickError, TickRun
from ..core.forgetting import NONE, ForgettingPolicy
from ..core.memory import ENCODE_CAUSES, WMEvent
from ..core.wm_manager import apply_ticks, configure_buffer
from ..core.scenario import ScenarioError, load_scenario
from .asking import declare_limits
from .common import StartupError, declare_number, descriptor, now_seconds, run_node, watch_clock

TIME = {"time": NUMBER, "turn": (int, None)}
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

        self.domain = domain
        self._events = publisher(self, contract.WM_EVENTS)
        self._state = publisher(self, contract.WM_STATE)
        self._assert_results = publisher(self, contract.LTM_ASSERT_RESULT)
        self._event_count = 0
        self._last_time = 0.0  # time of the latest change, for /wm/state
        self.consultant = Consultant(
            domain, spec.entities, spec.preference, threshold, sink=self._on_event, attributes=spec.attributes
        )
        # Retain nothing until the WM Manager says otherwise.
        self.policy = NONE
        configure_buffer(self.consultant.wm, NONE, 0.0)

        self.add_post_set_parameters_callback(self._after_set_parameters)
        self._query_ops: dict[str, Callable[[dict], dict]] = {
            "info": self._info,
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
        self.publish_state(self.now())
        self.get_logger().info(
            f"consultant of '{domain}': {len(self.consultant.entities)} entities, "
            f"{len(self.consultant.preference)} properties, threshold {threshold:g}, from {kb}"
        )

    # ----------------------------------------------------------------- helpers
    def now(self) -> float:
        return now_seconds(self)

    def _on_event(self, event: WMEvent) -> None:
        self._event_count += 1
        publish(self._events, event.to_json())

    def publish_state(self, time: float) -> None:
        """``/wm/state``: this domain's non-empty queues, LRU first."""
        publish(
            self._state,
            {"domain": self.domain, "time": time, "queues": self.consultant.wm.snapshot(), "events": self._event_count},
        )

    def _dispatch(self, request: dict, ops: dict[str, Callable[[dict], dict]]) -> dict:
        op = check_fields(request, {"op": str})["op"]
        handler = ops.get(op)
        if handler is None:
            raise MessageError(f"unknown op {printable(repr(op), 80)} (known: {', '.join(ops)})")
        contract.check_sizes(request, self.limits, names=("entity", "property", "cause"),
                             lists=("entities", "properties"))
        before = self._event_count
        reply = handler(request)
        if self._event_count != before:
            self.publish_state(self._last_time)
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
        c = self.consultant
        policy = self.policy
        return {
            "domain": self.domain,
            "entities": list(c.entities),
            "preference": list(c.preference),
            "threshold": c.threshold,
            "policy": policy.name,
            "memory": policy.to_json(),
            "events": self._event_count,
        }

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
        configure_buffer(buffer, policy, time)
        self.policy = policy
        self.get_logger().info(f"memory policy {policy.to_json()}")
        return {"memory": policy.to_json(), "queues_changed": _changed(before, buffer.snapshot())}

    def _decay(self, request: dict) -> dict:
        check_fields(request, {"ticks": dict})
        try:
            ticks = TickRun.from_json(request["ticks"])
        except TickError as err:
            raise MessageError(f"field 'ticks': {err}") from None
        buffer = self.consultant.wm
        before = buffer.snapshot()
        # Applied now (the buffer is lazy otherwise), so the events and the state go
        # out now, in the canonical order.
        apply_ticks(buffer, ticks, self.consultant.entities)
        self._last_time = ticks.last
        # ``policy`` lets the WM Manager notice a restarted consultant.
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
            time = self.now()
            before = self._event_count
            result = self.consultant.assert_facts(data["entity"], data["properties"], time)
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
        if self._event_count != before:
            self.publish_state(time)

    # ------------------------------------------------------------ parameters
    def _after_set_parameters(self, params) -> None:
        for param in params:
            if param.name == "threshold":
                value = float(param.value)  # typed and ranged by its descriptor
                if value != self.consultant.threshold:
                    now = now_seconds(self)
                    retracted = self.consultant.set_threshold(value, now)
                    self.get_logger().info(f"threshold {value:g}" + (f", retracted {retracted}" if retracted else ""))
                    if retracted:
                        self.publish_state(now)


def _changed(before: dict[str, list[str]], after: dict[str, list[str]]) -> int:
    """How many entities' queues differ between two snapshots."""
    return sum(1 for e in set(before) | set(after) if before.get(e) != after.get(e))


def main(args: Optional[list[str]] = None) -> int:
    return run_node(ConsultantNode, args)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
