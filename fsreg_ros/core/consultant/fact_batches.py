"""LTM facts asserted at run time, in batches: checked, stored durably, then applied in order.

A consultant's ``ltm/assert`` facts go through three steps so that nothing acknowledged is
lost and a refused fact changes nothing: :meth:`FactBatches.prepare` checks a batch against
LTM as the batches before it (prepared, not yet applied or abandoned: *in flight*) will
leave it, without changing anything; the state database stores what it accepted
(:meth:`Persistence.store_facts <fsreg_ros.core.consultant.persistence.Persistence.store_facts>`,
one fsynced transaction, possibly on another thread: :mod:`fsreg_ros.core.state.fact_writer`);
:meth:`FactBatches.apply` then changes LTM in preparation order, the retractions leaving WM
as one call of the service (journalled like any WM change).  A batch that could not be
stored is abandoned with every batch prepared against it (:meth:`FactBatches.abandon`: a
new *generation* starts from LTM as it is).

:class:`FactBatches` owns the batches in flight of one
:class:`~fsreg_ros.core.consultant.service.ConsultantService` (its ``facts``), which keeps
its ``ltm_assert`` / ``prepare_facts`` / ``apply_facts`` / ``abandon_facts`` methods as the
entry points and runs each application as one of its calls.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping, Optional, Protocol, Sequence

from ..memory import WMBuffer
from ..state import journal
from .consultant import Consultant, KnowledgeError
from .persistence import Persistence


class FactHost(Protocol):
    """What :class:`FactBatches` uses of the service holding it (all public)."""

    consultant: Consultant
    buffer: WMBuffer
    persistence: Persistence

    def request_time(self, value: Any, name: str = "time") -> float:
        """Return a request's time checked, or now."""

    def run(self, body: Callable[[], dict], listening: bool = False, counted: bool = False) -> Any:
        """Run one call; return its outcome (``reply``, ``changes``, ``events``)."""

    def record(self, record: list) -> None:
        """Add a journal record to the current call."""

    def touch(self, time: float, wm: bool = True) -> None:
        """Note a request's time (and a WM change)."""


@dataclass
class PreparedFacts:
    """A batch of facts validated by :meth:`FactBatches.prepare`, to be stored, then applied.

    ``facts`` as given; ``refusals`` one per fact (None: accepted); ``accepted`` per
    accepted fact (entity, properties, values to store, new entity?, properties that stop
    holding, properties that leave WM); ``when`` the time it is applied at;
    ``generation`` the previews it was checked against (:meth:`FactBatches.abandon`).
    """

    facts: list[tuple[str, Mapping[str, Any]]]
    refusals: list[Optional[KnowledgeError]]
    accepted: list[tuple[str, Mapping[str, Any], dict[str, float], bool, list[str], list[str]]]
    when: float
    generation: int

    @property
    def stored(self) -> list[tuple[str, dict[str, float], bool]]:
        """Return what the state database must hold before the batch is applied: (entity, values, new) per fact."""
        return [(entity, values, new) for entity, _, values, new, _, _ in self.accepted]


