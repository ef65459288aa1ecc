"""Wire fuzzing: what no schema can save, sent to every endpoint the contract declares.

The part of the graph fuzzer (``fuzzgraph``: per-endpoint templates and mutations) that
needs no template: every topic of ``contract.TOPICS`` and every service of
``contract.SERVICES`` (``<domain>`` filled in for each domain), so a new endpoint is
fuzzed as soon as the contract declares it, each sent every :data:`ENVELOPES` input:
nesting 5,000 deep, the oversized message of issue 38.1 (76 kB, its ``id`` nested 3,000
deep), an oversized message with a readable id, a 1 MB string, bytes that are not UTF-8
(topics only: rclpy cannot send them in a service request), a 5,000-digit number, a lone
surrogate, ``NaN``, a top-level array nested 3,000 deep, an empty text.

The checks (:class:`WireFuzz`): every service answers every input with a refusal that
is not ``kind: internal`` (an internal error is a bug); every topic answered by
contract (``Topic.answered_on``) answers each with such a refusal, seen before the
reply to a marker sent after it; a topic with no answer is sent its inputs and the
writer waits until every reader acknowledged them (they sit in the readers' queues,
ahead of the check's requests); then every node answers a real request
(:meth:`WireFuzz.real_requests`: each consultant ``info``, the WM Manager's ``status``,
an utterance through the parser and RR, a REG request).  In one process a callback that
raises stops the executor's spin (recorded as a crash); with node processes the test also
asks that none exited.  Works on any :class:`~fsreg_ros.testing.RosSession` whose probe is
in the graph's namespace (the names used are the contract's relative ones) and whose probe
listens on no topic through ``RosSession.listen`` (its listener decodes whatever comes,
the inputs sent on the answer topics too): give it a graph of its own.
"""

from __future__ import annotations

import itertools
import struct
import time
from dataclasses import dataclass, field
from typing import Callable, Optional, Union

from diagnostic_msgs.srv import AddDiagnostics
from rclpy.duration import Duration
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from fsreg_ros import contract
from fsreg_ros.contract.codec import MessageError, dumps, parse
from fsreg_ros.ros.carrier import CarrierError, qos_profile
from fsreg_ros.testing.ros_session import Inbox, RosSession, Timeout

TIME = 1.0  # the sim time of the real requests (the graph must stand at it)
REPLY_TIMEOUT = 10.0
#: The id prefix of the markers sent until an endpoint's answers are heard (:meth:`WireFuzz._hears_the_answers`).
HELLO = "fz-wire-hello-"
DEEP = 5_000
#: The message of issue 38.1 (it killed the consultant and the WM Manager through the oversized path).
ISSUE_38 = '{"id":' + "[" * 3000 + "]" * 3000 + ',"pad":"' + "x" * 70_000 + '"}'


@dataclass(frozen=True)
class Envelope:
    """One input: a name and its text (``bytes``: the raw UTF-8 payload of a ``String``) for a request id."""

    name: str
    make: Callable[[str], Union[str, bytes]]
    keeps_id: bool = False  # its refusal must name its id (read off the head of an oversized message too)


ENVELOPES = (
    Envelope("nested 5000 deep", lambda rid: '{"id": "%s", "a": %s%s}' % (rid, "[" * DEEP, "]" * DEEP)),
    Envelope("issue 38.1: 76 kB, id nested 3000 deep", lambda rid: ISSUE_38),
    Envelope("76 kB with a readable id", lambda rid: '{"id": "%s", "pad": "%s"}' % (rid, "x" * 76_000), True),
    Envelope("1 MB string", lambda rid: '{"id": "%s", "x": "%s"}' % (rid, "y" * 1_000_000), True),
    Envelope("not UTF-8", lambda rid: b'{"id": "%s", "x": "\xff\xfe\xed\xa0\x80\xc0"}' % rid.encode(), True),
    Envelope("a 5000-digit number", lambda rid: '{"id": "%s", "x": %s}' % (rid, "9" * 5000)),
    Envelope("lone surrogate", lambda rid: '{"id": "%s", "x": "\\ud800"}' % rid),
    Envelope("NaN", lambda rid: '{"id": "%s", "x": NaN}' % rid),
    Envelope("array nested 3000 deep", lambda rid: "[" * 3000 + "]" * 3000),
    Envelope("empty", lambda rid: ""),
)


@dataclass(frozen=True)
class Endpoint:
    """One endpoint of one graph: relative name, and its contract entry (a Topic or a Service)."""

    name: str
    entry: Union[contract.Topic, contract.Service]

    @property
    def is_service(self) -> bool:
        return isinstance(self.entry, contract.Service)


def endpoints(domains: list[str]) -> list[Endpoint]:
    """Every topic and service the contract declares, ``<domain>`` filled in for each domain."""
    out = []
    for entry in (*contract.TOPICS, *contract.SERVICES):
        names = [entry.name.replace("<domain>", d) for d in domains] if "<domain>" in entry.name else [entry.name]
        out += [Endpoint(name, entry) for name in names]
    return out


