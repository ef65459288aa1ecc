"""Shared base of the nodes that ask consultants questions (RR and REG).

Such a node knows the consultant domains it may ask (``domains`` parameter), reaches
each through a :class:`~fsreg_ros.remote.RemotePort`, and handles one request at a
time, in arrival order: the request subscription is an async callback in a mutually
exclusive group (the group stays busy until the coroutine returns), while the
service clients live in a reentrant group so their responses can arrive meanwhile
(ROS-NOTES: a client in the busy group deadlocks).

Requests carry an ``id``.  Delivery is at-least-once: a requester that heard no
answer may send the same id again, and the node answers it from a small cache
instead of running the algorithm twice (which would encode into WM twice).
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Optional

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.exceptions import ParameterUninitializedException
from rclpy.parameter import Parameter
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node

from ..carrier import to_msg
from ..remote import RemotePort
from .common import now_seconds

#: How many answered request ids a node remembers for duplicate suppression.
ANSWER_CACHE_SIZE = 1024
#: Deadline for the consultants to answer their first round trip.
READY_TIMEOUT = 30.0


class AnswerCache:
    """The answers to the last N request ids (insertion order, oldest dropped)."""

    def __init__(self, size: int = ANSWER_CACHE_SIZE) -> None:
        self.size = size
        self._answers: OrderedDict[str, dict] = OrderedDict()

    @staticmethod
    def key(request_id: object) -> str:
        return repr(request_id)

    def get(self, request_id: object) -> Optional[dict]:
        return self._answers.get(self.key(request_id))

    def put(self, request_id: object, answer: dict) -> None:
        self._answers[self.key(request_id)] = answer
        while len(self._answers) > self.size:
            self._answers.popitem(last=False)


class AskingNode(Node):
    """A node that resolves or generates by asking the consultants of ``domains``."""

    def __init__(self, name: str, **kwargs) -> None:
        super().__init__(name, **kwargs)
        self.declare_parameter(
            "domains",
            Parameter.Type.STRING_ARRAY,
            ParameterDescriptor(description="consultant domains to ask (one consultant node per domain)", read_only=True),
        )
        try:
            domains = [d for d in self.get_parameter("domains").value if d]
        except ParameterUninitializedException:
            domains = []
        if not domains:
            raise ValueError("parameter 'domains' must name at least one consultant domain")
        self.request_group = MutuallyExclusiveCallbackGroup()
        self.client_group = ReentrantCallbackGroup()
        self.ports = {d: RemotePort(self, d, self.client_group) for d in domains}
        self.answers = AnswerCache()
        self._ready = False

    async def ensure_ready(self) -> None:
        """Wait (once, with a deadline) until every consultant has answered a round trip."""
        if self._ready:
            return
        for port in self.ports.values():
            await port.wait_ready(READY_TIMEOUT)
        self._ready = True

    def request_time(self, data: dict) -> float:
        """The request's ``time`` (the robot-clock time of the utterance), else now."""
        time = data.get("time")
        return float(time) if isinstance(time, (int, float)) and not isinstance(time, bool) else now_seconds(self)

    async def answer_once(self, data: dict, publisher) -> None:
        """Publish the answer to request ``data``: computed by :meth:`answer` the first
        time its id is seen, from the cache when the id repeats."""
        reply = self.answers.get(data["id"])
        if reply is None:
            reply = await self.answer(data)
            self.answers.put(data["id"], reply)
        publisher.publish(to_msg(reply))

    async def answer(self, data: dict) -> dict:  # pragma: no cover - abstract
        raise NotImplementedError
