"""Alignment, measured: how far the robot's descriptions reuse the human's words.

The paper argues that working memory makes the robot *align* with its partner
(SD-PIA, Algorithm 4, prefers properties in WM, and the human's descriptions are
encoded there by rule 1).  This module measures it on a played game:

* **aligned**: a property the robot selected for referent R is aligned if the
  human had used it for R in an earlier turn (R is the human turn's ``target``,
  else what RR resolved it to);
* **origin**: for a property taken from WM (``sources`` = ``wm``), what had put it
  there, from the ``/wm/events`` trace: ``human-speech`` (cause ``speaker`` on a
  human turn), ``robot-speech`` (``speaker`` on a robot turn), ``rr`` (reference
  resolution affirming it for a candidate, rule 2) or ``reg-distractor`` (REG
  affirming it for a distractor, rule 3).  It is the encoding that last made the
  property *enter* WM (a refresh while present does not change it).  On a human
  turn, RR affirms the human's words for every candidate before rule 1 encodes
  them for the referent, so an ``rr`` entry of a property the human said, for the
  entity the turn referred to, counts as ``human-speech``: the human's
  description put it there; ``rr`` is left for what RR affirmed of other
  candidates;
* **gain**: alignment under a policy minus alignment of the same game under
  policy ``none`` (No-WM).

Inputs are the docs/semantics.md section 6 result dict and the event trace (``Simulation.trace()``).
:func:`annotate` adds these figures to a result as extra keys (docs/semantics.md section 6 allows
them): ``aligned`` and ``wm_origins`` on each robot turn and an ``alignment`` block;
``fsreg-sim`` and ``fsreg-graph`` both print results annotated by it.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any, Mapping, Optional, Sequence

ORIGINS = ("human-speech", "rr", "reg-distractor", "robot-speech")
#: What each origin means, for reports.
ORIGIN_WORDS = {
    "human-speech": "the human's own description",
    "rr": "reference resolution checking a candidate",
    "reg-distractor": "REG ruling out a distractor",
    "robot-speech": "the robot's own earlier description",
}


@dataclass
class TurnAlignment:
    """One robot turn: what it said, what the human had said of the referent, where WM properties came from."""

    turn: int
    target: str
    description: list[str]
    human_used: list[str]
    aligned: list[str]
    origins: dict[str, str] = field(default_factory=dict)
    wm_size: int = 0  # properties in the domain's WM (all entities) just before the turn


@dataclass
class AlignmentSummary:
    """A game's alignment figures (pooled over robot turns)."""

    robot_turns: int
    properties: int
    aligned: int
    from_wm: int
    origins: dict[str, int]
    turns: list[TurnAlignment]

    @property
    def alignment(self) -> float:
        """Share of the robot's properties the human had already used for that referent."""
        return self.aligned / self.properties if self.properties else 0.0

    @property
    def wm_share(self) -> float:
        """Share of the robot's properties taken from WM."""
        return self.from_wm / self.properties if self.properties else 0.0

    def to_json(self) -> dict:
        return {
            "robot_turns": self.robot_turns,
            "properties": self.properties,
            "aligned": self.aligned,
            "alignment": round(self.alignment, 4),
            "from_wm": self.from_wm,
            "wm_origins": {o: self.origins.get(o, 0) for o in ORIGINS},
        }


def _referent(record: Mapping[str, Any]) -> Optional[str]:
    return record.get("target") or record.get("resolved")


def turn_alignment(result: Mapping[str, Any], trace: Sequence[Mapping[str, Any]]) -> list[TurnAlignment]:
    """Return each robot turn's alignment record, in turn order."""
    turns = list(result.get("turns", ()))
    speaker_of = {t.get("turn"): t.get("speaker") for t in turns}
    said = {  # human turn -> (referent, properties the human said)
        t.get("turn"): (_referent(t), set(t.get("description") or ())) for t in turns if t.get("speaker") == "human"
    }
    entered: dict[tuple, str] = {}  # (domain, entity, property) in WM -> what put it there
    events = iter(trace)
    pending: Optional[Mapping[str, Any]] = next(events, None)
    used: dict[str, list[str]] = {}
    out = []
    for record in turns:
        index, time = record.get("turn"), record.get("time") or 0.0
        # Replay every event before this turn (decay ticks at its time come first).
        while pending is not None and _before(pending, index, time):
            _apply(pending, entered, speaker_of, said)
            pending = next(events, None)
        if record.get("speaker") == "human":
            referent = _referent(record)
            if referent is not None:
                mentioned = used.setdefault(referent, [])
                mentioned += [p for p in record.get("description") or () if p not in mentioned]
            continue
        target = record.get("target")
        description = list(record.get("description") or ())
        human = used.get(target, [])
        origins = {
            p: entered.get((record.get("domain"), target, p), "unknown")
            for p, source in zip(description, record.get("sources") or ())
            if source == "wm"
        }
        aligned = [p for p in description if p in human]
        wm_size = sum(1 for key in entered if key[0] == record.get("domain"))
        out.append(TurnAlignment(index, target, description, list(human), aligned, origins, wm_size))
    return out


