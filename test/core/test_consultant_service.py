"""The core consultant service: every op, exact change sets, persistence that replays to the same WM.

No ROS: :class:`ConsultantService` over a small consultant, with and without a real
state database in a temporary directory.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import pytest

from fsreg_ros.contract import check
from fsreg_ros.contract.codec import MessageError
from fsreg_ros.contract.consultant_codec import ALL_OPS
from fsreg_ros.ros.consultant_ops import apply
from fsreg_ros.core.state import journal
from fsreg_ros.core.consultant.consultant import Consultant, KnowledgeError
from fsreg_ros.core.forgetting.policies import PolicyError
from fsreg_ros.core.algorithms.generation import generate
from fsreg_ros.core.consultant.local_port import LocalPort
from fsreg_ros.core.consultant.persistence import CHECKPOINT_RECORDS
from fsreg_ros.core.algorithms.port import Walked, WalkStep, run_sync, walk_by_narrowing
from fsreg_ros.core.state.fact_writer import FactWriter
from fsreg_ros.core.consultant.service import ConsultantService, NotReady, PreparedFacts, RequestError
from fsreg_ros.core.state.store import DomainStore, StateDamaged, StoreError, fingerprint
from fsreg_ros.core.consultant.views import SessionError, ViewTable

PREF = ["light-hair", "dark-hair", "male", "female", "glasses", "lab-coat"]
ENTITIES = {
    "face1": {"light-hair": 1.0, "male": 1.0, "glasses": 1.0, "lab-coat": 1.0},
    "face2": {"dark-hair": 1.0, "female": 1.0, "glasses": 0.7},
    "face3": {"dark-hair": 0.9, "male": 1.0, "lab-coat": 0.4},
}
KB = fingerprint(PREF, ENTITIES, 0.5, {})
POLICY = {"policy": "decay+displacement", "decay_period": 10.0, "capacity": 3}
TICK = {"origin": 0.0, "period": 10.0, "first": 1, "count": 1}
#: What a consultant that found no stored state reports it restored.
FRESH = {"fresh": True, "runtime_entities": 0, "runtime_facts": 0, "queues": 0, "run": None, "clock": None,
         "latest": None}


class Steady:
    """A steady clock the test moves."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def make(tmp_path=None, clock: str = "system", persist_wm: bool = True, steady=None, **kwargs):
    consultant = Consultant("faces", ENTITIES, PREF, **kwargs)
    store = DomainStore(tmp_path / "faces.sqlite3", KB) if tmp_path is not None else None
    service = ConsultantService(consultant, store=store, clock=clock, persist_wm=persist_wm,
                                now=lambda: 50.0, steady=steady or Steady(),
                                sessions=ViewTable(capacity=8, per_client=2))
    if store is not None:
        service.restore(store.open())
    return service


def configure(service, policy=POLICY, time=0.0):
    return apply(service, "configure", {"op": "configure", "policy": policy, "time": time})


def encode(service, entity, props, time, listening=False):
    return apply(service, "encode", {"op": "encode", "entity": entity, "properties": props, "cause": "speaker",
                                     "time": time}, listening=listening)


# ------------------------------------------------------------------ ops and change sets
def test_queries_wait_for_the_wm_manager_but_info_and_manage_ops_do_not():
    service = make()
    info = apply(service, "info", {"op": "info"}).reply
    assert info["policy"] == "none" and info["events"] == 0 and info["version"] == "1:3"
    assert info["state"] == {"wm": "empty", "persisted": True}
    for op, request in (("open", {"op": "open"}), ("snapshot", {"op": "snapshot"})):
        with pytest.raises(NotReady, match="incarnation 1"):
            apply(service, op, request)
    assert apply(service, "size", {"op": "size"}).reply == {"size": 0}
    outcome = configure(service)
    assert outcome.reply == {"memory": POLICY, "incarnation": 1, "state": {"wm": "empty", "persisted": True},
                             "queues_changed": 0}
    assert outcome.changes.policy == {"policy": "decay+displacement", "decay_period": 10.0, "capacity": 3}
    assert service.ready and ("info", "configured by the WM Manager (incarnation 1): serving") in service.notices


