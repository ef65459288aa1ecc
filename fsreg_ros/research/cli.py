"""Command-line entry points of the research workbench: fsreg-sweep and fsreg-plot here, fsreg-eval in :mod:`.eval_cli`.

Bad input is reported as one line on stderr with exit code 2, never a traceback (:mod:`.cli_common`).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Optional, Sequence

from ..core.algorithms.generation import WM_ORDERS
from ..core.memory.entity_clock import CLOCKS
from .cli_common import UsageError, _run, number_list
from .eval_cli import eval_main, eval_parser
from .execution import add_engine_arguments, engine_from_args
from .games import BOARD_SIZE, MAX_BOARD_SIZE, WORLDS
from .listener import MAX_REPAIRS, ORDERS, PARTNERS, ListenerOptions


# ----------------------------------------------------------------- fsreg-sweep
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
    parser.add_argument("--episode-windows", default="1,2,3,4",
                        help="comma-separated integers (k: the entity's last k reference episodes), for episodes")
    parser.add_argument("--activation-clocks", default="", metavar="CLOCK,...",
                        help="comma-separated clocks rule activation runs on, each a setting of its own: "
                             f"{', '.join(CLOCKS)} (default: none given, activation on its fallback, seconds, "
                             "and no activation_clock column)")
    parser.add_argument("--wm-orders", default="lru-first", metavar="ORDER,...",
                        help=f"REG's order of the target's WM properties, each non-none policy run under each: "
                             f"{', '.join(WM_ORDERS)} (default lru-first, the paper's; strength: strongest first, "
                             "by episode age, then episodes used in); a sweep of another order adds a wm_order column")
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
    listener = parser.add_argument_group(
        "listener", "who resolves the robot's descriptions (any of these adds the listener's metrics; "
                    "see docs/research.md)")
    listener.add_argument("--listener-missing", metavar="RATE",
                          help="share of facts the listener does not know, in [0, 1] (default 0)")
    listener.add_argument("--listener-noise", metavar="RATE",
                          help="share of known facts the listener misperceives, in [0, 1] (default 0)")
    listener.add_argument("--listener-order", metavar="ORDER",
                          help=f"the listener's preference order, with --partner robot: {', '.join(ORDERS)} "
                               "(default: robot)")
    listener.add_argument("--max-repairs", metavar="N",
                          help=f"repairs per robot turn before the reference counts as failed (default {MAX_REPAIRS})")
    listener.add_argument("--partner", metavar="WHO",
                          help="who plays the human's role: human (the game's Incremental-Algorithm human, default) "
                               "or robot (a second fsreg agent with its own WM; robot-robot mode)")
    listener.add_argument("--partner-memory", action="append", default=[], metavar="KEY=VALUE",
                          help="with --partner robot: its WM settings (default: the same as the robot's in each run)")
    parser.add_argument("--out", type=Path, required=True, help="output directory")
    parser.add_argument("--resume", action="store_true",
                        help="play only the games missing from --out's games.jsonl (same command, same code)")
    parser.add_argument("--shard", metavar="K/N",
                        help="play only shard K of N (every N-th seed from the K-th); combine the shards with "
                             "'fsreg-sweep merge OUT SHARD_DIR...'")
    add_engine_arguments(parser, "games")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    return parser


def merge_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fsreg-sweep merge",
        description="Combine finished sweeps of one configuration and commit (the shards of --shard K/N, or sweeps "
                    "of disjoint seeds) into OUT, with the files one sweep over all their seeds writes.",
    )
    parser.add_argument("out", type=Path, metavar="OUT", help="output directory")
    parser.add_argument("shards", type=Path, nargs="+", metavar="SHARD_DIR", help="a finished sweep's --out")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    return parser


def parse_shard(text: str) -> tuple[int, int]:
    """Parse ``--shard K/N`` (1 <= K <= N <= 100000)."""
    k, sep, n = text.partition("/")
    if not sep or not k.strip().isdigit() or not n.strip().isdigit():
        raise UsageError(f"--shard: expected K/N (shard K of N, e.g. 2/4), got '{text}'")
    index, count = int(k), int(n)
    if not 1 <= index <= count <= 100_000:
        raise UsageError(f"--shard {text}: K must be in [1, N] and N in [1, 100000]")
    return index, count


def wm_order_list(text: str) -> tuple:
    """Parse ``--wm-orders``: REG's WM orders, comma-separated, each one of :data:`WM_ORDERS`."""
    return choice_list("--wm-orders", text, WM_ORDERS, required=True)


def choice_list(option: str, text: str, choices: Sequence[str], required: bool = False) -> tuple:
    """Parse a comma-separated list of ``choices`` (repeats once; none given: ``()`` unless ``required``)."""
    values = tuple(dict.fromkeys(v.strip() for v in text.split(",") if v.strip()))
    wrong = [v for v in values if v not in choices]
    if required and not values or wrong:
        raise UsageError(f"{option}: expected one or more of {', '.join(choices)}, got '{text}'")
    return values


