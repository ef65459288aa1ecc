"""The one place fsreg relies on rclpy's internals (Jazzy, rclpy 7.1): what, and why.

Everything here is something rclpy does not promise, used for a measured reason;
``test/ros/test_rclpy_internals.py`` asserts each on the installed rclpy, so an upgrade
that changes one fails there, by name, instead of somewhere in a graph.

* Taking what waits in an entity's reader now, as the executor takes it
  (``rclpy.executors.Executor._take_subscription`` / ``_take_service``): a subscription's
  ``handle.take_message(msg_type, raw)`` and a service's
  ``handle.service_take_request(srv_type.Request)``, each under ``with handle``
  (:func:`take_message`, :func:`take_request`).  A callback drains a burst this way
  (:mod:`fsreg_ros.ros.batches`, :mod:`fsreg_ros.ros.serving`), the recorder writes
  serialized messages (:mod:`fsreg_ros.ros.recorder`), a node reads ``/clock`` on demand
  (:mod:`fsreg_ros.ros.sim_clock`).
* A callback group's weak references: ``CallbackGroup.entities`` is a set of
  ``weakref.ref`` that ``destroy_timer`` never prunes (:func:`forget_entity`; a timer per
  call leaked ~100 bytes a call).
* The sim-time clock: ``Node._time_source`` (a ``TimeSource``), its ``_clock_sub`` (the
  ``/clock`` subscription, None without sim time) and ``clock_callback`` (which rclpy gives
  every clock subscription it creates later) (:func:`clock_subscription`,
  :func:`clock_callback`, :func:`set_clock_callback`).
* Moving a subscription and its QoS event handlers (``Subscription.event_handlers``) into
  another callback group after creation (:func:`move_to_group`).
* ``RCLError``, what a publish raises when the writer cannot take the message (a keep-all
  writer whose readers are far behind: :mod:`fsreg_ros.ros.exchange`), is only reachable
  through ``rclpy.impl.implementation_singleton`` (:data:`RCLError`).
* The executor builds its wait set from the entities whose group's ``can_execute`` is
  true, asking again at every wait: a group that says no holds an entity's messages in
  its reader (:class:`~fsreg_ros.ros.gathering.GatheringGroup`,
  :class:`~fsreg_ros.ros.sim_clock.OnDemand`); the test checks that too.
"""

from __future__ import annotations

import weakref
from typing import Any, Callable, Optional

from rclpy.exceptions import InvalidHandle
from rclpy.impl.implementation_singleton import rclpy_implementation

#: The error rclpy's C extension raises for a failed rcl call (e.g. a publish a full keep-all writer refuses).
RCLError = rclpy_implementation.RCLError


def take_message(subscription, raw: Optional[bool] = None) -> Optional[tuple[Any, dict]]:
    """Take the next message waiting in ``subscription``'s reader: ``(message, info)``, or None (none, or destroyed).

    ``raw`` (default: the subscription's own) takes the serialized bytes.
    """
    handle = subscription.handle
    try:
        with handle:
            return handle.take_message(subscription.msg_type, subscription.raw if raw is None else raw)
    except InvalidHandle:
        return None


def take_request(server) -> Optional[tuple[Any, Any]]:
    """Take the next request waiting on ``server``: ``(request, header)``, or None (none, or destroyed)."""
    try:
        with server.handle:
            request, header = server.handle.service_take_request(server.srv_type.Request)
    except InvalidHandle:
        return None
    return None if header is None else (request, header)


def forget_entity(group, entity) -> None:
    """Drop ``group``'s weak reference to ``entity`` (rclpy never does when the entity is destroyed)."""
    group.entities.discard(weakref.ref(entity))


def time_source(node) -> Any:
    """Return the node's ``TimeSource`` (None if rclpy keeps it elsewhere)."""
    return getattr(node, "_time_source", None)


def clock_subscription(node) -> Optional[Any]:
    """Return the node's ``/clock`` subscription (its time source's; None without sim time)."""
    source = time_source(node)
    return getattr(source, "_clock_sub", None) if source is not None else None


def clock_callback(node) -> Optional[Callable[[Any], None]]:
    """Return the callback the node's time source turns each ``/clock`` message into clock time with."""
    source = time_source(node)
    return None if source is None else source.clock_callback


def set_clock_callback(node, callback: Callable[[Any], None]) -> None:
    """Make ``callback`` take every ``/clock`` message: the current subscription's and any created later."""
    source = time_source(node)
    source.clock_callback = callback
    subscription = getattr(source, "_clock_sub", None)
    if subscription is not None:
        subscription.callback = callback


def move_to_group(subscription, group) -> None:
    """Put ``subscription`` and its QoS event handlers in ``group`` (the executor asks that group from now on)."""
    for entity in [subscription, *subscription.event_handlers]:
        entity.callback_group = group
        group.add_entity(entity)
