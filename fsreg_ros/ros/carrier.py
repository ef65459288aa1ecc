"""JSON over ROS 2 services and topics: serving, subscribing, calling (docs/semantics.md §7).

The one small module for fsreg's carrier convention, and the only place where the
ROS-free contract meets ROS types: names, QoS specs and schemas are in
:mod:`fsreg_ros.contract` (:func:`qos_profile` makes an rclpy profile of a
:class:`~fsreg_ros.contract.QosSpec`); the JSON codec is :mod:`fsreg_ros.contract.codec`
(:func:`to_msg`/:func:`from_msg` wrap it in ``std_msgs/String``).

Services use ``diagnostic_msgs/srv/AddDiagnostics`` as a string-to-string carrier
(common_interfaces has no such service): the request JSON goes in ``load_namespace``,
the reply JSON in ``message``; ``success=false`` means the reply is
``{"error": "...", "kind": "..."}``.

Serving: :func:`serve` serves a contract service: each request is decoded (bounded in
size), validated once against the service's request schema (names and lists within the
node's limits; :func:`fsreg_ros.contract.check`, one-line errors naming the field), and
only then passed to the handler (one, or one per ``op``).  A :class:`MessageError`, any
other ``ValueError`` (e.g. the core's ``KnowledgeError``) or a :class:`CarrierError`
becomes ``success=false`` plus a logged warning; anything else becomes
``kind: "internal"`` plus a logged error naming the service and the request id.  Every
call is answered (the reply is built by :func:`~fsreg_ros.contract.codec.error_json`, which cannot
fail) and the server keeps serving.

Graph identity: a node's read-only ``graph`` parameter (declared here, by :func:`publisher`,
when the node has not declared it) names the graph it belongs to; every JSON object it
publishes through :func:`publish` then carries it as ``graph``
(:data:`fsreg_ros.contract.GRAPH_FIELD`), so a listener can tell another graph's messages
from its own.  An empty ``graph`` (a node started by hand) stamps nothing.

Subscribing: :func:`subscribe` does the same for a topic: a message that is not a JSON
object of the topic's schema within the limits, or whose handler raises, is rejected
(``reject(id, error, kind)`` publishes the reply the contract has for it, if any) and logged
with the topic and id.  :func:`subscribe_batches` hands over every message waiting at once,
and with ``gather`` takes a stream once a period instead of a round per message
(:class:`GatheringGroup` holds the reader from the executor meanwhile).

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
from rclpy.callback_groups import CallbackGroup, MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.exceptions import InvalidHandle
from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from std_msgs.msg import String

from rcl_interfaces.msg import ParameterDescriptor

from ..contract.codec import (MessageError, TooLarge, dumps, error_json, leading_id, parse, printable, request_id,
                              safe_dumps)
from .diagnostics import request_stats
from ..contract import GRAPH_FIELD, GRAPH_PARAMETER, SERVICE_QOS, Limits, QosSpec, Service, Topic, check

#: The service type used as a JSON carrier.
SERVICE_TYPE = AddDiagnostics
#: Default deadline of a service call, seconds (measured: a new process's first call to a running server
#: took 1.0-4.4 s, later ones ~1 ms).
DEFAULT_TIMEOUT = 10.0
#: Most CPU seconds :func:`serve`'s ``drain`` spends answering the requests waiting, per round.
DRAIN_SECONDS = 0.01

Limit = Union[None, int, Callable[[], Optional[int]]]


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


def _limit(limit: Limit) -> Optional[int]:
    return limit() if callable(limit) else limit


def _context(where: str, rid: Any) -> str:
    return f"{where} (id {printable(repr(rid), 80)})" if rid is not None else where


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


def _checker(schema: Any, limits: LimitsSource) -> Callable[[dict], None]:
    """Return the validation of a decoded message against ``schema`` (nothing without one)."""
    if schema is None:
        return lambda data: None
    return lambda data: check(schema, data, _limit(limits))


async def _run(handler, text: str, max_bytes: Limit, seen: dict, validate: Callable[[dict], None],
               accept: Optional[Callable[[dict], bool]] = None) -> Any:
    """Decode ``text`` (bounded), note its request id in ``seen``, validate it, run ``handler``; its result.

    A message ``accept`` refuses is not for this node: ``seen["ignored"]`` is set and nothing runs.
    """
    try:
        payload = parse(text, max_bytes=_limit(max_bytes))
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


def _reply_object(result: Any) -> Mapping[str, Any]:
    """Return a handler's reply as a JSON object: a mapping as it is, a contract model dumped (fields set only)."""
    if isinstance(result, BaseModel):
        return result.model_dump(mode="json", exclude_unset=True)
    if not isinstance(result, Mapping):
        raise TypeError(f"handler returned {type(result).__name__}, not a JSON object")
    return result


