"""JSON over ROS 2 services and topics: serving, subscribing, calling (docs/semantics.md §7).

The one small module for fsreg's carrier convention, and the only place where the
ROS-free contract meets ROS types: names, QoS specs and schemas are in
:mod:`fsreg_ros.contract` (:func:`qos_profile` makes an rclpy profile of a
:class:`~fsreg_ros.contract.QosSpec`); the JSON codec is :mod:`fsreg_ros.codec`
(:func:`to_msg`/:func:`from_msg` wrap it in ``std_msgs/String``).

Services use ``diagnostic_msgs/srv/AddDiagnostics`` as a string-to-string carrier
(common_interfaces has no such service): the request JSON goes in ``load_namespace``,
the reply JSON in ``message``; ``success=false`` means the reply is
``{"error": "...", "kind": "..."}``.

Serving: :func:`serve` wraps a sync or async ``handler(dict) -> dict``.  A
:class:`MessageError`, any other ``ValueError`` (e.g. the core's ``KnowledgeError``) or a
:class:`CarrierError` from the handler becomes ``success=false`` plus a logged warning;
anything else becomes ``kind: "internal"`` plus a logged error naming the service and the
request id.  Every call is answered (the reply is built by :func:`~fsreg_ros.codec.error_json`,
which cannot fail) and the server keeps serving.

Subscribing: :func:`subscribe` does the same for a topic: a message that is not a JSON
object within the size limit, or whose handler raises, is rejected (``reject(id, error)``
publishes the reply the contract has for it, if any) and logged with the topic and id.

Calling: :class:`JsonClient` (one per service) sends at once (:meth:`JsonClient.send`,
so requests leave in program order) and awaits with a deadline enforced by a
steady-clock timer (it fires even under sim time with a stopped ``/clock``).  Await only
from a callback whose group is not the client's group (ROS-NOTES: a client in the
awaiting callback's mutually exclusive group deadlocks); by default each client gets
its own :class:`~rclpy.callback_groups.ReentrantCallbackGroup`.
"""

from __future__ import annotations

import inspect
import time
import weakref
from typing import Any, Awaitable, Callable, Mapping, Optional, Union

from diagnostic_msgs.srv import AddDiagnostics
from rclpy.callback_groups import CallbackGroup, ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from std_msgs.msg import String

from .codec import FieldSpec, MessageError, dumps, error_json, parse, printable, request_id, safe_dumps
from .contract import QosSpec, Topic

#: The service type used as a JSON carrier.
SERVICE_TYPE = AddDiagnostics
#: Default deadline of a service call, seconds (ROS-NOTES: a first call can take ~4 s).
DEFAULT_TIMEOUT = 10.0

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
    return type(err).__name__


def _limit(limit: Limit) -> Optional[int]:
    return limit() if callable(limit) else limit


def _context(where: str, rid: Any) -> str:
    return f"{where} (id {printable(repr(rid), 80)})" if rid is not None else where


async def _run(handler, text: str, max_bytes: Limit, seen: dict) -> Any:
    """Decode ``text`` (bounded), note its request id in ``seen``, run ``handler``; return its result."""
    payload = parse(text, max_bytes=_limit(max_bytes))
    seen["id"] = request_id(payload)
    result = handler(payload)
    if inspect.isawaitable(result):
        result = await result
    return result


# ----------------------------------------------------------------- serving
Handler = Callable[[dict], Union[Mapping[str, Any], Awaitable[Mapping[str, Any]]]]


def serve(node, name: str, handler: Handler, callback_group: Optional[CallbackGroup] = None,
          *, max_bytes: Limit = None):
    """Serve ``handler`` as a JSON service ``name`` on ``node``; return the service.

    ``handler(request: dict) -> dict`` may be sync or ``async``.  Errors never escape:
    see the module docstring.  ``max_bytes`` (a number or a callable giving one) bounds
    the request size.  An async handler that awaits other services must use clients
    outside ``callback_group`` (by default the node's mutually exclusive group).
    """
    logger = node.get_logger()

    async def callback(request, response):
        seen: dict = {}
        try:
            result = await _run(handler, request.load_namespace, max_bytes, seen)
            if not isinstance(result, Mapping):
                raise TypeError(f"handler returned {type(result).__name__}, not a JSON object")
            text = dumps(result)
        except (ValueError, CarrierError) as err:
            rid = seen.get("id")
            logger.warning(printable(f"{_context(name, rid)}: {err}"))
            response.success = False
            response.message = error_json(err, error_kind(err), rid)
            return response
        except Exception as err:  # noqa: BLE001 - a server must answer, whatever happened
            rid = seen.get("id")
            logger.error(printable(f"{_context(name, rid)}: internal error: {type(err).__name__}: {err}"))
            response.success = False
            response.message = error_json(f"internal error: {type(err).__name__}: {err}", "internal", rid)
            return response
        response.success = True
        response.message = text
        return response

    return node.create_service(SERVICE_TYPE, name, callback, callback_group=callback_group)


