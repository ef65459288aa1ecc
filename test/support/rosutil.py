"""The project's ROS tests use the public harness, :mod:`fsreg_ros.testing`; this keeps their short names.

:class:`~fsreg_ros.testing.RosSession` is the harness's low level (one context and
executor, a probe node, bounded waits); ``ros_graph`` is the body of a fixture yielding one.  ``call`` is
a test-only helper for driving a bare ``AddDiagnostics`` client.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Optional

from fsreg_ros.contract.codec import dumps
from fsreg_ros.ros.carrier import DEFAULT_TIMEOUT, SERVICE_TYPE, CarrierError, ServiceCaller
from fsreg_ros.testing.ros_session import Inbox, RosSession, Timeout

DATA = Path(__file__).resolve().parent / "data" / "graph"
KB = str(DATA / "kb.yaml")

__all__ = ["DATA", "KB", "Inbox", "RosSession", "Timeout", "call", "ros_graph"]


def ros_graph():
    """Yield a RosSession and close it after: the body of a pytest fixture."""
    graph = RosSession()
    try:
        yield graph
    finally:
        graph.close()


async def call(client, payload: Any, timeout: Optional[float] = None, *, node=None) -> dict:
    """Await one JSON call and return the reply, or raise :class:`CarrierError`.

    ``client`` is a :class:`ServiceCaller`, or a plain ``AddDiagnostics`` client.  For a
    plain client pass its ``node`` so the deadline is a timer; without it the deadline
    is only checked when something else wakes the executor (this branch busy-waits by
    yielding to the executor), so a dead server can block a quiet ``spin()`` forever.
    """
    if isinstance(client, ServiceCaller):
        return await client.call(payload, timeout)
    timeout = DEFAULT_TIMEOUT if timeout is None else timeout
    if node is not None:
        return await ServiceCaller.wrap(node, client, timeout).call(payload, timeout)
    future = client.call_async(SERVICE_TYPE.Request(load_namespace=dumps(payload)))
    deadline = time.monotonic() + timeout
    while not future.done():
        if time.monotonic() >= deadline:
            client.remove_pending_request(future)
            raise CarrierError(f"no reply within {timeout:g} s", kind="timeout", service=client.srv_name)
        await _Yield()
    return ServiceCaller.decode_response(future, client.srv_name)


class _Yield:
    """Awaitable that gives control back to the rclpy executor once."""

    def __await__(self):
        yield