def _check_op(handlers: Mapping[str, Any], request: dict) -> None:
    """Refuse a request whose ``op`` has no handler (before its schema, which depends on the op)."""
    if "op" not in request:
        raise MessageError(f"missing field 'op' (one of {', '.join(handlers)})")
    op = request["op"]
    if not isinstance(op, str) or op not in handlers:
        raise MessageError(f"field 'op': expected one of {', '.join(handlers)}, got {printable(repr(op), 60)}")


def _dispatch(handlers: Mapping[str, Handler]) -> Handler:
    """One handler per ``op``: the request's ``op`` chooses (checked by :func:`_check_op` first)."""
    return lambda request: handlers[request["op"]](request)


# ----------------------------------------------------------------- serving
Handler = Callable[[dict], Union[Mapping[str, Any], BaseModel, Awaitable[Union[Mapping[str, Any], BaseModel]]]]
LimitsSource = Union[None, Any, Callable[[], Any]]


def serve(node, service: Union[Service, str], handlers: Union[Handler, Mapping[str, Handler]],
          callback_group: Optional[CallbackGroup] = None, *, max_bytes: Limit = None, limits: LimitsSource = None,
          domain: Optional[str] = None, drain: int = 0):
    """Serve a contract service on ``node``: every request validated once, then handled; return the service.

    ``service`` is a :class:`~fsreg_ros.contract.Service` (its ``<domain>`` filled in
    with ``domain``): each request must fit its request schema, names and lists within
    ``limits`` (a :class:`~fsreg_ros.contract.Limits`, also the default ``max_bytes``;
    without either, the default ``Limits().max_message_bytes``), else it gets an error
    reply naming the field and the handler never sees it.  (A
    plain name serves without a schema.)  ``handlers`` is one ``handler(request: dict)``
    or a mapping op -> handler; a handler may be sync or ``async`` and returns a dict or
    a contract model.  Errors never escape: see the module docstring.  An async handler
    that awaits other services must use clients outside ``callback_group`` (by default
    the node's mutually exclusive group).

    ``drain`` > 0 (synchronous handlers only): after a request is answered, the requests
    waiting behind it (at most ``drain``, or :data:`DRAIN_SECONDS` of work) are answered
    at the start of the executor's next round, ahead of its other callbacks, instead of
    one per round (an executor takes one request per service per round, so a node whose
    rounds also carry other work, the consultant's facts, otherwise serves only a few
    requests a round however many wait).  Same order, same answers; the answers leave
    in a burst, which a client reads whole with the contract's depth (:data:`SERVICE_QOS
    <fsreg_ros.contract.SERVICE_QOS>`, 1000; a reader of depth 10 taking one answer a
    round would lose some).
    """
    logger = node.get_logger()
    if isinstance(service, Service):
        name, schema = service.name.replace("<domain>", domain or "<domain>"), service.request
    else:
        name, schema = service, None
    validate = _checker(schema, limits)
    handler = handlers
    if isinstance(handlers, Mapping):
        check_schema, handler = validate, _dispatch(handlers)

        def validate(data: dict) -> None:
            _check_op(handlers, data)
            check_schema(data)
    if max_bytes is None and limits is not None:
        max_bytes = lambda: _limit(limits).max_message_bytes  # noqa: E731
    if max_bytes is None:  # a service is never unbounded (the WM Manager's status read 1 MB requests whole)
        max_bytes = Limits().max_message_bytes

    stats = request_stats(node)

    async def callback(request, response):
        started = time.monotonic()
        response = await answer(request, response)
        stats.record(time.monotonic() - started, refused=not response.success)
        if drain and not draining[0] and node.executor is not None:
            waiting = take_request()  # a cheap look: nothing waits, nothing is scheduled
            if waiting is not None:
                draining[0] = True
                try:
                    node.executor.create_task(answer_waiting, waiting)  # run first in the next round
                except Exception:  # noqa: BLE001 - an executor shutting down: answer it now
                    draining[0] = False
                    await answer_taken(*waiting)
        return response

    draining = [False]

    def take_request() -> Optional[tuple]:
        """Take the next request waiting (request, header), or None, as the executor takes one."""
        try:
            with server.handle:
                request, header = server.handle.service_take_request(server.srv_type.Request)
        except InvalidHandle:
            return None
        return None if header is None else (request, header)

    async def answer_taken(request, header) -> bool:
        """Answer one taken request as the executor would; False once the service is gone."""
        begun = time.monotonic()
        reply = await answer(request, server.srv_type.Response())
        stats.record(time.monotonic() - begun, refused=not reply.success)
        try:
            server.send_response(reply, header)
        except InvalidHandle:
            return False
        return True

    async def answer_waiting(first: tuple) -> None:
        """Answer ``first`` and the requests waiting behind it now (bounded), in order."""
        try:
            budget = time.thread_time()  # CPU time: a process kept waiting by the OS still answers as many
            waiting: Optional[tuple] = first
            for _ in range(drain):
                if waiting is None or not await answer_taken(*waiting):
                    return
                if time.thread_time() - budget >= DRAIN_SECONDS:
                    return
                waiting = take_request()
            if waiting is not None:  # over the count: answered now, the rest as the executor takes them
                await answer_taken(*waiting)
        finally:
            draining[0] = False

    async def answer(request, response):
        seen: dict = {}
        try:
            result = await _run(handler, request.load_namespace, max_bytes, seen, validate)
            text = dumps(_reply_object(result))
        except (ValueError, CarrierError) as err:
            rid = seen.get("id")
            log_warning(logger, f"{_context(name, rid)}: {printable(err)}")
            response.success = False
            detail = reply_kind(err)  # a specific kind (unknown-entity, ...) beside the class name
            response.message = error_json(err, error_kind(err), rid,
                                          **({"detail": detail} if detail != error_kind(err) else {}))
            return response
        except Exception as err:  # noqa: BLE001 - a server must answer, whatever happened
            rid = seen.get("id")
            text = f"internal error: {type(err).__name__}: {printable(err)}"
            log_error(logger, f"{_context(name, rid)}: {text}")
            response.success = False
            response.message = error_json(text, "internal", rid)
            return response
        response.success = True
        response.message = text
        return response

    server = node.create_service(SERVICE_TYPE, name, callback, qos_profile=qos_profile(SERVICE_QOS),
                                 callback_group=callback_group)
    return server


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


