"""Reference episodes: each entity's episode counter, the episodes its entries were used in, rule ``episodes``.

An *episode* of an entity is one act of referring to it (docs/semantics.md section 2):
a human utterance that reference resolution resolved to it, a robot description of it,
or, in a corpus, one trial about its referent.  :meth:`WMBuffer.begin_episode` starts
one; the consultant does so when REG opens its view of a target (before the view reads
WM) and when RR's view closes with rule 1's encoding, before that encoding
(:mod:`fsreg_ros.core.consultant.views`).  Every
encoding of a property for an entity is *used in* the entity's current episode (0
before its first one), whatever its cause.

:class:`EpisodeLog` owns, per entity, the stamps its episodes began at (the buffer's
stamp counter then: an encoding with a larger stamp belongs to that episode or a
later one) and, per entry present at the entity's last episode boundary, how many
closed episodes it was used in since it entered the queue.  Nothing is noted per
encoding: an entry's last episode follows from its latest stamp, and the count is
brought up to date at each boundary, so the encoding paths carry nothing for it.
Only the entries used in the closing episode (the back of the queue, read alone:
:meth:`WMBuffer.entry_stamps` ``since``) change count at a boundary; the count of an
entry gone from the queue is never read (one entering again starts afresh) and is
dropped when the counts are rebuilt from the whole queue (under rule ``episodes``, or
once they hold more than twice the queue's length then, plus 8).
It reads the buffer only through its public interface (:class:`EpisodeHost`).

Rule ``episodes`` (``episode_window`` k): when episode n of an entity begins, before
its own encodings, every entry of the entity's queue whose last episode is before
n - k is forgotten (cause ``episodes``, LRU first).  So during episode n the queue
holds what was used in episodes n - k ... n: k = 1 keeps what was said in the previous
episode and what is said in the current one.  Only the entity whose episode begins
can change, and installing the rule forgets nothing until that entity's next boundary.
"""

from __future__ import annotations

import math
from bisect import bisect_left
from typing import Any, Iterable, Mapping, NamedTuple, Optional, Protocol

#: The forgetting cause of rule ``episodes``.
EPISODES_CAUSE = "episodes"


class Strength(NamedTuple):
    """How strongly one WM entry is held (:meth:`WMBuffer.strength`, parallel to :meth:`WMBuffer.queue`).

    ``age``: the entity's current episode minus the last episode the entry was used in
    (0: used in the current one); ``episodes``: in how many distinct episodes of the
    entity it was used since it entered the queue (at least 1); ``activation``: its ACT-R
    base-level activation at the buffer's clock while rule ``activation`` is in force
    (``math.inf`` at the very time of an encoding), else None.
    """

    age: int
    episodes: int
    activation: Optional[float] = None

    def to_json(self) -> dict:
        """Return ``{"age", "episodes", "activation"}`` (activation ``"inf"`` when infinite: JSON has no infinity)."""
        act = self.activation
        return {"age": self.age, "episodes": self.episodes,
                "activation": "inf" if act is not None and math.isinf(act) else act}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> "Strength":
        """Rebuild a strength from :meth:`to_json`'s dict."""
        act = data.get("activation")
        return cls(int(data["age"]), int(data["episodes"]), math.inf if act == "inf" else act)


class EntryStamps(NamedTuple):
    """One entry as the episode log reads it: property, latest stamp, stamp it entered with (None: unknown)."""

    property: str
    stamp: int
    entered: Optional[int]


class EpisodeHost(Protocol):
    """What :class:`EpisodeLog` uses of a buffer (all public)."""

    def entry_stamps(self, entity: str, since: int = 0) -> list[EntryStamps]:
        """Q[entity]'s entries (those encoded after stamp ``since``), LRU first."""

    def counters(self) -> tuple[int, int]:
        """``(stamp counter, decay ticks)``."""

    def remove(self, entity: str, prop: str, cause: str, time: float, turn: Optional[int] = None) -> bool:
        """Forget one property of Q[entity]."""


