"""Referring expression generation (REG): SD-PIA, DIST-PIA and two baselines.

docs/semantics.md section 4.  A property *rules out* a distractor iff it holds for the target
and not for the distractor.

* :func:`sd_pia` - the paper's forgetting-sensitive REG (SD-PIA, Algorithm 4).  Phase 1 walks
  the target's WM queue (LRU to MRU by default), Phase 2 the domain's preference
  order; LTM is only consulted as far as needed.  Both phases are read here; the
  walk's rules (take, skip a taken attribute, stop when no distractor is left) are
  :class:`~fsreg_ros.core.algorithms.port.Walk`, which the consultant runs in one call.  When a property that holds for
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

from ..memory import Strength, attribute_of
from .port import ConsultantPort, KnowledgeError, Reference, View, WalkStep

ALGORITHMS = ("sd-pia", "dist-pia", "full-brevity", "greedy")
#: The algorithm setting that lets the domain's memory policy choose (see :func:`algorithm_for`).
AUTO = "auto"
WM_ORDERS = ("lru-first", "mru-first", "preference", "strength")
#: Full Brevity is exponential in the number of useful properties; beyond this many
#: subsets it gives up with a clear error instead of running for hours.
FULL_BREVITY_MAX_SUBSETS = 5_000_000


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

    def __init__(self, message: str = "", kind: Optional[str] = None) -> None:
        super().__init__(message)
        #: The ``kind`` an error reply on a topic carries (``unknown-entity``, ...); None: the class name.
        self.kind = kind


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
    #: Parallel to ``description``: for a property taken from WM, the raw origin of its entry in
    #: Q[target] (``{"cause", "turn"}`` of the encoding that made it enter, as the buffer kept it);
    #: None for the others.  :mod:`fsreg_ros.core.algorithms.alignment` names it from the turns' records.
    origins: list[Optional[dict]] = field(default_factory=list)
    #: Parallel to ``description``: for a property taken from WM, how strongly its entry was held when
    #: the view opened (``Strength.to_json``: ``{"age", "episodes", "activation"}``); None for the others.
    strengths: list[Optional[dict]] = field(default_factory=list)

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
            "origins": [None if o is None else dict(o) for o in self.origins],
            "strengths": [None if s is None else dict(s) for s in self.strengths],
        }


def phase1_order(wm_before: Sequence[str], wm_order: str, preference: Sequence[str],
                 strength: Sequence[Strength] = ()) -> list[str]:
    """Return the order Phase 1 walks WM in (the paper's footnote lists the alternatives).

    ``strength`` (parallel to ``wm_before``) serves ``strength``: strongest first, that is
    the fewest episodes old first (:class:`~fsreg_ros.core.memory.Strength` ``age``), then
    the most episodes used in, then LRU order.
    """
    if wm_order == "strength":
        if len(strength) != len(wm_before):
            raise GenerationError("wm_order 'strength' needs the strength of each WM entry, which the consultant "
                                  f"did not report ({len(strength)} for {len(wm_before)} entries)")
        ranked = sorted(range(len(wm_before)), key=lambda i: (strength[i].age, -strength[i].episodes, i))
        return [wm_before[i] for i in ranked]
    if wm_order == "lru-first":
        return list(wm_before)
    if wm_order == "mru-first":
        return list(reversed(wm_before))
    if wm_order == "preference":
        rank = {p: i for i, p in enumerate(preference)}
        return sorted(wm_before, key=lambda p: rank.get(p, len(rank)))
    raise GenerationError(f"unknown wm_order '{wm_order}' (known: {', '.join(WM_ORDERS)})")


async def open_referring(port: ConsultantPort, target: str, context: Optional[Sequence[str]], time: float,
                         turn: Optional[int], reference: Optional[str] = None) -> View:
    """Open REG's view of ``target`` as an act of referring to it (``reference``: the act's id, for retries).

    The target's next reference episode begins at the open, before the view reads
    Q[target] (docs/semantics.md section 2): during a description WM holds what rule
    ``episodes`` keeps for that episode, as in the corpus replay the rule was fitted on.
    """
    return await port.open(target, context, refer=Reference(time, turn, reference))


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
    view: Optional[View] = None,
) -> Expression:
    """SD-PIA, the paper's Algorithm 4 (and, with ``use_wm=False``, DIST-PIA).  docs/semantics.md section 4.

    The consultant keeps the distractor set (``view``, opened here unless given).
    Phase 1 (Q[target] in ``wm_order``: the properties recently encoded for the target)
    and Phase 2 (the preference order, minus what Phase 1 considered: LTM, asked only
    as far as needed) are one :class:`~fsreg_ros.core.algorithms.port.Walk` over the
    properties that hold for the target (the others are skipped, nothing asked): each
    considered property narrows the distractors, encoding it for every remaining
    distractor it holds for (rule 3), and is selected when it rules one out; once a
    value of an attribute is selected, other values of it are skipped (a description
    never holds two values of one attribute); the walk ends when no distractor is
    left.  The port runs the walk in one call (:meth:`~fsreg_ros.core.algorithms.port.ConsultantPort.walk`);
    the description is encoded for the target when the view closes (rule 1, :func:`_finish`).
    """
    algorithm = "sd-pia" if use_wm else "dist-pia"
    if view is None:
        view = await open_referring(port, target, context, time, turn)
    preference = await port.preference()
    expression = Expression(target, port.domain, algorithm, wm_before=list(view.queue))
    entered = {p: {"cause": cause, "turn": turn} for p, (cause, turn) in zip(view.queue, view.origins)}
    held = {p: s.to_json() for p, s in zip(view.queue, view.strength)}
    phase1 = phase1_order(view.queue, wm_order, preference, view.strength) if use_wm else []  # Phase 1: WM
    walked_wm = set(phase1)
    phase2 = [p for p in preference if p not in walked_wm]  # Phase 2: LTM, in preference order
    candidates = [(p, "wm") for p in phase1] + [(p, "ltm") for p in phase2]
    if view.holding is not None:  # p does not hold for t (as read when the view opened): skipped, nothing asked
        candidates = [(p, source) for p, source in candidates if p in view.holding]
    steps = [WalkStep(p, attribute_of(p, attributes, own=True)) for p, _ in candidates]
    if steps and view.size:
        walked = await port.walk(view, steps, "reg-distractor", time, turn)
        for i in walked.taken:
            prop, source = candidates[i]
            expression.description.append(prop)
            expression.sources.append(source)
            expression.origins.append(entered.get(prop) if source == "wm" else None)
            expression.strengths.append(held.get(prop) if source == "wm" else None)
    return await _finish(expression, view, port, time, turn)


async def dist_pia(target: str, port: ConsultantPort, **options) -> Expression:
    """DIST-PIA: the Incremental Algorithm over distributed consultants (no WM)."""
    options.pop("wm_order", None)
    return await sd_pia(target, port, use_wm=False, **options)


async def _baseline_view(
    target: str, port: ConsultantPort, context: Optional[Sequence[str]], view: Optional[View], time: float,
    turn: Optional[int]
) -> tuple[View, list[str], list[int]]:
    """Return what a baseline works from: the open view and each property's rule-out bitmask.

    The view's ``queue`` is Q[target], reported only (docs/semantics.md section 6; baselines never
    use WM); for each property holding for the target *that the port's preference order
    names*, in that order, the bitmask of distractors it rules out (bit i = the i-th
    distractor in entity order).  A property the order does not name is never
    considered, and ties are broken by the order (the port may serve a per-call order,
    :class:`~fsreg_ros.core.simulation.describe.ViewPort`).  Queries only, no encoding.
    """
    if view is None:
        view = await open_referring(port, target, context, time, turn)
    preference = await port.preference()
    props, masks = await port.rule_out(view)
    rank = {p: i for i, p in enumerate(preference)}
    named = sorted((rank[p], p, m) for p, m in zip(props, masks) if p in rank)
    return view, [p for _, p, _ in named], [m for _, _, m in named]


async def full_brevity(
    target: str,
    port: ConsultantPort,
    *,
    context: Optional[Sequence[str]] = None,
    time: float = 0.0,
    turn: Optional[int] = None,
    attributes: Optional[Mapping[str, str]] = None,
    view: Optional[View] = None,
    **_ignored,
) -> Expression:
    """Full Brevity: a shortest set ruling out every distractor that can be ruled out.

    Among equally short sets (never two values of one attribute), the one whose
    sorted preference ranks are lexicographically smallest; output in preference order.
    """
    view, props, masks = await _baseline_view(target, port, context, view, time, turn)
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
                if len({attribute_of(p, attributes, own=True) for p, _ in combo}) < size:
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
    expression = Expression(target, port.domain, "full-brevity", wm_before=list(view.queue))
    expression.description = [p for p, _ in chosen]
    expression.sources = ["ltm"] * len(chosen)
    expression.origins = [None] * len(chosen)
    expression.strengths = [None] * len(chosen)
    return await _finish(expression, view, port, time, turn, ruled_out=best_cover)


async def greedy(
    target: str,
    port: ConsultantPort,
    *,
    context: Optional[Sequence[str]] = None,
    time: float = 0.0,
    turn: Optional[int] = None,
    attributes: Optional[Mapping[str, str]] = None,
    view: Optional[View] = None,
    **_ignored,
) -> Expression:
    """Greedy: repeatedly select the property ruling out most remaining distractors.

    Ties go to the more preferred; attributes already used are skipped; it stops
    when no property rules out any remaining distractor.
    """
    view, props, masks = await _baseline_view(target, port, context, view, time, turn)
    everyone = (1 << view.size) - 1
    remaining = everyone
    expression = Expression(target, port.domain, "greedy", wm_before=list(view.queue))
    used: set[str] = set()
    while remaining:
        best, best_count = -1, 0
        for i, mask in enumerate(masks):
            if attribute_of(props[i], attributes, own=True) in used:
                continue
            count = (mask & remaining).bit_count()
            if count > best_count:
                best, best_count = i, count
        if best < 0:
            break
        expression.description.append(props[best])
        expression.sources.append("ltm")
        expression.origins.append(None)
        expression.strengths.append(None)
        used.add(attribute_of(props[best], attributes, own=True))
        remaining &= ~masks[best]
    return await _finish(expression, view, port, time, turn, ruled_out=everyone & ~remaining)


async def _finish(
    expression: Expression,
    view: View,
    port: ConsultantPort,
    time: float,
    turn: Optional[int],
    ruled_out: int = 0,
) -> Expression:
    """Close the view, encoding the description for the target (rule 1); fill in what is left.

    The view's members are the distractors left, except those in ``ruled_out`` (the
    baselines never narrow the view: bit i = the i-th member).
    """
    members = await port.close(view, expression.description, time, turn)
    left = [d for i, d in enumerate(members) if not ruled_out >> i & 1] if ruled_out else list(members)
    expression.distractors_left = left
    expression.distinguishing = not left
    return expression


async def generate(
    target: str,
    port: ConsultantPort,
    algorithm: Optional[str] = "sd-pia",
    *,
    context: Optional[Sequence[str]] = None,
    wm_order: str = "lru-first",
    time: float = 0.0,
    turn: Optional[int] = None,
    attributes: Optional[Mapping[str, str]] = None,
    reference: Optional[str] = None,
) -> Expression:
    """Run the named REG algorithm for ``target`` in ``port``'s domain.

    ``algorithm`` None or ``auto`` chooses by the domain's memory policy, as read
    when the distractor set is opened (:func:`algorithm_for`).  The open begins the
    target's reference episode (:func:`open_referring`; ``reference`` names the act, so a
    retried request with the same id begins no second one).
    """
    if wm_order not in WM_ORDERS:
        raise GenerationError(f"unknown wm_order '{wm_order}' (known: {', '.join(WM_ORDERS)})")
    if algorithm and algorithm != AUTO and algorithm not in ALGORITHMS:
        raise GenerationError(f"unknown algorithm '{algorithm}' (known: {', '.join(ALGORITHMS)})")
    try:
        view = await open_referring(port, target, context, time, turn, reference)
        options = dict(context=context, time=time, turn=turn, attributes=attributes, view=view)
        algorithm = algorithm_for(view.retains, algorithm)
        if algorithm == "sd-pia":
            return await sd_pia(target, port, wm_order=wm_order, **options)
        if algorithm == "dist-pia":
            return await dist_pia(target, port, **options)
        if algorithm == "full-brevity":
            return await full_brevity(target, port, **options)
        return await greedy(target, port, **options)
    except KnowledgeError as err:
        raise GenerationError(str(err), kind=err.kind) from err
