"""Command-line front ends: ``fsreg-sim`` (and the options ``fsreg-graph`` shares).

Both take a scenario file (format: ``docs/scenario-format.md``) and the same
options; ``--json`` prints the result object, otherwise a readable table
(:mod:`fsreg_ros.core.simulation.report`).  ``--compare-policies`` runs the scenario once per
policy and prints every turn side by side, and ``--expect FILE`` checks the robot's
descriptions against expected ones (e.g. the paper's Table 1 in
``config/paper_table1.yaml``).  Command-line memory options are merged over the
file's before the effective setting of each domain is checked.  Errors in the
input are one line on stderr and exit code 2, never a traceback.

Every run is measured for alignment (:func:`fsreg_ros.core.algorithms.alignment.annotate`,
from the run's result records alone) against the same game under policy ``none``:
the compared ``none`` run if there is one, the run itself under ``none``, else the
core simulator under ``none``, played without a trace (for ``fsreg-graph`` too, so
both print the same bytes).  The WM event trace is built only when an option writes
it: ``--trace``, ``--trace-dir`` and ``--plot-dir`` (:func:`needs_trace`).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any, Callable, Optional, Sequence

from ..core.algorithms.alignment import BASELINE_COMPARED, BASELINE_RUN, BASELINE_SIMULATOR, annotate, summarise
from ..core.consultant.consultant import KnowledgeError
from ..core.forgetting import presets, settings
from ..core.forgetting.presets import PRESETS
from ..core.forgetting.policies import PolicyError, check_setting, parse_rules
from ..core.algorithms.generation import ALGORITHMS, WM_ORDERS, GenerationError
from ..core.lexicon import Lexicon
from ..core.algorithms.resolution import ResolutionError
from ..core.scenario import coverage_warning, lexicon_template, load_scenario, unsayable
from ..core.simulation.simulator import Options, Simulation, dumps
from ..core.io.yaml_source import SourceError, find_line, read_yaml
from ..core.simulation.report import render_comparison, render_table, run_label

EXIT_OK, EXIT_MISMATCH, EXIT_BAD_INPUT = 0, 1, 2
EXIT_FAILED = 1


class UsageError(ValueError):
    """A combination of command-line options that does not make sense."""


#: Errors that are the user's input, reported as one line with exit code 2.
INPUT_ERRORS = (SourceError, PolicyError, KnowledgeError, ResolutionError, GenerationError, OSError, UsageError)


def add_memory_options(parser: argparse.ArgumentParser) -> None:
    """Add one option per memory setting, from the settings table (read back by :func:`options_from_args`)."""
    memory = parser.add_argument_group("forgetting (override every domain's memory settings)")
    named = "; ".join(f"{p.name}: {p.description}" for p in PRESETS)
    memory.add_argument("--preset", metavar="NAME",
                        help=f"named settings and WM order ({named}); any setting or --wm-order given beside it "
                             "overrides the preset's")
    for row in settings.TABLE:
        memory.add_argument(row.option, type=row.kind, metavar=row.metavar, help=row.description.replace("%", "%%"))


def build_parser(prog: str, description: str) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument("scenario", type=Path, help="scenario YAML file (docs/scenario-format.md)")
    add_memory_options(parser)
    reg = parser.add_argument_group("generation")
    reg.add_argument("--algorithm", choices=ALGORITHMS, help="default: sd-pia, or dist-pia under policy none")
    reg.add_argument("--wm-order", choices=WM_ORDERS, help="order SD-PIA walks WM in (default lru-first)")
    out = parser.add_argument_group("output")
    out.add_argument("--json", action="store_true", help="print the result as one JSON object")
    out.add_argument(
        "--trace", type=Path, metavar="FILE", help="write every WM encode/forget event as JSON lines (one run only)"
    )
    out.add_argument(
        "--trace-dir", type=Path, metavar="DIR", help="write each run's WM events to DIR/<scenario>-<policy>.jsonl"
    )
    out.add_argument(
        "--plot-dir", type=Path, metavar="DIR", help="draw each run's WM timeline to DIR/<scenario>-<policy>.png"
    )
    out.add_argument(
        "--compare-policies",
        metavar="P1,P2,...",
        help="run once per policy and print every turn side by side",
    )
    out.add_argument(
        "--expect",
        type=Path,
        metavar="FILE",
        help="check the robot's descriptions per policy against this YAML; alone, compares the policies it lists",
    )
    parser.add_argument("--lexicon", type=Path, help="lexicon YAML that extends the built-in config/lexicon.yaml")
    parser.add_argument("--lexicon-template", type=Path, metavar="OUT",
                        help="write a lexicon skeleton for the properties the lexicon cannot say to OUT, and stop")
    return parser


def options_from_args(args: argparse.Namespace, policy: Optional[str] = None) -> Options:
    """Return the memory overrides and REG options given on the command line (each value checked).

    They are merged over the file's settings later, by ``Scenario.policy_for``,
    which checks the effective setting of each domain.  ``--preset`` fills in what
    is not given explicitly (:mod:`fsreg_ros.core.forgetting.presets`).
    """
    memory: dict[str, Any] = {}
    for name in settings.names():
        value = policy if name == "policy" and policy is not None else getattr(args, name)
        if value is not None:
            check_setting(name, value)
            memory[name] = value
    memory, wm_order = presets.apply(args.preset, memory, args.wm_order)
    return Options(memory=memory, algorithm=args.algorithm, wm_order=wm_order or "lru-first")


def compared_policies(args: argparse.Namespace, expected: Optional[dict]) -> list[str]:
    """Return the policies to compare: ``--compare-policies``, else those ``--expect`` lists."""
    if args.compare_policies is None:
        assert expected is not None
        policies = list(expected)
    else:
        policies = [p.strip() for p in args.compare_policies.split(",") if p.strip()]
    if not policies:
        raise UsageError("--compare-policies needs at least one policy")
    for policy in policies:
        parse_rules(policy)
    return policies


def check_usage(args: argparse.Namespace) -> None:
    """Refuse option combinations that would otherwise be ignored."""
    if args.trace is not None and (args.compare_policies or args.expect):
        raise UsageError("--trace writes the events of one run: use it without --compare-policies and --expect")
    if args.policy is not None and (args.compare_policies or args.expect):
        raise UsageError("--policy chooses one policy: use it without --compare-policies and --expect")


def load_expected(path: Path) -> dict[str, list[list[str]]]:
    """Return expected robot descriptions per policy: ``robot_descriptions: {policy: [[p, ...], ...]}``."""
    root, data = read_yaml(path)
    table = data.get("robot_descriptions") if isinstance(data, dict) else None
    if not isinstance(table, dict) or not all(
        isinstance(rows, list) and all(isinstance(r, list) for r in rows) for rows in table.values()
    ):
        line, _ = find_line(root, ("robot_descriptions",))
        raise SourceError(str(path), "robot_descriptions", "must map each policy to a list of property lists", line)
    return table


# ---------------------------------------------------------------------- main
#: Plays one scenario: (args, options) -> (result, WM event trace, or None when :func:`needs_trace` is False).
Runner = Callable[[argparse.Namespace, Options], tuple[dict, Optional[list[dict]]]]


def needs_trace(args: argparse.Namespace) -> bool:
    """Whether an option writes WM events (``--trace``, ``--trace-dir``, ``--plot-dir``): only then is a trace built."""
    return bool(args.trace or args.trace_dir or args.plot_dir)


def play_all(args: argparse.Namespace, runner: Runner, policies: Sequence[Optional[str]]) -> dict[str, tuple]:
    """Play the scenario once per policy (None: the options as given); return label -> (result, trace)."""
    runs = {}
    for policy in policies:
        result, trace = runner(args, options_from_args(args, policy))
        runs[policy if policy is not None else run_label(result)] = (result, trace)
    return runs


def with_alignment(args: argparse.Namespace, runs: dict[str, tuple]) -> dict[str, dict]:
    """Return each run's result annotated with its alignment against the same game under ``none``.

    The baseline is the run labelled ``none`` if there is one (no extra game), else
    the core simulator under ``none`` with the same options, played without a trace.
    """
    if "none" in runs:
        baseline = summarise(runs["none"][0])
        sources = {label: BASELINE_RUN if len(runs) == 1 else BASELINE_COMPARED for label in runs}
    else:
        baseline = summarise(play_core(args, options_from_args(args, "none"), trace=False)[0])
        sources = {label: BASELINE_SIMULATOR for label in runs}
    return {label: annotate(result, baseline, sources[label]) for label, (result, _) in runs.items()}


def write_run_files(args: argparse.Namespace, runs: dict[str, tuple], results: dict[str, dict]) -> list[Path]:
    """Write ``--trace`` / ``--trace-dir`` traces and ``--plot-dir`` WM timelines; return the files written."""
    written = []
    if args.trace:
        (_, trace), = runs.values()
        write_trace(args.trace, trace)
    for label, (_, trace) in runs.items():
        name = f"{args.scenario.stem}-{label}"
        if args.trace_dir:
            written.append(write_trace(args.trace_dir / f"{name}.jsonl", trace))
        if args.plot_dir:
            from ..research.plot import wm_timeline

            path = args.plot_dir / f"{name}.png"
            wm_timeline(trace, path, results[label], f"{args.scenario.stem} under {label}: working memory over time")
            written += [path, path.with_suffix(".pdf")]  # wm_timeline draws both formats
    return written


def write_trace(path: Path, trace: Sequence[dict]) -> Path:
    """Write WM events as JSON lines; return the path."""
    with path.open("w", encoding="utf-8") as out:
        for event in trace:
            out.write(json.dumps(event, sort_keys=True) + "\n")
    return path


def run_cli(
    prog: str,
    description: str,
    runner: Runner,
    argv: Optional[Sequence[str]] = None,
    failures: tuple[type[BaseException], ...] = (),
) -> int:
    """Run the shared main of ``fsreg-sim`` and ``fsreg-graph``.

    ``runner`` plays one scenario with the given options and returns (result,
    trace); the trace is needed only when :func:`needs_trace` says so (alignment reads
    the result records alone).  Bad input exits 2; a
    run that fails in one of the ``failures`` ways exits 1; both print one message.
    A comparison checked with ``--expect`` exits 1 unless every robot turn was
    checked and matched.
    """
    args = build_parser(prog, description).parse_args(argv)
    try:
        if args.lexicon_template is not None:
            return write_lexicon_template(prog, args)
        check_usage(args)
        for directory in (args.trace_dir, args.plot_dir):
            if directory is not None:
                directory.mkdir(parents=True, exist_ok=True)
        compare = bool(args.compare_policies or args.expect)
        expected = load_expected(args.expect) if args.expect else None
        policies: list[Optional[str]] = list(compared_policies(args, expected)) if compare else [None]
        runs = play_all(args, runner, policies)
        results = with_alignment(args, runs)
        written = write_run_files(args, runs, results)
    except INPUT_ERRORS as err:
        print(f"{prog}: error: {one_line(err)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except failures as err:
        print(f"{prog}: failed: {err}", file=sys.stderr)
        return EXIT_FAILED
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    code = EXIT_OK
    if compare:
        comparison = render_comparison(results, expected)
        text = dumps(results) if args.json else comparison.text
        code = EXIT_OK if expected is None or comparison.passed else EXIT_MISMATCH
    else:
        (result,) = results.values()
        text = dumps(result) if args.json else render_table(result)
    sys.stdout.write(text)
    if written:
        note = "files written: " + ", ".join(str(p) for p in written)
        print(note, file=sys.stderr if args.json else sys.stdout)
    return code


def one_line(err: BaseException) -> str:
    """Return an error as one line (an OSError with its file name)."""
    if isinstance(err, OSError) and err.filename is not None:
        return f"{err.filename}: {err.strerror or err}"
    return " ".join(str(err).split())


_WARNED: set[str] = set()


def warn_unsayable(prog: str, lexicon: Lexicon, scenario) -> None:
    """Print, once per scenario, the one-line warning naming the properties the lexicon cannot say."""
    warning = coverage_warning(lexicon, scenario)
    if warning and scenario.name not in _WARNED:
        _WARNED.add(scenario.name)
        print(f"{prog}: warning: {warning}", file=sys.stderr)


def write_lexicon_template(prog: str, args: argparse.Namespace) -> int:
    """Write ``--lexicon-template``'s lexicon skeleton for the scenario; say where (exit 0)."""
    lexicon, scenario = loaded(args)
    count = sum(len(props) for props in unsayable(lexicon, scenario).values())
    args.lexicon_template.write_text(lexicon_template(lexicon, scenario, str(args.scenario)), encoding="utf-8")
    plural = "property" if count == 1 else "properties"
    print(f"{prog}: wrote {args.lexicon_template}: a lexicon skeleton for {count} {plural}")
    return EXIT_OK


