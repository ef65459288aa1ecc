"""In-process rclpy test harness (ROS-NOTES "Tests").

One :class:`Graph` per test: its own ``rclpy.Context`` (no signal handlers), one
``SingleThreadedExecutor`` running every node of the test plus a ``probe`` node the
test talks through, bounded spin loops only (every wait has a deadline and fails the
test with a message when it passes), and a full teardown.

    with Graph() as g:
        c = g.add(ConsultantNode, domain="faces", kb=KB)
        reply = g.call(contract.consultant_service("faces"), {"op": "info"})
        states = g.listen(contract.WM_STATE.name, contract.STATE_QOS)
        g.set_time(10.0)              # publish /clock; wait until sim-time nodes read it
"""

from __future__ import annotations

import os

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ.setdefault("ROS_DOMAIN_ID", "57")
if not os.environ.get("ROS_LOG_DIR"):
    import tempfile

    os.environ["ROS_LOG_DIR"] = tempfile.mkdtemp(prefix="fsreg-test-roslog-")
assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST", "ROS tests must keep discovery on localhost"

import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any, Callable, Optional  # noqa: E402

import rclpy  # noqa: E402
from rclpy.callback_groups import ReentrantCallbackGroup  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.signals import SignalHandlerOptions  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from fsreg_ros.carrier import DEFAULT_TIMEOUT, SERVICE_TYPE, CarrierError, JsonClient, qos_profile, to_msg  # noqa: E402
from fsreg_ros.codec import dumps  # noqa: E402
from fsreg_ros.contract import CLOCK, DEFAULT_QOS, clock_remap, normalise_namespace  # noqa: E402
from fsreg_ros.nodes.dialogue_player import clock_message  # noqa: E402

DATA = Path(__file__).resolve().parent / "data" / "graph"
KB = str(DATA / "kb.yaml")


class Timeout(AssertionError):
    """A bounded wait ran out."""


class Graph:
    """Nodes of one test in one context and executor, plus a probe node."""

    def __init__(self, namespace: str = "", context: Optional[rclpy.Context] = None,
                 executor: Optional[SingleThreadedExecutor] = None) -> None:
        """Start a context and executor, or share those of another Graph (two graphs in one process).

        ``namespace`` puts every node (and the probe) under it, with ``/clock`` remapped into
        it as the runner does (:func:`fsreg_ros.contract.clock_remap`).
        """
        self.owner = context is None
        self.context = context or rclpy.Context()
        if self.owner:
            rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.executor = executor or SingleThreadedExecutor(context=self.context)
        self.namespace = normalise_namespace(namespace)
        self.remaps = (["-r", f"__ns:={self.namespace}"] + clock_remap(self.namespace)) if self.namespace else []
        self.nodes: list[Node] = []
        self.probe = Node("probe", context=self.context, cli_args=["--ros-args", *self.remaps] if self.remaps else None)
        self.executor.add_node(self.probe)
        self.group = ReentrantCallbackGroup()
        self._clients: dict[str, JsonClient] = {}
        self._publishers: dict[str, Any] = {}
        self._clock_pub = None
        self.time = 0.0

    # ---------------------------------------------------------------- nodes
    def add(self, node_cls: Callable[..., Node], use_sim_time: bool = False, name: Optional[str] = None,
            **params: Any) -> Node:
        """Construct ``node_cls`` in this context with ``params`` and spin it here."""
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
        self.executor.remove_node(node)
        self.nodes.remove(node)
        node.destroy_node()

    # -------------------------------------------------------------- spinning
    def spin_until(self, predicate: Callable[[], bool], timeout: float = 5.0, what: str = "condition") -> None:
        """Spin until ``predicate()``; fail the test after ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > deadline:
                raise Timeout(f"timed out after {timeout} s waiting for {what}")
            self.executor.spin_once(timeout_sec=0.01)

    def spin_for(self, seconds: float) -> None:
        """Spin for a while (only to show that something does NOT happen)."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)

    def run(self, coroutine, timeout: float = 10.0) -> Any:
        """Run a coroutine as an executor task until done; its result (or exception)."""
        task = self.executor.create_task(coroutine)
        self.spin_until(task.done, timeout, what="task")
        return task.result()

    # -------------------------------------------------------------- services
    def client(self, service: str) -> JsonClient:
        if service not in self._clients:
            self._clients[service] = JsonClient(self.probe, service, self.group)
        return self._clients[service]

    def wait_service(self, service: str, timeout: float = 5.0) -> None:
        client = self.client(service)
        self.spin_until(client.ready, timeout, what=f"service {service}")

    def call(self, service: str, payload: dict, timeout: float = 5.0) -> dict:
        """Call a JSON service; the reply (raises CarrierError on failure)."""
        self.wait_service(service, timeout)
        return self.run(self.client(service).call(payload, timeout), timeout + 1.0)

    def call_error(self, service: str, payload: Any, timeout: float = 5.0) -> CarrierError:
        """Call expecting failure; the CarrierError.  ``payload`` may be raw text."""
        self.wait_service(service, timeout)
        client = self.client(service)
        if isinstance(payload, str):
            from diagnostic_msgs.srv import AddDiagnostics

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
        """Publish a JSON object (or raw text) as std_msgs/String."""
        if topic not in self._publishers:
            self._publishers[topic] = self.probe.create_publisher(String, topic, qos_profile(qos))
        pub = self._publishers[topic]
        self.spin_until(lambda: pub.get_subscription_count() > 0, 5.0, what=f"a subscriber of {topic}")
        pub.publish(String(data=obj) if isinstance(obj, str) else to_msg(obj))

    def listen(self, topic: str, qos=DEFAULT_QOS) -> "Inbox":
        """Collect the JSON objects published on ``topic`` from now on."""
        import json

        inbox = Inbox()
        self.probe.create_subscription(String, topic, lambda m: inbox.append(json.loads(m.data)), qos_profile(qos))
        return inbox

    # ------------------------------------------------------------- sim time
    def set_time(self, t: float, nodes: Optional[list[Node]] = None) -> None:
        """Publish ``/clock`` = t; spin until every (given) sim-time node reads it."""
        if self._clock_pub is None:
            self._clock_pub = self.probe.create_publisher(Clock, CLOCK, 10)
        msg = clock_message(t)
        ns = int(round(t * 1e9))
        watch = [n for n in (nodes or self.nodes) if n.get_parameter("use_sim_time").value]
        self.spin_until(lambda: self._clock_pub.get_subscription_count() >= len(watch), 5.0, what="/clock subscribers")
        self._clock_pub.publish(msg)
        self.spin_until(
            lambda: all(n.get_clock().now().nanoseconds >= ns for n in watch), 5.0, what=f"/clock = {t}"
        )
        self.time = t

    # -------------------------------------------------------------- teardown
    def close(self) -> None:
        for node in list(self.nodes):
            try:
                self.executor.remove_node(node)
                node.destroy_node()
            except Exception:  # noqa: BLE001 - best effort
                pass
        self.executor.remove_node(self.probe)
        self.probe.destroy_node()
        if self.owner:
            self.executor.shutdown(timeout_sec=1.0)
            rclpy.try_shutdown(context=self.context)

    def __enter__(self) -> "Graph":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


