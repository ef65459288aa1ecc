"""Schemas of the long-term-memory topics: ``ltm/assert`` and ``ltm/assert/result``."""

from __future__ import annotations

from typing import Optional

from .base import Id, Message, Name, NameNumbers, Number


class LtmAssert(Message):
    """``ltm/assert``: facts (property -> certainty) about an entity, new or known."""

    domain: Name
    entity: Name
    properties: NameNumbers
    id: Optional[Id] = None


class LtmAssertResult(Message):
    """``ltm/assert/result``: what an assertion changed, or why it was refused."""

    domain: Optional[str] = None
    entity: Optional[str] = None
    ok: bool
    new_entity: Optional[bool] = None
    updated: Optional[dict[str, Number]] = None
    retracted: Optional[list[str]] = None
    error: Optional[str] = None
    kind: Optional[str] = None
    id: Optional[Id] = None
