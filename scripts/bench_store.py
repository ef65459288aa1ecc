#!/usr/bin/env python3
"""Benchmark the cost of persisting WM per turn (fsreg_ros.core.store), at 16 and 10,000 entities.

A consultant's turn is what the graph does per dialogue turn: a decay tick when one
falls due (delta 10 s), then a human turn (the description encoded into the named
entity, as RR does) or a robot turn (one SD-PIA ``generate`` call, which encodes the
target's description and every distractor it rules out, rule 3), alternating, in a
random world (:mod:`fsreg_ros.worlds`: 40 attributes x 5 values; policy
decay+displacement, capacity 3).  The event sink records which queues each turn
changed, as the consultant node does; the turn's persistence is then one
``DomainStore.save_wm`` transaction with those queues and the buffer's counters, in
WAL mode with ``synchronous=FULL`` (an fsync per turn) -- exactly what the node does
before it replies.

Reported per world size: median and p95 of the core turn (ms), of the persistence
(ms), queues written per turn, and persistence / core.  The database lives in a
temporary directory (``--dir`` to choose the disk).

Usage: ``scripts/bench_store.py [--turns N] [--sizes 16,10000] [--seed S] [--dir DIR]``.
"""

from __future__ import annotations

import argparse
import random
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))
from venv_python import use_venv  # noqa: E402

use_venv()  # run with .venv/bin/python, however started

from fsreg_ros.core.consultant import Consultant, LocalPort, run_sync  # noqa: E402
from fsreg_ros.core.decay import TickRun  # noqa: E402
from fsreg_ros.core.forgetting import ForgettingPolicy  # noqa: E402
from fsreg_ros.core.generation import generate  # noqa: E402
from fsreg_ros.core.store import DomainStore  # noqa: E402
from fsreg_ros.core.wm_manager import apply_ticks, configure_buffer  # noqa: E402
from fsreg_ros.worlds import DOMAIN, WorldShape, random_world  # noqa: E402

POLICY = {"policy": "decay+displacement", "decay_period": 10.0, "capacity": 3}


def p95(values: list[float]) -> float:
    return statistics.quantiles(values, n=20, method="inclusive")[18] if len(values) > 1 else values[0]


def bench(entities: int, turns: int, seed: int, directory: Path) -> dict:
    world = random_world(WorldShape(entities=entities, human_turns=turns, robot_turns=turns, seed=seed))
    domain = world["domains"][DOMAIN]
    facts = {e: {p: 1.0 for p in props} for e, props in domain["entities"].items()}
    dirty: dict[str, None] = {}
    consultant = Consultant(DOMAIN, facts, domain["preference"], sink=lambda event: dirty.setdefault(event.entity))
    policy = ForgettingPolicy.from_settings(POLICY)
    configure_buffer(consultant.wm, policy, 0.0)
    store = DomainStore(directory / f"bench-{entities}.sqlite3", f"bench-{entities}")
    store.open()
    store.save_wm({}, consultant.wm.counters(), policy=policy.settings())
    port = LocalPort(consultant)
    rng = random.Random(seed)
    names = list(consultant.entities)
    core, persist, written = [], [], []
    applied = 0
    for index, turn in enumerate(world["dialogue"]):
        t = turn["time"]
        start = time.perf_counter()
        due = int(t // 10.0) - applied
        if due > 0:
            apply_ticks(consultant.wm, TickRun(0.0, 10.0, applied + 1, due), consultant.entities)
            applied += due
        if turn["speaker"] == "human":
            consultant.encode(turn["target"], turn["description"], "speaker", t, index)
        else:
            run_sync(generate(turn.get("target") or rng.choice(names), port, "sd-pia", time=t, turn=index))
        middle = time.perf_counter()
        wm = consultant.wm
        store.save_wm({e: wm.export_queue(e) for e in dirty}, wm.counters(), decay_until=10.0 * applied)
        end = time.perf_counter()
        core.append((middle - start) * 1e3)
        persist.append((end - middle) * 1e3)
        written.append(len(dirty))
        dirty.clear()
    store.close()
    return {"entities": entities, "turns": len(core), "core_p50": statistics.median(core), "core_p95": p95(core),
            "persist_p50": statistics.median(persist), "persist_p95": p95(persist),
            "queues_p50": statistics.median(written), "queues_max": max(written),
            "ratio": statistics.median(persist) / statistics.median(core)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--turns", type=int, default=100, help="human and robot turns each (default 100)")
    parser.add_argument("--sizes", default="16,10000", help="world sizes, comma-separated (default 16,10000)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--dir", type=Path, help="directory of the databases (default: a temporary one)")
    args = parser.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",")]
    with tempfile.TemporaryDirectory(prefix="fsreg-bench-store-", dir=args.dir) as tmp:
        print(f"{'entities':>9} {'turns':>6} {'core p50/p95 ms':>18} {'persist p50/p95 ms':>20} "
              f"{'queues p50/max':>15} {'persist/core':>13}")
        for size in sizes:
            r = bench(size, args.turns, args.seed, Path(tmp))
            print(f"{r['entities']:>9} {r['turns']:>6} {r['core_p50']:>8.2f} / {r['core_p95']:<7.2f} "
                  f"{r['persist_p50']:>9.2f} / {r['persist_p95']:<8.2f} {r['queues_p50']:>6.0f} / {r['queues_max']:<6} "
                  f"{r['ratio']:>12.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
