"""A deliberately naive, eager reference simulator (tests and benchmark only).

It plays a scenario file as docs/semantics.md sections 2-4 say, as literally as possible, and
shares no algorithm code with :mod:`fsreg_ros.core`:

* the scenario is read with plain ``yaml`` (libyaml when present) and used as the
  dict it is: no validation (give it files the project's loader accepts);
* working memory is :class:`naive_wm.NaiveWM` per domain (lists, eager decay over
  every queue at every tick, displacement and the global limit after every event);
* reference resolution (docs/semantics.md section 3) and SD-PIA / DIST-PIA (docs/semantics.md section 4, with
  the rule-3 encodings for distractors) are written out as loops over entities;
* a property holds iff its certainty >= the domain's threshold, looked up in the
  entity's facts on every check.

Only words borrow from the project: the lexicon's parser turns text turns into
properties, and its realiser says the robot's descriptions.  :func:`simulate_naive`
returns the turns as the simulator's records (docs/semantics.md section 6, with the
raw WM origin of each property REG took from WM).

:func:`annotate_naive` adds what ``fsreg-sim --json`` prints beyond them, written out
from the definitions in README.md and docs/research.md section 3 (alignment per robot
turn, the pooled figures, the gains over the same game under policy ``none``), and
:func:`run_command` is that whole command: ``python test/support/naive_sim.py WORLD --json``
prints the same bytes as ``fsreg-sim WORLD --json`` (scripts/bench_sim.py times both).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any, Optional

import yaml
from naive_wm import NaiveClock, NaiveWM

DEFAULT_THRESHOLD = 0.5
#: Forgetting rules in the order a policy name lists them, and the parameters each reads.
RULE_ORDER = ("decay", "displacement", "global-capacity")
RULE_READS = {"decay": ("decay_period",), "displacement": ("capacity",), "global-capacity": ("global_capacity",)}
#: What had put a property in WM, as the alignment report names it.
ORIGIN_NAMES = ("human-speech", "rr", "reg-distractor", "robot-speech")
NONE_FROM_SIMULATOR = "the core simulator under policy none"
NONE_FROM_THIS_RUN = "this run"


def load_naive(path) -> dict:
    """Return the scenario document at ``path``, read by libyaml's loader if available."""
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    with open(path, encoding="utf-8") as handle:
        return yaml.load(handle, Loader=loader)


class NaiveDomain:
    """One domain: its LTM as written in the file, its preference order and its WM."""

    def __init__(self, name: str, block: dict, memory: dict) -> None:
        self.name = name
        self.preference: list[str] = list(block["preference"])
        self.threshold: float = block.get("threshold", DEFAULT_THRESHOLD)
        self.facts: dict[str, dict[str, float]] = {}
        for entity, facts in (block.get("entities") or {}).items():
            self.facts[entity] = {p: 1.0 for p in facts} if isinstance(facts, list) else dict(facts)
        self.entities: list[str] = list(self.facts)
        self.policy = memory.get("policy", "none")
        rules = [] if self.policy.strip() == "none" else [r.strip() for r in self.policy.split("+")]
        self.rules = rules
        self.memory = memory
        self.wm = NaiveWM(rules, memory.get("capacity"), memory.get("global_capacity"), record=False)
        self.clock = NaiveClock(memory["decay_period"]) if "decay" in rules else None

    def holds(self, entity: str, prop: str) -> bool:
        return self.facts[entity].get(prop, 0.0) >= self.threshold

    def effective(self) -> dict:
        """Return the domain's memory setting as the result's ``memory`` block reports it: what its rules read."""
        rules = [r for r in RULE_ORDER if r in self.rules]
        out: dict[str, Any] = {"policy": "+".join(rules) if rules else "none"}
        for rule in rules:
            for key in RULE_READS[rule]:
                out[key] = float(self.memory[key]) if key == "decay_period" else self.memory[key]
        return out


def memory_settings(document: dict, domain: str, overrides: Optional[dict]) -> dict:
    """Top-level ``memory:``, then the domain's own, then ``overrides``, key by key."""
    merged: dict[str, Any] = {}
    for layer in (document.get("memory"), document["domains"][domain].get("memory"), overrides):
        merged.update({k: v for k, v in (layer or {}).items() if v is not None})
    return merged


