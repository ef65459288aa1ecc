"""Readable reports of played scenarios: one run as a table, and several policies side by side.

Used by ``fsreg-sim`` and ``fsreg-graph`` (:mod:`fsreg_ros.tools.sim`) and by the
``dialogue_player`` node; it reads the result objects of
:mod:`fsreg_ros.core.simulation.simulator`, with the alignment keys that
:func:`fsreg_ros.core.algorithms.alignment.annotate` adds when present, and computes nothing
itself.  Every figure printed is explained by a sentence printed with it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any, Mapping, Optional

from ..algorithms.alignment import ORIGIN_WORDS, ORIGINS

#: What the marks of a checked comparison mean.
MARKS = (
    "ok   = the robot's description has exactly the expected properties (their order is not compared)",
    "DIFF = it does not; the expected properties follow in brackets",
    "--   = no expected description was given for this turn (unchecked)",
)


def said(record: Mapping[str, Any]) -> str:
    """Return what the speaker of a turn said, quoted."""
    if record["speaker"] == "human":
        return '"' + (record.get("text") or ", ".join(record.get("description") or [])) + '"'
    return f'"{record.get("text")}"'


def heard(record: Mapping[str, Any]) -> str:
    """Return what reference resolution made of a human turn: the entity, or the status and candidates."""
    if record.get("resolved"):
        return str(record["resolved"])
    return f"{record.get('status')} {record.get('candidates')}"


def describe(record: Mapping[str, Any]) -> str:
    """Return one turn's utterance and outcome for the table of one run."""
    if record["speaker"] == "human":
        return f"{said(record)} -> {heard(record)}"
    mark = "" if record.get("distinguishing") else "  (not distinguishing)"
    return f'{said(record)}  [{", ".join(record.get("sources") or [])}]{mark}'


def render_table(result: Mapping[str, Any]) -> str:
    """Return a readable table of one run, with what its columns mean."""
    memory = "; ".join(f"{d}: {json.dumps(m, sort_keys=True)}" for d, m in result["memory"].items())
    lines = [f"scenario {result['scenario']}  memory {memory}", ""]
    lines.append(f"{'turn':>4}  {'time':>7}  {'speaker':<7}  {'target':<10}  {'WM before':<34}  utterance")
    for record in result["turns"]:
        wm = ", ".join(record.get("wm_before") or []) if record["speaker"] == "robot" else ""
        lines.append(
            f"{record['turn']:>4}  {record['time']:>7.2f}  {record['speaker']:<7}  "
            f"{str(record.get('target') or ''):<10}  {wm:<34}  {describe(record)}"
        )
    lines += [
        "",
        "human turns: what was said -> the entity reference resolution found (or its status and candidates).",
        "robot turns: the description, then where each of its properties came from (wm: the target's working "
        "memory, ltm: long-term memory, in preference order).",
        "WM before: the target's working memory just before the robot spoke, least recently used first.",
    ]
    if any(r["speaker"] == "robot" and not r.get("distinguishing") for r in result["turns"]):
        lines.append("(not distinguishing): the description also fits other entities.")
    if "alignment" in result:
        label = run_label(result)
        lines += ["", *turn_alignment_lines({label: result}), "", *summary_lines({label: result})]
        lines += ["", *conclusion_lines({label: result})] if label != "none" else []
    return "\n".join(lines) + "\n"


def run_label(result: Mapping[str, Any]) -> str:
    """Return the policy of a run if every domain has the same one, else ``run``."""
    policies = {str(m.get("policy")) for m in result.get("memory", {}).values()}
    return policies.pop() if len(policies) == 1 else "run"


@dataclass
class Comparison:
    """The text of a policy comparison and how it fared against expected descriptions."""

    text: str
    matched: int = 0
    checked: int = 0
    #: "policy: robot turn n" for each robot turn without an expected description.
    unchecked: list[str] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        """Whether every robot turn was checked and matched."""
        return self.matched == self.checked and not self.unchecked