def loaded(args: argparse.Namespace) -> tuple[Lexicon, Any]:
    """Return the lexicon and scenario of ``args``, loaded once per command (every run and the baseline share them)."""
    if getattr(args, "loaded", None) is None:
        lexicon = Lexicon.load(args.lexicon)
        args.loaded = (lexicon, load_scenario(args.scenario, lexicon))
    return args.loaded


def play_core(args: argparse.Namespace, options: Options, trace: bool) -> tuple[dict, Optional[list[dict]]]:
    """Play the scenario of ``args`` with the core; return (result, WM event trace if ``trace`` else None)."""
    lexicon, scenario = loaded(args)
    simulation = Simulation(scenario, options, lexicon, trace=trace)
    result = simulation.run()
    return result, simulation.trace() if trace else None


def simulate_args(args: argparse.Namespace, options: Options) -> tuple[dict, Optional[list[dict]]]:
    """Play the scenario of ``args`` with the core; return (result, WM event trace when an option writes it)."""
    warn_unsayable("fsreg-sim", *loaded(args))
    return play_core(args, options, needs_trace(args))


def sim_main(argv: Optional[Sequence[str]] = None) -> int:
    """``fsreg-sim SCENARIO.yaml [options]``: play a scenario with the core alone (``--replay DIR``: a recording)."""
    words = list(sys.argv[1:] if argv is None else argv)
    if any(w == "--replay" or w.startswith("--replay=") for w in words):
        return replay_main(words)
    description = "Play a scenario's dialogue through the fsreg core on a simulated clock."
    return run_cli("fsreg-sim", description, simulate_args, argv)


