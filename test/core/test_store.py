"""The consultant's state database: durability, locking, integrity, upgrade; export/restore; ticks once."""

from __future__ import annotations

import json
import math
import os
import socket
import sqlite3
import subprocess
import sys

import pytest

from fsreg_ros.core.memory.ticks import TickRun
from fsreg_ros.core.forgetting.policies import ForgettingPolicy
from fsreg_ros.core.memory import WMBuffer
from fsreg_ros.core.state.store import (
    SCHEMA_VERSION, Batch, Checkpoint, DomainStore, StateDamaged, StateInUse, StoreError, default_state_dir,
    fingerprint, legacy_state_path, state_path,
)
from fsreg_ros.core.forgetting.wm_manager import WMManager, unapplied

KB = fingerprint(["a", "b", "c"], {"e1": {"a": 1.0}, "e2": {"b": 1.0}}, 0.5, {})
TICK = {"origin": 0.0, "period": 10.0, "first": 3, "count": 1}


def store(tmp_path, kb=KB) -> DomainStore:
    return DomainStore(tmp_path / "ns" / "consultant_d" / "d.sqlite3", kb)


def read(tmp_path, kb=KB):
    """Open the store, read its state and close it again (releasing the lock)."""
    s = store(tmp_path, kb)
    try:
        return s.open()
    finally:
        s.close()


def test_a_new_store_is_created_on_first_use_in_wal_mode_and_counts_incarnations(tmp_path):
    first = store(tmp_path)
    state = first.open()
    assert state.created and state.incarnation == 1 and state.policy is None and state.queues == {}
    assert state.entities == [] and state.journal == [] and not state.other_kb
    assert state.decay_until == -math.inf and state.stamp == 0 and state.ticks == 0 and state.clock is None
    first.close()
    db = sqlite3.connect(tmp_path / "ns" / "consultant_d" / "d.sqlite3")
    assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert db.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
    db.close()
    again = store(tmp_path)
    reopened = again.open()
    assert reopened.incarnation == 2 and not reopened.created
    again.close()


def test_facts_checkpoint_journal_and_meta_survive_a_reopen(tmp_path):
    s = store(tmp_path)
    s.open()
    s.commit(Batch(facts=("e3", {"a": 1.0, "c": 0.9}, True)))
    s.commit(Batch(facts=("e1", {"a": 0.0}, False)))  # a retraction of a KB fact
    s.commit(Batch(facts=("e3", {"c": 0.2}, False), records=[["remove", "e3", ["c"], 4.0]]))
    s.commit(Batch(checkpoint=Checkpoint({"e2": [("b", 3, 1, "rr", 2)], "e3": [("a", 4, 1, "speaker", None)]},
                                         5, 2, {"policy": "decay", "decay_period": 10.0}),
                   meta={"decay_until": 20.0, "clock": "sim", "latest": 21.5,
                         "policy": {"policy": "decay", "decay_period": 10.0}}))
    s.commit(Batch(records=[["each", "b", ["e1", "e3"], "reg-distractor", 22.0, 7], ["decay", TICK]]))
    s.close()
    state = read(tmp_path)
    assert state.incarnation == 2
    assert state.entities == ["e3"]
    assert state.facts == {"e3": {"a": 1.0, "c": 0.2}, "e1": {"a": 0.0}}
    assert state.queues == {"e2": [("b", 3, 1, "rr", 2)], "e3": [("a", 4, 1, "speaker", None)]}
    assert (state.stamp, state.ticks, state.limits) == (5, 2, {"policy": "decay", "decay_period": 10.0})
    assert state.journal == [["each", "b", ["e1", "e3"], "reg-distractor", 22.0, 7], ["decay", TICK]]
    assert (state.decay_until, state.clock, state.latest) == (20.0, "sim", 21.5)
    assert state.policy == {"policy": "decay", "decay_period": 10.0}


def test_a_checkpoint_empties_the_journal_deletes_emptied_queues_and_can_clear_them_all(tmp_path):
    s = store(tmp_path)
    s.open()
    s.commit(Batch(checkpoint=Checkpoint({"e1": [("a", 1, 1, "rr", 0)], "e2": [("b", 2, 1, "rr", 0)]}, 2, 0, None)))
    s.commit(Batch(records=[["encode", "e1", ["c"], "speaker", 1.0, 1]]))
    assert s.journal_length() == 1
    s.commit(Batch(checkpoint=Checkpoint({"e1": []}, 3, 0, None)))  # an emptied queue is deleted
    assert s.journal_length() == 0
    s.close()
    assert read(tmp_path).queues == {"e2": [("b", 2, 1, "rr", 0)]}
    s = store(tmp_path)
    s.open()
    s.commit(Batch(checkpoint=Checkpoint({"e3": [("c", 4, 1, "rr", 1)]}, 4, 0, None, clear=True)))
    s.close()
    assert read(tmp_path).queues == {"e3": [("c", 4, 1, "rr", 1)]}