class NaiveSimulator:
    """Plays a scenario document turn by turn (docs/semantics.md sections 2-4 and 6)."""

    def __init__(
        self,
        document: dict,
        memory: Optional[dict] = None,
        algorithm: Optional[str] = None,
        wm_order: str = "lru-first",
        lexicon=None,
    ) -> None:
        self.document = document
        self.domains = {
            name: NaiveDomain(name, block, memory_settings(document, name, memory))
            for name, block in document["domains"].items()
        }
        self.algorithm = algorithm
        self.wm_order = wm_order
        self.lexicon = lexicon

    def run(self) -> list[dict]:
        return [self.play(index, turn) for index, turn in enumerate(self.document.get("dialogue") or [])]

    def memory(self) -> dict:
        """Every domain's effective memory setting, by domain name."""
        return {name: self.domains[name].effective() for name in sorted(self.domains)}

    def play(self, index: int, turn: dict) -> dict:
        for domain in self.domains.values():  # every tick at or before T comes first
            if domain.clock is not None:
                for tick_time in domain.clock.due(turn["time"]):
                    domain.wm.tick(tick_time)
        if turn["speaker"] == "human":
            return self.hear(index, turn)
        return self.describe(index, turn)

    # ------------------------------------------------------------- docs/semantics.md §3
    def hear(self, index: int, turn: dict) -> dict:
        unknown: list[str] = []
        if "text" in turn:
            known = {p for d in self.domains.values() for p in d.preference}
            parsed = self.get_lexicon().parse(turn["text"], known)
            description, unknown = list(parsed.properties), list(parsed.unknown_words)
        else:
            description = list(turn["description"])
        name = turn.get("domain")
        if name is None:
            fitting = [d for d in self.domains.values() if all(p in d.preference for p in description)]
            assert len(fitting) == 1, f"turn {index}: domain not determined"
            name = fitting[0].name
        domain = self.domains[name]
        candidates = list(domain.entities)
        for prop in description:
            still = []
            for candidate in candidates:
                if domain.holds(candidate, prop):
                    domain.wm.encode(candidate, [prop], "rr", turn["time"], index)  # rule 2
                    still.append(candidate)
            candidates = still
        status = "resolved" if len(candidates) == 1 else "ambiguous" if candidates else "no-match"
        if status == "resolved":
            domain.wm.encode(candidates[0], description, "speaker", turn["time"], index)  # rule 1
        record = {
            "turn": index,
            "time": turn["time"],
            "speaker": "human",
            "description": description,
            "status": status,
            "resolved": candidates[0] if status == "resolved" else None,
            "candidates": candidates,
            "domain": name,
        }
        if "target" in turn:
            record["target"] = turn["target"]
        if "text" in turn:
            record["text"] = turn["text"]
            record["unknown_words"] = unknown
        return record

    # ------------------------------------------------------------- docs/semantics.md §4
    def describe(self, index: int, turn: dict) -> dict:
        target = turn["target"]
        domain = next(d for d in self.domains.values() if target in d.facts)
        if turn.get("context") is None:
            remaining = [e for e in domain.entities if e != target]
        else:
            remaining = [e for e in domain.entities if e in turn["context"] and e != target]
        wm_before = domain.wm.queue(target)
        entered = dict(zip(wm_before, domain.wm.origins_of(target)))  # as REG starts
        algorithm = self.algorithm or ("dist-pia" if domain.policy.strip() == "none" else "sd-pia")
        order: list[tuple[str, str]] = []
        if algorithm == "sd-pia":
            order += [(p, "wm") for p in self.phase1(wm_before, domain.preference)]
        order += [(p, "ltm") for p in domain.preference]
        description, sources, origins, considered = [], [], [], []
        for prop, source in order:
            if not remaining:
                break
            if prop in considered:
                continue
            considered.append(prop)
            if not domain.holds(target, prop):
                continue
            kept = []
            for distractor in remaining:
                if domain.holds(distractor, prop):
                    domain.wm.encode(distractor, [prop], "reg-distractor", turn["time"], index)  # rule 3
                    kept.append(distractor)
            if len(kept) < len(remaining):
                description.append(prop)
                sources.append(source)
                cause_turn = entered[prop] if source == "wm" else None
                origins.append(None if cause_turn is None else {"cause": cause_turn[0], "turn": cause_turn[1]})
                remaining = kept
        if description:
            domain.wm.encode(target, description, "speaker", turn["time"], index)  # rule 1
        record = {
            "turn": index,
            "time": turn["time"],
            "speaker": "robot",
            "target": target,
            "wm_before": wm_before,
            "description": description,
            "sources": sources,
            "distinguishing": not remaining,
            "distractors_left": remaining,
            "domain": domain.name,
            "algorithm": algorithm,
            "origins": origins,
            "text": self.get_lexicon().realise(description, domain.name),
        }
        if turn.get("context") is not None:
            record["context"] = list(turn["context"])
        return record

    def phase1(self, wm_before: list[str], preference: list[str]) -> list[str]:
        if self.wm_order == "mru-first":
            return list(reversed(wm_before))
        if self.wm_order == "preference":
            return [p for p in preference if p in wm_before]
        return list(wm_before)

    def get_lexicon(self):
        if self.lexicon is None:
            from fsreg_ros.core.lexicon import Lexicon

            self.lexicon = Lexicon.load()
        return self.lexicon


