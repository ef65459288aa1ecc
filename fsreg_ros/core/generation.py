"""Referring expression generation (REG): SD-PIA, DIST-PIA and two baselines.

SPEC section 4.  A property *rules out* a distractor iff it holds for the target
and not for the distractor.

* :func:`sd_pia` - the paper's forgetting-sensitive REG (SD-PIA).  Phase 1 walks
  the target's WM queue (LRU to MRU by default), Phase 2 the domain's preference
  order; LTM is only consulted as far as needed.  When a property that holds for
  the target is considered, it is encoded for every remaining distractor it also
  holds for (rule 3), selected or not.  The description is encoded for the target
  at the end (rule 1).
* :func:`dist_pia` - Phase 2 only: Dale & Reiter's (1995) Incremental Algorithm
  over distributed consultants with certainty thresholds (the paper's "No WM").
* :func:`full_brevity` and :func:`greedy` - classic baselines for comparison.
  They ignore WM and encode only their final description.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations
from typing import Mapping, Optional, Sequence

from .consultant import ConsultantPort, KnowledgeError

ALGORITHMS = ("sd-pia", "dist-pia", "full-brevity", "greedy")
#: The algorithm setting that lets the domain's memory policy choose (see :func:`algorithm_for`).
AUTO = "auto"
WM_ORDERS = ("lru-first", "mru-first", "preference")
#: Full Brevity is exponential in the number of useful properties; beyond this many
#: subsets it gives up with a clear error instead of running for hours.
FULL_BREVITY_MAX_SUBSETS = 5_000_000


def attribute_of(prop: str, attributes: Optional[Mapping[str, str]] = None) -> str:
    """Return the attribute a property belongs to.

    The domain's declared mapping wins; otherwise ``colour=red`` belongs to
    ``colour`` and a plain name such as ``glasses`` is its own attribute.
    """
    if attributes and prop in attributes:
        return attributes[prop]
    return prop.split("=", 1)[0]


def algorithm_for(retains: bool, algorithm: Optional[str] = None) -> str:
    """Return the algorithm to run: the one named, else SD-PIA, or DIST-PIA when WM retains nothing.

    Policy ``none`` keeps no WM, so SD-PIA's Phase 1 has nothing to walk and the paper's
    "No WM" condition is DIST-PIA; ``None``, ``""`` and ``"auto"`` all mean "choose".
    """
    if algorithm and algorithm != AUTO:
        return algorithm
    return "sd-pia" if retains else "dist-pia"


class GenerationError(ValueError):
    """REG cannot run: unknown target, bad context set, bad option."""


@dataclass
class Expression:
    """A generated referring expression (the ``/reg/expression`` fields)."""

    target: str
    domain: str
    algorithm: str
    description: list[str] = field(default_factory=list)
    sources: list[str] = field(default_factory=list)
    distinguishing: bool = True
    distractors_left: list[str] = field(default_factory=list)
    wm_before: list[str] = field(default_factory=list)
    text: str = ""

    def to_json(self) -> dict:
        return {
            "target": self.target,
            "domain": self.domain,
            "algorithm": self.algorithm,
            "description": list(self.description),
            "sources": list(self.sources),
            "distinguishing": self.distinguishing,
            "distractors_left": list(self.distractors_left),
            "wm_before": list(self.wm_before),
            "text": self.text,
        }


async def distractors_for(
    target: str, port: ConsultantPort, context: Optional[Sequence[str]] = None
) -> list[str]:
    """Every other entity of the target's domain, or of an explicit context set,
    in the domain's entity order."""
    entities = await port.entities()
    try:
        at = entities.index(target)  # entity names are unique
    except ValueError:
        raise GenerationError(f"domain '{port.domain}' has no entity '{target}'") from None
    if context is None:
        return entities[:at] + entities[at + 1 :]  # one C-level pass, not two Python ones
    unknown = [e for e in context if e not in entities]
    if unknown:
        raise GenerationError(f"context names unknown entities of domain '{port.domain}': {', '.join(unknown)}")
    wanted = set(context)
    return [e for e in entities if e in wanted and e != target]


