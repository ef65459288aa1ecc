"""A serving consultant's persistence: restore at start, clock epochs, writing and checkpoints.

:class:`Persistence` is the half of a :class:`~fsreg_ros.core.consultant.service.ConsultantService`
that keeps its state database (:mod:`fsreg_ros.core.state.store`) in step with memory.  It owns:

* **restore**: taking up what the store held at start (runtime facts, policy, decay
  mark, WM as a checkpoint plus a replayed :mod:`~fsreg_ros.core.state.journal`), refusing a
  damaged database by name and migrating one written for another KB (:class:`Restored`);
* **clock epochs**: at the first ``configure`` of an incarnation, stored WM on a clock
  of another kind, or ahead of the clock (a restarted simulation), is dropped;
* **writing**: each call's journal records committed once (:meth:`Persistence.finish`),
  LTM facts stored and fsynced *before* memory changes, a batch in one transaction
  (:meth:`Persistence.store_facts`, which may run on a writer thread of its own),
  a failed WM write kept pending and retried (at most once a second) as a checkpoint;
* **checkpoints**: every queue changed since the last one (read off the buffer's change
  record), written when the journal grows long, after a failure, and at shutdown;
* what :meth:`~fsreg_ros.core.consultant.service.ConsultantService.status` reports of the stored
  state (``wm``, ``persisted``, ``note``, ``error``).

It reads and sets the serving state it persists through the :class:`Served` protocol
(the service's consultant, buffer, incarnation, policy, decay mark, latest time,
notices and steady clock); the service owns the ops and calls it at the points above.
Durability by kind of data: docs/deployment.md, "State".
"""

from __future__ import annotations

import math
from datetime import datetime, timezone
from dataclasses import dataclass, field
from typing import Any, Callable, Optional, Protocol, Sequence

from ..state import journal
from .consultant import Consultant, KnowledgeError
from ..forgetting.policies import NONE, ForgettingPolicy, PolicyError
from ..memory import ENCODE_CAUSES, UNKNOWN_ORIGIN, WMBuffer
from ..state.store import Batch, Checkpoint, DomainStore, StoreError, StoreContents, damaged
from ..forgetting.wm_manager import configure_buffer

#: Journal length (records, names) at which :meth:`Persistence.maintain` writes a checkpoint ...
CHECKPOINT_RECORDS, CHECKPOINT_NAMES = 256, 200_000
#: ... and at which a call writes one itself.
FORCE_RECORDS, FORCE_NAMES = 4096, 2_000_000
#: Least time between two attempts to write after a failed write (steady seconds).
RETRY_AFTER = 1.0


class Served(Protocol):
    """The serving state :class:`Persistence` reads (and, restoring, sets): a consultant service's."""

    consultant: Consultant
    buffer: WMBuffer
    incarnation: int
    policy: ForgettingPolicy
    decay_until: float
    latest: float
    notices: list[tuple[str, str]]
    steady: Callable[[], float]


@dataclass
class Restored:
    """What :meth:`Persistence.restore` found and kept.

    ``run`` is the incarnation that wrote the state taken up (None: nothing was stored,
    the database is new or was moved aside, ``fresh``); ``clock`` and ``latest`` its
    clock epoch (the kind of clock WM was stored on, and the time it reflects);
    ``moved_aside`` where a reset put the old database.  ``queues`` counts the WM
    queues restored; when the first configure drops them (another clock or run,
    :meth:`Persistence.settle_epoch`) they move to ``queues_dropped``.
    """

    incarnation: int
    runtime_entities: int = 0
    runtime_facts: int = 0
    queues: int = 0
    records: int = 0
    dropped: list[str] = field(default_factory=list)  # what a migration could not keep
    migrated: bool = False
    backup: Optional[str] = None
    run: Optional[int] = None
    clock: Optional[str] = None
    latest: Optional[float] = None
    moved_aside: Optional[str] = None
    queues_dropped: int = 0

    @property
    def fresh(self) -> bool:
        """Whether nothing was taken up: the scenario alone."""
        return not (self.runtime_entities or self.runtime_facts or self.queues or self.queues_dropped)

    def summary(self) -> str:
        """Return one log line."""
        text = (f"incarnation {self.incarnation}, {self.runtime_entities} runtime entities, "
                f"{self.runtime_facts} runtime facts, {self.queues} WM queues ({self.records} journal records)")
        if self.run is not None:
            text += f", stored by incarnation {self.run}" + (f" on the {self.clock} clock" if self.clock else "") + (
                f" up to {time_text(self.clock, self.latest)}" if self.latest is not None else "")
        if self.moved_aside:
            text += f"; the old state moved aside to {self.moved_aside}"
        if self.migrated:
            text += (f"; written for another KB: migrated, {len(self.dropped)} dropped"
                     + (f" ({'; '.join(self.dropped[:10])}{'; ...' if len(self.dropped) > 10 else ''})"
                        if self.dropped else "")
                     + (f", the old database kept as {self.backup}" if self.backup else ""))
        return text

    def to_json(self) -> dict:
        """Return what announcements and ``wm_manager/status`` carry (``restored`` of the stored state)."""
        out: dict[str, Any] = {"fresh": self.fresh, "runtime_entities": self.runtime_entities,
                               "runtime_facts": self.runtime_facts, "queues": self.queues,
                               "run": self.run, "clock": self.clock, "latest": self.latest}
        if self.queues_dropped:
            out["queues_dropped"] = self.queues_dropped
        if self.moved_aside:
            out["moved_aside"] = self.moved_aside
        if self.migrated:
            out["migrated"] = True
            out["dropped"] = len(self.dropped)
        return out


