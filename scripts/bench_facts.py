#!/usr/bin/env python3
"""A consultant's query latency while it takes facts at robot rates: that node alone, open loop.

``scripts/soak.py --facts-rate N`` measures the whole graph (six processes and the sender
on the machine's two cores); this measures only what the consultant does to queries
while perception floods it.  One consultant process (the scenario's first domain, state
database on, wall clock, debug off, as ``fsreg-up`` runs it) and, from this process,
open loop for ``--seconds``: ``--facts-rate`` facts/s on ``ltm/assert`` in messages of
``--batch`` (about ``--facts-entities`` perceived entities, as soak.py sends them) and
``--queries`` queries/s on ``consultant/<domain>``, each an ``open`` of a target followed,
once answered, by its ``close`` (as RR and REG do), sent at its scheduled moment
whatever the answers.  Printed: the queries' latency (scheduled moment to the ``close``
reply) p50/p95/p99/max, the facts sent, answered, applied and their latency, and the
consultant's CPU seconds.

    scripts/bench_facts.py --facts-rate 10000 --batch 50
    scripts/bench_facts.py --facts-rate 1000
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path
from typing import Optional

from venv_python import prepare  # noqa: E402

REPO = prepare("bench_facts.py", loopback=True)  # .venv, import path, loopback ROS

import psutil  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from fsreg_ros import contract  # noqa: E402
from fsreg_ros.core.scenario import load_scenario  # noqa: E402
from fsreg_ros.ros.carrier import qos_profile  # noqa: E402
from fsreg_ros.testing.ros_session import RosSession  # noqa: E402

READY_TIMEOUT = 60.0
DRAIN = 15.0  # seconds without an answer after which the unanswered are lost


def percentile(values: list[float], q: float) -> float:
    if not values:
        return float("nan")
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, math.ceil(q / 100 * len(ordered)) - 1))]


def number(value: float) -> str:
    """Return a bound as people write it: 1000000, 0.1."""
    return str(int(value)) if float(value).is_integer() else f"{value:g}"


def figures(name: str, ms: list[float]) -> str:
    return (f"{name} latency ms p50 {percentile(ms, 50):.1f} p95 {percentile(ms, 95):.1f} "
            f"p99 {percentile(ms, 99):.1f} max {max(ms, default=float('nan')):.1f}")


def main(argv: Optional[list[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="bench_facts.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("scenario", type=Path, nargs="?", default=REPO / "scenarios" / "guess_who_table1.yaml")
    parser.add_argument("--facts-rate", type=float, default=10000.0, metavar="N", help="facts per second (10000)")
    parser.add_argument("--batch", type=int, default=50, metavar="K", help="facts per ltm/assert message (50)")
    parser.add_argument("--facts-entities", type=int, default=100, metavar="P", help="perceived entities (100)")
    parser.add_argument("--queries", type=float, default=60.0, help="open+close queries per second (60: about "
                        "RR's and REG's calls at 20 turns/s and 20 requests/s)")
    parser.add_argument("--seconds", type=float, default=20.0, help="how long to send (20)")
    args = parser.parse_args(argv)
    for name, value, low, high in (("--facts-rate", args.facts_rate, 0, 1_000_000),
                                   ("--queries", args.queries, 0.1, 10_000), ("--seconds", args.seconds, 0.1, 3600)):
        if not (math.isfinite(value) and low <= value <= high):
            parser.error(f"{name} must be a number in [{number(low)}, {number(high)}], got {value:g}")
    if not 1 <= args.batch <= 1000 or not 1 <= args.facts_entities <= 1_000_000:
        parser.error("--batch must be in [1, 1000] and --facts-entities in [1, 1000000]")
    if not args.scenario.is_file():
        parser.error(f"scenario not found: {args.scenario}")
    scenario = load_scenario(args.scenario)
    domain, spec = next(iter(scenario.domains.items()))
    targets, preference = list(spec.entities), list(spec.preference)
    namespace = f"/bench_facts_{uuid.uuid4().hex[:8]}"
    service, manage = (f"{namespace}/{contract.consultant_service(domain)}",
                       f"{namespace}/{contract.manage_service(domain)}")
    with tempfile.TemporaryDirectory(prefix="fsreg-bench-facts-") as state, RosSession() as session:
        cmd = [str(Path(sys.executable).parent / "consultant"), "--ros-args", "-r", f"__node:=consultant_{domain}",
               "-r", f"__ns:={namespace}", "-p", f"domain:={domain}", "-p", f"kb:={args.scenario}",
               "-p", f"state_dir:={state}", "-p", "debug:=false"]
        with open(Path(state) / "consultant.log", "wb") as log:  # a pipe nobody reads would stall it
            proc = subprocess.Popen(cmd, env=os.environ, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT)
        try:
            return run(args, session, proc, domain, targets, preference, namespace, service, manage)
        finally:
            proc.terminate()
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()


def run(args, session: RosSession, proc, domain, targets, preference, namespace, service, manage) -> int:
    # One real round trip each, read-only ops sent again if lost (a new server's first request can be).
    session.wait_ready(service, {"op": "info"}, READY_TIMEOUT)
    session.wait_ready(manage, {"op": "size"}, READY_TIMEOUT)
    session.call(manage, {"op": "configure", "policy": {"policy": "displacement", "capacity": 4}}, READY_TIMEOUT)
    arrival: dict[str, tuple[float, int]] = {}  # facts message id -> (answered at, facts applied)

    def on_result(msg: String) -> None:
        data = json.loads(msg.data)
        arrival.setdefault(data.get("id"), (time.monotonic(), data.get("applied", 0)))

    session.probe.create_subscription(String, f"{namespace}/{contract.LTM_ASSERT_RESULT.name}", on_result,
                                      qos_profile(contract.LTM_ASSERT_RESULT.qos))
    assert_topic = f"{namespace}/{contract.LTM_ASSERT.name}"
    caller = session.client(service)
    plan: list[tuple[float, str, object]] = []
    count = int(args.seconds * args.facts_rate)
    for start in range(0, count, args.batch):
        facts = [{"entity": f"perceived{i % args.facts_entities}",
                  "properties": {preference[(i // args.facts_entities) % len(preference)]:
                                 1.0 if (i // args.facts_entities) % 2 else 0.8}}
                 for i in range(start, min(count, start + args.batch))]
        plan.append((start / args.facts_rate, "facts", facts))
    for i in range(int(args.seconds * args.queries)):
        plan.append((i / args.queries + 0.5 / args.queries, "query", targets[i % len(targets)]))
    plan.sort(key=lambda item: item[0])
    session.publish(assert_topic, {"id": "warm", "domain": domain, "facts": plan[0][2]}, contract.LTM_ASSERT.qos)
    session.spin_until(lambda: "warm" in arrival, READY_TIMEOUT, what="the warm-up assertion's answer")
    facts_sent: dict[str, tuple[float, int]] = {}
    opens: list[tuple[float, object]] = []  # (scheduled, future of open)
    closes: list[list] = []  # [scheduled, future of close, answered at]
    cpu = psutil.Process(proc.pid)
    cpu_before = sum(cpu.cpu_times()[:2])
    began = time.monotonic()

    def pump() -> None:
        """Send the close of every open answered (the second step of a query)."""
        still = []
        for due, future in opens:
            if future.done():
                reply = caller.decode(future)
                closes.append([due, caller.send({"op": "close", "session": reply["session"]}), None])
            else:
                still.append((due, future))
        opens[:] = still
        now = time.monotonic()
        for entry in closes:
            if entry[2] is None and entry[1].done():
                entry[2] = now

    for n, (offset, kind, payload) in enumerate(plan):
        due = began + offset
        while time.monotonic() < due:
            session.executor.spin_once(timeout_sec=max(0.0, min(0.002, due - time.monotonic())))
            pump()
        if kind == "facts":
            key = f"f{n}"
            session.publish(assert_topic, {"id": key, "domain": domain, "facts": payload}, contract.LTM_ASSERT.qos)
            facts_sent[key] = (due, len(payload))
        else:
            opens.append((due, caller.send({"op": "open", "target": payload, "client": "bench"})))
    deadline = time.monotonic() + DRAIN

    def settle() -> bool:
        pump()
        return not opens and all(e[2] is not None for e in closes) and all(k in arrival for k in facts_sent)

    while not settle() and time.monotonic() < deadline:
        session.executor.spin_once(timeout_sec=0.002)
    cpu_used = sum(cpu.cpu_times()[:2]) - cpu_before
    seconds = time.monotonic() - began
    query_ms = [1000 * (at - due) for due, _, at in closes if at is not None]
    answered = {k: arrival[k][1] for k in facts_sent if k in arrival}
    print(f"== bench_facts: {args.facts_rate:g} facts/s in messages of {args.batch}, {args.queries:g} queries/s, "
          f"{args.seconds:g} s; load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    unanswered = len(opens) + sum(1 for e in closes if e[2] is None)
    print(f"queries {len(closes) + len(opens)}, unanswered {unanswered}; " + figures("query", query_ms))
    facts_ms = [1000 * (arrival[k][0] - due) for k, (due, _) in facts_sent.items() if k in arrival]
    print(f"facts sent {sum(n for _, n in facts_sent.values())}, answered messages {len(answered)} of "
          f"{len(facts_sent)}, applied {sum(answered.values())}; " + figures("facts", facts_ms))
    print(f"consultant CPU {cpu_used:.1f} s in {seconds:.1f} s ({cpu_used / seconds:.0%} of a core)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