def test_every_op_reports_whether_it_changed_wm_and_manage_ops_exactly_which_queues():
    service = make()
    configure(service)
    take = service.buffer.take_changes  # what a query changed, read off the buffer here

    out = encode(service, "face1", ["male", "glasses"], 1.0, listening=True)
    assert out.changes.wm and out.changes.queues == [] and take() == ["face1"]
    assert [e["seq"] for e in out.events] == [1, 2]
    assert out.events[0] == {"op": "encode", "domain": "faces", "entity": "face1", "property": "male",
                             "cause": "speaker", "time": 1.0, "turn": None, "seq": 1, "incarnation": 1}
    out = apply(service, "affirm", {"op": "affirm", "property": "glasses", "entities": ["face3", "face2", "face1"],
                                    "cause": "rr", "time": 2.0, "turn": 1})
    assert out.reply == {"holds": ["face2", "face1"]} and out.changes.wm and take() == ["face2", "face1"]
    assert out.events == []  # nobody listening: no events built, none numbered
    opened = apply(service, "open", {"op": "open", "target": "face1", "client": "reg"})
    assert opened.reply["queue"] == ["male", "glasses"] and not opened.changes.wm and take() == []
    assert opened.reply["origins"] == [{"cause": "speaker", "turn": None}, {"cause": "speaker", "turn": None}]
    session = opened.reply["session"]
    step = {"op": "narrow", "session": session, "cause": "reg-distractor", "time": 3.0, "turn": 2}
    out = apply(service, "narrow", {**step, "property": "male"}, listening=True)
    assert out.reply == {"target_holds": True, "size": 1, "version": "1:3"}
    assert out.changes.wm and take() == ["face3"] and [e["seq"] for e in out.events] == [3]  # no gap
    out = apply(service, "narrow", {**step, "property": "female"})  # not the target's: nothing
    assert not out.changes.wm and take() == []
    assert not apply(service, "rule_out", {"op": "rule_out", "session": session}).changes.wm and take() == []
    out = apply(service, "close", {"op": "close", "session": session, "encode": ["light-hair"], "time": 3.0,
                                   "turn": 2})
    assert out.reply == {"members": ["face3"], "version": "1:3"} and out.changes.wm and take() == ["face1"]
    assert apply(service, "snapshot", {"op": "snapshot"}).reply == {
        "queues": {"face1": ["male", "glasses", "light-hair"], "face2": ["glasses"], "face3": ["male"]}, "events": 3}
    encode(service, "face2", ["female"], 4.0)  # not taken: the next manage op does not count it
    out = apply(service, "decay", {"op": "decay", "ticks": TICK})
    assert out.reply == {"policy": "decay+displacement", "queues_changed": 3} and out.changes.decay_until == 10.0
    assert out.changes.queues == ["face1", "face2", "face3"]  # every queue popped by the tick, in entity order
    assert apply(service, "decay", {"op": "decay", "ticks": TICK}).reply["queues_changed"] == 0  # applied once
    out = apply(service, "evict", {"op": "evict", "count": 1, "time": 11.0})
    assert out.reply == {"size": 2, "queues_changed": 1} and out.changes.queues == ["face1"]
    out = configure(service, {"policy": "none"}, 12.0)
    assert out.changes.queues == ["face1", "face2"] and out.reply["queues_changed"] == 2
    assert apply(service, "wm", {"op": "wm", "entity": "face1"}).reply == {"queue": []}


def test_refused_requests_change_nothing():
    service = make()
    configure(service)
    encode(service, "face1", ["male"], 1.0)
    before = service.buffer.snapshot()
    service.buffer.take_changes()
    bad = [
        ("encode", {"op": "encode", "entity": "face9", "properties": ["male"], "cause": "speaker"}, KnowledgeError),
        ("encode", {"op": "encode", "entity": "face1", "properties": ["male", "wings"], "cause": "speaker"},
         KnowledgeError),
        ("encode", {"op": "encode", "entity": "face1", "properties": ["male"], "cause": "decay"}, MessageError),
        ("encode", {"op": "encode", "entity": "face1", "properties": ["male"], "cause": "rr", "time": 10 ** 400},
         MessageError),
        ("encode", {"op": "encode", "entity": "face1", "properties": ["male"], "cause": "rr", "time": 1e13},
         RequestError),  # a number, but no clock reading (the service's own check)
        ("open", {"op": "open", "target": "face9"}, KnowledgeError),
        ("open", {"op": "open", "first": {"property": "wings", "cause": "rr"}}, KnowledgeError),
        ("narrow", {"op": "narrow", "session": "nope", "property": "male", "cause": "rr"}, SessionError),
        ("configure", {"op": "configure", "policy": {"policy": "decay"}}, PolicyError),
        ("decay", {"op": "decay", "ticks": {"origin": 0.0, "period": 1.0, "first": 1, "count": 0}}, MessageError),
        ("evict", {"op": "evict", "count": -1}, MessageError),
        ("info", {"op": "info", "entities_from": -1}, MessageError),
        ("fly", {"op": "fly"}, RequestError),
    ]
    for op, request, error in bad:
        with pytest.raises(error):
            if error is MessageError:  # refused by the op's schema, which the node's carrier checks first
                check(ALL_OPS[op][0], request)
            apply(service, op, request)
        assert service.buffer.snapshot() == before, request
        assert service.buffer.take_changes() == []
    assert len(service.sessions) == 0  # the refused opens stored no session


