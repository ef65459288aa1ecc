"""What every part of :class:`~fsreg_ros.ros.client.GraphClient` shares: its error, its defaults, bounded spinning.

:class:`ClientError` (with its ``kind``) is how every part of the client fails;
:class:`Spinning` owns how the client waits: it spins the caller's executor in
bounded loops (every wait has a deadline and fails with :class:`ClientError`),
checking on each turn that the graph is still there (``check_gone``, from
:mod:`fsreg_ros.ros.readiness`).  The client's other jobs live beside this module
(:mod:`fsreg_ros.ros.client` says which where).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Callable

#: Seconds a client waits for an answer, by default.
DEFAULT_TIMEOUT = 10.0
#: Seconds after which an unanswered message is sent again.
RETRY_AFTER = 2.0


class ClientError(RuntimeError):
    """A request that did not get an answer of its graph.

    ``kind``: ``not-ready`` (no graph, or not serving yet), ``timeout`` (no answer in
    time), ``gone`` (the graph left while the client waited: its WM Manager stopped, or
    its readiness was lost), ``clash`` (two graphs on one name), ``foreign`` (an answer
    stamped by another graph), ``busy`` (a message not sent: its receivers are too far
    behind, see :meth:`GraphClient.send`), ``rejected`` (a parameter change refused),
    ``refused`` (a clock the graph does not take), ``usage`` (a request that cannot be
    made: a name the graph does not have, a value out of range, a message over the
    graph's size limits), or the error kind a service reported.
    """

    def __init__(self, message: str, kind: str = "error") -> None:
        super().__init__(message)
        self.kind = kind


@dataclass
class Answer:
    """One message heard on a reply topic, and when (monotonic seconds)."""

    data: dict
    received: float


def describe_graph(graph: Any) -> str:
    """Return a graph identity for messages ('none' for an unstamped message)."""
    return repr(graph) if graph else "none (unstamped)"


class Spinning:
    """Bounded waits of a client on its ``node``, spun through its ``executor`` (both the caller's)."""

    node: Any
    executor: Any

    def check_gone(self) -> None:
        """Raise ClientError ``gone`` once the graph left (:class:`~fsreg_ros.ros.readiness.Readiness` checks)."""

    @property
    def namespace(self) -> str:
        """The namespace of the graph this client talks to ('/' for none)."""
        return self.node.get_namespace()

    def where(self) -> str:
        """Return 'namespace N on ROS domain D', for messages."""
        return f"namespace {self.namespace} on ROS domain {self.node.context.get_domain_id()}"

    def spin_until(self, predicate: Callable[[], bool], timeout: float, what: str, kind: str = "timeout") -> None:
        """Spin until ``predicate()``; raise ClientError(``kind``) naming ``what`` after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > deadline:
                raise ClientError(f"{what}: nothing within {timeout:g} s", kind)
            self.check_gone()
            self.executor.spin_once(timeout_sec=0.005)

    def spin_for(self, seconds: float) -> None:
        """Spin for ``seconds`` (collects what arrives meanwhile)."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.005)

    def run(self, coroutine, timeout: float, what: str) -> Any:
        """Run a coroutine as a task of the executor until done; its result."""
        task = self.executor.create_task(coroutine)
        try:
            self.spin_until(task.done, timeout, what)
        except ClientError:
            task.cancel()
            raise
        return task.result()
