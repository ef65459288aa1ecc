"""Rule ``activation`` on an entity's own clock: ``activation_clock`` = ``episodes`` or ``words``.

ACT-R's base-level activation (:mod:`fsreg_ros.core.memory.trace`'s arithmetic, unchanged)
read on a clock of each entity's own instead of the buffer's seconds
(:class:`~fsreg_ros.core.memory.activation.LazyActivation`, ``seconds``, the default):

* ``episodes``: the entity's reference episode counter (:meth:`WMBuffer.episode`,
  owned by :class:`~fsreg_ros.core.memory.episodes.EpisodeLog`); it moves when the
  entity's episode begins (:meth:`WMBuffer.begin_episode`);
* ``words``: how many properties were encoded for the entity since the rule was
  installed: every encoding event of a property into Q[entity] (Algorithm 1's push,
  a refresh included, whatever its cause) moves it by one.  This module owns these
  counters (:attr:`EntityClockActivation.words`); they survive a restart beside the
  episode log (:meth:`WMBuffer.export_episodes`).

Ages count from 1, so t^-d is finite: an encoding made when the entity's clock reads m
(during episode m; or as its (m+1)-th encoding, the clock then moving to m+1) is noted
at time m - 1 on that clock, on the episodes clock it is of age 1 during its own
episode, on the words clock of age 1 right after it is made; each move of the clock
adds 1.  An entry's activation at the entity's clock C is ln sum_j (C - t_j)^-d, and it
is forgotten (cause ``activation``) once C reaches its crossing time (activation at or
below tau), so a single encoding stays while its age is below exp(-tau / d).

Each entity has its own clock, so an entity's entries can only cross when its own
clock moves: at its episode's beginning (forgotten there, the event at that time) or at
an encoding for it (forgotten when Q[entity] is next read or encoded into, the event at
the time of the encoding that moved the clock).  Nothing else ages them: another
entity's episodes or encodings, or the seconds that pass.  The queues of this rule are
dict queues only (the column form keeps one clock: :func:`fsreg_ros.core.memory.columns`).
"""

from __future__ import annotations

from typing import Callable, Mapping, Optional, Union

from .activation import LazyActivation
from .host import HostBuffer
from .limits import Limits
from .queue import Queue
from .ticks import TIME_EPSILON
from .trace import Trace

#: The clocks rule ``activation`` may count on; the first is the buffer's own (seconds).
CLOCKS = ("seconds", "episodes", "words")


class EntityClockActivation(LazyActivation):
    """Rule ``activation`` on each entity's own clock (module docstring): traces in that clock's units.

    ``words[entity]`` is the entity's words clock (``counting == "words"``);
    ``moved[entity]`` the time (seconds) its clock last moved, which its forgettings are
    stamped with; ``pending`` the entities whose entries may have crossed since the last
    :meth:`flush`.  ``clock`` stays the buffer's seconds (the time stamps only).
    """

    def __init__(self, wm: HostBuffer, decay: float, threshold: float, clock: float, counting: str) -> None:
        super().__init__(wm, decay, threshold, clock)
        self.counting = counting
        self.words: dict[str, int] = {}
        self.moved: dict[str, float] = {}
        self.pending: set[str] = set()

    def now_of(self, entity: str) -> float:
        """Return the entity's own clock: its current episode, or how many encodings were made for it."""
        if self.counting == "words":
            return self.words.get(entity, 0)
        return self.wm.episode(entity)

    def begin(self, entity: str, time: float) -> None:
        """Note that the entity's episode began at ``time`` (its episodes clock moves; forgettings are stamped so)."""
        if self.counting == "episodes":
            self.moved[entity] = max(time, self.clock)
            self.pending.add(entity)

    def adopt(self, entity: str, q: Queue, time: float, traces: Optional[dict[str, Trace]] = None) -> None:
        """Take Q[entity] under the rule: ``traces`` kept, one encoding now (age 1) for the others."""
        super().adopt(entity, q, self.now_of(entity) - 1, traces)
        self.pending.add(entity)

    def record(self, entity: str, prop: str, time: float, present: bool) -> None:
        """Note an encoding into Q[entity] at ``time`` (seconds): on the entity's clock, at its reading less 1.

        On the words clock the encoding moves the clock by one first.
        """
        if self.counting == "words":
            self.words[entity] = self.words.get(entity, 0) + 1
            self.moved[entity] = max(time, self.clock)
        self.note(entity, prop, self.now_of(entity) - 1, present)
        self.pending.add(entity)

    def sync(self, entity: str, q: Queue) -> None:
        """Forget the entries of ``q`` whose crossing the entity's own clock reached (events when it moved)."""
        self.forget_crossed(entity, q, self.now_of(entity) + TIME_EPSILON, self.moved.get(entity, self.clock))

    def flush(self) -> None:
        """Bring the queues whose entity's clock moved (or that were encoded into) since the last flush up to it."""
        pending, self.pending = self.pending, set()
        get = self.wm.store.get
        for entity in pending:
            q = get(entity)
            if q:
                self.sync(entity, q)

    # ------------------------------------------------------------ persistence
    def clocks(self) -> dict[str, int]:
        """Return the words clocks a store keeps (``{}`` on the episodes clock: the episode log keeps those)."""
        return dict(self.words)

    def restore_clocks(self, words: Mapping[str, int]) -> None:
        """Take back :meth:`clocks`'s dict (checked by the caller)."""
        self.words = dict(words)


def new_rule(wm: HostBuffer, limits: Limits, clock: float) -> Union[LazyActivation, EntityClockActivation]:
    """Return rule ``activation`` per ``limits`` (``(d, tau)`` and the clock it counts on), the buffer at ``clock``."""
    decay, threshold = limits.activation  # type: ignore[misc]
    if limits.activation_clock == CLOCKS[0]:
        return LazyActivation(wm, decay, threshold, clock)
    return EntityClockActivation(wm, decay, threshold, clock, limits.activation_clock)


def export_clocks(wm: HostBuffer) -> dict:
    """Return the entities' own clocks as a store keeps them (:meth:`WMBuffer.export_episodes`).

    The episode log's dict (:meth:`EpisodeLog.export <.episodes.EpisodeLog.export>`),
    each entity's words clock under rule ``activation`` on it added as ``"words"`` (an
    entity with no episode yet: ``{"starts": [], "words": n}``).
    """
    out = wm.episodes.export()
    for entity, words in (wm.activation.clocks() if wm.activation is not None else {}).items():
        out.setdefault(entity, {"starts": [], "counts": {}})["words"] = words
    return out


def restore_clocks(wm: HostBuffer, data: Mapping, keep: Optional[Callable[[str], bool]] = None) -> list[str]:
    """Take back :func:`export_clocks`'s dict (after a restore); ValueError, nothing changed, if it is malformed.

    ``keep``: a predicate on entity names; the others' clocks are dropped and returned.
    """
    words = {}
    for entity, value in data.items() if isinstance(data, Mapping) else ():
        count = value.get("words", 0) if isinstance(value, Mapping) else 0
        if not isinstance(count, int) or isinstance(count, bool) or count < 0:
            raise ValueError(f"words clock of {entity!r}: {count!r} is not a whole number >= 0")
        if count and (keep is None or keep(entity)):
            words[entity] = count
    dropped = wm.episodes.restore(data, keep)
    if wm.activation is not None:
        wm.activation.restore_clocks(words)
    return dropped
