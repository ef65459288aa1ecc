#!/usr/bin/env python3
"""Benchmark what persistence costs a consultant per dialogue turn, at 16 and 10,000 entities.

One turn is what the graph's consultant does for a dialogue turn, through the core
:class:`~fsreg_ros.core.consultant.service.ConsultantService` exactly as the node calls it (one
``apply`` per service call, so one commit per call): a decay tick when one falls due
(delta 10 s), then a human turn (RR: ``open`` with the first property, ``narrow`` per
further property, ``close`` with the description, rules 1 and 2) or a robot turn (REG:
``open`` of the target, ``narrow`` per considered property, ``close``, rules 1 and 3),
alternating, in a random world (:mod:`fsreg_ros.tools.worlds`; policy decay+displacement,
capacity 3).  The same calls run twice in the same process, on two identical
consultants: one service without a store (the core) and one with its state database
(the defaults: WM persisted as a journal record per call in WAL mode with
``synchronous=NORMAL``; a checkpoint when the journal is long, written by the node
when idle and timed here separately).

Reported per world size: core turn p50/p95 (ms), turn with persistence p50/p95, the
persistence itself per turn (the time spent in the store's commits, measured around
them: two 10,000-entity worlds interleaved in one process make the difference of the
turn medians noisy) and its ratio to the core turn, journal rows per turn, the
checkpoint (ms, queues written) and the restore at start (load the checkpoint, replay
the journal; here a journal as long as the run, never checkpointed).  The earlier design (every changed queue
rewritten per call, ``synchronous=FULL``) is timed on the same turns for comparison
(``--no-baseline`` to skip).

Usage: ``scripts/bench_store.py [--turns N] [--sizes 16,10000] [--seed S] [--dir DIR]``.
"""

from __future__ import annotations

import argparse
import json
import random
import statistics
import sqlite3
import sys
import tempfile
import time
from pathlib import Path

from venv_python import prepare  # noqa: E402

prepare("bench_store.py")  # .venv, import path

from fsreg_ros.ros.consultant_ops import apply  # noqa: E402
from fsreg_ros.core.consultant.consultant import Consultant  # noqa: E402
from fsreg_ros.core.algorithms.generation import generate  # noqa: E402
from fsreg_ros.core.algorithms.port import Narrowed, View, Walked, run_sync  # noqa: E402
from fsreg_ros.core.algorithms.resolution import resolve  # noqa: E402
from fsreg_ros.core.consultant.service import ConsultantService  # noqa: E402
from fsreg_ros.core.state.store import DomainStore  # noqa: E402
from fsreg_ros.tools.worlds import DOMAIN, WorldShape, random_world  # noqa: E402

POLICY = {"policy": "decay+displacement", "decay_period": 10.0, "capacity": 3}


def p95(values: list[float]) -> float:
    return statistics.quantiles(values, n=20, method="inclusive")[18] if len(values) > 1 else values[0]


class ApplyPort:
    """A consultant port whose every call is one ``ConsultantService.apply``, as the node runs a service call."""

    def __init__(self, service: ConsultantService, after=None) -> None:
        self.service = service
        self.domain = service.domain
        self.after = after or (lambda changed: None)  # run after each call (the earlier design's write)

    def _apply(self, op: str, request: dict) -> dict:
        outcome = apply(self.service, op, {"op": op, **request})
        self.after(outcome.changes.queues)
        return outcome.reply

    async def preference(self) -> list[str]:
        return list(self.service.consultant.preference)

    async def open(self, target=None, context=None, first=None, refer=None) -> View:
        request: dict = {"target": target} if target is not None else {}
        if first is not None:
            request["first"] = {"property": first.prop, "cause": first.cause, "time": first.time, "turn": first.turn}
        if refer is not None:
            request["refer"] = {"id": refer.id, "time": refer.time, "turn": refer.turn}
        reply = self._apply("open", request)
        view = View(reply["session"], reply["size"], reply["queue"], reply["retains"],
                    frozenset(reply["holding"]) if reply["holding"] is not None else None)
        if first is not None:
            view.first = Narrowed(reply["first"]["target_holds"], reply["first"]["size"])
        return view

    async def narrow(self, view: View, prop, cause, time, turn) -> Narrowed:
        reply = self._apply("narrow", {"session": view.handle, "property": prop, "cause": cause, "time": time,
                                       "turn": turn})
        return Narrowed(reply["target_holds"], reply["size"])

    async def walk(self, view: View, steps, cause, time, turn, size=None) -> Walked:
        reply = self._apply("walk", {"session": view.handle, "cause": cause, "time": time, "turn": turn,
                                     "steps": [{"property": step.prop, "group": step.group} for step in steps]})
        return Walked(tuple(reply["taken"]), reply["size"], reply["narrowed"])

    async def rule_out(self, view: View):
        reply = self._apply("rule_out", {"session": view.handle})
        return reply["properties"], [int(m, 16) for m in reply["masks"]]

    async def close(self, view: View, encode=(), time=0.0, turn=None) -> list[str]:
        return self._apply("close", {"session": view.handle, "encode": list(encode), "time": time,
                                     "turn": turn})["members"]


