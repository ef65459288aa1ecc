"""LTM's holder index: per property, the bitset of the entities it holds for, packed from the facts.

A :class:`~fsreg_ros.core.consultant.consultant.Consultant` keeps LTM twice: per entity, the
certainty of each listed property, and per property, the bitset of the entities whose
certainty reaches the threshold (bit i = the i-th entity in entity order,
:mod:`fsreg_ros.core.memory.bitset`), which every query reads.  :func:`holder_bitsets`
builds the second from the first, whole (at start and when the threshold changes); a
runtime fact updates single bits in the consultant.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ..memory import bitset


def holder_bitsets(certainty: Mapping[str, Mapping[str, float]], entities: Sequence[str],
                   preference: Sequence[str], threshold: float) -> dict[str, int]:
    """Return every property's holder bitset, built fact by fact (not property x entity).

    ``certainty`` maps each of ``entities`` to its listed facts.  An entity whose every
    listed fact holds (the common case: a list of properties, certainty 1) contributes
    its properties in one C-level step; the bitsets are then packed from one (property,
    entity) boolean block per group of properties (:func:`bitset.rows_from_pairs`), not
    from one Python list per property.
    """
    size = len(entities)
    if threshold <= 0.0:  # certainty 0 (unlisted) holds too
        return {p: (1 << size) - 1 for p in preference}
    held: list[str] = []
    counts: list[int] = []
    for entity in entities:
        facts = certainty[entity]
        if facts and min(facts.values()) >= threshold:
            held.extend(facts)
            counts.append(len(facts))
        else:
            holding = [p for p, c in facts.items() if c >= threshold]
            held.extend(holding)
            counts.append(len(holding))
    rank = {p: k for k, p in enumerate(preference)}
    props = np.fromiter(map(rank.__getitem__, held), dtype=np.intp, count=len(held))
    owners = np.repeat(np.arange(size, dtype=np.intp), counts)
    return dict(zip(preference, bitset.rows_from_pairs(props, owners, len(preference), size)))
