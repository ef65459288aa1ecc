#!/usr/bin/env python3
"""Write a random world scenario (fsreg_ros.tools.worlds) as YAML, deterministic from --seed.

Usage: ``scripts/make_world.py [-o FILE] [--preset sparse|dense] [--entities N]
[--attributes A] [--values V] [--human H] [--robot R] [--policy P] [--decay-period D]
[--capacity C] [--global-capacity G] [--seed S]``.  Writes to stdout without -o.

Presets (the benchmark worlds of ``scripts/bench_sim.py``; options given after them
override their values):

* ``sparse`` (the default): 10,000 entities, 40 attributes x 5 values = 200
  properties, each holding for about a fifth of the entities;
* ``dense`` (issue 17): 10,000 entities, 3 attributes x 2 values = 6 properties, each
  holding for about half the entities: most descriptions cannot distinguish their
  target, and every rule 2 and 3 encoding reaches thousands of queues.

Both: 100 human and 100 robot turns, decay+displacement, delta 10, alpha 3.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from venv_python import prepare  # noqa: E402

prepare("make_world.py")  # .venv, import path

from fsreg_ros.tools.worlds import WorldShape, dump_world, random_world  # noqa: E402

#: The benchmark worlds: changes to :class:`WorldShape`'s defaults.
PRESETS: dict[str, dict] = {
    "sparse": {},
    "dense": {"attributes": 3, "values": 2},
}
#: Options that change a world's shape, and the WorldShape field each sets.
SHAPE_OPTIONS = {
    "entities": "entities",
    "attributes": "attributes",
    "values": "values",
    "human": "human_turns",
    "robot": "robot_turns",
    "policy": "policy",
    "decay_period": "decay_period",
    "capacity": "capacity",
    "global_capacity": "global_capacity",
    "seed": "seed",
}


def preset_shape(name: str, **changes) -> WorldShape:
    """Return the checked shape of preset ``name`` with ``changes`` (WorldShape fields) applied.

    Raises ValueError naming the preset or the field that is wrong.
    """
    if name not in PRESETS:
        raise ValueError(f"unknown preset '{name}' (known: {', '.join(PRESETS)})")
    return replace(WorldShape(**PRESETS[name]), **changes).check()


def describe(shape: WorldShape) -> str:
    """Return a one-line description of a world shape, for reports."""
    share = 1 / shape.values
    return (f"{shape.entities:,} entities, {shape.attributes * shape.values} properties "
            f"({shape.attributes} attributes x {shape.values} values: each holds for ~{share:.0%} of them), "
            f"{shape.human_turns} human + {shape.robot_turns} robot turns, {shape.policy}, "
            f"delta {shape.decay_period:g}, alpha {shape.capacity}, seed {shape.seed}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("-o", "--output", metavar="FILE", help="write here (default: stdout)")
    parser.add_argument("--preset", default="sparse", choices=sorted(PRESETS), help="base shape (default: sparse)")
    parser.add_argument("--entities", type=int)
    parser.add_argument("--attributes", type=int)
    parser.add_argument("--values", type=int, help="values per attribute")
    parser.add_argument("--human", type=int, help="human turns")
    parser.add_argument("--robot", type=int, help="robot turns")
    parser.add_argument("--policy")
    parser.add_argument("--decay-period", type=float)
    parser.add_argument("--capacity", type=int)
    parser.add_argument("--global-capacity", type=int)
    parser.add_argument("--seed", type=int)
    args = parser.parse_args(argv)
    changes = {field: getattr(args, option) for option, field in SHAPE_OPTIONS.items()
               if getattr(args, option) is not None}
    try:
        shape = preset_shape(args.preset, **changes)
    except ValueError as err:
        parser.error(str(err))
    text = dump_world(random_world(shape))
    if args.output is None:
        sys.stdout.write(text)
        return 0
    try:
        Path(args.output).write_text(text, encoding="utf-8")
    except OSError as err:
        parser.error(f"cannot write {args.output}: {err.strerror or err}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
