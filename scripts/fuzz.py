#!/usr/bin/env python3
"""A longer fuzz run of every topic and service of the graph than the test suite's.

Same fuzzer as ``test/ros/test_fuzz_graph.py`` (``test/support/fuzzgraph.py``: the graph in one
process on sim time, catalogued hostile inputs then hypothesis-generated ones with a
fixed seed), with ``--examples`` generated inputs per endpoint.  Prints per topic or
service the inputs tried, rejected and accepted, and every crash (a callback that
raised: a node process would have died), unanswered input, invalid input accepted,
and rejected input that changed WM or LTM.  Exit 1 if anything was found.

With ``--wire`` it is the fault probe of issue 38 instead (``test/support/fuzzwire.py``):
a graph of node processes (as ``fsreg-up`` runs them; ``--in-process`` for one process)
is sent, on every topic and service the contract declares, what no schema can save (deep
nesting, the oversized message of issue 38.1, a 1 MB string, bytes that are not UTF-8,
a key twice, a lone surrogate, NaN, an empty text), ``--rounds`` times; it prints per
endpoint the messages sent, refused (answered with a refusal) and taken (topics with no
answer by contract: acknowledged by every reader), then how many nodes still run and
answer a real request.  Exit 1 if any input was unanswered, accepted, refused as an
internal error, or any node died or stopped answering.

    scripts/fuzz.py --examples 500
    scripts/fuzz.py --examples 200 --endpoint /wm_manager/sync
    scripts/fuzz.py --wire --rounds 3
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

from venv_python import prepare  # noqa: E402

REPO = prepare("fuzz.py", loopback=True, support=True)  # .venv, import path, loopback ROS

from fuzzgraph import Fuzzer, fuzz_endpoint, start_graph  # noqa: E402
from fuzzinputs import ENDPOINTS  # noqa: E402

from fsreg_ros.core.scenario import load_scenario  # noqa: E402


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="fuzz.py", description=__doc__.split("\n\n")[0])
    default = REPO / "scenarios" / "guess_who_table1.yaml"  # Table 1 (or $FSREG_SHARED_DATA/table1.yaml)
    if not default.is_file() and os.environ.get("FSREG_SHARED_DATA"):
        default = Path(os.environ["FSREG_SHARED_DATA"]) / "table1.yaml"
    parser.add_argument("scenario", type=Path, nargs="?", default=default, help="Table 1 scenario (domain faces)")
    parser.add_argument("--examples", type=int, default=500, help="generated inputs per endpoint (default 500)")
    parser.add_argument("--endpoint", action="append", choices=ENDPOINTS, help="only these (repeatable)")
    parser.add_argument("--wire", action="store_true", help="the fault probe: every endpoint the contract declares")
    parser.add_argument("--in-process", action="store_true", help="with --wire: the graph in this process")
    parser.add_argument("--rounds", type=int, default=1, help="with --wire: times every input is sent (default 1)")
    args = parser.parse_args(argv)
    if not args.scenario.is_file():
        parser.error(f"scenario not found: {args.scenario}")
    if args.examples < 1:
        parser.error("--examples must be at least 1")
    if not 1 <= args.rounds <= 100:
        parser.error("--rounds must be 1 to 100")
    if args.wire:
        return wire_probe(args.scenario, args.rounds, processes=not args.in_process)
    with tempfile.TemporaryDirectory(prefix="fsreg-fuzz-") as tmp:
        fuzzer = Fuzzer(lambda: start_graph(args.scenario, Path(tmp)), load_scenario(args.scenario))
        try:
            for i, endpoint in enumerate(args.endpoint or ENDPOINTS):
                start = time.monotonic()
                fuzz_endpoint(fuzzer, endpoint, args.examples, first_id=100_000 * (i + 1))
                print(f"{endpoint}: done in {time.monotonic() - start:.1f} s", file=sys.stderr, flush=True)
        finally:
            fuzzer.close()
    print(fuzzer.report())
    print(f"graph restarts after a crash: {fuzzer.restarts}")
    return 1 if any(o.failures() for o in fuzzer.outcomes.values()) else 0


def wire_probe(scenario_path: Path, rounds: int, processes: bool) -> int:
    """Run the wire fault probe on a fresh graph of ``scenario_path``; print the counts; 0 if nothing failed."""
    from fuzzwire import TIME, WireFuzz

    from fsreg_ros.testing import LiveGraph

    scenario = load_scenario(scenario_path)
    domains = list(scenario.domains)
    spec = scenario.domains[domains[0]]
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="fsreg-fuzz-") as tmp, \
            LiveGraph(scenario_path, processes=processes, state_dir=Path(tmp) / "state",
                      log_dir=Path(tmp) / "logs") as live:
        live.set_clock(TIME)
        wire = WireFuzz(live.session, domains)
        for _ in range(rounds):
            wire.run()
        unanswered = wire.real_requests(next(iter(spec.entities)), spec.preference[0])
        names = [s.name for s in live.specs]
        dead = [f"{s.name} (exit {code})" for s, code in live.graph.dead()] if live.graph is not None else []
        asked = len(domains) + 4  # each consultant's info, status, an utterance, semantics, a REG request
        print(wire.report())
        print(f"endpoints: {len(wire.tallies)}; messages sent: {sum(t.sent for t in wire.tallies.values())}, "
              f"refused: {sum(t.refused for t in wire.tallies.values())}, "
              f"taken without an answer: {sum(t.taken for t in wire.tallies.values())}, "
              f"not sendable: {sum(t.unsendable for t in wire.tallies.values())}, "
              f"failures: {len(wire.failures())}")
        print(f"nodes alive: {len(names) - len(dead)} of {len(names)} ({'processes' if processes else 'in-process'})"
              + (f"; dead: {', '.join(dead)}" if dead else ""))
        print(f"real requests answered after: {asked - len(unanswered)} of {asked}")
        for line in unanswered:
            print(f"    {line}")
    print(f"({time.monotonic() - started:.1f} s)", file=sys.stderr)
    return 1 if wire.failures() or dead or unanswered else 0


if __name__ == "__main__":
    sys.exit(main())
