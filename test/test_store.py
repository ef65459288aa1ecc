"""The consultant's state database (core.store), the buffer's export/restore, and ticks applied once."""

from __future__ import annotations

import math
import sqlite3

import pytest

from fsreg_ros.core.decay import TickRun
from fsreg_ros.core.forgetting import ForgettingPolicy
from fsreg_ros.core.memory import WMBuffer
from fsreg_ros.core.store import DomainStore, StoreError, default_state_dir, fingerprint
from fsreg_ros.core.wm_manager import WMManager, unapplied

KB = fingerprint(["a", "b", "c"], {"e1": {"a": 1.0}, "e2": {"b": 1.0}}, 0.5, {})


def store(tmp_path, kb=KB) -> DomainStore:
    return DomainStore(tmp_path / "ns" / "consultant_d" / "d.sqlite3", kb)


def test_a_new_store_is_created_on_first_use_in_wal_mode_and_counts_incarnations(tmp_path):
    first = store(tmp_path)
    state = first.open()
    assert state.incarnation == 1 and state.policy is None and state.queues == {} and state.entities == []
    assert state.decay_until == -math.inf and state.stamp == 0 and state.ticks == 0
    first.close()
    db = sqlite3.connect(tmp_path / "ns" / "consultant_d" / "d.sqlite3")
    assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    db.close()
    again = store(tmp_path)
    assert again.open().incarnation == 2
    again.close()


def test_facts_queues_counters_policy_and_decay_ledger_survive_a_reopen(tmp_path):
    s = store(tmp_path)
    s.open()
    s.save_facts("e3", {"a": 1.0, "c": 0.9}, True)
    s.save_facts("e1", {"a": 0.0}, False)  # a retraction of a KB fact
    s.save_facts("e3", {"c": 0.2}, False)  # a later certainty wins
    s.save_wm({"e2": [("b", 3, 1)], "e3": [("a", 4, 1), ("c", 5, 2)]}, (5, 2), decay_until=20.0,
              policy={"policy": "decay", "decay_period": 10.0})
    s.save_wm({"e2": []}, (6, 2))  # an emptied queue is deleted
    s.close()
    state = store(tmp_path).open()
    assert state.incarnation == 2
    assert state.entities == ["e3"]
    assert state.facts == {"e3": {"a": 1.0, "c": 0.2}, "e1": {"a": 0.0}}
    assert state.queues == {"e3": [("a", 4, 1), ("c", 5, 2)]}
    assert (state.stamp, state.ticks, state.decay_until) == (6, 2, 20.0)
    assert state.policy == {"policy": "decay", "decay_period": 10.0}


def test_a_store_of_another_kb_is_moved_aside_not_reused(tmp_path):
    s = store(tmp_path)
    s.open()
    s.save_facts("e3", {"a": 1.0}, True)
    s.close()
    other = store(tmp_path, kb="another")
    state = other.open()
    assert state.incarnation == 1 and state.facts == {} and state.discarded is not None
    assert state.discarded.exists() and state.discarded.name.endswith(".old")


def test_an_unusable_path_is_one_clear_error(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(StoreError, match="state database .*file"):
        DomainStore(tmp_path / "file" / "d.sqlite3", KB).open()
    (tmp_path / "junk.sqlite3").write_bytes(b"not a database" * 100)
    with pytest.raises(StoreError, match="junk.sqlite3"):
        DomainStore(tmp_path / "junk.sqlite3", KB).open()


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