def time_text(clock: Optional[str], t: float) -> str:
    """Return a time of a clock epoch for people: ``t=12.5 s`` (sim time), ``2026-11-26 19:30:12 UTC`` (system)."""
    if clock == "system" and t > 1e8:
        return datetime.fromtimestamp(t, timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    return f"t={t:g} s"


class Persistence:
    """One serving consultant's state database kept in step with its memory (see the module docstring)."""

    def __init__(self, served: Served, store: Optional[DomainStore], persist_wm: bool, clock: str) -> None:
        """Persist ``served`` to ``store`` (None: nothing is written).

        ``persist_wm`` False keeps facts and policy only; ``clock`` is the robot clock's
        kind (``sim`` or ``system``), stored with WM for the epoch check.
        """
        self.served = served
        self.store = store
        self.persist_wm = persist_wm
        self.clock = clock
        self.recording = store is not None and persist_wm  # WM changes are journalled
        self.wm_state = "empty"  # restored | dropped | empty | not-persisted
        self.wm_note = ""
        self.persisted = True
        self.store_error: Optional[str] = None
        self.runtime: list[str] = []  # runtime-added entities, in order (restored)
        self._stored_epoch: Optional[tuple[Optional[str], float]] = None
        self._unsaved: set[str] = set()  # entities changed since the last checkpoint
        self._unsaved_meta: dict[str, Any] = {}
        self._journal_rows = 0
        self._journal_names = 0
        self._journal_ok = True  # False after a failed write: the next WM write is a checkpoint
        self._failed_at = -math.inf
        self._clock_saved = False
        self._clear_stored = False  # the next checkpoint deletes every stored queue first
        self.restored: Optional[Restored] = None  # what restore took up (reported in status)

    # ============================================================ status
    def status(self) -> dict:
        """Return what ``info`` and the announcement report of the stored state."""
        out: dict[str, Any] = {"wm": self.wm_state, "persisted": self.persisted}
        if self.restored is not None:
            out["restored"] = self.restored.to_json()
        if self.wm_note:
            out["note"] = self.wm_note
        if self.store_error:
            out["error"] = self.store_error
        return out

    def health(self) -> dict:
        """Return the store's health, for ``/diagnostics``.

        The state file, the journal records since the last checkpoint, whether the last write
        succeeded (false after a refused write, e.g. a full disk, until a retry succeeds), and how
        many entities' queues are not saved yet.
        """
        return {"state_file": str(self.store.path) if self.store is not None else "",
                "journal_records": self._journal_rows, "last_write_ok": bool(self.persisted),
                "store_error": "" if self.persisted else (self.store_error or ""),
                "unsaved_entities": len(self._unsaved)}

    def note(self, key: str, value: Any) -> None:
        """Mark a setting as changed and unsaved (``policy`` settings or the ``decay_until`` mark)."""
        self._unsaved_meta[key] = value

    def journals(self) -> bool:
        """Whether WM changes can be journalled (not with random displacement victims)."""
        return self.served.buffer.limits.victim != "random"

    # ============================================================ restore
    def restore(self, state: StoreContents) -> Restored:
        """Take up what the store held: runtime facts, policy, decay mark and WM (checkpoint + journal).

        Nothing is announced (no events).  A database written for this KB must name
        only known entities and properties (else StateDamaged naming the file); one
        written for another KB is migrated: what still validates is kept, the rest
        listed in :attr:`Restored.dropped`, and the database rewritten (its old
        version kept aside).  WM is checked against the clock at the first
        configure (:meth:`settle_epoch`).
        """
        served, buffer = self.served, self.served.buffer
        migrate = state.other_kb
        path = self.store.path if self.store is not None else "state"
        report = Restored(state.incarnation, migrated=migrate)
        if not state.created:  # a database this program wrote before: its last writer and clock epoch
            report.run = state.incarnation - 1
            report.clock = state.clock
            report.latest = state.latest if math.isfinite(state.latest) else None
        if state.moved_aside is not None:
            report.moved_aside = str(state.moved_aside)
        served.incarnation = state.incarnation
        kb_entities = list(served.consultant.entities)  # before any runtime entity joins
        if state.kb_entities is None and self.recording:
            self._unsaved_meta["kb_entities"] = kb_entities
        sink, buffer.sink = buffer.sink, None
        try:
            runtime = self._restore_facts(state, report, path)
            if state.policy is not None:
                try:
                    served.policy = ForgettingPolicy.from_settings(state.policy)
                except PolicyError as err:
                    raise damaged(path, f"stored policy: {err}") from None
            if self.persist_wm:
                self._restore_wm(state, report, path)
            else:
                configure_buffer(buffer, served.policy, 0.0)
                self.wm_state = "not-persisted"
        finally:
            buffer.sink = sink
        self.take_changes()
        if report.records:
            self._journal_ok = False  # compact the replayed journal at the next write
        if migrate and self.store is not None:
            backup = self.store.rewrite(self._export(state, runtime, kb_entities))
            report.backup = str(backup) if backup else None
            self._unsaved.clear()
            self._journal_ok, self._journal_rows, self._journal_names = True, 0, 0
        report.queues = len(buffer.nonempty_entities())
        if report.latest is not None or report.records:  # the journal's records carry their own times
            report.latest = served.latest if math.isfinite(served.latest) else report.latest
        self.restored = report
        return report

    def _restore_facts(self, state: StoreContents, report: Restored, path: Any) -> dict[str, dict[str, float]]:
        """Re-apply the runtime facts; return those kept (entity -> facts), runtime entities first."""
        c, migrate = self.served.consultant, state.other_kb
        kept: dict[str, dict[str, float]] = {}
        runtime = list(state.entities)
        for entity in runtime + [e for e in state.facts if e not in runtime]:
            facts = dict(state.facts.get(entity, {}))
            if entity not in runtime and not c.knows_entity(entity):
                if not migrate:
                    raise damaged(path, f"facts about entity {entity!r}, which neither the KB nor the runtime "
                                        "entities hold")
                report.dropped.append(f"{entity}: no longer in the KB")
                continue
            unknown = [p for p in facts if not c.knows_property(p)]
            if unknown and not migrate:
                raise damaged(path, f"a fact about {entity!r} names property {unknown[0]!r}, unknown to the KB")
            for prop in unknown:
                report.dropped.append(f"{entity}.{prop}: unknown property")
                del facts[prop]
            if not facts:
                if entity in runtime:
                    report.dropped.append(f"{entity}: none of its facts is valid")
                continue
            try:
                c.assert_facts(entity, facts, 0.0, exclude=False)  # as stored: exclusions were stored with them
            except KnowledgeError as err:
                if not migrate:
                    raise damaged(path, f"a stored fact about {entity!r}: {err}") from None
                report.dropped.append(f"{entity}: {err}")
                continue
            kept[entity] = facts
            report.runtime_entities += entity in runtime
            report.runtime_facts += len(facts)
        self.runtime = [e for e in runtime if e in kept]
        return kept

    def _restore_wm(self, state: StoreContents, report: Restored, path: Any) -> None:
        served = self.served
        c, buffer, migrate = served.consultant, served.buffer, state.other_kb
        queues = {}
        for entity, items in state.queues.items():
            stray = [item[3] for item in items if item[3] not in ENCODE_CAUSES and item[3] != UNKNOWN_ORIGIN[0]]
            if stray:
                raise damaged(path, f"the WM queue of {entity!r} has an entry with cause {stray[0]!r}")
            if not c.knows_entity(entity):
                if not migrate:
                    raise damaged(path, f"a WM queue of entity {entity!r}, which the domain does not hold")
                report.dropped.append(f"WM of {entity}: no longer in the KB")
                continue
            unknown = [item[0] for item in items if not c.knows_property(item[0])]
            if unknown:
                if not migrate:
                    raise damaged(path, f"the WM queue of {entity!r} holds property {unknown[0]!r}, unknown to the KB")
                report.dropped.append(f"WM of {entity}: {', '.join(unknown)} (unknown properties)")
                items = [item for item in items if c.knows_property(item[0])]
            if items:
                queues[entity] = items
        try:
            limits = ForgettingPolicy.from_settings(state.limits) if state.limits is not None else NONE
        except PolicyError as err:
            raise damaged(path, f"stored checkpoint policy: {err}") from None
        buffer.restore(queues, state.stamp, state.ticks, limits.limits())
        try:
            strays = buffer.restore_episodes(state.episodes, c.knows_entity)
        except ValueError as err:
            raise damaged(path, f"stored checkpoint {err}") from None
        if strays and not migrate:
            raise damaged(path, f"reference episodes of entity {strays[0]!r}, which the domain does not hold")
        report.dropped += [f"episodes of {entity}: no longer in the KB" for entity in strays]
        records = []
        order = None if state.kb_entities is None else state.kb_entities + state.entities
        for record in state.journal:
            try:
                record = journal.decode(record, order)
                checked = journal.check(record, c.knows_entity, c.knows_property, keep_known=state.other_kb)
            except journal.JournalError as err:
                raise damaged(path, f"journal: {err}") from None
            if checked is None:
                report.dropped.append(f"journal record {record[0]!r}: names nothing the KB still holds")
            else:
                records.append(checked)
        for record in records:
            journal.replay(buffer, c.entities, record)
        report.records = len(records)
        latest = max([state.latest, *(journal.time_of(record) for record in records)])
        if c.retract_on_update:  # a runtime retraction stored while WM could not be: apply it now
            for entity, facts in state.facts.items():
                gone = [p for p, certainty in facts.items() if certainty < c.threshold and c.knows_entity(entity)
                        and c.knows_property(p) and p not in c.properties_of(entity)]
                for prop in gone:
                    buffer.remove(entity, prop, "retract", 0.0)
        served.decay_until = state.decay_until
        served.latest = latest
        self._clock_saved = state.clock == self.clock
        self._stored_epoch = (state.clock, latest)
        self.wm_state = "restored" if buffer.nonempty_entities() or records else "empty"

    def _export(self, state: StoreContents, runtime_facts: dict[str, dict[str, float]],
                kb_entities: list[str]) -> StoreContents:
        """Return the state to write after a migration: what was kept, as of now."""
        served = self.served
        export = served.buffer.export_queue
        stamp, ticks = served.buffer.counters()
        return StoreContents(
            served.incarnation, policy=state.policy, decay_until=served.decay_until, clock=state.clock,
            latest=served.latest, entities=list(self.runtime), facts=runtime_facts,
            queues={e: export(e) for e in served.buffer.nonempty_entities()} if self.persist_wm else {},
            stamp=stamp, ticks=ticks, limits=served.policy.settings(), kb_entities=kb_entities,
            episodes=served.buffer.export_episodes() if self.persist_wm else {})

    # ============================================================ clock epochs
    def settle_epoch(self, time: float) -> None:
        """At the first configure: drop stored WM that belongs to another clock or run."""
        served, buffer = self.served, self.served.buffer
        stored, self._stored_epoch = self._stored_epoch, None
        if stored is None or (not buffer.nonempty_entities() and served.decay_until == -math.inf):
            return  # nothing stored to judge
        clock, latest = stored
        if clock is not None and clock != self.clock:
            why = f"it was stored on the {clock} clock and this consultant runs on the {self.clock} clock"
        elif time + 1e-9 < latest:
            why = (f"it reflects time {latest:g} s but the clock reads {time:g} s "
                   "(a restarted simulation or a clock set back)")
        else:
            return
        stamp, ticks = buffer.counters()
        if self.restored is not None:
            self.restored.queues_dropped, self.restored.queues = self.restored.queues, 0
        buffer.restore({}, stamp, ticks, buffer.limits)
        buffer.take_changes()
        served.decay_until = -math.inf
        served.latest = -math.inf
        self.wm_state, self.wm_note = "dropped", f"stored WM not restored: {why}"
        served.notices.append(("warning", f"{self.wm_note}; runtime facts and policy restored"))
        if self.recording:  # the stored queues go at the next write, which is a checkpoint
            self._unsaved.clear()
            self._clear_stored, self._journal_ok = True, False
            self._unsaved_meta["decay_until"] = -math.inf

    # ============================================================ writing
    def store_facts(self, facts: Sequence[tuple[str, dict[str, float], bool]]) -> None:
        """Store LTM updates durably (one fsynced transaction) before they are applied.

        Raises StoreError, having stored nothing.  ``facts``: (entity, {property:
        certainty}, new entity?) per update, in order (a batch of ``ltm/assert``, or the
        batches a :class:`~fsreg_ros.core.state.fact_writer.FactWriter` groups, is one call).
        The WM retractions they cause are journalled when they are applied, as that
        call's records (a restart between the two removes them from the restored WM:
        :meth:`restore` drops every property whose stored certainty is below the
        threshold).  Nothing to store: nothing is written.  Touches nothing but the
        store, so it may run on a thread of its own (the store serialises its commits).
        """
        if self.store is None or not facts:
            return
        self.store.commit(Batch(facts=list(facts)))  # fsynced before it returns

    def finish(self, changes: Any) -> None:
        """Account for a call's :class:`~.service.Changes`; write them (once) unless nothing needs it."""
        changes.policy = self._unsaved_meta.get("policy")
        changes.decay_until = self._unsaved_meta.get("decay_until")
        if self.store is None:
            self._unsaved_meta.clear()
            return
        if self.recording:
            if not changes.records and not self._unsaved_meta and self._journal_ok:
                return  # nothing to write
        elif not self._unsaved_meta:
            return
        if self.served.steady() - self._failed_at < RETRY_AFTER:
            return  # a write failed just now: keep everything pending
        force = (not self._journal_ok or not self.journals() or self._journal_rows >= FORCE_RECORDS
                 or self._journal_names >= FORCE_NAMES)
        self._write(checkpoint=self.recording and force, records=changes.records)

    def maintain(self) -> None:
        """Write a checkpoint when the journal has grown long, or retry a failed write (call when idle)."""
        if not self.recording:
            return
        due = (self._journal_rows >= CHECKPOINT_RECORDS or self._journal_names >= CHECKPOINT_NAMES
               or not self._journal_ok)
        if due and self.served.steady() - self._failed_at >= RETRY_AFTER:
            self._write(checkpoint=True)

    def shutdown(self) -> None:
        """Write what is unsaved as a checkpoint (best effort) and close the store."""
        if self.store is None:
            return
        if self.recording:
            self._write(checkpoint=True)
        self.store.close()

    def take_changes(self) -> list[str]:
        """Take the buffer's change record (entities whose queue changed), keeping them for the checkpoint."""
        changed = self.served.buffer.take_changes()
        if self.recording:
            self._unsaved.update(changed)
        return changed

    def _write(self, checkpoint: bool, records: Sequence[list] = ()) -> None:
        """Commit what is unsaved: the call's journal records, or a checkpoint; on failure keep it pending."""
        served = self.served
        batch = Batch()
        meta: dict[str, Any] = {}
        if "policy" in self._unsaved_meta or (checkpoint and self.recording):
            meta["policy"] = served.policy.settings()
        if self.recording:
            if "decay_until" in self._unsaved_meta:
                meta["decay_until"] = served.decay_until if math.isfinite(served.decay_until) else None
            if checkpoint:  # the journal's records carry their own times
                meta["latest"] = served.latest if math.isfinite(served.latest) else None
            if not self._clock_saved:
                meta["clock"] = self.clock
            if "kb_entities" in self._unsaved_meta:
                meta["kb_entities"] = self._unsaved_meta["kb_entities"]
            if checkpoint:
                batch.checkpoint = self._checkpoint()
            else:
                batch.records = list(records)
        batch.meta = meta
        try:
            self.store.commit(batch)  # type: ignore[union-attr]
        except StoreError as err:
            self._failed_at = served.steady()
            self._journal_ok = False
            if self.persisted or self.store_error != str(err):
                served.notices.append(("warning", f"WM not stored (serving on; retrying with a checkpoint): {err}"))
            self.persisted, self.store_error = False, str(err)
            return
        self._unsaved_meta.clear()
        self._clock_saved = self._clock_saved or self.recording
        if batch.checkpoint is not None:
            self._unsaved.clear()
            self._clear_stored = False
            self._journal_ok, self._journal_rows, self._journal_names = True, 0, 0
        else:
            self._journal_rows += len(batch.records)
            self._journal_names += sum(journal.names_in(r) for r in batch.records)
        if not self.persisted:
            served.notices.append(("info", "WM stored again"))
        self.persisted, self.store_error = True, None

    def _checkpoint(self) -> Checkpoint:
        self.take_changes()
        buffer = self.served.buffer
        export, unsaved = buffer.export_queue, self._unsaved
        held = [e for e in buffer.nonempty_entities() if e in unsaved]  # in the buffer's order
        emptied = sorted(unsaved.difference(held))
        stamp, ticks = buffer.counters()
        return Checkpoint({e: export(e) for e in held + emptied}, stamp, ticks, self.served.policy.settings(),
                          clear=self._clear_stored, episodes=buffer.export_episodes())