WALK = [{"property": "glasses"}, {"property": "dark-hair", "group": "hair"},
        {"property": "light-hair", "group": "hair"}, {"property": "male"}, {"property": "lab-coat"}]


def test_a_walk_is_one_call_doing_what_its_narrows_do(tmp_path):
    # face3's distractors face1 and face2: 'glasses' does not hold for face3 (not taken), 'dark-hair' rules out
    # face1 (taken: its group 'hair' is done, so 'light-hair' is skipped unasked), 'male' rules out face2 (taken),
    # and with no distractor left 'lab-coat' is never asked.
    walked, by_narrows = make(tmp_path), make()
    for service in (walked, by_narrows):
        configure(service)
        encode(service, "face2", ["female"], 1.0)
    session = apply(walked, "open", {"op": "open", "target": "face3"}).reply["session"]
    out = apply(walked, "walk", {"op": "walk", "session": session, "steps": WALK, "cause": "reg-distractor",
                                 "time": 2.0, "turn": 4}, listening=True)
    assert out.reply == {"taken": [1, 3], "size": 0, "narrowed": 3, "version": "1:3"}
    assert [(e["entity"], e["property"], e["cause"], e["turn"]) for e in out.events] == [
        ("face2", "dark-hair", "reg-distractor", 4)]
    # The same walk as one narrow per step (how ports without a walk of their own run it): the same answer, WM, events.
    port = LocalPort(by_narrows.consultant)
    port.service = by_narrows
    view = run_sync(port.open("face3"))
    steps = [WalkStep(step["property"], step.get("group")) for step in WALK]
    assert run_sync(walk_by_narrowing(port, view, steps, "reg-distractor", 2.0, 4)) == Walked((1, 3), 0, 3)
    assert walked.buffer.snapshot() == by_narrows.buffer.snapshot() == {"face2": ["female", "dark-hair"]}
    assert apply(walked, "close", {"op": "close", "session": session}).reply["members"] == []
    # One call, one commit: what it encoded survives a restart.
    assert replayed(tmp_path, walked).buffer.snapshot() == {"face2": ["female", "dark-hair"]}


def test_a_walk_naming_an_unknown_property_changes_nothing():
    service = make()
    configure(service)
    session = apply(service, "open", {"op": "open", "target": "face3"}).reply["session"]
    before = service.buffer.snapshot()
    service.buffer.take_changes()
    with pytest.raises(KnowledgeError, match="knows no property 'wings' \\(step 2 of the walk\\)"):
        apply(service, "walk", {"op": "walk", "session": session, "cause": "reg-distractor", "time": 1.0,
                                "steps": [{"property": "dark-hair"}, {"property": "male"}, {"property": "wings"}]})
    assert service.buffer.snapshot() == before and service.buffer.take_changes() == []
    # The session was not narrowed either: both distractors are still in it.
    assert apply(service, "close", {"op": "close", "session": session}).reply["members"] == ["face1", "face2"]


def test_sessions_are_counted_per_client():
    service = make()
    configure(service)
    hog = [apply(service, "open", {"op": "open", "client": "hog"}).reply["session"] for _ in range(5)]
    mine = apply(service, "open", {"op": "open", "client": "rr"}).reply["session"]
    assert service.sessions.held("hog") == 2 and service.sessions.held("rr") == 1
    with pytest.raises(SessionError):
        apply(service, "close", {"op": "close", "session": hog[0]})
    assert apply(service, "close", {"op": "close", "session": mine}).reply["members"] == ["face1", "face2", "face3"]


def test_local_port_is_the_same_service():
    consultant = Consultant("faces", ENTITIES, PREF)
    port = LocalPort(consultant)
    assert port.service.consultant is consultant and port.service.ready
    expression = run_sync(generate("face2", port, "sd-pia", time=1.0, turn=0))
    assert expression.description == ["dark-hair", "female"]
    assert port.service.store is None and port.service.sessions is not None


