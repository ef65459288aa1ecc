"""A sim-time node reads ``/clock`` on demand, not on every message (issue 37 item 2).

``fsreg_ros.ros.sim_clock`` reads it through ``fsreg_ros.ros.rclpy_internals`` (whose own test,
test_rclpy_internals.py, fails if rclpy changes them).  Here: decay and readiness give exactly the same results
when the clock comes in 1 ms steps (a simulator's 1 kHz ``/clock``) as in coarse steps.
"""

from __future__ import annotations

import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock

from fsreg_ros import contract
from fsreg_ros.contract import EVENTS_QOS
from fsreg_ros.nodes.consultant import ConsultantNode
from fsreg_ros.nodes.wm_manager import WMManagerNode
from fsreg_ros.ros.graph_clock import clock_message
from fsreg_ros.ros.node_base import now_seconds
from fsreg_ros.ros.rclpy_internals import clock_subscription
from fsreg_ros.ros.sim_clock import follow_clock, refresh
from rosutil import KB, RosSession, ros_graph

pytestmark = pytest.mark.graph


class Plain(Node):
    """A bare node (no fsreg wrapper), as rclpy makes it."""

    def __init__(self, node_name: str = "plain", **kwargs) -> None:
        super().__init__(node_name, **kwargs)


STATUS, SYNC = contract.STATUS.name, contract.SYNC.name


@pytest.fixture
def graph():
    yield from ros_graph()


def test_a_followed_node_reads_the_latest_clock_on_demand_and_never_per_message(graph: RosSession):
    node = graph.add(Plain, use_sim_time=True, name="follower")
    follow_clock(node, period=3600.0)  # no periodic read here: only on demand
    sub = clock_subscription(node)
    assert not graph.executor.can_execute(sub)  # not in the executor's wait set, nor its QoS events
    assert sub.event_handlers and not any(graph.executor.can_execute(h) for h in sub.event_handlers)
    publisher = graph.probe.create_publisher(Clock, contract.CLOCK, 10)
    graph.spin_until(lambda: publisher.get_subscription_count() >= 1, 5.0, "the /clock subscription")
    for ms in range(1, 201):
        publisher.publish(clock_message(ms / 1000))
        graph.executor.spin_once(timeout_sec=0)
    assert node.get_clock().now().nanoseconds == 0  # 200 messages, no wake-up for any
    graph.spin_until(lambda: now_seconds(node) == 0.2, 5.0, "the latest clock, read on demand")
    assert refresh(node) == 0  # nothing newer
    # use_sim_time switched off and on at run time: rclpy makes a new subscription, read on demand too
    node.set_parameters([Parameter("use_sim_time", value=False)])
    node.set_parameters([Parameter("use_sim_time", value=True)])
    graph.spin_until(lambda: publisher.get_subscription_count() >= 1, 5.0, "the new /clock subscription")
    publisher.publish(clock_message(7.0))
    graph.spin_until(lambda: now_seconds(node) == 7.0, 5.0, "the clock through the new subscription")
    assert not graph.executor.can_execute(clock_subscription(node))


def test_every_fsreg_node_follows_the_clock_on_demand(graph: RosSession):
    nodes = [graph.add(ConsultantNode, use_sim_time=True, domain="faces", kb=KB, name="consultant_faces"),
             graph.add(WMManagerNode, use_sim_time=True, domains=["faces"])]
    assert [graph.executor.can_execute(clock_subscription(n)) for n in nodes] == [False, False]


# ------------------------------------------------------------------ decay and readiness at a fast clock
def _decay_at(graph: RosSession, step: float) -> tuple:
    """The timer-decay run of test_wm_manager_node's test_timer_decay_follows_the_clock, the clock in ``step`` s."""
    graph.add(ConsultantNode, use_sim_time=True, domain="faces", kb=KB, name="consultant_faces", debug=True)
    manager = graph.add(WMManagerNode, use_sim_time=True, domains=["faces"], policy="decay", decay_period=2.0)
    events = graph.listen("/wm/events", EVENTS_QOS)
    graph.wait_service(STATUS)
    graph.spin_until(lambda: graph.call(STATUS, {})["ready"], what="the consultant configured (ready)")
    for entity, props in (("face1", ["male", "glasses", "lab-coat", "light-hair", "dark-hair"]), ("face2", ["female"])):
        graph.call("/consultant/faces/debug", {"op": "encode", "entity": entity, "properties": props,
                                               "cause": "speaker", "time": 0.5})
    publisher = graph.probe.create_publisher(Clock, contract.CLOCK, 10)
    graph.spin_until(lambda: publisher.get_subscription_count() >= 2, 5.0, "both /clock subscriptions")
    steps = int(round(9.0 / step))
    for k in range(1, steps + 1):
        publisher.publish(clock_message(k * step))
        graph.executor.spin_once(timeout_sec=0)
    graph.spin_until(lambda: now_seconds(manager) == 9.0, 5.0, "the manager's clock at 9 s")

    def forgets() -> list:
        return [(e["entity"], e["property"], e["time"]) for e in events
                if e["op"] == "forget" and e["cause"] == "decay"]

    graph.spin_until(lambda: len(forgets()) == 5, 10.0, "the ticks at 2, 4, 6 and 8 s")
    status = graph.call(STATUS, {})
    queues = graph.call("/consultant/faces/debug", {"op": "snapshot"})["queues"]
    return (forgets(), queues, status["ready"], status["next_tick"], graph.call(SYNC, {"time": 9.0})["applied"])


@pytest.mark.slow
def test_decay_and_readiness_are_the_same_with_a_1_khz_clock_as_with_a_coarse_one():
    results = {}
    for step in (0.5, 0.001):
        with RosSession() as graph:
            results[step] = _decay_at(graph, step)
    expected = ([("face1", "male", 2.0), ("face2", "female", 2.0), ("face1", "glasses", 4.0),
                 ("face1", "lab-coat", 6.0), ("face1", "light-hair", 8.0)],
                {"face1": ["dark-hair"]}, True, {"faces": 10.0}, {"faces": 0})
    assert results == {0.5: expected, 0.001: expected}