def simulate_naive(document: dict, **options) -> list[dict]:
    """Play ``document`` (a scenario file's dict) with the naive reference; return its turns."""
    return NaiveSimulator(document, **options).run()


def result_naive(document: dict, name: str, **options) -> dict:
    """Play ``document`` and return the whole result object: scenario name, memory settings, turns."""
    simulator = NaiveSimulator(document, **options)
    turns = simulator.run()
    return {"scenario": document.get("name") or name, "memory": simulator.memory(), "turns": turns}


# ------------------------------------------------------------------ alignment
def _dice(a: list, b: list) -> float:
    a, b = set(a), set(b)
    return 1.0 if not a and not b else 2 * len(a & b) / (len(a) + len(b))


def _mean(values: list) -> float:
    return sum(values) / len(values) if values else 0.0


def _round(value: Optional[float]) -> Optional[float]:
    return None if value is None else round(value, 4)


def robot_alignment(turns: list[dict]) -> dict[int, dict]:
    """Each robot turn's alignment figures, by turn index, from the records alone.

    For the referent R of a robot turn: every property the human had used for R in an
    earlier turn (R of a human turn: its ``target``, else what RR resolved), the human's
    most recent description of R, Dice and recall against it, and what had put each
    property taken from WM there (``human-speech``: the human said it, including RR
    affirming the human's own words for the referent of that turn; ``rr``: RR affirming
    it for another candidate; ``reg-distractor``; ``robot-speech``).
    """
    by_turn = {t["turn"]: t for t in turns}
    used: dict[str, list[str]] = {}
    last: dict[str, tuple[int, list[str]]] = {}
    out = {}
    for record in turns:
        if record["speaker"] == "human":
            referent = record.get("target") or record.get("resolved")
            if referent is not None and record["description"]:
                used.setdefault(referent, [])
                for prop in record["description"]:
                    if prop not in used[referent]:
                        used[referent].append(prop)
                last[referent] = (record["turn"], list(record["description"]))
            continue
        target, description = record["target"], record["description"]
        origins = {}
        for prop, source, raw in zip(description, record["sources"], record["origins"]):
            if source != "wm":
                continue
            then = by_turn.get(raw["turn"], {})
            name = raw["cause"]
            if name == "speaker":
                name = "robot-speech" if then.get("speaker") == "robot" else "human-speech"
            elif (name == "rr" and then.get("speaker") == "human"
                  and (then.get("target") or then.get("resolved")) == target and prop in then["description"]):
                name = "human-speech"
            origins[prop] = name
        human = used.get(target, [])
        last_turn, last_said = last.get(target, (None, None))
        out[record["turn"]] = {
            "description": description,
            "aligned": [p for p in description if p in human],
            "human_last": last_said,
            "human_last_turn": last_turn,
            "dice": None if last_said is None else _dice(description, last_said),
            "recall": None if not last_said else len(set(description) & set(last_said)) / len(set(last_said)),
            "wm_origins": origins,
        }
    return out