# ------------------------------------------------------------------ persistence
def replayed(tmp_path, service):
    """Close ``service`` abruptly (no checkpoint) and return a new one restored from the same database."""
    service.store.close()
    return make(tmp_path)


def test_one_call_is_one_journal_record_and_a_restore_replays_to_the_same_wm(tmp_path):
    service = make(tmp_path)
    configure(service)
    store = service.store
    session = apply(service, "open", {"op": "open", "target": "face1"}).reply["session"]
    apply(service, "narrow", {"op": "narrow", "session": session, "property": "male", "cause": "reg-distractor",
                              "time": 1.0, "turn": 0})
    apply(service, "close", {"op": "close", "session": session, "encode": ["light-hair"], "time": 1.0, "turn": 0})
    encode(service, "face2", ["female", "glasses", "dark-hair", "female"], 2.0)
    apply(service, "decay", {"op": "decay", "ticks": TICK})
    apply(service, "evict", {"op": "evict", "count": 1, "time": 11.0})
    assert store.journal_length() == 6  # configure, narrow, close, encode, decay, evict
    expected = {e: service.buffer.export_queue(e) for e in service.buffer.nonempty_entities()}
    counters = service.buffer.counters()
    again = replayed(tmp_path, service)
    assert {e: again.buffer.export_queue(e) for e in again.buffer.nonempty_entities()} == expected
    assert again.buffer.counters() == counters and again.decay_until == 10.0
    assert again.policy.to_json() == POLICY and again.incarnation == 2 and again.persistence.wm_state == "restored"
    again.maintain()  # the replayed journal is compacted into a checkpoint
    assert again.store.journal_length() == 0
    third = replayed(tmp_path, again)
    assert {e: third.buffer.export_queue(e) for e in third.buffer.nonempty_entities()} == expected


def test_the_journal_is_checkpointed_when_long_and_random_victims_checkpoint_every_call(tmp_path):
    service = make(tmp_path)
    configure(service, {"policy": "displacement", "capacity": 2})
    for i in range(CHECKPOINT_RECORDS):
        encode(service, "face1", [PREF[i % 6]], float(i))
    assert service.store.journal_length() == CHECKPOINT_RECORDS + 1  # and the configure
    service.maintain()
    assert service.store.journal_length() == 0
    configure(service, {"policy": "displacement-random", "capacity": 2, "seed": 3}, 300.0)
    encode(service, "face2", ["female", "glasses", "dark-hair"], 301.0)
    assert service.store.journal_length() == 0  # not journalled: the generator's state is not in a record
    expected = service.buffer.snapshot()
    assert replayed(tmp_path, service).buffer.snapshot() == expected


def test_facts_are_stored_before_memory_changes_and_a_refused_write_changes_nothing(tmp_path):
    service = make(tmp_path)
    configure(service)
    encode(service, "face2", ["glasses", "female"], 1.0)
    real = service.store.commit

    def full(batch):
        raise StoreError("state database x: database or disk is full")

    service.store.commit = full
    with pytest.raises(StoreError, match="disk is full"):
        service.ltm_assert("face9", {"male": 1.0}, 2.0)
    with pytest.raises(StoreError):
        service.ltm_assert("face2", {"glasses": 0.0}, 2.0)
    assert not service.consultant.knows_entity("face9") and service.consultant.version == 0
    assert service.buffer.queue("face2") == ("glasses", "female")  # the retraction was not applied either
    # WM writes fail too, but the call is served; the changes wait, the status says so
    encode(service, "face1", ["male"], 3.0)
    assert service.status() == {"wm": "empty", "persisted": False,
                                "error": "state database x: database or disk is full", "restored": FRESH}
    service.store.commit = real
    service.steady.now += 2.0  # past the retry pause
    service.maintain()
    assert service.status()["persisted"] and service.store.journal_length() == 0
    out = service.ltm_assert("face2", {"glasses": 0.0}, 4.0)
    assert out.reply["retracted"] == ["glasses"] and out.changes.facts == [("face2", {"glasses": 0.0}, False)]
    expected = service.buffer.snapshot()
    again = replayed(tmp_path, service)
    assert again.buffer.snapshot() == expected == {"face2": ["female"], "face1": ["male"]}
    assert again.consultant.certainty("face2", "glasses") == 0.0


