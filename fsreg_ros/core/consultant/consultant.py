"""Consultants: one per knowledge domain, owning its LTM and its WM buffer.

DIARC's consultant pattern: each domain (faces, objects, locations, ...) has one
consultant that answers queries about *its own* entities only.  Long-term memory
(LTM) gives a certainty in [0, 1] per entity and property; a property *holds* iff
its certainty >= the domain's threshold.  A property not listed has certainty 0.

This module owns long-term memory (:class:`Consultant`: facts, the threshold, the
preference order, runtime updates, the queries over LTM and the encodings they make
into its WM buffer) and candidate sets (:class:`CandidateSet`, a bitset of the
entities still in play).  The algorithms reach a consultant through the port
(:mod:`fsreg_ros.core.algorithms.port`); the service that serves one is :mod:`fsreg_ros.core.consultant.service`.
"""

from __future__ import annotations

import math
from collections import abc
from dataclasses import dataclass
from typing import Any, Iterable, Mapping, Optional, Sequence

import numpy as np

from ..memory import bitset
from ..algorithms.port import KnowledgeError
from ..memory import EventSink, WMBuffer
from .holders import holder_bitsets

DEFAULT_THRESHOLD = 0.5
#: The certainty types :meth:`Consultant._checked_facts` checks by distinct value.
_FLOAT_ONLY = frozenset((float,))


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
    """A domain's LTM (certainties, threshold, preference order) and WM buffer.

    LTM is kept twice: per entity, the certainty of each listed property (what
    :meth:`certainty` and :meth:`assert_facts` work on), and per property, the bitset
    of the entities it holds for (:mod:`fsreg_ros.core.memory.bitset`; bit i = the i-th
    entity in entity order), which is what every query reads.  Entities are only
    ever appended (a new entity joins last), so an index never changes meaning.
    ``version`` counts LTM changes (facts, entities, threshold).
    """

    def __init__(
        self,
        domain: str,
        entities: Mapping[str, Mapping[str, float]],
        preference: Sequence[str],
        threshold: float = DEFAULT_THRESHOLD,
        sink: Optional[EventSink] = None,
        attributes: Optional[Mapping[str, str]] = None,
        retract_on_update: bool = True,
        exclusive: Sequence[Sequence[str]] = (),
    ) -> None:
        """Build a domain's consultant.

        ``attributes`` maps a property to its attribute (for similarity interference);
        a property named ``attribute=value`` needs no entry.  ``retract_on_update``
        False leaves WM alone when an LTM change makes a property stop holding (WM
        is not told of LTM changes; only forgetting clears such a property).
        ``exclusive`` lists groups of properties that exclude each other (the scenario's
        ``exclusive:`` block); the values ``attr=v1``, ``attr=v2``, ... of one attribute
        named so form a group without being listed (:func:`exclusive_groups`).
        """
        self.domain = domain
        self.preference: list[str] = list(preference)
        self._known = set(self.preference)
        if len(self._known) != len(self.preference):
            raise KnowledgeError(f"domain '{domain}': preference order lists a property twice")
        self.threshold = check_certainty("threshold", threshold)
        self.entities: list[str] = list(entities)
        self._index: dict[str, int] = {entity: i for i, entity in enumerate(self.entities)}
        self._certainty: dict[str, dict[str, float]] = {e: self._checked_facts(e, f) for e, f in entities.items()}
        self._holders: dict[str, int] = {}
        self._name_array: np.ndarray = np.zeros(0, dtype=object)  # see _names_of
        self._rebuild_holders()
        self.version = 0
        self.retract_on_update = retract_on_update
        #: property -> the other properties of its exclusive group (only properties in a group).
        self.excludes: dict[str, tuple[str, ...]] = {}
        for group in exclusive_groups(self.preference, exclusive, domain):
            for prop in group:
                self.excludes[prop] = tuple(p for p in group if p != prop)
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

    def differences(self, kb: Mapping[str, Mapping[str, float]]) -> dict[str, int]:
        """Count what LTM holds beyond the KB ``kb`` (entity -> facts): ``runtime_entities``, ``runtime_facts``.

        A runtime fact is a property whose certainty differs from the KB's (asserted,
        changed or retracted at run time), on any entity.
        """
        entities = facts = 0
        for entity in self.entities:
            mine, given = self._certainty[entity], kb.get(entity)
            if given is None:
                entities += 1
                facts += len(mine)
            elif mine != given:
                facts += sum(mine.get(p, 0.0) != given.get(p, 0.0) for p in set(mine) | set(given))
        return {"runtime_entities": entities, "runtime_facts": facts}

    def queue(self, entity: str) -> list[str]:
        """Return the WM queue of a known entity, LRU first (reading never refreshes)."""
        self._require_entity(entity)
        return list(self.wm.queue(entity))

    def encode(self, entity: str, properties: Sequence[str], cause: str, time: float, turn: Optional[int],
               episode: bool = False) -> None:
        """Encode properties for a known entity in WM; KnowledgeError (nothing encoded) for unknown names.

        ``episode``: the encoding is an act of referring to ``entity`` (rule 1 at a view's
        close): the entity's next reference episode begins first (:meth:`WMBuffer.begin_episode`).
        """
        self._require_entity(entity)
        for prop in properties:
            self._require_property(prop)
        if episode:
            self.wm.begin_episode(entity, time, turn)
        self.wm.encode(entity, properties, cause, time, turn)

    def holders(self, prop: str) -> set[str]:
        """Return every entity ``prop`` holds for (a new set)."""
        self._require_property(prop)
        return set(self._names_of(self._holders[prop]))

    def holds(self, prop: str, entities: Iterable[str]) -> list[str]:
        """Return the entities (in the given order) that ``prop`` holds for.  No encoding."""
        self._require_property(prop)
        if not isinstance(entities, (list, tuple)):
            entities = list(entities)
        index = self._index
        if not index.keys() >= set(entities):
            for entity in entities:  # name the first unknown one
                self._require_entity(entity)
        bits = self._holders[prop]
        return [e for e in entities if bits >> index[e] & 1]

    def affirm(
        self, prop: str, entities: Iterable[str], cause: str, time: float, turn: Optional[int] = None
    ) -> list[str]:
        """Check ``prop`` for each entity in order; encode it for each it holds for.

        This is how affirming a property through an LTM query enters WM (docs/semantics.md
        section 2, rules 2 and 3).  Returns the entities it holds for.
        """
        held = self.holds(prop, entities)
        self.wm.encode_each(held, prop, cause, time, turn)  # Encode(e, [prop]) for each, in order
        return held

    # ------------------------------------------------------ candidate sets
    def open_set(self, target: Optional[str] = None, context: Optional[Sequence[str]] = None) -> "CandidateSet":
        """Open the candidate set of one RR request or the distractor set of one REG request.

        Without a target: every entity (RR's candidates, docs/semantics.md section 3).  With one:
        every other entity, or the entities of an explicit ``context`` set other
        than the target (REG's distractors, docs/semantics.md section 4).  Raises KnowledgeError
        for an unknown target or context entity.
        """
        everyone = (1 << len(self.entities)) - 1
        where: Optional[int] = None
        if target is not None:
            self._require_entity(target)
            where = self._index[target]
        members = everyone
        if context is not None:
            unknown = [e for e in context if e not in self._index]
            if unknown:
                raise KnowledgeError(
                    f"context names unknown entities of domain '{self.domain}': {', '.join(unknown)}",
                    kind="unknown-entity")
            members = bitset.from_indices((self._index[e] for e in context), len(self.entities))
        if where is not None:
            members &= ~(1 << where)
        return CandidateSet(members, where)

    def narrow(
        self, candidates: "CandidateSet", prop: str, cause: Optional[str], time: float, turn: Optional[int]
    ) -> bool:
        """Keep the members ``prop`` holds for, encoding ``prop`` for each (rules 2 and 3).

        With a target, nothing happens unless ``prop`` holds for it (SD-PIA skips
        such a property; checking the target encodes nothing, rule 4); the return
        value says whether it does (always True without a target).  Members are
        visited in entity order; ``cause`` None checks without encoding.
        """
        self._require_property(prop)
        holders = self._holders[prop]
        if candidates.target is not None and not holders >> candidates.target & 1:
            return False
        kept = candidates.members & holders
        if cause is not None and kept and self.wm.retains:
            self.wm.encode_members(kept, self.entities, prop, cause, time, turn)
        candidates.members = kept
        return True

    def members(self, candidates: "CandidateSet") -> list[str]:
        """Return a candidate set's members, in entity order."""
        return self._names_of(candidates.members)

    def rule_out(self, candidates: "CandidateSet") -> tuple[list[str], list[int]]:
        """For each property holding for the target (preference order), the members it rules out.

        Each set is written by member rank: bit k = the k-th member in entity order.
        Queries only, no encoding.
        """
        if candidates.target is None:
            raise KnowledgeError("rule-out sets need a target")
        props, masks = [], []
        members = candidates.members
        for prop in self.preference:
            holders = self._holders[prop]
            if holders >> candidates.target & 1:
                props.append(prop)
                masks.append(bitset.positions(members & ~holders, members))
        return props, masks

    # ------------------------------------------------------------ updates
    def set_threshold(self, threshold: float, time: float = 0.0) -> list[tuple[str, str]]:
        """Change the domain's threshold.

        A property that stops holding for an entity is forgotten from its WM (cause
        ``retract``), as with :meth:`assert_facts`, unless ``retract_on_update`` is
        False; returns those (entity, property) pairs.
        """
        self.threshold = check_certainty("threshold", threshold)
        self._rebuild_holders()
        self.version += 1
        retracted: list[tuple[str, str]] = []
        if not self.retract_on_update:
            return retracted
        for entity, queue in self.wm.snapshot().items():
            for prop in queue:
                if not self._holders[prop] >> self._index[entity] & 1:
                    self.wm.remove(entity, prop, "retract", time)
                    retracted.append((entity, prop))
        return retracted

    def preview_assert(self, entity: str, facts: Mapping[str, Any], exclude: bool = True,
                       pending: Optional[dict[str, dict[str, float]]] = None,
                       effective: Optional[dict[str, float]] = None) -> tuple[bool, list[str]]:
        """Validate an LTM update without applying it: (new entity?, properties that would stop holding).

        Raises KnowledgeError for anything :meth:`assert_facts` would refuse.  The
        properties are in preference order, including those an asserted property
        excludes (:meth:`effective_update`; ``exclude`` False takes the facts as given);
        they are forgotten from WM only when ``retract_on_update`` is True.  ``pending``
        previews a batch: it maps each entity an earlier fact of the batch (previewed,
        not yet applied) changed to its facts as that fact leaves them, and is updated
        with this one's (nothing else is).  ``effective``, a dict, receives the update as
        :meth:`effective_update` makes it (what to store; :meth:`assert_facts` takes it as ``update``).
        """
        if not isinstance(entity, str) or not entity:
            raise KnowledgeError(f"entity must be a non-empty string, got {entity!r}")
        if not isinstance(facts, abc.Mapping) or not facts:
            raise KnowledgeError(f"properties for '{entity}' must be a non-empty mapping of property to certainty")
        self._check_facts(entity, facts)
        earlier = pending.get(entity) if pending is not None else None
        new = entity not in self._certainty and earlier is None
        current = earlier if earlier is not None else self._certainty.get(entity, {})
        update = (self.effective_update(entity, facts, current) if exclude
                  else {p: float(c) for p, c in facts.items()})
        if effective is not None:
            effective.update(update)
        after = {**current, **update}
        if pending is not None:
            pending[entity] = {p: c for p, c in after.items() if c > 0}
        if new:
            return new, []
        threshold = self.threshold
        return False, [p for p in self.preference
                       if current.get(p, 0.0) >= threshold and after.get(p, 0.0) < threshold]

    def effective_update(self, entity: str, facts: Mapping[str, Any],
                         current: Optional[Mapping[str, float]] = None) -> dict[str, float]:
        """Return the LTM update ``facts`` makes for ``entity`` (checked facts): the facts, then what they exclude.

        A property asserted to hold (certainty > 0 and >= the threshold) retracts the
        other properties of its exclusive group that the entity has (certainty > 0,
        holding or not) and the update does not name: they are set to 0, after the
        given facts.  Two properties of one group asserted to hold in one update
        contradict each other: KnowledgeError (kind ``contradiction``), nothing changes.
        ``current``: the entity's facts to exclude from (default: as LTM holds them now;
        a batch's preview passes them as its earlier facts leave them).
        """
        values = {p: float(c) for p, c in facts.items()}
        if not self.excludes:
            return values
        threshold = self.threshold
        if current is None:
            current = self._certainty.get(entity, {})
        excluded: dict[str, float] = {}
        for prop, c in values.items():
            others = self.excludes.get(prop)
            if not others or c <= 0.0 or c < threshold:
                continue
            for other in others:
                given = values.get(other)
                if given is not None:
                    if given > 0.0 and given >= threshold:
                        raise KnowledgeError(
                            f"domain '{self.domain}', entity '{entity}': '{prop}' and '{other}' exclude each other "
                            "and are both asserted to hold", kind="contradiction")
                elif current.get(other, 0.0) > 0.0:
                    excluded[other] = 0.0
        return {**values, **excluded}

    def assert_facts(self, entity: str, facts: Mapping[str, Any], time: float, exclude: bool = True,
                     previewed: Optional[tuple[bool, list[str]]] = None,
                     update: Optional[Mapping[str, float]] = None) -> AssertResult:
        """Add or update LTM facts for one entity (perception, a user); atomic.

        A new entity joins the domain (last in entity order).  Certainty 0 retracts
        a fact; a property asserted to hold also retracts the others of its
        exclusive group (:meth:`effective_update`; ``updated`` lists them with
        certainty 0).  A property that stops holding is also forgotten from
        Q[entity] (cause ``retract``) unless ``retract_on_update`` is False (the
        follow-up study's configuration: WM not told of LTM changes); ``retracted``
        lists those properties either way.  Everything is validated
        (:meth:`preview_assert`) before anything changes.  ``exclude`` False applies
        the facts as given (a restore: the stored facts carry their exclusions already).
        ``previewed``: what :meth:`preview_assert` returned for exactly this update just
        now (a batch previews every fact first; not validated again), and ``update`` the
        effective update it computed (with ``previewed`` only).
        """
        new, retracted = previewed if previewed is not None else self.preview_assert(entity, facts, exclude)
        if update is None or previewed is None:
            update = self.effective_update(entity, facts) if exclude else {p: float(c) for p, c in facts.items()}
        if new:
            self._index[entity] = len(self.entities)
            self.entities.append(entity)
            self._certainty[entity] = {}
        current = self._certainty[entity]
        bit = 1 << self._index[entity]
        for prop, c in update.items():
            if c > 0:
                current[prop] = c
            else:
                current.pop(prop, None)
            if current.get(prop, 0.0) >= self.threshold:
                self._holders[prop] |= bit
            else:
                self._holders[prop] &= ~bit
        self.version += 1
        for prop in retracted if self.retract_on_update else ():
            self.wm.remove(entity, prop, "retract", time)
        return AssertResult(entity, new, update, retracted)

    # ------------------------------------------------------------ internals
    def _check_facts(self, entity: str, facts: Mapping[str, Any]) -> None:
        for prop, c in facts.items():
            if prop not in self._known:
                raise KnowledgeError(
                    f"domain '{self.domain}', entity '{entity}': unknown property '{prop}' "
                    f"(not in the domain's preference order)", kind="unknown-property"
                )
            check_certainty(f"certainty of '{prop}' for '{entity}'", c)

    def _checked_facts(self, entity: str, facts: Mapping[str, Any]) -> dict[str, float]:
        """Return an entity's LTM facts as kept (certainty > 0, as floats); KnowledgeError for a bad one.

        Exactly :meth:`_check_facts` and then the conversion, but a domain of 10,000
        entities x 40 facts is built twice per ``fsreg-sim`` run (the game and its
        ``none`` baseline), so the common case is checked by C-level set operations:
        every property known, every certainty a float, and the few *distinct*
        certainties (usually just 1.0) checked once each.  Anything else (an int, a
        bool: ``True == 1.0`` would hide in a set of values) goes fact by fact.
        """
        if not self._known.issuperset(facts) or not _FLOAT_ONLY.issuperset(map(type, facts.values())):
            self._check_facts(entity, facts)
            return {p: float(c) for p, c in facts.items() if c > 0}
        distinct = set(facts.values())
        for c in distinct:
            if not 0.0 <= c <= 1.0:  # also NaN
                self._check_facts(entity, facts)  # names the property
        if 0.0 in distinct:
            return {p: c for p, c in facts.items() if c > 0}
        return dict(facts)

    def _rebuild_holders(self) -> None:
        """Rebuild every property's holder bitset from the facts (:func:`.holders.holder_bitsets`)."""
        self._holders = holder_bitsets(self._certainty, self.entities, self.preference, self.threshold)

    def _names_of(self, bits: int) -> list[str]:
        """Return the entities of a bitset, in entity order.

        One numpy take from an object array of the entity names (kept, and rebuilt when
        entities were appended): an RR or REG request names thousands of candidates or
        distractors in a large domain, several times faster than indexing the list.
        """
        if len(self._name_array) != len(self.entities):
            self._name_array = np.array(self.entities, dtype=object)
        return self._name_array[bitset.index_array(bits)].tolist()

    def _require_entity(self, entity: str) -> None:
        if entity not in self._certainty:
            raise KnowledgeError(f"domain '{self.domain}' has no entity '{entity}'", kind="unknown-entity")

    def _require_property(self, prop: str) -> None:
        if prop not in self._known:
            raise KnowledgeError(f"domain '{self.domain}' knows no property '{prop}'", kind="unknown-property")


