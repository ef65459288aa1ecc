"""The TUNA corpus (singular trials): load, describe each target, score against the humans.

Each trial file holds a DOMAIN of seven ENTITYs (one target) with ATTRIBUTEs and
the ATTRIBUTE-SET the participant used (the gold set).  A trial becomes a
knowledge base (:func:`fsreg_ros.core.simulation.describe.knowledge_base`) whose properties
are ``attribute=value``; the algorithm describes the target with ``type`` forced
(the head noun, as TUNA evaluations do) and the description is scored with Dice,
MASI and accuracy (:mod:`fsreg_ros.research.scores`).

Scoring choices (docs/research.md explains them and their effect):

* values are stripped (``"old "`` -> ``old``); gold pairs are compared as given,
  so gold values no algorithm can produce (``type=other``, ``other=other``,
  ``x-dimension=unknown``) count against every algorithm alike;
* in ``-LOC`` trials ``x-dimension`` and ``y-dimension`` are not in the
  knowledge base (participants were told not to use location);
* boolean attributes are properties only when true (``hasBeard=1``): "the man
  without glasses" is not generated, as in the TUNA-era Incremental Algorithm runs.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Mapping, Optional, Sequence

from ..core.consultant.consultant import Consultant
from ..core.simulation.describe import describe, knowledge_base
from ..core.memory import attribute_of
from ..core.io.input_file import MAX_CORPUS_BYTES, InputFileError, read_text
from .scores import dice, masi, mean

DOMAINS = ("furniture", "people")
CONDITIONS = ("-LOC", "+LOC")
LOCATION = ("x-dimension", "y-dimension")
HEAD = "type"
ALGORITHMS = ("dist-pia", "full-brevity", "greedy")


class TunaError(ValueError):
    """A corpus file or option is unusable; the message names which and why."""


@dataclass(frozen=True)
class Trial:
    """One singular TUNA trial: its entities (attribute -> value), target and gold set."""

    id: str
    domain: str
    condition: str
    target: str
    entities: Mapping[str, Mapping[str, str]]
    types: Mapping[str, str]
    gold: frozenset


@dataclass(frozen=True)
class TrialScore:
    """How one algorithm's description of one trial compares with the human's."""

    trial: str
    domain: str
    condition: str
    algorithm: str
    order: tuple
    description: tuple
    gold: tuple
    dice: float
    masi: float
    minimal: bool
    unique: bool


def _value(text: Optional[str]) -> str:
    return (text or "").strip()


def parse_trial(text: str, source: str) -> Trial:
    """Parse one trial's XML text; ``source`` names it in errors."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as err:
        raise TunaError(f"{source}: not well-formed XML ({err})") from None
    domain, condition = root.get("DOMAIN"), root.get("CONDITION")
    if root.tag != "TRIAL" or domain not in DOMAINS or condition not in CONDITIONS:
        raise TunaError(f"{source}: not a TUNA trial (TRIAL with DOMAIN furniture|people and CONDITION -LOC|+LOC)")
    entities: dict[str, dict[str, str]] = {}
    types: dict[str, str] = {}
    target = None
    for entity in root.iterfind("DOMAIN/ENTITY"):
        name = entity.get("ID")
        if not name or name in entities:
            raise TunaError(f"{source}: an ENTITY has no ID or a repeated one ({name!r})")
        facts = {_value(a.get("NAME")): _value(a.get("VALUE")) for a in entity.iterfind("ATTRIBUTE")}
        entities[name] = facts
        types.update({f"{k}={v}": a.get("TYPE", "literal") for k, v, a in _typed(entity)})
        if entity.get("TYPE") == "target":
            if target is not None:
                raise TunaError(f"{source}: more than one target ENTITY")
            target = name
    if target is None:
        raise TunaError(f"{source}: no ENTITY has TYPE=\"target\"")
    gold = frozenset(
        f"{_value(a.get('NAME'))}={_value(a.get('VALUE'))}" for a in root.iterfind("ATTRIBUTE-SET/ATTRIBUTE")
    )
    return Trial(root.get("ID") or source, domain, condition, target, entities, types, gold)


def _typed(entity: ET.Element) -> Iterable[tuple[str, str, ET.Element]]:
    for a in entity.iterfind("ATTRIBUTE"):
        yield _value(a.get("NAME")), _value(a.get("VALUE")), a


def load_trials(path: Path) -> list[Trial]:
    """Load every ``*.xml`` trial under ``path`` (a directory or one file), sorted by ID."""
    path = Path(path)
    if not path.exists():
        raise TunaError(f"{path}: no such file or directory")
    files = [path] if path.is_file() else sorted(path.rglob("*.xml"))
    if not files:
        raise TunaError(f"{path}: no TUNA trial files (*.xml) found")
    trials = []
    for file in files:
        try:
            text = read_text(file, MAX_CORPUS_BYTES)
        except InputFileError as err:
            raise TunaError(f"{file}: cannot read ({err.message})") from None
        trials.append(parse_trial(text, str(file)))
    return sorted(trials, key=lambda t: t.id)