def phase1_order(wm_before: Sequence[str], wm_order: str, preference: Sequence[str]) -> list[str]:
    """The order Phase 1 walks WM in (the paper's footnote lists the alternatives)."""
    if wm_order == "lru-first":
        return list(wm_before)
    if wm_order == "mru-first":
        return list(reversed(wm_before))
    if wm_order == "preference":
        rank = {p: i for i, p in enumerate(preference)}
        return sorted(wm_before, key=lambda p: rank.get(p, len(rank)))
    raise GenerationError(f"unknown wm_order '{wm_order}' (known: {', '.join(WM_ORDERS)})")


async def sd_pia(
    target: str,
    port: ConsultantPort,
    *,
    context: Optional[Sequence[str]] = None,
    wm_order: str = "lru-first",
    use_wm: bool = True,
    time: float = 0.0,
    turn: Optional[int] = None,
    attributes: Optional[Mapping[str, str]] = None,
) -> Expression:
    """SD-PIA (and, with ``use_wm=False``, DIST-PIA).  SPEC section 4.

    Once a value of an attribute is selected, other values of it are skipped
    (a description never holds two values of one attribute).
    """
    algorithm = "sd-pia" if use_wm else "dist-pia"
    remaining = await distractors_for(target, port, context)
    preference = await port.preference()
    wm_before = await port.wm(target)
    expression = Expression(target, port.domain, algorithm, wm_before=list(wm_before))
    considered: set[str] = set()
    selected_attributes: set[str] = set()

    async def consider(prop: str, source: str) -> None:
        nonlocal remaining
        considered.add(prop)
        if attribute_of(prop, attributes) in selected_attributes:
            return
        if not await port.holds(prop, [target]):
            return
        # Rule 3: p is encoded for each remaining distractor it cannot rule out.
        kept = await port.affirm(prop, remaining, "reg-distractor", time, turn)
        if len(kept) < len(remaining):
            expression.description.append(prop)
            expression.sources.append(source)
            selected_attributes.add(attribute_of(prop, attributes))
            remaining = kept

    if use_wm:
        for prop in phase1_order(wm_before, wm_order, preference):  # Phase 1: WM
            if not remaining:
                break
            await consider(prop, "wm")
    for prop in preference:  # Phase 2: LTM, lazily
        if not remaining:
            break
        if prop not in considered:
            await consider(prop, "ltm")
    return await _finish(expression, remaining, port, time, turn)


async def dist_pia(target: str, port: ConsultantPort, **options) -> Expression:
    """DIST-PIA: the Incremental Algorithm over distributed consultants (no WM)."""
    options.pop("wm_order", None)
    return await sd_pia(target, port, use_wm=False, **options)


async def _rule_out_sets(
    target: str, port: ConsultantPort, distractors: list[str]
) -> tuple[list[str], list[int]]:
    """For each property holding for the target (preference order), the bitmask of
    distractors it rules out (bit i = distractors[i]).  Queries only, no encoding."""
    index = {d: i for i, d in enumerate(distractors)}
    everyone = (1 << len(distractors)) - 1
    props, masks = [], []
    for prop in await port.preference():
        held = await port.holds(prop, [target] + distractors)
        if not held or held[0] != target:
            continue
        keep = 0
        for d in held[1:]:
            keep |= 1 << index[d]
        props.append(prop)
        masks.append(everyone & ~keep)
    return props, masks


async def _baseline_view(
    target: str, port: ConsultantPort, context: Optional[Sequence[str]]
) -> tuple[list[str], list[str], list[str], list[int]]:
    """What a baseline works from: the distractors, Q[target] (reported only, SPEC
    section 6; baselines never use WM) and each property's rule-out bitmask."""
    distractors = await distractors_for(target, port, context)
    wm_before = await port.wm(target)
    props, masks = await _rule_out_sets(target, port, distractors)
    return distractors, wm_before, props, masks


