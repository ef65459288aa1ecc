"""Shared base of the nodes that ask consultants questions (RR and REG).

Such a node knows the consultant domains it may ask (``domains`` parameter), reaches
each through a :class:`~fsreg_ros.ros.remote.RemotePort`, and handles one request at a
time, in arrival order: the request subscription is an async callback in a mutually
exclusive group (the group stays busy until the coroutine returns), while the
service clients live in a reentrant group so their responses can arrive meanwhile
(a client in the busy group deadlocks: see :mod:`fsreg_ros.ros.carrier`, "Calling").

Request ids have one meaning per client (a request's optional ``client`` field; see
:mod:`fsreg_ros.contract.attribution`).  Delivery is at-least-once: a requester that
heard no answer may send the same request again, and the node answers it from its cache
instead of running the algorithm twice (which would encode into WM twice).  A request
that reuses an id for a *different* request is answered with an error of kind
``IdConflict`` whose ``conflicts_with`` names the request holding the id (its client and
fingerprint), never with the other request's answer, and the cache keeps the first
answer.  Every answer echoes the request's ``id``, ``client`` and fingerprint
(``request``), so requesters sharing the answer topic can each tell theirs.  An answer
that carries an error (a consultant timed out or is down, an unknown entity, ...) is not
cached: a retry runs again.  The cache is bounded in entries and in bytes (answers are
kept as their JSON text).
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Optional

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.exceptions import ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import String

from .clock_parameter import fix_use_sim_time
from .. import contract
from .carrier import DEFAULT_TIMEOUT, stamped, subscribe
from ..contract.codec import printable, safe_dumps
from ..contract import LIMIT_RANGES, Limits, RequestRef, attribution, cache_key, fingerprint
from .remote import RemotePort
from .diagnostics import OK, WARN
from .node_base import StartupError, declare_number, descriptor, now_seconds, watch_clock

#: Deadline for the consultants to answer their first round trip (seconds).
READY_TIMEOUT = 30.0


class AnswerCache:
    """The answers to the latest request ids, bounded by entries and by bytes (oldest dropped).

    Keyed by :func:`~fsreg_ros.contract.cache_key` (client, id); each entry is (the
    request's client and fingerprint, the answer as JSON text), so a reused id is told
    apart from a resent request without keeping the request.
    """

    #: Bytes counted per entry on top of the answer text (key, fingerprint, dict slot).
    OVERHEAD = 200

    def __init__(self, max_entries: int = Limits.answer_cache_entries,
                 max_bytes: int = Limits.answer_cache_bytes) -> None:
        self.max_entries = max_entries
        self.max_bytes = max_bytes
        self.bytes = 0
        self._answers: OrderedDict[tuple, tuple[RequestRef, str]] = OrderedDict()

    def __len__(self) -> int:
        return len(self._answers)

    def get(self, request: dict, fingerprint: str) -> tuple[Optional[str], Optional[RequestRef]]:
        """Return (cached answer text or None, the request holding the id if it is another one)."""
        entry = self._answers.get(cache_key(request))
        if entry is None:
            return None, None
        if entry[0].request != fingerprint:
            return None, entry[0]
        return entry[1], None

    def put(self, request: dict, fingerprint: str, answer: str) -> None:
        key = cache_key(request)
        size = len(answer) + len(str(key)) + self.OVERHEAD
        if key in self._answers or size > self.max_bytes or self.max_entries == 0:
            return
        self._answers[key] = (RequestRef(client=key[0], request=fingerprint), answer)
        self.bytes += size
        while len(self._answers) > self.max_entries or self.bytes > self.max_bytes:
            old_key, (_, old) = self._answers.popitem(last=False)
            self.bytes -= len(old) + len(str(old_key)) + self.OVERHEAD


class AskingNode(Node):
    """A node that resolves or generates by asking the consultants of ``domains``."""

    def __init__(self, name: str, **kwargs) -> None:
        super().__init__(name, **kwargs)
        fix_use_sim_time(self)  # one clock for the whole graph
        self.declare_parameter(
            "domains",
            Parameter.Type.STRING_ARRAY,
            descriptor("consultant domains to ask (one consultant node per domain)", read_only=True),
        )
        try:
            domains = [d for d in self.get_parameter("domains").value if d]
        except ParameterUninitializedException:
            domains = []
        if not domains:
            raise StartupError("parameter 'domains' must name at least one consultant domain "
                               "(e.g. -p \"domains:=[faces]\")")
        self.limits = declare_limits(self)
        timeout = declare_number(self, "service_timeout", DEFAULT_TIMEOUT, 0.05, 600.0,
                                 "deadline of one consultant call, s; after a timeout that consultant fails fast "
                                 "until it answers again", read_only=True)
        self.ready_timeout = declare_number(self, "ready_timeout", READY_TIMEOUT, 0.1, 3600.0,
                                            "deadline for the consultants' first round trip, s", read_only=True)
        self.request_group = MutuallyExclusiveCallbackGroup()
        self.client_group = ReentrantCallbackGroup()
        self.ports = {d: RemotePort(self, d, self.client_group, timeout) for d in domains}
        self.answers = AnswerCache(self.limits.answer_cache_entries, self.limits.answer_cache_bytes)
        subscribe(self, contract.ANNOUNCE, self._on_announce, callback_group=self.client_group)
        subscribe(self, contract.READY, self._on_manager_ready, callback_group=self.client_group)
        self._clock_watch = watch_clock(self)

    def _on_announce(self, announce: dict) -> None:
        """Tell the port of a (re)started consultant, so it stops waiting on the previous incarnation."""
        port = self.ports.get(announce["domain"])
        if port is not None:
            port.restarted(announce["incarnation"])

    def _on_manager_ready(self, ready: dict) -> None:
        """Tell each port the incarnation the WM Manager reports (and whether it configured it)."""
        for domain, state in ready["domains"].items():
            port = self.ports.get(domain)
            if port is not None:
                port.reported(state.get("incarnation"), bool(state.get("configured")))

    def diagnostic_values(self) -> tuple[int, str, dict]:
        """``/diagnostics``: each consultant this node asks, alive or not (its liveliness)."""
        values = {f"{d}.alive": port.alive for d, port in sorted(self.ports.items())}
        values.update({f"{d}.incarnation": port.incarnation for d, port in sorted(self.ports.items())})
        lost = sorted(d for d, port in self.ports.items() if port.alive is False)
        if lost:
            return WARN, f"consultant(s) unreachable: {', '.join(lost)}", values
        return OK, "running", values

    async def ensure_ready(self) -> None:
        """Wait (with the ``ready_timeout`` deadline) for a round trip with each consultant that needs one.

        At start, and after the WM Manager reported a consultant's restart (see
        :mod:`fsreg_ros.ros.remote`): then the next request waits for the new incarnation
        instead of failing while this process has not discovered it yet.
        """
        for port in self.ports.values():
            if port.needs_round_trip():
                await port.wait_ready(self.ready_timeout)

    def request_time(self, data: dict) -> float:
        """Return the request's ``time`` (the robot-clock time of the utterance), else now."""
        time = data.get("time")
        return float(time) if isinstance(time, (int, float)) and not isinstance(time, bool) else now_seconds(self)

    def answer_once_on(self, publisher):
        """Return the request handler that answers each (validated) request once on ``publisher``."""
        return lambda data: self.answer_once(data, publisher)

    def fingerprint(self, data: dict) -> str:
        """Return the fingerprint of request ``data`` (what its answer echoes as ``request``)."""
        return fingerprint(data)

    async def answer_once(self, data: dict, publisher) -> None:
        """Publish the answer to request ``data``, computed once per (client, id, request).

        See the module docstring for what a repeated or reused id gets.
        """
        request = self.fingerprint(data)
        cached, holder = self.answers.get(data, request)
        if holder is not None:
            who = f" of client {printable(repr(data['client']), 80)}" if data.get("client") is not None else ""
            error = (f"request id {printable(repr(data['id']), 80)}{who} was already used for a different request "
                     f"(fingerprint {holder.request}; this one is {request}); use a new id for a new request")
            self.get_logger().warning(error)
            reply = {**attribution(data, request), "error": error, "kind": "IdConflict",
                     "conflicts_with": holder.model_dump(), **self.error_fields(data)}
            publisher.publish(String(data=safe_dumps(stamped(publisher, reply))))
            return
        if cached is None:
            reply = {**attribution(data, request), **await self.answer(data)}
            cached = safe_dumps(stamped(publisher, reply))  # the answer as published, graph identity included
            if "error" not in reply:
                self.answers.put(data, request, cached)
        publisher.publish(String(data=cached))

    def error_fields(self, data: dict) -> dict:
        """Return the fields an error answer on this node's topic needs besides ``error`` (subclasses add theirs)."""
        return {}

    async def answer(self, data: dict) -> dict:  # pragma: no cover - abstract
        """Return the answer to one request (without its attribution, which :meth:`answer_once` adds)."""
        raise NotImplementedError


def declare_limits(node) -> Limits:
    """Declare the size-limit parameters (read-only, with ranges); return their values."""
    defaults = Limits()
    docs = {
        "max_message_bytes": "largest accepted message or request, UTF-8 bytes of JSON",
        "max_name_chars": "longest accepted entity/property/domain/target name, characters",
        "max_list_items": "longest accepted list (descriptions, context sets, entity lists)",
        "answer_cache_entries": "answers remembered for repeated request ids, entries",
        "answer_cache_bytes": "answers remembered for repeated request ids, bytes of JSON",
    }
    values = {
        name: declare_number(node, name, getattr(defaults, name), *LIMIT_RANGES[name], docs[name],
                             integer=True, read_only=True)
        for name in docs
    }
    return Limits(**values)
