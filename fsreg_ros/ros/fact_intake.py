"""A consultant's ``ltm/assert`` intake: facts drained, checked, stored off the serving thread, applied, answered.

Owns the path of a fact through a consultant node (docs/semantics.md, "Facts in batches"):
the messages of this domain are drained and validated together
(:func:`~fsreg_ros.ros.batches.subscribe_batches`, a stream gathered every
:data:`FACTS_GATHER`), checked on the executor thread as one batch
(:meth:`~fsreg_ros.core.consultant.service.ConsultantService.prepare_facts`), stored by a
:class:`~fsreg_ros.core.state.fact_writer.FactWriter` thread (one fsynced transaction for
every batch waiting), then applied and answered back on the executor thread (a guard
condition), so RR and REG are answered while the disk works.  Each message gets one
answer on ``ltm/assert/result``.  What the facts changed is published through the node
(:class:`FactHost`).
"""

from __future__ import annotations

from dataclasses import dataclass
from time import monotonic, thread_time
from typing import Any, Callable, Optional, Protocol

from .. import contract
from ..contract.codec import MessageError, printable
from ..core.consultant.service import ConsultantService, Outcome, PreparedFacts, RequestError
from ..core.state.fact_writer import FactWriter
from ..core.state.store import StoreError
from .batches import subscribe_batches
from .carrier import CarrierError, publish, publisher
from .consultant_outbox import ConsultantOutbox

#: Least seconds between two log lines about facts applied (steady clock): a stream is summarised.
FACTS_LOG_PERIOD = 5.0
#: Most facts one ``ltm/assert`` batch takes from the messages waiting, and the most CPU seconds spent taking them
#: (RR's and REG's calls wait meanwhile; the writer thread groups batches into one commit whatever their size;
#: docs/semantics.md, "Facts in batches").
MAX_DRAIN_FACTS, MAX_DRAIN_SECONDS = 250, 0.005
#: Seconds between two takes of a stream of ``ltm/assert`` messages (the first of a stream is taken at once):
#: one fact a message at 1,000/s is then ~10 messages a round, one commit and one apply, instead of a round,
#: a commit and an apply each (:func:`~fsreg_ros.ros.batches.subscribe_batches`' ``gather``).
FACTS_GATHER = 0.01


class FactHost(Protocol):
    """What the intake needs of its consultant node."""

    domain: str
    service: ConsultantService  # the current one (a state reset replaces it)

    def get_logger(self) -> Any: ...

    def guarded(self, run: Callable[[bool], Outcome]) -> Outcome: ...


@dataclass
class Submitted:
    """A batch handed to the writer: its messages (to answer), the prepared facts and the service that made them."""

    messages: list[dict]
    prepared: PreparedFacts
    service: ConsultantService

    @property
    def generation(self) -> int:
        return self.prepared.generation


def facts_of(data: dict) -> list[tuple[str, dict]]:
    """Return the facts of a validated ``ltm/assert``: (entity, properties) per fact, in order."""
    if data.get("facts") is not None:
        return [(fact["entity"], fact["properties"]) for fact in data["facts"]]
    return [(data["entity"], data["properties"])]