def test_only_facts_are_fsynced_wm_commits_use_synchronous_normal(tmp_path):
    s = store(tmp_path)
    s.open()
    seen = []
    s._db.set_trace_callback(seen.append)
    s.commit(Batch(records=[["evict", 1, 2.0]]))
    assert not any("synchronous" in sql for sql in seen)
    s.commit(Batch(facts=("e9", {"a": 1.0}, True)))
    assert [sql for sql in seen if "synchronous" in sql] == ["PRAGMA synchronous=FULL", "PRAGMA synchronous=NORMAL"]
    assert s._db.execute("PRAGMA synchronous").fetchone()[0] == 1  # NORMAL
    s.close()


def test_a_second_live_opener_is_refused_naming_the_file_and_the_holders_pid(tmp_path):
    first = store(tmp_path)
    first.open()
    with pytest.raises(StateInUse) as err:
        store(tmp_path).open()
    text = str(err.value)
    assert str(first.path) in text and f"process {os.getpid()}" in text and "\n" not in text
    first.close()  # released: the next opener gets it
    second = store(tmp_path)
    assert second.open().incarnation == 2
    second.close()


def test_a_holder_in_another_process_is_named_by_the_kernel_not_by_the_pid_in_the_lock_file(tmp_path):
    path = store(tmp_path).path
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time\nfrom fsreg_ros.core.state.store import DomainStore\n"
         f"s = DomainStore({str(path)!r}, {KB!r}); s.open(); print('open', flush=True); time.sleep(60)"],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "open"
        lock = path.with_name(path.name + ".lock")
        lock.write_text("424242\n")  # a lie: only the kernel knows who holds the lock
        with pytest.raises(StateInUse) as err:
            store(tmp_path).open()
        text = str(err.value)
        assert f"in use by process {holder.pid} (" in text and "424242" not in text and "\n" not in text, text
    finally:
        holder.kill()
        holder.wait()
    again = store(tmp_path)  # the holder died: its locks went with it
    assert again.open().incarnation == 2
    again.close()


