"""JSON over ROS 2: the one place that knows how fsreg puts JSON on the wire (SPEC §7).

Topics carry ``std_msgs/msg/String`` whose ``data`` is one JSON object.  Services use
``diagnostic_msgs/srv/AddDiagnostics`` as a string-to-string carrier (common_interfaces
has no such service): the request JSON goes in ``load_namespace``, the reply JSON in
``message``; ``success=false`` means the reply is ``{"error": "...", "kind": "..."}``.

Reading a message:
    ``from_msg(msg, {"entity": str, "properties": list[str]}, optional={"time": NUMBER})``
returns the decoded object or raises :class:`MessageError` naming the field and what is
wrong.  A field spec is a type, a tuple of types (``None`` allows JSON ``null``), or
``list[T]`` / ``dict[str, T]``.  ``float`` accepts whole numbers; ``int`` never accepts
``true``/``false``; NaN and infinities are never valid JSON here.

Serving: :func:`serve` wraps a sync or async ``handler(dict) -> dict``.  A
:class:`MessageError`, any other ``ValueError`` (e.g. the core's ``KnowledgeError``) or a
:class:`CarrierError` from the handler becomes ``success=false`` plus a logged warning;
anything else becomes ``kind: "internal"`` plus a logged error.  The server never dies.

Calling: :class:`JsonClient` (one per service) sends at once (:meth:`JsonClient.send`,
so requests leave in program order) and awaits with a deadline enforced by a
steady-clock timer (it fires even under sim time with a stopped ``/clock``).  Await only
from a callback whose group is not the client's group (ROS-NOTES: a client in the
awaiting callback's mutually exclusive group deadlocks); by default each client gets
its own :class:`~rclpy.callback_groups.ReentrantCallbackGroup`.
"""

from __future__ import annotations

import inspect
import json
import math
import time
import types
from typing import Any, Awaitable, Callable, Mapping, Optional, Union

from diagnostic_msgs.srv import AddDiagnostics
from rclpy.callback_groups import CallbackGroup, ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from std_msgs.msg import String

__all__ = [
    "NUMBER",
    "SERVICE_TYPE",
    "STATE_QOS",
    "STATE_PUB_QOS",
    "EVENTS_QOS",
    "DEFAULT_QOS",
    "DEFAULT_TIMEOUT",
    "MessageError",
    "CarrierError",
    "JsonClient",
    "to_msg",
    "from_msg",
    "parse",
    "check_fields",
    "dumps",
    "serve",
    "call",
    "wait_until",
]

#: The service type used as a JSON carrier.
SERVICE_TYPE = AddDiagnostics
#: Field spec for "any JSON number" (whole numbers included, booleans excluded).
NUMBER = (int, float)
#: Default deadline of a service call, seconds (ROS-NOTES: a first call can take ~4 s).
DEFAULT_TIMEOUT = 10.0

#: ``/wm/state`` readers: latched (transient local), reliable, depth 10 so a late
#: joiner gets the state of up to 10 consultants (ROS-NOTES: reader depth >= domains).
STATE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
#: ``/wm/state`` writer (one per consultant): latched, but only the latest state is
#: kept for late joiners, so N consultants hand a late reader N messages, not 10 N.
STATE_PUB_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
#: ``/wm/events``: reliable and volatile; a deep history because one change (a reset,
#: a decay tick) can emit many events at once and every one of them matters.
EVENTS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
#: Everything else: reliable, volatile, depth 10 (the rclpy default).
DEFAULT_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

FieldSpec = Union[type, tuple, types.GenericAlias, None]


class MessageError(ValueError):
    """A message or request that is not what it must be: not JSON, not an object, a
    missing or wrong-typed field, an unknown op.  The text says which field and why."""


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


# ----------------------------------------------------------------- encoding
def dumps(obj: Mapping[str, Any]) -> str:
    """Compact JSON text of one object (NaN/Infinity refused: they are not JSON)."""
    return json.dumps(obj, separators=(",", ":"), allow_nan=False)


def to_msg(obj: Mapping[str, Any]) -> String:
    """A ``std_msgs/String`` carrying ``obj`` as JSON."""
    return String(data=dumps(obj))


def _reject_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def parse(
    text: str,
    required: Optional[Mapping[str, FieldSpec]] = None,
    optional: Optional[Mapping[str, FieldSpec]] = None,
) -> dict:
    """Decode one JSON object from ``text`` and check its fields (see :func:`check_fields`)."""
    if not isinstance(text, str):
        raise MessageError(f"expected JSON text, got {type(text).__name__}")
    try:
        obj = json.loads(text, parse_constant=_reject_constant)
    except (ValueError, RecursionError) as err:
        raise MessageError(f"not JSON ({err}): {_clip(text)}") from None
    if not isinstance(obj, dict):
        raise MessageError(f"expected a JSON object, got {_json_kind(obj)}: {_clip(text)}")
    return check_fields(obj, required or {}, optional)


