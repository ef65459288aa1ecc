#!/usr/bin/env python3
"""Latency of the node graph as users run it, next to the bare hop and the core, at three sizes.

For each world -- Table 1 and the random worlds of ``scripts/make_world.py`` with 1,000
and 10,000 entities (:mod:`fsreg_ros.tools.worlds`, seeded, its default shape) -- it starts the
graph ``fsreg-up`` starts, with every default: one process per node, persistence on (a
state directory of its own), sim time, the scenario's memory settings, a namespace of
its own (:class:`fsreg_ros.testing.LiveGraph` with ``processes=True``; the consultants'
debug service off, as ``fsreg-up`` has it).  Every world's graph is up at once and their
turns are interleaved (turn i of each world before turn i + 1 of any), so every figure,
across worlds too, is taken under the same machine load.  It waits until the graph says it is ready
(``wm_manager/ready`` and every topic matched: :meth:`GraphClient.wait_ready`) and then,
through the public :class:`~fsreg_ros.ros.client.GraphClient`, measures per turn:

* human turn -> ``rr/result`` (parser -> RR -> consultant calls);
* ``reg/request`` -> ``reg/expression``;
* the *bare hop*, interleaved with the turns (same graph, same machine load): one
  consultant service call that does no work (``info`` of the entities past the last),
  from this process.

p50 / p95 over ``--rounds`` rounds of the world's first ``--turns`` turns (after one
warm-up round; each round shifts the turns' times by the dialogue's length, so time never
runs backwards), next to the same turns run in-process by the core (RR and REG through
a :class:`LocalPort`, one continuous memory, the same memory settings), which also counts
the consultant calls per turn (each port call is one service call of the graph's).

Targets, checked per path: on Table 1 (where the core's work is tens of microseconds)
the graph's p50 is within ``1.5 x (calls per turn + 2)`` bare hops (each call is a hop;
the two more are the request and the reply); from Table 1 to 10,000 entities the graph's
p50 grows by at most ``3 x`` what the core's grows (``(graph 10k - graph T1) / (core 10k
- core T1) <= 3``: what the graph adds on top of the core's work must not grow with the
world).

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

from venv_python import prepare  # noqa: E402

REPO = prepare("bench_graph.py", loopback=True)  # .venv, import path, loopback ROS

from fsreg_ros import contract  # noqa: E402
from fsreg_ros.core.consultant.local_port import LocalPort  # noqa: E402
from fsreg_ros.core.algorithms.port import run_sync  # noqa: E402
from fsreg_ros.core.algorithms.generation import generate  # noqa: E402
from fsreg_ros.core.algorithms.resolution import resolve  # noqa: E402
from fsreg_ros.core.scenario import load_scenario  # noqa: E402
from fsreg_ros.core.simulation.simulator import Options, Simulation  # noqa: E402
from fsreg_ros.ros.client_base import ClientError  # noqa: E402
from fsreg_ros.tools.worlds import WorldShape, dump_world, random_world  # noqa: E402

TABLE1 = REPO / "scenarios" / "guess_who_table1.yaml"
#: A Table 1 turn's p50 may take this many bare hops per (calls per turn + 2).
HOP_FACTOR = 1.5
#: From Table 1 to 10,000 entities the graph's p50 may grow this many times what the core's grows.
GROWTH_FACTOR = 3.0
PATHS = (("human", "human turn -> rr/result"), ("robot", "reg/request -> reg/expression"))
READY_TIMEOUT = 120.0  # a 10,000-entity consultant loads its KB and restores its state first


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q * (len(ordered) - 1))))]


class CountingPort(LocalPort):
    """A LocalPort that counts the calls a RemotePort would send as service calls."""

    calls = 0

    async def open(self, target=None, context=None, first=None, refer=None):
        CountingPort.calls += 1
        return await super().open(target, context, first, refer)

    async def narrow(self, view, prop, cause, time, turn):
        CountingPort.calls += 1
        return await super().narrow(view, prop, cause, time, turn)

    async def walk(self, view, steps, cause, time, turn, size=None):
        CountingPort.calls += 1  # one call: the consultant runs the walk, as the node does
        return self.service.walk(view.handle, steps, cause, time, turn)

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
    out: dict = {"human": [], "robot": []}
    calls: dict = {"human": [], "robot": []}
    for rnd in range(rounds + 1):  # round 0 warms up
        for turn in turns:
            when = turn.time + rnd * span
            before = CountingPort.calls
            start = time.perf_counter()
            if turn.speaker == "human":
                run_sync(resolve(list(turn.description), ports, domain=turn.domain, time=when, turn=turn.index))
            else:
                domain = scenario.domain_of(turn.target)
                run_sync(generate(turn.target, ports[domain], "sd-pia", time=when, turn=turn.index))
            elapsed = (time.perf_counter() - start) * 1e3
            kind = "human" if turn.speaker == "human" else "robot"
            if rnd:
                out[kind].append(elapsed)
                calls[kind].append(CountingPort.calls - before)
    out["calls"] = {k: statistics.fmean(v) if v else 0.0 for k, v in calls.items()}
    return out


class WorldGraph:
    """One world's live graph (as ``fsreg-up`` runs it) and its measurements, turn by turn."""

    def __init__(self, name: str, scenario, path: Path, turns: list, domain_id) -> None:
        from fsreg_ros.testing import LiveGraph

        self.name, self.scenario, self.turns = name, scenario, turns
        debug_off = {f"consultant_{d}": {"debug": False} for d in scenario.domains}  # as fsreg-up runs them
        started = time.perf_counter()
        self.live = LiveGraph(path, processes=True, parameters=debug_off, ready_timeout=READY_TIMEOUT,
                              domain_id=domain_id).start()  # returns once the graph says it is ready
        self.ready_s = time.perf_counter() - started
        self.client = self.live.client
        self.hop_clients = {d: self.client.service(contract.consultant_service(d)) for d in scenario.domains}
        for domain in scenario.domains:  # a first request to a server just discovered can be lost: one answered
            # round trip each (GraphClient.call resends until answered) before any hop is timed with one send
            self.client.call(contract.consultant_service(domain), {"op": "info", "entities_from": 1 << 30},
                             timeout=READY_TIMEOUT)
        self.span = turns[-1].time + 1.0
        self.human: list[float] = []
        self.robot: list[float] = []
        self.hops: list[float] = []

    def hop(self, domain: str) -> float:
        """One consultant call that does no work (``info`` of no entity), from this process; its ms."""
        service, executor = self.hop_clients[domain], self.client.executor
        start = time.perf_counter()
        future = service.send({"op": "info", "entities_from": 1 << 30})
        while not future.done():
            executor.spin_once(timeout_sec=0.001)
            if time.perf_counter() - start > 10.0:
                raise RuntimeError(f"{self.name}: no answer from {service.name}")
        reply = service.decode(future)
        if "error" in reply:
            raise RuntimeError(f"{self.name}: {service.name}: {reply['error']}")
        return (time.perf_counter() - start) * 1e3

    def step(self, rnd: int, index: int) -> None:
        """Run turn ``index`` of round ``rnd`` (0 warms up) with one bare hop before it."""
        if index >= len(self.turns):
            return
        turn, scenario = self.turns[index], self.scenario
        when = turn.time + rnd * self.span
        domain = scenario.domain_of(turn.target) if turn.speaker == "robot" else \
            turn.domain or next(iter(scenario.domains))
        ms_hop = self.hop(domain)
        start = time.perf_counter()
        if turn.speaker == "human":
            reply = self.client.say(description=list(turn.description), domain=turn.domain, time=when,
                                    turn=turn.index, timeout=30.0)
        else:
            reply = self.client.describe(turn.target, time=when, turn=turn.index, timeout=30.0)
        ms = (time.perf_counter() - start) * 1e3
        if reply.get("error"):
            raise RuntimeError(f"{self.name}, turn {turn.index}: {reply['error']}")
        if rnd:
            self.hops.append(ms_hop)
            (self.human if turn.speaker == "human" else self.robot).append(ms)

    def close(self) -> None:
        self.live.close()


