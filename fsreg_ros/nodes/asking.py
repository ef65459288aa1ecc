"""Shared base of the nodes that ask consultants questions (RR and REG).

Such a node knows the consultant domains it may ask (``domains`` parameter), reaches
each through a :class:`~fsreg_ros.remote.RemotePort`, and handles one request at a
time, in arrival order: the request subscription is an async callback in a mutually
exclusive group (the group stays busy until the coroutine returns), while the
service clients live in a reentrant group so their responses can arrive meanwhile
(ROS-NOTES: a client in the busy group deadlocks).

Request ids have one meaning.  Delivery is at-least-once: a requester that heard no
answer may send the same request again, and the node answers it from its cache
instead of running the algorithm twice (which would encode into WM twice).  A
request that reuses an id for a *different* request is answered with an error naming
the conflict (kind ``IdConflict``), never with the other request's answer, and the
cache keeps the first answer.  An answer that carries an error (a consultant timed out
or is down, an unknown entity, ...) is not cached: a retry runs again.  The cache is
bounded in entries and in bytes (answers are kept as their JSON text).
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from typing import Optional

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.exceptions import ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import String

from .. import contract
from ..carrier import DEFAULT_TIMEOUT, stamped, subscribe
from ..codec import printable, safe_dumps
from ..contract import LIMIT_RANGES, Limits
from ..remote import RemotePort
from .common import StartupError, declare_number, descriptor, now_seconds, watch_clock

#: Deadline for the consultants to answer their first round trip (seconds).
READY_TIMEOUT = 30.0


class AnswerCache:
    """The answers to the latest request ids, bounded by entries and by bytes (oldest dropped).

    Each entry is (fingerprint of the request, answer as JSON text); the fingerprint is
    a SHA-256 of the request's canonical JSON, so a reused id is told apart from a
    resent request without keeping the request.
    """

    #: Bytes counted per entry on top of the answer text (key, digest, dict slot).
    OVERHEAD = 200

    def __init__(self, max_entries: int = Limits.answer_cache_entries,
                 max_bytes: int = Limits.answer_cache_bytes) -> None:
        self.max_entries = max_entries
        self.max_bytes = max_bytes
        self.bytes = 0
        self._answers: OrderedDict[str, tuple[bytes, str]] = OrderedDict()

    def __len__(self) -> int:
        return len(self._answers)

    @staticmethod
    def key(request_id: object) -> str:
        return f"{type(request_id).__name__}:{request_id}"

    @staticmethod
    def fingerprint(request: dict) -> bytes:
        return hashlib.sha256(safe_dumps(dict(sorted(request.items()))).encode("utf-8", "surrogatepass")).digest()

    def get(self, request: dict) -> tuple[Optional[str], bool]:
        """Return (cached answer text or None, True if the id was used for another request)."""
        entry = self._answers.get(self.key(request["id"]))
        if entry is None:
            return None, False
        if entry[0] != self.fingerprint(request):
            return None, True
        return entry[1], False

    def put(self, request: dict, answer: str) -> None:
        key = self.key(request["id"])
        size = len(answer) + len(key) + self.OVERHEAD
        if key in self._answers or size > self.max_bytes or self.max_entries == 0:
            return
        self._answers[key] = (self.fingerprint(request), answer)
        self.bytes += size
        while len(self._answers) > self.max_entries or self.bytes > self.max_bytes:
            old_key, (_, old) = self._answers.popitem(last=False)
            self.bytes -= len(old) + len(old_key) + self.OVERHEAD


class AskingNode(Node):
    """A node that resolves or generates by asking the consultants of ``domains``."""

    def __init__(self, name: str, **kwargs) -> None:
        super().__init__(name, **kwargs)
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
        self._ready = False
        self._clock_watch = watch_clock(self)

    def _on_announce(self, data: dict) -> None:
        """Tell the port of a (re)started consultant, so it stops waiting on the previous incarnation."""
        announce = contract.check(contract.ConsultantAnnounce, data)
        port = self.ports.get(announce["domain"])
        if port is not None:
            port.restarted(announce["incarnation"])

    async def ensure_ready(self) -> None:
        """Wait (with a deadline) until every consultant has answered a round trip; once."""
        if self._ready:
            return
        for port in self.ports.values():
            await port.wait_ready(self.ready_timeout)
        self._ready = True

    def request_time(self, data: dict) -> float:
        """Return the request's ``time`` (the robot-clock time of the utterance), else now."""
        time = data.get("time")
        return float(time) if isinstance(time, (int, float)) and not isinstance(time, bool) else now_seconds(self)

    async def answer_once(self, data: dict, publisher) -> None:
        """Publish the answer to request ``data``, computed once per (id, request).

        See the module docstring for what a repeated or reused id gets.
        """
        cached, conflict = self.answers.get(data)
        if conflict:
            error = (f"request id {printable(repr(data['id']), 80)} was already used for a different request; "
                     "use a new id for a new request")
            self.get_logger().warning(error)
            publisher.publish(String(data=safe_dumps(stamped(publisher, self.conflict_reply(data, error)))))
            return
        if cached is None:
            reply = await self.answer(data)
            cached = safe_dumps(stamped(publisher, reply))  # the answer as published, graph identity included
            if "error" not in reply:
                self.answers.put(data, cached)
        publisher.publish(String(data=cached))

    def conflict_reply(self, data: dict, error: str) -> dict:
        """Return the reply to a request whose id is taken (subclasses add their topic's fields)."""
        return {"id": data["id"], "error": error, "kind": "IdConflict"}

    async def answer(self, data: dict) -> dict:  # pragma: no cover - abstract
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
