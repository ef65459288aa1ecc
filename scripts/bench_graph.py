#!/usr/bin/env python3
"""Latency of the multi-process node graph next to the same work done by the core.

Starts the real graph (one process per node, as ``fsreg-graph`` does, without the
player) for a scenario, then measures from this process:

* human turn -> ``/rr/result``: publish a description on ``/dialogue/human``, wait
  for the result with its id (parser -> RR -> consultant service calls);
* REG request -> ``/reg/expression``;

p50 / p95 over ``--rounds`` rounds of the scenario's turns, next to the same turns
run in-process by the core (``Simulation``), as a ratio measured in the same run.
It also counts consultant service calls per turn (with a counting port in-process:
a RemotePort makes exactly one service call per port call; REG adds one ``info``
call per domain to find the target's domain).

    scripts/bench_graph.py [SCENARIO.yaml] [--rounds 20] [--json FILE]

Runs with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST unless you set otherwise.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))
from venv_python import use_venv  # noqa: E402

use_venv()  # run with .venv/bin/python, however started

from fsreg_ros.graph import Graph, graph_nodes, ros_environment  # noqa: E402

os.environ.update(ros_environment())  # LOCALHOST discovery unless set; before rclpy loads

from fsreg_ros.core.consultant import LocalPort, run_sync  # noqa: E402
from fsreg_ros.core.generation import generate  # noqa: E402
from fsreg_ros.core.resolution import resolve  # noqa: E402
from fsreg_ros.core.scenario import load_scenario  # noqa: E402
from fsreg_ros.core.simulation import Options, Simulation  # noqa: E402


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q * (len(ordered) - 1))))]


class CountingPort(LocalPort):
    """A LocalPort that counts calls (each is one service call over the graph)."""

    calls = 0

    def _count(self):
        CountingPort.calls += 1

    async def entities(self):
        self._count()
        return await super().entities()

    async def holds(self, prop, entities):
        self._count()
        return await super().holds(prop, entities)

    async def affirm(self, prop, entities, cause, time, turn):
        self._count()
        return await super().affirm(prop, entities, cause, time, turn)

    async def wm(self, entity):
        self._count()
        return await super().wm(entity)

    async def encode(self, entity, properties, cause, time, turn):
        self._count()
        return await super().encode(entity, properties, cause, time, turn)


def core_latencies(scenario, options: Options, rounds: int) -> tuple[list[float], list[float], float, float]:
    """In-process latencies (ms) of the same turns, and service calls per turn."""
    human, robot = [], []
    calls_human = calls_robot = 0
    for _ in range(rounds):
        sim = Simulation(scenario, options)
        ports = {d: CountingPort(c) for d, c in sim.consultants.items()}
        for turn in scenario.dialogue:
            before = CountingPort.calls
            start = time.perf_counter()
            if turn.speaker == "human":
                run_sync(resolve(list(turn.description), ports, domain=turn.domain, time=turn.time, turn=turn.index))
                human.append((time.perf_counter() - start) * 1e3)
                calls_human += CountingPort.calls - before
            else:
                domain = scenario.domain_of(turn.target)
                run_sync(generate(turn.target, ports[domain], "sd-pia", time=turn.time, turn=turn.index))
                robot.append((time.perf_counter() - start) * 1e3)
                calls_robot += CountingPort.calls - before + len(ports)  # + REG's info per domain
    return human, robot, calls_human / max(1, len(human)), calls_robot / max(1, len(robot))


def graph_latencies(scenario, scenario_path: Path, options: Options, rounds: int) -> tuple[list[float], list[float], float]:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import String

    from fsreg_ros import contract
    from fsreg_ros.codec import from_msg, to_msg

    tmp = Path(tempfile.mkdtemp(prefix="fsreg-bench-"))
    nodes = [n for n in graph_nodes(scenario, scenario_path, options, tmp / "unused.json") if n.name != "dialogue_player"]
    graph = Graph(nodes, tmp)
    started = time.perf_counter()
    graph.start()
    rclpy.init()
    node = rclpy.create_node("bench_graph")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    answers: dict[str, dict] = {}

    def on_answer(msg):
        data = from_msg(msg, {})
        answers[str(data.get("id"))] = data

    node.create_subscription(String, contract.RR_RESULT.name, on_answer, contract.RR_RESULT.qos)
    node.create_subscription(String, contract.REG_EXPRESSION.name, on_answer, contract.REG_EXPRESSION.qos)
    human_pub = node.create_publisher(String, contract.HUMAN.name, contract.HUMAN.qos)
    reg_pub = node.create_publisher(String, contract.REG_REQUEST.name, contract.REG_REQUEST.qos)

    def exchange(publisher, message: dict, timeout: float = 30.0) -> float:
        key = str(message["id"])
        start = time.perf_counter()
        publisher.publish(to_msg(message))
        resend = start + 2.0
        while key not in answers:
            executor.spin_once(timeout_sec=0.001)
            now = time.perf_counter()
            if now - start > timeout:
                raise RuntimeError(f"no answer to {key}")
            if now > resend:  # discovery not complete yet: at-least-once, ids deduplicated
                publisher.publish(to_msg(message))
                resend = now + 2.0
        if "error" in answers[key]:
            raise RuntimeError(answers[key]["error"])
        return (time.perf_counter() - start) * 1e3

    try:
        # Warm-up: one full round (first calls to new servers are slow), also readiness.
        human, robot = [], []
        for rnd in range(rounds + 1):
            for turn in scenario.dialogue:
                message = {"id": f"{rnd}/{turn.index}", "time": turn.time, "turn": turn.index}
                if turn.speaker == "human":
                    ms = exchange(human_pub, {**message, "description": list(turn.description)})
                    (human if rnd else []).append(ms)
                else:
                    ms = exchange(reg_pub, {**message, "target": turn.target})
                    (robot if rnd else []).append(ms)
            if rnd == 0:
                ready = time.perf_counter() - started
        return human, robot, ready
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        graph.stop()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenario", nargs="?", type=Path, default=REPO / "scenarios" / "guess_who_table1.yaml")
    parser.add_argument("--rounds", type=int, default=20)
    parser.add_argument("--policy", default="displacement", help="decay ticks need a clock; displacement does not")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    scenario = load_scenario(args.scenario)
    options = Options(memory={"policy": args.policy})
    if any(t.text is not None for t in scenario.dialogue):
        print("bench_graph: use a scenario with description turns", file=sys.stderr)
        return 2
    core_h, core_r, calls_h, calls_r = core_latencies(scenario, options, args.rounds)
    graph_h, graph_r, ready = graph_latencies(scenario, args.scenario, options, args.rounds)
    rows = {
        "human turn -> /rr/result": (graph_h, core_h),
        "REG request -> /reg/expression": (graph_r, core_r),
    }
    results = {"scenario": scenario.name, "rounds": args.rounds, "startup_and_warmup_s": ready,
               "service_calls_per_turn": {"human": calls_h, "robot": calls_r}, "latency_ms": {}}
    print(f"scenario {scenario.name}, {args.rounds} rounds, policy {args.policy}; "
          f"graph up + warm-up round in {ready:.2f} s")
    print(f"{'path':<32} {'graph p50':>10} {'graph p95':>10} {'core p50':>10} {'core p95':>10} {'p50 ratio':>10}")
    for name, (graph, core) in rows.items():
        g50, g95 = statistics.median(graph), percentile(graph, 0.95)
        c50, c95 = statistics.median(core), percentile(core, 0.95)
        results["latency_ms"][name] = {"graph_p50": g50, "graph_p95": g95, "core_p50": c50, "core_p95": c95,
                                       "ratio_p50": g50 / c50}
        print(f"{name:<32} {g50:>9.2f}  {g95:>9.2f}  {c50:>9.3f}  {c95:>9.3f}  {g50 / c50:>9.0f}x")
    print(f"consultant service calls per turn: human {calls_h:.1f}, robot {calls_r:.1f}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=2, sort_keys=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