def trial_entities(trial: Trial) -> dict[str, list[str]]:
    """Each entity's properties as the algorithms see them (see the module's scoring choices)."""
    out = {}
    for name, facts in trial.entities.items():
        props = []
        for attribute, value in facts.items():
            if trial.condition == "-LOC" and attribute in LOCATION:
                continue
            prop = f"{attribute}={value}"
            if trial.types.get(prop) == "boolean" and value != "1":
                continue
            props.append(prop)
        out[name] = props
    return out


def trial_kb(trial: Trial) -> Consultant:
    """Return the trial's knowledge base (one consultant, entities in file order)."""
    return knowledge_base(trial.domain, trial_entities(trial))


def score_trial(trial: Trial, kb: Consultant, algorithm: str, order: Sequence[str]) -> TrialScore:
    """Describe the trial's target (``type`` forced, WM untouched) and score it against the gold set."""
    expression = describe(trial.target, kb, algorithm, preference=order, forced=(HEAD,))
    shortest = describe(trial.target, kb, "full-brevity", preference=order, forced=(HEAD,))
    got = expression.description
    return TrialScore(
        trial.id,
        trial.domain,
        trial.condition,
        algorithm,
        tuple(order),
        tuple(got),
        tuple(sorted(trial.gold)),
        dice(got, trial.gold),
        masi(got, trial.gold),
        expression.distinguishing and len(got) <= len(shortest.description),
        expression.distinguishing,
    )


def learn_order(trials: Sequence[Trial]) -> list[str]:
    """Return ``type`` then every other attribute by how often the humans used it (ties by name)."""
    usable: set[str] = set()
    used: Counter = Counter()
    for trial in trials:
        for props in trial_entities(trial).values():
            usable.update(attribute_of(p, own=True) for p in props)
        used.update({attribute_of(p, own=True) for p in trial.gold})
    rest = sorted(usable - {HEAD}, key=lambda a: (-used[a], a))
    return [HEAD] + rest


def folds(trials: Sequence[Trial], k: int) -> list[tuple[list[Trial], list[Trial]]]:
    """Split trials (sorted by ID) into k (train, test) pairs: trial i is tested in fold i mod k."""
    if k < 2 or k > len(trials):
        raise TunaError(f"--folds must be between 2 and the number of trials ({len(trials)}), got {k}")
    out = []
    for f in range(k):
        test = [t for i, t in enumerate(trials) if i % k == f]
        train = [t for i, t in enumerate(trials) if i % k != f]
        out.append((train, test))
    return out


@dataclass
class Result:
    """The scores of one algorithm on one domain and condition."""

    domain: str
    condition: str
    algorithm: str
    order: list
    scores: list
    fold_orders: Optional[list] = None

    def to_json(self) -> dict:
        """Return the row: means over the trials, unrounded (a report rounds once, when it prints)."""
        out = {
            "domain": self.domain,
            "condition": self.condition,
            "algorithm": self.algorithm,
            "order": list(self.order),
            "n": len(self.scores),
            "dice": mean([s.dice for s in self.scores]),
            "masi": mean([s.masi for s in self.scores]),
            "accuracy": mean([s.dice == 1.0 for s in self.scores]),
            "minimality": mean([s.minimal for s in self.scores]),
            "uniqueness": mean([s.unique for s in self.scores]),
        }
        if self.fold_orders is not None:
            out["learned"] = "cross-validated"
            out["fold_orders"] = [list(o) for o in self.fold_orders]
        return out


def evaluate(
    trials: Sequence[Trial],
    orders: Mapping[str, Sequence[str]],
    algorithms: Sequence[str] = ALGORITHMS,
    k: int = 10,
) -> list[Result]:
    """Score every algorithm per domain and condition.

    A domain with a given order uses it; otherwise the order is learned from the
    human sets with k-fold cross-validation (held-out scores; ``order`` is then
    the one learned from all trials of the group, ``fold_orders`` the per-fold ones).
    """
    results = []
    kbs = {t.id: trial_kb(t) for t in trials}
    for domain in DOMAINS:
        for condition in CONDITIONS:
            group = [t for t in trials if t.domain == domain and t.condition == condition]
            if not group:
                continue
            for algorithm in algorithms:
                if domain in orders:
                    order = list(orders[domain])
                    scores = [score_trial(t, kbs[t.id], algorithm, order) for t in group]
                    results.append(Result(domain, condition, algorithm, order, scores))
                    continue
                if len(group) < 2:  # nothing to hold out: learn from the trial itself
                    order = learn_order(group)
                    only = score_trial(group[0], kbs[group[0].id], algorithm, order)
                    results.append(Result(domain, condition, algorithm, order, [only], [order]))
                    continue
                scores, fold_orders = [], []
                for train, test in folds(group, min(k, len(group))):
                    learned = learn_order(train)
                    fold_orders.append(learned)
                    scores += [score_trial(t, kbs[t.id], algorithm, learned) for t in test]
                scores.sort(key=lambda s: s.trial)
                results.append(Result(domain, condition, algorithm, learn_order(group), scores, fold_orders))
    return results
