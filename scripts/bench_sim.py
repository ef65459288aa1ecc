#!/usr/bin/env python3
"""Benchmark of ``fsreg-sim WORLD --json``, as users run it, against a naive eager reference (issue 17).

Each world is played by two commands, each a fresh process started the way a user
starts it, timed end to end (wall time, and peak RSS from the kernel's accounting of
that process):

* ``fsreg-sim WORLD --json`` (the installed console script, default settings): load,
  the game, the same game under policy ``none`` for the alignment baseline, the
  alignment, the JSON text;
* ``python test/support/naive_sim.py WORLD --json``: the naive reference computing the same
  (plain libyaml load, list queues, eager decay, RR and SD-PIA written out as loops
  over entities, alignment written out from its definitions; only the lexicon is
  borrowed, to say the descriptions).

Their outputs must be byte-identical (exit status 1 otherwise, with the first
differences).  The ratio naive / fsreg of wall times is the figure (target: at least
x5 on both worlds); the ratio of CPU times (user + system) is printed beside it, as it
suffers less from other load on the machine.  The split -- start-up, loading, the game, the ``none`` game with the
alignment, the JSON text -- is measured by running the same steps in-process in
another fresh process per side (``fsreg_ros.tools.sim``'s own functions for fsreg).

Worlds: the presets of ``scripts/make_world.py`` (default ``sparse,dense``: 10,000
entities with 200 properties, or with 6 properties each holding for about half the
entities), generated into a temporary directory, or files given with ``--world``.
``--profile`` also runs ``fsreg-sim WORLD --json`` under cProfile (the command's own
``main``) and prints the top functions.  No timing is asserted anywhere.

Usage: ``scripts/bench_sim.py [--worlds sparse,dense] [--world FILE ...] [--entities N]
[--human H] [--robot R] [--seed S] [--repeat N] [--no-split] [--profile] [--json FILE]``
(re-runs itself with the repository's ``.venv`` Python when started otherwise).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Optional

from venv_python import prepare  # noqa: E402

REPO = prepare("bench_sim.py", support=True)  # .venv, import path

from make_world import PRESETS, describe, preset_shape  # noqa: E402

from fsreg_ros.tools.worlds import dump_world, random_world  # noqa: E402

TARGET_RATIO = 5.0  # naive / fsreg, end to end
NAIVE = REPO / "test" / "support" / "naive_sim.py"
SIDES = ("fsreg", "naive")
#: The in-process split: phase key, label.
PHASES = (
    ("start_s", "start-up (imports)"),
    ("load_s", "load (YAML, checks, LTM)"),
    ("play_s", "the game"),
    ("baseline_s", "none game + alignment"),
    ("output_s", "JSON text"),
)
PROFILE_TOP = 30
MAX_DIFFERENCES = 20


# ------------------------------------------------------------ end to end
def command(which: str, world: str) -> list[str]:
    """Return the command line of one side, as a user would type it."""
    if which == "fsreg":
        return [str(Path(sys.executable).parent / "fsreg-sim"), world, "--json"]
    return [sys.executable, str(NAIVE), world, "--json"]


#: Starts one measured command and reports its own wall time and resources (run as ``python -I -S -c``).
LAUNCHER = """
import json, os, sys, time
report, argv = sys.argv[1], sys.argv[2:]
start = time.perf_counter()
pid = os.posix_spawn(argv[0], argv, os.environ)
_, status, usage = os.wait4(pid, 0)
wall = time.perf_counter() - start
with open(report, "w") as out:
    json.dump({"wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime, "peak_rss_mb": usage.ru_maxrss / 1024,
               "code": os.waitstatus_to_exitcode(status)}, out)