def test_stored_wm_of_another_run_is_dropped_at_the_first_configure(tmp_path):
    service = make(tmp_path, clock="sim")
    configure(service, time=1000.0)
    apply(service, "decay", {"op": "decay", "ticks": {**TICK, "first": 99}})  # the tick at 990
    encode(service, "face1", ["male"], 1000.0)
    service.ltm_assert("face9", {"male": 1.0}, 1000.0)
    service.shutdown()
    again = make(tmp_path, clock="sim")
    assert again.buffer.snapshot() == {"face1": ["male"]}  # restored, not yet judged
    out = configure(again, time=5.0)
    assert out.reply["state"]["wm"] == "dropped" and again.buffer.snapshot() == {}
    assert again.decay_until == -math.inf and again.consultant.knows_entity("face9")
    assert any("reflects time 1000 s but the clock reads 5 s" in text for _, text in again.notices)
    again.shutdown()
    third = make(tmp_path, clock="sim")  # the drop was stored: nothing comes back
    assert third.buffer.snapshot() == {} and third.decay_until == -math.inf
    third.shutdown()
    other = make(tmp_path, clock="system")
    configure(other, time=2000.0)
    assert other.persistence.wm_state == "empty"


def test_a_clock_of_another_kind_drops_wm_and_a_later_clock_keeps_it(tmp_path):
    service = make(tmp_path, clock="system")
    configure(service, time=10.0)
    encode(service, "face1", ["male"], 10.0)
    service.shutdown()
    sim = make(tmp_path, clock="sim")
    assert configure(sim, time=50.0).reply["state"]["note"].startswith(
        "stored WM not restored: it was stored on the system clock")
    encode(sim, "face2", ["female"], 50.0)
    sim.shutdown()
    later = make(tmp_path, clock="sim")
    assert configure(later, time=60.0).reply["state"] == {
        "wm": "restored", "persisted": True,
        "restored": {"fresh": False, "runtime_entities": 0, "runtime_facts": 0, "queues": 1, "run": 2, "clock": "sim",
                     "latest": 50.0}}
    assert later.buffer.snapshot() == {"face2": ["female"]}


def test_rows_naming_what_the_kb_does_not_hold_are_refused_at_restore(tmp_path):
    service = make(tmp_path)
    configure(service)
    service.store.commit(journal_batch(["each", "male", ["face1", "ghost"], "rr", 1.0, 0]))
    service.store.close()
    with pytest.raises(StateDamaged, match="journal: 'each' record names an unknown entity 'ghost'"):
        make(tmp_path)


def journal_batch(record):
    from fsreg_ros.core.state.store import Batch

    return Batch(records=[record])


def test_journal_records_are_checked_and_filtered_for_a_migration():
    known_e, known_p = {"a", "b"}.__contains__, {"x"}.__contains__
    assert journal.check(["each", "x", ["a", "c"], "rr", 1.0, 2], known_e, known_p, keep_known=True) == [
        "each", "x", ["a"], "rr", 1.0, 2]
    assert journal.check(["encode", "a", ["x", "y"], "speaker", 1.0, None], known_e, known_p, keep_known=True) == [
        "encode", "a", ["x"], "speaker", 1.0, None]
    assert journal.check(["remove", "c", ["x"], 1.0], known_e, known_p, keep_known=True) is None
    for bad in (["each", "x", ["a"], "decay", 1.0, 2], ["each", "x", "a", "rr", 1.0, 2], ["fly"], "x",
                ["decay", {"origin": 0.0}], ["limits", {"policy": "forget-all"}, 1.0], ["evict", True, 1.0],
                ["each", "x", ["a"], "rr", float("inf"), 2]):
        with pytest.raises(journal.JournalError):
            journal.check(bad, known_e, known_p)


# ------------------------------------------------------------------ exclusive properties
EXCLUSIVE = [["glasses", "lab-coat"], ["male", "female"]]


def stored_facts(service) -> dict:
    """The facts table of the service's state database, read beside it (entity -> {property: certainty})."""
    import sqlite3

    db = sqlite3.connect(f"file:{service.store.path}?mode=ro", uri=True)
    try:
        out: dict = {}
        for entity, prop, certainty in db.execute("SELECT entity, property, certainty FROM facts ORDER BY rowid"):
            out.setdefault(entity, {})[prop] = certainty
        return out
    finally:
        db.close()