def _before(event: Mapping[str, Any], index: Any, time: float) -> bool:
    turn = event.get("turn")
    if turn is not None:
        return index is None or turn < index
    return (event.get("time") or 0.0) <= time


def _apply(event: Mapping[str, Any], entered: dict, speaker_of: Mapping[Any, Any], said: Mapping[Any, tuple]) -> None:
    key = (event.get("domain"), event.get("entity"), event.get("property"))
    if event.get("op") == "forget":
        entered.pop(key, None)
        return
    if key in entered:
        return
    cause = event.get("cause")
    if cause == "speaker":
        cause = "robot-speech" if speaker_of.get(event.get("turn")) == "robot" else "human-speech"
    elif cause == "rr" and event.get("turn") in said:
        referent, words = said[event.get("turn")]
        if event.get("entity") == referent and event.get("property") in words:
            cause = "human-speech"
    entered[key] = cause


def summarise(result: Mapping[str, Any], trace: Sequence[Mapping[str, Any]]) -> AlignmentSummary:
    """Pool :func:`turn_alignment` over the game's robot turns."""
    turns = turn_alignment(result, trace)
    origins = Counter(o for t in turns for o in t.origins.values())
    return AlignmentSummary(
        robot_turns=len(turns),
        properties=sum(len(t.description) for t in turns),
        aligned=sum(len(t.aligned) for t in turns),
        from_wm=sum(len(t.origins) for t in turns),
        origins=dict(origins),
        turns=turns,
    )


def gain(summary: AlignmentSummary, baseline: AlignmentSummary) -> float:
    """Alignment gain over No-WM: this game's alignment minus the same game's under policy ``none``."""
    return summary.alignment - baseline.alignment


def explain(summary: AlignmentSummary, baseline: Optional[AlignmentSummary] = None) -> list[str]:
    """Return one plain sentence per figure of ``summary`` (and its gain, given the ``none`` baseline)."""
    sentences = [
        f"Alignment {summary.alignment:.0%}: of the robot's {summary.properties} properties, {summary.aligned} "
        f"had already been used by the human for the same referent earlier in the game."
    ]
    parts = [f"{summary.origins.get(o, 0)} by {ORIGIN_WORDS[o]}" for o in ORIGINS]
    sentences.append(
        f"From WM {summary.from_wm} of {summary.properties}: the robot took these from working memory, "
        f"put there {', '.join(parts)}."
    )
    if baseline is not None:
        sentences.append(
            f"Alignment gain {gain(summary, baseline) * 100:+.0f} points: the same game without working memory "
            f"(policy none) reaches {baseline.alignment:.0%}."
        )
    return sentences


#: Where the ``none`` baseline of an annotated result came from (the ``none_baseline`` key).
BASELINE_RUN = "this run"
BASELINE_COMPARED = "the none run of this comparison"
BASELINE_SIMULATOR = "the core simulator under policy none"


def annotate(
    result: Mapping[str, Any],
    trace: Sequence[Mapping[str, Any]],
    baseline: AlignmentSummary,
    baseline_source: str,
) -> dict:
    """Return ``result`` with its alignment figures added as extra keys (the input is not changed).

    Each robot turn gets ``aligned`` (its properties the human had used for that
    referent earlier) and ``wm_origins`` (property -> what had put it in WM, for
    those taken from WM); the result gets ``alignment``: the pooled figures of
    :meth:`AlignmentSummary.to_json`, ``none_alignment`` and ``gain_over_none``
    against ``baseline`` (the same game under policy ``none``) and
    ``none_baseline``, where that baseline came from.
    """
    summary = summarise(result, trace)
    by_turn = {t.turn: t for t in summary.turns}
    turns = []
    for record in result.get("turns", ()):
        record = dict(record)
        mine = by_turn.get(record.get("turn")) if record.get("speaker") == "robot" else None
        if mine is not None:
            record["aligned"] = list(mine.aligned)
            record["wm_origins"] = dict(mine.origins)
        turns.append(record)
    block = summary.to_json()
    block.update(
        none_alignment=round(baseline.alignment, 4),
        gain_over_none=round(gain(summary, baseline), 4),
        none_baseline=baseline_source,
    )
    return {**result, "turns": turns, "alignment": block}
