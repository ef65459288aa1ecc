"""A ROS session for tests: one context, one executor, a probe node, bounded waits only.

:class:`RosSession` is the low-level half of the harness (:mod:`fsreg_ros.testing`):
nodes built in one ``rclpy.Context`` (no signal handlers, optionally on a private ROS
domain) and spun by one ``SingleThreadedExecutor`` together with a ``probe`` node the
test talks through.  Every wait has a deadline and fails the test with
:class:`Timeout` naming what it waited for; :meth:`RosSession.close` tears all down.

    with RosSession() as ros:
        consultant = ros.add(ConsultantNode, name="consultant_faces", domain="faces", kb="kb.yaml")
        reply = ros.call(contract.consultant_service("faces"), {"op": "info"})
        states = ros.listen(contract.WM_STATE.name, contract.STATE_QOS)
        ros.set_clock(10.0)              # publish /clock; spin until the sim-time nodes read it
"""

from __future__ import annotations

import json
import os
import time
from typing import Any, Callable, Optional

import rclpy
from diagnostic_msgs.srv import AddDiagnostics
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from ..ros.carrier import CarrierError, ServiceCaller, qos_profile, to_msg
from ..ros.graph_clock import clock_message
from ..contract import CLOCK, DEFAULT_QOS, clock_remap, normalise_namespace
from ..ros.network import enforce_loopback
from ..ros.sim_clock import now_ns

#: Seconds a wait on the ROS graph (discovery, a match, a condition) may take before it fails.  Discovery
#: takes 0.5-2.5 s on a quiet machine and several times that on a loaded one (the suite runs two workers
#: beside other work); a wait ends as soon as its condition holds, so only a failing wait takes this long.
WAIT = 15.0


class Timeout(AssertionError):
    """A bounded wait ran out (an AssertionError, so a test fails with its message)."""


class Inbox(list):
    """Messages received on one topic (decoded JSON), in arrival order.

    A message that is not JSON (a fuzzer's, say, on a shared domain) is not raised out of
    the spin: its text, clipped, goes to ``undecodable``.
    """

    def __init__(self) -> None:
        super().__init__()
        self.undecodable: list[str] = []

    def take(self, text: str) -> None:
        """Append the decoded ``text``, or note it in ``undecodable`` if it cannot be decoded."""
        try:
            self.append(json.loads(text))
        except (ValueError, RecursionError):
            self.undecodable.append(text[:200])

    def latest(self, **match: Any) -> Optional[dict]:
        """Return the last message whose fields equal ``match`` (None if none)."""
        for item in reversed(self):
            if all(item.get(k) == v for k, v in match.items()):
                return item
        return None

    def where(self, **match: Any) -> list[dict]:
        """Return every message whose fields equal ``match``."""
        return [item for item in self if all(item.get(k) == v for k, v in match.items())]

    def clear_all(self) -> None:
        del self[:]


