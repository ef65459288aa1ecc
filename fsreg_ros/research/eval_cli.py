"""The ``fsreg-eval`` command: TUNA (``tuna``), and people's repeated reference (``reference-games``, ``tangrams``).

``fsreg-eval reference-games FILE`` evaluates any corpus in the reference-game format
(:mod:`.reference_games`); ``fsreg-eval tangrams DIR`` reads Hawkins, Frank & Goodman's tangram
file through its adapter (:mod:`.tangrams`) and runs the same evaluation (:mod:`.reuse_eval`).
Bad input is reported as one line on stderr with exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path
from typing import Optional, Sequence

from .cli_common import UsageError, number_list, run_command
from .tuna import ALGORITHMS, DOMAINS, evaluate, load_trials


def parse_orders(entries: Sequence[str]) -> dict[str, list[str]]:
    """``["furniture=type,colour"]`` -> ``{"furniture": ["type", "colour"]}``."""
    orders: dict[str, list[str]] = {}
    for entry in entries:
        domain, sep, rest = entry.partition("=")
        attributes = [a.strip() for a in rest.split(",") if a.strip()]
        if not sep or domain not in DOMAINS or not attributes:
            raise UsageError(
                f"--order '{entry}': expected DOMAIN=ATTR,ATTR,... with DOMAIN one of {', '.join(DOMAINS)}"
            )
        if len(set(attributes)) != len(attributes):
            raise UsageError(f"--order '{entry}' names an attribute twice")
        orders[domain] = attributes
    return orders


def eval_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fsreg-eval",
        description="Score REG algorithms (tuna) and forgetting rules (reference-games, tangrams) against human "
                    "referring expressions."
    )
    sub = parser.add_subparsers(dest="corpus", required=True)
    tuna = sub.add_parser("tuna", help="the TUNA corpus (singular trials)")
    tuna.add_argument("path", type=Path, help="directory holding the TUNA trial XML files")
    tuna.add_argument(
        "--order", action="append", default=[], metavar="DOMAIN=ATTR,...",
        help="preference order for a domain (else learned by cross-validation)",
    )
    tuna.add_argument("--algorithms", default=",".join(ALGORITHMS), help="comma-separated (default: all three)")
    tuna.add_argument("--folds", type=int, default=10, help="k for cross-validated order learning (default 10)")
    tuna.add_argument("--per-trial", type=Path, metavar="FILE.csv", help="write one row per trial and algorithm")
    tuna.add_argument("--json", action="store_true", help="print the results as JSON")
    games = sub.add_parser(
        "reference-games",
        help="any repeated-reference corpus in the reference-game format (docs/reference-games.md): forgetting "
             "rules against people's reuse")
    games.add_argument("path", type=Path, help="the corpus: CSV with a header, or JSON Lines (.jsonl)")
    tangrams = sub.add_parser(
        "tangrams",
        help="the tangram games of Hawkins, Frank & Goodman (2020), read as reference games")
    tangrams.add_argument("path", type=Path, help="directory holding tangramsSequential.csv (or the file)")
    tangrams.add_argument("--export-rows", type=Path, metavar="FILE",
                          help="write the corpus as a reference-game file (CSV, or JSON Lines for .jsonl) and stop")
    for command in (games, tangrams):
        add_reuse_arguments(command)
    return parser


def eval_tuna(args: argparse.Namespace) -> int:
    algorithms = [a.strip() for a in args.algorithms.split(",") if a.strip()]
    unknown = [a for a in algorithms if a not in ALGORITHMS]
    if unknown or not algorithms:
        given = ", ".join(unknown) or "(none given)"
        raise UsageError(f"--algorithms: unknown {given} (known: {', '.join(ALGORITHMS)})")
    if args.folds < 2:
        raise UsageError(f"--folds must be at least 2, got {args.folds}")
    orders = parse_orders(args.order)
    trials = load_trials(args.path)
    for domain, order in orders.items():
        known = {a for t in trials if t.domain == domain for facts in t.entities.values() for a in facts}
        unknown = [a for a in order if a not in known]
        if unknown:
            raise UsageError(f"--order {domain}: no {domain} trial has attribute {', '.join(unknown)}")
    results = evaluate(trials, orders, algorithms, args.folds)
    if args.per_trial:
        write_per_trial(args.per_trial, results)
    rows = [r.to_json() for r in results]
    if args.json:
        print(json.dumps({"results": rows}, indent=2))
        return 0
    header = ("domain", "cond", "algorithm", "n", "dice", "masi", "acc", "min", "uniq")
    print("{:10} {:5} {:13} {:>4} {:>6} {:>6} {:>6} {:>6} {:>6}  order".format(*header))
    for r in rows:
        print(
            f"{r['domain']:10} {r['condition']:5} {r['algorithm']:13} {r['n']:>4} {r['dice']:6.3f} {r['masi']:6.3f} "
            f"{r['accuracy']:6.3f} {r['minimality']:6.3f} {r['uniqueness']:6.3f}  {' > '.join(r['order'])}"
            + ("  (learned, held-out scores)" if "learned" in r else "")
        )
    return 0


def write_per_trial(path: Path, results: list) -> None:
    with path.open("w", newline="", encoding="utf-8") as out:
        writer = csv.writer(out)
        writer.writerow(["trial", "domain", "condition", "algorithm", "order", "description", "gold", "dice", "masi",
                         "minimal", "unique"])
        for result in results:
            for s in result.scores:
                writer.writerow([
                    s.trial, s.domain, s.condition, s.algorithm, " ".join(s.order), " ".join(s.description),
                    " ".join(s.gold), f"{s.dice:.6f}", f"{s.masi:.6f}", int(s.minimal), int(s.unique),
                ])


def tangram_grids(entries: Sequence[str]) -> dict:
    """``["capacity=1,2,3"]`` -> ``{"capacity": (1, 2, 3)}``, each value checked against the settings table."""
    from ..core.forgetting import settings as table
    from .reuse_models import wm_models

    fitted = {p for model in wm_models() for p in model.parameters}
    grids: dict = {}
    for entry in entries:
        name, sep, text = entry.partition("=")
        name = name.strip()
        if not sep or name not in fitted:
            known = ", ".join(sorted(fitted))
            raise UsageError(f"--grid '{entry}': expected PARAM=V1,V2,... with PARAM one of {known}")
        row = table.setting(name)
        grids[name] = tuple(sorted(number_list(f"--grid {name}", text, row.kind, row.low, row.high)))
    return grids


def add_reuse_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of a reference-game evaluation (``reference-games`` and ``tangrams``)."""
    parser.add_argument("--tokens", default="content", metavar="NAME",
                        help="tokenisation: content (stop list), stems (stop list + Snowball stems) or all "
                             "(default content)")
    parser.add_argument("--folds", type=int, default=10, help="k of the cross-validation by game (default 10)")
    parser.add_argument("--grid", action="append", default=[], metavar="PARAM=V1,V2,...",
                        help="replace a parameter's grid (e.g. decay_period=5,10,20)")
    parser.add_argument("--resamples", type=int, default=10_000,
                        help="bootstrap resamples for the intervals (default 10000)")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes for the replays (results do not "
                                                            "depend on it)")
    parser.add_argument("--plots", type=Path, metavar="DIR", help="write the figures (PNG and PDF) into DIR")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")


