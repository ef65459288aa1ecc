"""Rule ``activation`` on an entity's own clock: ``activation_clock`` = ``episodes`` or ``words``.

ACT-R's base-level activation (:mod:`fsreg_ros.core.memory.trace`'s arithmetic, unchanged)
read on a clock of each entity's own instead of the buffer's seconds
(:class:`~fsreg_ros.core.memory.activation.LazyActivation`, ``seconds``, the default):

* ``episodes`` (:class:`EpisodeActivation`): the entity's reference episode counter
  (:meth:`WMBuffer.episode`, owned by :class:`~fsreg_ros.core.memory.episodes.EpisodeLog`);
  an entry's presentations are the episodes it was used in (one each, however many
  encodings in it), and it is decided when the entity's episode begins, the only time
  that clock moves.  Nothing is noted per encoding (as the episode log, it reads the
  entries' stamps at the boundary), so the encoding paths, the column form included,
  carry nothing for it;
* ``words`` (:class:`EntityClockActivation`): how many properties were encoded for the
  entity since the rule was installed: every encoding event of a property into Q[entity]
  (Algorithm 1's push, a refresh included, whatever its cause) moves it by one, and is a
  presentation.  Its counters are kept here (:attr:`EntityClockActivation.words`) for
  dict queues, and in their rows for column queues (each row keeps its entity's clock,
  :class:`~fsreg_ros.core.memory.trace_columns.TraceColumns`; the clock moves with the
  queue, as its traces do).

Ages count from 1, so t^-d is finite: a presentation made while the entity's clock reads
m (during episode m; or as its m-th encoding, that encoding moving the clock to m) is
noted at time m - 1, so it is of age 1 during its episode, or right after it is made,
and each move of the clock adds 1.  An entry's activation at the entity's clock C is
ln sum_j (C - t_j)^-d; it is forgotten (cause ``activation``) once C reaches its crossing.
Only the entity's own clock ages its entries, never another entity's episodes or
encodings, nor the seconds that pass.  Both clocks survive a restart beside the episode
log (:func:`export_clocks`).
"""

from __future__ import annotations

from typing import Callable, Mapping, Optional, Union

import numpy as np

from .activation import LazyActivation
from .episodes import EntryStamps
from .host import HostBuffer
from .limits import Limits
from .queue import Queue
from .ticks import TIME_EPSILON
from .trace import Trace, activation, crossing

#: The clocks rule ``activation`` may count on; the first is the buffer's own (seconds).
CLOCKS = ("seconds", "episodes", "words")


class EpisodeActivation:
    """Rule ``activation`` on the episodes clock: per entry, the episodes it was used in, decided at boundaries.

    ``traces[entity][prop]`` holds the presentations of the entry up to the entity's last
    boundary (episode m at time m - 1); whether it was used in the current episode
    follows from its latest stamp (:meth:`EpisodeLog.episode_of
    <fsreg_ros.core.memory.episodes.EpisodeLog.episode_of>`), and an entry that entered
    during the current episode starts afresh.  It reads the buffer only through its
    public interface.
    """

    def __init__(self, wm: HostBuffer, decay: float, threshold: float) -> None:
        self.wm, self.decay, self.threshold = wm, decay, threshold
        self.traces: dict[str, dict[str, Trace]] = {}

    def install(self) -> None:
        """Take every entry under the rule: each counts as used once, in its entity's current episode."""
        for entity in self.wm.nonempty_entities():
            self.traces[entity] = self._current(entity, self.wm.entry_stamps(entity))

    def _current(self, entity: str, entries: list[EntryStamps]) -> dict[str, Trace]:
        """Return each entry's presentations, its use in the current episode (if any) included."""
        log, mine = self.wm.episodes, self.traces.get(entity, {})
        now = log.current(entity)
        out = {}
        for entry in entries:
            fresh = entry.entered is not None and log.episode_of(entity, entry.entered) == now
            kept = None if fresh else mine.get(entry.property)
            trace = Trace(kept.first) if kept is not None else None
            if trace is not None:  # a copy: reading the current episode changes no kept trace
                trace.n, trace.recent = kept.n, list(kept.recent)
            if log.episode_of(entity, entry.stamp) == now or trace is None:
                if trace is None:
                    trace = Trace(now - 1)
                elif trace.recent[-1] < now - 1:
                    trace.add(now - 1)
            out[entry.property] = trace
        return out

    def begin(self, entity: str, time: float, turn: Optional[int]) -> None:
        """Before the entity's next episode begins: note the closing one, forget what the new clock takes below tau.

        Forgotten in crossing order (ties: LRU first), cause ``activation``, at ``time``.
        """
        traces = self._current(entity, self.wm.entry_stamps(entity))
        clock = self.wm.episode(entity) + 1 + TIME_EPSILON
        gone = sorted((due, i, prop) for i, (prop, trace) in enumerate(traces.items())
                      if (due := crossing(trace, self.decay, self.threshold)) <= clock)
        for _, _, prop in gone:
            self.wm.remove(entity, prop, "activation", time, turn)
            del traces[prop]
        if traces:
            self.traces[entity] = traces
        else:
            self.traces.pop(entity, None)

    def strength(self, entity: str, entries: list[EntryStamps]) -> list[float]:
        """Return each entry's activation at the entity's clock (finite: ages count from 1)."""
        traces, now = self._current(entity, entries), self.wm.episode(entity)
        return [activation(traces[e.property], now, self.decay) for e in entries]

    def export(self) -> dict[str, dict[str, list]]:
        """Return the kept presentations, ``{entity: {prop: trace as JSON}}``, of the entries held now.

        An entry that entered during the current episode has none (a kept one is an earlier
        stay's): restored, it starts afresh as it would here, whatever its entering stamp
        (which a store does not keep).
        """
        out, log = {}, self.wm.episodes
        for entity, traces in self.traces.items():
            now = log.current(entity)
            kept = {e.property: traces[e.property].to_json() for e in self.wm.entry_stamps(entity)
                    if e.property in traces
                    and not (e.entered is not None and log.episode_of(entity, e.entered) == now)}
            if kept:
                out[entity] = kept
        return out