"""


def run_timed(argv: list[str], out: Path) -> dict:
    """Run ``argv`` with stdout to ``out``; return its wall time, CPU time and peak RSS (that process alone).

    The command is started by a tiny launcher process (no site packages): a
    process's peak RSS starts from that of the process it was forked from (Linux
    keeps the high-water mark across exec), so started from this script, which holds
    a generated world, every command would report at least this script's size.
    ``os.wait4`` gives the command's own usage.
    """
    report = out.with_suffix(".usage.json")
    with open(out, "wb") as stdout, tempfile.TemporaryFile() as stderr:
        proc = subprocess.run([sys.executable, "-I", "-S", "-c", LAUNCHER, str(report), *argv],
                              stdout=stdout, stderr=stderr, check=False)
        stderr.seek(0)
        errors = stderr.read().decode("utf-8", "replace").strip()
    figures = json.loads(report.read_text(encoding="utf-8")) if report.exists() else {"code": proc.returncode}
    if proc.returncode != 0 or figures["code"] != 0:
        raise SystemExit(f"bench_sim: {' '.join(argv)} failed ({figures['code']}): {errors.splitlines()[-1:]}")
    return figures


# ------------------------------------------------------------ split (child processes)
def split_fsreg(world: str) -> tuple[dict, str]:
    """Time ``fsreg-sim WORLD --json``'s steps in-process with the CLI's own functions; return (phases, text)."""
    start = time.perf_counter()
    from fsreg_ros.tools import sim as cli
    from fsreg_ros.core.simulation.simulator import dumps

    marks = [time.perf_counter()]
    args = cli.build_parser("fsreg-sim", "").parse_args([world, "--json"])
    cli.loaded(args)
    marks.append(time.perf_counter())
    runs = cli.play_all(args, cli.simulate_args, [None])
    marks.append(time.perf_counter())
    (result,) = cli.with_alignment(args, runs).values()
    marks.append(time.perf_counter())
    text = dumps(result)
    marks.append(time.perf_counter())
    return {**_phases(start, marks), "node_tree_s": node_tree_floor(world)}, text


def node_tree_floor(world: str) -> float:
    """Return the time libyaml's composer alone takes to build the file's node tree (the loading floor).

    Measured after the run, with the garbage collector paused as fsreg's loader
    pauses it: no loader reading the file through PyYAML can be faster than this,
    whatever it does after (the naive reference uses the same parser).
    """
    from fsreg_ros.core.io.yaml_source import FastLoader, collector_paused, read_text

    text = read_text(world)
    start = time.perf_counter()
    with collector_paused():
        loader = FastLoader(text)
        loader.get_single_node()
        loader.dispose()
        took = time.perf_counter() - start
        del loader
    return took


def split_naive(world: str) -> tuple[dict, str]:
    """Time the naive reference's steps in-process; return (phases, text)."""
    start = time.perf_counter()
    import naive_sim
    from fsreg_ros.core.lexicon import Lexicon  # it says the descriptions

    marks = [time.perf_counter()]
    lexicon = Lexicon.load()
    document = naive_sim.load_naive(world)
    marks.append(time.perf_counter())
    result = naive_sim.result_naive(document, Path(world).stem, lexicon=lexicon)
    marks.append(time.perf_counter())
    result = naive_sim.with_baseline(document, result, lexicon=lexicon)
    marks.append(time.perf_counter())
    text = naive_sim.dumps_naive(result)
    marks.append(time.perf_counter())
    return _phases(start, marks), text


def _phases(start: float, marks: list[float]) -> dict:
    points = [start, *marks]
    return {key: points[i + 1] - points[i] for i, (key, _) in enumerate(PHASES)}


def child_split(which: str, world: str) -> int:
    phases, text = (split_fsreg if which == "fsreg" else split_naive)(world)
    print(json.dumps({**phases, "output_bytes": len(text.encode("utf-8")), "output_hash": hash_text(text)}))
    return 0