def eval_reuse(args: argparse.Namespace) -> int:
    """Run ``fsreg-eval reference-games`` or ``fsreg-eval tangrams`` (the corpus read through its adapter)."""
    from .reference_games import TOKENISATIONS, load_games
    from .reuse_eval import evaluate_games, report

    if args.tokens not in TOKENISATIONS:
        raise UsageError(f"--tokens: unknown tokenisation '{args.tokens}' (known: {', '.join(TOKENISATIONS)})")
    if not 2 <= args.folds <= 1000:
        raise UsageError(f"--folds must be in [2, 1000], got {args.folds}")
    if not 100 <= args.resamples <= 1_000_000:
        raise UsageError(f"--resamples must be in [100, 1000000], got {args.resamples}")
    if not 1 <= args.jobs <= 64:
        raise UsageError(f"--jobs must be in [1, 64], got {args.jobs}")
    if args.plots is not None and args.plots.exists() and not args.plots.is_dir():
        raise UsageError(f"--plots {args.plots}: not a directory")
    grids = tangram_grids(args.grid)
    if args.corpus == "tangrams":
        from . import tangrams

        if args.export_rows is not None:
            from .reference_games import write_rows

            rows = tangrams.tangram_rows(args.path)
            try:
                write_rows(args.export_rows, rows)
            except OSError as err:
                raise UsageError(f"--export-rows {args.export_rows}: cannot write ({err.strerror or err})") from None
            print(f"{len(rows)} messages of {len({r.game for r in rows})} games written to {args.export_rows}")
            return 0
        result = tangrams.evaluate(args.path, args.tokens, args.folds, grids, args.jobs, args.resamples)
    else:
        games = load_games(args.path, args.tokens)
        result = evaluate_games(games, args.tokens, args.folds, grids, args.jobs, args.resamples,
                                f"reference games ({args.path.name})")
    written = []
    if args.plots is not None:
        from .tangrams_plot import write_figures

        written = write_figures(result, args.plots)
    if args.json:
        print(json.dumps(result.to_json(), indent=2))
        return 0
    for line in report(result):
        print(line)
    if written:
        print(f"figures written to {args.plots}: {', '.join(written)}")
    return 0


def eval_command(args: argparse.Namespace) -> int:
    return eval_tuna(args) if args.corpus == "tuna" else eval_reuse(args)


def eval_main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``fsreg-eval``."""
    return run_command(eval_command, eval_parser(), argv)