def from_msg(
    msg: String,
    required: Optional[Mapping[str, FieldSpec]] = None,
    optional: Optional[Mapping[str, FieldSpec]] = None,
) -> dict:
    """Decode a ``std_msgs/String`` carrying one JSON object; check its fields.

    ``required`` maps field names to specs; a missing or wrong-typed one raises
    :class:`MessageError`.  ``optional`` fields are checked only when present.
    Other fields are kept unchecked.
    """
    return parse(getattr(msg, "data", msg), required, optional)


def check_fields(
    obj: Mapping[str, Any],
    required: Mapping[str, FieldSpec],
    optional: Optional[Mapping[str, FieldSpec]] = None,
) -> dict:
    """Check the fields of an already decoded object; return it as a dict."""
    for name, spec in required.items():
        if name not in obj:
            raise MessageError(f"missing field '{name}' (expected {describe(spec)})")
        _check_value(name, obj[name], spec)
    for name, spec in (optional or {}).items():
        if name in obj:
            _check_value(name, obj[name], spec)
    return dict(obj)


def describe(spec: FieldSpec) -> str:
    """English for a field spec: ``list[str]`` -> ``"a list of strings"``."""
    if spec is None or spec is type(None):
        return "null"
    if isinstance(spec, tuple):
        return " or ".join(describe(s) for s in spec)
    if isinstance(spec, types.GenericAlias):
        origin, args = spec.__origin__, spec.__args__
        if origin is list:
            return f"a list of {_plural(args[0])}"
        if origin is dict:
            return f"an object of {_plural(args[0]).replace('strings', 'names')} to {_plural(args[1])}"
    return {
        str: "a string",
        int: "a whole number",
        float: "a number",
        bool: "true or false",
        list: "a list",
        dict: "an object",
    }.get(spec, getattr(spec, "__name__", str(spec)))


def _plural(spec: FieldSpec) -> str:
    if spec == NUMBER or spec is float:
        return "numbers"
    return {str: "strings", int: "whole numbers", bool: "booleans", dict: "objects", list: "lists"}.get(
        spec, describe(spec)
    )


def _matches(value: Any, spec: FieldSpec) -> bool:
    if spec is None or spec is type(None):
        return value is None
    if isinstance(spec, tuple):
        return any(_matches(value, s) for s in spec)
    if isinstance(spec, types.GenericAlias):
        origin, args = spec.__origin__, spec.__args__
        if origin is list:
            return isinstance(value, list) and all(_matches(v, args[0]) for v in value)
        if origin is dict:
            return isinstance(value, dict) and all(
                _matches(k, args[0]) and _matches(v, args[1]) for k, v in value.items()
            )
        raise TypeError(f"unsupported field spec {spec!r}")
    if spec is bool:
        return isinstance(value, bool)
    if isinstance(value, bool):
        return False  # JSON true/false is not a number
    if spec is float:
        return isinstance(value, (int, float)) and math.isfinite(value)
    return isinstance(value, spec)


def _check_value(name: str, value: Any, spec: FieldSpec) -> None:
    if _matches(value, spec):
        return
    where = f"field '{name}'"
    if isinstance(spec, types.GenericAlias) and spec.__origin__ is list and isinstance(value, list):
        for i, item in enumerate(value):
            if not _matches(item, spec.__args__[0]):
                raise MessageError(
                    f"{where}[{i}]: expected {describe(spec.__args__[0])}, got {_show(item)}"
                )
    if isinstance(spec, types.GenericAlias) and spec.__origin__ is dict and isinstance(value, dict):
        for key, item in value.items():
            if not _matches(item, spec.__args__[1]):
                raise MessageError(f"{where}['{key}']: expected {describe(spec.__args__[1])}, got {_show(item)}")
    raise MessageError(f"{where}: expected {describe(spec)}, got {_show(value)}")


def _json_kind(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, float)):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "a list"
    return "an object"


def _show(value: Any) -> str:
    try:
        text = json.dumps(value)
    except (TypeError, ValueError):
        text = repr(value)
    return f"{_json_kind(value)} ({_clip(text)})"


def _clip(text: str, limit: int = 80) -> str:
    text = str(text)
    return text if len(text) <= limit else text[: limit - 3] + "..."


# ----------------------------------------------------------------- serving
Handler = Callable[[dict], Union[Mapping[str, Any], Awaitable[Mapping[str, Any]]]]


