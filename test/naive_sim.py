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

Only text turns borrow from the project: the lexicon's parser turns their text into
properties.  :func:`simulate_naive` returns the turns as the simulator's records, with
the keys both compute (no realised text).
"""

from __future__ import annotations

from typing import Any, Optional

import yaml
from naive_wm import NaiveClock, NaiveWM

DEFAULT_THRESHOLD = 0.5


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
        self.wm = NaiveWM(rules, memory.get("capacity"), memory.get("global_capacity"), record=False)
        self.clock = NaiveClock(memory["decay_period"]) if "decay" in rules else None

    def holds(self, entity: str, prop: str) -> bool:
        return self.facts[entity].get(prop, 0.0) >= self.threshold


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
        if "text" in turn:
            known = {p for d in self.domains.values() for p in d.preference}
            description = list(self.get_lexicon().parse(turn["text"], known).properties)
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
        return {
            "turn": index,
            "speaker": "human",
            "description": description,
            "status": status,
            "resolved": candidates[0] if status == "resolved" else None,
            "candidates": candidates,
            "domain": name,
        }

    # ------------------------------------------------------------- docs/semantics.md §4
    def describe(self, index: int, turn: dict) -> dict:
        target = turn["target"]
        domain = next(d for d in self.domains.values() if target in d.facts)
        if turn.get("context") is None:
            remaining = [e for e in domain.entities if e != target]
        else:
            remaining = [e for e in domain.entities if e in turn["context"] and e != target]
        wm_before = domain.wm.queue(target)
        algorithm = self.algorithm or ("dist-pia" if domain.policy.strip() == "none" else "sd-pia")
        order: list[tuple[str, str]] = []
        if algorithm == "sd-pia":
            order += [(p, "wm") for p in self.phase1(wm_before, domain.preference)]
        order += [(p, "ltm") for p in domain.preference]
        description, sources, considered = [], [], []
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
                remaining = kept
        if description:
            domain.wm.encode(target, description, "speaker", turn["time"], index)  # rule 1
        return {
            "turn": index,
            "speaker": "robot",
            "target": target,
            "wm_before": wm_before,
            "description": description,
            "sources": sources,
            "distinguishing": not remaining,
            "distractors_left": remaining,
            "domain": domain.name,
            "algorithm": algorithm,
        }

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