@pytest.mark.parametrize("checkpoint", [False, True])
def test_an_exclusive_retraction_is_stored_with_its_fact_and_restored(tmp_path, checkpoint):
    service = make(tmp_path, exclusive=EXCLUSIVE)
    configure(service)
    encode(service, "face2", ["glasses", "female"], 1.0)
    out = service.ltm_assert("face2", {"lab-coat": 1.0}, 2.0)
    assert out.reply == {"entity": "face2", "new_entity": False, "updated": {"lab-coat": 1.0, "glasses": 0.0},
                         "retracted": ["glasses"]}
    assert out.changes.facts == [("face2", {"lab-coat": 1.0, "glasses": 0.0}, False)]
    assert service.buffer.snapshot() == {"face2": ["female"]}
    assert stored_facts(service) == {"face2": {"lab-coat": 1.0, "glasses": 0.0}}  # one commit carries both
    if checkpoint:
        service.shutdown()
    else:
        service.store.close()  # abruptly: the journal carries the WM retraction
    again = make(tmp_path, exclusive=EXCLUSIVE)
    assert again.consultant.properties_of("face2") == ["dark-hair", "female", "lab-coat"]
    assert again.consultant.certainty("face2", "glasses") == 0.0
    assert again.buffer.snapshot() == {"face2": ["female"]}
    # the restored facts are consistent: asserting glasses back retracts lab-coat, and that is restored too
    again.ltm_assert("face2", {"glasses": 1.0}, 3.0)
    again.store.close()
    third = make(tmp_path, exclusive=EXCLUSIVE)
    assert third.consultant.properties_of("face2") == ["dark-hair", "female", "glasses"]


def test_a_contradicting_assert_is_refused_before_anything_is_stored(tmp_path):
    service = make(tmp_path, exclusive=EXCLUSIVE)
    configure(service)
    with pytest.raises(KnowledgeError, match="exclude each other") as err:
        service.ltm_assert("face3", {"male": 1.0, "female": 1.0}, 1.0)
    assert err.value.kind == "contradiction"
    assert stored_facts(service) == {} and service.consultant.version == 0


# ------------------------------------------------------------------ what a restart restored (issue 28.6)
def test_a_restart_reports_what_it_restored_with_exact_counts_run_and_clock_epoch(tmp_path):
    service = make(tmp_path, clock="sim")
    assert service.status()["restored"] == FRESH
    configure(service, time=5.0)
    service.ltm_assert("face9", {"male": 1.0, "glasses": 0.8}, 6.0)
    service.ltm_assert("face2", {"glasses": 0.0}, 7.0)
    encode(service, "face1", ["male"], 8.0)
    encode(service, "face3", ["male", "dark-hair"], 12.5)
    service.shutdown()
    again = make(tmp_path, clock="sim")
    restored = again.persistence.restored
    assert again.status()["restored"] == {"fresh": False, "runtime_entities": 1, "runtime_facts": 3, "queues": 2,
                                          "run": 1, "clock": "sim", "latest": 12.5}
    assert restored.summary().endswith("stored by incarnation 1 on the sim clock up to t=12.5 s")
    # the first configure on an earlier clock drops the WM it restored: the report says so
    configure(again, time=1.0)
    assert again.status()["restored"]["queues"] == 0 and again.status()["restored"]["queues_dropped"] == 2


def test_a_reset_moves_the_database_aside_and_counts_incarnations_on(tmp_path):
    service = make(tmp_path)
    configure(service)
    service.ltm_assert("face9", {"male": 1.0}, 1.0)
    service.shutdown()
    store = DomainStore(tmp_path / "faces.sqlite3", KB)
    fresh = ConsultantService(Consultant("faces", ENTITIES, PREF), store=store)
    stored = store.open(reset=True, after=7)
    fresh.restore(stored)
    assert stored.incarnation == 8 and stored.moved_aside is not None and stored.moved_aside.exists()
    assert fresh.status()["restored"] == {**FRESH, "moved_aside": str(stored.moved_aside)}
    assert not fresh.consultant.knows_entity("face9")


def test_a_restore_applies_the_stored_facts_as_stored_without_excluding_again(tmp_path):
    """Facts stored before a group was declared (both values held) come back as they were, never refused."""
    service = make(tmp_path)
    configure(service)
    service.ltm_assert("face3", {"female": 1.0}, 1.0)  # no groups yet: face3 is male and female
    service.shutdown()
    again = make(tmp_path, exclusive=EXCLUSIVE)
    assert again.consultant.properties_of("face3") == ["dark-hair", "male", "female"]
    assert again.ltm_assert("face3", {"male": 1.0}, 2.0).reply["updated"] == {"male": 1.0, "female": 0.0}
    again.shutdown()
    assert make(tmp_path, exclusive=EXCLUSIVE).consultant.properties_of("face3") == ["dark-hair", "male"]


