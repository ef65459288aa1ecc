"""The client side of a live fsreg graph: readiness, requests and their answers, graph identity.

One :class:`GraphClient` talks to one graph (one namespace of one ROS domain) through
a node the caller owns and an executor the client spins in bounded loops (every wait
has a deadline and fails with :class:`ClientError`).  It is what ``fsreg-ctl`` runs,
what ``fsreg-up`` waits for readiness with, and what :mod:`fsreg_ros.testing` drives a
graph through, so a robot builder's integration test, the command line and the
project's own tests use one client.

* Readiness: the WM Manager's latched ``wm_manager/ready``
  (:class:`~fsreg_ros.contract.ManagerReady`) says when every consultant serves;
  :meth:`GraphClient.wait_ready` waits for it, and for the dialogue pipeline to be
  matched with this client, instead of retrying requests.
* Identity: every node stamps what it publishes with its graph's identity
  (:data:`~fsreg_ros.contract.GRAPH_FIELD`).  The client expects one graph (given, or the
  one whose WM Manager answers), refuses to go on when two graphs' WM Managers share
  the namespace (kind ``clash``), and rejects an answer stamped by another graph (kind
  ``foreign``) instead of counting it.
* Requests: ``say`` (``dialogue/human`` -> ``rr/result``), ``describe``
  (``reg/request`` -> ``reg/expression``), ``assert_facts`` (``ltm/assert`` ->
  ``ltm/assert/result``), each with a fresh id, resent every ``retry_after`` seconds
  until answered (RR, REG and the consultants answer a repeated id once); ``wm``,
  ``status``, ``sync``, ``set_clock`` and node parameters through services.
"""

from __future__ import annotations

import dataclasses
import difflib
import itertools
import secrets
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Mapping, Optional, Sequence

from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, GetParameters, ListParameters, SetParametersAtomically
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rosgraph_msgs.msg import Clock

from .. import contract
from ..contract import Limits
from ..contract.codec import MessageError, printable, safe_dumps
from ..core.decay import MAX_TIME
from .carrier import CarrierError, ServiceCaller, publish, publisher, subscribe

#: Seconds a client waits for an answer, by default.
DEFAULT_TIMEOUT = 10.0
#: Seconds after which an unanswered message is sent again.
RETRY_AFTER = 2.0
#: Seconds to collect every WM Manager's latched readiness once more than one publishes it.
CLASH_WAIT = 2.0
#: Seconds a runner looks for a graph already running where it would start one (discovery on this
#: machine takes 0.1-2.5 s; the wait ends as soon as one is seen).
DISCOVERY_WAIT = 2.5
#: Seconds a waiting client lets its graph stay not ready (after it was ready) before reporting it gone.
GONE_AFTER = 1.5
#: Seconds the ready writer's liveliness must stay lapsed before the graph counts as gone (a stall
#: of the WM Manager's process beyond its 1 s lease, as on a loaded machine, is not a death).
LAPSE_CONFIRM = 0.8
#: Seconds ``set_clock`` waits for the graph's nodes to subscribe the clock topic before publishing.
CLOCK_DISCOVERY = 2.5
#: Seconds between two ``/clock`` messages while ``set_clock`` waits for the graph's clock to reach the time.
CLOCK_RESEND = 0.25
#: Seconds a client waits after its request and reply topics first match before sending (see wait_matched).
MATCH_SETTLE = 0.25
#: The node names of a graph (besides ``consultant_<domain>``).
GRAPH_NODES = ("wm_manager", "parser", "reference_resolution", "reg", "dialogue_player")
#: Publishers the pipeline must have matched before a request is sent: topic -> publisher/subscriber side.
KIND_TOPICS = {"say": (contract.HUMAN, contract.RR_RESULT), "describe": (contract.REG_REQUEST, contract.REG_EXPRESSION),
               "assert": (contract.LTM_ASSERT, contract.LTM_ASSERT_RESULT)}


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


def clock_message(seconds: float) -> Clock:
    """Return a ``/clock`` message for a time in seconds (nanoseconds always < 1e9)."""
    stamp = Clock()
    stamp.clock.sec, stamp.clock.nanosec = divmod(int(round(seconds * 1e9)), 10**9)
    return stamp


def _facts(properties: Mapping[str, float] | Iterable[str]) -> dict[str, float]:
    """Return facts as property -> certainty (a list of properties: each certain)."""
    return dict(properties) if isinstance(properties, Mapping) else {p: 1.0 for p in properties}


def describe_graph(graph: Any) -> str:
    """Return a graph identity for messages ('none' for an unstamped message)."""
    return repr(graph) if graph else "none (unstamped)"