@dataclass
class CandidateSet:
    """The entities still in play in one RR or REG request, held by the consultant.

    ``members`` is a bitset over entity indices (:mod:`fsreg_ros.core.memory.bitset`);
    ``target`` is REG's target's index (None for RR); ``referred``: the target's reference
    episode began when the set was opened (REG's open with a reference), so closing it begins none.
    """

    members: int
    target: Optional[int] = None
    referred: bool = False

    @property
    def size(self) -> int:
        return self.members.bit_count()


def exclusive_groups(preference: Sequence[str], declared: Sequence[Sequence[str]] = (),
                     domain: str = "") -> list[tuple[str, ...]]:
    """Return a domain's exclusive groups: the ``declared`` ones, then one per attribute named ``attr=value``.

    The values of an attribute named so (``colour=red``, ``colour=blue``) exclude each
    other by default; a declared group may not hold such a value, name a property
    outside ``preference``, repeat one, or have fewer than two (KnowledgeError; a
    scenario file's checks say the same with file and line).
    """
    known = set(preference)
    groups: list[tuple[str, ...]] = []
    seen: dict[str, int] = {}
    where = f"domain '{domain}': " if domain else ""
    for k, group in enumerate(declared):
        group = tuple(group)
        if len(set(group)) < 2:
            raise KnowledgeError(f"{where}exclusive group {k} needs at least two distinct properties, got "
                                 f"{list(group)}")
        for prop in group:
            if prop not in known:
                raise KnowledgeError(f"{where}exclusive group {k} names unknown property '{prop}'",
                                     kind="unknown-property")
            if prop in seen or implied_attribute(prop) is not None:
                other = f"group {seen[prop]}" if prop in seen else f"the values of '{implied_attribute(prop)}'"
                raise KnowledgeError(f"{where}property '{prop}' of exclusive group {k} is already in {other}")
            seen[prop] = k
        groups.append(group)
    by_attribute: dict[str, list[str]] = {}
    for prop in preference:
        attribute = implied_attribute(prop)
        if attribute is not None:
            by_attribute.setdefault(attribute, []).append(prop)
    groups.extend(tuple(values) for values in by_attribute.values() if len(values) > 1)
    return groups


def implied_attribute(prop: str) -> Optional[str]:
    """Return ``attr`` for a property named ``attr=value`` (both non-empty), else None."""
    attribute, sep, value = prop.partition("=")
    return attribute if sep and attribute and value else None


def check_certainty(what: str, value: Any) -> float:
    """Validate a certainty or threshold: a number in [0, 1]."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise KnowledgeError(f"{what} must be a number in [0, 1], got {value!r}")
    if isinstance(value, int) and not -1 <= value <= 2:  # checked before float(): 10**400 has no float
        raise KnowledgeError(f"{what} must be in [0, 1], got an integer of {value.bit_length()} bits")
    if not math.isfinite(value):
        raise KnowledgeError(f"{what} must be a number in [0, 1], got {value!r}")
    if not 0.0 <= value <= 1.0:
        raise KnowledgeError(f"{what} must be in [0, 1], got {value!r}")
    return float(value)