# ------------------------------------------------------------------ facts in batches (issue 28.10)
def test_a_batch_is_one_commit_all_or_nothing_per_fact_and_replays(tmp_path):
    service = make(tmp_path)
    configure(service)
    encode(service, "face2", ["glasses", "female"], 1.0)
    store = service.store
    commits, rows = store.durable_commits, store.journal_length()
    out = service.ltm_assert_batch([
        ("face9", {"male": 1.0}),  # a new entity ...
        ("face9", {"glasses": 0.9}),  # ... and a second fact about it, in the same batch: not new any more
        ("face1", {"wings": 1.0, "male": 0.0}),  # refused whole (an unknown property): male stays
        ("face2", {"glasses": 0.0}),  # a retraction: leaves WM, journalled in the same commit
        ("face3", {"male": 1.5}),  # refused: a certainty out of range
    ], 2.0)
    assert out.reply == {"applied": 3, "refused": 2, "results": [
        {"entity": "face9", "ok": True, "new_entity": True, "updated": {"male": 1.0}, "retracted": []},
        {"entity": "face9", "ok": True, "new_entity": False, "updated": {"glasses": 0.9}, "retracted": []},
        {"entity": "face1", "ok": False, "kind": "unknown-property",
         "error": "domain 'faces', entity 'face1': unknown property 'wings' (not in the domain's preference order)"},
        {"entity": "face2", "ok": True, "new_entity": False, "updated": {"glasses": 0.0}, "retracted": ["glasses"]},
        {"entity": "face3", "ok": False, "kind": "KnowledgeError",
         "error": "certainty of 'male' for 'face3' must be in [0, 1], got 1.5"},
    ]}
    assert store.durable_commits == commits + 1  # one fsynced transaction for the three accepted facts
    assert store.journal_length() == rows + 1  # the retraction's record, journalled as it is applied
    assert out.changes.facts == [("face9", {"male": 1.0}, True), ("face9", {"glasses": 0.9}, False),
                                 ("face2", {"glasses": 0.0}, False)]
    c = service.consultant
    assert c.entities[-1] == "face9" and c.entities.count("face9") == 1
    assert c.certainty("face9", "glasses") == 0.9 and c.certainty("face1", "male") == 1.0
    assert service.buffer.queue("face2") == ("female",)
    again = replayed(tmp_path, service)
    assert again.consultant.entities == c.entities and again.consultant.certainty("face9", "male") == 1.0
    assert again.consultant.certainty("face2", "glasses") == 0.0 and again.buffer.queue("face2") == ("female",)


def test_a_batch_the_store_refuses_changes_nothing_and_single_asserts_keep_their_errors(tmp_path):
    service = make(tmp_path)
    configure(service)
    encode(service, "face2", ["glasses"], 1.0)

    def full(batch):
        raise StoreError("state database x: database or disk is full")

    real, service.store.commit = service.store.commit, full
    with pytest.raises(StoreError, match="disk is full"):
        service.ltm_assert_batch([("face9", {"male": 1.0}), ("face2", {"glasses": 0.0})], 2.0)
    assert not service.consultant.knows_entity("face9") and service.buffer.queue("face2") == ("glasses",)
    service.store.commit = real
    # a batch of refused facts writes nothing; a single assert raises its fact's refusal, kind and all
    commits = service.store.durable_commits
    assert service.ltm_assert_batch([("face1", {"wings": 1.0})], 3.0).reply["refused"] == 1
    assert service.store.durable_commits == commits
    with pytest.raises(KnowledgeError, match="unknown property 'wings'") as refused:
        service.ltm_assert("face1", {"wings": 1.0}, 3.0)
    assert refused.value.kind == "unknown-property"
    assert service.ltm_assert("face9", {"male": 1.0}, 3.0).reply == {
        "entity": "face9", "new_entity": True, "updated": {"male": 1.0}, "retracted": []}


