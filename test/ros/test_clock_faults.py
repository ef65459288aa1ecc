"""``/clock`` of every sign and size: no sim-time node stops (issue 19, item 2).

rclpy turns each ``/clock`` message into a ``Time``, which raises for negative seconds;
out of a callback that stopped every sim-time node.  ``common.guard_clock`` (installed by
``watch_clock`` in every node) ignores such a message with a warning, counts it, and
keeps the clock where it was.  The nodes here are the runner's own, on sim time, in one
executor: an exception out of any callback would surface from ``spin_once`` and fail
the test.  Every step is synchronised positively: a valid time is awaited on every
node's clock, an invalid one on every node's count of ignored messages.
"""

from __future__ import annotations

import pytest
from rosgraph_msgs.msg import Clock

from rosutil import RosSession

from fsreg_ros import contract
from fsreg_ros.core.scenario import load_scenario
from fsreg_ros.core.simulation.simulator import Options
from fsreg_ros.tools.graph import live_nodes
from fsreg_ros.ros.node_base import clock_guard
from fsreg_ros.testing.live import node_classes

pytestmark = pytest.mark.graph

INT32 = 2**31
#: (sec, nanosec) as builtin_interfaces/Time can carry them: int32 seconds, uint32 nanoseconds.
VALUES = [(-1, 0), (7, 0), (-INT32, 0), (0, 2**32 - 1), (-1, 999_999_999), (INT32 - 1, 2**32 - 1), (-5, 5),
          (INT32 - 1, 0), (-INT32, 2**32 - 1), (3, 0)]


def stamp(sec: int, nanosec: int) -> Clock:
    msg = Clock()
    msg.clock.sec, msg.clock.nanosec = sec, nanosec
    return msg


def test_clock_values_of_every_sign_and_size(table1_path, tmp_path):
    scenario = load_scenario(table1_path)
    specs = live_nodes(scenario, table1_path, Options(memory={"policy": "decay", "decay_period": 10.0}),
                       state_dir=str(tmp_path))
    classes = node_classes()
    with RosSession() as g:
        nodes = []
        for spec in specs:
            params = dict(spec.parameters)
            sim = params.pop("use_sim_time")
            nodes.append(g.add(classes[spec.executable], use_sim_time=sim, name=spec.name, **params))
        assert all(clock_guard(n) is not None for n in nodes)
        clock = g.probe.create_publisher(Clock, contract.CLOCK, 10)
        g.spin_until(lambda: clock.get_subscription_count() >= len(nodes), 10.0, "every node's /clock subscription")
        g.spin_until(lambda: g.call(contract.STATUS.name, {})["ready"], 10.0, "the consultant configured")
        now, ignored = 0, 0
        for sec, nanosec in VALUES:
            clock.publish(stamp(sec, nanosec))
            if sec < 0:
                ignored += 1
                g.spin_until(lambda: all(clock_guard(n).ignored == ignored for n in nodes), 10.0,
                             f"every node to ignore sec={sec}, nanosec={nanosec}")
            else:
                now = sec * 10**9 + nanosec
                g.spin_until(lambda: all(n.get_clock().now().nanoseconds == now for n in nodes), 10.0,
                             f"every node at sec={sec}, nanosec={nanosec}")
            assert [n.get_clock().now().nanoseconds for n in nodes] == [now] * len(nodes)
        # Every node still works: the WM Manager's barrier (the clock went back to 3 s) and a consultant query.
        memory = g.call(contract.SYNC.name, {"time": 3.0})["memory"]
        assert memory == {"faces": {"policy": "decay", "decay_period": 10.0}}
        assert g.call(contract.consultant_service("faces"), {"op": "info"})["domain"] == "faces"