class EntityClockActivation(LazyActivation):
    """Rule ``activation`` on each entity's words clock (module docstring): traces in that clock's units.

    ``words[entity]`` is the entity's clock while its queue is a dict queue (a column
    queue's row keeps it: :meth:`release_clocks`, :meth:`take_clock`); ``moved[entity]``
    the time (seconds) it last moved, which the forgettings it causes are stamped with
    (column queues are encoded into only while nobody listens); ``pending`` the entities
    encoded into since the last :meth:`flush`.  ``clock`` stays the buffer's seconds.
    """

    counting = "words"

    def __init__(self, wm: HostBuffer, decay: float, threshold: float, clock: float) -> None:
        super().__init__(wm, decay, threshold, clock)
        self.words: dict[str, int] = {}
        self.moved: dict[str, float] = {}
        self.pending: set[str] = set()

    def now_of(self, entity: str) -> float:
        """Return the entity's own clock: how many encodings were made for it."""
        words = self.words.get(entity)
        if words is not None:
            return words
        store = self.wm.store
        if store.in_columns(entity):
            return store.columns.store.traces.clock_of(store.columns.row[entity])
        return 0

    def column_clock(self) -> Optional[float]:
        """Return None: column rows are read and noted at each row's own clock."""
        return None

    def forget_members(self, rows: np.ndarray, members: int) -> None:
        """Before encoding into the column rows ``rows``, forget what is due there at each row's clock.

        Never skipped (:meth:`LazyActivation.forget_members`): every encoding moves its row's clock.
        """
        self.forget_rows(rows)

    def release_clocks(self, entities: list[str]) -> Optional[tuple[list[int], list[Optional[float]]]]:
        """Hand over the entities' clocks and when each moved (queues moving to column rows); kept here no longer."""
        pop, moved = self.words.pop, self.moved.pop
        return [pop(entity, 0) for entity in entities], [moved(entity, None) for entity in entities]

    def take_clock(self, entity: str, clock: int, moved: Optional[float]) -> None:
        """Keep the entity's clock and when it moved (its queue back from its column row)."""
        if clock:
            self.words[entity] = clock
        if moved is not None:
            self.moved[entity] = moved

    def carry_clocks(self, old: LazyActivation) -> None:
        """Take over the words clocks of ``old``, the rule this one replaces (new limits on the same clock).

        Its traces' times are on those clocks: they go on from where they were (a column
        queue's row keeps its own).
        """
        if isinstance(old, EntityClockActivation):
            self.words, self.moved = dict(old.words), dict(old.moved)

    def adopt(self, entity: str, q: Queue, time: float, traces: Optional[dict[str, Trace]] = None) -> None:
        """Take Q[entity] under the rule: ``traces`` kept, one encoding now (age 1) for the others."""
        super().adopt(entity, q, self.now_of(entity) - 1, traces)
        self.pending.add(entity)

    def record(self, entity: str, prop: str, time: float, present: bool) -> None:
        """Note an encoding into Q[entity] at ``time`` (seconds): it moves the entity's clock to m, noted at m - 1."""
        words = self.words[entity] = self.words.get(entity, 0) + 1
        self.moved[entity] = time if time > self.clock else self.clock
        self.note(entity, prop, words - 1, present)
        self.pending.add(entity)

    def sync(self, entity: str, q: Queue) -> None:
        """Forget the entries of ``q`` whose crossing the entity's clock reached (stamped when it moved)."""
        self.forget_crossed(entity, q, self.now_of(entity) + TIME_EPSILON, self.moved.get(entity, self.clock))

    def flush(self) -> None:
        """Bring the queues encoded into since the last flush, and the column queues, up to their entity's clock."""
        pending, self.pending = self.pending, set()
        pending.update(self.flush_columns())
        get = self.wm.store.get
        for entity in pending:
            q = get(entity)
            if q:
                self.sync(entity, q)

    def clocks(self) -> dict[str, int]:
        """Return the words clocks a store keeps (a column queue's from its row)."""
        out = dict(self.words)
        columns = self.wm.store.columns
        if columns.entities:
            row, traces = columns.row, columns.store.traces
            for entity in columns.entities:
                words = traces.clock_of(row[entity])
                if words:
                    out[entity] = words
        return out

    def restore_clocks(self, words: dict[str, int]) -> None:
        """Take back :meth:`clocks`'s dict (checked by the caller)."""
        self.words = dict(words)