class Inbox(list):
    """Messages received on one topic (decoded JSON), in arrival order."""

    def latest(self, **match: Any) -> Optional[dict]:
        for item in reversed(self):
            if all(item.get(k) == v for k, v in match.items()):
                return item
        return None

    def where(self, **match: Any) -> list[dict]:
        return [item for item in self if all(item.get(k) == v for k, v in match.items())]

    def clear_all(self) -> None:
        del self[:]


def ros_graph():
    """Yield a Graph and close it after: the body of a pytest fixture."""
    graph = Graph()
    try:
        yield graph
    finally:
        graph.close()


def as_json(obj: Any) -> str:
    return dumps(obj)


async def call(client, payload: Any, timeout: Optional[float] = None, *, node=None) -> dict:
    """Await one JSON call and return the reply, or raise :class:`CarrierError`.

    Test-only: the bare-client branch busy-waits by yielding to the executor.

    ``client`` is a :class:`JsonClient`, or a plain ``AddDiagnostics`` client.  For a
    plain client pass its ``node`` so the deadline is a timer; without it the deadline
    is only checked when something else wakes the executor (rclpy resumes pending
    tasks on every wake-up), so a dead server can block a quiet ``spin()`` forever.
    """
    if isinstance(client, JsonClient):
        return await client.call(payload, timeout)
    timeout = DEFAULT_TIMEOUT if timeout is None else timeout
    if node is not None:
        return await JsonClient.wrap(node, client, timeout).call(payload, timeout)
    future = client.call_async(SERVICE_TYPE.Request(load_namespace=dumps(payload)))
    deadline = time.monotonic() + timeout
    while not future.done():
        if time.monotonic() >= deadline:
            client.remove_pending_request(future)
            raise CarrierError(f"no reply within {timeout:g} s", kind="timeout", service=client.srv_name)
        await _Yield()
    return JsonClient.decode_response(future, client.srv_name)


class _Yield:
    """Awaitable that gives control back to the rclpy executor once."""

    def __await__(self):
        yield
