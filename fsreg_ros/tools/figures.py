"""Every figure of README.md and docs/research.md, with the one command that regenerates it.

A *figure* is one command users can run (``fsreg-eval``, ``fsreg-sweep``,
``fsreg-sim``, ``fsreg-graph``) and the blocks of the documents that show what it printed or wrote.
In a document a block sits between ``<!-- figure NAME -->`` and ``<!-- /figure -->``
and starts with the command itself, so every number in it sits next to the command
that regenerates it; a ``Run time:`` line says how long the command took.

``python -m fsreg_ros.tools.figures --tuna DIR --tangrams DIR`` (what ``scripts/figures.sh``
runs; the tangram corpus also from ``$FSREG_TANGRAMS_DIR``) plays every command at its documented
size, from the repository root, and
rewrites the blocks; ``--check`` plays them again and fails, showing the difference,
if any block other than its run time differs from the documents.  ``--only NAME``
restricts either to some figures; :func:`run_small` plays a figure at a small scale
(the test suite does, for every figure).  Outputs go to ``out/figures/`` (git-ignored).
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import difflib
import io
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional, Sequence

from ..core.forgetting.settings import setting as memory_setting
from ..research.grid import DEFAULT_WM_ORDER, NUMERIC, WM_ORDER

ROOT = Path(__file__).resolve().parents[2]
DOCS = ("README.md", "docs/research.md")
OUT = "out/figures"
TUNA = "$FSREG_TUNA_DIR"
TANGRAMS = "$FSREG_TANGRAMS_DIR"
PEOPLE_ORDER = "type,hasBeard,hasGlasses,hairColour,hasHair,age,orientation,hasSuit,hasTie,hasShirt"
ORDERS = ("--order", "furniture=type,colour,orientation,size", "--order", f"people={PEOPLE_ORDER}")
BEGIN, END = "<!-- figure {} -->", "<!-- /figure -->"
RUN_TIME = "Run time: "


@dataclass
class Output:
    """What one figure's command printed and wrote, and how long it took."""

    argv: list
    stdout: str
    directory: Optional[Path]
    seconds: float


Renderer = Callable[["Figure", Output], str]


def verbatim(figure: "Figure", output: Output) -> str:
    """Render the command's printed output as it is."""
    return _code(output.stdout.rstrip("\n"), "")


def from_line(prefix: str) -> Renderer:
    """Render the printed output from the first line starting with ``prefix`` on."""
    def render(figure: "Figure", output: Output) -> str:
        lines = output.stdout.splitlines()
        start = next((i for i, line in enumerate(lines) if line.startswith(prefix)), len(lines))
        return _code("\n".join(lines[start:]), "")
    return render


def until_line(prefix: str) -> Renderer:
    """Render the printed output before the first line starting with ``prefix``."""
    def render(figure: "Figure", output: Output) -> str:
        lines = output.stdout.splitlines()
        stop = next((i for i, line in enumerate(lines) if line.startswith(prefix)), len(lines))
        return _code("\n".join(lines[:stop]), "")
    return render


def between(start: str, stop: str) -> Renderer:
    """Render the printed output from the first line starting with ``start`` to the next starting with ``stop``."""
    def render(figure: "Figure", output: Output) -> str:
        lines = output.stdout.splitlines()
        first = next((i for i, line in enumerate(lines) if line.startswith(start)), len(lines))
        last = next((i for i in range(first, len(lines)) if lines[i].startswith(stop)), len(lines))
        return _code("\n".join(lines[first:last]).rstrip("\n"), "")
    return render


def lines_with(text: str) -> Renderer:
    """Render the printed lines that contain ``text``."""
    def render(figure: "Figure", output: Output) -> str:
        return _code("\n".join(line for line in output.stdout.splitlines() if text in line), "")
    return render


def tuna_dice_table(figure: "Figure", output: Output) -> str:
    """Dice per domain, condition and algorithm, from ``fsreg-eval tuna``'s printed table."""
    rows: dict[tuple, dict] = {}
    for line in output.stdout.splitlines()[1:]:
        cells = line.split()
        if len(cells) >= 5:
            rows.setdefault((cells[0], cells[1]), {})[cells[2]] = cells[4]
    algorithms = ("dist-pia", "full-brevity", "greedy")
    lines = ["| domain | condition | IA (dist-pia) | Full Brevity | Greedy |", "|---|---|---|---|---|"]
    for (domain, condition), dice in rows.items():
        lines.append(f"| {domain} | {condition} | " + " | ".join(dice.get(a, "") for a in algorithms) + " |")
    return "\n".join(lines)


