"""JSON over ROS 2 topics and services: the carrier convention, topics, calling (docs/semantics.md §7).

The only place where the ROS-free contract meets ROS types: names, QoS specs and schemas
are in :mod:`fsreg_ros.contract` (:func:`qos_profile` makes an rclpy profile of a
:class:`~fsreg_ros.contract.QosSpec`); the JSON codec is :mod:`fsreg_ros.contract.codec`
(:func:`to_msg`/:func:`from_msg` wrap it in ``std_msgs/String``).  This module owns the
convention and what every receiving side shares (:class:`CarrierError`, the error kinds,
:class:`Refusal`, :func:`run_handler`); its neighbours own the rest of the carrier:

* :mod:`fsreg_ros.ros.serving`: serving a contract service (:func:`~fsreg_ros.ros.serving.serve`,
  validation, one handler per ``op``, every call answered, the waiting requests drained);
* :mod:`fsreg_ros.ros.batches`: a topic handed over a batch at a time
  (:func:`~fsreg_ros.ros.batches.subscribe_batches`);
* :mod:`fsreg_ros.ros.gathering`: a stream's reader held from the executor and taken once a
  period (:class:`~fsreg_ros.ros.gathering.GatheringGroup`);
* :mod:`fsreg_ros.ros.rclpy_internals`: every use of rclpy's internals.

Services use ``diagnostic_msgs/srv/AddDiagnostics`` as a string-to-string carrier
(common_interfaces has no such service): the request JSON goes in ``load_namespace``,
the reply JSON in ``message``; ``success=false`` means the reply is
``{"error": "...", "kind": "..."}``.

Graph identity: a node's read-only ``graph`` parameter (declared here, by :func:`publisher`,
when the node has not declared it) names the graph it belongs to; every JSON object it
publishes through :func:`publish` then carries it as ``graph``
(:data:`fsreg_ros.contract.GRAPH_FIELD`), so a listener can tell another graph's messages
from its own.  An empty ``graph`` (a node started by hand) stamps nothing.

Subscribing: :func:`subscribe` decodes each message (bounded in size), validates it once
against the topic's schema within the limits (:func:`fsreg_ros.contract.check`, one-line
errors naming the field) and only then calls the handler; a message that is not a JSON
object of the topic's schema, or whose handler raises, is rejected
(``reject(id, error, kind)`` publishes the reply the contract has for it, if any) and logged
with the topic and id.

Logging: :func:`log_warning` and :func:`log_error` never raise (rclpy raises when one call
site logs with two severities, which a failing message after a malformed one did).

Calling: :class:`ServiceCaller` (one per service) sends at once (:meth:`ServiceCaller.send`,
so requests leave in program order) and awaits with a deadline enforced by a
steady-clock timer (it fires even under sim time with a stopped ``/clock``).  Await only
from a callback whose group is not the client's group (measured on this project's
Jazzy: an ``async`` callback awaiting a client in its own mutually exclusive group
deadlocks, 0 of 5 calls answered, and blocks every other callback of that group,
rclpy#834; in a group of its own, 5 of 5 in 1-4 ms); by default each client gets
its own :class:`~rclpy.callback_groups.ReentrantCallbackGroup`.
"""

from __future__ import annotations

import inspect
import sys
import time
import weakref
from typing import Any, Awaitable, Callable, Mapping, Optional, Union

from diagnostic_msgs.srv import AddDiagnostics
from pydantic import BaseModel
from rclpy.callback_groups import CallbackGroup, ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from std_msgs.msg import String

from rcl_interfaces.msg import ParameterDescriptor

from ..contract.codec import MessageError, TooLarge, dumps, leading_id, parse, printable, request_id, safe_dumps
from .diagnostics import request_stats
from .rclpy_internals import forget_entity
from ..contract import GRAPH_FIELD, GRAPH_PARAMETER, SERVICE_QOS, QosSpec, Topic, check

#: The service type used as a JSON carrier.
SERVICE_TYPE = AddDiagnostics
#: Default deadline of a service call, seconds (measured: a new process's first call to a running server
#: took 1.0-4.4 s, later ones ~1 ms).
DEFAULT_TIMEOUT = 10.0

Limit = Union[None, int, Callable[[], Optional[int]]]
Handler = Callable[[dict], Union[Mapping[str, Any], BaseModel, Awaitable[Union[Mapping[str, Any], BaseModel]]]]
LimitsSource = Union[None, Any, Callable[[], Any]]
Reject = Callable[[Any, str], None]


