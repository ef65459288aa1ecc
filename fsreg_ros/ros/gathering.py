"""A stream's reader held from the executor and taken once a period: :class:`GatheringGroup`, :class:`Gatherer`.

Owns the gathering of :func:`fsreg_ros.ros.batches.subscribe_batches` (``gather``): a
message into a quiet reader is taken at once; after that the executor stops waiting on the
reader (the group *holds* it) and a steady-clock timer takes whatever arrived every period,
until a period brings nothing (then the reader is waited on again and the timer stops: an
idle node pays nothing).  One message a millisecond is then ~``period`` x 1,000 messages a
round instead of a round each.  A client blocked on one answer takes it at once with
:meth:`GatheringGroup.release` (:mod:`fsreg_ros.ros.exchange`).
"""

from __future__ import annotations

from typing import Any, Callable, Optional

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.clock import Clock, ClockType
from std_msgs.msg import String

#: Takes ``first`` (None: the next waiting) and what waits behind it: None if nothing waited, else whether a
#: budget stopped it with messages left (:meth:`fsreg_ros.ros.batches.BatchReader.drain`).
Drain = Callable[[Optional[String]], Optional[bool]]


class GatheringGroup(MutuallyExclusiveCallbackGroup):
    """The callback group of a gathered subscription, its QoS events and its timer (:class:`Gatherer`).

    Mutually exclusive, and able to *hold* the subscription: while :attr:`holding`, ``can_execute``
    says no for every entity of the group but :attr:`timer`, so rclpy's executor (which asks
    every entity when it builds its wait set, once a wait: :mod:`fsreg_ros.ros.rclpy_internals`)
    leaves them out and is not woken by the subscription's messages; they wait in the reader
    until the timer takes them.  The subscription's QoS event handlers are held too: Fast DDS
    wakes a wait on a reader's events when data arrives for it (measured: with only the
    subscription held, ~4,000 empty wake-ups a second at 1,000 messages a second, a core spent
    spinning).
    """

    def __init__(self) -> None:
        super().__init__()
        self.holding = False
        self.holds = 0  # how many times the reader was held (a count, not a snapshot that races the timer)
        self.timer = None  # the entity never held
        self.drain: Optional[Callable[[], Any]] = None  # takes what waits in the reader now (the Gatherer's)

    def can_execute(self, entity) -> bool:
        return (not self.holding or entity is self.timer) and super().can_execute(entity)

    def hold(self) -> None:
        """Hold the reader from the executor until the timer finds a period empty; counted in :attr:`holds`."""
        self.holding = True
        self.holds += 1

    def release(self) -> None:
        """Take what waits in the held reader now and hand it back to the executor (a caller blocked on one message).

        Call it from the thread that spins the node, outside its callbacks (``GraphClient``
        waiting for the answer to its own request): the answer is then taken as it arrives,
        not at the period's end.  Nothing happens while the reader is not held.
        """
        if self.holding and self.drain is not None:
            self.drain()
            self.holding = False


class Gatherer:
    """A ``String`` subscription to ``topic`` whose messages ``drain`` takes: at once when quiet, else each period."""

    def __init__(self, node, topic: str, qos, drain: Drain, period: float) -> None:
        self.drain = drain
        self.group = GatheringGroup()
        self.timer = node.create_timer(period, self.gathered, callback_group=self.group,
                                       clock=Clock(clock_type=ClockType.STEADY_TIME), autostart=False)
        self.group.timer, self.group.drain = self.timer, lambda: drain(None)
        self.subscription = node.create_subscription(String, topic, self.arrived, qos, callback_group=self.group)

    def arrived(self, msg: String) -> None:
        """Take the first message into a quiet reader now, then gather."""
        self.drain(msg)
        self.group.hold()
        self.timer.reset()

    def gathered(self) -> None:
        """Take what came in the period just over; hand the reader back when nothing came or more waits."""
        stopped = self.drain(None)
        if stopped is None:  # the stream has ended: wait on the reader again
            self.timer.cancel()
            self.group.holding = False
        elif stopped:  # more waits than a drain takes: let the executor take it at once
            self.group.holding = False
