"""The dialogue exchange of a client with its graph (:class:`DialogueExchange`, a part of ``GraphClient``).

Requests on topics: ``say`` (``dialogue/human`` -> ``rr/result``), ``describe``
(``reg/request`` -> ``reg/expression``), ``assert_facts`` (``ltm/assert`` ->
``ltm/assert/result``), each with a fresh id, checked against the graph's size limits
before it is sent, resent every ``retry_after`` seconds until answered (RR, REG and the
consultants answer a repeated id once); an answer stamped by another graph is
rejected (kind ``foreign``) instead of counted.  The pipeline is waited for
(:meth:`DialogueExchange.wait_matched`) before a request goes out.
"""

from __future__ import annotations

import time
from typing import Any, Iterable, Mapping, Optional, Sequence

from .. import contract
from ..contract.codec import MessageError, printable, safe_dumps
from .carrier import publish
from .gathering import GatheringGroup
from .rclpy_internals import RCLError
from .client_base import Answer, ClientError, Spinning, describe_graph

#: Seconds a client waits after its request and reply topics first match before sending (see wait_matched).
MATCH_SETTLE = 0.25
#: Seconds at most a new client waits for every discovered reader of a request topic to match (see wait_matched).
MATCH_EVERY = 1.0
#: Seconds between two takes of a stream of ``ltm/assert/result`` answers (the first is taken at once): a client
#: sending facts at 1,000/s is not woken a thousand times a second (:func:`~.batches.subscribe_batches`' gather).
ANSWERS_GATHER = 0.01
#: Publishers the pipeline must have matched before a request is sent: topic -> publisher/subscriber side.
KIND_TOPICS = {"say": (contract.HUMAN, contract.RR_RESULT), "describe": (contract.REG_REQUEST, contract.REG_EXPRESSION),
               "assert": (contract.LTM_ASSERT, contract.LTM_ASSERT_RESULT)}


def _facts(properties: Mapping[str, float] | Iterable[str]) -> dict[str, float]:
    """Return facts as property -> certainty (a list of properties: each certain)."""
    return dict(properties) if isinstance(properties, Mapping) else {p: 1.0 for p in properties}


class DialogueExchange(Spinning):
    """Requests and their answers on the dialogue topics (state set up by ``GraphClient``).

    Uses the client's ``_publishers`` and ``_reply_subs`` (one pair per kind of
    :data:`KIND_TOPICS`), ``answers`` (id -> what was heard), ``limits`` (the graph's
    size limits), ``time`` (the clock stamped on requests), ``_ids`` and ``_prefix``
    (request ids), and from its other parts ``domains`` and ``domain_of``.
    """

    def _on_answer(self, data: dict) -> None:
        key = str(data.get("id"))
        if key in self.answers:
            self.answers[key].append(Answer(data, time.monotonic()))

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
        # and the request went out twice (the second copy answered from the node's cache).  Other readers
        # this client has discovered (a recorder, a view) get up to MATCH_EVERY to match as well, so a
        # one-shot command's request is in a recording too; one that never matches (QoS) is not waited for.
        settled, every = time.monotonic() + MATCH_SETTLE, time.monotonic() + MATCH_EVERY
        while time.monotonic() < settled or (time.monotonic() < every and not self._every_reader_matched(pub)):
            self.executor.spin_once(timeout_sec=0.005)

    def _every_reader_matched(self, pub) -> bool:
        """Whether ``pub`` has matched every reader of its topic that this client's node has discovered."""
        return pub.get_subscription_count() >= self.node.count_subscribers(pub.topic_name)

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
            self._publish(kind, message)
        except RCLError as err:
            self.answers.pop(key, None)
            raise ClientError(f"{KIND_TOPICS[kind][0].name} {key!r} not sent (the receivers are too far behind): "
                              f"{printable(str(err).split(',')[0], 200)}", "busy") from None
        return key

    def _publish(self, kind: str, message: Mapping[str, Any]) -> None:
        writer = self._publishers[kind]
        self.reach_recorders(writer)
        publish(writer, message)
        self._note_sent(writer, lambda: publish(writer, message))

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
                    self.spin_until(lambda: self._answered(kind, key),
                                    min(self.retry_after, deadline - time.monotonic()), "answer")
                    return self.answer_of(key) or {}
                except ClientError as err:
                    if err.kind != "timeout" or time.monotonic() >= deadline:
                        if err.kind == "timeout":
                            raise ClientError(f"no answer to {request} {key!r} within {timeout:g} s in "
                                              f"{self.where()}", "timeout") from None
                        raise
                self._publish(kind, message)
        finally:
            self.answers.pop(key, None)

    def _answered(self, kind: str, key: str) -> bool:
        """Whether request ``key`` has an answer; a held answer reader (ANSWERS_GATHER) is released first.

        A caller waiting for its own answer is not kept waiting for the period's end; a
        stream sent open loop (:meth:`send`) still has its answers gathered.
        """
        group = self._reply_subs[kind].callback_group
        if isinstance(group, GatheringGroup):
            group.release()
        return bool(self.answers[key])

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
