#!/usr/bin/env python3
"""Benchmark of one rule 2/3 encoding: one property into N entities (``WMBuffer``).

Policy decay+displacement (capacity 4), no event sink, 8 properties encoded in turn
into every entity (so from the fifth on every encoding displaces a front).  Two ways
in: ``encode_each`` (entity names, queue by queue) and ``encode_members`` (a bitset
over the domain's entities, as ``Consultant.narrow`` calls it; column queues in a
domain of at least ``memory.COLUMN_MIN`` entities).  Reported: the best time of one
call over many, and its ratio to two floors: a plain Python loop assigning one dict
item per entity (the floor for any per-entity Python work), and a vectorised numpy
assignment of one column of an entities x properties stamp matrix, including the
conversion of the entity names the call receives to row numbers (the floor for an
array representation).
Usage: ``scripts/bench_encode.py [--entities N] [--rounds R]``.
"""

from __future__ import annotations

import argparse
import time

from venv_python import prepare  # noqa: E402

prepare("bench_encode.py")  # .venv, import path

from fsreg_ros.core.forgetting.policies import ForgettingPolicy  # noqa: E402
from fsreg_ros.core.memory import WMBuffer  # noqa: E402


def best_encode(names: list[str], rounds: int, members: bool) -> float:
    buffer = WMBuffer("d")
    buffer.set_limits(ForgettingPolicy.parse("decay+displacement", decay_period=10.0, capacity=4).limits(), 0.0)
    props = [f"p{j}" for j in range(8)]
    everyone = (1 << len(names)) - 1

    def encode(prop: str) -> None:
        if members:
            buffer.encode_members(everyone, names, prop, "rr", 0.0)
        else:
            buffer.encode_each(names, prop, "rr", 0.0)

    for prop in props:  # fill every queue first
        encode(prop)
    times = []
    for _ in range(rounds):
        for prop in props:
            start = time.perf_counter()
            encode(prop)
            times.append(time.perf_counter() - start)
    return min(times)


def best_assignment(n: int, rounds: int) -> float:
    queues = [{} for _ in range(n)]
    times = []
    for r in range(rounds * 8):
        start = time.perf_counter()
        for q in queues:
            q["p"] = r
        times.append(time.perf_counter() - start)
    return min(times)


def best_vectorised(names: list[str], rounds: int) -> float:
    import numpy as np

    rows = {name: i for i, name in enumerate(names)}
    stamps = np.zeros((len(names), 8), dtype=np.int64)
    times = []
    for r in range(rounds * 8):
        start = time.perf_counter()
        index = np.fromiter(map(rows.__getitem__, names), dtype=np.intp, count=len(names))
        stamps[index, r % 8] = np.arange(r * len(names), (r + 1) * len(names))
        times.append(time.perf_counter() - start)
    return min(times)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--entities", type=int, default=10_000)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args(argv)
    names = [f"e{i}" for i in range(args.entities)]
    each = best_encode(names, args.rounds, members=False)
    members = best_encode(names, args.rounds, members=True)
    assign = best_assignment(args.entities, args.rounds)
    vector = best_vectorised(names, args.rounds)
    print(f"{args.entities} entities: dict assignment loop {assign * 1e3:.3f} ms; "
          f"numpy column assignment from names {vector * 1e3:.3f} ms")
    for label, best in (("encode_each (names)", each), ("encode_members (bitset)", members)):
        print(f"  {label:<24} {best * 1e3:.3f} ms: x{best / assign:.1f} the dict loop, x{best / vector:.1f} "
              "the numpy floor")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
