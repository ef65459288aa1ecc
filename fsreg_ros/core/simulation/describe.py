"""Generation as a library call: describe one target in one call (docs/semantics.md section 4).

:func:`describe` runs a REG algorithm (SD-PIA, DIST-PIA, Full Brevity, Greedy;
paper Algorithm 4 and its baselines) for a target in a knowledge base, with a
per-call preference order, forced attributes (a head noun such as TUNA's
``type``) and with or without touching working memory.  It composes rather than
changes the consultant: a :class:`ViewPort` wraps any :class:`ConsultantPort`,
serves the per-call preference order, hides the forced attributes from the
algorithm and, when read-only, drops every encoding.  So an order sweep reuses
one consultant per knowledge base.

Preference orders may name attributes (``colour``) as well as properties
(``colour=red``): :func:`expand_order` lists each attribute's values in the
knowledge base's own order.  Properties written ``attribute=value`` belong to
``attribute`` (:func:`fsreg_ros.core.memory.limits.attribute_of`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping, Optional, Sequence, Union

from ..consultant.consultant import Consultant, KnowledgeError
from ..consultant.local_port import LocalPort
from ..algorithms.port import ConsultantPort, Narrowed, Reference, Step, View, Walked, WalkStep, run_sync
from ..algorithms.generation import ALGORITHMS, Expression, GenerationError, generate
from ..memory import attribute_of

#: What :func:`knowledge_base` accepts per entity: properties, or attribute -> value.
Facts = Union[Sequence[str], Mapping[str, object]]


def entity_properties(facts: Facts) -> list[str]:
    """Return an entity's properties: a list as given, or ``attribute=value`` per pair."""
    if isinstance(facts, Mapping):
        return [f"{attribute}={value}" for attribute, value in facts.items()]
    if isinstance(facts, (list, tuple)):
        return [str(p) for p in facts]
    raise GenerationError(f"an entity's facts must be a list of properties or a mapping, got {type(facts).__name__}")


def knowledge_base(domain: str, entities: Mapping[str, Facts], preference: Sequence[str] = ()) -> Consultant:
    """Build a consultant whose entities hold exactly the given properties (certainty 1).

    ``preference`` (attributes or properties) orders the properties; the rest follow
    in order of first appearance.
    """
    properties: dict[str, None] = {}
    table = {}
    for entity, facts in entities.items():
        props = entity_properties(facts)
        table[entity] = {p: 1.0 for p in props}
        properties.update(dict.fromkeys(props))
    known = list(properties)
    order = expand_order(preference, known) if preference else []
    order += [p for p in known if p not in set(order)]
    return Consultant(domain, table, order)


def expand_order(
    order: Sequence[str], properties: Sequence[str], attributes: Optional[Mapping[str, str]] = None
) -> list[str]:
    """Return the properties in ``order``: a property stands for itself, an attribute for its values.

    Values of an attribute keep their order in ``properties``; entries naming
    nothing known are ignored, and properties the order does not name are left out
    (the Incremental Algorithm never considers them).
    """
    known = set(properties)
    by_attribute: dict[str, list[str]] = {}
    for prop in properties:
        by_attribute.setdefault(attribute_of(prop, attributes, own=True), []).append(prop)
    out: dict[str, None] = {}
    for entry in order:
        if entry in known:
            out[entry] = None
        else:
            out.update(dict.fromkeys(by_attribute.get(entry, ())))
    return list(out)


