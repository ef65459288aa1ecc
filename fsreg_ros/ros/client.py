"""The client side of a live fsreg graph: :class:`GraphClient`, and where each of its jobs lives.

One :class:`GraphClient` talks to one graph (one namespace of one ROS domain) through
a node the caller owns and an executor the client spins in bounded loops (every wait
has a deadline and fails with :class:`ClientError`).  It is what ``fsreg-ctl`` runs,
what ``fsreg-up`` waits for readiness with, and what :mod:`fsreg_ros.testing` drives a
graph through, so a robot builder's integration test, the command line and the
project's own tests use one client.

This module owns the client's state (set up in :meth:`GraphClient.__init__`: the
node's publishers, subscriptions and service clients, and what they heard) and
:func:`find_graph`.  Its jobs are parts of the class, one module each:

=====================  ==============================================================
``client_base``        :class:`ClientError`, the defaults, bounded spinning
                       (:class:`~.client_base.Spinning`)
``readiness``          readiness, graph identity and presence (``wait_ready``,
                       ``check_clash``, ``gone``, ``domains``, ``node_names``)
``exchange``           requests and answers on the dialogue topics (``say``,
                       ``describe``, ``assert_facts``, ``exchange``)
``graph_queries``      service calls and WM reads (``call``, ``status``, ``sync``,
                       ``reset_state``, ``wm``, ``snapshot``, ``state``, ``watch``)
``graph_clock``        the graph's clock (``set_clock``, ``publish_clock``,
                       ``graph_time``)
``parameter_access``   node parameters (``list_parameters`` ... ``set_parameters``)
``recorders``          reaching the graph's recorders before publishing
                       (``reach_recorders``, ``unheard``)
=====================  ==============================================================

The names those modules define that the client's users import (``ClientError``,
``clock_message``, ``describe_graph``, ``DISCOVERY_WAIT``, ...) are importable from
here as well.
"""

from __future__ import annotations

import dataclasses
import itertools
import secrets
import time
from typing import Any, Callable, Optional

from rclpy.event_handler import SubscriptionEventCallbacks
from rosgraph_msgs.msg import Clock

from .. import contract
from ..contract import Limits
from .batches import subscribe_batches
from .carrier import ServiceCaller, publisher, subscribe
from .client_base import DEFAULT_TIMEOUT, RETRY_AFTER, Answer, ClientError, describe_graph
from .exchange import ANSWERS_GATHER, KIND_TOPICS, MATCH_EVERY, MATCH_SETTLE, DialogueExchange
from .graph_clock import CLOCK_DISCOVERY, CLOCK_RESEND, ClockControl, check_clock, clock_message
from .graph_queries import GraphQueries, state_version
from .parameter_access import ParameterAccess, parameter_value, python_value, range_problem
from .readiness import CLASH_WAIT, DISCOVERY_WAIT, GONE_AFTER, GRAPH_NODES, LAPSE_CONFIRM, Readiness
from .recorders import RECORDER_WAIT, RecorderReach

__all__ = [
    "GraphClient", "ClientError", "Answer", "find_graph", "describe_graph", "clock_message", "check_clock",
    "state_version", "parameter_value", "python_value", "range_problem", "DEFAULT_TIMEOUT", "RETRY_AFTER",
    "CLASH_WAIT", "DISCOVERY_WAIT", "GONE_AFTER", "LAPSE_CONFIRM", "CLOCK_DISCOVERY", "CLOCK_RESEND",
    "MATCH_SETTLE", "GRAPH_NODES", "KIND_TOPICS",
]

#: Seconds at most :meth:`GraphClient.delivered` waits for the readers to acknowledge what the client sent.
DELIVERY_WAIT = 2.0