def test_a_holder_with_only_a_flock_is_found_in_proc_locks(tmp_path):
    path = store(tmp_path).path
    path.parent.mkdir(parents=True)
    lock = path.with_name(path.name + ".lock")
    holder = subprocess.Popen(
        [sys.executable, "-c", f"import fcntl, os, time\nfd = os.open({str(lock)!r}, os.O_RDWR | os.O_CREAT)\n"
         "fcntl.flock(fd, fcntl.LOCK_EX)\nprint('locked', flush=True)\ntime.sleep(60)"],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(StateInUse, match=f"in use by process {holder.pid} \\("):
            store(tmp_path).open()
    finally:
        holder.kill()
        holder.wait()


@pytest.mark.parametrize("make, kind", [
    (os.mkfifo, "a named pipe (FIFO)"),
    (os.mkdir, "a directory"),
    (lambda p: socket.socket(socket.AF_UNIX).bind(str(p)), "a socket"),
])
def test_a_state_path_that_is_not_a_regular_file_is_refused_as_what_it_is(tmp_path, make, kind):
    path = store(tmp_path).path
    path.parent.mkdir(parents=True)
    make(path)
    with pytest.raises(StateDamaged) as err:
        store(tmp_path).open()
    text = str(err.value)
    assert text.startswith(f"state database {path}: it is {kind}, not a database file;"), text
    assert "empty" not in text and "\n" not in text


def test_a_lock_file_that_is_a_fifo_is_refused_as_one(tmp_path):
    path = store(tmp_path).path
    path.parent.mkdir(parents=True)
    os.mkfifo(path.with_name(path.name + ".lock"))
    with pytest.raises(StateDamaged, match="the lock file is a named pipe \\(FIFO\\), not a regular file"):
        store(tmp_path).open()


def test_the_state_path_holds_the_ros_domain_id_and_the_namespace(tmp_path):
    a = state_path(tmp_path, 3, "/robot1/consultant_faces", "faces")
    assert a == tmp_path / "ros_domain_3" / "robot1" / "consultant_faces" / "faces.sqlite3"
    assert len({a, state_path(tmp_path, 4, "/robot1/consultant_faces", "faces"),
                state_path(tmp_path, 3, "/robot2/consultant_faces", "faces"),
                state_path(tmp_path, 3, "/consultant_faces", "faces")}) == 4
    assert legacy_state_path(tmp_path, "/consultant_faces", "faces") == tmp_path / "consultant_faces" / "faces.sqlite3"


def test_reset_moves_the_old_database_aside_and_starts_afresh(tmp_path):
    s = store(tmp_path)
    s.open()
    s.commit(Batch(facts=("e3", {"a": 1.0}, True)))
    s.close()
    again = store(tmp_path)
    state = again.open(reset=True)
    again.close()
    assert state.created and state.incarnation == 1 and state.facts == {}
    assert state.moved_aside is not None and state.moved_aside.name.endswith(".old")
    old = sqlite3.connect(state.moved_aside)
    assert old.execute("SELECT entity FROM facts").fetchall() == [("e3",)]
    old.close()


def test_a_store_of_another_kb_is_read_for_migration_not_moved_away(tmp_path):
    s = store(tmp_path)
    s.open()
    s.commit(Batch(facts=("e3", {"a": 1.0}, True)))
    s.close()
    other = store(tmp_path, kb="another")
    state = other.open()
    assert state.other_kb and state.incarnation == 2 and state.facts == {"e3": {"a": 1.0}}
    state.facts = {"e3": {"a": 1.0}}
    backup = other.rewrite(state)
    other.close()
    assert backup is not None and backup.exists()
    migrated = read(tmp_path, kb="another")
    assert not migrated.other_kb and migrated.facts == {"e3": {"a": 1.0}} and migrated.entities == ["e3"]


def damage_empty(path):
    path.write_bytes(b"")


def damage_not_a_database(path):
    path.write_bytes(b"not a database" * 100)


def damage_drop_facts(path):
    db = sqlite3.connect(path)
    db.execute("DROP TABLE facts")
    db.commit()
    db.close()


def damage_queue_row(path):
    db = sqlite3.connect(path)
    db.execute("INSERT INTO queues VALUES ('e1', '[[\"a\", \"x\", 1, \"rr\", null]]')")
    db.commit()
    db.close()


def damage_journal_row(path):
    db = sqlite3.connect(path)
    db.execute("INSERT INTO journal (record) VALUES ('{not json')")
    db.commit()
    db.close()


def damage_schema_version(path):
    db = sqlite3.connect(path)
    db.execute("PRAGMA user_version = 9")
    db.close()


def damage_certainty(path):
    db = sqlite3.connect(path)
    db.execute("INSERT INTO facts VALUES ('e1', 'a', 7.5)")
    db.commit()
    db.close()


@pytest.mark.parametrize("damage, problem", [
    (damage_empty, "the file is empty (0 bytes)"),
    (damage_not_a_database, "not a readable SQLite database"),
    (damage_drop_facts, "table 'facts' is missing"),
    (damage_queue_row, "the WM queue of 'e1' is malformed"),
    (damage_journal_row, "journal record 1 is not JSON"),
    (damage_schema_version, "schema version 9"),
    (damage_certainty, "certainty 7.5"),
])
def test_a_damaged_database_is_refused_with_one_line_naming_the_file_and_the_way_out(tmp_path, damage, problem):
    s = store(tmp_path)
    s.open()
    s.close()
    damage(s.path)
    with pytest.raises(StateDamaged) as err:
        store(tmp_path).open()
    text = str(err.value)
    assert text.startswith(f"state database {s.path}: ") and problem in text, text
    assert "reset_state:=true" in text and "\n" not in text
    again = store(tmp_path)  # the lock was released: the way out works
    assert again.open(reset=True).created
    again.close()


def test_a_version_1_database_is_upgraded_in_place(tmp_path):
    path = tmp_path / "v1.sqlite3"
    db = sqlite3.connect(path)
    db.executescript("""
        CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
        CREATE TABLE entities (seq INTEGER PRIMARY KEY, name TEXT NOT NULL UNIQUE);
        CREATE TABLE facts (entity TEXT NOT NULL, property TEXT NOT NULL, certainty REAL NOT NULL,
                            PRIMARY KEY (entity, property));
        CREATE TABLE queues (entity TEXT PRIMARY KEY, items TEXT NOT NULL);
        PRAGMA user_version = 1;
    """)
    db.executemany("INSERT INTO meta VALUES (?, ?)", [("kb", json.dumps(KB)), ("incarnation", "3"), ("stamp", "9"),
                                                      ("ticks", "2"), ("policy", '{"policy": "displacement", '
                                                                                 '"capacity": 2}')])
    db.execute("INSERT INTO queues VALUES ('e1', '[[\"a\", 8, 1], [\"b\", 9, 2]]')")
    db.commit()
    db.close()
    s = DomainStore(path, KB)
    state = s.open()
    s.close()
    assert state.found_version == 1 and state.incarnation == 4
    assert state.queues == {"e1": [("a", 8, 1, "unknown", None), ("b", 9, 2, "unknown", None)]}
    assert (state.stamp, state.ticks, state.limits) == (9, 2, {"policy": "displacement", "capacity": 2})
    assert DomainStore(path, KB).open().found_version == SCHEMA_VERSION


def test_a_full_disk_refuses_the_write_and_keeps_what_was_stored(tmp_path):
    s = store(tmp_path)
    s.open()
    s.commit(Batch(facts=("e3", {"a": 1.0}, True)))
    pages = s._db.execute("PRAGMA page_count").fetchone()[0]
    s.execute(f"PRAGMA max_page_count = {pages}")
    big = {f"p{i}": 1.0 for i in range(2000)}
    with pytest.raises(StoreError, match="database or disk is full"):
        s.commit(Batch(facts=("e4", big, True)))
    s.close()
    state = read(tmp_path)
    assert state.facts == {"e3": {"a": 1.0}} and state.entities == ["e3"]


def test_default_state_dir_follows_xdg_state_home(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path))
    assert default_state_dir() == tmp_path / "fsreg_ros"