def retraction_list(text: str) -> tuple:
    """Parse ``on``, ``off`` or ``on,off`` into booleans (WM told of LTM changes)."""
    values = [v.strip() for v in text.split(",") if v.strip()]
    if not values or any(v not in ("on", "off") for v in values):
        raise UsageError(f"--retraction: expected on, off or on,off, got '{text}'")
    return tuple(dict.fromkeys(v == "on" for v in values))


def rate(option: str, text: str) -> float:
    """Parse a probability for ``option``: a finite number in [0, 1]."""
    try:
        value = float(text)
    except ValueError:
        raise UsageError(f"{option}: '{text}' is not a number") from None
    if not 0.0 <= value <= 1.0:  # also refuses nan
        raise UsageError(f"{option} must be in [0, 1], got {text}")
    return value


def listener_options(args: argparse.Namespace) -> Optional[ListenerOptions]:
    """Return the listener the options describe, or None when none of them is given (no listener, as before)."""
    given = [args.listener_missing, args.listener_noise, args.listener_order, args.max_repairs, args.partner]
    if all(v is None for v in given) and not args.partner_memory:
        return None
    partner = args.partner if args.partner is not None else "human"
    if partner not in PARTNERS:
        raise UsageError(f"--partner: expected {' or '.join(PARTNERS)}, got '{partner}'")
    robot = partner == "robot"
    if args.listener_order is not None:
        if args.listener_order not in ORDERS:
            raise UsageError(f"--listener-order: expected one of {', '.join(ORDERS)}, got '{args.listener_order}'")
        if not robot:
            raise UsageError("--listener-order needs --partner robot (the order decides what the listener says; "
                             "resolution checks every property in any order)")
    if args.partner_memory and not robot:
        raise UsageError("--partner-memory needs --partner robot")
    if robot and args.human_memory:
        raise UsageError("--human-memory and --partner robot both give the human's role a WM: "
                         "use --partner-memory")
    repairs = MAX_REPAIRS
    if args.max_repairs is not None:
        try:
            repairs = int(args.max_repairs)
        except ValueError:
            raise UsageError(f"--max-repairs: '{args.max_repairs}' is not an integer") from None
        if not 0 <= repairs <= 20:
            raise UsageError(f"--max-repairs must be in [0, 20], got {repairs}")
    return ListenerOptions(
        missing=rate("--listener-missing", args.listener_missing) if args.listener_missing is not None else 0.0,
        noise=rate("--listener-noise", args.listener_noise) if args.listener_noise is not None else 0.0,
        order=args.listener_order,
        max_repairs=repairs,
        partner=partner,
        partner_memory=memory_settings(args.partner_memory, "--partner-memory") if args.partner_memory else None,
    )


def sweep_config(args: argparse.Namespace):
    """Return the checked SweepConfig, engine and shard (or None) of fsreg-sweep's arguments."""
    from .sweep import Shard, SweepConfig

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
    engine = engine_from_args(args)
    seeds = tuple(range(args.seed_base, args.seed_base + args.seeds))
    shard = None
    if args.shard is not None:
        index, count = parse_shard(args.shard)
        if count > len(seeds):
            raise UsageError(f"--shard {args.shard}: {count} shards of {len(seeds)} games leave some empty "
                             f"(give at most --seeds shards)")
        shard = Shard(index, count, seeds)
        seeds = shard.mine()
    listener = listener_options(args)
    config = SweepConfig(
        policies=policies,
        decay_periods=number_list("--decay-periods", args.decay_periods, float, 1e-2, 1e6),
        capacities=number_list("--capacities", args.capacities, int, 1, 10_000),
        global_capacities=number_list("--global-capacities", args.global_capacities, int, 1, 1_000_000),
        shared_capacities=number_list("--shared-capacities", args.shared_capacities, int, 1, 1_000_000),
        activation_thresholds=number_list("--activation-thresholds", args.activation_thresholds, float, -20.0, 20.0),
        episode_windows=number_list("--episode-windows", args.episode_windows, int, 1, 1_000_000),
        activation_clocks=choice_list("--activation-clocks", args.activation_clocks, CLOCKS),
        wm_orders=wm_order_list(args.wm_orders),
        seeds=seeds,
        turns=args.turns,
        memory=memory_settings(args.memory),
        human_memory=memory_settings(args.human_memory, "--human-memory") if args.human_memory else None,
        board_size=args.board_size,
        world=args.world,
        changes=args.changes,
        retraction=retraction_list(args.retraction),
        wm_belief=args.wm_belief,
        listener=listener,
    )
    return config, engine, shard


