"""The consultant service: one domain's consultant as it serves RR, REG and the WM Manager.

:class:`ConsultantService` holds a :class:`~fsreg_ros.core.consultant.consultant.Consultant` (LTM
and its WM buffer) and everything that lives beside it while it serves: the open
views of RR and REG (:mod:`fsreg_ros.core.consultant.views`), the forgetting policy the WM
Manager installed, readiness (configured in this incarnation), the decay high-water
mark (the last tick applied: a tick is never applied twice), the numbering of the
events it publishes, and its persistence (below).  The ROS node is wiring around it; the in-process
:class:`~fsreg_ros.core.consultant.local_port.LocalPort` uses its typed methods, so the simulator
and the graph run the same code.

One call, one :meth:`ConsultantService.apply` (ops as in :mod:`fsreg_ros.contract.consultant`):

1. the op runs (typed methods: :meth:`open`, :meth:`narrow`, :meth:`close`,
   :meth:`configure`, ...); while someone listens to the events, the buffer's sink
   collects them, otherwise encodings take the buffer's quiet path;
2. the call's :class:`Changes` say whether WM changed, with the journal records of
   its buffer operations (:mod:`fsreg_ros.core.state.journal`) and the policy, decay mark
   and facts it set; a manage op also lists exactly the queues it changed
   (``WMBuffer.take_changes``: the WM Manager is told how many);
3. they are committed to the store, once, by :meth:`Persistence.finish
   <fsreg_ros.core.consultant.persistence.Persistence.finish>` (the records; a checkpoint of the
   queues changed since the last one, read off ``take_changes``, when the journal is long);
4. the :class:`Outcome` carries the reply, the changes and the numbered events.

LTM facts asserted at run time are checked, stored and applied in batches by
:class:`~fsreg_ros.core.consultant.fact_batches.FactBatches` (held as
:attr:`ConsultantService.facts`; each application is one call of the service).

Persistence (restore at start, clock epochs, writing each call's changes once,
checkpoints, retries after a failed write) is :class:`~fsreg_ros.core.consultant.persistence.Persistence`,
held as :attr:`ConsultantService.persistence`: an LTM fact is stored before memory
changes (a refused write changes nothing); a failed WM write does not fail the call
(the service serves on and reports ``persisted: false`` in :meth:`status`); stored WM
of another clock or run is dropped at the first ``configure``.
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Optional, Sequence

from ..state import journal
from .consultant import CandidateSet, Consultant, KnowledgeError
from ..algorithms.port import Narrowed, Reference, Step, View, Walk, Walked, WalkStep
from .views import close_view, open_view
from ..memory.ticks import TickError, TickRun, check_time
from ..forgetting.policies import NONE, ForgettingPolicy
from ..memory import WMEvent
from .fact_batches import FactBatches, PreparedFacts
from .persistence import Persistence, Restored
from ..state.store import DomainStore, StoreContents
from .views import ViewTable
from ..forgetting.wm_manager import configure_buffer, unapplied


class NotReady(RuntimeError):
    """A query before the WM Manager configured this incarnation (error kind ``not-ready``)."""


class RequestError(ValueError):
    """A request the contract's types admit but whose content is unusable (a time out of range, bad ticks)."""


@dataclass
class Changes:
    """What one call changed, and so what the state database must hold.

    ``wm``: whether the call changed WM (encoded or forgot something); ``queues``: for
    the manage ops (``configure``, ``decay``, ``evict``) exactly the entities whose queue
    changed, first change first (other calls leave them to the next checkpoint: listing
    the thousands of queues a rule-3 narrowing touches would cost more than the call);
    ``records``: the journal records of the call's WM operations; ``policy``: the
    settings installed, if it installed a policy; ``decay_until``: the new decay mark, if
    ticks were applied; ``facts``: the LTM updates applied (entity, facts, new entity?), if any.
    """

    wm: bool = False
    queues: list[str] = field(default_factory=list)
    records: list[list] = field(default_factory=list)
    policy: Optional[dict] = None
    decay_until: Optional[float] = None
    facts: list[tuple[str, dict[str, float], bool]] = field(default_factory=list)


