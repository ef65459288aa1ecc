#!/usr/bin/env python3
"""What a simulator's ``/clock`` costs one sim-time node: its CPU share with the clock at each rate.

Starts one node process of the graph (``--node``, as ``fsreg-graph`` starts it, sim time,
a ROS domain of its own is up to you: set ``ROS_DOMAIN_ID``) and, for each rate of
``--hz``, a process publishing ``/clock`` that often (``scripts/simulator_clock.py``;
0 = no clock), then reads the node's CPU time over ``--seconds`` and prints its share of
one core::

    scripts/bench_clock.py --node parser --hz 0,20,1000 --seconds 10
    bench_clock: parser, /clock at 0 Hz: 0.3% of a core (load average 2.10 on 2 cores)
    ...

The difference to 0 Hz is the clock's cost.  Run it any way (``python3 scripts/bench_clock.py``):
it re-executes itself with ``.venv/bin/python``.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from venv_python import prepare  # noqa: E402

REPO = prepare("bench_clock.py", loopback=True)  # .venv, import path, loopback ROS

import psutil  # noqa: E402

from fsreg_ros.ros.graph_spec import node_specs  # noqa: E402
from fsreg_ros.tools.graph import command  # noqa: E402

KB = REPO / "test" / "support" / "data" / "graph" / "kb.yaml"
WARM_UP = 4.0


def share(node: str, hz: float, seconds: float, state: Path) -> float:
    """Return the node's CPU share of one core over ``seconds`` with ``/clock`` at ``hz`` (0: none)."""
    spec = next(s for s in node_specs(str(KB), ["faces"], {"faces": {"policy": "none"}},
                                      state_dir=str(state)) if s.executable == node)
    env = dict(os.environ)
    proc = subprocess.Popen(command(spec), env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    clock = None
    if hz:
        clock = subprocess.Popen([sys.executable, str(REPO / "scripts" / "simulator_clock.py"), "/clock", repr(hz),
                                  repr(time.monotonic())], env=env, stdin=subprocess.DEVNULL)
    try:
        time.sleep(WARM_UP)  # a benchmark: the node starts and discovers the clock
        ps = psutil.Process(proc.pid)
        before, start = ps.cpu_times(), time.monotonic()
        time.sleep(seconds)
        after, end = ps.cpu_times(), time.monotonic()
        return (after.user + after.system - before.user - before.system) / (end - start)
    finally:
        for p in (clock, proc):
            if p is not None and p.poll() is None:
                p.send_signal(signal.SIGINT)
                try:
                    p.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="bench_clock", description=__doc__.split("\n\n")[0])
    parser.add_argument("--node", default="parser", choices=["consultant", "wm_manager", "parser",
                                                             "reference_resolution", "reg"])
    parser.add_argument("--hz", default="0,20,1000", help="clock rates, comma-separated (default 0,20,1000)")
    parser.add_argument("--seconds", type=float, default=10.0, help="measured seconds per rate (default 10)")
    args = parser.parse_args(argv)
    try:
        rates = [float(x) for x in args.hz.split(",")]
    except ValueError:
        parser.error(f"--hz: expected comma-separated numbers, got {args.hz!r}")
    if any(not 0 <= r <= 10_000 for r in rates) or not 1 <= args.seconds <= 600:
        parser.error("--hz rates must be in [0, 10000] and --seconds in [1, 600]")
    import tempfile

    with tempfile.TemporaryDirectory(prefix="fsreg-bench-clock-") as tmp:
        for hz in rates:
            used = share(args.node, hz, args.seconds, Path(tmp))
            load = os.getloadavg()[0]
            print(f"bench_clock: {args.node}, /clock at {hz:g} Hz: {used:.1%} of a core "
                  f"(load average {load:.2f} on {os.cpu_count()} cores)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