def graph_latencies(worlds: dict, rounds: int, domain_id) -> dict:
    """Latencies (ms) of every world's turns through its live graph, all graphs up at once, turns interleaved.

    Turn i of every world runs before turn i + 1 of any, so every world (and its bare
    hop) is measured under the same machine load: the growth from one world to the
    next is a ratio within one run.
    """
    graphs: dict[str, WorldGraph] = {}
    try:
        for name, (scenario, path, turns) in worlds.items():
            graphs[name] = WorldGraph(name, scenario, path, turns, domain_id)
        longest = max(len(g.turns) for g in graphs.values())
        for rnd in range(rounds + 1):  # round 0 warms up (first calls to new servers are slow)
            for index in range(longest):
                for graph in graphs.values():
                    graph.step(rnd, index)
            print(f"    round {rnd} done", file=sys.stderr, flush=True)
        return {name: {"human": g.human, "robot": g.robot, "hop": g.hops, "ready_s": g.ready_s}
                for name, g in graphs.items()}
    finally:
        for graph in graphs.values():
            graph.close()


def world_path(size: str, tmp: Path) -> Path:
    """Return Table 1's scenario, or write the random world of ``size`` entities (make_world.py's shape)."""
    if size == "table1":
        return TABLE1
    path = tmp / f"world-{size}.yaml"
    path.write_text(dump_world(random_world(WorldShape(entities=int(size)))), encoding="utf-8")
    return path