class ViewPort:
    """A :class:`ConsultantPort` seen through one call's options.

    It serves ``preference`` instead of the consultant's order, hides properties
    of the ``hidden`` attributes from the preference order and from WM, hands out
    ``opened`` (a view :func:`describe_async` has already narrowed by the forced
    head) instead of opening one, and forwards encodings only when ``writes`` is
    true.  Final (``speaker``) encodings are never forwarded: :func:`describe`
    encodes the whole description itself.
    """

    def __init__(
        self,
        port: ConsultantPort,
        preference: Sequence[str],
        *,
        writes: bool,
        opened: View,
        hidden: Sequence[str] = (),
        attributes: Optional[Mapping[str, str]] = None,
    ) -> None:
        self.port = port
        self.domain = port.domain
        self.writes = writes
        self._opened = opened
        self._hidden = set(hidden)
        self._attributes = attributes
        self._preference = [p for p in preference if not self._is_hidden(p)]

    def _is_hidden(self, prop: str) -> bool:
        return attribute_of(prop, self._attributes, own=True) in self._hidden

    async def preference(self) -> list[str]:
        return list(self._preference)

    async def open(
        self, target: Optional[str] = None, context: Optional[Sequence[str]] = None, first: Optional[Step] = None,
        refer: Optional[Reference] = None,
    ) -> View:
        view = self._opened  # opened by describe_async, without a reference: no episode begins
        shown = [(p, o) for p, o in zip(view.queue, view.origins) if not self._is_hidden(p)]
        view = View(view.handle, view.size, [p for p, _ in shown], view.retains, view.holding,
                    origins=[o for _, o in shown])
        if first is not None:
            view.first = await self.narrow(view, first.prop, first.cause, first.time, first.turn)
        return view

    async def narrow(self, view: View, prop: str, cause: Optional[str], time: float, turn: Optional[int]) -> Narrowed:
        return await self.port.narrow(view, prop, cause if self.writes else None, time, turn)

    async def walk(self, view: View, steps: Sequence[WalkStep], cause: Optional[str], time: float,
                   turn: Optional[int], size: Optional[int] = None) -> Walked:
        return await self.port.walk(view, steps, cause if self.writes else None, time, turn, size)

    async def rule_out(self, view: View) -> tuple[list[str], list[int]]:
        props, masks = await self.port.rule_out(view)
        shown = [(p, m) for p, m in zip(props, masks) if not self._is_hidden(p)]
        return [p for p, _ in shown], [m for _, m in shown]

    async def close(
        self, view: View, encode: Sequence[str] = (), time: float = 0.0, turn: Optional[int] = None
    ) -> list[str]:
        return await self.port.close(view)

    async def wm(self, entity: str) -> list[str]:
        return [p for p in await self.port.wm(entity) if not self._is_hidden(p)]

    async def encode(
        self, entity: str, properties: Sequence[str], cause: str, time: float, turn: Optional[int]
    ) -> None:
        return None


@dataclass
class Request:
    """One :func:`describe` call's options (defaults: DIST-PIA, read-only)."""

    algorithm: str = "dist-pia"
    preference: Optional[Sequence[str]] = None
    forced: Sequence[str] = ()
    writes: bool = False
    context: Optional[Sequence[str]] = None
    wm_order: str = "lru-first"
    attributes: Optional[Mapping[str, str]] = None
    time: float = 0.0
    turn: Optional[int] = None


async def describe_async(target: str, port: ConsultantPort, request: Request) -> Expression:
    """Describe ``target`` through ``port`` as ``request`` says (see :func:`describe`)."""
    if request.algorithm not in ALGORITHMS:
        raise GenerationError(f"unknown algorithm '{request.algorithm}' (known: {', '.join(ALGORITHMS)})")
    full = await port.preference()
    order = full if request.preference is None else expand_order(request.preference, full, request.attributes)
    cause = "reg-distractor" if request.writes else None
    try:
        opened = await port.open(target, request.context)
        size = opened.size
        head = []  # the target's values of the forced attributes, selected first
        for attribute in request.forced:
            for prop in full:  # the first value holding for the target narrows the distractors
                if attribute_of(prop, request.attributes, own=True) == attribute:
                    step = await port.narrow(opened, prop, cause, request.time, request.turn)
                    if step.target_holds:
                        head.append(prop)
                        size = step.size
                        break
    except KnowledgeError as err:
        raise GenerationError(str(err)) from err
    opened = replace(opened, size=size, first=None)
    view = ViewPort(port, order, writes=request.writes, opened=opened, hidden=request.forced,
                    attributes=request.attributes)
    expression = await generate(
        target,
        view,
        request.algorithm,
        context=request.context,
        wm_order=request.wm_order,
        time=request.time,
        turn=request.turn,
        attributes=request.attributes,
    )
    expression.description = head + expression.description
    expression.sources = ["forced"] * len(head) + expression.sources
    expression.origins = [None] * len(head) + expression.origins
    expression.strengths = [None] * len(head) + expression.strengths
    if request.writes and expression.description:  # rule 1: the robot's own description
        await port.encode(target, expression.description, "speaker", request.time, request.turn)
    return expression


def describe(
    target: str,
    kb: Union[Consultant, ConsultantPort],
    algorithm: str = "dist-pia",
    *,
    preference: Optional[Sequence[str]] = None,
    forced: Sequence[str] = (),
    writes: bool = False,
    context: Optional[Sequence[str]] = None,
    wm_order: str = "lru-first",
    attributes: Optional[Mapping[str, str]] = None,
    time: float = 0.0,
    turn: Optional[int] = None,
) -> Expression:
    """Describe ``target`` in a knowledge base in one call.

    ``kb`` is a :class:`Consultant` (or a port answering at once).  ``preference``
    lists attributes and/or properties, most preferred first (default: the
    consultant's order); ``forced`` names attributes whose target value always
    heads the description (TUNA's ``type``); ``writes=False`` leaves WM untouched
    (SD-PIA still reads it).  Raises :class:`GenerationError` on bad input.
    """
    port = LocalPort(kb) if isinstance(kb, Consultant) else kb
    request = Request(algorithm, preference, tuple(forced), writes, context, wm_order, attributes, time, turn)
    return run_sync(describe_async(target, port, request))