def error_kind(err: BaseException) -> str:
    """The ``kind`` an error reply carries: the exception's class name, or for a
    :class:`CarrierError` its own kind (e.g. ``timeout`` of a call made downstream)."""
    if isinstance(err, CarrierError):
        return err.kind
    return type(err).__name__


def serve(node, name: str, handler: Handler, callback_group: Optional[CallbackGroup] = None):
    """Serve ``handler`` as a JSON service ``name`` on ``node``; returns the service.

    ``handler(request: dict) -> dict`` may be sync or ``async``.  Errors never escape:
    see the module docstring.  An async handler that awaits other services must use
    clients outside ``callback_group`` (by default the node's mutually exclusive group).
    """
    logger = node.get_logger()

    async def callback(request, response):
        try:
            payload = parse(request.load_namespace)
            result = handler(payload)
            if inspect.isawaitable(result):
                result = await result
            if not isinstance(result, Mapping):
                raise TypeError(f"handler returned {type(result).__name__}, not a JSON object")
            text = dumps(result)
        except (ValueError, CarrierError) as err:
            logger.warning(f"{name}: {err}")
            response.success = False
            response.message = dumps({"error": str(err), "kind": error_kind(err)})
            return response
        except Exception as err:  # noqa: BLE001 - a server must answer, whatever happened
            logger.error(f"{name}: internal error: {type(err).__name__}: {err}")
            response.success = False
            response.message = dumps({"error": f"internal error: {type(err).__name__}: {err}", "kind": "internal"})
            return response
        response.success = True
        response.message = text
        return response

    return node.create_service(SERVICE_TYPE, name, callback, callback_group=callback_group)


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
        """A JsonClient over an existing ``AddDiagnostics`` client of ``node``."""
        return cls(node, client.srv_name, timeout=timeout, client=client)

    def ready(self) -> bool:
        """A server is matched (not proof it answers: see :meth:`wait_ready`)."""
        return self.client.service_is_ready()

    def send(self, payload: Mapping[str, Any]) -> Future:
        """Send one request now (so requests leave in call order); a Future of the reply."""
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
                timer.cancel()
                self.node.destroy_timer(timer)
        return self.decode(future)

    def expire(self, future: Future, timeout: float) -> None:
        """Give up on a pending request: its future fails with kind ``timeout``."""
        if not future.done():
            self.client.remove_pending_request(future)
            future.set_exception(
                CarrierError(f"no reply within {timeout:g} s", kind="timeout", service=self.name)
            )

    def decode(self, future: Future) -> dict:
        """The reply of a done future, or raise :class:`CarrierError`."""
        return self.decode_response(future, self.name)

    @staticmethod
    def decode_response(future: Future, name: str) -> dict:
        """The reply object of a done service future, or :class:`CarrierError`."""
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
                error if isinstance(error, str) else f"failed without a reason: {_clip(response.message)}",
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
        """Readiness = one real round trip (ROS-NOTES): wait for the server, then call
        ``payload`` until one succeeds or ``timeout`` passes; returns its reply.

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


async def call(client, payload: Mapping[str, Any], timeout: Optional[float] = None, *, node=None) -> dict:
    """``await call(client, {"op": ...}, timeout)``: the reply, or :class:`CarrierError`.

    ``client`` is a :class:`JsonClient`, or a plain ``AddDiagnostics`` client.  For a
    plain client pass its ``node`` so the deadline is a timer; without it the deadline
    is only checked when something else wakes the executor (rclpy resumes pending
    tasks on every wake-up), so a dead server can block a quiet ``spin()`` forever.
    """
    if isinstance(client, JsonClient):
        return await client.call(payload, timeout)
    timeout = DEFAULT_TIMEOUT if timeout is None else timeout
    if node is not None:
        return await JsonClient.wrap(node, client, timeout).call(payload, timeout)
    future = client.call_async(SERVICE_TYPE.Request(load_namespace=dumps(payload)))
    deadline = time.monotonic() + timeout
    while not future.done():
        if time.monotonic() >= deadline:
            client.remove_pending_request(future)
            raise CarrierError(f"no reply within {timeout:g} s", kind="timeout", service=client.srv_name)
        await _Yield()
    return JsonClient.decode_response(future, client.srv_name)


class _Yield:
    """Awaitable that gives control back to the rclpy executor once."""

    def __await__(self):
        yield


async def wait_until(
    node,
    predicate: Callable[[], bool],
    timeout: float,
    *,
    callback_group: Optional[CallbackGroup] = None,
    period: float = 0.02,
) -> bool:
    """Await (without blocking the executor) until ``predicate()`` or ``timeout`` seconds
    (steady clock) pass; True if the predicate came true.  A steady-clock timer in
    ``callback_group`` (not the awaiting callback's group) polls the predicate."""
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
        timer.cancel()
        node.destroy_timer(timer)