def pooled(figures: dict[int, dict]) -> dict:
    """Return the game's pooled alignment figures (the ``alignment`` block without the gains)."""
    rows = list(figures.values())
    said = sum(len(r["description"]) for r in rows)
    aligned = sum(len(r["aligned"]) for r in rows)
    described = [r for r in rows if r["human_last"] is not None]
    named = [name for r in rows for name in r["wm_origins"].values()]
    return {
        "robot_turns": len(rows),
        "properties": said,
        "aligned": aligned,
        "alignment": aligned / said if said else 0.0,
        "described_turns": len(described),
        "entrainment": _mean([r["dice"] for r in described]),
        "recall": _mean([r["recall"] for r in described]),
        "from_wm": len(named),
        "wm_origins": {name: named.count(name) for name in ORIGIN_NAMES},
    }


def annotate_naive(result: dict, baseline: dict, baseline_source: str) -> dict:
    """Return ``result`` with the alignment keys ``fsreg-sim`` adds, against ``baseline`` (the game under none)."""
    mine, theirs = robot_alignment(result["turns"]), robot_alignment(baseline["turns"])
    turns = []
    for record in result["turns"]:
        record = dict(record)
        if record["speaker"] == "robot":
            figures = mine[record["turn"]]
            record.update(aligned=figures["aligned"], human_last=figures["human_last"],
                          human_last_turn=figures["human_last_turn"], dice_last=_round(figures["dice"]),
                          recall_last=_round(figures["recall"]), wm_origins=figures["wm_origins"])
        turns.append(record)
    block, base = pooled(mine), pooled(theirs)
    paired = [(mine[t], theirs[t]) for t in mine if t in theirs]
    dice_pairs = [(a["dice"], b["dice"]) for a, b in paired if a["dice"] is not None and b["dice"] is not None]
    same_length = [(a, b) for a, b in paired if len(a["description"]) == len(b["description"])]
    block.update(
        alignment=round(block["alignment"], 4),
        entrainment=round(block["entrainment"], 4),
        recall=round(block["recall"], 4),
        none_alignment=round(base["alignment"], 4),
        gain_over_none=round(block["alignment"] - base["alignment"], 4),
        none_entrainment=round(base["entrainment"], 4),
        entrainment_gain=round(_mean([a - b for a, b in dice_pairs]), 4),
        paired_turns=len(dice_pairs),
        length_matched_gain=round(_mean([len(a["aligned"]) - len(b["aligned"]) for a, b in same_length]), 4),
        length_matched_turns=len(same_length),
        none_baseline=baseline_source,
    )
    return {**result, "turns": turns, "alignment": block}


def with_baseline(document: dict, result: dict, **options) -> dict:
    """Return ``result`` annotated against the same game under policy none (itself, if it was played so)."""
    if all(m["policy"] == "none" for m in result["memory"].values()):
        return annotate_naive(result, result, NONE_FROM_THIS_RUN)
    memory = {**(options.pop("memory", None) or {}), "policy": "none"}
    return annotate_naive(result, {"turns": simulate_naive(document, memory=memory, **options)}, NONE_FROM_SIMULATOR)


def run_command(path: str, lexicon=None) -> dict:
    """Compute what ``fsreg-sim PATH --json`` prints, naively: the game, the same game under none, alignment."""
    document = load_naive(path)
    if lexicon is None:
        from fsreg_ros.core.lexicon import Lexicon

        lexicon = Lexicon.load()
    return with_baseline(document, result_naive(document, Path(path).stem, lexicon=lexicon), lexicon=lexicon)


def dumps_naive(result: dict) -> str:
    """Return the result as ``fsreg-sim --json`` prints it."""
    return json.dumps(result, sort_keys=True, indent=2, ensure_ascii=False) + "\n"


def main(argv: Optional[list[str]] = None) -> int:
    """``python test/support/naive_sim.py SCENARIO.yaml --json``: what ``fsreg-sim SCENARIO.yaml --json`` prints."""
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 2 or args[1] != "--json":
        print("usage: naive_sim.py SCENARIO.yaml --json", file=sys.stderr)
        return 2
    sys.stdout.write(dumps_naive(run_command(args[0])))
    return 0


if __name__ == "__main__":
    sys.exit(main())
