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
from .games import BOARD_SIZE, MAX_BOARD_SIZE, WORLDS
from .tuna import ALGORITHMS, DOMAINS, TunaError, evaluate, load_trials


class UsageError(ValueError):
    """A command-line value is unusable; the message names the option."""


def _run(
    main: Callable[[argparse.Namespace], int], parser: argparse.ArgumentParser, argv: Optional[Sequence[str]]
) -> int:
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
            raise UsageError(
                f"--order '{entry}': expected DOMAIN=ATTR,ATTR,... with DOMAIN one of {', '.join(DOMAINS)}"
            )
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


def eval_main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``fsreg-eval``."""
    return _run(eval_tuna, eval_parser(), argv)


# ----------------------------------------------------------------- fsreg-sweep
def number_list(option: str, text: str, kind: type, low: float, high: float) -> tuple:
    """Parse a comma-separated list of numbers in [low, high] for ``option``."""
    values = []
    for part in text.split(","):
        part = part.strip()
        try:
            value = kind(part)
        except ValueError:
            raise UsageError(f"{option}: '{part}' is not a{'n integer' if kind is int else ' number'}") from None
        if not low <= value <= high or value != value:
            raise UsageError(f"{option}: {part} is out of range [{low}, {high}]")
        values.append(value)
    if not values:
        raise UsageError(f"{option}: give at least one value")
    return tuple(dict.fromkeys(values))


def memory_settings(entries: Sequence[str], option: str = "--memory") -> dict:
    """``["global_capacity=4"]`` -> ``{"global_capacity": 4}`` (numbers parsed, else text)."""
    out: dict = {}
    for entry in entries:
        key, sep, value = entry.partition("=")
        if not sep or not key.strip():
            raise UsageError(f"{option} '{entry}': expected KEY=VALUE")
        try:
            out[key.strip()] = json.loads(value)
        except json.JSONDecodeError:
            out[key.strip()] = value
    return out


def sweep_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fsreg-sweep",
        description="Play generated Guess-Who games under forgetting settings; each policy runs over the parameters "
                    "it reads.",
    )
    parser.add_argument("--policies", default="decay,displacement,none", help="comma-separated policy strings")
    parser.add_argument("--decay-periods", default="5,10,20", help="comma-separated seconds (delta), for decay")
    parser.add_argument("--capacities", default="1,2,3",
                        help="comma-separated integers (alpha), for the displacement rules")
    parser.add_argument("--global-capacities", default="4,8,16", help="comma-separated integers, for global-capacity")
    parser.add_argument("--shared-capacities", default="4,8,16",
                        help="comma-separated integers (one pool for all domains), for shared-capacity")
    parser.add_argument("--activation-thresholds", default="-1.5,-1.15,-0.8",
                        help="comma-separated thresholds (tau), for activation (d: --memory activation_decay=D, "
                             "default 0.5; with it, one encoding stays exp(-tau/d) s: 20, 10, 5 by default)")
    parser.add_argument("--seeds", type=int, default=10, help="number of games (seeds --seed-base ... +N-1)")
    parser.add_argument("--seed-base", type=int, default=0, help="first seed (default 0)")
    parser.add_argument("--turns", type=int, default=100, help="dialogue turns per game, human and robot alternating")
    parser.add_argument("--board-size", type=int, default=BOARD_SIZE,
                        help=f"entities per domain (default {BOARD_SIZE}, at most {MAX_BOARD_SIZE})")
    parser.add_argument("--world", choices=list(WORLDS), default="faces",
                        help="faces (the paper's board) or faces+objects (two domains)")
    parser.add_argument("--changes", type=float, default=0.0, metavar="N",
                        help="fact changes per 100 turns (glasses taken off, clothes changed, objects moved); "
                             "default 0: static games")
    parser.add_argument("--retraction", default="on",
                        help="with --changes: on (WM told of LTM changes), off (not told), or on,off")
    parser.add_argument("--wm-belief", action="store_true",
                        help="REG takes the target's WM as true without checking LTM (see docs/research.md)")
    parser.add_argument("--memory", action="append", default=[], metavar="KEY=VALUE",
                        help="extra memory setting for every non-none run (fixes that parameter)")
    parser.add_argument("--human-memory", action="append", default=[], metavar="KEY=VALUE",
                        help="give the human a WM of its own (e.g. policy=decay, decay_period=10)")
    parser.add_argument("--out", type=Path, required=True, help="output directory")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (results do not depend on it)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    return parser


def retraction_list(text: str) -> tuple:
    """Parse ``on``, ``off`` or ``on,off`` into booleans (WM told of LTM changes)."""
    values = [v.strip() for v in text.split(",") if v.strip()]
    if not values or any(v not in ("on", "off") for v in values):
        raise UsageError(f"--retraction: expected on, off or on,off, got '{text}'")
    return tuple(dict.fromkeys(v == "on" for v in values))


def sweep_command(args: argparse.Namespace, argv: Optional[Sequence[str]] = None) -> int:
    from .sweep import SweepConfig, recommend, run

    policies = tuple(dict.fromkeys(p.strip() for p in args.policies.split(",") if p.strip()))
    if not policies:
        raise UsageError("--policies: give at least one policy")
    if not 1 <= args.seeds <= 100_000:
        raise UsageError(f"--seeds must be in [1, 100000], got {args.seeds}")
    if not 0 <= args.seed_base <= 2**31:
        raise UsageError(f"--seed-base must be in [0, 2^31], got {args.seed_base}")
    if not 2 <= args.turns <= 10_000:
        raise UsageError(f"--turns must be in [2, 10000], got {args.turns}")
    if not 2 <= args.board_size <= MAX_BOARD_SIZE:
        raise UsageError(f"--board-size must be in [2, {MAX_BOARD_SIZE}], got {args.board_size}")
    if not 0 <= args.changes <= 100 or args.changes != args.changes:
        raise UsageError(f"--changes must be in [0, 100] (per 100 turns), got {args.changes}")
    if not 1 <= args.jobs <= 256:
        raise UsageError(f"--jobs must be in [1, 256], got {args.jobs}")
    config = SweepConfig(
        policies=policies,
        decay_periods=number_list("--decay-periods", args.decay_periods, float, 1e-2, 1e6),
        capacities=number_list("--capacities", args.capacities, int, 1, 10_000),
        global_capacities=number_list("--global-capacities", args.global_capacities, int, 1, 1_000_000),
        shared_capacities=number_list("--shared-capacities", args.shared_capacities, int, 1, 1_000_000),
        activation_thresholds=number_list("--activation-thresholds", args.activation_thresholds, float, -20.0, 20.0),
        seeds=tuple(range(args.seed_base, args.seed_base + args.seeds)),
        turns=args.turns,
        memory=memory_settings(args.memory),
        human_memory=memory_settings(args.human_memory, "--human-memory") if args.human_memory else None,
        board_size=args.board_size,
        world=args.world,
        changes=args.changes,
        retraction=retraction_list(args.retraction),
        wm_belief=args.wm_belief,
    )
    rows, summary = run(config, args.out, args.jobs, progress=not args.no_progress, plots=not args.no_plots,
                        argv=argv)
    settings_run = len(summary)
    print(f"fsreg-sweep: {len(rows)} distinct runs ({settings_run} settings x {len(config.seeds)} games) "
          f"written to {args.out / 'runs.csv'}")
    for line in headline(summary, dynamic=config.changes > 0):
        print(line)
    if config.changes > 0:
        for line in recommendation_lines(recommend(summary)):
            print(line)
    return 0


def headline(summary: list, dynamic: bool = False) -> list[str]:
    """Return one line per setting: entrainment, its gain over none with the 95 % interval, and what moves with it."""
    from .stats import METHOD

    labels = [e["setting"].label() for e in summary]
    width = max([len(label) for label in labels] + [7])
    head = (f"  {'setting':{width}}  {'entrainment':>11}  {'gain over none [95% CI]':>25}  {'len.-matched':>12}  "
            f"{'length':>6}  {'WM':>5}  {'diverg.':>7}" + ("  outdated [95% CI]" if dynamic else ""))
    lines = [head]
    for label, entry in zip(labels, summary):
        e = entry["estimates"]
        line = (f"  {label:{width}}  {e['entrainment'].mean:11.3f}  {e['entrainment_gain'].text(3, True):>25}  "
                f"{e['length_matched_gain'].mean:+12.3f}  {e['mean_length'].mean:6.2f}  "
                f"{e['mean_wm_occupancy'].mean:5.1f}  {e['divergence'].mean:7.3f}")
        if dynamic:
            line += f"  {e['outdated_rate'].text(4)}"
        lines.append(line)
    n = max((entry["n"] for entry in summary), default=0)
    rate = min((entry["estimates"]["distinguishing_rate"].mean for entry in summary), default=1.0)
    lines += [
        f"  entrainment: mean Dice with the human's last description of the referent; gain: paired by game against "
        f"none, {METHOD}, n = {n};",
        "  len.-matched: aligned properties gained per description on turns where both descriptions are as long; "
        "length: properties per description; WM: properties in WM before the robot speaks; diverg.: share of "
        "descriptions differing from none" + ("; outdated: share of properties said that no longer held." if dynamic
                                              else "."),
        "  every description was distinguishing." if rate == 1.0 else
        f"  lowest distinguishing rate of a setting: {rate:.3f}.",
    ]
    return lines


def recommendation_lines(table: list) -> list[str]:
    """Return the recommendation table as text: per WM configuration and bound, the best setting."""
    lines = ["recommendation: per WM configuration, the setting with the most entrainment whose mean outdated "
             "rate is within the bound"]
    for entry in table:
        best = entry["best"]
        if best is None:
            lines.append(f"  {entry['wm']:22}  outdated <= {entry['bound']:.0%}: no setting qualifies")
            continue
        e = best["estimates"]
        lines.append(
            f"  {entry['wm']:22}  outdated <= {entry['bound']:.0%}: {best['setting'].label():32}  entrainment "
            f"{e['entrainment'].mean:.3f} (gain {e['entrainment_gain'].text(3, True)}), outdated "
            f"{e['outdated_rate'].text(4)}  ({entry['allowed']} of {entry['considered']} settings within the bound)"
        )
    return lines


def sweep_main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``fsreg-sweep``."""
    return _run(lambda args: sweep_command(args, argv), sweep_parser(), argv)


