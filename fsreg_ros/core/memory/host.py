"""What the buffer's collaborators see of it and of each other: protocols, so that none imports ``buffer``.

:class:`~fsreg_ros.core.memory.buffer.WMBuffer` holds its state in a
:class:`~fsreg_ros.core.memory.queues.QueueStore` and its collaborators (lazy decay and
activation, interference, the origin log, the change record) beside it, and hands each
itself; persistence's and the column paths' functions take it too.  They annotate it
with :class:`HostBuffer` rather than with ``WMBuffer``, and each other with the
protocols below (the public methods one calls on another), so that no collaborator
imports the module that imports them all (the package's import graph has no circle;
``test/project/test_layers.py`` checks).  Nothing here is private: a collaborator
changes queues only through the store's methods and the buffer's forgetting
primitives (:meth:`HostBuffer.forget_entry`, :meth:`HostBuffer.pop_entry`,
:meth:`HostBuffer.forget_everything`), which report events and keep the records.
"""

from __future__ import annotations

from typing import Mapping, Optional, Protocol, Sequence

import numpy as np

from .columns import QueueColumns
from .episodes import EntryStamps, EpisodeLog
from .limits import Limits
from .queue import Entry, EventSink, Origin, Queue
from .queues import QueueStore
from .ticks import TickLedger, TickRun
from .trace import Trace


class DecayRule(Protocol):
    """Decay's pops (:class:`~fsreg_ros.core.memory.decay.LazyDecay`) as the others call them."""

    ticks: TickLedger
    settled: int

    def catch_up(self, entity: str) -> None:
        """Apply the ticks Q[entity] still owes."""

    def sync(self, entity: str, q: Queue) -> None:
        """Apply the ticks a dict queue owes."""

    def settle_columns(self, rows: np.ndarray) -> None:
        """Apply the ticks column ``rows`` owe (no events)."""

    def flush(self) -> None:
        """Bring every queue up to date with the ticks given."""

    def reset(self, count: int) -> None:
        """Start over with ``count`` ticks given (a restore)."""

    def add(self, ticks: TickRun) -> None:
        """Give ticks lazily."""

    def now(self, ticks: TickRun, entity_order: Sequence[str]) -> None:
        """Apply ticks at once, in the canonical event order."""


class ActivationRule(Protocol):
    """Rule ``activation`` (:class:`~fsreg_ros.core.memory.activation.LazyActivation`) as the others call it."""

    clock: float
    counting: str  # the clock it counts on: seconds, episodes or words (:mod:`.entity_clock`)

    def advance(self, time: float) -> None:
        """Note that the clock reached ``time``."""

    def now_of(self, entity: str) -> float:
        """Return the time Q[entity]'s traces are read at (the entity's own clock, or the buffer's)."""

    def clocks(self) -> dict[str, int]:
        """Return the per-entity clocks a store keeps."""

    def restore_clocks(self, words: dict[str, int]) -> None:
        """Take back :meth:`clocks`'s dict."""

    def sync(self, entity: str, q: Queue) -> None:
        """Forget what crossed in a dict queue."""

    def record(self, entity: str, prop: str, time: float, present: bool) -> None:
        """Note an encoding."""

    def forget(self, entity: str, prop: str) -> None:
        """Note that an entry left its queue."""

    def flush(self) -> None:
        """Bring every queue up to the clock."""

    def release(self, entity: str) -> dict[str, Trace]:
        """Hand over the traces of a queue moving to the column form."""

    def take(self, entity: str, traces: dict[str, Trace]) -> None:
        """Keep the traces of a queue back from the column form."""

    def traces_of(self, entity: str) -> dict[str, Trace]:
        """Return the traces of a dict queue's entries."""

    def adopt(self, entity: str, q: Queue, time: float, traces: Optional[dict[str, Trace]] = None) -> None:
        """Take a queue under the rule."""

    def carry_clocks(self, old: "ActivationRule") -> None:
        """Take over the per-entity clocks of the rule this one replaces."""

    def passed(self, store: QueueColumns, rows: np.ndarray) -> np.ndarray:
        """Return the column slots whose crossing passed."""

    def forget_members(self, rows: np.ndarray, members: int) -> None:
        """Forget what is due in column rows before encoding into them."""

    def forget_row(self, row: int) -> None:
        """Forget what is due in one column row."""

    def noting(self) -> tuple[Optional[float], float, float, Optional[float]]:
        """Return how column queues note an encoding made now."""

    def column_clock(self) -> Optional[float]:
        """Return the clock column rows are read at (None: each row's own)."""

    def settle_columns(self, rows: np.ndarray) -> None:
        """Bring column rows up to the clock (no events)."""


