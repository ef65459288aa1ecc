#!/usr/bin/env python3
"""Benchmark of ``fsreg-eval tangrams DIR`` (the reference-game evaluation), as users run it (issue 36).

Target: ``fsreg-eval reference-games`` on the tangram games, all models, 1,000 resamples, at
most 30 s on one core.  The command -- ``fsreg-eval tangrams DIR --resamples 1000 --jobs 1
--json`` by default, the installed console script in a fresh process -- is timed end to end:
wall time, and its CPU time (user + system, from the kernel's accounting of the child), which
suffers less from other load on the shared machine; the load average before each run is printed.
The target is judged on the CPU time.

The split -- the imports, reading and tokenising the games, the events, the group WM replays of
every model's grid at once as the command plays them (every grid point through the core's
``WMBuffer``, :func:`fsreg_ros.research.reuse_replay.cells_of`), then each model's grid alone --
is measured in-process in another fresh process (CPU time of each step); the rest of the
command's CPU time is the per-player replays, the fits, the bootstrapped differences and the
JSON. ``--more-grids N`` adds to the figure what N more grids of rule ``activation``'s size
would cost (its replay time per grid point x its grid's size x N), an estimate for models still
to come (a grid point's cost depends on how many games it may forget something in, so run the
models themselves once they exist); ``--profile`` runs the command once under cProfile and
prints the top functions. No timing is asserted anywhere.

Usage: ``scripts/bench_eval.py DIR [--resamples 1000] [--repeat N] [--more-grids N] [--profile]
[--json FILE]`` (DIR: the directory holding tangramsSequential.csv, or the file; default
``$FSREG_TANGRAMS_DIR``; re-runs itself with the repository's ``.venv`` Python when started otherwise).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from venv_python import prepare  # noqa: E402

REPO = prepare("bench_eval.py")  # .venv, import path

TARGET_S = 30.0
EVAL = Path(sys.prefix) / "bin" / "fsreg-eval"

#: The in-process split, run in a fresh process: one JSON line of step -> CPU seconds.
SPLIT = r"""
import json, sys, time
clock = time.process_time
t = clock()
from fsreg_ros.research import tangrams
from fsreg_ros.research.reuse_events import build_events
from fsreg_ros.research.reuse_models import wm_models
from fsreg_ros.research.reuse_replay import cells_of
out = {"imports": clock() - t}
t = clock(); games = tangrams.load_games(sys.argv[1]); out["read"] = clock() - t
t = clock(); events = build_events(games); out["events"] = clock() - t
settings = [None] + [s for model in wm_models() for s in model.settings]
t = clock(); cells_of(events, settings); out["group_replays"] = clock() - t
replays = {}
for model in wm_models():
    t = clock(); cells_of(events, model.settings); replays[model.name] = [len(model.settings), clock() - t]
out["replays"] = replays
print(json.dumps(out))
"""


def run_once(argv: list) -> dict:
    """Run the command in a fresh process: wall and CPU seconds (its own and its children's), exit code."""
    load = os.getloadavg()[0]
    start = time.perf_counter()
    child = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(child.pid, 0)
    wall = time.perf_counter() - start
    err = child.stderr.read().decode(errors="replace") if child.stderr else ""
    child.stderr.close()
    code = os.waitstatus_to_exitcode(status)
    if code != 0:
        raise SystemExit(f"bench_eval: {' '.join(map(str, argv))} exited {code}: {err.strip()[-400:]}")
    return {"load": load, "wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime}


def split(corpus: Path) -> dict:
    text = subprocess.run([sys.executable, "-c", SPLIT, str(corpus)], check=True,
                          capture_output=True, text=True).stdout
    return json.loads(text.strip().splitlines()[-1])


def profile(argv: list) -> None:
    import cProfile
    import pstats

    from fsreg_ros.research.cli import eval_main

    profiler = cProfile.Profile()
    stdout = sys.stdout
    with open(os.devnull, "w") as sink:
        sys.stdout = sink
        try:
            profiler.runcall(eval_main, argv)
        finally:
            sys.stdout = stdout
    pstats.Stats(profiler).sort_stats("tottime").print_stats(20)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("corpus", nargs="?", type=Path, default=os.environ.get("FSREG_TANGRAMS_DIR"),
                        help="the directory holding tangramsSequential.csv, or the file (default $FSREG_TANGRAMS_DIR)")
    parser.add_argument("--resamples", type=int, default=1000, help="the command's --resamples (default 1000)")
    parser.add_argument("--repeat", type=int, default=1, help="runs of the command (default 1)")
    parser.add_argument("--more-grids", type=int, default=0, metavar="N",
                        help="add N more grids of rule activation's size to the figure (default 0)")
    parser.add_argument("--no-split", action="store_true", help="skip the in-process split")
    parser.add_argument("--profile", action="store_true", help="also run the command under cProfile")
    parser.add_argument("--json", type=Path, metavar="FILE", help="write the figures as JSON")
    args = parser.parse_args(argv)
    if args.corpus is None or not Path(args.corpus).exists():
        parser.error("give the tangram games' directory (or set FSREG_TANGRAMS_DIR)")
    if args.repeat < 1 or args.more_grids < 0:
        parser.error("--repeat must be at least 1 and --more-grids at least 0")
    command = ["tangrams", str(args.corpus), "--resamples", str(args.resamples), "--jobs", "1", "--json"]
    print(f"fsreg-eval {' '.join(command)}")
    runs = [run_once([str(EVAL), *command]) for _ in range(args.repeat)]
    for run in runs:
        print(f"  wall {run['wall_s']:6.1f} s, CPU {run['cpu_s']:6.1f} s (load {run['load']:.1f} before)")
    cpu = min(run["cpu_s"] for run in runs)
    report = {"command": "fsreg-eval " + " ".join(command), "runs": runs, "target_s": TARGET_S}
    if not args.no_split:
        parts = split(args.corpus)
        report["split"] = parts
        replays = parts["replays"]
        total = parts["group_replays"]
        rest = cpu - parts["imports"] - parts["read"] - parts["events"] - total
        print(f"split (CPU s, in-process): imports {parts['imports']:.2f}, read {parts['read']:.2f}, "
              f"events {parts['events']:.2f}, group WM replays {total:.2f} "
              f"({sum(n for n, _ in replays.values())} grid points); the rest (player replays, fits, "
              f"differences, JSON; by difference with the command's, so noisy under load) {rest:.2f}")
        print("each model's grid replayed alone (a combination then reuses none of its rules' grid points):")
        for name, (points, seconds) in replays.items():
            print(f"  {name:22} {points:4} grid points {seconds:6.2f} s ({1000 * seconds / points:5.1f} ms a point)")
        if args.more_grids:
            points, seconds = replays["activation"]
            extra = args.more_grids * seconds
            report["more_grids"] = {"grids": args.more_grids, "points": args.more_grids * points, "cpu_s": extra}
            print(f"with {args.more_grids} more grid(s) of activation's size ({args.more_grids * points} points): "
                  f"+{extra:.1f} s -> CPU {cpu + extra:.1f} s")
            cpu += extra
    met = "met" if cpu <= TARGET_S else "MISSED"
    print(f"target: CPU <= {TARGET_S:g} s: {cpu:.1f} s ({met})")
    report["cpu_s"] = cpu
    if args.profile:
        profile(command)
    if args.json:
        args.json.write_text(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