@dataclass
class Tally:
    """What one endpoint did with the envelopes: counts, and one line per failure."""

    sent: int = 0
    refused: int = 0  # answered with a refusal (services, and topics answered by contract)
    taken: int = 0  # acknowledged by every reader (topics with no answer by contract)
    unsendable: int = 0
    failures: list[str] = field(default_factory=list)

    def line(self, name: str) -> str:
        return (f"{name}: {self.sent} sent, {self.refused} refused, {self.taken} taken without an answer "
                f"(none by contract), {self.unsendable} not sendable, {len(self.failures)} failures")


def _serialized(payload: bytes) -> bytes:
    """Return the CDR of a ``std_msgs/String`` whose data are ``payload`` (any bytes, UTF-8 or not)."""
    header = serialize_message(String(data=""))[:4]  # the encapsulation header
    return header + struct.pack("<I", len(payload) + 1) + payload + b"\x00"


class WireFuzz:
    """Sends every envelope to every endpoint of the graph ``session`` talks to; checks and counts."""

    def __init__(self, session: RosSession, domains: list[str]) -> None:
        self.g = session
        self.domains = domains
        self.tallies: dict[str, Tally] = {}
        self.crashes: list[str] = []
        self._ids = itertools.count()
        self.inboxes = {t.answered_on: self._listen(t.answered_on, t.qos)
                        for t in contract.TOPICS if t.answered_on is not None}

    def _listen(self, topic: str, qos) -> Inbox:
        """Collect the JSON objects on ``topic`` (the fuzz's own inputs there, which are not, left out).

        Returns once the reader has matched every writer the graph shows on it (an answer
        to a reader not yet matched is lost: the topic is volatile).
        """
        inbox = Inbox()

        def heard(msg: String) -> None:
            try:
                inbox.append(parse(msg.data))
            except MessageError:
                pass  # an input this fuzz sent on the reply topic itself
        sub = self.g.probe.create_subscription(String, topic, heard, qos_profile(qos))
        self.g.spin_until(lambda: sub.get_publisher_count() >= max(1, self.g.probe.count_publishers(topic)),
                          REPLY_TIMEOUT, what=f"the writers of {topic}")
        return inbox

    # --------------------------------------------------------------- sending
    def run(self, only: Optional[list[str]] = None) -> None:
        """Send every envelope to every endpoint (or those named in ``only``)."""
        for endpoint in endpoints(self.domains):
            if only is None or endpoint.name in only:
                tally = self.tallies.setdefault(endpoint.name, Tally())
                try:
                    (self._services if endpoint.is_service else self._topic)(endpoint, tally)
                except Exception as err:  # noqa: BLE001 - a callback raised out of the spin: a node died
                    self.crashes.append(f"{endpoint.name}: {type(err).__name__}: {str(err)[:200]}")

    def _services(self, endpoint: Endpoint, tally: Tally) -> None:
        self.g.wait_service(endpoint.name, REPLY_TIMEOUT)
        client = self.g.client(endpoint.name)
        for envelope in ENVELOPES:
            rid = f"fz-wire-{next(self._ids)}"
            text = envelope.make(rid)
            if isinstance(text, bytes):
                tally.unsendable += 1
                continue
            tally.sent += 1
            future = client.client.call_async(AddDiagnostics.Request(load_namespace=text))
            try:
                reply = self.g.run(client.result(future, REPLY_TIMEOUT), REPLY_TIMEOUT + 1.0)
            except CarrierError as err:
                self._judge(tally, envelope, rid, err.kind, str(err), err.kind == "timeout", err.reply)
            else:
                tally.failures.append(f"{envelope.name}: accepted, {str(reply)[:100]}")

    def _topic(self, endpoint: Endpoint, tally: Tally) -> None:
        topic: contract.Topic = endpoint.entry
        pub = self.g.probe.create_publisher(String, endpoint.name, qos_profile(topic.qos))
        try:
            self.g.spin_until(lambda: pub.get_subscription_count() >= self.g.probe.count_subscribers(endpoint.name),
                              REPLY_TIMEOUT, what=f"the readers of {endpoint.name}")
            if topic.answered_on is not None:
                self._hears_the_answers(endpoint, pub)
            for envelope in ENVELOPES:
                rid = f"fz-wire-{next(self._ids)}"
                text = envelope.make(rid)
                tally.sent += 1
                inbox = self.inboxes.get(topic.answered_on)
                before = len(inbox) if inbox is not None else 0
                pub.publish(_serialized(text) if isinstance(text, bytes) else String(data=text))
                if inbox is not None:
                    self._answered(endpoint, pub, inbox, before, envelope, rid, tally)
            if topic.answered_on is None:
                if pub.wait_for_all_acked(Duration(seconds=REPLY_TIMEOUT)):
                    tally.taken += len(ENVELOPES)
                else:
                    tally.failures.append("not every reader took the inputs (unacknowledged)")
        finally:
            self.g.probe.destroy_publisher(pub)  # a latched topic keeps no junk for later readers

    def _hears_the_answers(self, endpoint: Endpoint, pub) -> None:
        """Send a marker again (every second) until its answer arrives: the answering writer matched this reader.

        A reader's own match count says only that it sees the writer; the writer may not yet see
        the reader, and a volatile answer published before it does is lost.  A marker is refused
        by the endpoint (it carries no request) and changes nothing.
        """
        inbox = self.inboxes[endpoint.entry.answered_on]
        hello = f"{HELLO}{next(self._ids)}"
        message = {"id": hello, **({"domain": self.domains[0]} if endpoint.entry is contract.LTM_ASSERT else {})}
        deadline = time.monotonic() + REPLY_TIMEOUT
        while not any(r.get("id") == hello for r in inbox):
            if time.monotonic() > deadline:
                raise Timeout(f"timed out after {REPLY_TIMEOUT} s waiting for the answer to {hello} on "
                              f"{endpoint.entry.answered_on}")
            pub.publish(String(data=dumps(message)))
            try:
                self.g.spin_until(lambda: any(r.get("id") == hello for r in inbox), 1.0, what=hello)
            except Timeout:
                pass

    def _answered(self, endpoint: Endpoint, pub, inbox, before: int, envelope: Envelope, rid: str,
                  tally: Tally) -> None:
        """Send a marker after the input; the replies before the marker's are the input's."""
        marker = f"fz-wire-marker-{next(self._ids)}"
        message = {"id": marker, **({"domain": self.domains[0]} if endpoint.entry is contract.LTM_ASSERT else {})}
        pub.publish(String(data=dumps(message)))
        try:
            self.g.spin_until(lambda: any(r.get("id") == marker for r in inbox[before:]), REPLY_TIMEOUT,
                              what=f"the reply to {marker} on {endpoint.entry.answered_on}")
        except Timeout as err:
            tally.failures.append(f"{envelope.name}: {err}")
            return
        replies = [r for r in itertools.takewhile(lambda r: r.get("id") != marker, inbox[before:])
                   if not str(r.get("id")).startswith(HELLO)]  # a late answer to _hears_the_answers
        if not replies:
            tally.failures.append(f"{envelope.name}: unanswered (the marker after it was answered)")
        for reply in replies:
            self._judge(tally, envelope, rid, reply.get("kind"), str(reply.get("error") or ""), False, reply)

    def _judge(self, tally: Tally, envelope: Envelope, rid: str, kind, error: str, timed_out: bool,
               reply: Optional[dict]) -> None:
        if timed_out:
            tally.failures.append(f"{envelope.name}: unanswered ({error[:100]})")
        elif not error.strip():
            tally.failures.append(f"{envelope.name}: not refused: {str(reply)[:100]}")
        elif kind == "internal":
            tally.failures.append(f"{envelope.name}: refused as an internal error: {error[:160]}")
        elif envelope.keeps_id and (reply or {}).get("id") != rid:
            tally.failures.append(f"{envelope.name}: refused without its id {rid!r}: {str(reply)[:120]}")
        else:
            tally.refused += 1

    # --------------------------------------------------------------- liveness
    def real_requests(self, entity: str, prop: str) -> list[str]:
        """Ask every node of the graph a real request; return what did not answer (empty: all did)."""
        failed = []
        checks = [*((contract.consultant_service(d), {"op": "info"}) for d in self.domains),
                  (contract.STATUS.name, {})]
        for service, payload in checks:
            try:
                self.g.call(service, payload, timeout=REPLY_TIMEOUT)
            except Exception as err:  # noqa: BLE001 - a dead or broken node: reported
                failed.append(f"{service}: {type(err).__name__}: {str(err)[:160]}")
        asks = [(contract.HUMAN, {"description": [prop], "time": TIME}),
                (contract.SEMANTICS, {"description": [prop], "time": TIME}),
                (contract.REG_REQUEST, {"target": entity, "time": TIME})]
        for topic, payload in asks:
            rid = f"fz-wire-real-{next(self._ids)}"
            inbox = self.inboxes[topic.answered_on]
            try:
                self.g.publish(topic.name, {**payload, "id": rid}, topic.qos)
                self.g.spin_until(lambda: inbox.latest(id=rid) is not None, REPLY_TIMEOUT,
                                  what=f"the answer to {rid} on {topic.answered_on}")
                answer = inbox.latest(id=rid)
                if answer.get("error"):
                    failed.append(f"{topic.name}: answered with an error: {answer['error'][:160]}")
            except Exception as err:  # noqa: BLE001
                failed.append(f"{topic.name}: {type(err).__name__}: {str(err)[:160]}")
        return failed

    def report(self) -> str:
        lines = [tally.line(name) for name, tally in self.tallies.items()]
        lines += [f"    {f}" for tally in self.tallies.values() for f in tally.failures]
        lines += [f"crash: {c}" for c in self.crashes]
        return "\n".join(lines)

    def failures(self) -> list[str]:
        return [*(f"{n}: {f}" for n, t in self.tallies.items() for f in t.failures), *self.crashes]