class EpisodeActivationRule(Protocol):
    """Rule ``activation`` on the episodes clock (:class:`~fsreg_ros.core.memory.entity_clock.EpisodeActivation`)."""

    decay: float
    threshold: float
    traces: dict[str, dict[str, Trace]]

    def install(self) -> None:
        """Take every entry under the rule."""

    def begin(self, entity: str, time: float, turn: Optional[int]) -> None:
        """Decide the entity's entries as its next episode begins."""

    def strength(self, entity: str, entries: list[EntryStamps]) -> list[float]:
        """Return each entry's activation at the entity's clock."""

    def export(self) -> dict[str, dict[str, list]]:
        """Return the kept presentations as a store keeps them."""


class InterferenceRule(Protocol):
    """Displacement and the global limits (:class:`~fsreg_ros.core.memory.displacement.Interference`)."""

    def install(self, limits: Limits) -> None:
        """Choose the victim rule of ``limits``."""

    def enforce(self, entity: str, q: Queue, prop: str, time: float, turn: Optional[int]) -> None:
        """Enforce the limits after one encoding event."""

    def displace(self, entity: str, q: Queue, capacity: int, newest: str, time: float, turn: Optional[int]) -> None:
        """Keep a queue within ``capacity``."""

    def evict_global(self, limit: int, time: float, turn: Optional[int], cause: str = "global-capacity") -> None:
        """Keep the domain within ``limit``."""

    def evict_oldest(self, count: int, cause: str, time: float) -> None:
        """Forget the domain's ``count`` oldest fronts."""


class OriginRecord(Protocol):
    """The origin log (:class:`~fsreg_ros.core.memory.origins.OriginLog`)."""

    starts: list[int]
    runs: list[Origin]

    def log(self, first: int, cause: str, turn: Optional[int]) -> None:
        """Note the origin of the encodings from stamp ``first`` on."""

    def of(self, value: Entry) -> Origin:
        """Return a dict queue entry's origin."""

    def clear(self) -> None:
        """Forget every run (a restore)."""


class ChangeLog(Protocol):
    """The change record (:class:`~fsreg_ros.core.memory.changes.ChangeRecord`)."""

    entries: list

    def record(self, entity: str, q: Queue) -> None:
        """Note that a dict queue changed."""

    def note(self, entity: str) -> None:
        """Note that a column queue changed."""

    def mark_rows(self, rows: np.ndarray) -> None:
        """Note that column rows changed."""

    def compact(self) -> None:
        """Fold the column marks into names."""

    def clear(self) -> None:
        """Forget the record (a restore)."""

    def take(self) -> list[str]:
        """Return the changed entities and clear the record."""


class HostBuffer(Protocol):
    """A domain's WM buffer as its collaborators see it (:class:`~.buffer.WMBuffer` is the one)."""

    domain: str
    sink: Optional[EventSink]
    attributes: dict[str, str]  # property -> attribute (similarity)
    limits: Limits
    column_min: int
    store: QueueStore
    lazy_decay: DecayRule
    activation: Optional[ActivationRule]
    episode_activation: Optional[EpisodeActivationRule]
    interference: InterferenceRule
    origin_log: OriginRecord
    changes: ChangeLog
    episodes: EpisodeLog
    watchers: tuple  # the side logs kept per entry (buffer.EntryWatcher)

    @property
    def quiet(self) -> bool:
        """True when nobody must hear single encodings and forgettings (no event sink, no watcher)."""

    @property
    def ticks(self) -> TickLedger:
        """Every decay tick given so far."""

    def __len__(self) -> int:
        """Properties held, after applying owed decay."""

    def episode(self, entity: str) -> int:
        """Return the entity's current reference episode number (0 before its first)."""

    def entry_stamps(self, entity: str, since: int = 0) -> list[EntryStamps]:
        """Return each entry of Q[entity] (encoded after stamp ``since``) as the episode log reads it, LRU first."""

    def nonempty_entities(self) -> list[str]:
        """Entities whose queues are non-empty, every queue brought up to date first."""

    def front_stamp(self, entity: str) -> int:
        """Stamp of Q[entity]'s front."""

    def flush(self) -> None:
        """Bring every queue up to date with the ticks and the clock."""

    def readable(self, entity: str) -> Optional[Mapping]:
        """Return Q[entity] up to date with decay and the clock, for reading."""

    def pop_entry(self, entity: str, cause: str, time: float, turn: Optional[int]) -> Optional[str]:
        """Forget Q[entity]'s front (reported, recorded); return it."""

    def forget_entry(self, entity: str, q: Queue, prop: str, cause: str, time: float, turn: Optional[int]) -> None:
        """Forget one entry of a dict queue (reported, recorded)."""

    def remove(self, entity: str, prop: str, cause: str, time: float, turn: Optional[int] = None) -> bool:
        """Forget one property of Q[entity] (reported, recorded)."""

    def forget_everything(self, cause: str, time: float, turn: Optional[int]) -> None:
        """Forget every property (reported, recorded)."""