class GraphClient:
    """A client of one live graph, on ``node`` (spun by this client through ``executor``).

    ``graph`` is the identity expected; None takes the identity of the graph whose WM
    Manager announces readiness (:meth:`wait_ready`).  Names are relative, so the
    node's namespace chooses the graph's (and a remapping of ``/clock`` its clock).
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
        self._reply_subs = {kind: subscribe(node, topics[1], self._on_answer) for kind, topics in KIND_TOPICS.items()}
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

    # ------------------------------------------------------------ callbacks
    def _on_answer(self, data: dict) -> None:
        key = str(data.get("id"))
        if key in self.answers:
            self.answers[key].append(Answer(data, time.monotonic()))

    def _on_ready(self, data: dict) -> None:  # subscribe() has checked it against contract.ManagerReady
        key = (data.get(contract.GRAPH_FIELD) or "", data.get("pid"), data.get("host"))
        self.ready_messages[key] = data
        self._ready_heard[key] = time.monotonic()

    def _on_liveliness(self, info) -> None:
        self._ready_alive = info.alive_count
        if info.alive_count == 0:
            self._lapsed_since = self._lapsed_since or time.monotonic()
        else:
            self._lapsed_since = None

    def gone(self) -> Optional[str]:
        """Return why this client's graph has left (None while it is there, or before it was found).

        Gone: its WM Manager's ``wm_manager/ready`` writer is no longer matched (the
        process stopped), or its liveliness lapsed for :data:`LAPSE_CONFIRM` s (the process
        died: within the topic's 1 s lease and that; a process that only stalled for a
        moment, as on a loaded machine, comes back within it), or the graph said ``ready``
        and then not for :data:`GONE_AFTER` s.
        """
        message = self.readiness()
        if message is None:
            return None
        who = f"graph {describe_graph(self.graph or message.get(contract.GRAPH_FIELD))} in {self.where()}"
        if self._ready_sub.get_publisher_count() == 0:
            return f"{who} left: its WM Manager stopped"
        now = time.monotonic()
        if self._ready_alive == 0 and self._lapsed_since is not None and now - self._lapsed_since >= LAPSE_CONFIRM:
            return f"{who} left: its WM Manager's liveliness lapsed (the process died)"
        if message["ready"]:
            self._was_ready, self._unready_since = True, None
        elif self._was_ready:
            self._unready_since = self._unready_since or now
            if now - self._unready_since >= GONE_AFTER:
                waiting = [d for d, st in (message.get("domains") or {}).items() if not st.get("configured")]
                return (f"{who} lost its readiness for {GONE_AFTER:g} s (consultants not configured: "
                        f"{', '.join(waiting) or 'none'})")
        return None

    def check_gone(self) -> None:
        """Raise ClientError ``gone`` if :attr:`notice_leaving` is set and the graph left (checked every 0.1 s)."""
        now = time.monotonic()
        if not self.notice_leaving or now - self._gone_checked < 0.1:
            return
        self._gone_checked = now
        reason = self.gone()
        if reason is not None:
            raise ClientError(reason, "gone")

    # -------------------------------------------------------------- spinning
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

    # ----------------------------------------------------------------- ready
    def readiness(self) -> Optional[dict]:
        """Return the latest ``wm_manager/ready`` of this client's graph (None before one arrived)."""
        mine = [k for k in self.ready_messages if self.graph is None or k[0] == self.graph]
        return self.ready_messages[max(mine, key=self._ready_heard.__getitem__)] if mine else None

    def _graphs(self) -> list[tuple]:
        return sorted(self.ready_messages, key=str)

    def check_clash(self) -> None:
        """Raise ClientError(``clash``) if two WM Managers announce readiness on this client's names.

        Two messages from WM Managers that are not both matched now (one was restarted)
        are not a clash: the latest heard stands.
        """
        def others() -> bool:  # another WM Manager is known (matched, or a node of that name): hear it
            managers = sum(1 for name, ns in self.node.get_node_names_and_namespaces()
                           if name == "wm_manager" and ns == self.namespace)
            return max(self._ready_sub.get_publisher_count(), managers) > len(self.ready_messages)

        if others():  # collect its latched message (or let a dead one's entity go)
            deadline = time.monotonic() + CLASH_WAIT
            while time.monotonic() < deadline and others():
                self.executor.spin_once(timeout_sec=0.01)
        if len(self.ready_messages) > 1 and self._ready_sub.get_publisher_count() <= 1:
            latest = max(self.ready_messages, key=self._ready_heard.__getitem__)
            self.ready_messages = {latest: self.ready_messages[latest]}
        if len(self.ready_messages) > 1:
            graphs = "; ".join(f"graph {describe_graph(g)} (wm_manager pid {pid} on {host})"
                               for g, pid, host in self._graphs())
            raise ClientError(f"two graphs in {self.where()}: {graphs}; give each its own --namespace or "
                              "ROS_DOMAIN_ID", "clash")

    def wait_ready(self, timeout: float = 30.0, pipeline: bool = True) -> dict:
        """Wait until the graph serves: its WM Manager says ``ready`` (and, with ``pipeline``, every topic matched).

        Learns the graph identity if none was given.  Raises ClientError: ``not-ready``
        (no WM Manager, or not ready in time), ``clash`` (two graphs on these names).
        """
        deadline = time.monotonic() + timeout
        self.spin_until(lambda: self.ready_messages, timeout,
                        f"no fsreg graph answers in {self.where()} (is fsreg-up running there?)", "not-ready")
        self.check_clash()
        if self.graph is None:
            (self.graph, _, _), = self.ready_messages
        if not any(graph == self.graph for graph, _, _ in self.ready_messages):
            found = ", ".join(describe_graph(g) for g, _, _ in self._graphs())
            raise ClientError(f"graph {describe_graph(self.graph)} is not in {self.where()} (found {found})",
                              "not-ready")

        def serving() -> bool:
            message = self.readiness()
            return bool(message and message["ready"])

        remaining = max(0.0, deadline - time.monotonic())
        try:
            self.spin_until(serving, remaining, f"graph {describe_graph(self.graph)} in {self.where()} did not "
                            "become ready", "not-ready")
        except ClientError as err:
            message = self.readiness() or {}
            waiting = [d for d, state in (message.get("domains") or {}).items() if not state.get("configured")]
            raise ClientError(f"{err} (consultants not configured: {', '.join(waiting) or 'none'})",
                              "not-ready") from None
        if pipeline:
            for kind in KIND_TOPICS:
                self.wait_matched(kind, max(0.0, deadline - time.monotonic()))
        return self.readiness() or {}

    def find_running(self, wait: float) -> Optional[str]:
        """Look for a graph in this client's namespace for up to ``wait`` s; describe it in one line (None: none).

        A graph is a node of a graph's name (:data:`GRAPH_NODES`, ``consultant_<domain>``)
        in the namespace, or a WM Manager's readiness there.
        """
        deadline = time.monotonic() + wait
        while True:
            found = sorted(f"{ns.rstrip('/')}/{name}" for name, ns in self.node.get_node_names_and_namespaces()
                           if ns == self.namespace and (name in GRAPH_NODES or name.startswith("consultant_")))
            if found or self.ready_messages:
                if not self.ready_messages:  # its WM Manager's latched readiness names its owner
                    try:
                        self.spin_until(lambda: self.ready_messages, CLASH_WAIT, "readiness")
                    except ClientError:
                        pass
                owners = "; ".join(f"graph {describe_graph(g)}, wm_manager pid {pid} on {host}"
                                   for g, pid, host in self._graphs())
                nodes = f"nodes {', '.join(found)}" if found else "a WM Manager"
                return f"{self.where()} already has a graph: {nodes}" + (f" ({owners})" if owners else "")
            if time.monotonic() >= deadline:
                return None
            self.executor.spin_once(timeout_sec=0.05)

    def domains(self) -> list[str]:
        """Return the names of the graph's domains, as its readiness lists them."""
        message = self.readiness()
        if message is None:
            raise ClientError(f"no fsreg graph answers in {self.where()}", "not-ready")
        return list(message["domains"])

    def wait_matched(self, kind: str, timeout: float) -> None:
        """Wait until the request topic of ``kind`` has its readers and the reply topic its writers."""
        needed = len(self.domains()) if kind == "assert" else 1
        pub, sub = self._publishers[kind], self._reply_subs[kind]
        request, reply = KIND_TOPICS[kind]

        def matched() -> bool:
            return pub.get_subscription_count() >= needed and sub.get_publisher_count() >= needed

        if matched():
            return
        self.spin_until(matched, timeout, f"{request.name} -> {reply.name} is not connected in {self.where()}",
                        "not-ready")
        # This side sees the other; the other side's discovery of this one usually completes within this
        # settle time.  Without it, a first request or answer was sometimes lost to the half-made match
        # and the request went out twice (the second copy answered from the node's cache).
        self.spin_for(MATCH_SETTLE)

    # ---------------------------------------------------------------- topics
    def new_id(self, kind: str) -> str:
        return f"{self._prefix}-{kind}-{next(self._ids)}"

    def send(self, kind: str, message: Mapping[str, Any]) -> str:
        """Publish one request of ``kind`` (say, describe, assert) now; return its id.

        Its answers collect in ``answers`` under that id.  ClientError ``busy`` when the
        message could not be sent: ``ltm/assert`` keeps every message until the consultants
        took it, and a sender about 10,000 messages ahead of them waits up to 100 ms, then
        is refused (backpressure: send it again later; nothing of it was delivered).
        """
        self.check_message(kind, message)
        key = str(message["id"])
        self.answers.setdefault(key, [])
        try:
            publish(self._publishers[kind], message)
        except _rclpy.RCLError as err:
            self.answers.pop(key, None)
            raise ClientError(f"{KIND_TOPICS[kind][0].name} {key!r} not sent (the receivers are too far behind): "
                              f"{printable(str(err).split(',')[0], 200)}", "busy") from None
        return key

    def check_message(self, kind: str, message: Mapping[str, Any]) -> None:
        """Raise ClientError ``usage`` if the graph would refuse ``message`` for its form or size (:attr:`limits`).

        The same check the nodes make (the request topic's schema, names, lists and the
        message's bytes within :class:`~fsreg_ros.contract.Limits`), made before sending,
        so an oversized request is refused at once instead of answered by silence.
        """
        topic = KIND_TOPICS[kind][0]
        size = len(safe_dumps(message).encode("utf-8"))
        if size > self.limits.max_message_bytes:
            raise ClientError(f"{topic.name}: the message is {size} bytes; the graph takes at most "
                              f"{self.limits.max_message_bytes} (max_message_bytes)", "usage")
        try:
            contract.check(topic.schema, dict(message), self.limits)
        except MessageError as err:
            raise ClientError(printable(f"{topic.name}: {err}", 300), "usage") from None

    def answer_of(self, key: str) -> Optional[dict]:
        """Return the first answer to request ``key`` (ClientError ``foreign`` if it came from another graph)."""
        heard = self.answers.get(key) or []
        if not heard:
            return None
        data = heard[0].data
        graph = data.get(contract.GRAPH_FIELD) or ""
        if self.graph is not None and graph != self.graph:
            raise ClientError(f"the answer to {key!r} came from another graph ({describe_graph(graph)}, expected "
                              f"{describe_graph(self.graph)}) in {self.where()}", "foreign")
        return data

    def exchange(self, kind: str, message: dict, timeout: Optional[float] = None) -> dict:
        """Send ``message`` (resent every ``retry_after`` s) and return its answer."""
        timeout = self.timeout if timeout is None else timeout
        request = KIND_TOPICS[kind][0].name
        self.wait_matched(kind, timeout)
        key = self.send(kind, message)
        deadline = time.monotonic() + timeout
        try:
            while True:
                try:
                    self.spin_until(lambda: self.answers[key], min(self.retry_after, deadline - time.monotonic()),
                                    "answer")
                    return self.answer_of(key) or {}
                except ClientError as err:
                    if err.kind != "timeout" or time.monotonic() >= deadline:
                        if err.kind == "timeout":
                            raise ClientError(f"no answer to {request} {key!r} within {timeout:g} s in "
                                              f"{self.where()}", "timeout") from None
                        raise
                publish(self._publishers[kind], message)
        finally:
            self.answers.pop(key, None)

    def _stamp(self, message: dict, time_: Optional[float]) -> dict:
        when = self.time if time_ is None else time_
        if when is not None:
            message["time"] = when
        return message

    def say(self, text: Optional[str] = None, *, description: Optional[Sequence[str]] = None,
            domain: Optional[str] = None, time: Optional[float] = None, turn: Optional[int] = None,
            timeout: Optional[float] = None) -> dict:
        """Say something to the robot (text, or a property list); return its ``rr/result``."""
        if (text is None) == (description is None):
            raise ClientError("say: give text or a description, not both", "usage")
        message: dict[str, Any] = {"id": self.new_id("say")}
        if text is not None:
            message["text"] = text
        else:
            message["description"] = list(description or ())
        if domain is not None:
            message["domain"] = domain
        if turn is not None:
            message["turn"] = turn
        return self.exchange("say", self._stamp(message, time), timeout)

    def describe(self, target: str, *, context: Optional[Sequence[str]] = None, time: Optional[float] = None,
                 turn: Optional[int] = None, timeout: Optional[float] = None) -> dict:
        """Ask the robot to describe ``target`` (against ``context`` if given); return its ``reg/expression``."""
        message: dict[str, Any] = {"id": self.new_id("describe"), "target": target}
        if context is not None:
            message["context"] = list(context)
        if turn is not None:
            message["turn"] = turn
        return self.exchange("describe", self._stamp(message, time), timeout)

    def assert_facts(self, entity: str | Mapping[str, Mapping[str, float] | Iterable[str]],
                     properties: Mapping[str, float] | Iterable[str] | None = None, *,
                     domain: Optional[str] = None, timeout: Optional[float] = None) -> dict:
        """Tell the consultant of ``domain`` facts about ``entity`` (property -> certainty); its ``ltm/assert/result``.

        ``properties`` may be a list (each certain, 1.0).  Without ``domain``: the
        graph's only domain, or the one whose consultant knows ``entity``.  A batch: a
        mapping entity -> properties as ``entity`` (no ``properties``), sent as one
        message (``facts``) and applied in one commit; its result lists each fact's in
        ``results``, in order (docs/semantics.md, "Facts in batches").
        """
        if domain is not None and domain not in self.domains():
            raise ClientError(f"the graph has no domain {printable(repr(domain), 80)} (its domains: "
                              f"{', '.join(self.domains())})", "usage")
        if isinstance(entity, Mapping):
            if properties is not None:
                raise ClientError("assert_facts: give a batch (entity -> properties) or an entity and its "
                                  "properties, not both", "usage")
            if not entity:
                raise ClientError("assert_facts: an empty batch", "usage")
            batch = [{"entity": name, "properties": _facts(props)} for name, props in entity.items()]
            if domain is None:
                domains = {self.domain_of(name, new_ok=True) for name in entity}
                if len(domains) > 1:
                    raise ClientError(f"assert_facts: a batch is for one domain; its entities are in "
                                      f"{', '.join(sorted(domains))} (name the domain)", "usage")
                domain = domains.pop()
            message: dict[str, Any] = {"id": self.new_id("assert"), "domain": domain, "facts": batch}
        else:
            if properties is None:
                raise ClientError(f"assert_facts: no properties for {entity!r}", "usage")
            domain = domain or self.domain_of(entity, new_ok=True)
            message = {"id": self.new_id("assert"), "domain": domain, "entity": entity,
                       "properties": _facts(properties)}
        answer = self.exchange("assert", message, timeout)
        self._entities.pop(domain, None)
        return answer

    # -------------------------------------------------------------- services
    def service(self, name: str) -> ServiceCaller:
        if name not in self._services:
            self._services[name] = ServiceCaller(self.node, name)
        return self._services[name]

    def call(self, name: str, payload: Mapping[str, Any], timeout: Optional[float] = None) -> dict:
        """Call one of the graph's JSON services; its reply (ClientError with the service's error kind).

        Every service the client calls is idempotent (status, sync, a consultant's
        queries), so a call that times out is sent again within ``timeout``: a first
        request to a server just discovered can be lost.
        """
        timeout = self.timeout if timeout is None else timeout
        client = self.service(name)
        self.spin_until(client.ready, timeout, f"service {self.node.resolve_service_name(name)} is not available",
                        "not-ready")
        try:
            return self.run(client.wait_ready(payload, timeout), timeout + 1.0, f"service {name}")
        except CarrierError as err:
            raise ClientError(printable(str(err)), err.kind) from None

    def status(self, timeout: Optional[float] = None) -> dict:
        """Return the WM Manager's ``wm_manager/status`` (``ready``, ``memory``, ``running``, ...)."""
        reply = self.call(contract.STATUS.name, {}, timeout)
        graph = reply.get("graph") or ""
        if self.graph is not None and graph != self.graph:
            raise ClientError(f"{contract.STATUS.name} answered by another graph ({describe_graph(graph)}, expected "
                              f"{describe_graph(self.graph)}) in {self.where()}", "foreign")
        return reply

    def reset_state(self, domain: str, timeout: Optional[float] = None) -> dict:
        """Ask ``domain``'s consultant to set its state aside and start from its KB again (manage op ``reset``).

        Sent once (not idempotent: never resent); its reply (``incarnation``, ``moved_aside``,
        ``cleared``, ``state``) or ClientError.  The consultant then serves as a new
        incarnation, ready once the WM Manager configured it (:meth:`wait_ready`).
        """
        timeout = self.timeout if timeout is None else timeout
        name = contract.manage_service(domain)
        client = self.service(name)
        self.spin_until(client.ready, timeout, f"service {self.node.resolve_service_name(name)} is not available",
                        "not-ready")
        future = client.send({"op": "reset", "client": self.node.get_fully_qualified_name()})
        try:
            return self.run(client.result(future, timeout), timeout + 1.0, f"service {name}")
        except CarrierError as err:
            raise ClientError(printable(str(err)), err.kind) from None

    def sync(self, t: float, timeout: Optional[float] = None) -> dict:
        """Call the WM Manager's barrier: every decay tick due at or before ``t`` applied (docs/design.md)."""
        return self.call(contract.SYNC.name, {"time": t}, timeout)

    def publish_clock(self, t: float) -> None:
        """Publish the graph's clock = ``t`` (nothing waits: see :meth:`set_clock`)."""
        self._clock.publish(clock_message(t))

    def set_clock(self, t: float, timeout: Optional[float] = None, *, confirm: bool = False) -> dict:
        """Publish the graph's clock = ``t`` and wait until the forgetting due by then is applied; the sync reply.

        ``t`` must be a finite number of seconds in [0, 1e12] (ClientError ``usage``).
        The clock is published once the graph's nodes subscribe it (a message published
        before that is lost).  With ``confirm``: refused (ClientError ``refused``) when no
        node follows the clock topic (a wall-clock graph) or ``t`` is earlier than the
        graph's clock (a clock does not go back), and the call returns only when the WM
        Manager's clock reads ``t`` or later (the clock is sent again until it does), so a
        request sent afterwards is stamped ``t`` or later.  Later requests from this
        client are stamped with ``t``.
        """
        timeout = self.timeout if timeout is None else timeout
        t = check_clock(t)
        deadline = time.monotonic() + timeout
        expected = len(GRAPH_NODES) - 1 + len(self.domains()) if self.readiness() is not None else 1
        try:
            self.spin_until(lambda: self._clock.get_subscription_count() >= expected,
                            min(CLOCK_DISCOVERY, timeout), "clock subscribers")
        except ClientError:
            if confirm and self._clock.get_subscription_count() == 0:
                raise ClientError(f"clock {t:g} s refused: no node of the graph follows "
                                  f"{self.node.resolve_topic_name(contract.CLOCK)} (it runs on wall-clock time, or "
                                  "follows another clock topic: --clock)", "refused") from None
        if confirm:
            now = float(self.status(timeout)["time"])
            if t < now - 1e-9:
                raise ClientError(f"clock {t:g} s refused: the graph's clock is at {now:g} s and does not go back "
                                  "(forgetting already applied is never undone)", "refused")
        self.publish_clock(t)
        reply = self.sync(t, max(0.0, deadline - time.monotonic()))
        if confirm:
            def reached() -> bool:
                if float(self.status(max(0.0, deadline - time.monotonic()))["time"]) >= t - 1e-9:
                    return True
                self.publish_clock(t)  # /clock is best effort for the nodes' time sources: send it again
                self.spin_for(CLOCK_RESEND)
                return False

            self.spin_until(reached, max(0.0, deadline - time.monotonic()),
                            f"the graph's clock at {t:g} s (does it follow "
                            f"{self.node.resolve_topic_name(contract.CLOCK)}?)", "refused")
        self.time = t
        return reply

    def graph_time(self, timeout: Optional[float] = None) -> float:
        """Return the graph's clock (its WM Manager's, from ``wm_manager/status``), seconds."""
        return float(self.status(timeout)["time"])

    def domain_of(self, entity: str, new_ok: bool = False) -> str:
        """Return the domain whose consultant knows ``entity`` (or the only domain, for a new one if ``new_ok``)."""
        domains = self.domains()
        for domain in domains:
            if domain not in self._entities:
                info = self.call(contract.consultant_service(domain), {"op": "info"})
                self._entities[domain] = set(info.get("entities") or ())
            if entity in self._entities[domain]:
                return domain
        if new_ok and len(domains) == 1:
            return domains[0]
        raise ClientError(f"no consultant knows entity {entity!r} (domains: {', '.join(domains)})"
                          + ("; name the domain of a new entity" if new_ok else ""), "usage")

    def wm(self, entity: str, domain: Optional[str] = None) -> list[str]:
        """Return ``entity``'s working memory now, least recently used first (reading never refreshes it).

        Asks the consultant's debug service (served when its ``debug`` parameter is true,
        as :mod:`fsreg_ros.testing` starts it); :meth:`state` needs no debug service.
        """
        domain = domain or self.domain_of(entity)
        return list(self.call(contract.debug_service(domain), {"op": "wm", "entity": entity})["queue"])

    def snapshot(self, domain: str) -> dict[str, list[str]]:
        """Return every non-empty WM queue of ``domain`` now (the debug service, as :meth:`wm`)."""
        return dict(self.call(contract.debug_service(domain), {"op": "snapshot"})["queues"])

    def state(self, domain: str, timeout: Optional[float] = None, current: bool = False) -> dict:
        """Return ``domain``'s latest ``wm/state`` (latched: its non-empty queues as last published).

        A consultant publishes it after each request that changed WM, at most every
        ``state_period`` (0.1 s by default), so it may lag a change by that much.
        ``current``: first ask the consultant (``info``) how many of its calls changed
        WM, and wait for the state that shows them all (what ``fsreg-ctl wm`` prints).
        """
        if self._states is None:
            self._states = {}
            subscribe(self.node, contract.WM_STATE, self._on_state)
        wait = self.timeout if timeout is None else timeout
        if not current:
            self.spin_until(lambda: domain in self._states, wait,
                            f"no {contract.WM_STATE.name} of domain {domain!r} in {self.where()}", "not-ready")
            return self._states[domain]
        info = self.call(contract.consultant_service(domain), {"op": "info"}, timeout)
        wanted = (contract.version_incarnation(info["version"]), info["wm_version"])

        def caught_up() -> bool:
            state = self._states.get(domain)
            return state is not None and state_version(state) >= wanted

        self.spin_until(caught_up, wait, f"no {contract.WM_STATE.name} of domain {domain!r} as of "
                        f"incarnation {wanted[0]}, WM change {wanted[1]} in {self.where()}", "not-ready")
        return self._states[domain]

    def _on_state(self, data: dict) -> None:
        graph = data.get(contract.GRAPH_FIELD) or ""
        if self.graph is not None and graph != self.graph:
            if self._state_watcher is not None:
                self.foreign = self._foreign(graph)
            return
        self._states[data["domain"]] = data
        if self._state_watcher is not None:
            self._state_watcher(data)

    def _foreign(self, graph: str) -> str:
        return (f"a message from another graph ({describe_graph(graph)}, expected "
                f"{describe_graph(self.graph)}) in {self.where()}")

    # ------------------------------------------------------------ parameters
    def _param_client(self, node_name: str, srv_type, suffix: str):
        key = (node_name, suffix)
        if key not in self._param_clients:
            self._param_clients[key] = self.node.create_client(srv_type, f"{node_name}/{suffix}")
        return self._param_clients[key]

    def _service_call(self, client, request, timeout: float, what: str):
        """Call a parameter service (idempotent: sent again after 2, 4, ... s without a reply, until ``timeout``)."""
        self.spin_until(client.service_is_ready, timeout, f"{what}: service {client.srv_name} is not available",
                        "not-ready")
        deadline, attempt = time.monotonic() + timeout, 2.0
        while True:
            future = client.call_async(request)
            try:
                self.spin_until(future.done, min(attempt, max(0.0, deadline - time.monotonic())), what)
                return future.result()
            except ClientError:
                client.remove_pending_request(future)
                if time.monotonic() >= deadline:
                    raise
                attempt *= 2

    def graph_nodes(self) -> list[str]:
        """Return the names of the graph's nodes seen in this client's namespace (discovery; may lag)."""
        return sorted(name for name, ns in self.node.get_node_names_and_namespaces()
                      if ns == self.namespace and (name in GRAPH_NODES or name.startswith("consultant_")))

    def node_names(self) -> list[str]:
        """Return the names of the graph's nodes, from its readiness (its domains' consultants and the rest)."""
        return sorted([*GRAPH_NODES[:-1], *(f"consultant_{d}" for d in self.domains())])

    def require_node(self, node_name: str, timeout: Optional[float] = None) -> None:
        """Raise ClientError unless ``node_name`` is a node of the graph whose parameter services answer.

        ``usage`` at once for a name the graph does not have (:meth:`node_names`);
        ``not-ready`` if its parameter services are not found within ``timeout``.
        """
        if node_name not in self.node_names():
            raise ClientError(f"no node {printable(repr(node_name), 80)} in graph {describe_graph(self.graph)} (its "
                              f"nodes: {', '.join(self.node_names())})", "usage")
        client = self._param_client(node_name, ListParameters, "list_parameters")
        self.spin_until(client.service_is_ready, self.timeout if timeout is None else timeout,
                        f"{node_name}: service {client.srv_name} is not available", "not-ready")

    def list_parameters(self, node_name: str, timeout: Optional[float] = None) -> list[str]:
        """Return the names of node ``node_name``'s parameters, sorted."""
        timeout = self.timeout if timeout is None else timeout
        client = self._param_client(node_name, ListParameters, "list_parameters")
        reply = self._service_call(client, ListParameters.Request(), timeout, f"{node_name}: list parameters")
        return sorted(reply.result.names)

    def describe_parameters(self, node_name: str, names: Sequence[str], timeout: Optional[float] = None) -> dict:
        """Return node ``node_name``'s descriptors of ``names`` (rcl_interfaces ParameterDescriptor), by name."""
        timeout = self.timeout if timeout is None else timeout
        client = self._param_client(node_name, DescribeParameters, "describe_parameters")
        reply = self._service_call(client, DescribeParameters.Request(names=list(names)), timeout,
                                   f"{node_name}: describe parameters")
        return dict(zip(names, reply.descriptors))

    def get_parameters(self, node_name: str, names: Optional[Sequence[str]] = None,
                       timeout: Optional[float] = None) -> dict[str, Any]:
        """Return node ``node_name``'s parameter values (all of them without ``names``), as Python values."""
        timeout = self.timeout if timeout is None else timeout
        names = self.list_parameters(node_name, timeout) if names is None else list(names)
        client = self._param_client(node_name, GetParameters, "get_parameters")
        reply = self._service_call(client, GetParameters.Request(names=names), timeout,
                                   f"{node_name}: get parameters")
        return {name: python_value(value) for name, value in zip(names, reply.values)}

    def set_parameters(self, node_name: str, values: Mapping[str, Any], timeout: Optional[float] = None) -> dict:
        """Set parameters of node ``node_name`` (e.g. ``wm_manager``) all at once, or none; the values now in force.

        Checked before anything is sent, each error naming the node, the key and what is
        allowed (ClientError ``usage``): a node or parameter the graph does not have, a
        read-only parameter, a value of the wrong type or outside the declared range
        (converted from text to the declared type first), and for the WM Manager the
        memory settings as the whole effective policy of every domain.  A change the
        node refuses raises ``rejected`` with its reason.  The values returned are read
        back from the node after the change.
        """
        from . import node_parameters
        from .memory_parameters import effective_policies, parameter_names

        timeout = self.timeout if timeout is None else timeout
        self.require_node(node_name, timeout)
        known = self.list_parameters(node_name, timeout)
        names = list(values)
        for name in names:
            if name not in known:
                close = difflib.get_close_matches(name, known, n=1)
                hint = f"did you mean {close[0]}?" if close else f"its parameters: {', '.join(known)}"
                raise ClientError(f"{node_name}: no parameter {printable(repr(name), 80)} ({hint})", "usage")
        described = self.describe_parameters(node_name, names, timeout)
        messages, typed = [], {}
        for name in names:
            desc = described[name]
            if desc.read_only:
                raise ClientError(f"{node_name}: {name} is read-only (set when the node starts: "
                                  "fsreg-up --params-file)", "usage")
            value = parameter_value(f"{node_name}: {name}", values[name], desc.type)
            typed[name] = python_value(value)
            problem = range_problem(desc, typed[name])
            if problem:
                raise ClientError(f"{node_name}: {name}: {problem}", "usage")
            messages.append(ParameterMsg(name=name, value=value))
        executable = "consultant" if node_name.startswith("consultant_") else node_name
        catalogue = node_parameters.node_parameters(executable, self.domains())
        for name in names:  # the node's own checks (choices, the settings table), as data
            if name in catalogue:
                try:
                    node_parameters.check_parameter(catalogue[name], typed[name])
                except node_parameters.ParameterError as err:
                    raise ClientError(f"{node_name}: {name}: {err}", "usage") from None
        if node_name == "wm_manager" and any(n in parameter_names(self.domains()) for n in names):
            current = self.get_parameters(node_name, parameter_names(self.domains()), timeout)
            try:
                effective_policies({**current, **typed}, self.domains())
            except ValueError as err:
                raise ClientError(f"{node_name}: {printable(str(err), 300)}", "usage") from None
        setter = self._param_client(node_name, SetParametersAtomically, "set_parameters_atomically")
        result = self._service_call(setter, SetParametersAtomically.Request(parameters=messages), timeout,
                                    f"{node_name}: set parameters").result
        if not result.successful:
            raise ClientError(f"{node_name} refused {', '.join(names)}: {result.reason or 'no reason given'}",
                              "rejected")
        return self.get_parameters(node_name, names, timeout)

    # ---------------------------------------------------------------- watching
    def watch(self, on_state: Callable[[dict], None], on_event: Optional[Callable[[dict], None]] = None) -> list:
        """Pass every ``wm/state`` and (with ``on_event``) ``wm/events`` message of this graph on.

        Each domain's current state comes first (:meth:`state` with ``current``), then
        each newer one as it is published (an older latched copy is not passed on); the
        states come through :meth:`state`'s subscription.  Returns the subscriptions made
        (``wm/events``'s, if ``on_event`` is given).

        A message stamped by another graph raises ClientError ``foreign`` out of the spin.
        """
        shown: dict[str, tuple[int, int]] = {}

        def newer(state: dict) -> None:
            version = state_version(state)
            if version > shown.get(state["domain"], (-1, -1)):
                shown[state["domain"]] = version
                on_state(state)

        for domain in self.domains():
            newer(self.state(domain, current=True))
        self.foreign = None
        self._state_watcher = newer  # wm/state keeps coming through state()'s subscription
        if on_event is None:
            return []

        def checked_event(data: dict) -> None:
            graph = data.get(contract.GRAPH_FIELD) or ""
            if self.graph is not None and graph != self.graph:
                self.foreign = self._foreign(graph)
                return
            on_event(data)

        return [subscribe(self.node, contract.WM_EVENTS, checked_event)]


