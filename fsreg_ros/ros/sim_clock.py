"""A sim-time node's clock, read from ``/clock`` on demand instead of on every message (issue 37 item 2).

With ``use_sim_time`` rclpy's ``TimeSource`` subscribes ``/clock`` (depth 1, best effort)
and the executor wakes the node for every message: a simulator's 1 kHz clock cost every
node a thousand Python callbacks a second and tripled the dialogue's latency.  A node
need not wake for every clock message to know the time.  :func:`follow_clock`:

* takes the time source's ``/clock`` subscription out of the executor's wait set (it is
  put in :class:`OnDemand`, a callback group that never executes); DDS keeps its latest
  message (KEEP_LAST 1);
* reads that latest message whenever the node asks the time (:func:`refresh`, called by
  :func:`fsreg_ros.ros.node_base.now_seconds`), so a handler sees the newest clock it has
  received, not the last one the executor happened to dispatch;
* and on a steady timer every :data:`FOLLOW_PERIOD` seconds, which moves the ROS clock and
  so fires the node's sim-time timers (decay ticks) at most that late in wall time.  What
  such a timer does is derived from the clock (the WM Manager applies every period due by
  ``now``, and ``wm_manager/sync(t)`` every period due by ``t``), so decay and readiness
  are the same at any clock rate.

The cost is one cheap timer callback per :data:`FOLLOW_PERIOD` whatever the clock's rate.
The rclpy internals this needs (the time source's ``/clock`` subscription, taking its
latest message, moving it and its event handlers to another group) are used through
:mod:`fsreg_ros.ros.rclpy_internals`; ``test/ros/test_rclpy_internals.py`` fails if rclpy
changes them.  A ``use_sim_time`` switched at
run time makes rclpy create a new subscription: the next :func:`refresh` moves it out of the
wait set too.
"""

from __future__ import annotations

import weakref
from typing import Any

from rclpy.callback_groups import CallbackGroup
from rclpy.clock import Clock, ClockType

from .rclpy_internals import clock_subscription, move_to_group, take_message

#: Seconds between two reads of the latest ``/clock`` on the steady clock (a sim-time timer fires at most this late).
#: Each read wakes the executor (~0.3% of a core at 10 Hz on this machine; 50 Hz cost 3% under load).
FOLLOW_PERIOD = 0.1
#: Messages taken at most per read (the reader keeps one; a few arrive while reading).
MAX_TAKES = 8


class OnDemand(CallbackGroup):
    """A callback group whose entities the executor never waits on nor runs: they are read on demand."""

    def can_execute(self, entity: Any) -> bool:
        return False

    def beginning_execution(self, entity: Any) -> bool:
        return False

    def ending_execution(self, entity: Any) -> None:
        pass


_GROUPS: "weakref.WeakKeyDictionary[Any, OnDemand]" = weakref.WeakKeyDictionary()


def _on_demand(node, subscription) -> None:
    """Move ``subscription`` and its QoS event handlers into the node's :class:`OnDemand` group.

    So neither is in the executor's wait set.  The event handlers must go too: a sample
    replaced before it was taken raises the subscription's "message lost" event, which
    woke the executor hundreds of times a second with nothing to run.
    """
    group = _GROUPS.get(node)
    if group is None or subscription.callback_group is group:
        return
    move_to_group(subscription, group)


def refresh(node) -> int:
    """Apply the latest ``/clock`` message the node has received to its clock; return how many were taken.

    Does nothing for a node that does not follow the clock on demand or has no sim time.
    The message goes through the time source's callback (so :func:`~fsreg_ros.ros.node_base.guard_clock`'s
    guard applies).
    """
    subscription = clock_subscription(node)
    if subscription is None or node not in _GROUPS:
        return 0
    _on_demand(node, subscription)
    latest = None
    taken = 0
    while taken < MAX_TAKES:
        message = take_message(subscription)
        if message is None:
            break
        latest = message[0]
        taken += 1
    if latest is not None:
        subscription.callback(latest)
    return taken


def now_ns(node) -> int:
    """Return the node's clock in nanoseconds, the latest ``/clock`` received applied first (:func:`refresh`)."""
    refresh(node)
    return node.get_clock().now().nanoseconds


def follow_clock(node, period: float = FOLLOW_PERIOD):
    """Make the node read ``/clock`` on demand (and every ``period`` s), not wake for each message; the timer."""
    _GROUPS.setdefault(node, OnDemand())
    subscription = clock_subscription(node)
    if subscription is not None:
        _on_demand(node, subscription)
    return node.create_timer(period, lambda: refresh(node), clock=Clock(clock_type=ClockType.STEADY_TIME))