class FactIntake:
    """The ``ltm/assert`` subscription, the writer thread and the answers of one consultant node.

    What the facts changed goes out through the node's ``outbox``
    (:class:`~fsreg_ros.ros.consultant_outbox.ConsultantOutbox`).
    """

    def __init__(self, node: FactHost, limits, outbox: ConsultantOutbox) -> None:
        self.node, self.outbox = node, outbox
        self.log = FactLog(node.get_logger())
        self.committed = node.create_guard_condition(self.on_committed)  # the writer's batches, back here
        self.writer = self.start_writer()
        self.results = publisher(node, contract.LTM_ASSERT_RESULT)
        domain = node.domain
        subscribe_batches(node, contract.LTM_ASSERT, self.on_asserts, reject=self.reject, limits=limits,
                          accept=lambda data: not isinstance(data.get("domain"), str) or data["domain"] == domain,
                          size=lambda data: len(data.get("facts") or ()) or 1, max_size=MAX_DRAIN_FACTS,
                          max_seconds=MAX_DRAIN_SECONDS, clock=thread_time, gather=FACTS_GATHER)

    def start_writer(self) -> FactWriter:
        """Start the thread that stores the current service's facts (each group of batches in one fsynced commit)."""
        store = self.node.service.persistence.store_facts
        return FactWriter(lambda batches: store([fact for b in batches for fact in b.prepared.stored]),
                          self.committed.trigger, name=f"facts-{self.node.domain}")

    def reject(self, request_id: Any, error: str, kind: str = "bad-request") -> None:
        """Answer an ``ltm/assert`` refused before it was checked (malformed, not JSON, too large)."""
        reply = {"domain": None, "consultant": self.node.domain, "entity": None, "ok": False, "error": error,
                 "kind": kind}
        if request_id is not None:
            reply["id"] = request_id
        publish(self.results, reply)

    def on_asserts(self, messages: list[dict]) -> None:
        """Prepare ``ltm/assert`` messages of this domain as ONE batch and hand it to the writer thread.

        They were routed by ``accept``, validated and drained together by
        :func:`~fsreg_ros.ros.batches.subscribe_batches`.  A message holds one entity's facts
        or a batch (``facts``); every fact of every message is one fact of one
        :meth:`~fsreg_ros.core.consultant.service.ConsultantService.prepare_facts` (all-or-nothing per
        fact, checked against LTM as the batches already in flight leave it).  The
        :class:`~fsreg_ros.core.state.fact_writer.FactWriter` stores it (with whatever else
        waits, in one fsynced transaction) while this thread serves RR and REG;
        :meth:`on_committed` then applies it and answers each message.
        """
        facts: list[tuple[str, dict]] = []
        for data in messages:
            facts.extend(facts_of(data))
        service = self.node.service
        try:
            prepared = service.prepare_facts(facts)
        except RequestError as err:
            raise MessageError(str(err)) from None
        try:
            self.writer.submit(Submitted(messages, prepared, service))
        except RuntimeError as err:  # the writer is closed (shutting down): nothing stored, nothing applied
            service.abandon_facts(prepared)
            raise CarrierError(f"not stored: {err}", kind="not-stored") from None

    def on_committed(self) -> None:
        """Apply and answer the batches the writer is done with, up to MAX_DRAIN_FACTS a round (queries go between).

        What they changed is published right after their answers, in this round (at 1,000
        single facts/s a flush of its own cost an executor round per batch).
        """
        facts = 0
        while facts < MAX_DRAIN_FACTS and (done := self.writer.take_done(1)):
            submitted, error = done[0]
            facts += max(1, len(submitted.prepared.facts))
            try:
                self.settle(submitted, error)
            except Exception as err:  # noqa: BLE001 - a guard condition's error would stop the node: answer, serve on
                text = printable(f"internal error: {type(err).__name__}: {err}")
                self.node.get_logger().error(f"{contract.LTM_ASSERT.name}: {text}")
                for data in submitted.messages:
                    self.answer(data, ok=False, error=text, kind="internal")
        self.outbox.flush()
        if self.writer.has_done():
            self.committed.trigger()

    def settle(self, submitted: Submitted, error: Optional[StoreError]) -> None:
        """Apply a committed batch and answer each of its messages, or answer them all ``not-stored``."""
        messages, prepared = submitted.messages, submitted.prepared
        if submitted.service is not self.node.service:  # stored before a reset set that database aside: not served
            error = StoreError("the state was reset before this batch was applied; it is in the database set aside")
        if error is not None:  # memory unchanged: nothing was applied
            submitted.service.abandon_facts(prepared)
            self.node.get_logger().error(
                printable(f"{contract.LTM_ASSERT.name}: not stored ({len(prepared.facts)} facts): {error}"))
            for data in messages:
                self.answer(data, ok=False, error=printable(f"not stored: {error}"), kind="not-stored")
            return
        service = self.node.service
        outcome = self.node.guarded(lambda listening: service.apply_facts(prepared, listening=listening))
        self.answer_applied(messages, outcome.reply["results"])
        applied = outcome.reply["applied"]
        if applied:
            new = sum(1 for _, _, is_new in outcome.changes.facts if is_new)
            retracted = sum(len(r.get("retracted") or ()) for r in outcome.reply["results"] if r["ok"])
            self.log.facts(outcome, applied, len(messages), new, retracted)
            self.outbox.published(outcome, later=False)  # on_committed flushes once the round's answers are out

    def answer_applied(self, messages: list[dict], results: list[dict]) -> None:
        """Answer each message with the results of its facts (in order; a batch message with all of them)."""
        log = self.node.get_logger()
        results = iter(results)
        for data in messages:
            mine = [next(results) for _ in range(len(data["facts"]) if data.get("facts") is not None else 1)]
            for result in mine:
                if not result["ok"]:
                    log.warning(printable(f"{contract.LTM_ASSERT.name}: {result['error']}"))
            if data.get("facts") is None:
                self.answer(data, **{k: v for k, v in mine[0].items() if k != "entity"})
            else:
                applied = sum(r["ok"] for r in mine)
                self.answer(data, ok=applied == len(mine), results=mine, applied=applied, refused=len(mine) - applied)

    def answer(self, data: dict, **fields: Any) -> None:
        """Publish the answer to one ``ltm/assert`` message (its entity or batch, its id, ``fields``)."""
        reply: dict[str, Any] = {"domain": self.node.domain}
        if data.get("facts") is None:
            reply["entity"] = data.get("entity")
        if "id" in data:
            reply["id"] = data["id"]
        reply.update(fields)
        publish(self.results, reply)

    def settle_all(self) -> None:
        """Wait for the writer, then apply and answer every batch in flight (before LTM changes otherwise)."""
        self.writer.flush()
        for submitted, error in self.writer.take_done():
            self.settle(submitted, error)

    def pause(self) -> None:
        """Apply and answer every batch in flight, then stop the writer (a state reset; :meth:`resume` after)."""
        self.settle_all()
        self.writer.close()

    def resume(self) -> None:
        """Store the facts from now on in the current service's database (a new writer)."""
        self.writer = self.start_writer()

    def close(self) -> None:
        """Stop the writer: what was submitted is stored, and answered if the node still can."""
        self.writer.close()
        try:
            for submitted, error in self.writer.take_done():
                self.settle(submitted, error)
        except Exception as err:  # noqa: BLE001 - shutting down: the facts are stored, the answers may not go
            self.node.get_logger().warning(printable(f"{contract.LTM_ASSERT.name}: stored, not answered at shutdown: "
                                                     f"{type(err).__name__}: {err}"))


