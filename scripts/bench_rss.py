#!/usr/bin/env python3
"""Resident memory of each node over many REG requests: it must stay flat once REG's answer cache is full.

Starts a consultant, the WM Manager and REG as their own processes (as ``fsreg-graph``
does, persistence on, policy displacement so WM stays bounded), then sends ``--requests`` REG requests
with distinct ids from this process, one at a time, waiting for each answer, and reads
every node's RSS (``/proc/<pid>/status`` VmRSS) every ``--every`` requests.  It prints the RSS
at each sample and, per node, the slope after REG's cache is full (default 1,024 entries), in
bytes per request: fitted by least squares over the samples, with its 95 % interval. Before the
fix, REG grew ~1.9 kB per request after the cache filled: every service call created a deadline
timer, and rclpy's callback group kept a weak reference
to each timer forever (see ``fsreg_ros.ros.carrier.drop_timer``).

    scripts/bench_rss.py [SCENARIO.yaml] [--requests 6000] [--every 500]

Wall-clock figures belong here, not in the tests.  Runs with
ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST unless you set otherwise.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

from venv_python import prepare  # noqa: E402

REPO = prepare("bench_rss.py", loopback=True)  # .venv, import path, loopback ROS

from fsreg_ros.tools.graph import Graph, graph_nodes  # noqa: E402

import numpy as np  # noqa: E402
import rclpy  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from fsreg_ros import contract  # noqa: E402
from fsreg_ros.ros.carrier import publisher, qos_profile, to_msg  # noqa: E402
from fsreg_ros.core.scenario import load_scenario  # noqa: E402
from fsreg_ros.core.simulation.simulator import Options  # noqa: E402


NAMESPACE = "/bench_rss"


def rss_kb(pid: int) -> int:
    """Return the resident set size of a process in kB."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise RuntimeError(f"no VmRSS for pid {pid}")


def fit_slope(points: list[tuple[int, float]]) -> tuple[float, tuple[float, float]]:
    """Return the least-squares slope of (requests, bytes) and its 95 % interval (nan without 3 points).

    RSS moves in pages and the allocator's arenas, so two samples' difference says little;
    the fitted slope over many samples, with its interval, says whether memory grows.
    """
    if len(points) < 3:
        return float("nan"), (float("nan"), float("nan"))
    x = np.array([n for n, _ in points], dtype=float)
    y = np.array([b for _, b in points], dtype=float)
    slope, intercept = np.polyfit(x, y, 1)
    residuals = y - (slope * x + intercept)
    se = math.sqrt(float(residuals @ residuals) / (len(x) - 2) / float(((x - x.mean()) ** 2).sum()))
    margin = 1.96 * se
    return float(slope), (float(slope - margin), float(slope + margin))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario", nargs="?", type=Path,
                        default=REPO / "test" / "support" / "data" / "graph" / "kb.yaml")
    parser.add_argument("--requests", type=int, default=6000)
    parser.add_argument("--every", type=int, default=500)
    parser.add_argument("--json", type=Path, help="also write the samples here")
    args = parser.parse_args(argv)
    if not 1 <= args.every <= 100_000:
        parser.error(f"--every must be in [1, 100000], got {args.every}")
    first = -(-(1024 + args.every) // args.every) * args.every  # the first sample fitted (see `full` below)
    if not first + 2 * args.every <= args.requests <= 10_000_000:  # the slope needs 3 samples past REG's cache
        parser.error(f"--requests must be in [{first + 2 * args.every}, 10000000] with --every {args.every} "
                     f"(3 samples after REG's 1,024-entry cache filled), got {args.requests}")

    scenario = load_scenario(args.scenario)
    targets = [e for spec in scenario.domains.values() for e in spec.entities]
    options = Options(memory={"policy": "displacement", "capacity": 2})
    with tempfile.TemporaryDirectory(prefix="fsreg-rss-") as tmp:
        nodes = [n for n in graph_nodes(scenario, args.scenario, options, Path(tmp) / "unused.json")
                 if n.executable in ("consultant", "wm_manager", "reg")]
        for spec in nodes:
            spec.parameters["use_sim_time"] = False
        graph = Graph(nodes, Path(tmp), namespace=NAMESPACE)  # its own namespace: other graphs may share the domain
        rclpy.init()
        node = Node("bench_rss", namespace=NAMESPACE)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        answers: dict[str, dict] = {}
        node.create_subscription(String, contract.REG_EXPRESSION.name,
                                 lambda m: answers.__setitem__(json.loads(m.data).get("id"), json.loads(m.data)),
                                 qos_profile(contract.REG_EXPRESSION.subscriber_qos))
        requests = publisher(node, contract.REG_REQUEST)
        try:
            graph.start()
            pids = {s.name: p.pid for s, p in graph.procs}

            def ask(rid: str, target: str, timeout: float = 30.0) -> dict:
                deadline = time.monotonic() + timeout
                requests.publish(to_msg({"id": rid, "target": target}))
                resend = time.monotonic() + 2.0
                while rid not in answers:
                    if time.monotonic() > deadline:
                        raise RuntimeError(f"no answer to {rid}")
                    if time.monotonic() > resend:  # discovery may drop the first ones
                        requests.publish(to_msg({"id": rid, "target": target}))
                        resend = time.monotonic() + 2.0
                    executor.spin_once(timeout_sec=0.01)
                return answers.pop(rid)

            deadline = time.monotonic() + 60.0  # ready: the WM Manager configured the consultant
            while "error" in ask(f"warm-up-{time.monotonic()}", targets[0], timeout=60.0):
                if time.monotonic() > deadline:
                    raise RuntimeError("the graph did not serve within 60 s")
                time.sleep(0.2)
            samples = [(0, {name: rss_kb(pid) for name, pid in pids.items()})]
            started = time.monotonic()
            for i in range(1, args.requests + 1):
                reply = ask(f"r{i}", targets[i % len(targets)])
                if "error" in reply:
                    raise RuntimeError(f"request r{i}: {reply['error']}")
                if i % args.every == 0:
                    samples.append((i, {name: rss_kb(pid) for name, pid in pids.items()}))
                    sizes = "  ".join(f"{name} {kb / 1024:7.1f}" for name, kb in sorted(samples[-1][1].items()))
                    print(f"{i:>6} requests  RSS MB {sizes}", flush=True)
            seconds = time.monotonic() - started
        finally:
            graph.stop()
            node.destroy_node()
            rclpy.try_shutdown()
    full = [(n, kb) for n, kb in samples if n >= 1024 + args.every]
    slopes, intervals = {}, {}
    print(f"{args.requests} requests in {seconds:.1f} s; RSS slope after REG's cache filled "
          f"({full[0][0] if full else '-'}..{args.requests}), least squares over {len(full)} samples with "
          "its 95 % interval, per node:")
    for name in sorted(pids):
        first, last = samples[0][1][name], samples[-1][1][name]
        slopes[name], intervals[name] = fit_slope([(n, kb[name] * 1024) for n, kb in full])
        print(f"  {name:22} RSS {first / 1024:7.1f} -> {last / 1024:7.1f} MB  "
              f"{slopes[name]:+.1f} bytes/request [{intervals[name][0]:+.1f}, {intervals[name][1]:+.1f}]")
    if args.json:
        args.json.write_text(json.dumps({"samples": samples, "slope_bytes_per_request": slopes,
                                         "interval_95": intervals, "seconds": seconds}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
