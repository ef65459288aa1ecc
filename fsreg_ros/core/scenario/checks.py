"""The checks of a scenario file that need more than types; builds the Scenario.

Unknown properties and entities, preference orders, attributes, times, forgetting
settings, turn shapes and domains.  The rules of forgetting settings and
certainties are the core's own (:mod:`fsreg_ros.core.forgetting.policies`,
:func:`fsreg_ros.core.consultant.consultant.check_certainty`).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Optional, Sequence, Union

import yaml

from ..consultant.consultant import KnowledgeError, check_certainty, exclusive_groups, implied_attribute
from ..lexicon import Lexicon
from ..algorithms.resolution import domains_knowing
from ..io.yaml_source import PathLoc, find_line, render_path
from .model import DomainSpec, Scenario, ScenarioError, Turn, memory_setting_problem, names
from .schema import DomainBlock, MemoryBlock, ScenarioFile, TurnEntry

#: How many entity names an "unknown entity" message lists before eliding the rest.
MAX_LISTED = 20


class Checker:
    """The checks of a scenario that need more than types; builds the Scenario."""

    def __init__(self, source: str, root: Optional[yaml.Node], lexicon: Optional["Lexicon"]) -> None:
        self.source = source
        self.root = root
        self.lexicon = lexicon

    def fail(self, loc: PathLoc, message: str) -> ScenarioError:
        line, _ = find_line(self.root, loc)
        return ScenarioError(self.source, render_path(loc), message, line)

    def line(self, loc: PathLoc) -> Optional[int]:
        line, found = find_line(self.root, loc)
        return line if found else None

    # ------------------------------------------------------------ whole file
    def scenario(self, model: ScenarioFile) -> Scenario:
        if not model.domains:
            raise self.fail(("domains",), "no domains: a scenario needs at least one")
        domains: dict[str, DomainSpec] = {}
        owner: dict[str, str] = {}  # entity -> domain
        all_properties = {p for block in model.domains.values() for p in block.preference}
        for name, block in model.domains.items():
            domains[name] = self.domain(name, block, owner, all_properties)
        memory = self.memory_block(("memory",), model.memory)
        lines = self.lines(model)
        scenario = Scenario(
            name=model.name if model.name is not None else Path(self.source).stem,
            source=self.source,
            domains=domains,
            memory=memory,
            dialogue=(),
            lines=lines,
        )
        return replace(scenario, dialogue=tuple(self.dialogue(model.dialogue or [], scenario)))

    def lines(self, model: ScenarioFile) -> dict[str, int]:
        paths: list[PathLoc] = [("memory",)]
        for name in model.domains:
            paths += [("domains", name), ("domains", name, "memory")]
        found = {render_path(loc): self.line(loc) for loc in paths}
        return {path: line for path, line in found.items() if line is not None}

    # ---------------------------------------------------------------- domains
    def domain(self, name: str, block: DomainBlock, owner: dict[str, str], all_properties: set[str]) -> DomainSpec:
        here = ("domains", name)
        try:
            threshold = check_certainty("threshold", block.threshold)
        except KnowledgeError as err:
            raise self.fail(here + ("threshold",), str(err)) from None
        first: dict[str, int] = {}
        for i, prop in enumerate(block.preference):
            if prop in first:
                raise self.fail(
                    here + ("preference", i),
                    f"property '{prop}' is listed twice in the preference order (also at preference[{first[prop]}])",
                )
            first[prop] = i
        entities: dict[str, dict[str, float]] = {}
        known = set(block.preference)
        for entity, facts in block.entities.items():
            at = here + ("entities", entity)
            if entity in owner:
                raise self.fail(
                    at,
                    f"duplicate entity '{entity}': already in domain '{owner[entity]}' "
                    "(an entity belongs to exactly one domain; names are unique across the file)",
                )
            owner[entity] = name
            entities[entity] = self.facts(at, name, block.preference, facts, all_properties, known)
        memory = self.memory_block(here + ("memory",), block.memory)
        attributes = self.attributes(here + ("attributes",), block)
        exclusive = self.exclusive(here, block, entities, threshold)
        return DomainSpec(name, tuple(block.preference), entities, threshold, memory, attributes, exclusive)

    def exclusive(self, here: PathLoc, block: DomainBlock, entities: dict[str, dict[str, float]],
                  threshold: float) -> tuple[tuple[str, ...], ...]:
        """Return the declared exclusive groups, checked; and check no entity holds two properties of one group.

        A group names properties of the domain's preference order, at least two, none
        in another group (nor an ``attr=value`` property: the values of an attribute
        named so are a group already).  The groups in force are these plus the
        ``attr=value`` ones (:func:`~fsreg_ros.core.consultant.consultant.exclusive_groups`).
        """
        at = here + ("exclusive",)
        known = set(block.preference)
        owner: dict[str, int] = {}
        for k, group in enumerate(block.exclusive):
            if len(set(group)) < 2:
                raise self.fail(at + (k,), f"a group of one ({', '.join(group)}): an exclusive group needs at "
                                           "least two properties that exclude each other")
            for i, prop in enumerate(group):
                if prop not in known:
                    raise self.fail(at + (k, i), f"unknown property '{prop}': exclusive groups name the domain's "
                                                 f"properties (its preference order: {names(block.preference)})")
                if prop in owner:
                    where = "in this group already" if owner[prop] == k else f"in exclusive group {owner[prop]} too"
                    raise self.fail(at + (k, i), f"property '{prop}' is {where} (a property is in one group at most)")
                implied = implied_attribute(prop)
                if implied is not None:
                    raise self.fail(at + (k, i), f"property '{prop}' is in the group of attribute '{implied}' by its "
                                                 "name (every 'attr=value' of one attribute excludes the others)")
                owner[prop] = k
        groups = exclusive_groups(block.preference, block.exclusive)
        if groups:
            group_of = {prop: k for k, group in enumerate(groups) for prop in group}
            get, grouped = group_of.get, group_of.keys()
            for entity, facts in entities.items():
                # No two held properties of one group: decided in C for nearly every entity (a world
                # of 10,000 entities x 40 attr=value facts spent 40 ms here); the loop below only
                # runs when two of its properties share a group, to weigh certainties and say which.
                if len(set(map(get, facts))) == len(facts):
                    continue  # distinct groups (at most one property in none)
                in_groups = grouped & facts.keys()
                if len(set(map(group_of.__getitem__, in_groups))) == len(in_groups):
                    continue
                seen: dict[int, str] = {}
                for prop, certainty in facts.items():
                    k = group_of.get(prop)
                    if k is None or certainty < threshold:
                        continue
                    if k in seen:
                        raise self.fail(here + ("entities", entity),
                                        f"entity '{entity}' holds both '{seen[k]}' and '{prop}', which exclude "
                                        "each other")
                    seen[k] = prop
        return tuple(tuple(group) for group in block.exclusive)

    def attributes(self, at: PathLoc, block: DomainBlock) -> dict[str, str]:
        """Return property -> attribute: the ``attributes:`` block, then ``attr=value`` names.

        Each listed property must be in the domain's preference order, in at most
        one attribute, and not named for another attribute (``colour=red`` under
        ``size``).
        """
        known = set(block.preference)
        owner: dict[str, str] = {}
        for attribute, members in block.attributes.items():
            for i, prop in enumerate(members):
                if prop not in known:
                    raise self.fail(
                        at + (attribute, i),
                        f"unknown property '{prop}': attributes group the domain's properties "
                        f"(its preference order: {names(block.preference)})",
                    )
                if prop in owner:
                    raise self.fail(
                        at + (attribute, i), f"property '{prop}' is already in attribute '{owner[prop]}'"
                    )
                implied = implied_attribute(prop)
                if implied is not None and implied != attribute:
                    raise self.fail(
                        at + (attribute, i), f"property '{prop}' belongs to attribute '{implied}' by its name"
                    )
                owner[prop] = attribute
        for prop in block.preference:
            implied = implied_attribute(prop)
            if implied is not None:
                owner.setdefault(prop, implied)
        return {prop: owner[prop] for prop in block.preference if prop in owner}

    def facts(
        self,
        at: PathLoc,
        domain: str,
        preference: Sequence[str],
        facts: Union[list[str], dict[str, float]],
        all_properties: set[str],
        known: Optional[set[str]] = None,
    ) -> dict[str, float]:
        """Return an entity's facts as {property: certainty}; list form means certainty 1.

        ``known`` is ``set(preference)``, when the caller has it.  A list of distinct
        known properties (the usual case, and all of a generated world) is accepted
        with two set operations; anything else is checked fact by fact, which names
        the first problem.
        """
        known = set(preference) if known is None else known
        if isinstance(facts, list) and known.issuperset(facts):
            out = dict.fromkeys(facts, 1.0)
            if len(out) == len(facts):
                return out
        # (path key, property, certainty): list items are addressed by index.
        items: list[tuple[Union[int, str], str, float]]
        if isinstance(facts, list):
            items = [(i, prop, 1.0) for i, prop in enumerate(facts)]
        else:
            items = [(prop, prop, certainty) for prop, certainty in facts.items()]
        out: dict[str, float] = {}
        for key, prop, certainty in items:
            if prop not in known:
                where = " (it is in no preference order)"
                if prop in all_properties:
                    where = " (it is in another domain's preference order)"
                raise self.fail(
                    at + (key,),
                    f"unknown property '{prop}'{where}: an entity's properties must be in its domain's "
                    f"preference order (domain '{domain}' knows: {names(preference)})",
                )
            if prop in out:
                raise self.fail(at + (key,), f"property '{prop}' is listed twice for entity '{at[-1]}'")
            try:
                out[prop] = check_certainty(f"certainty of '{prop}' for '{at[-1]}'", certainty)
            except KnowledgeError as err:
                raise self.fail(at + (key,), str(err)) from None
        return out

    # ----------------------------------------------------------------- memory
    def memory_block(self, at: PathLoc, block: Optional[MemoryBlock]) -> Optional[dict]:
        """Return a ``memory:`` block's non-null settings, each checked by the core's rules."""
        if block is None:
            return None
        settings = {k: v for k, v in block.model_dump(exclude_unset=True).items() if v is not None}
        for key, value in settings.items():
            problem = memory_setting_problem(key, value)
            if problem is not None:
                raise self.fail(at + (key,), problem)
        return settings

    # --------------------------------------------------------------- dialogue
    def dialogue(self, entries: Sequence[TurnEntry], scenario: Scenario) -> list[Turn]:
        turns: list[Turn] = []
        previous: Optional[float] = None
        for index, entry in enumerate(entries):
            at = ("dialogue", index)
            if entry.time < 0:
                raise self.fail(at + ("time",), f"negative time {entry.time}: times are seconds from t = 0")
            if previous is not None and entry.time < previous:
                raise self.fail(
                    at + ("time",),
                    f"decreasing time: {entry.time} is before the previous turn's {previous} "
                    "(turns are in time order; equal times are allowed)",
                )
            previous = entry.time
            check = self.human_turn if entry.speaker == "human" else self.robot_turn
            check(at, entry, scenario)
            turns.append(
                Turn(
                    index=index,
                    time=entry.time,
                    speaker=entry.speaker,
                    target=entry.target,
                    description=tuple(entry.description) if entry.description is not None else None,
                    text=entry.text,
                    domain=entry.domain,
                    context=tuple(entry.context) if entry.context is not None else None,
                )
            )
        return turns

    def human_turn(self, at: PathLoc, entry: TurnEntry, scenario: Scenario) -> None:
        if entry.context is not None:
            raise self.fail(at + ("context",), "only robot turns have a context")
        if entry.description is not None and entry.text is not None:
            raise self.fail(at, "a human turn gives either description or text, not both")
        if entry.description is None and entry.text is None:
            raise self.fail(at, "a human turn needs a description (a list of properties) or text")
        if entry.domain is not None and entry.domain not in scenario.domains:
            raise self.fail(at + ("domain",), f"unknown domain '{entry.domain}' (known: {names(scenario.domains)})")
        if entry.description is not None:
            if not entry.description:
                raise self.fail(at + ("description",), "empty description")
            properties, whole, indexed = entry.description, at + ("description",), True
        else:
            properties = self.parse_text(at + ("text",), entry.text or "", scenario)
            whole, indexed = at + ("text",), False
        domain = self.turn_domain(entry.domain, properties, whole, indexed, scenario)
        if entry.target is not None:
            self.entity_in(at + ("target",), entry.target, domain, scenario, "the description's domain")

    def robot_turn(self, at: PathLoc, entry: TurnEntry, scenario: Scenario) -> None:
        if entry.target is None:
            raise self.fail(at, "a robot turn needs a target (the entity to describe)")
        for key in ("description", "text"):
            if getattr(entry, key) is not None:
                raise self.fail(at + (key,), f"a robot turn has no {key}: the robot generates it")
        domain = self.entity_in(at + ("target",), entry.target, None, scenario, "")
        if entry.domain is not None and entry.domain != domain:
            raise self.fail(
                at + ("domain",),
                f"domain '{entry.domain}' is not the target's domain ('{entry.target}' is in '{domain}')",
            )
        for i, entity in enumerate(entry.context or ()):
            self.entity_in(at + ("context", i), entity, domain, scenario, "the target's domain")

    def entity_in(self, at: PathLoc, entity: str, domain: Optional[str], scenario: Scenario, what: str) -> str:
        """Check ``entity`` exists (and is in ``domain`` if given); return its domain."""
        owner = next((name for name, spec in scenario.domains.items() if entity in spec.entities), None)
        if owner is None:
            candidates = scenario.domains[domain].entities if domain is not None else scenario.entities()
            scope = f"domain '{domain}' has" if domain is not None else "known"
            raise self.fail(at, f"unknown entity '{entity}' ({scope}: {names(list(candidates), MAX_LISTED)})")
        if domain is not None and owner != domain:
            raise self.fail(at, f"entity '{entity}' is in domain '{owner}', not in {what} '{domain}'")
        return owner

    def parse_text(self, at: PathLoc, text: str, scenario: Scenario) -> list[str]:
        """Return the properties of a text turn, as the simulator parses them (all properties)."""
        if not text.strip():
            raise self.fail(at, "empty text")
        lexicon = self.get_lexicon(at)
        properties = list(lexicon.parse(text, scenario.properties()).properties)
        if not properties:
            raise self.fail(at, f"no known property in text {text!r}")
        return properties

    def get_lexicon(self, at: PathLoc) -> "Lexicon":
        if self.lexicon is None:
            try:
                self.lexicon = Lexicon.load()
            except (OSError, ValueError) as err:
                raise self.fail(at, f"text turns need the lexicon, which cannot be loaded: {err}") from None
        return self.lexicon

    def turn_domain(
        self,
        named: Optional[str],
        properties: Sequence[str],
        whole: PathLoc,
        indexed: bool,
        scenario: Scenario,
    ) -> str:
        """Return the domain a human description resolves in.

        That is the named one, else the only domain whose preference order has
        every property.  Errors about one property point at ``whole[i]`` when
        ``indexed`` (a description list), else at ``whole`` (a text).
        """

        def where(i: int) -> PathLoc:
            return whole + (i,) if indexed else whole

        domains = scenario.domains
        if named is not None:
            preference = domains[named].preference
            for i, prop in enumerate(properties):
                if prop not in preference:
                    message = f"unknown property '{prop}' (domain '{named}' knows: {names(preference)})"
                    raise self.fail(where(i), message)
            return named
        for i, prop in enumerate(properties):
            if not any(prop in spec.preference for spec in domains.values()):
                known = "; ".join(f"domain '{d}' knows: {names(spec.preference)}" for d, spec in domains.items())
                raise self.fail(where(i), f"unknown property '{prop}' ({known})")
        fitting = domains_knowing(properties, {d: spec.preference for d, spec in domains.items()})
        if len(fitting) == 1:
            return fitting[0]
        if fitting:
            raise self.fail(
                whole,
                f"domain not determined: several domains know every property ({', '.join(fitting)}); "
                "name one with 'domain:'",
            )
        owners = "; ".join(
            f"'{p}': {', '.join(d for d, spec in domains.items() if p in spec.preference)}"
            for p in dict.fromkeys(properties)
        )
        raise self.fail(
            whole, f"domain not determined: no domain knows every property (candidate domains per property: {owners})"
        )
