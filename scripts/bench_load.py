#!/usr/bin/env python3
"""Benchmark of scenario loading and of the simulator's optional trace, on a large random scenario.

Writes a random scenario (``--entities`` faces with random attribute values, 100
human and 100 robot turns, ``decay+displacement``, delta 10, alpha 3), then times,
best of ``--repeat`` runs:

* YAML parsing with libyaml's C parser (:class:`FastLoader`, what loading uses) and
  with the pure-Python parser (:class:`ExactLoader`, used only to explain an error);
* the whole :func:`load_scenario` (YAML, structure, checks);
* ``fsreg-sim`` without and with ``--trace`` (the trace is built only when asked).

Ratios are what count on a shared machine.  Run it any way
(``scripts/bench_load.py``, ``python3 scripts/bench_load.py``): it re-executes
itself with ``.venv/bin/python`` (:mod:`venv_python`).
"""

from __future__ import annotations

import argparse
import os
import random
import sys
import tempfile
import time
from pathlib import Path

from venv_python import prepare  # noqa: E402

prepare("bench_load.py")  # .venv, import path

from fsreg_ros.tools.sim import sim_main  # noqa: E402
from fsreg_ros.core.scenario import load_scenario  # noqa: E402
from fsreg_ros.core.io.yaml_source import ExactLoader, FastLoader  # noqa: E402

#: Attribute -> values of the random faces (one value per attribute per face).
ATTRIBUTES = {
    "hair": ["light-hair", "dark-hair", "red-hair", "grey-hair"],
    "length": ["short-hair", "long-hair", "bald"],
    "sex": ["male", "female"],
    "top": ["lab-coat", "t-shirt", "hoodie", "jumper", "shirt"],
    "eyes": ["glasses", "no-glasses"],
    "hat": ["hat", "no-hat"],
    "beard": ["beard", "no-beard"],
}


def random_scenario(entities: int, turns: int, seed: int = 1) -> str:
    """Return the YAML text of a random Guess-Who-like scenario with ``entities`` faces."""
    rng = random.Random(seed)
    preference = [p for values in ATTRIBUTES.values() for p in values]
    facts = {f"face{i}": [rng.choice(values) for values in ATTRIBUTES.values()] for i in range(entities)}
    lines = [
        "name: random-large",
        "memory: {policy: decay+displacement, decay_period: 10, capacity: 3}",
        "domains:",
        "  faces:",
        f"    preference: [{', '.join(preference)}]",
        "    attributes:",
        *(f"      {attribute}: [{', '.join(values)}]" for attribute, values in ATTRIBUTES.items()),
        "    entities:",
        *(f"      {name}: [{', '.join(props)}]" for name, props in facts.items()),
        "dialogue:",
    ]
    names = list(facts)
    for t in range(turns):
        target = rng.choice(names)
        said = rng.sample(facts[target], 3)
        lines.append(f"  - {{time: {6 * t + 1}.0, speaker: human, target: {target}, description: [{', '.join(said)}]}}")
        lines.append(f"  - {{time: {6 * t + 4}.0, speaker: robot, target: {rng.choice(names)}}}")
    return "\n".join(lines) + "\n"


def best_of(repeat: int, work) -> float:
    """Return the best wall-clock time of ``repeat`` calls of ``work``, in seconds."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        work()
        times.append(time.perf_counter() - start)
    return min(times)


def parse_with(loader_class: type, text: str) -> None:
    loader = loader_class(text)
    try:
        loader.construct_document(loader.get_single_node())
    finally:
        loader.dispose()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--entities", type=int, default=10_000)
    parser.add_argument("--turns", type=int, default=100, help="human turns (as many robot turns)")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    text = random_scenario(args.entities, args.turns)
    with tempfile.TemporaryDirectory(prefix="fsreg-bench-load-") as tmp:
        path = Path(tmp) / "large.yaml"
        path.write_text(text, encoding="utf-8")
        trace = Path(tmp) / "trace.jsonl"
        devnull = open(os.devnull, "w")
        stdout, sys.stdout = sys.stdout, devnull
        try:
            c_parse = best_of(args.repeat, lambda: parse_with(FastLoader, text))
            py_parse = best_of(args.repeat, lambda: parse_with(ExactLoader, text))
            load = best_of(args.repeat, lambda: load_scenario(path))
            sim = best_of(1, lambda: sim_main([str(path)]))
            sim_trace = best_of(1, lambda: sim_main([str(path), "--trace", str(trace)]))
        finally:
            sys.stdout = stdout
            devnull.close()
    print(f"scenario: {args.entities} entities, {2 * args.turns} turns, {len(text) / 1e6:.1f} MB of YAML")
    print(f"YAML parse, C parser:          {c_parse:7.3f} s")
    print(f"YAML parse, pure Python:       {py_parse:7.3f} s   (C is x{py_parse / c_parse:.1f} faster)")
    print(f"load_scenario (all stages):    {load:7.3f} s")
    print(f"fsreg-sim, no trace:           {sim:7.3f} s")
    print(f"fsreg-sim --trace:             {sim_trace:7.3f} s   (trace costs x{sim_trace / sim:.2f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