@dataclass
class Outcome:
    """The result of one call: the reply, its :class:`Changes`, and the events to publish (numbered)."""

    reply: dict
    changes: Changes
    events: list[dict] = field(default_factory=list)


class ConsultantService:
    """One domain's consultant with its sessions, policy, readiness, decay mark, events and store."""

    def __init__(
        self,
        consultant: Consultant,
        *,
        incarnation: int = 1,
        sessions: Optional[ViewTable[CandidateSet]] = None,
        store: Optional[DomainStore] = None,
        persist_wm: bool = True,
        clock: str = "system",
        now: Optional[Callable[[], float]] = None,
        steady: Callable[[], float] = _time.monotonic,
        ready: bool = False,
    ) -> None:
        """Serve ``consultant``.

        ``now`` gives the robot clock (seconds) for requests without a ``time``;
        ``steady`` a monotonic clock for session expiry and write retries; ``clock``
        the robot clock's kind (``sim`` or ``system``); ``ready`` True serves queries at
        once (in-process use: no WM Manager to wait for).  Until configured, the
        buffer retains nothing (policy ``none``).
        """
        self.consultant = consultant
        self.buffer = consultant.wm
        self.domain = consultant.domain
        self.incarnation = incarnation
        self.sessions: ViewTable[CandidateSet] = sessions if sessions is not None else ViewTable()
        self.now = now or (lambda: 0.0)
        self.steady = steady
        self.ready = ready
        self.policy = NONE
        if not ready:
            configure_buffer(self.buffer, NONE, 0.0)
        self.decay_until = -math.inf
        self.time = 0.0  # the latest request time (the time /wm/state reports)
        self.latest = -math.inf  # the latest time WM reflects (clock epochs)
        self.seq = 0  # events numbered so far
        self.wm_version = 0  # calls of this incarnation that changed WM (wm/state and info report it)
        self.notices: list[tuple[str, str]] = []  # (level, line) for the node's log: epochs, write failures
        self.persistence = Persistence(self, store, persist_wm, clock)
        self._recording = self.persistence.recording  # WM changes are journalled (fixed at start)
        self._records: list[list] = []
        self._events: list[WMEvent] = []
        self._touched = False  # the current call changed WM
        self.facts = FactBatches(self)  # LTM facts prepared, not yet applied or abandoned
        self._references: dict[str, Optional[str]] = {}  # entity -> the reference id its current episode began by

    # ================================================================ calls
    def require_ready(self) -> None:
        """Raise NotReady until the WM Manager configured this incarnation (queries wait for it)."""
        if not self.ready:
            raise NotReady(f"consultant '{self.domain}' (incarnation {self.incarnation}) is not configured by the "
                           "WM Manager yet; try again")

    def run(self, body: Callable[[], dict], listening: bool = False, counted: bool = False) -> Outcome:
        """Run one call (``body`` returns its reply); return its :class:`Outcome`, its changes written once.

        ``listening``: whether anyone hears the events (else no events are built);
        ``counted``: list exactly the queues the call changed (the manage ops' replies
        say how many).  The ops of the consultant protocol come here decoded, as the
        typed calls of :mod:`fsreg_ros.core.consultant.ops`
        (:func:`fsreg_ros.ros.consultant_ops.apply`); a refusal (KnowledgeError,
        PolicyError, RequestError, SessionError) changes nothing.
        """
        self._records, self._events, self._touched = [], [], False
        if counted:
            self.persistence.take_changes()  # what earlier calls changed is not this one's
        sink = self.buffer.sink
        self.buffer.sink = self._events.append if listening else None
        try:
            reply = body()
        finally:
            self.buffer.sink = sink
            queues = self.persistence.take_changes() if counted else []
            changes = Changes(self._touched or bool(queues), queues, self._records)
            if changes.wm:
                self.wm_version += 1
            self.persistence.finish(changes)  # written once
        return Outcome(reply, changes, self.numbered(self._events))

    def touch(self, time: float, wm: bool = True) -> None:
        """Note a request's time (and, for a WM change, that WM changed and the latest time it reflects)."""
        self.time = time
        if wm:
            self._touched = True
            if time > self.latest:
                self.latest = time

    def request_time(self, value: Any, name: str = "time") -> float:
        """Return a request's ``time`` (field ``name``) checked (RequestError), or the robot clock's now if None."""
        if value is None:
            return self.now()
        try:
            return check_time("time", value)
        except TickError as err:
            raise RequestError(f"field '{name}': {err}") from None

    def ltm_assert(self, entity: str, facts: Mapping[str, Any], time: Optional[float] = None,
                   listening: bool = False) -> Outcome:
        """Add or update LTM facts about one entity (``ltm/assert``): stored durably first, then applied.

        Raises KnowledgeError (invalid: nothing changes) or StoreError (not stored:
        nothing changes).  The reply is the :class:`~fsreg_ros.core.consultant.consultant.AssertResult` as JSON.
        """
        outcome, refusals = self.facts.assert_batch([(entity, facts)], time, listening)
        if refusals[0] is not None:
            raise refusals[0]
        result = outcome.reply["results"][0]
        outcome.reply = {key: result[key] for key in ("entity", "new_entity", "updated", "retracted")}
        return outcome

    def ltm_assert_batch(self, facts: Sequence[tuple[str, Mapping[str, Any]]], time: Optional[float] = None,
                         listening: bool = False) -> Outcome:
        """Add or update LTM facts about many entities (a batch of ``ltm/assert``) in ONE commit.

        All-or-nothing per fact, one transaction for the accepted ones: each fact
        ``(entity, properties)`` is validated in order, as if the accepted ones before it
        were applied (a refused fact does not stop the others); the accepted ones are
        stored in one fsynced transaction, then applied in order.  The reply's
        ``results`` hold, per fact and in order, its :class:`~fsreg_ros.core.consultant.consultant.AssertResult`
        as JSON with ``ok: true``, or ``ok: false`` with ``error`` and ``kind``;
        ``applied`` and ``refused`` count them.  Raises StoreError (nothing stored,
        nothing changed) or RequestError (a bad ``time``: nothing changed).  The same
        in three steps, the commit on another thread: :meth:`prepare_facts`,
        :meth:`Persistence.store_facts <fsreg_ros.core.consultant.persistence.Persistence.store_facts>`
        of :attr:`PreparedFacts.stored`, :meth:`apply_facts` (:mod:`fsreg_ros.core.state.fact_writer`).
        """
        return self.facts.assert_batch(facts, time, listening)[0]

    def prepare_facts(self, facts: Sequence[tuple[str, Mapping[str, Any]]],
                      time: Optional[float] = None) -> PreparedFacts:
        """Validate a batch of facts without changing anything (:meth:`.fact_batches.FactBatches.prepare`)."""
        return self.facts.prepare(facts, time)

    def apply_facts(self, prepared: PreparedFacts, listening: bool = False) -> Outcome:
        """Apply a prepared batch whose facts are stored (:meth:`.fact_batches.FactBatches.apply`)."""
        return self.facts.apply(prepared, listening)

    def abandon_facts(self, prepared: PreparedFacts) -> None:
        """Forget a batch that could not be stored (:meth:`.fact_batches.FactBatches.abandon`)."""
        self.facts.abandon(prepared)

    def facts_in_flight(self) -> int:
        """Return the prepared batches neither applied nor abandoned yet."""
        return self.facts.in_flight

    def set_threshold(self, threshold: float, time: Optional[float] = None, listening: bool = False) -> Outcome:
        """Change the domain's threshold (not stored: it comes from the parameters); retractions are journalled.

        Not while batches of facts are in flight (they were checked against the threshold
        in force): apply them first (RuntimeError).
        """
        if self.facts.in_flight:
            raise RuntimeError(f"{self.facts.in_flight} batches of facts are in flight; apply them before the "
                               "threshold changes")

        def run() -> dict:
            when = self.request_time(time)
            retracted = self.consultant.set_threshold(threshold, when)
            by_entity: dict[str, list[str]] = {}
            for entity, prop in retracted:
                by_entity.setdefault(entity, []).append(prop)
            for entity, props in by_entity.items():
                self.record(journal.remove(entity, props, when))
            self.touch(when, wm=bool(retracted))
            return {"threshold": self.consultant.threshold, "retracted": [list(pair) for pair in retracted]}
        return self.run(run, listening)

    # ============================================================ typed ops
    def open(self, target: Optional[str] = None, context: Optional[Sequence[str]] = None,
             first: Optional[Step] = None, refer: Optional[Reference] = None) -> View:
        """Open a view (its handle is the candidate set); see :meth:`~.port.ConsultantPort.open`.

        With ``refer`` (REG's act of referring; RequestError without a target), the target's
        next reference episode begins before the view reads WM, journalled as a ``refer``
        record that encodes nothing.  An open whose reference ``id`` began the target's
        current episode (a retried request) begins none (docs/semantics.md section 2).
        """
        if refer is not None and target is None:
            raise RequestError("open: 'refer' needs a 'target' (RR's referent is known only when its view closes, "
                               "so its episode begins there)")
        begin = refer is not None and (refer.id is None or self._references.get(target) != refer.id)
        view = open_view(self.consultant, target, context, first, refer, begin)
        if begin:
            self._references[target] = refer.id
            self.record(journal.refer(target, [], refer.time, refer.turn))
            self.touch(refer.time, wm=self.buffer.retains)
        if first is not None and view.first.target_holds:
            self._narrowed(view.handle, first.prop, first.cause, first.time, first.turn)
        return view

    def narrow(self, candidates: CandidateSet, prop: str, cause: Optional[str], time: float,
               turn: Optional[int]) -> Narrowed:
        """Keep the members ``prop`` holds for, encoding it for each (rules 2 and 3)."""
        holds = self.consultant.narrow(candidates, prop, cause, time, turn)
        if holds:
            self._narrowed(candidates, prop, cause, time, turn)
        return Narrowed(holds, candidates.size)

    def walk(self, candidates: CandidateSet, steps: Sequence[WalkStep], cause: Optional[str], time: float,
             turn: Optional[int]) -> Walked:
        """Narrow by ``steps`` as a :class:`~fsreg_ros.core.algorithms.port.Walk` decides, in this one call.

        Every step's property is checked first: an unknown one changes nothing (KnowledgeError).
        """
        for i, step in enumerate(steps):
            if not self.consultant.knows_property(step.prop):
                raise KnowledgeError(f"domain '{self.domain}' knows no property '{step.prop}' (step {i} of the walk)")
        walk = Walk(steps, candidates.size)
        while (step := walk.next()) is not None:
            walk.record(self.narrow(candidates, step.prop, cause, time, turn))
        return walk.result()

    def close(self, candidates: CandidateSet, encode: Sequence[str] = (), time: float = 0.0,
              turn: Optional[int] = None) -> list[str]:
        """Close a view: its members; ``encode`` is rule 1 for the target (or the only member).

        The entity's reference episode begins first, unless the view's open began it (``refer``).
        """
        members = close_view(self.consultant, candidates, encode, time, turn)
        if encode:
            speaker = self.consultant.entities[candidates.target] if candidates.target is not None else members[0]
            if candidates.referred:
                if self._recording and self.buffer.retains:
                    self.record(journal.encode(speaker, encode, "speaker", time, turn))
            else:
                self._references.pop(speaker, None)  # its current episode is no open's any more
                self.record(journal.refer(speaker, encode, time, turn))
        return members

    def rule_out(self, candidates: CandidateSet) -> tuple[list[str], list[int]]:
        """For each property holding for the target, the members it rules out (by member rank)."""
        return self.consultant.rule_out(candidates)

    def encode(self, entity: str, properties: Sequence[str], cause: str, time: float, turn: Optional[int]) -> None:
        """Encode(entity, properties) (Algorithm 1)."""
        self.consultant.encode(entity, properties, cause, time, turn)
        if self._recording and self.buffer.retains:
            self.record(journal.encode(entity, properties, cause, time, turn))

    def affirm(self, prop: str, entities: Sequence[str], cause: str, time: float,
               turn: Optional[int] = None) -> list[str]:
        """Check ``prop`` for each entity in order and encode it for each it holds for."""
        held = self.consultant.affirm(prop, entities, cause, time, turn)
        if held and self._recording and self.buffer.retains:
            self.record(journal.each(prop, held, cause, time, turn))
        return held

    def configure(self, policy: ForgettingPolicy, time: float) -> None:
        """Install ``policy`` (trims at once; the policy already installed changes nothing) and serve."""
        if not self.ready:
            self.persistence.settle_epoch(time)
        if policy != self.policy:
            configure_buffer(self.buffer, policy, time)
            self.policy = policy
            self.record(journal.limits(policy, time))
            self.persistence.note("policy", policy.settings())
            self.notices.append(("info", f"memory policy {policy.to_json()}"))
        if not self.ready:
            self.ready = True
            self.notices.append(("info", f"configured by the WM Manager (incarnation {self.incarnation}): serving"))
        self.touch(time)

    def decay_now(self, ticks: TickRun) -> None:
        """Apply decay ticks now, eagerly (Algorithm 2), skipping those at or before the last one applied.

        Eager as :meth:`WMBuffer.decay_now <fsreg_ros.core.memory.WMBuffer.decay_now>` (the events in their
        canonical order), where :meth:`WMBuffer.decay` defers the pops.
        """
        due = unapplied(ticks, self.decay_until)
        if due is not None:
            self.buffer.decay_now(due, self.consultant.entities)
            self.decay_until = due.last
            self.record(journal.decay(due))
            self.persistence.note("decay_until", due.last)
        self.touch(ticks.last)

    def advance(self, time: float) -> None:
        """Note that the clock reached ``time``: entries below the activation threshold go now (rule ``activation``)."""
        self.buffer.advance(time)
        self.buffer.flush()  # at once, as decay ticks are applied: their events are published now
        self.record(journal.advance(time))
        self.touch(time)

    def evict(self, count: int, time: float) -> None:
        """Forget the domain's ``count`` least recently encoded fronts (the shared pool's trim)."""
        self.buffer.evict_oldest(count, "shared-capacity", time)
        self.record(journal.evict(count, time))
        self.touch(time)

    # ============================================================ state, status
    @property
    def store(self) -> Optional[DomainStore]:
        """The state database (None: nothing is stored); :attr:`persistence` keeps it."""
        return self.persistence.store

    def status(self) -> dict:
        """Return what ``info`` and the announcement report of the stored state."""
        return self.persistence.status()

    def version(self) -> str:
        """Return ``"<incarnation>:<entities>"``: the catalogue's version, what callers cache it by.

        The catalogue (the preference order and the entity list) changes only when an entity
        is added (entities are only ever appended, the preference order is the incarnation's),
        so the entity count versions it.  Facts about known entities leave it as it was: a
        perception stream updating them does not make every RR turn and REG request ask
        ``info`` again (at 1,000 facts/s it did, a round trip more each).
        """
        return f"{self.incarnation}:{len(self.consultant.entities)}"

    def numbered(self, events: Sequence[WMEvent]) -> list[dict]:
        """Return events as messages, numbered ``seq`` 1, 2, 3, ... per incarnation, with the ``incarnation``."""
        out = []
        for event in events:
            self.seq += 1
            message = event._asdict()
            message["seq"] = self.seq
            message["incarnation"] = self.incarnation
            out.append(message)
        return out

    def restore(self, state: StoreContents) -> Restored:
        """Take up what the store held (:meth:`~fsreg_ros.core.consultant.persistence.Persistence.restore`)."""
        return self.persistence.restore(state)

    def health(self) -> dict:
        """Return the store's health, for ``/diagnostics`` (:meth:`Persistence.health`)."""
        return self.persistence.health()

    def maintain(self) -> None:
        """Write a checkpoint when the journal has grown long, or retry a failed write (call when idle)."""
        self.persistence.maintain()

    def shutdown(self) -> None:
        """Write what is unsaved as a checkpoint (best effort) and close the store."""
        self.persistence.shutdown()

    # ============================================================ internals: a call
    def record(self, record: list) -> None:
        """Add a journal record to the current call's changes (when WM changes are journalled)."""
        if self._recording:
            self._records.append(record)

    def _narrowed(self, candidates: CandidateSet, prop: str, cause: Optional[str], time: float,
                  turn: Optional[int]) -> None:
        """Note (and record) the rule 2/3 encodings a narrowing (or an open's first step) just did, if any."""
        if cause is not None and candidates.members and self.buffer.retains:
            self.record(journal.bits(prop, candidates.members, cause, time, turn))
            self.touch(time)
