"""The rclpy internals fsreg relies on, asserted on the installed rclpy (``fsreg_ros.ros.rclpy_internals``).

Each test names what the adapter uses and checks that it exists and behaves as the
adapter needs; an rclpy upgrade that changes one fails here, by name.
"""

from __future__ import annotations

import weakref

import pytest
from diagnostic_msgs.srv import AddDiagnostics
from rclpy.callback_groups import CallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, ReliabilityPolicy
from rclpy.subscription import Subscription
from rclpy.time_source import TimeSource
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from fsreg_ros import contract
from fsreg_ros.ros import rclpy_internals as internals
from fsreg_ros.ros.graph_clock import clock_message
from fsreg_ros.ros.sim_clock import OnDemand
from rosutil import RosSession

pytestmark = pytest.mark.graph


class Plain(Node):
    """A bare node (no fsreg wrapper), as rclpy makes it."""

    def __init__(self, node_name: str = "plain", **kwargs) -> None:
        super().__init__(node_name, **kwargs)


def test_rclpy_keeps_the_clock_subscription_the_adapter_reads(graph: RosSession):
    """rclpy's ``Node._time_source`` is a ``TimeSource`` whose ``_clock_sub`` is a depth-1 ``/clock`` subscription
    (created when ``use_sim_time`` is set, destroyed when it is unset) with ``callback_group``, ``handle``,
    ``msg_type``, ``raw`` and a ``callback`` that sets the clock; the executor leaves an entity whose group's
    ``can_execute`` is false out of its wait set; ``handle.take_message`` returns ``(message, info)`` or None."""
    node = graph.add(Plain, use_sim_time=True)
    source = internals.time_source(node)
    assert isinstance(source, TimeSource) and source is node._time_source
    sub = internals.clock_subscription(node)
    assert sub is source._clock_sub
    assert isinstance(sub, Subscription) and sub.topic_name == "/clock" and sub.msg_type is Clock
    assert sub.qos_profile.history == HistoryPolicy.KEEP_LAST and sub.qos_profile.depth == 1
    assert sub.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT
    assert sub.raw is False and sub.callback == source.clock_callback == internals.clock_callback(node)
    assert sub.event_handlers and all(h.callback_group is sub.callback_group for h in sub.event_handlers)
    assert graph.executor.can_execute(sub)  # rclpy's own: dispatched per message
    internals.move_to_group(sub, OnDemand())
    assert not graph.executor.can_execute(sub)
    assert not any(graph.executor.can_execute(h) for h in sub.event_handlers)
    publisher = graph.probe.create_publisher(Clock, contract.CLOCK, 10)
    graph.spin_until(lambda: publisher.get_subscription_count() >= 1, 5.0, "the /clock subscription")
    publisher.publish(clock_message(4.5))
    taken = []

    def take() -> bool:
        got = internals.take_message(sub)
        if got is not None:
            taken.append(got[0])
        return bool(taken)

    graph.spin_until(take, 5.0, "the /clock message, taken on demand")
    assert (taken[0].clock.sec, taken[0].clock.nanosec) == (4, 500_000_000)
    assert node.get_clock().now().nanoseconds == 0  # the executor never ran its callback
    sub.callback(taken[0])
    assert node.get_clock().now().nanoseconds == 4_500_000_000
    node.set_parameters([Parameter("use_sim_time", value=False)])
    assert internals.clock_subscription(node) is None and source._clock_sub is None


def test_a_clock_callback_set_through_the_adapter_takes_every_clock_subscription(graph: RosSession):
    """``TimeSource.clock_callback`` is what rclpy gives each ``/clock`` subscription it creates later."""
    node = graph.add(Plain, use_sim_time=True, name="guarded")
    heard: list = []
    internals.set_clock_callback(node, heard.append)
    assert internals.clock_subscription(node).callback == heard.append
    node.set_parameters([Parameter("use_sim_time", value=False)])
    node.set_parameters([Parameter("use_sim_time", value=True)])  # a new subscription
    assert internals.clock_subscription(node).callback == heard.append
    publisher = graph.probe.create_publisher(Clock, contract.CLOCK, 10)
    graph.spin_until(lambda: publisher.get_subscription_count() >= 1, 5.0, "the new /clock subscription")
    publisher.publish(clock_message(2.0))
    graph.spin_until(lambda: bool(heard), 5.0, "the message, through the callback set")
    assert heard[0].clock.sec == 2 and node.get_clock().now().nanoseconds == 0