def new_rule(wm: HostBuffer, limits: Limits, clock: float) -> Union[LazyActivation, EntityClockActivation]:
    """Return rule ``activation`` per ``limits`` (``(d, tau)``, on seconds or words), the buffer at ``clock``."""
    decay, threshold = limits.activation  # type: ignore[misc]
    if limits.activation_clock == "words":
        return EntityClockActivation(wm, decay, threshold, clock)
    return LazyActivation(wm, decay, threshold, clock)


def install_episodes(wm: HostBuffer, limits: Limits, fresh: bool = False) -> None:
    """Start, change or stop rule ``activation`` on the episodes clock per ``limits`` (kept presentations stay).

    ``fresh`` (a restore): start with no presentation (:func:`restore_clocks` brings them).
    """
    old = wm.episode_activation
    if limits.episode_activation is None:
        wm.episode_activation = None
    elif old is not None and not fresh:
        old.decay, old.threshold = limits.episode_activation
    else:
        wm.episode_activation = EpisodeActivation(wm, *limits.episode_activation)
        if not fresh:
            wm.episode_activation.install()


def begin_episode(wm: HostBuffer, entity: str, time: float, turn: Optional[int]) -> int:
    """Begin the entity's next episode (:meth:`WMBuffer.begin_episode`): activation on its clock, then the window."""
    if wm.episode_activation is not None:
        wm.episode_activation.begin(entity, time, turn)
    window = wm.limits.episode_window if wm.limits.retains else None
    return wm.episodes.begin(entity, window, time, turn)


def export_clocks(wm: HostBuffer) -> dict:
    """Return the entities' own clocks as a store keeps them (:meth:`WMBuffer.export_episodes`).

    The episode log's dict (:meth:`EpisodeLog.export <.episodes.EpisodeLog.export>`),
    with, per entity, its words clock (``"words": n``) or its entries' presentations on
    the episodes clock (``"activation": {prop: [n, first, recent...]}``) while rule
    ``activation`` counts on one (an entity with no episode yet: ``"starts": []``).
    """
    out = wm.episodes.export()
    for entity, words in (wm.activation.clocks() if wm.activation is not None else {}).items():
        out.setdefault(entity, {"starts": [], "counts": {}})["words"] = words
    if wm.episode_activation is not None:
        for entity, traces in wm.episode_activation.export().items():
            out.setdefault(entity, {"starts": [], "counts": {}})["activation"] = traces
    return out


def restore_clocks(wm: HostBuffer, data: Mapping, keep: Optional[Callable[[str], bool]] = None) -> list[str]:
    """Take back :func:`export_clocks`'s dict (after a restore); ValueError, nothing changed, if it is malformed.

    ``keep``: a predicate on entity names; the others' clocks are dropped and returned.
    """
    words, traces = {}, {}
    for entity, value in data.items() if isinstance(data, Mapping) else ():
        value = value if isinstance(value, Mapping) else {}
        count, presented = value.get("words", 0), value.get("activation", {})
        if not isinstance(count, int) or isinstance(count, bool) or count < 0:
            raise ValueError(f"words clock of {entity!r}: {count!r} is not a whole number >= 0")
        if not isinstance(presented, Mapping):
            raise ValueError(f"activation of {entity!r}: not {{property: [n, first, recent...]}}")
        if keep is None or keep(entity):
            words[entity] = count
            traces[entity] = {str(p): Trace.from_json(t) for p, t in presented.items()}  # ValueError if malformed
    dropped = wm.episodes.restore(data, keep)
    if wm.activation is not None:
        wm.activation.restore_clocks({e: n for e, n in words.items() if n})
    if wm.episode_activation is not None:
        wm.episode_activation.traces = {e: t for e, t in traces.items() if t}
    return dropped
