"""QoS of every fsreg topic, as plain data (no ROS import).

:class:`QosSpec` says what a profile is; :func:`fsreg_ros.carrier.qos_profile` turns it
into an rclpy ``QoSProfile`` where a node creates its publisher or subscription.  So a
tool that only needs names and schemas imports no ROS package.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class QosSpec:
    """A reliable, keep-last QoS profile: ``depth`` samples, latched (transient local) or volatile."""

    depth: int
    latched: bool = False

    def describe(self) -> str:
        """Return the profile in words, as the docs' message table shows it."""
        return f"{'latched' if self.latched else 'volatile'}, depth {self.depth}"


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