class RosSession:
    """Nodes of one test in one context and executor, plus a probe node.

    ``namespace`` puts every node added (and the probe) under it, with ``/clock``
    remapped into it as the runners do (:func:`fsreg_ros.contract.clock_remap`).
    ``domain_id`` puts the session on a ROS domain of its own.  ``context`` and
    ``executor`` let a second session share the first one's (two graphs in one process).
    The loopback policy (:func:`fsreg_ros.ros.network.enforce_loopback`) is applied to the
    process's environment before a context is created.
    """

    def __init__(self, namespace: str = "", context: Optional[rclpy.Context] = None,
                 executor: Optional[SingleThreadedExecutor] = None, *, domain_id: Optional[int] = None) -> None:
        self.owner = context is None
        if self.owner:
            enforce_loopback(os.environ)
            self.context = rclpy.Context()
            rclpy.init(context=self.context, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
        else:
            self.context = context
        self.executor = executor or SingleThreadedExecutor(context=self.context)
        self.namespace = normalise_namespace(namespace)
        self.remaps = (["-r", f"__ns:={self.namespace}"] + clock_remap(self.namespace)) if self.namespace else []
        self.nodes: list[Node] = []
        self.probe = Node("probe", context=self.context, cli_args=["--ros-args", *self.remaps] if self.remaps else None)
        self.executor.add_node(self.probe)
        self.group = ReentrantCallbackGroup()
        self._clients: dict[str, ServiceCaller] = {}
        self._publishers: dict[str, Any] = {}
        self._clock_pub = None
        self.time = 0.0

    # ---------------------------------------------------------------- nodes
    def add(self, node_cls: Callable[..., Node], use_sim_time: bool = False, name: Optional[str] = None,
            **params: Any) -> Node:
        """Construct ``node_cls`` in this context with ``params`` (parameter overrides) and spin it here.

        ``name`` renames the node (``-r __node:=name``, which every node class honours).
        """
        overrides = [Parameter(k, value=v) for k, v in params.items()]
        overrides.append(Parameter("use_sim_time", value=use_sim_time))
        kwargs: dict[str, Any] = {"context": self.context, "parameter_overrides": overrides}
        remaps = list(self.remaps) + (["-r", f"__node:={name}"] if name is not None else [])
        if remaps:
            kwargs["cli_args"] = ["--ros-args", *remaps]
        node = node_cls(**kwargs)
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def remove(self, node: Node) -> None:
        """Stop spinning ``node`` and destroy it."""
        self.executor.remove_node(node)
        self.nodes.remove(node)
        node.destroy_node()

    # -------------------------------------------------------------- spinning
    def spin_until(self, predicate: Callable[[], bool], timeout: float = WAIT, what: str = "condition") -> None:
        """Spin until ``predicate()``; fail with :class:`Timeout` after ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > deadline:
                raise Timeout(f"timed out after {timeout} s waiting for {what}")
            self.executor.spin_once(timeout_sec=0.01)

    def spin_for(self, seconds: float) -> None:
        """Spin for a while (lets what is under way arrive; never proof that something does not happen)."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)

    def run(self, coroutine, timeout: float = 10.0) -> Any:
        """Run a coroutine as an executor task until done; its result (or exception)."""
        task = self.executor.create_task(coroutine)
        self.spin_until(task.done, timeout, what="task")
        return task.result()

    # -------------------------------------------------------------- services
    def client(self, service: str) -> ServiceCaller:
        """Return the probe's JSON client of ``service`` (made once)."""
        if service not in self._clients:
            self._clients[service] = ServiceCaller(self.probe, service, self.group)
        return self._clients[service]

    def wait_service(self, service: str, timeout: float = WAIT) -> None:
        client = self.client(service)
        self.spin_until(client.ready, timeout, what=f"service {service}")

    def wait_ready(self, service: str, payload: dict, timeout: float = 30.0) -> dict:
        """Wait for one real round trip of ``payload`` (an idempotent op) to ``service``; its reply.

        A new server's first request can be lost while discovery completes, so
        attempts that time out are sent again (:meth:`ServiceCaller.wait_ready`).
        """
        return self.run(self.client(service).wait_ready(payload, timeout), timeout + 1.0)

    def call(self, service: str, payload: dict, timeout: float = 5.0) -> dict:
        """Call a JSON service; the reply (raises CarrierError on failure)."""
        self.wait_service(service, timeout)
        return self.run(self.client(service).call(payload, timeout), timeout + 1.0)

    def call_error(self, service: str, payload: Any, timeout: float = 5.0) -> CarrierError:
        """Call expecting failure; the CarrierError.  ``payload`` may be raw text."""
        self.wait_service(service, timeout)
        client = self.client(service)
        if isinstance(payload, str):
            future = client.client.call_async(AddDiagnostics.Request(load_namespace=payload))
        else:
            future = client.send(payload)
        try:
            reply = self.run(client.result(future, timeout), timeout + 1.0)
        except CarrierError as err:
            return err
        raise AssertionError(f"{service} accepted {payload!r}: {reply}")

    # ---------------------------------------------------------------- topics
    def publish(self, topic: str, obj: Any, qos=DEFAULT_QOS) -> None:
        """Publish a JSON object (or raw text) as std_msgs/String, once a subscriber is matched."""
        if topic not in self._publishers:
            self._publishers[topic] = self.probe.create_publisher(String, topic, qos_profile(qos))
        pub = self._publishers[topic]
        self.spin_until(lambda: pub.get_subscription_count() > 0, WAIT, what=f"a subscriber of {topic}")
        pub.publish(String(data=obj) if isinstance(obj, str) else to_msg(obj))

    def listen(self, topic: str, qos=DEFAULT_QOS) -> Inbox:
        """Collect the JSON objects published on ``topic`` from now on."""
        inbox = Inbox()
        self.probe.create_subscription(String, topic, lambda m: inbox.take(m.data), qos_profile(qos))
        return inbox

    # ------------------------------------------------------------- sim time
    def set_clock(self, t: float, nodes: Optional[list[Node]] = None) -> None:
        """Publish ``/clock`` = t; spin until every (given) sim-time node reads it."""
        if self._clock_pub is None:
            self._clock_pub = self.probe.create_publisher(Clock, CLOCK, 10)
        msg = clock_message(t)
        ns = int(round(t * 1e9))
        watch = [n for n in (nodes or self.nodes) if n.get_parameter("use_sim_time").value]
        self.spin_until(lambda: self._clock_pub.get_subscription_count() >= len(watch), WAIT, what="/clock subscribers")
        self._clock_pub.publish(msg)
        self.spin_until(lambda: all(now_ns(n) >= ns for n in watch), WAIT, what=f"/clock = {t}")
        self.time = t

    set_time = set_clock  # the name the project's older tests use

    # -------------------------------------------------------------- teardown
    def close(self) -> None:
        """Destroy every node and the probe; shut the context down if this session made it."""
        for node in list(self.nodes):
            try:
                self.executor.remove_node(node)
                node.destroy_node()
            except Exception:  # noqa: BLE001 - best effort: the others must still go
                pass
        self.nodes.clear()
        self.executor.remove_node(self.probe)
        self.probe.destroy_node()
        if self.owner:
            self.executor.shutdown(timeout_sec=1.0)
            rclpy.try_shutdown(context=self.context)

    def __enter__(self) -> "RosSession":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