def test_buffer_export_and_restore_continue_exactly_as_the_original():
    """A buffer restored from its exported queues and counters behaves as the original from then on."""
    policy = ForgettingPolicy.from_settings({"policy": "decay+displacement-lfu", "decay_period": 10.0, "capacity": 2})
    original = WMBuffer("d")
    original.set_limits(policy.limits(), 0.0)
    for i, (entity, prop) in enumerate([("e1", "a"), ("e1", "b"), ("e1", "a"), ("e2", "c"), ("e1", "c")]):
        original.encode(entity, prop, "speaker", float(i))
    original.decay_now(TickRun(0.0, 10.0, 1, 1), ["e1", "e2"])
    copy = WMBuffer("d")
    copy.restore({e: original.export_queue(e) for e in original.nonempty_entities()}, *original.counters(),
                 policy.limits())
    assert copy.snapshot() == original.snapshot() and copy.counters() == original.counters()
    for buffer in (original, copy):
        buffer.encode("e1", "b", "speaker", 12.0)  # LFU: the victim depends on the restored hit counts
        buffer.encode("e2", "a", "rr", 13.0)
        buffer.decay_now(TickRun(0.0, 10.0, 2, 1), ["e1", "e2"])
    assert copy.snapshot() == original.snapshot()
    assert [copy.export_queue(e) for e in ("e1", "e2")] == [original.export_queue(e) for e in ("e1", "e2")]


def test_unapplied_skips_ticks_already_applied_in_constant_time():
    run = TickRun(0.0, 10.0, 1, 5)  # ticks at 10, 20, 30, 40, 50
    assert unapplied(run, -math.inf) == run
    assert unapplied(run, 30.0) == TickRun(0.0, 10.0, 4, 2)
    assert unapplied(run, 35.0) == TickRun(0.0, 10.0, 4, 2)
    assert unapplied(run, 50.0) is None and unapplied(run, 1e9) is None
    far = TickRun(0.1, 0.1, 0, 10**15)
    assert unapplied(far, 0.1 + 0.1 * 10**12).first == 10**12 + 1


def test_the_manager_resends_unacknowledged_ticks_in_time_order_and_the_consultant_applies_them_once():
    buffer = WMBuffer("d")
    manager = WMManager()
    manager.manage(buffer, ForgettingPolicy.from_settings({"policy": "decay", "decay_period": 10.0}), 0.0)
    sent = []

    class Port:
        def configure(self, domain, policy, time):
            sent.append(("configure", policy.name))

        def decay(self, domain, ticks):
            sent.append(("decay", ticks))

    manager.port = Port()
    manager.advance(25.0)  # ticks 10, 20 sent
    manager.detach("d")
    manager.owe("d", TickRun(0.0, 10.0, 1, 2))  # their reply was lost: owed again
    manager.advance(45.0)  # ticks 30, 40 owed while detached
    sent.clear()
    manager.attach("d", 2, 45.0)
    runs = [t for kind, t in sent if kind == "decay"]
    assert [(r.time(0), r.last) for r in runs] == [(10.0, 40.0)] and sent[-1] == ("configure", "decay")
    applied_until, popped = 20.0, []  # the consultant had applied 10 and 20 before it was killed
    for run in runs:
        due = unapplied(run, applied_until)
        if due is not None:
            popped += [due.time(i) for i in range(due.count)]
            applied_until = due.last
    assert popped == [30.0, 40.0]