Reject = Callable[[Any, str], None]


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
    rejected as an internal error.  The node keeps serving either way.
    ``event_callbacks``: rclpy's ``SubscriptionEventCallbacks`` (e.g. the liveliness of
    the topic's writers).
    """
    logger = node.get_logger()
    validate = _checker(topic.schema, limits)
    if max_bytes is None and limits is not None:
        max_bytes = lambda: _limit(limits).max_message_bytes  # noqa: E731

    def refuse(rid: Any, error: str, internal: bool, kind: str) -> None:
        text = f"{_context(topic.name, rid)}: {error}"
        if internal:
            log_error(logger, text)
        else:
            log_warning(logger, text)
        if reject is not None:
            try:
                reject(rid, printable(error), kind)
            except Exception as err:  # noqa: BLE001 - the rejection itself must not kill the node
                log_error(logger, f"{topic.name}: cannot publish the rejection: {type(err).__name__}: {printable(err)}")

    stats = request_stats(node) if reject is not None else None  # an answered topic carries requests

    async def callback(msg: String) -> None:
        seen: dict = {}
        started, refused = time.monotonic(), True
        try:
            await _run(handler, msg.data, max_bytes, seen, validate, accept)
            refused = False
        except (ValueError, CarrierError) as err:
            refuse(seen.get("id"), printable(err), internal=False, kind=reply_kind(err))
        except Exception as err:  # noqa: BLE001 - log with context, keep serving
            refuse(seen.get("id"), f"internal error: {type(err).__name__}: {printable(err)}", internal=True,
                   kind="internal")
        if stats is not None and not seen.get("ignored"):  # a message for another node (accept) is not counted
            stats.record(time.monotonic() - started, refused=refused)

    return node.create_subscription(String, topic.name, callback, qos_profile(topic.subscriber_qos),
                                    callback_group=callback_group, event_callbacks=event_callbacks)


class GatheringGroup(MutuallyExclusiveCallbackGroup):
    """The callback group of a gathered subscription, its QoS events and its timer (:func:`subscribe_batches`).

    Mutually exclusive, and able to *hold* the subscription: while :attr:`holding`, ``can_execute``
    says no for every entity of the group but :attr:`timer`, so rclpy's executor (which asks
    every entity when it builds its wait set, once a wait) leaves them out and is not woken
    by the subscription's messages; they wait in the reader until the timer takes them.  The
    subscription's QoS event handlers are held too: Fast DDS wakes a wait on a reader's
    events when data arrives for it (measured: with only the subscription held, ~4,000 empty
    wake-ups a second at 1,000 messages a second, a core spent spinning).
    """

    def __init__(self) -> None:
        super().__init__()
        self.holding = False
        self.holds = 0  # how many times the reader was held (a count, not a snapshot that races the timer)
        self.timer = None  # the entity never held
        self.drain: Optional[Callable[[], Any]] = None  # takes what waits in the reader now (subscribe_batches')

    def can_execute(self, entity) -> bool:
        return (not self.holding or entity is self.timer) and super().can_execute(entity)

    def hold(self) -> None:
        """Hold the reader from the executor until the timer finds a period empty; counted in :attr:`holds`."""
        self.holding = True
        self.holds += 1

    def release(self) -> None:
        """Take what waits in the held reader now and hand it back to the executor (a caller blocked on one message).

        Call it from the thread that spins the node, outside its callbacks (``GraphClient``
        waiting for the answer to its own request): the answer is then taken as it arrives,
        not at the period's end.  Nothing happens while the reader is not held.
        """
        if self.holding and self.drain is not None:
            self.drain()
            self.holding = False


def subscribe_batches(node, topic: Topic, handler: Callable[[list[dict]], None], *, reject: Optional[Reject],
                      limits: LimitsSource = None, accept: Optional[Callable[[dict], bool]] = None,
                      size: Callable[[dict], int] = lambda data: 1, max_size: int = 1000,
                      max_seconds: float = 0.02, clock: Callable[[], float] = time.monotonic,
                      gather: Optional[float] = None):
    """Subscribe like :func:`subscribe`, but hand ``handler`` every message already waiting, at once.

    When a message arrives, the messages waiting behind it in the reader are taken too
    (until their ``size`` sum reaches ``max_size``, or taking them has taken ``max_seconds``,
    so the node's other callbacks wait at most that long), each decoded and validated alone (a
    bad one is rejected alone, as :func:`subscribe` does); ``handler(messages)`` then
    gets the valid ones in arrival order, in one call, so a node can apply them in one
    commit (the consultant's ``ltm/assert``).  If it raises, every one of them is
    rejected with its id (``reject`` None: only logged, as :func:`subscribe` does for a topic nobody
    answers).  ``clock`` measures ``max_seconds`` (``time.thread_time``: this
    thread's CPU time, so a process the OS keeps waiting still takes as much work per
    callback, instead of a few messages and a whole round's overhead for them).

    ``gather`` (seconds): take a *stream* at most once a period.  A message into a quiet
    reader is taken at once, as above; after that the executor stops waiting on the reader
    (:class:`GatheringGroup`) and a steady-clock timer takes whatever arrived every
    ``gather`` seconds, until a period brings nothing (then the reader is waited on again,
    and the timer stops: an idle node pays nothing).  One message a millisecond is then
    ~``gather`` x 1,000 messages a round instead of a round each (an executor round,
    its wait set and the node's per-batch work cost far more than a message).  A drain
    stopped by ``max_size`` or ``max_seconds`` with messages still waiting hands the
    reader back to the executor at once, so a stream faster than the budget is not held
    back.  Returns the subscription.
    """
    logger = node.get_logger()
    validate = _checker(topic.schema, limits)
    max_bytes = (lambda: _limit(limits).max_message_bytes) if limits is not None else None  # noqa: E731
    stats = request_stats(node) if reject is not None else None  # an answered topic carries requests
    subscription = None

    def refuse(rid: Any, error: str, internal: bool, kind: str) -> None:
        text = f"{_context(topic.name, rid)}: {error}"
        (log_error if internal else log_warning)(logger, text)
        if reject is None:
            return
        try:
            reject(rid, printable(error), kind)
        except Exception as err:  # noqa: BLE001 - the rejection itself must not kill the node
            log_error(logger, f"{topic.name}: cannot publish the rejection: {type(err).__name__}: {printable(err)}")

    ignored = [0]

    def decoded(text: str) -> Optional[dict]:
        """Return the message if it is valid and for this node; None (rejected or ignored) otherwise."""
        seen: dict = {}
        try:
            payload = parse(text, max_bytes=_limit(max_bytes))
        except TooLarge as err:
            refuse(leading_id(text), printable(err), internal=False, kind=reply_kind(err))
            return None
        except ValueError as err:
            refuse(None, printable(err), internal=False, kind=reply_kind(err))
            return None
        seen["id"] = request_id(payload)
        if accept is not None and not accept(payload):
            ignored[0] += 1
            return None
        try:
            validate(payload)
        except ValueError as err:
            refuse(seen["id"], printable(err), internal=False, kind=reply_kind(err))
            return None
        except Exception as err:  # noqa: BLE001 - out of a drain it would stop the node: log, refuse, go on
            refuse(seen["id"], f"internal error: {type(err).__name__}: {printable(err)}", internal=True,
                   kind="internal")
            return None
        return payload

    def drain(first: Optional[String]) -> Optional[bool]:
        """Take ``first`` (None: the next waiting) and what waits behind it, within the budget; hand them over.

        Returns None if nothing was waiting, else whether the budget stopped the drain.
        """
        started, budget = time.monotonic(), clock()
        ignored[0] = 0
        if first is None and (first := take_waiting(subscription)) is None:
            return None
        data = decoded(first.data)
        batch = [data] if data is not None else []
        total = sum(size(data) for data in batch)
        taken, stopped = 1, False
        while not (stopped := total >= max_size or clock() - budget >= max_seconds):
            waiting = take_waiting(subscription)
            if waiting is None:
                break
            taken += 1
            data = decoded(waiting.data)
            if data is not None:
                batch.append(data)
                total += size(data)
        refused = len(batch) + ignored[0] < taken
        if batch:
            try:
                handler(batch)
            except (ValueError, CarrierError) as err:
                refused = True
                for data in batch:
                    refuse(request_id(data), printable(err), internal=False, kind=reply_kind(err))
            except Exception as err:  # noqa: BLE001 - log with context, keep serving
                refused = True
                for data in batch:
                    refuse(request_id(data), f"internal error: {type(err).__name__}: {printable(err)}",
                           internal=True, kind="internal")
        if stats is not None and taken > ignored[0]:  # messages for another node are not counted
            stats.record(time.monotonic() - started, refused=refused)
        return stopped

    if gather is None:
        subscription = node.create_subscription(String, topic.name, drain, qos_profile(topic.subscriber_qos))
        return subscription

    group = GatheringGroup()

    def arrived(msg: String) -> None:  # the first message into a quiet reader: take it now, then gather
        drain(msg)
        group.hold()
        timer.reset()

    def gathered() -> None:  # a period is over: take what came in it
        stopped = drain(None)
        if stopped is None:  # the stream has ended: wait on the reader again
            timer.cancel()
            group.holding = False
        elif stopped:  # more waits than a drain takes: let the executor take it at once
            group.holding = False

    timer = node.create_timer(gather, gathered, callback_group=group, clock=Clock(clock_type=ClockType.STEADY_TIME),
                              autostart=False)
    group.timer, group.drain = timer, lambda: drain(None)
    subscription = node.create_subscription(String, topic.name, arrived, qos_profile(topic.subscriber_qos),
                                            callback_group=group)
    return subscription


def take_waiting(subscription) -> Optional[String]:
    """Take the next message waiting in ``subscription``'s reader now (None: none waits).

    What the executor would deliver to the callback next, taken the way it takes it
    (``rclpy.executors.Executor._take_subscription``), so a callback can drain a burst.
    """
    try:
        with subscription.handle:
            taken = subscription.handle.take_message(subscription.msg_type, subscription.raw)
    except InvalidHandle:
        return None
    return None if taken is None else taken[0]


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
        group.entities.discard(weakref.ref(timer))
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
