"""Alignment, measured: how far the robot's descriptions reuse the human's words.

The paper argues that working memory makes the robot *align* (entrain) with its
partner (SD-PIA, Algorithm 4, prefers properties in WM, and the human's descriptions
are encoded there by rule 1).  This module measures it on a played game, from the
docs/semantics.md section 6 result records alone (no event trace):

* per robot description of referent R: **aligned**, the properties the human had
  used for R in an earlier turn (R is the human turn's ``target``, else what RR
  resolved); the **share** aligned (aligned / said); and against the human's *most
  recent* description of R (``human_last``): **recall** (the share of the human's
  words the robot repeated) and **Dice** (2 |robot & human| / (|robot| + |human|)).
* **entrainment** (the headline): the mean Dice with the human's last description of
  the referent, over the robot descriptions of referents the human had described.
  Unlike the share, it cannot be bought with length: a shorter description raises
  the share whenever it drops an unaligned property, and a longer one raises recall,
  but Dice falls with every unaligned property *and* every human word left out
  (docs/research.md, section 3).
* **origin**: for a property taken from WM (``sources`` = ``wm``), what had made it
  enter the target's queue.  REG reports the raw origin of each such property (the
  ``origins`` field: ``{"cause", "turn"}`` of the encoding that made it enter, kept by
  the WM buffer; a refresh while present keeps it), and :func:`origin_name` names it
  from the records: ``human-speech`` (cause ``speaker`` on a human turn),
  ``robot-speech`` (``speaker`` on a robot turn), ``rr`` (reference resolution
  affirming it for a candidate, rule 2) or ``reg-distractor`` (REG affirming it for a
  distractor, rule 3).  On a human turn RR affirms the human's words for every
  candidate before rule 1 encodes them for the referent, so an ``rr`` entry of a
  property the human said, for the entity the turn referred to, is ``human-speech``;
  ``rr`` is left for what RR affirmed of the other candidates.
* **gains** over No-WM: the same figures of the same game under policy ``none``,
  paired turn by turn (:func:`entrainment_gain`, :func:`length_matched`).

:func:`annotate` adds these figures to a result as extra keys (docs/semantics.md
section 6 allows them); ``fsreg-sim`` and ``fsreg-graph`` both print results
annotated by it.
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


def dice(a: Sequence[str], b: Sequence[str]) -> float:
    """Return the Dice coefficient of two property sets (1.0 for two empty sets)."""
    a, b = set(a), set(b)
    if not a and not b:
        return 1.0
    return 2 * len(a & b) / (len(a) + len(b))


@dataclass
class TurnAlignment:
    """One robot turn: what it said, what the human had said of the referent, where WM properties came from."""

    turn: int
    target: str
    description: list[str]
    human_used: list[str]  # every property the human had used for the target, first use first
    aligned: list[str]
    human_last: Optional[list[str]] = None  # the human's most recent description of the target (None: never)
    origins: dict[str, str] = field(default_factory=dict)
    human_last_turn: Optional[int] = None  # the turn of ``human_last``

    @property
    def share(self) -> float:
        """Share of the description the human had used for the referent (0.0 for an empty one)."""
        return len(self.aligned) / len(self.description) if self.description else 0.0

    @property
    def recall(self) -> Optional[float]:
        """Share of the human's last description of the referent that the robot repeated (None: none)."""
        if not self.human_last:
            return None
        return len(set(self.description) & set(self.human_last)) / len(set(self.human_last))

    @property
    def dice(self) -> Optional[float]:
        """Dice of the description with the human's last description of the referent (None: none)."""
        if self.human_last is None:
            return None
        return dice(self.description, self.human_last)


