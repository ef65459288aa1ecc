"""Command-line entry points of the research workbench: fsreg-eval, fsreg-sweep, fsreg-plot.

Bad input is reported as one line on stderr with exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path
from typing import Callable, Optional, Sequence

from ..core.forgetting import PolicyError
from ..core.generation import GenerationError
from .tuna import ALGORITHMS, DOMAINS, TunaError, evaluate, load_trials


class UsageError(ValueError):
    """A command-line value is unusable; the message names the option."""


def _run(main: Callable[[argparse.Namespace], int], parser: argparse.ArgumentParser, argv: Optional[Sequence[str]]) -> int:
    args = parser.parse_args(argv)
    try:
        return main(args)
    except (UsageError, TunaError, GenerationError, PolicyError, OSError, ValueError) as err:
        print(f"{parser.prog}: error: {err}", file=sys.stderr)
        return 2


# ------------------------------------------------------------------ fsreg-eval
def parse_orders(entries: Sequence[str]) -> dict[str, list[str]]:
    """``["furniture=type,colour"]`` -> ``{"furniture": ["type", "colour"]}``."""
    orders: dict[str, list[str]] = {}
    for entry in entries:
        domain, sep, rest = entry.partition("=")
        attributes = [a.strip() for a in rest.split(",") if a.strip()]
        if not sep or domain not in DOMAINS or not attributes:
            raise UsageError(f"--order '{entry}': expected DOMAIN=ATTR,ATTR,... with DOMAIN one of {', '.join(DOMAINS)}")
        if len(set(attributes)) != len(attributes):
            raise UsageError(f"--order '{entry}' names an attribute twice")
        orders[domain] = attributes
    return orders


def eval_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fsreg-eval", description="Score REG algorithms against human referring expressions."
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
    return parser


def eval_tuna(args: argparse.Namespace) -> int:
    algorithms = [a.strip() for a in args.algorithms.split(",") if a.strip()]
    unknown = [a for a in algorithms if a not in ALGORITHMS]
    if unknown or not algorithms:
        raise UsageError(f"--algorithms: unknown {', '.join(unknown) or '(none given)'} (known: {', '.join(ALGORITHMS)})")
    if args.folds < 2:
        raise UsageError(f"--folds must be at least 2, got {args.folds}")
    orders = parse_orders(args.order)
    results = evaluate(load_trials(args.path), orders, algorithms, args.folds)
    if args.per_trial:
        write_per_trial(args.per_trial, results)
    rows = [r.to_json() for r in results]
    if args.json:
        print(json.dumps({"results": rows}, indent=2))
        return 0
    print(f"{'domain':10} {'cond':5} {'algorithm':13} {'n':>4} {'dice':>6} {'masi':>6} {'acc':>6} {'min':>6} {'uniq':>6}  order")
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
                writer.writerow([s.trial, s.domain, s.condition, s.algorithm, " ".join(s.order), " ".join(s.description),
                                 " ".join(s.gold), f"{s.dice:.4f}", f"{s.masi:.4f}", int(s.minimal), int(s.unique)])


def eval_main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``fsreg-eval``."""
    return _run(eval_tuna, eval_parser(), argv)
