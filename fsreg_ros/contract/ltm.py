"""Schemas of the long-term-memory topics: ``ltm/assert`` and ``ltm/assert/result``.

An assertion carries facts about one entity (``entity`` + ``properties``) or a batch of
facts about many entities of one domain (``facts``: a list of ``{"entity", "properties"}``);
a batch is applied in one commit (docs/semantics.md, "Facts in batches") and answered by
one result whose ``results`` say, per fact and in order, what was applied or refused.
"""

from __future__ import annotations

from typing import Optional

from pydantic import model_validator

from .base import Id, Message, Name, NameNumbers, Number, bounded_list


class LtmFact(Message):
    """One fact of a batch: properties (property -> certainty) of an entity, new or known."""

    entity: Name
    properties: NameNumbers


class LtmAssert(Message):
    """``ltm/assert``: facts about an entity (``entity``, ``properties``) or a batch of them (``facts``)."""

    domain: Name
    entity: Optional[Name] = None
    properties: Optional[NameNumbers] = None
    facts: Optional[bounded_list(LtmFact)] = None
    id: Optional[Id] = None

    @model_validator(mode="after")
    def _one_form(self) -> "LtmAssert":
        if self.facts is not None:
            if self.entity is not None or self.properties is not None:
                raise ValueError("give 'facts' (a batch) or 'entity' and 'properties', not both")
            if not self.facts:
                raise ValueError("field 'facts': an empty batch")
        elif self.entity is None or self.properties is None:
            raise ValueError(f"missing field '{'entity' if self.entity is None else 'properties'}' "
                             "(or give a batch as 'facts')")
        return self


class LtmFactResult(Message):
    """What one fact of a batch did: applied (``ok``) with what it changed, or refused with why."""

    entity: Optional[str] = None
    ok: bool
    new_entity: Optional[bool] = None
    updated: Optional[dict[str, Number]] = None
    retracted: Optional[list[str]] = None
    error: Optional[str] = None
    kind: Optional[str] = None


class LtmAssertResult(Message):
    """``ltm/assert/result``: what an assertion changed, or why it was refused.

    For a batch: ``results`` (one per fact, in order), ``applied`` and ``refused``
    (counts), and ``ok`` true only when every fact was applied.
    """

    domain: Optional[str] = None
    entity: Optional[str] = None
    ok: bool
    new_entity: Optional[bool] = None
    updated: Optional[dict[str, Number]] = None
    retracted: Optional[list[str]] = None
    results: Optional[list[LtmFactResult]] = None
    applied: Optional[int] = None
    refused: Optional[int] = None
    error: Optional[str] = None
    kind: Optional[str] = None
    id: Optional[Id] = None
