"""A contract topic handed over a batch at a time: :func:`subscribe_batches` (the consultants' ``ltm/assert``).

Owns taking every message waiting in a reader at once, within a budget, each decoded and
validated alone (a bad one refused alone, as :func:`fsreg_ros.ros.carrier.subscribe` does),
and handing the valid ones to the handler in one call, so a node can apply them in one
commit.  With ``gather`` a stream is taken once a period (:mod:`fsreg_ros.ros.gathering`).
"""

from __future__ import annotations

import time
from typing import Callable, Optional

from std_msgs.msg import String

from ..contract import Topic
from ..contract.codec import TooLarge, leading_id, parse, printable, request_id
from .carrier import LimitsSource, Refusal, Reject, checker, limit_value, max_bytes_of, qos_profile, reply_kind
from .diagnostics import request_stats
from .gathering import Gatherer
from .rclpy_internals import take_message


def subscribe_batches(node, topic: Topic, handler: Callable[[list[dict]], None], *, reject: Optional[Reject],
                      limits: LimitsSource = None, accept: Optional[Callable[[dict], bool]] = None,
                      size: Callable[[dict], int] = lambda data: 1, max_size: int = 1000,
                      max_seconds: float = 0.02, clock: Callable[[], float] = time.monotonic,
                      gather: Optional[float] = None):
    """Subscribe like :func:`~fsreg_ros.ros.carrier.subscribe`, but hand ``handler`` every message waiting, at once.

    When a message arrives, the messages waiting behind it in the reader are taken too
    (until their ``size`` sum reaches ``max_size``, or taking them has taken ``max_seconds``,
    so the node's other callbacks wait at most that long), each decoded and validated alone (a
    bad one is rejected alone, as ``subscribe`` does); ``handler(messages)`` then
    gets the valid ones in arrival order, in one call, so a node can apply them in one
    commit (the consultant's ``ltm/assert``).  If it raises, every one of them is
    rejected with its id (``reject`` None: only logged, as ``subscribe`` does for a topic nobody
    answers).  ``clock`` measures ``max_seconds`` (``time.thread_time``: this
    thread's CPU time, so a process the OS keeps waiting still takes as much work per
    callback, instead of a few messages and a whole round's overhead for them).

    ``gather`` (seconds): take a *stream* at most once a period (:class:`~fsreg_ros.ros.gathering.Gatherer`).
    A message into a quiet reader is taken at once, as above; after that the executor stops
    waiting on the reader (:class:`~fsreg_ros.ros.gathering.GatheringGroup`) and a steady-clock
    timer takes whatever arrived every ``gather`` seconds, until a period brings nothing.  A drain
    stopped by ``max_size`` or ``max_seconds`` with messages still waiting hands the
    reader back to the executor at once, so a stream faster than the budget is not held
    back.  Returns the subscription.
    """
    reader = BatchReader(node, topic, handler, reject, limits, accept, size, max_size, max_seconds, clock)
    qos = qos_profile(topic.subscriber_qos)
    if gather is None:
        reader.subscription = node.create_subscription(String, topic.name, reader.drain, qos)
    else:
        reader.subscription = Gatherer(node, topic.name, qos, reader.drain, gather).subscription
    return reader.subscription


class BatchReader:
    """What :func:`subscribe_batches` does with a reader: :meth:`drain` takes a batch and hands it over."""

    def __init__(self, node, topic: Topic, handler: Callable[[list[dict]], None], reject: Optional[Reject],
                 limits: LimitsSource, accept: Optional[Callable[[dict], bool]], size: Callable[[dict], int],
                 max_size: int, max_seconds: float, clock: Callable[[], float]) -> None:
        self.handler, self.accept, self.size = handler, accept, size
        self.max_size, self.max_seconds, self.clock = max_size, max_seconds, clock
        self.validate = checker(topic.schema, limits)
        self.max_bytes = max_bytes_of(limits)
        self.refusal = Refusal(node.get_logger(), topic.name, reject)
        self.stats = request_stats(node) if reject is not None else None  # an answered topic carries requests
        self.subscription = None
        self.ignored = 0  # messages of this drain that were for another node

    def drain(self, first: Optional[String]) -> Optional[bool]:
        """Take ``first`` (None: the next waiting) and what waits behind it, within the budget; hand them over.

        Returns None if nothing was waiting, else whether the budget stopped the drain.
        """
        started = time.monotonic()
        self.ignored = 0
        if first is None and (first := self.take()) is None:
            return None
        batch, taken, stopped = self.take_batch(first)
        refused = len(batch) + self.ignored < taken
        if batch and not self.hand_over(batch):
            refused = True
        if self.stats is not None and taken > self.ignored:  # messages for another node are not counted
            self.stats.record(time.monotonic() - started, refused=refused)
        return stopped

    def take(self) -> Optional[String]:
        """Take the next message waiting in the reader now (None: none waits), as the executor would."""
        taken = take_message(self.subscription)
        return None if taken is None else taken[0]

    def take_batch(self, first: String) -> tuple[list[dict], int, bool]:
        """Decode ``first`` and take what waits behind it within the budget: (valid messages, taken, budget hit)."""
        budget = self.clock()
        data = self.decoded(first.data)
        batch = [data] if data is not None else []
        total = sum(self.size(data) for data in batch)
        taken, stopped = 1, False
        while not (stopped := total >= self.max_size or self.clock() - budget >= self.max_seconds):
            waiting = self.take()
            if waiting is None:
                break
            taken += 1
            data = self.decoded(waiting.data)
            if data is not None:
                batch.append(data)
                total += self.size(data)
        return batch, taken, stopped

    def hand_over(self, batch: list[dict]) -> bool:
        """Run the handler on ``batch``; if it raises, refuse every message of it (False)."""
        try:
            self.handler(batch)
        except Exception as err:  # noqa: BLE001 - log with context, keep serving
            for data in batch:
                self.refusal.error(request_id(data), err)
            return False
        return True

    def decoded(self, text: str) -> Optional[dict]:
        """Return the message if it is valid and for this node; None (refused or ignored) otherwise."""
        try:
            payload = parse(text, max_bytes=limit_value(self.max_bytes))
        except TooLarge as err:
            self.refusal.refuse(leading_id(text), printable(err), internal=False, kind=reply_kind(err))
            return None
        except ValueError as err:
            self.refusal.refuse(None, printable(err), internal=False, kind=reply_kind(err))
            return None
        if self.accept is not None and not self.accept(payload):
            self.ignored += 1
            return None
        try:
            self.validate(payload)
        except Exception as err:  # noqa: BLE001 - out of a drain it would stop the node: log, refuse, go on
            self.refusal.error(request_id(payload), err)
            return None
        return payload
