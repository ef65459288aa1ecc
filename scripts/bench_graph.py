#!/usr/bin/env python3
"""Latency of the multi-process node graph next to the same work done by the core, at three sizes.

For each world -- Table 1 and random worlds of 1,000 and 10,000 entities
(:mod:`fsreg_ros.worlds`, seeded) -- it starts the real graph (one process per node,
as ``fsreg-graph`` does, without the player) and measures from this process:

* human turn -> ``/rr/result``: publish a description on ``/dialogue/human``, wait for
  the result with its id (parser -> RR -> consultant service calls);
* REG request -> ``/reg/expression``;

p50 / p95 over ``--rounds`` rounds of the world's first ``--turns`` turns (after one
warm-up round), next to the same turns run in-process by the core (RR and REG through a
:class:`LocalPort`, one continuous memory as in the graph), as ratios measured in the
same run.  Each round shifts the turns' times by the dialogue's length, so time never
runs backwards.

The fixed cost of the graph is measured in the same graph, interleaved with the turns:
the p50 of one trivial consultant service round trip (``info`` of no entities) from this process (a
*hop*), and of *null* requests that do no work -- a human turn with no known word (the
parser -> RR -> result pipeline, no consultant call) and a REG request whose context is
its target alone (open and close, no distractor).  Consultant calls per turn are
counted in-process with a port that counts what a ``RemotePort`` sends (every port
call is one service call; the preference order and the entity list are cached).  The
verdict per path is ``graph p50 <= k x core p50 + fixed`` with k = 1.5 at 1,000
entities and 3 at 10,000, and ``fixed`` = the null request's p50 + (this world's calls
per turn - the null request's) x the cost of one call inside the pipeline, calibrated
on Table 1 (where the core's work is tens of microseconds; a call from inside a node
costs more than the bare hop: an awaited future, a deadline timer).

    scripts/bench_graph.py [--worlds table1,1000,10000] [--turns 40] [--rounds 3] [--json FILE]

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
from fsreg_ros.worlds import WorldShape, dump_world, random_world  # noqa: E402

TABLE1 = REPO / "scenarios" / "guess_who_table1.yaml"
#: Consultant calls of the null requests: a human turn with no known word (none), REG
#: with no distractor (open and close).
NULL_CALLS = {"human": 0, "robot": 2}
#: Target ratio graph p50 / core p50 (on top of the fixed cost) by world size.
TARGETS = {1_000: 1.5, 10_000: 3.0}


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q * (len(ordered) - 1))))]


class CountingPort(LocalPort):
    """A LocalPort that counts the calls a RemotePort would send as service calls."""

    calls = 0

    async def open(self, target=None, context=None, first=None):
        CountingPort.calls += 1
        return await super().open(target, context, first)

    async def narrow(self, view, prop, cause, time, turn):
        CountingPort.calls += 1
        return await super().narrow(view, prop, cause, time, turn)

    async def rule_out(self, view):
        CountingPort.calls += 1
        return await super().rule_out(view)

    async def close(self, view, encode=(), time=0.0, turn=None):
        CountingPort.calls += 1
        return await super().close(view, encode, time, turn)

    async def wm(self, entity):
        CountingPort.calls += 1
        return await super().wm(entity)

    async def encode(self, entity, properties, cause, time, turn):
        CountingPort.calls += 1
        return await super().encode(entity, properties, cause, time, turn)


def turns_of(scenario, count: int) -> list:
    """Return the first ``count`` turns that are robot turns or human turns given as properties."""
    return [t for t in scenario.dialogue if t.speaker == "robot" or t.description is not None][:count]


def core_latencies(scenario, options: Options, turns: list, rounds: int) -> dict:
    """In-process latencies (ms) of the turns, round after round on one memory, and calls per turn."""
    sim = Simulation(scenario, options)
    ports = {d: CountingPort(c) for d, c in sim.consultants.items()}
    span = turns[-1].time + 1.0
    human, robot, calls = [], [], {"human": [], "robot": []}
    for rnd in range(rounds + 1):  # round 0 warms up
        for turn in turns:
            when = turn.time + rnd * span
            before = CountingPort.calls
            start = time.perf_counter()
            if turn.speaker == "human":
                run_sync(resolve(list(turn.description), ports, domain=turn.domain, time=when, turn=turn.index))
                kind, out = "human", human
            else:
                domain = scenario.domain_of(turn.target)
                run_sync(generate(turn.target, ports[domain], "sd-pia", time=when, turn=turn.index))
                kind, out = "robot", robot
            elapsed = (time.perf_counter() - start) * 1e3
            if rnd:
                out.append(elapsed)
                calls[kind].append(CountingPort.calls - before)
    return {"human": human, "robot": robot,
            "calls": {k: statistics.fmean(v) if v else 0.0 for k, v in calls.items()}}


def graph_latencies(scenario, scenario_path: Path, options: Options, turns: list, rounds: int) -> dict:
    import rclpy
    from diagnostic_msgs.srv import AddDiagnostics
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import String

    from fsreg_ros import contract
    from fsreg_ros.carrier import from_msg, qos_profile, to_msg

    tmp = Path(tempfile.mkdtemp(prefix="fsreg-bench-"))
    nodes = [n for n in graph_nodes(scenario, scenario_path, options, tmp / "unused.json")
             if n.name != "dialogue_player"]
    graph = Graph(nodes, tmp)
    started = time.perf_counter()
    graph.start()
    rclpy.init()
    node = rclpy.create_node("bench_graph")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    answers: dict[str, dict] = {}

    def on_answer(msg):
        data = from_msg(msg)
        answers[str(data.get("id"))] = data

    node.create_subscription(String, contract.RR_RESULT.name, on_answer, qos_profile(contract.RR_RESULT.qos))
    node.create_subscription(String, contract.REG_EXPRESSION.name, on_answer,
                             qos_profile(contract.REG_EXPRESSION.qos))
    human_pub = node.create_publisher(String, contract.HUMAN.name, qos_profile(contract.HUMAN.qos))
    reg_pub = node.create_publisher(String, contract.REG_REQUEST.name, qos_profile(contract.REG_REQUEST.qos))
    domain = next(iter(scenario.domains))
    hop_client = node.create_client(AddDiagnostics, contract.consultant_service(domain))

    def exchange(publisher, message: dict, timeout: float = 60.0) -> float:
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

    status_client = node.create_client(AddDiagnostics, contract.STATUS.name)

    def call(client, payload: dict, timeout: float = 10.0) -> dict:
        future = client.call_async(AddDiagnostics.Request(load_namespace=json.dumps(payload)))
        start = time.perf_counter()
        while not future.done():
            executor.spin_once(timeout_sec=0.001)
            if time.perf_counter() - start > timeout:
                raise RuntimeError(f"no answer from {client.srv_name}")
        return json.loads(future.result().message)

    def hop_info() -> dict:
        return call(hop_client, {"op": "info", "entities_from": 1 << 30}, timeout=2.0)

    def configured() -> bool:
        return status_client.service_is_ready() and all(
            call(status_client, {}, timeout=2.0).get("configured", {}).values())

    def hop(timeout: float = 10.0) -> float:
        # a production op with no work: info for the entities past the last (none)
        request = AddDiagnostics.Request(load_namespace=json.dumps({"op": "info", "entities_from": 1 << 30}))
        start = time.perf_counter()
        future = hop_client.call_async(request)
        while not future.done():
            executor.spin_once(timeout_sec=0.001)
            if time.perf_counter() - start > timeout:
                raise RuntimeError("no answer to a consultant hop")
        return (time.perf_counter() - start) * 1e3

    try:
        human, robot, hops = [], [], []
        span = turns[-1].time + 1.0
        ready = 0.0
        deadline = time.monotonic() + 10.0
        while not hop_client.service_is_ready() and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.01)
        while True:  # one real round trip, and the WM Manager has configured every consultant
            try:
                if hop_info() and configured():
                    break
            except RuntimeError:  # a first request to a server just discovered can be lost: ask again
                pass
            if time.monotonic() > deadline + 50.0:
                raise RuntimeError("the consultants were not configured within 60 s")
            executor.spin_once(timeout_sec=0.05)
        null_human, null_robot = [], []
        for rnd in range(rounds + 1):  # round 0 warms up (first calls to new servers are slow)
            for turn in turns:
                if rnd:  # one hop and one null request per turn, interleaved: the same machine load
                    hops.append(hop())
                    null = {"id": f"null/{rnd}/{turn.index}", "time": turn.time + rnd * span}
                    if turn.speaker == "human":  # no known word: the pipeline, no consultant call
                        null_human.append(exchange(human_pub, {**null, "text": "zzz"}))
                    else:  # no distractor: open and close only
                        null_robot.append(exchange(reg_pub, {**null, "target": turn.target, "context": [turn.target]}))
                else:
                    hop(30.0)
                message = {"id": f"{rnd}/{turn.index}", "time": turn.time + rnd * span, "turn": turn.index}
                if turn.speaker == "human":
                    ms = exchange(human_pub, {**message, "description": list(turn.description)})
                    (human if rnd else []).append(ms)
                else:
                    ms = exchange(reg_pub, {**message, "target": turn.target})
                    (robot if rnd else []).append(ms)
            if rnd == 0:
                ready = time.perf_counter() - started
            print(f"    round {rnd} done", file=sys.stderr, flush=True)
        return {"human": human, "robot": robot, "hop": statistics.median(hops), "ready_s": ready,
                "null": {"human": statistics.median(null_human), "robot": statistics.median(null_robot)}}
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        graph.stop()


def world_path(size: str, turns: int, tmp: Path) -> Path:
    if size == "table1":
        return TABLE1
    shape = WorldShape(entities=int(size), human_turns=turns // 2, robot_turns=turns - turns // 2)
    path = tmp / f"world-{size}.yaml"
    path.write_text(dump_world(random_world(shape)), encoding="utf-8")
    return path


def run_world(size: str, args, tmp: Path) -> dict:
    path = world_path(size, args.turns, tmp)
    t0 = time.perf_counter()
    scenario = load_scenario(path)
    load_s = time.perf_counter() - t0
    options = Options(memory={"policy": args.policy})
    turns = turns_of(scenario, args.turns)
    core = core_latencies(scenario, options, turns, args.rounds)
    graph = graph_latencies(scenario, path, options, turns, args.rounds)
    entities = sum(len(spec.entities) for spec in scenario.domains.values())
    row = {"world": size, "entities": entities, "turns": len(turns), "load_s": load_s, "hop_ms": graph["hop"],
           "ready_s": graph["ready_s"], "calls_per_turn": core["calls"], "null_ms": graph["null"], "paths": {}}
    for kind, label in (("human", "human turn -> /rr/result"), ("robot", "REG -> /reg/expression")):
        g, c = graph[kind], core[kind]
        row["paths"][kind] = {"label": label, "graph_p50": statistics.median(g), "graph_p95": percentile(g, 0.95),
                              "core_p50": statistics.median(c), "core_p95": percentile(c, 0.95)}
    return row


def per_call_ms(rows: list[dict], kind: str) -> float:
    """Return what one consultant call costs inside the pipeline, calibrated where the core's work is nil.

    On Table 1 (tens of microseconds of core work): (graph p50 - core p50 - null p50) /
    (calls per turn - the null request's calls); the bare hop from this process if
    Table 1 was not run.
    """
    base = next((r for r in rows if r["world"] == "table1"), None)
    if base is None:
        return statistics.median(r["hop_ms"] for r in rows)
    path = base["paths"][kind]
    extra = base["calls_per_turn"][kind] - NULL_CALLS[kind]
    return max(0.0, path["graph_p50"] - path["core_p50"] - base["null_ms"][kind]) / max(extra, 1.0)


def verdicts(rows: list[dict]) -> None:
    """Add the fixed cost, the net ratio and the verdict to each world's paths."""
    for row in rows:
        for kind, path in row["paths"].items():
            path["ratio_p50"] = path["graph_p50"] / path["core_p50"]
            path["per_call_ms"] = per_call = per_call_ms(rows, kind)
            fixed = row["null_ms"][kind] + max(0.0, row["calls_per_turn"][kind] - NULL_CALLS[kind]) * per_call
            path["fixed_ms"] = fixed
            path["net_ratio_p50"] = max(0.0, path["graph_p50"] - fixed) / path["core_p50"]
            target = TARGETS.get(row["entities"])
            if target is not None:
                met = path["graph_p50"] <= target * path["core_p50"] + fixed
                path["verdict"] = f"{'met' if met else 'MISSED'} (<= {target:g}x core + fixed)"


def render(rows: list[dict], args) -> str:
    lines = [f"bench_graph: {args.rounds} rounds of up to {args.turns} turns, policy {args.policy}"]
    header = (f"{'world':<8} {'path':<26} {'graph p50':>9} {'p95':>7} {'core p50':>9} {'p95':>7} "
              f"{'ratio':>7} {'fixed':>7} {'net':>6} {'calls':>5}  verdict")
    lines += [header, "-" * len(header)]
    for row in rows:
        for kind, p in row["paths"].items():
            lines.append(
                f"{row['world']:<8} {p['label']:<26} {p['graph_p50']:>9.2f} {p['graph_p95']:>7.2f} "
                f"{p['core_p50']:>9.3f} {p['core_p95']:>7.3f} {p['ratio_p50']:>6.1f}x "
                f"{p.get('fixed_ms', 0.0):>7.2f} {p.get('net_ratio_p50', 0.0):>5.2f}x "
                f"{row['calls_per_turn'][kind]:>5.1f}  {p.get('verdict', '')}")
    lines.append("")
    for row in rows:
        lines.append(f"{row['world']}: {row['entities']} entities, scenario loaded in {row['load_s']:.2f} s, "
                     f"graph up + warm-up round {row['ready_s']:.1f} s, one consultant hop p50 {row['hop_ms']:.2f} ms, "
                     f"null human turn p50 {row['null_ms']['human']:.2f} ms, "
                     f"null REG p50 {row['null_ms']['robot']:.2f} ms")
    per_call = {kind: p["per_call_ms"] for kind, p in rows[0]["paths"].items()} if rows else {}
    lines.append("(ms; ratio = graph p50 / core p50; fixed = the null request's p50 + the calls it lacks x one call's "
                 "cost in the pipeline, " + ", ".join(f"{k} {v:.2f}" for k, v in per_call.items()) +
                 " ms; net = (graph p50 - fixed) / core p50)")
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--worlds", default="table1,1000,10000",
                        help="comma-separated: table1 and/or entity counts of random worlds")
    parser.add_argument("--turns", type=int, default=40, help="turns per round (a world's first N)")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--policy", default="displacement", help="decay ticks need a clock; displacement does not")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="fsreg-worlds-"))
    rows = []
    for size in args.worlds.split(","):
        rows.append(run_world(size.strip(), args, tmp))
        print(f"  {size}: done", file=sys.stderr, flush=True)
    verdicts(rows)
    sys.stdout.write(render(rows, args))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=2, sort_keys=True) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
