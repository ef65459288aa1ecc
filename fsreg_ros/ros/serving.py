"""Serving a contract service over the JSON carrier (docs/semantics.md §7): :func:`serve`.

Owns what a server does with a request: each one is decoded (bounded in size), validated
once against the service's request schema (names and lists within the node's limits;
:func:`fsreg_ros.contract.check`, one-line errors naming the field), and only then passed to
the handler (one, or one per ``op``: :func:`dispatch`).  A
:class:`~fsreg_ros.contract.codec.MessageError`, any other ``ValueError`` (e.g. the core's
``KnowledgeError``) or a :class:`~fsreg_ros.ros.carrier.CarrierError` becomes
``success=false`` plus a logged warning; anything else becomes ``kind: "internal"`` plus a
logged error naming the service and the request id.  Every call is answered (the reply is
built by :func:`~fsreg_ros.contract.codec.error_json`, which cannot fail) and the server
keeps serving.  With ``drain``, the requests waiting behind an answered one are answered
ahead of the executor's next round (:class:`JsonService`).
"""

from __future__ import annotations

import time
from typing import Any, Mapping, Optional, Union

from pydantic import BaseModel
from rclpy.callback_groups import CallbackGroup
from rclpy.exceptions import InvalidHandle

from ..contract import SERVICE_QOS, Limits, Service
from ..contract.codec import MessageError, dumps, error_json, printable
from .carrier import (SERVICE_TYPE, CarrierError, Handler, Limit, LimitsSource, checker, error_kind, log_error,
                      log_warning, max_bytes_of, qos_profile, reply_kind, run_handler, where)
from .diagnostics import request_stats
from .rclpy_internals import take_request

#: Most CPU seconds a :class:`JsonService` spends answering the requests waiting, per round.
DRAIN_SECONDS = 0.01


def reply_object(result: Any) -> Mapping[str, Any]:
    """Return a handler's reply as a JSON object: a mapping as it is, a contract model dumped (fields set only)."""
    if isinstance(result, BaseModel):
        return result.model_dump(mode="json", exclude_unset=True)
    if not isinstance(result, Mapping):
        raise TypeError(f"handler returned {type(result).__name__}, not a JSON object")
    return result


def check_op(handlers: Mapping[str, Any], request: dict) -> None:
    """Refuse a request whose ``op`` has no handler (before its schema, which depends on the op)."""
    if "op" not in request:
        raise MessageError(f"missing field 'op' (one of {', '.join(handlers)})")
    op = request["op"]
    if not isinstance(op, str) or op not in handlers:
        raise MessageError(f"field 'op': expected one of {', '.join(handlers)}, got {printable(repr(op), 60)}")


def dispatch(handlers: Mapping[str, Handler], validate) -> tuple:
    """One handler per ``op``: ``(handler, validate)``, the request's ``op`` checked first, then its schema."""
    def validate_op(data: dict) -> None:
        check_op(handlers, data)
        validate(data)

    return (lambda request: handlers[request["op"]](request)), validate_op


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
    if isinstance(service, Service):
        name, schema = service.name.replace("<domain>", domain or "<domain>"), service.request
    else:
        name, schema = service, None
    validate, handler = checker(schema, limits), handlers
    if isinstance(handlers, Mapping):
        handler, validate = dispatch(handlers, validate)
    if max_bytes is None:
        max_bytes = max_bytes_of(limits)
    if max_bytes is None:  # a service is never unbounded (the WM Manager's status read 1 MB requests whole)
        max_bytes = Limits().max_message_bytes
    return JsonService(node, name, handler, validate, max_bytes, drain, callback_group).server


class JsonService:
    """One served service: answers each request (:meth:`answer`) and, with ``drain``, the requests waiting behind it."""

    def __init__(self, node, name: str, handler: Handler, validate, max_bytes: Limit, drain: int,
                 callback_group: Optional[CallbackGroup]) -> None:
        self.node, self.name, self.handler, self.validate = node, name, handler, validate
        self.max_bytes, self.drain = max_bytes, drain
        self.logger = node.get_logger()
        self.stats = request_stats(node)
        self.draining = False  # a drain is scheduled or running: no second one
        self.server = node.create_service(SERVICE_TYPE, name, self.callback, qos_profile=qos_profile(SERVICE_QOS),
                                          callback_group=callback_group)

    async def callback(self, request, response):
        """Answer ``request`` (the executor's callback), then schedule the drain of what waits behind it."""
        started = time.monotonic()
        response = await self.answer(request, response)
        self.stats.record(time.monotonic() - started, refused=not response.success)
        if self.drain and not self.draining and self.node.executor is not None:
            waiting = take_request(self.server)  # a cheap look: nothing waits, nothing is scheduled
            if waiting is not None:
                await self.schedule(waiting)
        return response

    async def schedule(self, waiting: tuple) -> None:
        """Answer ``waiting`` and what follows it first in the executor's next round (now, if it is shutting down)."""
        self.draining = True
        try:
            self.node.executor.create_task(self.answer_waiting, waiting)  # run first in the next round
        except Exception:  # noqa: BLE001 - an executor shutting down: answer it now
            self.draining = False
            await self.answer_taken(*waiting)

    async def answer_taken(self, request, header) -> bool:
        """Answer one taken request as the executor would; False once the service is gone."""
        begun = time.monotonic()
        reply = await self.answer(request, self.server.srv_type.Response())
        self.stats.record(time.monotonic() - begun, refused=not reply.success)
        try:
            self.server.send_response(reply, header)
        except InvalidHandle:
            return False
        return True

    async def answer_waiting(self, first: tuple) -> None:
        """Answer ``first`` and the requests waiting behind it now (bounded), in order."""
        try:
            budget = time.thread_time()  # CPU time: a process kept waiting by the OS still answers as many
            waiting: Optional[tuple] = first
            for _ in range(self.drain):
                if waiting is None or not await self.answer_taken(*waiting):
                    return
                if time.thread_time() - budget >= DRAIN_SECONDS:
                    return
                waiting = take_request(self.server)
            if waiting is not None:  # over the count: answered now, the rest as the executor takes them
                await self.answer_taken(*waiting)
        finally:
            self.draining = False

    async def answer(self, request, response):
        """Fill ``response`` with the reply to ``request``: the handler's, or an error reply (never raises)."""
        seen: dict = {}
        try:
            result = await run_handler(self.handler, request.load_namespace, self.max_bytes, seen, self.validate)
            text = dumps(reply_object(result))
        except (ValueError, CarrierError) as err:
            return self.refuse(response, seen.get("id"), err)
        except Exception as err:  # noqa: BLE001 - a server must answer, whatever happened
            rid = seen.get("id")
            text = f"internal error: {type(err).__name__}: {printable(err)}"
            log_error(self.logger, f"{where(self.name, rid)}: {text}")
            response.success = False
            response.message = error_json(text, "internal", rid)
            return response
        response.success = True
        response.message = text
        return response

    def refuse(self, response, rid: Any, err: BaseException):
        """Fill ``response`` with the error reply to a refused request; log it as a warning."""
        log_warning(self.logger, f"{where(self.name, rid)}: {printable(err)}")
        response.success = False
        detail = reply_kind(err)  # a specific kind (unknown-entity, ...) beside the class name
        response.message = error_json(err, error_kind(err), rid,
                                      **({"detail": detail} if detail != error_kind(err) else {}))
        return response