def check_clock(t: Any) -> float:
    """Return ``t`` if a graph can take it as its clock (finite seconds in [0, 1e12]); else ClientError ``usage``."""
    try:
        value = float(t)
    except (TypeError, ValueError, OverflowError):
        raise ClientError(f"clock: expected a number of seconds, got {printable(repr(t), 60)}", "usage") from None
    if isinstance(t, bool) or not value == value or abs(value) == float("inf"):
        raise ClientError(f"clock: expected a finite number of seconds, got {printable(repr(t), 60)}", "usage")
    if not 0.0 <= value <= MAX_TIME:
        raise ClientError(f"clock: {value:g} s is out of range: a clock is in [0, {MAX_TIME:g}] s", "usage")
    return value


def state_version(state: Mapping[str, Any]) -> tuple[int, int]:
    """Return which state a ``wm/state`` message shows: ``(incarnation, wm_version)``, later compares greater."""
    return state["incarnation"], state["wm_version"]


def parameter_value(name: str, value: Any, kind: int) -> ParameterValue:
    """Return ``value`` (text from a command line, or a Python value) as a ParameterValue of type ``kind``."""
    out = ParameterValue(type=kind)
    text = value if isinstance(value, str) else None
    try:
        if kind == ParameterType.PARAMETER_BOOL:
            if text is not None:
                lowered = text.strip().lower()
                if lowered not in ("true", "false"):
                    raise ValueError
                value = lowered == "true"
            if not isinstance(value, bool):
                raise ValueError
            out.bool_value = value
        elif kind == ParameterType.PARAMETER_INTEGER:
            number = int(text.strip()) if text is not None else value
            if isinstance(number, bool) or not isinstance(number, int) or not -2**63 <= number < 2**63:
                raise ValueError
            out.integer_value = number
        elif kind == ParameterType.PARAMETER_DOUBLE:
            number = float(text.strip()) if text is not None else float(value)
            if isinstance(value, bool) or number != number or number in (float("inf"), float("-inf")):
                raise ValueError
            out.double_value = number
        elif kind == ParameterType.PARAMETER_STRING:
            if not isinstance(value, str):
                raise ValueError
            out.string_value = value
        elif kind == ParameterType.PARAMETER_STRING_ARRAY:
            items = [v.strip() for v in text.strip().strip("[]").split(",") if v.strip()] if text is not None \
                else list(value)
            out.string_array_value = [str(v) for v in items]
        else:
            raise ClientError(f"{name}: a parameter of a type this client does not set ({kind})", "usage")
    except (ValueError, TypeError, AttributeError):
        expected = {ParameterType.PARAMETER_BOOL: "true or false", ParameterType.PARAMETER_INTEGER: "a whole number",
                    ParameterType.PARAMETER_DOUBLE: "a finite number", ParameterType.PARAMETER_STRING: "text"}
        raise ClientError(f"{name}: expected {expected.get(kind, 'a value of its type')}, got "
                          f"{printable(repr(value), 60)}", "usage") from None
    return out