def replay_main(argv: Sequence[str]) -> int:
    """``fsreg-sim --replay DIR [--scenario FILE] [--lexicon FILE] [--json]``: a recorded session, turn by turn.

    Exit 0 when every turn's answer and WM equal the live graph's, 1 on a difference, 2 when
    the recording cannot be read or replayed (one line naming the file and the problem).
    """
    from ..core.io.recording import RecordingError, open_recording
    from ..core.simulation.replay import ReplayError, render, replay, session_of

    parser = argparse.ArgumentParser(
        prog="fsreg-sim", description="Replay a recorded live session (fsreg-ctl record, fsreg-up --record) through "
        "the simulator and report, turn by turn, whether its answers and WM equal the live graph's.")
    parser.add_argument("--replay", type=Path, required=True, metavar="DIR",
                        help="the recording: a rosbag2 folder (or its .mcap file)")
    parser.add_argument("--scenario", type=Path, metavar="FILE",
                        help="the knowledge base the graph ran with (default: the copy in the recording)")
    parser.add_argument("--lexicon", type=Path, metavar="FILE", help="its lexicon (default: the recording's, if any)")
    parser.add_argument("--json", action="store_true", help="print one JSON object per turn")
    args = parser.parse_args(argv)
    try:
        session = session_of(open_recording(args.replay), args.scenario, args.lexicon)
        reports = replay(session)
    except (RecordingError, ReplayError) as err:
        print(f"fsreg-sim: error: {one_line(err)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except INPUT_ERRORS as err:
        print(f"fsreg-sim: error: {args.replay}: {one_line(err)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.json:
        for r in reports:
            print(json.dumps({"turn": r.index, "speaker": r.kind, "time": r.time, "request": r.request,
                              "live": r.live, "equal": not r.differences, "differences": r.differences},
                             sort_keys=True))
    else:
        sys.stdout.write(render(session, reports))
    for note in session.notes:
        if args.json:
            print(f"fsreg-sim: note: {note}", file=sys.stderr)
    return EXIT_MISMATCH if any(r.differences for r in reports) else EXIT_OK


if __name__ == "__main__":  # pragma: no cover
    sys.exit(sim_main())