def sweep_command(args: argparse.Namespace, argv: Optional[Sequence[str]] = None) -> int:
    from .ledger import GAMES
    from .sweep import recommend, run

    config, engine, shard = sweep_config(args)
    try:
        rows, summary, execution = run(config, args.out, progress=not args.no_progress, plots=not args.no_plots,
                                       argv=argv, engine=engine, resume=args.resume, shard=shard)
    except KeyboardInterrupt:
        kept = _games_kept(args.out / GAMES)
        print(f"fsreg-sweep: interrupted; {kept} of {len(config.seeds)} games are kept in {args.out / GAMES}: "
              "the same command with --resume plays the rest", file=sys.stderr)
        return 130
    settings_run = len(summary)
    print(f"fsreg-sweep: {len(rows)} distinct runs ({settings_run} settings x {len(config.seeds)} games) "
          f"written to {args.out / 'runs.csv'}")
    for line in headline(summary, dynamic=config.changes > 0):
        print(line)
    if config.listener is not None:
        for line in listener_lines(summary, config.listener):
            print(line)
    if config.changes > 0:
        for line in recommendation_lines(recommend(summary)):
            print(line)
    for line in execution_lines(execution):
        print(line)
    return 0


def _games_kept(path: Path) -> int:
    try:
        with path.open("rb") as games:
            return max(sum(1 for line in games if line.endswith(b"\n")) - 1, 0)
    except OSError:
        return 0


def execution_lines(execution: dict) -> list[str]:
    """Return what the sweep says of where it ran: games resumed, the shard, the cluster and its retried tasks."""
    lines = []
    if execution.get("resumed_games"):
        lines.append(f"fsreg-sweep: resumed: {execution['resumed_games']} games were already done, "
                     f"{execution['played_games']} played now")
    if execution.get("shard"):
        shard = execution["shard"]
        lines.append(f"fsreg-sweep: shard {shard['shard']} of seeds {shard['all_seeds'][0]}-"
                     f"{shard['all_seeds'][1] - 1}; combine the shards with 'fsreg-sweep merge OUT SHARD_DIR...'")
    if execution.get("engine") in ("cluster", "scheduler"):
        retried = execution["retried"]
        lines.append(f"fsreg-sweep: ran on {execution['label']} ({execution['workers']} workers at the start); "
                     f"{retried} task{'' if retried == 1 else 's'} retried after a worker was lost")
    return lines


def merge_command(args: argparse.Namespace, argv: Optional[Sequence[str]] = None) -> int:
    from .sweep import recommend
    from .sweep_merge import merge

    rows, summary, config = merge(args.out, args.shards, plots=not args.no_plots, argv=argv)
    print(f"fsreg-sweep merge: {len(args.shards)} sweeps, {len(rows)} distinct runs ({len(summary)} settings x "
          f"{len(config.seeds)} games) written to {args.out / 'runs.csv'}")
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


def listener_lines(summary: list, listener: ListenerOptions) -> list[str]:
    """Return one line per setting: the listener's success, turns to success, length and entrainment, with intervals."""
    from .stats import METHOD

    robot = listener.partner == "robot"
    who = (f"a second fsreg agent (order {listener.order_name()}, WM "
           + (", ".join(f"{k}={v}" for k, v in listener.partner_memory.items()) if listener.partner_memory
              else "as the robot's") + ")") if robot else "the human"
    lines = [f"listener: {who}, facts missing {listener.missing:g}, misperceived {listener.noise:g}, "
             f"at most {listener.max_repairs} repairs"]
    labels = [e["setting"].label() for e in summary]
    width = max([len(label) for label in labels] + [7])
    lines.append(f"  {'setting':{width}}  {'success [95% CI]':>22}  {'1st try':>7}  {'turns to success [95% CI]':>25}  "
                 f"{'length':>6}  {'heard':>5}  {'entrainment [95% CI]':>22}" + ("  robot resolved" if robot else ""))
    for label, entry in zip(labels, summary):
        e = entry["estimates"]
        line = (f"  {label:{width}}  {e['success'].text(3):>22}  {e['first_success'].mean:7.3f}  "
                f"{e['turns_to_success'].text(3):>25}  {e['mean_length'].mean:6.2f}  {e['final_length'].mean:5.2f}  "
                f"{e['entrainment'].text(3):>22}")
        if robot:
            line += f"  {e['partner_resolved'].mean:14.3f}"
        lines.append(line)
    lines.append("  success: share of robot turns whose referent the listener identified (repairs included); 1st try: "
                 "at once; turns to success: attempts, over the turns that succeeded; length: properties per robot "
                 "description; heard: in the description the listener resolved last"
                 + ("; robot resolved: share of the partner's descriptions the robot resolved to their referent"
                    if robot else "") + f"; {METHOD}.")
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
    """Entry point of ``fsreg-sweep`` (and of ``fsreg-sweep merge``)."""
    given = list(sys.argv[1:] if argv is None else argv)
    if given[:1] == ["merge"]:
        return _run(lambda args: merge_command(args, given[1:]), merge_parser(), given[1:])
    return _run(lambda args: sweep_command(args, argv), sweep_parser(), argv)