class CarrierError(RuntimeError):
    """A service call that did not succeed.

    ``kind`` is ``"timeout"``, ``"cancelled"``, ``"protocol"`` (the reply is not JSON)
    or, when the server answered ``success=false``, the error kind it reported (the
    class name of the server-side exception, e.g. ``"KnowledgeError"``,
    ``"MessageError"``, or ``"internal"``).  ``error`` is the server's own message
    (or ours), ``service`` the service name, ``reply`` the decoded failure reply.
    """

    def __init__(
        self,
        error: str,
        *,
        kind: str = "remote",
        service: Optional[str] = None,
        reply: Optional[dict] = None,
    ) -> None:
        self.error = error
        self.kind = kind
        self.service = service
        self.reply = reply or {}
        super().__init__(f"{service}: {error}" if service else error)


def error_kind(err: BaseException) -> str:
    """Return the ``kind`` an error reply carries: the exception's class name, or a CarrierError's kind."""
    if isinstance(err, CarrierError):
        return err.kind
    if isinstance(err, TooLarge):
        return err.kind
    return type(err).__name__


def reply_kind(err: BaseException) -> str:
    """Return the ``kind`` of an error answered on a topic (``rr/result``, ``reg/expression``, ``ltm/assert/result``).

    The error's own ``kind`` when it names one (``unknown-entity``, ``unknown-property``,
    ``unknown-domain``, ``too-large``, ``not-ready``, ...), ``bad-request`` for a message
    that is not of its schema, else the exception's class name (docs/semantics.md §7).
    """
    kind = getattr(err, "kind", None)
    if isinstance(kind, str) and kind:
        return kind
    if isinstance(err, MessageError):
        return "bad-request"
    return type(err).__name__


def limit_value(limit: Limit) -> Optional[int]:
    """Return a limit's value now (a callable limit is asked each time: parameters change at run time)."""
    return limit() if callable(limit) else limit


def where(name: str, rid: Any) -> str:
    """Return ``name`` with the request id of the message a log line is about, if it has one."""
    return f"{name} (id {printable(repr(rid), 80)})" if rid is not None else name


def log_warning(logger, text: Any) -> None:
    """Log one warning line that cannot raise (see :func:`log_error`)."""
    try:
        logger.warning(printable(text))
    except Exception as err:  # noqa: BLE001 - a log line must never take a node down
        _log_fallback("warning", text, err)


def log_error(logger, text: Any) -> None:
    """Log one error line that cannot raise.

    rclpy remembers each logging call site and raises ``ValueError`` if one site logs
    with another severity (or other filters) later, and the text may hold anything a
    message carried.  So every severity has its own call site here, the text is made
    printable, and a logger failure goes to stderr instead of out of the callback.
    """
    try:
        logger.error(printable(text))
    except Exception as err:  # noqa: BLE001 - a log line must never take a node down
        _log_fallback("error", text, err)


def _log_fallback(severity: str, text: Any, err: BaseException) -> None:
    try:
        print(printable(f"[{severity}] {text} (logger failed: {type(err).__name__}: {err})"), file=sys.stderr)
    except Exception:  # noqa: BLE001 - stderr closed: nothing left to tell
        pass


def checker(schema: Any, limits: LimitsSource) -> Callable[[dict], None]:
    """Return the validation of a decoded message against ``schema`` (nothing without one)."""
    if schema is None:
        return lambda data: None
    return lambda data: check(schema, data, limit_value(limits))


def max_bytes_of(limits: LimitsSource) -> Limit:
    """Return the message size bound ``limits`` sets (asked each time), None without limits."""
    return None if limits is None else (lambda: limit_value(limits).max_message_bytes)


async def run_handler(handler, text: str, max_bytes: Limit, seen: dict, validate: Callable[[dict], None],
                      accept: Optional[Callable[[dict], bool]] = None) -> Any:
    """Decode ``text`` (bounded), note its request id in ``seen``, validate it, run ``handler``; its result.

    A message ``accept`` refuses is not for this node: ``seen["ignored"]`` is set and nothing runs.
    """
    try:
        payload = parse(text, max_bytes=limit_value(max_bytes))
    except TooLarge:
        seen["id"] = leading_id(text)  # so the sender hears which of its messages was refused
        raise
    seen["id"] = request_id(payload)
    if accept is not None and not accept(payload):
        seen["ignored"] = True
        return None
    validate(payload)
    result = handler(payload)
    if inspect.isawaitable(result):
        result = await result
    return result


