"""Consultants: one per knowledge domain, owning its LTM and its WM buffer.

DIARC's consultant pattern: each domain (faces, objects, locations, ...) has one
consultant that answers queries about *its own* entities only.  Long-term memory
(LTM) gives a certainty in [0, 1] per entity and property; a property *holds* iff
its certainty >= the domain's threshold.  A property not listed has certainty 0.

The algorithms (reference resolution, REG) talk to consultants through the small
asynchronous :class:`ConsultantPort` interface.  In-process, :class:`LocalPort`
answers at once and :func:`run_sync` drives the algorithm without an event loop;
in the ROS graph the same algorithm coroutines await service calls to consultant
nodes instead.  One implementation of each algorithm serves both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Coroutine, Iterable, Mapping, Optional, Protocol, Sequence, TypeVar

from .memory import EventSink, WMBuffer

DEFAULT_THRESHOLD = 0.5


class KnowledgeError(ValueError):
    """A query or update names something the domain does not know, or is malformed.

    The message says what and where; the consultant's state is unchanged.
    """


@dataclass(frozen=True)
class AssertResult:
    """What an LTM update changed: the entity, whether it is new, and retractions."""

    entity: str
    new_entity: bool
    updated: dict[str, float]
    retracted: list[str]

    def to_json(self) -> dict:
        return {
            "entity": self.entity,
            "new_entity": self.new_entity,
            "updated": dict(self.updated),
            "retracted": list(self.retracted),
        }


class Consultant:
    """A domain's LTM (certainties, threshold, preference order) and WM buffer."""

    def __init__(
        self,
        domain: str,
        entities: Mapping[str, Mapping[str, float]],
        preference: Sequence[str],
        threshold: float = DEFAULT_THRESHOLD,
        sink: Optional[EventSink] = None,
        attributes: Optional[Mapping[str, str]] = None,
    ) -> None:
        """Build a domain's consultant.

        ``attributes`` maps a property to its attribute (for similarity interference);
        a property named ``attribute=value`` needs no entry.
        """
        self.domain = domain
        self.preference: list[str] = list(preference)
        self._known = set(self.preference)
        if len(self._known) != len(self.preference):
            raise KnowledgeError(f"domain '{domain}': preference order lists a property twice")
        self.threshold = check_certainty("threshold", threshold)
        self.entities: list[str] = []
        self._certainty: dict[str, dict[str, float]] = {}
        # The same entities as a set, for validating long entity lists in one C call.
        self._entity_set: set[str] = set()
        self._holders: dict[str, set[str]] = {p: set() for p in self.preference}
        for entity, facts in entities.items():
            self._check_facts(entity, facts)
            self.entities.append(entity)
            self._entity_set.add(entity)
            self._certainty[entity] = {p: float(c) for p, c in facts.items() if c > 0}
        self._rebuild_holders()
        self.wm = WMBuffer(domain, sink, attributes)

    # ----------------------------------------------------------------- LTM
    def knows_property(self, prop: str) -> bool:
        return prop in self._known

    def knows_entity(self, entity: str) -> bool:
        return entity in self._certainty

    def certainty(self, entity: str, prop: str) -> float:
        self._require_entity(entity)
        self._require_property(prop)
        return self._certainty[entity].get(prop, 0.0)

    def properties_of(self, entity: str) -> list[str]:
        """Properties that hold for ``entity``, in preference order."""
        self._require_entity(entity)
        facts = self._certainty[entity]
        return [p for p in self.preference if facts.get(p, 0.0) >= self.threshold]

    def queue(self, entity: str) -> list[str]:
        """Return the WM queue of a known entity, LRU first (reading never refreshes)."""
        self._require_entity(entity)
        return list(self.wm.queue(entity))

    def encode(self, entity: str, properties: Sequence[str], cause: str, time: float, turn: Optional[int]) -> None:
        """Encode properties for a known entity in WM; KnowledgeError (nothing encoded) for unknown names."""
        self._require_entity(entity)
        for prop in properties:
            self._require_property(prop)
        self.wm.encode(entity, properties, cause, time, turn)

    def holders(self, prop: str) -> set[str]:
        """Every entity ``prop`` holds for (a live view: do not modify)."""
        self._require_property(prop)
        return self._holders[prop]

    def holds(self, prop: str, entities: Iterable[str]) -> list[str]:
        """The entities (in the given order) that ``prop`` holds for.  No encoding."""
        self._require_property(prop)
        if not isinstance(entities, (list, tuple)):
            entities = list(entities)
        if not self._entity_set.issuperset(entities):
            for entity in entities:  # name the first unknown one
                self._require_entity(entity)
        holders = self._holders[prop]
        return [e for e in entities if e in holders]

    def affirm(
        self, prop: str, entities: Iterable[str], cause: str, time: float, turn: Optional[int] = None
    ) -> list[str]:
        """Check ``prop`` for each entity in order; encode it for each it holds for.

        This is how affirming a property through an LTM query enters WM (SPEC
        section 2, rules 2 and 3).  Returns the entities it holds for.
        """
        held = self.holds(prop, entities)
        self.wm.encode_each(held, prop, cause, time, turn)  # Encode(e, [prop]) for each, in order
        return held

    def set_threshold(self, threshold: float, time: float = 0.0) -> list[tuple[str, str]]:
        """Change the domain's threshold.  A property that stops holding for an entity
        is forgotten from its WM (cause ``retract``), as with :meth:`assert_facts`;
        returns those (entity, property) pairs."""
        self.threshold = check_certainty("threshold", threshold)
        self._rebuild_holders()
        retracted = []
        for entity, queue in self.wm.snapshot().items():
            for prop in queue:
                if entity not in self._holders[prop]:
                    self.wm.remove(entity, prop, "retract", time)
                    retracted.append((entity, prop))
        return retracted

    def assert_facts(self, entity: str, facts: Mapping[str, Any], time: float) -> AssertResult:
        """Add or update LTM facts for one entity (perception, a user); atomic.

        A new entity joins the domain (last in entity order).  Certainty 0 retracts
        a fact; a property that stops holding is also forgotten from Q[entity]
        (cause ``retract``).  Everything is validated before anything changes.
        """
        if not isinstance(entity, str) or not entity:
            raise KnowledgeError(f"entity must be a non-empty string, got {entity!r}")
        if not isinstance(facts, Mapping) or not facts:
            raise KnowledgeError(f"properties for '{entity}' must be a non-empty mapping of property to certainty")
        self._check_facts(entity, facts)
        new = entity not in self._certainty
        old_holding = set() if new else set(self.properties_of(entity))
        if new:
            self.entities.append(entity)
            self._entity_set.add(entity)
            self._certainty[entity] = {}
        current = self._certainty[entity]
        for prop, c in facts.items():
            if c > 0:
                current[prop] = float(c)
            else:
                current.pop(prop, None)
            if current.get(prop, 0.0) >= self.threshold:
                self._holders[prop].add(entity)
            else:
                self._holders[prop].discard(entity)
        now_holding = set(self.properties_of(entity))
        retracted = [p for p in self.preference if p in old_holding and p not in now_holding]
        for prop in retracted:
            self.wm.remove(entity, prop, "retract", time)
        return AssertResult(entity, new, {p: float(c) for p, c in facts.items()}, retracted)

    # ------------------------------------------------------------ internals
    def _check_facts(self, entity: str, facts: Mapping[str, Any]) -> None:
        for prop, c in facts.items():
            if prop not in self._known:
                raise KnowledgeError(
                    f"domain '{self.domain}', entity '{entity}': unknown property '{prop}' "
                    f"(not in the domain's preference order)"
                )
            check_certainty(f"certainty of '{prop}' for '{entity}'", c)

    def _rebuild_holders(self) -> None:
        for prop in self.preference:
            self._holders[prop] = {
                e for e in self.entities if self._certainty[e].get(prop, 0.0) >= self.threshold
            }

    def _require_entity(self, entity: str) -> None:
        if entity not in self._certainty:
            raise KnowledgeError(f"domain '{self.domain}' has no entity '{entity}'")

    def _require_property(self, prop: str) -> None:
        if prop not in self._known:
            raise KnowledgeError(f"domain '{self.domain}' knows no property '{prop}'")


