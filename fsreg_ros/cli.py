"""Command-line front ends: ``fsreg-sim`` (and the options ``fsreg-graph`` shares).

Both take a scenario file and the same options; ``--json`` prints exactly the
SPEC section 6 object, otherwise a readable table.  ``--compare-policies`` runs the
scenario once per policy and prints the robot's turns side by side, and
``--expect FILE`` checks them against expected descriptions (e.g. the paper's
Table 1 in ``config/paper_table1.yaml``).  Errors in the input are one line on
stderr and exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any, Callable, Mapping, Optional, Sequence

import yaml

from .core.consultant import KnowledgeError
from .core.forgetting import PolicyError, check_parameter, parse_rules
from .core.generation import ALGORITHMS, WM_ORDERS, GenerationError
from .core.lexicon import Lexicon, LexiconError
from .core.resolution import ResolutionError
from .core.scenario import ScenarioError, load_scenario
from .core.simulation import Options, Simulation, dumps

EXIT_OK, EXIT_MISMATCH, EXIT_BAD_INPUT = 0, 1, 2
EXIT_FAILED = 1

#: Errors that are the user's input, reported as one line with exit code 2.
INPUT_ERRORS = (ScenarioError, PolicyError, LexiconError, KnowledgeError, ResolutionError, GenerationError, OSError)


def build_parser(prog: str, description: str) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument("scenario", type=Path, help="scenario YAML file (SPEC section 5)")
    memory = parser.add_argument_group("forgetting (override every domain's memory settings)")
    memory.add_argument("--policy", help="none, or decay / displacement / global-capacity joined by +")
    memory.add_argument("--decay-period", type=float, metavar="S", help="decay period delta in seconds")
    memory.add_argument("--capacity", type=int, metavar="N", help="per-entity queue limit alpha")
    memory.add_argument("--global-capacity", type=int, metavar="N", help="per-domain total limit")
    reg = parser.add_argument_group("generation")
    reg.add_argument("--algorithm", choices=ALGORITHMS, help="default: sd-pia, or dist-pia under policy none")
    reg.add_argument("--wm-order", choices=WM_ORDERS, default="lru-first", help="order SD-PIA walks WM in")
    out = parser.add_argument_group("output")
    out.add_argument("--json", action="store_true", help="print the SPEC section 6 JSON object")
    out.add_argument("--trace", type=Path, metavar="FILE", help="write every WM encode/forget event as JSON lines")
    out.add_argument(
        "--compare-policies",
        metavar="P1,P2,...",
        help="run once per policy and print the robot's descriptions side by side",
    )
    out.add_argument("--expect", type=Path, metavar="FILE", help="expected robot descriptions per policy (YAML)")
    parser.add_argument("--lexicon", type=Path, help="lexicon YAML (default: config/lexicon.yaml)")
    return parser


def options_from_args(args: argparse.Namespace, policy: Optional[str] = None) -> Options:
    """The memory overrides and REG options given on the command line (validated)."""
    memory: dict[str, Any] = {}
    policy = policy if policy is not None else args.policy
    if policy is not None:
        parse_rules(policy)
        memory["policy"] = policy
    for name in ("decay_period", "capacity", "global_capacity"):
        value = getattr(args, name)
        if value is not None:
            check_parameter(name, value)
            memory[name] = value
    return Options(memory=memory, algorithm=args.algorithm, wm_order=args.wm_order)


def compared_policies(args: argparse.Namespace) -> list[str]:
    policies = [p.strip() for p in args.compare_policies.split(",") if p.strip()]
    if not policies:
        raise PolicyError("--compare-policies needs at least one policy")
    for policy in policies:
        parse_rules(policy)
    return policies


# ------------------------------------------------------------------ rendering
def _describe(record: Mapping[str, Any]) -> str:
    if record["speaker"] == "human":
        said = record.get("text") or ", ".join(record.get("description") or [])
        outcome = record.get("resolved") or f"{record.get('status')} {record.get('candidates')}"
        return f'"{said}" -> {outcome}'
    mark = "" if record.get("distinguishing") else "  (not distinguishing)"
    return f'"{record.get("text")}"  [{", ".join(record.get("sources") or [])}]{mark}'


def render_table(result: Mapping[str, Any]) -> str:
    """A readable table of one run."""
    memory = "; ".join(f"{d}: {json.dumps(m, sort_keys=True)}" for d, m in result["memory"].items())
    lines = [f"scenario {result['scenario']}  memory {memory}", ""]
    lines.append(f"{'turn':>4}  {'time':>7}  {'speaker':<7}  {'target':<10}  {'WM before':<34}  utterance")
    for record in result["turns"]:
        wm = ", ".join(record.get("wm_before") or []) if record["speaker"] == "robot" else ""
        lines.append(
            f"{record['turn']:>4}  {record['time']:>7.2f}  {record['speaker']:<7}  "
            f"{str(record.get('target') or ''):<10}  {wm:<34}  {_describe(record)}"
        )
    return "\n".join(lines) + "\n"


def load_expected(path: Path) -> dict[str, list[list[str]]]:
    """Expected robot descriptions per policy: ``robot_descriptions: {policy: [[p, ...], ...]}``."""
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as err:
        raise ScenarioError(str(path), "", f"not valid YAML: {err}") from err
    table = data.get("robot_descriptions") if isinstance(data, dict) else None
    if not isinstance(table, dict) or not all(
        isinstance(rows, list) and all(isinstance(r, list) for r in rows) for rows in table.values()
    ):
        raise ScenarioError(str(path), "robot_descriptions", "must map each policy to a list of property lists")
    return table


def render_comparison(
    results: Mapping[str, Mapping[str, Any]], expected: Optional[Mapping[str, list]] = None
) -> tuple[str, int, int]:
    """Robot turns side by side, one column per policy; returns (text, matched, checked)."""
    labels = list(results)
    robot_rows = {label: [t for t in results[label]["turns"] if t["speaker"] == "robot"] for label in labels}
    first = robot_rows[labels[0]]
    columns: dict[str, list[str]] = {}
    matched = checked = 0
    for label in labels:
        cells = []
        for i, record in enumerate(robot_rows[label]):
            cell = record.get("text") or ""
            if expected and label in expected and i < len(expected[label]):
                checked += 1
                ok = set(expected[label][i]) == set(record.get("description") or [])
                matched += ok
                cell = ("ok   " if ok else "DIFF ") + cell
            cells.append(cell)
        columns[label] = cells
    widths = {label: max([len(label)] + [len(c) for c in columns[label]]) for label in labels}
    lines = [f"{'turn':>4}  {'target':<8}  " + "  ".join(f"{label:<{widths[label]}}" for label in labels).rstrip()]
    for i, row in enumerate(first):
        cells = "  ".join(f"{columns[label][i]:<{widths[label]}}" for label in labels)
        lines.append(f"{row['turn']:>4}  {str(row['target']):<8}  {cells}".rstrip())
    lines.append("")
    for label in labels:
        lines.append(f"{label:<{max(map(len, labels))}}  {alignment_summary(robot_rows[label])}")
    if expected:
        lines.append("")
        lines.append(f"{matched}/{checked} robot descriptions match the expected ones")
    return "\n".join(lines) + "\n", matched, checked


def alignment_summary(robot_turns: Sequence[Mapping[str, Any]]) -> str:
    """How much of what the robot said came from working memory (alignment), and how
    long its descriptions were."""
    sources = [s for t in robot_turns for s in (t.get("sources") or [])]
    from_wm = sources.count("wm")
    mean = len(sources) / len(robot_turns) if robot_turns else 0.0
    share = f"{100 * from_wm / len(sources):.0f}%" if sources else "-"
    return f"{from_wm}/{len(sources)} properties reused from WM ({share}), {mean:.2f} properties per description"


# ---------------------------------------------------------------------- main
Runner = Callable[[argparse.Namespace, Options], tuple[dict, list[dict]]]


def run_cli(
    prog: str,
    description: str,
    runner: Runner,
    argv: Optional[Sequence[str]] = None,
    failures: tuple[type[BaseException], ...] = (),
) -> int:
    """Shared main of ``fsreg-sim`` and ``fsreg-graph``: ``runner`` plays one scenario
    with the given options and returns (result, trace).  Bad input exits 2; a run
    that fails in one of the ``failures`` ways exits 1; both print one message."""
    args = build_parser(prog, description).parse_args(argv)
    try:
        if args.compare_policies:
            expected = load_expected(args.expect) if args.expect else None
            results = {}
            for policy in compared_policies(args):
                results[policy], _ = runner(args, options_from_args(args, policy))
            if args.json:
                sys.stdout.write(dumps(results))
                return EXIT_OK
            text, matched, checked = render_comparison(results, expected)
            sys.stdout.write(text)
            return EXIT_OK if matched == checked else EXIT_MISMATCH
        result, trace = runner(args, options_from_args(args))
    except INPUT_ERRORS as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except failures as err:
        print(f"{prog}: failed: {err}", file=sys.stderr)
        return EXIT_FAILED
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    if args.trace:
        with args.trace.open("w", encoding="utf-8") as out:
            for event in trace:
                out.write(json.dumps(event, sort_keys=True) + "\n")
    sys.stdout.write(dumps(result) if args.json else render_table(result))
    return EXIT_OK


def simulate_args(args: argparse.Namespace, options: Options) -> tuple[dict, list[dict]]:
    lexicon = Lexicon.load(args.lexicon)
    scenario = load_scenario(args.scenario, lexicon)
    simulation = Simulation(scenario, options, lexicon)
    result = simulation.run()
    return result, simulation.trace()


def sim_main(argv: Optional[Sequence[str]] = None) -> int:
    """``fsreg-sim SCENARIO.yaml [options]``: play a scenario with the core alone."""
    return run_cli("fsreg-sim", "Play a scenario's dialogue through the fsreg core on a simulated clock.", simulate_args, argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(sim_main())
