"""Reference resolution (RR): find the entity a heard description refers to.

docs/semantics.md section 3.  The description's properties are checked in utterance order
against every candidate still in play (the consultant keeps the candidate set: opening it
checks the first property, one :class:`~fsreg_ros.core.algorithms.port.Walk` the others, see
:class:`~fsreg_ros.core.algorithms.port.ConsultantPort`).  Each time a property is affirmed for a
candidate it is encoded into that candidate's WM (rule 2), even if the candidate
is ruled out by a later property.  A description that resolves to exactly one
entity is then encoded, whole and in utterance order, for its referent (rule 1).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Collection, Mapping, Optional, Sequence

from .port import ConsultantPort, KnowledgeError, Step, WalkStep

RESOLVED, AMBIGUOUS, NO_MATCH = "resolved", "ambiguous", "no-match"


class ResolutionError(ValueError):
    """The description cannot be resolved at all (unknown property, no domain)."""

    def __init__(self, message: str = "", kind: Optional[str] = None) -> None:
        super().__init__(message)
        #: The ``kind`` an error reply on a topic carries (``unknown-entity``, ...); None: the class name.
        self.kind = kind


@dataclass
class Resolution:
    """Result of resolving one description (the ``/rr/result`` fields)."""

    status: str
    domain: Optional[str]
    description: list[str]
    candidates: list[str] = field(default_factory=list)

    @property
    def resolved(self) -> Optional[str]:
        return self.candidates[0] if self.status == RESOLVED else None

    def to_json(self) -> dict:
        return {
            "status": self.status,
            "resolved": self.resolved,
            "candidates": list(self.candidates),
            "description": list(self.description),
            "domain": self.domain,
        }


def domains_knowing(description: Sequence[str], preferences: Mapping[str, Collection[str]]) -> list[str]:
    """Return the domains (in the given order) whose preference order contains every property.

    A description resolves in a domain only if exactly one fits.
    """
    return [d for d, preference in preferences.items() if all(p in preference for p in description)]


async def choose_domain(
    description: Sequence[str], ports: Mapping[str, ConsultantPort], domain: Optional[str] = None
) -> str:
    """Return the domain to resolve in.

    The given one, else the only domain whose preference order contains every property
    of the description (the ports cache preference orders: no call per turn).
    """
    if domain is not None:
        if domain not in ports:
            raise ResolutionError(f"unknown domain '{domain}' (known: {', '.join(sorted(ports))})",
                                  kind="unknown-domain")
        preference = set(await ports[domain].preference())
        missing = [p for p in description if p not in preference]
        if missing:
            raise ResolutionError(f"domain '{domain}' knows no property {', '.join(repr(p) for p in missing)}",
                                  kind="unknown-property")
        return domain
    preferences = {name: set(await port.preference()) for name, port in ports.items()}
    known = set().union(*preferences.values())
    fitting = domains_knowing(description, preferences)
    unknown = [p for p in description if p not in known]
    if unknown:
        raise ResolutionError(f"no consultant knows property {', '.join(repr(p) for p in unknown)}",
                              kind="unknown-property")
    if len(fitting) != 1:
        which = "no domain" if not fitting else f"several domains ({', '.join(sorted(fitting))})"
        raise ResolutionError(f"cannot tell the domain of {list(description)}: {which} know every property; "
                              "name it with 'domain'")
    return fitting[0]


async def resolve(
    description: Sequence[str],
    ports: Mapping[str, ConsultantPort],
    *,
    domain: Optional[str] = None,
    time: float = 0.0,
    turn: Optional[int] = None,
) -> Resolution:
    """Resolve a heard description (docs/semantics.md section 3), encoding as rules 1 and 2 say."""
    description = list(description)
    if not description:
        raise ResolutionError("the description is empty")
    domain = await choose_domain(description, ports, domain)
    port = ports[domain]
    try:
        # The consultant keeps the candidate set; opening it checks the first property, one walk the rest.
        view = await port.open(first=Step(description[0], "rr", time, turn))  # rule 2
        remaining = view.first.size if view.first is not None else view.size
        if remaining and len(description) > 1:
            steps = [WalkStep(prop) for prop in description[1:]]  # no target: every step narrows until none is left
            remaining = (await port.walk(view, steps, "rr", time, turn, size=remaining)).size  # rule 2
        # Rule 1 for a resolved description, in utterance order.
        candidates = await port.close(view, description if remaining == 1 else (), time, turn)
    except KnowledgeError as err:  # raced with an LTM change; report, never guess
        raise ResolutionError(str(err), kind=getattr(err, "kind", None)) from err
    if len(candidates) == 1:
        return Resolution(RESOLVED, domain, description, candidates)
    return Resolution(AMBIGUOUS if candidates else NO_MATCH, domain, description, candidates)