class FactBatches:
    """The batches of facts one consultant service prepared and has neither applied nor abandoned."""

    def __init__(self, service: FactHost) -> None:
        self.service = service
        self.in_flight = 0  # batches prepared, neither applied nor abandoned
        self._pending: dict[str, dict[str, float]] = {}  # entity -> its facts as those batches leave them
        self._generation = 0  # a failed commit voids the batches prepared up to it

    def assert_batch(self, facts: Sequence[tuple[str, Mapping[str, Any]]], time: Optional[float],
                     listening: bool) -> tuple[Any, list[Optional[KnowledgeError]]]:
        """Prepare, store and apply ``facts`` in one go; the outcome and each fact's refusal (None: applied)."""
        prepared = self.prepare(facts, time)
        try:
            self.service.persistence.store_facts(prepared.stored)  # one transaction, fsynced, before memory changes
        except BaseException:
            self.abandon(prepared)
            raise
        return self.apply(prepared, listening), prepared.refusals

    def prepare(self, facts: Sequence[tuple[str, Mapping[str, Any]]], time: Optional[float] = None) -> PreparedFacts:
        """Validate a batch of facts without changing anything; return what to store and then apply.

        Each fact is checked as LTM will be once every batch in flight and the accepted
        facts before it in this batch are applied, so batches may be prepared while
        earlier ones are being stored.  Raises RequestError (a bad ``time``).  Hand the
        result to :meth:`apply` once :attr:`PreparedFacts.stored` is durable, or to
        :meth:`abandon` if storing it failed; batches are applied in the order they were
        prepared, and nothing else may change LTM meanwhile (the threshold waits for them:
        :meth:`ConsultantService.set_threshold`).
        """
        consultant = self.service.consultant
        when = self.service.request_time(time)
        refusals: list[Optional[KnowledgeError]] = []
        accepted = []  # (entity, properties, values, new, stopped, retracted)
        for entity, props in facts:
            try:
                values: dict[str, float] = {}  # the update with what it excludes, at 0
                new, stopped = consultant.preview_assert(entity, props, pending=self._pending, effective=values)
                _check_storable([entity, *props])
            except KnowledgeError as err:
                refusals.append(err)
                continue
            refusals.append(None)
            retracted = stopped if consultant.retract_on_update else []  # what leaves WM
            accepted.append((entity, props, values, new, stopped, retracted))
        self.in_flight += 1
        return PreparedFacts(list(facts), refusals, accepted, when, self._generation)

    def apply(self, prepared: PreparedFacts, listening: bool = False) -> Any:
        """Apply a prepared batch whose facts are stored (in preparation order); return the service's outcome.

        The facts change LTM in order and their retractions leave WM (journalled as this
        call's records, like any WM change); the reply is
        :meth:`ConsultantService.ltm_assert_batch`'s.
        """
        if prepared.generation != self._generation:
            raise RuntimeError("a batch of facts prepared before a failed commit cannot be applied")
        service = self.service
        applied: list[tuple[str, dict[str, float], bool]] = []

        def body() -> dict:
            when = prepared.when
            records = [journal.remove(entity, gone, when) for entity, gone in self._retractions(prepared)]
            results = iter(service.consultant.assert_facts(entity, props, when, previewed=(new, stopped),
                                                           update=values).to_json()
                           for entity, props, values, new, stopped, _ in prepared.accepted)
            replies = []
            for (entity, _), refusal in zip(prepared.facts, prepared.refusals):
                if refusal is None:
                    result = next(results)
                    applied.append((result["entity"], result["updated"], result["new_entity"]))
                    replies.append({**result, "ok": True})
                else:
                    replies.append({"entity": entity if isinstance(entity, str) else None, "ok": False,
                                    "error": str(refusal), "kind": refusal.kind or type(refusal).__name__})
            for record in records:
                service.record(record)
            if prepared.accepted:
                service.touch(when, wm=any(gone for *_, gone in prepared.accepted))
            return {"results": replies, "applied": len(prepared.accepted),
                    "refused": len(prepared.facts) - len(prepared.accepted)}
        self.in_flight -= 1
        if not self.in_flight:
            self._pending = {}  # LTM holds them all now
        outcome = service.run(body, listening)
        outcome.changes.facts = applied
        return outcome

    def abandon(self, prepared: PreparedFacts) -> None:
        """Forget a prepared batch that could not be stored, with every batch prepared against it.

        The batches in flight of its generation are void (each was checked as if it would
        be applied); a new generation starts from LTM as it is.  A batch of an older
        generation changes nothing.
        """
        if prepared.generation == self._generation:
            self._generation += 1
            self.in_flight, self._pending = 0, {}

    def _retractions(self, prepared: PreparedFacts) -> list[tuple[str, list[str]]]:
        """Return (entity, properties) per accepted fact whose retractions change WM, before they are applied.

        Without rule ``activation`` (where a removal also moves its clock), a retraction
        of nothing WM holds is a no-op and is not journalled (perception mostly
        retracts facts of entities no one spoke about).
        """
        if not self.service.persistence.recording:
            return []
        buffer = self.service.buffer
        out = []
        for entity, _, _, _, _, retracted in prepared.accepted:
            if not retracted:
                continue
            if buffer.activation is None:
                held = buffer.queue(entity)
                retracted = [p for p in retracted if p in held]  # later facts of the batch: kept if held now
            if retracted:
                out.append((entity, retracted))
        return out


def _check_storable(names: Sequence[str]) -> None:
    """Raise KnowledgeError for a name the state database cannot hold (not valid UTF-8, e.g. a lone surrogate)."""
    for name in names:
        try:
            name.encode("utf-8")
        except UnicodeEncodeError:
            raise KnowledgeError(f"name {name[:40]!r} is not valid UTF-8 (a lone surrogate?)") from None