# ----------------------------------------------------------------- messages
def qos_profile(spec: Union[QosSpec, QoSProfile]) -> QoSProfile:
    """Return the rclpy profile of a contract QoS spec: reliable, keep last ``depth``, latched or volatile."""
    if isinstance(spec, QoSProfile):
        return spec
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=spec.depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if spec.latched else DurabilityPolicy.VOLATILE,
    )


def to_msg(obj: Mapping[str, Any]) -> String:
    """Return a ``std_msgs/String`` carrying ``obj`` as JSON (NaN/Infinity refused: they are not JSON)."""
    return String(data=dumps(obj))


def from_msg(
    msg: String,
    required: Optional[Mapping[str, FieldSpec]] = None,
    optional: Optional[Mapping[str, FieldSpec]] = None,
    *,
    max_bytes: Optional[int] = None,
) -> dict:
    """Decode a ``std_msgs/String`` carrying one JSON object; check its fields.

    ``required`` maps field names to specs; a missing or wrong-typed one raises
    :class:`MessageError`.  ``optional`` fields are checked only when present.
    Other fields are kept unchecked.
    """
    return parse(getattr(msg, "data", msg), required, optional, max_bytes=max_bytes)


# ----------------------------------------------------------------- topics
def publisher(node, topic: Topic):
    """Return a ``std_msgs/String`` publisher of a contract topic, with its QoS."""
    return node.create_publisher(String, topic.name, qos_profile(topic.qos))


def publish(pub, obj: Mapping[str, Any]) -> None:
    """Publish one JSON object (sanitised if it is not JSON as it stands: never raises on content)."""
    pub.publish(String(data=safe_dumps(obj)))


Reject = Callable[[Any, str], None]


def subscribe(node, topic: Topic, handler: Handler, *, reject: Optional[Reject] = None,
              callback_group: Optional[CallbackGroup] = None, max_bytes: Limit = None):
    """Subscribe ``handler(data: dict)`` (sync or async) to a contract topic; return the subscription.

    A message that is not a JSON object (within ``max_bytes``), or whose handler raises
    a ``ValueError``/:class:`CarrierError`, is logged as a warning naming the topic and
    id and passed to ``reject(id, error)``; any other exception is logged as an error
    and rejected as an internal error.  The node keeps serving either way.
    """
    logger = node.get_logger()

    def refuse(rid: Any, error: str, internal: bool) -> None:
        text = printable(f"{_context(topic.name, rid)}: {error}")
        (logger.error if internal else logger.warning)(text)
        if reject is not None:
            try:
                reject(rid, printable(error))
            except Exception as err:  # noqa: BLE001 - the rejection itself must not kill the node
                logger.error(printable(f"{topic.name}: cannot publish the rejection: {type(err).__name__}: {err}"))

    async def callback(msg: String) -> None:
        seen: dict = {}
        try:
            await _run(handler, msg.data, max_bytes, seen)
        except (ValueError, CarrierError) as err:
            refuse(seen.get("id"), str(err), internal=False)
        except Exception as err:  # noqa: BLE001 - log with context, keep serving
            refuse(seen.get("id"), f"internal error: {type(err).__name__}: {err}", internal=True)

    return node.create_subscription(String, topic.name, callback, qos_profile(topic.subscriber_qos),
                                    callback_group=callback_group)


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


class JsonClient:
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
            self.client = node.create_client(SERVICE_TYPE, name, callback_group=self.callback_group)
        self._steady = Clock(clock_type=_STEADY)

    @classmethod
    def wrap(cls, node, client, timeout: float = DEFAULT_TIMEOUT) -> "JsonClient":
        """Return a JsonClient over an existing ``AddDiagnostics`` client of ``node``."""
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