async def full_brevity(
    target: str,
    port: ConsultantPort,
    *,
    context: Optional[Sequence[str]] = None,
    time: float = 0.0,
    turn: Optional[int] = None,
    attributes: Optional[Mapping[str, str]] = None,
    **_ignored,
) -> Expression:
    """Full Brevity: a shortest set ruling out every distractor that can be ruled out.

    Among equally short sets (never two values of one attribute), the one whose
    sorted preference ranks are lexicographically smallest; output in preference order.
    """
    distractors, wm_before, props, masks = await _baseline_view(target, port, context)
    useful = [(p, m) for p, m in zip(props, masks) if m]
    goal = 0
    for _, mask in useful:
        goal |= mask
    chosen: tuple = ()
    best_cover = 0  # when one value per attribute cannot reach the goal: the widest cover
    tried = 0
    if goal:
        for size in range(1, len(useful) + 1):
            found = None
            for combo in combinations(useful, size):  # lexicographic in preference rank
                tried += 1
                if tried > FULL_BREVITY_MAX_SUBSETS:
                    raise GenerationError(
                        f"full-brevity gave up after {FULL_BREVITY_MAX_SUBSETS} subsets for '{target}'"
                    )
                if len({attribute_of(p, attributes) for p, _ in combo}) < size:
                    continue
                covered = 0
                for _, mask in combo:
                    covered |= mask
                if covered.bit_count() > best_cover.bit_count():
                    chosen, best_cover = combo, covered
                if covered == goal:
                    found = combo
                    break
            if found is not None:
                chosen = found
                break
    expression = Expression(target, port.domain, "full-brevity", wm_before=list(wm_before))
    expression.description = [p for p, _ in chosen]
    expression.sources = ["ltm"] * len(chosen)
    left = [d for i, d in enumerate(distractors) if not best_cover >> i & 1]
    return await _finish(expression, left, port, time, turn)


async def greedy(
    target: str,
    port: ConsultantPort,
    *,
    context: Optional[Sequence[str]] = None,
    time: float = 0.0,
    turn: Optional[int] = None,
    attributes: Optional[Mapping[str, str]] = None,
    **_ignored,
) -> Expression:
    """Greedy: repeatedly select the property ruling out most remaining distractors.

    Ties go to the more preferred; attributes already used are skipped; it stops
    when no property rules out any remaining distractor.
    """
    distractors, wm_before, props, masks = await _baseline_view(target, port, context)
    remaining = (1 << len(distractors)) - 1
    expression = Expression(target, port.domain, "greedy", wm_before=list(wm_before))
    used: set[str] = set()
    while remaining:
        best, best_count = -1, 0
        for i, mask in enumerate(masks):
            if attribute_of(props[i], attributes) in used:
                continue
            count = (mask & remaining).bit_count()
            if count > best_count:
                best, best_count = i, count
        if best < 0:
            break
        expression.description.append(props[best])
        expression.sources.append("ltm")
        used.add(attribute_of(props[best], attributes))
        remaining &= ~masks[best]
    left = [d for i, d in enumerate(distractors) if remaining >> i & 1]
    return await _finish(expression, left, port, time, turn)


async def _finish(
    expression: Expression, left: list[str], port: ConsultantPort, time: float, turn: Optional[int]
) -> Expression:
    expression.distractors_left = list(left)
    expression.distinguishing = not left
    if expression.description:  # rule 1: the robot's own description
        await port.encode(expression.target, expression.description, "speaker", time, turn)
    return expression


async def generate(
    target: str,
    port: ConsultantPort,
    algorithm: str = "sd-pia",
    *,
    context: Optional[Sequence[str]] = None,
    wm_order: str = "lru-first",
    time: float = 0.0,
    turn: Optional[int] = None,
    attributes: Optional[Mapping[str, str]] = None,
) -> Expression:
    """Run the named REG algorithm for ``target`` in ``port``'s domain."""
    if wm_order not in WM_ORDERS:
        raise GenerationError(f"unknown wm_order '{wm_order}' (known: {', '.join(WM_ORDERS)})")
    options = dict(context=context, time=time, turn=turn, attributes=attributes)
    try:
        if algorithm == "sd-pia":
            return await sd_pia(target, port, wm_order=wm_order, **options)
        if algorithm == "dist-pia":
            return await dist_pia(target, port, **options)
        if algorithm == "full-brevity":
            return await full_brevity(target, port, **options)
        if algorithm == "greedy":
            return await greedy(target, port, **options)
    except KnowledgeError as err:
        raise GenerationError(str(err)) from err
    raise GenerationError(f"unknown algorithm '{algorithm}' (known: {', '.join(ALGORITHMS)})")
