"""The scenario data model: what a validated scenario or KB file holds.

Built by :func:`fsreg_ros.core.scenario.load_scenario`; immutable afterwards.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Mapping, Optional, Sequence

from ..forgetting import settings
from ..consultant.consultant import DEFAULT_THRESHOLD, Consultant
from ..forgetting.policies import (
    DEFAULTS, RULE_PARAMETERS, ForgettingPolicy, PolicyError, check_setting, merge_settings, parse_rules,
)
from ..io.yaml_source import SourceError

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..memory import EventSink

#: Path used for errors in command-line overrides of the ``memory:`` settings.
COMMAND_LINE = "<command line>"
#: The keys of a ``memory:`` block (the settings table's names).
MEMORY_KEYS = settings.names()


class ScenarioError(SourceError):
    """One problem with a scenario file: where it is and what is wrong (one line)."""


@dataclass(frozen=True)
class DomainSpec:
    """One domain of a scenario: its LTM, preference order and own memory settings."""

    name: str
    preference: tuple[str, ...]
    #: entity -> {property: certainty}, in file order; the list form means certainty 1.0.
    entities: dict[str, dict[str, float]]
    threshold: float = DEFAULT_THRESHOLD
    #: The domain's own ``memory:`` block (keys given with a non-null value), or None.
    memory: Optional[dict] = None
    #: property -> attribute, from the ``attributes:`` block and ``attr=value`` names.
    attributes: dict[str, str] = field(default_factory=dict)
    #: The declared exclusive groups (the ``exclusive:`` block); the ``attr=value`` groups are implied
    #: (:func:`~fsreg_ros.core.consultant.consultant.exclusive_groups`).
    exclusive: tuple[tuple[str, ...], ...] = ()


@dataclass(frozen=True)
class Turn:
    """One dialogue turn, as written in the file."""

    index: int  # position in the dialogue list, 0-based
    time: float
    speaker: str  # "human" | "robot"
    target: Optional[str] = None  # robot: required; human: optional ground truth
    description: Optional[tuple[str, ...]] = None  # human turns given as property lists
    text: Optional[str] = None  # human turns given as English
    domain: Optional[str] = None  # as written; None when absent
    context: Optional[tuple[str, ...]] = None  # robot turns only


@dataclass(frozen=True)
class Scenario:
    """A validated scenario or KB file."""

    name: str
    source: str  # file name used in error messages
    domains: dict[str, DomainSpec]  # file order
    memory: Optional[dict]  # top-level ``memory:`` block (non-null keys) or None
    dialogue: tuple[Turn, ...]  # may be empty (a KB file)
    #: Line numbers of some paths (``memory``, ``domains.<d>``, ``domains.<d>.memory``),
    #: for messages about them after loading.
    lines: Mapping[str, int] = field(default_factory=dict, repr=False, compare=False)

    def policy_for(self, domain: str, overrides: Optional[Mapping[str, Any]] = None) -> ForgettingPolicy:
        """Return the effective forgetting policy of ``domain``.

        The top-level ``memory:`` block, then the domain's own block, then
        ``overrides`` (command-line options; None values are ignored), merged key by
        key with :func:`forgetting.merge_settings`.  No policy anywhere means
        ``none``.  A bad setting becomes a :class:`ScenarioError` naming where it
        came from: ``memory``, ``domains.<d>.memory`` or ``<command line>``.
        """
        if domain not in self.domains:
            raise ScenarioError(self.source, "", f"unknown domain '{domain}' (known: {names(self.domains)})")
        layers = (
            ("memory", self.memory),
            (f"domains.{domain}.memory", self.domains[domain].memory),
            (COMMAND_LINE, dict(overrides) if overrides is not None else None),
        )
        for path, layer in layers:
            for key, value in (layer or {}).items():
                problem = memory_setting_problem(key, value)
                if problem is not None:
                    where = path if path == COMMAND_LINE else f"{path}.{key}"
                    raise ScenarioError(self.source, where, problem, self.lines.get(where, self.lines.get(path)))
        try:
            return merge_settings(*(layer for _, layer in layers))
        except PolicyError as err:
            # Every single value is valid, so a parameter is missing: blame the
            # most specific layer that chose the policy, and say how to give it.
            path, policy = "memory", "none"
            for candidate, layer in layers:
                if layer and layer.get("policy") is not None:
                    path, policy = candidate, str(layer["policy"])
            given = {k for _, layer in layers for k, v in (layer or {}).items() if v is not None}
            missing = [
                p for r in parse_rules(policy) for p in RULE_PARAMETERS[r] if p not in given and p not in DEFAULTS
            ]
            message = f"domain '{domain}': {err}"
            if missing:
                message = f"domain '{domain}': policy '{policy}' needs " + " and ".join(
                    f"'{name}' (add {settings.setting(name).option} {settings.setting(name).metavar}, or {name}: in a "
                    "memory block)" for name in missing
                )
            raise ScenarioError(self.source, path, message, self.lines.get(path)) from None

    def domain_of(self, entity: str) -> str:
        """Return the domain ``entity`` belongs to; ScenarioError if no domain has it."""
        for name, spec in self.domains.items():
            if entity in spec.entities:
                return name
        raise ScenarioError(self.source, "", f"unknown entity '{entity}' (known: {names(self.entities())})")

    def entities(self) -> list[str]:
        """Return every entity of every domain, in file order."""
        return [entity for spec in self.domains.values() for entity in spec.entities]

    def properties(self) -> set[str]:
        """Return every property: the union of all preference orders."""
        return {prop for spec in self.domains.values() for prop in spec.preference}

    def consultants(self, sink: Optional["EventSink"] = None) -> dict[str, Consultant]:
        """Return a fresh core :class:`Consultant` per domain.

        Entity order, preference and threshold are as in the file; ``sink``
        receives every WM event.
        """
        return {
            name: Consultant(name, spec.entities, spec.preference, spec.threshold, sink, attributes=spec.attributes,
                             exclusive=spec.exclusive)
            for name, spec in self.domains.items()
        }


def names(items: Sequence[str] | Mapping[str, Any], limit: Optional[int] = None) -> str:
    """Return ``a, b, c`` (or the first ``limit`` and a count), for messages."""
    items = list(items)
    if not items:
        return "none"
    if limit is not None and len(items) > limit:
        return f"{', '.join(items[:limit])}, ... ({len(items)} in all)"
    return ", ".join(items)


def memory_setting_problem(key: str, value: Any) -> Optional[str]:
    """Return what is wrong with one ``memory:`` setting, by the core's rules, or None."""
    if key not in MEMORY_KEYS:
        return f"unknown memory setting '{key}' (known: {', '.join(MEMORY_KEYS)})"
    if value is None:
        return None
    try:
        check_setting(key, value)
    except PolicyError as err:
        return str(err)
    return None