def render_comparison(
    results: Mapping[str, Mapping[str, Any]], expected: Optional[Mapping[str, list]] = None
) -> Comparison:
    """Return every turn side by side, one column per policy, checked against ``expected`` if given.

    ``expected`` maps a policy to its robot descriptions in turn order (property
    lists, compared as sets).
    """
    labels = list(results)
    turns = {label: results[label]["turns"] for label in labels}
    out = Comparison(text="")
    cells: dict[str, list[str]] = {label: [] for label in labels}
    for label in labels:
        n = 0
        for record in turns[label]:
            if record["speaker"] == "human":
                cells[label].append(f"-> {heard(record)}")
                continue
            cell = record.get("text") or ""
            if expected is not None:
                wanted = expected.get(label, [])
                if n < len(wanted):
                    out.checked += 1
                    ok = set(wanted[n]) == set(record.get("description") or [])
                    out.matched += ok
                    cell = ("ok   " + cell) if ok else f"DIFF {cell} [expected: {', '.join(wanted[n])}]"
                else:
                    out.unchecked.append(f"{label}: robot turn {n + 1} (turn {record['turn']})")
                    cell = "--   " + cell
            cells[label].append(cell)
            n += 1
    first = turns[labels[0]]
    widths = {label: max([len(label)] + [len(c) for c in cells[label]]) for label in labels}
    said_width = max([4] + [len(said(row)) for row in first if row["speaker"] == "human"])
    lines = [
        f"{'turn':>4}  {'speaker':<7}  {'target':<8}  {'said':<{said_width}}  "
        + "  ".join(f"{label:<{widths[label]}}" for label in labels).rstrip()
    ]
    for i, row in enumerate(first):
        what = said(row) if row["speaker"] == "human" else ""
        row_cells = "  ".join(f"{cells[label][i]:<{widths[label]}}" for label in labels)
        target = str(row.get("target") or "")
        lines.append(f"{row['turn']:>4}  {row['speaker']:<7}  {target:<8}  {what:<{said_width}}  {row_cells}".rstrip())
    lines.append("")
    lines.append("human turns: what the human said, and per policy the entity reference resolution found.")
    lines.append("robot turns: per policy, what the robot said about the target.")
    if expected is not None:
        lines += ["", *MARKS]
    if all("alignment" in results[label] for label in labels):
        lines += ["", *turn_alignment_lines(results), "", *summary_lines(results), "", *conclusion_lines(results)]
    if expected is not None:
        lines.append("")
        lines.append(f"{out.matched}/{out.checked} robot descriptions match the expected ones")
        if out.unchecked:
            lines.append(f"{len(out.unchecked)} robot turns had no expected description: " + "; ".join(out.unchecked))
    out.text = "\n".join(lines) + "\n"
    return out


def aligned_cell(record: Mapping[str, Any]) -> str:
    """Return a robot turn's alignment: aligned/said, Dice with the human's last description, WM origins."""
    cell = f"{len(record.get('aligned') or [])}/{len(record.get('description') or [])} aligned"
    if record.get("dice_last") is not None:
        cell += f", Dice {record['dice_last']:.2f} with H{record.get('human_last_turn')}"
    origins = record.get("wm_origins") or {}
    if origins:
        cell += "; from WM: " + ", ".join(f"{p} ({o})" for p, o in origins.items())
    return cell