def row_of(size: str, scenario, turns: list, core: dict, graph: dict) -> dict:
    """Return one world's figures: graph and core p50/p95 per path, the bare hop, calls per turn."""
    entities = sum(len(spec.entities) for spec in scenario.domains.values())
    hop = statistics.median(graph["hop"])
    row = {"world": size, "entities": entities, "turns": len(turns), "ready_s": graph["ready_s"],
           "hop_p50": hop, "hop_p95": percentile(graph["hop"], 0.95), "paths": {}}
    for kind, label in PATHS:
        g, c = graph[kind], core[kind]
        if not g:
            continue
        calls = core["calls"][kind]
        row["paths"][kind] = {
            "label": label, "graph_p50": statistics.median(g), "graph_p95": percentile(g, 0.95),
            "core_p50": statistics.median(c), "core_p95": percentile(c, 0.95), "calls": calls,
            "hops": statistics.median(g) / hop, "hop_budget": HOP_FACTOR * (calls + 2)}
    return row


def verdicts(rows: list[dict]) -> list[str]:
    """Check the targets; return one line per check (and mark each row's path)."""
    lines = []
    base = next((r for r in rows if r["world"] == "table1"), None)
    big = next((r for r in rows if r["entities"] >= 10_000), None)
    for kind, label in PATHS:
        if base is not None and kind in base["paths"]:
            p = base["paths"][kind]
            met = p["hops"] <= p["hop_budget"]
            p["verdict_hops"] = met
            lines.append(f"Table 1 {label}: {p['hops']:.1f} bare hops, target <= {HOP_FACTOR:g} x "
                         f"({p['calls']:.1f} calls + 2) = {p['hop_budget']:.1f}: {'met' if met else 'MISSED'}")
        if base is not None and big is not None and kind in base["paths"] and kind in big["paths"]:
            b, p = base["paths"][kind], big["paths"][kind]
            graph_growth = p["graph_p50"] - b["graph_p50"]
            core_growth = p["core_p50"] - b["core_p50"]
            ratio = graph_growth / core_growth if core_growth > 0 else float("inf")
            p["growth_ratio"] = ratio
            met = ratio <= GROWTH_FACTOR
            extra = (p["calls"] - b["calls"]) * big["hop_p50"]  # the hops of the calls the bigger world needs
            p["growth_net_ratio"] = net = (graph_growth - extra) / core_growth if core_growth > 0 else float("inf")
            lines.append(f"Table 1 -> {big['entities']:,} {label}: graph p50 +{graph_growth:.2f} ms, core p50 "
                         f"+{core_growth:.2f} ms: x{ratio:.2f} the core's growth, target <= x{GROWTH_FACTOR:g}: "
                         f"{'met' if met else 'MISSED'}; of it {p['calls'] - b['calls']:+.1f} calls per turn x "
                         f"{big['hop_p50']:.2f} ms hop = {extra:.2f} ms, the rest x{net:.2f} the core's growth")
    return lines


