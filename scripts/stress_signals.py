#!/usr/bin/env python3
"""Stress check of issue 37 item 1: Ctrl-C under ``ros2 launch``, N rounds (default 50).

Each round starts the live graph's node processes as the launch file defines them
(:func:`fsreg_ros.ros.graph_spec.node_specs`: consultant, WM Manager, parser, RR, REG),
waits until every node spins, then stops them as a terminal's Ctrl-C under ``ros2 launch``
does: SIGINT to the process group, then a second signal to every node a few ms later
(launch's forwarded SIGINT, or SIGTERM), taking turns between ``int-int`` and ``int-term``
and gaps of 1, 5 and 20 ms (:mod:`fsreg_ros.testing.stop_signals`).  A node passes when it
exits 0, without a traceback, within 2 s of the first signal.  Prints one line per round
and a summary::

    stress_signals: 250/250 node exits clean in 50 rounds (int-int 125/125, int-term 125/125); slowest 0.41 s

Exit status: 0 if every exit was clean, 1 otherwise, 2 on bad usage.  Set ``ROS_DOMAIN_ID``.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

from venv_python import prepare  # noqa: E402

REPO = prepare("stress_signals.py")  # .venv, import path

from fsreg_ros.ros.network import ros_environment  # noqa: E402
from fsreg_ros.testing.stop_signals import CASES, stop_round  # noqa: E402

KB = REPO / "test" / "support" / "data" / "graph" / "kb.yaml"
GAPS = (0.001, 0.005, 0.02)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="stress_signals", description=__doc__.split("\n\n")[0])
    parser.add_argument("rounds", nargs="?", type=int, default=50, help="rounds (default 50)")
    args = parser.parse_args(argv)
    if args.rounds < 1:
        parser.error(f"rounds must be >= 1, got {args.rounds}")
    os.environ.update(ros_environment(dict(os.environ)))
    clean = {case: [0, 0] for case in CASES}
    slowest = 0.0
    with tempfile.TemporaryDirectory(prefix="fsreg-stress-signals-") as work:
        for n in range(args.rounds):
            case = list(CASES)[n % len(CASES)]
            gap = GAPS[(n // len(CASES)) % len(GAPS)]
            ended = stop_round(str(KB), Path(work) / f"round{n}", case, gap, namespace=f"/stress{n}")
            bad = {e.name: e.problems() for e in ended if e.problems()}
            clean[case][0] += len(ended) - len(bad)
            clean[case][1] += len(ended)
            slowest = max([slowest] + [e.seconds for e in ended])
            times = " ".join(f"{e.seconds:.2f}" for e in ended)
            print(f"round {n + 1}: {case} gap {gap * 1000:g} ms: {len(ended) - len(bad)}/{len(ended)} clean, "
                  f"exits after {times} s" + (f"; {bad}" if bad else ""), flush=True)
            for e in ended:
                if e.problems():
                    print(f"  [{e.name}] stderr: {e.stderr[-800:]}", flush=True)
    good, total = sum(c[0] for c in clean.values()), sum(c[1] for c in clean.values())
    per_case = ", ".join(f"{case} {c[0]}/{c[1]}" for case, c in clean.items())
    print(f"stress_signals: {good}/{total} node exits clean in {args.rounds} rounds ({per_case}); "
          f"slowest {slowest:.2f} s")
    return 0 if good == total else 1


if __name__ == "__main__":
    sys.exit(main())