class Refusal:
    """How a subscription refuses a message: a log line naming the topic and id, then ``reject(id, error, kind)``.

    A ``ValueError`` or :class:`CarrierError` is a warning with its :func:`reply_kind`; anything
    else an error of kind ``internal``.  The rejection itself never raises out of here.
    """

    def __init__(self, logger, name: str, reject: Optional[Reject]) -> None:
        self.logger, self.name, self.reject = logger, name, reject

    def error(self, rid: Any, err: BaseException) -> None:
        """Refuse the message ``rid`` for ``err`` (expected errors as warnings, the rest as internal errors)."""
        if isinstance(err, (ValueError, CarrierError)):
            self.refuse(rid, printable(err), internal=False, kind=reply_kind(err))
        else:
            self.refuse(rid, f"internal error: {type(err).__name__}: {printable(err)}", internal=True,
                        kind="internal")

    def refuse(self, rid: Any, error: str, internal: bool, kind: str) -> None:
        """Log ``error`` about message ``rid`` and pass it to ``reject``, if any."""
        text = f"{where(self.name, rid)}: {error}"
        (log_error if internal else log_warning)(self.logger, text)
        if self.reject is None:
            return
        try:
            self.reject(rid, printable(error), kind)
        except Exception as err:  # noqa: BLE001 - the rejection itself must not kill the node
            log_error(self.logger, f"{self.name}: cannot publish the rejection: {type(err).__name__}: {printable(err)}")


# ----------------------------------------------------------------- messages
def qos_profile(spec: Union[QosSpec, QoSProfile]) -> QoSProfile:
    """Return the rclpy profile of a contract QoS spec: reliable, keep last ``depth`` (or all), latched or volatile.

    A ``lease`` makes liveliness automatic with that lease duration.
    """
    if isinstance(spec, QoSProfile):
        return spec
    lease = {}
    if spec.lease is not None:
        lease = {"liveliness": LivelinessPolicy.AUTOMATIC, "liveliness_lease_duration": Duration(seconds=spec.lease)}
    if spec.keep_all:
        return QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.TRANSIENT_LOCAL if spec.latched else DurabilityPolicy.VOLATILE,
                          **lease)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=spec.depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if spec.latched else DurabilityPolicy.VOLATILE,
        **lease,
    )


def to_msg(obj: Mapping[str, Any]) -> String:
    """Return a ``std_msgs/String`` carrying ``obj`` as JSON (NaN/Infinity refused: they are not JSON)."""
    return String(data=dumps(obj))


def from_msg(msg: String, *, max_bytes: Optional[int] = None) -> dict:
    """Decode a ``std_msgs/String`` carrying one JSON object (its fields: :func:`fsreg_ros.contract.check`)."""
    return parse(getattr(msg, "data", msg), max_bytes=max_bytes)


# ----------------------------------------------------------------- topics
#: Publisher -> the graph identity its messages are stamped with.
_STAMPS: "weakref.WeakKeyDictionary[Any, str]" = weakref.WeakKeyDictionary()


def graph_identity(node) -> str:
    """Return the identity of the graph ``node`` belongs to: its ``graph`` parameter ('' if none).

    The parameter is declared (read-only, default '') if the node has not declared it.
    """
    if not node.has_parameter(GRAPH_PARAMETER):
        node.declare_parameter(GRAPH_PARAMETER, "", ParameterDescriptor(
            description="identity of the graph this node belongs to, stamped on what it publishes "
                        "('' = none); set by fsreg-up, fsreg-graph and fsreg_ros.testing", read_only=True))
    value = node.get_parameter(GRAPH_PARAMETER).value
    return value if isinstance(value, str) else ""


def publisher(node, topic: Topic):
    """Return a ``std_msgs/String`` publisher of a contract topic, with its QoS.

    What :func:`publish` sends through it is stamped with the node's graph identity.
    """
    pub = node.create_publisher(String, topic.name, qos_profile(topic.qos))
    graph = graph_identity(node)
    if graph:
        _STAMPS[pub] = graph
    return pub


def stamped(pub, obj: Mapping[str, Any]) -> Mapping[str, Any]:
    """Return ``obj`` with the graph identity of ``pub``'s node (``obj`` itself when it has none)."""
    graph = _STAMPS.get(pub)
    return {**obj, GRAPH_FIELD: graph} if graph else obj


def publish(pub, obj: Mapping[str, Any]) -> None:
    """Publish one JSON object, stamped (sanitised if it is not JSON as it stands: never raises on content)."""
    pub.publish(String(data=safe_dumps(stamped(pub, obj))))