def render(rows: list[dict], checks: list[str], args) -> str:
    load = os.getloadavg()
    lines = [f"bench_graph: {args.rounds} rounds of up to {args.turns} turns, every default (persistence on, "
             f"sim time, one process per node); load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} "
             f"on {os.cpu_count()} cores"]
    header = (f"{'world':<8} {'path':<30} {'graph p50':>9} {'p95':>7} {'core p50':>9} {'p95':>7} "
              f"{'hop p50':>7} {'calls':>5} {'hops':>6} {'budget':>6}")
    lines += [header, "-" * len(header)]
    for row in rows:
        for kind, p in row["paths"].items():
            lines.append(
                f"{row['world']:<8} {p['label']:<30} {p['graph_p50']:>9.2f} {p['graph_p95']:>7.2f} "
                f"{p['core_p50']:>9.3f} {p['core_p95']:>7.3f} {row['hop_p50']:>7.2f} {p['calls']:>5.1f} "
                f"{p['hops']:>6.1f} {p['hop_budget']:>6.1f}")
    lines.append("")
    for row in rows:
        lines.append(f"{row['world']}: {row['entities']} entities, {row['turns']} turns, ready after "
                     f"{row['ready_s']:.1f} s, bare hop p50 {row['hop_p50']:.2f} ms, p95 {row['hop_p95']:.2f} ms")
    lines.append("(ms; hops = graph p50 / bare hop p50; budget = 1.5 x (calls per turn + 2))")
    lines += [""] + checks
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--worlds", default="table1,1000,10000",
                        help="comma-separated: table1 and/or entity counts of make_world.py worlds")
    parser.add_argument("--turns", type=int, default=40, help="turns per round (a world's first N)")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--domain-id", type=int, help="ROS domain of the graphs (default: ROS_DOMAIN_ID)")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    if args.turns < 1 or args.rounds < 1:
        parser.error("--turns and --rounds must be >= 1")
    sizes = [s.strip() for s in args.worlds.split(",") if s.strip()]
    for size in sizes:
        if size != "table1" and not (size.isdigit() and int(size) >= 1):
            parser.error(f"--worlds: {size!r} is neither 'table1' nor an entity count")
    tmp = Path(tempfile.mkdtemp(prefix="fsreg-worlds-"))
    worlds, cores = {}, {}
    for size in sizes:
        path = world_path(size, tmp)
        scenario = load_scenario(path)
        turns = turns_of(scenario, args.turns)
        worlds[size] = (scenario, path, turns)
        cores[size] = core_latencies(scenario, Options(), turns, args.rounds)  # the same memory settings
        print(f"  {size}: core done", file=sys.stderr, flush=True)
    try:
        graphs = graph_latencies(worlds, args.rounds, args.domain_id)
    except (RuntimeError, ClientError) as err:  # a graph that did not answer: one line, not a traceback
        print(f"bench_graph: {err}", file=sys.stderr)
        return 1
    rows = [row_of(size, worlds[size][0], worlds[size][2], cores[size], graphs[size]) for size in sizes]
    checks = verdicts(rows)
    sys.stdout.write(render(rows, checks, args))
    if args.json:
        args.json.write_text(json.dumps({"rows": rows, "checks": checks, "load": os.getloadavg()}, indent=2,
                                        sort_keys=True) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
