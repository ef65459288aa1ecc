"""QoS of every fsreg topic, as plain data (no ROS import).

:class:`QosSpec` says what a profile is; :func:`fsreg_ros.ros.carrier.qos_profile` turns it
into an rclpy ``QoSProfile`` where a node creates its publisher or subscription.  So a
tool that only needs names and schemas imports no ROS package.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional


@dataclass(frozen=True)
class QosSpec:
    """A reliable QoS profile: keep-last ``depth`` samples (or keep all), latched (transient local) or volatile."""

    depth: int
    latched: bool = False
    #: Seconds of DDS liveliness lease (automatic liveliness): readers learn within it that the writer died.
    lease: Optional[float] = None
    #: Keep every sample until the readers took it (``depth`` unused): a reader never drops one; a writer
    #: whose readers are too far behind blocks, then its ``publish`` fails (backpressure the sender hears).
    keep_all: bool = False

    def describe(self) -> str:
        """Return the profile in words, as the docs' message table shows it."""
        lease = f", liveliness lease {self.lease:g} s" if self.lease is not None else ""
        history = "keep all" if self.keep_all else f"depth {self.depth}"
        return f"{'latched' if self.latched else 'volatile'}, {history}{lease}"


#: ``wm/state`` readers: latched, reliable, depth 10 so a late joiner gets the state of
#: up to 10 consultants (a reader's depth must be at least the number of writers).
STATE_QOS = QosSpec(10, latched=True)
#: ``wm/state`` writer (one per consultant): latched, only its latest state kept.
STATE_PUB_QOS = QosSpec(1, latched=True)
#: ``wm/events``: reliable, volatile, deep (one reset or decay tick emits many events).
EVENTS_QOS = QosSpec(1000)
#: The dialogue pipeline (human, semantics, RR results, REG requests and expressions).
PIPELINE_QOS = QosSpec(100)
#: Everything else: reliable, volatile, depth 10 (the rclpy default).
DEFAULT_QOS = QosSpec(10)
#: ``ltm/assert``: reliable, volatile, keep all.  With depth 10 a consultant more than 10
#: messages behind silently dropped the oldest (measured: 56 of 10,000 facts at 500/s
#: never answered; 79 of 8,000 new entities at 1,000/s never applied).  Keep-all never
#: drops: a sender whose consultants are about 10,000 messages behind blocks (up to
#: 100 ms a message) and then its publish fails (rclpy raises), so nothing is lost silently.
ASSERT_QOS = QosSpec(10, keep_all=True)
#: ``ltm/assert/result``: reliable, volatile, depth 10,000 (an answer per assertion, a
#: burst of them answered at once).  Keep-last, so a stalled reader never blocks a
#: consultant: an asserter more than 10,000 answers behind loses the oldest.
ASSERT_RESULT_QOS = QosSpec(10_000)
#: ``consultant/<domain>/alive``: latched, and the writer's liveliness lapses within 1 s of its process dying.
ALIVE_QOS = QosSpec(1, latched=True, lease=1.0)
#: ``wm_manager/ready`` writer: latched, only the latest kept, and its liveliness lapses within 1 s of the WM
#: Manager's process dying, so a client waiting on the graph notices it leaving (a reader asking no lease matches).
READY_QOS = QosSpec(1, latched=True, lease=1.0)
#: Every service (requests and replies): depth 1000.  With rclpy's default (depth 10) a
#: server more than 10 requests behind silently dropped the oldest (measured: 10 of 100
#: concurrent calls answered; 100 of 100 with depth 1000).
SERVICE_QOS = QosSpec(1000)