# ------------------------------------------------------------------ fsreg-plot
def plot_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fsreg-plot", description="Draw a WM timeline from an fsreg-sim --trace file."
    )
    parser.add_argument("trace", type=Path, help="JSON lines of WM events (fsreg-sim --trace)")
    parser.add_argument("-o", "--output", type=Path, required=True, help="PNG file to write")
    parser.add_argument("--result", type=Path, help="fsreg-sim --json output, for the turns' times and speakers")
    parser.add_argument("--title", default="", help="plot title")
    parser.add_argument("--entities", metavar="E1,E2,...", help="draw only these entities' lanes")
    parser.add_argument("--top", type=int, metavar="N", help="draw only the N lanes longest in WM")
    return parser


def read_trace(path: Path) -> list[dict]:
    """Read a JSON-lines event trace; a bad line is named by number."""
    events = []
    with path.open(encoding="utf-8") as lines:
        for number, line in enumerate(lines, 1):
            if not line.strip():
                continue
            try:
                event = json.loads(line)
            except json.JSONDecodeError as err:
                raise UsageError(f"{path}:{number}: not JSON ({err.msg})") from None
            if not isinstance(event, dict) or event.get("op") not in ("encode", "forget"):
                raise UsageError(f"{path}:{number}: not a WM event (an object with op encode|forget)")
            if not isinstance(event.get("time", 0), (int, float)) or isinstance(event.get("time"), bool):
                raise UsageError(f"{path}:{number}: 'time' must be a number")
            events.append(event)
    return events


def plot_command(args: argparse.Namespace) -> int:
    from .plot import wm_timeline

    events = read_trace(args.trace)
    result = None
    if args.result:
        try:
            result = json.loads(args.result.read_text(encoding="utf-8"))
        except json.JSONDecodeError as err:
            raise UsageError(f"{args.result}: not JSON ({err.msg})") from None
        if not isinstance(result, dict) or not isinstance(result.get("turns"), list):
            raise UsageError(f"{args.result}: not an fsreg-sim --json result (no 'turns' list)")
    entities = [e.strip() for e in args.entities.split(",") if e.strip()] if args.entities is not None else None
    if entities is not None:
        known = {e.get("entity") for e in events}
        unknown = [e for e in entities if e not in known]
        if not entities or unknown:
            raise UsageError(f"--entities: no event names {', '.join(unknown) or '(none given)'}")
    if args.top is not None and args.top < 1:
        raise UsageError(f"--top must be at least 1, got {args.top}")
    segments = wm_timeline(events, args.output, result, args.title, entities, args.top)
    print(f"fsreg-plot: {len(segments)} WM stays from {len(events)} events drawn to {args.output}")
    return 0


def plot_main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``fsreg-plot``."""
    return _run(plot_command, plot_parser(), argv)