def python_value(value: ParameterValue) -> Any:
    """Return a ParameterValue as a Python value (None when not set)."""
    kind = value.type
    if kind == ParameterType.PARAMETER_BOOL:
        return bool(value.bool_value)
    if kind == ParameterType.PARAMETER_INTEGER:
        return int(value.integer_value)
    if kind == ParameterType.PARAMETER_DOUBLE:
        return float(value.double_value)
    if kind == ParameterType.PARAMETER_STRING:
        return str(value.string_value)
    arrays = {ParameterType.PARAMETER_BYTE_ARRAY: "byte_array_value", ParameterType.PARAMETER_BOOL_ARRAY:
              "bool_array_value", ParameterType.PARAMETER_INTEGER_ARRAY: "integer_array_value",
              ParameterType.PARAMETER_DOUBLE_ARRAY: "double_array_value",
              ParameterType.PARAMETER_STRING_ARRAY: "string_array_value"}
    if kind in arrays:
        return [v.item() if hasattr(v, "item") else v for v in getattr(value, arrays[kind])]
    return None


def range_problem(desc, value: Any) -> Optional[str]:
    """Return what is wrong with a number outside a descriptor's declared range (None: in range, or no range)."""
    ranges = list(desc.integer_range) or list(desc.floating_point_range)
    if not ranges or isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    low, high = sorted((ranges[0].from_value, ranges[0].to_value))
    if low <= value <= high:
        return None
    kind = "a whole number" if desc.integer_range else "a number"
    return f"expected {kind} in [{low:g}, {high:g}], got {value!r}"


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
