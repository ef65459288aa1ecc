"""Bounds on what a node accepts (message size, name length, list length, answer caches)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Limits:
    """Bounds on what a node accepts; each is a parameter of the nodes that take input.

    ``max_message_bytes`` bounds a message or request (UTF-8 bytes of its JSON);
    ``max_name_chars`` any entity, property, domain or target name; ``max_list_items``
    any list (descriptions, context sets, entity lists, LTM assertions).  RR and REG also
    bound their answer caches by entries and by bytes (``answer_cache_*``).
    """

    max_message_bytes: int = 65_536
    max_name_chars: int = 256
    max_list_items: int = 1_000
    answer_cache_entries: int = 1_024
    answer_cache_bytes: int = 4 * 1024 * 1024


#: Declared ranges of the limit parameters (low, high).
LIMIT_RANGES = {
    "max_message_bytes": (256, 16 * 1024 * 1024),
    "max_name_chars": (8, 65_536),
    "max_list_items": (1, 1_000_000),
    "answer_cache_entries": (0, 1_000_000),
    "answer_cache_bytes": (0, 1024 * 1024 * 1024),
}