class GraphClient(Readiness, DialogueExchange, GraphQueries, ClockControl, ParameterAccess, RecorderReach):
    """A client of one live graph, on ``node`` (spun by this client through ``executor``).

    ``graph`` is the identity expected; None takes the identity of the graph whose WM
    Manager announces readiness (:meth:`wait_ready`).  Names are relative, so the
    node's namespace chooses the graph's (and a remapping of ``/clock`` its clock).
    Its methods come from its parts (the module docstring says which does what); the
    state they share is set up here.
    """

    def __init__(self, node, executor, *, graph: Optional[str] = None, timeout: float = DEFAULT_TIMEOUT,
                 retry_after: float = RETRY_AFTER) -> None:
        self.node = node
        self.executor = executor
        self.graph = graph
        self.timeout = timeout
        self.retry_after = retry_after
        self.time: Optional[float] = None  # the clock set through this client, stamped on requests
        self.answers: dict[str, list[Answer]] = {}
        self.ready_messages: dict[tuple, dict] = {}  # (graph, pid, host) -> latest wm_manager/ready
        self._ready_heard: dict[tuple, float] = {}  # when each was heard (monotonic)
        self._publishers = {kind: publisher(node, topics[0]) for kind, topics in KIND_TOPICS.items()}
        self._reply_subs = {kind: subscribe(node, topics[1], self._on_answer) for kind, topics in KIND_TOPICS.items()
                            if kind != "assert"}
        # A perception stream's answers (one per ltm/assert) are gathered as the consultants gather the stream.
        self._reply_subs["assert"] = subscribe_batches(
            node, contract.LTM_ASSERT_RESULT, lambda answers: [self._on_answer(data) for data in answers],
            reject=None, gather=ANSWERS_GATHER)
        # The reader asks the writer's liveliness lease: only then does Fast DDS report the writer's death.
        ready_topic = dataclasses.replace(contract.READY, reader_qos=contract.READY_QOS)
        self._ready_sub = subscribe(node, ready_topic, self._on_ready,
                                    event_callbacks=SubscriptionEventCallbacks(liveliness=self._on_liveliness))
        self._ready_alive: Optional[int] = None  # live writers of wm_manager/ready (None: no liveliness event yet)
        self.notice_leaving = False  # every wait checks that the graph is still there (:meth:`gone`)
        self._was_ready = False
        self._unready_since: Optional[float] = None
        self._lapsed_since: Optional[float] = None  # when the ready writer's liveliness lapsed (None: alive)
        self._gone_checked = 0.0
        self.limits = Limits()  # the graph's size limits (the nodes' defaults), checked before sending
        self._clock = node.create_publisher(Clock, contract.CLOCK, 10)
        self._services: dict[str, ServiceCaller] = {}
        self._param_clients: dict[tuple[str, str], Any] = {}
        self._entities: dict[str, set[str]] = {}
        self.foreign: Optional[str] = None  # set by :meth:`watch` when another graph's message arrives
        self._states: Optional[dict[str, dict]] = None  # domain -> latest wm/state (once :meth:`state` is used)
        self._state_watcher: Optional[Callable[[dict], None]] = None  # :meth:`watch`'s, once it runs
        self._ids = itertools.count(1)
        self._prefix = f"{node.get_name()}-{secrets.token_hex(3)}"
        self._sent: dict[str, tuple[Any, Callable[[], None], int]] = {}  # topic -> last message (see delivered)
        self.recorder_wait = RECORDER_WAIT  # seconds a send waits for each recorder the graph names
        self._unheard: dict[str, list[str]] = {}  # recorder -> topics it was not reached on (see unheard)
        self._reached: set[tuple[str, str]] = set()  # (recorder, topic) matched already (see reach_recorders)

    def _note_sent(self, writer, resend: Callable[[], None]) -> None:
        """Remember the last message sent on ``writer`` (how to send it again) and how many readers had matched."""
        self._sent[writer.topic_name] = (writer, resend, writer.get_subscription_count())

    def delivered(self, timeout: float = DELIVERY_WAIT) -> bool:
        """Make every reader matched with this client's writers hold the last message each sent; whether all do.

        A short-lived client (``fsreg-ctl``) calls it before its node goes.  An answer from
        the graph says that the node asked heard the request, not that every other reader
        did: a recorder discovered only after the request went out never got it (a writer
        sends to the readers matched when it writes).  So a reader this node discovered is
        waited for until its writer matches it (for at most ``MATCH_EVERY`` seconds: one
        whose QoS never matches is not waited for), and the last message of a writer that
        has matched more readers since it was sent is sent again (same id: the graph answers
        a repeated id once, a replay counts it once) and waited for until every matched
        reader acknowledged it (received, not merely sent).  Only those are waited for: a
        reader acknowledges on the writer's periodic heartbeat (every 3 s in Fast DDS), so
        waiting for every acknowledgment would hold every command that long.  Waits at most
        ``timeout`` seconds in all; returns at once when no reader came since the sending.
        """
        from rclpy.duration import Duration

        deadline = time.monotonic() + timeout
        settle = time.monotonic() + min(timeout, MATCH_EVERY)
        again: dict[str, Any] = {}
        while True:
            for topic, (writer, resend, matched) in list(self._sent.items()):
                now = writer.get_subscription_count()
                if now > matched:
                    resend()
                    self._sent[topic] = (writer, resend, now)
                    again[topic] = writer
            # a reader this node has discovered but its writer not yet matched: wait for the match
            pending = any(self.node.count_subscribers(w.topic_name) > w.get_subscription_count()
                          for w, _, _ in self._sent.values())
            if not pending or time.monotonic() >= settle:
                break
            time.sleep(0.01)
        done = True
        for writer in again.values():
            left = max(0.0, deadline - time.monotonic())
            done = writer.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9))) and done
        return done


def find_graph(namespace: str, wait: float = DISCOVERY_WAIT) -> Optional[str]:
    """Describe the graph running in ``namespace`` on this process's ROS domain (None if none is seen in ``wait`` s).

    Starts and ends a context of its own; set the ROS environment first.
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    executor = SingleThreadedExecutor(context=context)
    node = rclpy.create_node(f"fsreg_probe_{secrets.token_hex(4)}", namespace=namespace or "/", context=context)
    try:
        executor.add_node(node)
        return GraphClient(node, executor).find_running(wait)
    finally:
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
