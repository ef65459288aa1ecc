#!/usr/bin/env python3
"""Write a random world scenario (fsreg_ros.worlds) as YAML, deterministic from --seed.

Usage: ``scripts/make_world.py [-o FILE] [--entities N] [--attributes A] [--values V]
[--human H] [--robot R] [--policy P] [--decay-period D] [--capacity C] [--seed S]``.
Defaults: issue 11's world (10,000 entities, 40 attributes x 5 values, 100 human and
100 robot turns, decay+displacement, delta 10, alpha 3).  Writes to stdout without -o.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from venv_python import use_venv  # noqa: E402

use_venv()  # run with .venv/bin/python, however started

from fsreg_ros.worlds import WorldShape, dump_world, random_world  # noqa: E402


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    defaults = WorldShape()
    parser.add_argument("-o", "--output", metavar="FILE", help="write here (default: stdout)")
    parser.add_argument("--entities", type=int, default=defaults.entities)
    parser.add_argument("--attributes", type=int, default=defaults.attributes)
    parser.add_argument("--values", type=int, default=defaults.values, help="values per attribute")
    parser.add_argument("--human", type=int, default=defaults.human_turns, help="human turns")
    parser.add_argument("--robot", type=int, default=defaults.robot_turns, help="robot turns")
    parser.add_argument("--policy", default=defaults.policy)
    parser.add_argument("--decay-period", type=float, default=defaults.decay_period)
    parser.add_argument("--capacity", type=int, default=defaults.capacity)
    parser.add_argument("--global-capacity", type=int, default=None)
    parser.add_argument("--seed", type=int, default=defaults.seed)
    args = parser.parse_args(argv)
    try:
        shape = WorldShape(
            entities=args.entities,
            attributes=args.attributes,
            values=args.values,
            human_turns=args.human,
            robot_turns=args.robot,
            policy=args.policy,
            decay_period=args.decay_period,
            capacity=args.capacity,
            global_capacity=args.global_capacity,
            seed=args.seed,
        ).check()
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