def check_certainty(what: str, value: Any) -> float:
    """Validate a certainty or threshold: a number in [0, 1]."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise KnowledgeError(f"{what} must be a number in [0, 1], got {value!r}")
    if not 0.0 <= value <= 1.0:
        raise KnowledgeError(f"{what} must be in [0, 1], got {value!r}")
    return float(value)


# --------------------------------------------------------------------- ports
class ConsultantPort(Protocol):
    """What reference resolution and REG may ask of a domain's consultant."""

    domain: str

    async def entities(self) -> list[str]:
        """The domain's entities, in entity order."""

    async def preference(self) -> list[str]:
        """The domain's preference order, most preferred first."""

    async def holds(self, prop: str, entities: Sequence[str]) -> list[str]:
        """The given entities ``prop`` holds for, in the given order.  No encoding."""

    async def affirm(
        self, prop: str, entities: Sequence[str], cause: str, time: float, turn: Optional[int]
    ) -> list[str]:
        """As :meth:`holds`, and encode ``prop`` for each entity it holds for."""

    async def wm(self, entity: str) -> list[str]:
        """Q[entity], LRU first."""

    async def encode(
        self, entity: str, properties: Sequence[str], cause: str, time: float, turn: Optional[int]
    ) -> None:
        """Encode(entity, properties) (Algorithm 1)."""


class LocalPort:
    """A :class:`ConsultantPort` over an in-process :class:`Consultant`."""

    def __init__(self, consultant: Consultant) -> None:
        self.consultant = consultant
        self.domain = consultant.domain

    async def entities(self) -> list[str]:
        return list(self.consultant.entities)

    async def preference(self) -> list[str]:
        return list(self.consultant.preference)

    async def holds(self, prop: str, entities: Sequence[str]) -> list[str]:
        return self.consultant.holds(prop, entities)

    async def affirm(
        self, prop: str, entities: Sequence[str], cause: str, time: float, turn: Optional[int]
    ) -> list[str]:
        return self.consultant.affirm(prop, entities, cause, time, turn)

    async def wm(self, entity: str) -> list[str]:
        return self.consultant.queue(entity)

    async def encode(
        self, entity: str, properties: Sequence[str], cause: str, time: float, turn: Optional[int]
    ) -> None:
        self.consultant.encode(entity, properties, cause, time, turn)


T = TypeVar("T")


def run_sync(coroutine: Coroutine[Any, Any, T]) -> T:
    """Run an algorithm coroutine whose ports answer at once (e.g. :class:`LocalPort`).

    No event loop is needed: a coroutine that never suspends finishes on its first
    step.  One that does suspend was given a port that does real I/O; that is a
    programming error, reported as such.
    """
    try:
        coroutine.send(None)
    except StopIteration as done:
        return done.value
    coroutine.close()
    raise RuntimeError("run_sync: the algorithm awaited real I/O; use an event loop or executor")