# ------------------------------------------------------------------ fsreg-plot
def plot_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fsreg-plot", description="Draw a WM timeline from an fsreg-sim --trace file, fsreg-ctl watch --events "
        "--json output, or a recording (fsreg-ctl record, fsreg-up --record)."
    )
    parser.add_argument("trace", type=Path, help="JSON lines of WM events (fsreg-sim --trace, fsreg-ctl watch --events "
                        "--json: lines without 'op' are skipped), or a recording's folder or .mcap file")
    parser.add_argument("-o", "--output", type=Path, required=True, help="PNG file to write")
    parser.add_argument("--result", type=Path, help="fsreg-sim --json output, for the turns' times and speakers")
    parser.add_argument("--title", default="", help="plot title")
    parser.add_argument("--entities", metavar="E1,E2,...", help="draw only these entities' lanes")
    parser.add_argument("--top", type=int, metavar="N", help="draw only the N lanes longest in WM")
    return parser


#: The fields of a WM event that name what changed and why (``WMEvent``; docs/semantics.md section 2).
EVENT_NAMES = ("domain", "entity", "property", "cause")


def read_trace(path: Path) -> list[dict]:
    """Read a JSON-lines event trace; a bad line is named by number.

    Objects without ``op`` (``fsreg-ctl watch --events --json`` prints each ``wm/state`` too)
    are not events and are skipped; anything else must be an encode/forget event.
    """
    from ..core.io.input_file import MAX_CORPUS_BYTES, InputFileError, json_lines

    events = []
    try:
        for number, event in json_lines(path, MAX_CORPUS_BYTES):
            if isinstance(event, dict) and "op" not in event:
                continue  # a WM state (or another record of a watch): not an event
            if not isinstance(event, dict) or event.get("op") not in ("encode", "forget"):
                raise UsageError(f"{path}: line {number}: not a WM event (an object with op encode|forget)")
            if not isinstance(event.get("time", 0), (int, float)) or isinstance(event.get("time"), bool):
                raise UsageError(f"{path}: line {number}: 'time' must be a number")
            for name in EVENT_NAMES:
                if not isinstance(event.get(name), str):
                    raise UsageError(f"{path}: line {number}: {name!r} must be a string (a WM event names its "
                                     f"{', '.join(EVENT_NAMES)})")
            events.append(event)
    except InputFileError as err:
        raise UsageError(str(err)) from None
    return events


#: Transport fields of a recorded ``wm/events`` message (not part of the event itself).
TRANSPORT = ("seq", "incarnation", "graph")


def read_recording(path: Path) -> tuple[list[dict], dict]:
    """Return a recording's WM events and its turns (a result with ``turns``: time and speaker of each answer).

    A recording cut short is read as far as it goes, and what is lost is said on stderr.
    """
    from ..core.io.recording import open_recording

    recording = open_recording(path)
    if recording.lost:
        print(f"fsreg-plot: note: {recording.lost}", file=sys.stderr)
    events = [{k: v for k, v in m.data.items() if k not in TRANSPORT} for m in recording.on("events")
              if isinstance(m.data, dict)]
    turns, seen = [], set()
    for message in recording.messages:
        speaker = {"rr": "human", "expression": "robot"}.get(recording.role(message) or "")
        data = message.data
        if speaker is None or not isinstance(data, dict) or (speaker, data.get("id")) in seen:
            continue
        seen.add((speaker, data.get("id")))
        if isinstance(data.get("time"), (int, float)):
            turns.append({"turn": len(turns), "time": float(data["time"]), "speaker": speaker})
    return events, {"turns": turns}


def plot_command(args: argparse.Namespace) -> int:
    from .plot import wm_timeline

    result = None
    if args.trace.is_dir() or args.trace.suffix == ".mcap":
        events, result = read_recording(args.trace)
    else:
        events = read_trace(args.trace)
    if args.result:
        from ..core.io.input_file import InputFileError, read_text

        try:
            result = json.loads(read_text(args.result))
        except InputFileError as err:
            raise UsageError(str(err)) from None
        except json.JSONDecodeError as err:
            raise UsageError(f"{args.result}: not JSON ({err.msg})") from None
        except RecursionError:
            raise UsageError(f"{args.result}: not an fsreg-sim --json result (JSON nested too deeply)") from None
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


__all__ = ["UsageError", "number_list", "eval_main", "eval_parser", "sweep_main", "sweep_parser", "plot_main"]
