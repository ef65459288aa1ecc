"""The origin log: which encoding made each queue entry enter its queue.

Every queue entry knows the cause and turn of the encoding that made its property
*enter* the queue (a refresh while present keeps it; after it is forgotten, the next
encoding sets a new one): :meth:`WMBuffer.origins`.  Entries do not store it: an
entry that entered with stamp s refers to s, and this log maps stamps to origins.
``starts[i]`` is the first stamp of a run of encodings that all had origin
``runs[i]`` (consecutive calls with the same cause and turn share one run).  It
only has to answer for entries that refer to an entering stamp, so it is pruned to
those from time to time.
"""

from __future__ import annotations

from bisect import bisect_right
from typing import Optional

from .host import HostBuffer
from .queue import Entry, Origin

#: The log is pruned when it reaches twice its size after the last pruning, or this.
ORIGIN_LOG_MIN = 1024


class OriginLog:
    """Stamp -> origin for one buffer, as runs (see the module docstring)."""

    def __init__(self, wm: HostBuffer) -> None:
        self.wm = wm
        self.starts: list[int] = []
        self.runs: list[Origin] = []
        self.prune_at = ORIGIN_LOG_MIN

    def clear(self) -> None:
        self.starts, self.runs, self.prune_at = [], [], ORIGIN_LOG_MIN

    def log(self, first: int, cause: str, turn: Optional[int]) -> None:
        """Note that the encodings from stamp ``first`` on have origin ``(cause, turn)``."""
        starts, runs = self.starts, self.runs
        if runs and runs[-1] == (cause, turn):
            return  # the run goes on
        if starts and starts[-1] == first:  # the previous run pushed nothing
            runs[-1] = (cause, turn)
            return
        if len(starts) >= self.prune_at:
            self.prune()
            starts, runs = self.starts, self.runs
        starts.append(first)
        runs.append((cause, turn))

    def at(self, stamp: int) -> Origin:
        """Return the origin of the encoding with this stamp (one still referenced by an entry)."""
        return self.runs[bisect_right(self.starts, stamp) - 1]

    def of(self, value: Entry) -> Origin:
        """Return the origin of a dict queue's entry (see :mod:`fsreg_ros.core.memory.queue`)."""
        if value.__class__ is int:
            return self.at(value)
        ref = value[1]
        return self.at(ref) if ref.__class__ is int else ref

    def prune(self) -> None:
        """Keep only the runs some entry still stored as a bare stamp falls in.

        O(entries stored); run when the log has doubled since the last pruning, so
        its cost per encoding call stays bounded and the log's size follows WM's.
        """
        store = self.wm.store
        live = [v if v.__class__ is int else v[1] for _, q in store.dict_queues() for v in q.values()]
        live = [ref for ref in live if ref.__class__ is int]
        if store.columns.entities:
            live += store.columns.store.origin_stamps().tolist()
        live.sort()
        starts, runs = self.starts, self.runs
        kept_starts: list[int] = []
        kept_runs: list[Origin] = []
        i = 0
        for stamp in live:
            while i + 1 < len(starts) and starts[i + 1] <= stamp:
                i += 1
            if not kept_starts or kept_starts[-1] != starts[i]:
                kept_starts.append(starts[i])
                kept_runs.append(runs[i])
        self.starts, self.runs = kept_starts, kept_runs
        self.prune_at = max(ORIGIN_LOG_MIN, 2 * len(kept_starts))