def message_bytes(pub, obj: Mapping[str, Any]) -> int:
    """Return the UTF-8 bytes :func:`publish` would send for ``obj`` through ``pub``."""
    return len(safe_dumps(stamped(pub, obj)).encode("utf-8", "surrogatepass"))


def subscribe(node, topic: Topic, handler: Handler, *, reject: Optional[Reject] = None,
              callback_group: Optional[CallbackGroup] = None, max_bytes: Limit = None, limits: LimitsSource = None,
              accept: Optional[Callable[[dict], bool]] = None, event_callbacks=None):
    """Subscribe ``handler(data: dict)`` (sync or async) to a contract topic; return the subscription.

    Every message is validated once against the topic's schema (names and lists within
    ``limits``, a :class:`~fsreg_ros.contract.Limits`, also the default ``max_bytes``)
    before the handler sees it.  ``accept(data)`` false (after decoding, before
    validation) means the message is for another node: ignored, silently.  A message
    that is not a JSON object of the schema, or whose handler raises a
    ``ValueError``/:class:`CarrierError`, is logged as a warning naming the topic and id
    and passed to ``reject(id, error, kind)`` (:func:`reply_kind`); any other exception is logged as an error and
    rejected as an internal error (:class:`Refusal`).  The node keeps serving either way.
    ``event_callbacks``: rclpy's ``SubscriptionEventCallbacks`` (e.g. the liveliness of
    the topic's writers).
    """
    validate = checker(topic.schema, limits)
    if max_bytes is None:
        max_bytes = max_bytes_of(limits)
    refusal = Refusal(node.get_logger(), topic.name, reject)
    stats = request_stats(node) if reject is not None else None  # an answered topic carries requests

    async def callback(msg: String) -> None:
        seen: dict = {}
        started, refused = time.monotonic(), True
        try:
            await run_handler(handler, msg.data, max_bytes, seen, validate, accept)
            refused = False
        except Exception as err:  # noqa: BLE001 - log with context, keep serving
            refusal.error(seen.get("id"), err)
        if stats is not None and not seen.get("ignored"):  # a message for another node (accept) is not counted
            stats.record(time.monotonic() - started, refused=refused)

    return node.create_subscription(String, topic.name, callback, qos_profile(topic.subscriber_qos),
                                    callback_group=callback_group, event_callbacks=event_callbacks)


# ----------------------------------------------------------------- timers
def drop_timer(node, timer, group: Optional[CallbackGroup]) -> None:
    """Cancel and destroy a short-lived timer, and forget it in its callback group.

    rclpy's ``CallbackGroup.add_entity`` keeps a weak reference to every timer ever
    created in the group and ``destroy_timer`` never removes it, so a timer per call
    leaked ~100 bytes per call (REG's RSS grew ~1.9 kB per request).  A weak reference
    to a live object equals a new one to the same object, so it can be discarded here.
    """
    timer.cancel()
    if group is not None:
        forget_entity(group, timer)
    node.destroy_timer(timer)


# ----------------------------------------------------------------- calling
_STEADY = ClockType.STEADY_TIME