def run_turn(port: ApplyPort, turn: dict, index: int, target: str) -> None:
    """One dialogue turn: the decay ticks due, then RR (human) or SD-PIA (robot)."""
    t = turn["time"]
    due = int(t // 10.0)
    if due >= 1 and "decay" in port.service.policy.rules:  # ticks already applied are skipped (applied once)
        port._apply("decay", {"ticks": {"origin": 0.0, "period": 10.0, "first": 1, "count": due}})
    if turn["speaker"] == "human":
        run_sync(resolve(turn["description"], {DOMAIN: port}, domain=DOMAIN, time=t, turn=index))
    else:
        run_sync(generate(target, port, "sd-pia", time=t, turn=index))


class TimedStore(DomainStore):
    """A state database that adds up the time its commits take."""

    spent = 0.0

    def commit(self, batch) -> None:
        start = time.perf_counter()
        try:
            super().commit(batch)
        finally:
            self.spent += time.perf_counter() - start


def make(world: dict, store: DomainStore | None) -> ConsultantService:
    domain = world["domains"][DOMAIN]
    facts = {e: {p: 1.0 for p in props} for e, props in domain["entities"].items()}
    service = ConsultantService(Consultant(DOMAIN, facts, domain["preference"]), store=store)
    if store is not None:
        service.restore(store.open())
    apply(service, "configure", {"op": "configure", "policy": POLICY, "time": 0.0})
    return service


def bench(entities: int, turns: int, seed: int, directory: Path, baseline: bool) -> dict:
    world = random_world(WorldShape(entities=entities, human_turns=turns, robot_turns=turns, seed=seed))
    path = directory / f"bench-{entities}.sqlite3"
    core, stored = make(world, None), make(world, TimedStore(path, f"bench-{entities}"))
    old = _OldStore(directory / f"old-{entities}.sqlite3", make(world, None)) if baseline else None
    rng = random.Random(seed)
    core_ms, stored_ms, rows, old_ms, commit_ms = [], [], [], [], []
    for index, turn in enumerate(world["dialogue"]):
        target = turn.get("target") or rng.choice(core.consultant.entities)
        for service, times in ((core, core_ms), (stored, stored_ms)):
            before = service.store.journal_length() if service.store is not None else 0
            spent = service.store.spent if service.store is not None else 0.0
            start = time.perf_counter()
            run_turn(ApplyPort(service), turn, index, target)
            times.append((time.perf_counter() - start) * 1e3)
            if service.store is not None:
                rows.append(service.store.journal_length() - before)
                commit_ms.append((service.store.spent - spent) * 1e3)
        if old is not None:
            start = time.perf_counter()
            run_turn(old.port, turn, index, target)
            old_ms.append((time.perf_counter() - start) * 1e3)
    assert core.buffer.snapshot() == stored.buffer.snapshot(), "the two consultants diverged"
    unsaved, journal = len(stored.persistence._unsaved), stored.store.journal_length()
    start = time.perf_counter()
    stored.maintain()  # what the node's timer does when the journal is long (forced here)
    stored.persistence._write(checkpoint=True)
    checkpoint_ms = (time.perf_counter() - start) * 1e3
    expected = stored.buffer.snapshot()
    stored.store.close()
    # the restore a restarted consultant does: from a journal as long as this run left it
    replay_path = directory / f"replay-{entities}.sqlite3"
    replay = make(world, DomainStore(replay_path, f"bench-{entities}"))
    for index, turn in enumerate(world["dialogue"]):
        run_turn(ApplyPort(replay), turn, index, rng.choice(core.consultant.entities) if not turn.get("target")
                 else turn["target"])
    replay.store.close()
    restored, restore_ms = make_restored(world, path, entities)
    assert restored.buffer.snapshot() == expected, "the restored WM differs"
    core_p50, stored_p50 = statistics.median(core_ms), statistics.median(stored_ms)
    return {"entities": entities, "turns": len(core_ms), "core_p50": core_p50, "core_p95": p95(core_ms),
            "stored_p50": stored_p50, "stored_p95": p95(stored_ms), "persist_p50": statistics.median(commit_ms),
            "persist_p95": p95(commit_ms), "ratio": statistics.median(commit_ms) / core_p50,
            "rows_p50": statistics.median(rows),
            "checkpoint_ms": checkpoint_ms, "checkpoint_queues": unsaved, "journal": journal,
            "restore_ms": restore_ms, "replay_ms": make_restored(world, replay_path, entities)[1],
            "old_p50": statistics.median(old_ms) if old_ms else None}


def make_restored(world: dict, path: Path, entities: int) -> tuple[ConsultantService, float]:
    domain = world["domains"][DOMAIN]
    facts = {e: {p: 1.0 for p in props} for e, props in domain["entities"].items()}
    store = DomainStore(path, f"bench-{entities}")
    start = time.perf_counter()
    service = ConsultantService(Consultant(DOMAIN, facts, domain["preference"]), store=store)
    service.restore(store.open())
    elapsed = (time.perf_counter() - start) * 1e3
    store.close()
    return service, elapsed


class _OldStore:
    """The earlier persistence, for comparison: each call's changed queues rewritten, ``synchronous=FULL``."""

    def __init__(self, path: Path, service: ConsultantService) -> None:
        self.db = sqlite3.connect(str(path), isolation_level=None)
        self.db.execute("PRAGMA journal_mode=WAL")
        self.db.execute("PRAGMA synchronous=FULL")
        self.db.execute("CREATE TABLE queues (entity TEXT PRIMARY KEY, items TEXT NOT NULL)")
        self.service = service
        self.port = ApplyPort(service, self.write)

    def write(self, _: list[str]) -> None:
        changed = self.service.buffer.take_changes()  # this call's changed queues, as that design took them
        export = self.service.buffer.export_queue
        self.db.execute("BEGIN IMMEDIATE")
        self.db.executemany("INSERT INTO queues VALUES (?, ?) ON CONFLICT(entity) DO UPDATE SET items = "
                            "excluded.items", [(e, json.dumps(export(e))) for e in changed])
        self.db.execute("COMMIT")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--turns", type=int, default=100, help="human and robot turns each (default 100)")
    parser.add_argument("--sizes", default="16,10000", help="world sizes, comma-separated (default 16,10000)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--dir", type=Path, help="directory of the databases (default: a temporary one)")
    parser.add_argument("--no-baseline", action="store_true", help="do not time the earlier design")
    args = parser.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",")]
    with tempfile.TemporaryDirectory(prefix="fsreg-bench-store-", dir=args.dir) as tmp:
        print(f"{'entities':>9} {'turns':>6} {'core p50/p95':>15} {'stored p50/p95':>16} {'persist p50/p95':>16} "
              f"{'/core':>6} {'rows':>5} {'checkpoint ms (queues)':>23} {'restore ms (journal)':>21} "
              f"{'earlier p50':>12}")
        for size in sizes:
            r = bench(size, args.turns, args.seed, Path(tmp), not args.no_baseline)
            old = f"{r['old_p50']:>12.2f}" if r["old_p50"] is not None else f"{'-':>12}"
            print(f"{r['entities']:>9} {r['turns']:>6} {r['core_p50']:>7.2f}/{r['core_p95']:<7.2f} "
                  f"{r['stored_p50']:>8.2f}/{r['stored_p95']:<7.2f} {r['persist_p50']:>8.2f}/{r['persist_p95']:<7.2f} "
                  f"{r['ratio']:>6.2f} "
                  f"{r['rows_p50']:>5.0f} {r['checkpoint_ms']:>14.1f} ({r['checkpoint_queues']:>5}) "
                  f"{r['replay_ms']:>12.1f} ({r['journal']:>5}) {old}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