class FactLog:
    """Log lines about facts applied: one at once after a quiet :data:`FACTS_LOG_PERIOD`, else a period's summary.

    A perception stream would otherwise log hundreds of lines a second (and rclpy's
    logging, which inspects the caller's frame, cost a tenth of the consultant's CPU).
    """

    def __init__(self, logger) -> None:
        self.logger = logger
        self.logged, self.unlogged = float("-inf"), [0] * 5  # facts, batches, messages, new entities, retracted

    def facts(self, outcome: Outcome, applied: int, messages: int, new: int, retracted: int) -> None:
        """Log what a batch changed: at once after a quiet period, else in the period's summary."""
        now = monotonic()
        if now - self.logged >= FACTS_LOG_PERIOD and not self.unlogged[0]:
            self.logged = now
            if applied == 1:
                entity, updated, is_new = outcome.changes.facts[0]
                self.logger.info(printable(
                    f"LTM {'added' if is_new else 'updated'} '{entity}': {updated}"
                    + (f", retracted {retracted} propert{'y' if retracted == 1 else 'ies'}" if retracted else "")))
            else:
                self.logger.info(f"LTM: {applied} facts applied in one batch ({messages} messages, {new} new "
                                 f"entities, {retracted} properties retracted)")
            return
        for i, n in enumerate((applied, 1, messages, new, retracted)):
            self.unlogged[i] += n

    def summary(self) -> None:
        """Log the facts applied since the last line, once FACTS_LOG_PERIOD has passed (the node's timer calls it)."""
        now = monotonic()
        if self.unlogged[0] and now - self.logged >= FACTS_LOG_PERIOD:
            facts, batches, messages, new, retracted = self.unlogged
            self.logger.info(f"LTM: {facts} facts applied in {batches} batches in the last "
                             f"{now - self.logged:.1f} s ({messages} messages, {new} new entities, "
                             f"{retracted} properties retracted)")
            self.unlogged = [0] * 5
            self.logged = now
