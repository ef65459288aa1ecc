#!/usr/bin/env python3
"""Benchmark of fsreg-sweep on a Dask cluster against local processes, and a projection beyond this machine (issue 25).

What it measures, in one run (ratios within the run; the load average is printed
before each timed command, since other work on the machine moves every figure):

* the README's follow-up sweep (``fsreg_ros.tools.figures.FOLLOWUP``: 6 policies,
  131 settings, 30 games of 200 turns), run as users run it -- ``fsreg-sweep ...
  --jobs 2`` and ``fsreg-sweep ... --cluster local:2``, each a fresh process, timed
  end to end.  Their runs.csv, summary.csv, divergence.csv and recommendation.csv must
  be byte-identical (exit status 1 otherwise).  The figure is the ratio cluster / jobs
  (target: at most 1.15) and the cluster path's overhead per game;
* the cluster's fixed costs in-process: starting a loopback LocalCluster of two
  workers with a client, a worker's first task (imports), closing it;
* the per-task cost: one game of the sweep played in this process (seconds of one
  core), and the Dask round trip of an empty task on the running cluster;
* transfer sizes: a task sent to a worker (the pickled configuration and seed), a
  game's result sent back (pickled), and its line in games.jsonl;
* the calling process's work per game (the ledger's fsync'd append, read back) and
  the summary's bootstrap over all games, both serial in the client.

From these it *projects* a sweep 100 times larger (3,000 games) on 50 one-thread
workers, each as fast as a core of this machine; the projection is printed with its
assumptions and is not a measurement.  ``--quick`` runs a small sweep instead (for
the smoke test).  No timing is asserted anywhere.

Usage: ``scripts/bench_cluster.py [--quick] [--seeds N] [--turns N] [--workers N]
[--scale 100] [--to 50] [--repeat N] [--json FILE]`` (re-runs itself with the repository's
``.venv`` Python when started otherwise).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pickle
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from venv_python import prepare  # noqa: E402

prepare("bench_cluster.py")  # .venv, import path


TARGET_RATIO = 1.15  # cluster / local processes, end to end
SUMMARY_GAMES = (30, 300)  # the summary's bootstrap is timed at these numbers of games
OUTPUTS = ("runs.csv", "summary.csv", "divergence.csv", "recommendation.csv")


def load() -> str:
    return "load average " + " ".join(f"{x:.2f}" for x in os.getloadavg())


def sweep_args(seeds: int, turns: int) -> list:
    from fsreg_ros.tools.figures import FOLLOWUP

    argv = [a for a in FOLLOWUP]
    argv[argv.index("--seeds") + 1] = str(seeds)
    argv[argv.index("--turns") + 1] = str(turns)
    at = argv.index("--jobs")
    del argv[at:at + 2]  # the engine is chosen per run
    return argv + ["--no-plots"]


def timed_sweep(args: list, engine: list, out: Path) -> dict:
    tool = Path(sys.executable).parent / "fsreg-sweep"
    before = load()
    start = time.perf_counter()
    done = subprocess.run([str(tool), *args, *engine, "--out", str(out)], capture_output=True, text=True)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        sys.exit(f"bench_cluster: {' '.join(engine)} failed:\n{done.stderr}")
    manifest = json.loads((out / "manifest.json").read_text())
    return {"engine": " ".join(engine), "wall_s": wall, "load_before": before, "execution": manifest["execution"]}


def cluster_costs(config, workers: int, tasks: int) -> dict:
    """Start, first task, empty-task round trip and close of a loopback LocalCluster, in this process."""
    from fsreg_ros.research.execution import Engine, dask_client, run_tasks
    from fsreg_ros.research.sweep import run_seed

    engine = Engine("cluster", workers)
    start = time.perf_counter()
    context = dask_client(engine)
    client = context.__enter__()
    up = time.perf_counter() - start
    try:
        start = time.perf_counter()
        tiny = replace(config, policies=("none",), turns=2)  # a worker's imports and set-up, next to no game
        run_tasks(run_seed, [(tiny, seed) for seed in range(workers)], engine, progress=False, client=client)
        first = time.perf_counter() - start
        run_tasks(abs, list(range(workers * 4)), engine, progress=False, client=client)  # warm
        start = time.perf_counter()
        run_tasks(abs, list(range(tasks)), engine, progress=False, client=client)
        empty = (time.perf_counter() - start) / tasks
    finally:
        start = time.perf_counter()
        context.__exit__(None, None, None)
        down = time.perf_counter() - start
    return {"start_s": up, "first_tasks_s": first, "empty_task_ms": empty * 1e3, "close_s": down}


def per_game(args: list, games: int, summary_games: tuple = SUMMARY_GAMES) -> dict:
    """One core's cost of a game, the transfer sizes and the client's work per game, in this process."""
    from fsreg_ros.research import cli
    from fsreg_ros.research.ledger import Ledger, header
    from fsreg_ros.research.sweep import COLUMNS, assemble, record_of, run_seed, summarise_runs

    config, _, _ = cli.sweep_config(cli.sweep_parser().parse_args([*args, "--seeds", str(games), "--out", "-"]))
    tasks = [(config, seed) for seed in config.seeds]
    results, costs = [], []
    for task in tasks:
        start = time.process_time()
        results.append(run_seed(task))
        costs.append(time.process_time() - start)
    task_bytes = [len(pickle.dumps(t, protocol=5)) for t in tasks]
    result_bytes = [len(pickle.dumps(r, protocol=5)) for r in results]
    with tempfile.TemporaryDirectory(prefix="fsreg-bench-ledger-") as tmp:
        book = Ledger.start(Path(tmp), header(config, COLUMNS, {}))
        start = time.perf_counter()
        for seed, result in zip(config.seeds, results):
            book.append(record_of(seed, result))
        client_ms = (time.perf_counter() - start) / len(results) * 1e3
        book.close()
        line_bytes = (Path(tmp) / "games.jsonl").stat().st_size / len(results)
    rows, _, _ = assemble(book.games, config.seeds)
    summary_s = {}
    for n in summary_games:  # the sampled games' rows, repeated under other seeds: the bootstrap's cost at n games
        many = [{**row, "seed": row["seed"] + len(rows) * k} for k in range(math.ceil(n / games)) for row in rows]
        many = many[:n * len(rows) // games]
        start = time.perf_counter()
        summary = summarise_runs(many)
        summary_s[n] = time.perf_counter() - start
    return {"config": config, "game_cpu_s": sum(costs) / len(costs), "task_bytes": sum(task_bytes) / len(tasks),
            "result_bytes": sum(result_bytes) / len(results), "ledger_line_bytes": line_bytes,
            "client_ms_per_game": client_ms, "summary_s": summary_s, "settings": len(summary)}


def projection(measured: dict, games: int, workers: int, scale: int, to: int, costs: dict) -> dict:
    """Project a sweep ``scale`` times larger on ``to`` workers from the measured per-task figures."""
    total = games * scale
    waves = math.ceil(total / to)
    compute = waves * measured["game_cpu_s"]
    scheduler = total * costs["empty_task_ms"] / 1e3 / to  # round trips, overlapped across workers
    client = total * measured["client_ms_per_game"] / 1e3  # serial, but overlapped with the workers' compute
    (n1, t1), (n2, t2) = sorted(measured["summary_s"].items())
    summary = t1 + (t2 - t1) * (total - n1) / (n2 - n1)  # the bootstrap grows linearly with the games
    transfer = total * (measured["task_bytes"] + measured["result_bytes"])
    start = costs["start_s"] + costs["first_tasks_s"]
    wall = start + max(compute + scheduler, client) + summary
    return {"games": total, "workers": to, "waves": waves, "compute_s": compute, "scheduler_s": scheduler,
            "client_s": client, "summary_s": summary, "start_s": start, "transfer_mb": transfer / 1e6,
            "projected_wall_s": wall, "one_core_s": total * measured["game_cpu_s"]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="a small sweep (4 games of 20 turns), for the smoke test")
    parser.add_argument("--seeds", type=int, help="games of the timed sweeps (default 30, the README's)")
    parser.add_argument("--turns", type=int, help="turns per game (default 200)")
    parser.add_argument("--workers", type=int, default=2, help="--jobs N against --cluster local:N (default 2)")
    parser.add_argument("--scale", type=int, default=100, help="the projected sweep is this many times larger")
    parser.add_argument("--to", type=int, default=50, help="workers of the projection (default 50)")
    parser.add_argument("--sample", type=int, default=4, help="games played in-process for the per-task figures")
    parser.add_argument("--repeat", type=int, default=1,
                        help="timed pairs, in alternating order (the figure is the ratio of the means)")
    parser.add_argument("--json", type=Path, help="also write every figure as JSON")
    args = parser.parse_args()
    seeds = args.seeds or (4 if args.quick else 30)
    turns = args.turns or (20 if args.quick else 200)
    for name, value, low in (("--seeds", seeds, 1), ("--turns", turns, 2), ("--workers", args.workers, 1),
                             ("--scale", args.scale, 1), ("--to", args.to, 1), ("--sample", args.sample, 1),
                             ("--repeat", args.repeat, 1)):
        if value < low:
            parser.error(f"{name} must be at least {low}, got {value}")
    sweep = sweep_args(seeds, turns)
    print(f"bench_cluster: the follow-up sweep, {seeds} games of {turns} turns, on {os.cpu_count()} cores; "
          f"uptime: {subprocess.run(['uptime'], capture_output=True, text=True).stdout.strip()}")
    work = Path(tempfile.mkdtemp(prefix="fsreg-bench-cluster-"))
    try:
        runs: dict = {"jobs": [], "cluster": []}
        engines = {"jobs": ["--jobs", str(args.workers)], "cluster": ["--cluster", f"local:{args.workers}"]}
        for rep in range(args.repeat):  # A B, B A, ...: drifting load weighs on both alike
            for name in (("jobs", "cluster") if rep % 2 == 0 else ("cluster", "jobs")):
                runs[name].append(timed_sweep(sweep, engines[name], work / name))
        differ = [n for n in OUTPUTS if (work / "jobs" / n).read_bytes() != (work / "cluster" / n).read_bytes()]
        local = {"wall_s": sum(r["wall_s"] for r in runs["jobs"]) / args.repeat,
                 "load_before": "; ".join(r["load_before"] for r in runs["jobs"]), "runs": runs["jobs"]}
        cluster = {"wall_s": sum(r["wall_s"] for r in runs["cluster"]) / args.repeat,
                   "load_before": "; ".join(r["load_before"] for r in runs["cluster"]), "runs": runs["cluster"],
                   "execution": runs["cluster"][-1]["execution"]}
        measured = per_game(sweep, min(args.sample, seeds), (8, 16) if args.quick else SUMMARY_GAMES)
        costs = cluster_costs(measured.pop("config"), args.workers, 200)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    ratio = cluster["wall_s"] / local["wall_s"]
    overhead = (cluster["wall_s"] - local["wall_s"]) / seeds
    fixed = costs["start_s"] + costs["first_tasks_s"] + costs["close_s"]
    marginal = (cluster["wall_s"] - local["wall_s"] - fixed) / seeds
    mean = f"mean of {args.repeat}, " if args.repeat > 1 else ""
    print(f"\n  --jobs {args.workers}:            {local['wall_s']:7.1f} s   ({mean}{local['load_before']} before)")
    print(f"  --cluster local:{args.workers}:   {cluster['wall_s']:7.1f} s   ({mean}{cluster['load_before']} before; "
          f"{cluster['execution']['retried']} tasks retried)")
    print(f"  ratio cluster / jobs: {ratio:.3f} (target at most {TARGET_RATIO}: "
          f"{'met' if ratio <= TARGET_RATIO else 'MISSED'}); cluster overhead {overhead * 1e3:+.0f} ms per game "
          f"({overhead / (local['wall_s'] / seeds) * 100:+.1f} % of a game's share of the --jobs time); of it, "
          f"the fixed start, imports and close ({fixed:.1f} s, measured below) leave {marginal * 1e3:+.0f} ms per game")
    print(f"  outputs: {'byte-identical' if not differ else 'DIFFER: ' + ', '.join(differ)} "
          f"({', '.join(OUTPUTS)})")
    print(f"\n  LocalCluster of {args.workers} on 127.0.0.1: start {costs['start_s']:.2f} s, first task per worker "
          f"(imports, set-up) {costs['first_tasks_s']:.2f} s, close {costs['close_s']:.2f} s; empty-task round trip "
          f"{costs['empty_task_ms']:.2f} ms")
    print(f"  per game ({measured['settings']} settings, {turns} turns): {measured['game_cpu_s']:.2f} s of one core; "
          f"task sent {measured['task_bytes'] / 1e3:.1f} kB, result back {measured['result_bytes'] / 1e3:.1f} kB, "
          f"games.jsonl line {measured['ledger_line_bytes'] / 1e3:.1f} kB; client work "
          f"{measured['client_ms_per_game']:.1f} ms (fsync'd append); summary (bootstrap) "
          + ", ".join(f"{t:.1f} s for {n} games" for n, t in measured["summary_s"].items()))
    plan = projection(measured, seeds, args.workers, args.scale, args.to, costs)
    print(f"\n  PROJECTION (not measured): {plan['games']:,} games on {plan['workers']} one-thread workers, each as "
          f"fast as a core here: {plan['waves']} waves x {measured['game_cpu_s']:.2f} s = {plan['compute_s']:.0f} s "
          f"of compute, + scheduler {plan['scheduler_s']:.1f} s, + start {plan['start_s']:.1f} s, + summary "
          f"{plan['summary_s']:.0f} s (bootstrap, grows with the games); the client's serial work "
          f"({plan['client_s']:.0f} s) overlaps the compute; {plan['transfer_mb']:.0f} MB over the network in all."
          f"\n  => about {plan['projected_wall_s'] / 60:.1f} min, against {plan['one_core_s'] / 3600:.2f} h on one "
          "core")
    if args.json:
        args.json.write_text(json.dumps({"local": local, "cluster": cluster, "ratio": ratio,
                                         "overhead_per_game_s": overhead,
                                         "marginal_overhead_per_game_s": marginal, "identical": not differ,
                                         "cluster_costs": costs, "per_game": measured, "projection": plan},
                                        indent=2) + "\n")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
