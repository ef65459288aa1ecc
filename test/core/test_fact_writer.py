"""The writer thread that commits facts off the serving thread (group commit).

No timing: the writer's commit is held on an event, so what is queued behind it is
known exactly; ``flush`` waits for it.  The service's two steps around it (prepare, apply)
are tested in test_consultant_service.py.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import pytest

from fsreg_ros.core.state.fact_writer import FactWriter
from fsreg_ros.core.state.store import StoreError


@dataclass
class Item:
    name: str
    generation: int = 0


class Gate:
    """A commit function that records each group and, while closed, holds the writer inside the commit."""

    def __init__(self, fail: set[str] = frozenset()) -> None:
        self.groups: list[list[str]] = []
        self.entered = threading.Event()
        self.open = threading.Event()
        self.fail = fail

    def __call__(self, batches) -> None:
        self.entered.set()
        assert self.open.wait(30), "the test never opened the gate"
        names = [getattr(b, "name", "?") for b in batches]
        self.groups.append(names)
        if self.fail & set(names):
            raise StoreError("state database x: database or disk is full")


def test_batches_submitted_during_a_commit_go_in_one_commit_and_come_back_in_order():
    gate = Gate()
    writer = FactWriter(gate)
    try:
        writer.submit(Item("a"))
        assert gate.entered.wait(30)  # the writer holds "a" in its commit ...
        for name in "bcd":  # ... while three more are submitted
            writer.submit(Item(name))
        assert writer.take_done() == [] and writer.in_flight() == 4  # nothing is done before its commit returns
        gate.open.set()
        writer.flush()
        assert gate.groups == [["a"], ["b", "c", "d"]]  # one transaction for everything that waited
        assert [(b.name, err) for b, err in writer.take_done()] == [("a", None), ("b", None), ("c", None),
                                                                    ("d", None)]
        assert writer.commits == 2 and writer.in_flight() == 0
    finally:
        gate.open.set()
        writer.close()


def test_a_failed_commit_fails_every_batch_checked_against_it_and_not_the_next_generation():
    gate = Gate(fail={"a"})
    woken = []
    writer = FactWriter(gate, notify=lambda: woken.append(1))
    try:
        writer.submit(Item("a"))
        assert gate.entered.wait(30)
        writer.submit(Item("b"))  # prepared while "a" was in flight: checked as if "a" were applied
        gate.open.set()
        writer.flush()
        done = writer.take_done()
        assert [b.name for b, _ in done] == ["a", "b"]
        assert str(done[0][1]) == "state database x: database or disk is full"
        writer.submit(Item("c"))  # still of generation 0: submitted before the failure was handled
        writer.submit(Item("d", generation=1))  # prepared after it (a new generation)
        writer.flush()
        done += writer.take_done()
        names = [(b.name, err is None) for b, err in done]
        assert names == [("a", False), ("b", False), ("c", False), ("d", True)]
        assert "an earlier commit of facts failed" in str(done[1][1]) and "nothing of this one" in str(done[1][1])
        assert ["b"] not in gate.groups and ["c"] not in gate.groups  # never written
        assert woken  # the serving thread is woken for each group done
    finally:
        gate.open.set()
        writer.close()


def test_close_commits_what_is_queued():
    gate = Gate()
    gate.open.set()
    writer = FactWriter(gate)
    for name in "xy":
        writer.submit(Item(name))
    writer.close()
    assert [b.name for b, _ in writer.take_done()] == ["x", "y"]
    with pytest.raises(RuntimeError, match="closed"):
        writer.submit(Item("z"))