class EpisodeLog:
    """Per entity: the stamps its episodes began at, and its entries' counts of closed episodes (module docstring)."""

    def __init__(self, wm: EpisodeHost) -> None:
        self.wm = wm
        self.starts: dict[str, list[int]] = {}  # entity -> stamp counter when each of its episodes began
        self.counts: dict[str, dict[str, int]] = {}  # entity -> prop -> closed episodes used (at the last boundary)
        self.held: dict[str, int] = {}  # entity -> its queue's length when its counts were last rebuilt

    def clear(self) -> None:
        self.starts, self.counts, self.held = {}, {}, {}

    def current(self, entity: str) -> int:
        """Return the entity's current episode (0 before its first)."""
        return len(self.starts.get(entity, ()))

    def episode_of(self, entity: str, stamp: int) -> int:
        """Return the episode of the entity an encoding with this stamp was made in."""
        return bisect_left(self.starts.get(entity, ()), stamp)

    def begin(self, entity: str, window: Optional[int], time: float, turn: Optional[int]) -> int:
        """Begin the entity's next episode; under rule ``episodes`` (``window`` k) forget what left it.  Return it."""
        counts = self.counts.get(entity)
        if window is not None or counts is None or len(counts) > 2 * self.held.get(entity, 0) + 8:
            entries = self.wm.entry_stamps(entity)  # every entry: the counts of those gone are dropped
            self.counts[entity] = {e.property: n for e, n in zip(entries, self._counts(entity, entries))}
            self.held[entity] = len(entries)
        else:  # only the entries used in the closing episode change; an entry gone keeps a count no one reads
            starts = self.starts.get(entity)
            used = self.wm.entry_stamps(entity, starts[-1] if starts else 0)
            counts.update(zip([e.property for e in used], self._counts(entity, used)))
        starts = self.starts.setdefault(entity, [])
        starts.append(self.wm.counters()[0])
        episode = len(starts)
        if window is not None:
            oldest = episode - window  # the earliest episode an entry may have been last used in to stay
            for entry in entries:
                if self.episode_of(entity, entry.stamp) < oldest:
                    self.wm.remove(entity, entry.property, EPISODES_CAUSE, time, turn)
                    del self.counts[entity][entry.property]
        return episode

    def strength(self, entity: str, entries: Iterable[EntryStamps]) -> list[tuple[int, int]]:
        """Return ``(age, episodes)`` of each entry (:class:`Strength`'s first two fields)."""
        if not isinstance(entries, (list, tuple)):
            entries = list(entries)
        starts = self.starts.get(entity, ())
        current = len(starts)
        return [(current - bisect_left(starts, e.stamp), n) for e, n in zip(entries, self._counts(entity, entries))]

    def _counts(self, entity: str, entries: list[EntryStamps]) -> list[int]:
        """Return the distinct episodes each entry was used in, the current one included."""
        starts = self.starts.get(entity)
        begun = starts[-1] if starts else 0  # stamps start at 1
        known = self.counts.get(entity, {}).get
        return [1 if e.entered is not None and e.entered > begun  # it entered during the current episode
                else known(e.property, 0) + (e.stamp > begun) for e in entries]

    # ------------------------------------------------------------ persistence
    def export(self) -> dict:
        """Return the log as a store keeps it: ``{entity: {"starts": [...], "counts": {prop: n}}}``.

        ``counts`` are the closed episodes of the entries present now (an entry that entered
        during the current episode: 0), so they hold whatever the restored entries' entering
        stamps (which a store does not keep).
        """
        out = {}
        for entity, starts in self.starts.items():
            begun = starts[-1]
            known = self.counts.get(entity, {})
            counts = {e.property: known.get(e.property, 0) for e in self.wm.entry_stamps(entity)
                      if not (e.entered is not None and e.entered > begun)}
            out[entity] = {"starts": list(starts), "counts": {p: n for p, n in counts.items() if n}}
        return out

    def restore(self, data: Mapping[str, Any], keep: Optional[Any] = None) -> list[str]:
        """Replace the log with :meth:`export`'s dict; ValueError (nothing changed) if it is malformed.

        ``keep`` (a predicate on entity names) drops the other entities; they are returned.
        """
        if not isinstance(data, Mapping):
            raise ValueError("episodes: not an object")
        starts: dict[str, list[int]] = {}
        counts: dict[str, dict[str, int]] = {}
        dropped = []
        for entity, value in data.items():
            if not isinstance(value, Mapping) or not isinstance(value.get("starts"), list) \
                    or not isinstance(value.get("counts", {}), Mapping):
                raise ValueError(f"episodes of {entity!r}: not {{'starts': [...], 'counts': {{...}}}}")
            begun = value["starts"]
            if not all(_whole(s) and s >= 0 for s in begun) or any(a > b for a, b in zip(begun, begun[1:])):
                raise ValueError(f"episodes of {entity!r}: starts {begun[:8]!r} are not stamps in order")
            if not all(isinstance(p, str) and _whole(n) and n >= 0 for p, n in value.get("counts", {}).items()):
                raise ValueError(f"episodes of {entity!r}: counts are not property -> whole number")
            if keep is not None and not keep(entity):
                dropped.append(entity)
                continue
            if begun:
                starts[entity] = list(begun)
                counts[entity] = dict(value.get("counts", {}))
        self.starts, self.counts, self.held = starts, counts, {}
        return dropped


def _whole(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)