def turn_alignment_lines(results: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """Return the alignment of every robot turn, one column per run (the results carry ``aligned``)."""
    labels = list(results)
    rows = {label: [t for t in results[label]["turns"] if t["speaker"] == "robot"] for label in labels}
    cells = {label: [aligned_cell(t) for t in rows[label]] for label in labels}
    widths = {label: max([len(label)] + [len(c) for c in cells[label]]) for label in labels}
    lines = [
        "alignment per robot turn: how many of the properties said the human had already used for that target "
        "earlier in the game; the Dice of the description with the human's most recent description of the target "
        "(Hn: the human turn n; left out if the human had not described it); then each property taken from WM "
        "with what had put it there.",
        f"{'turn':>4}  {'target':<8}  " + "  ".join(f"{label:<{widths[label]}}" for label in labels).rstrip(),
    ]
    for i, record in enumerate(rows[labels[0]]):
        row = "  ".join(f"{cells[label][i]:<{widths[label]}}" for label in labels)
        lines.append(f"{record['turn']:>4}  {str(record.get('target') or ''):<8}  {row}".rstrip())
    return lines


def summary_lines(results: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """Return the per-run alignment figures (``alignment`` blocks), each explained in one sentence.

    For each run: entrainment (the headline) and its gain over the same game under
    policy ``none``, the length-matched gain, the aligned share and recall, the
    properties taken from WM by what had put them there, and the mean description length.
    """
    width = max(map(len, results)) if results else 0
    lines = []
    for label, result in results.items():
        block = result["alignment"]
        rows = [t for t in result["turns"] if t["speaker"] == "robot"]
        mean = block["properties"] / len(rows) if rows else 0.0
        origins = ", ".join(f"{o} {block['wm_origins'].get(o, 0)}" for o in ORIGINS)
        lines.append(
            f"{label:<{width}}  entrainment {block['entrainment']:.2f} over {block['described_turns']} turns, "
            f"gain {block['entrainment_gain']:+.2f} over none ({block['none_entrainment']:.2f}); length-matched "
            f"{block['length_matched_gain']:+.2f} aligned ({block['length_matched_turns']} turns); aligned "
            f"{block['aligned']}/{block['properties']} ({block['alignment']:.0%}), recall {block['recall']:.2f}; "
            f"from WM {block['from_wm']}/{block['properties']}: {origins}; {mean:.2f} properties per description"
        )
    sources = sorted({r["alignment"]["none_baseline"] for r in results.values()})
    words = ", ".join(f"{o} = {ORIGIN_WORDS[o]}" for o in ORIGINS)
    lines += [
        "entrainment: the mean Dice of the robot's description with the human's most recent description of the same "
        "referent, over the robot turns whose referent the human had described; unlike the aligned share, length "
        "alone cannot raise it (Dice falls with every property the human did not say and every one of theirs left "
        "out).",
        "gain over none: entrainment minus that of the same game under policy none (no working memory), paired turn "
        f"by turn; the none figure comes from {' and '.join(sources)}. One game: no interval (fsreg-sweep gives "
        "intervals over many games).",
        "length-matched: the mean change in aligned properties against none on the turns where both descriptions "
        "are as long.",
        "aligned: the robot's properties that the human had already used for the same referent earlier in the game "
        "(the share can rise just by saying less); recall: the mean share of the human's last description repeated.",
        "from WM: the properties the robot took from the target's working memory, counted by what had put each "
        f"there ({words}).",
        "properties per description: the mean number of properties in the robot's descriptions.",
    ]
    return lines


def conclusion_lines(results: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """Return what the runs say about alignment through WM, from the headline (entrainment gain over none)."""
    gains = {label: r["alignment"]["entrainment_gain"] for label, r in results.items() if label != "none"}
    if not gains:
        return []
    paired = max(r["alignment"]["paired_turns"] for r in results.values())
    parts = []
    for word, test in (("lower", lambda g: g < 0), ("higher", lambda g: g > 0), ("unchanged", lambda g: g == 0)):
        mine = [f"{label} ({gain:+.2f})" for label, gain in gains.items() if test(gain)]
        if mine:
            parts.append(f"{word} under " + (" and ".join(mine) if len(mine) < 3 else
                                             ", ".join(mine[:-1]) + " and " + mine[-1]))
    return [
        f"conclusion: on this one dialogue ({paired} paired turns), compared with no working memory the robot's "
        f"entrainment with the human (Dice with the human's last description) is {'; '.join(parts)}. One game is no "
        "evidence either way: fsreg-sweep measures the gain over many games, with intervals (docs/research.md)."
    ]