# ------------------------------------------------------------------ facts stored off the serving thread (28.10)
def test_batches_prepared_while_earlier_ones_are_stored_apply_as_if_one_after_the_other(tmp_path):
    service = make(tmp_path)
    configure(service, {"policy": "displacement", "capacity": 4})
    encode(service, "face1", ["glasses", "male"], 1.0)
    held, go = threading.Event(), threading.Event()

    def commit(batches):  # the writer thread: held in the commit until the test lets it go
        held.set()
        assert go.wait(30)
        service.persistence.store_facts([fact for b in batches for fact in b.prepared.stored])

    writer = FactWriter(commit)
    try:
        first = service.prepare_facts([("face9", {"male": 1.0})], 2.0)
        writer.submit(Submitted(first))
        assert held.wait(30)
        second = service.prepare_facts([("face9", {"glasses": 1.0}), ("face1", {"glasses": 0.0})], 2.0)
        writer.submit(Submitted(second))
        assert second.stored[0] == ("face9", {"glasses": 1.0}, False)  # not new: the batch in flight adds it
        assert not service.consultant.knows_entity("face9")  # stored but not acknowledged: queries do not see it
        rows = service.store.journal_length()
        go.set()
        writer.flush()
        done = writer.take_done()
        assert [err for _, err in done] == [None, None] and writer.commits == 2
        outcomes = [service.apply_facts(s.prepared) for s, _ in done]
    finally:
        go.set()
        writer.close()
    assert [o.reply["results"] for o in outcomes] == [
        [{"entity": "face9", "ok": True, "new_entity": True, "updated": {"male": 1.0}, "retracted": []}],
        [{"entity": "face9", "ok": True, "new_entity": False, "updated": {"glasses": 1.0}, "retracted": []},
         {"entity": "face1", "ok": True, "new_entity": False, "updated": {"glasses": 0.0}, "retracted": ["glasses"]}]]
    assert service.consultant.certainty("face9", "glasses") == 1.0 and service.buffer.queue("face1") == ("male",)
    assert service.store.journal_length() == rows + 1  # the retraction, journalled when applied
    assert service.facts_in_flight() == 0
    again = replayed(tmp_path, service)  # killed after the acknowledgements: everything acknowledged is back
    assert again.consultant.entities[-1] == "face9" and again.consultant.certainty("face9", "male") == 1.0
    assert again.consultant.certainty("face1", "glasses") == 0.0 and again.buffer.queue("face1") == ("male",)


def test_a_kill_between_the_commit_and_the_retraction_keeps_the_retraction(tmp_path):
    service = make(tmp_path)
    configure(service, {"policy": "displacement", "capacity": 4})
    encode(service, "face2", ["glasses", "female"], 1.0)
    prepared = service.prepare_facts([("face2", {"glasses": 0.0})], 2.0)
    service.persistence.store_facts(prepared.stored)  # durable; killed before it was applied and journalled
    again = replayed(tmp_path, service)
    assert again.consultant.certainty("face2", "glasses") == 0.0 and again.buffer.queue("face2") == ("female",)


def test_a_failed_commit_voids_the_batches_checked_against_it_and_the_next_starts_from_ltm(tmp_path):
    service = make(tmp_path)
    configure(service)
    real = service.store.commit

    def full(batch):
        raise StoreError("state database x: database or disk is full")

    service.store.commit = full
    first = service.prepare_facts([("face9", {"male": 1.0})], 2.0)
    second = service.prepare_facts([("face9", {"glasses": 1.0})], 2.0)  # checked as if the first were applied
    with pytest.raises(StoreError):
        service.persistence.store_facts(first.stored)
    service.abandon_facts(first)
    service.abandon_facts(second)  # of the voided generation: nothing more changes
    with pytest.raises(RuntimeError, match="prepared before a failed commit"):
        service.apply_facts(second)
    assert service.facts_in_flight() == 0 and not service.consultant.knows_entity("face9")
    service.store.commit = real
    third = service.prepare_facts([("face9", {"glasses": 1.0})], 3.0)
    assert third.stored == [("face9", {"glasses": 1.0}, True)]  # new again: nothing of the failed ones holds
    service.persistence.store_facts(third.stored)
    assert service.apply_facts(third).reply["results"][0]["new_entity"] is True
    again = replayed(tmp_path, service)
    assert again.consultant.certainty("face9", "glasses") == 1.0 and again.consultant.certainty("face9", "male") == 0


def test_the_threshold_waits_for_the_facts_in_flight(tmp_path):
    service = make(tmp_path)
    configure(service)
    prepared = service.prepare_facts([("face9", {"male": 0.6})], 1.0)
    with pytest.raises(RuntimeError, match="1 batches of facts are in flight"):
        service.set_threshold(0.7)
    service.persistence.store_facts(prepared.stored)
    service.apply_facts(prepared)
    assert service.set_threshold(0.7).reply["threshold"] == 0.7
    assert service.consultant.holds("male", ["face1", "face9"]) == ["face1"]


@dataclass
class Submitted:
    """What a node hands the writer: the prepared batch (its generation decides a failure's reach)."""

    prepared: PreparedFacts

    @property
    def generation(self) -> int:
        return self.prepared.generation