class ServiceCaller:
    """A JSON client of one service: send at once, await with a deadline.

    ``callback_group`` holds the client and its deadline timers; it must not be the
    group of the callback that awaits (default: a new ReentrantCallbackGroup).
    """

    def __init__(
        self,
        node,
        name: str,
        callback_group: Optional[CallbackGroup] = None,
        timeout: float = DEFAULT_TIMEOUT,
        *,
        client=None,
    ) -> None:
        self.node = node
        self.timeout = timeout
        if client is not None:  # wrap an existing AddDiagnostics client
            self.client = client
            self.name = client.srv_name
            self.callback_group = client.callback_group
        else:
            self.name = name
            self.callback_group = callback_group if callback_group is not None else ReentrantCallbackGroup()
            self.client = node.create_client(SERVICE_TYPE, name, qos_profile=qos_profile(SERVICE_QOS),
                                             callback_group=self.callback_group)
        self._steady = Clock(clock_type=_STEADY)

    @classmethod
    def wrap(cls, node, client, timeout: float = DEFAULT_TIMEOUT) -> "ServiceCaller":
        """Return a ServiceCaller over an existing ``AddDiagnostics`` client of ``node``."""
        return cls(node, client.srv_name, timeout=timeout, client=client)

    def ready(self) -> bool:
        """Return True if a server is matched (not proof it answers: see :meth:`wait_ready`)."""
        return self.client.service_is_ready()

    def send(self, payload: Mapping[str, Any]) -> Future:
        """Send one request now (so requests leave in call order); return a Future of the reply."""
        return self.client.call_async(SERVICE_TYPE.Request(load_namespace=dumps(payload)))

    async def result(self, future: Future, timeout: Optional[float] = None) -> dict:
        """Await a :meth:`send` future: the reply object, or :class:`CarrierError`."""
        timeout = self.timeout if timeout is None else timeout
        if not future.done():
            timer = self.node.create_timer(
                max(timeout, 1e-3), lambda: self.expire(future, timeout), self.callback_group, clock=self._steady
            )
            try:
                await future
            except CarrierError:
                raise
            except Exception as err:  # noqa: BLE001 - e.g. the context shut down
                raise CarrierError(f"call failed: {err}", kind="cancelled", service=self.name) from None
            finally:
                drop_timer(self.node, timer, self.callback_group)
        return self.decode(future)

    def expire(self, future: Future, timeout: float) -> None:
        """Give up on a pending request: its future fails with kind ``timeout``."""
        if not future.done():
            self.client.remove_pending_request(future)
            future.set_exception(
                CarrierError(f"no reply within {timeout:g} s", kind="timeout", service=self.name)
            )

    def decode(self, future: Future) -> dict:
        """Return the reply of a done future, or raise :class:`CarrierError`."""
        return self.decode_response(future, self.name)

    @staticmethod
    def decode_response(future: Future, name: str) -> dict:
        """Return the reply object of a done service future, or raise :class:`CarrierError`."""
        if future.cancelled():
            raise CarrierError("call cancelled", kind="cancelled", service=name)
        exc = future.exception()
        if exc is not None:
            if isinstance(exc, CarrierError):
                raise exc
            raise CarrierError(f"call failed: {exc}", kind="cancelled", service=name)
        response = future.result()
        if response is None:
            raise CarrierError("call cancelled", kind="cancelled", service=name)
        try:
            body = parse(response.message)
        except MessageError as err:
            raise CarrierError(f"reply is {err}", kind="protocol", service=name) from None
        if not response.success:
            error = body.get("error")
            kind = body.get("kind")
            raise CarrierError(
                error if isinstance(error, str) else f"failed without a reason: {printable(response.message, 80)}",
                kind=kind if isinstance(kind, str) else "remote",
                service=name,
                reply=body,
            )
        return body

    async def call(self, payload: Mapping[str, Any], timeout: Optional[float] = None) -> dict:
        """Send ``payload`` and await the reply (CarrierError on failure or timeout)."""
        return await self.result(self.send(payload), timeout)

    async def wait_ready(
        self, payload: Mapping[str, Any], timeout: float, attempt_timeout: float = 2.0
    ) -> dict:
        """Wait for one real round trip (readiness); return its reply.

        Wait for the server, then call ``payload`` until one call succeeds or
        ``timeout`` passes.

        A request sent before discovery completes can be lost, so timed-out attempts
        are retried; an error reply from the server is raised at once.
        """
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise CarrierError(f"not ready within {timeout:g} s", kind="timeout", service=self.name)
            if not self.ready():
                await wait_until(self.node, self.ready, remaining, callback_group=self.callback_group)
                continue
            try:
                return await self.call(payload, min(remaining, max(attempt_timeout, 0.05)))
            except CarrierError as err:
                if err.kind != "timeout":
                    raise
                attempt_timeout *= 2  # the first call to a new server can be slow

    def destroy(self) -> None:
        self.node.destroy_client(self.client)


async def wait_until(
    node,
    predicate: Callable[[], bool],
    timeout: float,
    *,
    callback_group: Optional[CallbackGroup] = None,
    period: float = 0.02,
) -> bool:
    """Await ``predicate()`` without blocking the executor; return True if it came true in time.

    Gives up after ``timeout`` seconds (steady clock).  A steady-clock timer in
    ``callback_group`` (not the awaiting callback's group) polls the predicate.
    """
    if predicate():
        return True
    done = Future()
    deadline = time.monotonic() + timeout

    def poll() -> None:
        if done.done():
            return
        if predicate():
            done.set_result(True)
        elif time.monotonic() >= deadline:
            done.set_result(False)

    group = callback_group if callback_group is not None else ReentrantCallbackGroup()
    timer = node.create_timer(period, poll, group, clock=Clock(clock_type=_STEADY))
    try:
        return bool(await done)
    finally:
        drop_timer(node, timer, group)