def divergence_blocks(figure: "Figure", output: Output) -> str:
    """Divergence from ``none`` by blocks of 20 robot turns, per setting (mean over games, from divergence.csv)."""
    assert output.directory is not None
    flags: dict[str, dict[int, list[float]]] = {}
    per_game: dict[tuple, list[int]] = {}
    with (output.directory / "divergence.csv").open(encoding="utf-8") as handle:
        for row in csv.DictReader(handle):
            if row["policy"] == "none":
                continue
            label = _setting_label(row)
            per_game.setdefault((label, row["seed"]), []).append(int(row["diverged"]))
    longest = max((len(v) for v in per_game.values()), default=0)
    width = 20 if longest >= 40 else max(1, longest // 2)
    for (label, _seed), values in per_game.items():
        blocks = flags.setdefault(label, {})
        for b in range(0, len(values), width):
            chunk = values[b:b + width]
            blocks.setdefault(b // width, []).append(sum(chunk) / len(chunk))
    spans = [f"{b * width + 1}-{min((b + 1) * width, longest)}" for b in range((longest + width - 1) // width)]
    lines = ["| setting | " + " | ".join(spans) + " |", "|---|" + "---|" * len(spans)]
    for label, blocks in flags.items():
        cells = [f"{sum(v) / len(v):.2f}" for _, v in sorted(blocks.items())]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def origin_table(figure: "Figure", output: Output) -> str:
    """Of the properties the robot took from WM, the share each origin had put there, per setting (mean over games)."""
    assert output.directory is not None
    from ..core.algorithms.alignment import ORIGINS

    sums: dict[str, list[list[float]]] = {}
    with (output.directory / "runs.csv").open(encoding="utf-8") as handle:
        for row in csv.DictReader(handle):
            if row["policy"] == "none" or not row[f"from_{ORIGINS[0]}"]:
                continue
            sums.setdefault(_setting_label(row), []).append(
                [float(row["from_wm_share"])] + [float(row[f"from_{o}"]) for o in ORIGINS])
    lines = ["| setting | taken from WM | " + " | ".join(ORIGINS) + " |", "|---|---|" + "---|" * len(ORIGINS)]
    for label, values in sums.items():
        means = [sum(col) / len(col) for col in zip(*values)]
        lines.append(f"| {label} | " + " | ".join(f"{m:.0%}" for m in means) + " |")
    return "\n".join(lines)


def tangram_table(figure: "Figure", output: Output) -> str:
    """Render the model table of ``fsreg-eval tangrams`` as markdown: held-out LL, difference from constant, setting."""
    import re

    lines = output.stdout.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("model "))
    rows = ["| model | held-out log-likelihood per candidate | difference from constant [95 % CI] "
            "| fitted on all games |", "|---|---|---|---|"]
    for line in lines[start + 1:]:
        if not line.strip():
            break
        found = re.match(r"^(\S+)\s+(-?\d+\.\d+)\s+([+-]\d\.\d+ \[[^\]]+\])?\s*(.*)$", line)
        if found:
            name, ll, diff, setting = found.groups()
            rows.append(f"| {name} | {ll} | {diff or '(reference)'} | {setting} |")
    summary = next((line for line in lines if line.startswith("tangram games")), "")
    return "\n".join(rows) + f"\n\n{summary.split(': ', 1)[-1]}."


def _read(output: Output, name: str) -> list[dict]:
    assert output.directory is not None
    with (output.directory / name).open(encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def _interval(row: dict, metric: str, digits: int, signed: bool = False) -> str:
    form = f"{{:+.{digits}f}}" if signed else f"{{:.{digits}f}}"
    values = [float(row[metric + suffix]) for suffix in ("", "_low", "_high")]
    return f"{form.format(values[0])} [{form.format(values[1])}, {form.format(values[2])}]"


def summary_table(figure: "Figure", output: Output) -> str:
    """Per setting: entrainment, its gain over none with the interval, and what moves with it (summary.csv)."""
    rows = _read(output, "summary.csv")
    lines = ["| setting | entrainment | gain over none [95 % CI] | length-matched gain | properties per description "
             "| WM occupancy | divergence |", "|---|---|---|---|---|---|---|"]
    for row in rows:
        lines.append(
            f"| {_setting_label(row)} | {float(row['entrainment']):.3f} | "
            f"{_interval(row, 'entrainment_gain', 3, True)} | {float(row['length_matched_gain']):+.3f} | "
            f"{float(row['mean_length']):.2f} | {float(row['mean_wm_occupancy']):.1f} | "
            f"{float(row['divergence']):.2f} |")
    return "\n".join(lines) + f"\n\nMeans over {rows[0]['games']} games; intervals: {_method()}."


def listener_table(figure: "Figure", output: Output) -> str:
    """Per setting: the listener's success, turns to success, length and entrainment with intervals (summary.csv)."""
    rows = _read(output, "summary.csv")
    robot = "partner_resolved" in rows[0]
    lines = ["| setting | success [95 % CI] | at once | turns to success [95 % CI] | length | said, repairs incl. "
             "[95 % CI] | entrainment [95 % CI] |" + (" robot resolved |" if robot else ""),
             "|---|---|---|---|---|---|---|" + ("---|" if robot else "")]
    for row in rows:
        lines.append(
            f"| {_setting_label(row)} | {_interval(row, 'success', 3)} | {float(row['first_success']):.3f} | "
            f"{_interval(row, 'turns_to_success', 2)} | {float(row['mean_length']):.2f} | "
            f"{_interval(row, 'said_length', 2)} | {_interval(row, 'entrainment', 3)} |"
            + (f" {float(row['partner_resolved']):.3f} |" if robot else ""))
    return "\n".join(lines) + f"\n\nMeans over {rows[0]['games']} games; intervals: {_method()}."


def repetition_table(figure: "Figure", output: Output) -> str:
    """Per setting: entrainment, success, repairs and the length of the k-th description of a referent (summary.csv)."""
    from ..research.repetition import METRICS

    rows = _read(output, "summary.csv")
    lines = ["| setting | entrainment [95 % CI] | success [95 % CI] | repairs | "
             + " | ".join(f"length {k}" for k in range(1, len(METRICS) + 1)) + " | 1st - 6th (6th's 95 % CI) |",
             "|---|---|---|---|" + "---|" * (len(METRICS) + 1)]
    for row in rows:
        lengths = " | ".join(f"{float(row[m]):.2f}" for m in METRICS)
        first, last = (_interval(row, m, 2).split(" ", 1) for m in (METRICS[0], METRICS[-1]))
        lines.append(f"| {_setting_label(row)} | {_interval(row, 'entrainment', 3)} | {_interval(row, 'success', 3)} "
                     f"| {float(row['repairs']):.2f} | {lengths} | "
                     f"{float(first[0]) - float(last[0]):+.2f} (6th: {last[1]}) |")
    return "\n".join(lines) + f"\n\nMeans over {rows[0]['games']} games; length k: properties (content words) of the " \
        f"robot's k-th description of one referent, per game over the referents described k times; " \
        f"intervals: {_method()}."


def recommendation_table(figure: "Figure", output: Output) -> str:
    """Render the follow-up's recommendation (recommendation.csv): per WM configuration and bound, the best."""
    rows = _read(output, "recommendation.csv")
    lines = ["| WM | outdated rate at most | setting | entrainment [95 % CI] | gain over none [95 % CI] | "
             "outdated rate [95 % CI] | settings within the bound |", "|---|---|---|---|---|---|---|"]
    for row in rows:
        if not row["policy"]:
            lines.append(f"| {row['wm']} | {float(row['max_outdated_rate']):.0%} | none qualifies | | | | 0 |")
            continue
        lines.append(
            f"| {row['wm']} | {float(row['max_outdated_rate']):.0%} | {_setting_label({**row, 'retraction': 'on'})} | "
            f"{_interval(row, 'entrainment', 3)} | {_interval(row, 'entrainment_gain', 3, True)} | "
            f"{_interval(row, 'outdated_rate', 4)} | {row['settings_allowed']} of {row['settings_considered']} |")
    return "\n".join(lines) + f"\n\nIntervals: {_method()}."


def _method() -> str:
    from ..research.stats import METHOD

    return METHOD


def max_outdated(figure: "Figure", output: Output) -> str:
    """Render the largest mean outdated rate of any setting (summary.csv)."""
    assert output.directory is not None
    with (output.directory / "summary.csv").open(encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    worst = max(rows, key=lambda r: float(r["outdated_rate"]))
    return (f"Largest mean outdated rate over the {len(rows)} settings: {float(worst['outdated_rate']):.4f} "
            f"({worst['policy']}, WM {worst['wm']}).")


def _setting_label(row: dict) -> str:
    params = ", ".join(f"{memory_setting(p).symbol} = {float(row[p]):g}" for p in NUMERIC if row.get(p))
    told = "" if row.get("retraction", "on") == "on" else " (not told)"
    order = row.get(WM_ORDER) or DEFAULT_WM_ORDER
    shown = f", {order} order" if order != DEFAULT_WM_ORDER and row["policy"] != "none" else ""
    return f"{row['policy']} {params}".strip() + shown + told


def _code(text: str, language: str = "bash") -> str:
    return f"```{language}\n{text}\n```"


@dataclass(frozen=True)
class Figure:
    """One command and the document blocks that show its results."""

    name: str
    tool: str
    argv: tuple  # as users type it after the tool's name (``$FSREG_TUNA_DIR`` for the corpus)
    blocks: dict  # block name -> (document, renderer)
    small: dict = field(default_factory=dict)  # option -> value at small scale (the tests)
    small_argv: tuple = ()  # or the whole argv at small scale (a corpus of other attributes)
    writes: bool = False  # has an --out directory

    def command(self) -> str:
        """Return the command as the documents show it."""
        import shlex

        args = [a if a in (TUNA, TANGRAMS) else shlex.quote(a) for a in self.argv]
        words = [f".venv/bin/{self.tool}"]
        for arg in args:  # an option and its value stay on one line
            if words[-1].startswith("--") and not arg.startswith("--") and " " not in words[-1]:
                words[-1] += " " + arg
            else:
                words.append(arg)
        text, line = "", ""
        for word in words:  # wrapped at about 100 columns with shell continuations
            if line and len(line) + len(word) > 96:
                text += line + " \\\n"
                line = "   "
            line += " " + word if line else word
        return text + line


SWEEP = ("--policies", "decay,displacement,none", "--decay-periods", "5,10,20,40", "--capacities", "1,2,3,4",
         "--seeds", "30", "--turns", "200", "--jobs", "2", "--no-progress")
FOLLOWUP = ("--world", "faces+objects", "--changes", "20", "--retraction", "on,off", "--wm-belief",
            "--policies", "decay,displacement,decay+displacement,shared-capacity,decay+shared-capacity,none",
            "--decay-periods", "5,10,20,40,80", "--capacities", "1,2,3,4,6", "--shared-capacities", "8,16,32,64,128",
            "--seeds", "30", "--turns", "200", "--jobs", "2", "--no-progress")
SMALL = {"--seeds": "2", "--turns": "12"}
LISTENER = ("--policies", "decay,displacement,none", "--decay-periods", "10,40", "--capacities", "2,4",
            "--seeds", "30", "--turns", "100", "--jobs", "2", "--no-progress")

FIGURES = (
    Figure("tuna", "fsreg-eval", ("tuna", TUNA, *ORDERS),
           {"tuna": ("docs/research.md", verbatim), "tuna-dice": ("docs/research.md", tuna_dice_table)},
           small_argv=("tuna", TUNA, ORDERS[0], ORDERS[1], "--order", "people=type,hasBeard,hasGlasses")),
    Figure("tuna-learned", "fsreg-eval", ("tuna", TUNA, "--folds", "10"),
           {"tuna-learned": ("docs/research.md", verbatim)}, small={"--folds": "2"}),
    Figure("table1", "fsreg-sim",
           ("scenarios/guess_who_table1.yaml", "--compare-policies", "decay,displacement,none",
            "--expect", "config/paper_table1.yaml", "--plot-dir", "out"),
           {"table1": ("README.md", verbatim),
            "table1-alignment": ("docs/research.md", from_line("decay         entrainment"))}),
    # The main job itself (scripts/table1.sh): the same comparison through the multi-process node graph, for its
    # run time (its output is the table1 block's, byte for byte; the block shows the check's verdict).
    Figure("table1-graph", "fsreg-graph",
           ("scenarios/guess_who_table1.yaml", "--compare-policies", "decay,displacement,none",
            "--expect", "config/paper_table1.yaml", "--plot-dir", "out"),
           {"table1-graph": ("README.md", lines_with("robot descriptions match"))},
           small_argv=("scenarios/guess_who_table1.yaml", "--policy", "decay")),
    Figure("sweep", "fsreg-sweep", SWEEP + ("--out", f"{OUT}/sweep"),
           {"sweep": ("docs/research.md", summary_table), "sweep-full": ("docs/research.md", verbatim),
            "sweep-divergence": ("docs/research.md", divergence_blocks),
            "sweep-origins": ("docs/research.md", origin_table)},
           small=SMALL, writes=True),
    Figure("sweep-both", "fsreg-sweep",
           ("--policies", "decay+displacement,none", "--decay-periods", "10,20,40", "--capacities", "1,2,3",
            "--seeds", "30", "--turns", "200", "--jobs", "2", "--no-progress", "--out", f"{OUT}/sweep-both"),
           {"sweep-both": ("docs/research.md", verbatim)}, small=SMALL, writes=True),
    Figure("sweep-human-wm", "fsreg-sweep",
           SWEEP[:-7] + ("--seeds", "30", "--turns", "200", "--human-memory", "policy=decay", "--human-memory",
                         "decay_period=10", "--jobs", "2", "--no-progress", "--out", f"{OUT}/sweep-human-wm"),
           {"sweep-human-wm": ("docs/research.md", verbatim)}, small=SMALL, writes=True),
    Figure("sweep-rules", "fsreg-sweep",
           ("--policies", "displacement,displacement-lfu,displacement-random,similarity,global-capacity,none",
            "--capacities", "1,2,3", "--global-capacities", "8,16,32", "--seeds", "30", "--turns", "200",
            "--jobs", "2", "--no-progress", "--out", f"{OUT}/sweep-rules"),
           {"sweep-rules": ("docs/research.md", verbatim)}, small=SMALL, writes=True),
    Figure("listener", "fsreg-sweep", LISTENER + ("--listener-missing", "0.1", "--listener-noise", "0.05",
                                                  "--out", f"{OUT}/listener"),
           {"listener": ("docs/research.md", listener_table)}, small=SMALL, writes=True),
    Figure("robot-robot", "fsreg-sweep", LISTENER + ("--partner", "robot", "--listener-noise", "0.05",
                                                     "--out", f"{OUT}/robot-robot"),
           {"robot-robot": ("docs/research.md", listener_table)}, small=SMALL, writes=True),
    Figure("followup", "fsreg-sweep", FOLLOWUP + ("--out", f"{OUT}/followup"),
           {"followup": ("docs/research.md", recommendation_table),
            "followup-readme": ("docs/research.md", recommendation_table),
            "followup-settings": ("docs/research.md", until_line("recommendation:"))},
           small=SMALL, writes=True),
    Figure("followup-verified", "fsreg-sweep",
           tuple(a for a in FOLLOWUP if a != "--wm-belief")[:-7] + ("--seeds", "10", "--turns", "200", "--jobs", "2",
                                                                    "--no-progress", "--out",
                                                                    f"{OUT}/followup-verified"),
           {"followup-verified": ("docs/research.md", max_outdated)}, small=SMALL, writes=True),
)


TANGRAM_SMALL = {"--folds": "2"}
FIGURES += (
    Figure("tangrams", "fsreg-eval",
           ("tangrams", TANGRAMS, "--folds", "10", "--jobs", "2", "--plots", f"{OUT}/tangrams"),
           {"tangrams": ("docs/research.md", verbatim), "tangrams-readme": ("docs/research.md", tangram_table),
            "tangrams-answer": ("docs/research.md", between("the paper's rules against each other", "best:"))},
           small=TANGRAM_SMALL),
    Figure("tangrams-stems", "fsreg-eval",
           ("tangrams", TANGRAMS, "--tokens", "stems", "--folds", "10", "--jobs", "2", "--plots",
            f"{OUT}/tangrams-stems"),
           {"tangrams-stems": ("docs/research.md", verbatim)}, small=TANGRAM_SMALL),
    # The robot with the parameters fitted to people (above) beside the paper's delta = 10, alpha = 2.
    Figure("sweep-human-fitted", "fsreg-sweep",
           ("--policies", "decay,displacement,decay+displacement,none", "--decay-periods", "10,180,480",
            "--capacities", "2,4,6", "--seeds", "30", "--turns", "200", "--jobs", "2", "--no-progress",
            "--out", f"{OUT}/sweep-human-fitted"),
           {"sweep-human-fitted": ("docs/research.md", summary_table),
            "sweep-human-fitted-readme": ("docs/research.md", summary_table)}, small=SMALL, writes=True),
    # The robot with people's rule (reference episodes, the strength order) beside the paper's and the best
    # rule fitted to people (activation, d = 0.99, tau = -6), with the listener that can fail.
    Figure("people-rule", "fsreg-sweep",
           ("--policies", "decay+displacement,activation,episodes,none", "--decay-periods", "10", "--capacities", "2",
            "--activation-thresholds", "-6", "--memory", "activation_decay=0.99", "--episode-windows", "1,2",
            "--wm-orders", "lru-first,strength", "--listener-missing", "0.1", "--listener-noise", "0.05",
            "--seeds", "40", "--turns", "200", "--jobs", "2", "--no-progress", "--out", f"{OUT}/people-rule"),
           {"people-rule": ("docs/research.md", repetition_table)}, small=SMALL, writes=True),
)


def tool_main(tool: str) -> Callable[[Sequence[str]], int]:
    """Return the entry point of one of the workbench's commands."""
    from .graph import main as graph_main
    from .sim import sim_main
    from ..research.cli import eval_main, sweep_main

    return {"fsreg-eval": eval_main, "fsreg-sweep": sweep_main, "fsreg-sim": sim_main, "fsreg-graph": graph_main}[tool]


def _argv(figure: Figure, tuna: Optional[Path], overrides: dict, small: bool = False,
          tangrams: Optional[Path] = None) -> list:
    argv = list(figure.small_argv if small and figure.small_argv else figure.argv)
    for option, value in overrides.items():
        if option in argv:
            argv[argv.index(option) + 1] = value
    return [str(tuna) if a == TUNA else str(tangrams) if a == TANGRAMS else a for a in argv]


def run(figure: Figure, tuna: Optional[Path], overrides: Optional[dict] = None, small: bool = False,
        tangrams: Optional[Path] = None) -> Output:
    """Run a figure's command in this process (from the repository root); return what it printed and wrote."""
    argv = _argv(figure, tuna, overrides or {}, small, tangrams)
    if TUNA in figure.argv and tuna is None:
        raise SystemExit(f"figures: {figure.name} needs the TUNA corpus: give --tuna DIR or set FSREG_TUNA_DIR")
    if TANGRAMS in figure.argv and tangrams is None:
        raise SystemExit(f"figures: {figure.name} needs the tangram corpus: give --tangrams DIR or set "
                         "FSREG_TANGRAMS_DIR")
    directory = ROOT / argv[argv.index("--out") + 1] if "--out" in argv else None
    printed = io.StringIO()
    cwd = Path.cwd()
    os.chdir(ROOT)
    try:
        start = time.perf_counter()
        with contextlib.redirect_stdout(printed):
            code = tool_main(figure.tool)(argv)
        seconds = time.perf_counter() - start
    finally:
        os.chdir(cwd)
    if code != 0 and not (figure.tool in ("fsreg-sim", "fsreg-graph") and code == 1):
        raise RuntimeError(f"{figure.name}: {figure.tool} exited {code}")
    return Output(argv, printed.getvalue(), directory, seconds)


def run_small(figure: Figure, tuna: Path, out: Path) -> dict:
    """Run a figure at small scale (its ``small`` overrides, outputs under ``out``); return its rendered blocks."""
    overrides = dict(figure.small)
    for option in ("--out", "--plot-dir", "--plots"):
        if option in figure.argv:
            overrides[option] = str(out / figure.name)
    tangrams = None
    if TANGRAMS in figure.argv:  # a tiny hand-made corpus in the corpus's format
        from ..research.tangrams import write_example

        tangrams = write_example(out / "tangrams-example").parent
    return render(figure, run(figure, tuna, overrides, small=True, tangrams=tangrams))


def render(figure: Figure, output: Output) -> dict:
    """Return every block of the figure: its command, the rendered results and the run time."""
    blocks = {}
    for name, (_, renderer) in figure.blocks.items():
        text = _code(figure.command()) + "\n\n" + renderer(figure, output)
        text += f"\n\n{RUN_TIME}{output.seconds:.0f} s on this project's 2-core machine ({figure.name}, " \
                "measured by `scripts/figures.sh`)."
        blocks[name] = text
    return blocks


def replace_blocks(text: str, blocks: dict, path: str) -> str:
    """Return ``text`` with every named block's content replaced; a block the text lacks is an error."""
    for name, content in blocks.items():
        begin = BEGIN.format(name)
        if begin not in text:
            raise SystemExit(f"figures: {path} has no block '{begin}'")
        head, rest = text.split(begin, 1)
        _, tail = rest.split(END, 1)
        text = head + begin + "\n" + content + "\n" + END + tail
    return text


def _comparable(text: str) -> list[str]:
    return [line for line in text.splitlines() if not line.startswith(RUN_TIME)]


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Regenerate (or ``--check``) every figure block of README.md and docs/research.md."""
    parser = argparse.ArgumentParser(prog="figures", description=__doc__.splitlines()[0])
    parser.add_argument("--tuna", type=Path, default=os.environ.get("FSREG_TUNA_DIR") or None,
                        help="the TUNA corpus directory (default: $FSREG_TUNA_DIR)")
    parser.add_argument("--tangrams", type=Path, default=os.environ.get("FSREG_TANGRAMS_DIR") or None,
                        help="the tangram corpus directory (default: $FSREG_TANGRAMS_DIR)")
    parser.add_argument("--check", action="store_true", help="compare with the documents instead of rewriting them")
    parser.add_argument("--only", action="append", default=[], metavar="NAME", help="only these figures")
    args = parser.parse_args(argv)
    unknown = [n for n in args.only if n not in {f.name for f in FIGURES}]
    if unknown:
        parser.error(f"--only: unknown figure {', '.join(unknown)} (known: {', '.join(f.name for f in FIGURES)})")
    if args.tuna is None:
        parser.error("give the TUNA corpus directory: --tuna DIR or FSREG_TUNA_DIR (it is not shipped)")
    chosen = [f for f in FIGURES if not args.only or f.name in args.only]
    if args.tangrams is None and any(TANGRAMS in f.argv for f in chosen):
        parser.error("give the tangram corpus directory: --tangrams DIR or FSREG_TANGRAMS_DIR (it is not shipped)")
    tangrams = args.tangrams.resolve() if args.tangrams is not None else None
    documents = {doc: (ROOT / doc).read_text(encoding="utf-8") for doc in DOCS}
    differ = []
    total = 0.0
    for figure in chosen:
        output = run(figure, args.tuna.resolve(), tangrams=tangrams)
        total += output.seconds
        print(f"figures: {figure.name}: {output.seconds:.1f} s", file=sys.stderr)
        for name, content in render(figure, output).items():
            doc = figure.blocks[name][0]
            if args.check:
                current = replace_blocks(documents[doc], {name: content}, doc)
                if _comparable(current) != _comparable(documents[doc]):
                    differ.append((doc, name, documents[doc], current))
            else:
                documents[doc] = replace_blocks(documents[doc], {name: content}, doc)
    print(f"figures: {len(chosen)} commands in {total:.0f} s", file=sys.stderr)
    if args.check:
        for doc, name, old, new in differ:
            for line in difflib.unified_diff(_comparable(old), _comparable(new), f"{doc} (documented)",
                                             f"{doc} (now: {name})", lineterm="", n=1):
                print(line)
        print(f"figures --check: {len(differ)} block(s) differ from the documents" if differ
              else "figures --check: every block equals the documents")
        return 1 if differ else 0
    for doc, text in documents.items():
        (ROOT / doc).write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