def _mean(values: Sequence[float]) -> float:
    return sum(values) / len(values) if values else 0.0


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
        """Share of the robot's properties the human had already used for that referent (pooled)."""
        return self.aligned / self.properties if self.properties else 0.0

    @property
    def wm_share(self) -> float:
        """Share of the robot's properties taken from WM."""
        return self.from_wm / self.properties if self.properties else 0.0

    @property
    def described(self) -> list[TurnAlignment]:
        """The robot turns whose referent the human had described earlier."""
        return [t for t in self.turns if t.human_last is not None]

    @property
    def entrainment(self) -> float:
        """Mean Dice with the human's last description of the referent (the headline; 0.0 if none)."""
        return _mean([t.dice for t in self.described])  # type: ignore[misc]

    @property
    def recall(self) -> float:
        """Mean recall of the human's last description of the referent."""
        return _mean([t.recall for t in self.described])  # type: ignore[misc]

    @property
    def mean_length(self) -> float:
        """Mean number of properties per robot description."""
        return self.properties / self.robot_turns if self.robot_turns else 0.0

    def to_json(self) -> dict:
        return {
            "robot_turns": self.robot_turns,
            "properties": self.properties,
            "aligned": self.aligned,
            "alignment": round(self.alignment, 4),
            "described_turns": len(self.described),
            "entrainment": round(self.entrainment, 4),
            "recall": round(self.recall, 4),
            "from_wm": self.from_wm,
            "wm_origins": {o: self.origins.get(o, 0) for o in ORIGINS},
        }


def _referent(record: Mapping[str, Any]) -> Optional[str]:
    return record.get("target") or record.get("resolved")


def origin_name(raw: Mapping[str, Any], prop: str, target: str, turns: Mapping[Any, Mapping[str, Any]]) -> str:
    """Name the raw origin ``{"cause", "turn"}`` of ``prop`` in Q[``target``] from the turns' records.

    ``turns`` maps a turn index to its record (speaker, referent, description).
    """
    cause, record = raw.get("cause"), turns.get(raw.get("turn"), {})
    if cause == "speaker":
        return "robot-speech" if record.get("speaker") == "robot" else "human-speech"
    if cause == "rr" and record.get("speaker") == "human":
        if _referent(record) == target and prop in (record.get("description") or ()):
            return "human-speech"
    return str(cause)


def turn_alignment(result: Mapping[str, Any]) -> list[TurnAlignment]:
    """Return each robot turn's alignment record, in turn order, from the result records alone."""
    records = list(result.get("turns", ()))
    by_turn = {r.get("turn"): r for r in records}
    used: dict[str, list[str]] = {}
    last: dict[str, tuple[Any, list[str]]] = {}  # referent -> (turn, what the human said) of the latest
    out = []
    for record in records:
        if record.get("speaker") == "human":
            referent = _referent(record)
            said = list(record.get("description") or ())
            if referent is not None and said:
                mentioned = used.setdefault(referent, [])
                mentioned += [p for p in said if p not in mentioned]
                last[referent] = (record.get("turn"), said)
            continue
        target = record.get("target")
        description = list(record.get("description") or ())
        raw = record.get("origins") or [None] * len(description)
        origins = {
            p: origin_name(o, p, target, by_turn) if o else "unknown"
            for p, source, o in zip(description, record.get("sources") or (), raw)
            if source == "wm"
        }
        human = used.get(target, [])
        aligned = [p for p in description if p in human]
        last_turn, last_said = last.get(target, (None, None))
        out.append(TurnAlignment(record.get("turn"), target, description, list(human), aligned,
                                 last_said, origins, last_turn))
    return out


def summarise(result: Mapping[str, Any]) -> AlignmentSummary:
    """Pool :func:`turn_alignment` over the game's robot turns."""
    turns = turn_alignment(result)
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
    """Share gain over No-WM: this game's pooled share minus the same game's under policy ``none``."""
    return summary.alignment - baseline.alignment


def _paired(summary: AlignmentSummary, baseline: AlignmentSummary) -> list[tuple[TurnAlignment, TurnAlignment]]:
    """Pair the robot turns of the same game under two policies by turn index."""
    theirs = {t.turn: t for t in baseline.turns}
    return [(t, theirs[t.turn]) for t in summary.turns if t.turn in theirs]


def entrainment_gain(summary: AlignmentSummary, baseline: AlignmentSummary) -> tuple[float, int]:
    """Return the mean Dice gain over No-WM, paired by turn, and how many turns it is over.

    Only turns whose referent the human had described in both runs count.
    """
    pairs = [(a.dice, b.dice) for a, b in _paired(summary, baseline) if a.dice is not None and b.dice is not None]
    return _mean([a - b for a, b in pairs]), len(pairs)  # type: ignore[operator]


