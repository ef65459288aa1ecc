#!/usr/bin/env python3
"""A longer fuzz run of every topic and service of the graph than the test suite's.

Same fuzzer as ``test/ros/test_fuzz_graph.py`` (``test/support/fuzzgraph.py``: the graph in one
process on sim time, catalogued hostile inputs then hypothesis-generated ones with a
fixed seed), with ``--examples`` generated inputs per endpoint.  Prints per topic or
service the inputs tried, rejected and accepted, and every crash (a callback that
raised: a node process would have died), unanswered input, invalid input accepted,
and rejected input that changed WM or LTM.  Exit 1 if anything was found.

    scripts/fuzz.py --examples 500
    scripts/fuzz.py --examples 200 --endpoint /wm_manager/sync
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO), str(REPO / "test" / "support")]

from fsreg_ros.ros.network import use_loopback_environment  # noqa: E402

use_loopback_environment("fuzz.py")  # before rclpy loads

from fuzzgraph import ENDPOINTS, Fuzzer, fuzz_endpoint, start_graph  # noqa: E402

from fsreg_ros.core.scenario import load_scenario  # noqa: E402


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="fuzz.py", description=__doc__.split("\n\n")[0])
    default = REPO / "scenarios" / "guess_who_table1.yaml"  # Table 1 (or $FSREG_SHARED_DATA/table1.yaml)
    if not default.is_file() and os.environ.get("FSREG_SHARED_DATA"):
        default = Path(os.environ["FSREG_SHARED_DATA"]) / "table1.yaml"
    parser.add_argument("scenario", type=Path, nargs="?", default=default, help="Table 1 scenario (domain faces)")
    parser.add_argument("--examples", type=int, default=500, help="generated inputs per endpoint (default 500)")
    parser.add_argument("--endpoint", action="append", choices=ENDPOINTS, help="only these (repeatable)")
    args = parser.parse_args(argv)
    if not args.scenario.is_file():
        parser.error(f"scenario not found: {args.scenario}")
    if args.examples < 1:
        parser.error("--examples must be at least 1")
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


if __name__ == "__main__":
    sys.exit(main())
