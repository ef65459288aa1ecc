"""Set-overlap scores for referring expressions (TUNA REG Challenge 2008).

A description is compared with a human's as a set of ``attribute=value``
properties.  Dice = 2|A & B| / (|A| + |B|); MASI (Passonneau 2006) = Jaccard x m,
with m = 1 if the sets are equal, 2/3 if one contains the other, 1/3 if they only
overlap and 0 if they are disjoint; accuracy is the share of trials with Dice 1.
"""

from __future__ import annotations

from typing import Collection

from ..core.algorithms.alignment import dice

__all__ = ["dice", "masi", "mean"]  # dice is defined once, in the core (alignment)


def masi(a: Collection[str], b: Collection[str]) -> float:
    """Return MASI: Jaccard weighted by monotonicity (1, 2/3, 1/3, 0)."""
    a, b = set(a), set(b)
    if a == b:
        return 1.0
    common = a & b
    if not common:
        return 0.0
    jaccard = len(common) / len(a | b)
    monotonicity = 2 / 3 if a <= b or b <= a else 1 / 3
    return jaccard * monotonicity


def mean(values: Collection[float]) -> float:
    """Return the average of the values (0.0 for none)."""
    return sum(values) / len(values) if values else 0.0