def length_matched(summary: AlignmentSummary, baseline: AlignmentSummary) -> tuple[float, int]:
    """Return the mean gain in aligned properties over No-WM on turns where both descriptions are as long.

    A length-matched comparison: on those turns a gain cannot come from saying more
    or fewer words.  Returns (mean gain in aligned count, number of such turns).
    """
    pairs = [(a, b) for a, b in _paired(summary, baseline) if len(a.description) == len(b.description)]
    return _mean([len(a.aligned) - len(b.aligned) for a, b in pairs]), len(pairs)


def explain(summary: AlignmentSummary, baseline: Optional[AlignmentSummary] = None) -> list[str]:
    """Return one plain sentence per figure of ``summary`` (and its gains, given the ``none`` baseline)."""
    described = len(summary.described)
    sentences = [
        f"Entrainment {summary.entrainment:.2f}: the mean Dice of the robot's {described} descriptions of referents "
        f"the human had described with the human's most recent description of that referent.",
        f"Aligned {summary.aligned} of {summary.properties} properties ({summary.alignment:.0%}): those the human "
        f"had already used for the same referent earlier in the game.",
    ]
    parts = [f"{summary.origins.get(o, 0)} by {ORIGIN_WORDS[o]}" for o in ORIGINS]
    sentences.append(
        f"From WM {summary.from_wm} of {summary.properties}: the robot took these from working memory, "
        f"put there {', '.join(parts)}."
    )
    if baseline is not None:
        delta, n = entrainment_gain(summary, baseline)
        matched, m = length_matched(summary, baseline)
        sentences.append(
            f"Entrainment gain {delta:+.2f} over {n} paired turns: the same game without working memory "
            f"(policy none) reaches {baseline.entrainment:.2f}."
        )
        sentences.append(
            f"Length-matched: on the {m} turns where both descriptions are as long, WM changes the aligned count by "
            f"{matched:+.2f} properties per description."
        )
    return sentences


#: Where the ``none`` baseline of an annotated result came from (the ``none_baseline`` key).
BASELINE_RUN = "this run"
BASELINE_COMPARED = "the none run of this comparison"
BASELINE_SIMULATOR = "the core simulator under policy none"


def _round(value: Optional[float]) -> Optional[float]:
    return None if value is None else round(value, 4)


def annotate(result: Mapping[str, Any], baseline: AlignmentSummary, baseline_source: str) -> dict:
    """Return ``result`` with its alignment figures added as extra keys (the input is not changed).

    Each robot turn gets ``aligned`` (its properties the human had used for that
    referent earlier), ``human_last`` (the human's most recent description of it,
    or null) and ``human_last_turn`` (its turn), ``dice_last`` and ``recall_last`` (against that description, or null)
    and ``wm_origins`` (property -> what had put it in WM, for those taken from WM);
    the result gets ``alignment``: the pooled figures of
    :meth:`AlignmentSummary.to_json`, the baseline's (``none_alignment``,
    ``none_entrainment``), the gains over it (``gain_over_none`` in share,
    ``entrainment_gain`` paired by turn over ``paired_turns``, and
    ``length_matched_gain`` over ``length_matched_turns``) and ``none_baseline``,
    where that baseline came from (the same game under policy ``none``).
    """
    summary = summarise(result)
    by_turn = {t.turn: t for t in summary.turns}
    turns = []
    for record in result.get("turns", ()):
        record = dict(record)
        mine = by_turn.get(record.get("turn")) if record.get("speaker") == "robot" else None
        if mine is not None:
            record["aligned"] = list(mine.aligned)
            record["human_last"] = None if mine.human_last is None else list(mine.human_last)
            record["human_last_turn"] = mine.human_last_turn
            record["dice_last"] = _round(mine.dice)
            record["recall_last"] = _round(mine.recall)
            record["wm_origins"] = dict(mine.origins)
        turns.append(record)
    delta, paired = entrainment_gain(summary, baseline)
    matched, matched_turns = length_matched(summary, baseline)
    block = summary.to_json()
    block.update(
        none_alignment=round(baseline.alignment, 4),
        gain_over_none=round(gain(summary, baseline), 4),
        none_entrainment=round(baseline.entrainment, 4),
        entrainment_gain=round(delta, 4),
        paired_turns=paired,
        length_matched_gain=round(matched, 4),
        length_matched_turns=matched_turns,
        none_baseline=baseline_source,
    )
    return {**result, "turns": turns, "alignment": block}
