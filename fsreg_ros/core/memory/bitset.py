"""Sets of a domain's entities as Python int bitsets over entity indices.

Bit i stands for the domain's i-th entity in entity order (docs/semantics.md section 2, "Entity
order"), so ascending bits are entity order and set algebra (``&``, ``|``, ``~``) is
one C-level operation on the whole domain.  Chosen by measurement (issue 11): asking
whether a property holds for each of 10,000 remaining entities took 553 us with a
list comprehension over a Python set, 6.9 us with a numpy boolean mask and 0.9 us
with an int bitset.  Turning a bitset back into indices goes through numpy
(~0.1 ms for 2,000 members of 10,000), so only the members that must be named are.
"""

from __future__ import annotations

from typing import Iterable, Sequence

import numpy as np


def from_indices(indices: Iterable[int], size: int) -> int:
    """Return the bitset of the given entity indices (each in ``range(size)``)."""
    flags = np.zeros(max(size, 1), dtype=bool)
    flags[np.fromiter(indices, dtype=np.int64)] = True
    return int.from_bytes(np.packbits(flags, bitorder="little").tobytes(), "little")


def rows_from_pairs(rows: np.ndarray, columns: np.ndarray, nrows: int, size: int) -> list[int]:
    """Return ``nrows`` bitsets over ``range(size)``: bitset r has bit c for every pair (rows[k], columns[k]) = (r, c).

    E.g. each property's holders from (property, entity) pairs.  The pairs are packed
    a block of rows at a time, at most :data:`BLOCK_BYTES` of flags per block.
    """
    out: list[int] = []
    per_block = max(1, BLOCK_BYTES // max(size, 1))
    if nrows > per_block:  # several blocks: each one's pairs in one slice
        order = np.argsort(rows, kind="stable")
        rows, columns = rows[order], columns[order]
    for first in range(0, nrows, per_block):
        last = min(first + per_block, nrows)
        flags = np.zeros((last - first, max(size, 1)), dtype=bool)
        if nrows > per_block:
            start, end = np.searchsorted(rows, [first, last])
            flags[rows[start:end] - first, columns[start:end]] = True
        else:
            flags[rows, columns] = True
        packed = np.packbits(flags, axis=1, bitorder="little")
        out.extend(int.from_bytes(row.tobytes(), "little") for row in packed)
    return out


#: Most bytes of flags :func:`rows_from_pairs` builds at once.
BLOCK_BYTES = 1 << 24


def indices(bits: int) -> list[int]:
    """Return the indices of the set bits of ``bits``, ascending."""
    return index_array(bits).tolist()


def index_array(bits: int) -> np.ndarray:
    """Return the indices of the set bits of ``bits``, ascending, as a numpy array (no Python ints)."""
    if not bits:
        return np.zeros(0, dtype=np.intp)
    data = np.frombuffer(bits.to_bytes((bits.bit_length() + 7) // 8, "little"), dtype=np.uint8)
    return np.flatnonzero(np.unpackbits(data, bitorder="little"))


def names(bits: int, entities: Sequence[str]) -> list[str]:
    """Return the entities whose bits are set, in entity order."""
    return [entities[i] for i in indices(bits)]


def positions(bits: int, members: int) -> int:
    """Return ``bits`` restricted to ``members`` and renumbered by member rank.

    Bit k of the result is set iff the k-th member (ascending) of ``members`` is in
    ``bits``: how a set of entities is written relative to one request's members.
    """
    if not members:
        return 0
    size = members.bit_length()
    chosen = np.asarray(indices(members), dtype=np.int64)
    flags = _flags(bits, size)[chosen]
    return int.from_bytes(np.packbits(flags, bitorder="little").tobytes(), "little")


def _flags(bits: int, size: int) -> np.ndarray:
    """Return ``bits`` as a boolean array of length ``size`` (higher bits dropped)."""
    nbytes = (size + 7) // 8
    data = np.frombuffer((bits & ((1 << (nbytes * 8)) - 1)).to_bytes(nbytes, "little"), dtype=np.uint8)
    return np.unpackbits(data, bitorder="little")[:size].astype(bool)