def hash_text(text: str) -> str:
    import hashlib

    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def measure_split(which: str, world: str) -> dict:
    proc = subprocess.run([sys.executable, __file__, "--child-split", which, world],
                          capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise SystemExit(f"bench_sim: the {which} split run failed: {proc.stderr.strip().splitlines()[-1:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def child_profile(world: str) -> int:
    """Profile ``fsreg-sim WORLD --json`` (its ``main``, output discarded): top functions."""
    import cProfile
    import pstats

    from fsreg_ros.tools.sim import sim_main

    profiler = cProfile.Profile()
    stdout = sys.stdout
    start = time.perf_counter()
    with open(os.devnull, "w", encoding="utf-8") as sys.stdout:
        code = profiler.runcall(sim_main, [world, "--json"])
    sys.stdout = stdout
    took = time.perf_counter() - start
    stats = pstats.Stats(profiler, stream=sys.stdout)
    print(f"== profile of fsreg-sim {world} --json: {took:.2f} s under cProfile (exit {code}); "
          f"top {PROFILE_TOP} by cumulative time")
    stats.sort_stats("cumulative").print_stats(PROFILE_TOP)
    print(f"== the same, top {PROFILE_TOP} by own time")
    stats.sort_stats("tottime").print_stats(PROFILE_TOP)
    return 0


# ------------------------------------------------------------------- parent
def differences(fsreg_text: str, naive_text: str) -> list[str]:
    """Where the two printed results disagree, one line each (empty when byte-identical)."""
    if fsreg_text == naive_text:
        return []
    try:
        ours, ref = json.loads(fsreg_text), json.loads(naive_text)
    except ValueError as err:
        return [f"an output is not JSON: {err}"]
    out = [f"{key}: fsreg {ours.get(key)!r} != naive {ref.get(key)!r}"
           for key in sorted(set(ours) | set(ref)) if key != "turns" and ours.get(key) != ref.get(key)]
    mine, theirs = ours.get("turns", []), ref.get("turns", [])
    if len(mine) != len(theirs):
        out.append(f"{len(mine)} turns from fsreg, {len(theirs)} from the naive reference")
    for i, (a, b) in enumerate(zip(mine, theirs)):
        for key in sorted(set(a) | set(b)):
            if a.get(key) != b.get(key):
                out.append(f"turn {i} ({b.get('speaker')}): {key}: fsreg {a.get(key)!r} != naive {b.get(key)!r}")
    return out or ["the texts differ but parse to equal objects (formatting)"]


def bench_world(label: str, world: str, note: str, repeat: int, split: bool, workdir: str) -> dict:
    """Measure one world: end to end and (unless ``split`` is False) the in-process split."""
    report: dict = {"world": label, "file": world, "note": note, "end_to_end": {}, "split": {}, "differences": []}
    texts: dict[str, str] = {}
    for _ in range(repeat):  # alternate, so that other load on the machine hits both alike
        for which in SIDES:
            out = Path(workdir) / f"{label}-{which}.json"
            figures = run_timed(command(which, world), out)
            text = out.read_text(encoding="utf-8")
            if which in texts and text != texts[which]:
                report["differences"].append(f"{which}: the output changed between runs")
            texts.setdefault(which, text)
            kept = report["end_to_end"].setdefault(which, {**figures, "runs": []})
            kept["runs"].append(figures)
            kept["wall_s"] = min(kept["wall_s"], figures["wall_s"])  # fastest: least disturbed
            kept["cpu_s"] = min(kept["cpu_s"], figures["cpu_s"])
            kept["peak_rss_mb"] = max(kept["peak_rss_mb"], figures["peak_rss_mb"])  # highest: the bound
        if split:
            for which in SIDES:
                figures = measure_split(which, world)
                if figures["output_hash"] != hash_text(texts[which]):
                    report["differences"].append(f"{which}: the in-process split printed other bytes than the command")
                kept = report["split"].setdefault(which, figures)
                for key in [key for key, _ in PHASES] + ["node_tree_s"]:  # fastest of each (least disturbed)
                    if key in figures:
                        kept[key] = min(kept[key], figures[key])
    report["differences"] += differences(texts["fsreg"], texts["naive"])
    report["output_bytes"] = len(texts["fsreg"].encode("utf-8"))
    report["turns"] = len(json.loads(texts["naive"]).get("turns", []))
    e2e = report["end_to_end"]
    report["ratio_total"] = e2e["naive"]["wall_s"] / e2e["fsreg"]["wall_s"]
    report["ratio_cpu"] = e2e["naive"]["cpu_s"] / e2e["fsreg"]["cpu_s"]
    report["ratio_rss"] = e2e["naive"]["peak_rss_mb"] / e2e["fsreg"]["peak_rss_mb"]
    return report


def render(report: dict, repeat: int) -> str:
    e2e, split = report["end_to_end"], report["split"]
    f, n = e2e["fsreg"], e2e["naive"]
    lines = [
        f"world {report['world']}: {report['note']}",
        f"end to end, as users run it (fastest of {repeat} alternating run(s), each a fresh process):",
        f"  {'command':<38} {'wall s':>8} {'CPU s':>8} {'peak RSS MB':>12}",
        *(f"  {label:<38} {side['wall_s']:>8.3f} {side['cpu_s']:>8.3f} {side['peak_rss_mb']:>12.1f}"
          for label, side in (("fsreg-sim WORLD --json", f), ("python test/support/naive_sim.py WORLD --json", n))),
        f"  {'naive / fsreg':<38} {'x' + format(report['ratio_total'], '.2f'):>8} "
        f"{'x' + format(report['ratio_cpu'], '.2f'):>8} {'x' + format(report['ratio_rss'], '.2f'):>12}",
    ]
    same = not report["differences"]
    lines.append(f"  output: {'byte-identical' if same else 'DIFFERENT'} ({report['output_bytes']:,} bytes, "
                 f"{report['turns']} turns, alignment block included)")
    lines.extend(f"    {d}" for d in report["differences"][:MAX_DIFFERENCES])
    if split:
        lines.append(f"split (the same steps in-process, a fresh process per side; fastest of {repeat}):")
        lines.append(f"  {'phase':<28} {'fsreg':>9} {'naive':>9} {'naive/fsreg':>12} {'share of fsreg':>15}")
        total = {side: sum(split[side][key] for key, _ in PHASES) for side in SIDES}
        for key, label in PHASES:
            a, b = split["fsreg"][key], split["naive"][key]
            lines.append(f"  {label:<28} {a:>9.3f} {b:>9.3f} {_ratio(b, a):>12} {a / total['fsreg']:>15.0%}")
        lines.append(f"  {'sum':<28} {total['fsreg']:>9.3f} {total['naive']:>9.3f} "
                     f"{_ratio(total['naive'], total['fsreg']):>12}")
        floor = split["fsreg"]["node_tree_s"]
        lines.append(f"  loading floor: libyaml's composer alone builds this file's node tree in {floor:.3f} s "
                     f"({floor / split['fsreg']['load_s']:.0%} of fsreg's loading)")
    ratio = report["ratio_total"]
    verdict = "met" if ratio >= TARGET_RATIO else f"MISSED by x{TARGET_RATIO / ratio:.2f}"
    lines.append(f"target: fsreg-sim >= x{TARGET_RATIO:.0f} the naive reference end to end, same output: "
                 f"x{report['ratio_total']:.2f} -> {verdict}{'' if same else ', output DIFFERENT'}")
    return "\n".join(lines) + "\n"


def _ratio(a: float, b: float) -> str:
    return f"x{a / b:.2f}" if b > 0 else "-"


def main(argv: Optional[list[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--worlds", default="sparse,dense",
                        help=f"presets of scripts/make_world.py to play, comma-separated (known: {', '.join(PRESETS)})")
    parser.add_argument("--world", metavar="FILE", action="append", help="play this scenario file (repeatable) "
                        "instead of the presets")
    parser.add_argument("--entities", type=int, help="presets: entities (default 10,000)")
    parser.add_argument("--human", type=int, help="presets: human turns (default 100)")
    parser.add_argument("--robot", type=int, help="presets: robot turns (default 100)")
    parser.add_argument("--seed", type=int, help="presets: random seed (default 0)")
    parser.add_argument("--repeat", type=int, default=1,
                        help="run each side N times, alternating, and keep the fastest (default 1)")
    parser.add_argument("--no-split", action="store_true", help="skip the in-process split")
    parser.add_argument("--profile", action="store_true", help="also profile fsreg-sim on each world (cProfile)")
    parser.add_argument("--json", metavar="FILE", help="also write the figures to FILE as JSON")
    parser.add_argument("--child-split", nargs=2, metavar=("WHICH", "WORLD"), help=argparse.SUPPRESS)
    parser.add_argument("--child-profile", metavar="WORLD", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child_split:
        return child_split(*args.child_split)
    if args.child_profile:
        return child_profile(args.child_profile)
    if args.repeat < 1:
        parser.error(f"--repeat must be >= 1, got {args.repeat}")

    with tempfile.TemporaryDirectory(prefix="fsreg-bench-sim-") as workdir:
        worlds: list[tuple[str, str, str]] = []
        for path in args.world or ():
            if not os.path.isfile(path):
                parser.error(f"--world {path}: no such file")
            worlds.append((Path(path).stem, path, "given file"))
        if not args.world:
            changes = {field: value for field, value in (("entities", args.entities), ("human_turns", args.human),
                                                         ("robot_turns", args.robot), ("seed", args.seed))
                       if value is not None}
            for name in [w.strip() for w in args.worlds.split(",") if w.strip()]:
                try:
                    shape = preset_shape(name, **changes)
                except ValueError as err:
                    parser.error(str(err))
                text = dump_world(random_world(shape))
                path = os.path.join(workdir, f"{name}.yaml")
                Path(path).write_text(text, encoding="utf-8")
                option = " ".join([f"--preset {name}"] + [f"--{k.split('_')[0]} {v}" for k, v in changes.items()])
                worlds.append((name, path, f"{describe(shape)}; {len(text) / 1e6:.1f} MB of YAML "
                                           f"(scripts/make_world.py {option})"))
        reports = []
        for label, path, note in worlds:
            report = bench_world(label, path, note, args.repeat, not args.no_split, workdir)
            reports.append(report)
            sys.stdout.write(render(report, args.repeat) + "\n")
            sys.stdout.flush()
            if args.profile:
                subprocess.run([sys.executable, __file__, "--child-profile", path], check=False)
                sys.stdout.write("\n")
                sys.stdout.flush()
        if args.json:
            data = {"repeat": args.repeat, "target_ratio": TARGET_RATIO, "worlds": reports}
            Path(args.json).write_text(json.dumps(data, indent=2, sort_keys=True) + "\n", encoding="utf-8")
    return 0 if all(not r["differences"] for r in reports) else 1


if __name__ == "__main__":
    sys.exit(main())