class Held(CallbackGroup):
    """A group whose entities the executor never runs (as GatheringGroup while it holds)."""

    def can_execute(self, entity) -> bool:
        return False

    def beginning_execution(self, entity) -> bool:
        return False

    def ending_execution(self, entity) -> None:
        pass


def test_a_held_reader_keeps_its_messages_for_take_message_as_objects_or_bytes(graph: RosSession):
    """The executor asks ``can_execute`` before it runs an entity; ``take_message`` takes in arrival order,
    ``(message, info)`` with ``info["received_timestamp"]`` (the recorder orders by it), raw bytes with
    ``raw=True``, and None for an empty reader or a destroyed subscription (``InvalidHandle``)."""
    node = graph.add(Plain, name="reader")
    heard: list = []
    sub = node.create_subscription(String, "/internals/held", heard.append, 10, callback_group=Held())
    assert sub.handle is not None and sub.msg_type is String and sub.raw is False
    pub = graph.probe.create_publisher(String, "/internals/held", 10)
    graph.spin_until(lambda: pub.get_subscription_count() >= 1, 5.0, "the held subscription")
    for text in ("one", "two"):
        pub.publish(String(data=text))
    graph.spin_for(0.3)
    assert heard == []  # held: never run by the executor
    first = internals.take_message(sub)
    assert first is not None and first[0].data == "one" and first[1]["received_timestamp"] > 0
    raw, info = internals.take_message(sub, raw=True)
    assert isinstance(raw, bytes) and b"two" in raw
    assert internals.take_message(sub) is None
    node.destroy_subscription(sub)
    assert internals.take_message(sub) is None


def test_a_request_waiting_on_a_service_is_taken_and_answered_outside_the_executor(graph: RosSession):
    """``Service.handle.service_take_request(srv_type.Request)`` gives ``(request, header)`` (header None: nothing
    waits) and ``send_response(reply, header)`` answers it; a destroyed service takes nothing."""
    node = Plain("server", context=graph.context)  # not spun: its requests wait in the service's reader
    graph.nodes.append(node)
    server = node.create_service(AddDiagnostics, "/internals/service", lambda req, resp: resp)
    assert internals.take_request(server) is None
    client = graph.probe.create_client(AddDiagnostics, "/internals/service")
    graph.spin_until(client.service_is_ready, 5.0, "the service")
    future = client.call_async(AddDiagnostics.Request(load_namespace="ping"))
    taken: list = []
    graph.spin_until(lambda: bool(taken.append(internals.take_request(server)) or taken[-1]), 5.0, "the request")
    request, header = taken[-1]
    assert request.load_namespace == "ping"
    server.send_response(AddDiagnostics.Response(success=True, message="pong"), header)
    graph.spin_until(future.done, 5.0, "the answer")
    assert future.result().message == "pong"
    node.destroy_service(server)
    assert internals.take_request(server) is None


def test_a_callback_group_keeps_a_weak_reference_to_a_destroyed_timer_until_forgotten(graph: RosSession):
    """``CallbackGroup.entities`` is a set of ``weakref.ref``; ``destroy_timer`` leaves the timer's in it."""
    group = ReentrantCallbackGroup()
    timer = graph.probe.create_timer(3600.0, lambda: None, group)
    assert weakref.ref(timer) in group.entities
    graph.probe.destroy_timer(timer)
    assert weakref.ref(timer) in group.entities  # rclpy's leak the adapter works around
    internals.forget_entity(group, timer)
    assert weakref.ref(timer) not in group.entities


def test_rcl_error_is_the_error_rclpy_raises_for_a_failed_rcl_call(graph: RosSession):
    """``rclpy.impl.implementation_singleton.rclpy_implementation.RCLError`` (caught by the exchange's publish of a
    full keep-all writer) is what a refused rcl call raises, here a timer of negative period."""
    assert issubclass(internals.RCLError, RuntimeError)
    with pytest.raises(internals.RCLError, match="timer period must be non-negative"):
        graph.probe.create_timer(-1.0, lambda: None)
